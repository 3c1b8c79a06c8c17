"""derive excite (issue 22, item 2): a Fourier excitation within the limits, at rest at both ends,
optimised for the condition number, deterministic; limits that cannot be met are one error."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.cli import main
from derive.errors import DataError
from derive.identify.excite import excitation_limits, fourier, optimise, stacked
from derive.identify.regressor import derive_regressor
from derive.model.spec import load_arm

from .pinplant import read_trajectory


@pytest.fixture(scope="module")
def trajectory(tmp_path_factory):
    out = tmp_path_factory.mktemp("excite") / "traj.csv"
    code = main(["excite", "vertical_2link", "--duration", "15", "--out", str(out), "--iterations", "25",
                 "--velocity-limit", "3,2.5", "--json", str(out.with_suffix(".json"))])
    assert code == 0
    return out


def test_every_sample_within_the_limits_and_at_rest_at_both_ends(trajectory):
    t, q, dq, ddq = read_trajectory(trajectory)
    data = json.loads(trajectory.with_suffix(".json").read_text())
    assert t[0] == 0 and math.isclose(t[-1], 15.0) and len(t) == 15001
    for i, lim in enumerate(data["limits"]):
        assert lim["lower"] <= q[:, i].min() and q[:, i].max() <= lim["upper"]
        assert np.abs(dq[:, i]).max() <= lim["velocity"] and np.abs(ddq[:, i]).max() <= lim["acceleration"]
    assert [lim["velocity"] for lim in data["limits"]] == [3.0, 2.5]
    assert data["limits"][0]["sources"] == ["default +-3.14159 rad", "--velocity-limit", "default 5 rad/s^2"]
    for k in (0, -1):
        np.testing.assert_allclose(dq[k], 0, atol=1e-12)
        np.testing.assert_allclose(ddq[k], 0, atol=1e-12)
    np.testing.assert_allclose(q[0], q[-1], atol=1e-12)
    # the CSV's derivatives are those of the series (central differences agree)
    h = t[1] - t[0]
    np.testing.assert_allclose(np.gradient(q, h, axis=0)[5:-5], dq[5:-5], atol=1e-4)


def test_the_stated_condition_number_is_that_of_the_stacked_regressor(trajectory):
    data = json.loads(trajectory.with_suffix(".json").read_text())
    reg = derive_regressor(load_arm("vertical_2link").chain)
    assert data["base_parameters"] == list(reg.names)
    _, q, dq, ddq = read_trajectory(trajectory)
    s = np.linalg.svd(stacked(reg, q, dq, ddq), compute_uv=False)
    assert math.isclose(data["condition_number"], s[0] / s[-1], rel_tol=1e-6)


def test_the_optimiser_lowers_the_condition_number_and_is_deterministic():
    arm = load_arm("glasgow_2link")
    reg = derive_regressor(arm.chain)
    limits = excitation_limits(arm.chain)
    start = optimise(reg, limits, 10.0, iterations=0)
    best = optimise(reg, limits, 10.0, iterations=25)
    assert best.cond < 0.5 * start.cond
    again = optimise(reg, limits, 10.0, iterations=25)
    assert again.cond == best.cond and np.array_equal(again.a, best.a)
    other = optimise(reg, limits, 10.0, iterations=25, seed=2)
    assert not np.array_equal(other.a, best.a)
    # a long run repeats a period of at most 10 s
    assert optimise(reg, limits, 25.0, iterations=0).period == 25.0 / 3


def test_fourier_series_derivatives_are_exact():
    rng = np.random.default_rng(1)
    a, b, q0, w = rng.normal(size=(2, 4)), rng.normal(size=(2, 4)), rng.normal(size=2), 0.7
    t = np.linspace(0, 5, 7)
    h = 1e-5
    _, dq, ddq = fourier(t, q0, a, b, w)
    qp, dqp, _ = fourier(t + h, q0, a, b, w)
    qm, dqm, _ = fourier(t - h, q0, a, b, w)
    np.testing.assert_allclose((qp - qm) / (2 * h), dq, atol=1e-8)
    np.testing.assert_allclose((dqp - dqm) / (2 * h), ddq, atol=1e-8)


@pytest.mark.parametrize("args, message", [
    (["--velocity-limit", "0"], r"joint 1 \('joint1'\): velocity limit 0 rad/s \(--velocity-limit\): expected a "
                                r"finite number > 0"),
    (["--acceleration-limit", "1,-2"], r"joint 2 \('joint2'\): acceleration limit -2 rad/s\^2"),
    (["--velocity-limit", "1,2,3"], r"--velocity-limit: expected one finite number or 2 comma-separated ones"),
    (["--duration", "0"], r"--duration 0 s: expected a finite number > 0"),
    (["--harmonics", "1"], r"--harmonics 1: expected at least 2"),
])
def test_limits_that_cannot_be_met_are_one_clear_error(tmp_path, capsys, args, message):
    out = tmp_path / "traj.csv"
    base = ["excite", "glasgow_2link", "--duration", "5", "--out", str(out), "--iterations", "0"]
    assert main(base + args) == 2
    err = capsys.readouterr().err
    assert err.startswith("derive: error: ") and "Traceback" not in err
    import re
    assert re.search(message, err), err
    assert not out.exists()


def test_limits_come_from_the_urdf_and_the_arm_file():
    ur5 = load_arm("tests/data/urdf/ur5.toml")
    lim = excitation_limits(ur5.chain)
    assert lim[2].upper == pytest.approx(3.14159265359) and lim[0].velocity == pytest.approx(3.15)
    assert lim[0].sources[1] == "urdf joint 'shoulder_pan_joint' <limit velocity>"
    assert lim[0].acceleration == 5.0 and lim[0].sources[2] == "default 5 rad/s^2"
    with pytest.raises(DataError, match="expected lower < upper"):
        from dataclasses import replace
        from derive.model.chain import Limits
        from fractions import Fraction
        j = replace(ur5.chain.joints[0], limits=Limits(Fraction(1), Fraction(1), Fraction(1)))
        excitation_limits(replace(ur5.chain, joints=(j,) + ur5.chain.joints[1:]))


ROUND4 = Path(__file__).parent / "data" / "urdf" / "round4"


def test_a_zero_urdf_velocity_or_effort_is_no_limit_in_every_command(tmp_path, capsys):
    """Issue 34 item 6 (the case zero_effort_velocity): <limit effort="0" velocity="0"> is read as no
    limit once, by the URDF reader, and noted in the starter file; init, show (the speed box) and
    excite agree: excite takes controller.max_joint_speed (exit 0) where it read a zero limit (exit 2)."""
    import shutil

    from derive.control.sampling.grid import speed_box

    for f in ("effz.urdf", "effz.toml"):
        shutil.copy(ROUND4 / f, tmp_path / f)
    arm = load_arm(tmp_path / "effz.toml")
    assert all(j.limits.velocity is None and j.limits.effort is None for j in arm.chain.joints)
    note = "<limit velocity=\"0\"> of joints 'j1', 'j2', 'j3' read as no velocity limit"
    assert any(note in x for x in arm.chain.notes)
    assert speed_box(derive.derive(arm)).source == "controller.max_joint_speed"
    out = tmp_path / "traj.csv"
    assert main(["excite", str(tmp_path / "effz.toml"), "--duration", "5", "--out", str(out), "--iterations", "0"]) == 0
    printed = capsys.readouterr().out
    assert "controller.max_joint_speed[1]" in printed and out.exists()
    lim = excitation_limits(arm.chain, arm.controller.max_joint_speed)
    assert [x.velocity for x in lim] == [2.0, 2.0, 2.0]
    (tmp_path / "init").mkdir()
    shutil.copy(ROUND4 / "effz.urdf", tmp_path / "init" / "effz.urdf")
    assert main(["init", str(tmp_path / "init" / "effz.urdf")]) == 0
    text = (tmp_path / "init" / "effz.toml").read_text()
    assert f"#   {note} (the same in every command)\n" in text
    assert "velocity 0 rad/s" not in text and "# joint 1: 'j1' (revolute; position [-3, 3] rad)\n" in text
    assert "# torque_limit = 10.0" in text     # no effort limit: u is not clipped


def test_a_limit_from_the_file_that_cannot_be_met_names_the_option_that_overrides_it():
    from dataclasses import replace
    from fractions import Fraction

    from derive.model.chain import Limits

    ur5 = load_arm("tests/data/urdf/ur5.toml")
    j = replace(ur5.chain.joints[0], limits=Limits(Fraction(-1), Fraction(1), Fraction(-2)))
    with pytest.raises(DataError, match=r"joint 1 \('shoulder_pan_joint'\): velocity limit -2 rad/s \(urdf joint "
                                        r"'shoulder_pan_joint' <limit velocity>\): expected a finite number > 0 \(the "
                                        r"joint must move to be excited\); --velocity-limit gives another"):
        excitation_limits(replace(ur5.chain, joints=(j,) + ur5.chain.joints[1:]))
