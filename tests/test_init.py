"""``derive init robot.urdf``: a starter arm file that loads as written, never
overwrites, and picks the chain's ends or says which to choose."""
from __future__ import annotations

import shutil
from fractions import Fraction
from pathlib import Path

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
    assert "nondecreasing" not in text and "derive check certifies them" in text   # no ordering of w is imposed
    assert "derive generate" in capsys.readouterr().err


def test_init_panda_with_tip_lists_limits_and_notes(tmp_path):
    urdf = _copy(tmp_path, "panda")
    out = tmp_path / "sub" / "arm.toml"
    out.parent.mkdir()
    assert main(["init", str(urdf), "--tip", "panda_hand_tcp", "--out", str(out)]) == 0
    text = out.read_text(encoding="utf-8")
    assert 'urdf = "../panda.urdf"' in text
    assert "# torque_limit = 87" in text and "# torque_limit = 12" in text
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
