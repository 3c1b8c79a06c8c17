"""Composite law (eq. 27) and its nonlinear PID form (eq. 28-38).

Along the composite loop the estimate moves as (eq. 29, with the printed
'y_d-dot' read as y_d-double-dot)

    dhat' = -B^-1 W C^-1 (e'' + K2 e' + K1 e).

Integrating from 0 to t (eq. 30) leaves the constant
B^-1 W C^-1 (e'(0) + K2 e(0)) + dhat(0); the initial estimate that removes it,
so that the composite law and the PID form give the same u for all t, is
solved for here rather than copied from eq. (31):

    dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0)).

Printed eq. (31) lacks the K2 on e(0); it agrees only when K2 = I (see
``derive check``). P, D, I, N are the Jacobians of u* - dhat(t) in e, e',
int e and the remainder: eq. (35-38).

The estimate of the PID form is dhat = -B^-1 W xi with the PID error
xi = C^-1 (e' + K2 e + K1 int e) (eq. 32), so u = u* + B^-1 W xi. The
sampled form that matches the backward-Euler observer (derive.codegen.kernels,
``--observer implicit``) replaces W by W_dt = W (J + dt W)^-1 J there, and so
in the initial estimate too: dhat(0) = -B^-1 W_dt C^-1 (e'(0) + K2 e(0)), with
J at the first sample. With dhat(0) of W instead, the DOBC form starts from
another estimate than the PID form applies (on a light wrist, dt W J^-1 >> 1,
W_dt is about J / dt, far below W: 87.5 against 9.6 N m on the iiwa's wrist
for a 0.2 rad step at 1 ms, issue 20 item 5). After the first sample the two sampled forms differ by
W (J + dt W)^-1 c with c = O(dt) (the left-rectangle sums of e' and yd'' and dt (G_k - G_0) in the
observer step; the exact recursion is in the README, "Implicit observer step", and is tested):
O(dt) where dt W J^-1 is small, O(1) on a joint where it is large (issue 34 item 4).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.dynamics.dag import jacobian, matrix_xreplace
from derive.dynamics.equations import Dynamics
from derive.errors import DerivationError
from derive.control.mpc import Mpc
from derive.control.observer import Observer
from derive.summary import compact_repr


@compact_repr
@dataclass(frozen=True)
class Npid:
    """Composite and PID forms (shapes for n joints, in gain symbols).

    dhat_rate: eq. (29) in e'', e', e (n x 1); dhat_t: eq. (30) with dhat(0)
    symbols; dhat0: the derived initial estimate in e(0), e'(0) (n x 1);
    u_dobc: u* - dhat with dhat of eq. (22) (n x 1, eq. 27);
    P, D, I: n x n gains (eq. 35-37); N: n x 1 (eq. 38); xi: the PID error
    C^-1 (e' + K2 e + K1 int e) (n x 1), so that u_npid = u* + B^-1 W xi.
    u_dobc_rnea, u_npid_rnea: u_dobc and u_npid with u* by the recursive
    Newton-Euler pass (Mpc.u_star_rnea): the same laws, as the kernels compute them.
    """

    dhat_rate: sp.Matrix
    dhat_t: sp.Matrix
    dhat0: sp.Matrix
    u_dobc: sp.Matrix
    u_npid: sp.Matrix
    P: sp.Matrix
    D: sp.Matrix
    I: sp.Matrix
    N: sp.Matrix
    xi: sp.Matrix
    u_dobc_rnea: sp.Matrix
    u_npid_rnea: sp.Matrix


def derive_npid(dyn: Dynamics, mpc: Mpc, obs: Observer) -> Npid:
    """The composite law, the derived dhat(0) and the PID gains (eq. 27-38)."""
    n = dyn.J.rows
    s = dyn.sym
    e, de, int_e = sp.Matrix(s.e), sp.Matrix(s.de), sp.Matrix(s.int_e)
    e0, de0 = sp.Matrix(s.e0), sp.Matrix(s.de0)
    dde = sp.Matrix([sp.Symbol(f"dde{i + 1}", real=True) for i in range(n)])
    Binv = sp.diag(*[1 / dyn.B[i, i] for i in range(n)])
    M = Binv * obs.W * mpc.Cout.inv()               # B^-1 W C^-1
    rate = -M * (dde + mpc.K2 * de + mpc.K1 * e)    # eq. (29)
    # eq. (30): integrate each term from 0 to t; the map is applied to the
    # three derivatives at once so that no term is renamed twice.
    antiderivative = {**{a: b for a, b in zip(dde, de)}, **{a: b for a, b in zip(de, e)},
                      **{a: b for a, b in zip(e, int_e)}}
    at_zero = {**{a: b for a, b in zip(dde, de0)}, **{a: b for a, b in zip(de, e0)},
               **{a: 0 for a in e}}
    dhat_init = sp.Matrix([sp.Symbol(f"dhat0_{i + 1}", real=True) for i in range(n)])
    dhat_t = rate.xreplace(antiderivative) - rate.xreplace(at_zero) + dhat_init
    # dhat(0) such that dhat(t) has no constant part: solve for the unknowns
    constant = dhat_t.xreplace({**{a: 0 for a in e}, **{a: 0 for a in de}, **{a: 0 for a in int_e}})
    # the constant is dhat_init plus terms free of it (eq. 30): the unique dhat(0) is minus those terms
    rest = constant - dhat_init
    if set(dhat_init) & set().union(*(x.free_symbols for x in rest)):
        raise DerivationError("no unique initial estimate dhat(0) removes the constant of eq. (30)")
    dhat0 = -rest   # expanded once the arm's values are in (derive.control.pipeline), not over T1, T2
    dhat_pid = rate.xreplace(antiderivative)  # eq. (32): dhat(t) with its constant removed
    xi = mpc.Cout.inv() * (de + mpc.K2 * e + mpc.K1 * int_e)   # dhat_pid = -B^-1 W xi
    u_npid = mpc.u_star - dhat_pid  # kept factored: its Jacobians keep the structure of J, G
    P, D, I = (jacobian(u_npid, v) for v in (e, de, int_e))
    zero = {**{a: 0 for a in e}, **{a: 0 for a in de}, **{a: 0 for a in int_e}}
    N = matrix_xreplace(u_npid, zero)
    return Npid(dhat_rate=rate, dhat_t=dhat_t, dhat0=dhat0, u_dobc=mpc.u_star - obs.dhat,
                u_npid=u_npid, P=P, D=D, I=I, N=N, xi=xi, u_dobc_rnea=mpc.u_star_rnea - obs.dhat,
                u_npid_rnea=mpc.u_star_rnea - dhat_pid)
