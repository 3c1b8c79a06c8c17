"""The generalized-momentum observer: a further disturbance estimate (issue 12 item 6).

With the generalized momentum p = J(theta) theta' and the Coriolis matrix C of
Christoffel symbols (J' = C + C^T), the plant J theta'' + G = B (u + d) (eq. 12,
G = C theta' + g + F theta', F the motor and viscous damping) gives

    p' = B (u + d) + C^T theta' - g - F theta' = B (u + d) + beta,
    beta = C^T theta' - g - F theta' = J'(theta, theta') theta' - G(theta, theta'),

so the residual

    r = K (p - m),   m' = B u + beta + r,   m(0) = J(theta0) theta0'          (*)

i.e. r = K (J theta' - int_0^t (B u + C^T theta' - g - F theta' + r) dt - J(theta0) theta0'),
obeys r' = K (B d - r) exactly, whatever the state: for any K > 0 (diagonal, per
joint) it converges exponentially to B d with no bound on the speed (unlike
eq. 21, whose theorem 2 needs condition 26). The estimate is dhat = B^-1 r and
the composite law is eq. 27 with it: u = u* - dhat.

It does not reduce to a PID. Under the composite law, B d - r = J theta'' + G - B u*,
so (as eq. 28-29 for dhat) r' = -K J(theta) C^-1 (e'' + K2 e' + K1 e). In eq. (29) the
factor is the constant W, which integrates to the PID error of eq. (32); here it is
K J(theta): int K J e'' dt = K (J e' - int J' e' dt) keeps an integral of J'(theta, theta') e'
that is no function of e, e' and int e, so the law keeps a state of its own (it is a
PID only when J is constant).

Discretised (derive.codegen.kernels): m_{k+1} = m_k + dt (B u_k + beta_k + r_k)
with the applied u_k (forward Euler); r_k = K (J theta'_k - m_k). ``beta`` is the
reference form, from the chain's Coriolis matrix (derive.dynamics.coriolis, O(n^2),
no derivative of J) as C^T theta' - g - F theta'; the kernels compute ``p_rnea`` and
``beta_rnea``, the same vectors by one recursion over the chain
(derive.dynamics.momentum: J theta' and C^T theta' from the bodies' spatial momenta,
De Luca and Ferrajoli 2009), neither J nor C formed. Under the composite law
u = u* - B^-1 r (unclipped), B u + r = B u* = J a + G, so the step is
m_{k+1} = m_k + dt (B u*_k + beta_k) + dt B (u_k - u_law,k): the last term is the
voltage limit's share, zero while no joint is clipped.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.dynamics.dag import times
from derive.dynamics.equations import Dynamics
from derive.model.spec import momentum_symbols


@dataclass(frozen=True)
class Momentum:
    """The momentum observer in symbols (shapes for n joints).

    k: the gain symbols kr1..krn [1/s], K = diag(k) (n x n); m: the state symbols
    (the integral of (*), n); p = J theta' (n x 1); beta = C^T theta' - g - F theta' (n x 1);
    r = K (p - m) (n x 1); m_rate = B u + beta + r (n x 1); dhat = B^-1 r (n x 1);
    p_rnea, beta_rnea, dhat_rnea: p, beta and dhat as the kernels compute them (one recursion,
    derive.dynamics.momentum), equal to p, beta and dhat. A derivation's own stage (the dynamics
    put in) holds ``beta`` and ``m_rate`` in the recursion's form (:func:`by_recursion`): the
    Coriolis matrix of ``beta`` is formed only where a check compares the two (derive check,
    the code generator's reference: :func:`coriolis_rate`).
    """

    k: tuple[sp.Symbol, ...]
    m: tuple[sp.Symbol, ...]
    K: sp.Matrix
    p: sp.Matrix
    beta: sp.Matrix
    r: sp.Matrix
    m_rate: sp.Matrix
    dhat: sp.Matrix
    p_rnea: sp.Matrix
    beta_rnea: sp.Matrix
    dhat_rnea: sp.Matrix


def state_symbols(n: int) -> tuple[sp.Symbol, ...]:
    """The momentum observer's state m1..mn (the integral of (*), kg m^2/s per joint)."""
    return tuple(sp.Symbol(f"mom{i + 1}", real=True) for i in range(n))


def derive_momentum(dyn: Dynamics) -> Momentum:
    """The momentum observer of ``dyn`` (module docstring)."""
    s = dyn.sym
    n = len(s.theta)
    k = momentum_symbols(n)
    m = state_symbols(n)
    K = sp.diag(*k)
    dq = sp.Matrix(s.dtheta)
    p = dyn.J * dq
    C = dyn.coriolis   # J' = C + C^T, C theta' + g = bias (derive.dynamics.coriolis)
    beta = sp.Matrix([sum((C[j, i] * s.dtheta[j] for j in range(n)), sp.S.Zero) for i in range(n)]) \
        - dyn.gravity - dyn.damping * dq
    r = K * (p - sp.Matrix(m))
    Binv = sp.diag(*[1 / dyn.B[i, i] for i in range(n)])   # B is diagonal (eq. 12)
    p_rnea, ct = dyn.momentum   # J theta', C^T theta' by the recursion
    beta_rnea = ct - dyn.gravity - dyn.damping * dq
    return Momentum(k=k, m=m, K=K, p=p, beta=beta, r=r, m_rate=dyn.B * sp.Matrix(s.u) + beta + r,
                    dhat=Binv * r, p_rnea=p_rnea, beta_rnea=beta_rnea,
                    dhat_rnea=times(Binv * K, p_rnea - sp.Matrix(m)))   # diagonal x large: derive.dynamics.dag.times


def by_recursion(mom: Momentum, dyn: Dynamics) -> Momentum:
    """``mom`` with beta and m_rate = B u + beta + r in the recursion's form (beta_rnea, equal to
    C^T theta' - g - F theta'): what a derivation keeps once the dynamics are put in, so that no
    command forms the Coriolis matrix unless it checks the identity (0.3 s of SymPy on a 7-joint
    arm, for show, init and the sample-time analysis that read only m_rate)."""
    from dataclasses import replace

    return replace(mom, beta=mom.beta_rnea, m_rate=dyn.B * sp.Matrix(dyn.sym.u) + mom.beta_rnea + mom.r)


def coriolis_rate(dyn: Dynamics, mom: Momentum) -> sp.Matrix:
    """m' = B u + C^T theta' - g - F theta' + K (J theta' - m) (*) from ``dyn``'s own Coriolis matrix
    (n x 1): the reference form, independent of the recursion the kernels use."""
    n = len(dyn.sym.theta)
    dq = sp.Matrix(dyn.sym.dtheta)
    C = dyn.coriolis
    beta = sp.Matrix([sum((C[j, i] * dq[j] for j in range(n)), sp.S.Zero) for i in range(n)]) \
        - dyn.gravity - dyn.damping * dq
    return dyn.B * sp.Matrix(dyn.sym.u) + beta + times(mom.K, times(dyn.J, dq) - sp.Matrix(mom.m))
