"""What ``derive show`` prints of a matrix: its Fourier form at a stated precision.

Each entry is brought to its exact Fourier form (derive.dynamics.fourier: products of
sines and cosines as sines and cosines of sums; prismatic coordinates, rates and errors
as polynomial factors). A matrix is printed whole when it has at most ``BUDGET`` terms;
beyond, the terms smaller than ``tol`` times the matrix's largest term are left out, with
``tol`` raised through 1, 2, 5 x 10^k from 1e-6 until the rest fits, and every entry that lost terms
says how many and the bound of their sum (a term m (a cos + b sin) is at most
sqrt(a^2 + b^2) |m|). So a 7-joint J fits a few screens and nothing is left out silently.
A term's size is per unit of its rates or errors (its monomial): for those the bound is
per unit too.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.dynamics.fourier import fourier_series

BUDGET = 200          # terms per matrix printed whole
# an entry's Fourier form has at most prod over the angles (2 d_k + 1) terms (d_k its degree in angle k):
# 5^11 for a 12-joint J. Past this many the matrix is shown at the zero pose, and says so
TERM_CAP = 50_000
# the tolerances tried, relative to the matrix's largest term, when a matrix is over the budget
_LADDER = tuple(m * 10.0 ** e for e in range(-6, 1) for m in (1, 2, 5))


@dataclass(frozen=True)
class Shown:
    """A quantity ready to print: ``value`` (display expressions), ``notes``: per entry index
    a remark on the omitted terms, ``tol``: the relative tolerance used (0: every term)."""

    value: object
    notes: dict
    tol: float = 0.0
    note: str = ""    # what the whole quantity is, when not its Fourier form (past TERM_CAP)


def _quotient(x: sp.Expr, angles) -> sp.Expr:
    """num/den of a rational entry (L = W J^-1 of two joints), each in its Fourier form,
    the denominator's constant term made 1."""
    num, den = (fourier_series([f], angles)[0].to_expr() for f in sp.fraction(sp.together(x)))
    scale = den.as_coeff_Add()[0] or 1
    return sp.Mul(sp.expand(num / scale), sp.Pow(sp.expand(den / scale), -1), evaluate=False)


def shown(value: object, angles: tuple[sp.Symbol, ...], exact: bool, budget: int | None = BUDGET) -> Shown:
    """``value`` (a matrix or an expression) in its display form (module docstring); ``exact``:
    rationals and every term; ``budget`` None: every term."""
    matrix = isinstance(value, sp.MatrixBase)
    items = list(value) if matrix else [sp.sympify(value)]
    terms = term_bound(items, angles)
    if terms > TERM_CAP:
        return _at_zero(value, items, angles, exact, terms)
    try:
        series = fourier_series(items, angles)
    except ValueError:                     # a quotient (L of a 2-link arm)
        out = [_quotient(x, angles) if x.free_symbols else x for x in items]
        return Shown(_pack(value, out if exact else [sp.N(x, 15) for x in out], exact), {})
    sizes = [{k: s.magnitude(k) for k in s.terms} for s in series]
    scale = max((x for sz in sizes for x in sz.values()), default=0.0)
    tol, notes = 0.0, {}
    if not exact and budget is not None and sum(len(sz) for sz in sizes) > budget:
        ranked = sorted((x / scale for sz in sizes for x in sz.values()), reverse=True)
        tol = next(t for t in _LADDER if sum(1 for x in ranked if x >= t) <= budget)
    out = []
    for index, (s, sz) in enumerate(zip(series, sizes)):
        kept, dropped, bound = [], 0, 0.0
        for key, (a, b) in s.terms.items():
            if tol and sz[key] < tol * scale:
                dropped += 1
                bound += sz[key]
                continue
            kept.append(s.term(key, _number(a, exact), _number(b, exact)))
        out.append(sp.Add(*kept))
        if dropped:
            notes[index] = (f"and {dropped} term{'s' if dropped > 1 else ''} below {tol * scale:.1e}, "
                            f"their sum at most {bound:.1e}")
    return Shown(_pack(value, out, exact), notes, tol)


def term_bound(items, angles) -> float:
    """An upper bound of the terms of the largest entry's Fourier form: prod_k (2 d_k + 1) over the
    angles, d_k the entry's degree in cos, sin of angle k read off its graph in one pass (a sum the
    largest, a product the sum, a power the multiple; sin, cos of an integer combination its
    coefficients); 0 for entries that are not such polynomials (fourier_series says why)."""
    from derive.dynamics.program import postorder

    index = {a: i for i, a in enumerate(angles)}
    m = len(angles)
    zero = (0,) * m
    deg: dict = {}
    for e in postorder(items):
        if e.is_Symbol or not e.args:
            deg[e] = zero
        elif isinstance(e, (sp.sin, sp.cos)):
            arg = e.args[0]
            d = [0] * m
            for t in sp.Add.make_args(arg):
                c, rest = t.as_coeff_Mul()
                if rest in index and c.is_Integer:
                    d[index[rest]] += abs(int(c))
                elif t.free_symbols & set(index):
                    return 0.0
            deg[e] = tuple(d)
        elif e.is_Add:
            deg[e] = tuple(max(col) for col in zip(*(deg[a] for a in e.args)))
        elif e.is_Mul:
            deg[e] = tuple(sum(col) for col in zip(*(deg[a] for a in e.args)))
        elif e.is_Pow and e.exp.is_Integer and e.exp >= 0:
            deg[e] = tuple(int(e.exp) * x for x in deg[e.base])
        else:
            deg[e] = zero
    top = 0.0
    for x in items:
        count = 1.0
        for d in deg[sp.sympify(x)]:
            count *= 2 * d + 1
        top = max(top, count)
    return top


def _at_zero(value, items, angles, exact: bool, terms: float) -> Shown:
    """``value`` at the zero pose (every angle 0), its numbers to 15 digits, with the statement why."""
    from derive.dynamics.dag import xreplace_all

    out = xreplace_all(items, {a: sp.Integer(0) for a in angles})
    out = [sp.expand(x) if exact else sp.expand(sp.N(x, 15)) for x in out]
    note = (f"at θ = 0: its Fourier form has up to {terms:.1e} terms an entry, past show's {TERM_CAP:,}; "
            "derive show --at evaluates it at any pose")
    return Shown(_pack(value, out, exact), {}, 0.0, note)


def _number(x, exact: bool) -> sp.Expr:
    r = sp.Rational(int(x.p), int(x.q))
    return r if exact or r.is_Integer else sp.Float(r, 15)


def _pack(value: object, out: list, exact: bool) -> object:
    """The entries as a matrix or a scalar (their coefficients are already exact or Floats)."""
    return sp.Matrix(value.rows, value.cols, out) if isinstance(value, sp.MatrixBase) else out[0]
