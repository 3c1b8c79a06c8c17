"""Issue 21: MuJoCo's integration of the arm's own URDF as the plant, against derive's plant.

Friction off (``--mujoco-friction off``: MuJoCo's joint damping is derive's bv, no friction loss,
no limits, the same [simulation] mismatch), the two plants integrate the same equations with the
same classical RK4 at the same step h = sample_time / substeps, u held over each sample: their
truncation errors are the same function of the state, so the trajectories differ only by how
each evaluates the dynamics in double precision (MuJoCo's recursive algorithms in its body
frames, derive's CasADi kernels of exact values), about 1e-16 relative per evaluation, and by
how each holds the parameters: MuJoCo keeps every body's inertia in principal axes (an
eigendecomposition), which moves the mass matrix by up to PARAM_REL = 1e-12 of its largest entry
(measured 6e-14). Over the default experiment (30 s, 60,000 RK4 steps at h = 0.5 ms) the first
accumulates to at most about 60,000 x 1e-16 x 2 rad = 1.2e-11 rad in a contracting closed loop,
the second, an acceleration error of PARAM_REL |theta''| integrated twice, to PARAM_REL
max|theta''| T^2 / 2. The stated tolerance of a run is the sum, TOL = 1e-9 rad (a factor 100 over
the first) + PARAM_REL max|theta''| T^2 / 2: about 2e-8 rad for the runs that track here
(|theta''| up to about 40 rad/s^2; measured at most 4e-13 rad), 4.6e-7 rad for the Kinova under MPC
alone, whose wrist, pushed by the default disturbance, spins at 27 rad/s with accelerations of
1,000 rad/s^2 (measured 1.2e-8 rad: the one run where the second term shows). This holds while RK4
is stable in the plant's stiffest mode, h lambda <= 2.785 (derive.sim.plant.stiffest_mode: the
damping and the smooth Coulomb friction's slope over the joint inertia); beyond, both
integrations are wrong and their rounding differences grow (the Kinova's light wrist at 4 steps
per sample: 1.7e-5 rad), so the Kinova runs at 16 steps per sample, and derive simulate warns.

With the URDF's friction on (each joint's <dynamics friction> set in a copy of the vendored
file: MuJoCo's friction loss, a dry-friction constraint that derive's plant models only as its
smooth law, here at the unmodified arm's [simulation] values), DOBC and
NPID still track: their steady-state error stays below TRACKING[arm] on every joint (the observer,
eq. 21-27, and NPID's integral action, eq. 34-38, take the friction as a disturbance; measured
with MuJoCo 4.0: UR5 4.0 mrad at 2 N m, Panda 0.74 mrad at 0.5 N m, Kinova 22 mrad at 0.3 N m
with its 100 times slower observer w = 0.05/s, double pendulum 0.03 mrad at 0.05 N m, where MPC
alone, eq. 15, leaves 106, 139, 5300 and 1300 mrad); the difference from derive's plant is
reported by ``compare``, not asserted.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from derive.control.pipeline import derive
from derive.model.spec import load_arm
from derive.sim.plants import DerivedPlant, build, compare, select
from derive.sim.simulate import metrics
from tests.mujoco_arms import arm_copy

TOL = 1e-9          # rad: MuJoCo's and derive's plant, friction off (module docstring)
PARAM_REL = 1e-12   # MuJoCo's compiled mass matrix against derive's J, relative to its largest entry
ARMS = ("ur5", "panda", "kinova", "double_pendulum", "synthetic")
FRICTION = {"ur5": 2.0, "panda": 0.5, "kinova": 0.3, "double_pendulum": 0.05, "synthetic": 1.0}   # N m, the test's
TRACKING = {"ur5": 5e-3, "panda": 1e-3, "kinova": 3e-2, "double_pendulum": 1e-4, "synthetic": 5e-3}   # rad


def tolerance(tr, s) -> float:
    """The stated tolerance of a run (module docstring): TOL + PARAM_REL max|theta''| T^2 / 2."""
    acc = float(np.max(np.abs(np.diff(tr.dtheta, axis=0)))) / s.sample_time if len(tr.t) > 1 else 0.0
    return TOL + PARAM_REL * acc * s.duration ** 2 / 2


@pytest.fixture(scope="module", params=ARMS)
def case(request, tmp_path_factory):
    """One arm: its derivation and one compiled library with both plants' loops."""
    name = request.param
    arm = load_arm(arm_copy(tmp_path_factory.mktemp(name), name))
    d = derive(arm)
    mj = select(arm, "mujoco", "off")
    return name, arm, d, mj, build(d, sources=(mj, DerivedPlant()))


@pytest.mark.parametrize("controller", ("mpc", "dobc", "npid"))
def test_mujoco_and_derived_plant_agree_without_friction(case, controller):
    """Issue 21: over the default experiment, theta on MuJoCo minus theta on derive's plant
    stays within the stated tolerance on every joint, for MPC (eq. 15), DOBC (eq. 27) and NPID
    (eq. 34)."""
    name, arm, d, mj, loop = case
    s = arm.simulation
    a = mj.run(d, loop, s, controller)
    b = DerivedPlant().run(d, loop, s, controller)
    assert a.failure is None and b.failure is None, (a.failure, b.failure)
    assert len(a.t) == len(b.t) == round(s.duration / s.sample_time)
    moved = np.max(np.abs(b.theta), axis=0)
    assert moved[0] > 0.5, f"{name}: joint 1 hardly moved ({moved[0]:.3g} rad): the comparison would say little"
    diff = compare([a], [b], {"name": "derive"})
    bound = tolerance(b, s)
    assert diff["max_theta_difference"] <= bound, (name, controller, bound, diff["controllers"][controller])
    assert np.max(np.abs(a.u - b.u)) <= 1e-6 * max(1.0, float(np.max(np.abs(b.u)))), (name, controller)


def test_mujoco_model_has_derives_parameters_when_friction_is_off(case):
    """The MuJoCo model of the comparison has derive's numbers: its mass matrix at a pose is
    derive's J (armature = rotor inertia included) to PARAM_REL of its largest entry, its gravity the arm
    file's, no friction loss, damping = bv + [simulation] viscous_friction, RK4 at h."""
    import mujoco

    name, arm, d, mj, _ = case
    s = arm.simulation
    c = mj.model(d, s)
    m = c.model
    data = mujoco.MjData(m)
    data.qpos[c.qadr] = np.linspace(0.1, 0.7, d.n)
    mujoco.mj_forward(m, data)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, data, M)
    M = M[np.ix_(c.dadr, c.dadr)]
    from derive.dynamics.program import lambdify
    from derive.sim.plant import true_plant

    values = dict(zip((sym for sym, _ in d.values), true_plant(d, s).values))
    J = np.array(lambdify(list(d.dynamics.sym.theta) + list(values), list(d.dynamics.J))(
        *np.linspace(0.1, 0.7, d.n), *values.values()), dtype=float).reshape(d.n, d.n)
    assert np.max(np.abs(M - J)) <= PARAM_REL * np.max(np.abs(J)), (name, M - J)
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4 and math.isclose(m.opt.timestep,
                                                                               s.sample_time / s.substeps)
    assert np.allclose(m.opt.gravity, [0, 0, -9.81])
    assert not np.any(m.dof_frictionloss)
    bv = [values[a.viscous_friction] for a in d.dynamics.chain.actuators]
    assert np.allclose(m.dof_damping[c.dadr], np.array(bv) + np.array(s.viscous_friction), rtol=1e-15, atol=0)
    assert c.description["beyond_derive"] == [] and c.description["friction"] == "off"


def test_dobc_and_npid_track_on_mujoco_with_the_urdfs_friction(case, tmp_path):
    """With the URDF's friction on (MuJoCo's friction loss; derive's plant keeps the unmodified arm's), DOBC and
    NPID keep the steady-state error below TRACKING[arm] on every joint; the difference from
    derive's plant is reported (finite, named), not asserted."""
    name, arm, d, _, loop = case
    rough = load_arm(arm_copy(tmp_path, name, friction=FRICTION[name]))
    mj = select(rough, "mujoco", "file")
    s = arm.simulation
    desc = mj.describe(d, s)
    assert sum("friction loss" in x for x in desc["beyond_derive"]) == d.n, desc["beyond_derive"]
    assert mj.model(d, s).model.dof_frictionloss[mj.model(d, s).dadr].tolist() == [FRICTION[name]] * d.n
    for controller in ("dobc", "npid"):
        tr = mj.run(d, loop, s, controller)
        assert tr.failure is None, tr.failure
        settled = [m["steady_state_error"] for m in metrics(tr, s)]
        defined = [x for x in settled if isinstance(x, float)]
        assert len(defined) == d.n and max(defined) < TRACKING[name], (name, controller, settled)
        report = compare([tr], [DerivedPlant().run(d, loop, s, controller)], {"name": "derive"})
        assert math.isfinite(report["max_theta_difference"]) and report["max_theta_difference"] > TOL


def test_rk4_stability_is_the_condition_of_the_agreement(tmp_path):
    """The tolerance needs RK4 stable in the plant's stiffest mode: the double pendulum with 0.05 N m
    of smooth Coulomb friction on its light second joint at 4 steps per sample (stiffest_mode says
    unstable and asks for more steps) lets the two plants drift apart beyond TOL within 2 s; at the
    steps it asks for, they agree."""
    from dataclasses import replace

    from derive.sim.plant import RK4_REAL_LIMIT, stiffest_mode

    arm = load_arm(arm_copy(tmp_path, "double_pendulum", {"substeps": 4, "duration": 2.0,
                                                           "coulomb_friction": [0.05, 0.05]}))
    d = derive(arm)
    s = arm.simulation
    coarse = stiffest_mode(d, s)
    assert not coarse["stable"] and coarse["h_rate"] > RK4_REAL_LIMIT and coarse["substeps"] > 4, coarse
    fine = replace(s, substeps=coarse["substeps"])
    assert stiffest_mode(d, fine)["stable"]
    mj = select(arm, "mujoco", "off")
    loop = build(d, sources=(mj, DerivedPlant()))
    gap = {k: compare([mj.run(d, loop, x, "npid")], [DerivedPlant().run(d, loop, x, "npid")], {})["max_theta_difference"]
           for k, x in (("coarse", s), ("fine", fine))}
    assert gap["coarse"] > 100 * TOL and gap["fine"] <= TOL, gap


def test_issue34_mujoco_applies_the_coulomb_smoothing_widths_as_derives_plant_does(tmp_path):
    """Issue 34 item 1: the double pendulum's 0.05 N m of smooth Coulomb friction, at 4 steps per sample
    unstable with eps = 0.01 rad/s (the test above), is stable with eps = [0.1, 0.2]; MuJoCo's loop
    (compiled and stepped from Python) takes the widths from [simulation] coulomb_smoothing, as derive's
    plant does, so the two agree within TOL, and the widths change the run."""
    from derive.sim.plant import stiffest_mode

    arm = load_arm(arm_copy(tmp_path, "double_pendulum", {"substeps": 4, "duration": 2.0,
                                                           "coulomb_friction": [0.05, 0.05],
                                                           "coulomb_smoothing": [0.1, 0.2]}))
    d = derive(arm)
    s = arm.simulation
    assert s.coulomb_smoothing == (0.1, 0.2) and stiffest_mode(d, s)["stable"]
    mj = select(arm, "mujoco", "off")
    loop = build(d, sources=(mj, DerivedPlant()))
    a, b = mj.run(d, loop, s, "npid"), DerivedPlant().run(d, loop, s, "npid")
    assert compare([a], [b], {})["max_theta_difference"] <= TOL
    stepped, plant = mj.stepped(d, s), DerivedPlant().stepped(d, s)
    for p in (stepped, plant):
        p.reset(s.initial_theta, 1)
        for _ in range(200):
            p.step(np.array([[0.5, -0.3]]), s.sample_time, s.substeps)
    np.testing.assert_allclose(stepped.theta, plant.theta, rtol=0, atol=TOL)
    sharp = mj.run(d, loop, replace(s, coulomb_smoothing=(0.01, 0.01), substeps=stiffest_mode(
        d, replace(s, coulomb_smoothing=(0.01, 0.01)))["substeps"]), "npid")
    assert np.max(np.abs(sharp.theta - a.theta)) > 1e-6
