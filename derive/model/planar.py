"""Planar arm files: ``[[link]]`` and ``[[point_mass]]`` tables -> a :class:`Chain`.

A planar serial chain of n >= 1 revolute joints about +z, angles relative to
the previous link (eq. a6 uses theta_2 so), theta = 0 along +x: joint 1 at the
base origin, joint i + 1 at (l_i, 0, 0) in F_i. Body i is link i with the
point masses it carries, each a lamina along its link's x axis: a link of mass
m, centre of mass at (c, 0, 0) and inertia Ic about it has
I_c = diag(0, Ic, Ic) (a point mass likewise with Ip); only m, h_x = m c and
I_zz = Ic + m c^2 enter planar motion, and the tensor is physical (Ixx + Iyy >=
Izz holds with equality).

The runtime parameters are the file's own values (issue 15, item 3): l, m,
c, Ic of each link, mass, distance and inertia of each point mass, and g. A
value the file leaves to its default is an expression of them, never a
parameter of its own: ``com`` defaults to l/2 and ``inertia = "uniform_rod"``
(the default) is m l^2 / 12, so changing m or l at run time moves them too.

A link may be massless (mass = 0, inertia 0): URDF and Drake accept such
bodies; :mod:`derive.model.singular` refuses the arm only where a joint then
moves no inertia at all.
"""
from __future__ import annotations

import numbers
import re
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import sympy as sp

from derive.model.chain import Body, Chain, Joint, JointType, Limits, Parameter, Transform
from derive.model.fields import ANY, NONNEGATIVE, POSITIVE, Num, Reader, domain
from derive.model.rigid import body_from_com, merge, translation

UNIFORM_ROD = "uniform_rod"
_ZERO = Fraction(0)
LINK_INERTIA = Num("kg m^2, about the centre of mass", _ZERO, alternative=" or 'uniform_rod' (m l^2 / 12)")
# What each field accepts: the reader checks it, and its parameter's symbol has that domain (fields.domain)
LENGTH, MASS, COM = POSITIVE["m"], NONNEGATIVE["kg"], ANY["m"]
PM_MASS, PM_DISTANCE, PM_INERTIA = POSITIVE["kg"], ANY["m"], NONNEGATIVE["kg m^2"]
LINK_KEYS = {"length": LENGTH.expected, "mass": MASS.expected, "com": None,
             "inertia": None, "viscous_friction": None}
PM_KEYS = {"link": "the number of the link that carries it", "distance": PM_DISTANCE.expected,
           "mass": PM_MASS.expected, "inertia": None, "label": None}


@dataclass(frozen=True)
class Link:
    """One link: length l, mass m, centre of mass at distance com from its joint
    along the link, inertia about the centre of mass, viscous joint friction.
    ``com_default``: the file left com out (it is l/2); ``uniform_rod``: the
    inertia is m l^2 / 12."""

    length: Fraction
    mass: Fraction
    com: Fraction
    inertia: Fraction
    viscous_friction: Fraction
    com_default: bool = False
    uniform_rod: bool = False


@dataclass(frozen=True)
class PointMass:
    """A point mass (a carried motor, a tip payload) on link ``link`` (0-based),
    at ``distance`` from that link's joint along the link."""

    link: int
    distance: Fraction
    mass: Fraction
    inertia: Fraction
    label: str


def array_of_tables(r: Reader, value: Any, field: str) -> list | None:
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        r.bad(field, f"an array of tables ([[{field}]] sections)", value)
        return None
    return value


def read_links(r: Reader, value: Any) -> list[Link] | None:
    """The links, or None when the number of joints is unknown (``value`` None: missing)."""
    if value is None or (entries := array_of_tables(r, value, "link")) is None:
        return None
    if not entries:
        r.add("link", "at least one [[link]] table (n >= 1 joints)", "an empty array (0 links)")
        return None
    links = []
    for i, entry in enumerate(entries, 1):
        f = f"link[{i}]"
        d = r.table(entry, f, LINK_KEYS, "a table")
        length = r.number(d, "length", f, LENGTH)
        mass = r.number(d, "mass", f, MASS)
        com = r.number(d, "com", f, COM, None if length is None else length / 2)
        rod = d.get("inertia", UNIFORM_ROD)
        is_rod = isinstance(rod, str) and rod == UNIFORM_ROD
        if is_rod:
            inertia = None if mass is None or length is None else mass * length ** 2 / 12
        else:
            inertia = r.value(rod, f"{f}.inertia", LINK_INERTIA)
        friction = r.number(d, "viscous_friction", f, NONNEGATIVE["N m s/rad"], _ZERO)
        links.append(Link(length, mass, com, inertia, friction, "com" not in d, is_rod))
    return links


def read_point_masses(r: Reader, value: Any, n: int | None) -> list[PointMass]:
    out = []
    for i, entry in enumerate(array_of_tables(r, value, "point_mass") or [], 1):
        f = f"point_mass[{i}]"
        d = r.table(entry, f, PM_KEYS, "a table")
        link = d.get("link")
        ok = (isinstance(link, numbers.Integral) and not isinstance(link, bool)
              and 1 <= link <= (n if n is not None else link))
        if "link" in d and not ok:
            r.bad(f"{f}.link", f"a link number from 1 to {n}" if n else "a link number >= 1", link)
        out.append(PointMass(int(link) - 1 if ok else -1, r.number(d, "distance", f, PM_DISTANCE),
                             r.number(d, "mass", f, PM_MASS),
                             r.number(d, "inertia", f, PM_INERTIA, _ZERO), r.text(d, "label", f)))
    return out


def _lamina(mass: sp.Expr, distance: sp.Expr, inertia: sp.Expr) -> Body:
    """A planar body along x: centre of mass (distance, 0, 0), I_c = diag(0, inertia, inertia)."""
    return body_from_com(mass, sp.Matrix([distance, 0, 0]), sp.diag(0, inertia, inertia))


def planar_chain(links: list[Link], point_masses: list[PointMass], gravity: Parameter,
                 direction: sp.Matrix) -> Chain:
    """The chain of a planar arm file; ``direction``: the unit vector of free
    fall in the base xy plane (3 x 1, z = 0); gravity = g direction."""
    n = len(links)
    params: dict[str, list[Parameter]] = {k: [] for k in ("l", "m", "c", "Ic", "mp", "rp", "Ip")}

    def add(kind: str, index: int, value: Fraction, unit: str, field: str, doc: str, **assume: bool) -> sp.Symbol:
        p = Parameter(sp.Symbol(f"{kind}{index}", **assume), value, unit, field, doc)
        params[kind].append(p)
        return p.symbol

    joints, bodies = [], []
    previous: sp.Symbol | None = None
    for i, link in enumerate(links, 1):
        f = f"link[{i}]"
        l = add("l", i, link.length, "m", f"{f}.length", f"length of link {i}", **domain(LENGTH))
        m = add("m", i, link.mass, "kg", f"{f}.mass", f"mass of link {i}", **domain(MASS))
        c = l / 2 if link.com_default else add("c", i, link.com, "m", f"{f}.com",
                                                 f"centre-of-mass distance of link {i} from its joint", **domain(COM))
        Ic = m * l ** 2 / 12 if link.uniform_rod else add(
            "Ic", i, link.inertia, "kg m^2", f"{f}.inertia", f"inertia of link {i} about its centre of mass",
            **domain(LINK_INERTIA))
        body = _lamina(m, c, Ic)
        for k, pm in enumerate(point_masses, 1):
            if pm.link == i - 1:
                pf = f"point_mass[{k}]"
                mp = add("mp", k, pm.mass, "kg", f"{pf}.mass", f"mass of point mass {k}", **domain(PM_MASS))
                rp = add("rp", k, pm.distance, "m", f"{pf}.distance",
                         f"distance of point mass {k} from its link's joint", **domain(PM_DISTANCE))
                Ip = add("Ip", k, pm.inertia, "kg m^2", f"{pf}.inertia",
                         f"inertia of point mass {k} about its centre", **domain(PM_INERTIA))
                body = merge(body, _lamina(mp, rp, Ip))
        origin = Transform.identity() if previous is None else translation(previous, 0, 0)
        previous = l
        joints.append(Joint(f"joint{i}", JointType.REVOLUTE, origin, sp.ImmutableMatrix([0, 0, 1]),
                            Limits(), f))
        bodies.append(body)
    index = lambda p: int(re.search(r"\d+\Z", p.symbol.name)[0])  # noqa: E731
    order = [p for kind in ("l", "m", "c", "Ic", "mp", "rp", "Ip") for p in sorted(params[kind], key=index)]
    vector = sp.ImmutableMatrix((gravity.symbol * sp.Matrix(direction)).applyfunc(sp.expand))
    return Chain(tuple(joints), tuple(bodies), vector, tuple(order) + (gravity,))
