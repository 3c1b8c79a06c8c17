"""Plausibility of a valid arm: values an engineer would query (issue 15 item 6).

A valid arm file can still hold a unit mistake: ``length = 350`` (millimetres written as
metres), a 250 kg gripper (grams as kilograms), ``rotor_inertia = 10.0`` (kg cm^2 as
kg m^2), a centre of mass or a point mass beyond the end of its link. None of these is
impossible, so none is a :class:`~derive.errors.SpecError` of :func:`derive.model.spec.load_arm`;
:func:`plausibility` lists them as :class:`~derive.errors.Problem` (field, the rule as what
was expected, the value given). The command line prints each as one
``derive: warning: <field>: expected ..., got ...`` line, and ``--strict`` makes them one
exit-2 error. Designs that are odd but real stay silent: a counterweight behind the joint
(a negative ``com`` or ``distance`` down to minus the link's length), a massless tube
carrying a tool, gear ratios below 1.

The rules (each message names its rule by the bound it states):

===============================  ===========================================  ==========================
rule                             bound                                        typical mistake
===============================  ===========================================  ==========================
length                           every length, distance, offset |x| <= 10 m   mm written as m
mass                             every mass <= 1000 kg                        g written as kg
point mass vs the rest           <= 20 x the rest of the arm's mass           g written as kg
centre of mass, point mass       -l <= com, distance <= l (l: its link)       a wrong link, mm vs m
link / point-mass inertia        <= m l^2 about its centre (l: its link)      kg cm^2 written as kg m^2
rotor inertia                    Jm <= 0.1 kg m^2                             kg cm^2 or g cm^2 as kg m^2
drive inertia (torque, gear 1)   Jm <= 0.1 kg m^2 x 100^2 = 1000 kg m^2       kg cm^2 or g cm^2 as kg m^2
resistance                       1 mOhm <= R <= 1 kOhm                        mOhm written as Ohm
gear ratio                       1/100 <= gear ratio <= 10000                 a ratio of teeth or speeds
torque vs voltage constant       1/2 <= Kt / Kv <= 2 (equal in SI units)      Kv in V/krpm or rpm/V
voltage limit                    <= 1000 V                                    mV written as V
gravity                          g <= 20 m/s^2                                cm/s^2 written as m/s^2
revolute joint range             |lower|, |upper| <= 4 pi rad                 degrees written as radians
prismatic joint travel           |lower|, |upper| <= 10 m                     mm written as m
joint velocity limit             <= 50 rad/s (10 m/s prismatic)               deg/s or rpm as rad/s
controller.max_joint_speed       <= 50 rad/s                                  deg/s or rpm as rad/s
===============================  ===========================================  ==========================

A torque-actuated motor with gear ratio 1 (what ``derive init`` writes for a URDF: u is the joint
torque) models the drive at the joint: its ``rotor_inertia`` is the whole drive's reflected inertia
gr^2 Jm, which ``derive identify`` writes there, 0.1-2 kg m^2 for a harmonic-drive arm such as the
Schunk LWA 4P. Its bound is that of a 0.1 kg m^2 rotor behind a 100:1 gear.

The last four are the ranges the operating-point grids cover (the observer certificate's box, the
sample-time analysis, derive.control.sampling.grid): a range in the wrong unit would put the grids, and
the guarantees stated over them, far from the arm's real motion.
"""
from __future__ import annotations

from fractions import Fraction
from typing import TYPE_CHECKING

import sympy as sp

from derive.errors import Problem
from derive.model.actuators import Motor
from derive.model.chain import Actuation
from derive.model.fields import fmt

if TYPE_CHECKING:
    from derive.model.spec import Arm

MAX_LENGTH = Fraction(10)            # m: no robot arm's link, offset or reach is longer
MAX_MASS = Fraction(1000)            # kg: heavier than the heaviest industrial arm's links
MAX_PAYLOAD_RATIO = Fraction(20)     # a point mass 20 times the rest of the arm
MAX_ROTOR_INERTIA = Fraction(1, 10)  # kg m^2: a large servo motor's rotor is about 1e-2
MAX_DRIVE_INERTIA = MAX_ROTOR_INERTIA * 100 ** 2   # kg m^2: reflected through a 100:1 gear (torque, gear ratio 1)
RESISTANCE = (Fraction(1, 1000), Fraction(1000))   # ohm
GEAR_RATIO = (Fraction(1, 100), Fraction(10000))
KT_OVER_KV = (Fraction(1, 2), Fraction(2))         # Kt [N m/A] = Kv [V s/rad] for an ideal DC motor
MAX_VOLTAGE = Fraction(1000)         # V
MAX_GRAVITY = Fraction(20)           # m/s^2: twice the Earth's
MAX_ANGLE = 4 * Fraction(355, 113)   # rad: two turns each way (4 pi, rounded up)
MAX_JOINT_SPEED = Fraction(50)       # rad/s: faster than any arm joint (direct-drive ones reach about 10-20)
MAX_TRAVEL_SPEED = Fraction(10)      # m/s


def plausibility(arm: Arm) -> tuple[Problem, ...]:
    """Every rule of the module docstring that ``arm`` breaks, in file order (empty: none).

    Each :class:`~derive.errors.Problem` names the field, the rule (``expected``, with the
    likely unit mistake) and the value given with its unit. Pure; never raises."""
    out: list[Problem] = []
    if arm.gravity > MAX_GRAVITY:
        out.append(Problem("arm.gravity", f"at most {fmt(MAX_GRAVITY)} m/s^2 (the Earth's is 9.81; "
                           "cm/s^2 written as m/s^2?)", f"{fmt(arm.gravity)} m/s^2"))
    out += _planar(arm) if arm.spatial is None else _spatial(arm)
    for i, v in enumerate(arm.controller.max_joint_speed or (), 1):
        if v > MAX_JOINT_SPEED:
            out.append(Problem(f"controller.max_joint_speed[{i}]", f"at most {fmt(MAX_JOINT_SPEED)} rad/s (no arm "
                               "joint is faster; deg/s or rpm written as rad/s?)", f"{fmt(v)} rad/s"))
    for i, motor in enumerate(arm.motors, 1):
        out += _motor(motor, f"motor[{i}]")
    return tuple(out)


def _planar(arm: Arm) -> list[Problem]:
    out: list[Problem] = []
    for i, link in enumerate(arm.links, 1):
        f, l = f"link[{i}]", link.length
        out += _length(f"{f}.length", l) + _mass(f"{f}.mass", link.mass)
        if not link.com_default:
            out += _length(f"{f}.com", link.com) or _along(f"{f}.com", "centre of mass", link.com, l)
        if not link.uniform_rod:
            out += _inertia(f"{f}.inertia", link.inertia, link.mass, l)
    total = sum((link.mass for link in arm.links), Fraction(0)) + sum((p.mass for p in arm.point_masses), Fraction(0))
    for k, p in enumerate(arm.point_masses, 1):
        f, l = f"point_mass[{k}]", arm.links[p.link].length
        out += _length(f"{f}.distance", p.distance) or _along(f"{f}.distance", "point mass", p.distance, l)
        heavy = _mass(f"{f}.mass", p.mass)
        rest = total - p.mass
        if not heavy and rest > 0 and p.mass > MAX_PAYLOAD_RATIO * rest:
            heavy = [Problem(f"{f}.mass", f"at most {fmt(MAX_PAYLOAD_RATIO)} times the rest of the arm "
                             f"({fmt(rest)} kg: links and other point masses; grams written as kg?)",
                             f"{fmt(p.mass)} kg")]
        out += heavy + _inertia(f"{f}.inertia", p.inertia, p.mass, l)
    return out


def _spatial(arm: Arm) -> list[Problem]:
    """DH and URDF arms: every mass and length parameter of the chain, and each joint's
    fixed offset from the previous joint (a DH row's a and d, a URDF ``<origin xyz>``)."""
    out: list[Problem] = []
    for p in arm.spatial.parameters:
        if p.unit == "kg":
            out += _mass(p.field, p.value)
        elif p.unit == "m":
            out += _length(p.field, p.value)
    for joint in arm.spatial.joints:
        out += _ranges(joint)
        offset = joint.origin.p
        if not offset.free_symbols:
            size = Fraction(repr(float(sp.sqrt((offset.T * offset)[0, 0]))))
            if size > MAX_LENGTH:
                out.append(Problem(f"{joint.field} origin", f"a joint at most {fmt(MAX_LENGTH)} m from the previous "
                                   "one (DH a and d, URDF <origin xyz>; millimetres written as metres?)",
                                   f"{fmt(size)} m"))
    return out


def _ranges(joint) -> list[Problem]:
    """A joint's stated range and velocity limit in their units (rad or m, rad/s or m/s)."""
    out: list[Problem] = []
    lim, rotates = joint.limits, joint.type.rotates
    for key, x in (("lower", lim.lower), ("upper", lim.upper)):
        if x is None:
            continue
        if rotates and abs(x) > MAX_ANGLE:
            out.append(Problem(f"{joint.field} <limit {key}>", "a joint angle within -4 pi ... 4 pi rad (two turns "
                               "each way; degrees written as radians?)", f"{fmt(x)} rad"))
        elif not rotates and abs(x) > MAX_LENGTH:
            out.append(Problem(f"{joint.field} <limit {key}>", f"a travel within -{fmt(MAX_LENGTH)} ... "
                               f"{fmt(MAX_LENGTH)} m (millimetres written as metres?)", f"{fmt(x)} m"))
    bound, unit = (MAX_JOINT_SPEED, "rad/s") if rotates else (MAX_TRAVEL_SPEED, "m/s")
    if lim.velocity is not None and lim.velocity > bound:
        out.append(Problem(f"{joint.field} <limit velocity>", f"at most {fmt(bound)} {unit} (no arm joint is "
                           f"faster; {'deg/s or rpm' if rotates else 'mm/s'} written as {unit}?)",
                           f"{fmt(lim.velocity)} {unit}"))
    return out


def _length(field: str, x: Fraction) -> list[Problem]:
    if abs(x) <= MAX_LENGTH:
        return []
    return [Problem(field, f"at most {fmt(MAX_LENGTH)} m in size (no robot link is longer; millimetres "
                    "written as metres?)", f"{fmt(x)} m")]


def _mass(field: str, m: Fraction) -> list[Problem]:
    if m <= MAX_MASS:
        return []
    return [Problem(field, f"at most {fmt(MAX_MASS)} kg (grams written as kilograms?)", f"{fmt(m)} kg")]


def _along(field: str, what: str, x: Fraction, l: Fraction) -> list[Problem]:
    """A position along a link of length l: within it, or behind the joint by at most l."""
    if -l <= x <= l:
        return []
    where = "beyond the end of" if x > l else "further behind the joint than the length of"
    return [Problem(field, f"a {what} on its link: between -{fmt(l)} m (a counterweight behind the joint) "
                    f"and the link's length {fmt(l)} m", f"{fmt(x)} m, {where} the link")]


def _inertia(field: str, inertia: Fraction, m: Fraction, l: Fraction) -> list[Problem]:
    """An inertia about the centre of mass above m l^2 (all the mass one link length away)."""
    bound = m * l * l
    if inertia <= bound:
        return []
    return [Problem(field, f"at most m l^2 = {fmt(bound)} kg m^2 about its centre (all its mass a link length "
                    "away; kg cm^2 written as kg m^2?)", f"{fmt(inertia)} kg m^2")]


def _motor(motor: Motor, f: str) -> list[Problem]:
    out: list[Problem] = []
    drive = motor.actuation is Actuation.TORQUE and motor.gear_ratio == 1
    if drive and motor.rotor_inertia > MAX_DRIVE_INERTIA:
        out.append(Problem(f"{f}.rotor_inertia", f"at most {fmt(MAX_DRIVE_INERTIA)} kg m^2 for a drive's reflected "
                           "inertia (torque actuation, gear ratio 1; kg cm^2 or g cm^2 written as kg m^2?)",
                           f"{fmt(motor.rotor_inertia)} kg m^2"))
    elif not drive and motor.rotor_inertia > MAX_ROTOR_INERTIA:
        out.append(Problem(f"{f}.rotor_inertia", f"at most {fmt(MAX_ROTOR_INERTIA)} kg m^2 for a motor's rotor "
                           "(kg cm^2 or g cm^2 written as kg m^2?)", f"{fmt(motor.rotor_inertia)} kg m^2"))
    low, high = GEAR_RATIO
    if not low <= motor.gear_ratio <= high:
        out.append(Problem(f"{f}.gear_ratio", f"a gear ratio between {fmt(low)} and {fmt(high)} (motor speed over "
                           "joint speed)", fmt(motor.gear_ratio)))
    if motor.actuation is not Actuation.VOLTAGE:
        return out
    low, high = RESISTANCE
    if motor.resistance is not None and not low <= motor.resistance <= high:
        out.append(Problem(f"{f}.resistance", f"an armature resistance between {fmt(low)} and {fmt(high)} ohm "
                           "(milliohms written as ohms?)", f"{fmt(motor.resistance)} ohm"))
    kt, kv = motor.torque_constant, motor.voltage_constant
    if kt and kv and not KT_OVER_KV[0] <= kt / kv <= KT_OVER_KV[1]:
        out.append(Problem(f"{f}.voltage_constant", f"close to the torque constant {fmt(kt)} N m/A (Kv in V s/rad "
                           "equals Kt in N m/A for a DC motor; within a factor 2; V/krpm or rpm/V written?)",
                           f"{fmt(kv)} V s/rad"))
    if motor.voltage_limit is not None and motor.voltage_limit > MAX_VOLTAGE:
        out.append(Problem(f"{f}.voltage_limit", f"at most {fmt(MAX_VOLTAGE)} V (millivolts written as volts?)",
                           f"{fmt(motor.voltage_limit)} V"))
    return out
