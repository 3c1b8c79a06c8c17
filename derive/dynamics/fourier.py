"""Trigonometric (Fourier) series of the dynamics' entries, exact, in FLINT.

An entry of J, G or a law is a polynomial, with rational coefficients (derive.model.rigid
makes every constant rational), in other symbols (rates, prismatic coordinates, errors)
and in sin/cos of integer combinations of the joint angles. Its unique Fourier form is

    sum over distinct monomials m of the other symbols and frequency vectors k
    (first non-zero k_i positive) of  m (a cos(k . theta) + b sin(k . theta)).

Computed with x_i = exp(i theta_i) and the imaginary unit I as polynomial variables over Q
(FLINT's ``fmpq_mpoly``), a value held as x^-o q (a Laurent polynomial: o a nonnegative offset
per angle), so cos = (x + x^-1)/2, sin = -I (x - x^-1)/2 and x x^-1 = 1 needs no reduction; I^2 is
reduced to -1 after each product; each distinct subexpression of the recursion's DAG is converted
once, and e^{ik.theta} pairs are combined into real cosines and sines (the form is unique). The
Tiago arm's J (7 joints, 17,000 terms) takes about half a second (a quotient modulo x_i y_i - 1 and
I^2 + 1 with a second variable per angle took twice that).
Display only (``derive show``); the proofs have their own ring (derive.proofs.torus).
"""
from __future__ import annotations

from collections.abc import Sequence
import math
from dataclasses import dataclass

import flint
import numpy as np
import sympy as sp

from derive.dynamics.program import free_symbols, postorder

_ZERO = flint.fmpq(0)


@dataclass(frozen=True)
class Series:
    """One entry's Fourier series: terms[(k, powers)] = (a, b) for m (a cos(k.theta) + b sin(k.theta)),
    k a frequency per angle (first non-zero entry positive), m = prod(others ** powers)."""

    angles: tuple[sp.Symbol, ...]
    others: tuple[sp.Symbol, ...]
    terms: dict[tuple[tuple[int, ...], tuple[int, ...]], tuple[flint.fmpq, flint.fmpq]]

    def term(self, key: tuple[tuple[int, ...], tuple[int, ...]], a: object, b: object) -> sp.Expr:
        """One term as a SymPy expression with the coefficients ``a``, ``b`` (exact or Floats)."""
        k, powers = key
        m = sp.Mul(*(s ** p for s, p in zip(self.others, powers)))
        if not any(k):
            return m * a
        arg = sp.Add(*(x * t for x, t in zip(k, self.angles)))
        # unevaluated: sin/cos of an integer combination of symbols has nothing to evaluate,
        # and asking SymPy to try costs a millisecond per term
        wave = (a * sp.cos(arg, evaluate=False) if a else 0) + (b * sp.sin(arg, evaluate=False) if b else 0)
        return m * wave

    def magnitude(self, key) -> float:
        """sqrt(a^2 + b^2) of a term: its largest value over the angles, per unit of its monomial."""
        a, b = self.terms[key]
        return math.hypot(float(a), float(b))

    def to_expr(self) -> sp.Expr:
        """The whole series, exact."""
        return sp.Add(*(self.term(key, _q(a), _q(b)) for key, (a, b) in self.terms.items()))


def _q(x: flint.fmpq) -> sp.Rational:
    return sp.Rational(int(x.p), int(x.q))


class _Laurent:
    """x^-o q: a Laurent polynomial in x_i = exp(i theta_i) (o: a nonnegative offset per angle, q an
    fmpq_mpoly in the x_i, I and the other symbols), so that x_i x_i^-1 = 1 holds by construction
    and products never carry the pairs a division by x_i y_i - 1 would remove; ``i2``: I^2 + 1 in
    q's ring, by which a product is reduced."""

    __slots__ = ("q", "o", "ctx", "i2")

    def __init__(self, q, o: tuple[int, ...], ctx, i2) -> None:
        self.q, self.o, self.ctx, self.i2 = q, o, ctx, i2

    def _shifted(self, o: tuple[int, ...]):
        if o == self.o:
            return self.q
        nv = self.ctx.nvars()
        exps = tuple(a - b for a, b in zip(o, self.o)) + (0,) * (nv - len(o))
        return self.q * self.ctx.from_dict({exps: 1})

    def __add__(self, other: "_Laurent") -> "_Laurent":
        o = tuple(max(a, b) for a, b in zip(self.o, other.o))
        return _Laurent(self._shifted(o) + other._shifted(o), o, self.ctx, self.i2)

    def __mul__(self, other: "_Laurent") -> "_Laurent":
        q = self.q * other.q
        m = len(self.o)
        if q.degrees()[m] >= 2:
            q = divmod(q, self.i2)[1]
        return _Laurent(q, tuple(a + b for a, b in zip(self.o, other.o)), self.ctx, self.i2)

    def __pow__(self, e: int) -> "_Laurent":
        return _Laurent(self.q ** e, tuple(a * e for a in self.o), self.ctx, self.i2)


def _terms(p: _Laurent, m: int) -> dict:
    """The real series {(k, powers): (a, b)} of p (first non-zero k_i positive): x^a with offset o is
    e^{i (a - o) theta}, I^e is (-1)^(e // 2) I^(e % 2) (the remainder modulo I^2 + 1, read off the
    exponents), and c e^{ik} + c' e^{-ik} with c = re + I im is (c + c') cos + I (c - c') sin. The
    exponents are grouped with numpy; each coefficient is placed by one Python step."""
    monos = np.array(p.q.monoms(), dtype=np.int64).reshape(-1, p.ctx.nvars())
    k = monos[:, :m] - np.array(p.o, dtype=np.int64)
    e = monos[:, m]
    nonzero = k != 0
    first = np.where(nonzero.any(axis=1), k[np.arange(k.shape[0]), nonzero.argmax(axis=1)], 0)
    flip = first < 0
    rows = np.hstack([np.where(flip[:, None], -k, k), monos[:, m + 1:]])
    unique, where, group = _group(rows)
    slots = (4 * group + 2 * flip + e % 2).tolist()     # re, im of e^{ik}, then of e^{-ik}, per group
    acc = [_ZERO] * (4 * unique)
    for slot, negative, c in zip(slots, (e % 4 >= 2).tolist(), p.q.coeffs()):
        acc[slot] = acc[slot] - c if negative else acc[slot] + c
    terms: dict = {}
    for g, row in enumerate(rows[where].tolist()):
        re, im, re2, im2 = acc[4 * g:4 * g + 4]
        key = (tuple(row[:m]), tuple(row[m:]))
        a, b = (re, _ZERO) if not any(key[0]) else (re + re2, im2 - im)
        if a or b:
            terms[key] = (a, b)
    return terms


def _group(rows: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """(the number of distinct rows, the index of each one's first row in sorted order, the group of
    every row) of an integer matrix: its rows as one mixed-radix integer each when that fits in 62
    bits (a sort of integers), else numpy's row-wise unique."""
    if rows.shape[0] == 0:
        return 0, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    low = rows.min(axis=0)
    radix = rows.max(axis=0) - low + 1
    if float(np.prod(radix.astype(float))) < 2.0 ** 62:
        code = (rows - low) @ np.concatenate([np.cumprod(radix[::-1])[::-1][1:], [1]])
        _, where, group = np.unique(code, return_index=True, return_inverse=True)
    else:
        _, where, group = np.unique(rows, axis=0, return_index=True, return_inverse=True)
    return where.shape[0], where, group.reshape(-1)


def fourier_series(exprs: Sequence[sp.Expr], angles: Sequence[sp.Symbol]) -> list[Series]:
    """The Fourier series of each expression (module docstring). Raises ValueError for an
    expression that is not such a polynomial (an angle outside sin/cos, sin/cos of a
    non-integer combination of the angles, a division by a symbol, another function)."""
    exprs = [sp.sympify(e) for e in exprs]
    angles = tuple(angles)
    others = tuple(sorted(free_symbols(exprs) - set(angles), key=sp.default_sort_key))
    m = len(angles)
    names = [f"x{i}" for i in range(m)] + ["I"] + [f"v{i}" for i in range(len(others))]
    ctx = flint.fmpq_mpoly_ctx.get(tuple(names), "lex")
    gens = ctx.gens()
    imag = gens[m]
    i2 = imag * imag + 1
    zero_o = (0,) * m
    var = {s: _Laurent(g, zero_o, ctx, i2) for s, g in zip(others, gens[m + 1:])}
    one = ctx.from_dict({(0,) * len(names): 1})
    index = {a: i for i, a in enumerate(angles)}

    def constant(r) -> _Laurent:
        return _Laurent(one * flint.fmpq(int(r.p), int(r.q)), zero_o, ctx, i2)

    def trig(e: sp.Basic) -> _Laurent:
        arg = e.args[0]
        coeffs = sp.Poly(arg, *angles).as_dict() if arg.free_symbols and arg.free_symbols <= set(angles) else None
        if not coeffs or any(sum(k) != 1 or not c.is_Integer for k, c in coeffs.items()):
            raise ValueError(f"sin/cos of {arg}: expected an integer combination of the angles")
        c = [0] * m
        for k, v in coeffs.items():
            c[k.index(1)] = int(v)
        o = tuple(abs(x) for x in c)
        rest = (0,) * (len(names) - m)
        plus = ctx.from_dict({tuple(x + y for x, y in zip(c, o)) + rest: 1})       # e^{i c.theta}
        minus = ctx.from_dict({tuple(y - x for x, y in zip(c, o)) + rest: 1})      # e^{-i c.theta}
        half = flint.fmpq(1, 2)
        q = (plus + minus) * half if isinstance(e, sp.cos) else (plus - minus) * half * (-imag)
        return _Laurent(q, o, ctx, i2)

    memo: dict = {}
    for node in postorder(exprs):
        if node in memo:
            continue
        if node.is_Rational:
            out = constant(node)
        elif node.is_Symbol:
            out = None if node in index else var[node]
        elif isinstance(node, (sp.sin, sp.cos)):
            out = trig(node)
        elif not (node.is_Add or node.is_Mul or node.is_Pow):
            raise ValueError(f"{node}: expected a polynomial in sin/cos of the angles")
        else:
            args = [memo[a] for a in node.args]
            if any(a is None for a in args):
                out = None             # an angle in it: fine under sin/cos only
            elif node.is_Add:
                out = args[0]
                for a in args[1:]:
                    out = out + a
            elif node.is_Mul:
                out = args[0]
                for a in args[1:]:
                    out = out * a
            elif node.is_Pow and node.exp.is_Integer and node.exp >= 0:
                out = args[0] ** int(node.exp)
            elif node.is_Pow and node.base.is_Rational and node.exp.is_Integer:
                out = constant(sp.Rational(node))
            else:
                raise ValueError(f"{node}: expected a polynomial in sin/cos of the angles")
        memo[node] = out
    result = []
    for e in exprs:
        p = memo[e]
        if p is None:
            bad = sorted(map(str, e.free_symbols & set(angles)))
            raise ValueError(f"{', '.join(bad)} appears outside sin/cos")
        terms = _terms(p, m)
        result.append(Series(angles, others, terms))
    return result
