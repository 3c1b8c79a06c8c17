"""Planar arm files as a Chain (derive.model.planar): the same bodies as the
lumped planar form of eq. (11-12), massless links (issue 10 item 7), gravity
direction (issue 15 item 9) and parameters that are the file's own values
(issue 15 item 3)."""
from __future__ import annotations

from pathlib import Path

import pytest
import sympy as sp

import derive
from derive.dynamics.identities import matrix_is_zero
from derive.dynamics.equations import derive_dynamics
from derive.dynamics.planar import lumped_bodies
from derive.errors import SpecError
from derive.model.spec import arm_from_dict, packaged_arms
from derive.model.singular import joint_motion

from .arms import chain_dict

DATA = Path(__file__).parent / "data" / "arms"


@pytest.mark.parametrize("name", packaged_arms())
def test_packaged_arms_chain_bodies_equal_the_lumped_bodies(name: str):
    """Body i of the chain has the planar (M, hx, Io) of link i with its point masses
    (derive.dynamics.planar.lumped_bodies, read from the file's links in the plane),
    exactly; the defaults the file left out are the expressions they are
    (com = l/2, uniform rod Ic = m l^2/12)."""
    arm = derive.load_arm(name)
    for i, (old, body) in enumerate(zip(lumped_bodies(arm), arm.chain.bodies)):
        expect = [old.M, old.hx, 0, 0, old.Io]
        got = [body.mass, body.first_moment[0], body.first_moment[1], body.first_moment[2], body.inertia[2, 2]]
        for e, g in zip(expect, got):
            assert sp.expand(sp.sympify(e) - g) == 0, (name, i, e, g)
    by = {p.field: p.symbol for p in arm.chain.parameters}
    for i, joint in enumerate(arm.chain.joints):
        assert joint.axis == sp.ImmutableMatrix([0, 0, 1]) and joint.origin.R == sp.eye(3)
        assert joint.origin.p[0] == (0 if i == 0 else by[f"link[{i}].length"])
    assert arm.chain.planar


def test_uniform_rod_and_default_com_are_expressions_not_parameters():
    """my3.toml: links with inertia = "uniform_rod" and no com give parameters l, m only;
    the chain's inertia about joint 3 is m3 l3^2 / 12 + m3 (l3/2)^2 + the gripper."""
    arm = derive.load_arm(DATA / "my3.toml")
    names = [p.symbol.name for p in arm.parameters]
    assert not any(n.startswith(("c", "Ic")) for n in names), names
    assert names[:6] == ["l1", "l2", "l3", "m1", "m2", "m3"]
    assert names[-8:] == ["T1", "T2", "w1", "w2", "w3", "kr1", "kr2", "kr3"]   # kr: the momentum observer's K
    by = {p.symbol.name: p for p in arm.parameters}
    assert (by["m3"].field, by["m3"].unit, str(by["m3"].value)) == ("link[3].mass", "kg", "3/10")
    m3, l3, mp3, rp3, Ip3 = (by[k].symbol for k in ("m3", "l3", "mp3", "rp3", "Ip3"))
    izz = arm.chain.bodies[2].inertia[2, 2]
    assert sp.expand(izz - (m3 * l3 ** 2 / 12 + m3 * l3 ** 2 / 4 + mp3 * rp3 ** 2 + Ip3)) == 0
    assert sp.expand(arm.chain.bodies[2].first_moment[0] - (m3 * l3 / 2 + mp3 * rp3)) == 0


def test_massless_link_carrying_a_point_mass_is_accepted():
    """f9_massless_link.toml (issue 10 item 7): link 2 has mass 0 and inertia 0 and
    carries 0.2 kg at 0.3 m: its body is the point mass alone, J_22 = 0.2 * 0.3^2."""
    arm = derive.load_arm(DATA / "f9_massless_link.toml")
    body = arm.chain.bodies[1]
    values = dict(arm.chain.values())
    assert body.mass.xreplace(values) == sp.Rational(1, 5)
    assert body.first_moment.xreplace(values) == sp.Matrix([sp.Rational(3, 50), 0, 0])
    assert body.inertia.xreplace(values) == sp.diag(0, sp.Rational(9, 500), sp.Rational(9, 500))
    d = derive.derive(arm)
    assert d.J[1, 1] == sp.Rational(9, 500)


def test_massless_joint_that_moves_nothing_is_refused_naming_it():
    """A massless last link with nothing on it and no rotor: joint 2 moves no inertia."""
    data = chain_dict(2)
    data["link"][1].update(mass=0.0, inertia=0.0)
    data["point_mass"] = [p for p in data["point_mass"] if p["link"] != 2]
    data["motor"][1]["rotor_inertia"] = 0.0
    with pytest.raises(SpecError, match=r"link\[2\]: expected an inertia about joint 2 > 0 at every "
                       r"configuration .* got 0 \(nothing beyond the joint has inertia about its axis\)"):
        arm_from_dict(data)
    data["motor"][1]["rotor_inertia"] = 1e-6   # a rotor alone makes J_22 > 0
    assert arm_from_dict(data).n == 2


def test_massless_joint_singular_only_at_zero_is_refused():
    """Link 2 massless with a point mass on joint 2's axis, link 1 massless too: nothing
    has inertia about joint 2 anywhere; and a point mass only on joint 2 makes J_22 = 0."""
    data = chain_dict(2)
    data["link"][1].update(mass=0.0, inertia=0.0)
    data["point_mass"] = [p for p in data["point_mass"] if p["link"] != 2]
    data["point_mass"].append({"link": 2, "distance": 0.0, "mass": 0.5})
    data["motor"][1]["rotor_inertia"] = 0.0
    with pytest.raises(SpecError, match=r"link\[2\]: expected an inertia about joint 2"):
        arm_from_dict(data)


def _gravity_torque(arm) -> sp.Matrix:
    """dV/dq from the chain alone: V = -sum m_i gravity . (position of body i's centre of mass)."""
    chain = arm.chain
    q = [sp.Symbol(f"q{i + 1}", real=True) for i in range(chain.n)]
    V, pose = sp.Integer(0), None
    for i, body in enumerate(chain.bodies):
        step = joint_motion(chain, i, q[i])
        pose = step if pose is None else pose.compose(step)
        V -= (chain.gravity.T * (pose.R * body.first_moment + body.mass * pose.p))[0, 0]
    return sp.Matrix([sp.diff(V, x) for x in q]).xreplace(dict(chain.values())), q


def test_ceiling_arm_gravity_torque_is_the_floor_arms_negated():
    """gravity_direction = [0, 1] (a ceiling-mounted arm) gives the gravity vector
    (0, g, 0) and the negated gravity torque, in the chain and through the dynamics."""
    floor = chain_dict(3, gravity=9.81)
    ceiling = chain_dict(3, gravity=9.81)
    ceiling["arm"]["gravity_direction"] = [0, 1]
    a, b = arm_from_dict(floor), arm_from_dict(ceiling)
    g = next(p.symbol for p in b.chain.parameters if p.field == "arm.gravity")
    assert a.chain.gravity == sp.ImmutableMatrix([0, -g, 0]) and b.chain.gravity == sp.ImmutableMatrix([0, g, 0])
    (ta, q), (tb, _) = _gravity_torque(a), _gravity_torque(b)
    assert ta != sp.zeros(3, 1) and sp.expand(ta + tb) == sp.zeros(3, 1)
    da, db = derive_dynamics(a), derive_dynamics(b)
    values = dict(da.values)
    ga, gb = (d.gravity.xreplace(values) for d in (da, db))
    assert sp.expand(ga + gb) == sp.zeros(3, 1)
    theta = {t: x for t, x in zip(da.sym.theta, q)}
    assert matrix_is_zero(ga.xreplace(theta) - ta, q)


def test_sideways_gravity_direction_is_normalised_exactly():
    data = chain_dict(2, gravity=9.81)
    data["arm"]["gravity_direction"] = [1, 1]
    chain = arm_from_dict(data).chain
    g = next(p.symbol for p in chain.parameters if p.field == "arm.gravity")
    # rational (the proofs' ring holds rationals), exactly of length g, within 2^-60 of (1, 1)/sqrt 2
    unit = chain.gravity / g
    assert all(x.is_Rational for x in unit) and unit[2] == 0
    assert (unit.T * unit)[0, 0] == 1
    assert all(abs(sp.N(x - sp.sqrt(2) / 2, 40)) < 1e-17 for x in unit[:2])


@pytest.mark.parametrize("value, match", [
    ([0, 0], "a non-zero direction"),
    ([0, 1, 0], "an array of 2 numbers [x, y]"),
    ([0, "up"], "arm.gravity_direction[2]: expected a finite number"),
])
def test_bad_gravity_direction_is_named(value, match):
    data = chain_dict(2, gravity=9.81)
    data["arm"]["gravity_direction"] = value
    with pytest.raises(SpecError, match=match.replace("[", r"\[").replace("]", r"\]")):
        arm_from_dict(data)
