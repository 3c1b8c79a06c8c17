"""Example arms built in code: planar chains of any length, for tests,
benchmarks and experiments beyond the packaged arm files."""
from __future__ import annotations

from fractions import Fraction

import sympy as sp

from derive.model.chain import (Actuation, Actuator, Body, Chain, Joint, JointType, Limits, Parameter,
                                Transform)
from derive.model.spec import Arm, arm_from_dict
from derive.model.symbols import ParamSymbols


def planar_chain_dict(n: int, gravity: float = 0.0, name: str = "chain") -> dict:
    """An n-link planar chain with varied, non-uniform parameters: geared motors
    with rotor inertia, a tip mass and a point mass (a carried motor) at each
    inner joint. The arm is named ``<name><n>``."""
    links = [{"length": 0.3 + 0.05 * i, "mass": 0.4 + 0.1 * i, "com": 0.12 + 0.02 * i,
              "inertia": 0.002 + 0.001 * i, "viscous_friction": 0.01 * i} for i in range(n)]
    motors = [{"torque_constant": 0.05 + 0.01 * i, "voltage_constant": 0.04 + 0.01 * i,
               "resistance": 2.0 + i, "gear_ratio": 1.0 + i, "rotor_inertia": 1e-5 * i} for i in range(n)]
    point_masses = [{"link": n, "distance": 0.3 + 0.05 * (n - 1), "mass": 0.15}]
    point_masses += [{"link": i, "distance": 0.3 + 0.05 * (i - 1), "mass": 0.2, "inertia": 1e-4}
                     for i in range(1, n)]
    return {"arm": {"name": f"{name}{n}", "gravity": gravity}, "link": links, "motor": motors,
            "point_mass": point_masses,
            "controller": {"T1": 0.0, "T2": 0.5, "w": [1.0 + i for i in range(n)]}}


def planar_chain(n: int, gravity: float = 0.0) -> Arm:
    """The validated :func:`planar_chain_dict` arm."""
    return arm_from_dict(planar_chain_dict(n, gravity), f"<chain{n}>")


# -- chains built in code (the dynamics' tests and benchmarks) ------------------------------

def _param(symbol: sp.Symbol, value, unit: str, field: str, doc: str) -> Parameter:
    return Parameter(symbol, Fraction(value), unit, field, doc)


def planar_arm_chain(arm: Arm) -> Chain:
    """The planar ``arm`` as a Chain in the symbols of :class:`ParamSymbols`:
    revolute z joints, joint i+1 at (l_i, 0, 0) of frame i, each link lumped
    with its point masses (mass, first moment along x, inertia I_zz about the
    joint; I_yy = I_zz, I_xx = 0 as for bodies on the x axis: planar motion
    does not see them), gravity along -y, voltage-driven motors."""
    p = ParamSymbols.make(arm)
    zero, z = sp.Integer(0), sp.ImmutableMatrix([0, 0, 1])
    joints, bodies, actuators = [], [], []
    for i in range(arm.n):
        offset = zero if i == 0 else p.length[i - 1]
        joints.append(Joint(f"joint{i + 1}", JointType.REVOLUTE,
                            Transform(sp.ImmutableMatrix.eye(3), sp.ImmutableMatrix([offset, 0, 0])),
                            z, Limits(), f"link[{i + 1}]"))
        M = p.mass[i]
        hx = p.mass[i] * p.com[i]
        Io = p.inertia[i] + p.mass[i] * p.com[i] ** 2
        for k, pm in enumerate(arm.point_masses):
            if pm.link == i:
                M += p.pm_mass[k]
                hx += p.pm_mass[k] * p.pm_distance[k]
                Io += p.pm_inertia[k] + p.pm_mass[k] * p.pm_distance[k] ** 2
        bodies.append(Body(M, sp.ImmutableMatrix([hx, 0, 0]), sp.ImmutableMatrix(sp.diag(0, Io, Io))))
        actuators.append(Actuator(Actuation.VOLTAGE, p.gear[i], p.Jm[i], p.friction[i],
                                  p.Kt[i], p.Kv[i], p.R[i]))
    parameters = tuple(Parameter(s, Fraction(int(v.p), int(v.q)), "", str(s), str(s)) for s, v in p.values)
    return Chain(tuple(joints), tuple(bodies), sp.ImmutableMatrix([0, -p.g, 0]), parameters,
                 actuators=tuple(actuators))
