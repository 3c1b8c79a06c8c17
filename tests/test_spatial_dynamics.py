"""The dynamics of spatial chains (URDF arms) through the chain model (issue 11.4):
J, the bias, the Coriolis matrix and gravity of every vendored URDF against
Pinocchio (test oracle only), J = J^T > 0 and J' - 2C skew-symmetric (a proof
for up to 3 joints, numeric for 6 and 7), the Euler-Lagrange reference proved
equal for a 3-joint spatial arm with a prismatic joint, URDF normalisation seen
in J and g (inertial origin, massless fixed links, a tool after the last joint)."""
from __future__ import annotations

import functools
import math
import tomllib
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import sympy as sp

from derive.dynamics.sx import to_sx
from derive.dynamics.dag import Memo
from derive.dynamics.equations import Dynamics, derive_dynamics, reference_mismatch
from derive.dynamics.program import dag_xreplace
from derive.dynamics.trigpoly import TrigRing, constant_angles
from derive.model.spec import Arm, arm_from_dict, load_arm

from .test_model_urdf import ENDS, joint, link, robot, write

URDF = Path(__file__).parent / "data" / "urdf"
VENDORED = sorted(ENDS)    # ur5, panda, kinova, the double pendulum (with and without <axis>), synthetic
STATES = 20
RTOL = 1e-10


def urdf_arm(urdf: Path, base: str, tip: str, n: int, name: str = "test_arm") -> Arm:
    """A torque-driven arm file for a URDF (unit gears, no rotor inertia), gravity -z."""
    return arm_from_dict({
        "arm": {"name": name, "urdf": str(urdf), "base_link": base, "tip_link": tip, "gravity": 9.81,
                "gravity_direction": [0, 0, -1], "actuation": "torque"},
        "motor": [{"gear_ratio": 1.0, "rotor_inertia": 0.0} for _ in range(n)],
        "controller": {"T1": 0.0, "T2": 0.2, "w": [5.0] * n}}, f"<{name}>")


def vendored_arm(name: str) -> Arm:
    path = URDF / f"{name}.toml"
    if path.exists():
        return load_arm(path)
    base, tip = ENDS[name]
    data = tomllib.loads((URDF / "double_pendulum.toml").read_text())
    return urdf_arm(URDF / f"{name}.urdf", base, tip, len(data["motor"]), name)


@functools.lru_cache(maxsize=None)
def numeric(name: str) -> tuple[Dynamics, ca.Function]:
    """The arm's dynamics and a CasADi function (q, v) -> (J, bias, C, g) with its values put in."""
    dyn = derive_dynamics(vendored_arm(name))
    return dyn, casadi_function(dyn)


def casadi_function(dyn: Dynamics) -> ca.Function:
    n = dyn.n
    q, v = ca.SX.sym("q", n), ca.SX.sym("v", n)
    env = {**{s: q[i] for i, s in enumerate(dyn.sym.theta)}, **{s: v[i] for i, s in enumerate(dyn.sym.dtheta)},
           **{s: ca.SX(float(x)) for s, x in dyn.values}}
    memo = Memo()

    def m(M) -> ca.SX:
        return ca.vertcat(*[to_sx(sp.sympify(e), env, memo) for e in M]).reshape((M.cols, M.rows)).T

    J, C = m(dyn.J), m(dyn.coriolis)
    Jdot = ca.jtimes(J, q, v)   # d/dt J(q) along q' = v, by automatic differentiation
    return ca.Function("f", [q, v], [J, m(dyn.bias), C, m(dyn.gravity), Jdot])


def pinocchio_model(dyn: Dynamics, name: str):
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(URDF / f"{name}.urdf"))
    moving = [j.name for j in dyn.chain.joints]
    lock = [model.getJointId(n) for n in model.names[1:] if n not in moving]
    model = pin.buildReducedModel(model, lock, pin.neutral(model)) if lock else model
    assert list(model.names[1:]) == moving
    return pin, model


def close(got, want) -> bool:
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    return got.shape == want.shape and np.abs(got - want).max() <= RTOL * max(np.abs(want).max(), 1e-300)


@pytest.mark.parametrize("name", VENDORED)
def test_eq12_vendored_urdf_dynamics_match_pinocchio(name: str) -> None:
    """J (crba), bias (rnea at zero acceleration), Coriolis matrix and gravity of the derived
    dynamics equal Pinocchio's at 20 random states, 1e-10 relative (continuous joints: one
    angle here, a (cos, sin) pair at the oracle)."""
    dyn, f = numeric(name)
    pin, model = pinocchio_model(dyn, name)
    data = model.createData()
    rng = np.random.default_rng(20)
    for k in range(STATES):
        q, v = rng.uniform(-3, 3, dyn.n), rng.uniform(-2, 2, dyn.n)
        qp = np.concatenate([[math.cos(x), math.sin(x)] if j.nq == 2 else [x] for j, x in zip(model.joints[1:], q)])
        J, bias, C, g, _ = (np.array(x) for x in f(q, v))
        M = pin.crba(model, data, qp)
        M = np.triu(M) + np.triu(M, 1).T
        assert close(J, M), (name, k, "J")
        assert close(bias.ravel(), pin.rnea(model, data, qp, v, np.zeros(dyn.n))), (name, k, "bias")
        assert close(C, pin.computeCoriolisMatrix(model, data, qp, v)), (name, k, "C")
        assert close(g.ravel(), pin.computeGeneralizedGravity(model, data, qp)), (name, k, "g")


def test_pinocchio_comparison_fails_for_another_arm() -> None:
    """The comparison can fail: UR5's J is not the Kinova's at the same state."""
    (_, f), (dyn, _) = numeric("ur5"), numeric("kinova")
    pin, model = pinocchio_model(dyn, "kinova")
    q = np.full(6, 0.3)
    qp = np.concatenate([[math.cos(x), math.sin(x)] if j.nq == 2 else [x] for j, x in zip(model.joints[1:], q)])
    M = pin.crba(model, model.createData(), qp)
    assert not close(np.array(f(q, q)[0]), np.triu(M) + np.triu(M, 1).T)


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_jdot_minus_2c_is_skew_and_j_positive_definite_numerically(name: str) -> None:
    """6 and 7 joints: J = J^T > 0 and J' - 2C skew-symmetric at 20 random states (J' by
    automatic differentiation of the derived J), while J' - 2C itself is not zero."""
    dyn, f = numeric(name)
    rng = np.random.default_rng(7)
    for _ in range(STATES):
        q, v = rng.uniform(-3, 3, dyn.n), rng.uniform(-2, 2, dyn.n)
        J, _, C, _, Jdot = (np.array(x) for x in f(q, v))
        S = Jdot - 2 * C
        assert np.abs(J - J.T).max() <= 1e-14 * np.abs(J).max() and np.linalg.eigvalsh(J).min() > 0
        assert np.abs(S + S.T).max() <= 1e-12 * np.abs(S).max()
        assert np.abs(S).max() > 1e-3


# -- symbolic: the 3-joint spatial arm with a prismatic joint ------------------------------

HALF_PI = "1.5707963267948966"


def three_joint(tmp: Path) -> Dynamics:
    """A 3-joint spatial arm: a revolute joint about -z, one about y behind an offset and a
    quarter turn about x, a prismatic joint along x behind a quarter turn about y; bodies
    with off-axis centres of mass and products of inertia; a tool on a fixed joint after it."""
    text = robot(link("a") + link("b", 2.0, "0.1 0 0.05", inertia=(0.02, 0.001, 0, 0.03, 0.002, 0.025))
                 + link("c", 1.0, "0.2 0.01 0", inertia=(0.01, 0, 0.001, 0.012, 0, 0.009))
                 + link("e", 0.5, "0 0 0.1", inertia=(1e-3, 0, 0, 2e-3, 0, 2e-3)) + link("tool", 0.25)
                 + joint("j1", "a", "b", xyz="0 0 0.1", axis="0 0 -1")
                 + joint("j2", "b", "c", xyz="0.3 0 0.05", rpy_=f"{HALF_PI} 0 0", axis="0 1 0")
                 + joint("j3", "c", "e", "prismatic", "0.25 0.02 0", f"0 {HALF_PI} 0", axis="1 0 0")
                 + joint("t", "e", "tool", "fixed", "0.05 0 0.02"))
    return derive_dynamics(urdf_arm(write(tmp, text), "a", "tool", 3))


def ring_of(dyn: Dynamics, exprs: list) -> tuple[TrigRing, list]:
    """``exprs`` with the arm's values put in, in the ring of sin/cos polynomials (canonical)."""
    exprs = dag_xreplace(exprs, dyn.subs)
    rot = dyn.angles
    others = set(dyn.sym.dtheta) | (set(dyn.sym.theta) - set(rot))
    F = TrigRing(rot, others, constant_angles(exprs))
    return F, F.convert(exprs)


def test_three_joint_spatial_arm_equals_the_euler_lagrange_reference_symbolically(tmp_path) -> None:
    """Recursive J and bias = the Euler-Lagrange equations, identically in q, q' (a proof)."""
    dyn = three_joint(tmp_path)
    assert [j.type.value for j in dyn.chain.joints] == ["revolute", "revolute", "prismatic"]
    assert reference_mismatch(dyn, numeric=True) is None


def test_three_joint_jdot_minus_2c_is_skew_symmetric_symbolically(tmp_path) -> None:
    """J' - 2C + (J' - 2C)^T = 0 identically in q, q' (canonical sin/cos polynomials); J' - 2C != 0."""
    dyn = three_joint(tmp_path)
    n, q, dq = dyn.n, dyn.sym.theta, dyn.sym.dtheta
    F, conv = ring_of(dyn, list(dyn.J) + list(dyn.coriolis))
    J, C = conv[:n * n], conv[n * n:]
    S = [F.d_dt(J[k], q, dq) - 2 * C[k] for k in range(n * n)]
    assert all(S[i * n + j] + S[j * n + i] == 0 for i in range(n) for j in range(n))
    assert any(S)


# -- URDF normalisation seen in the dynamics --------------------------------------------------

def test_inertial_rpy_rotates_the_inertia_into_the_joint_frame(tmp_path) -> None:
    """One body, inertia diag(1, 2, 2.5) at an inertial frame turned by yaw pi/2, centre of mass
    d = 0.5 off the x axis, joint axis x: J = 2 + m d^2 (not 1 + m d^2)."""
    m = 3.0
    text = robot(link("base") + link("body", m, "0 0.5 0", "0 0 1.5707963267948966", (1, 0, 0, 2, 0, 2.5))
                 + joint("j", "base", "body", axis="1 0 0"))
    dyn = derive_dynamics(urdf_arm(write(tmp_path, text), "base", "body", 1))
    J = dag_xreplace([dyn.J[0, 0]], dyn.subs)[0]
    assert abs(float(J) - (2 + m * 0.25)) <= 1e-15


def test_tool_after_the_last_joint_changes_gravity_as_the_closed_form_says(tmp_path) -> None:
    """A 1 kg point tool 0.2 m along the last link's x on a fixed joint (with an rpy of its own),
    joint axis y, gravity -z: g(q) gains d/dq (m g z_tool) = -1 * 9.81 * 0.2 cos q exactly."""
    base = link("a") + link("b", 1.0, "0.1 0 0", inertia=(1e-3, 0, 0, 2e-3, 0, 2e-3)) + joint("j", "a", "b", axis="0 1 0")
    tool = link("tool", 1.0) + joint("t", "b", "tool", "fixed", "0.2 0 0", "0.3 -0.7 1.1")
    plain = derive_dynamics(urdf_arm(write(tmp_path, robot(base), "a.urdf"), "a", "b", 1))
    tooled = derive_dynamics(urdf_arm(write(tmp_path, robot(base + tool), "b.urdf"), "a", "tool", 1))
    q = plain.sym.theta[0]
    for x in (sp.Rational(3, 10), sp.Rational(-2)):
        ga = dag_xreplace([plain.gravity[0]], {**plain.subs, q: x})[0]
        gb = dag_xreplace([tooled.gravity[0]], {**tooled.subs, q: x})[0]
        assert abs(float(gb - ga) - (-9.81 * 0.2 * math.cos(float(x)))) <= 1e-13


def test_dh_spatial_arm_derives_and_equals_the_euler_lagrange_reference() -> None:
    """A 3-joint DH arm (standard convention, twists of pi/2, a prismatic third joint) goes
    through the whole derivation (predictive law, observer, PID form) and its recursive J and
    bias equal the Euler-Lagrange equations identically in q, q' (a proof)."""
    import derive

    from .test_model_urdf import _dh_arm

    data = _dh_arm("standard", [[0.0, "pi/2", 0.2, 0.0], [0.3, 0.0, 0.0, 0.0], [0.0, "-pi/2", 0.1, 0.0]],
                   [{"mass": 2.0, "com": [0, -0.05, 0.02], "inertia": [[0.02, 0.001, 0], [0.001, 0.03, 0], [0, 0, 0.02]]},
                    {"mass": 1.0, "com": [-0.15, 0, 0.01], "inertia": [[0.001, 0, 0], [0, 0.01, 0], [0, 0, 0.01]]},
                    {"mass": 0.5, "com": [0, 0, -0.05]}], ["revolute", "revolute", "prismatic"])
    data["arm"]["name"] = "dh_arm"
    d = derive.derive(arm_from_dict(data))
    assert d.n == 3 and d.lumped is None and d.npid.P.shape == (3, 3)
    assert reference_mismatch(d.dynamics, numeric=True) is None


def test_inserted_massless_fixed_links_leave_the_derived_dynamics_unchanged(tmp_path) -> None:
    """Issue 11's invariance on the derived dynamics (eq. 12), not only on the chain: a massless
    link on a fixed joint of random rpy and offset before every joint leaves J, the bias and g
    unchanged at random states (1e-12)."""
    from .test_model_urdf import plain_and_inserted

    rng = np.random.default_rng(5)
    plain, busy = plain_and_inserted(rng)
    fa = casadi_function(derive_dynamics(urdf_arm(write(tmp_path, plain, "plain.urdf"), "a", "e", 3, "plain")))
    fb = casadi_function(derive_dynamics(urdf_arm(write(tmp_path, busy, "busy.urdf"), "a", "e", 3, "busy")))
    for _ in range(10):
        q, v = rng.uniform(-2, 2, 3), rng.uniform(-3, 3, 3)
        a, b = fa(q, v), fb(q, v)
        for k in (0, 1, 3):   # J, bias, g
            assert np.max(np.abs(np.array(a[k]) - np.array(b[k]))) <= 1e-12, k


def test_recursions_keep_shared_sums_fewer_operations_same_values() -> None:
    """The recursions build with SymPy's distribution of numbers over sums off
    (derive.dynamics.spatial.keep_sums): a joint offset or a -1 of a rotation
    times a shared sum stays one product. The UR5's bias built so has the same
    values as the one built distributing (1e-12), and fewer operations after CSE."""
    from derive.dynamics.identities import count_ops_cse
    from derive.dynamics.rnea import rnea
    from derive.dynamics.spatial import vec

    dyn = numeric("ur5")[0]
    args = (dyn.bodies, dyn.frames, dyn.sym.dtheta, [0] * dyn.n, vec(dyn.chain.gravity))
    kept, spread = (dag_xreplace(list(f(*args)), dyn.subs) for f in (rnea, rnea.__wrapped__))
    assert count_ops_cse(kept) < 0.95 * count_ops_cse(spread)
    q, v = ca.SX.sym("q", dyn.n), ca.SX.sym("v", dyn.n)
    env = {**dict(zip(dyn.sym.theta, ca.vertsplit(q))), **dict(zip(dyn.sym.dtheta, ca.vertsplit(v)))}
    memo = Memo()
    f = ca.Function("f", [q, v], [ca.vertcat(*[to_sx(e, env, memo) for e in kept]),
                                  ca.vertcat(*[to_sx(e, env, memo) for e in spread])])
    rng = np.random.default_rng(11)
    for _ in range(5):
        a, b = f(rng.uniform(-2, 2, dyn.n), rng.uniform(-2, 2, dyn.n))
        assert close(a, b) and np.abs(np.asarray(a)).max() > 1


def _evaluator(exprs: list, symbols: list) -> ca.Function:
    """A CasADi function of ``symbols`` computing ``exprs`` (shared subexpressions once)."""
    x = ca.SX.sym("x", len(symbols))
    memo = Memo()
    env = dict(zip(symbols, ca.vertsplit(x)))
    return ca.Function("f", [x], [ca.vertcat(*[to_sx(sp.sympify(e), env, memo) for e in exprs])])


@pytest.mark.parametrize("name", ["synthetic", "panda"])
def test_inverse_dynamics_by_one_rnea_pass_equals_j_a_plus_g(name: str) -> None:
    """Dynamics.inverse_dynamics(a) = J a + G (eq. 12) at random states and
    accelerations: the recursive form the generated laws compute (the synthetic
    arm has a prismatic joint and an off-axis joint)."""
    dyn = numeric(name)[0]   # shared with the Pinocchio tests of this module
    a = [sp.Symbol(f"acc{i}", real=True) for i in range(dyn.n)]
    mine = dag_xreplace(list(dyn.inverse_dynamics(a)), dyn.subs)
    ref = dag_xreplace(list(dyn.J * sp.Matrix(a) + dyn.G), dyn.subs)
    f = _evaluator(mine + ref, [*dyn.sym.theta, *dyn.sym.dtheta, *a])
    rng = np.random.default_rng(5)
    for _ in range(5):
        out = np.asarray(f(rng.uniform(-2, 2, 3 * dyn.n))).ravel()
        assert close(out[:dyn.n], out[dyn.n:]) and np.abs(out).max() > 1


def test_u_star_by_rnea_equals_eq15_with_motor_terms() -> None:
    """Mpc.u_star_rnea = u* of eq. (15) for the default arm (DC motors: B, the
    reflected rotor inertia and the damping in play), every symbol valued."""
    import derive
    d = derive.derive(derive.load_arm())
    s = d.dynamics.sym
    rule = dict(d.values)
    mine, ref = (dag_xreplace(list(m), rule) for m in (d.mpc.u_star_rnea, d.mpc.u_star))
    symbols = [*s.theta, *s.dtheta, *s.e, *s.de, *s.ddyd]
    f = _evaluator(mine + ref, symbols)
    rng = np.random.default_rng(6)
    for _ in range(10):
        out = np.asarray(f(rng.uniform(-2, 2, len(symbols)))).ravel()
        assert close(out[:d.n], out[d.n:]) and np.abs(out).max() > 1e-3


def test_inverse_dynamics_refuses_the_wrong_number_of_accelerations() -> None:
    dyn = numeric("panda")[0]
    with pytest.raises(ValueError, match=r"inverse_dynamics: expected 7 accelerations, got 2"):
        dyn.inverse_dynamics([0, 1])
