"""The ``[payload]`` table of an arm file: the range of payloads the controller is designed for.

::

    [payload]                   # derive init --payload MASS writes it
    mass = 5.0                  # kg: the controller must hold every payload from 0 to this
    com = [0.0, 0.0, 0.05]      # m, in the tip link's frame: the nominal centre of mass
    com_radius = 0.1            # m: the centre of mass may lie anywhere within this ball around com
    # inertia = [[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]   # kg m^2 about the centre of mass, at `mass`

The payload is a rigid body fixed to the tip link (derive.dynamics.payload adds it to the last
body's dynamics). Its inertia about its centre of mass is ``inertia`` at the full ``mass`` and
scales with the mass below it (the same shape, lighter), by default a solid sphere of 5 cm radius
(2/5 m r^2 on the diagonal). The frame is the tip link's (``arm.tip_link`` of a URDF arm; the last
moving body's frame F_n otherwise, derive.model.chain).

Checked: ``mass`` finite and >= 0; ``com`` three finite numbers; ``com_radius`` finite and >= 0;
every centre of mass of the ball within MAX_REACH of the tip frame's origin (a payload 2 m off the
flange is a typing error, not a tool); ``inertia`` symmetric, positive definite and a possible
mass distribution (each principal moment at most the sum of the other two: Ixx + Iyy >= Izz, ...).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from derive.dynamics.payload import SPHERE_RADIUS, payload_values, sphere_inertia
from derive.model.fields import Reader, show

KEYS = {"mass": "the largest payload [kg] (a finite number >= 0)", "com": None, "com_radius": None, "inertia": None}
MAX_REACH = 2.0    # m: |com| + com_radius at most this


@dataclass(frozen=True)
class PayloadRange:
    """The payloads an arm file states (module docstring): ``mass`` [kg] (every payload from 0 to
    it), ``com`` [m] (3, tip link's frame), ``com_radius`` [m], ``inertia`` (3 x 3 about the centre
    of mass at ``mass`` [kg m^2]; None: the solid sphere of 5 cm radius)."""

    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    com_radius: float = 0.0
    inertia: tuple[tuple[float, ...], ...] | None = None

    def inertia_at(self, mass: float) -> np.ndarray:
        """The inertia about the centre of mass [kg m^2] of a payload of ``mass`` kg of this shape."""
        if self.inertia is None:
            return sphere_inertia(mass)
        return np.array(self.inertia, dtype=float) * (mass / self.mass if self.mass > 0 else 0.0)

    def describe(self) -> str:
        """One line for statements: the range and where its centre of mass may lie."""
        shape = "a solid sphere of 5 cm radius" if self.inertia is None else "the stated inertia, scaled with the mass"
        c = ", ".join(f"{x:g}" for x in self.com)
        return (f"0 to {self.mass:g} kg, centre of mass within {self.com_radius:g} m of [{c}] m in the tip link's "
                f"frame, {shape}")


def tip_to_body(chain, com, inertia) -> tuple[np.ndarray, np.ndarray]:
    """A centre of mass (3) and an inertia about it (3 x 3) given in the tip link's frame, expressed in
    F_n (derive.model.chain.Chain.tip)."""
    c, I = np.asarray(com, dtype=float), np.asarray(inertia, dtype=float)
    if getattr(chain, "tip", None) is None:
        return c, I
    R = np.array(chain.tip.R.tolist(), dtype=float)
    p = np.array(chain.tip.p.tolist(), dtype=float).reshape(3)
    return R @ c + p, R @ I @ R.T


def body_values(chain, mass: float, com, inertia=None) -> tuple[float, ...]:
    """The ten payload parameters (derive.dynamics.payload.NAMES, in F_n) of a payload of ``mass`` [kg]
    at ``com`` (tip link's frame) with ``inertia`` about its centre of mass (None: the 5 cm sphere)."""
    I = sphere_inertia(mass) if inertia is None else np.asarray(inertia, dtype=float)
    c, I = tip_to_body(chain, com, I)
    return payload_values(mass, c, I)


def _triple(r: Reader, value: Any, field: str) -> tuple[float, float, float] | None:
    if not (isinstance(value, list) and len(value) == 3):
        r.bad(field, "an array of 3 finite numbers [m] in the tip link's frame", value)
        return None
    out = []
    for i, x in enumerate(value, 1):
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            r.bad(f"{field}[{i}]", "a finite number (m)", x)
            return None
        out.append(float(x))
    return tuple(out)


def _inertia(r: Reader, value: Any, field: str) -> tuple[tuple[float, ...], ...] | None:
    ok = (isinstance(value, list) and len(value) == 3 and all(isinstance(row, list) and len(row) == 3 for row in value)
          and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                  for row in value for x in row))
    if not ok:
        r.bad(field, "a 3 x 3 array of finite numbers [kg m^2] (the inertia about the centre of mass)", value)
        return None
    I = np.array(value, dtype=float)
    if not np.allclose(I, I.T, rtol=0, atol=1e-12 * max(1.0, np.abs(I).max())):
        r.bad(field, "a symmetric 3 x 3 inertia (ixy written twice the same)", value)
        return None
    lam = np.linalg.eigvalsh(I)
    if lam[0] <= 0 or lam[2] > lam[0] + lam[1] + 1e-12 * lam[2]:
        r.add(field, "the inertia of a possible mass distribution: positive principal moments, each at most the sum "
              "of the other two", f"{show(value)} (principal moments {', '.join(f'{x:.4g}' for x in lam)})")
        return None
    return tuple(tuple(float(x) for x in row) for row in I)


def parse_payload(r: Reader, value: Any, field: str = "payload") -> PayloadRange | None:
    """The ``[payload]`` table (module docstring), problems added to ``r``; None when absent or wrong."""
    if value is None:
        return None
    d = r.table(value, field, KEYS, "a table [payload] with mass, com, com_radius and inertia")
    if d is None:
        return None
    before = len(r.problems)
    mass = d.get("mass")
    if isinstance(mass, bool) or not isinstance(mass, (int, float)) or not math.isfinite(mass) or mass < 0:
        r.bad(f"{field}.mass", KEYS["mass"], mass)
        mass = None
    com = _triple(r, d["com"], f"{field}.com") if "com" in d else (0.0, 0.0, 0.0)
    radius = d.get("com_radius", 0.0)
    if isinstance(radius, bool) or not isinstance(radius, (int, float)) or not math.isfinite(radius) or radius < 0:
        r.bad(f"{field}.com_radius", "a finite number >= 0 (m): the ball the centre of mass may lie in", radius)
        radius = None
    inertia = _inertia(r, d["inertia"], f"{field}.inertia") if "inertia" in d else None
    if com is not None and radius is not None and (reach := math.sqrt(sum(x * x for x in com)) + radius) > MAX_REACH:
        alone = math.sqrt(sum(x * x for x in com)) > MAX_REACH
        r.add(f"{field}.com" if alone or radius == 0 else f"{field}.com_radius",
              f"a centre of mass within {MAX_REACH:g} m of the tip link's origin (|com| + com_radius <= {MAX_REACH:g} m)",
              f"|com| + com_radius = {reach:g} m")
    if inertia is not None and mass == 0:
        r.add(f"{field}.inertia", "no inertia for a payload of mass 0 (it is the inertia at the full mass)",
              show(d["inertia"]))
    if len(r.problems) > before:
        return None
    return PayloadRange(mass=float(mass), com=com, com_radius=float(radius), inertia=inertia)


SPHERE_NOTE = f"a solid sphere of {SPHERE_RADIUS * 100:g} cm radius"
