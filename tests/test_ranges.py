"""Derived constants out of the real type's range (issue 10, item 2).

T2 of the predictive horizon (eq. 14) sets k1 = Tbar31 / Tbar33 = 10 / (3 T2^2) for
T1 = 0 (eq. 16-18): T2 = 1e-20 gives 3.333e40, beyond float (3.4e38); T2 = 1e-170
gives 3.333e340, beyond double. Every command refuses such an arm with one message
naming the fields, exit code 2, before anything is written; so do a subnormal or an
underflowing constant, at the parameter level and inside a derived matrix (J of eq. 12).
The printer refuses any constant that reaches it anyway.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import derive
from derive.cli import main
from derive.codegen.files import generate_files
from derive.codegen.printing import c_literal, py_literal
from derive.errors import DerivationError, SpecError
from derive.proofs.core import run as run_obligations
from derive.proofs.project import OBLIGATIONS

ONE_LINK = """[arm]
name = "{name}"

[[link]]
length = {length}
mass = {mass}
{link_extra}

[[motor]]
torque_constant = 0.05
voltage_constant = 0.05
resistance = 2.0
{motor_extra}

[controller]
T1 = 0.0
T2 = {T2}
w = [1.0]
"""


def arm_file(tmp_path: Path, name: str = "one_link", length: str = "0.3", mass: str = "0.5", T2: str = "1.0",
             link_extra: str = "", motor_extra: str = "") -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(ONE_LINK.format(name=name, length=length, mass=mass, T2=T2, link_extra=link_extra,
                                    motor_extra=motor_extra), encoding="utf-8")
    return path


def refused(capsys, argv: list[str], *fragments: str) -> str:
    """Run the CLI in-process: exit code 2, one message with every fragment."""
    assert main(argv) == 2, argv
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("derive: error:")]  # warnings may precede
    assert len(errors) == 1 and errors[0].startswith("derive: error: invalid arm description"), err
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in err, (fragment, err)
    return err


K1_DOUBLE = ("controller.T1 and controller.T2", "controller.T2 = 1e-170 give K1[1][1] (eq. 16) = 3.333e+340", "overflows double")
K1_FLOAT = ("controller.T1 and controller.T2", "controller.T2 = 1e-20 give K1[1][1] (eq. 16) = 3.333e+40", "overflows float")


def test_f2_k1_beyond_double_is_refused_by_every_command(tmp_path, capsys):
    f2 = str(arm_file(tmp_path, "f2_double_inf", T2="1e-170"))
    out = tmp_path / "out"
    for argv in (["show", f2], ["check", f2], ["generate", f2, "--out", str(out)],
                 ["generate", f2, "--out", str(out), "--real", "float", "--params", "runtime"],
                 ["simulate", f2, "--duration", "1", "--out", str(out / "sim")]):
        refused(capsys, argv, *K1_DOUBLE)
    assert not out.exists(), "nothing may be written"
    with pytest.raises(SpecError, match=r"controller\.T1 and controller\.T2: .*3\.333e\+340, which overflows double"):
        derive.derive(derive.load_arm(f2))


def test_f1_k1_beyond_float_is_refused_by_generate_and_embedded(tmp_path, capsys):
    f1 = str(arm_file(tmp_path, "f1_float_inf", T2="1e-20"))
    out = tmp_path / "out"
    for mode in ("baked", "runtime"):
        refused(capsys, ["generate", f1, "--out", str(out), "--real", "float", "--params", mode], *K1_FLOAT)
    assert not out.exists()
    # double holds k1 = 10 / (3 T2^2) = 3.3e40: the same arm generates in double
    assert main(["generate", f1, "--out", str(out), "--params", "runtime"]) == 0
    assert "p->T2 = 1e-20;" in (out / "f1_float_inf" / "c" / "f1_float_inf.c").read_text()
    capsys.readouterr()
    keep = tmp_path / "keep"
    refused(capsys, ["embedded", f1, "--keep", str(keep)], *K1_FLOAT)
    assert not keep.exists(), "embedded writes nothing before every real type fits"


def test_f1_generate_float_from_a_process_exits_2_without_traceback(tmp_path):
    f1 = arm_file(tmp_path, "f1_float_inf", T2="1e-20")
    proc = subprocess.run([sys.executable, "-m", "derive", "generate", str(f1), "--real", "float",
                           "--out", str(tmp_path / "out")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stderr.count("derive: error:") == 1, proc.stderr
    assert "Traceback" not in proc.stderr and "K1[1][1] (eq. 16) = 3.333e+40" in proc.stderr


def test_float_subnormal_and_underflowing_gains_are_refused(tmp_path):
    # T2 = 1e20: k1 = 3.333e-40, below FLT_MIN = 1.18e-38 but above the smallest subnormal 1.4e-45
    d = derive.derive(derive.load_arm(arm_file(tmp_path, "slow_arm", T2="1e20")))
    with pytest.raises(SpecError, match=r"K1\[1\]\[1\] \(eq\. 16\) = 3\.333e-40, which is subnormal in float"):
        generate_files(d, b"", "float")
    # T2 = 1e30: k1 = 3.333e-60 rounds to 0 in float
    d = derive.derive(derive.load_arm(arm_file(tmp_path, "slower_arm", T2="1e30")))
    with pytest.raises(SpecError, match=r"K1\[1\]\[1\] \(eq\. 16\) = 3\.333e-60, which underflows to 0 in float"):
        generate_files(d, b"", "float")
    assert "c/slower_arm_kernels.c" in generate_files(d, b"", "double")  # double holds it


def test_a_subnormal_double_parameter_names_its_field(tmp_path):
    path = arm_file(tmp_path, motor_extra="rotor_inertia = 1e-310")
    with pytest.raises(SpecError, match=r"motor\[1\]\.rotor_inertia: .*got 1e-310, which is subnormal in double"):
        derive.derive(derive.load_arm(path))


def test_a_derived_constant_beyond_float_names_the_fields_of_its_entry(tmp_path):
    """Every parameter fits float (mass 1e20 kg, length 1e20 m), but J11 = m (l/2)^2 + ... = 2.5e59
    (eq. 12) does not: the error names J[1][1] and the fields of its out-of-range term."""
    path = arm_file(tmp_path, length="1e20", mass="1e20", link_extra="inertia = 0.0")
    d = derive.derive(derive.load_arm(path))  # double holds 2.5e59
    with pytest.raises(SpecError, match=r"link\[1\]\.length = 1e\+20, link\[1\]\.mass = 1e\+20 give J\[1\]\[1\] \(eq\. 12\) = 2\.5e\+59, which overflows float") as info:
        generate_files(d, b"", "float")
    # J11 = Ic + m c^2 + Jm gr^2: the term out of range is m c^2 with c = l / 2 (the default):
    # length and mass, not the motor's gear ratio or rotor inertia
    assert [p.field for p in info.value.problems] == ["link[1].length and link[1].mass"]


@pytest.mark.parametrize("value, real, why", [
    (1e39, "float", "overflows float"), (float("inf"), "double", "is not finite"),
    (float("nan"), "float", "is not finite"), (1e-40, "float", "is subnormal in float"),
    (1e-50, "float", "underflows to 0 in float"), (5e-324, "double", "is subnormal in double")])
def test_the_printer_refuses_every_constant_the_real_type_cannot_hold(value, real, why):
    with pytest.raises(DerivationError, match=why):
        c_literal(value, real)
    if real == "double":
        with pytest.raises(DerivationError, match=why):
            py_literal(value)


def test_the_printer_keeps_the_extremes_of_the_normal_range():
    assert c_literal(3.4028234663852886e38, "float") == "3.4028235e+38f"
    assert c_literal(1.1754943508222875e-38, "float") == "1.1754944e-38f"
    assert c_literal(-0.0, "float") == "-0.0f" and c_literal(0.0, "double") == "0.0"
    assert py_literal(2.2250738585072014e-308) == "2.2250738585072014e-308"


def test_eq16_hurwitz_evidence_for_extreme_gains_is_computed(tmp_path):
    """check's u*-loop obligation gave a NoConvergence traceback from nroots for k1 = 3.3e40."""
    d = derive.derive(derive.load_arm(arm_file(tmp_path, T2="1e-20")))
    law = next(ob for ob in OBLIGATIONS if ob.check.__name__ == "check_law")
    result, = run_obligations([law], d)
    # s^2 + k2 s + k1 with k1 = 10 / (3 T2^2), k2 = 5 / (2 T2): roots -1.25e20 +- 1.331e20 i
    assert result.outcome.evidence == "roots of s^2 + k2 s + k1: -1.25e+20-1.331e+20j, -1.25e+20+1.331e+20j"
