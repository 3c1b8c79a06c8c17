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
from derive.model.actuators import Motor, actuator, input_unit, read_motors
from derive.model.chain import Actuator, Chain, Parameter
from derive.model.fields import TEXT_RULE, Reader, domain, inline, printable, show, text_problem
from derive.model.override import apply_overrides
from derive.model.payload import PayloadRange, parse_payload
from derive.model.planar import UNIFORM_ROD, Link, PointMass, planar_chain, read_links, read_point_masses
from derive.model.simspec import SimSettings, parse_simulation
from derive.model.rigid import rational_unit
from derive.model.sweepspec import SweepSpec, parse_sweep
from derive.paths import ARMS_DIR, DEFAULT_ARM, packaged_arms, resolve_arm_path  # noqa: F401 (re-exported)
from derive.model.controller import (T1_SYMBOL, T2_SYMBOL, CONTROLLER_KEYS, Controller, MOMENTUM, MOMENTUM_GAIN,
                                     OBSERVER_STEPS, OBSERVER_STRUCTURES, RATE, W_EXPECTED, _MISSING, _ZERO,
                                     _controller, _matrix, _observer_gain, _vector, controller_parameters,
                                     full_w_symbols, gain_unit, gain_units_text, momentum_parameters,
                                     momentum_symbols, observer_parameters, w_symbols)  # noqa: F401 (re-exported)
from derive.model.arm_table import (ARM_KEYS, FILE_ONLY, GRAVITY, KINEMATICS, MJCF_ONLY, NO_NULL, URDF_ONLY, _Head,
                                    _direction, _head, _kind, _moves_inertia, _nones, unmoved_inertia)  # noqa: F401 (re-exported)

__all__ = ["Arm", "Controller", "Link", "Motor", "PointMass", "UNIFORM_ROD", "load_arm", "arm_from_dict"]

MAX_FILE_BYTES = 1 << 20   # an arm file is a few kB; never read /dev/zero whole


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


