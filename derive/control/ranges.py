"""The derived constants of an arm, checked against the real type they are computed in.

Every number the generated code (or the simulation, in double) holds is either a
parameter value (a mass, a gain k1 of eq. 16, a voltage limit) or an exact number of a
derived matrix (J, G, B, K1, K2, W, P, D, I, N, dhat(0), u*, u; eq. 12-38). Each must be
a *normal* number of the real type: not beyond its largest finite value (it would
become inf), not a nonzero value below its smallest normal value (subnormal: precision
lost, flushed to zero under -ffast-math; or underflowing to zero). A value that is not
is reported as a :class:`~derive.errors.SpecError` naming the arm-file fields it comes
from, so every command fails the same way (exit code 2) before anything is printed.

Parameter values are checked first, each naming its own field (k1, k2 name T1 and T2);
the derived matrices only when every parameter fits (one out-of-range parameter would
spoil every matrix that uses it), each naming the fields its entry depends on.
"""
from __future__ import annotations

from fractions import Fraction
from typing import Any   # d: derive.control.pipeline.Derivation (which imports this module)

import numpy as np
import sympy as sp

from derive.errors import Problem, SpecError
from derive.model.fields import printable

REALS = ("double", "float")


def normal_range(real: str) -> tuple[Fraction, Fraction]:
    """(smallest normal, largest finite) magnitude of ``real`` ('double' or 'float'), exact."""
    info = np.finfo(np.float64 if real == "double" else np.float32)
    return Fraction(float(info.smallest_normal)), Fraction(float(info.max))


def exact(value: Fraction | sp.Number | float) -> Fraction:
    """The exact value of a finite Fraction, SymPy number or float."""
    if isinstance(value, sp.Rational):
        return Fraction(int(value.p), int(value.q))
    if isinstance(value, sp.Number):
        value = sp.Rational(value)
        return Fraction(int(value.p), int(value.q))
    return Fraction(value)


def range_problem(value: Fraction | sp.Number | float, real: str) -> str | None:
    """Why ``value`` is not a normal number of ``real`` ('overflows ...'), or None."""
    if isinstance(value, float) and not np.isfinite(value) or isinstance(value, sp.Number) and not value.is_finite:
        return f"is not finite ({value})"
    x = abs(exact(value))
    tiny, huge = normal_range(real)
    if x > huge:
        return f"overflows {real} (largest {float(huge):.3g})"
    if 0 < x < tiny:
        below = x < tiny * Fraction(1, 2 ** (52 if real == "double" else 23)) / 2
        return (f"{'underflows to 0 in' if below else 'is subnormal in'} {real} "
                f"(smallest normal {float(tiny):.3g})")
    return None


def shown(x: Fraction | sp.Number) -> str:
    """An exact value in 4 significant digits, for any magnitude (no float overflow)."""
    q = exact(x)
    if q == 0:
        return "0"
    sign, q = ("-" if q < 0 else ""), abs(q)
    e = len(str(q.numerator)) - len(str(q.denominator))
    if q < Fraction(10) ** e:
        e -= 1
    m = q / Fraction(10) ** e  # 1 <= m < 10
    return f"{sign}{float(m):.4g}e{e:+d}" if abs(e) >= 5 else f"{sign}{float(q):.5g}"


def parameter_fields(d: Any) -> dict[sp.Symbol, str]:
    """The arm-file field of each parameter symbol of ``d`` (``link[2].mass``,
    ``controller.T2``, ``urdf link 'forearm' <inertial><mass>``): the arm's Parameter records."""
    return {p.symbol: p.field for p in d.arm.parameters}


# (name, paper, numeric attribute of Derivation, symbolic counterpart, uses C)
_MATRICES = (("J", "eq. 12", "J", lambda d: d.dynamics.J, False),
             ("G", "eq. 12", "G", lambda d: d.dynamics.G, False),
             ("B", "eq. 12", "B", lambda d: d.dynamics.B, False),
             ("K1", "eq. 16", "K1", lambda d: d.mpc.K1, False),
             ("K2", "eq. 17", "K2", lambda d: d.mpc.K2, False),
             ("W", "eq. 25", "W", lambda d: d.observer.W, False),
             ("u*", "eq. 15", "u_star", lambda d: d.mpc.u_star, True),
             ("dhat", "eq. 22", "dhat", lambda d: d.observer.dhat, False),
             ("P", "eq. 35", "P", lambda d: d.npid.P, True),
             ("D", "eq. 36", "D", lambda d: d.npid.D, True),
             ("I", "eq. 37", "I", lambda d: d.npid.I, True),
             ("N", "eq. 38", "N", lambda d: d.npid.N, True),
             ("dhat(0)", "eq. 30", "dhat0", lambda d: d.npid.dhat0, True),
             ("u", "eq. 27", "u_dobc", lambda d: d.npid.u_dobc, True),
             ("u", "eq. 34", "u_npid", lambda d: d.npid.u_npid, True))


def _order(fields: set[str]) -> list[str]:
    """Fields in arm-file order (links, point masses, motors, controller, arm)."""
    rank = {"link": 0, "point_mass": 1, "motor": 2, "controller": 3, "arm": 4}
    return sorted(fields, key=lambda f: (rank.get(f.split("[")[0].split(".")[0], 5), f))


def _expected(real: str) -> str:
    tiny, huge = normal_range(real)
    return (f"values that keep every derived constant a normal {real} number "
            f"(0, or {float(tiny):.3g} to {float(huge):.3g} in magnitude)")


def range_problems(d: Any, real: str) -> list[Problem]:
    """Every derived constant of ``d`` that is not a normal ``real``, as problems naming fields."""
    problems: list[Problem] = []
    for p in d.arm.parameters:
        if (why := range_problem(p.value, real)) is not None:
            problems.append(Problem(p.field, _expected(real), f"{shown(p.value)}, which {why}"))
    for i, motor in enumerate(d.arm.motors, 1):
        limit = motor.input_limit
        if limit is not None and (why := range_problem(limit, real)) is not None:
            key = "voltage_limit" if limit is motor.voltage_limit else "torque_limit"
            problems.append(Problem(f"motor[{i}].{key}", _expected(real), f"{shown(limit)}, which {why}"))
    if problems:
        return problems  # one out-of-range parameter spoils every matrix that uses it
    if all(range_problem(x, real) is None for x in _numbers(getattr(d, m[2]) for m in _MATRICES)):
        return problems
    fields, values = parameter_fields(d), dict(d.values)
    for name, paper, attr, symbolic, uses_c in _MATRICES:
        numeric = getattr(d, attr)
        for k, entry in enumerate(numeric):
            bad = next(((x, why) for x in sorted(sp.sympify(entry).atoms(sp.Number), key=exact)
                        if (why := range_problem(x, real)) is not None), None)
            if bad is None:
                continue
            culprits = _culprits(sp.sympify(symbolic(d)[k]), values, real)
            found = {fields.get(s, str(s)): values[s] for s in culprits}
            if uses_c and d.C != sp.eye(d.n):
                found["controller.C"] = None
            square = name in ("J", "B", "K1", "K2", "W", "P", "D", "I")  # the others are n x 1
            where = f"[{k // numeric.cols + 1}][{k % numeric.cols + 1}]" if square else f"[{k + 1}]"
            names = _order(set(found))
            given = ", ".join(f if found[f] is None else f"{f} = {shown(found[f])}" for f in names)
            # the first matrix in the order of the derivation: the later ones are made of it
            return [Problem(" and ".join(names) or "controller", _expected(real),
                            f"{given}{' give ' if given else ''}{name}{where} ({paper}) "
                            f"{'= ' if sp.sympify(entry).is_Number else 'holding the constant '}{shown(bad[0])}, "
                            f"which {bad[1]}")]
    return problems


def _numbers(matrices) -> set[sp.Number]:
    """Every number in the matrices' entries (each shared subexpression visited once)."""
    seen: set = set()
    stack = [sp.sympify(e) for m in matrices for e in m]
    numbers = set()
    while stack:
        e = stack.pop()
        if e not in seen:
            seen.add(e)
            if e.is_Number:
                numbers.add(e)
            else:
                stack.extend(e.args)
    return numbers


def _culprits(entry: sp.Expr, values: dict[sp.Symbol, sp.Rational], real: str) -> set[sp.Symbol]:
    """The parameter symbols of the term of ``entry`` (expanded) that is out of range:
    J11 = Ic + m c^2 + Jm gr^2 with m c^2 = 2.5e59 names m and c, not Jm. All of the
    entry's parameters when no single term is (or the entry is too large to expand)."""
    params = entry.free_symbols & set(values)
    if sp.count_ops(entry) > 400:
        return params
    worst, score = None, -1.0
    for term in sp.Add.make_args(sp.expand(entry)):
        coeff, _ = term.xreplace(values).as_coeff_Mul()
        if range_problem(coeff, real) is not None:
            magnitude = abs(float(sp.log(abs(coeff), 10)))
            if magnitude > score:
                worst, score = term, magnitude
    return params if worst is None else worst.free_symbols & set(values)


def check_ranges(d: Any, real: str) -> None:
    """Raise SpecError (naming the arm-file fields) unless every derived constant of
    ``d`` is a normal number of ``real`` ('double' or 'float')."""
    if real not in REALS:
        raise ValueError(f"real: expected one of {', '.join(REALS)}, got {real!r}")
    problems = range_problems(d, real)
    if problems:
        raise SpecError(printable(d.arm.source), problems)
