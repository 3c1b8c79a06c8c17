"""Bad input to derive identify (issue 22): one clear message naming the row, column or
parameters, exit 2, nothing written; and the [[body_override]] tables of the arm file."""
from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from derive.cli import main
from derive.errors import SpecError
from derive.model.spec import arm_from_dict

UR5 = Path(__file__).parent / "data" / "urdf" / "ur5.toml"


def _log(path: Path, header: str, rows: list[list]) -> Path:
    path.write_text(header + "\n" + "\n".join(",".join(str(x) for x in row) for row in rows) + "\n")
    return path


def _moving(n_rows: int = 400, rate: float = 100.0, still: bool = False) -> list[list]:
    """A 2-joint log of smooth motion (joint 2 held still when ``still``)."""
    t = np.arange(n_rows) / rate
    q1, q2 = np.sin(0.9 * t) + 0.3 * np.sin(2.3 * t), (0 * t if still else np.cos(1.3 * t) - 0.2 * np.sin(3.1 * t))
    return [[a, b, c, 0.1 * b, 0.05 * c] for a, b, c in zip(t, q1, q2)]


HEADER = "t,theta1,theta2,tau1,tau2"


def _fails(tmp_path, capsys, log: Path, pattern: str, arm: str = "glasgow_2link") -> str:
    out = tmp_path / "out" / "identified.toml"
    assert main(["identify", arm, str(log), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("derive: error: ") and "Traceback" not in err, err
    assert re.search(pattern, err), err
    assert not (tmp_path / "out").exists(), "nothing is written"
    return err


def test_nan_and_inf_are_named_by_line_and_column(tmp_path, capsys):
    rows = _moving()
    rows[57][3] = "nan"
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER, rows),
           r"log.csv: line 59, column 'tau1': expected a finite number, got nan")
    rows[57][3] = 0.0
    rows[80][2] = "-inf"
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", "# a comment\n" + HEADER, rows),
           r"line 83, column 'theta2': expected a finite number, got -inf")


def test_unsorted_and_repeated_times(tmp_path, capsys):
    rows = _moving()
    rows[10][0] = rows[9][0]
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER, rows), r"line 12: expected times that increase, "
           r"got t = 0.09 after t = 0.09 on line 11 \(repeated times\)")
    rows = _moving()
    rows[10][0], rows[11][0] = rows[11][0], rows[10][0]
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER, rows), r"\(unsorted times\)")
    rows = _moving()
    rows[200][0] += 0.003
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER, rows), r"expected uniform sample times")


def test_column_count_unknown_missing_and_repeated_columns(tmp_path, capsys):
    rows = _moving()
    rows[20] = rows[20][:4]
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER, rows),
           r"line 22: expected 5 comma-separated values \(the header's columns\), got 4")
    rows = _moving()
    rows[30][4] = "abc"
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER, rows),
           r"line 32, column 'tau2': expected a number, got 'abc'")
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER + ",force1", [r + [0] for r in _moving()]),
           r"column 6 'force1': expected one of the columns t, theta1..theta2, one of tau1..tau2")
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER + ",tau3", [r + [0] for r in _moving()]),
           r"column 6 'tau3'.*the arm has 2 joints")
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", "t,theta1,theta2,tau1", [r[:4] for r in _moving()]),
           r"missing tau2")
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER + ",current1,current2", [r + [0, 0] for r in _moving()]),
           r"exactly one of the column families tau, current or u, got tau and current")
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER + ",tau1", [r + [0] for r in _moving()]),
           r"column 6 'tau1': expected each column once")


def test_fewer_samples_than_parameters(tmp_path, capsys):
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER, _moving(3)),
           r"3 samples x 2 joints = 6 equations, fewer than the 7 base parameters")
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER, _moving(30)),
           r"30 samples: expected more than")


def test_a_motion_that_leaves_parameters_unexcited_names_them(tmp_path, capsys):
    err = _fails(tmp_path, capsys, _log(tmp_path / "log.csv", HEADER, _moving(still=True)),
                 r"the logged motion leaves base parameter")
    assert "Ia2" in err and "fv2" in err   # joint 2 never moves: its rotor and friction are never seen


def test_a_current_log_needs_motor_constants(tmp_path, capsys):
    header = "t," + ",".join(f"theta{i}" for i in range(1, 7)) + "," + ",".join(f"current{i}" for i in range(1, 7))
    rows = [[k / 100] + [0.01 * k] * 6 + [0.0] * 6 for k in range(500)]
    _fails(tmp_path, capsys, _log(tmp_path / "log.csv", header, rows),
           r"a current log \(current1..6\) needs each joint's motor constants.*motor\[1\] of the arm is "
           r"torque-actuated", arm=str(UR5))


def test_a_cutoff_above_nyquist_and_an_unreadable_log(tmp_path, capsys):
    log = _log(tmp_path / "log.csv", HEADER, _moving())
    out = tmp_path / "out" / "x.toml"
    assert main(["identify", "glasgow_2link", str(log), "--cutoff", "60", "--out", str(out)]) == 2
    assert "--cutoff 60 Hz: expected a frequency > 0 below the log's Nyquist frequency 50 Hz" in capsys.readouterr().err
    assert main(["identify", "glasgow_2link", str(tmp_path / "missing.csv"), "--out", str(out)]) == 2
    assert "cannot read the log" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


# -- [[body_override]] -----------------------------------------------------------------------

def _ur5(overrides) -> dict:
    data = tomllib.loads(UR5.read_text())
    data["body_override"] = overrides
    return data


def _body(joint, mass=1.0, h=(0.0, 0.0, 0.1), inertia=((0.02, 0, 0), (0, 0.02, 0), (0, 0, 0.01))):
    return {"joint": joint, "mass": mass, "first_moment": list(h), "inertia": [list(r) for r in inertia]}


def test_a_body_override_replaces_the_bodys_ten_parameters():
    arm = arm_from_dict(_ur5([_body("wrist_3_joint", 1.5)]), str(UR5))
    p = {str(x.symbol): x for x in arm.chain.parameters}
    assert p["m6"].value == 1.5 and p["m6"].field == "body_override[1].mass"
    assert p["hz6"].value == pytest.approx(0.1) and p["Izz6"].field == "body_override[1].inertia[3][3]"
    assert p["m5"].field.startswith("urdf link")               # the other bodies as the URDF has them
    assert len(arm.chain.parameters) == len(arm_from_dict(tomllib.loads(UR5.read_text()), str(UR5)).chain.parameters)


@pytest.mark.parametrize("override, message", [
    (_body("no_such_joint"), r"body_override\[1\].joint: expected a moving joint of the chain"),
    (_body(7), r"or its number 1..6, got 7"),
    (_body(2, mass=-1), r"body_override\[1\].mass: expected a finite number >= 0 \(kg\), got -1"),
    (_body(2, h=(0, 0)), r"body_override\[1\].first_moment: expected an array of 3 numbers"),
    (_body(2, inertia=((0.02, 0.01, 0), (0, 0.02, 0), (0, 0, 0.01))), r"expected a symmetric 3 x 3 array"),
    (_body(2, inertia=((0.01, 0, 0), (0, 0.01, 0), (0, 0, 0.5))), r"body_override\[1\]: expected a physically "
                                                                    r"consistent body"),
    (_body(2, mass=0.0), r"body_override\[1\]: expected a physically consistent body"),   # h without mass
    ({"joint": 2, "mass": 1}, r"body_override\[1\].first_moment: expected h = m c, 3 numbers"),
    ({**_body(2), "com": [0, 0, 0]}, r"body_override\[1\].com: expected one of the keys"),
])
def test_bad_body_overrides_are_named(override, message):
    with pytest.raises(SpecError, match=message):
        arm_from_dict(_ur5([override]), str(UR5))


def test_one_override_per_joint_and_none_on_a_planar_arm():
    with pytest.raises(SpecError, match=r"body_override\[2\].joint: expected at most one \[\[body_override\]\] per "
                                        r"joint, got string 'shoulder_lift_joint', overridden by body_override\[1\] "
                                        r"already"):
        arm_from_dict(_ur5([_body(2), _body("shoulder_lift_joint")]), str(UR5))
    planar = tomllib.loads((Path(__file__).parents[1] / "derive/model/arms/glasgow_2link.toml").read_text())
    planar["body_override"] = [_body(1)]
    with pytest.raises(SpecError, match=r"body_override: expected no \[\[body_override\]\] tables with \[\[link\]\] "
                                        r"tables"):
        arm_from_dict(planar, "planar.toml")
