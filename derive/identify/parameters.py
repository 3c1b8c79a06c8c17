"""The standard dynamic parameters of a chain: what identification estimates.

Per body i (1-based, in its joint frame F_i, as :mod:`derive.model.chain`):
the ten inertial parameters m_i, h_i = m_i c_i (hx, hy, hz) and the inertia
about F_i's origin (Ixx, Ixy, Ixz, Iyy, Iyz, Izz), in which J(q) q'' + G is
linear (Atkeson, An, Hollerbach, "Estimation of inertial parameters of
manipulator loads and links", IJRR 5(3), 1986); per joint j the reflected
rotor inertia Ia_j = gr_j^2 Jm_j on J's diagonal, the viscous damping fv_j
of G (the motor's back-EMF gr^2 Kt Kv / Ra plus the joint's viscous
friction bv: the whole damping diagonal of eq. 12), and, on request, a
Coulomb friction fc_j sign(q'_j) (not part of the controller's model).

Names are those of the runtime parameters of a URDF arm (m1, hx1, ..., Izz1)
and Ia1, fv1, fc1. :func:`standard_values` gives an arm's exact values.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.model.actuators import terms
from derive.model.chain import Chain, JointType

BODY_NAMES = ("m", "hx", "hy", "hz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")
BODY_UNITS = ("kg",) + ("kg m",) * 3 + ("kg m^2",) * 6
INERTIA_INDEX = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))   # the six inertia entries, row, column
KINDS = ("body", "rotor", "viscous", "coulomb")


@dataclass(frozen=True)
class StandardParameter:
    """One standard parameter: symbol (its name), kind (KINDS), joint (1-based), SI unit, description."""

    symbol: sp.Symbol
    kind: str
    joint: int
    unit: str
    doc: str

    @property
    def name(self) -> str:
        return self.symbol.name


def _body_docs(i: int) -> tuple[str, ...]:
    return (f"mass of body {i}",) + tuple(f"first moment m c of body {i}, {a}" for a in "xyz") + tuple(
        f"inertia of body {i} about its joint frame's origin, {n[1:]}" for n in BODY_NAMES[4:])


def standard_parameters(chain: Chain, coulomb: bool = False) -> tuple[StandardParameter, ...]:
    """The standard parameters of ``chain``: 10 per body, then Ia, fv (and fc) per joint."""
    out = []
    for i in range(1, chain.n + 1):
        for name, unit, doc in zip(BODY_NAMES, BODY_UNITS, _body_docs(i)):
            out.append(StandardParameter(sp.Symbol(f"{name}{i}", real=True), "body", i, unit, doc))
    kinds = (("rotor", "Ia", "reflected rotor inertia gr^2 Jm of joint {j}"),
             ("viscous", "fv", "viscous damping of joint {j} (back-EMF gr^2 Kt Kv / Ra plus bv)"))
    kinds += (("coulomb", "fc", "Coulomb friction of joint {j}: fc sign(theta')"),) if coulomb else ()
    for kind, prefix, doc in kinds:
        for j, joint in enumerate(chain.joints, 1):
            linear = joint.type is JointType.PRISMATIC
            unit = {"rotor": "kg" if linear else "kg m^2", "viscous": "N s/m" if linear else "N m s/rad",
                    "coulomb": "N" if linear else "N m"}[kind]
            out.append(StandardParameter(sp.Symbol(f"{prefix}{j}", real=True), kind, j, unit, doc.format(j=j)))
    return tuple(out)


def body_entries(body) -> tuple[sp.Expr, ...]:
    """The ten parameters of a body (m, h, I about the frame's origin) in BODY_NAMES order."""
    return (body.mass, *body.first_moment, *(body.inertia[a, b] for a, b in INERTIA_INDEX))


def standard_values(chain: Chain, coulomb: bool = False) -> tuple[sp.Expr, ...]:
    """The exact values the arm file gives the standard parameters (fc = 0: derive's
    model has no Coulomb friction), in :func:`standard_parameters` order."""
    values = chain.values()
    out = [sp.sympify(e).xreplace(values) for b in chain.bodies for e in body_entries(b)]
    motor = [terms(a) for a in chain.actuators]
    out += [sp.sympify(t[2]).xreplace(values) for t in motor]
    out += [sp.sympify(t[1]).xreplace(values) for t in motor]
    out += [sp.Integer(0)] * (chain.n if coulomb else 0)
    return tuple(out)


def pseudo_inertia(entries) -> list[list]:
    """The 4 x 4 pseudo-inertia [[S, h], [h^T, m]] of ten body parameters (S = tr(I)/2 1 - I,
    the second moment of the mass about the frame's origin): positive semidefinite exactly
    when some mass distribution has these parameters (Wensing, Kim, Slotine, "Linear matrix
    inequalities for physically consistent inertial parameter identification", IEEE RA-L
    3(1), 2017). Works on numbers, SymPy expressions and cvxpy expressions alike."""
    m, hx, hy, hz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz = entries
    half = (Ixx + Iyy + Izz) / 2
    return [[half - Ixx, -Ixy, -Ixz, hx], [-Ixy, half - Iyy, -Iyz, hy], [-Ixz, -Iyz, half - Izz, hz],
            [hx, hy, hz, m]]
