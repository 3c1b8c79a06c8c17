"""Arm description: TOML file -> validated, typed, frozen :class:`Arm`.

Every number is kept exact as a :class:`fractions.Fraction` of the decimal the
file wrote (0.38 is 19/50, not the nearest double), so that symbolic identities
hold exactly and generated constants round once. Numbers must be finite doubles
(TOML reads ``nan``, ``inf`` and ``1e400`` -> inf; none is accepted). Every
problem in a file is collected and reported in one :class:`SpecError`, each
naming the field (``link[2].mass``), the expected (``a finite number > 0 (kg)``)
and the given value (``-0.3``, ``string 'abc'``); unknown keys are problems too.

The model (see README, "Describing an arm"): a planar serial chain of n >= 1
revolute joints, angles relative to the previous link (eq. a6 uses theta_2 so);
gravity, when given, acts along -y of the base frame with theta = 0 along +x.
"""
from __future__ import annotations

import hashlib
import numbers
import tomllib
from dataclasses import dataclass, field, replace
from fractions import Fraction
from pathlib import Path
from typing import Any

from derive.errors import Problem, SpecError
from derive.model.fields import ANY, NONNEGATIVE, POSITIVE, TEXT_RULE, Num, Reader, fmt, inline, printable, show, text_problem
from derive.model.names import name_check
from derive.model.simspec import SimSettings, parse_simulation

DEFAULT_ARM = "glasgow_2link"
ARMS_DIR = Path(__file__).parent / "arms"
UNIFORM_ROD = "uniform_rod"
MAX_FILE_BYTES = 1 << 20   # an arm file is a few kB; never read /dev/zero whole
_MISSING = object()
_ZERO = Fraction(0)


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
    simulation: SimSettings = field(default_factory=SimSettings, compare=False)
    source_sha256: str = ""  # of the bytes validated (load_arm), recorded in MANIFEST.json

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.links)


def packaged_arms() -> tuple[str, ...]:
    """Names of the arm files shipped in ``derive/model/arms``."""
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

    Raises SpecError listing every problem (a missing, unreadable, oversized,
    non-UTF-8 or non-TOML file, or a file name unfit for generated comments, too).
    """
    file = resolve_arm_path(path)
    source = str(file)

    def fail(expected: str, given: str) -> SpecError:
        return SpecError(printable(source), [Problem("file", expected, given)])

    try:
        with open(file, "rb") as stream:
            raw = stream.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise fail("a readable arm file (TOML)", exc.strerror or type(exc).__name__) from None
    except ValueError as exc:  # a NUL byte in the path
        raise fail("a readable arm file (TOML)", f"an unusable path ({exc})") from None
    if len(raw) > MAX_FILE_BYTES:
        raise fail(f"an arm file of at most {MAX_FILE_BYTES} bytes", "a larger file")
    if (why := text_problem(file.name)) is not None:  # the name goes into generated comments
        raise fail(f"a file name that is {TEXT_RULE}", f"{inline(file.name)} ({why})")
    try:
        data = tomllib.loads(raw.decode("utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise fail("UTF-8 text", f"byte 0x{raw[exc.start]:02x} at offset {exc.start}") from None
    except tomllib.TOMLDecodeError as exc:
        raise fail("valid TOML", str(exc)) from None
    except RecursionError:
        raise fail("valid TOML", "arrays or tables nested too deeply to read") from None
    except ValueError as exc:  # an integer beyond Python's digit limit
        raise fail("valid TOML with numbers a double can hold", str(exc).split(";")[0]) from None
    return replace(arm_from_dict(data, source), source_sha256=hashlib.sha256(raw).hexdigest())


# -- the schema ---------------------------------------------------------------------------

LINK_INERTIA = Num("kg m^2, about the centre of mass", _ZERO, alternative=" or 'uniform_rod' (m l^2 / 12)")
TOP_KEYS = {"arm": "a table [arm] with at least a name", "link": "one [[link]] table per joint, base to tip",
            "point_mass": None, "motor": "one [[motor]] table per joint",
            "controller": "a table [controller] with T1, T2 and w", "simulation": None}
ARM_KEYS = {"name": "a lowercase C identifier (the prefix of the generated code)",
            "description": None, "gravity": None}
LINK_KEYS = {"length": POSITIVE["m"].expected, "mass": POSITIVE["kg"].expected, "com": None,
             "inertia": None, "viscous_friction": None}
PM_KEYS = {"link": "the number of the link that carries it", "distance": ANY["m"].expected,
           "mass": POSITIVE["kg"].expected, "inertia": None, "label": None}
MOTOR_KEYS = {"torque_constant": POSITIVE["N m/A"].expected, "voltage_constant": NONNEGATIVE["V s/rad"].expected,
              "resistance": POSITIVE["ohm"].expected, "gear_ratio": None, "rotor_inertia": None,
              "voltage_limit": None}
CONTROLLER_KEYS = {"T1": NONNEGATIVE["s"].expected, "T2": POSITIVE["s"].expected,
                   "w": "an array of observer gains, one per joint (eq. 25)", "C": None, "max_joint_speed": None}


def arm_from_dict(data: Any, source: str = "<dict>") -> Arm:
    """Validate a parsed arm mapping; raise SpecError with every problem."""
    r = Reader()
    if isinstance(data, dict):
        top = r.table(data, "", TOP_KEYS, "")
    else:
        r.bad("arm file", "a table of [arm], [[link]], [[motor]] and [controller]", data)
        top = {}
    name, description, gravity = _head(r, top.get("arm", _MISSING))
    links = _links(r, top.get("link", _MISSING))
    n = None if links is None else len(links)
    point_masses = _point_masses(r, top.get("point_mass", []), n)
    motors = _motors(r, top.get("motor", _MISSING), n)
    controller = _controller(r, top.get("controller", _MISSING), n)
    if links:
        _last_joint_inertia(r, links, point_masses, motors)
    simulation, sim_problems = parse_simulation(top.get("simulation"), n or 1)
    r.problems.extend(sim_problems if n else [])
    if r.problems:
        raise SpecError(printable(source), r.problems)
    return Arm(name=name, description=description, gravity=gravity, links=tuple(links),
               point_masses=tuple(point_masses), motors=tuple(motors), controller=controller, source=source,
               simulation=simulation)


def _head(r: Reader, value: Any) -> tuple[str, str, Fraction | None]:
    d = None if value is _MISSING else r.table(value, "arm", ARM_KEYS, "a table [arm] with at least a name")
    if d is None:
        return "", "", _ZERO
    name = d.get("name", "")
    if "name" in d and (found := name_check(name)):
        r.add("arm.name", found[0], found[1] if isinstance(name, str) else show(name))
    return name, r.text(d, "description", "arm"), r.number(d, "gravity", "arm", NONNEGATIVE["m/s^2"], _ZERO)


def _array_of_tables(r: Reader, value: Any, field: str) -> list | None:
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        r.bad(field, f"an array of tables ([[{field}]] sections)", value)
        return None
    return value


def _links(r: Reader, value: Any) -> list[Link] | None:
    """The links, or None when the number of joints is unknown."""
    if value is _MISSING or (entries := _array_of_tables(r, value, "link")) is None:
        return None
    if not entries:
        r.add("link", "at least one [[link]] table (n >= 1 joints)", "an empty array (0 links)")
        return None
    links = []
    for i, entry in enumerate(entries, 1):
        f = f"link[{i}]"
        d = r.table(entry, f, LINK_KEYS, "a table")
        length = r.number(d, "length", f, POSITIVE["m"])
        mass = r.number(d, "mass", f, POSITIVE["kg"])
        com = r.number(d, "com", f, ANY["m"], None if length is None else length / 2)
        rod = d.get("inertia", UNIFORM_ROD)
        if isinstance(rod, str) and rod == UNIFORM_ROD:
            inertia = None if mass is None or length is None else mass * length ** 2 / 12
        else:
            inertia = r.value(rod, f"{f}.inertia", LINK_INERTIA)
        friction = r.number(d, "viscous_friction", f, NONNEGATIVE["N m s/rad"], _ZERO)
        links.append(Link(length, mass, com, inertia, friction))
    return links


def _point_masses(r: Reader, value: Any, n: int | None) -> list[PointMass]:
    out = []
    for i, entry in enumerate(_array_of_tables(r, value, "point_mass") or [], 1):
        f = f"point_mass[{i}]"
        d = r.table(entry, f, PM_KEYS, "a table")
        link = d.get("link")
        ok = (isinstance(link, numbers.Integral) and not isinstance(link, bool)
              and 1 <= link <= (n if n is not None else link))
        if "link" in d and not ok:
            r.bad(f"{f}.link", f"a link number from 1 to {n}" if n else "a link number >= 1", link)
        out.append(PointMass(int(link) - 1 if ok else -1, r.number(d, "distance", f, ANY["m"]),
                             r.number(d, "mass", f, POSITIVE["kg"]),
                             r.number(d, "inertia", f, NONNEGATIVE["kg m^2"], _ZERO), r.text(d, "label", f)))
    return out


def _motors(r: Reader, value: Any, n: int | None) -> list[Motor]:
    if value is _MISSING or (entries := _array_of_tables(r, value, "motor")) is None:
        return []
    if n is not None and len(entries) != n:
        r.add("motor", f"one [[motor]] table per joint: {n}, as many as [[link]]",
              f"{len(entries)} [[motor]] table{'' if len(entries) == 1 else 's'}")
    out = []
    for i, entry in enumerate(entries, 1):
        f = f"motor[{i}]"
        d = r.table(entry, f, MOTOR_KEYS, "a table")
        out.append(Motor(
            torque_constant=r.number(d, "torque_constant", f, POSITIVE["N m/A"]),
            voltage_constant=r.number(d, "voltage_constant", f, NONNEGATIVE["V s/rad"]),
            resistance=r.number(d, "resistance", f, POSITIVE["ohm"]),
            gear_ratio=r.number(d, "gear_ratio", f, POSITIVE[""], Fraction(1)),
            rotor_inertia=r.number(d, "rotor_inertia", f, NONNEGATIVE["kg m^2"], _ZERO),
            voltage_limit=r.number(d, "voltage_limit", f, POSITIVE["V"])))
    return out


def _controller(r: Reader, value: Any, n: int | None) -> Controller | None:
    f = "controller"
    d = None if value is _MISSING else r.table(value, f, CONTROLLER_KEYS, "a table [controller] with T1, T2 and w")
    if d is None:
        return None
    T1, T2 = r.number(d, "T1", f, NONNEGATIVE["s"]), r.number(d, "T2", f, POSITIVE["s"])
    if T1 is not None and T2 is not None and T1 >= T2:
        shown = show(d["T2"]) + (f" (= {fmt(T2)})" if isinstance(d["T2"], str) else "")
        r.add("controller.T2", f"a number > T1 = {fmt(T1)} (s; the prediction horizon [T1, T2] of eq. 14)", shown)
    w = _vector(r, d, "w", n, ANY["1/s"])
    if w and None not in w:
        if w[0] <= 0:
            r.add("controller.w[1]", "w1 > 0 (observer gain, eq. 26)", show(d["w"][0]))
        for i in range(1, len(w)):
            if w[i] < w[i - 1]:
                r.add(f"controller.w[{i + 1}]", f"w{i + 1} >= w{i} = {fmt(w[i - 1])} "
                      "(eq. 26: nondecreasing observer gains)", show(d["w"][i]))
    speeds = _vector(r, d, "max_joint_speed", n, POSITIVE["rad/s"])
    C = _matrix(r, d.get("C"), n)
    if None in (T1, T2) or not w or None in w or (speeds and None in speeds):
        return None
    return Controller(T1, T2, tuple(w), C, tuple(speeds) if speeds else None)


def _vector(r: Reader, d: dict, key: str, n: int | None, num: Num) -> list | None:
    """An array of one number per joint (its entries named key[1], key[2], ...)."""
    if key not in d:
        return None
    value, field = d[key], f"controller.{key}"
    if not isinstance(value, list) or not value or (n is not None and len(value) != n):
        count = "n numbers" if n is None else f"{n} number{'' if n == 1 else 's'}"
        r.bad(field, f"an array of {count}, one per joint", value)
        return None
    return [r.value(x, f"{field}[{i}]", num) for i, x in enumerate(value, 1)]


def _det(rows: list[list[Fraction]]) -> Fraction:
    """Exact determinant by Gaussian elimination."""
    a, det = [row[:] for row in rows], Fraction(1)
    for c in range(len(a)):
        pivot = next((i for i in range(c, len(a)) if a[i][c] != 0), None)
        if pivot is None:
            return _ZERO
        if pivot != c:
            a[c], a[pivot], det = a[pivot], a[c], -det
        det *= a[c][c]
        for i in range(c + 1, len(a)):
            a[i] = [x - a[i][c] / a[c][c] * y for x, y in zip(a[i], a[c])]
    return det


def _matrix(r: Reader, value: Any, n: int | None) -> tuple[tuple[Fraction, ...], ...]:
    """C of y = C theta (eq. 13): n x n and invertible; the identity when not given."""
    identity = tuple(tuple(Fraction(int(i == j)) for j in range(n)) for i in range(n or 0))
    if value is None:
        return identity
    m = n if n is not None else (len(value) if isinstance(value, list) else 0)
    if (not isinstance(value, list) or m == 0 or len(value) != m
            or not all(isinstance(row, list) and len(row) == m for row in value)):
        r.bad("controller.C", f"a {m or 'n'} x {m or 'n'} array of numbers "
              "(the output matrix of y = C theta, eq. 13)", value)
        return identity
    rows = [[r.value(x, f"controller.C[{i}][{j}]", ANY[""]) for j, x in enumerate(row, 1)]
            for i, row in enumerate(value, 1)]
    if any(x is None for row in rows for x in row):
        return identity
    if _det(rows) == 0:
        r.add("controller.C", "an invertible matrix (u* of eq. 15 uses C^-1)",
              f"the singular matrix {inline(value)} (det C = 0)")
        return identity
    return tuple(tuple(row) for row in rows)


def _last_joint_inertia(r: Reader, links: list[Link], point_masses: list[PointMass],
                        motors: list[Motor]) -> None:
    """The last joint must move some inertia, else J(theta) is singular for every theta.

    (An inner joint with nothing on its own link is a legitimate model: the
    links beyond it move, and J can stay positive definite.)
    """
    n, link = len(links), links[-1]
    if None in (link.mass, link.com, link.inertia) or any(p.link == -1 for p in point_masses):
        return
    total = link.inertia + link.mass * link.com ** 2
    for p in (p for p in point_masses if p.link == n - 1):
        if None in (p.mass, p.distance, p.inertia):
            return
        total += p.inertia + p.mass * p.distance ** 2
    if len(motors) == n:
        if None in (motors[-1].rotor_inertia, motors[-1].gear_ratio):
            return
        total += motors[-1].rotor_inertia * motors[-1].gear_ratio ** 2
    if total == 0:
        r.add(f"link[{n}]", f"an inertia about joint {n} > 0 (else J(theta) is singular): a com away "
              "from the joint, an inertia > 0, a point mass away from the joint or a rotor_inertia > 0",
              "0 kg m^2 (com = 0 and inertia = 0, nothing else on the last link)")
