"""Bad URDF and DH arm files: each is ONE SpecError naming the element (link or
joint and attribute) or arm-file field, what was expected and what was given;
through the CLI, exit code 2, no traceback, nothing written. Same table style
as test_bad_input.py: an id, the arm file and URDF, the fields, a fragment."""
from __future__ import annotations

import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

import derive
from derive.errors import SpecError

from .test_bad_input import to_toml

HEAD = {"name": "bad", "gravity": 9.81, "actuation": "torque"}
CONTROLLER = {"T1": 0.0, "T2": 0.5, "w": [1.0, 1.0]}
BOX = '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'


def link(name: str, inertial: str | None = None) -> str:
    body = inertial if inertial is not None else f'<origin xyz="0.1 0 0"/><mass value="1.0"/>{BOX}'
    return f'<link name="{name}"><inertial>{body}</inertial></link>'


def joint(name: str, parent: str, child: str, kind: str = "revolute", extra: str = '<axis xyz="0 0 1"/>') -> str:
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="0 0 0.1" rpy="0 0 0"/>{extra}</joint>')


def robot(*parts: str, prolog: str = "") -> str:
    return f'<?xml version="1.0"?>\n{prolog}<robot name="r">{"".join(parts)}</robot>\n'


GOOD = (link("a"), link("b"), link("c"), joint("j1", "a", "b"), joint("j2", "b", "c"))


def good(**change: str) -> str:
    """The good 2-joint URDF with parts replaced by name (a, b, c, j1, j2)."""
    names = ("a", "b", "c", "j1", "j2")
    return robot(*[change.get(n, part) for n, part in zip(names, GOOD)])


BOMB = ('<!DOCTYPE r [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">'
        '<!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">]>\n')
XXE = '<!DOCTYPE r [<!ENTITY xxe SYSTEM "file:///etc/passwd">]>\n'


@dataclass(frozen=True)
class Case:
    id: str
    urdf: str | None          # the URDF text (None: no file)
    arm: dict                 # [arm] keys beyond HEAD (urdf path added unless given)
    fields: tuple[str, ...]
    match: str
    cli: bool = False
    top: dict | None = None   # a whole arm mapping instead (DH cases)


def arm_keys(**extra) -> dict:
    return {"base_link": "a", "tip_link": "c", **extra}


def dh(table: list, bodies: int = 2, **extra) -> dict:
    return {"arm": dict(HEAD), "dh": {"convention": "standard", "table": table, **extra},
            "body": [{"mass": 1.0, "com": [0.1, 0, 0]}] * bodies, "controller": CONTROLLER}


C = Case
CASES = [
    C("malformed-xml", robot(*GOOD)[:-12], arm_keys(), ("arm.urdf",), "well-formed XML", cli=True),
    C("entity-bomb", robot(*GOOD[:3], joint("j1", "a", "b"), joint("j2", "b", "c"), prolog=BOMB).replace(
        '<robot name="r">', '<robot name="&lol3;">'), arm_keys(), ("arm.urdf",), "an entity declaration 'lol'",
      cli=True),
    C("external-entity", robot(*GOOD, prolog=XXE).replace('<robot name="r">', '<robot name="&xxe;">'), arm_keys(),
      ("arm.urdf",), "an external entity 'xxe' -> 'file:///etc/passwd'", cli=True),
    C("external-dtd", robot(*GOOD, prolog='<!DOCTYPE robot SYSTEM "file:///etc/passwd">\n'), arm_keys(),
      ("arm.urdf",), "without an external DTD"),
    C("not-a-robot", '<?xml version="1.0"?><sdf/>', arm_keys(), ("arm.urdf",), "root element is <robot>"),
    C("no-such-file", None, arm_keys(urdf="missing.urdf"), ("arm.urdf",), "(no such file", cli=True),
    C("missing-base", good(), {"tip_link": "c"}, ("arm.base_link",), "got nothing (the key is missing)"),
    C("unknown-tip", good(), arm_keys(tip_link="cc"), ("arm.tip_link",), "not a link of the URDF; did you mean 'c'"),
    C("tip-not-below-base", good(), arm_keys(base_link="c", tip_link="a"), ("arm.tip_link",),
      "whose chain to the root 'a' does not pass 'c'"),
    C("two-parents", good(j2=joint("j2", "b", "c") + joint("j3", "a", "c")), arm_keys(), ("urdf link 'c'",),
      "2 parent joints, 'j2' and 'j3'"),
    C("loop", robot(*GOOD, link("d"), joint("j3", "c", "d"), joint("j4", "d", "b")).replace(
        joint("j1", "a", "b"), ""), arm_keys(base_link="b", tip_link="d"), ("urdf link 'b'",),
      "a kinematic loop b -> d -> c -> b"),
    C("floating-on-chain", good(j2=joint("j2", "b", "c", "floating", "")), arm_keys(), ("urdf joint 'j2' type",),
      "a floating joint is not supported"),
    C("planar-on-chain", good(j1=joint("j1", "a", "b", "planar")), arm_keys(), ("urdf joint 'j1' type",),
      "a planar joint is not supported"),
    C("mimic-on-chain", good(j2=joint("j2", "b", "c", extra='<axis xyz="0 0 1"/><mimic joint="j1"/>')), arm_keys(),
      ("urdf joint 'j2' <mimic>",), "(it follows chain joint 'j1': derive's chain has one coordinate per joint); "
      "lock it (locked = { j2 = 0.0 } under [arm]) or remove the <mimic>", cli=True),
    C("negative-mass", good(b=link("b", f'<mass value="-1.0"/>{BOX}')), arm_keys(),
      ("urdf link 'b' <inertial><mass value>",), ">= 0 (kg), got -1.0"),
    C("inertia-not-psd", good(b=link("b", '<mass value="1"/><inertia ixx="0.01" ixy="0.02" ixz="0" iyy="0.01" '
                                          'iyz="0" izz="0.01"/>')), arm_keys(),
      ("urdf link 'b' <inertial><inertia>",), "a positive semi-definite tensor"),
    C("inertia-triangle", good(c=link("c", '<mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" '
                                           'iyz="0" izz="0.03"/>')), arm_keys(),
      ("urdf link 'c' <inertial><inertia>",), "triangle inequality"),
    C("xacro-number-on-chain", good(j2=joint("j2", "b", "c").replace('xyz="0 0 0.1"', 'xyz="${l} 0 0.1"')),
      arm_keys(), ("urdf joint 'j2' <origin xyz>",), "3 numbers separated by spaces, got '${l} 0 0.1'", cli=True),
    C("mimic-of-unknown-joint", good(j2=joint("j2", "b", "c", extra='<axis xyz="0 0 1"/><mimic joint="zz"/>')),
      arm_keys(), ("urdf joint 'j2' <mimic joint>",), "revolute, continuous or prismatic joint of the URDF, got "
      "'zz', an unknown joint", cli=True),
    C("mimic-cycle", robot(*GOOD, link("f"), link("g"), joint("m", "c", "f", "prismatic",
                                                              '<axis xyz="1 0 0"/><mimic joint="n"/>'),
                           joint("n", "c", "g", "prismatic", '<axis xyz="1 0 0"/><mimic joint="m"/>')),
      arm_keys(), ("urdf joint 'n' <mimic joint>",), "got 'm', a mimic cycle m -> n -> m", cli=True),
    C("repair-negative-mass", good(b=link("b", f'<mass value="-1.0"/>{BOX}')), arm_keys(repair_inertia=True),
      ("urdf link 'b' <inertial><mass value>",), "repair_inertia repairs the inertia tensor, not a negative mass, "
      "got -1.0", cli=True),
    C("mass-twice-on-chain", good(b=link("b", f'<mass value="1.0"/><mass value="2.0"/>{BOX}')), arm_keys(),
      ("urdf link 'b' <inertial><mass>",), "expected one <mass>, got 2", cli=True),
    C("origin-twice-on-chain", good(j2=joint("j2", "b", "c").replace("<origin", '<origin xyz="1 0 0"/><origin')),
      arm_keys(), ("urdf joint 'j2' <origin>",), "expected one <origin>, got 2"),
    C("zero-axis", good(j1=joint("j1", "a", "b", extra='<axis xyz="0 0 0"/>')), arm_keys(),
      ("urdf joint 'j1' <axis xyz>",), "a non-zero axis"),
    C("nan-origin", good(j2=joint("j2", "b", "c").replace('xyz="0 0 0.1"', 'xyz="nan 0 0.1"')), arm_keys(),
      ("urdf joint 'j2' <origin xyz>",), "3 finite numbers, got 'nan 0 0.1'"),
    C("inf-mass", good(c=link("c", f'<mass value="inf"/>{BOX}')), arm_keys(), ("urdf link 'c' <inertial><mass value>",),
      "a finite number, got 'inf'"),
    C("short-rpy", good(j1=joint("j1", "a", "b").replace('rpy="0 0 0"', 'rpy="0 0"')), arm_keys(),
      ("urdf joint 'j1' <origin rpy>",), "3 numbers separated by spaces, got '0 0'"),
    C("nan-inertia", good(b=link("b", '<mass value="1"/>' + BOX.replace('iyy="0.01"', 'iyy="NaN"'))), arm_keys(),
      ("urdf link 'b' <inertial><inertia iyy>",), "expected a finite number, got 'NaN'"),
    C("word-mass", good(b=link("b", f'<mass value="abc"/>{BOX}')), arm_keys(), ("urdf link 'b' <inertial><mass value>",),
      "expected a number, got 'abc'"),
    C("base-is-tip", good(), arm_keys(base_link="b", tip_link="b"), ("arm.tip_link",),
      "got 'b': base and tip are the same link"),
    C("no-inertia", robot('<link name="a"/><link name="b"/><link name="c"/>', joint("j1", "a", "b"),
                          joint("j2", "b", "c")), arm_keys(), ("urdf joint 'j1'", ), "J(theta) is singular", cli=True),
    C("unknown-locked", good(), arm_keys(locked={"nope": 0.1}), ("arm.locked.nope",), "got an unknown joint"),
    C("locked-fixed", good(c=link("c") + link("d"), j2=joint("j2", "b", "c") + joint("f", "c", "d", "fixed", "")),
      arm_keys(locked={"f": 0.0}), ("arm.locked.f",), "got a fixed joint"),
    C("base-link-on-planar", None, {}, ("arm.base_link",), "no such key without urdf",
      top={"arm": {**HEAD, "base_link": "a"}, "link": [{"length": 0.3, "mass": 1.0}],
           "controller": {"T1": 0.0, "T2": 0.5, "w": [1.0]}}),
    C("dh-wrong-column-count", None, {}, ("dh.table[2]",), "expected 4 numbers [a (m), alpha (rad), d (m), theta "
      "(rad)], got array [0.3, 0.0, 0.0] (3 entries)", cli=True,
      top=dh([[0.0, "pi/2", 0.1, 0.0], [0.3, 0.0, 0.0]])),
    C("dh-bad-angle", None, {}, ("dh.table[1].alpha",), "a fraction of pi as text", top=dh([[0, "pi/x", 0, 0],
                                                                                           [0.3, 0, 0, 0]])),
    C("dh-body-count", None, {}, ("body",), "one [[body]] table per row of dh.table: 2, got 1 [[body]] table",
      top=dh([[0, 0, 0, 0], [0.3, 0, 0, 0]], bodies=1)),
    C("dh-convention", None, {}, ("dh.convention",), "'standard' (Denavit-Hartenberg) or 'modified'",
      top={**dh([[0, 0, 0, 0], [0.3, 0, 0, 0]]), "dh": {"convention": "craig", "table": [[0, 0, 0, 0],
                                                                                          [0.3, 0, 0, 0]]}}),
    C("dh-and-link", None, {}, ("arm file",), "planar and dh together",
      top={**dh([[0, 0, 0, 0], [0.3, 0, 0, 0]]), "link": [{"length": 0.3, "mass": 1.0}]}),
]


def write(case: Case, tmp_path: Path) -> Path:
    if case.top is not None:
        data = case.top
    else:
        if case.urdf is not None:
            (tmp_path / "r.urdf").write_text(case.urdf, encoding="utf-8")
        data = {"arm": {**HEAD, "urdf": "r.urdf", **case.arm}, "controller": CONTROLLER}
    path = tmp_path / "arm.toml"
    path.write_text(to_toml(data), encoding="utf-8")
    return path


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_urdf_or_dh_is_one_spec_error_naming_the_element(case: Case, tmp_path: Path):
    path = write(case, tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(SpecError, match=re.escape(case.match)) as info:
        derive.load_arm(path)
    err = info.value
    assert sorted(p.field for p in err.problems) == sorted(case.fields), str(err)
    assert all(f"  - {p.field}: expected {p.expected}, got {p.given}" in str(err) for p in err.problems)
    assert "root:x:0:0" not in str(err)   # /etc/passwd never read
    assert sorted(p.name for p in tmp_path.iterdir()) == before


@pytest.mark.parametrize("case", [c for c in CASES if c.cli], ids=[c.id for c in CASES if c.cli])
def test_cli_reports_bad_urdf_exit_2(case: Case, tmp_path: Path):
    path = write(case, tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    proc = subprocess.run([sys.executable, "-m", "derive", "generate", str(path), "--out", str(tmp_path / "out")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and proc.stdout == ""
    assert proc.stderr.startswith("derive: error: invalid arm description")
    assert all(f"  - {f}: expected " in proc.stderr for f in case.fields), proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_init_with_a_tip_below_a_floating_joint_exits_2_naming_it(tmp_path: Path):
    """derive init r.urdf --tip c, c below a floating joint: one message, exit 2, nothing written."""
    (tmp_path / "r.urdf").write_text(good(j2=joint("j2", "b", "c", "floating", "")), encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "derive", "init", "r.urdf", "--tip", "c"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr and proc.stdout == ""
    assert "urdf joint 'j2' type: expected revolute, continuous, prismatic or fixed on the chain from 'a' to 'c' " \
           "(a floating joint is not supported" in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.urdf"]


def test_an_element_given_twice_off_the_chain_is_a_warning_naming_it(tmp_path: Path):
    """Tester's twomass.urdf, off the chain: a side link on the base with two <mass> elements is read
    leniently (the first, as urdf_parser_py does) and said on stderr by every command, not only noted."""
    side = link("s", f'<mass value="0.1"/><mass value="0.3"/>{BOX}')
    urdf = robot(*GOOD, side, joint("js", "a", "s", "fixed", ""))
    path = write(Case("side", urdf, arm_keys(), (), ""), tmp_path)
    arm = derive.load_arm(path)
    assert [str(w) for w in arm.warnings] == [
        "urdf link 's' <inertial><mass> (not on the chain, read leniently): expected one <mass>, got 2"]
    assert not any("parser said" in note for note in arm.chain.notes)


def test_a_parser_complaint_is_an_error_on_the_chain_and_a_warning_off_it():
    """What urdf_parser_py says while reading (derive's cut-down leaves it nothing to say today, so
    its messages are judged directly) names the link and element it concerns."""
    from derive.model.fields import Reader
    from derive.model.urdf_rules import judge_findings
    from derive.model.urdf_xml import _parser_finding

    said = "Unknown tag \"bar\" in /robot[@name='r']/link[@name='b']/inertial"
    f = _parser_finding(said)
    assert (f.kind, f.name, f.problem.field) == ("link", "b", "urdf link 'b' <inertial>")
    r, notes = Reader(), []
    assert judge_findings(r, [f], {"b"}, set(), set(), notes) == [] and [str(p) for p in r.problems] == [
        f"urdf link 'b' <inertial>: expected a URDF that urdf_parser_py reads without a complaint, got it said: {said}"]
    r = Reader()
    warned = judge_findings(r, [f], {"c"}, set(), set(), notes)
    assert r.problems == [] and [w.field for w in warned] == ["urdf link 'b' <inertial> (not on the chain, read leniently)"]
    robot_level = _parser_finding("Material has neither a color nor texture.")
    assert [w.field for w in judge_findings(Reader(), [robot_level], set(), set(), set(), [])] == ["arm.urdf"]
