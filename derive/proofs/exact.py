"""Exact rational-function arithmetic for the proof obligations of ``derive check``.

A claim of the paper is an identity between matrices whose entries are rational
in parameters, states and sin/cos of joint angles (eq. 12-42, a3-a14). Built as
nested SymPy expressions and decided with ``together`` they take seconds per
entry once J^-1, B^-1 and C^-1 appear (generic 2 x 2 B and C: ~10 s a line).
Here the same objects live in the field Q(x_1, ..., s_i, c_i) of SymPy's
polys (``DomainMatrix`` over ``QQ.frac_field``): every sum, product and
inverse is reduced to a canonical numerator/denominator pair as it is formed,
so whole derivations take milliseconds.

Deciding zero is the test of :func:`derive.dynamics.identities.trig_normal`: the
numerator, a polynomial, is reduced modulo {s_i^2 + c_i^2 - 1}. Those
polynomials have leading monomials s_i^2 (the s_i come first in the lex order)
that are pairwise coprime, so they are a Groebner basis and the remainder is
zero exactly when the rational function vanishes for every angle: ``is_zero``
returning True is a proof, False a refutation. An expression outside this class
(an angle outside sin/cos, sqrt, Abs, exp) raises :class:`Undecidable`.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import sympy as sp
from sympy.polys.fields import FracElement
from sympy.polys.matrices import DomainMatrix
from sympy.polys.polyerrors import CoercionFailed

from derive.dynamics.program import free_symbols, postorder
from derive.dynamics.trigpoly import constant_angles


class Undecidable(ValueError):
    """The expression is not rational in the symbols and sin/cos of the angles."""


Point = Mapping[sp.Symbol, sp.Expr]


class Field:
    """Q(symbols, sin/cos of ``angles``): exact matrices and the zero test.

    ``symbols`` must contain every symbol that will be converted (angles may
    occur only under sin and cos). Elements are SymPy ``FracElement``;
    matrices are ``DomainMatrix`` over the field.
    """

    def __init__(self, symbols: Iterable[sp.Symbol], angles: Sequence[sp.Symbol] = (),
                 constants: Sequence[sp.Expr] = ()) -> None:
        self.angles = tuple(angles)
        # constants: numbers a whose sin(a), cos(a) occur (a URDF angle that is not a multiple of
        # pi/2 stays exact as sin/cos of its Rational); their own s, c with s^2 + c^2 = 1
        turned = self.angles + tuple(constants)
        self._sin = {a: sp.Dummy(f"s_{a}") for a in turned}
        self._cos = {a: sp.Dummy(f"c_{a}") for a in turned}
        plain = sorted(set(symbols) - set(self.angles), key=sp.default_sort_key)
        self.symbols = tuple(plain) + self.angles
        # s_i first: lex order then makes s_i^2 the leading monomial of s_i^2 + c_i^2 - 1
        gens = [self._sin[a] for a in turned] + [self._cos[a] for a in turned] + plain
        self.K = sp.QQ.frac_field(*gens)
        self._ring = self.K.field.ring
        self._forward = {**{sp.sin(a): s for a, s in self._sin.items()},
                         **{sp.cos(a): c for a, c in self._cos.items()}}
        self._back = {v: k for k, v in self._forward.items()}
        self._ideal = [self._ring.from_expr(self._sin[a] ** 2 + self._cos[a] ** 2 - 1) for a in turned]

    @staticmethod
    def for_exprs(exprs: Iterable[sp.Basic], angles: Sequence[sp.Symbol], extra: Iterable[sp.Symbol] = ()) -> "Field":
        """The field of every free symbol of ``exprs`` (and ``extra``), with the constant
        angles they take sin/cos of."""
        exprs = [x for e in exprs for x in (e if isinstance(e, sp.MatrixBase) else [e])]
        syms: set[sp.Symbol] = set(extra) | free_symbols(exprs)
        return Field(syms, angles, constant_angles(exprs))

    # -- conversion -----------------------------------------------------------------------
    def __call__(self, expr: sp.Expr) -> FracElement:
        """``expr`` as a field element (sin/cos of sums expanded first). Each distinct
        subexpression is converted once (memo shared by every call on this field), so the
        shared-subexpression entries of a chain's dynamics convert in time proportional to
        their DAG; a node this walk does not know goes through SymPy's own conversion."""
        expr = sp.sympify(expr)
        memo = self.__dict__.setdefault("_memo", {})
        for node in postorder([expr]):
            if node not in memo:
                memo[node] = self._node(node, memo)
        out = memo[expr]
        return out if out is not None else self._convert(expr)   # _convert raises Undecidable

    def _node(self, e: sp.Basic, memo: dict) -> FracElement | None:
        """One node from its converted arguments; None where the node is not an element
        by itself (an angle, a sum of angles: fine under sin/cos only)."""
        if e in self._forward:
            return self.K(self._forward[e])
        if e.is_Rational:
            return self.K(sp.QQ(int(e.p), int(e.q)))
        if e.is_Symbol:
            return None if e in self.angles else self._convert(e)
        args = [memo[a] for a in e.args]
        if any(a is None for a in args) and not isinstance(e, (sp.sin, sp.cos)):
            return None
        if e.is_Add:
            out = self.K.zero
            for a in args:
                out += a
            return out
        if e.is_Mul:
            out = self.K.one
            for a in args:
                out *= a
            return out
        if e.is_Pow and e.exp.is_Integer:
            return args[0] ** int(e.exp)
        if isinstance(e, (sp.sin, sp.cos)):
            return self._convert(sp.expand_trig(e))   # sin/cos of a sum or a multiple of angles
        return self._convert(e)

    def _convert(self, expr: sp.Expr) -> FracElement:
        """SymPy's conversion of one expression (sin/cos of sums expanded first)."""
        if expr.has(*self._forward):
            expr = sp.expand_trig(expr)
        expr = expr.xreplace(self._forward)
        leftover = expr.free_symbols & set(self.angles)
        if leftover:
            raise Undecidable(f"angle {sorted(map(str, leftover))} outside sin/cos")
        try:
            return self.K.from_sympy(expr)
        except (CoercionFailed, ValueError) as exc:
            raise Undecidable(f"not a rational function of the symbols and sin/cos: {expr}") from exc

    def matrix(self, m: sp.MatrixBase | Sequence[Sequence[sp.Expr]]) -> DomainMatrix:
        """A SymPy matrix (or nested rows) as a DomainMatrix over the field."""
        rows = m.tolist() if isinstance(m, sp.MatrixBase) else [list(r) for r in m]
        return DomainMatrix([[self(x) for x in row] for row in rows], (len(rows), len(rows[0])), self.K)

    def column(self, xs: Iterable[sp.Expr]) -> DomainMatrix:
        """Column vector (n x 1)."""
        return self.matrix([[x] for x in xs])

    def eye(self, n: int) -> DomainMatrix:
        """Identity (n x n)."""
        return DomainMatrix.eye(n, self.K)

    def to_sympy(self, x: FracElement | DomainMatrix) -> sp.Expr | sp.Matrix:
        """Back to a SymPy expression (or Matrix) in sin/cos of the angles."""
        if isinstance(x, DomainMatrix):
            return x.to_Matrix().applyfunc(lambda e: e.xreplace(self._back))
        return self.K.to_sympy(x).xreplace(self._back)

    @staticmethod
    def entries(m: DomainMatrix) -> list[FracElement]:
        """Entries of a matrix, row by row."""
        return [x for row in m.to_list() for x in row]

    # -- deciding -------------------------------------------------------------------------
    def normal(self, x: FracElement) -> sp.Expr:
        """Canonical numerator of ``x`` modulo s_i^2 + c_i^2 - 1 (zero iff x == 0)."""
        num = x.numer
        if self._ideal and num != 0:
            num = num.rem(self._ideal)
        return num.as_expr()

    def is_zero(self, x: FracElement | DomainMatrix) -> bool:
        """True when x (every entry) is identically zero: a proof; False refutes."""
        xs = self.entries(x) if isinstance(x, DomainMatrix) else [x]
        return all(self.normal(e) == 0 for e in xs)

    # -- calculus -------------------------------------------------------------------------
    def d_dt(self, x: FracElement | DomainMatrix, rates: Mapping[sp.Symbol, FracElement]) -> FracElement | DomainMatrix:
        """Time derivative by the chain rule: sum over symbols v of dx/dv * rates[v].

        An angle's rate r acts through sin and cos: d sin(a) = cos(a) r, d cos(a) = -sin(a) r.
        """
        if isinstance(x, DomainMatrix):
            rows = [[self.d_dt(e, rates) for e in row] for row in x.to_list()]
            return DomainMatrix(rows, x.shape, self.K)
        out = self.K.zero
        for v, r in rates.items():
            if v in self._sin:
                s, c = self.K(self._sin[v]), self.K(self._cos[v])
                out += (x.diff(s) * c - x.diff(c) * s) * r
            else:
                out += x.diff(self.K(v)) * r
        return out

    def jacobian(self, m: DomainMatrix, wrt: Sequence[sp.Symbol]) -> DomainMatrix:
        """d m / d wrt for a column m (no angles in ``wrt``)."""
        col = self.entries(m)
        rows = [[e.diff(self.K(v)) for v in wrt] for e in col]
        return DomainMatrix(rows, (len(col), len(wrt)), self.K)

    # -- numbers --------------------------------------------------------------------------
    def at(self, x: FracElement | DomainMatrix, point: Point) -> sp.Expr | sp.Matrix:
        """Exact value at ``point`` (angles given as values whose sin/cos SymPy evaluates)."""
        expr = self.to_sympy(x)
        return evaluate(expr, point)


def evaluate(expr: sp.Expr | sp.MatrixBase, point: Point) -> sp.Expr | sp.Matrix:
    """Exact value of a SymPy expression or matrix at ``point``.

    sin/cos of sums are expanded first, so that angles like atan(4/3) give
    rational sin and cos.
    """
    def one(e: sp.Expr) -> sp.Expr:
        """One entry."""
        e = sp.sympify(e)
        if e.has(sp.sin, sp.cos):
            e = sp.expand_trig(e)
        return e.xreplace(dict(point))

    if isinstance(expr, sp.MatrixBase):
        return expr.applyfunc(one)
    return one(expr)


# Angles with rational sine and cosine (Pythagorean triples), for exact counterexamples.
PYTHAGOREAN = (sp.Rational(4, 3), sp.Rational(5, 12), sp.Rational(8, 15), sp.Rational(7, 24),
               sp.Rational(20, 21), sp.Rational(12, 35))
SAMPLES = (sp.Rational(1, 2), sp.Rational(-2, 3), sp.Rational(3, 4), sp.Integer(1), sp.Rational(-1, 5),
           sp.Rational(5, 3), sp.Rational(2, 7), sp.Rational(-3, 2), sp.Rational(4, 5), sp.Rational(-7, 4))


def sample_value(sym: sp.Symbol, k: int) -> sp.Expr:
    """k-th deterministic exact sample for ``sym`` respecting its sign assumptions."""
    v = SAMPLES[k % len(SAMPLES)]
    if sym.is_positive or sym.is_nonnegative:
        v = abs(v)
    return v


def sample_angle(k: int) -> sp.Expr:
    """k-th angle with rational sine and cosine: +-atan(p/q) of a Pythagorean triple."""
    r = PYTHAGOREAN[k % len(PYTHAGOREAN)]
    return sp.atan(r) if k % 2 == 0 else -sp.atan(r)
