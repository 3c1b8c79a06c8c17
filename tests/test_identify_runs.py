"""derive identify on several runs with what real logs hold (issue 37): joins, brake phases,
zero dropouts, a valid column; and the bad inputs of that (one message each, exit 2,
nothing written).

The plant is Pinocchio's (tests/pinplant.py), noise-free, so that any sample that leaks
into the regression (a 0 N m dropout through the filter, a brake phase, a flagged sample
holding garbage, the filter or the derivative run across the join of two runs) shows as
an error far above 1e-6: the same motion cut into runs with those defects gives the
clean log's parameters to 1e-6, and the report counts what each rule removed.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from derive.cli import main  # noqa: E402
from derive.identify.exclude import Exclusion, parse_exclude  # noqa: E402
from derive.identify.log import read_log  # noqa: E402
from derive.identify.regressor import derive_regressor  # noqa: E402
from derive.identify.run import identify  # noqa: E402
from derive.model.spec import load_arm  # noqa: E402

from . import pinplant  # noqa: E402

PAYLOAD = pin.Inertia(0.05, np.array([0.3, 0.0, 0.0]), np.zeros((3, 3)))
BRAKE = 300          # samples of each brake phase (the arm holds still, every torque reads 0)
DROPOUTS = 7         # isolated zeros per run


def _write(path: Path, t, q, tau, valid=None) -> Path:
    cols = ["t"] + [f"theta{i + 1}" for i in range(q.shape[1])] + [f"tau{i + 1}" for i in range(q.shape[1])]
    blocks = [t[:, None], q, tau]
    if valid is not None:
        cols.append("valid")
        blocks.append(valid[:, None])
    np.savetxt(path, np.hstack(blocks), delimiter=",", header=",".join(cols), comments="", fmt="%.17g")
    return path


@pytest.fixture(scope="module")
def motion(tmp_path_factory):
    """vertical_2link (gravity), a 12 s excitation at 1 kHz (two periods of 6 s, at rest between),
    its noise-free torques with a payload."""
    tmp = tmp_path_factory.mktemp("runs")
    traj = tmp / "traj.csv"
    assert main(["excite", "vertical_2link", "--duration", "12", "--out", str(traj), "--iterations", "15"]) == 0
    arm = load_arm("vertical_2link")
    t, q, dq, ddq = pinplant.read_trajectory(traj)
    Ia, bv, _ = pinplant.drives(arm)
    tau = pinplant.torques(pinplant.chain_model(arm, PAYLOAD), q, dq, ddq, Ia, bv)
    reg = derive_regressor(arm.chain)
    clean = identify(arm, read_log(_write(tmp / "clean.csv", t, q, tau), 2), reg=reg)
    return {"tmp": tmp, "arm": arm, "reg": reg, "t": t, "q": q, "tau": tau, "clean": clean}


def _defective_runs(m: dict, where: Path) -> tuple[list[Path], dict]:
    """The clean motion cut into its two periods (each starts and ends at rest, as a real run
    does), each followed by a brake phase (the arm still, every torque 0) and carrying
    isolated zero dropouts; file 1: run 1 with a valid column flagging a stretch of garbage;
    file 2: run 2, a gap of 0.5 s (a join), run 1 again. Returns the files and what was put in."""
    t, q, tau = m["t"], m["q"], m["tau"]
    rng = np.random.default_rng(5)
    half = len(t) // 2

    def run(a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        rq, rtau = q[a:b + 1].copy(), tau[a:b + 1].copy()
        for k in rng.choice(np.arange(300, b - a - 300), DROPOUTS, replace=False):
            rtau[k, rng.integers(2)] = 0.0                              # one joint reads 0 mid-motion
        return np.vstack([rq, np.repeat(rq[-1:], BRAKE, axis=0)]), np.vstack([rtau, np.zeros((BRAKE, 2))])

    dt = t[1] - t[0]
    q1, tau1 = run(0, half)
    valid = np.ones(len(q1))
    valid[2000:2100] = 0
    q1[2000:2100] = 1e3                                                 # the logger's garbage, flagged
    q2, tau2 = run(half, len(t) - 1)
    q3, tau3 = run(0, half)
    times = np.concatenate([dt * np.arange(len(q2)), dt * (len(q2) + 500 + np.arange(len(q3)))])
    files = [_write(where / "run1.csv", dt * np.arange(len(q1)), q1, tau1, valid),
             _write(where / "run21.csv", 3.0 + times, np.vstack([q2, q3]), np.vstack([tau2, tau3]))]
    return files, {"zeros": 3 * DROPOUTS, "brake": 3 * BRAKE, "valid": 100, "joins": 1}


def test_runs_with_joins_brakes_dropouts_and_flags_give_the_clean_result_to_1e_6(motion, tmp_path, capsys):
    files, put = _defective_runs(motion, tmp_path)
    out = tmp_path / "out" / "id.toml"
    assert main(["identify", "vertical_2link", str(tmp_path / "run*.csv"), "--exclude", "brake", "--exclude", "zeros",
                 "--out", str(out)]) == 0
    report = json.loads((tmp_path / "out" / "id_report" / "identification.json").read_text())
    clean = motion["clean"]
    scale = np.abs(clean.ls.pi).max()
    got = np.array([b["least_squares"] for b in report["base_parameters"]])
    np.testing.assert_allclose(got, clean.ls.pi, rtol=0, atol=1e-6 * scale)
    cons = np.array([b["consistent"] for b in report["base_parameters"]])
    np.testing.assert_allclose(cons, clean.cons.pi, rtol=0, atol=1e-6 * scale)
    # the report counts what each rule removed, per log
    logs = {Path(r["log"]).name: r for r in report["logs"]}
    assert set(logs) == {"run1.csv", "run21.csv"}
    assert logs["run1.csv"]["removed"]["valid"] == put["valid"]
    assert sum(r["removed"]["brake"] for r in logs.values()) == put["brake"]
    assert sum(r["removed"]["zeros"] for r in logs.values()) == put["zeros"]
    assert logs["run21.csv"]["joins"] == put["joins"] and logs["run1.csv"]["joins"] == 0
    assert report["exclude"] == "brake,zeros" and "2 logs" in capsys.readouterr().out


def test_without_the_rules_the_defects_leak_into_the_estimate(motion, tmp_path):
    """The same runs without --exclude: the dropouts and brake phases are used (an error far
    above 1e-6, so the test above can fail), and a finding names the exact zeros."""
    from derive.identify.quality import findings

    files, _ = _defective_runs(motion, tmp_path)
    logs = [read_log(f, 2) for f in files]
    idn = identify(motion["arm"], logs, reg=motion["reg"])
    err = np.abs(idn.ls.pi - motion["clean"].ls.pi).max() / np.abs(motion["clean"].ls.pi).max()
    assert err > 1e-3, err
    assert any(f.rule == "exact zeros kept" and "--exclude brake" in f.text for f in findings(idn))
    fixed = identify(motion["arm"], logs, reg=motion["reg"], rules=Exclusion(brake=True, zeros=True))
    assert not any(f.rule == "exact zeros kept" for f in findings(fixed))


def test_ends_and_saturated_rules_remove_what_they_name(motion, tmp_path):
    """ends=MS drops MS ms at each end of every log; saturated drops the torques at the motor's
    limit (vertical_2link is voltage-driven: u against its voltage limit)."""
    arm = motion["arm"]
    t, q, tau = motion["t"], motion["q"], motion["tau"]
    from derive.identify.signals import drive_constants

    B, emf, _ = drive_constants(arm.chain)
    dq = np.gradient(q, t, axis=0)
    u = (tau + emf * dq) / B
    limit = float(arm.motors[0].input_limit)
    top = 0.6 * np.abs(u[:, 0]).max()
    u[:, 0] = np.clip(u[:, 0], -top, top) * (limit / top)    # joint 1 clipped exactly at its limit
    assert np.abs(u[:, 1]).max() < 0.9 * float(arm.motors[1].input_limit)
    clipped = int((np.abs(u[:, 0]) >= limit * (1 - 1e-3)).sum())
    assert clipped > 100
    path = tmp_path / "u.csv"
    np.savetxt(path, np.hstack([t[:, None], q, u]), delimiter=",", header="t,theta1,theta2,u1,u2", comments="",
               fmt="%.17g")
    log = read_log(path, 2)
    idn = identify(arm, log, reg=motion["reg"], rules=parse_exclude(["saturated,ends=250"]))
    removed = idn.samples.runs[0].removed
    assert removed["ends"] == 2 * 250 and removed["saturated_per_joint"][1] == 0
    assert removed["saturated"] == int((np.abs(u[250:-250, 0]) >= limit * (1 - 1e-3)).sum())
    assert idn.samples.t.min() >= 0.25 + 0.3 - 1e-9      # the ends, then 3 / f_c at a cut (derive.identify.signals)


# -- bad inputs: one message each, exit 2, nothing written --------------------------------------

def _fails(tmp_path, capsys, args: list[str], pattern: str) -> None:
    out = tmp_path / "out" / "id.toml"
    assert main(["identify", *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("derive: error: ") and "Traceback" not in err and err.count("derive: error") == 1, err
    assert re.search(pattern, err), err
    assert not (tmp_path / "out").exists(), "nothing is written"


def test_a_valid_column_with_other_values(motion, tmp_path, capsys):
    t, q, tau = motion["t"], motion["q"], motion["tau"]
    valid = np.ones(len(t))
    valid[[40, 41, 90]] = [0.5, 2, -1]
    log = _write(tmp_path / "log.csv", t, q, tau, valid)
    _fails(tmp_path, capsys, ["vertical_2link", str(log)],
           r"log.csv: line 42, column 'valid': expected 0 or 1 \(1: the sample is used, 0: it is left out\), got 0.5 "
           r"\(3 such values\)")


def test_a_glob_that_matches_nothing_and_a_log_named_twice(motion, tmp_path, capsys):
    _fails(tmp_path, capsys, ["vertical_2link", str(tmp_path / "nothing*.csv")],
           r"nothing\*.csv: expected the glob to match at least one log file, got no match")
    log = _write(tmp_path / "log.csv", motion["t"], motion["q"], motion["tau"])
    _fails(tmp_path, capsys, ["vertical_2link", str(log), str(tmp_path / "l*.csv")],
           r"log.csv: expected each log once, got it twice")


@pytest.mark.parametrize("rule, pattern", [
    ("brakes", r"--exclude 'brakes': expected one of brake, zeros, saturated, ends=MS"),
    ("ends=-5", r"--exclude 'ends=-5': expected ends=MS with MS > 0 milliseconds"),
    ("zeros=3", r"--exclude 'zeros=3': expected the rule zeros without a value"),
])
def test_unknown_or_malformed_exclusion_rules(motion, tmp_path, capsys, rule, pattern):
    log = _write(tmp_path / "log.csv", motion["t"], motion["q"], motion["tau"])
    _fails(tmp_path, capsys, ["vertical_2link", str(log), "--exclude", rule], pattern)


def test_logs_of_different_signals_and_saturated_without_a_limit(motion, tmp_path, capsys):
    t, q, tau = motion["t"], motion["q"], motion["tau"]
    a = _write(tmp_path / "a.csv", t, q, tau)
    b = tmp_path / "b.csv"
    pinplant.write_log(b, t, q, tau, family="u")
    _fails(tmp_path, capsys, ["vertical_2link", str(a), str(b)],
           r"expected every log to hold the same signal, got tau1..2 and u1..2")
    # glasgow_2link's motors give no torque limit to compare a joint torque with
    _fails(tmp_path, capsys, ["glasgow_2link", str(a), "--exclude", "saturated"],
           r"--exclude saturated: expected a limit to compare the log's tau1..2 with")


def test_a_log_whose_every_sample_is_excluded(motion, tmp_path, capsys):
    t, q = motion["t"][:3000], motion["q"][:3000]
    log = _write(tmp_path / "log.csv", t, q, np.zeros((3000, 2)))
    _fails(tmp_path, capsys, ["vertical_2link", str(log), "--exclude", "brake"],
           r"0 torque equations are left after the exclusions")
