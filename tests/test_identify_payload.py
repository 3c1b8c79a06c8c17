"""derive identify --payload (issue 38): a known payload comes back from a noisy log of an independent plant.

The plant is Pinocchio's RNEA of the UR5 URDF (tests/pinplant.py) carrying a 1.3 kg payload at
[0.02, -0.01, 0.06] m in the tip link's frame (tool0) with an inertia of its own; the motion is
``derive excite --payload`` (20 s, the wrist only, the arm held at a bent pose); the log has the
angles quantised as a 17-bit encoder reads them and white noise on every torque. Required: the
mass within 2 %, the centre of mass within 5 mm (and both within 4 of their standard deviations:
the uncertainty is honest), the written arm file loads with that ``[payload]``; a file's larger
range mass is kept; bad input is one message, exit 2, nothing written.
"""
from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from derive.cli import main  # noqa: E402
from derive.identify.log import read_log  # noqa: E402
from derive.identify.payload import identify_payload, payload_regressor  # noqa: E402
from derive.identify.payload_file import payload_result  # noqa: E402
from derive.model.payload import tip_to_body  # noqa: E402
from derive.model.spec import load_arm  # noqa: E402

from . import pinplant  # noqa: E402

UR5 = Path(__file__).parent / "data" / "urdf" / "ur5.toml"
MASS, COM, IC = 1.3, np.array([0.02, -0.01, 0.06]), np.diag([2e-3, 3e-3, 1.5e-3])   # kg, m, kg m^2 (tip frame)
ENCODER = 2 * np.pi / 2 ** 17      # rad: one count of a 17-bit encoder
NOISE = 0.1                        # N m, white, on every joint torque (1 kHz)


def _plant(arm, mass: float = MASS):
    c, Ic = tip_to_body(arm.chain, COM, IC)
    return pinplant.urdf_model(UR5.parent / "ur5.urdf", pin.Inertia(mass, c, Ic) if mass > 0 else None)


def _log(path: Path, arm, t, q, dq, ddq, mass: float = MASS, seed: int = 3) -> Path:
    Ia, bv, _ = pinplant.drives(arm)
    tau = pinplant.torques(_plant(arm, mass), q, dq, ddq, Ia, bv)
    rng = np.random.default_rng(seed)
    pinplant.write_log(path, t, np.round(q / ENCODER) * ENCODER, tau + NOISE * rng.normal(size=tau.shape))
    return path


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("payload")
    traj = tmp / "traj.csv"
    assert main(["excite", str(UR5), "--payload", "--hold", "0,-1.5708,1.5708", "--duration", "20",
                 "--iterations", "10", "--out", str(traj)]) == 0
    arm = load_arm(UR5)
    t, q, dq, ddq = pinplant.read_trajectory(traj)
    return {"tmp": tmp, "arm": arm, "t": t, "q": q, "dq": dq, "ddq": ddq,
            "log": _log(tmp / "log.csv", arm, t, q, dq, ddq)}


def test_payload_regressor_matches_pinocchio_at_random_states():
    arm = load_arm(UR5)
    reg = payload_regressor(arm.chain)
    rng = np.random.default_rng(1)
    q, dq, ddq = (rng.uniform(-2, 2, (8, 6)) for _ in range(3))
    Ia, bv, _ = pinplant.drives(arm)
    truth = pinplant.torques(_plant(arm), q, dq, ddq, Ia, bv)
    Y, nominal = reg.torques(q, dq, ddq)
    c, Ic = tip_to_body(arm.chain, COM, IC)
    m, hx, hy, hz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz = pin.Inertia(MASS, c, Ic).toDynamicParameters()
    pi = np.array([m, hx, hy, hz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz])
    err = np.abs(Y @ pi + nominal - truth).max()
    assert err <= 1e-8 * np.abs(truth).max(), f"Y_n pi_p + (J q'' + G)_file against Pinocchio: {err:.3g} N m"


def test_excitation_moves_the_wrist_only(case):
    q = case["q"]
    assert np.ptp(q[:, :3], axis=0).max() == 0.0
    assert np.all(np.ptp(q[:, 3:], axis=0) > 1.0), np.ptp(q, axis=0)
    assert case["t"][-1] == pytest.approx(20.0)


def test_identified_payload_within_2_percent_and_5_mm_and_written(case, capsys):
    out = case["tmp"] / "ur5_payload.toml"
    assert main(["identify", str(UR5), "--payload", str(case["log"]), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert re.search(r"payload: mass 1\.\d+ ± [\d.e-]+ kg", text), text
    arm = load_arm(out)
    p = arm.payload
    assert abs(p.mass - MASS) <= 0.02 * MASS, p.mass
    assert np.linalg.norm(np.array(p.com) - COM) <= 5e-3, p.com
    assert p.inertia is not None
    assert np.abs(np.array(p.inertia) - IC).max() <= 5e-4, p.inertia
    report = tomllib.loads(out.read_text())["payload"]
    assert report["com_radius"] >= np.linalg.norm(np.array(p.com) - COM)       # 3 sigma covers the truth here
    assert (out.parent / "ur5_payload_report" / "payload.md").is_file()


def test_uncertainty_is_honest_and_inertia_consistent(case):
    arm = load_arm(UR5)
    fit = identify_payload(arm, read_log(case["log"], 6))
    res = payload_result(fit, arm)
    assert abs(res.mass - MASS) <= 4 * res.mass_std, (res.mass, res.mass_std)
    assert np.all(np.abs(res.com - COM) <= 4 * res.com_std), (res.com, res.com_std)
    assert res.inertia is not None and not res.inertia_note
    assert np.all(np.abs(res.inertia - IC) <= 4 * res.inertia_std + 1e-12), (res.inertia, res.inertia_std)
    assert np.all(fit.rms_fit < 0.1 * fit.rms_file[1:].min())        # the payload explains the torque it adds


def test_only_the_last_joint_moving_leaves_the_inertia_unexcited_mass_and_com_still_found(case, tmp_path):
    arm = case["arm"]
    t = case["t"]
    w = 2 * np.pi / 10
    q = np.tile([0.0, -1.5708, 1.5708, -1.0, 1.2, 0.0], (len(t), 1))
    dq, ddq = np.zeros_like(q), np.zeros_like(q)
    q[:, 5], dq[:, 5], ddq[:, 5] = 2.5 * np.sin(w * t), 2.5 * w * np.cos(w * t), -2.5 * w * w * np.sin(w * t)
    fit = identify_payload(arm, read_log(_log(tmp_path / "j6.csv", arm, t, q, dq, ddq), 6))
    res = payload_result(fit, arm)
    assert not fit.inertia_excited and res.inertia is None and "not excited" in res.inertia_note
    assert abs(res.mass - MASS) <= 0.02 * MASS and np.linalg.norm(res.com - COM) <= 5e-3, (res.mass, res.com)


def test_coulomb_adds_the_moving_joints_friction_as_nuisance_parameters(case, tmp_path):
    """A plant with Coulomb and extra viscous friction on the wrist: --coulomb finds them (within 4
    standard deviations) and the payload stays within 2 % and 5 mm; the held joints get none."""
    arm, t, q, dq, ddq = case["arm"], case["t"], case["q"], case["dq"], case["ddq"]
    fc, fv = np.array([0.8, 0.6, 0.5]), np.array([0.3, 0.2, 0.2])
    Ia, bv, _ = pinplant.drives(arm)
    tau = pinplant.torques(_plant(arm), q, dq, ddq, Ia, bv)
    tau[:, 3:] += fc * np.sign(dq[:, 3:]) + fv * dq[:, 3:]
    tau += NOISE * np.random.default_rng(4).normal(size=tau.shape)
    path = tmp_path / "friction.csv"
    pinplant.write_log(path, t, np.round(q / ENCODER) * ENCODER, tau)
    fit = identify_payload(arm, read_log(path, 6), coulomb=True)
    assert fit.friction_names == ("dfv4", "dfv5", "dfv6", "fc4", "fc5", "fc6") and set(fit.refused) == {1, 2, 3}
    truth = np.concatenate([fv, fc])
    assert np.all(np.abs(fit.friction - truth) <= 4 * fit.friction_std), (fit.friction, fit.friction_std)
    res = payload_result(fit, arm)
    assert abs(res.mass - MASS) <= 0.02 * MASS and np.linalg.norm(res.com - COM) <= 5e-3, (res.mass, res.com)


def test_the_files_larger_range_mass_and_radius_are_kept(case, tmp_path, capsys):
    arm_file = tmp_path / "ur5_range.toml"
    text = UR5.read_text().replace('urdf = "ur5.urdf"', f'urdf = "{(UR5.parent / "ur5.urdf").as_posix()}"')
    arm_file.write_text(text + "\n[payload]\nmass = 5.0\ncom = [0.0, 0.0, 0.05]\ncom_radius = 0.1\n")
    out = tmp_path / "out.toml"
    assert main(["identify", str(arm_file), "--payload", str(case["log"]), "--out", str(out)]) == 0
    assert "the file's 5 kg kept" in capsys.readouterr().err
    p = load_arm(out).payload
    assert p.mass == 5.0 and p.com_radius == 0.1
    assert np.linalg.norm(np.array(p.com) - COM) <= 5e-3
    # the inertia is written at the range's mass: at the identified mass it is the identified one
    assert np.abs(p.inertia_at(MASS) - IC).max() <= 5e-4


def _refused(args: list[str], tmp: Path, message: str, capsys) -> None:
    before = sorted(tmp.iterdir())
    assert main(args) == 2
    err = capsys.readouterr().err
    assert re.search(message, err), err
    assert err.count("error") == 1, err
    assert sorted(tmp.iterdir()) == before, "something was written"


def test_bad_input_one_message_exit_2_nothing_written(case, tmp_path, capsys):
    out = str(tmp_path / "out.toml")
    no_tau = tmp_path / "no_tau.csv"
    no_tau.write_text("t," + ",".join(f"theta{i}" for i in range(1, 7)) + "\n"
                      + "".join(f"{k / 1000},0,0,0,0,0,0\n" for k in range(100)))
    _refused(["identify", str(UR5), "--payload", str(no_tau), "--out", out], tmp_path,
             r"expected exactly one of the column families tau, current or u", capsys)
    _refused(["identify", "glasgow_2link", "--payload", str(case["log"]), "--out", out], tmp_path,
             r"planar \[\[link\]\] arm: expected a URDF, DH or MJCF arm", capsys)
    empty = _log(tmp_path / "empty.csv", case["arm"], case["t"], case["q"], case["dq"], case["ddq"], mass=0.0)
    _refused(["identify", str(UR5), "--payload", str(empty), "--out", out], tmp_path,
             r"expected a mass more than 3 standard deviations above 0", capsys)
    _refused(["excite", "glasgow_2link", "--payload", "--duration", "5", "--out", out], tmp_path,
             r"planar \[\[link\]\] arm", capsys)
    _refused(["excite", str(UR5), "--hold", "0", "--duration", "5", "--out", out], tmp_path,
             r"--hold: expected with --payload only", capsys)
    _refused(["excite", str(UR5), "--payload", "--hold", "0,9,0", "--duration", "5", "--out", out], tmp_path,
             r"--hold: expected positions within the joints' ranges, got joint 2: 9", capsys)
    _refused(["identify", str(UR5), "--out", out], tmp_path, r"expected at least one LOG", capsys)
