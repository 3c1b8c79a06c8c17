"""Motor terms of eq. (11-12): input matrix B, damping and reflected inertia.

Per joint, from its :class:`derive.model.chain.Actuator` (a motor behind a
gear of ratio gr, joint torque = gr x motor torque; the formulas are
:func:`derive.model.actuators.terms`, the one definition of them):

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
from derive.model.actuators import terms
from derive.model.chain import Actuator


@dataclass(frozen=True)
class MotorTerms:
    """B (n x n, diagonal), damping (n x n, diagonal) and reflected (n entries)."""

    B: sp.Matrix
    damping: sp.Matrix
    reflected: tuple[sp.Expr, ...]


def motor_terms(actuators: Sequence[Actuator], n: int) -> MotorTerms:
    """The motor terms of n joints (each from :func:`derive.model.actuators.terms`);
    a DerivationError unless there is one actuator per joint."""
    if len(actuators) != n:
        raise DerivationError(f"the chain has {n} moving joints but {len(actuators)} actuators")
    gains, damping, reflected = zip(*(terms(a) for a in actuators))
    return MotorTerms(B=sp.diag(*gains), damping=sp.diag(*damping), reflected=tuple(reflected))
