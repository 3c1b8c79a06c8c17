"""The rules an arm's parameter values obey, stated once for the arm-file validator and the FMU.

A :class:`Rule` is a SymPy expression in parameter symbols with a relation to 0 (``>``, ``>=``,
``!=``) and what it means in words. The validator decides with :meth:`Rule.holds` on the exact
values of the file; ``derive fmu`` prints the same expressions into the FMU (derive.fmu.rules), so
that a tunable parameter set to a value the validator would refuse is refused there too.

* Each parameter's own range is its symbol's domain (``positive``: > 0, ``nonnegative``: >= 0,
  ``real``: none), which the readers give the symbol from the same :class:`~derive.model.fields.Num`
  they check the field with (:func:`~derive.model.fields.domain`): :func:`domain_rules`.
* T1 < T2, the prediction horizon of eq. (14): :func:`horizon`.
* A full observer gain W (eq. 23-25): a positive diagonal (that of W + W^T) and det W != 0 (V of
  eq. a7 uses W^-1): :func:`gain_rules`; the determinant without a division or a pivot
  (:func:`division_free_det`, Berkowitz: O(n^4) products). In double, a determinant within
  2^10 u times Hadamard's bound (the product of the rows' lengths) of 0 counts as 0: W with two
  equal rows gives -3.8e-10 where the bound times u is 5.1e-6 (the Panda's starter W).
* A rigid body (a URDF, DH or identified arm): its pseudo-inertia [[tr(I)/2 1 - I, h], [h^T, m]]
  positive semidefinite, every principal minor >= 0 (Wensing, Kim, Slotine, IEEE RA-L 3(1), 2017):
  :func:`body_rules`. Exact arithmetic decides a minor that is 0 (a rod, a point mass); a double
  evaluation gets the allowance ``slack`` (in units of the real type's unit roundoff: 2^10 times
  the product of the minor's diagonal magnitudes, above the rounding of the at most 4! products
  of 4 factors and of the entries).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from fractions import Fraction
from itertools import combinations
from typing import Iterable, Mapping, Sequence, TypeVar

import sympy as sp

from derive.model.chain import Body, Parameter

RELATIONS = (">", ">=", "!=")
SLACK = 2 ** 10    # a principal minor's rounding allowance per unit roundoff and diagonal product

T = TypeVar("T")


@dataclass(frozen=True)
class Rule:
    """``value`` (SymPy, in parameter symbols) ``relation`` 0; ``expected``: the rule in words;
    ``slack`` (>= 0, in the same symbols): the rounding allowance, in units of the unit roundoff u,
    of a floating evaluation: a ``>=`` rule holds there when value >= -slack u, a ``!=`` rule when
    |value| > slack u (a determinant within rounding of 0 is 0); ``names``: the parameters it reads."""

    value: sp.Expr
    relation: str
    expected: str
    slack: sp.Expr = sp.S.Zero

    def __post_init__(self) -> None:
        if self.relation not in RELATIONS:
            raise ValueError(f"Rule: expected a relation of {RELATIONS}, got {self.relation!r}")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(sorted((s.name for s in sp.sympify(self.value).free_symbols), key=_natural))

    def holds(self, values: Mapping[sp.Symbol, Fraction]) -> bool:
        """The rule decided exactly at ``values`` (every symbol of ``value``; Fractions)."""
        x = sp.sympify(self.value).xreplace({s: sp.Rational(v.numerator, v.denominator) for s, v in values.items()})
        if not x.is_Rational:
            raise ValueError(f"Rule {self.expected!r}: not every symbol has a value ({x})")
        return bool(x > 0) if self.relation == ">" else bool(x >= 0) if self.relation == ">=" else x != 0


def _natural(name: str) -> tuple:
    """A sort key that orders W2_10 after W2_9."""
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name))


def domain_rules(parameters: Iterable[Parameter]) -> tuple[Rule, ...]:
    """Each parameter's own range, from its symbol's domain: > 0 (positive), >= 0 (nonnegative)."""
    out = []
    for p in parameters:
        s = p.symbol
        relation = ">" if s.is_positive else ">=" if s.is_nonnegative else None
        if relation is not None:
            out.append(Rule(s, relation, f"{s.name} {relation} 0" + (f" ({p.unit})" if p.unit else "")
                            + f", as {p.field} must be"))
    return tuple(out)


def horizon(T1: sp.Symbol, T2: sp.Symbol) -> Rule:
    """T1 < T2: the prediction horizon [T1, T2] of eq. (14)."""
    return Rule(T2 - T1, ">", "T1 < T2 (s; the prediction horizon [T1, T2] of eq. 14)")


def division_free_det(rows: Sequence[Sequence[T]], zero: T) -> T:
    """det of a square matrix without a division or a pivot (exact for Fractions, a polynomial of
    the entries for SymPy): Berkowitz's algorithm, the characteristic polynomial of each leading
    principal submatrix from the previous one by a Toeplitz product (S. J. Berkowitz, Inf. Process.
    Lett. 18(3), 1984). O(n^4) products for n x n; (-1)^n times the last coefficient."""
    n = len(rows)
    one = zero + 1
    if n == 0:
        return one
    coeffs = [one, zero - rows[0][0]]                 # det(x I - A_1) = x - a11
    for r in range(1, n):
        S = [rows[i][r] for i in range(r)]            # A_{r+1} = [[A_r, S], [R, a]]
        R = [rows[r][j] for j in range(r)]
        col = [one, zero - rows[r][r]]                # the Toeplitz column: 1, -a, -R S, -R A_r S, ...
        v = S
        for _ in range(r):
            col.append(zero - sum((x * y for x, y in zip(R, v)), zero))
            v = [sum((rows[i][j] * v[j] for j in range(r)), zero) for i in range(r)]
        coeffs = [sum((col[i - j] * coeffs[j] for j in range(min(i, r) + 1)), zero) for i in range(r + 2)]
    return coeffs[n] if n % 2 == 0 else zero - coeffs[n]


def gain_rules(W: sp.Matrix) -> tuple[Rule, ...]:
    """A full observer gain W: W[i][i] > 0 (the diagonal of W + W^T, eq. 25) and det W != 0 (V of
    eq. a7 uses W^-1). A diagonal entry that is a positive symbol is its domain rule already, and
    a triangular W's det is the product of its diagonal: then no det rule."""
    n = W.rows
    out = [Rule(W[i, i], ">", f"W[{i + 1}][{i + 1}] > 0 (observer gain: the diagonal of W + W^T must be positive, "
                                 "eq. 25)") for i in range(n) if not (W[i, i].is_Symbol and W[i, i].is_positive)]
    triangular = all(W[i, j] == 0 for i in range(n) for j in range(i + 1, n)) or \
        all(W[i, j] == 0 for i in range(n) for j in range(i))
    if not triangular:
        hadamard = math.prod(sp.sqrt(sum((W[i, j] ** 2 for j in range(n)), sp.S.Zero)) for i in range(n))
        out.append(Rule(division_free_det([[W[i, j] for j in range(n)] for i in range(n)], sp.S.Zero), "!=",
                        "det W != 0 (an invertible observer gain: V of eq. a7 uses W^-1)", SLACK * hadamard))
    return tuple(out)


def pseudo_inertia(m: T, h: Sequence[T], I: Sequence[Sequence[T]]) -> list[list[T]]:
    """[[tr(I)/2 1 - I, h], [h^T, m]] (4 x 4) of a body: mass m, first moment h = m c and inertia
    I about the frame's origin (Wensing et al. 2017)."""
    half = (I[0][0] + I[1][1] + I[2][2]) / 2
    return [[(half if a == b else 0) - I[a][b] for b in range(3)] + [h[a]] for a in range(3)] + [[*h, m]]


def principal_minors(P: Sequence[Sequence[T]], zero: T) -> list[tuple[tuple[int, ...], T]]:
    """(rows, det) of every principal minor of P, by size then rows."""
    k_max = len(P)
    return [(rows, division_free_det([[P[a][b] for b in rows] for a in rows], zero))
            for k in range(1, k_max + 1) for rows in combinations(range(k_max), k)]


PHYSICAL = ("a physically consistent body: pseudo-inertia [[tr(I)/2 1 - I, h], [h^T, m]] positive "
            "semidefinite (mass >= 0, the inertia about the centre of mass positive semidefinite with "
            "the triangle inequality)")


def physical(entries: Sequence[Fraction]) -> bool:
    """Whether ten exact body parameters (m, h, I about the frame's origin, I as xx, xy, xz, yy,
    yz, zz) have a mass distribution: every principal minor of the pseudo-inertia >= 0."""
    m, hx, hy, hz, xx, xy, xz, yy, yz, zz = (Fraction(x) for x in entries)
    P = pseudo_inertia(m, (hx, hy, hz), ((xx, xy, xz), (xy, yy, yz), (xz, yz, zz)))
    return all(d >= 0 for _, d in principal_minors(P, Fraction(0)))


def body_rules(bodies: Sequence[Body]) -> tuple[Rule, ...]:
    """Each body's pseudo-inertia positive semidefinite: its 15 principal minors >= 0, each with
    its rounding allowance (module docstring)."""
    out = []
    for i, b in enumerate(bodies, 1):
        I = [[b.inertia[a, c] for c in range(3)] for a in range(3)]
        P = pseudo_inertia(b.mass, list(b.first_moment), I)
        trace = sum((abs(I[a][a]) for a in range(3)), sp.S.Zero)
        size = [trace] * 3 + [abs(b.mass)]     # bounds of the diagonal entries' magnitudes
        for rows, d in principal_minors(P, sp.S.Zero):
            if d.is_number:
                continue
            slack = SLACK * math.prod(size[a] for a in rows)
            out.append(Rule(d, ">=", f"body {i}: {PHYSICAL} (principal minor of rows {', '.join(str(a + 1) for a in rows)})",
                            slack))
    return tuple(out)


def violated(rules: Iterable[Rule], values: Mapping[sp.Symbol, Fraction]) -> list[Rule]:
    """The rules that do not hold at ``values`` (exact)."""
    return [r for r in rules if not r.holds(values)]


def all_rules(parameters: Sequence[Parameter], *, horizon_symbols: tuple[sp.Symbol, sp.Symbol] | None = None,
              W: sp.Matrix | None = None, bodies: Sequence[Body] = ()) -> tuple[Rule, ...]:
    """Every rule on ``parameters``: their domains, T1 < T2 (``horizon_symbols``), a full ``W``'s
    and the ``bodies``' (the rigid bodies of a URDF, DH or identified arm; a planar arm's links
    are physical by their own fields' ranges). Only rules whose symbols all are parameters."""
    known = {p.symbol for p in parameters}
    out = list(domain_rules(parameters))
    if horizon_symbols is not None:
        out.append(horizon(*horizon_symbols))
    if W is not None:
        out += gain_rules(W)
    out += body_rules(bodies)
    return tuple(r for r in out if sp.sympify(r.value).free_symbols <= known)

