"""The dynamics as placeholders: the control stages are algebra over J, G, g, C.

Every control law of the paper is a matrix expression in the dynamics' J(theta),
G(theta, theta') and, for the momentum observer, g(theta) and the Coriolis matrix
C(theta, theta') (eq. 15, 21-27, 34-38): products with the gains and the errors,
never a derivative of J. So the stages build their laws over small matrices of
placeholder symbols (``_J1_2`` for J_12 = J_21, ``_G1``, ``_g1``, ``_C1_2``):
SymPy then manipulates a few dozen symbols instead of the recursion's shared
subexpressions (building the Panda's laws over its J took seconds of SymPy's
assumption queries; over placeholders it takes milliseconds), and
:meth:`Placeholders.inline` puts the dynamics in afterwards, each shared
subexpression rebuilt once (:func:`derive.dynamics.dag.xreplace`).

The laws in placeholders are also what the proof obligations decide
(:mod:`derive.proofs.project`): an identity that holds for symbols J_ij = J_ji,
G_i holds for every symmetric J and every G, so for the arm's; the identities
that rest on what J and G are (symmetry of the recursion's J, J' - 2C skew,
energy, the RNEA law equal to J a + G) are decided on the dynamics themselves
(:mod:`derive.proofs.arm`).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import sympy as sp

from derive.dynamics.dag import Memo, free_symbols, xreplace, xreplace_all
from derive.dynamics.equations import Dynamics

PREFIX = "_"   # placeholder names: no arm input names a symbol with a leading underscore


def _sym(name: str) -> sp.Symbol:
    return sp.Symbol(PREFIX + name, real=True)


@dataclass(frozen=True)
class Placeholders:
    """n x n symmetric J, n x 1 G and g, n x n C of placeholder symbols for ``dyn``."""

    dyn: Dynamics

    @cached_property
    def J(self) -> sp.Matrix:
        return sp.Matrix(self.n, self.n, lambda i, j: _sym(f"J{min(i, j) + 1}_{max(i, j) + 1}"))

    @cached_property
    def G(self) -> sp.Matrix:
        return sp.Matrix([_sym(f"G{i + 1}") for i in range(self.n)])

    @cached_property
    def g(self) -> sp.Matrix:
        return sp.Matrix([_sym(f"g{i + 1}") for i in range(self.n)])

    @cached_property
    def C(self) -> sp.Matrix:
        return sp.Matrix(self.n, self.n, lambda i, j: _sym(f"C{i + 1}_{j + 1}"))

    @property
    def n(self) -> int:
        return self.dyn.n

    def rule(self, used: set[sp.Symbol]) -> dict[sp.Symbol, sp.Expr]:
        """placeholder -> the dynamics' expression (parameter symbols), for the ``used`` ones."""
        out: dict[sp.Symbol, sp.Expr] = {}
        pairs = [(self.J, lambda: self.dyn.J), (self.G, lambda: self.dyn.G),
                 (self.g, lambda: self.dyn.gravity), (self.C, lambda: self.dyn.coriolis)]
        for ph, real in pairs:
            if used.isdisjoint(ph):
                continue
            value = real()
            for i in range(ph.rows):
                for j in range(ph.cols):
                    if ph[i, j] in used:
                        out[ph[i, j]] = value[i, j]
        return out

    def symbols(self) -> set[sp.Symbol]:
        """Every placeholder that has been created."""
        found: set[sp.Symbol] = set()
        for name in ("J", "G", "g", "C"):
            if name in self.__dict__:
                found |= set(self.__dict__[name])
        return found

    def inline(self, m: sp.MatrixBase, rule: Mapping[sp.Symbol, sp.Expr] | None = None,
               memo: Memo | None = None) -> sp.Matrix:
        """``m`` with the placeholders replaced by the dynamics (``rule``: another mapping, e.g.
        to the numeric dynamics); shared subexpressions kept (``memo`` may be shared between
        calls with the same rule)."""
        if rule is None:
            rule = self.rule(self.symbols())
        memo = Memo() if memo is None else memo
        return sp.Matrix(m.rows, m.cols, xreplace_all([sp.sympify(v) for v in m], rule, memo, keep_sums=True))


class OpaqueDynamics:
    """A :class:`~derive.dynamics.equations.Dynamics` seen through placeholders: J, G,
    gravity and coriolis are the placeholder matrices; sym, chain, B, damping, reflected
    inverse_dynamics (the RNEA law, what the kernels compute) and momentum (J q', C^T q' by a
    recursion) are the dynamics' own.
    The control stages take it where they take a Dynamics."""

    def __init__(self, dyn: Dynamics) -> None:
        self.real = dyn
        self.ph = Placeholders(dyn)
        self.sym, self.chain, self.B, self.damping = dyn.sym, dyn.chain, dyn.B, dyn.damping
        self.reflected, self.n = dyn.reflected, dyn.n
        self.J, self.G = self.ph.J, self.ph.G

    @property
    def gravity(self) -> sp.Matrix:
        return self.ph.g

    @property
    def coriolis(self) -> sp.Matrix:
        return self.ph.C

    @property
    def values(self):
        return self.real.values

    def inverse_dynamics(self, ddq) -> sp.Matrix:
        return self.real.inverse_dynamics(ddq)

    @property
    def momentum(self) -> tuple[sp.Matrix, sp.Matrix]:
        return self.real.momentum

    def inline(self, value, memo: Memo | None = None):
        """A stage's value with the dynamics put in: a matrix entry by entry, an unevaluated
        matrix product (W J^-1 for n > 2) factor by factor; anything else as it is."""
        memo = Memo() if memo is None else memo
        if isinstance(value, sp.MatrixBase):
            used = self.ph.symbols() & free_symbols(list(value))
            if not used:
                return value
            return self.ph.inline(value, self.ph.rule(used), memo)
        if isinstance(value, (sp.MatMul, sp.Inverse)):
            return value.func(*[self.inline(a, memo) for a in value.args], evaluate=False) \
                if isinstance(value, sp.MatMul) else sp.Inverse(self.inline(value.args[0], memo))
        return value

    def inline_stage(self, stage):
        """A stage dataclass (Mpc, Observer, Npid, Momentum) with every matrix field inlined."""
        import dataclasses

        memo = Memo()
        changes = {f.name: self.inline(getattr(stage, f.name), memo) for f in dataclasses.fields(stage)
                   if isinstance(getattr(stage, f.name), (sp.MatrixBase, sp.MatMul))}
        return dataclasses.replace(stage, **changes)

