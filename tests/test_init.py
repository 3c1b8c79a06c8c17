"""``derive init robot.urdf``: a starter arm file that loads as written, never
overwrites, and picks the chain's ends or says which to choose."""
from __future__ import annotations

import re
import shutil
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.cli import main
from derive.model.chain import Actuation

URDF = Path(__file__).parent / "data" / "urdf"


def _copy(tmp_path: Path, name: str) -> Path:
    target = tmp_path / f"{name}.urdf"
    shutil.copy(URDF / f"{name}.urdf", target)
    return target


def test_init_writes_an_arm_file_that_loads(tmp_path, capsys):
    urdf = _copy(tmp_path, "double_pendulum")
    assert main(["init", str(urdf)]) == 0
    path = tmp_path / "double_pendulum.toml"
    text = path.read_text(encoding="utf-8")
    arm = derive.load_arm(path)
    assert (arm.n, arm.name) == (2, "arm_2dof_planar")   # robot name "2dof_planar" made an identifier
    assert all(a.actuation is Actuation.TORQUE for a in arm.actuators)
    assert 'urdf = "double_pendulum.urdf"' in text and 'tip_link = "link2"' in text
    assert "# viscous_friction = 0.05" in text            # <dynamics damping="0.05">, used as the default
    assert [p.value for p in arm.parameters if p.symbol.name.startswith("bv")] == [Fraction(1, 20)] * 2
    assert "position [0, 0] rad" in text                 # the URDF's limits, as comments
    assert "nondecreasing" not in text and "derive check certifies the observer on this box" in text
    err = capsys.readouterr().err
    assert "derive generate" in err
    renamed = ("the URDF's robot name '2dof_planar' is not a name derive can use (a C identifier of lowercase ASCII "
               "letters, digits and '_'): the arm is named 'arm_2dof_planar' (--name chooses another)")
    assert f"derive: note: {renamed}" in err and f"\n#   {renamed}\n" in text
    # velocity="0" effort="0": no limits given, so the box is the stated default and u is not clipped
    assert [float(v) for v in arm.controller.max_joint_speed] == [2.0, 2.0]
    assert "joints 1, 2: assumption, 2 rad/s (0.5 m/s if prismatic), the URDF gives no velocity limit" in text
    assert "# torque_limit = 10.0" in text and all(m.input_limit is None for m in arm.motors)
    W = np.array([[float(x) for x in row] for row in arm.controller.W])
    assert np.allclose(W, W.T) and np.linalg.eigvalsh(W)[0] > 0 and "[N m s/rad" in text
    assert "1/s, assumption: observer gains" not in text      # W is not a rate (issue 20 item 3)
    assert 0 < arm.simulation.sample_time <= 2e-3


def test_init_panda_with_tip_lists_limits_and_notes(tmp_path):
    urdf = _copy(tmp_path, "panda")
    out = tmp_path / "sub" / "arm.toml"
    out.parent.mkdir()
    assert main(["init", str(urdf), "--tip", "panda_hand_tcp", "--out", str(out)]) == 0
    text = out.read_text(encoding="utf-8")
    assert 'urdf = "../panda.urdf"' in text
    assert "\ntorque_limit = 87 " in text and "\ntorque_limit = 12 " in text      # the effort limits clip u
    arm = derive.load_arm(out)
    assert [float(m.input_limit) for m in arm.motors] == [87] * 4 + [12] * 3
    assert [float(v) for v in arm.controller.max_joint_speed] == [2.175] * 4 + [2.61] * 3   # the URDF's velocity
    assert "'panda_finger_joint1' at 0" in text and "'panda_joint8', 'panda_hand_joint'" in text
    assert derive.load_arm(out).n == 7


def test_init_never_overwrites(tmp_path, capsys):
    urdf = _copy(tmp_path, "double_pendulum")
    out = tmp_path / "mine.toml"
    out.write_text("# my own notes\n", encoding="utf-8")
    assert main(["init", str(urdf), "--out", str(out)]) == 2
    assert out.read_text(encoding="utf-8") == "# my own notes\n"
    assert "never overwrites" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["double_pendulum.urdf", "mine.toml"]


@pytest.mark.parametrize("name, listed", [("ur5", "'ee_link', 'tool0'"),
                                          ("panda", "'panda_hand_tcp', 'panda_leftfinger', 'panda_rightfinger'")])
def test_init_lists_the_candidates_when_the_deepest_leaf_is_ambiguous(tmp_path, capsys, name, listed):
    urdf = _copy(tmp_path, name)
    assert main(["init", str(urdf)]) == 2
    err = capsys.readouterr().err
    assert listed in err and "--tip" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{name}.urdf"]


def test_init_bad_urdf_is_one_message_nothing_written(tmp_path, capsys):
    urdf = tmp_path / "bad.urdf"
    urdf.write_text('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]><robot name="&x;"/>',
                    encoding="utf-8")
    assert main(["init", str(urdf)]) == 2
    err = capsys.readouterr().err
    assert "urdf: expected XML without external entities" in err and "Traceback" not in err
    assert main(["init", str(_copy(tmp_path, "synthetic")), "--tip", "nowhere"]) == 2
    assert "--tip: expected the name of a link of the URDF" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.urdf", "synthetic.urdf"]


def test_init_names_a_hostile_robot_name_it_replaced(tmp_path, capsys):
    """Tester's hostile_name.urdf: a robot name that is a shell command, a path and C comment text, and a
    newline that would end a TOML comment; init names the arm safely and says so on stderr and in the file.
    A base link named with a quote and a backslash is written as an escaped TOML string (was a traceback)."""
    text = (URDF / "double_pendulum.urdf").read_text(encoding="utf-8")
    hostile = "../../evil; rm -rf ~ &amp; $(id) `x` &quot;&lt;b&gt;*/ #define&#10;[arm]"
    urdf = tmp_path / "hostile.urdf"
    text = text.replace('"base_link"', '"base&quot;\\link"')   # a link name that must be escaped in TOML
    urdf.write_text(re.sub(r'<robot name="[^"]*"', f'<robot name="{hostile}"', text), encoding="utf-8")
    assert main(["init", str(urdf)]) == 0
    err = capsys.readouterr().err
    written = (tmp_path / "hostile.toml").read_text(encoding="utf-8")
    note = ("the URDF's robot name '../../evil; rm -rf ~ & $(id) `x` \"<b>*/ #define\\n[arm]' is not a name derive "
            "can use (a C identifier of lowercase ASCII letters, digits and '_'): the arm is named "
            "'evil_rm_rf_id_x_b_define_arm' (--name chooses another)")
    assert f"derive: note: {note}" in err and f"\n#   {note}\n" in written
    arm = derive.load_arm(tmp_path / "hostile.toml")
    assert arm.name == "evil_rm_rf_id_x_b_define_arm" and 'base_link = "base\\"\\\\link"' in written
    assert 'description = "evil_rm_rf_id_x_b_define_arm from hostile.urdf"\n' in written   # no '\\' in C comments


@pytest.mark.parametrize("argv, message", [
    (["init", "r.urdf", "--out", "nodir/sub/x.toml"],
     "derive: error: --out: expected a file in an existing folder, got nodir/sub/x.toml (no folder nodir/sub)"),
    (["init", "nope.urdf"], "  - urdf: expected a readable URDF file (the path as given on the command line), "
     "got string 'nope.urdf' (no such file: "),
    (["init", "r.urdf", "--base", "link1", "--tip", "link1"], "  - --tip: expected a link below the base link "
     "'link1' (the chain runs from base to tip), got 'link1': base and tip are the same link"),
])
def test_init_bad_arguments_are_one_message_naming_the_argument(tmp_path, monkeypatch, capsys, argv, message):
    """Tester's cases: --out in a folder that does not exist, a URDF that does not exist (said as given on the
    command line, not relative to an arm file), base and tip the same link: exit 2, nothing written."""
    shutil.copy(URDF / "double_pendulum.urdf", tmp_path / "r.urdf")
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and err.count("derive: error:") == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.urdf"]


# -- issue 20: the starter file works as it is ---------------------------------------------------------------------
def _first_run(tmp_path: Path, name: str, *options: str, duration: str = "12") -> tuple:
    """derive init, the certificate and the limits on the written file, derive simulate: (arm, derivation, metrics)."""
    import json

    from derive.control.sampling import limits
    from derive.proofs.certificate import check_certificate
    from derive.proofs.core import Status

    urdf = _copy(tmp_path, name)
    assert main(["init", str(urdf), *options]) == 0
    path = urdf.with_suffix(".toml")
    arm = derive.load_arm(path)
    d = derive.derive(arm)
    out = check_certificate(d)                     # derive check's obligation on the written box
    assert out.status is Status.PROVED and "on the stated box" in out.detail, out.detail
    dt = arm.simulation.sample_time
    for observer in ("explicit", "implicit"):      # inside every stated limit of every form, with room
        assert all(dt <= 0.5 * lim.limit for lim in limits(d, observer).values()), (observer, dt)
    assert main(["simulate", str(path), "--duration", duration, "--out", str(tmp_path / "sim"),
                 "--json", str(tmp_path / "m.json")]) == 0
    return arm, d, json.loads((tmp_path / "m.json").read_text())


def _tracks(metrics: dict, rms: float, peak: float) -> None:
    """DOBC and NPID (the forms W is chosen for): on every joint RMS error below ``rms`` and max error below
    ``peak`` [rad], and the worst joint's RMS error a tenth of MPC alone's at most (no observer: the disturbance
    and friction are the point of it); MOM (its own default gain K) below MPC alone's on every joint."""
    links = {form: metrics["controllers"][form]["links"] for form in ("mpc", "dobc", "npid", "mom")}
    for form in ("dobc", "npid"):
        assert max(x["rms_error"] for x in links[form]) < rms, form
        assert max(x["max_error"] for x in links[form]) < peak, form
        assert 10 * max(x["rms_error"] for x in links[form]) < max(x["rms_error"] for x in links["mpc"]), form
    assert all(m["rms_error"] < a["rms_error"] for m, a in zip(links["mom"], links["mpc"]))


def test_init_then_simulate_on_a_two_joint_arm_works_as_written(tmp_path):
    """The double pendulum (no velocity or effort limits in its URDF): the written box is certified, the written
    sample time is within half of every limit, and the starter file simulates and tracks: RMS error below 0.03 rad
    (0.018 measured, against 0.59 rad under MPC alone: the default 0.3 N m disturbance on a 0.1 kg m^2 arm)."""
    arm, d, metrics = _first_run(tmp_path, "double_pendulum", duration="8")
    _tracks(metrics, rms=0.03, peak=0.15)


@pytest.mark.slow
@pytest.mark.parametrize("name, options", [("panda", ("--tip", "panda_hand_tcp")), ("iiwa", ()),
                                           ("kinova", ("--tip", "j2s6s200_end_effector"))])
def test_init_then_simulate_on_light_wristed_vendor_arms(tmp_path, name, options):
    """Issue 20: the Panda, the KUKA iiwa (J77 = 1e-3 kg m^2, 10 rad/s box) and the Kinova Gen2: derive init writes
    the URDF's velocity box, its effort limits and a W scaled by the arm's inertia; derive check certifies the box;
    the sample time lies within half of every limit of every form; derive simulate exits 0 and DOBC and NPID
    track: RMS error below 0.03 rad and max error below 0.2 rad on every joint (the wrists, 1e-3 kg m^2 under the
    default 0.1 N m disturbance: Panda 1.8e-3 / 1.2e-2 rad, iiwa 1.3e-2 / 8.9e-2 rad, Kinova 2.1e-2 / 0.14 rad,
    against 0.26, 1.1 and 10 rad RMS under MPC alone)."""
    arm, d, metrics = _first_run(tmp_path, name, *options)
    _tracks(metrics, rms=0.03, peak=0.2)
    assert arm.controller.max_joint_speed is not None and all(m.input_limit for m in arm.motors)


def test_init_writes_the_rk4_substeps_a_light_joints_urdf_friction_needs(tmp_path, capsys):
    """A URDF's <dynamics friction> on a light joint (the double pendulum's, 0.05 N m) is the plant's smooth
    Coulomb law, whose slope 0.05 / 0.01 rad/s over the joint inertia is a fast mode: derive init writes the
    substeps that keep RK4 stable there (derive.sim.plant.stiffest_mode), so simulate runs as written, and
    without them simulate refuses (the trajectories would be wrong)."""
    import re

    from derive.sim.plant import stiffest_mode

    urdf = _copy(tmp_path, "double_pendulum")
    urdf.write_text(urdf.read_text().replace('<dynamics damping="0.05" />', '<dynamics damping="0.05" friction="0.05"/>'))
    assert main(["init", str(urdf)]) == 0
    path = urdf.with_suffix(".toml")
    text = path.read_text()
    substeps = int(re.search(r"^substeps = (\d+)", text, flags=re.M).group(1))
    arm = derive.load_arm(path)
    assert arm.simulation.coulomb_friction == (0.05, 0.05) and substeps > 4
    from dataclasses import replace

    d = derive.derive(arm)
    assert stiffest_mode(d, arm.simulation)["stable"]                   # the smallest stable count
    assert not stiffest_mode(d, replace(arm.simulation, substeps=substeps - 1))["stable"]
    capsys.readouterr()
    argv = ["simulate", str(path), "--controllers", "npid", "--duration", "0.5", "--out", str(tmp_path / "sim")]
    assert main(argv) == 0 and "stiffest mode" not in capsys.readouterr().err
    path.write_text(text.replace(f"substeps = {substeps}", "substeps = 4"))
    assert main([*argv[:-1], str(tmp_path / "sim2")]) == 2
    assert "derive: error: simulation.substeps of" in capsys.readouterr().err and not (tmp_path / "sim2").exists()


def test_init_sample_time_fits_the_sampled_loop_when_a_joints_viscous_damping_binds(tmp_path, capsys):
    """Issue 20 (the xArm6 kind: <dynamics damping="1"> on a 1e-4 kg m^2 wrist): a URDF's viscous damping b is
    in G, a mode of rate b / J that the sampled laws (eq. 15, 27, 34 and MOM) compensate, so the sampled loop's
    limits fall far below the estimates from W and K alone (double pendulum with b = 2 N m s/rad: MOM 1.74 ms,
    DOBC 1.91 ms, where those estimates allow 2 ms). derive init writes at most half of every limit derive show
    states for the file, both observer steps, lists them, and simulate runs the file as written."""
    from derive.control.sampling import OBSERVERS, limits
    from derive.control.starter import round_sample_time

    urdf = _copy(tmp_path, "double_pendulum")
    urdf.write_text(urdf.read_text().replace('<dynamics damping="0.05" />', '<dynamics damping="2" />'))
    assert main(["init", str(urdf)]) == 0
    path = urdf.with_suffix(".toml")
    arm = derive.load_arm(path)
    d = derive.derive(arm)
    stated = [lim.limit for observer in OBSERVERS for lim in limits(d, observer).values()]
    dt = arm.simulation.sample_time
    assert dt == round_sample_time(0.5 * min(stated)) and dt < 1e-3      # the sampled loop set it
    text = path.read_text()
    for observer, forms in (("forward-Euler", limits(d, "explicit")), ("backward-Euler step", limits(d, "implicit"))):
        line = next(x for x in text.splitlines() if x.startswith(f"#   {observer}"))
        assert all(f"{form.upper()} {lim.limit * 1e3:.3g} ms" in line for form, lim in forms.items()), line
    capsys.readouterr()
    assert main(["simulate", str(path), "--duration", "1", "--out", str(tmp_path / "sim")]) == 0


def test_init_starts_the_experiment_where_the_effort_limits_hold_and_scales_its_loads_to_the_arm(tmp_path, capsys):
    """Issue 20 (Baxter's kind: its zero pose needs 56 N m on a 50 N m shoulder, so every form sagged; and the
    SO-100's kind: the paper's 0.1 N m disturbance is 1e4 rad/s^2 on its 20 g jaw). The double pendulum with
    0.3 N m effort limits: upright it holds, but the 90 deg pulses of section 5.2 need about 0.5 N m. derive init
    writes a start pose within the joint ranges, reference_start = "measured" and an amplitude (>= 15 deg) such
    that the gravity torques (eq. 12) stay within 0.8 of the limits all along the experiment, and scales the
    disturbance and Coulomb friction to at most 5 rad/s^2 times each joint's inertia there; the file tracks."""
    import json
    import math
    import re

    from derive.cli.init_numbers import DISTURBANCE_ACCEL, POSE_LOAD
    from derive.control.sampling.grid import mass_function
    from derive.dynamics.program import lambdify
    from derive.model.simspec import default_settings

    urdf = _copy(tmp_path, "double_pendulum")
    urdf.write_text(urdf.read_text().replace('<limit lower="0" upper="0" effort="0" velocity="0" />',
                                             '<limit lower="-3.1" upper="3.1" effort="0.3" velocity="3" />'))
    assert main(["init", str(urdf)]) == 0
    path = urdf.with_suffix(".toml")
    arm = derive.load_arm(path)
    s = arm.simulation
    assert s.reference_start == "measured" and all(math.radians(15) <= a <= math.radians(90) for a in s.amplitude)
    theta0, amp = np.array(s.initial_theta), np.array(s.amplitude)
    assert np.all(np.abs(theta0) <= 3.1 - 0.05 * 6.2) and np.all(theta0 + amp <= 3.1 - 0.2 * (3.1 - theta0) + 1e-9)
    d = derive.derive(arm)
    g = lambdify(list(d.dynamics.sym.theta), [x.xreplace(dict(d.dynamics.values)) for x in d.dynamics.gravity])
    for a in np.linspace(0, 1, 11):          # both pulses up, one, none, and the moves between
        for mask in ((1, 1), (1, 0), (0, 1)):
            load = np.abs(np.array(g(*(theta0 + a * amp * np.array(mask))), dtype=float)) / 0.3
            assert load.max() <= POSE_LOAD + 1e-3, (a, mask, load)
    J = np.diag(mass_function(d)(theta0[None])[0])
    want = [float(f"{min(x, DISTURBANCE_ACCEL * j):.3g}") for x, j in zip(default_settings(2).disturbance, J)]
    assert list(s.disturbance) == want and want != list(default_settings(2).disturbance)
    assert re.search(r"^coulomb_friction = ", path.read_text(), re.M)
    capsys.readouterr()
    assert main(["simulate", str(path), "--out", str(tmp_path / "sim"), "--json", str(tmp_path / "m.json")]) == 0
    assert "leaves its range" not in capsys.readouterr().err
    links = {f: c["links"] for f, c in json.loads((tmp_path / "m.json").read_text())["controllers"].items()}
    for form in ("dobc", "npid"):
        assert max(x["rms_error"] for x in links[form]) < 0.02                # 0.0039 measured
        assert 5 * max(x["rms_error"] for x in links[form]) < max(x["rms_error"] for x in links["mpc"])
