"""Nonlinear disturbance observer (eq. 21-25).

    z' = -L(theta) z + L(theta) (G(theta, theta') - B u - p(theta'))   (21)
    dhat = B^-1 (z + p(theta'))                                          (22)
    p = W theta',  L(theta) = W J^-1(theta)                              (23-25)

For n joints W generalises eq. (25) as the lower-triangular W[i][j] = w_j
(j <= i): for n = 2 it is [[w1, 0], [w1, w2]]; an arm may also give a full
n x n W (gain symbols W1_1 .. Wn_n), stated or synthesised
(derive.control.certificate.synthesis); p = W theta' and the proof of theorem 2 need no
structure (derive.control.certificate). J is never inverted
symbolically beyond n = 2: L is kept as the product W J^-1 and the generated
code solves J x = G - B u - p - z numerically.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.dynamics.equations import Dynamics
from derive.model.spec import w_symbols as spec_w_symbols
from derive.summary import compact_repr


def w_symbols(n: int) -> tuple[sp.Symbol, ...]:
    """Observer gain symbols w1..wn (the arm's parameters, derive.model.spec.w_symbols)."""
    return spec_w_symbols(n)


def full_symbols(n: int) -> tuple[sp.Symbol, ...]:
    """Gain symbols of a full W, row-major: W1_1, W1_2, ..., Wn_n [1/s]."""
    return tuple(sp.Symbol(f"W{i + 1}_{j + 1}", real=True) for i in range(n) for j in range(n))


def w_matrix(w) -> sp.Matrix:
    """W of eq. (25), generalised: W[i][j] = w_j for j <= i, else 0 (n x n)."""
    n = len(w)
    return sp.Matrix(n, n, lambda i, j: w[j] if j <= i else 0)


def inverse_or_product(W: sp.Matrix, J: sp.Matrix):
    """L = W J^-1: explicit for n <= 2, an unevaluated matrix product beyond."""
    if J.rows <= 2:
        return (W * J.adjugate() / J.det()).applyfunc(sp.cancel)
    return sp.MatMul(W, sp.Inverse(J), evaluate=False)


@compact_repr
@dataclass(frozen=True)
class Observer:
    """Observer in the gain symbols w (shapes for n joints).

    W: n x n, p: n x 1, L: n x n (explicit for n <= 2), zdot_rhs: n x 1 vector r
    with z' = W r and J r = G - B u - p - z (eq. 21 without J^-1), dhat: n x 1 (eq. 22).
    """

    w: tuple[sp.Symbol, ...]   # w1..wn (eq. 25 pattern) or W1_1..Wn_n (full W)
    W: sp.Matrix
    p: sp.Matrix
    L: object
    J_solve_rhs: sp.Matrix
    dhat: sp.Matrix
    values: tuple[tuple[sp.Symbol, sp.Rational], ...]
    full: bool = False

    @property
    def structure(self) -> str:
        """'chen' (W[i][j] = w_j for j <= i, eq. 25) or 'full'."""
        return "full" if self.full else "chen"


def derive_observer(dyn: Dynamics, w_values=None, W_values=None) -> Observer:
    """Observer (eq. 21-25) for the dynamics: ``w_values`` the n gains of eq. (25)
    generalised, or ``W_values`` a full n x n W (rows of exact numbers)."""
    n = dyn.J.rows
    s = dyn.sym
    full = W_values is not None
    if full:
        w = full_symbols(n)
        W = sp.Matrix(n, n, w)
        w_values = [x for row in W_values for x in row]
    else:
        w = w_symbols(n)
        W = w_matrix(w)
    p = W * sp.Matrix(s.dtheta)
    z, u = sp.Matrix(s.z), sp.Matrix(s.u)
    Binv = sp.diag(*[1 / dyn.B[i, i] for i in range(n)])
    values = tuple((wi, sp.Rational(v.numerator, v.denominator)) for wi, v in zip(w, w_values))
    return Observer(w=w, W=W, p=p, L=inverse_or_product(W, dyn.J),
                    J_solve_rhs=dyn.G - dyn.B * u - p - z, dhat=Binv * (z + p), values=values, full=full)


def zdot(obs: Observer, dyn: Dynamics) -> sp.Matrix:
    """z' of eq. (21) as an explicit matrix (uses J^-1: for n <= 2 and for checks)."""
    return obs.W * dyn.J.LUsolve(obs.J_solve_rhs)


def speed_bound(X: sp.Expr, w1: sp.Expr) -> sp.Expr:
    """Supremum of |theta2'| for which w1 > X theta2' holds (eq. 26), w1 / X."""
    return w1 / X
