"""derive identify on real measurements (issue 37): a Schunk LWA 4P, 250 Hz, 34 runs of two
point-to-point moves with brake phases and zero dropouts (S. Liu, M. Althoff, IROS 2018).

The data is GPL-3 (its README: ../shared/cases/round4/schunk_real/README.md) and stays
there: this test reads it from the shared folder beside the checkout (CI has it; a clone
without it skips this module) and writes derive's CSV logs into its own temporary folder.
As the user did: identify on runs 1-10 and 80-86, validate on 11-20 and 87-93.

* held out, the identified model's torque error is below the URDF's by at least 3x on
  every joint (relative RMS over the used samples, the logs filtered alike);
* every mass the data cannot see (no base parameter holds it: m1, m2 here) is written
  within 3x of the URDF's (the report that filed the issue had m1 = 11-203 kg, m2 = 29-413);
* the solver reaches its stated accuracy, its status is in words, the report's expressions
  have no long rationals, the written reflected rotor inertias set off no unit warning;
* the report counts what each rule removed and the joins of an appended log.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from derive.cli import main
from derive.identify.exclude import parse_exclude
from derive.identify.log import read_log
from derive.identify.run import _columns
from derive.identify.signals import Samples, prepare
from derive.identify.exclude import mask
from derive.model.plausibility import plausibility
from derive.model.spec import load_arm

ROOT = Path(__file__).resolve().parents[1]
CASE = next((p / "shared" / "cases" / "round4" / "schunk_real" for p in ROOT.parents
             if (p / "shared" / "cases" / "round4" / "schunk_real" / "data").is_dir()), None)
pytestmark = pytest.mark.skipif(CASE is None, reason="../shared/cases/round4/schunk_real (GPL-3 data, not copied "
                                                     "into derive) is not beside this checkout")
TRAIN = list(range(1, 11)) + list(range(80, 87))
HELD_OUT = list(range(11, 21)) + list(range(87, 94))
RULES = "brake,zeros"

ARM = """[arm]
name = "lwa4p"
urdf = "{urdf}"
base_link = "arm_0_link"
tip_link = "arm_6_link"
gravity = 9.81
gravity_direction = [0, 0, -1]
actuation = "torque"
{motors}
[controller]
T1 = 0.0
T2 = 0.2
max_joint_speed = [2, 2, 2, 2, 2, 2]
w = [1, 1, 1, 1, 1, 1]
"""


def _log(run: int, folder: Path) -> Path:
    """Run ``run`` of the data as derive's CSV: t, theta1..6, dtheta1..6 (the logged speeds), tau1..6."""
    d = CASE / "data" / f"m{run}"
    traj = np.loadtxt(d / "trajectory.csv", delimiter=",")
    tau = np.loadtxt(d / "input.csv", delimiter=",")             # one row fewer: row k acts over [t_k, t_k+1)
    t = np.loadtxt(d / "time.csv", delimiter=",")
    n = len(tau)
    head = ["t"] + [f"theta{i}" for i in range(1, 7)] + [f"dtheta{i}" for i in range(1, 7)] + [f"tau{i}" for i in
                                                                                               range(1, 7)]
    path = folder / f"m{run:02d}.csv"
    np.savetxt(path, np.hstack([t[:n, None], traj[:n], tau]), delimiter=",", header=",".join(head), comments="",
               fmt="%.10g")
    return path


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("schunk")
    motors = "".join(f"\n[[motor]]\ngear_ratio = 1.0\nrotor_inertia = 0.0\ntorque_limit = {e}\n"
                     for e in (370, 370, 176, 176, 41.6, 20.1))
    arm_file = tmp / "lwa4p.toml"
    arm_file.write_text(ARM.format(urdf=(CASE / "lwa4p.urdf").as_posix(), motors=motors))
    (tmp / "train").mkdir()
    (tmp / "held").mkdir()
    for r in TRAIN:
        _log(r, tmp / "train")
    held = [_log(r, tmp / "held") for r in HELD_OUT]
    out = tmp / "out" / "lwa4p_identified.toml"
    code = main(["identify", str(arm_file), str(tmp / "train" / "m*.csv"), "--exclude", RULES, "--out", str(out)])
    report = json.loads((out.parent / "lwa4p_identified_report" / "identification.json").read_text())
    return {"tmp": tmp, "arm_file": arm_file, "out": out, "code": code, "report": report, "held": held}


def test_held_out_torque_error_at_least_3x_below_the_urdf_on_every_joint(identified):
    assert identified["code"] == 0
    arm = load_arm(identified["arm_file"])
    from derive.identify.regressor import derive_regressor

    reg = derive_regressor(arm.chain)
    rules = parse_exclude([RULES])
    logs = [read_log(p, 6) for p in identified["held"]]
    s = Samples.stack([prepare(log, arm.chain, 10.0, mask(log, rules, arm.motors)) for log in logs])
    W = _columns(reg, s, ())
    y = np.where(s.use, s.y, 0.0)

    def relative(pi: np.ndarray) -> np.ndarray:
        res = np.where(s.use, s.y - W @ pi, 0.0)
        return np.sqrt((res ** 2).sum(axis=0) / (y ** 2).sum(axis=0))

    base = identified["report"]["base_parameters"]
    urdf = relative(np.array([b["prior"] for b in base]))
    ours = relative(np.array([b["consistent"] for b in base]))
    written = relative(derive_regressor(load_arm(identified["out"]).chain).base_values())
    np.testing.assert_allclose(written, ours, rtol=1e-5)            # the file holds what the report states (7 digits)
    assert np.all(3 * ours <= urdf), (ours, urdf)
    assert np.all(ours < 0.3), ours                                  # 0.10-0.21 measured


def test_masses_the_data_cannot_see_stay_within_3x_of_the_urdf(identified):
    arm = load_arm(identified["arm_file"])
    from derive.identify.regressor import derive_regressor

    K = derive_regressor(arm.chain).K
    unseen = [i for i in range(6) if not K[:, 10 * i].any()]
    assert unseen == [0, 1]                                          # m1, m2: in no base parameter
    import tomllib

    bodies = tomllib.loads(identified["out"].read_text())["body_override"]
    standard = {p["name"]: p for p in identified["report"]["standard_parameters"]}
    for i in unseen:
        prior = standard[f"m{i + 1}"]["prior"]
        assert prior / 3 <= bodies[i]["mass"] <= 3 * prior, (i + 1, bodies[i]["mass"], prior)


def test_solver_status_precision_rotor_inertia_and_counts(identified, capsys):
    report = identified["report"]
    c = report["consistent"]
    assert c["status"] == "optimal" and c["status_words"].startswith("solved: Clarabel met its tolerances (1e-08")
    md = (identified["out"].parent / "lwa4p_identified_report" / "identification.md").read_text()
    for text in (md, json.dumps([b["expression"] for b in report["base_parameters"]])):
        numbers = re.findall(r"\d+(?:\.\d+)?", text)
        longest = max(numbers, key=lambda x: len(x.replace(".", "").lstrip("0")))
        assert len(longest.replace(".", "").lstrip("0")) <= 7, longest     # 7 significant digits at most
    # the identified reflected inertias (0.1-1 kg m^2, gear ratio 1) are no "kg cm^2 as kg m^2" warning
    arm = load_arm(identified["out"])
    Ia = [float(m.rotor_inertia) for m in arm.motors]
    assert max(Ia) > 0.1 and not [p for p in plausibility(arm) if "rotor_inertia" in p.field]
    # brake phases and zero dropouts removed and counted per log: 43 brake samples per motion A run, 50 per E
    logs = {Path(r["log"]).name: r for r in report["logs"]}
    assert logs["m01.csv"]["removed"]["brake"] == 43 and logs["m80.csv"]["removed"]["brake"] == 50
    assert logs["m01.csv"]["removed"]["zeros"] > 0 and len(logs) == len(TRAIN)


def test_an_appended_log_is_split_at_the_join(identified):
    """Runs 1 and 80 appended in one file (time running on): the angles jump by up to 2.35 rad
    at the join, found and filtered on each side on its own."""
    a, b = (np.loadtxt(identified["tmp"] / "train" / f"m{r:02d}.csv", delimiter=",", skiprows=1) for r in (1, 80))
    b[:, 0] += a[-1, 0] + 0.004
    path = identified["tmp"] / "appended.csv"
    head = (identified["tmp"] / "train" / "m01.csv").read_text().splitlines()[0]
    np.savetxt(path, np.vstack([a, b]), delimiter=",", header=head, comments="", fmt="%.10g")
    log = read_log(path, 6)
    assert log.joins == (len(a),) and log.gaps == 0
    assert np.abs(np.diff(log.theta, axis=0)).max() > 2.0             # 2.35 rad on joint 3
