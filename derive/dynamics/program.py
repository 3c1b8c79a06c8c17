"""Working with the recursive dynamics as what it is: a DAG of shared subexpressions.

The recursions (:mod:`derive.dynamics.crba`, :mod:`derive.dynamics.rnea`)
reuse each quantity several times in the next joint's, so an entry of J or of
the bias is a small DAG whose tree (every path spelled out) grows
exponentially with n: a 6-joint arm's bias has about 400 distinct
subexpressions and over a million tree nodes. SymPy's tree walks
(``xreplace``, ``free_symbols``, ``has``, ``diff``, printing) visit the tree,
so on such entries they take seconds to hours. Here every walk visits each
distinct subexpression once:

* :func:`tree_size`, :func:`free_symbols`, :func:`dag_xreplace`;
* :func:`straight_line`: the DAG as a straight-line program, a tuple of
  definitions ``(x_k, expr_k)`` (each in earlier x's) and outputs over them;
  the form the pipeline hands large arms' J and G to the control laws in
  (:mod:`derive.control.pipeline`), so that SymPy manipulates small
  expressions and the generated code computes each x_k once;
* :func:`inline`: a program back to plain expressions.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import sympy as sp
from sympy.core.parameters import distribute

Definitions = tuple[tuple[sp.Symbol, sp.Expr], ...]

# The prefix of intermediate symbols: not an identifier any arm input can name
# (parameter names are plain identifiers without a leading underscore).
PREFIX = "_x"


def postorder(exprs: Iterable[sp.Basic]) -> list[sp.Basic]:
    """Every distinct subexpression, children before parents (deterministic: args order)."""
    seen: set[sp.Basic] = set()
    order: list[sp.Basic] = []
    for root in exprs:
        if root in seen:
            continue
        stack: list[tuple[sp.Basic, bool]] = [(root, False)]
        while stack:
            node, done = stack.pop()
            if done:
                order.append(node)
                continue
            if node in seen:
                continue
            seen.add(node)
            stack.append((node, True))
            stack.extend((a, False) for a in reversed(node.args) if a not in seen)
    return order


def tree_size(exprs: Iterable[sp.Basic]) -> int:
    """Nodes of the expressions as trees (what a SymPy tree walk visits)."""
    exprs = [sp.sympify(e) for e in exprs]
    size: dict[sp.Basic, int] = {}
    for node in postorder(exprs):
        size[node] = 1 + sum(size[a] for a in node.args)
    return sum(size[e] for e in exprs)


def free_symbols(exprs: Iterable[sp.Basic]) -> set[sp.Symbol]:
    """The symbols of the expressions (each distinct subexpression visited once)."""
    return {node for node in postorder(sp.sympify(e) for e in exprs) if node.is_Symbol}


def dag_xreplace(exprs: Sequence[sp.Basic], mapping: Mapping[sp.Basic, sp.Basic],
                 keep_sums: bool = True) -> list[sp.Basic]:
    """``[e.xreplace(mapping) for e in exprs]``, each distinct subexpression rebuilt once.

    ``keep_sums``: a number that lands in front of a sum (a parameter replaced
    by its value) multiplies the sum rather than being distributed over its
    terms (SymPy's default), which keeps the sum shared.
    """
    exprs = [sp.sympify(e) for e in exprs]
    memo: dict[sp.Basic, sp.Basic] = {}
    with distribute(not keep_sums):
        for node in postorder(exprs):
            if node in mapping:
                memo[node] = mapping[node]
            elif not node.args:
                memo[node] = node
            else:
                args = [memo[a] for a in node.args]
                memo[node] = node.func(*args) if any(a is not b for a, b in zip(args, node.args)) else node
    return [memo[e] for e in exprs]


def matrix_xreplace(m: sp.MatrixBase, mapping: Mapping[sp.Basic, sp.Basic]) -> sp.Matrix:
    """A matrix with :func:`dag_xreplace` applied to all its entries at once."""
    return sp.Matrix(m.rows, m.cols, dag_xreplace(list(m), mapping))


def _inline_worthy(node: sp.Basic) -> bool:
    """Cheap to repeat: an atom, sin/cos of a symbol, or a product or power of atoms."""
    if not node.args or isinstance(node, (sp.sin, sp.cos)) and node.args[0].is_Symbol:
        return True
    return (node.is_Mul or node.is_Pow) and len(node.args) == 2 and all(not a.args for a in node.args)


def straight_line(exprs: Sequence[sp.Expr], prefix: str = PREFIX) -> tuple[Definitions, list[sp.Expr]]:
    """(definitions, outputs): every subexpression used more than once (and not
    cheap to repeat) becomes a definition ``x_k = expr_k`` over earlier x's;
    the outputs are the expressions over them. Names are ``<prefix><k>``, k in
    post-order (deterministic). Inlining the definitions gives ``exprs`` back."""
    exprs = [sp.sympify(e) for e in exprs]
    order = postorder(exprs)
    uses: dict[sp.Basic, int] = {}
    for node in order:
        for a in node.args:
            uses[a] = uses.get(a, 0) + 1
    memo: dict[sp.Basic, sp.Basic] = {}
    definitions: list[tuple[sp.Symbol, sp.Expr]] = []
    for node in order:
        if not node.args:
            memo[node] = node
            continue
        args = [memo[a] for a in node.args]
        built = node.func(*args) if any(a is not b for a, b in zip(args, node.args)) else node
        if uses.get(node, 0) > 1 and not _inline_worthy(node):
            x = sp.Symbol(f"{prefix}{len(definitions) + 1}", real=True)
            definitions.append((x, built))
            memo[node] = x
        else:
            memo[node] = built
    return tuple(definitions), [memo[e] for e in exprs]


def inline(definitions: Definitions, exprs: Sequence[sp.Basic]) -> list[sp.Basic]:
    """The expressions with every definition substituted back (shared, not expanded)."""
    full: dict[sp.Basic, sp.Basic] = {}
    for x, e in definitions:
        full[x] = dag_xreplace([e], full, keep_sums=False)[0]
    return dag_xreplace(list(exprs), full, keep_sums=False)


def lambdify(args: Sequence[sp.Symbol], exprs, modules: str = "numpy"):
    """``sympy.lambdify(args, exprs, modules)`` for shared-subexpression entries:
    the function computes the :func:`straight_line` program (each shared
    subexpression once), so building and calling it take time proportional to
    the DAG, not the tree (SymPy's own printer spells every path out: minutes
    for a 6-joint arm's bias). ``exprs``: a matrix (the function returns its
    nested list) or a sequence of expressions (a list)."""
    shape = (exprs.rows, exprs.cols) if isinstance(exprs, sp.MatrixBase) else None
    flat = list(exprs)
    definitions, outputs = straight_line(flat)
    if shape is not None:
        outputs = [outputs[i * shape[1]:(i + 1) * shape[1]] for i in range(shape[0])]
    return sp.lambdify(list(args), outputs, modules=modules, use_imps=False,
                       cse=lambda e: (list(definitions), e))
