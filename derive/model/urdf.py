"""URDF arm files: ``urdf = "robot.urdf"`` under ``[arm]`` -> a :class:`Chain`.

::

    [arm]
    urdf = "panda.urdf"            # path relative to the arm file
    base_link = "panda_link0"      # the chain runs from this link ...
    tip_link = "panda_hand_tcp"    # ... to this one
    locked = { panda_finger_joint1 = 0.0 }   # joints held at a value (rad or m)
    repair_inertia = ["link2"]     # or true: non-physical inertias moved to the nearest physical one
    snap_angles = 1e-05            # rad: rpy angles this close to k pi/2 are k pi/2 (default 1e-08)

Reading (derive.model.urdf_xml): the file is checked by ``defusedxml`` first
(no entity declarations, no external entities or DTDs: an entity-expansion
bomb or ``file:///etc/passwd`` is refused unexpanded), cut down to what derive
reads (transmissions, Gazebo tags, sensors, visual and collision meshes are
dropped unread, with a note), every number of the elements used is checked
(finite, the right count) and named in a message, and the URDF is parsed by
``urdf_parser_py`` (ROS's reference Python parser). What does not move with
the chain is read leniently, what does strictly (derive.model.urdf_rules): a
bad number or a non-physical inertia there is an error (``repair_inertia``
repairs the latter: derive.model.inertia_repair), an ignored element that may
change the dynamics (``<dynamics><damping>``) a warning every command prints.

Normalisation follows the URDF specification: ``rpy`` is fixed-axis X-Y-Z,
R = Rz(yaw) Ry(pitch) Rx(roll) (angles within 1e-08 rad of k pi/2 are k pi/2, or within ``snap_angles``:
derive.model.rigid.snapping); an
absent ``<origin>`` is the identity; an absent ``<axis>`` is (1, 0, 0); a
non-unit axis is normalised (noted), a zero axis of a joint that moves is an
error; the inertia tensor of ``<inertial>`` is rotated by its origin's rpy as
R I R^T, moved to the joint frame by the parallel-axis theorem; a
``continuous`` joint is one angle (its limits are ignored, as the
specification says). Fixed joints are merged into the body of the moving joint
above them (links after the last moving joint, such as a flange or tool,
included); moving joints off the base-to-tip chain (gripper fingers) are locked
at ``locked``'s value (default 0) and merged likewise; joints on the chain
listed in ``locked`` are held too; a held ``<mimic>`` joint follows its
held master (value = multiplier * master + offset), a mimic of a moving chain
joint is refused unless it moves no mass. Each of these steps is a sentence in
:attr:`Chain.notes`. A ``floating``/``planar`` joint on the chain is an error
(not supported). ``<dynamics damping>`` is the joint's viscous friction
(motor.viscous_friction's default), ``<dynamics friction>`` the simulation's
Coulomb friction (simulation.coulomb_friction's default). Links above the base
link do not move and are left out.

Numbers are exact: a decimal of the file is the Rational of the shortest
decimal that reads back as the parser's double (the file's own text for up
to 15 significant digits); an angle not snapped to k pi/2 stays exact as
cos/sin of that Rational, and a body parameter that is then irrational is
rounded to 40 significant digits.

Chain joint i's frame F_i is the URDF child link frame of moving joint i.
The runtime parameters are the ten body parameters of each body in F_i (after
merging): m, h = m c (hx, hy, hz) and the inertia about F_i's origin (Ixx, Ixy,
Ixz, Iyy, Iyz, Izz), named m1, hx1, ..., Izz1; the kinematics are constants.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from difflib import get_close_matches
from fractions import Fraction
from pathlib import Path
from typing import Any

import sympy as sp

from derive.errors import Problem
from derive.model.chain import Body, Chain, Joint, JointType, Parameter, Transform
from derive.model.fields import Reader, inline, show, to_fraction
from derive.model.rigid import empty_body, exact_angle, merge, move, rational, snap_choice, snapping, tidy
from derive.model.urdf_rules import (chain_mimics, check_inertials, held_values, judge_findings, mattering_joints,
                                     moving_links, repair_choice)
from derive.model.urdf_xml import parse_safely
from derive.model.urdf_elements import (_BODY_NAMES, _INERTIA_INDEX, _dynamics, _dynamics_notes, _joint_field,
                                        _limits, _link_body, _link_field, _motion, _origin, _unit_axis, _value,
                                        _zero_limit_notes, angle_notes)  # noqa: F401 (re-exported)

MOVING = {"revolute": JointType.REVOLUTE, "continuous": JointType.CONTINUOUS, "prismatic": JointType.PRISMATIC}


@dataclass(frozen=True)
class UrdfChain:
    """What a URDF gives an arm: its chain and, per moving joint, the viscous
    damping of ``<dynamics damping>`` (0 when absent) and that element's field, the
    Coulomb friction of ``<dynamics friction>`` (None when absent; the simulation's
    default), the warnings (ignored elements that may change the dynamics of the
    chain: printed by every command), the links whose inertia was repaired, and per
    moving joint the reflected rotor inertia the file gives (an MJCF's ``armature``,
    the default of motor.rotor_inertia; empty for a URDF, which has none) [kg m^2], and how far
    each rpy angle kept near a multiple of pi/2 is from it [rad] (derive.model.rigid.angle_note)."""

    chain: Chain
    damping: tuple[Fraction, ...]
    damping_fields: tuple[str, ...]
    friction: tuple[Fraction | None, ...] = ()
    warnings: tuple[Problem, ...] = ()
    repaired: tuple[str, ...] = ()
    armature: tuple[Fraction, ...] = ()
    kept_angles: tuple[float, ...] = ()   # rad: how far each angle near k pi/2 kept as written is from it


def _tree(r: Reader, robot: Any) -> dict[str, Any] | None:
    """link -> its parent joint; None (problems added) unless a tree of unique names."""
    links = [link.name for link in robot.links]
    for kind, names in (("link", links), ("joint", [j.name for j in robot.joints])):
        seen: set[str] = set()
        for name in names:
            if name in seen:
                r.add(f"urdf {kind} {name!r}", f"one {kind} of each name", f"two {kind}s named {name!r}")
            seen.add(name)
    parent: dict[str, Any] = {}
    for j in robot.joints:
        for end in (j.parent, j.child):
            if end not in links:
                r.add(_joint_field(j.name, "<parent link>" if end == j.parent else "<child link>"),
                      "the name of a link of the URDF", repr(end))
        if j.child in parent:
            r.add(_link_field(j.child), "one parent joint (a URDF is a tree; a kinematic loop is not supported)",
                  f"2 parent joints, {parent[j.child].name!r} and {j.name!r}")
        parent[j.child] = j
    if r.problems:
        return None
    for start in links:
        path, link = [start], start
        while link in parent:
            link = parent[link].parent
            if link in path:
                loop = " -> ".join(path[path.index(link):] + [link])
                r.add(_link_field(start), "a link below a root (a URDF is a tree)", f"a kinematic loop {loop}")
                return None
            path.append(link)
    return parent


def name_choice(r: Reader, d: dict, key: str, names: list[str], what: str) -> str | None:
    """``d[key]`` when it is one of ``names`` (``what``: "link of the URDF", "body of the MJCF"), else
    None after adding a problem of ``arm.<key>`` listing them, with the closest names."""
    name = d.get(key)
    if not isinstance(name, str) or name not in names:
        close = get_close_matches(name, names, n=3) if isinstance(name, str) else []
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
        listed = ", ".join(map(repr, names[:12])) + (", ..." if len(names) > 12 else "")
        given = "nothing (the key is missing)" if name is None else (
            f"{show(name)}, not a {what}{hint}" if isinstance(name, str) else show(name))
        r.add(f"arm.{key}", f"the name of a {what} ({listed})", given)
        return None
    return name


def locked_table(r: Reader, value: Any, kinds: dict[str, str], rotates: dict[str, bool], word: str
                 ) -> dict[str, sp.Expr]:
    """``[arm] locked``: joint name -> held value, exact (an angle snapped as derive.model.rigid.exact_angle
    does); ``kinds``: every joint's type, ``rotates``: the movable types (whether each turns), ``word``:
    "URDF" or "MJCF". Problems (an unknown or fixed joint, a value not a finite number) added to ``r``."""
    if value is None:
        return {}
    if not isinstance(value, dict):
        r.bad("arm.locked", "a table {joint = value} of joints held at a value (rad or m)", value)
        return {}
    types = list(rotates)
    expected = f"the name of a {', '.join(types[:-1])} or {types[-1]} joint of the {word}"
    out = {}
    for name, v in value.items():
        f = f"arm.locked.{inline(name) if not isinstance(name, str) else name}"
        if kinds.get(name) not in rotates:
            close = get_close_matches(name, [n for n, k in kinds.items() if k in rotates], n=2)
            r.add(f, expected + (f" (did you mean {', '.join(map(repr, close))}?)" if close else ""),
                  "an unknown joint" if name not in kinds else f"a {kinds[name]} joint")
            continue
        x = to_fraction(v)
        if x is None:
            r.bad(f, "a finite number (rad or m)", v)
            continue
        out[name] = exact_angle(x) if rotates[kinds[name]] else rational(x)
    return out


_CHAINS: dict = {}   # urdf_chain's results in this process (a key holds the file's bytes)
_CHAIN_KEYS = ("urdf", "base_link", "tip_link", "locked", "repair_inertia", "snap_angles")


def urdf_chain(r: Reader, d: dict, base_dir: Path, gravity: Parameter, direction: sp.Matrix) -> UrdfChain | None:
    """The chain of the URDF named by the ``[arm]`` table ``d``, or None after
    adding its problems (each naming the element or arm-file field) to ``r``.
    What does not move with the chain is read leniently (derive.model.urdf_rules).

    A chain found without problems is kept for the process, keyed by the file's bytes and
    everything else it was read with: ``derive init`` reads the same URDF three times
    (the chain, the draft it certifies, the file it writes: 0.3 s each for Tiago's tree)."""
    snap = snap_choice(r, d.get("snap_angles"), "arm.snap_angles")
    if snap is False:
        return None
    with snapping(snap):
        return _cached_chain(r, d, base_dir, gravity, direction)


def _cached_chain(r: Reader, d: dict, base_dir: Path, gravity: Parameter, direction: sp.Matrix) -> UrdfChain | None:
    """:func:`urdf_chain` inside its snapping tolerance, kept for the process (urdf_chain's docstring)."""
    name = d.get("urdf")
    try:
        raw = (Path(base_dir) / name).read_bytes() if isinstance(name, str) and not r.problems else None
    except OSError:
        raw = None
    if raw is None:
        return _urdf_chain(r, d, base_dir, gravity, direction)
    key = (raw, str(Path(base_dir) / name), repr([d.get(k) for k in _CHAIN_KEYS]), repr(gravity),
           tuple(sp.sympify(x) for x in direction))
    if key not in _CHAINS:
        found = _urdf_chain(r, d, base_dir, gravity, direction)
        if found is None or r.problems:
            return found
        _CHAINS.clear()   # one file at a time: a test session reads hundreds
        _CHAINS[key] = found
    return _CHAINS[key]


def _urdf_chain(r: Reader, d: dict, base_dir: Path, gravity: Parameter, direction: sp.Matrix) -> UrdfChain | None:
    notes: list[str] = []
    doc = parse_safely(r, d.get("urdf"), base_dir)
    if doc is None:
        return None
    robot = doc.robot
    notes += doc.notes
    parent = _tree(r, robot)
    links = [link.name for link in robot.links]
    base, tip = (name_choice(r, d, key, links, "link of the URDF") for key in ("base_link", "tip_link"))
    locked = locked_table(r, d.get("locked"), {j.name: j.type for j in robot.joints},
                          {"revolute": True, "continuous": True, "prismatic": False}, "URDF")
    repair = repair_choice(r, d.get("repair_inertia"), links)
    if parent is None or base is None or tip is None or r.problems:
        return None
    if base == tip:
        r.add("arm.tip_link", f"a link below the base link {base!r} (the chain runs from base to tip)",
              f"{tip!r}: base and tip are the same link")
        return None
    path, link = [], tip
    while link != base:
        if link not in parent:
            r.add("arm.tip_link", f"a link below base_link {base!r} (the chain runs from base to tip)",
                  f"{tip!r}, whose chain to the root {link!r} does not pass {base!r}")
            return None
        path.append(parent[link])
        link = parent[link].parent
    path.reverse()
    on_path = {j.name for j in path}
    for j in path:
        if j.name not in locked and j.type in ("floating", "planar"):
            r.add(_joint_field(j.name, "type"), "revolute, continuous, prismatic or fixed on the chain from "
                  f"{base!r} to {tip!r} (a {j.type} joint is not supported: choose a base link below it or a tip "
                  "link above it)", repr(j.type))
    if r.problems:
        return None
    chain_joints = {j.name for j in path if j.type in MOVING and j.name not in locked and j.mimic is None}
    moving = moving_links(robot, base, chain_joints)
    matters = mattering_joints(robot, path, moving)
    warnings = judge_findings(r, doc.findings, moving, matters, chain_joints, notes)
    repairs = check_inertials(r, robot, moving, repair, notes)
    held = held_values(r, robot, chain_joints, locked, on_path, matters, notes)
    chain_mimics(r, path, held, chain_joints, base, tip)
    if r.problems:
        return None
    found = _build(r, robot, base, path, on_path, held, notes, gravity, direction)
    if found is None:
        return None
    chain = replace(found.chain, held=tuple((name, float(value)) for name, value in sorted(held.items())),
                    repaired=tuple((name, fix.entries) for name, fix in repairs))
    return replace(found, chain=chain, warnings=tuple(warnings), repaired=tuple(name for name, _ in repairs))


def _build(r: Reader, robot: Any, base: str, path: list, on_path: set[str], locked: dict[str, sp.Expr],
           notes: list[str], gravity: Parameter, direction: sp.Matrix) -> UrdfChain | None:
    children: dict[str, list] = {}
    for j in robot.joints:
        children.setdefault(j.parent, []).append(j)
    link_map = {link.name: link for link in robot.links}
    joints: list[Joint] = []
    bodies: list[Body] = []
    members: list[list[str]] = []
    damping: list[Fraction] = []
    friction: list[Fraction | None] = []
    merged, held = [], []
    log: list[tuple[str, str, str, float]] = []   # angles snapped to k pi/2, or kept near one (derive.model.rigid)
    zero: dict[str, list[str]] = {"velocity": [], "effort": []}   # <limit> keys of 0: no limit
    stack = [(base, -1, Transform.identity())]   # (link, owning moving joint or -1 = base, F_owner <- link)
    tip_name, tip = path[-1].child, None
    while stack:
        name, owner, T = stack.pop()
        if name == tip_name:
            tip = T
        if owner >= 0:
            bodies[owner] = merge(bodies[owner], move(_link_body(link_map[name], log), T))
            members[owner].append(name)
        for j in reversed(children.get(name, [])):
            origin = T.compose(_origin(j.origin, f"joint {j.name!r} <origin rpy>", log))
            if j.type in MOVING and j.name in on_path and j.name not in locked:
                axis = _unit_axis(r, j, notes)
                if axis is None:
                    continue
                joints.append(Joint(j.name, MOVING[j.type], tidy(origin), axis, _limits(j, zero), _joint_field(j.name)))
                bodies.append(empty_body())
                members.append([])
                damping.append(_dynamics(j, "damping") or Fraction(0))
                friction.append(_dynamics(j, "friction"))
                stack.append((j.child, len(joints) - 1, Transform.identity()))
                continue
            if j.type in MOVING or j.type in ("floating", "planar"):
                value = locked.get(j.name, sp.Integer(0))
                if j.type in MOVING and value != 0:
                    axis = _unit_axis(r, j, notes)
                    if axis is None:
                        continue
                    origin = origin.compose(_motion(axis, j.type, value))
                held.append(f"{j.name!r} at {value}")
            elif owner >= 0:
                merged.append(repr(j.name))
            stack.append((j.child, owner, tidy(origin)))
    if r.problems:
        return None
    if not joints:
        r.add("arm.tip_link", "a tip link with at least one revolute, continuous or prismatic joint between it "
              "and base_link", "a chain of fixed joints only")
        return None
    notes += angle_notes(log)
    _dynamics_notes(joints, damping, friction, notes)
    _zero_limit_notes(zero, notes)
    if merged:
        notes.append(f"fixed joints merged into the body of the moving joint above them: {', '.join(merged)}")
    if held:
        notes.append(f"joints held (locked) and their bodies merged: {', '.join(held)}")
    for j in joints:
        if j.type is JointType.CONTINUOUS:
            notes.append(f"joint {j.name!r} is continuous: one angle, its <limit lower/upper> ignored")
    params, symbolic = body_parameters(bodies, members, joints)
    vector = sp.ImmutableMatrix((gravity.symbol * sp.Matrix(direction)).applyfunc(sp.expand))
    chain = Chain(tuple(joints), tuple(symbolic), vector, tuple(params) + (gravity,), tuple(notes),
                  tip=None if tip is None or tip == Transform.identity() else tip)
    return UrdfChain(chain, tuple(damping), tuple(_joint_field(j.name, "<dynamics damping>") for j in joints),
                     tuple(friction), kept_angles=tuple(off for kind, _, _, off in log if kind == "kept"))


def body_parameters(bodies: list[Body], members: list[list[str]], joints: list[Joint], what: str = "urdf link"
                    ) -> tuple[list[Parameter], list[Body]]:
    """The ten body parameters of each body (in F_i), and the bodies in their symbols; ``members``:
    the names of what each body merges (``what``: "urdf link" or "mjcf body"), for the fields."""
    params: list[Parameter] = []
    out = []
    for i, (body, names, joint) in enumerate(zip(bodies, members, joints), 1):
        plural = what[:-1] + "ies" if what.endswith("y") else what + "s"
        where = (f"{what if len(names) == 1 else plural} {', '.join(map(repr, names))} "
                 f"(at joint {joint.name!r})" if names else f"nothing (at joint {joint.name!r})")
        entries = [body.mass, *body.first_moment] + [body.inertia[a, b] for a, b in _INERTIA_INDEX]
        units = ["kg"] + ["kg m"] * 3 + ["kg m^2"] * 6
        docs = ["mass", "first moment m c, x", "first moment m c, y", "first moment m c, z"] + [
            f"inertia about the joint frame's origin, {n[1:]}" for n in _BODY_NAMES[4:]]
        syms = []
        for name, value, unit, doc in zip(_BODY_NAMES, entries, units, docs):
            assume = {"nonnegative": True} if name in ("m", "Ixx", "Iyy", "Izz") else {"real": True}
            p = Parameter(sp.Symbol(f"{name}{i}", **assume), _value(sp.sympify(value)), unit, where,
                          f"{doc} of body {i}")
            params.append(p)
            syms.append(p.symbol)
        I = sp.Matrix(3, 3, lambda a, b: syms[4 + _INERTIA_INDEX.index((min(a, b), max(a, b)))])
        out.append(Body(syms[0], sp.ImmutableMatrix(syms[1:4]), sp.ImmutableMatrix(I)))
    return params, out

