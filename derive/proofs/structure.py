"""Sound facts about an expression DAG that need no expansion: which monomials it can
have, and when two DAGs are the same expression.

* :func:`bidegrees`: an over-approximation of the set of (degree in group a, degree in
  group b) over the monomials of an expression's expansion (a sum takes the union, a
  product the sums of pairs). So "affine in a, with a never multiplied by b" is decided
  without expanding: if no pair has deg_a > 1, or deg_a = 1 with deg_b > 0, the
  expansion has no such monomial (degrees above ``CAP`` are kept as ``CAP``: a cap only
  over-approximates).
* :func:`same`: two expressions are syntactically identical (value numbering over the
  DAG, each distinct subexpression numbered once: no tree walk): a proof of equality.

Used by the dynamics' obligations (derive.proofs.dynamics) to split an identity into
parts that the exact torus ring (derive.proofs.torus) decides in the joint angles only.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence

import sympy as sp

from derive.dynamics.dag import Memo, xreplace
from derive.dynamics.program import postorder

CAP = 3
Bideg = frozenset[tuple[int, int]]


def bidegrees(exprs: Sequence[sp.Expr], a: Iterable[sp.Symbol], b: Iterable[sp.Symbol]) -> list[Bideg]:
    """For each expression, a superset of the (deg_a, deg_b) of the monomials of its expansion
    (module docstring). Symbols of neither group (angles under sin/cos, parameters) count 0.
    A division by, or a function of, something that contains a or b raises ValueError."""
    a, b = set(a), set(b)
    memo: dict[sp.Basic, Bideg] = {}
    zero: Bideg = frozenset({(0, 0)})
    for node in postorder([sp.sympify(e) for e in exprs]):
        if node in memo:
            continue
        if node.is_Symbol:
            memo[node] = frozenset({(1, 0)}) if node in a else frozenset({(0, 1)}) if node in b else zero
        elif not node.args or node.is_number:
            memo[node] = zero
        elif node.is_Add:
            memo[node] = frozenset().union(*(memo[x] for x in node.args))
        elif node.is_Mul:
            out = zero
            for x in node.args:
                out = frozenset((min(p + r, CAP), min(q + s, CAP)) for p, q in out for r, s in memo[x])
            memo[node] = out
        elif node.is_Pow and node.exp.is_Integer and node.exp >= 0:
            out = zero
            for _ in range(int(node.exp)):
                out = frozenset((min(p + r, CAP), min(q + s, CAP)) for p, q in out for r, s in memo[node.base])
            memo[node] = out
        else:
            inner = frozenset().union(*(memo[x] for x in node.args))
            if inner != zero:
                raise ValueError(f"{type(node).__name__} of an expression in the grouped symbols")
            memo[node] = zero
    return [memo[sp.sympify(e)] for e in exprs]


def affine_apart(exprs: Sequence[sp.Expr], a: Iterable[sp.Symbol], b: Iterable[sp.Symbol]) -> bool:
    """Every expression is affine in ``a`` and no monomial has both an ``a`` and a ``b`` factor."""
    return all(all(p == 0 or (p == 1 and q == 0) for p, q in bd) for bd in bidegrees(exprs, a, b))


def same(xs: Sequence[sp.Expr], ys: Sequence[sp.Expr]) -> bool:
    """The expressions are pairwise syntactically identical (value numbering, one memo)."""
    memo = Memo()
    for e in list(xs) + list(ys):
        xreplace(sp.sympify(e), {}, memo)
    return len(xs) == len(ys) and all(memo.number(sp.sympify(x)) == memo.number(sp.sympify(y))
                                      for x, y in zip(xs, ys))
