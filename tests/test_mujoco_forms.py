"""MuJoCo in the loop (issue 21) with what the other branches gave derive's own loop: the wrapped
error of continuous joints (issue 19 item 5, derive.control.sampling.wrap), the reference from the measured
pose and the implicit observer step whose dobc_init takes dt (issue 20 items 5-7, derive.sim.start),
the units of u after the actuation (N m in torque mode), and a URDF's <dynamics friction> as the
default [simulation] coulomb_friction (the corpus branch), counted once on MuJoCo.

The arm is the case's continuous arm (tests/data/urdf/continuous.*: two continuous joints, torque
drives); tolerances are those of tests/test_mujoco_plant.py (its module docstring).
"""
from __future__ import annotations

import json
import math
import re
from dataclasses import replace

import numpy as np
import pytest

from derive.cli import main
from derive.control.pipeline import derive
from derive.model.spec import load_arm
from derive.sim.plants import DerivedPlant, build, compare, select
from tests.mujoco_arms import DATA, arm_copy
from tests.test_mujoco_plant import tolerance

TWO_PI = 2 * math.pi
FORMS = ("npid", "dobc", "mom")


@pytest.fixture(scope="module")
def contarm():
    """The continuous arm, MuJoCo's plant of its URDF (friction off: derive's parameters) and one
    library per observer step with both plants' loops."""
    arm = load_arm(DATA / "continuous.toml")
    d = derive(arm)
    mj = select(arm, "mujoco", "off")
    loops = {o: build(d, o, (mj, DerivedPlant())) for o in ("explicit", "implicit")}
    return arm, d, mj, loops


def test_continuous_joints_on_mujoco_give_the_same_commands_a_turn_off(contarm):
    """MuJoCo's hinge holds theta unwrapped; the generated controller wraps e = yd - C theta (eq. 20)
    to (-pi, pi], so a start a whole turn off on each joint gives the same u (1e-9) and the same
    wrapped error on MuJoCo, in the compiled loop and the Python-stepped one; the arm tracks, and
    MuJoCo agrees with derive's plant within the stated tolerance."""
    from derive.sim.backends import Backend
    from derive.sim.simulate import metrics, run_many

    arm, d, mj, loops = contarm
    assert d.wrapped == (0, 1)
    loop = loops["explicit"]
    runs = {}
    for label, start in (("plain", (0.2, -0.1)), ("turned", (0.2 - TWO_PI, -0.1 + 2 * TWO_PI))):
        s = replace(arm.simulation, duration=2.0, initial_theta=start)
        runs[label] = {f: mj.run(d, loop, s, f) for f in FORMS}
        runs["derive " + label] = {f: DerivedPlant().run(d, loop, s, f) for f in FORMS}
    backend = Backend(d, "python")
    try:
        stepped = run_many(d, backend, mj.stepped(d, s), s, list(FORMS))
    finally:
        backend.close()
    for f in FORMS:
        a, b, p = runs["plain"][f], runs["turned"][f], stepped[f]
        assert a.failure is None and b.failure is None and p.failure is None, f
        scale = float(np.max(np.abs(a.u)))
        np.testing.assert_allclose(b.u, a.u, rtol=0, atol=1e-9 * scale, err_msg=f)
        np.testing.assert_allclose(p.u, b.u, rtol=0, atol=1e-9 * scale, err_msg=f)
        np.testing.assert_allclose(b.error, a.error, rtol=0, atol=1e-9, err_msg=f)
        assert np.max(np.abs(b.theta - a.theta - (-TWO_PI, 2 * TWO_PI))) < 1e-9, f   # MuJoCo does not wrap theta
        assert max(m["max_error"] for m in metrics(b, s)) < 0.5, f   # tracks (unwrapped: errors of 2 pi)
        for label in ("plain", "turned"):
            ours, theirs = runs[label][f], runs["derive " + label][f]
            assert compare([ours], [theirs], {})["max_theta_difference"] <= tolerance(theirs, s), (label, f)


@pytest.mark.parametrize("observer", ("explicit", "implicit"))
def test_reference_from_the_pose_and_the_observer_step_on_mujoco(contarm, observer):
    """reference_start = "measured": y_d(0) = C theta(0) on MuJoCo as on derive's plant, so e(0) = 0;
    with the implicit observer step the MuJoCo loop's dobc_init takes dt (W_dt, eq. 22 with the
    implicit step), so DOBC's and NPID's first commands are equal after a zero-start step e(0) != 0,
    as in derive's loop; the plants agree within the stated tolerance in either start."""
    arm, d, mj, loops = contarm
    loop = loops[observer]
    theta0 = (0.3, -0.2)
    zero = replace(arm.simulation, duration=1.0, initial_theta=theta0)
    pose = replace(zero, reference_start="measured")
    for s in (zero, pose):
        ours = {f: mj.run(d, loop, s, f) for f in ("dobc", "npid")}
        theirs = {f: DerivedPlant().run(d, loop, s, f) for f in ("dobc", "npid")}
        for f in ("dobc", "npid"):
            assert ours[f].failure is None, (s.reference_start, f)
            assert compare([ours[f]], [theirs[f]], {})["max_theta_difference"] <= tolerance(theirs[f], s)
            np.testing.assert_array_equal(ours[f].u[0], theirs[f].u[0])
        if s is pose:
            np.testing.assert_array_equal(ours["dobc"].yd[0], theta0)
            assert np.max(np.abs(ours["dobc"].error[0])) == 0.0
        else:
            assert np.max(np.abs(ours["dobc"].error[0])) == pytest.approx(0.3)
            if observer == "implicit":   # both forms take W_dt at the first sample (derive.sim.start)
                np.testing.assert_allclose(ours["dobc"].u[0], ours["npid"].u[0], rtol=1e-9)


def test_simulate_on_mujoco_with_the_pose_start_implicit_step_and_torque_units(tmp_path, capsys):
    """From the command line: --plant mujoco --reference-from-pose --observer implicit --input-limits
    on the torque-driven continuous arm writes metrics in N m (_units, the table's sentence), names
    the plant, starts without the initial-estimate warning, and --compare stays within the tolerance."""
    folder = tmp_path / "arm"
    folder.mkdir()
    for name in ("continuous.toml", "continuous.urdf"):
        (folder / name).write_text((DATA / name).read_text())
    out, js = tmp_path / "out", tmp_path / "out" / "metrics.json"
    assert main(["simulate", str(folder / "continuous.toml"), "--plant", "mujoco", "--mujoco-friction", "off",
                 "--reference-from-pose", "--observer", "implicit", "--input-limits", "20,20", "--compare",
                 "--controllers", "dobc,npid", "--duration", "1", "--out", str(out), "--json", str(js)]) == 0
    assert "initial estimate" not in capsys.readouterr().err
    got = json.loads(js.read_text())
    assert got["_units"]["control_effort"] == "N m" and got["plant"]["name"] == "mujoco"
    assert got["plant"]["joints"][0]["actuator"] == "torque: gear 1"
    assert got["comparison"]["max_theta_difference"] <= 1e-9 + 1e-12 * 1e3 * 1.0 ** 2 / 2
    md = (out / "metrics.md").read_text()
    assert "(compiled backend, mujoco plant)" in md and "control effort is the RMS torque [N m]" in md
    for entry in got["controllers"].values():
        assert all(link["max_error"] < 0.05 for link in entry["links"])   # from the pose: no initial step


def test_urdf_friction_is_the_coulomb_default_and_counted_once_on_mujoco(tmp_path, capsys):
    """A URDF's <dynamics friction> is the [simulation] coulomb_friction default (derive's smooth law)
    and MuJoCo's friction loss (--mujoco-friction file): there MuJoCo's dry friction replaces the
    smooth law, not both; with friction off MuJoCo applies the smooth law as derive's plant does. The
    stiffness check takes the friction each plant applies: the smooth law's slope tau_c / 0.01 makes
    derive's plant stiff at 4 RK4 steps per sample, MuJoCo's constraint does not."""
    arm = load_arm(arm_copy(tmp_path / "a", "double_pendulum", friction=0.05))
    d = derive(arm)
    s = arm.simulation
    assert s.coulomb_friction == (0.05, 0.05)
    rough, smooth = select(arm, "mujoco", "file"), select(arm, "mujoco", "off")
    c = rough.model(d, s)
    assert c.coulomb.tolist() == [0.0, 0.0] and c.model.dof_frictionloss[c.dadr].tolist() == [0.05, 0.05]
    assert any("coulomb_friction not added where the file's friction loss" in x for x in c.description["notes"])
    c = smooth.model(d, s)
    assert c.coulomb.tolist() == [0.05, 0.05] and not np.any(c.model.dof_frictionloss)
    assert DerivedPlant().coulomb(d, s).tolist() == [0.05, 0.05]
    js = {}
    for label, options in (("derive", []), ("file", ["--plant", "mujoco"]),
                           ("off", ["--plant", "mujoco", "--mujoco-friction", "off"])):
        js[label] = tmp_path / f"{label}.json"
        assert main(["simulate", str(tmp_path / "a" / "double_pendulum.toml"), "--controllers", "npid", "--duration",
                     "0.2", "--out", str(tmp_path / label), "--json", str(js[label]), "--force", *options]) == 0
        err = capsys.readouterr().err
        stable = json.loads(js[label].read_text())["plant"]["stiffest_mode"]["stable"]
        assert stable == (label == "file") and ("stiffest mode" in err) == (not stable), (label, err)
    explicit = load_arm(arm_copy(tmp_path / "b", "double_pendulum", {"coulomb_friction": [0.02, 0.0]},
                                 friction=0.05))
    assert explicit.simulation.coulomb_friction == (0.02, 0.0)   # the arm file's value wins
    c = select(explicit, "mujoco", "file").model(d, explicit.simulation)
    assert c.coulomb.tolist() == [0.0, 0.0]
    assert any("friction loss is the joint's Coulomb friction: joint1 (0.02 N m)" in x
               for x in c.description["notes"]), c.description["notes"]


def test_mujoco_reads_rpy_angles_as_derive_snaps_them(tmp_path):
    """ROS's 1.57079632679 (4.9e-12 rad short of pi/2) is pi/2 for derive (derive.model.rigid);
    MuJoCo is given the same angle and the plant's notes say so (with the file's angle, MuJoCo's
    mass matrix of the UR5 is 3e-12 of its largest entry off derive's J, beyond the 1e-12 that
    tests/test_mujoco_plant.py holds it to); an angle derive keeps (1.5708) stays as written."""
    from derive.sim.mujoco.source import load_source

    path = arm_copy(tmp_path, "ur5")
    urdf = path.with_suffix(".urdf")
    text = urdf.read_text()
    assert text.count('"0.0 1.57079632679 0.0"') == 2 and '"0 0 -3.14159265359"' in text
    urdf.write_text(text.replace('rpy="0.0 0.0 1.57079632679"', 'rpy="0.0 0.0 1.5708"'))
    src = load_source(load_arm(path))
    assert not re.search(r"1\.57079632679(?!\d)", src.xml) and src.xml.count('rpy="0.0 1.5707963267948966 0.0"') == 2
    assert 'rpy="0.0 0.0 -3.141592653589793"' in src.xml and 'rpy="0.0 0.0 1.5708"' in src.xml
    assert any("1.57079632679 -> pi/2" in note and "-3.14159265359 -> -pi" in note for note in src.notes), src.notes


def test_a_sweeps_rerun_command_names_its_observer_step_and_plant():
    """The worst files' first line and summary.md say how to rerun a sample as the sweep ran it:
    --observer implicit (forms) and --plant mujoco --mujoco-friction (mujoco) together."""
    from derive.cli.sweep import rerun_command, worst_file
    from derive.model.spec import ARMS_DIR

    mujoco = {"name": "mujoco", "engine": "MuJoCo 4.0.0", "model": "arm.urdf", "friction": "off"}
    assert rerun_command() == "derive simulate"
    assert rerun_command("implicit", {"name": "derive"}) == "derive simulate --observer implicit"
    assert rerun_command("implicit", mujoco) == "derive simulate --observer implicit --plant mujoco --mujoco-friction off"
    arm = load_arm(None)
    text = worst_file((ARMS_DIR / "glasgow_2link.toml").read_text(), arm.simulation, "implicit", mujoco)
    assert text.startswith("# generated by derive sweep: the worst sample, rerun with derive simulate --observer "
                           "implicit --plant mujoco --mujoco-friction off; do not edit\n")
    assert 'reference_start = "zero"' in text and "mujoco_model" not in text
