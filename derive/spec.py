"""Arm description: TOML file -> validated, typed, frozen :class:`Arm`.

Every number is kept exact as a :class:`fractions.Fraction` of the decimal the
file wrote (0.38 is 19/50, not the nearest double), so that symbolic identities
hold exactly and generated constants round once. Every problem in a file is
collected and reported in one :class:`SpecError`.

The model (see README, "Describing an arm"): a planar serial chain of n >= 1
revolute joints, angles relative to the previous link (eq. a6 uses theta_2 so);
gravity, when given, acts along -y of the base frame with theta = 0 along +x.
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

from .errors import Problem, SpecError
from .names import name_problem

DEFAULT_ARM = "glasgow_2link"
ARMS_DIR = Path(__file__).parent / "arms"

_FRACTION_STRING = re.compile(r"\s*[0-9]+(\.[0-9]+)?([eE][-+]?[0-9]+)?\s*/\s*[0-9]+(\.[0-9]+)?([eE][-+]?[0-9]+)?\s*\Z")
UNIFORM_ROD = "uniform_rod"


@dataclass(frozen=True)
class Link:
    """One link: length l, mass m, centre of mass at distance com from its joint
    along the link, inertia about the centre of mass, viscous joint friction."""

    length: Fraction
    mass: Fraction
    com: Fraction
    inertia: Fraction
    viscous_friction: Fraction


@dataclass(frozen=True)
class PointMass:
    """A point mass (a carried motor, a tip payload) on link ``link`` (0-based),
    at ``distance`` from that link's joint along the link."""

    link: int
    distance: Fraction
    mass: Fraction
    inertia: Fraction
    label: str


@dataclass(frozen=True)
class Motor:
    """A DC motor with armature inductance neglected:
    tau = gear Kt (V - gear Kv dtheta) / R (eq. 11-12 with voltage input)."""

    torque_constant: Fraction
    voltage_constant: Fraction
    resistance: Fraction
    gear_ratio: Fraction
    rotor_inertia: Fraction
    voltage_limit: Fraction | None


@dataclass(frozen=True)
class Controller:
    """Settings of the predictive controller (eq. 14-19) and observer (eq. 23-25)."""

    T1: Fraction
    T2: Fraction
    w: tuple[Fraction, ...]
    C: tuple[tuple[Fraction, ...], ...]
    max_joint_speed: tuple[Fraction, ...] | None


@dataclass(frozen=True)
class Arm:
    """A validated arm description."""

    name: str
    description: str
    gravity: Fraction
    links: tuple[Link, ...]
    point_masses: tuple[PointMass, ...]
    motors: tuple[Motor, ...]
    controller: Controller
    source: str

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.links)


def packaged_arms() -> tuple[str, ...]:
    """Names of the arm files shipped in ``derive/arms``."""
    return tuple(sorted(p.stem for p in ARMS_DIR.glob("*.toml")))


def resolve_arm_path(arm: str | Path | None) -> Path:
    """A path, or the name of a packaged arm, or None (the default arm)."""
    if arm is None:
        return ARMS_DIR / f"{DEFAULT_ARM}.toml"
    path = Path(arm)
    if path.suffix != ".toml" and str(arm) in packaged_arms():
        return ARMS_DIR / f"{arm}.toml"
    return path


def load_arm(path: str | Path | None = None) -> Arm:
    """Read and validate an arm file; None loads the packaged default arm.

    Raises SpecError listing every problem (a missing or unreadable file too).
    """
    file = resolve_arm_path(path)
    source = str(file)
    try:
        raw = file.read_bytes()
    except OSError as exc:
        raise SpecError(source, [Problem("file", "a readable arm file (TOML)",
                                         exc.strerror or type(exc).__name__)]) from None
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise SpecError(source, [Problem("file", "UTF-8 text", f"undecodable byte at {exc.start}")]) from None
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(source, [Problem("file", "valid TOML", str(exc))]) from None
    return arm_from_dict(data, source)


class _Reader:
    """Collects problems while reading a nested mapping."""

    def __init__(self) -> None:
        self.problems: list[Problem] = []

    def bad(self, field: str, expected: str, given: Any) -> None:
        shown = given if isinstance(given, str) and given.startswith("<") else _show(given)
        self.problems.append(Problem(field, expected, shown))

    def table(self, data: Any, field: str, allowed: set[str], required: set[str]) -> dict:
        if not isinstance(data, dict):
            self.bad(field, "a table", data)
            return {}
        for key in sorted(set(data) - allowed):
            self.bad(f"{field}.{key}" if field else key, f"no such key (allowed: {', '.join(sorted(allowed))})",
                     "<present>")
        for key in sorted(required - set(data)):
            self.bad(f"{field}.{key}" if field else key, "a value", "<missing>")
        return data

    def number(self, data: dict, key: str, field: str, *, default: Fraction | None = None,
               low: Fraction | None = None, strict: bool = False, optional: bool = False) -> Fraction | None:
        name = f"{field}.{key}"
        if key not in data:
            return default
        value = data[key]
        bound = ""
        if low is not None:
            bound = f" {'>' if strict else '>='} {_fmt(low)}"
        expected = f"a finite number{bound}"
        frac = _to_fraction(value)
        if frac is None:
            self.bad(name, expected, value)
            return None
        if low is not None and (frac < low or (strict and frac == low)):
            self.bad(name, expected, value)
            return None
        return frac

    def array(self, data: dict, key: str, field: str, length: int) -> list | None:
        if key not in data:
            return None
        value = data[key]
        if not isinstance(value, list) or len(value) != length:
            self.bad(f"{field}.{key}", f"an array of {length} numbers (one per joint)", value)
            return None
        return value


def _fmt(x: Fraction) -> str:
    return str(int(x)) if x.denominator == 1 else str(float(x))


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return f"boolean {str(value).lower()}"
    if isinstance(value, str):
        text = value if len(value) <= 60 else value[:60] + f"... ({len(value)} characters)"
        return f"string {text!r}"
    if isinstance(value, float) and not math.isfinite(value):
        return f"{value} (non-finite; TOML reads 1e400 as inf)"
    if isinstance(value, (dict, list)):
        return f"{type(value).__name__} {str(value)[:60]}"
    return repr(value)


def _to_fraction(value: Any) -> Fraction | None:
    """Exact value of a TOML number or a 'p/q' string; None if not a finite number."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int):
        return Fraction(value)
    if isinstance(value, float):
        return Fraction(repr(value)) if math.isfinite(value) else None
    if isinstance(value, str) and _FRACTION_STRING.match(value):
        num, den = (Fraction(part.strip()) for part in value.split("/"))
        return num / den if den != 0 else None
    return None


def arm_from_dict(data: Any, source: str = "<dict>") -> Arm:
    """Validate a parsed arm mapping; raise SpecError with every problem."""
    r = _Reader()
    top = r.table(data, "", {"arm", "link", "point_mass", "motor", "controller"},
                  {"arm", "link", "motor", "controller"})
    head = r.table(top.get("arm", {}), "arm", {"name", "description", "gravity"}, {"name"})
    name = head.get("name", "")
    why = name_problem(name)
    if why and "name" in head:
        r.problems.append(Problem("arm.name", why.split(", got ")[0], why.split(", got ", 1)[-1]))
    description = head.get("description", "")
    if not isinstance(description, str):
        r.bad("arm.description", "a string", description)
    gravity = r.number(head, "gravity", "arm", default=Fraction(0), low=Fraction(0))

    links = _links(r, top.get("link"))
    n = len(links)
    point_masses = _point_masses(r, top.get("point_mass", []), n)
    motors = _motors(r, top.get("motor"), n)
    controller = _controller(r, top.get("controller", {}), n)
    if r.problems:
        raise SpecError(source, r.problems)
    return Arm(name=name, description=description, gravity=gravity, links=tuple(links),
               point_masses=tuple(point_masses), motors=tuple(motors), controller=controller,
               source=source)


def _entries(r: _Reader, value: Any, field: str) -> list:
    if value is None:
        return []
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        r.bad(field, f"an array of tables ([[{field}]])", value)
        return []
    return value


def _links(r: _Reader, value: Any) -> list[Link]:
    entries = _entries(r, value, "link")
    if value is not None and not entries and not r.problems:
        r.bad("link", "at least one [[link]] (n >= 1 joints)", "<none>")
    links = []
    for i, entry in enumerate(entries):
        f = f"link[{i + 1}]"
        d = r.table(entry, f, {"length", "mass", "com", "inertia", "viscous_friction"}, {"length", "mass"})
        length = r.number(d, "length", f, low=Fraction(0), strict=True)
        mass = r.number(d, "mass", f, low=Fraction(0), strict=True)
        com = r.number(d, "com", f, default=length / 2 if length else None)
        inertia = None
        if d.get("inertia", UNIFORM_ROD) == UNIFORM_ROD:
            if mass is not None and length is not None:
                inertia = mass * length ** 2 / 12
        else:
            inertia = r.number(d, "inertia", f, low=Fraction(0))
            if inertia is None and "inertia" in d:
                r.problems[-1] = Problem(f"{f}.inertia", f"a finite number >= 0 or '{UNIFORM_ROD}'",
                                         r.problems[-1].given)
        friction = r.number(d, "viscous_friction", f, default=Fraction(0), low=Fraction(0))
        links.append(Link(length, mass, com, inertia, friction))
    return links


def _point_masses(r: _Reader, value: Any, n: int) -> list[PointMass]:
    out = []
    for i, entry in enumerate(_entries(r, value, "point_mass")):
        f = f"point_mass[{i + 1}]"
        d = r.table(entry, f, {"link", "distance", "mass", "inertia", "label"}, {"link", "distance", "mass"})
        link = d.get("link")
        if "link" in d and (not isinstance(link, int) or isinstance(link, bool) or not 1 <= link <= n):
            r.bad(f"{f}.link", f"a link number from 1 to {n}", link)
            link = None
        label = d.get("label", "")
        if not isinstance(label, str):
            r.bad(f"{f}.label", "a string", label)
        distance = r.number(d, "distance", f)
        mass = r.number(d, "mass", f, low=Fraction(0), strict=True)
        inertia = r.number(d, "inertia", f, default=Fraction(0), low=Fraction(0))
        out.append(PointMass((link or 1) - 1, distance, mass, inertia, label if isinstance(label, str) else ""))
    return out


def _motors(r: _Reader, value: Any, n: int) -> list[Motor]:
    entries = _entries(r, value, "motor")
    if value is not None and len(entries) != n and n:
        r.bad("motor", f"one [[motor]] per joint ({n})", f"{len(entries)}")
    out = []
    for i, entry in enumerate(entries):
        f = f"motor[{i + 1}]"
        d = r.table(entry, f, {"torque_constant", "voltage_constant", "resistance", "gear_ratio",
                               "rotor_inertia", "voltage_limit"},
                    {"torque_constant", "voltage_constant", "resistance"})
        zero = Fraction(0)
        out.append(Motor(
            torque_constant=r.number(d, "torque_constant", f, low=zero, strict=True),
            voltage_constant=r.number(d, "voltage_constant", f, low=zero),
            resistance=r.number(d, "resistance", f, low=zero, strict=True),
            gear_ratio=r.number(d, "gear_ratio", f, default=Fraction(1), low=zero, strict=True),
            rotor_inertia=r.number(d, "rotor_inertia", f, default=zero, low=zero),
            voltage_limit=r.number(d, "voltage_limit", f, low=zero, strict=True),
        ))
    return out


def _controller(r: _Reader, value: Any, n: int) -> Controller:
    f = "controller"
    d = r.table(value, f, {"T1", "T2", "w", "C", "max_joint_speed"}, {"T1", "T2", "w"})
    zero = Fraction(0)
    T1 = r.number(d, "T1", f, low=zero)
    T2 = r.number(d, "T2", f, low=zero, strict=True)
    if T1 is not None and T2 is not None and T1 >= T2:
        r.bad("controller.T2", f"T2 > T1 = {_fmt(T1)} (prediction horizon, eq. 14)", d["T2"])
    w = _numbers(r, d, "w", n)
    if w and None not in w:
        if w[0] <= 0:
            r.bad("controller.w[1]", "w1 > 0 (observer gain, eq. 26)", d["w"][0])
        for i in range(1, n):
            if w[i] < w[i - 1]:
                r.bad(f"controller.w[{i + 1}]", f"w{i + 1} >= w{i} = {_fmt(w[i - 1])} (eq. 26: w2 >= w1)",
                      d["w"][i])
    speeds = _numbers(r, d, "max_joint_speed", n, low=zero)
    C = _matrix(r, d.get("C"), n)
    return Controller(T1, T2, tuple(w or ()), C, tuple(speeds) if speeds else None)


def _numbers(r: _Reader, d: dict, key: str, n: int, low: Fraction | None = None) -> list | None:
    values = r.array(d, key, "controller", n)
    if values is None:
        return None
    out = [r.number({key: v}, key, "controller", low=low, strict=low is not None) for v in values]
    for i, v in enumerate(out):
        if v is None:  # name the element, not the array
            r.problems[-1] = Problem(f"controller.{key}[{i + 1}]", r.problems[-1].expected, r.problems[-1].given)
            break
    return out


def _matrix(r: _Reader, value: Any, n: int) -> tuple[tuple[Fraction, ...], ...]:
    identity = tuple(tuple(Fraction(int(i == j)) for j in range(n)) for i in range(n))
    if value is None:
        return identity
    rows = value if isinstance(value, list) and len(value) == n else None
    if rows is None or not all(isinstance(row, list) and len(row) == n for row in rows):
        r.bad("controller.C", f"an {n}x{n} array of numbers (output matrix, eq. 13)", value)
        return identity
    out = tuple(tuple(_to_fraction(x) for x in row) for row in rows)
    if any(x is None for row in out for x in row):
        r.bad("controller.C", "finite numbers in every entry", value)
        return identity
    import sympy  # local: the spec stays light for the common case of C = identity

    if sympy.Matrix(out).det() == 0:
        r.bad("controller.C", "a matrix of full rank (eq. 13)", value)
        return identity
    return out
