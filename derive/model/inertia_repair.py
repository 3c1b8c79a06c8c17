"""The nearest physically consistent inertia tensor (``[arm] repair_inertia``).

A rotational inertia about the centre of mass is physical when its principal
moments l = (l1, l2, l3) obey the triangle inequality l_i <= l_j + l_k (which
implies l_i >= 0: add two of them). Equivalently l = M d with d >= 0 and
M = [[0, 1, 1], [1, 0, 1], [1, 1, 0]]: d_i = (l_j + l_k - l_i) / 2 are the
second moments of the mass distribution along the principal axes. The set P
of physical tensors is convex and *spectral* (it depends only on the
eigenvalues, symmetrically), so by von Neumann's trace inequality
(||X - Y||_F >= ||l(X) - l(Y)|| for sorted eigenvalues; A. S. Lewis, "Convex
analysis on the Hermitian matrices", SIAM J. Optim. 6 (1996)) the tensor of P
nearest to I in the Frobenius norm keeps I's principal axes and replaces its
principal moments l by their Euclidean projection onto the cone
{M d : d >= 0}: the non-negative least-squares problem
min_{d >= 0} ||M d - l||, solved exactly by trying the 8 supports of d (the
least-squares solution on the true support is feasible, and no feasible
restricted solution is better than the optimum).

The common case, one violated inequality l3 > l1 + l2 by e > 0 with the result
still positive, has the closed form l' = l + (e / 3) (1, 1, -1): the
projection onto the plane l3 = l1 + l2, whose unit normal is (1, 1, -1) / sqrt(3),
a change of e / sqrt(3) in the Frobenius norm.

The projection lies on the boundary of P; to keep the repaired tensor
physical after its entries are written as decimals, every principal moment is
then raised by ``MARGIN`` times the trace (each inequality then holds with a
slack of that much) and the entries are rounded to a quantum 1e-12 of the
trace's decade: within 2e-9 of the trace of the Frobenius-nearest tensor, and
checked physical in exact arithmetic. MuJoCo's ``balanceinertia`` differs: it
sets all three diagonal moments to their mean.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from fractions import Fraction

import mpmath
import sympy as sp

from derive.model.rigid import inertia_problem

MARGIN = Fraction(1, 10 ** 9)
_DIGITS = 50
_M = ((0, 1, 1), (1, 0, 1), (1, 1, 0))
_INDEX = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _mp(I) -> mpmath.matrix:
    with mpmath.workdps(_DIGITS):
        return mpmath.matrix([[mpmath.mpf(sp.Rational(I[i][j]).p) / sp.Rational(I[i][j]).q
                               if not isinstance(I[i][j], float) else mpmath.mpf(I[i][j]) for j in range(3)]
                              for i in range(3)])


def principal_moments(I) -> tuple[list, mpmath.matrix]:
    """The principal moments (ascending, 50 digits) and the principal axes (columns) of
    the symmetric 3 x 3 ``I`` (nested sequences of exact or float numbers)."""
    with mpmath.workdps(_DIGITS):
        values, vectors = mpmath.eigsy(_mp(I))
        order = sorted(range(3), key=lambda k: values[k])
        V = mpmath.matrix(3, 3)
        for c, k in enumerate(order):
            for i in range(3):
                V[i, c] = vectors[i, k]
        return [values[k] for k in order], V


def violation(I) -> str:
    """How the principal moments of ``I`` break the rules, with the margin (kg m^2)."""
    lam, _ = principal_moments(I)
    lo, mid, hi = (float(x) for x in lam)
    if lo < 0:
        return f"a negative principal moment {lo:.3g} kg m^2 (principal moments {lo:.4g}, {mid:.4g}, {hi:.4g})"
    return f"principal moments {hi:.4g} > {lo:.4g} + {mid:.4g} (violated by {hi - lo - mid:.2g} kg m^2)"


def project(lam: list) -> list:
    """The Euclidean projection of the principal moments ``lam`` onto the triangle cone
    {M d : d >= 0} (see the module docstring), in mpmath numbers."""
    with mpmath.workdps(_DIGITS):
        best, best_cost = [mpmath.mpf(0)] * 3, sum(x * x for x in lam)
        for size in (1, 2, 3):
            for support in itertools.combinations(range(3), size):
                A = mpmath.matrix([[_M[i][k] for k in support] for i in range(3)])
                d = mpmath.lu_solve(A.T * A, A.T * mpmath.matrix(lam))
                if any(x < 0 for x in d):
                    continue
                point = A * d
                cost = sum((point[i] - lam[i]) ** 2 for i in range(3))
                if cost < best_cost:
                    best, best_cost = [point[i] for i in range(3)], cost
        return best


@dataclass(frozen=True)
class Repair:
    """A repaired tensor: its six entries (ixx, ixy, ixz, iyy, iyz, izz, exact decimals),
    the principal moments before and after, and the Frobenius norm of the change."""

    entries: tuple[Fraction, ...]
    before: tuple[float, float, float]
    after: tuple[float, float, float]
    change: float
    norm: float

    def describe(self) -> str:
        b = ", ".join(f"{x:.6g}" for x in self.before)
        a = ", ".join(f"{x:.6g}" for x in self.after)
        shown = " ".join(f"{k}={float(x):.10g}" for k, x in zip(("ixx", "ixy", "ixz", "iyy", "iyz", "izz"),
                                                                 self.entries))
        return (f"principal moments ({b}) -> ({a}) kg m^2, a change of {self.change:.3g} kg m^2 in the Frobenius "
                f"norm ({100 * self.change / self.norm:.3g} % of the tensor's); now {shown}")


def nearest_physical(I) -> Repair:
    """The physical inertia nearest to the symmetric 3 x 3 ``I`` (about the centre of mass;
    nested sequences of exact or float numbers, kg m^2) in the Frobenius norm, with
    principal axes kept (module docstring: the method, the margin and the rounding)."""
    lam, V = principal_moments(I)
    with mpmath.workdps(_DIGITS):
        new = project(lam)
        trace = sum(new)
        raised = [x + mpmath.mpf(MARGIN.numerator) / MARGIN.denominator * trace for x in new]
        R = V * mpmath.diag(raised) * V.T
        quantum = Fraction(10) ** (int(mpmath.floor(mpmath.log10(trace))) - 12) if trace > 0 else Fraction(1)
        entries = tuple(Fraction(round(Fraction(mpmath.nstr(R[i, j], 40)) / quantum)) * quantum for i, j in _INDEX)
        old = _mp(I)
        exact = [[entries[_INDEX.index((min(i, j), max(i, j)))] for j in range(3)] for i in range(3)]
        diff = mpmath.matrix([[mpmath.mpf(exact[i][j].numerator) / exact[i][j].denominator - old[i, j]
                               for j in range(3)] for i in range(3)])
        change = float(mpmath.sqrt(sum(diff[i, j] ** 2 for i in range(3) for j in range(3))))
        norm = float(mpmath.sqrt(sum(old[i, j] ** 2 for i in range(3) for j in range(3))))
        after, _ = principal_moments(exact)
    if inertia_problem(sp.Matrix(3, 3, lambda i, j: sp.Rational(exact[i][j].numerator, exact[i][j].denominator))):
        raise ArithmeticError("the repaired inertia is not physical (a bug: the margin must keep it so)")
    return Repair(entries, tuple(float(x) for x in lam), tuple(float(x) for x in after), change, norm)
