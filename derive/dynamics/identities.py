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
    cosines become sines and cosines of sums, like ``fu.TR8`` but in sparse
    polynomial arithmetic over Q(i) with exp(i theta_j) as variables, so shared
    subexpressions of the recursive dynamics are expanded once (a 5-link bias
    vector in a tenth of a second where TR8 takes half a minute). Display only:
    nothing is simplified beyond this normal form. Raises ValueError when
    ``expr`` is not of that kind (an angle outside sin/cos, a division by a
    symbol, another function).
    """
    from sympy.polys.domains import QQ_I
    from sympy.polys.rings import ring

    expr = sp.sympify(expr)
    angles = tuple(angles)
    others = sorted(expr.free_symbols - set(angles), key=sp.default_sort_key)
    n = len(angles)
    names = [f"x{i}" for i in range(n)] + [f"y{i}" for i in range(n)] + [f"v{i}" for i in range(len(others))]
    R, *gens = ring(names, QQ_I)
    xs, ys, vs = gens[:n], gens[n:2 * n], dict(zip(others, gens[2 * n:]))
    index = {a: i for i, a in enumerate(angles)}
    half, half_i = QQ_I(sp.Rational(1, 2), 0), QQ_I(0, sp.Rational(-1, 2))   # 1/2, 1/(2i)
    memo: dict[sp.Expr, object] = {}

    def harmonic(arg: sp.Expr) -> tuple[object, object]:
        """exp(i arg) and exp(-i arg) for arg an integer combination of the angles."""
        coeffs = sp.Poly(arg, *angles).as_dict() if arg.free_symbols <= set(angles) else None
        if not coeffs or any(sum(m) != 1 or not c.is_Integer for m, c in coeffs.items()):
            raise ValueError(f"sin/cos of {arg}: expected an integer combination of the angles")
        plus, minus = R.one, R.one
        for m, c in coeffs.items():
            i = m.index(1)
            up, down = (xs[i], ys[i]) if c > 0 else (ys[i], xs[i])
            plus, minus = plus * up ** abs(int(c)), minus * down ** abs(int(c))
        return plus, minus

    def conv(e: sp.Expr) -> object:
        if e in memo:
            return memo[e]
        if e.is_Rational:
            out = R(QQ_I(e, 0))
        elif e.is_Symbol:
            if e in index:
                raise ValueError(f"{e} appears outside sin/cos")
            out = vs[e]
        elif e.is_Add:
            out = R.zero
            for a in e.args:
                out += conv(a)
        elif e.is_Mul:
            out = R.one
            for a in e.args:
                out *= conv(a)
        elif e.is_Pow and e.exp.is_Integer and (e.exp >= 0 or e.base.is_Rational):
            out = conv(e.base) ** int(e.exp) if e.exp >= 0 else R(QQ_I(e, 0))
        elif isinstance(e, (sp.sin, sp.cos)):
            plus, minus = harmonic(e.args[0])
            out = (plus + minus) * half if isinstance(e, sp.cos) else (plus - minus) * half_i
        else:
            raise ValueError(f"{e}: expected a polynomial in sin/cos of the angles")
        memo[e] = out
        return out

    series: dict[tuple[tuple[int, ...], tuple[int, ...]], object] = {}
    for monom, c in conv(expr).terms():
        key = (tuple(a - b for a, b in zip(monom[:n], monom[n:2 * n])), monom[2 * n:])
        series[key] = series.get(key, QQ_I.zero) + c
    total = []
    for (k, rest), c in series.items():
        first = next((x for x in k if x), 0)
        if first < 0:
            continue
        m = sp.Mul(*(s ** p for s, p in zip(others, rest)))
        if first == 0:
            total.append(m * QQ_I.to_sympy(c))
            continue
        c2 = series.get((tuple(-x for x in k), rest), QQ_I.zero)
        a, b = QQ_I.to_sympy(c + c2), QQ_I.to_sympy((c - c2) * QQ_I(0, 1))
        arg = sp.Add(*(x * t for x, t in zip(k, angles)))
        total.append(m * (a * sp.cos(arg) + b * sp.sin(arg)))
    return sp.expand(sp.Add(*total))
