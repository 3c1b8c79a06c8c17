"""Taylor-expansion predictive control (eq. 14-19) and its law u* (eq. 15).

Predicting y(t + tau) by its second-order Taylor expansion and minimising the
index (14) over [T1, T2] gives the closed form K1 = Tbar33^-1 Tbar31,
K2 = Tbar33^-1 Tbar32 (eq. 16-18). Since Tbar_i = diag(T_i, ..., T_i)
(eq. 19), K1 = k1 I and K2 = k2 I with scalar k1, k2.

The law is written without J^-1: (C J^-1 B)^-1 = B^-1 J C^-1, so
u* = B^-1 J C^-1 (K1 e + K2 e' + yd'') + B^-1 G   (eq. 15 with e = yd - y, eq. 20).
The same law in the form the generated code computes, ``u_star_rnea``, is
B^-1 (J a + G) with a = C^-1 (K1 e + K2 e' + yd'') by one recursive
Newton-Euler pass (:meth:`derive.dynamics.equations.Dynamics.inverse_dynamics`):
neither J nor the product J a is formed.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from fractions import Fraction

import sympy as sp

from derive.dynamics.equations import Dynamics
from derive.model.spec import T1_SYMBOL as T1
from derive.model.spec import T2_SYMBOL as T2
from derive.summary import compact_repr


def tbar(i: int, j: int, t1: sp.Expr = T1, t2: sp.Expr = T2) -> sp.Expr:
    """Scalar Tbar_ij of eq. (18) (the diagonal entry of the matrix, eq. 19)."""
    k = i + j - 1
    return (t2 ** k - t1 ** k) / (sp.factorial(i - 1) * sp.factorial(j - 1) * k)


@functools.lru_cache(maxsize=8)
def gains(t1: sp.Expr = T1, t2: sp.Expr = T2) -> tuple[sp.Expr, sp.Expr]:
    """(k1, k2) of eq. (16-17): K1 = k1 I, K2 = k2 I; symbolic by default, factored,

        k1 = Tbar31 / Tbar33 = 10 (t1^2 + t1 t2 + t2^2) / (3 q),
        k2 = Tbar32 / Tbar33 = 5 (t1 + t2)(t1^2 + t2^2) / (2 q),   q = t1^4 + t1^3 t2 + ... + t2^4,

    built as the products sp.factor gives for the quotients of eq. (18) (for the symbols T1, T2 the
    same SymPy trees, term for term: tests/test_show_speed.py; numbers for numbers), without its two
    factorisations (about 20 ms of ``derive show``). ``derive check`` proves the symbolic pair the
    minimiser of (14) (derive.proofs.project). Cached (SymPy expressions are immutable): every
    derivation and ``derive show`` read the same pair."""
    q = t1 ** 4 + t1 ** 3 * t2 + t1 ** 2 * t2 ** 2 + t1 * t2 ** 3 + t2 ** 4
    # three factors or more: Mul does not distribute the rational over the sum (with two it does)
    return (sp.Mul(sp.Rational(10, 3), t1 ** 2 + t1 * t2 + t2 ** 2, 1 / q),
            sp.Mul(sp.Rational(5, 2), t1 + t2, t1 ** 2 + t2 ** 2, 1 / q))


@compact_repr
@dataclass(frozen=True)
class Mpc:
    """Predictive controller in the arm's parameters T1, T2 (shapes for n joints).

    K1, K2: n x n (k1 I, k2 I with k1, k2 the expressions of T1, T2 of eq. 16-18,
    so a runtime T2 changes the gains); Cout: n x n output matrix C (eq. 13);
    u_star: n x 1 law (eq. 15) in e, e', yd'', theta, theta'; u_star_rnea: the
    same law by the recursive Newton-Euler pass (what the kernels compute); a: n x 1 the
    acceleration the law asks for, C^-1 (K1 e + K2 e' + yd''), so that J a + G = B u*;
    values: exact T1, T2.
    """

    K1: sp.Matrix
    K2: sp.Matrix
    Cout: sp.Matrix
    u_star: sp.Matrix
    u_star_rnea: sp.Matrix
    a: sp.Matrix
    values: tuple[tuple[sp.Symbol, sp.Rational], ...]


def _rational(x: Fraction) -> sp.Rational:
    return sp.Rational(x.numerator, x.denominator)


def derive_mpc(dyn: Dynamics, t1: Fraction, t2: Fraction, C: tuple[tuple[Fraction, ...], ...]) -> Mpc:
    """The law u* (eq. 15) for the dynamics, with gains k1(T1, T2), k2(T1, T2) for [t1, t2]."""
    n = dyn.J.rows
    s = dyn.sym
    k1, k2 = gains()
    K1, K2 = k1 * sp.eye(n), k2 * sp.eye(n)
    Cout = sp.Matrix([[_rational(x) for x in row] for row in C])
    e, de, ddyd = sp.Matrix(s.e), sp.Matrix(s.de), sp.Matrix(s.ddyd)
    Binv = sp.diag(*[1 / dyn.B[i, i] for i in range(n)])
    u_star = Binv * dyn.J * Cout.inv() * (K1 * e + K2 * de + ddyd) + Binv * dyn.G
    a = Cout.inv() * (K1 * e + K2 * de + ddyd)
    tau = dyn.inverse_dynamics(a)
    u_star_rnea = sp.Matrix([Binv[i, i] * tau[i] for i in range(n)])   # B is diagonal (eq. 12)
    return Mpc(K1=K1, K2=K2, Cout=Cout, u_star=u_star, u_star_rnea=u_star_rnea, a=a,
               values=((T1, _rational(t1)), (T2, _rational(t2))))
