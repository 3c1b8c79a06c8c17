"""Deciding symbolic identities cheaply and soundly.

Whole-matrix ``simplify``/``trigsimp`` is never used (seconds at n = 3,
minutes at n = 4). Instead an expression that is rational in the parameters
and polynomial in sin(theta_i), cos(theta_i) is brought to a canonical form:
``expand_trig``, then s_i = sin(theta_i), c_i = cos(theta_i) and the remainder
modulo s_i^2 + c_i^2 - 1 with respect to s_i. The polynomials
{s_i^2 + c_i^2 - 1} have pairwise disjoint variables, so they form a Groebner
basis and the remainder is zero exactly when the expression is identically
zero: ``is_zero`` returning True is a proof, False a refutation.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence

import sympy as sp


def trig_normal(expr: sp.Expr, angles: Sequence[sp.Symbol]) -> sp.Expr:
    """Canonical numerator of ``expr`` in s_i, c_i (zero iff expr == 0 identically)."""
    expr = sp.sympify(expr)
    if expr == 0:
        return sp.Integer(0)
    s = [sp.Dummy(f"s{i}") for i in range(len(angles))]
    c = [sp.Dummy(f"c{i}") for i in range(len(angles))]
    rep = {}
    for a, si, ci in zip(angles, s, c):
        rep[sp.sin(a)] = si
        rep[sp.cos(a)] = ci
    num, _ = sp.fraction(sp.together(sp.expand_trig(expr)))
    poly = sp.expand(num.xreplace(rep))
    leftover = poly.free_symbols & set(angles)
    if leftover:  # an angle outside sin/cos (or under another function): not decidable here
        raise ValueError(f"expression is not polynomial in sin/cos of {sorted(map(str, leftover))}")
    for si, ci in zip(s, c):
        if poly.has(si):
            poly = sp.rem(poly, si ** 2 + ci ** 2 - 1, si)
    return sp.expand(poly)


def is_zero(expr: sp.Expr, angles: Sequence[sp.Symbol] = ()) -> bool:
    """True when ``expr`` is identically zero (a proof), False when it is not."""
    return trig_normal(expr, angles) == 0


def matrix_is_zero(m: sp.MatrixBase, angles: Sequence[sp.Symbol] = ()) -> bool:
    """Every entry of ``m`` identically zero."""
    return all(is_zero(x, angles) for x in m)


def first_nonzero(m: sp.MatrixBase, angles: Sequence[sp.Symbol] = ()) -> tuple[int, int] | None:
    """Index (row, column) of the first entry that is not identically zero, or None."""
    for i in range(m.rows):
        for j in range(m.cols):
            if not is_zero(m[i, j], angles):
                return i, j
    return None


def _as_literals(expr: sp.Expr) -> sp.Expr:
    """``expr`` with every non-integer rational as a Float: one constant, as in generated code."""
    return expr.xreplace({r: sp.Float(r, 17) for r in expr.atoms(sp.Rational) if not r.is_Integer})


def count_ops_cse(exprs: Iterable[sp.Expr]) -> int:
    """Operations (sympy.count_ops) of a list of expressions after common
    subexpression elimination: the cost measure of the benchmarks.

    Counted as the generated code computes them: an exact rational constant
    p/q is one literal (the double nearest to it), not a division, so
    ``3*x/4`` is one multiplication and ``x + 1/3`` one addition (count_ops
    on SymPy's Rational would count a DIV for each: about a fifth of the
    operations of an arm with its values put in)."""
    replacements, reduced = sp.cse(list(exprs), order="none")
    return int(sum(sp.count_ops(_as_literals(r)) for _, r in replacements)
               + sum(sp.count_ops(_as_literals(r)) for r in reduced))


def fourier_form(expr: sp.Expr, angles: Sequence[sp.Symbol]) -> sp.Expr:
    """``expr`` as its unique trigonometric (Fourier) polynomial in the angles.

    ``expr`` is a polynomial, with rational coefficients, in other symbols and in
    sin/cos of integer combinations of ``angles``. The result is the sum of
    m(x) (a cos(k.theta) + b sin(k.theta)) over distinct monomials m of the other
    symbols and distinct k (first non-zero k_i positive): products of sines and
    cosines become sines and cosines of sums, like ``fu.TR8``, computed exactly in
    FLINT (:func:`derive.dynamics.fourier.fourier_series`). Display only: nothing
    is simplified beyond this normal form. Raises ValueError when ``expr`` is not
    of that kind (an angle outside sin/cos, a division by a symbol, another function).
    """
    from derive.dynamics.fourier import fourier_series

    return fourier_series([sp.sympify(expr)], angles)[0].to_expr()
