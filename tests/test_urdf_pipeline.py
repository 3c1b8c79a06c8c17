"""A URDF arm through the whole pipeline (issue 11.5): ``derive init robot.urdf`` then
``derive generate`` in two commands, the generated C self-test passing under strict flags,
and ``derive check``, ``show``, ``simulate`` on the same arm (gravity along -z of the base)."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
import sympy as sp

from derive.cli import main

from .cbuild import compile_c, library_sources

URDF = Path(__file__).parent / "data" / "urdf"


@pytest.fixture(scope="module")
def two_commands(tmp_path_factory) -> tuple[Path, Path, int, int]:
    """derive init double_pendulum.urdf; derive generate double_pendulum.toml: (arm file, output, exit codes)."""
    tmp = tmp_path_factory.mktemp("urdf_arm")
    urdf = tmp / "double_pendulum.urdf"
    shutil.copy(URDF / "double_pendulum.urdf", urdf)
    first = main(["init", str(urdf)])
    arm_file = tmp / "double_pendulum.toml"
    second = main(["generate", str(arm_file), "--out", str(tmp / "out")])
    return arm_file, tmp / "out", first, second


def test_init_then_generate_writes_c_whose_selftest_passes_strictly(two_commands, tmp_path) -> None:
    arm_file, out, first, second = two_commands
    assert (first, second) == (0, 0)
    c = out / "arm_2dof_planar" / "c"
    assert sorted(p.name for p in c.iterdir()) == sorted(
        ["CMakeLists.txt"] + [f"arm_2dof_planar{s}" for s in (".c", ".h", "_kernels.c", "_kernels.h", "_plant.c",
                                                               "_plant.h", "_plant_selftest.c", "_selftest.c")])
    for selftest in ("selftest", "plant_selftest"):
        exe = compile_c("gcc", [c / f"arm_2dof_planar_{selftest}.c", *library_sources(c, "arm_2dof_planar")],
                        tmp_path / selftest, ["-O2"])
        proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0 and re.search(r"^\d+ passed, 0 failed$", proc.stdout, re.M), proc.stdout
    manifest = json.loads((out / "arm_2dof_planar" / "MANIFEST.json").read_text())
    assert "c/arm_2dof_planar_kernels.c" in manifest["files"]


def test_check_of_a_urdf_arm_proves_what_applies(two_commands, capsys) -> None:
    """Every project obligation is proved or n/a; the planar 2-link ones (a6) are n/a."""
    arm_file = two_commands[0]
    assert main(["check", str(arm_file)]) == 0
    text = capsys.readouterr().out
    assert re.search(r"theorem2-arm .* n/a +theorem 2's proof rests on the planar 2-link form", text)
    assert re.search(r"skew-symmetry .* proved", text) and re.search(r"energy .* proved", text)
    assert " refuted" not in text.split("Numeric evidence")[0].replace("0 refuted", "")


def test_show_and_simulate_a_urdf_arm(two_commands, capsys, tmp_path) -> None:
    arm_file = two_commands[0]
    assert main(["show", str(arm_file), "--at", "theta=0.3,-0.2,dtheta=1,0.5"]) == 0
    text = capsys.readouterr().out
    assert "J(theta)" in text and "ddtheta at u = d = 0" in text
    out = tmp_path / "sim"
    assert main(["simulate", str(arm_file), "--controllers", "mpc", "--duration", "0.5", "--out", str(out),
                 "--json", str(tmp_path / "m.json")]) == 0
    metrics = json.loads((tmp_path / "m.json").read_text())
    links = metrics["controllers"]["mpc"]["links"]
    assert len(links) == 2 and all(0 < x["max_error"] < 1 for x in links)


def test_show_and_check_an_arm_whose_urdf_turns_by_an_inexact_angle(tmp_path, capsys) -> None:
    """A joint origin turned by rpy 0.3 (not a multiple of pi/2): the chain holds the nearest
    rational rotation (derive.model.rigid.rational_rotation: exactly orthogonal, within 4e-18
    of Rx(0.3)), so no sin/cos of a constant reaches the dynamics; shown and checked."""
    from .test_model_urdf import joint, link, robot, write
    from .test_spatial_dynamics import urdf_arm

    text = robot(link("a") + link("b", 1.0, "0.1 0 0", inertia=(1e-3, 0, 0, 2e-3, 0, 2e-3))
                 + link("c", 0.5, "0.1 0.02 0", inertia=(1e-3, 0, 0, 1e-3, 0, 1e-3))
                 + joint("j1", "a", "b", axis="0 1 0") + joint("j2", "b", "c", xyz="0.3 0 0", rpy_="0.3 0 0"))
    arm = urdf_arm(write(tmp_path, text), "a", "c", 2, "tilted")
    R = sp.Matrix(arm.chain.joints[1].origin.R)
    assert all(x.is_Rational for x in R) and R.T * R == sp.eye(3) and R.det() == 1
    exact = sp.Matrix([[1, 0, 0], [0, sp.cos(sp.Rational(3, 10)), -sp.sin(sp.Rational(3, 10))],
                       [0, sp.sin(sp.Rational(3, 10)), sp.cos(sp.Rational(3, 10))]])
    assert max(abs(sp.N(x, 40)) for x in R - exact) < 4e-18
    path = tmp_path / "tilted.toml"
    path.write_text(f'''[arm]
name = "tilted"
urdf = "t.urdf"
base_link = "a"
tip_link = "c"
gravity = 9.81
gravity_direction = [0, 0, -1]
actuation = "torque"

[[motor]]
gear_ratio = 1.0
rotor_inertia = 0.0

[[motor]]
gear_ratio = 1.0
rotor_inertia = 0.0

[controller]
T1 = 0.0
T2 = 0.2
w = [5.0, 5.0]
''', encoding="utf-8")
    assert main(["show", str(path)]) == 0
    out = capsys.readouterr().out
    assert "J(θ)" in out and "sin(0.3)" not in out
    assert main(["check", str(path)]) == 0   # the exact proofs and the observer certificate take sin(3/10) too
    out = capsys.readouterr().out
    assert re.search(r"observer-certificate .* proved", out) and re.search(r"skew-symmetry .* proved", out)
