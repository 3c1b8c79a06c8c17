"""The symbols of a derivation, named once, in canonical order.

Names are the ones the generated code uses for its ports and parameter
fields, so they are plain ASCII identifiers: ``theta1``, ``dtheta1``, ``m1``.
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import sympy as sp

from derive.model.spec import Arm


def _vec(prefix: str, n: int, **assumptions: bool) -> tuple[sp.Symbol, ...]:
    return tuple(sp.Symbol(f"{prefix}{i + 1}", **assumptions) for i in range(n))


@dataclass(frozen=True)
class JointSymbols:
    """State, reference and error symbols of an n-joint arm (each a tuple of n)."""

    theta: tuple[sp.Symbol, ...]
    dtheta: tuple[sp.Symbol, ...]
    ddtheta: tuple[sp.Symbol, ...]
    yd: tuple[sp.Symbol, ...]
    dyd: tuple[sp.Symbol, ...]
    ddyd: tuple[sp.Symbol, ...]
    int_e: tuple[sp.Symbol, ...]   # integral of e = yd - y from 0 to t (eq. 34)
    u: tuple[sp.Symbol, ...]       # applied motor voltages
    z: tuple[sp.Symbol, ...]       # observer state (eq. 21)
    e: tuple[sp.Symbol, ...]       # tracking error e = yd - y (eq. 20)
    de: tuple[sp.Symbol, ...]      # its derivative
    e0: tuple[sp.Symbol, ...]      # e(0)
    de0: tuple[sp.Symbol, ...]     # e-dot(0)

    @staticmethod
    def make(n: int) -> "JointSymbols":
        real = {"real": True}
        return JointSymbols(*(_vec(p, n, **real) for p in (
            "theta", "dtheta", "ddtheta", "yd", "dyd", "ddyd", "int_e", "u", "z", "e", "de", "e0_", "de0_")))


@dataclass(frozen=True)
class ParamSymbols:
    """Physical parameter symbols of an arm, with the arm's exact values.

    ``values`` pairs each symbol with its Rational value, in canonical order:
    links, point masses, motors, gravity.
    """

    length: tuple[sp.Symbol, ...]
    mass: tuple[sp.Symbol, ...]
    com: tuple[sp.Symbol, ...]
    inertia: tuple[sp.Symbol, ...]
    friction: tuple[sp.Symbol, ...]
    pm_mass: tuple[sp.Symbol, ...]
    pm_distance: tuple[sp.Symbol, ...]
    pm_inertia: tuple[sp.Symbol, ...]
    Kt: tuple[sp.Symbol, ...]
    Kv: tuple[sp.Symbol, ...]
    R: tuple[sp.Symbol, ...]
    gear: tuple[sp.Symbol, ...]
    Jm: tuple[sp.Symbol, ...]
    g: sp.Symbol
    values: tuple[tuple[sp.Symbol, sp.Rational], ...]

    @staticmethod
    def make(arm: Arm) -> "ParamSymbols":
        n, k = arm.n, len(arm.point_masses)
        pos = {"positive": True}
        nonneg = {"nonnegative": True}
        syms = dict(
            length=_vec("l", n, **pos), mass=_vec("m", n, **pos), com=_vec("c", n, real=True),
            inertia=_vec("Ic", n, **nonneg), friction=_vec("bv", n, **nonneg),
            pm_mass=_vec("mp", k, **pos), pm_distance=_vec("rp", k, real=True),
            pm_inertia=_vec("Ip", k, **nonneg),
            Kt=_vec("Kt", n, **pos), Kv=_vec("Kv", n, **nonneg), R=_vec("Ra", n, **pos),
            gear=_vec("gr", n, **pos), Jm=_vec("Jm", n, **nonneg), g=sp.Symbol("g", **nonneg))
        L, P, M = arm.links, arm.point_masses, arm.motors
        raw: list[tuple[sp.Symbol, Fraction]] = []
        for name, attr, items in (("length", "length", L), ("mass", "mass", L), ("com", "com", L),
                                  ("inertia", "inertia", L), ("friction", "viscous_friction", L),
                                  ("pm_mass", "mass", P), ("pm_distance", "distance", P),
                                  ("pm_inertia", "inertia", P), ("Kt", "torque_constant", M),
                                  ("Kv", "voltage_constant", M), ("R", "resistance", M),
                                  ("gear", "gear_ratio", M), ("Jm", "rotor_inertia", M)):
            raw += [(s, getattr(item, attr)) for s, item in zip(syms[name], items)]
        raw.append((syms["g"], arm.gravity))
        values = tuple((s, sp.Rational(v.numerator, v.denominator)) for s, v in raw)
        return ParamSymbols(**syms, values=values)

    @property
    def subs(self) -> dict[sp.Symbol, sp.Rational]:
        """Mapping symbol -> exact value, for ``expr.xreplace``."""
        return dict(self.values)
