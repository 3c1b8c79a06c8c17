"""Identified body parameters in an arm file: ``[[body_override]]`` tables (URDF and DH arms).

::

    [[body_override]]                     # derive identify writes these
    joint = "shoulder_lift_joint"         # the moving joint whose body it replaces: name or number (1-based)
    mass = 8.393                          # kg
    first_moment = [0.0, 0.0, 1.2]        # h = m c [kg m], in the joint's frame F_i
    inertia = [[0.2, 0, 0], [0, 0.2, 0], [0, 0, 0.03]]   # about F_i's origin [kg m^2], symmetric

Frames are the chain's (derive.model.chain): F_i is the joint's own frame (a
URDF: the child link's frame of the moving joint), and the body is everything
joint i moves after merging (fixed links, locked joints), so the ten numbers
replace exactly the ten runtime parameters m_i, hx_i, ..., Izz_i of a URDF arm
(a DH arm's body i is replaced likewise, its [[body]] entry then unused). At
most one override per joint. The body must be physically consistent: its
pseudo-inertia [[tr(I)/2 1 - I, h], [h^T, m]] positive semidefinite (a mass
distribution exists; Wensing, Kim, Slotine, IEEE RA-L 3(1), 2017), decided
exactly on the file's decimals. A planar ``[[link]]`` arm takes its identified
values in its link fields instead.
"""
from __future__ import annotations

from dataclasses import replace
from fractions import Fraction
from typing import Any

import sympy as sp

from derive.model.chain import Body, Chain, Parameter
from derive.model.fields import ANY, NONNEGATIVE, Reader, show
from derive.model.rules import PHYSICAL, physical

KEYS = {"joint": "the moving joint whose body this replaces: its name or number (1-based)",
        "mass": "the body's mass (kg)", "first_moment": "h = m c, 3 numbers [kg m] in the joint's frame",
        "inertia": "the 3 x 3 inertia about the joint frame's origin [kg m^2]"}
NAMES = ("m", "hx", "hy", "hz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")
_INDEX = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _joint(r: Reader, value: Any, field: str, chain: Chain) -> int | None:
    names = [j.name for j in chain.joints]
    if isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= chain.n:
        return value - 1
    if isinstance(value, str) and value in names:
        return names.index(value)
    r.bad(field, f"a moving joint of the chain: its name ({', '.join(map(repr, names[:8]))}"
                 f"{', ...' if len(names) > 8 else ''}) or its number 1..{chain.n}", value)
    return None


def _numbers(r: Reader, value: Any, field: str, shape: tuple[int, ...]) -> list | None:
    if len(shape) == 1:
        if not isinstance(value, list) or len(value) != shape[0]:
            r.bad(field, f"an array of {shape[0]} numbers", value)
            return None
        out = [r.value(x, f"{field}[{i}]", ANY[""]) for i, x in enumerate(value, 1)]
        return None if None in out else out
    if not (isinstance(value, list) and len(value) == 3 and all(isinstance(x, list) and len(x) == 3 for x in value)):
        r.bad(field, "a 3 x 3 array of numbers (kg m^2)", value)
        return None
    rows = [_numbers(r, row, f"{field}[{i}]", (3,)) for i, row in enumerate(value, 1)]
    return None if None in rows else rows


def physical_problem(entries: list[Fraction]) -> str | None:
    """Why ten exact body parameters (m, h, I about the frame's origin) have no mass
    distribution, or None (derive.model.rules.physical: every principal minor of the pseudo-inertia >= 0)."""
    return None if physical(entries) else PHYSICAL


def apply_overrides(r: Reader, value: Any, chain: Chain) -> Chain:
    """``chain`` with each ``[[body_override]]`` table's body in place of its joint's
    (problems added to ``r``; ``chain`` unchanged where a table has one)."""
    if not isinstance(value, list) or not all(isinstance(x, dict) for x in value):
        r.bad("body_override", "an array of tables ([[body_override]] sections), at most one per joint", value)
        return chain
    bodies, params, seen = list(chain.bodies), list(chain.parameters), {}
    for k, entry in enumerate(value, 1):
        f = f"body_override[{k}]"
        d = r.table(entry, f, KEYS, "a table")
        if d is None or any(key not in d for key in KEYS):
            continue
        i = _joint(r, d["joint"], f"{f}.joint", chain)
        mass = r.value(d["mass"], f"{f}.mass", NONNEGATIVE["kg"])
        h = _numbers(r, d["first_moment"], f"{f}.first_moment", (3,))
        inertia = _numbers(r, d["inertia"], f"{f}.inertia", (3, 3))
        if i is None or mass is None or h is None or inertia is None:
            continue
        if i in seen:
            r.add(f"{f}.joint", "at most one [[body_override]] per joint",
                  f"{show(d['joint'])}, overridden by body_override[{seen[i]}] already")
            continue
        seen[i] = k
        if any(inertia[a][b] != inertia[b][a] for a in range(3) for b in range(3)):
            r.bad(f"{f}.inertia", "a symmetric 3 x 3 array (kg m^2)", d["inertia"])
            continue
        entries = [mass, *h] + [inertia[a][b] for a, b in _INDEX]
        if (why := physical_problem(entries)) is not None:
            r.add(f, why, f"mass {show(d['mass'])}, first_moment {show(d['first_moment'])}, "
                          f"inertia {show(d['inertia'])}")
            continue
        bodies[i], params = _replace(chain, i, entries, f, bodies, params)
    return replace(chain, bodies=tuple(bodies), parameters=tuple(params))


def _replace(chain: Chain, i: int, entries: list[Fraction], field: str, bodies: list[Body],
             params: list[Parameter]) -> tuple[Body, list[Parameter]]:
    """Body i in ten new parameters (named as a URDF arm's), and the parameters without
    those only body i used (the new ones where the first of those stood)."""
    others = set().union(*(b.mass.free_symbols | b.first_moment.free_symbols | b.inertia.free_symbols
                           for k, b in enumerate(bodies) if k != i), *(j.origin.p.free_symbols for j in chain.joints))
    own = bodies[i].mass.free_symbols | bodies[i].first_moment.free_symbols | bodies[i].inertia.free_symbols
    drop = {s for s in own if s not in others}
    units = ("kg",) + ("kg m",) * 3 + ("kg m^2",) * 6
    fields = (f"{field}.mass",) + tuple(f"{field}.first_moment[{a}]" for a in (1, 2, 3)) + tuple(
        f"{field}.inertia[{a + 1}][{b + 1}]" for a, b in _INDEX)
    new = [Parameter(sp.Symbol(f"{name}{i + 1}", **({"nonnegative": True} if name in ("m", "Ixx", "Iyy", "Izz")
                                                     else {"real": True})),
                     value, unit, where, f"identified {name} of body {i + 1} (body_override)")
           for name, value, unit, where in zip(NAMES, entries, units, fields)]
    s = [p.symbol for p in new]
    I = sp.Matrix(3, 3, lambda a, b: s[4 + _INDEX.index((min(a, b), max(a, b)))])
    body = Body(s[0], sp.ImmutableMatrix(s[1:4]), sp.ImmutableMatrix(I))
    at = next((k for k, p in enumerate(params) if p.symbol in drop), len(params) - 1)
    kept = [p for p in params[:at] if p.symbol not in drop]
    rest = [p for p in params[at:] if p.symbol not in drop]
    return body, kept + new + rest
