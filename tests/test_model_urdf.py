"""URDF and DH arm files as a Chain (derive.model.urdf, derive.model.dh): URDF's
normalisation rules, exactness, merging and locking, checked on the chain and
against Pinocchio (the chain's J(q) and gravity torque, computed from the chain
alone by tests/chainnum.py)."""
from __future__ import annotations

import functools
import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from derive.model.chain import JointType
from derive.model.fields import Reader
from derive.model.rigid import rpy
from derive.model.spec import SPATIAL_DOWN, arm_from_dict, gravity_parameter, unit_direction
from derive.model.urdf import urdf_chain

from .arms import chain_dict
from .chainnum import NumericChain

URDF = Path(__file__).parent / "data" / "urdf"
ENDS = {"ur5": ("base_link", "tool0"), "panda": ("panda_link0", "panda_hand_tcp"),
        "kinova": ("base", "j2s6s200_end_effector"), "double_pendulum": ("base_link", "link2"),
        "double_pendulum_noaxis": ("base_link", "link2"), "synthetic": ("base_link", "tool")}
HALF_PI = "1.5707963267948966"


def load(name_or_path, base: str | None = None, tip: str | None = None, locked: dict | None = None, g: str = "9.81"):
    """The UrdfChain of a vendored URDF (by name) or a file; problems raise AssertionError."""
    if isinstance(name_or_path, str) and base is None and locked is None:
        return _vendored(name_or_path)
    return _load(name_or_path, base, tip, locked, g)


@functools.lru_cache(maxsize=None)
def _vendored(name: str):
    return _load(name, None, None, None, "9.81")


def _load(name_or_path, base, tip, locked, g):
    path = URDF / f"{name_or_path}.urdf" if isinstance(name_or_path, str) else name_or_path
    if base is None:
        base, tip = ENDS[name_or_path]
    table = {"urdf": str(path), "base_link": base, "tip_link": tip}
    if locked is not None:
        table["locked"] = locked
    r = Reader()
    found = urdf_chain(r, table, Path("/"), gravity_parameter(Fraction(g)), unit_direction(SPATIAL_DOWN))
    assert not r.problems, r.problems
    return found


def robot(body: str) -> str:
    return f'<?xml version="1.0"?>\n<robot name="t">\n{body}\n</robot>\n'


def link(name: str, mass: float = 0.0, xyz: str = "0 0 0", rpy_: str = "0 0 0",
         inertia: tuple = (0, 0, 0, 0, 0, 0)) -> str:
    if mass == 0 and not any(inertia):
        return f'<link name="{name}"/>'
    ixx, ixy, ixz, iyy, iyz, izz = inertia
    return (f'<link name="{name}"><inertial><origin xyz="{xyz}" rpy="{rpy_}"/><mass value="{mass}"/>'
            f'<inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" izz="{izz}"/></inertial></link>')


def joint(name: str, parent: str, child: str, kind: str = "revolute", xyz: str = "0 0 0", rpy_: str = "0 0 0",
          axis: str | None = "0 0 1", extra: str = "") -> str:
    ax = f'<axis xyz="{axis}"/>' if axis is not None else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy_}"/>{ax}<limit lower="-3" upper="3" effort="10" velocity="2"/>'
            f'{extra}</joint>')


def write(tmp_path: Path, text: str, name: str = "t.urdf") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# -- against Pinocchio --------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(ENDS))
def test_vendored_urdf_chain_matches_pinocchio(name: str):
    """J(q) and the gravity torque of the chain (fingers locked at 0, continuous joints one
    angle) equal Pinocchio's crba and computeGeneralizedGravity at 5 random states to 1e-10."""
    pin = pytest.importorskip("pinocchio")
    found = load(name)
    chain = found.chain
    num = NumericChain(chain)
    model = pin.buildModelFromUrdf(str(URDF / f"{name}.urdf"))
    moving = [j.name for j in chain.joints]
    lock = [model.getJointId(n) for n in model.names[1:] if n not in moving]
    model = pin.buildReducedModel(model, lock, pin.neutral(model)) if lock else model
    assert list(model.names[1:]) == moving
    data = model.createData()
    rng = np.random.default_rng(11)
    for _ in range(5):
        q = rng.uniform(-3, 3, chain.n)
        qp = np.concatenate([[math.cos(x), math.sin(x)] if j.nq == 2 else [x] for j, x in zip(model.joints[1:], q)])
        M = pin.crba(model, data, qp)
        M = np.triu(M) + np.triu(M, 1).T
        G = pin.computeGeneralizedGravity(model, data, qp)
        J = num.inertia_matrix(q)
        assert np.max(np.abs(J - M)) <= 1e-10 * np.max(np.abs(M))
        assert np.max(np.abs(num.gravity_torque(q) - G)) <= 1e-10 * np.max(np.abs(G))


# -- normalisation on the chain -----------------------------------------------------------

def test_rpy_is_extrinsic_xyz_and_exact_for_multiples_of_half_pi(tmp_path):
    """rpy="0 -1.5707963267948966 0" gives rows (0, 0, -1), (0, 1, 0), (1, 0, 0) exactly."""
    text = robot(link("a") + link("b", 1.0, "0.1 0 0", inertia=(1e-3, 0, 0, 1e-3, 0, 1e-3))
                 + joint("j", "a", "b", rpy_=f"0 -{HALF_PI} 0"))
    chain = load(write(tmp_path, text), "a", "b").chain
    R = chain.joints[0].origin.R
    assert R == sp.ImmutableMatrix([[0, 0, -1], [0, 1, 0], [1, 0, 0]])
    # extrinsic X-Y-Z: R = Rz(yaw) Ry(pitch) Rx(roll), checked against a general triple
    r, p, y = 0.3, -0.2, 0.5
    Rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    Ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    Rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    got = np.array(rpy(sp.Rational(3, 10), sp.Rational(-1, 5), sp.Rational(1, 2)).evalf(20).tolist(), dtype=float)
    assert np.max(np.abs(got - Rz @ Ry @ Rx)) <= 1e-15


def test_inertial_rpy_rotates_the_tensor(tmp_path):
    """One body, inertia diag(1, 2, 2.5), inertial rpy yaw = pi/2, centre of mass at d on y,
    joint axis x: its inertia about the axis through the joint is 2 + m d^2, not 1 + m d^2."""
    m, d = 3.0, 0.4
    text = robot(link("a") + link("b", m, f"0 {d} 0", f"0 0 {HALF_PI}", (1, 0, 0, 2, 0, 2.5))
                 + joint("j", "a", "b", axis="1 0 0"))
    chain = load(write(tmp_path, text), "a", "b").chain
    body, values = chain.bodies[0], chain.values()
    about_axis = (chain.joints[0].axis.T * body.inertia * chain.joints[0].axis)[0, 0].xreplace(values)
    assert about_axis == 2 + sp.Rational(3) * sp.Rational(2, 5) ** 2


def test_absent_axis_is_x_and_equals_explicit_axis():
    a, b = load("double_pendulum").chain, load("double_pendulum_noaxis").chain
    assert [j.axis for j in b.joints] == [sp.ImmutableMatrix([1, 0, 0])] * 2
    assert a.joints == b.joints and a.bodies == b.bodies
    assert [p.value for p in a.parameters] == [p.value for p in b.parameters]


def test_non_unit_axis_is_normalised_and_noted():
    chain = load("synthetic").chain
    elbow = next(j for j in chain.joints if j.name == "elbow")
    assert elbow.axis == sp.ImmutableMatrix([0, 0, 1])
    assert any("'elbow'" in n and "normalised" in n for n in chain.notes)
    pitch = next(j for j in chain.joints if j.name == "shoulder_pitch")
    assert pitch.axis == sp.ImmutableMatrix([0, -1, 0])
    assert [j.type for j in chain.joints].count(JointType.PRISMATIC) == 1


def test_a_urdf_read_again_in_one_process_gives_its_new_contents_and_a_problem_again(tmp_path):
    # urdf_chain keeps a chain found without problems for the process (derive init reads one URDF three
    # times); the key holds the file's bytes, so an edited file is read afresh, and a refusal is never kept
    body = link("base") + link("l1", 2.0, inertia=(0.1, 0, 0, 0.1, 0, 0.1)) + joint("j1", "base", "l1")
    path = write(tmp_path, robot(body))
    first = _load(path, "base", "l1", None, "9.81")
    assert _load(path, "base", "l1", None, "9.81") is first                    # the same file: kept
    write(tmp_path, robot(body.replace('<mass value="2.0"/>', '<mass value="3.0"/>')))
    masses = [p.value for p in _load(path, "base", "l1", None, "9.81").chain.parameters if p.unit == "kg"]
    assert masses == [Fraction(3)]
    write(tmp_path, robot(body.replace('<mass value="2.0"/>', '<mass value="-3.0"/>')))
    for _ in range(2):
        r = Reader()
        table = {"urdf": str(path), "base_link": "base", "tip_link": "l1"}
        assert urdf_chain(r, table, Path("/"), gravity_parameter(Fraction("9.81")), unit_direction(SPATIAL_DOWN)) is None
        assert any("mass" in p.field for p in r.problems), r.problems


def test_continuous_joint_is_one_angle():
    chain = load("kinova").chain
    assert chain.n == 6
    kinds = [j.type for j in chain.joints]
    assert kinds.count(JointType.CONTINUOUS) == 3
    assert all(j.limits.lower is None for j in chain.joints if j.type is JointType.CONTINUOUS)


def test_off_chain_joints_are_locked_and_noted():
    chain = load("panda").chain
    assert chain.n == 7
    assert any("'panda_finger_joint1' at 0" in n and "'panda_finger_joint2' at 0" in n for n in chain.notes)
    # held open at 0.04 m, each finger's mass moves away from the hand: the body changes
    open_ = load("panda", locked={"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}).chain
    assert any("'panda_finger_joint1' at 1/25" in n for n in open_.notes)
    assert open_.bodies[6] == chain.bodies[6]   # same symbols ...
    moved = [a.value != b.value for a, b in zip(open_.parameters, chain.parameters)]
    assert any(moved[60:70]) and not any(moved[:60])   # ... other values, body 7 only


def _direct_body(links: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]):
    """(m, c, I about c) of rigidly joined links, each (m, R, p, c_local, I_local) with pose (R, p)."""
    mass = sum(x[0] for x in links)
    com = sum(x[0] * (x[1] @ x[3] + x[2]) for x in links) / mass
    inertia = np.zeros((3, 3))
    for m, R, p, c, I in links:
        r = R @ c + p - com
        inertia += R @ I @ R.T + m * (r @ r * np.eye(3) - np.outer(r, r))
    return mass, com, inertia


def _np_rpy(r, p, y):
    return np.array(rpy(sp.Float(r), sp.Float(p), sp.Float(y)).evalf(20).tolist(), dtype=float)


def test_fixed_joint_merging_conserves_mass_centre_and_inertia(tmp_path):
    """link b and c (fixed, rpy (0.2, -0.4, 0.7), offset) form body 1: its (m, c, I_c)
    equals a direct computation of the two rigid bodies; a massless d after it adds nothing."""
    Ib, Ic = (0.01, 0.001, -0.002, 0.02, 0.0005, 0.015), (0.004, 0, 0.0003, 0.005, 0, 0.006)
    text = robot(link("a") + link("b", 1.5, "0.1 0.02 -0.03", "0.1 0.2 0.3", Ib)
                 + link("c", 0.7, "0.05 0 0.01", "0 0.5 0", Ic) + link("d")
                 + joint("j", "a", "b") + joint("f", "b", "c", "fixed", "0.3 0.1 0", "0.2 -0.4 0.7")
                 + joint("f2", "c", "d", "fixed", "0.1 0 0", "1 2 3"))
    found = load(write(tmp_path, text), "a", "d")
    body, values = found.chain.bodies[0], found.chain.values()
    m = float(body.mass.xreplace(values))
    h = np.array(body.first_moment.xreplace(values).evalf(30).tolist(), dtype=float).ravel()
    Io = np.array(body.inertia.xreplace(values).evalf(30).tolist(), dtype=float)

    def tensor(t):
        ixx, ixy, ixz, iyy, iyz, izz = t
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    Rb, Rc = _np_rpy(0.1, 0.2, 0.3), _np_rpy(0, 0.5, 0)
    Rf = _np_rpy(0.2, -0.4, 0.7)
    mass, com, Icom = _direct_body([
        (1.5, np.eye(3), np.zeros(3), np.array([0.1, 0.02, -0.03]), Rb @ tensor(Ib) @ Rb.T),
        (0.7, Rf, np.array([0.3, 0.1, 0]), np.array([0.05, 0, 0.01]), Rc @ tensor(Ic) @ Rc.T)])
    assert abs(m - mass) <= 1e-15 and np.max(np.abs(h / m - com)) <= 1e-15
    I_about_com = Io - m * (com @ com * np.eye(3) - np.outer(com, com))
    assert np.max(np.abs(I_about_com - Icom)) <= 1e-15
    assert any("'f'" in n and "'f2'" in n for n in found.chain.notes)


def _inv_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) with Rz(yaw) Ry(pitch) Rx(roll) = R (pitch away from +-pi/2)."""
    return (math.atan2(R[2, 1], R[2, 2]), -math.asin(R[2, 0]), math.atan2(R[1, 0], R[0, 0]))


def plain_and_inserted(rng: np.random.Generator) -> tuple[str, str]:
    """A 3-joint chain (revolute x, revolute y, prismatic x; bodies with products of inertia) and
    the same chain with a massless link on a fixed joint of random rpy and offset before every
    joint, the next joint's origin expressed from it: two URDFs of one arm, base a, tip e."""
    I1, I2, I3 = (0.02, 0.001, 0, 0.03, 0.002, 0.025), (0.01, 0, 0.001, 0.012, 0, 0.009), (1e-3, 0, 0, 2e-3, 0, 2e-3)
    bodies = (link("a") + link("b", 2.0, "0.1 0 0.05", "0.1 0 0", I1) + link("c", 1.0, "0.2 0.01 0", "0 0 0.3", I2)
              + link("e", 0.5, "0 0 0.1", inertia=I3))
    origins = [("0 0 0.1", "0 0 0"), ("0.3 0 0.05", f"{HALF_PI} 0 0"), ("0.25 0.02 0", "0 0.4 -0.2")]
    plain = robot(bodies + joint("j1", "a", "b", xyz=origins[0][0], rpy_=origins[0][1])
                  + joint("j2", "b", "c", xyz=origins[1][0], rpy_=origins[1][1], axis="0 1 0")
                  + joint("j3", "c", "e", "prismatic", origins[2][0], origins[2][1], axis="1 0 0"))
    inserted, parents = "", {"j1": "a", "j2": "b", "j3": "c"}
    for k, name in enumerate(("j1", "j2", "j3")):
        angles, offset = rng.uniform(-1, 1, 3), rng.uniform(-0.2, 0.2, 3)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = _np_rpy(*angles), offset
        xyz, rpy_text = origins[k]
        O = np.eye(4)
        O[:3, :3] = _np_rpy(*[float(sp.sympify(x)) for x in rpy_text.split()])
        O[:3, 3] = [float(x) for x in xyz.split()]
        rest = np.linalg.inv(T) @ O
        inserted += link(f"x{k}") + joint(f"f{k}", parents[name], f"x{k}", "fixed",
                                          " ".join(repr(float(v)) for v in offset),
                                          " ".join(repr(float(v)) for v in angles))
        parents[name] = f"x{k}"
        origins[k] = (" ".join(repr(float(v)) for v in rest[:3, 3]), " ".join(repr(v) for v in _inv_rpy(rest[:3, :3])))
    busy = robot(bodies + inserted + joint("j1", parents["j1"], "b", xyz=origins[0][0], rpy_=origins[0][1])
                 + joint("j2", parents["j2"], "c", xyz=origins[1][0], rpy_=origins[1][1], axis="0 1 0")
                 + joint("j3", parents["j3"], "e", "prismatic", origins[2][0], origins[2][1], axis="1 0 0"))
    return plain, busy


def test_inserted_massless_fixed_links_leave_the_bodies_unchanged(tmp_path):
    """Between every pair of joints of a 3-joint chain, a massless link on a fixed joint with an
    arbitrary rpy and offset, the next joint's origin expressed from it: the bodies (in the moving
    joints' frames) are unchanged exactly and J, G agree to 1e-12."""
    rng = np.random.default_rng(3)
    plain, busy = plain_and_inserted(rng)
    a = load(write(tmp_path, plain, "plain.urdf"), "a", "e").chain
    b = load(write(tmp_path, busy, "busy.urdf"), "a", "e").chain
    assert a.bodies == b.bodies and [p.value for p in a.parameters] == [p.value for p in b.parameters]
    na, nb = NumericChain(a), NumericChain(b)
    for _ in range(5):
        q = rng.uniform(-2, 2, 3)
        assert np.max(np.abs(na.inertia_matrix(q) - nb.inertia_matrix(q))) <= 1e-12
        assert np.max(np.abs(na.gravity_torque(q) - nb.gravity_torque(q))) <= 1e-12


def test_tool_on_a_fixed_joint_after_the_last_joint_joins_the_last_body(tmp_path):
    """A 1 kg point tool 0.2 m along the last link's x on a fixed joint: body n gains exactly
    m = 1, h = (0.2, 0, 0), I_o = 0.04 (yy, zz)."""
    base = link("a") + link("b", 1.0, "0.1 0 0", inertia=(1e-3, 0, 0, 2e-3, 0, 2e-3)) + joint("j", "a", "b")
    without = load(write(tmp_path, robot(base), "a.urdf"), "a", "b").chain
    with_tool = load(write(tmp_path, robot(base + link("tool", 1.0) + joint(
        "t", "b", "tool", "fixed", "0.2 0 0", f"{HALF_PI} 0 0")), "b.urdf"), "a", "tool").chain
    va, vb = without.values(), with_tool.values()
    da = [sp.sympify(x).xreplace(vb) - sp.sympify(y).xreplace(va) for x, y in zip(
        [with_tool.bodies[0].mass, *with_tool.bodies[0].first_moment, *with_tool.bodies[0].inertia],
        [without.bodies[0].mass, *without.bodies[0].first_moment, *without.bodies[0].inertia])]
    tool = sp.Rational(1, 5)
    assert da == [1, tool, 0, 0, 0, 0, 0, 0, tool ** 2, 0, 0, 0, tool ** 2]


def test_urdf_runtime_parameters_are_ten_per_body():
    chain = load("ur5").chain
    names = [p.symbol.name for p in chain.parameters]
    assert len(names) == 10 * 6 + 1 and names[:10] == ["m1", "hx1", "hy1", "hz1", "Ixx1", "Ixy1", "Ixz1",
                                                         "Iyy1", "Iyz1", "Izz1"]
    assert names[-1] == "g" and chain.gravity == sp.ImmutableMatrix([0, 0, -chain.parameters[-1].symbol])
    assert "shoulder_link" in chain.parameters[0].field


# -- DH tables ----------------------------------------------------------------------------

def _dh_arm(convention: str, table: list, bodies: list, joints: list | None = None) -> dict:
    data = {"arm": {"name": "dh", "gravity": 9.81, "actuation": "torque"},
            "dh": {"convention": convention, "table": table}, "body": bodies,
            "controller": {"T1": 0.0, "T2": 0.5, "w": [1.0] * len(table)}}
    if joints:
        data["dh"]["joints"] = joints
    return data


def test_dh_fraction_of_pi_is_exact():
    data = _dh_arm("standard", [[0.0, "pi/2", 0.1, 0.0], [0.3, "-pi/4", 0.0, "pi"]],
                   [{"mass": 1.0, "com": [0, 0, 0.05]}, {"mass": 0.5, "com": [-0.1, 0, 0]}])
    chain = arm_from_dict(data).chain
    # joint 2's origin: Tz(0.1) Rx(pi/2) of row 1, then theta = pi of row 2: exact entries
    assert chain.joints[1].origin.R == sp.ImmutableMatrix([[-1, 0, 0], [0, 0, -1], [0, -1, 0]])
    assert chain.joints[1].origin.p == sp.ImmutableMatrix([0, 0, sp.Rational(1, 10)])
    # body 2 given in DH frame 2 = F_2 Tx(0.3) Rx(-pi/4): centre of mass at x = 0.3 - 0.1
    values = chain.values()
    assert chain.bodies[1].first_moment.xreplace(values) == sp.Matrix([sp.Rational(1, 10), 0, 0])
    data["body"][1]["inertia"] = [[0.01, 0, 0], [0, 0.02, 0], [0, 0, 0.02]]
    inertia = arm_from_dict(data).chain.bodies[1].inertia
    assert inertia.xreplace(arm_from_dict(data).chain.values())[1, 1] == sp.Rational(2, 100) + sp.Rational(
        1, 2) * sp.Rational(2, 10) ** 2   # Rx(-pi/4) mixes yy and zz, both 0.02: exact


@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_dh_planar_arm_equals_the_planar_arm_file(convention: str):
    """A 3-link planar chain (a = l, alpha = 0) written as a DH table gives the planar arm's J and G."""
    planar = arm_from_dict(chain_dict(3, gravity=9.81))
    links, pms = planar.links, planar.point_masses
    bodies = []
    for i, l in enumerate(links):
        m = float(l.mass) + sum(float(p.mass) for p in pms if p.link == i)
        c = (float(l.mass * l.com) + sum(float(p.mass * p.distance) for p in pms if p.link == i)) / m
        izz = float(l.inertia + l.mass * l.com ** 2) + sum(float(p.inertia + p.mass * p.distance ** 2)
                                                            for p in pms if p.link == i) - m * c * c
        x = c - float(l.length) if convention == "standard" else c   # standard: frame i at the link's end
        bodies.append({"mass": m, "com": [x, 0, 0], "inertia": [[0, 0, 0], [0, izz, 0], [0, 0, izz]]})
    lengths = [float(l.length) for l in links]
    table = ([[a, 0, 0, 0] for a in lengths] if convention == "standard"
             else [[a, 0, 0, 0] for a in [0.0] + lengths[:-1]])
    data = _dh_arm(convention, table, bodies)
    data["arm"]["gravity_direction"] = [0, -1, 0]
    dh = NumericChain(arm_from_dict(data).chain)
    ref = NumericChain(planar.chain)
    for q in np.random.default_rng(5).uniform(-3, 3, (4, 3)):
        assert np.max(np.abs(dh.inertia_matrix(q) - ref.inertia_matrix(q))) <= 1e-12
        assert np.max(np.abs(dh.gravity_torque(q) - ref.gravity_torque(q))) <= 1e-12


def test_dh_prismatic_joint_moves_along_z():
    data = _dh_arm("modified", [[0, 0, 0, 0], [0.2, "-pi/2", 0.1, 0]], [{"mass": 1.0}, {"mass": 2.0}],
                   ["revolute", "prismatic"])
    chain = arm_from_dict(data).chain
    assert chain.joints[1].type is JointType.PRISMATIC
    # body 2 (2 kg, at F_2's origin) is at (0.2, 0, 0) + Rx(-pi/2) (0, 0, 0.1 + q2)
    num = NumericChain(chain)
    R, p = num.poses(np.array([0.0, 0.3]))[1]
    assert np.allclose(p, [0.2, 0.4, 0.0], atol=1e-15)
    assert abs(num.gravity_torque(np.array([0.0, 0.3]))[1]) <= 1e-15   # the slide is horizontal here


@pytest.mark.parametrize("name, n", [("panda", 7), ("ur5", 6), ("kinova", 6), ("double_pendulum", 2),
                                     ("synthetic", 4)])
def test_example_arm_files_load(name: str, n: int):
    """tests/data/urdf/<name>.toml (written by derive init): torque-actuated arms of n joints."""
    import derive
    from derive.model.chain import Actuation

    arm = derive.load_arm(URDF / f"{name}.toml")
    assert arm.n == n and arm.name == name
    assert all(a.actuation is Actuation.TORQUE for a in arm.actuators)
    assert arm.chain.gravity[2] == -arm.chain.parameters[10 * n].symbol   # g along -z of the base
