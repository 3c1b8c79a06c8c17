"""The [arm] table of an arm file and the checks on what it describes: its kind (planar, DH, URDF, MJCF),
name, gravity and direction, no null values, and a body no joint moves."""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from derive.errors import Problem
from derive.model.actuators import actuation_value, terms
from derive.model.chain import Actuation, Chain
from derive.model.controller import _MISSING, _ZERO
from derive.model.fields import ANY, NONNEGATIVE, Reader, show
from derive.model.fields import path as field_path
from derive.model.names import name_check
from derive.model.singular import unmoved_joint


ARM_KEYS = {"name": "a lowercase C identifier (the prefix of the generated code)",
            "description": None, "gravity": None, "gravity_direction": None, "actuation": None,
            "urdf": None, "base_link": None, "tip_link": None, "locked": None, "repair_inertia": None,
            "snap_angles": None,
            "mjcf": None, "base_body": None, "tip_body": None}


URDF_ONLY = ("base_link", "tip_link", "repair_inertia", "snap_angles")


MJCF_ONLY = ("base_body", "tip_body")


FILE_ONLY = ("locked",)   # a URDF's or an MJCF's


KINEMATICS = ("one [[link]] table per joint, base to tip (a planar arm), a [dh] table with [[body]] tables, "
              "or urdf = \"robot.urdf\" or mjcf = \"robot.xml\" under [arm]")


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


def _moves_inertia(r: Reader, arm) -> None:
    """Every joint of ``arm`` (derive.model.spec.Arm) must move some inertia at q = 0, else J is singular
    (issue 10, item 7)."""
    values = {p.symbol: p.rational for p in arm.parameters}
    problem = unmoved_inertia(arm.chain, [terms(a)[2] for a in arm.actuators], values)
    if problem is not None:
        r.problems.append(problem)


_UNMOVED: list = []   # [(key, unmoved_joint's answer)]: the last in this process


def unmoved_inertia(chain: Chain, reflected: list, values: dict) -> Problem | None:
    """The problem of the first joint of ``chain`` that moves no inertia (J singular) with
    the reflected rotor inertias ``reflected``, or None. The last answer is kept for the process
    (the same chain, rotors and values give the same: derive init loads its draft and its file,
    0.1 s of 50-digit arithmetic each on 7 joints)."""
    from sympy import sympify

    used = {p.symbol for p in chain.parameters}.union(*(sympify(r).free_symbols for r in reflected))
    values = {s: v for s, v in values.items() if s in used}   # the chain's and the rotors' (not the controller's)
    key = (chain, tuple(reflected), tuple(sorted(values.items(), key=lambda kv: str(kv[0]))))
    if _UNMOVED and _UNMOVED[0][0] == key:
        found = _UNMOVED[0][1]
    else:
        found = unmoved_joint(chain, reflected, values)
        _UNMOVED[:] = [(key, found)]
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
