"""Issue 35 on MuJoCo's side: whatever ``derive init`` accepts is what MuJoCo integrates.

* An arm read from its own MJCF (``[arm] mjcf``) runs on MuJoCo from that file: derive's plant and
  MuJoCo's agree within tests/test_mujoco_plant.py's stated tolerance (friction off); the file's
  armature is derive's rotor inertia, not added to it; the joints above the base (a free joint) and
  those held at 0 (a finger) are fixed; contacts are off unless ``mujoco_contacts`` asks.
* What MuJoCo integrates is what derive derived, checked where it would go wrong: the mass matrix of
  MuJoCo's compiled model (mj_fullM, friction off) equals derive's J to 1e-12 at seeded states, for a
  URDF with a repaired inertia (``repair_inertia``: MuJoCo alone refuses the file), with massless
  virtual joints above the base (a mobile base, as the Fetch's), with a mimic finger held at its
  mimic value, and with a non-physical inertia off the chain (MuJoCo alone refuses it too).
* A massless moving link: derive's message with the fix, exit 2, nothing written.
* ``derive simulate --plant mujoco`` writes the model it integrated (mujoco_model.xml), which MuJoCo
  loads again with derive's joints as its only degrees of freedom.
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from derive.cli import main
from derive.control.pipeline import derive
from derive.model.spec import load_arm
from derive.sim.plants import DerivedPlant, build, compare, select
from tests.test_mujoco_plant import tolerance

mujoco = pytest.importorskip("mujoco")

ARM = """<mujoco model="three">
  <compiler angle="radian" autolimits="true"/>
  <default><joint armature="0.01" damping="0.2" axis="0 1 0"/></default>
  <worldbody>
    <body name="cart">
      <freejoint name="float"/>
      <inertial pos="0 0 0" mass="5" diaginertia="0.1 0.1 0.1"/>
      <body name="base" pos="0 0 0.1">
        <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
        <body name="l1" pos="0 0 0.1" euler="0 0 0.3">
          <joint name="j1" axis="0 0 1"/>
          <inertial pos="0.1 0 0.05" mass="1.2" fullinertia="0.01 0.012 0.008 0.001 0 0.0005"/>
          <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.03" contype="1" conaffinity="1"/>
          <body name="l2" pos="0.2 0 0.05">
            <joint name="j2" range="-2 2"/>
            <inertial pos="0.15 0 0" quat="0.9 0.1 0 0.2" mass="0.8" diaginertia="0.002 0.01 0.011"/>
            <body name="l3" pos="0.3 0 0">
              <joint name="j3" axis="1 0 0"/>
              <inertial pos="0.05 0.01 0" mass="0.4" diaginertia="0.001 0.002 0.002"/>
              <body name="finger" pos="0.1 0 0">
                <joint name="slide" type="slide" axis="1 0 0" range="0 0.04"/>
                <inertial pos="0.02 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/>
              </body>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator><position joint="j1" kp="50"/></actuator>
</mujoco>
"""


def write_arm(folder: Path, name: str, model: str, head: str, w: int, simulation: str) -> Path:
    """The arm file ``name``.toml in ``folder``: [arm] with ``head`` (the file's keys), torque actuation,
    w = 0.5 for each of ``w`` joints, [simulation] ``simulation``; the model file ``model`` beside it."""
    folder.mkdir(parents=True, exist_ok=True)
    suffix = "xml" if model.lstrip().startswith("<mujoco") else "urdf"
    (folder / f"{name}.{suffix}").write_text(model)
    path = folder / f"{name}.toml"
    path.write_text(f"""[arm]
name = "{name}"
{head}
gravity = 9.81
actuation = "torque"

[controller]
T1 = 0.0
T2 = 0.2
w = [{', '.join(['0.5'] * w)}]

[simulation]
{simulation}""")
    return path


def arm_file(folder: Path, extra: str = "", simulation: str = "") -> Path:
    return write_arm(folder, "three", ARM, f'mjcf = "three.xml"\nbase_body = "base"\ntip_body = "l3"\n{extra}', 3,
                     f"sample_time = 0.002\nsubsteps = 4\nduration = 3.0\n{simulation}")


def fullM_equals_J(arm, states: int = 5) -> None:
    """MuJoCo's compiled model of the run (friction off: derive's armature) has derive's J (eq. 12)."""
    from derive.control.sampling.grid import mass_function

    d = derive(arm)
    c = select(arm, "mujoco", "off").model(d, arm.simulation)
    data = mujoco.MjData(c.model)
    J = mass_function(d)
    rng = np.random.default_rng(7)
    for _ in range(states):
        q = rng.uniform(-1.0, 1.0, d.n) * [0.04 if not j.type.rotates else 1.0 for j in d.dynamics.chain.joints]
        data.qpos[c.qadr] = q
        mujoco.mj_forward(c.model, data)
        M = np.zeros((c.model.nv, c.model.nv))
        mujoco.mj_fullM(c.model, data, M)
        want = J(np.array([q]))[0]
        got = M[np.ix_(c.dadr, c.dadr)]
        assert np.max(np.abs(got - want)) <= 1e-12 * np.max(np.abs(want)), (got, want)


def test_own_mjcf_runs_on_mujoco_as_derive_reads_it(tmp_path: Path) -> None:
    """The arm's own MJCF is MuJoCo's plant; the free joint of the body above the base and the finger
    held at 0 are fixed, the file's position servo removed, armature = derive's rotor inertia; the two
    plants agree within the stated tolerance (friction off) and MJCF contacts are off by default."""
    arm = load_arm(arm_file(tmp_path))
    fullM_equals_J(arm)
    d = derive(arm)
    mj = select(arm, "mujoco", "file")
    desc = mj.describe(d, arm.simulation)
    assert desc["kind"] == "mjcf" and desc["model"] == "three.xml"
    assert "float at the model pose (above or beside the chain's base)" in desc["held"]
    assert "slide at 0" in desc["held"]
    assert [j["armature"] for j in desc["joints"]] == pytest.approx([0.01] * 3)   # derive's, from the file's
    assert not any("contact" in x for x in desc["beyond_derive"]) and not any("armature" in x for x in
                                                                                desc["beyond_derive"])
    off = select(arm, "mujoco", "off")
    loop = build(d, sources=(off, DerivedPlant()))
    a, b = off.run(d, loop, arm.simulation, "npid"), DerivedPlant().run(d, loop, arm.simulation, "npid")
    assert a.failure is None and np.max(np.abs(b.theta)) > 0.5
    assert compare([a], [b], {})["max_theta_difference"] <= tolerance(b, arm.simulation)
    asked = load_arm(arm_file(tmp_path / "contacts", simulation="mujoco_contacts = true\n"))
    assert any("contacts between the MJCF's" in x for x in select(asked, "mujoco", "file").describe(
        derive(asked), asked.simulation)["beyond_derive"])


def test_rotor_inertia_changed_in_the_arm_file_reaches_mujoco(tmp_path: Path) -> None:
    """[[motor]] rotor_inertia replaces the MJCF's armature in both plants (never the sum)."""
    motors = "".join("[[motor]]\nrotor_inertia = 0.05\n" for _ in range(3))
    text = arm_file(tmp_path).read_text().replace("[controller]", motors + "[controller]")
    (tmp_path / "three.toml").write_text(text)
    arm = load_arm(tmp_path / "three.toml")
    fullM_equals_J(arm, 2)
    desc = select(arm, "mujoco", "file").describe(derive(arm), arm.simulation)
    assert [j["armature"] for j in desc["joints"]] == pytest.approx([0.05] * 3)
    assert sum("armature 0.05 kg m^2 (derive's rotor inertia), the file's 0.01 replaced" in x
               for x in desc["beyond_derive"]) == 3


URDF = """<robot name="mobile">
  <link name="world_anchor"/>
  <link name="virtual_x"/>
  <link name="base_link"><inertial><mass value="20"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="mast"><inertial><mass value="1"/><inertia ixx="0.011" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="upper"><inertial><origin xyz="0.2 0 0"/><mass value="2"/>
    <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.03"/></inertial></link>
  <link name="lower"><inertial><origin xyz="0.15 0 0"/><mass value="1"/>
    <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.011"/></inertial></link>
  <link name="hand"><inertial><mass value="0.5"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0.001"/></inertial></link>
  <link name="finger"><inertial><origin xyz="0.02 0 0"/><mass value="0.1"/>
    <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial></link>
  <link name="finger2"><inertial><origin xyz="0.02 0 0"/><mass value="0.1"/>
    <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial></link>
  <joint name="move_x" type="prismatic"><parent link="world_anchor"/><child link="virtual_x"/>
    <axis xyz="1 0 0"/><limit lower="-10" upper="10" effort="100" velocity="1"/></joint>
  <joint name="turn" type="continuous"><parent link="virtual_x"/><child link="base_link"/><axis xyz="0 0 1"/></joint>
  <joint name="mast_fixed" type="fixed"><parent link="base_link"/><child link="mast"/><origin xyz="-0.3 0 0.5"/></joint>
  <joint name="shoulder" type="revolute"><parent link="base_link"/><child link="upper"/><origin xyz="0 0 0.4"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="50" velocity="2"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="lower"/><origin xyz="0.4 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="30" velocity="2"/></joint>
  <joint name="wrist" type="fixed"><parent link="lower"/><child link="hand"/><origin xyz="0.3 0 0"/></joint>
  <joint name="grip" type="prismatic"><parent link="hand"/><child link="finger"/><origin xyz="0.05 0 0"/>
    <axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="10" velocity="0.1"/></joint>
  <joint name="grip2" type="prismatic"><parent link="hand"/><child link="finger2"/><origin xyz="0.05 0 0"/>
    <axis xyz="0 1 0"/><mimic joint="grip" multiplier="-1" offset="0"/>
    <limit lower="-0.04" upper="0" effort="10" velocity="0.1"/></joint>
</robot>
"""


def urdf_arm(folder: Path, urdf: str = URDF, extra: str = "") -> Path:
    return write_arm(folder, "mobile", urdf, f'urdf = "mobile.urdf"\nbase_link = "base_link"\ntip_link = "hand"\n{extra}',
                     2, "sample_time = 0.002\nduration = 2.0\n")


def test_repairs_held_joints_and_mimics_reach_mujoco(tmp_path: Path) -> None:
    """The hand's inertia (0, 0, 0.001: not physical) repaired, the massless virtual base joints above
    base_link fixed, the finger locked at 0.03 and its mimic at -0.03, the off-chain mast kept: MuJoCo's
    mass matrix is derive's J. Without derive, MuJoCo refuses the file."""
    path = urdf_arm(tmp_path, extra='repair_inertia = ["hand"]\nlocked = { grip = 0.03 }\n')
    with pytest.raises(ValueError, match="inertia|mass"):
        mujoco.MjModel.from_xml_string(URDF.replace("</robot>", '<mujoco><compiler fusestatic="false" '
                                                    'balanceinertia="false"/></mujoco></robot>'))
    arm = load_arm(path)
    fullM_equals_J(arm)
    desc = select(arm, "mujoco", "off").describe(derive(arm), arm.simulation)
    held = desc["held"]
    assert "move_x at the model pose (above or beside the chain's base)" in held and "grip at 0.03" in held
    assert "grip2 at -0.03" in held, held
    assert any("inertias as derive repaired them (repair_inertia): 'hand'" in x for x in desc["notes"])


def test_a_non_physical_inertia_off_the_chain_does_not_stop_mujoco(tmp_path: Path) -> None:
    """The mast (beside the chain, not used by derive) has a tensor breaking the triangle inequality:
    derive notes it, MuJoCo's model drops its <inertial> (said), and the plant's J is derive's."""
    arm = load_arm(urdf_arm(tmp_path, URDF.replace('ixx="0.011"', 'ixx="0.5"').replace(
        '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0.001"/>',
        '<inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/>')))
    fullM_equals_J(arm, 2)
    notes = select(arm, "mujoco", "off").describe(derive(arm), arm.simulation)["notes"]
    assert any("<inertial> removed from links derive does not use" in x and "'mast'" in x for x in notes), notes


def test_a_massless_moving_link_gets_derives_message(tmp_path: Path, capsys) -> None:
    """A massless link between two joints (derive's plant runs it): one error naming the body, the joint
    and the fix, not MuJoCo's message; exit 2, nothing written."""
    urdf = """<robot name="dummy"><link name="base"/><link name="mid"/>
      <link name="l2"><inertial><origin xyz="0.3 0 0"/><mass value="1.0"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="mid"/><origin xyz="0 0 0.1"/>
        <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="50" velocity="3"/></joint>
      <joint name="j2" type="revolute"><parent link="mid"/><child link="l2"/>
        <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" effort="50" velocity="3"/></joint></robot>"""
    path = urdf_arm(tmp_path, urdf)
    path.write_text(path.read_text().replace('tip_link = "hand"', 'tip_link = "l2"').replace(
        'base_link = "base_link"', 'base_link = "base"'))
    out = tmp_path / "out"
    assert main(["simulate", str(path), "--plant", "mujoco", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("derive: error:") == 1 and "Traceback" not in err
    for words in ("expected mass and inertia on body 'mid' (moved by joint 'j1'", "give 'mid' an <inertial>",
                  "locked = { j1 = 0.0 }"):
        assert words in err, err
    assert "mjMINVAL\nElement" not in err and not out.exists()


def test_simulate_writes_the_model_mujoco_integrated(tmp_path: Path) -> None:
    """mujoco_model.xml beside the outputs (listed in MANIFEST.json): MuJoCo loads it, its degrees of
    freedom are derive's joints, and it says it is generated."""
    path = arm_file(tmp_path)
    out = tmp_path / "sim"
    assert main(["simulate", str(path), "--plant", "mujoco", "--duration", "0.5", "--controllers", "npid",
                 "--out", str(out)]) == 0
    text = (out / "mujoco_model.xml").read_text()
    assert text.startswith("<!-- generated by derive simulate (the MuJoCo plant) from three.xml; do not edit.")
    import defusedxml.ElementTree as safe

    assert safe.fromstring(text.encode()).tag == "mujoco"   # well-formed XML: no "--" in the comment
    model = mujoco.MjModel.from_xml_string(text)
    assert [model.joint(j).name for j in range(model.njnt)] == ["j1", "j2", "j3"] and model.nu == 3
    assert "mujoco_model.xml" in json.loads((out / "MANIFEST.json").read_text())["files"]
    assert main(["simulate", str(path), "--duration", "0.5", "--controllers", "npid", "--out",
                 str(tmp_path / "derive")]) == 0
    assert not (tmp_path / "derive" / "mujoco_model.xml").exists()   # derive's own plant: no MuJoCo model
