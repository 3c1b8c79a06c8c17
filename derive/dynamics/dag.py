"""Expression-DAG versions of SymPy's tree walks: substitution, free symbols,
differentiation.

The recursive dynamics share their subexpressions: for an 8-link planar chain
the bias vector G has 299 distinct subexpressions but 1.6 million tree nodes.
SymPy's ``xreplace``, ``free_symbols`` and ``diff`` walk the tree, so every
stage after the dynamics (values put in, e written in measurements, the PID
Jacobians, the kernels' coverage check) grew exponentially with the chain.
These functions visit each distinct subexpression once (a memo keyed by the
subexpression, shared across the entries of a matrix) and build exactly what
SymPy's own functions build: the same constructors on the same arguments, in
the same order. Iterative, so deep chains do not hit Python's recursion limit.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping
from contextlib import nullcontext
from functools import reduce

import sympy as sp
from sympy.core.parameters import distribute


class Memo(dict):
    """Results per subexpression object, keyed by ``id`` (the object is kept
    alive beside its result): looking a subexpression up by equality would
    compare two equal but distinct trees node by node, a tree walk again.
    Results are also numbered by value (``numbers``: the node's class and its
    arguments' numbers -> number; ``objects``: number -> result), so equal
    subexpressions that are distinct objects are built once and share one
    result, without SymPy ever comparing two trees."""

    def __init__(self):
        super().__init__()
        self.numbers: dict = {}
        self.objects: list = []

    def has(self, e: sp.Basic) -> bool:
        return id(e) in self

    def get_(self, e: sp.Basic):
        return self[id(e)][1]

    def number(self, e: sp.Basic) -> int:
        return self[id(e)][2]

    def put(self, e: sp.Basic, value, number: int | None = None) -> None:
        self[id(e)] = (e, value, number)

    def numbered(self, key) -> int | None:
        return self.numbers.get(key)

    def register(self, key, value) -> int:
        number = self.numbers.setdefault(key, len(self.objects))
        if number == len(self.objects):
            self.objects.append(value)
        return number


def _postorder(roots: Iterable[sp.Basic], done: Memo, skip=None):
    """Distinct subexpression objects of ``roots`` not in ``done``, children
    before parents. ``skip(e)`` true: the node is yielded without its arguments."""
    stack = [(r, False) for r in roots]
    seen: set[int] = set()
    while stack:
        e, ready = stack.pop()
        if ready:
            yield e
            continue
        if id(e) in done or id(e) in seen:
            continue
        seen.add(id(e))
        stack.append((e, True))
        if skip is None or not skip(e):
            stack.extend((a, False) for a in e.args if id(a) not in done and id(a) not in seen)


def xreplace(expr: sp.Basic, rule: Mapping, memo: Memo | None = None, keep_sums: bool = False) -> sp.Basic:
    """``expr.xreplace(rule)`` building each distinct subexpression once;
    ``memo`` (old -> new) may be shared between calls with the same rule.

    ``keep_sums``: a number that lands in front of a sum (a parameter replaced
    by its value) multiplies the sum instead of being distributed over its
    terms as SymPy does by default: the sum stays one shared subexpression
    (distributing a body's mass over its acceleration's terms copies the
    recursion's shared sums, about two thirds more operations for the
    Panda's bias). Same value, fewer operations."""
    return xreplace_all([expr], rule, memo, keep_sums)[0]


def xreplace_all(exprs: Iterable[sp.Basic], rule: Mapping, memo: Memo | None = None,
                 keep_sums: bool = False) -> list[sp.Basic]:
    """:func:`xreplace` of each of ``exprs`` with one memo, in one ``distribute(False)`` context
    for ``keep_sums``: entering and leaving it clears SymPy's whole cache, which per entry of a
    matrix cost more than the replacement itself (a 3-joint arm's derivation: 500 clears)."""
    memo = Memo() if memo is None else memo
    exprs = list(exprs)
    with distribute(False) if keep_sums else nullcontext():
        for e in exprs:
            _xreplace(e, rule, memo)
    return [memo.get_(e) for e in exprs]


def _xreplace(expr: sp.Basic, rule: Mapping, memo: Memo) -> None:
    for e in _postorder([expr], memo, skip=lambda e: e in rule):
        if e in rule:
            out, key = rule[e], ("rule", e)
        elif not e.args:
            out, key = e, ("atom", e)
        else:
            key = (e.func, tuple(memo.number(a) for a in e.args))
            number = memo.numbered(key)
            if number is not None:  # an equal subexpression was built already
                memo.put(e, memo.objects[number], number)
                continue
            args = [memo.get_(a) for a in e.args]
            out = e if all(a is b for a, b in zip(args, e.args)) else e.func(*args)
        number = memo.register(key, out)
        memo.put(e, memo.objects[number], number)


def matrix_xreplace(m: sp.Matrix, rule: Mapping) -> sp.Matrix:
    """``m.xreplace(rule)`` with one memo for all entries (shared subexpressions)."""
    memo = Memo()
    return sp.Matrix(m.rows, m.cols, xreplace_all(m, rule, memo))


def free_symbols(exprs: Iterable[sp.Basic], memo: Memo | None = None) -> set:
    """Union of the free symbols of ``exprs`` (each distinct subexpression once)."""
    memo = Memo() if memo is None else memo
    roots = [sp.sympify(e) for e in exprs]
    for e in _postorder(roots, memo):
        if e.is_Symbol:
            memo.put(e, frozenset((e,)))
        elif not e.args:
            memo.put(e, frozenset())
        else:
            memo.put(e, frozenset().union(*(memo.get_(a) for a in e.args)))
    return set().union(*(memo.get_(r) for r in roots))


def diff(expr: sp.Expr, s: sp.Symbol, memo: Memo, symbols: Memo) -> sp.Expr:
    """``expr.diff(s)`` node by node as SymPy evaluates it (Add, Mul, Pow and
    functions of one argument by their ``_eval_derivative`` rules; anything
    else by SymPy itself). ``memo`` holds derivatives in ``s``, ``symbols`` the
    free symbols of each subexpression (share it between variables)."""
    free_symbols([expr], symbols)
    d = memo.get_
    for e in _postorder([expr], memo, skip=lambda e: s not in symbols.get_(e)):
        if s not in symbols.get_(e):
            out = sp.S.Zero
        elif e == s:
            out = sp.S.One
        elif e.is_Add:
            out = e.func(*[d(a) for a in e.args])
        elif e.is_Mul:
            args = list(e.args)
            out = sp.Add.fromiter([reduce(lambda x, y: x * y, args[:i] + [d(a)] + args[i + 1:], sp.S.One)
                                   for i, a in enumerate(args) if d(a)])
        elif e.is_Pow:
            base, exp = e.args
            out = e * (d(exp) * sp.log(base) + d(base) * exp / base)
        elif isinstance(e, sp.Function) and len(e.args) == 1:
            out = sp.Add(e.fdiff(1) * d(e.args[0]))
        else:
            out = sp.diff(e, s)
        memo.put(e, out)
    return d(expr)


def jacobian(m: sp.Matrix, variables: Iterable[sp.Symbol]) -> sp.Matrix:
    """``m.jacobian(variables)`` (rows: entries of m, columns: variables)."""
    variables = list(variables)
    symbols = Memo()
    memos = [Memo() for _ in variables]
    return sp.Matrix(len(m), len(variables),
                     lambda i, j: diff(m[i], variables[j], memos[j], symbols))


class Substitution:
    """``obj.xreplace(rule)`` for expressions and matrices, with one memo kept
    across calls: every matrix built from the same subexpressions (J, G, the
    laws and gains) pays for each distinct subexpression once. ``keep_sums``:
    as in :func:`xreplace` (the memo's results depend on it, so it is fixed
    per Substitution)."""

    def __init__(self, rule: Mapping, keep_sums: bool = False):
        self.rule = dict(rule)
        self.memo = Memo()
        self.keep_sums = keep_sums

    def __call__(self, obj):
        if isinstance(obj, sp.MatrixBase):
            out = sp.Matrix(obj.rows, obj.cols, xreplace_all(obj, self.rule, self.memo, self.keep_sums))
            return out.as_immutable() if isinstance(obj, sp.ImmutableMatrix) else out
        return xreplace(sp.sympify(obj), self.rule, self.memo, self.keep_sums)


def times(M: sp.Matrix, v: sp.Matrix) -> sp.Matrix:
    """M v for a small matrix M (B, B^-1: diagonal, numbers or symbols) and a column v of large
    expressions, entry by entry (zeros left out, a coefficient 1 not multiplied): SymPy's matrix
    product goes through its sparse domain matrices, which ask whether each entry is zero: on a
    large expression that query ran for minutes (B u* of the xArm6, B = I, in derive.codegen's
    kernels and reference); the products themselves are SymPy's own."""
    rows = []
    for i in range(M.rows):
        terms = [v[k] if M[i, k] == 1 else M[i, k] * v[k] for k in range(M.cols) if M[i, k] != 0]
        rows.append(sp.Add(*terms) if len(terms) != 1 else terms[0])
    return sp.Matrix(rows)
