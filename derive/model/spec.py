"""Arm description: TOML file -> validated, typed, frozen :class:`Arm`.

Every number is kept exact as a :class:`fractions.Fraction` of the decimal the
file wrote (0.38 is 19/50, not the nearest double), so that symbolic identities
hold exactly and generated constants round once. Numbers must be finite doubles
(TOML reads ``nan``, ``inf`` and ``1e400`` -> inf; none is accepted). Every
problem in a file is collected and reported in one :class:`SpecError`, each
naming the field (``link[2].mass``), the expected (``a finite number > 0 (kg)``)
and the given value (``-0.3``, ``string 'abc'``); unknown keys are problems too.

An arm is its kinematic chain (:attr:`Arm.chain`, the one model the dynamics
read, :mod:`derive.model.chain`), the drive of each joint
(:attr:`Arm.actuators`, :mod:`derive.model.actuators`), the controller settings
and the simulation settings. The chain comes from exactly one of:
``[[link]]`` and ``[[point_mass]]`` tables (a planar chain,
:mod:`derive.model.planar`), a ``[dh]`` table with ``[[body]]`` tables
(:mod:`derive.model.dh`), ``urdf = "robot.urdf"`` with ``base_link``,
``tip_link`` and ``locked`` under ``[arm]`` (:mod:`derive.model.urdf`), or
``mjcf = "robot.xml"`` with ``base_body``, ``tip_body`` and ``locked``
(:mod:`derive.model.mjcf`: MuJoCo's compiler reads it; its ``armature`` is the
default of ``motor.rotor_inertia`` as armature / gear_ratio^2).

``[arm]`` keys: ``name``, ``description``, ``gravity`` (the magnitude g >= 0 in
m/s^2, default 0), ``gravity_direction`` (the direction of free fall in the
base frame, normalised; a planar arm gives [x, y], default [0, -1], so
[0, 1] is a ceiling-mounted arm; a DH or URDF arm [x, y, z], default
[0, 0, -1]), ``actuation`` ("voltage", the default, or "torque": the default
of every ``[[motor]]``; torque-actuated arms may leave ``[[motor]]`` out).
DH and URDF arms give each joint's viscous friction in ``[[motor]]``
(``viscous_friction``; a URDF's ``<dynamics damping>`` is the default), and may
replace a body's ten parameters by a ``[[body_override]]`` table
(:mod:`derive.model.override`; derive identify writes them).

The runtime parameters (:attr:`Arm.parameters`) are the file's own values,
each with its unit and field: the chain's, the drives' (Kt, Kv, Ra, gr, Jm,
bv per joint) and the controller's (T1, T2, w); everything else is an
expression of them.
"""
from __future__ import annotations

import functools
import hashlib
import tomllib
from dataclasses import dataclass, field, replace
from fractions import Fraction
from pathlib import Path
from typing import Any

import sympy as sp

from derive.errors import Problem, SpecError
from derive.model.actuators import Motor, actuation_value, actuator, input_unit, read_motors, terms
from derive.model.chain import Actuation, Actuator, Chain, Parameter
from derive.model.fields import (ANY, NONNEGATIVE, POSITIVE, TEXT_RULE, Num, Reader, domain, fmt, inline, printable,
                                 show, text_problem)
from derive.model.fields import path as field_path
from derive.model.names import name_check
from derive.model.override import apply_overrides
from derive.model.payload import PayloadRange, parse_payload
from derive.model.planar import UNIFORM_ROD, Link, PointMass, planar_chain, read_links, read_point_masses
from derive.model.simspec import SimSettings, parse_simulation
from derive.model.singular import unmoved_joint
from derive.model.rigid import rational_unit
from derive.model.rules import division_free_det, horizon

from derive.model.sweepspec import SweepSpec, parse_sweep
from derive.paths import ARMS_DIR, DEFAULT_ARM, packaged_arms, resolve_arm_path  # noqa: F401 (re-exported)

__all__ = ["Arm", "Controller", "Link", "Motor", "PointMass", "UNIFORM_ROD", "load_arm", "arm_from_dict"]
MAX_FILE_BYTES = 1 << 20   # an arm file is a few kB; never read /dev/zero whole
_MISSING = object()
_ZERO = Fraction(0)


OBSERVER_STRUCTURES = ("chen", "full")
OBSERVER_STEPS = ("explicit", "implicit")   # controller.observer: the default of --observer (derive.codegen.kernels)


@dataclass(frozen=True)
class Controller:
    """Settings of the predictive controller (eq. 14-19) and observer (eq. 23-25).

    The observer gain W [N m s/rad: p = W theta' is a joint torque, eq. 22] is given one of
    three ways: ``w`` (n gains, ``W[i][j] = w_j``
    for j <= i, eq. 25 generalised), ``W`` (a full n x n matrix) or ``w_auto`` (chosen by
    derive.control.certificate.synthesis for the box ``max_joint_speed`` and the rate ``observer_rate``,
    with the structure ``observer_structure``: "chen" or "full"). ``observer_rate``
    [1/s]: the exponential rate the observer certificate must give (0: any).
    ``momentum_gain``: the diagonal gain K [1/s] of the generalized-momentum observer
    (form mom, derive.control.momentum: r' = K (B d - r)), one per joint; empty when the
    arm file does not give it (MOMENTUM_GAIN for every joint). ``observer``: the observer step the
    commands build by default (their ``--observer``): "explicit" (forward Euler of eq. 21) or
    "implicit" (backward Euler; ``derive init`` writes it where only it allows a usable sample time).
    """

    T1: Fraction
    T2: Fraction
    w: tuple[Fraction, ...] | None
    C: tuple[tuple[Fraction, ...], ...]
    max_joint_speed: tuple[Fraction, ...] | None
    W: tuple[tuple[Fraction, ...], ...] | None = None
    w_auto: bool = False
    observer_rate: Fraction = Fraction(0)
    observer_structure: str = "chen"
    momentum_gain: tuple[Fraction, ...] = ()   # K of the momentum observer [1/s]; () = MOMENTUM_GAIN each
    observer: str = "explicit"   # the observer step of the commands' default build (OBSERVER_STEPS)


@dataclass(frozen=True)
class Arm:
    """A validated arm description.

    ``links``, ``point_masses``: the planar tables as read; ``gravity``: the
    magnitude g [m/s^2]; ``gravity_direction``: as written (normalised in the
    chain); ``motors``: one per joint.
    """

    name: str
    description: str
    gravity: Fraction
    links: tuple[Link, ...]
    point_masses: tuple[PointMass, ...]
    motors: tuple[Motor, ...]
    controller: Controller
    source: str
    simulation: SimSettings = field(default_factory=SimSettings, compare=False)
    sweep: SweepSpec | None = field(default=None, compare=False)  # the [sweep] section, if any
    source_sha256: str = ""  # of the bytes validated (load_arm), recorded in MANIFEST.json
    gravity_direction: tuple[Fraction, ...] = (Fraction(0), Fraction(-1))
    spatial: Chain | None = None          # the chain of a DH or URDF arm (planar arms: None)
    joint_friction: tuple[tuple[Fraction, str], ...] = ()   # DH/URDF: (bv, its field) per joint
    warnings: tuple[Problem, ...] = field(default=(), compare=False)   # URDF: ignored elements on the chain
    payload: PayloadRange | None = field(default=None, compare=False)   # the [payload] range (derive.model.payload)

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.links) if self.spatial is None else self.spatial.n

    @property
    def chain(self) -> Chain:
        """The normalised kinematic chain (bodies, joints, drives, gravity) the dynamics read;
        its parameters are the arm's without the controller's."""
        base = self.spatial if self.spatial is not None else _planar(
            self.links, self.point_masses, self.gravity, self.gravity_direction)
        actuators, drives = _drives(self.motors, self._frictions())
        return replace(base, actuators=actuators, parameters=base.parameters + drives)

    def _frictions(self) -> tuple[tuple[Fraction, str], ...]:
        if self.spatial is not None:
            return self.joint_friction
        return tuple((link.viscous_friction, f"link[{i}].viscous_friction") for i, link in enumerate(self.links, 1))

    @property
    def actuators(self) -> tuple[Actuator, ...]:
        """The drive of each joint (its parameter symbols; derive.model.actuators.terms gives
        B_ii, the damping and the reflected rotor inertia, eq. 12)."""
        return _drives(self.motors, self._frictions())[0]

    @property
    def parameters(self) -> tuple[Parameter, ...]:
        """Every runtime parameter, in canonical order: the chain's (its bodies' and
        gravity, then the drives' grouped by kind: Kt, Kv, Ra, gr, Jm, bv), the
        controller's (T1, T2, w)."""
        return self.chain.parameters + controller_parameters(self.controller, self.prismatic)

    @property
    def prismatic(self) -> tuple[bool, ...]:
        """Per joint, base to tip: True for a prismatic joint (planar arms: none)."""
        if self.spatial is None:
            return (False,) * self.n
        return tuple(not j.type.rotates for j in self.spatial.joints)

    @property
    def input_units(self) -> tuple[str, ...]:
        """The unit of each u_i (and d_i, its limit): V, or N m (N) in torque mode
        (derive.model.actuators.input_unit)."""
        return tuple(input_unit(m, p) for m, p in zip(self.motors, self.prismatic))


T1_SYMBOL, T2_SYMBOL = sp.Symbol("T1", **domain(NONNEGATIVE["s"])), sp.Symbol("T2", **domain(POSITIVE["s"]))


def w_symbols(n: int) -> tuple[sp.Symbol, ...]:
    """Observer gain symbols w1..wn (eq. 25)."""
    return tuple(sp.Symbol(f"w{i + 1}", positive=True) for i in range(n))


def full_w_symbols(n: int) -> tuple[sp.Symbol, ...]:
    """Gain symbols of a full W, row-major: W1_1, W1_2, ..., Wn_n [N m s/rad]."""
    return tuple(sp.Symbol(f"W{i + 1}_{j + 1}", real=True) for i in range(n) for j in range(n))


MOMENTUM_GAIN = Fraction(50)   # 1/s: the default K_i of the momentum observer (time constant 20 ms)


def momentum_symbols(n: int) -> tuple[sp.Symbol, ...]:
    """Gain symbols kr1..krn [1/s] of the momentum observer, K = diag(kr) (derive.control.momentum)."""
    return tuple(sp.Symbol(f"kr{i + 1}", **domain(MOMENTUM)) for i in range(n))


def momentum_parameters(c: "Controller") -> tuple[Parameter, ...]:
    """K of the momentum observer as parameters kr1..krn (the arm file's, else MOMENTUM_GAIN)."""
    gains = c.momentum_gain or (MOMENTUM_GAIN,) * len(c.C)
    return tuple(Parameter(s, v, "1/s", f"controller.momentum_gain[{i}]",
                           f"momentum observer gain K{i}: r' = K (B d - r) (form mom)")
                 for i, (s, v) in enumerate(zip(momentum_symbols(len(gains)), gains), 1))


def gain_unit(prismatic: tuple[bool, ...], i: int, j: int) -> str:
    """The unit of W[i][j] (0-based): p = W theta' is a generalized force (z + p = B dhat, eq. 22,
    a joint torque in both actuations), so W[i][j] is joint i's force unit times s per joint j's
    coordinate unit: N m s/rad between revolute joints (N s/m between prismatic ones)."""
    return f"{'N' if prismatic[i] else 'N m'} s/{'m' if prismatic[j] else 'rad'}"


def gain_units_text(prismatic: tuple[bool, ...]) -> str:
    """W's unit in words: "N m s/rad" (every joint revolute), "N s/m" (every joint prismatic), else
    per entry (:func:`gain_unit`)."""
    if len(set(prismatic)) == 1:
        return gain_unit(prismatic, 0, 0)
    return "W[i][j] in joint i's force unit s per joint j's coordinate unit (N m s/rad, N m s/m, N s/rad, N s/m)"


def observer_parameters(w=None, W=None, field: str = "controller.w",
                        prismatic: tuple[bool, ...] | None = None) -> tuple[Parameter, ...]:
    """The observer gain as parameters: w1..wn (eq. 25 pattern) or W1_1..Wn_n (a full W), each with
    its unit (:func:`gain_unit`; ``prismatic``: which joints are prismatic, default none; w_j has the
    unit of the diagonal entry W[j][j])."""
    n = len(W) if W is not None else len(w)
    kinds = prismatic if prismatic is not None else (False,) * n
    if W is not None:
        return tuple(Parameter(s, W[k // n][k % n], gain_unit(kinds, k // n, k % n),
                               f"{field}[{k // n + 1}][{k % n + 1}]",
                               f"observer gain W[{k // n + 1}][{k % n + 1}] (full W, eq. 23-25)")
                     for k, s in enumerate(full_w_symbols(n)))
    return tuple(Parameter(s, v, gain_unit(kinds, i - 1, i - 1), f"{field}[{i}]", f"observer gain w{i} (eq. 25)")
                 for i, (s, v) in enumerate(zip(w_symbols(len(w)), w), 1))


def controller_parameters(c: Controller, prismatic: tuple[bool, ...] | None = None) -> tuple[Parameter, ...]:
    """T1, T2 (eq. 14), the observer gain (eq. 25; none here for w = "auto": the
    pipeline adds the synthesised one) and the momentum observer's K as parameters;
    k1, k2 are expressions of T1, T2. ``prismatic``: which joints are prismatic (W's units)."""
    out = [Parameter(T1_SYMBOL, c.T1, "s", "controller.T1", "minimum prediction time T1 (eq. 14)"),
           Parameter(T2_SYMBOL, c.T2, "s", "controller.T2", "maximum prediction time T2 (eq. 14)")]
    if not c.w_auto:
        out += observer_parameters(c.w, c.W, prismatic=prismatic)
    return tuple(out) + momentum_parameters(c)


def gravity_parameter(g: Fraction) -> Parameter:
    return Parameter(sp.Symbol("g", **domain(GRAVITY)), g, "m/s^2", "arm.gravity",
                     "acceleration of free fall along gravity_direction")


def unit_direction(direction: tuple[Fraction, ...]) -> sp.ImmutableMatrix:
    """The 3 x 1 unit vector of a direction given by 2 (planar: z = 0) or 3 exact numbers (rational:
    derive.model.rigid.rational_unit)."""
    v = sp.Matrix([sp.Rational(x.numerator, x.denominator) for x in direction] + [0] * (3 - len(direction)))
    return rational_unit(v)


@functools.lru_cache(maxsize=64)
def _planar(links: tuple[Link, ...], point_masses: tuple[PointMass, ...], g: Fraction,
            direction: tuple[Fraction, ...]) -> Chain:
    return planar_chain(list(links), list(point_masses), gravity_parameter(g), unit_direction(direction))


_KINDS = ("Kt", "Kv", "Ra", "gr", "Jm", "bv")


@functools.lru_cache(maxsize=64)
def _drives(motors: tuple[Motor, ...], frictions: tuple[tuple[Fraction, str], ...]
            ) -> tuple[tuple[Actuator, ...], tuple[Parameter, ...]]:
    acts, params = [], []
    for i, (m, (bv, where)) in enumerate(zip(motors, frictions), 1):
        act, ps = actuator(i, m, bv, where)
        acts.append(act)
        params += ps
    order = sorted(params, key=lambda p: _KINDS.index(p.symbol.name.rstrip("0123456789")))
    return tuple(acts), tuple(order)


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
    except FileNotFoundError:
        tried = f" (nor {printable(str(file))}.toml)" if path is not None and file.suffix == "" else ""
        raise SpecError(printable(source), [Problem(
            "file", f"an arm file (TOML) or the name of a packaged arm ({', '.join(packaged_arms())})",
            f"no such file{tried}")], title="no such arm") from None
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
    return replace(arm_from_dict(data, source, file.parent), source_sha256=hashlib.sha256(raw).hexdigest())


# -- the schema ---------------------------------------------------------------------------

TOP_KEYS = {"arm": "a table [arm] with at least a name", "link": None, "point_mass": None, "dh": None,
            "body": None, "motor": None, "controller": "a table [controller] with T1, T2 and w", "simulation": None,
            "sweep": None, "body_override": None, "payload": None}
ARM_KEYS = {"name": "a lowercase C identifier (the prefix of the generated code)",
            "description": None, "gravity": None, "gravity_direction": None, "actuation": None,
            "urdf": None, "base_link": None, "tip_link": None, "locked": None, "repair_inertia": None,
            "mjcf": None, "base_body": None, "tip_body": None}
URDF_ONLY = ("base_link", "tip_link", "repair_inertia")
MJCF_ONLY = ("base_body", "tip_body")
FILE_ONLY = ("locked",)   # a URDF's or an MJCF's
CONTROLLER_KEYS = {"T1": NONNEGATIVE["s"].expected, "T2": POSITIVE["s"].expected,
                   "w": "an array of observer gains, one per joint (eq. 25)", "C": None, "max_joint_speed": None,
                   "observer_rate": None, "observer_structure": None, "momentum_gain": None,
                   "observer": None}
KINEMATICS = ("one [[link]] table per joint, base to tip (a planar arm), a [dh] table with [[body]] tables, "
              "or urdf = \"robot.urdf\" or mjcf = \"robot.xml\" under [arm]")
W_EXPECTED = ("an array of n observer gains w_j > 0 [N m s/rad] (W[i][j] = w_j for j <= i, eq. 25), an n x n array "
              "(a full W), or 'auto' (chosen by an SDP for max_joint_speed)")
RATE = Num("1/s", _ZERO)
MOMENTUM = Num("1/s", _ZERO, True)   # controller.momentum_gain[i] > 0
GRAVITY = NONNEGATIVE["m/s^2"]


def _kind(r: Reader, top: dict, arm: Any) -> str | None:
    """Where the kinematics come from: 'planar', 'dh', 'urdf' or 'mjcf' (None: a problem was added)."""
    urdf = isinstance(arm, dict) and "urdf" in arm
    mjcf = isinstance(arm, dict) and "mjcf" in arm
    found = [k for k, present in (("planar", "link" in top), ("dh", "dh" in top), ("urdf", urdf), ("mjcf", mjcf))
             if present]
    if len(found) != 1:
        r.add("link" if not found else "arm file", KINEMATICS,
              "nothing (no [[link]], [dh], urdf or mjcf)" if not found else f"{' and '.join(found)} together")
        return None
    kind = found[0]
    for key, owner in (("point_mass", "planar"), ("body", "dh")):
        if key in top and kind != owner:
            r.add(key, f"no [[{key}]] tables (they belong to {'[[link]]' if owner == 'planar' else '[dh]'} arms)",
                  f"{len(top[key]) if isinstance(top[key], list) else 1} with a {kind} arm")
    if kind == "dh" and "body" not in top:
        r.add("body", "one [[body]] table per row of dh.table", "nothing (the key is missing)")
    for keys, owners, what in ((URDF_ONLY, ("urdf",), 'urdf = "robot.urdf"'), (MJCF_ONLY, ("mjcf",), 'mjcf = "robot.xml"'),
                               (FILE_ONLY, ("urdf", "mjcf"), 'urdf = "robot.urdf" or mjcf = "robot.xml"')):
        for key in keys:
            if isinstance(arm, dict) and key in arm and kind not in owners:
                r.add(f"arm.{key}", f"no such key without {what}", f"{show(arm[key])} with a {kind} arm")
    return kind


NO_NULL = "a value (TOML has no null: leave the key out for its default)"


def _nones(value: Any, field: str = "") -> list[str]:
    """The fields of every None inside a parsed mapping (``controller.C``, ``link[2].mass``,
    ``controller.w[2]``), at any depth."""
    items = (value.items() if isinstance(value, dict) else
             ((i, v) for i, v in enumerate(value, 1)) if isinstance(value, list) else ())
    found = []
    for key, v in items:
        name = f"{field}[{key}]" if isinstance(value, list) else field_path(field, key)
        found += [name] if v is None else _nones(v, name)
    return found


def arm_from_dict(data: Any, source: str = "<dict>", base_dir: Path | None = None) -> Arm:
    """Validate a parsed arm mapping (what ``tomllib`` gives for an arm file); raise
    SpecError with every problem.

    ``base_dir``: where a ``urdf`` path is relative to (default: the folder of
    ``source`` when it is a path, else the working directory). None is not a value:
    TOML has no null and the mapping mirrors the file, so a key set to None, at any
    depth, is a problem naming that key (never its default: leave the key out for that).
    """
    if nones := _nones(data):
        raise SpecError(printable(source), [Problem(f, NO_NULL, "nothing: None") for f in nones])
    r = Reader()
    if isinstance(data, dict):
        top = r.table(data, "", TOP_KEYS, "")
    else:
        r.bad("arm file", "a table of [arm], [[link]], [[motor]] and [controller]", data)
        top = {}
    arm_table = top.get("arm", _MISSING)
    kind = _kind(r, top, arm_table)
    head = _head(r, arm_table, 2 if kind == "planar" else 3)
    if base_dir is None:
        base_dir = Path(source).parent if not source.startswith("<") else Path.cwd()
    links, point_masses, spatial, friction, found = [], [], None, (), None
    g = gravity_parameter(head.gravity if head.gravity is not None else _ZERO)
    if kind == "planar":
        links = read_links(r, top.get("link"))
        point_masses = read_point_masses(r, top.get("point_mass", []), None if links is None else len(links))
        n = None if links is None else len(links)
    elif kind == "dh":
        from derive.model.dh import dh_chain   # here: a planar arm file needs neither reader (nor XML)

        spatial = dh_chain(r, top.get("dh"), top.get("body", []), g, unit_direction(head.direction or SPATIAL_DOWN))
        n = None if spatial is None else spatial.n
    elif kind == "urdf":
        from derive.model.urdf import urdf_chain

        found = urdf_chain(r, arm_table, base_dir, g, unit_direction(head.direction or SPATIAL_DOWN))
        spatial = None if found is None else found.chain
        n = None if spatial is None else spatial.n
    elif kind == "mjcf":
        from derive.model.mjcf import mjcf_chain   # here: only an MJCF arm needs MuJoCo

        found = mjcf_chain(r, arm_table, base_dir, g, unit_direction(head.direction or SPATIAL_DOWN))
        spatial = None if found is None else found.chain
        n = None if spatial is None else spatial.n
    else:
        n = None
    if "body_override" in top:   # identified bodies (derive identify): URDF and DH arms
        if kind == "planar":
            r.add("body_override", "no [[body_override]] tables with [[link]] tables (a planar arm's identified "
                  "values go into its [[link]] fields)", show(top["body_override"]))
        elif spatial is not None:
            spatial = apply_overrides(r, top["body_override"], spatial)
    joints = "[[link]]" if kind == "planar" else ("rows of dh.table" if kind == "dh" else "moving joints")
    motors = read_motors(r, top.get("motor"), n, head.actuation, joint_friction=kind != "planar", joints=joints)
    if kind == "mjcf" and found is not None and len(motors) == n:
        motors = _armature_defaults(top.get("motor"), motors, found.armature)
    if kind in ("urdf", "mjcf") and spatial is not None and len(motors) == n:
        friction = tuple((m.viscous_friction, f"motor[{i}].viscous_friction") if m.viscous_friction is not None
                         else (v, where) for i, (m, v, where) in enumerate(
                             zip(motors, found.damping, found.damping_fields), 1))
    elif kind == "dh" and len(motors) == n:
        friction = tuple((m.viscous_friction or _ZERO, f"motor[{i}].viscous_friction")
                         for i, m in enumerate(motors, 1))
    controller = _controller(r, top.get("controller", _MISSING), n)
    simulation, sim_problems = parse_simulation(top.get("simulation"), n or 1)
    r.problems.extend(sim_problems if n else [])
    if kind in ("urdf", "mjcf") and found is not None and not sim_problems and "coulomb_friction" not in (
            top.get("simulation") or {}):   # the URDF's <dynamics friction>, the MJCF's frictionloss: the default
        simulation = replace(simulation, coulomb_friction=tuple(
            float(f) if f is not None else c for f, c in zip(found.friction, simulation.coulomb_friction)))
    sweep, sweep_problems = parse_sweep(top.get("sweep"), n or 1)
    r.problems.extend(sweep_problems if n else [])
    payload = parse_payload(r, top.get("payload"))
    if r.problems:
        raise SpecError(printable(source), r.problems)
    arm = Arm(name=head.name, description=head.description, gravity=head.gravity, links=tuple(links),
              point_masses=tuple(point_masses), motors=tuple(motors), controller=controller, source=source,
              simulation=simulation, sweep=sweep, gravity_direction=head.direction or (
                  (Fraction(0), Fraction(-1)) if kind == "planar" else SPATIAL_DOWN),
              spatial=spatial, joint_friction=friction, payload=payload,
              warnings=found.warnings if kind in ("urdf", "mjcf") and found is not None else ())
    _moves_inertia(r, arm)
    if r.problems:
        raise SpecError(printable(source), r.problems)
    return arm


SPATIAL_DOWN = (Fraction(0), Fraction(0), Fraction(-1))


def _armature_defaults(tables: Any, motors: list, armature: tuple[Fraction, ...]) -> list:
    """An MJCF arm's motors with the file's ``armature`` A (the rotor inertia reflected to the joint)
    as the rotor inertia of each motor whose table does not give one: Jm = A / gear_ratio^2."""
    given = [isinstance(t, dict) and "rotor_inertia" in t for t in tables] if isinstance(tables, list) else \
        [False] * len(motors)
    return [m if have or not a else replace(m, rotor_inertia=a / (m.gear_ratio ** 2))
            for m, a, have in zip(motors, armature, given)]


@dataclass(frozen=True)
class _Head:
    name: str
    description: str
    gravity: Fraction | None
    direction: tuple[Fraction, ...] | None
    actuation: Actuation


def _head(r: Reader, value: Any, size: int) -> _Head:
    d = None if value is _MISSING else r.table(value, "arm", ARM_KEYS, "a table [arm] with at least a name")
    if d is None:
        return _Head("", "", _ZERO, None, Actuation.VOLTAGE)
    name = d.get("name", "")
    if "name" in d and (found := name_check(name)):
        r.add("arm.name", found[0], found[1] if isinstance(name, str) else show(name))
    return _Head(name, r.text(d, "description", "arm"), r.number(d, "gravity", "arm", GRAVITY, _ZERO),
                 _direction(r, d.get("gravity_direction"), size),
                 actuation_value(r, d.get("actuation"), "arm.actuation", Actuation.VOLTAGE))


def _direction(r: Reader, value: Any, size: int) -> tuple[Fraction, ...] | None:
    """gravity_direction: ``size`` finite numbers, not all zero (None: not given)."""
    if value is None:
        return None
    field = "arm.gravity_direction"
    what = ("[x, y], the direction of free fall in the base xy plane (e.g. [0, 1] for a ceiling-mounted "
            "arm)" if size == 2 else "[x, y, z], the direction of free fall in the base frame")
    if not isinstance(value, list) or len(value) != size:
        r.bad(field, f"an array of {size} numbers {what}", value)
        return None
    entries = [r.value(x, f"{field}[{i}]", ANY[""]) for i, x in enumerate(value, 1)]
    if None in entries:
        return None
    if all(x == 0 for x in entries):
        r.bad(field, f"a non-zero direction {what}", value)
        return None
    return tuple(entries)


def _moves_inertia(r: Reader, arm: Arm) -> None:
    """Every joint must move some inertia at q = 0, else J is singular (issue 10, item 7)."""
    values = {p.symbol: p.rational for p in arm.parameters}
    problem = unmoved_inertia(arm.chain, [terms(a)[2] for a in arm.actuators], values)
    if problem is not None:
        r.problems.append(problem)


def unmoved_inertia(chain: Chain, reflected: list, values: dict) -> Problem | None:
    """The problem of the first joint of ``chain`` that moves no inertia (J singular) with
    the reflected rotor inertias ``reflected``, or None."""
    found = unmoved_joint(chain, reflected, values)
    if found is None:
        return None
    i, everywhere = found
    k = i + 1
    joint = chain.joints[i]
    moved = "a mass" if not joint.type.rotates else f"an inertia about joint {k}"
    return Problem(joint.field, f"{moved} > 0 at every configuration (else J(theta) is singular): mass beyond "
                   f"joint {k} away from its axis, a link inertia > 0 or a rotor_inertia > 0",
                   "0 (nothing beyond the joint has inertia about its axis" + (")" if everywhere else
                   " at theta = 0, where J is singular)"))


def _controller(r: Reader, value: Any, n: int | None) -> Controller | None:
    f = "controller"
    d = None if value is _MISSING else r.table(value, f, CONTROLLER_KEYS, "a table [controller] with T1, T2 and w")
    if d is None:
        return None
    T1, T2 = r.number(d, "T1", f, NONNEGATIVE["s"]), r.number(d, "T2", f, POSITIVE["s"])
    if T1 is not None and T2 is not None and not horizon(T1_SYMBOL, T2_SYMBOL).holds({T1_SYMBOL: T1, T2_SYMBOL: T2}):
        shown = show(d["T2"]) + (f" (= {fmt(T2)})" if isinstance(d["T2"], str) else "")
        r.add("controller.T2", f"a number > T1 = {fmt(T1)} (s; the prediction horizon [T1, T2] of eq. 14)", shown)
    w, W, auto = _observer_gain(r, d, n)
    speeds = _vector(r, d, "max_joint_speed", n, POSITIVE["rad/s"])
    momentum = _vector(r, d, "momentum_gain", n, MOMENTUM)
    rate = r.number(d, "observer_rate", f, RATE, _ZERO)
    structure = d.get("observer_structure", "chen")
    if structure not in OBSERVER_STRUCTURES or ("observer_structure" in d and not auto):
        r.add("controller.observer_structure", "'chen' or 'full', with w = 'auto' (the structure of the "
              "synthesised W)", show(structure) + ("" if auto else " (w is not 'auto')"))
    step = d.get("observer", "explicit")
    if step not in OBSERVER_STEPS:
        r.add("controller.observer", "'explicit' or 'implicit' (the observer step the commands build by default)",
              show(step))
    if auto and "max_joint_speed" not in d:
        r.add("controller.max_joint_speed", "the speed box [rad/s] W is synthesised for (w = 'auto')",
              "nothing (the key is missing)")
    C = _matrix(r, d.get("C"), n)
    if None in (T1, T2, rate) or not (w or W or auto) or (speeds and None in speeds) or (momentum and None in momentum):
        return None
    return Controller(T1, T2, w, C, tuple(speeds) if speeds else None, W=W, w_auto=auto, observer_rate=rate,
                      momentum_gain=tuple(momentum) if momentum else (),
                      observer_structure=structure if structure in OBSERVER_STRUCTURES else "chen",
                      observer=step if step in OBSERVER_STEPS else "explicit")


def _observer_gain(r: Reader, d: dict, n: int | None) -> tuple[tuple | None, tuple | None, bool]:
    """(w, W, auto) from controller.w: n gains w_j > 0, an n x n matrix, or 'auto'.

    Whether the observer converges is the certificate's to decide (derive check); what is
    checked here is what every certificate needs: a positive diagonal of W (the diagonal
    of W + W^T) and an invertible W (V of (a7) uses W^-1)."""
    if "w" not in d:
        return None, None, False
    value = d["w"]
    if isinstance(value, str) and value == "auto":
        return None, None, True
    if isinstance(value, list) and value and all(isinstance(row, list) for row in value):
        m = n if n is not None else len(value)
        if len(value) != m or not all(len(row) == m for row in value):
            r.bad("controller.w", W_EXPECTED, value)
            return None, None, False
        rows = [[r.value(x, f"controller.w[{i}][{j}]", ANY["1/s"]) for j, x in enumerate(row, 1)]
                for i, row in enumerate(value, 1)]
        if any(x is None for row in rows for x in row):
            return None, None, False
        bad = [i for i in range(m) if rows[i][i] <= 0]
        for i in bad:
            r.add(f"controller.w[{i + 1}][{i + 1}]", "a diagonal entry > 0 [N m s/rad] (W + W^T must be positive "
                  "definite)", show(value[i][i]))
        if not bad and division_free_det(rows, _ZERO) == 0:
            r.add("controller.w", "an invertible W (V of eq. a7 uses W^-1)", f"{inline(value)} (det W = 0)")
            return None, None, False
        return (None, tuple(tuple(row) for row in rows), False) if not bad else (None, None, False)
    if not isinstance(value, list) or not value or (n is not None and len(value) != n) \
            or any(isinstance(x, list) for x in value):
        r.bad("controller.w", W_EXPECTED.replace("n observer", f"{n} observer") if n else W_EXPECTED, value)
        return None, None, False
    w = [r.value(x, f"controller.w[{i}]", ANY["1/s"]) for i, x in enumerate(value, 1)]
    if None in w:
        return None, None, False
    bad = [i for i, x in enumerate(w) if x <= 0]
    for i in bad:
        r.add(f"controller.w[{i + 1}]", f"w{i + 1} > 0 (observer gain [N m s/rad]: the diagonal of W + W^T, eq. 25)",
              show(value[i]))
    return (None if bad else tuple(w)), None, False


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
    if division_free_det(rows, _ZERO) == 0:
        r.add("controller.C", "an invertible matrix (u* of eq. 15 uses C^-1)",
              f"the singular matrix {inline(value)} (det C = 0)")
        return identity
    return tuple(tuple(row) for row in rows)
