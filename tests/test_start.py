"""The experiment's start (issue 20 items 6, 7): a reference that starts at the measured pose
([simulation] reference_start = "measured", derive simulate --reference-from-pose; the pulse
train an offset added to it), and the initial estimate dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0))
made visible: derive show --at prints it, derive simulate warns when it exceeds an input limit."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import derive
from derive.cli import main
from derive.errors import SpecError
from derive.sim.start import initial_estimate, reference_offset, start_estimate, start_warnings


@pytest.fixture(scope="module")
def paper():
    arm = derive.load_arm()
    return arm, derive.derive(arm)


def _arm_text(extra: str) -> str:
    from derive.model.spec import resolve_arm_path

    text = resolve_arm_path(None).read_text()
    assert "\n[simulation]" not in text   # the default arm has no [simulation] table: add one
    return text + "\n[simulation]\n" + extra


def test_reference_start_is_read_and_a_bad_value_is_one_error(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text(_arm_text('reference_start = "measured"\ninitial_theta = [0.3, -0.2]\n'))
    assert derive.load_arm(path).simulation.reference_start == "measured"
    assert derive.load_arm().simulation.reference_start == "zero"
    path.write_text(_arm_text('reference_start = "pose"\n'))
    with pytest.raises(SpecError, match=r"simulation\.reference_start: expected \"zero\" \(y_d starts at 0, "
                                        r"section 5\.2\) or \"measured\".*got 'pose'"):
        derive.load_arm(path)


def test_a_reference_from_the_pose_is_the_pulse_response_offset_by_the_pose(paper):
    """y_d = C theta(0) + (the zero-start reference): e(0) = 0 and dhat(0) = 0, in the compiled
    loop and the Python-stepped backend alike (1e-9), and the arm tracks from its pose."""
    from derive.sim.backends import Backend
    from derive.sim.compiled import build
    from derive.sim.simulate import Plant, run_compiled, run_many, true_plant

    arm, d = paper
    theta0 = (0.3, -0.2)
    zero = replace(arm.simulation, duration=3.0, initial_theta=theta0)
    pose = replace(zero, reference_start="measured")
    assert np.array_equal(reference_offset(d, pose), theta0) and not reference_offset(d, zero).any()
    assert np.allclose(start_estimate(d, pose), 0) and not np.allclose(start_estimate(d, zero), 0)
    loop = build(d)
    runs = {name: {f: run_compiled(d, loop, true_plant(d, s), s, f) for f in ("dobc", "npid")}
            for name, s in (("zero", zero), ("pose", pose))}
    backend = Backend(d, "python")
    try:
        stepped = run_many(d, backend, Plant(d, true_plant(d, pose)), pose, ["dobc", "npid"])
    finally:
        backend.close()
    for f in ("dobc", "npid"):
        a, b = runs["zero"][f], runs["pose"][f]
        np.testing.assert_allclose(b.yd - np.array(theta0), a.yd, atol=1e-12)   # Gr is linear, unit DC gain
        assert np.max(np.abs(b.error[0])) == 0.0 and np.max(np.abs(a.error[0])) == pytest.approx(0.3)
        assert np.max(np.abs(b.error)) < 0.05 < np.max(np.abs(a.error))
        np.testing.assert_allclose(stepped[f].u, b.u, rtol=0, atol=1e-9 * np.max(np.abs(b.u)))


def test_simulate_warns_when_the_initial_estimate_exceeds_a_limit_and_the_pose_start_is_smooth(tmp_path, capsys):
    """A 0.3 rad step at t = 0 with voltage limits 2 V: dhat(0) = -B^-1 W K2 e(0) is above them;
    simulate says so (naming the joint and the way out); --reference-from-pose starts smoothly,
    with no warning."""
    path = tmp_path / "arm.toml"
    path.write_text(_arm_text("initial_theta = [-0.3, -0.3]\n"))
    arm = derive.load_arm(path)
    d = derive.derive(arm)
    dhat = start_estimate(d, arm.simulation)
    W, K2, B = (np.array(m.tolist(), dtype=float) for m in (d.W, d.K2, d.B))
    np.testing.assert_allclose(dhat, -np.linalg.solve(B, W @ K2 @ np.array([0.3, 0.3])), rtol=1e-12)
    common = ["simulate", str(path), "--duration", "0.5", "--controllers", "dobc,npid", "--voltage-limits", "2,2"]
    assert main([*common, "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "derive: warning: simulation of glasgow_2link: the initial estimate dhat(0) = -B^-1 W C^-1" in err
    assert f"{abs(dhat[1]):.3g} V at joint 2 (limit 2 V)" in err and "--reference-from-pose" in err
    assert main([*common, "--out", str(tmp_path / "b"), "--reference-from-pose"]) == 0
    assert "initial estimate" not in capsys.readouterr().err
    assert start_warnings(d, replace(arm.simulation, reference_start="measured")) == []


def test_show_at_prints_the_initial_estimate_for_the_given_errors(paper, capsys):
    """derive show --at theta=...,e=...,de=...: dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0)) and the
    implicit step's (W_dt = W (J + dt W)^-1 J at the arm's sample time), as the 40-digit reference
    gives them, equal to the double formula."""
    arm, d = paper
    assert main(["show", "--at", "theta=0.3,-0.2,e=0.2,0.1,de=0.5,0"]) == 0
    out = capsys.readouterr().out
    theta, e, de = [0.3, -0.2], np.array([0.2, 0.1]), np.array([0.5, 0.0])
    explicit = initial_estimate(d, theta, [0, 0], e, de)
    implicit = initial_estimate(d, theta, [0, 0], e, de, arm.simulation.sample_time)
    block = out.split("dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0))  (derive.control.npid) [V] =\n")[1]
    shown = [float(line.strip(" []")) for line in block.splitlines()[:2]]
    assert shown == pytest.approx(explicit, rel=1e-5)
    block = out.split("dhat(0) with the implicit observer step, W_dt = W (J + dt W)^-1 J")[1].split("\n", 1)[1]
    assert [float(line.strip(" []")) for line in block.splitlines()[:2]] == pytest.approx(implicit, rel=1e-5)
    assert main(["show", "--at", "theta=0.3,-0.2,e=0.2"]) == 2
    assert "--at: expected theta=<2 numbers>[,dtheta=<2 numbers>][,e=<2 numbers>][,de=<2 numbers>]" in \
        capsys.readouterr().err
