"""The ``[simulation]`` section of an arm file: what the plant has that the
controller does not know, and how the paper's experiment (section 5) is run.

Defaults (every key optional):

==================  =====================  ===========================================
key                 default                meaning
==================  =====================  ===========================================
duration            30.0                   simulated time [s]
sample_time         0.002                  controller sample time [s]
substeps            4                      RK4 steps of the plant per sample
pulse_period        30.0                   period of the reference pulse train [s]
amplitude_deg       90.0                   pulse amplitude (section 5.2) [deg], every joint
amplitude           [amplitude_deg, ...]   pulse amplitude per joint in the joint's unit [rad; m
                                           prismatic], instead of amplitude_deg (not both)
start               [0, 5, 10, ...]        when each link's pulse train starts [s]
coulomb_friction    [0.05, 0.01, ...]      Coulomb friction per joint [N m], the smooth law
                                           tau_c tanh(theta'/eps) (derive.sim.plant)
coulomb_smoothing   [0.01, ...]            eps of that law per joint [rad/s; m/s prismatic], finite
                                           > 0: an array of n, or one number for every joint
viscous_friction    [0.01, 0.002, ...]     extra viscous friction per joint [N m s/rad]
payload_scale       1.2                    mass factor of the last link's point masses
payload_mass        0.0                    a rigid payload on the tip [kg], finite >= 0: the plant's
                                           J + J_p, G + G_p (eq. 12), never the controller's model
payload_com         [payload] com, or      the payload's centre of mass [m] in the tip link's
                    [0, 0, 0]              frame, |payload_com| <= 2 m; its inertia about it: the
                                           [payload] table's shape at payload_mass, else a solid
                                           sphere of 5 cm radius (derive.sim.plant.payload_values)
disturbance         [0.3, 0.1, ...]        unknown constant input disturbance d [V; N m in torque mode] (eq. 12)
velocity_noise      [0, ...]               tachometer noise std [rad/s]
position_noise      [0, ...]               potentiometer noise std [rad]
tacho_filter_hz     0.0                    first-order low-pass on theta-dot, 0 = none
initial_theta       [0, ...]               the arm's initial joint angles [rad] (at rest)
reference_start     "zero"                 where y_d starts: "zero" (section 5.2) or "measured":
                                           y_d(0) = C theta(0), the pulse train an offset added to it
seed                1                      noise seed
link_mass_scale     [1, ...]               mass factor of each link (its inertia scales too)
torque_constant_scale   [1, ...]           factor on each motor's torque constant
voltage_constant_scale  [1, ...]           factor on each motor's voltage constant
resistance_scale    [1, ...]               factor on each motor's resistance
mujoco_model        ""                     the MJCF (or URDF) MuJoCo integrates under
                                           ``--plant mujoco``, relative to the arm file;
                                           "" = the arm's own URDF or MJCF (derive.sim.mujoco)
mujoco_contacts     false                  MuJoCo's contacts between an MJCF's primitive
                                           geoms under ``--plant mujoco`` (default: off)
==================  =====================  ===========================================

The default friction makes the predictive controller's steady-state error
plain to see (the paper names friction as the main cause of MPC's poor tracking);
the default mismatch is a 20% heavier tip and an unknown constant input
disturbance (an amplifier offset: the theory's assumption, eq. 12 and 40). Voltage limits are the motors'
``voltage_limit``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from derive.errors import Problem


@dataclass(frozen=True)
class SimSettings:
    """Simulation settings (see module docstring for units and defaults)."""

    duration: float = 30.0
    sample_time: float = 0.002
    substeps: int = 4
    pulse_period: float = 30.0
    amplitude_deg: float = 90.0
    amplitude: tuple[float, ...] = ()   # per joint [rad, m prismatic]; () = amplitude_deg for every joint
    start: tuple[float, ...] = ()
    coulomb_friction: tuple[float, ...] = ()
    coulomb_smoothing: tuple[float, ...] = ()   # rad/s (m/s prismatic) per joint; () = COULOMB_SMOOTHING each
    viscous_friction: tuple[float, ...] = ()
    payload_scale: float = 1.2
    payload_mass: float = 0.0        # kg: a rigid payload on the tip link (derive.sim.plant)
    payload_com: tuple[float, ...] = ()   # m, tip link's frame (3); () = the [payload] table's com, else 0
    disturbance: tuple[float, ...] = ()
    velocity_noise: tuple[float, ...] = ()
    position_noise: tuple[float, ...] = ()
    tacho_filter_hz: float = 0.0
    seed: int = 1
    initial_theta: tuple[float, ...] = ()
    link_mass_scale: tuple[float, ...] = ()
    torque_constant_scale: tuple[float, ...] = ()
    voltage_constant_scale: tuple[float, ...] = ()
    resistance_scale: tuple[float, ...] = ()
    reference_start: str = "zero"   # "zero" or "measured" (derive.sim.start)
    mujoco_model: str = ""           # the file MuJoCo integrates under --plant mujoco (derive.sim.mujoco)
    mujoco_contacts: bool = False    # MuJoCo's contacts between an MJCF's primitive geoms (derive.sim.mujoco)


COULOMB_SMOOTHING = 0.01   # rad/s (m/s prismatic): the default width eps of tau_c tanh(theta'/eps)
REFERENCE_STARTS = ("zero", "measured")   # simulation.reference_start (derive.sim.start)
MAX_PAYLOAD_REACH = 2.0   # m: |payload_com| at most this (a payload 2 m off the flange is a typing error)


def pulse_amplitudes(s: SimSettings, n: int) -> tuple[float, ...]:
    """Each joint's pulse amplitude (n) in its own unit [rad, m prismatic]: ``amplitude``, else
    ``amplitude_deg`` in radians for every joint (a prismatic joint reads that number in metres)."""
    return s.amplitude if s.amplitude else (math.radians(s.amplitude_deg),) * n


def coulomb_widths(s: SimSettings, n: int) -> tuple[float, ...]:
    """Each joint's width eps [rad/s; m/s prismatic] of the smooth Coulomb law tau_c tanh(theta'/eps)
    (n): ``coulomb_smoothing``, else COULOMB_SMOOTHING for every joint."""
    return s.coulomb_smoothing if s.coulomb_smoothing else (COULOMB_SMOOTHING,) * n


def default_settings(n: int) -> SimSettings:
    """Defaults for an n-joint arm."""
    return SimSettings(start=tuple(5.0 * i for i in range(n)),
                       coulomb_friction=tuple(0.05 if i == 0 else 0.01 for i in range(n)),
                       coulomb_smoothing=(COULOMB_SMOOTHING,) * n,
                       viscous_friction=tuple(0.01 if i == 0 else 0.002 for i in range(n)),
                       disturbance=tuple(0.3 if i == 0 else 0.1 for i in range(n)), velocity_noise=(0.0,) * n,
                       position_noise=(0.0,) * n, initial_theta=(0.0,) * n, link_mass_scale=(1.0,) * n,
                       torque_constant_scale=(1.0,) * n, voltage_constant_scale=(1.0,) * n,
                       resistance_scale=(1.0,) * n)


_SCALARS = {"duration": (0.0, True), "sample_time": (0.0, True), "pulse_period": (0.0, True),
            "amplitude_deg": (None, False), "payload_scale": (0.0, False), "tacho_filter_hz": (0.0, False),
            "payload_mass": (0.0, False)}
_VECTORS = {"start": 0.0, "coulomb_friction": 0.0, "viscous_friction": 0.0, "disturbance": None, "amplitude": None,
            "velocity_noise": 0.0, "position_noise": 0.0, "initial_theta": None, "link_mass_scale": 0.0,
            "torque_constant_scale": 0.0, "voltage_constant_scale": 0.0, "resistance_scale": 0.0}
_POSITIVE = {"link_mass_scale", "torque_constant_scale", "resistance_scale"}  # factors that must stay > 0
# Every key of a [simulation] table (the reader rejects any other; derive.model.keydocs documents each)
KEYS = frozenset(_SCALARS) | frozenset(_VECTORS) | {"substeps", "seed", "reference_start", "mujoco_model",
                                                    "mujoco_contacts", "payload_com", "coulomb_smoothing"}


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _payload_com(v: Any, problems: list[Problem]) -> tuple[float, float, float] | None:
    """``payload_com``: 3 finite numbers [m] within MAX_PAYLOAD_REACH of the tip frame's origin."""
    field = "simulation.payload_com"
    if not (isinstance(v, list) and len(v) == 3 and all(_finite(x) for x in v)):
        problems.append(Problem(field, "an array of 3 finite numbers [m]: the payload's centre of mass in the tip "
                                "link's frame", repr(v)[:60]))
        return None
    reach = math.sqrt(sum(float(x) ** 2 for x in v))
    if reach > MAX_PAYLOAD_REACH:
        problems.append(Problem(field, f"a centre of mass within {MAX_PAYLOAD_REACH:g} m of the tip link's origin "
                                f"(|payload_com| <= {MAX_PAYLOAD_REACH:g} m)", f"{repr(v)[:60]} (|payload_com| = "
                                f"{reach:g} m)"))
        return None
    return tuple(float(x) for x in v)


def _coulomb_smoothing(v: Any, n: int, problems: list[Problem]) -> tuple[float, ...] | None:
    """``coulomb_smoothing``: one finite number > 0 for every joint, or an array of n of them."""
    values = [v] * n if _finite(v) else v
    if isinstance(values, list) and len(values) == n and all(_finite(x) and x > 0 for x in values):
        return tuple(float(x) for x in values)
    problems.append(Problem("simulation.coulomb_smoothing", f"a finite number > 0 [rad/s; m/s prismatic] for every "
                            f"joint, or an array of {n} of them: the width eps of tau_c tanh(theta'/eps)",
                            repr(v)[:60]))
    return None


def parse_simulation(table: Any, n: int) -> tuple[SimSettings, list[Problem]]:
    """Settings from a ``[simulation]`` table, and every problem found in it."""
    base = default_settings(n)
    problems: list[Problem] = []
    if table is None:
        return base, problems
    if not isinstance(table, dict):
        return base, [Problem("simulation", "a table", repr(table)[:60])]
    allowed = set(KEYS)
    values: dict[str, Any] = {}
    for key in sorted(set(table) - allowed):
        problems.append(Problem(f"simulation.{key}", f"no such key (allowed: {', '.join(sorted(allowed))})",
                                "<present>"))
    for key, (low, strict) in _SCALARS.items():
        if key in table:
            v = table[key]
            bound = "" if low is None else f" {'>' if strict else '>='} {low:g}"
            if not _finite(v) or (low is not None and (v < low or (strict and v == low))):
                problems.append(Problem(f"simulation.{key}", f"a finite number{bound}", repr(v)[:60]))
            else:
                values[key] = float(v)
    for key in ("substeps", "seed"):
        if key in table:
            v = table[key]
            if not isinstance(v, int) or isinstance(v, bool) or v < (1 if key == "substeps" else 0):
                problems.append(Problem(f"simulation.{key}", "a whole number >= 1" if key == "substeps"
                                        else "a whole number >= 0", repr(v)[:60]))
            else:
                values[key] = v
    if "mujoco_model" in table:
        v = table["mujoco_model"]
        if not isinstance(v, str) or not v.strip() or any(not c.isprintable() for c in v):
            problems.append(Problem("simulation.mujoco_model", "the path of an MJCF or URDF file (relative to "
                                    "the arm file), one line of printable text", repr(v)[:60]))
        else:
            values["mujoco_model"] = v
    if "mujoco_contacts" in table:
        v = table["mujoco_contacts"]
        if not isinstance(v, bool):
            problems.append(Problem("simulation.mujoco_contacts", "true (MuJoCo's contacts between the MJCF's "
                                    "primitive geoms, with --mujoco-friction file) or false (none, the default)",
                                    repr(v)[:60]))
        else:
            values["mujoco_contacts"] = v
    for key, low in _VECTORS.items():
        if key in table:
            v = table[key]
            ok = isinstance(v, list) and len(v) == n and all(_finite(x) for x in v)
            if ok and low is not None:
                ok = all(x > low if key in _POSITIVE else x >= low for x in v)
            if not ok:
                bound = "" if low is None else f" {'>' if key in _POSITIVE else '>='} {low:g}"
                problems.append(Problem(f"simulation.{key}", f"an array of {n} finite numbers{bound}",
                                        repr(v)[:60]))
            else:
                values[key] = tuple(float(x) for x in v)
    if "reference_start" in table:
        v = table["reference_start"]
        if v not in REFERENCE_STARTS:
            problems.append(Problem("simulation.reference_start", "\"zero\" (y_d starts at 0, section 5.2) or "
                                    "\"measured\" (y_d starts at the initial pose C theta(0), the pulse train added "
                                    "to it)", repr(v)[:60]))
        else:
            values["reference_start"] = v
    if "coulomb_smoothing" in table:
        widths = _coulomb_smoothing(table["coulomb_smoothing"], n, problems)
        if widths is not None:
            values["coulomb_smoothing"] = widths
    if "payload_com" in table:
        com = _payload_com(table["payload_com"], problems)
        if com is not None:
            values["payload_com"] = com
    if "amplitude" in table and "amplitude_deg" in table:
        problems.append(Problem("simulation.amplitude", "either amplitude (per joint, rad or m) or amplitude_deg "
                                "(every joint, deg), not both", "both"))
    duration = values.get("duration", base.duration)
    sample = values.get("sample_time", base.sample_time)
    if sample >= duration and "sample_time" in values:
        problems.append(Problem("simulation.sample_time", f"less than duration = {duration:g} s", repr(sample)))
    return (replace(base, **values) if not problems else base), problems
