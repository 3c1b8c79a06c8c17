"""The drives of an arm's joints: ``[[motor]]`` tables -> :class:`Motor` and :class:`Actuator`.

Every joint i has one drive, with input u_i (eq. 12: J theta'' + G = B (u + d)):

* ``actuation = "voltage"`` (the paper's DC motor, armature inductance
  neglected, section 5.1): tau_i = gr Kt (u_i - gr Kv theta_i') / Ra, so
  B_ii = gr Kt / Ra and the back-EMF adds gr^2 Kt Kv / Ra to the damping;
  u_i in V.
* ``actuation = "torque"`` (section 4.1 allows u to be a torque; a
  torque-controlled arm such as the Panda): tau_i = gr u_i, B_ii = gr, no
  back-EMF; u_i is the motor torque in N m (the joint torque when gr = 1).

Both add the joint's viscous friction bv to the damping and reflect the rotor
inertia Jm onto J_ii as gr^2 Jm (the rotor's gyroscopic coupling with the
carrying link is neglected). Each joint's
:class:`~derive.model.chain.Actuator` (in :attr:`Chain.actuators`) holds its
parameter symbols; :func:`terms` gives B_ii, the damping and gr^2 Jm.
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import sympy as sp

from derive.model.chain import Actuation, Actuator, Parameter
from derive.model.fields import NONNEGATIVE, POSITIVE, Num, Reader, domain

_ZERO = Fraction(0)


@dataclass(frozen=True)
class Motor:
    """One ``[[motor]]`` table as read (exact values; None: not given / not used).

    Voltage actuation: tau = gear Kt (V - gear Kv dtheta) / R (eq. 11-12 with
    voltage input); torque actuation: tau = gear u.
    """

    torque_constant: Fraction | None
    voltage_constant: Fraction | None
    resistance: Fraction | None
    gear_ratio: Fraction
    rotor_inertia: Fraction
    voltage_limit: Fraction | None
    actuation: Actuation = Actuation.VOLTAGE
    torque_limit: Fraction | None = None
    viscous_friction: Fraction | None = None   # of the joint, for arms without [[link]] tables

    @property
    def input_limit(self) -> Fraction | None:
        """The bound on |u| (V for voltage, N m for torque actuation), None: none."""
        return self.voltage_limit if self.actuation is Actuation.VOLTAGE else self.torque_limit


def input_unit(motor: Motor, prismatic: bool = False) -> str:
    """The unit of u_i, of the disturbance d_i (B (u + d), eq. 12) and of the input limit: "V" for
    voltage actuation, "N m" for torque actuation ("N" on a prismatic joint)."""
    if motor.actuation is Actuation.VOLTAGE:
        return "V"
    return "N" if prismatic else "N m"


def units_text(units) -> str:
    """One unit for a list of per-joint units: the unit when they agree, else "V or N m (per motor)"."""
    kinds = list(dict.fromkeys(units))
    return kinds[0] if len(kinds) == 1 else " or ".join(kinds) + " (per motor)"


def input_word(units) -> str:
    """"voltage", "torque" or "input" (mixed or forces) for per-joint input units."""
    kinds = set(units)
    return "voltage" if kinds == {"V"} else "torque" if kinds == {"N m"} else "input"


def terms(act: Actuator) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """(B_ii, damping, reflected rotor inertia) of one drive (eq. 12; module docstring)."""
    gr = act.gear_ratio
    if act.actuation is Actuation.VOLTAGE:
        kt, kv, ra = act.torque_constant, act.voltage_constant, act.resistance
        return gr * kt / ra, gr ** 2 * kt * kv / ra + act.viscous_friction, gr ** 2 * act.rotor_inertia
    return gr, act.viscous_friction, gr ** 2 * act.rotor_inertia


def _sym(name: str, **assumptions: bool) -> sp.Symbol:
    return sp.Symbol(name, **assumptions)


def actuator(i: int, motor: Motor, friction: Fraction, friction_field: str,
             friction_doc: str = "") -> tuple[Actuator, tuple[Parameter, ...]]:
    """Joint i's (1-based) actuator and its parameters, named as the generated code
    names them (Kt1, Kv1, Ra1, gr1, Jm1, bv1). The bound on |u_i| stays on the
    Motor (:attr:`Motor.input_limit`)."""
    f = f"motor[{i}]"

    def param(name: str, value: Fraction, unit: str, field: str, doc: str, num: Num) -> Parameter:
        return Parameter(_sym(f"{name}{i}", **domain(num)), value, unit, field, doc)

    gr = param("gr", motor.gear_ratio, "", f"{f}.gear_ratio", f"gear ratio of motor {i}", GEAR)
    Jm = param("Jm", motor.rotor_inertia, "kg m^2", f"{f}.rotor_inertia", f"rotor inertia of motor {i}", ROTOR)
    bv = param("bv", friction, "N m s/rad", friction_field, friction_doc or f"viscous friction of joint {i}", FRICTION)
    if motor.actuation is Actuation.VOLTAGE:
        Kt = param("Kt", motor.torque_constant, "N m/A", f"{f}.torque_constant", f"torque constant of motor {i}", KT)
        Kv = param("Kv", motor.voltage_constant, "V s/rad", f"{f}.voltage_constant",
                   f"voltage constant of motor {i}", KV)
        Ra = param("Ra", motor.resistance, "ohm", f"{f}.resistance", f"armature resistance of motor {i}", RA)
        act = Actuator(Actuation.VOLTAGE, gr.symbol, Jm.symbol, bv.symbol, Kt.symbol, Kv.symbol, Ra.symbol)
        return act, (Kt, Kv, Ra, gr, Jm, bv)
    return Actuator(Actuation.TORQUE, gr.symbol, Jm.symbol, bv.symbol), (gr, Jm, bv)


# -- reading [[motor]] ----------------------------------------------------------------------

ACTUATION_EXPECTED = "'voltage' (a DC motor, u in V) or 'torque' (u a motor torque in N m)"
VOLTAGE_KEYS = {"torque_constant": POSITIVE["N m/A"].expected, "voltage_constant": NONNEGATIVE["V s/rad"].expected,
                "resistance": POSITIVE["ohm"].expected, "gear_ratio": None, "rotor_inertia": None,
                "voltage_limit": None, "actuation": None}
TORQUE_KEYS = {"gear_ratio": None, "rotor_inertia": None, "torque_limit": None, "actuation": None}
_TORQUE_LIMIT = Num("N m", _ZERO, True)
# What each field accepts: the reader checks it, and its parameter's symbol has that domain (fields.domain)
GEAR, ROTOR, FRICTION = POSITIVE[""], NONNEGATIVE["kg m^2"], NONNEGATIVE["N m s/rad"]
KT, KV, RA = POSITIVE["N m/A"], NONNEGATIVE["V s/rad"], POSITIVE["ohm"]


def actuation_value(r: Reader, value: Any, field: str, default: Actuation) -> Actuation:
    if value is None:
        return default
    try:
        return Actuation(value)
    except (ValueError, TypeError):
        r.bad(field, ACTUATION_EXPECTED, value)
        return default


def read_motor(r: Reader, entry: Any, i: int, default: Actuation, joint_friction: bool) -> Motor:
    """One ``[[motor]]`` table; ``joint_friction``: the table may hold the joint's
    viscous_friction (arms whose joints have no [[link]] table)."""
    f = f"motor[{i}]"
    kind = actuation_value(r, entry.get("actuation") if isinstance(entry, dict) else None,
                           f"{f}.actuation", default)
    keys = dict(VOLTAGE_KEYS if kind is Actuation.VOLTAGE else TORQUE_KEYS)
    if joint_friction:
        keys["viscous_friction"] = None
    d = r.table(entry, f, keys, "a table") or {}
    friction = r.number(d, "viscous_friction", f, FRICTION) if joint_friction else None
    gear = r.number(d, "gear_ratio", f, GEAR, Fraction(1))
    rotor = r.number(d, "rotor_inertia", f, ROTOR, _ZERO)
    if kind is Actuation.TORQUE:
        return Motor(None, None, None, gear, rotor, None, kind,
                     r.number(d, "torque_limit", f, _TORQUE_LIMIT), friction)
    return Motor(torque_constant=r.number(d, "torque_constant", f, KT),
                 voltage_constant=r.number(d, "voltage_constant", f, KV),
                 resistance=r.number(d, "resistance", f, RA),
                 gear_ratio=gear, rotor_inertia=rotor,
                 voltage_limit=r.number(d, "voltage_limit", f, POSITIVE["V"]), actuation=kind,
                 viscous_friction=friction)


def read_motors(r: Reader, value: Any, n: int | None, default: Actuation, joint_friction: bool,
                joints: str = "[[link]]") -> list[Motor]:
    """The ``[[motor]]`` tables, one per joint. Torque-actuated arms may leave
    them out: then every joint has gear ratio 1, no rotor inertia and no limit."""
    if value is None:
        if default is Actuation.TORQUE:   # n None: the joints are unknown after another problem
            return [Motor(None, None, None, Fraction(1), _ZERO, None, Actuation.TORQUE) for _ in range(n or 0)]
        r.add("motor", f"one [[motor]] table per joint (voltage actuation; 'actuation = \"torque\"' "
              "under [arm] makes them optional)", "nothing (the key is missing)")
        return []
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        r.bad("motor", "an array of tables ([[motor]] sections)", value)
        return []
    if n is not None and len(value) != n:
        r.add("motor", f"one [[motor]] table per joint: {n}, as many as {joints}",
              f"{len(value)} [[motor]] table{'' if len(value) == 1 else 's'}")
    return [read_motor(r, entry, i, default, joint_friction) for i, entry in enumerate(value, 1)]

