"""What of a URDF moves with the chain, and the rules that depend on it.

Strict where it matters, lenient elsewhere: a link *moves with the chain*
when it is merged into the body of a moving chain joint (below a chain joint
through fixed joints or held off-chain joints); a joint *matters* when it is
on the base-to-tip path or its child link moves with the chain. For these, a
number that does not parse and a non-physical inertia are errors and an
ignored element that may change the dynamics is a warning; everything else
(the mobile base's antennas of a Tiago, a sensor frame above the base) is
read leniently: a note, never an error.

Held joints (:func:`held_values`): a moving joint off the chain, or one listed
in ``locked``, is held at a value: ``locked``'s, else, for a ``<mimic
joint="m" multiplier="k" offset="c">``, k times m's held value plus c
(URDF's rule), else 0. A mimic of a joint that moves on the chain cannot be
held: the serial-chain model has one coordinate per chain joint and a body
fixed in its joint's frame, so a body turned by a second function of a chain
coordinate is refused (unless nothing with mass hangs below it: then it is
held at 0 with a note, exactly, since it changes nothing).
"""
from __future__ import annotations

from fractions import Fraction
from typing import Any

import sympy as sp

from derive.errors import Problem
from derive.model.fields import Reader
from derive.model.inertia_repair import Repair, nearest_physical, violation
from derive.model.rigid import inertia_problem, rational
from derive.model.urdf_xml import INERTIA_KEYS, Finding

MOVING_TYPES = ("revolute", "continuous", "prismatic")
_INDEX = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def moving_links(robot: Any, base: str, chain_joints: set[str]) -> set[str]:
    """The links merged into a moving chain joint's body (below a chain joint)."""
    children: dict[str, list] = {}
    for j in robot.joints:
        children.setdefault(j.parent, []).append(j)
    out: set[str] = set()
    stack = [(base, False)]
    while stack:
        link, moving = stack.pop()
        if moving:
            out.add(link)
        for j in children.get(link, []):
            stack.append((j.child, moving or j.name in chain_joints))
    return out


def mattering_joints(robot: Any, path: list, moving: set[str]) -> set[str]:
    """The joints on the base-to-tip path and those whose child moves with the chain."""
    return {j.name for j in path} | {j.name for j in robot.joints if j.child in moving}


def judge_findings(r: Reader, findings: list[Finding], links: set[str], joints: set[str], chain: set[str],
                   notes: list[str]) -> list[Problem]:
    """Bad numbers (and elements given twice, :attr:`Finding.twice`) of what matters become
    problems of ``r``; elsewhere those are warnings (the first of the elements given twice read);
    ignored elements that may change the dynamics of what matters are returned as warnings (one per element and
    kind of thing ignored, naming every link or joint; a ``<dynamics>`` only on a moving
    chain joint of ``chain``: a held joint's damping changes nothing); the rest notes."""
    grouped: dict[tuple, list[str]] = {}
    warnings = []
    for f in findings:
        matters = f.name in (links if f.kind == "link" else joints)
        if f.number:
            if matters:
                r.problems.append(f.problem)
            elif f.twice:
                off = " (not on the chain, read leniently)" if f.kind in ("link", "joint") else ""
                warnings.append(Problem(f"{f.problem.field}{off}", f.problem.expected, f.problem.given))
            else:
                notes.append(f"{f.problem.field} (not on the chain, not read): expected {f.problem.expected}, "
                             f"got {f.problem.given}")
            continue
        dynamics = f.dynamics and (f.name in chain or "<dynamics>" not in f.problem.field)
        key = (f.kind, f.problem.field.split("'", 2)[-1], f.problem.expected, f.problem.given, matters and dynamics)
        grouped.setdefault(key, []).append(f.name)
    for (kind, where, expected, given, warn), names in grouped.items():
        owner = f"urdf {kind} {names[0]!r}" if len(names) == 1 else (
            f"urdf {kind}s {', '.join(map(repr, names[:4]))}{', ...' if len(names) > 4 else ''} ({len(names)} {kind}s)")
        problem = Problem(f"{owner}{where}", expected, given)
        if warn:
            warnings.append(problem)
        else:
            notes.append(f"not read: {problem}")
    return warnings


def _tensor(link: Any) -> list[list[Fraction]]:
    t = link.inertial.inertia
    entries = [Fraction(repr(float(getattr(t, k) or 0.0))) for k in INERTIA_KEYS]
    return [[entries[_INDEX.index((min(i, j), max(i, j)))] for j in range(3)] for i in range(3)]


def repair_choice(r: Reader, value: Any, links: list[str]) -> bool | set[str]:
    """``[arm] repair_inertia``: true/false, or a list of link names (problems added)."""
    if value is None or isinstance(value, bool):
        return bool(value)
    field = "arm.repair_inertia"
    if not isinstance(value, list) or not all(isinstance(x, str) for x in value):
        r.bad(field, "true (repair every link's inertia that is not physical), false, or a list of link names",
              value)
        return False
    for i, name in enumerate(value, 1):
        if name not in links:
            r.add(f"{field}[{i}]", "the name of a link of the URDF", f"{name!r}, not a link of the URDF")
    return set(value)


def check_inertials(r: Reader, robot: Any, moving: set[str], repair: bool | set[str],
                    notes: list[str]) -> list[tuple[str, Repair]]:
    """Masses and inertias: strict for the links that move with the chain (a repair
    where ``repair`` asks for it: true or the link's name), a note for the others.
    Returns the repairs made; the parsed ``robot``'s tensors are replaced by them."""
    repairs = []
    for link in robot.links:
        inertial = link.inertial
        if inertial is None:
            continue
        field = f"urdf link {link.name!r} <inertial>"
        strict = link.name in moving
        asked = repair is True or (isinstance(repair, set) and link.name in repair)
        mass = inertial.mass
        if mass is not None and mass < 0:
            expected = "a finite number >= 0 (kg)" + ("; repair_inertia repairs the inertia tensor, not a negative "
                                                      "mass" if asked and strict else "")
            if strict:
                r.add(f"{field}<mass value>", expected, repr(mass))
            else:
                notes.append(f"{field}<mass value> (not on the chain, not used): expected {expected}, got {mass!r}")
            continue
        if inertial.inertia is None:
            continue
        I = _tensor(link)
        why = inertia_problem(sp.Matrix(3, 3, lambda i, j: rational(I[i][j])))
        if why is None:
            if isinstance(repair, set) and link.name in repair:
                notes.append(f"link {link.name!r}: listed in repair_inertia, but its inertia is physical: "
                             "nothing repaired")
            continue
        shown = " ".join(f"{k}={float(getattr(inertial.inertia, k) or 0.0):g}" for k in INERTIA_KEYS)
        if not strict:
            notes.append(f"{field}<inertia> (not on the chain, not used): expected {why}, got {shown}: "
                         f"{violation(I)}")
            continue
        if not asked:
            r.add(f"{field}<inertia>", f"{why}, in kg m^2 about the centre of mass",
                  f"{shown}: {violation(I)}; to move it to the nearest physical tensor, add "
                  f"repair_inertia = [\"{link.name}\"] under [arm] (derive init --repair-inertia does)")
            continue
        fix = nearest_physical(I)
        for key, x in zip(INERTIA_KEYS, fix.entries):
            setattr(inertial.inertia, key, float(x))
        notes.append(f"link {link.name!r}: inertia repaired (repair_inertia) to the nearest physical tensor "
                     f"(Frobenius norm, principal axes kept): {fix.describe()}")
        repairs.append((link.name, fix))
    return repairs


def held_values(r: Reader, robot: Any, chain_joints: set[str], locked: dict[str, sp.Expr], on_path: set[str],
                matters: set[str], notes: list[str]) -> dict[str, sp.Expr]:
    """The value of every held moving joint (off the chain, or on it and locked or a mimic
    of a held joint): locked's, else its mimic's rule, else 0 (module docstring).
    Problems (a mimic cycle, a mimic of an unknown or fixed joint, an off-chain mimic of a
    moving chain joint that carries mass) are added to ``r`` for the joints that matter."""
    joints = {j.name: j for j in robot.joints}
    values: dict[str, sp.Expr] = {}
    mass_below = _mass_below(robot)

    failed: set[str] = set()

    def value(name: str, trail: tuple[str, ...]) -> sp.Expr | None:
        if name not in values and name not in failed:
            result = follow(name, trail)
            if result is None:
                failed.add(name)
            else:
                values[name] = result
        return values.get(name)

    def follow(name: str, trail: tuple[str, ...]) -> sp.Expr | None:
        j = joints[name]
        if name in locked:
            if j.mimic is not None and name in matters:
                notes.append(f"joint {name!r}: held at its locked value, its <mimic joint={j.mimic.joint!r}> "
                             "not followed")
            return locked[name]
        if j.mimic is None:
            return sp.Integer(0)
        master, strict = j.mimic.joint, name in matters
        field = f"urdf joint {name!r} <mimic joint>"
        if master not in joints or joints[master].type not in MOVING_TYPES:
            what = "an unknown joint" if master not in joints else f"a {joints[master].type} joint"
            return _bad(r, notes, strict, field, "the name of a revolute, continuous or prismatic joint of the URDF",
                        f"{master!r}, {what}")
        if master in trail:
            cycle = " -> ".join(trail[trail.index(master):] + (name, master))
            return _bad(r, notes, strict, field, "a joint that does not mimic back (a mimic chain ends at a joint "
                        "that moves on its own)", f"{master!r}, a mimic cycle {cycle}")
        if master in chain_joints:
            if name in on_path:
                return None   # a mimic on the chain of a chain joint: chain_mimics refuses it
            if not mass_below.get(j.child, False):
                notes.append(f"joint {name!r}: mimics chain joint {master!r} but nothing with mass hangs below it: "
                             "held at 0 (exact: it moves no mass)")
                return sp.Integer(0)
            return _bad(r, notes, strict, field, f"a mimic of a held joint (joint {name!r} is off the chain and "
                        f"follows chain joint {master!r}: the chain's bodies cannot move by a second function of "
                        f"its coordinate); lock {name!r} (locked = {{ {name} = 0.0 }} under [arm]) or remove its "
                        "<mimic>", f"<mimic joint={master!r}> moving {_mass_text(robot, j.child)}")
        base = value(master, trail + (name,))
        if base is None:
            return None
        k = rational(j.mimic.multiplier if j.mimic.multiplier is not None else 1.0)
        c = rational(j.mimic.offset if j.mimic.offset is not None else 0.0)
        result = sp.expand(k * base + c)
        if name in matters:
            notes.append(f"joint {name!r}: follows its <mimic> {master!r} ({k} * {base} + {c}): held at {result}")
        return result

    for j in robot.joints:
        if j.type not in MOVING_TYPES:
            if j.mimic is not None and j.name in matters:
                notes.append(f"joint {j.name!r}: <mimic> on a {j.type} joint ignored (it does not move)")
            continue
        if j.name in chain_joints and j.name not in locked:
            continue
        value(j.name, ())
    return values


def chain_mimics(r: Reader, path: list, held: dict[str, sp.Expr], chain_joints: set[str], base: str,
                 tip: str) -> None:
    """A mimic joint on the path that follows a moving chain joint: refused."""
    for j in path:
        if j.type in MOVING_TYPES and j.mimic is not None and j.name not in held and j.mimic.joint in chain_joints:
            r.add(f"urdf joint {j.name!r} <mimic>", f"a joint without <mimic> on the chain from {base!r} to {tip!r} "
                  f"(it follows chain joint {j.mimic.joint!r}: derive's chain has one coordinate per joint); lock it "
                  f"(locked = {{ {j.name} = 0.0 }} under [arm]) or remove the <mimic>",
                  f"<mimic joint={j.mimic.joint!r}>")


def _bad(r: Reader, notes: list[str], strict: bool, field: str, expected: str, given: str) -> sp.Expr | None:
    """A problem of a joint that matters (None: not held), else a note and the joint held at 0."""
    if strict:
        r.add(field, expected, given)
    else:
        notes.append(f"{field} (not on the chain, held at 0): expected {expected}, got {given}")
        return sp.Integer(0)
    return None


def _mass_below(robot: Any) -> dict[str, bool]:
    """link -> whether it or a link below it has mass > 0."""
    children: dict[str, list[str]] = {}
    for j in robot.joints:
        children.setdefault(j.parent, []).append(j.child)
    mass = {link.name: bool(link.inertial is not None and (link.inertial.mass or 0) > 0) for link in robot.links}
    memo: dict[str, bool] = {}

    def below(link: str) -> bool:
        if link not in memo:
            memo[link] = False   # a loop is refused elsewhere; never recurse forever
            memo[link] = mass.get(link, False) or any(below(c) for c in children.get(link, []))
        return memo[link]
    return {name: below(name) for name in mass}


def _mass_text(robot: Any, link: str) -> str:
    m = next((x.inertial.mass for x in robot.links if x.name == link and x.inertial is not None), None)
    return f"link {link!r} ({m:g} kg) and what hangs below it" if m else f"link {link!r} and the masses below it"
