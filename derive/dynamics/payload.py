"""A rigid payload on the arm's last body: its contribution to J(q) and G(q, q') (eq. 12).

The payload is one rigid body fixed to body n (the body the last joint moves), described in
that joint's frame F_n by ten parameters (:data:`NAMES`): its mass m [kg], its centre of mass
c [m] and its rotational inertia about c, Ic [kg m^2] (xx, xy, xz, yy, yz, zz). As a body of
the chain (derive.model.chain.Body) it is

    mass m,  first moment h = m c,  inertia about F_n's origin  I_o = Ic + m (|c|^2 1 - c c^T)

(the parallel-axis theorem). The chain's dynamics are linear in each body's mass, first moment
and inertia, so the arm carrying the payload has

    J_true(q) = J(q) + J_p(q),   G_true(q, q') = G(q, q') + G_p(q, q'),

J_p by the composite-rigid-body algorithm and G_p (its Coriolis, centrifugal and gravity forces)
by the recursive Newton-Euler algorithm over the same joint frames with every body but the last
massless (derive.dynamics.crba, derive.dynamics.rnea). J_p and G_p are expressions in the joint
symbols and the ten payload symbols, so one derivation serves every payload: a plant
(derive.sim.plant, the compiled loop, the plant FMU) takes the ten as runtime parameters, and the
payload limit (derive.control.payload) evaluates them at many payloads at once.

The controller's model never carries the payload (derive.control.payload's module docstring
says why the nominal payload is none).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sympy as sp

from derive.dynamics.crba import Composite, composites, crba
from derive.dynamics.rnea import rnea
from derive.dynamics.spatial import ZERO, ZERO_VEC, vec

NAMES = ("payload_m", "payload_cx", "payload_cy", "payload_cz", "payload_Ixx", "payload_Ixy", "payload_Ixz",
         "payload_Iyy", "payload_Iyz", "payload_Izz")
UNITS = ("kg", "m", "m", "m", "kg m^2", "kg m^2", "kg m^2", "kg m^2", "kg m^2", "kg m^2")
SPHERE_RADIUS = 0.05   # m: the default payload, a solid sphere of this radius (Ic = 2/5 m r^2 1)


def payload_symbols() -> tuple[sp.Symbol, ...]:
    """The ten payload symbols (:data:`NAMES`), real."""
    return tuple(sp.Symbol(name, real=True) for name in NAMES)


def sphere_inertia(mass: float, radius: float = SPHERE_RADIUS) -> np.ndarray:
    """3 x 3 inertia [kg m^2] of a solid sphere of ``mass`` [kg] and ``radius`` [m] about its centre."""
    return 0.4 * mass * radius * radius * np.eye(3)


def payload_values(mass: float, com, inertia=None) -> tuple[float, ...]:
    """The ten payload parameters (:data:`NAMES`) of a payload of ``mass`` [kg] at ``com`` (3, m, in
    F_n), with ``inertia`` (3 x 3 about the centre of mass [kg m^2]; None: the solid sphere of
    SPHERE_RADIUS). Raises ValueError for a non-finite or negative mass or a com not of 3 numbers."""
    c = np.asarray(com, dtype=float).reshape(-1)
    if not (math.isfinite(mass) and mass >= 0) or c.shape != (3,) or not np.isfinite(c).all():
        raise ValueError(f"payload_values: expected a finite mass >= 0 and a com of 3 finite numbers, got {mass!r}, {com!r}")
    I = sphere_inertia(mass) if inertia is None else np.asarray(inertia, dtype=float)
    return (float(mass), *map(float, c), float(I[0, 0]), float(I[0, 1]), float(I[0, 2]), float(I[1, 1]),
            float(I[1, 2]), float(I[2, 2]))


def payload_body(symbols) -> Composite:
    """The payload as a body in F_n (module docstring), in its ten symbols."""
    m, cx, cy, cz, ixx, ixy, ixz, iyy, iyz, izz = symbols
    c = (cx, cy, cz)
    Ic = ((ixx, ixy, ixz), (ixy, iyy, iyz), (ixz, iyz, izz))
    r2 = cx * cx + cy * cy + cz * cz
    Io = tuple(tuple(Ic[i][j] + m * ((r2 if i == j else 0) - c[i] * c[j]) for j in range(3)) for i in range(3))
    return Composite(m, vec([m * x for x in c]), Io)


@dataclass(frozen=True)
class PayloadTerms:
    """What a payload adds to the dynamics: J (n x n) and G (n x 1) in the joint symbols and
    ``symbols`` (the ten of :data:`NAMES`), zero at a zero payload."""

    symbols: tuple[sp.Symbol, ...]
    J: sp.Matrix
    G: sp.Matrix


def payload_terms(dyn) -> PayloadTerms:
    """J_p and G_p of a payload on the last body of ``dyn`` (derive.dynamics.equations.Dynamics),
    over its joint frames and gravity (module docstring)."""
    symbols = payload_symbols()
    n = dyn.n
    empty = Composite(ZERO, ZERO_VEC, (ZERO_VEC,) * 3)
    bodies = [empty] * (n - 1) + [payload_body(symbols)]
    fr = dyn.frames
    J = crba(composites(bodies, fr), fr, [ZERO] * n)
    G = rnea(bodies, fr, dyn.sym.dtheta, [ZERO] * n, vec(dyn.chain.gravity))
    return PayloadTerms(symbols, J, G)
