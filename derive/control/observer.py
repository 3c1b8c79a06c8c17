"""Nonlinear disturbance observer (eq. 21-25).

    z' = -L(theta) z + L(theta) (G(theta, theta') - B u - p(theta'))   (21)
    dhat = B^-1 (z + p(theta'))                                          (22)
    p = W theta',  L(theta) = W J^-1(theta)                              (23-25)

For n joints W generalises eq. (25) as the lower-triangular W[i][j] = w_j
(j <= i): for n = 2 it is [[w1, 0], [w1, w2]]. J is never inverted
symbolically beyond n = 2: L is kept as the product W J^-1 and the generated
code solves J x = G - B u - p - z numerically.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.dynamics.planar import Dynamics
from derive.model.spec import w_symbols as spec_w_symbols


def w_symbols(n: int) -> tuple[sp.Symbol, ...]:
    """Observer gain symbols w1..wn (the arm's parameters, derive.model.spec.w_symbols)."""
    return spec_w_symbols(n)


def w_matrix(w) -> sp.Matrix:
    """W of eq. (25), generalised: W[i][j] = w_j for j <= i, else 0 (n x n)."""
    n = len(w)
    return sp.Matrix(n, n, lambda i, j: w[j] if j <= i else 0)


def inverse_or_product(W: sp.Matrix, J: sp.Matrix):
    """L = W J^-1: explicit for n <= 2, an unevaluated matrix product beyond."""
    if J.rows <= 2:
        return (W * J.adjugate() / J.det()).applyfunc(sp.cancel)
    return sp.MatMul(W, sp.Inverse(J), evaluate=False)


@dataclass(frozen=True)
class Observer:
    """Observer in the gain symbols w (shapes for n joints).

    W: n x n, p: n x 1, L: n x n (explicit for n <= 2), zdot_rhs: n x 1 vector r
    with z' = W r and J r = G - B u - p - z (eq. 21 without J^-1), dhat: n x 1 (eq. 22).
    """

    w: tuple[sp.Symbol, ...]
    W: sp.Matrix
    p: sp.Matrix
    L: object
    J_solve_rhs: sp.Matrix
    dhat: sp.Matrix
    values: tuple[tuple[sp.Symbol, sp.Rational], ...]


def derive_observer(dyn: Dynamics, w_values) -> Observer:
    """Observer (eq. 21-25) for the dynamics; ``w_values`` the arm's gains."""
    n = dyn.J.rows
    s = dyn.sym
    w = w_symbols(n)
    W = w_matrix(w)
    p = W * sp.Matrix(s.dtheta)
    z, u = sp.Matrix(s.z), sp.Matrix(s.u)
    Binv = sp.diag(*[1 / dyn.B[i, i] for i in range(n)])
    values = tuple((wi, sp.Rational(v.numerator, v.denominator)) for wi, v in zip(w, w_values))
    return Observer(w=w, W=W, p=p, L=inverse_or_product(W, dyn.J),
                    J_solve_rhs=dyn.G - dyn.B * u - p - z, dhat=Binv * (z + p), values=values)


def zdot(obs: Observer, dyn: Dynamics) -> sp.Matrix:
    """z' of eq. (21) as an explicit matrix (uses J^-1: for n <= 2 and for checks)."""
    return obs.W * dyn.J.LUsolve(obs.J_solve_rhs)


def speed_bound(X: sp.Expr, w1: sp.Expr) -> sp.Expr:
    """Supremum of |theta2'| for which w1 > X theta2' holds (eq. 26), w1 / X."""
    return w1 / X
