"""An independent plant for the identification tests: Pinocchio's RNEA with known parameters.

The truth is never computed by derive's dynamics: the torques of a trajectory are
``pin.rnea(q, q', q'')`` of a Pinocchio model plus the drives' rotor inertia Ia q'' and
viscous friction bv q' (what Pinocchio's RNEA leaves out), optionally with white noise.
A planar arm's Pinocchio model is built from its chain's joint placements and body
parameters (as tests/test_pinocchio.py does), a URDF arm's by Pinocchio's own URDF
parser; either may carry a payload the arm file does not know.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import sympy as sp

import pinocchio as pin
from derive.identify.parameters import body_entries
from derive.model.actuators import terms
from derive.model.spec import Arm


def _inertia(e: list[float]) -> "pin.Inertia":
    """Ten body parameters (m, h, I about the frame's origin) as a Pinocchio Inertia."""
    m, h = e[0], np.array(e[1:4])
    Io = np.array([[e[4], e[5], e[6]], [e[5], e[7], e[8]], [e[6], e[8], e[9]]])
    c = h / m
    return pin.Inertia(m, c, Io - m * (c @ c * np.eye(3) - np.outer(c, c)))


def chain_model(arm: Arm, payload: "pin.Inertia | None" = None) -> "pin.Model":
    """The arm's chain (placements, axes, bodies at the arm file's values) in Pinocchio, with
    ``payload`` (in the last joint's frame) added to the last body."""
    chain, values = arm.chain, arm.chain.values()
    model = pin.Model()
    parent = 0
    for i, (j, b) in enumerate(zip(chain.joints, chain.bodies)):
        R = np.array(j.origin.R.xreplace(values), dtype=float)
        p = np.array(j.origin.p.xreplace(values), dtype=float).ravel()
        axis = np.array(j.axis, dtype=float).ravel()
        parent = model.addJoint(parent, pin.JointModelRevoluteUnaligned(axis), pin.SE3(R, p), j.name)
        inertia = _inertia([float(sp.sympify(x).xreplace(values)) for x in body_entries(b)])
        if payload is not None and i == chain.n - 1:
            inertia = inertia + payload
        model.appendBodyToJoint(parent, inertia, pin.SE3.Identity())
    model.gravity = pin.Motion(np.array(chain.gravity.xreplace(values), dtype=float).ravel(), np.zeros(3))
    return model


def urdf_model(urdf: Path, payload: "pin.Inertia | None" = None, gravity=(0.0, 0.0, -9.81),
               moving: list[str] | None = None) -> "pin.Model":
    """Pinocchio's model of a URDF (fixed joints merged by Pinocchio), the joints not in ``moving``
    locked at 0 (a gripper's fingers), ``payload`` on the last body."""
    model = pin.buildModelFromUrdf(str(urdf))
    if moving is not None:
        lock = [model.getJointId(name) for name in model.names[1:] if name not in moving]
        model = pin.buildReducedModel(model, lock, pin.neutral(model)) if lock else model
    if payload is not None:
        model.inertias[model.njoints - 1] = model.inertias[model.njoints - 1] + payload
    model.gravity = pin.Motion(np.array(gravity, dtype=float), np.zeros(3))
    return model


def drives(arm: Arm) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Ia = gr^2 Jm, bv, back-EMF damping) per joint at the arm file's values."""
    values = arm.chain.values()
    Ia, total, emf = [], [], []
    for a in arm.chain.actuators:
        _, damping, reflected = terms(a)
        e = (a.gear_ratio ** 2 * a.torque_constant * a.voltage_constant / a.resistance
             if a.torque_constant is not None else sp.Integer(0))
        Ia.append(float(sp.sympify(reflected).xreplace(values)))
        total.append(float(sp.sympify(damping).xreplace(values)))
        emf.append(float(sp.sympify(e).xreplace(values)))
    return np.array(Ia), np.array(total) - np.array(emf), np.array(emf)


def torques(model: "pin.Model", q, dq, ddq, Ia, bv) -> np.ndarray:
    """The joint torques (N x n) of the trajectory: Pinocchio's RNEA plus Ia q'' + bv q'."""
    data = model.createData()
    tau = np.array([pin.rnea(model, data, q[k], dq[k], ddq[k]) for k in range(len(q))])
    return tau + Ia * ddq + bv * dq


def true_standard(model: "pin.Model", Ia, fv) -> np.ndarray:
    """The standard parameters (derive.identify.parameters order) of the Pinocchio model."""
    out = []
    for i in range(1, model.njoints):
        m, hx, hy, hz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz = model.inertias[i].toDynamicParameters()
        out += [m, hx, hy, hz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]
    return np.array(out + list(Ia) + list(fv))


def write_log(path: Path, t, q, signal, family: str = "tau", dtheta=None) -> None:
    """A log as derive identify reads it."""
    n = q.shape[1]
    cols = ["t"] + [f"theta{i}" for i in range(1, n + 1)] + [f"{family}{i}" for i in range(1, n + 1)]
    blocks = [t[:, None], q, signal]
    if dtheta is not None:
        cols += [f"dtheta{i}" for i in range(1, n + 1)]
        blocks.append(dtheta)
    np.savetxt(path, np.hstack(blocks), delimiter=",", header=",".join(cols), comments="", fmt="%.17g")


def read_trajectory(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, q, q', q'') of a derive excite CSV."""
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    n = (data.shape[1] - 1) // 3
    return data[:, 0], data[:, 1:1 + n], data[:, 1 + n:1 + 2 * n], data[:, 1 + 2 * n:]
