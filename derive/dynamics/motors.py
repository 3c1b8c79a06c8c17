"""Motor terms of eq. (11-12): input matrix B, damping and reflected inertia.

Per joint, from its :class:`derive.model.chain.Actuator` (a motor behind a
gear of ratio gr, joint torque = gr x motor torque):

* voltage input (the paper's DC motor, inductance neglected): the motor
  torque is Kt (u - gr Kv q') / Ra, so B_ii = gr Kt / Ra and the damping is
  gr^2 Kt Kv / Ra + bv;
* torque input (section 4.1: u may be a torque): B_ii = gr, damping bv;
* both: the rotor's inertia Jm appears on the joint as gr^2 Jm on J's
  diagonal (the usual reflected inertia; the rotor's gyroscopic coupling with
  the link that carries it is neglected).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import sympy as sp

from derive.errors import DerivationError
from derive.model.chain import Actuation, Actuator


@dataclass(frozen=True)
class MotorTerms:
    """B (n x n, diagonal), damping (n x n, diagonal) and reflected (n entries)."""

    B: sp.Matrix
    damping: sp.Matrix
    reflected: tuple[sp.Expr, ...]


def _voltage_parts(i: int, act: Actuator) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    parts = (act.torque_constant, act.voltage_constant, act.resistance)
    if any(x is None for x in parts):
        raise DerivationError(f"joint {i + 1}: a voltage-driven actuator needs its torque constant, "
                              "voltage constant and resistance")
    return parts  # type: ignore[return-value]


def motor_terms(actuators: Sequence[Actuator], n: int) -> MotorTerms:
    """The motor terms of n joints; a DerivationError unless there is one actuator per joint."""
    if len(actuators) != n:
        raise DerivationError(f"the chain has {n} moving joints but {len(actuators)} actuators")
    gains, damping, reflected = [], [], []
    for i, act in enumerate(actuators):
        gr = act.gear_ratio
        if act.actuation is Actuation.VOLTAGE:
            Kt, Kv, Ra = _voltage_parts(i, act)
            gains.append(gr * Kt / Ra)
            damping.append(gr ** 2 * Kt * Kv / Ra + act.viscous_friction)
        else:
            gains.append(gr)
            damping.append(act.viscous_friction)
        reflected.append(gr ** 2 * act.rotor_inertia)
    return MotorTerms(B=sp.diag(*gains), damping=sp.diag(*damping), reflected=tuple(reflected))
