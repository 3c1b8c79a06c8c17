"""Polynomials in sin/cos of joint angles, reduced as they are formed.

The ring Q[s_1, c_1, ..., s_k, c_k, x_1, ...] (s_i = sin theta_i,
c_i = cos theta_i, x: every other symbol: rates, prismatic coordinates,
parameters) modulo the ideal (s_i^2 + c_i^2 - 1). Those generators of the
ideal have pairwise coprime leading monomials s_i^2, so they are a Groebner
basis and the remainder (no s_i above degree 1) is a canonical form: two
expressions are equal for every angle exactly when their remainders are
equal (the test of :mod:`derive.dynamics.identities`, here without
``expand``). Conversion visits each distinct subexpression once, so the
shared-subexpression entries of the recursive dynamics convert in time
proportional to their DAG, not their tree. Time derivatives act through
d s_i = c_i dtheta_i, d c_i = -s_i dtheta_i.

Used for the Euler-Lagrange reference (:mod:`derive.dynamics.lagrange`) and
to prove the recursive form equal to it.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence

import sympy as sp
from sympy.polys.rings import PolyElement, ring

from derive.dynamics.program import postorder


def constant_angles(exprs: Iterable[sp.Expr]) -> tuple[sp.Expr, ...]:
    """The numbers a under sin(a) or cos(a) in the expressions (a URDF angle that
    is not a multiple of pi/2 stays exact as cos/sin of its Rational)."""
    found = {node.args[0] for node in postorder(sp.sympify(e) for e in exprs)
             if isinstance(node, (sp.sin, sp.cos)) and not node.args[0].free_symbols}
    return tuple(sorted(found, key=sp.default_sort_key))


class TrigRing:
    """Q[s_i, c_i, x] / (s_i^2 + c_i^2 - 1) for ``angles`` and ``symbols``.

    ``symbols``: every other symbol an expression may contain; ``constants``:
    numbers a whose sin(a), cos(a) occur (treated like angles: their own s, c
    with s^2 + c^2 = 1, so identities that rest on it are decided too). An
    expression outside the ring (an angle outside sin/cos, a symbol in a
    denominator, another function) raises ValueError naming it.
    """

    def __init__(self, angles: Sequence[sp.Symbol], symbols: Iterable[sp.Symbol],
                 constants: Sequence[sp.Expr] = ()) -> None:
        self.angles = tuple(angles) + tuple(constants)
        others = sorted(set(symbols) - set(self.angles), key=sp.default_sort_key)
        k = len(self.angles)
        names = [f"s{i}" for i in range(k)] + [f"c{i}" for i in range(k)] + [f"v{i}" for i in range(len(others))]
        self.R, *gens = ring(names, sp.QQ)
        self.s, self.c = gens[:k], gens[k:2 * k]
        self.var = dict(zip(others, gens[2 * k:]))
        self.others = tuple(others)
        self._angle = {a: i for i, a in enumerate(self.angles)}
        self._ideal = [self.s[i] ** 2 + self.c[i] ** 2 - 1 for i in range(k)]
        self._back = {**{self.s[i]: sp.sin(a) for i, a in enumerate(self.angles)},
                      **{self.c[i]: sp.cos(a) for i, a in enumerate(self.angles)},
                      **{g: x for x, g in self.var.items()}}

    @property
    def zero(self) -> PolyElement:
        return self.R.zero

    @property
    def one(self) -> PolyElement:
        return self.R.one

    def reduce(self, p: PolyElement) -> PolyElement:
        """The canonical remainder of p modulo s_i^2 + c_i^2 - 1."""
        return p.rem(self._ideal) if self._ideal and not p.is_ground else p

    def mul(self, a: PolyElement, b: PolyElement) -> PolyElement:
        return self.reduce(a * b)

    def sin(self, angle: sp.Symbol) -> PolyElement:
        return self.s[self._angle[angle]]

    def cos(self, angle: sp.Symbol) -> PolyElement:
        return self.c[self._angle[angle]]

    def __call__(self, expr: sp.Expr) -> PolyElement:
        """``expr`` in the ring, reduced."""
        return self.convert([expr])[0]

    def convert(self, exprs: Sequence[sp.Expr]) -> list[PolyElement]:
        """Several expressions, sharing the work on their common subexpressions."""
        exprs = [sp.sympify(e) for e in exprs]
        memo: dict[sp.Basic, PolyElement | None] = {}
        for e in postorder(exprs):
            memo[e] = self._node(e, memo)
        out = [memo[e] for e in exprs]
        if any(x is None for x in out):
            raise ValueError("an angle outside sin/cos")
        return out  # type: ignore[return-value]

    def _node(self, e: sp.Basic, memo: dict) -> PolyElement:
        if e.is_Rational:
            return self.R(sp.QQ(int(e.p), int(e.q)))
        if e.is_Symbol:
            if e in self.var:
                return self.var[e]
            if e in self._angle:
                return None   # fine under sin/cos only: a parent using it otherwise raises
            raise ValueError(f"unknown symbol {e}")
        if any(memo.get(a, 0) is None for a in e.args) and not isinstance(e, (sp.sin, sp.cos)):
            bad = next(a for a in e.args if memo.get(a, 0) is None)
            raise ValueError(f"{bad} is an angle outside sin/cos (in {e})")
        if e.is_Add:
            out = self.R.zero
            for a in e.args:
                out += memo[a]
            return out
        if e.is_Mul:
            out = self.R.one
            for a in e.args:
                out = self.mul(out, memo[a])
            return out
        if e.is_Pow and e.exp.is_Integer and e.exp >= 0:
            out, base = self.R.one, memo[e.base]
            for _ in range(int(e.exp)):
                out = self.mul(out, base)
            return out
        if isinstance(e, (sp.sin, sp.cos)) and e.args[0] in self._angle:
            return self.sin(e.args[0]) if isinstance(e, sp.sin) else self.cos(e.args[0])
        if isinstance(e, (sp.sin, sp.cos)) and e.args[0].free_symbols & set(self._angle):
            return self(sp.expand_trig(e))
        if e.is_Number or isinstance(e, sp.NumberSymbol):
            raise ValueError(f"{e}: not a rational number")
        raise ValueError(f"{e}: not a polynomial in the symbols and sin/cos of the angles")

    def to_expr(self, p: PolyElement) -> sp.Expr:
        """Back to SymPy (s_i -> sin(theta_i), c_i -> cos(theta_i))."""
        return p.as_expr().xreplace({g.as_expr(): x for g, x in self._back.items()})

    # -- calculus --------------------------------------------------------------------------
    def diff(self, p: PolyElement, x: sp.Symbol) -> PolyElement:
        """dp/dx: for an angle through sin and cos, else the partial derivative."""
        if x in self._angle:
            i = self._angle[x]
            return self.reduce(p.diff(self.s[i]) * self.c[i] - p.diff(self.c[i]) * self.s[i])
        return p.diff(self.var[x])

    def d_dt(self, p: PolyElement, q: Sequence[sp.Symbol], dq: Sequence[sp.Symbol]) -> PolyElement:
        """dp/dt = sum_i dp/dq_i q_i' (q_i' symbols of the ring)."""
        out = self.R.zero
        for qi, dqi in zip(q, dq):
            d = self.diff(p, qi)
            if d:
                out += self.mul(d, self.var[dqi])
        return out
