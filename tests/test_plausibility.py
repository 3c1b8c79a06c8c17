"""Plausibility warnings (issue 15 item 6): valid arms with a likely unit mistake.

The issue's instances on its own arm (tests/data/arms/my3.toml): ``length = 350``, a 250 kg
gripper, ``rotor_inertia = 10.0``, a centre of mass at 0.5 m on a 0.35 m link, a point mass
at 0.6 m on a 0.15 m link; then one case per other rule of derive.model.plausibility. Every
command prints each as one ``derive: warning: <field>: ...`` line and goes on (exit 0);
``--strict`` makes them one exit-2 error before anything is done. Odd but real designs (a
counterweight behind the joint, a massless tube, a step-up gear) and every packaged and test
arm stay silent.
"""
from __future__ import annotations

import argparse
import copy
import tomllib
from pathlib import Path

import pytest
import tomlkit

from derive.cli import load_cli_arm, main
from derive.errors import SpecError
from derive.model.plausibility import plausibility
from derive.model.spec import arm_from_dict, load_arm

ROOT = Path(__file__).resolve().parents[1]
MY3 = tomllib.loads((ROOT / "tests" / "data" / "arms" / "my3.toml").read_text())
GLASGOW = tomllib.loads((ROOT / "derive" / "model" / "arms" / "glasgow_2link.toml").read_text())


def _edited(data: dict, *edits: tuple[tuple, object]) -> dict:
    out = copy.deepcopy(data)
    for where, value in edits:
        table = out
        for key in where[:-1]:
            table = table[key]
        table[where[-1]] = value
    return out


CASES = {   # id: (edit of my3, field, a fragment of the rule, the value given as shown)
    "length in mm": ((("link", 0, "length"), 350.0), "link[1].length", "millimetres written as metres", "350 m"),
    "gripper in g": ((("point_mass", 2, "mass"), 250.0), "point_mass[3].mass",
                     "at most 20 times the rest of the arm (2.8 kg", "250 kg"),
    "rotor inertia": ((("motor", 0, "rotor_inertia"), 10.0), "motor[1].rotor_inertia", "at most 0.1 kg m^2",
                      "10 kg m^2"),
    "com beyond the link": ((("link", 0, "com"), 0.5), "link[1].com", "and the link's length 0.35 m",
                            "0.5 m, beyond the end of the link"),
    "point mass beyond the link": ((("point_mass", 2, "distance"), 0.6), "point_mass[3].distance",
                                   "and the link's length 0.15 m", "0.6 m, beyond the end of the link"),
    "counterweight too far behind": ((("link", 1, "com"), -0.45), "link[2].com", "between -0.3 m",
                                     "-0.45 m, further behind the joint than the length of the link"),
    "link mass": ((("link", 1, "mass"), 1500.0), "link[2].mass", "at most 1000 kg", "1500 kg"),
    "link inertia": ((("link", 0, "inertia"), 5.0), "link[1].inertia", "at most m l^2 = 0.147 kg m^2", "5 kg m^2"),
    "point-mass inertia": ((("point_mass", 0, "inertia"), 0.5), "point_mass[1].inertia",
                           "at most m l^2 = 0.03675 kg m^2", "0.5 kg m^2"),
    "resistance": ((("motor", 0, "resistance"), 0.0005), "motor[1].resistance", "between 0.001 and 1000 ohm",
                   "0.0005 ohm"),
    "gear ratio": ((("motor", 1, "gear_ratio"), 20000.0), "motor[2].gear_ratio", "between 0.01 and 10000", "20000"),
    "Kv in V/krpm": ((("motor", 2, "voltage_constant"), 3.14), "motor[3].voltage_constant",
                     "close to the torque constant 0.03 N m/A", "3.14 V s/rad"),
    "voltage limit": ((("motor", 0, "voltage_limit"), 24000.0), "motor[1].voltage_limit", "at most 1000 V",
                      "24000 V"),
    "gravity": ((("arm", "gravity"), 981.0), "arm.gravity", "at most 20 m/s^2", "981 m/s^2"),
    "speed box in deg/s": ((("controller", "max_joint_speed"), [180.0, 4.0, 5.0]), "controller.max_joint_speed[1]",
                           "at most 50 rad/s", "180 rad/s"),
}


@pytest.mark.parametrize("edit, field, rule, given", CASES.values(), ids=CASES.keys())
def test_each_rule_fires_alone_naming_field_rule_and_value(edit, field, rule, given):
    problems = plausibility(arm_from_dict(_edited(MY3, edit)))
    assert [p.field for p in problems] == [field]
    assert rule in problems[0].expected and problems[0].given == given


@pytest.mark.parametrize("edit", [(("link", 0, "com"), -0.3),               # a counterweight behind the joint
                                  (("point_mass", 0, "distance"), -0.35),   # a mass behind it, a link length
                                  (("motor", 0, "gear_ratio"), 0.5),        # a step-up gear
                                  (("motor", 0, "voltage_constant"), 0.055)])   # Kt/Kv = 0.55: datasheet spread
def test_odd_but_real_designs_are_silent(edit):
    assert plausibility(arm_from_dict(_edited(MY3, edit))) == ()


ARM_FILES = sorted([*(ROOT / "derive" / "model" / "arms").glob("*.toml"),
                    *(p for p in (ROOT / "tests" / "data").rglob("*.toml") if p.name != "corpus.toml")])  # a list of arms


@pytest.mark.parametrize("path", ARM_FILES, ids=[p.name for p in ARM_FILES])
def test_packaged_and_test_arms_are_plausible(path):
    assert plausibility(load_arm(path)) == ()     # f9: a massless tube carrying a tool; URDFs of real arms


def test_dh_arm_body_mass_and_joint_offset():
    data = {"arm": {"name": "dh", "gravity": 9.81, "actuation": "torque"},
            "dh": {"convention": "standard", "table": [[30.0, "pi/2", 0.1, 0.0], [0.3, 0.0, 0.0, 0.0]]},
            "body": [{"mass": 1.0, "com": [0, 0, 0.05]}, {"mass": 2000.0, "com": [-0.1, 0, 0]}],
            "controller": {"T1": 0.0, "T2": 0.5, "w": [1.0, 1.0]}}
    problems = plausibility(arm_from_dict(data))
    assert [(p.field, p.given) for p in problems] == [("body[2].mass", "2000 kg"),
                                                      ("dh.table[2] origin", "30.0002 m")]   # row 1: a = 30 m


def test_strict_raises_one_spec_error_naming_every_rule(tmp_path):
    path = tmp_path / "my3.toml"
    path.write_text(tomlkit.dumps(_edited(MY3, CASES["length in mm"][0], CASES["gripper in g"][0])))
    with pytest.raises(SpecError, match=r"implausible arm description \(--strict\) .*2 problems\):\n"
                                        r"  - link\[1\]\.length: expected at most 10 m.*got 350 m\n"
                                        r"  - point_mass\[3\]\.mass: expected at most 20 times"):
        load_cli_arm(argparse.Namespace(arm=str(path), strict=True))


def test_show_prints_one_warning_line_per_rule_and_exits_0(tmp_path, capsys):
    path = tmp_path / "g2.toml"
    path.write_text(tomlkit.dumps(_edited(GLASGOW, (("link", 0, "length"), 380.0), (("motor", 1, "rotor_inertia"), 10.0))))
    assert main(["show", str(path)]) == 0
    lines = [x for x in capsys.readouterr().err.splitlines() if x.startswith("derive: warning: ")]
    assert lines == ["derive: warning: link[1].length: expected at most 10 m in size (no robot link is longer; "
                     "millimetres written as metres?), got 380 m",
                     "derive: warning: motor[2].rotor_inertia: expected at most 0.1 kg m^2 for a motor's rotor "
                     "(kg cm^2 or g cm^2 written as kg m^2?), got 10 kg m^2"]


@pytest.mark.parametrize("command", ["show", "check", "generate", "simulate", "fmu", "tune", "sweep", "embedded"])
def test_strict_is_exit_2_before_anything_for_every_command(tmp_path, monkeypatch, capsys, command):
    path = tmp_path / "my3.toml"
    path.write_text(tomlkit.dumps(_edited(MY3, CASES["rotor inertia"][0])))
    monkeypatch.chdir(tmp_path)
    assert main([command, str(path), "--strict"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("derive: error: implausible arm description (--strict)") and "motor[1].rotor_inertia" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["my3.toml"]       # nothing written


POLAR = ROOT / "tests" / "data" / "urdf" / "round3" / "polar.urdf"


@pytest.mark.parametrize("old, new, field, rule, given", [
    ('<limit lower="-3" upper="3" effort="50" velocity="3"/>', '<limit lower="-170" upper="170" effort="50" velocity="3"/>',
     "urdf joint 'j1' <limit lower>", "degrees written as radians", "-170 rad"),
    ('<limit lower="0.3" upper="0.6" effort="50" velocity="1"/>', '<limit lower="300" upper="600" effort="50" velocity="1"/>',
     "urdf joint 'j2' <limit lower>", "millimetres written as metres", "300 m"),
    ('<limit lower="-3" upper="3" effort="50" velocity="3"/>', '<limit lower="-3" upper="3" effort="50" velocity="180"/>',
     "urdf joint 'j1' <limit velocity>", "deg/s or rpm written as rad/s", "180 rad/s"),
    ('<limit lower="0.3" upper="0.6" effort="50" velocity="1"/>', '<limit lower="0.3" upper="0.6" effort="50" velocity="500"/>',
     "urdf joint 'j2' <limit velocity>", "mm/s written as m/s", "500 m/s")])
def test_joint_ranges_and_speeds_the_grids_cover_are_in_their_units(tmp_path, old, new, field, rule, given):
    """The ranges the operating-point grids cover (derive.control.sampling.grid): a revolute range in degrees, a
    prismatic travel in millimetres, a velocity limit in deg/s or mm/s."""
    text = POLAR.read_text()
    assert old in text
    (tmp_path / "polar.urdf").write_text(text.replace(old, new))
    data = tomllib.loads((POLAR.with_suffix(".toml")).read_text())
    problems = plausibility(arm_from_dict(data, str(tmp_path / "polar.toml"), base_dir=tmp_path))
    assert [p.field for p in problems][:1] == [field]
    assert rule in problems[0].expected and problems[0].given == given
