"""Denavit-Hartenberg arm files: ``[dh]`` and ``[[body]]`` tables -> a :class:`Chain`.

::

    [dh]
    convention = "standard"        # or "modified" (Craig)
    # one row per joint, base to tip: [a (m), alpha (rad), d (m), theta (rad)]
    table = [[0, "pi/2", 0.089159, 0], [-0.425, 0, 0, 0]]
    joints = ["revolute", "revolute"]   # optional; "prismatic": the joint variable is d

    [[body]]                       # one per row: the link joint i moves
    mass = 3.7                     # kg (0: massless)
    com = [0.0, -0.02561, 0.00193] # m, in the link's DH frame (default: its origin)
    inertia = [[0.0103, 0, 0], [0, 0.0103, 0], [0, 0, 0.00666]]  # kg m^2 about the com,
                                   # axes of the DH frame (default: 0, a point mass)

Conventions (Spong, Hutchinson, Vidyasagar 2006, sec. 3.2; Craig 2005, sec. 3.4):
standard: A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i), frame i at the distal
end of link i; modified: A_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i),
frame i at joint i, and row i holds (a_{i-1}, alpha_{i-1}, d_i, theta_i). The
joint variable q_i adds to theta_i (revolute) or d_i (prismatic); theta_i and
d_i in the table are its offsets. An angle is a number of radians (within
1e-8 rad of a multiple of pi/2 it is that multiple exactly) or a fraction of pi
written as text ("pi/2", "-pi/4", "2*pi/3"), which is exact; ``snap_angles = 1e-05`` under ``[dh]``
(rad, 1e-8 to 1e-3) takes the angles that close to a multiple of pi/2 as that multiple (a paper's 1.5708:
derive.model.rigid.snapping).

In the chain, joint i's frame F_i has z along joint i's axis: the DH frame
i - 1 turned by theta_i (standard) or the DH frame i (modified). Each body is
given in its DH frame and moved into F_i exactly. The runtime parameters are
the file's own values: per body m, com (cx, cy, cz) and the six inertia
entries (Ixx, Ixy, Ixz, Iyy, Iyz, Izz); the kinematics (a, alpha, d, theta)
are constants.
"""
from __future__ import annotations

from fractions import Fraction
from typing import Any

import sympy as sp

from derive.model.chain import Body, Chain, Joint, JointType, Limits, Parameter, Transform
from derive.model.fields import ANY, NONNEGATIVE, Num, Reader, to_fraction
from derive.model.rigid import (body_from_com, exact_angle, inertia_problem, move, parse_pi, rot_x, rot_z, rotation,
                                snap_choice, snapping, tidy, translation)

CONVENTIONS = ("standard", "modified")
DH_KEYS = {"convention": "'standard' or 'modified' (Craig)",
           "table": "an array of rows [a, alpha, d, theta], one per joint", "joints": None, "snap_angles": None}
BODY_KEYS = {"mass": NONNEGATIVE["kg"].expected, "com": None, "inertia": None}
ROW = "[a (m), alpha (rad), d (m), theta (rad)]"
ANGLE = "a finite number of radians or a fraction of pi as text ('pi/2', '-pi/4')"
_TENSOR_ENTRY = Num("kg m^2")
_INERTIA_NAMES = (("Ixx", 0, 0), ("Ixy", 0, 1), ("Ixz", 0, 2), ("Iyy", 1, 1), ("Iyz", 1, 2), ("Izz", 2, 2))


def _angle(r: Reader, value: Any, field: str) -> sp.Expr | None:
    if isinstance(value, str) and (x := parse_pi(value)) is not None:
        return x
    x = to_fraction(value)
    if x is None:
        r.bad(field, ANGLE, value)
        return None
    return exact_angle(x)


def _length(r: Reader, value: Any, field: str) -> sp.Expr | None:
    x = r.value(value, field, ANY["m"])
    return None if x is None else sp.Rational(x.numerator, x.denominator)


def _rows(r: Reader, d: dict) -> list[tuple[sp.Expr, ...]] | None:
    table = d.get("table")
    if not isinstance(table, list) or not table:
        r.bad("dh.table", f"an array of rows {ROW}, one per joint (n >= 1)", table)
        return None
    rows, ok = [], True
    for i, row in enumerate(table, 1):
        f = f"dh.table[{i}]"
        if not isinstance(row, list) or len(row) != 4:
            r.bad(f, f"4 numbers {ROW}", row)
            ok = False
            continue
        entry = (_length(r, row[0], f"{f}.a"), _angle(r, row[1], f"{f}.alpha"),
                 _length(r, row[2], f"{f}.d"), _angle(r, row[3], f"{f}.theta"))
        ok = ok and None not in entry
        rows.append(entry)
    return rows if ok else None


def _types(r: Reader, value: Any, n: int) -> list[JointType]:
    if value is None:
        return [JointType.REVOLUTE] * n
    if not isinstance(value, list) or len(value) != n:
        r.bad("dh.joints", f"an array of {n} joint types ('revolute' or 'prismatic'), one per row", value)
        return [JointType.REVOLUTE] * n
    out = []
    for i, v in enumerate(value, 1):
        if v not in ("revolute", "prismatic"):
            r.bad(f"dh.joints[{i}]", "'revolute' or 'prismatic'", v)
        out.append(JointType.PRISMATIC if v == "prismatic" else JointType.REVOLUTE)
    return out


def _vector3(r: Reader, value: Any, field: str) -> list[Fraction] | None:
    if value is None:
        return [Fraction(0)] * 3
    if not isinstance(value, list) or len(value) != 3:
        r.bad(field, "an array of 3 numbers [x, y, z] (m, in the link's DH frame)", value)
        return None
    out = [r.value(x, f"{field}[{i}]", ANY["m"]) for i, x in enumerate(value, 1)]
    return None if None in out else out


def _tensor(r: Reader, value: Any, field: str) -> list[list[Fraction]] | None:
    if value is None:
        return [[Fraction(0)] * 3 for _ in range(3)]
    if not (isinstance(value, list) and len(value) == 3 and all(isinstance(row, list) and len(row) == 3
                                                                for row in value)):
        r.bad(field, "a 3 x 3 array of numbers (kg m^2, about the centre of mass)", value)
        return None
    out = [[r.value(x, f"{field}[{i}][{j}]", _TENSOR_ENTRY)
            for j, x in enumerate(row, 1)] for i, row in enumerate(value, 1)]
    if any(x is None for row in out for x in row):
        return None
    why = inertia_problem(sp.Matrix(3, 3, lambda i, j: sp.Rational(out[i][j].numerator, out[i][j].denominator)))
    if why is not None:
        r.bad(field, f"{why} (kg m^2, about the centre of mass)", value)
        return None
    return out


def _body(r: Reader, entry: Any, i: int, params: list[Parameter]) -> Body | None:
    f = f"body[{i}]"
    d = r.table(entry, f, BODY_KEYS, "a table")
    if d is None:
        return None
    mass = r.number(d, "mass", f, NONNEGATIVE["kg"])
    com = _vector3(r, d.get("com"), f"{f}.com")
    tensor = _tensor(r, d.get("inertia"), f"{f}.inertia")
    if mass is None or com is None or tensor is None:
        return None

    def add(name: str, value: Fraction, unit: str, field: str, doc: str, **assume: bool) -> sp.Symbol:
        p = Parameter(sp.Symbol(f"{name}{i}", **assume), value, unit, field, doc)
        params.append(p)
        return p.symbol

    m = add("m", mass, "kg", f"{f}.mass", f"mass of body {i}", nonnegative=True)
    c = [add(f"c{axis}", com[k], "m", f"{f}.com[{k + 1}]", f"centre of mass of body {i}, {axis} (DH frame {i})",
             real=True) for k, axis in enumerate("xyz")]
    I = sp.zeros(3, 3)
    for name, a, b in _INERTIA_NAMES:
        s = add(name, tensor[a][b], "kg m^2", f"{f}.inertia[{a + 1}][{b + 1}]",
                f"inertia of body {i} about its centre of mass, {name[1:]}", **({"nonnegative": True} if a == b else
                                                                                  {"real": True}))
        I[a, b] = I[b, a] = s
    return body_from_com(m, sp.Matrix(c), I)


def dh_chain(r: Reader, dh: Any, bodies: Any, gravity: Parameter, direction: sp.Matrix) -> Chain | None:
    """The chain of a DH arm file, or None after adding its problems to ``r``."""
    d = r.table(dh, "dh", DH_KEYS, "a table [dh] with convention and table")
    if d is None:
        return None
    convention = d.get("convention")
    if "convention" in d and convention not in CONVENTIONS:
        r.bad("dh.convention", "'standard' (Denavit-Hartenberg) or 'modified' (Craig)", convention)
    snap = snap_choice(r, d.get("snap_angles"), "dh.snap_angles")
    with snapping(None if snap is False else snap):
        rows = _rows(r, d) if "table" in d else None
    n = len(rows) if rows else None
    types = _types(r, d.get("joints"), n) if n else []
    if not isinstance(bodies, list) or not all(isinstance(b, dict) for b in bodies):
        r.bad("body", f"an array of tables ([[body]] sections), one per row of dh.table", bodies)
        return None
    if n is not None and len(bodies) != n:
        r.add("body", f"one [[body]] table per row of dh.table: {n}",
              f"{len(bodies)} [[body]] table{'' if len(bodies) == 1 else 's'}")
        return None
    params: list[Parameter] = []
    raw = [_body(r, b, i, params) for i, b in enumerate(bodies, 1)]
    if not rows or None in raw or convention not in CONVENTIONS or r.problems:
        return None
    joints, chain_bodies = [], []
    before = Transform.identity()   # F_{i-1} <- DH frame i-1 (standard) or identity (modified)
    for i, ((a, alpha, dd, theta), kind, body) in enumerate(zip(rows, types, raw), 1):
        if convention == "standard":
            offset = rotation(rot_z(theta)) if kind is JointType.REVOLUTE else rotation(rot_z(theta)).compose(
                translation(0, 0, dd))
            origin = before.compose(offset)
            after = (translation(0, 0, dd) if kind is JointType.REVOLUTE else Transform.identity()).compose(
                translation(a, 0, 0)).compose(rotation(rot_x(alpha)))
            body = move(body, tidy(after))
            before = after
        else:
            origin = rotation(rot_x(alpha)).compose(translation(a, 0, 0)).compose(rotation(rot_z(theta))).compose(
                translation(0, 0, dd))
        joints.append(Joint(f"joint{i}", kind, tidy(origin), sp.ImmutableMatrix([0, 0, 1]), Limits(),
                            f"dh.table[{i}]"))
        chain_bodies.append(body)
    vector = sp.ImmutableMatrix((gravity.symbol * sp.Matrix(direction)).applyfunc(sp.expand))
    return Chain(tuple(joints), tuple(chain_bodies), vector, tuple(params) + (gravity,))

