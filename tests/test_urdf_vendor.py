"""Vendor URDFs as they ship (issue 19, items 3 and 5): what is not on the chain never
blocks, what moves with the chain is checked strictly; ``<mimic>`` is followed for held
joints; ``<dynamics damping friction>`` are used, a ``<dynamics><damping>`` element is a
warning on every command. The handed cases (shared/cases/round3: xarm6_transmission,
tiago_offchain, mimic_offchain, damping_element_silent) are here with their right values."""
from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.cli import main
from derive.errors import SpecError
from derive.model.fields import Reader
from derive.model.spec import SPATIAL_DOWN, gravity_parameter, unit_direction
from derive.model.urdf import urdf_chain

from .chainnum import NumericChain
from .test_bad_input import to_toml

DATA = Path(__file__).parent / "data" / "urdf"
CORPUS = DATA / "corpus"
BOX = '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'
NOT_PSD = '<inertia ixx="2.371e-08" ixy="6.119e-08" ixz="1.179e-08" iyy="2.833e-08" iyz="7.74e-09" izz="3.849e-08"/>'


def chain_of(path: Path, base: str, tip: str, **arm) -> tuple:
    """(UrdfChain or None, problems) of the URDF at ``path``."""
    r = Reader()
    found = urdf_chain(r, {"urdf": str(path), "base_link": base, "tip_link": tip, **arm}, Path("/"),
                       gravity_parameter(Fraction(981, 100)), unit_direction(SPATIAL_DOWN))
    return found, r.problems


def link(name: str, mass: str = "1.0", inertia: str = BOX, extra: str = "") -> str:
    return f'<link name="{name}"><inertial><origin xyz="0.1 0 0"/><mass value="{mass}"/>{inertia}</inertial>{extra}</link>'


def joint(name: str, parent: str, child: str, kind: str = "revolute", extra: str = "", xyz: str = "0 0 0.1") -> str:
    axis = '<axis xyz="0 0 1"/>' if kind != "fixed" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}"/>{axis}<limit lower="-2" upper="2" effort="10" velocity="2"/>{extra}</joint>')


def write(tmp_path: Path, *parts: str, name: str = "r.urdf") -> Path:
    path = tmp_path / name
    path.write_text(f'<?xml version="1.0"?>\n<robot name="r">{"".join(parts)}</robot>\n', encoding="utf-8")
    return path


# -- item 3: what is not on the chain never blocks ----------------------------------------

def test_xarm6_transmission_with_an_unexpanded_xacro_value_is_dropped_with_a_note() -> None:
    """Case xarm6_transmission: <mechanicalReduction>reduction</mechanicalReduction> used to
    reject the file ("could not convert string to flo"); it is not read now, and the one
    refusal left is xArm6's real defect, links 2 and 3 breaking the triangle inequality by
    2e-4 and 1e-3 kg m^2, each named with its margin."""
    found, problems = chain_of(CORPUS / "xarm6.urdf", "world", "link6")
    assert found is None and [p.field for p in problems] == [
        "urdf link 'link2' <inertial><inertia>", "urdf link 'link3' <inertial><inertia>"]
    text = "\n".join(map(str, problems))
    assert "violated by 0.0002 kg m^2" in text and "violated by 0.00098 kg m^2" in text
    assert "principal moments 0.0269 > 0.003058 + 0.02364" in text
    assert "could not convert" not in text and 'repair_inertia = ["link2"] under [arm]' in text
    found, problems = chain_of(CORPUS / "xarm6.urdf", "world", "link6", repair_inertia=True)
    assert not problems and found.chain.n == 6 and found.repaired == ("link2", "link3")
    assert any("6 <transmission>" in n and "8 <gazebo>" in n for n in found.chain.notes)


def test_offchain_inertia_that_is_not_physical_is_a_note(tmp_path: Path) -> None:
    """Case tiago_offchain (the mobile base's antennas, 1e-8 kg m^2 non-PSD, far from the
    chain): a note; the same tensor on a link merged into a chain body: an error."""
    parts = [link("base"), link("antenna", "0.001", NOT_PSD), link("a"), link("b"),
             joint("ant", "base", "antenna", "fixed"), joint("j1", "base", "a"), joint("j2", "a", "b")]
    found, problems = chain_of(write(tmp_path, *parts), "base", "b")
    assert not problems and found.chain.n == 2
    assert any("urdf link 'antenna' <inertial><inertia> (not on the chain, not used): expected a positive "
               "semi-definite tensor" in n for n in found.chain.notes)
    merged = [link("base"), link("a"), link("b"), link("sensor", "0.001", NOT_PSD),
              joint("j1", "base", "a"), joint("j2", "a", "b"), joint("s", "b", "sensor", "fixed")]
    found, problems = chain_of(write(tmp_path, *merged, name="m.urdf"), "base", "b")
    assert found is None and [p.field for p in problems] == ["urdf link 'sensor' <inertial><inertia>"]
    assert "a negative principal moment" in str(problems[0])


def test_a_number_that_does_not_parse_blocks_only_on_the_chain(tmp_path: Path) -> None:
    """An unexpanded xacro value: a note off the chain (above or at the base: it does not
    move), an error naming the element and attribute on it (a joint of the chain)."""
    parts = [link("world", "${m}"), link("base"), link("a"), link("b"),
             joint("w", "world", "base", "fixed"), joint("j1", "base", "a"), joint("j2", "a", "b")]
    found, problems = chain_of(write(tmp_path, *parts), "base", "b")
    assert not problems and any("urdf link 'world' <inertial><mass value> (not on the chain, not read)" in n
                                for n in found.chain.notes)
    found, problems = chain_of(write(tmp_path, *parts, name="w.urdf"), "world", "b")   # the base does not move
    assert not problems and found.chain.n == 2
    bad_on_chain = [link("base"), link("a"), link("b", extra=""), joint("j1", "base", "a"),
                    joint("j2", "a", "b", xyz="${l} 0 0.1")]
    found, problems = chain_of(write(tmp_path, *bad_on_chain, name="c.urdf"), "base", "b")
    assert found is None and [str(p) for p in problems] == [
        "urdf joint 'j2' <origin xyz>: expected 3 numbers separated by spaces, got '${l} 0 0.1'"]


def test_tiago_antennas_do_not_block_its_arm() -> None:
    """The real Tiago (78 links, 47 transmissions, 71 Gazebo tags): torso_lift_link -> arm_tool_link."""
    pytest.importorskip("pinocchio")
    found, problems = chain_of(CORPUS / "tiago.urdf", "torso_lift_link", "arm_tool_link")
    assert not problems and found.chain.n == 7
    assert any("'base_antenna_left_link'" in n and "not on the chain" in n for n in found.chain.notes)


test_tiago_antennas_do_not_block_its_arm = pytest.mark.slow(test_tiago_antennas_do_not_block_its_arm)


def test_messages_are_never_cut_mid_word(tmp_path: Path) -> None:
    """A long bad value is shortened at a word boundary, with the count of what was left out."""
    long = " ".join(f"word{k}" for k in range(40))
    parts = [link("base"), link("a"), joint("j1", "base", "a", xyz=long)]
    _, problems = chain_of(write(tmp_path, *parts), "base", "a")
    given = problems[0].given
    assert given.startswith("word0 word1") and "more characters)" in given
    shown = given.split(" ...")[0].split()
    assert all(w in long.split() for w in shown)


# -- item 5: <mimic> ----------------------------------------------------------------------

MIMIC_CHAIN = [  # case mimic_offchain/mimic_chain.urdf: jm (off the chain, 1 kg 0.2 m out) follows j1
    '<link name="base"/><link name="l1"/>',
    '<link name="lm"><inertial><origin xyz="0.2 0 0"/><mass value="1.0"/>'
    '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>',
    '<link name="tip"><inertial><origin xyz="0 0 0"/><mass value="0.001"/>'
    '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>',
    '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0"/>'
    '<axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="50" velocity="3"/></joint>',
    '<joint name="jtip" type="fixed"><parent link="l1"/><child link="tip"/><origin xyz="0.1 0 0"/></joint>',
    '<joint name="jm" type="revolute"><parent link="l1"/><child link="lm"/><origin xyz="0.3 0 0"/>'
    '<axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="50" velocity="3"/>'
    '<mimic joint="j1" multiplier="1" offset="0"/></joint>']


def test_offchain_mimic_of_a_chain_joint_is_refused_naming_joint_master_and_the_way_on(tmp_path: Path) -> None:
    """Case mimic_offchain 1: jm follows chain joint j1; derive held it at 0 (J = 0.25
    instead of 0.25 + 0.24 cos theta). The serial chain cannot follow it: one refusal."""
    found, problems = chain_of(write(tmp_path, *MIMIC_CHAIN), "base", "tip")
    assert found is None and len(problems) == 1
    p = problems[0]
    assert p.field == "urdf joint 'jm' <mimic joint>"
    assert "follows chain joint 'j1'" in p.expected and "lock 'jm' (locked = { jm = 0.0 } under [arm])" in p.expected
    assert "remove its <mimic>" in p.expected and "link 'lm' (1 kg)" in p.given
    found, problems = chain_of(write(tmp_path, *MIMIC_CHAIN, name="l.urdf"), "base", "tip", locked={"jm": 0.0})
    assert not problems and any("'jm': held at its locked value, its <mimic joint='j1'> not followed" in n
                                for n in found.chain.notes)


def test_offchain_mimic_of_a_chain_joint_that_moves_no_mass_is_held_exactly(tmp_path: Path) -> None:
    massless = [x.replace('<mass value="1.0"/>', '<mass value="0"/>') for x in MIMIC_CHAIN]
    found, problems = chain_of(write(tmp_path, *massless), "base", "tip")
    assert not problems and any("nothing with mass hangs below it" in n for n in found.chain.notes)


def test_locked_master_moves_its_mimic_panda_fingers_match_pinocchio() -> None:
    """Case mimic_offchain 2: locked = { panda_finger_joint1 = 0.04 } puts finger 2 (its
    mimic) at 0.04 too: J and gravity equal Pinocchio's with both fingers at 0.04 to 1e-10,
    and differ from finger 2 at 0 (what derive did: gravity off by 21 % on joint 7)."""
    pin = pytest.importorskip("pinocchio")
    found, problems = chain_of(DATA / "panda.urdf", "panda_link0", "panda_hand_tcp",
                               locked={"panda_finger_joint1": 0.04})
    assert not problems
    assert any("'panda_finger_joint2': follows its <mimic> 'panda_finger_joint1' (1 * 1/25 + 0): held at 1/25" in n
               for n in found.chain.notes)
    num = NumericChain(found.chain)

    def reduced(finger2: float):
        model = pin.buildModelFromUrdf(str(DATA / "panda.urdf"))
        q0 = pin.neutral(model)
        ids = [model.getJointId(f"panda_finger_joint{k}") for k in (1, 2)]
        q0[model.joints[ids[0]].idx_q], q0[model.joints[ids[1]].idx_q] = 0.04, finger2
        model = pin.buildReducedModel(model, ids, q0)
        return model, model.createData()
    both, wrong = reduced(0.04), reduced(0.0)
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = rng.uniform(-1.5, 1.5, 7)
        M = pin.crba(*both, q)
        M = np.triu(M) + np.triu(M, 1).T
        g = pin.computeGeneralizedGravity(*both, q)
        assert np.max(np.abs(num.inertia_matrix(q) - M)) <= 1e-10 * np.max(np.abs(M))
        assert np.max(np.abs(num.gravity_torque(q) - g)) <= 1e-10 * np.max(np.abs(g))
        assert np.max(np.abs(num.gravity_torque(q) - pin.computeGeneralizedGravity(*wrong, q))) > 1e-4


def test_mimic_multiplier_and_offset_of_a_locked_master(tmp_path: Path) -> None:
    """value = multiplier * master + offset, followed through a mimic of a mimic."""
    parts = [link("base"), link("a"), link("f1"), link("f2"), link("f3"), joint("j1", "base", "a"),
             joint("m", "a", "f1", "prismatic"),
             joint("s", "a", "f2", "prismatic", '<mimic joint="m" multiplier="-2" offset="0.01"/>'),
             joint("t", "a", "f3", "revolute", '<mimic joint="s" multiplier="10" offset="0.5"/>')]
    found, problems = chain_of(write(tmp_path, *parts), "base", "a", locked={"m": 0.02})
    assert not problems
    notes = "\n".join(found.chain.notes)
    assert "joint 's': follows its <mimic> 'm' (-2 * 1/50 + 1/100): held at -3/100" in notes
    assert "joint 't': follows its <mimic> 's' (10 * -3/100 + 1/2): held at 1/5" in notes


@pytest.mark.parametrize("mimic, given", [
    ('<mimic joint="nope"/>', "'nope', an unknown joint"),
    ('<mimic joint="fx"/>', "'fx', a fixed joint")])
def test_mimic_of_an_unknown_or_fixed_joint_is_an_error(tmp_path: Path, mimic: str, given: str) -> None:
    parts = [link("base"), link("a"), link("f"), link("g"), joint("j1", "base", "a"),
             joint("m", "a", "f", "prismatic", mimic), joint("fx", "a", "g", "fixed")]
    found, problems = chain_of(write(tmp_path, *parts), "base", "a")
    assert found is None and [str(p) for p in problems] == [
        f"urdf joint 'm' <mimic joint>: expected the name of a revolute, continuous or prismatic joint of the "
        f"URDF, got {given}"]


def test_mimic_cycle_is_an_error_naming_the_cycle(tmp_path: Path) -> None:
    parts = [link("base"), link("a"), link("f"), link("g"), joint("j1", "base", "a"),
             joint("m", "a", "f", "prismatic", '<mimic joint="n"/>'),
             joint("n", "a", "g", "prismatic", '<mimic joint="m"/>')]
    found, problems = chain_of(write(tmp_path, *parts), "base", "a")
    assert found is None and [str(p) for p in problems] == [
        "urdf joint 'n' <mimic joint>: expected a joint that does not mimic back (a mimic chain ends at a joint "
        "that moves on its own), got 'm', a mimic cycle m -> n -> m"]


# -- item 5: <dynamics damping friction> --------------------------------------------------

ARM = {"name": "damparm", "urdf": "damp.urdf", "base_link": "base", "tip_link": "l1", "gravity": 9.81,
       "gravity_direction": [0, 0, -1], "actuation": "torque"}
DAMP = ('<?xml version="1.0"?>\n<robot name="damp"><link name="base"/><link name="l1"><inertial>'
        '<origin xyz="0.15 0 0"/><mass value="1.0"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.008" iyz="0" '
        'izz="0.008"/></inertial></link><joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
        '<origin xyz="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="50" velocity="3"/>'
        '{dynamics}</joint></robot>\n')


def arm_file(tmp_path: Path, dynamics: str, **top) -> Path:
    (tmp_path / "damp.urdf").write_text(DAMP.format(dynamics=dynamics), encoding="utf-8")
    path = tmp_path / "damp.toml"
    path.write_text(to_toml({"arm": ARM, "motor": [{"gear_ratio": 1.0}], "controller": {"T1": 0.0, "T2": 0.2,
                                                                                      "w": [5.0]}, **top}))
    return path


@pytest.mark.parametrize("command", [["generate", "--out", "gen"], ["show"], ["fmu", "--out", "fmu"]])
def test_a_dynamics_damping_element_is_a_warning_on_every_command(tmp_path: Path, capsys, command) -> None:
    """Case damping_element_silent: <dynamics><damping>100</damping></dynamics> (an element,
    which URDF does not define: urdf_parser_py ignores it) changes G by 100 theta' if meant;
    every command that reads the URDF says so on stderr, not only init."""
    path = arm_file(tmp_path, "<dynamics><damping>100</damping></dynamics>")
    assert main([command[0], str(path), *[str(tmp_path / c) if c in ("gen", "fmu") else c for c in command[1:]]]) == 0
    err = capsys.readouterr().err
    assert ("derive: warning: urdf joint 'j1' <dynamics><damping>: expected only the elements URDF defines inside "
            "<dynamics> (none; <dynamics> takes damping, friction as attributes), got an element "
            "<damping>100</damping>, not read") in err


def test_the_damping_warning_is_an_error_with_strict(tmp_path: Path, capsys) -> None:
    path = arm_file(tmp_path, "<dynamics><damping>100</damping></dynamics>")
    assert main(["generate", str(path), "--out", str(tmp_path / "gen"), "--strict"]) == 2
    assert "<dynamics><damping>" in capsys.readouterr().err and not (tmp_path / "gen").exists()


def test_dynamics_damping_is_bv_and_friction_the_simulations_coulomb_default(tmp_path: Path) -> None:
    """<dynamics damping="0.7" friction="0.3">: bv = 0.7 (G's damping term) and the
    simulation's Coulomb friction 0.3, each with a note; [simulation] coulomb_friction wins."""
    arm = derive.load_arm(arm_file(tmp_path, '<dynamics damping="0.7" friction="0.3"/>'))
    assert arm.joint_friction == ((Fraction(7, 10), "urdf joint 'j1' <dynamics damping>"),)
    assert arm.simulation.coulomb_friction == (0.3,)
    notes = "\n".join(arm.chain.notes)
    assert "<dynamics damping> of joint 'j1' 0.7 is the viscous friction bv" in notes
    assert "<dynamics friction> of joint 'j1' 0.3 is the Coulomb friction in the simulation and the plant FMU" in notes
    arm = derive.load_arm(arm_file(tmp_path, '<dynamics damping="0.7" friction="0.3"/>',
                                   simulation={"coulomb_friction": [0.05]}))
    assert arm.simulation.coulomb_friction == (0.05,)
    arm = derive.load_arm(arm_file(tmp_path, ""))
    assert arm.simulation.coulomb_friction == (0.05,) and math.isclose(float(arm.joint_friction[0][0]), 0.0)


def test_no_warning_for_a_urdf_without_ignored_dynamics(tmp_path: Path, capsys) -> None:
    path = arm_file(tmp_path, '<dynamics damping="0.1"/>')
    assert main(["generate", str(path), "--out", str(tmp_path / "gen")]) == 0
    assert "derive: warning" not in capsys.readouterr().err


def test_every_problem_of_the_handed_cases_is_one_spec_error(tmp_path: Path) -> None:
    """Through load_arm: the off-chain mimic of case 1 is one SpecError (exit 2 in the CLI)."""
    (tmp_path / "m.urdf").write_text(f'<?xml version="1.0"?>\n<robot name="m">{"".join(MIMIC_CHAIN)}</robot>\n')
    path = tmp_path / "m.toml"
    path.write_text(to_toml({"arm": {**ARM, "urdf": "m.urdf", "tip_link": "tip"}, "controller": {
        "T1": 0.0, "T2": 0.2, "w": [5.0]}}))
    with pytest.raises(SpecError, match=r"urdf joint 'jm' <mimic joint>: expected a mimic of a held joint"):
        derive.load_arm(path)


def test_unknown_dynamics_attributes_of_many_joints_are_one_warning() -> None:
    """The Panda's <dynamics D K mu_coulomb mu_viscous> (franka_ros extensions, not URDF) on 7
    chain joints: one warning naming the joints and every attribute ignored."""
    arm = derive.load_arm(DATA / "panda.toml")
    assert [str(w) for w in arm.warnings] == [
        "urdf joints 'panda_joint1', 'panda_joint2', 'panda_joint3', 'panda_joint4', ... (7 joints) <dynamics>: "
        "expected the attributes URDF defines there (damping, friction), got also D='1', K='7000', "
        "mu_coulomb='0', mu_viscous='16', not read"]


def test_a_chain_joint_that_mimics_a_held_joint_is_held_too(tmp_path: Path) -> None:
    """j2 on the chain mimics m (off the chain, locked at 0.3): j2 is held at 2 * 0.3 = 0.6,
    so the chain has one moving joint; its pose follows (tip x = 0.1 cos 0.6 + ...)."""
    parts = [link("base"), link("a"), link("b"), link("f"), joint("j1", "base", "a"),
             joint("j2", "a", "b", extra='<mimic joint="m" multiplier="2"/>'), joint("m", "a", "f")]
    found, problems = chain_of(write(tmp_path, *parts), "base", "b", locked={"m": 0.3})
    assert not problems and [j.name for j in found.chain.joints] == ["j1"]
    assert any("joint 'j2': follows its <mimic> 'm' (2 * 3/10 + 0): held at 3/5" in n for n in found.chain.notes)
    num = NumericChain(found.chain)
    hx = float(found.chain.bodies[0].first_moment[0].xreplace(found.chain.values()))
    # 1 kg each at (0.1, 0, 0) of its link: a's own, b's turned by 0.6 about z, f's by 0.3
    assert math.isclose(hx, 0.1 + 0.1 * math.cos(0.6) + 0.1 * math.cos(0.3), rel_tol=1e-12)
    assert num.n == 1
