"""``[arm] snap_angles`` (issue 33: cost independent of how a file writes its numbers). CAD exporters
write pi/2 as 1.5708 (3.7e-6 rad off): kept as written its rotation is dense with 120-bit rationals and
derive check's exact proofs cost 3 to 8 times more (derive.proofs.torus; the decimal 7-joint chain: check
55.7 s and 1.3 GB against 22 s and 0.5 GB). With snap_angles the angle is pi/2 exactly, in derive's chain
and in the URDF MuJoCo is given; derive init writes it for angles within 1e-4 rad of a multiple of pi/2,
and says so. No timing assertions (make corpus and make bench measure)."""
from __future__ import annotations

import math
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from benchmarks.chains import snake_urdf
from derive.cli import main
from derive.model.spec import load_arm

CORPUS = Path(__file__).parent / "data" / "urdf" / "corpus"
HALF_PI = "1.5707963267948966"


def _arm(folder: Path, urdf_text: str, extra: str = "", n: int = 4) -> Path:
    (folder / "a.urdf").write_text(urdf_text, encoding="utf-8")
    text = "\n".join(['[arm]', 'name = "snake"', 'urdf = "a.urdf"', 'base_link = "base"', f'tip_link = "l{n}"',
                      'gravity = 9.81', 'gravity_direction = [0, 0, -1]', 'actuation = "torque"', extra,
                      *(['[[motor]]', 'gear_ratio = 1.0'] * n), '[controller]', 'T1 = 0.0', 'T2 = 0.2',
                      f'w = {[0.5] * n}', ''])
    (folder / "a.toml").write_text(text, encoding="utf-8")
    return folder / "a.toml"


def test_snap_angles_takes_the_exporters_pi_over_2_as_pi_over_2(tmp_path):
    """1.5708 with snap_angles = 5e-6 gives the chain of the same file written with pi/2 to 17 digits (the
    same exact rotations, 0 and +-1 where pi/2 puts them), and the note says what was snapped; without it the
    angle is kept as written (a different, dense rotation) and the note proposes the value."""
    decimal = snake_urdf(4, decimal=True)
    (tmp_path / "s").mkdir()
    (tmp_path / "x").mkdir()
    (tmp_path / "k").mkdir()
    snapped = load_arm(_arm(tmp_path / "s", decimal, "snap_angles = 5e-6")).spatial
    exact = load_arm(_arm(tmp_path / "x", decimal.replace('rpy="1.5708 ', f'rpy="{HALF_PI} '))).spatial
    kept = load_arm(_arm(tmp_path / "k", decimal)).spatial
    (tmp_path / "b").mkdir()   # just below the distance (3.7e-6 rad): kept as written
    below = load_arm(_arm(tmp_path / "b", decimal, "snap_angles = 3e-6")).spatial
    assert [j.origin.R for j in below.joints] == [j.origin.R for j in kept.joints]
    assert [j.origin.R for j in snapped.joints] == [j.origin.R for j in exact.joints]
    assert [j.origin.R for j in kept.joints] != [j.origin.R for j in exact.joints]
    assert sum(1 for j in snapped.joints for e in j.origin.R if e == 0) > \
        sum(1 for j in kept.joints for e in j.origin.R if e == 0)
    assert any("within 5e-06 rad of a multiple of pi/2 snapped to it" in n and "1.5708 -> pi/2" in n
               for n in snapped.notes)
    assert any("kept as written" in n and "snap_angles = 5e-06 under [arm]" in n for n in kept.notes)


@pytest.mark.parametrize("value, shown", [('"1e-5"', "'1e-5'"), ("-1e-5", "-1e-05"), ("0.01", "0.01"),
                                          ("true", "boolean true"), ("1e-9", "1e-09")])
def test_snap_angles_out_of_range_is_one_clear_problem(tmp_path, capsys, value, shown):
    """A value that is not a number of radians from 1e-8 to 1e-3 is refused, naming the field, what is
    expected and what was given: exit 2, no traceback."""
    path = _arm(tmp_path, snake_urdf(4, decimal=True), f"snap_angles = {value}")
    code = main(["show", str(path), "--no-cache"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert "arm.snap_angles" in err and "a number of radians from 1e-08 to 0.001" in err and shown in err, err


def test_snap_angles_belongs_to_urdf_arms(capsys, tmp_path):
    """On an arm whose kinematics are not a URDF's (here the planar default arm's file) the key is refused."""
    src = Path(__file__).parents[1] / "derive" / "model" / "arms" / "glasgow_2link.toml"
    text = src.read_text(encoding="utf-8").replace("[arm]\n", "[arm]\nsnap_angles = 1e-5\n", 1)
    (tmp_path / "g.toml").write_text(text, encoding="utf-8")
    code = main(["show", str(tmp_path / "g.toml"), "--no-cache"])
    err = capsys.readouterr().err
    assert code == 2 and "snap_angles" in err and "Traceback" not in err, err


def test_init_writes_snap_angles_for_an_exporters_rounding_and_not_otherwise(tmp_path, capsys):
    """derive init on the corpus' decimal chain writes snap_angles = 5e-06 with its reason, and the file it
    writes loads with the angles snapped; on the UR5 (no angle near a multiple of pi/2 but off it) nothing."""
    (tmp_path / "c.urdf").write_text((CORPUS / "snake7_decimal.urdf").read_text(encoding="utf-8"), encoding="utf-8")
    assert main(["init", str(tmp_path / "c.urdf"), "--out", str(tmp_path / "c.toml")]) == 0
    text = (tmp_path / "c.toml").read_text(encoding="utf-8")
    assert "\nsnap_angles = 5e-06 " in text and "Delete this line" in text
    assert any("1.5708 -> pi/2" in n for n in load_arm(tmp_path / "c.toml").spatial.notes)
    ur5 = Path(__file__).parent / "data" / "urdf" / "ur5.urdf"
    (tmp_path / "u.urdf").write_text(ur5.read_text(encoding="utf-8"), encoding="utf-8")
    assert main(["init", str(tmp_path / "u.urdf"), "--tip", "tool0", "--out", str(tmp_path / "u.toml")]) == 0
    assert "snap_angles" not in (tmp_path / "u.toml").read_text(encoding="utf-8")
    capsys.readouterr()


def test_mujoco_is_given_the_angles_derive_snaps():
    """The URDF MuJoCo compiles (derive.sim.mujoco.source) carries pi/2 where snap_angles takes 1.5708 as
    pi/2, and 1.5708 as written by default: both plants integrate the same kinematics."""
    from derive.sim.mujoco.source import _snap_angles

    def angles(tolerance=None):
        root = ET.fromstring(snake_urdf(3, decimal=True))
        said = _snap_angles(root) if tolerance is None else _snap_angles(root, tolerance)
        return [float(o.get("rpy").split()[0]) for o in root.findall("joint/origin")], said

    kept, said = angles()
    assert kept == [1.5708] * 3 and said == ""
    snapped, said = angles(5e-6)
    assert snapped == [math.pi / 2] * 3 and "1.5708 -> pi/2 (3 times)" in said


def test_dh_snap_angles_takes_a_papers_1_5708_as_pi_over_2(tmp_path, capsys):
    """[dh] snap_angles: a table written with 1.5708 gives the chain of the same table written "pi/2"; out of
    range it is one problem naming dh.snap_angles."""
    def arm(alpha: str, extra: str = "") -> Path:
        text = "\n".join(['[arm]', 'name = "dh2"', 'actuation = "torque"', 'gravity = 9.81',
                          '[dh]', 'convention = "standard"', f'table = [[0.3, {alpha}, 0.1, 0], [0.2, 0, 0, 0]]', extra,
                          '[[body]]', 'mass = 1.0', 'com = [0.1, 0, 0]', '[[body]]', 'mass = 0.5', 'com = [0.1, 0, 0]',
                          '[[motor]]', 'gear_ratio = 1.0', '[[motor]]', 'gear_ratio = 1.0',
                          '[controller]', 'T1 = 0.0', 'T2 = 0.2', 'w = [0.5, 0.5]', ''])
        path = tmp_path / f"dh{len(list(tmp_path.iterdir()))}.toml"
        path.write_text(text, encoding="utf-8")
        return path

    exact = load_arm(arm('"pi/2"')).spatial
    snapped = load_arm(arm("1.5708", "snap_angles = 1e-5")).spatial
    kept = load_arm(arm("1.5708")).spatial
    def frames(chain):
        return [j.origin for j in chain.joints], list(chain.bodies)

    assert frames(snapped) == frames(exact) and frames(kept) != frames(exact)
    code = main(["show", str(arm("1.5708", "snap_angles = 0.5")), "--no-cache"])
    err = capsys.readouterr().err
    assert code == 2 and "dh.snap_angles" in err and "a number of radians from 1e-08 to 0.001" in err, err
