"""The symbols of a derivation, named once, in canonical order.

Names are the ones the generated code uses for its ports and parameter
fields, so they are plain ASCII identifiers: ``theta1``, ``dtheta1``, ``m1``.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.model.spec import Arm, controller_parameters


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
    """The parameters of a planar arm (the old lumped planar dynamics' view of
    :attr:`Arm.parameters`), with the arm's exact values.

    Each field is a tuple of SymPy expressions in the parameter symbols: a
    symbol where the file gave the value, else the expression the default is
    (com = l/2, a uniform rod's inertia m l^2/12). Kt, Kv, R are None for a
    torque-actuated joint. ``values`` pairs each parameter symbol with its
    Rational value in :attr:`Arm.parameters` order, without the controller's.
    """

    length: tuple[sp.Expr, ...]
    mass: tuple[sp.Expr, ...]
    com: tuple[sp.Expr, ...]
    inertia: tuple[sp.Expr, ...]
    friction: tuple[sp.Expr, ...]
    pm_mass: tuple[sp.Expr, ...]
    pm_distance: tuple[sp.Expr, ...]
    pm_inertia: tuple[sp.Expr, ...]
    Kt: tuple[sp.Expr | None, ...]
    Kv: tuple[sp.Expr | None, ...]
    R: tuple[sp.Expr | None, ...]
    gear: tuple[sp.Expr, ...]
    Jm: tuple[sp.Expr, ...]
    g: sp.Symbol
    values: tuple[tuple[sp.Symbol, sp.Rational], ...]

    @staticmethod
    def make(arm: Arm) -> "ParamSymbols":
        controller = {p.symbol for p in controller_parameters(arm.controller)}
        params = [p for p in arm.parameters if p.symbol not in controller]
        by = {p.symbol.name: p.symbol for p in params}
        n, k = arm.n, len(arm.point_masses)

        def vec(prefix: str, count: int, default=None) -> tuple:
            return tuple(by.get(f"{prefix}{i}", default(i) if default else None) for i in range(1, count + 1))

        length, mass = vec("l", n), vec("m", n)
        return ParamSymbols(
            length=length, mass=mass, com=vec("c", n, lambda i: length[i - 1] / 2),
            inertia=vec("Ic", n, lambda i: mass[i - 1] * length[i - 1] ** 2 / 12), friction=vec("bv", n),
            pm_mass=vec("mp", k), pm_distance=vec("rp", k), pm_inertia=vec("Ip", k),
            Kt=vec("Kt", n), Kv=vec("Kv", n), R=vec("Ra", n), gear=vec("gr", n), Jm=vec("Jm", n), g=by["g"],
            values=tuple((p.symbol, p.rational) for p in params))

    @property
    def subs(self) -> dict[sp.Symbol, sp.Rational]:
        """Mapping symbol -> exact value, for ``expr.xreplace``."""
        return dict(self.values)
