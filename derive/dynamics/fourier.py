"""Trigonometric (Fourier) series of the dynamics' entries, exact, in FLINT.

An entry of J, G or a law is a polynomial, with rational coefficients (derive.model.rigid
makes every constant rational), in other symbols (rates, prismatic coordinates, errors)
and in sin/cos of integer combinations of the joint angles. Its unique Fourier form is

    sum over distinct monomials m of the other symbols and frequency vectors k
    (first non-zero k_i positive) of  m (a cos(k . theta) + b sin(k . theta)).

Computed with x_i = exp(i theta_i), y_i = exp(-i theta_i) and the imaginary unit I as
polynomial variables over Q (FLINT's ``fmpq_mpoly``): cos = (x + y)/2, sin = -I (x - y)/2;
each distinct subexpression of the recursion's DAG is converted once; the result is
reduced modulo x_i y_i - 1 and I^2 + 1 (leading monomials pairwise coprime: a Groebner
basis, so the remainder is canonical), and e^{ik.theta} pairs are combined into real
cosines and sines. The Panda's J (7 joints, about 10,000 terms) takes about a second.
Display only (``derive show``); the proofs have their own ring (derive.proofs.torus).
"""
from __future__ import annotations

from collections.abc import Sequence
import math
from dataclasses import dataclass

import flint
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


def fourier_series(exprs: Sequence[sp.Expr], angles: Sequence[sp.Symbol]) -> list[Series]:
    """The Fourier series of each expression (module docstring). Raises ValueError for an
    expression that is not such a polynomial (an angle outside sin/cos, sin/cos of a
    non-integer combination of the angles, a division by a symbol, another function)."""
    exprs = [sp.sympify(e) for e in exprs]
    angles = tuple(angles)
    others = tuple(sorted(free_symbols(exprs) - set(angles), key=sp.default_sort_key))
    m = len(angles)
    names = [f"x{i}" for i in range(m)] + [f"y{i}" for i in range(m)] + ["I"] + [f"v{i}" for i in range(len(others))]
    ctx = flint.fmpq_mpoly_ctx.get(tuple(names), "lex")
    gens = ctx.gens()
    xs, ys, imag = gens[:m], gens[m:2 * m], gens[2 * m]
    var = dict(zip(others, gens[2 * m + 1:]))
    one = ctx.from_dict({(0,) * len(names): 1})
    half = flint.fmpq(1, 2)
    index = {a: i for i, a in enumerate(angles)}

    def trig(e: sp.Basic):
        arg = e.args[0]
        coeffs = sp.Poly(arg, *angles).as_dict() if arg.free_symbols and arg.free_symbols <= set(angles) else None
        if not coeffs or any(sum(k) != 1 or not c.is_Integer for k, c in coeffs.items()):
            raise ValueError(f"sin/cos of {arg}: expected an integer combination of the angles")
        plus, minus = one, one
        for k, c in coeffs.items():
            i = k.index(1)
            up, down = (xs[i], ys[i]) if c > 0 else (ys[i], xs[i])
            plus, minus = plus * up ** abs(int(c)), minus * down ** abs(int(c))
        return (plus + minus) * half if isinstance(e, sp.cos) else (plus - minus) * half * (-imag)

    memo: dict = {}
    for node in postorder(exprs):
        if node in memo:
            continue
        if node.is_Rational:
            out = one * flint.fmpq(int(node.p), int(node.q))
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
                r = sp.Rational(node)
                out = one * flint.fmpq(int(r.p), int(r.q))
            else:
                raise ValueError(f"{node}: expected a polynomial in sin/cos of the angles")
        memo[node] = out
    ideal = [xs[i] * ys[i] - 1 for i in range(m)] + [imag * imag + 1]
    result = []
    for e in exprs:
        p = memo[e]
        if p is None:
            bad = sorted(map(str, e.free_symbols & set(angles)))
            raise ValueError(f"{', '.join(bad)} appears outside sin/cos")
        for g in ideal:
            p = divmod(p, g)[1]
        raw: dict = {}
        for mono, c in zip(p.monoms(), p.coeffs()):
            k = tuple(mono[i] - mono[m + i] for i in range(m))
            parts = raw.setdefault((k, tuple(mono[2 * m + 1:])), [_ZERO, _ZERO])
            parts[mono[2 * m]] += c
        terms: dict = {}
        for (k, powers), (re, im) in raw.items():
            first = next((x for x in k if x), 0)
            if first < 0:
                continue
            if first == 0:
                if re:
                    terms[(k, powers)] = (re, _ZERO)
                continue
            re2, im2 = raw.get((tuple(-x for x in k), powers), (_ZERO, _ZERO))
            # c e^{ik} + c' e^{-ik} with c = re + I im: (c + c') cos + I (c - c') sin, real parts
            a, b = re + re2, im2 - im
            if a or b:
                terms[(k, powers)] = (a, b)
        result.append(Series(angles, others, terms))
    return result
