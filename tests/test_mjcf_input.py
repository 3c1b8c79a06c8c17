"""Issue 35: MJCF, xacro and name-less URDF input (derive.model.mjcf, derive.cli.init_source).

* Frames, defaults, includes and inertials are MuJoCo's compiler's: an MJCF that writes its frames
  every way MJCF allows (``euler`` with the compiler's ``angle="degree"`` and ``eulerseq``,
  ``axisangle``, ``xyaxes``, ``zaxis``, ``quat``, a ``<frame>``, ``<default>`` classes, an
  ``<include>``, ``fullinertia`` and ``diaginertia`` with orientation, a ``ref``, a slide joint)
  gives J, g and the bias of MuJoCo's own model (mj_fullM, qfrc_bias) to 1e-10.
* ``derive init`` on an MJCF writes ``[arm] mjcf`` with the body names, the MJCF's gravity in the base
  frame, the armature as rotor inertia and the actuators' force limits as torque limits.
* Bad input (a ball joint on the chain, a tip that is not below the base, a missing include, a moving
  body with no inertial, two moving joints on a body): one clear error, exit 2, nothing written.
* xacro: ``--xacro-arg NAME:=VALUE`` expands with the xacro package; the URDF is written beside the arm
  file; a missing package or a malformed argument is one clear error.
* A URDF whose ``<robot>`` has no name is read; its name comes from the file, or ``--name``.
"""
from __future__ import annotations

import math
import sys
import tomllib
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from derive.cli import main
from derive.dynamics.equations import derive_dynamics
from derive.dynamics.program import lambdify
from derive.model.spec import arm_from_dict, load_arm

mujoco = pytest.importorskip("mujoco")

FRAMES = """<mujoco model="frames">
  <compiler angle="degree" eulerseq="zyx" autolimits="true"/>
  <option gravity="0 0 -9.81"/>
  <default>
    <joint armature="0.02" damping="0.3" frictionloss="0.05"/>
    <default class="wrist"><joint axis="1 0 0" range="-90 90" armature="0.01"/></default>
  </default>
  <include file="parts/hand.xml"/>
  <worldbody>
    <body name="base" pos="0.1 0 0" euler="0 0 30">
      <inertial pos="0 0 0.05" mass="2" diaginertia="0.01 0.01 0.01"/>
      <body name="l1" pos="0 0 0.2" axisangle="0 0 1 45">
        <joint name="j1" axis="0 0 1" range="-170 170"/>
        <inertial pos="0.02 0.01 0.1" mass="1.5" fullinertia="0.02 0.018 0.005 0.001 -0.002 0.0015"/>
        <frame pos="0 0.05 0.3" euler="10 20 30">
          <body name="l2" xyaxes="0 1 0 -1 0 0">
            <joint name="j2" axis="0 1 0" pos="0 0 -0.02" ref="15"/>
            <inertial pos="0.15 0 0" quat="0.9 0.1 0.3 -0.2" mass="1.2" diaginertia="0.004 0.03 0.032"/>
            <body name="l3" pos="0.3 0 0" zaxis="0 1 1">
              <joint name="j3" type="slide" axis="0 0 1" range="-0.1 0.1"/>
              <inertial pos="0 0 0.05" mass="0.7" diaginertia="0.002 0.002 0.001"/>
              <body name="l4" pos="0 0 0.1" quat="1 2 3 4">
                <joint name="j4" class="wrist"/>
                <geom type="box" size="0.03 0.02 0.05" mass="0.4"/>
                <body name="hand_mount" pos="0 0 0.08"/>
              </body>
            </body>
          </body>
        </frame>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="j1" gear="50" ctrlrange="-2 2"/>
    <position joint="j2" kp="100" forcerange="-30 40"/>
  </actuator>
</mujoco>
"""
HAND = """<mujoco><worldbody><body name="tray" pos="1 1 0">
  <inertial pos="0 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/></body></worldbody></mujoco>"""


def frames_file(folder: Path, text: str = FRAMES) -> Path:
    (folder / "parts").mkdir(parents=True, exist_ok=True)
    (folder / "parts" / "hand.xml").write_text(HAND)
    path = folder / "frames.xml"
    path.write_text(text)
    return path


def _mapping(path: Path, tip: str = "hand_mount", n: int = 4, **extra) -> dict:
    """The arm mapping of the MJCF at ``path``, gravity the MJCF's in the base body's frame."""
    from derive.model.mjcf import gravity_in_base

    try:
        size, direction = gravity_in_base(mujoco.MjModel.from_xml_path(str(path)), "base")
    except ValueError:    # a file MuJoCo refuses: derive's reader says why
        size, direction = 9.81, (0.0, 0.0, -1.0)
    return {"arm": {"name": "frames", "mjcf": str(path), "base_body": "base", "tip_body": tip, "gravity": size,
                    "gravity_direction": list(direction), "actuation": "torque", **extra},
            "controller": {"T1": 0.0, "T2": 0.2, "w": [1.0] * n}}


def test_frames_defaults_and_includes_are_muJoCos(tmp_path: Path) -> None:
    """Every way MJCF writes a frame, resolved by MuJoCo's compiler, gives MuJoCo's J, bias and g."""
    path = frames_file(tmp_path)
    arm = arm_from_dict(_mapping(path, n=4), "frames")   # the base is tilted (eulerseq zyx: 30 deg about x)
    assert [j.name for j in arm.chain.joints] == ["j1", "j2", "j3", "j4"]
    assert [j.type.value for j in arm.chain.joints] == ["revolute", "continuous", "prismatic", "revolute"]
    d = derive_dynamics(arm)
    n = d.n
    syms, vals = [s for s, _ in d.values], [float(v) for _, v in d.values]
    f = lambdify([*d.sym.theta, *d.sym.dtheta, *syms], list(d.J) + list(d.bias) + list(d.gravity))
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    for _ in range(20):
        q, v = rng.uniform(-1, 1, n) * [1, 1, 0.1, 1], rng.uniform(-2, 2, n)
        out = np.array(f(*q, *v, *vals), dtype=float)
        data.qpos[:], data.qvel[:] = q, v
        mujoco.mj_forward(model, data)
        M = np.zeros((n, n))
        mujoco.mj_fullM(model, data, M)
        bias = data.qfrc_bias.copy()
        data.qvel[:] = 0
        mujoco.mj_forward(model, data)
        for got, want in ((out[:n * n].reshape(n, n), M), (out[n * n:n * n + n], bias), (out[n * n + n:],
                                                                                        data.qfrc_bias)):
            assert np.max(np.abs(got - want)) <= 1e-10 * np.max(np.abs(want)), (got, want)


def test_what_is_read_from_joints_and_actuators(tmp_path: Path) -> None:
    """armature -> rotor inertia (Jm = A / gr^2), damping -> viscous friction, frictionloss -> the
    simulation's Coulomb friction, range -> limits (radians from the compiler's degrees), a motor's
    ctrlrange x gear and a servo's forcerange (its smaller side) -> effort limits."""
    path = frames_file(tmp_path)
    table = _mapping(path)
    table["motor"] = [{"gear_ratio": 2.0}, {}, {}, {"rotor_inertia": 0.5}]
    arm = arm_from_dict(table, "frames")
    assert [m.rotor_inertia for m in arm.motors] == [Fraction(1, 200), Fraction(1, 50), Fraction(1, 50), Fraction(1, 2)]
    assert [bv for bv, _ in arm.joint_friction] == [Fraction(3, 10)] * 4
    assert arm.simulation.coulomb_friction == (0.05,) * 4
    j1, j2, j3, j4 = arm.chain.joints
    assert float(j1.limits.upper) == pytest.approx(math.radians(170), rel=1e-15)
    assert (j1.limits.effort, j2.limits.effort, j3.limits.effort, j4.limits.effort) == (100, 30, None, None)
    assert (j3.limits.lower, j3.limits.upper) == (Fraction(-1, 10), Fraction(1, 10))
    assert j2.limits.lower is None   # a hinge without a range: continuous
    assert any("effort limits from the MJCF's actuators" in x for x in arm.chain.notes)


def _init_fails(tmp_path: Path, capsys, argv: list[str], *words: str) -> None:
    out = tmp_path / "out.toml"
    assert main(["init", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("derive: error:") == 1 and "Traceback" not in err, err
    for word in words:
        assert word in err, (word, err)
    assert not out.exists() and not list(tmp_path.glob("*.toml")) and not list(tmp_path.glob("*.urdf"))


BAD = {
    "ball joint on the chain": (lambda t: t.replace('<joint name="j3" type="slide" axis="0 0 1" range="-0.1 0.1"/>',
                                                    '<joint name="j3" type="ball"/>'), "hand_mount",
                                ["mjcf body 'l3' <joint 'j3'>", "hinge or slide joints on the chain", "a ball joint"]),
    "tip not below the base": (lambda t: t, "tray", ["--tip", "a body below base_body 'base'", "'tray'"]),
    "missing include": (lambda t: t.replace("parts/hand.xml", "parts/gone.xml"), "hand_mount",
                        ["<include file='parts/gone.xml'>", "expected a readable MJCF file", "no such file"]),
    "moving body without inertial": (lambda t: t.replace(
        '<inertial pos="0 0 0.05" mass="0.7" diaginertia="0.002 0.002 0.001"/>', '').replace(
        '<geom type="box" size="0.03 0.02 0.05" mass="0.4"/>', '').replace(
        '<joint name="j4" class="wrist"/>', ''), "hand_mount",
        ["body 'l3'", "mass and inertia on every body a joint moves", "none"]),
    "two moving joints on a body": (lambda t: t.replace('<joint name="j4" class="wrist"/>',
                                                        '<joint name="j4" class="wrist"/><joint name="j5" axis="0 1 0"/>'),
                                    "hand_mount", ["mjcf body 'l4'", "at most one moving joint per body", "'j4', 'j5'"]),
    "mesh inertia": (lambda t: t.replace('<geom type="box" size="0.03 0.02 0.05" mass="0.4"/>',
                                         '<geom type="mesh" mesh="shell"/>').replace(
        "<worldbody>", '<asset><mesh name="shell" file="shell.stl"/></asset><worldbody>', 1), "hand_mount",
        ["body 'l4'", "an <inertial>", "from its mesh geom"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_mjcf_is_one_error_from_init(tmp_path: Path, capsys, case: str) -> None:
    """Each defect: one clear error naming the body, joint or include, exit 2, nothing written."""
    edit, tip, words = BAD[case]
    path = frames_file(tmp_path, edit(FRAMES))
    _init_fails(tmp_path, capsys, [str(path), "--base", "base", "--tip", tip], *words)


def test_bad_mjcf_arm_file_is_one_error(tmp_path: Path) -> None:
    """The same defects from an arm file name its field (arm.tip_body) or the body."""
    from derive.errors import SpecError

    path = frames_file(tmp_path)
    with pytest.raises(SpecError, match=r"arm\.tip_body: expected a body below base_body 'base'"):
        arm_from_dict(_mapping(path, tip="tray"), "frames")
    with pytest.raises(SpecError, match=r"arm\.base_body: expected the name of a body of the MJCF .*did you mean"):
        arm_from_dict({**_mapping(path), "arm": {**_mapping(path)["arm"], "base_body": "bas"}}, "frames")
    with pytest.raises(SpecError, match=r"arm\.base_link: expected no such key without urdf"):
        arm_from_dict({**_mapping(path), "arm": {**_mapping(path)["arm"], "base_link": "base"}}, "frames")


def test_init_reads_an_mjcf(tmp_path: Path, capsys) -> None:
    """derive init on an MJCF: [arm] mjcf (relative), base_body/tip_body, the MJCF's gravity turned into
    the base body's frame (the base is tilted 90 degrees about x here: gravity along -y... of the base),
    armature as rotor inertia, the motor's ctrlrange x gear as its torque limit; the file loads."""
    path = frames_file(tmp_path, FRAMES.replace('euler="0 0 30"', 'euler="0 0 90" quat="0.7071067811865476 '
                                                '0.7071067811865476 0 0"').replace(' euler="0 0 90"', ''))
    out = tmp_path / "frames.toml"
    assert main(["init", str(path), "--base", "base", "--tip", "hand_mount", "--out", str(out)]) == 0, \
        capsys.readouterr().err
    text = out.read_text()
    data = tomllib.loads(text)
    assert data["arm"]["mjcf"] == "frames.xml" and data["arm"]["base_body"] == "base"
    assert data["arm"]["tip_body"] == "hand_mount" and data["arm"]["gravity"] == 9.81
    assert data["arm"]["gravity_direction"] == [0, -1, 0]   # R_x(90)^T (0, 0, -1)
    assert [m["rotor_inertia"] for m in data["motor"]] == [0.02, 0.02, 0.02, 0.01]
    assert data["motor"][0]["torque_limit"] == 100 and "the MJCF's armature" in text
    arm = load_arm(out)
    assert arm.n == 4 and arm.chain.gravity.free_symbols


def test_init_reads_a_nameless_urdf(tmp_path: Path, capsys) -> None:
    """A <robot> without a name (Robotis' xacro-generated open_manipulator.urdf): the arm is named after
    the file, or --name."""
    urdf = tmp_path / "Open-Manip.urdf"
    urdf.write_text("""<robot><link name="base"/><link name="l1"><inertial><mass value="1"/>
      <origin xyz="0.2 0 0"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
      <limit lower="-1" upper="1" effort="5" velocity="2"/></joint></robot>""")
    assert main(["init", str(urdf), "--out", str(tmp_path / "a.toml")]) == 0, capsys.readouterr().err
    assert tomllib.loads((tmp_path / "a.toml").read_text())["arm"]["name"] == "open_manip"
    assert "the URDF file's name 'Open-Manip'" in (tmp_path / "a.toml").read_text()
    assert main(["init", str(urdf), "--out", str(tmp_path / "b.toml"), "--name", "omx"]) == 0
    assert tomllib.loads((tmp_path / "b.toml").read_text())["arm"]["name"] == "omx"


XACRO = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="$(arg kind)_arm">
  <xacro:arg name="kind" default="small"/>
  <xacro:property name="reach" value="${0.3 if '$(arg kind)' == 'small' else 0.6}"/>
  <xacro:macro name="link" params="name mass">
    <link name="${name}"><inertial><origin xyz="${reach / 2} 0 0"/><mass value="${mass}"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  </xacro:macro>
  <link name="base"/>
  <xacro:link name="upper" mass="2"/>
  <xacro:link name="lower" mass="1"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="20" velocity="2"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="lower"/><origin xyz="${reach} 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="10" velocity="2"/></joint>
</robot>
"""


def test_init_expands_xacro_with_arguments(tmp_path: Path, capsys) -> None:
    """--xacro-arg kind:=large: the xacro package expands the file (the argument reaches the robot's name
    and a property), the URDF is written beside the arm file and named by it."""
    pytest.importorskip("xacro")
    src = tmp_path / "arm.urdf.xacro"
    src.write_text(XACRO)
    out = tmp_path / "big.toml"
    assert main(["init", str(src), "--xacro-arg", "kind:=large", "--out", str(out)]) == 0, capsys.readouterr().err
    data = tomllib.loads(out.read_text())
    assert data["arm"]["urdf"] == "big.urdf" and data["arm"]["name"] == "large_arm"
    assert 'origin xyz="0.6 0 0"' in (tmp_path / "big.urdf").read_text()
    assert "expansion of `xacro arm.urdf.xacro kind:=large`" in out.read_text()
    assert load_arm(out).n == 2


def test_xacro_bad_argument_or_missing_package_is_one_error(tmp_path: Path, capsys, monkeypatch) -> None:
    src = tmp_path / "arm.urdf.xacro"
    src.write_text(XACRO)
    _init_fails(tmp_path, capsys, [str(src), "--xacro-arg", "kind=large"], "--xacro-arg: expected NAME:=VALUE")
    monkeypatch.setitem(sys.modules, "xacro", None)
    _init_fails(tmp_path, capsys, [str(src)], "expected the xacro package", "pip install 'derive[xacro]'")


def test_xacro_that_does_not_expand_is_one_error(tmp_path: Path, capsys) -> None:
    pytest.importorskip("xacro")
    src = tmp_path / "arm.urdf.xacro"
    src.write_text(XACRO.replace("${reach / 2}", "${undefined_property}"))
    _init_fails(tmp_path, capsys, [str(src), "--xacro-arg", "kind:=small"], "expected a xacro file the xacro "
                "package expands with kind:=small", "undefined_property")


def test_an_mjcf_without_mujoco_installed_is_one_error(tmp_path: Path, capsys, monkeypatch) -> None:
    """MuJoCo is an optional dependency: reading an MJCF without it names the install command."""
    path = frames_file(tmp_path)
    monkeypatch.setitem(sys.modules, "mujoco", None)
    _init_fails(tmp_path, capsys, [str(path), "--base", "base", "--tip", "hand_mount"],
                "expected the mujoco package to read an MJCF", "pip install 'derive[mujoco]'")


def test_xacro_find_resolves_to_the_package_above_the_file(tmp_path: Path, capsys) -> None:
    """$(find my_description) without ROS: the folder above the xacro file that holds that package's
    package.xml; a package found nowhere is one error naming it."""
    pytest.importorskip("xacro")
    pkg = tmp_path / "src" / "description_checkout"
    (pkg / "urdf").mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>my_description</name></package>")
    (pkg / "urdf" / "macros.xacro").write_text(XACRO.split("<link name=\"base\"/>")[0].split(
        '<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="$(arg kind)_arm">')[1].replace(
        '<xacro:arg name="kind" default="small"/>', "").join(
        ['<robot xmlns:xacro="http://www.ros.org/wiki/xacro">', "</robot>"]))
    main_file = pkg / "urdf" / "arm.urdf.xacro"
    main_file.write_text(XACRO.replace('<xacro:macro name="link"', '<xacro:include filename="$(find my_description)'
                                       '/urdf/macros.xacro"/>\n  <xacro:macro name="unused"'))
    out = tmp_path / "arm.toml"
    assert main(["init", str(main_file), "--xacro-arg", "kind:=small", "--out", str(out)]) == 0, \
        capsys.readouterr().err
    assert load_arm(out).n == 2
    main_file.write_text(main_file.read_text().replace("$(find my_description)", "$(find not_here)"))
    _init_fails(tmp_path / "src", capsys, [str(main_file), "--xacro-arg", "kind:=small"], "not_here")


def test_repair_inertia_is_for_urdfs(tmp_path: Path, capsys) -> None:
    """MuJoCo's compiler refuses a non-physical inertia before derive reads an MJCF: --repair-inertia and
    repair_inertia say so (one error each)."""
    from derive.errors import SpecError

    path = frames_file(tmp_path)
    _init_fails(tmp_path, capsys, [str(path), "--base", "base", "--tip", "hand_mount", "--repair-inertia"],
                "--repair-inertia: expected a URDF")
    with pytest.raises(SpecError, match=r"arm\.repair_inertia: expected false or absent for an MJCF"):
        arm_from_dict({**_mapping(path), "arm": {**_mapping(path)["arm"], "repair_inertia": True}}, "frames")
