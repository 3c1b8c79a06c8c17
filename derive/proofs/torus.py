"""Exact polynomials on the torus of the joint angles, in FLINT: the dynamics' identities at n = 7.

The dynamics of a chain with rational data (derive.model.rigid makes every constant
rational) are polynomials with rational coefficients in c_i = cos(q_i), s_i = sin(q_i)
of the revolute joints and in the other symbols (rates, accelerations, prismatic
coordinates, inputs). Here they are elements of Q[c_1, s_1, ..., x_1, ...] with the
c_i, s_i *free* while they are built: sums and products are plain polynomial
arithmetic (FLINT's ``fmpq_mpoly``, through python-flint), and the recursion's shared
subexpressions are converted once each (a memo over the DAG). Only a difference that
must vanish is reduced, by division with remainder by c_i^2 + s_i^2 - 1 for each angle
in turn: those polynomials have pairwise coprime leading monomials c_i^2 (c_i comes
first in the lexicographic order), so they are a Groebner basis of the ideal, the
remainder is canonical (degree <= 1 in each c_i) and it is zero exactly when the
expression vanishes at every angle: :meth:`Torus.is_zero` returning True is a proof,
False a refutation. Never sampling.

Keeping c, s free until the end keeps the Panda's J entries at a few hundred terms (a
substitution t = tan(q/2) would lift every sum to a common denominator and make them
dense: 10,000 terms), so J' - 2C skew, the energy balance and the RNEA law equal to
J a + G take seconds for a 7-joint arm, where SymPy's fraction field took minutes.
Time derivatives act as d c_i = -s_i q_i', d s_i = c_i q_i'.

An expression outside this class (an angle outside sin/cos, a division by a symbol, a
float, sin/cos of a constant) raises :class:`derive.proofs.exact.Undecidable`.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import flint
import sympy as sp

from derive.dynamics.program import postorder
from derive.proofs.exact import Undecidable

Poly = flint.fmpq_mpoly


class TooLarge(Undecidable):
    """A polynomial grew past the ring's term limit (the proof's budget)."""


class Torus:
    """Q[c_i, s_i (``angles``), x (``others``)] and the zero test modulo c_i^2 + s_i^2 - 1.

    A product of more than ``REDUCE_ABOVE`` terms is reduced as it is formed (on arms whose
    constant rotations are not multiples of pi/2 the free c, s otherwise swell 100-fold);
    a polynomial of more than ``limit`` terms, or a conversion holding more than ``total`` at once, raises
    :class:`TooLarge`."""

    REDUCE_ABOVE = 300

    def __init__(self, angles: Sequence[sp.Symbol], others: Iterable[sp.Symbol], limit: int | None = None,
                 total: int | None = None) -> None:
        self.limit = limit
        self.total = total   # terms :meth:`convert` may hold at once (TooLarge past it)
        self.angles = tuple(angles)
        self.others = tuple(sorted(set(others) - set(self.angles), key=sp.default_sort_key))
        m = len(self.angles)
        names = ([f"c{i}" for i in range(m)] + [f"s{i}" for i in range(m)]
                 + [f"x{i}" for i in range(len(self.others))])
        self.ctx = flint.fmpq_mpoly_ctx.get(tuple(names), "lex")
        gens = self.ctx.gens()
        self.c, self.s = gens[:m], gens[m:2 * m]
        self._var = dict(zip(self.others, gens[2 * m:]))
        self._index = {a: i for i, a in enumerate(self.angles)}
        self.zero = self.ctx.from_dict({})
        self.one = self.ctx.from_dict({(0,) * len(names): 1})
        self._ideal = [c * c + s * s - 1 for c, s in zip(self.c, self.s)]
        self._memo: dict[sp.Basic, Poly | None] = {}

    def var(self, x: sp.Symbol) -> Poly:
        """The generator of a symbol that is not an angle."""
        return self._var[x]

    def number(self, r: sp.Rational | int) -> Poly:
        r = sp.Rational(r)
        return self.one * flint.fmpq(int(r.p), int(r.q))

    # -- conversion ------------------------------------------------------------------------
    def __call__(self, expr: sp.Expr) -> Poly:
        """``expr`` as a polynomial (each distinct subexpression converted once, memo shared)."""
        expr = sp.sympify(expr)
        for node in postorder([expr]):
            if node not in self._memo:
                self._memo[node] = self._node(node)
        out = self._memo[expr]
        if out is None:
            raise Undecidable(f"{expr}: an angle outside sin/cos")
        return out

    def convert(self, exprs: Iterable[sp.Expr]) -> list[Poly]:
        """``exprs`` as polynomials, each distinct subexpression converted once; a subexpression this
        call converts is dropped from the memo once its last parent is converted (the memo holds the
        live ones only: a 12-joint chain's Coriolis matrix held 26 million terms of intermediate
        polynomials for its 5.6 million, 1.9 GB)."""
        exprs = [sp.sympify(e) for e in exprs]
        order = [node for node in postorder(exprs) if node not in self._memo]
        uses: dict[sp.Basic, int] = {}
        for node in order:
            for a in set(node.args):
                uses[a] = uses.get(a, 0) + 1
        roots, fresh = set(exprs), set(order)
        live = 0   # terms of the polynomials this call holds
        for node in order:
            p = self._memo[node] = self._node(node)
            live += 0 if p is None else len(p)
            if self.total is not None and live > self.total:
                for x in fresh:   # what this call converted: dropped (memory)
                    self._memo.pop(x, None)
                raise TooLarge(f"the polynomials held at once passed {self.total:,} terms")
            for a in set(node.args):
                uses[a] -= 1
                if not uses[a] and a in fresh and a not in roots:
                    gone = self._memo.pop(a)
                    live -= 0 if gone is None else len(gone)
        out = [self._memo[e] for e in exprs]
        for e, p in zip(exprs, out):
            if p is None:
                raise Undecidable(f"{e}: an angle outside sin/cos")
        return out

    def forget(self) -> None:
        """Drop the polynomials of the subexpressions converted so far (keep the ring)."""
        self._memo.clear()

    def _node(self, e: sp.Basic) -> Poly | None:
        if e.is_Rational:
            return self.number(e)
        if e.is_Symbol:
            if e in self._index:
                return None            # an angle: fine under sin/cos only
            if e not in self._var:
                raise Undecidable(f"symbol {e} is not a variable of this ring")
            return self._var[e]
        if isinstance(e, (sp.sin, sp.cos)):
            return self._trig(e)
        args = [self._memo[a] for a in e.args]
        if any(a is None for a in args):
            return None                # an angle in it: fine as the argument of sin/cos only
        if e.is_Add:
            out = args[0]
            for a in args[1:]:
                out = out + a
            return out if self.limit is None or len(out) <= self.limit else self._settle(out)
        if e.is_Mul:
            out = args[0]
            for a in args[1:]:
                out = out * a
            return self._settle(out)
        if e.is_Pow and e.exp.is_Integer and e.exp >= 0:
            return self._settle(args[0] ** int(e.exp))
        if e.is_Pow and e.base.is_Rational and e.exp.is_Integer:
            return self.number(e)
        raise Undecidable(f"not a polynomial in the symbols and sin/cos of the angles: {e}")

    def _settle(self, p: Poly) -> Poly:
        if len(p) > self.REDUCE_ABOVE:
            p = self.reduce(p)
        if self.limit is not None and len(p) > self.limit:
            raise TooLarge(f"a polynomial of {len(p)} terms, over the proof's budget of {self.limit}")
        return p

    def _trig(self, e: sp.Basic) -> Poly:
        arg = e.args[0]
        if not arg.free_symbols or not arg.free_symbols <= set(self.angles):
            raise Undecidable(f"{e}: sin/cos of something other than the joint angles")
        coeffs = sp.Poly(arg, *self.angles).as_dict()
        if any(sum(k) != 1 or not c.is_Integer for k, c in coeffs.items()):
            raise Undecidable(f"{e}: sin/cos of a non-integer combination of the angles")
        c, s = self.one, self.zero
        for k, mult in coeffs.items():
            i = k.index(1)
            ci, si = self.c[i], self.s[i]
            if mult < 0:
                si, mult = -si, -mult
            ck, sk = ci, si
            for _ in range(int(mult) - 1):
                ck, sk = ck * ci - sk * si, sk * ci + ck * si
            c, s = c * ck - s * sk, s * ck + c * sk
        return c if isinstance(e, sp.cos) else s

    # -- calculus --------------------------------------------------------------------------
    def diff(self, p: Poly, x: sp.Symbol) -> Poly:
        """d p / d x: for an angle through its c, s (d c = -s, d s = c), else the variable's."""
        if x in self._index:
            i = self._index[x]
            m = len(self.angles)
            return p.derivative(i) * (-self.s[i]) + p.derivative(m + i) * self.c[i]
        return p.derivative(2 * len(self.angles) + self.others.index(x))

    def d_dt(self, p: Poly, rates: Mapping[sp.Symbol, Poly]) -> Poly:
        """Time derivative by the chain rule: the sum over symbols v of dp/dv * rates[v]."""
        out = self.zero
        for v, r in rates.items():
            out = out + self.diff(p, v) * r
        return out

    # -- deciding --------------------------------------------------------------------------
    def reduce(self, p: Poly) -> Poly:
        """The canonical remainder modulo c_i^2 + s_i^2 - 1 (degree <= 1 in every c_i).

        Only the angles whose c_i has degree 2 or more are divided by (a division by c_i^2 + s_i^2 - 1
        moves no other c_j's degree, so p's degrees taken once decide them): on a chain with dense
        constant rotations 9 of 10 divisions found nothing to divide and cost a pass over p each
        (the decimal 7-joint snake's skew-symmetry proof: 49 s, 28 s with the test)."""
        if p.is_zero():
            return p
        degrees = p.degrees()
        for i, g in enumerate(self._ideal):
            if degrees[i] >= 2:
                p = divmod(p, g)[1]
                if p.is_zero():
                    break
        return p

    def is_zero(self, p: Poly) -> bool:
        """True when p vanishes for every angle and every value of the other symbols (a proof)."""
        return self.reduce(p).is_zero()


def torus_for(exprs: Iterable[sp.Expr], angles: Sequence[sp.Symbol], extra: Iterable[sp.Symbol] = ()) -> Torus:
    """The ring of the free symbols of ``exprs`` (DAG walk) and ``extra``, with ``angles``."""
    from derive.dynamics.program import free_symbols

    flat = [x for e in exprs for x in (e if isinstance(e, sp.MatrixBase) else [e])]
    return Torus(angles, free_symbols(flat) | set(extra))
