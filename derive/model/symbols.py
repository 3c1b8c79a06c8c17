"""The symbols of a derivation, named once, in canonical order.

Names are the ones the generated code uses for its ports and parameter
fields, so they are plain ASCII identifiers: ``theta1``, ``dtheta1``, ``m1``.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp


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
