"""The inputs the speed box's operating points need, against the motors' limits (issue 34 item 2).

The sample-time limits (derive.control.sampling) linearise the sampled loop at operating points
(theta0, theta0') of derive.control.sampling.grid: configurations within the joint limits times the speed box's
vertices and each joint alone at its bound. At such a point the loop holds theta'' = 0, the observer's
estimate vanishes and every form applies

    u0 = B^-1 G(theta0, theta0')      (eq. 12 with theta'' = 0: J theta'' + G = B u),

G holding the Coriolis and centrifugal terms, gravity, friction and, with voltage actuation, the
back-EMF. "Stable" at a point says nothing about whether the motors can drive it: where |u0_i| exceeds
joint i's input limit (motor.voltage_limit, V, or torque_limit, N m), u is clipped there and the
linearisation describes a loop that is not the one that runs: the box is beyond what the motors
can drive (the vertical two-link arm at 60 rad/s: joint 1 needs 635 V and joint 2 671 V against 24 V).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Excess:
    """Joint ``joint`` (1-based) needs |u| = ``needed`` at the operating point (theta, theta') against its
    input limit ``limit`` (same unit, ``unit``: V, N m or N)."""

    joint: int
    needed: float
    limit: float
    unit: str
    theta: tuple[float, ...]
    dtheta: tuple[float, ...]


def box_inputs(d) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """u0 = B^-1 G(theta0, theta0') at every operating point of derive.control.sampling (P x n), with the
    points' theta0 and theta0' (P x n each)."""
    from derive.control.sampling import _loop, operating_points

    pts = operating_points(d)
    Q = np.array([p[0] for p in pts], dtype=float)
    DQ = np.array([p[1] for p in pts], dtype=float)
    G0, _ = _loop(d).bias(Q, DQ)
    B = np.array(d.B.tolist(), dtype=float)
    return np.linalg.solve(B, G0.T).T, Q, DQ


def beyond_limits(d) -> list[Excess]:
    """Per joint with an input limit, the operating point needing the largest |u0_i| when it exceeds the
    limit (empty when every point is within every limit, or no joint has a limit)."""
    from derive.model.actuators import input_unit

    motors = d.arm.motors
    if all(m.input_limit is None for m in motors):
        return []
    U, Q, DQ = box_inputs(d)
    prismatic = [not j.type.rotates for j in d.arm.spatial.joints] if d.arm.spatial is not None else [False] * d.n
    out = []
    for i, m in enumerate(motors):
        if m.input_limit is None:
            continue
        k = int(np.argmax(np.abs(U[:, i])))
        if abs(U[k, i]) > float(m.input_limit) * (1 + 1e-9):
            out.append(Excess(i + 1, float(abs(U[k, i])), float(m.input_limit), input_unit(m, prismatic[i]),
                              tuple(float(x) for x in Q[k]), tuple(float(x) for x in DQ[k])))
    return out


def summary(d) -> str | None:
    """One sentence for ``derive show`` and ``derive check`` (None when the box is within the limits)."""
    over = beyond_limits(d)
    if not over:
        return None
    parts = "; ".join(f"joint {e.joint} needs {e.needed:.3g} {e.unit} against its limit {e.limit:g} {e.unit} "
                      f"(at theta' = [{', '.join(f'{x:.3g}' for x in e.dtheta)}])" for e in over)
    return (f"the speed box is beyond what the motors can drive: holding its operating points (u = B^-1 G, "
            f"theta'' = 0) {parts}; the sample-time limits say the linearised loop is stable there, not that it "
            "tracks (u is clipped): lower max_joint_speed")
