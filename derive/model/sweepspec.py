"""The ``[sweep]`` section of an arm file: a Monte-Carlo robustness study of the
controllers under a distribution of plants (``derive sweep``).

```toml
[sweep]
samples = 200                 # default of --samples
seed = 1                      # every sample's draws come from (seed, sample index)
controllers = ["mpc", "dobc", "npid"]
duration = 30.0               # optional, default simulation.duration [s]

[sweep.vary]                  # what is drawn, one independent draw per joint for vectors
payload_scale = { distribution = "uniform", low = 0.7, high = 1.3 }
coulomb_friction = { distribution = "lognormal", median = 1.0, sigma = 0.4, low = 0.5, high = 2.0 }
disturbance = { distribution = "normal", mean = 0.0, sd = 0.2, low = -0.5, high = 0.5 }

[[sweep.criterion]]           # pass criteria: metric <= max (on every link, or on `link`)
metric = "steady_state_error"
max = 0.005
```

Parameters (each sets a ``[simulation]`` key of the sample, so a sample is rerun
by ``derive simulate`` with that ``[simulation]`` section):

====================== ====================================================== ==========
name                   drawn value                                            per
====================== ====================================================== ==========
payload_scale          mass factor of the last link's point masses            arm
payload_mass           a rigid payload on the tip [kg]                        arm
payload_com            its centre of mass [m], tip link's frame; low and high component
                       keep it within 2 m: sqrt(3) max(|low|, |high|) <= 2
link_mass              factor on each link's mass (and inertia)               link
coulomb_friction       factor on simulation.coulomb_friction                  joint
viscous_friction       factor on simulation.viscous_friction                  joint
disturbance            input disturbance d [V; N m if torque-driven] (eq. 12) joint
torque_constant        factor on the motor's torque constant                  joint
voltage_constant       factor on the motor's voltage constant                 joint
resistance             factor on the motor's resistance                       joint
velocity_noise         tachometer noise standard deviation [rad/s]            joint
position_noise         potentiometer noise standard deviation [rad]           joint
====================== ====================================================== ==========

Distributions: ``uniform`` (low, high), ``normal`` (mean, sd >= 0), ``lognormal``
(median > 0, sigma >= 0: median exp(sigma Z)); normal and lognormal take optional
bounds ``low``/``high`` (draws outside are drawn again: a truncated distribution).
"per": ``arm`` one draw; ``joint`` one independent draw per joint; ``component`` one per
component x, y, z (``payload_com = { distribution = "uniform", low = -0.05, high = 0.05 }``
draws each of the three independently from it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from derive.errors import Problem

METRICS = ("rms_error", "max_error", "steady_state_error", "control_effort", "saturated_time")
# parameter -> (simulation key it sets, "arm" (one value), "joint" (one per joint) or "component" (x, y, z),
# factor or value)
PARAMETERS: dict[str, tuple[str, str, bool]] = {
    "payload_scale": ("payload_scale", "arm", False),
    "payload_mass": ("payload_mass", "arm", False),
    "payload_com": ("payload_com", "component", False),
    "link_mass": ("link_mass_scale", "joint", False),
    "coulomb_friction": ("coulomb_friction", "joint", True),
    "viscous_friction": ("viscous_friction", "joint", True),
    "disturbance": ("disturbance", "joint", False),
    "torque_constant": ("torque_constant_scale", "joint", False),
    "voltage_constant": ("voltage_constant_scale", "joint", False),
    "resistance": ("resistance_scale", "joint", False),
    "velocity_noise": ("velocity_noise", "joint", False),
    "position_noise": ("position_noise", "joint", False),
}
# parameters whose drawn values must be > 0 (factors of physical constants) or >= 0 (noise, friction)
_POSITIVE = {"payload_scale", "link_mass", "torque_constant", "resistance"}
_NONNEGATIVE = {"payload_mass", "coulomb_friction", "viscous_friction", "voltage_constant", "velocity_noise", "position_noise"}
DISTRIBUTIONS = {"uniform": ("low", "high"), "normal": ("mean", "sd"), "lognormal": ("median", "sigma")}


@dataclass(frozen=True)
class Distribution:
    """One distribution: ``kind`` with its two parameters ``a``, ``b`` (see
    DISTRIBUTIONS) and optional truncation bounds."""

    kind: str
    a: float
    b: float
    low: float | None = None
    high: float | None = None


@dataclass(frozen=True)
class Criterion:
    """Pass when ``metric`` <= ``max`` on link ``link`` (1-based) or on every link (None)."""

    metric: str
    max: float
    link: int | None = None

    def label(self) -> str:
        where = "every link" if self.link is None else f"link {self.link}"
        return f"{self.metric} <= {self.max:g} on {where}"


@dataclass(frozen=True)
class SweepSpec:
    """A validated ``[sweep]`` section."""

    samples: int = 0
    seed: int = 1
    controllers: tuple[str, ...] = ("mpc", "dobc", "npid")
    vary: tuple[tuple[str, Distribution], ...] = ()
    criteria: tuple[Criterion, ...] = ()
    duration: float | None = None


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _distribution(name: str, v: Any, problems: list[Problem]) -> Distribution | None:
    field = f"sweep.vary.{name}"
    if not isinstance(v, dict):
        problems.append(Problem(field, "a table such as { distribution = \"uniform\", low = 0.5, high = 2.0 }",
                                repr(v)[:60]))
        return None
    kind = v.get("distribution")
    if kind not in DISTRIBUTIONS:
        problems.append(Problem(f"{field}.distribution", f"one of {', '.join(DISTRIBUTIONS)}", repr(kind)[:60]))
        return None
    a_key, b_key = DISTRIBUTIONS[kind]
    allowed = {"distribution", a_key, b_key} | ({"low", "high"} if kind != "uniform" else set())
    for key in sorted(set(v) - allowed):
        problems.append(Problem(f"{field}.{key}", f"no such key for {kind} (allowed: {', '.join(sorted(allowed))})",
                                "<present>"))
    values = {}
    for key in sorted(allowed - {"distribution"}):
        if key in v:
            if not _finite(v[key]):
                problems.append(Problem(f"{field}.{key}", "a finite number", repr(v[key])[:60]))
            else:
                values[key] = float(v[key])
        elif key in (a_key, b_key):
            problems.append(Problem(f"{field}.{key}", f"a number (the {kind} distribution needs {a_key} and {b_key})",
                                    "nothing"))
    if a_key not in values or b_key not in values:
        return None
    a, b = values[a_key], values[b_key]
    low, high = (a, b) if kind == "uniform" else (values.get("low"), values.get("high"))
    ok = True
    if kind in ("normal", "lognormal") and b < 0:
        problems.append(Problem(f"{field}.{b_key}", "a number >= 0", repr(b)))
        ok = False
    if kind == "lognormal" and a <= 0:
        problems.append(Problem(f"{field}.median", "a number > 0", repr(a)))
        ok = False
    if low is not None and high is not None and low > high:
        problems.append(Problem(f"{field}.low", f"at most high = {high:g}", repr(low)))
        ok = False
    if name in _POSITIVE | _NONNEGATIVE and kind != "lognormal":  # log-normal draws are > 0 anyway
        positive = name in _POSITIVE
        if low is None or (low <= 0 if positive else low < 0):
            need = "> 0" if positive else ">= 0"
            problems.append(Problem(f"{field}.low", f"a lower bound {need} ({name} cannot be "
                                    f"{'zero or negative' if positive else 'negative'})",
                                    "nothing" if low is None else repr(low)))
            ok = False
    if name == "payload_com" and ok:
        ok = _within_reach(field, kind, low, high, problems)
    return Distribution(kind, a, b, None if kind == "uniform" else low, None if kind == "uniform" else high) \
        if ok else None


def _within_reach(field: str, kind: str, low: float | None, high: float | None, problems: list[Problem]) -> bool:
    """payload_com's bounds keep every drawn centre of mass within MAX_PAYLOAD_REACH (the check
    of simulation.payload_com): sqrt(3) max(|low|, |high|) <= 2 m."""
    from derive.model.simspec import MAX_PAYLOAD_REACH

    if low is None or high is None:
        problems.append(Problem(f"{field}.{'low' if low is None else 'high'}", "bounds low and high on payload_com "
                                f"(each component; every drawn centre of mass within {MAX_PAYLOAD_REACH:g} m of the tip)",
                                "nothing"))
        return False
    reach = math.sqrt(3) * max(abs(low), abs(high))
    if reach > MAX_PAYLOAD_REACH:
        problems.append(Problem(f"{field}.{'low' if abs(low) >= abs(high) else 'high'}", f"bounds within "
                                f"{MAX_PAYLOAD_REACH / math.sqrt(3):.4g} m (sqrt(3) max(|low|, |high|) <= "
                                f"{MAX_PAYLOAD_REACH:g} m: every drawn centre of mass within {MAX_PAYLOAD_REACH:g} m "
                                f"of the tip, as simulation.payload_com)", f"low = {low:g}, high = {high:g} ({kind})"))
        return False
    return True


def parse_sweep(table: Any, n: int) -> tuple[SweepSpec | None, list[Problem]]:
    """The spec of a ``[sweep]`` table (None when absent), and every problem found in it."""
    if table is None:
        return None, []
    problems: list[Problem] = []
    if not isinstance(table, dict):
        return None, [Problem("sweep", "a table", repr(table)[:60])]
    allowed = {"samples", "seed", "controllers", "duration", "vary", "criterion"}
    for key in sorted(set(table) - allowed):
        problems.append(Problem(f"sweep.{key}", f"no such key (allowed: {', '.join(sorted(allowed))})", "<present>"))
    out: dict[str, Any] = {}
    for key, low in (("samples", 1), ("seed", 0)):
        if key in table:
            v = table[key]
            if not isinstance(v, int) or isinstance(v, bool) or v < low:
                problems.append(Problem(f"sweep.{key}", f"a whole number >= {low}", repr(v)[:60]))
            else:
                out[key] = v
    if "duration" in table:
        v = table["duration"]
        if not _finite(v) or v <= 0:
            problems.append(Problem("sweep.duration", "a finite number > 0 (s)", repr(v)[:60]))
        else:
            out["duration"] = float(v)
    if "controllers" in table:
        v = table["controllers"]
        if not (isinstance(v, list) and v and all(isinstance(c, str) for c in v)):
            problems.append(Problem("sweep.controllers", "a non-empty array of controller names", repr(v)[:60]))
        else:
            out["controllers"] = tuple(v)
    vary = table.get("vary", {})
    if not isinstance(vary, dict):
        problems.append(Problem("sweep.vary", "a table of parameter = { distribution = ... }", repr(vary)[:60]))
        vary = {}
    dists = []
    for name, v in vary.items():
        if name not in PARAMETERS:
            problems.append(Problem(f"sweep.vary.{name}", f"one of {', '.join(PARAMETERS)}", repr(name)))
            continue
        dist = _distribution(name, v, problems)
        if dist is not None:
            dists.append((name, dist))
    out["vary"] = tuple(dists)
    criteria = table.get("criterion", [])
    if not isinstance(criteria, list):
        problems.append(Problem("sweep.criterion", "an array of tables [[sweep.criterion]]", repr(criteria)[:60]))
        criteria = []
    parsed = []
    for i, c in enumerate(criteria):
        field = f"sweep.criterion[{i + 1}]"
        if not isinstance(c, dict):
            problems.append(Problem(field, "a table with metric and max", repr(c)[:60]))
            continue
        for key in sorted(set(c) - {"metric", "max", "link"}):
            problems.append(Problem(f"{field}.{key}", "no such key (allowed: link, max, metric)", "<present>"))
        metric, bound, link = c.get("metric"), c.get("max"), c.get("link")
        good = True
        if metric not in METRICS:
            problems.append(Problem(f"{field}.metric", f"one of {', '.join(METRICS)}", repr(metric)[:60]))
            good = False
        if not _finite(bound):
            problems.append(Problem(f"{field}.max", "a finite number", repr(bound)[:60]))
            good = False
        if link is not None and (not isinstance(link, int) or isinstance(link, bool) or not 1 <= link <= n):
            problems.append(Problem(f"{field}.link", f"a link number 1..{n}", repr(link)[:60]))
            good = False
        if good:
            parsed.append(Criterion(metric, float(bound), link))
    out["criteria"] = tuple(parsed)
    return (SweepSpec(**out) if not problems else None), problems
