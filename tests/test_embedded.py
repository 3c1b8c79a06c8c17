"""`make embedded`: the generated controller cross-compiled for Cortex-M4F (float) and
Cortex-M3 (double, float), its self-test run on QEMU's MPS2 boards, and the report.

These tests need the Arm toolchain and QEMU that scripts/install-system-deps.sh
installs (`make test` and .ci/run call it; `make embedded` does too). Where they
are missing the tests fail, they never skip.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from derive.embedded import qemu as embedded

ROOT = Path(__file__).resolve().parent.parent
ROW = re.compile(r"^\| (Cortex-M\w+) \((mps2-an38[56])\) \| (double|float) \| (\d+) passed, (\d+) failed \| (.*)$",
                 re.M)
CONFIGS = {("Cortex-M4F", "mps2-an386", "float"), ("Cortex-M3", "mps2-an385", "double"),
           ("Cortex-M3", "mps2-an385", "float")}


@pytest.fixture(scope="module")
def make_embedded() -> subprocess.CompletedProcess:
    proc = subprocess.run(["make", "-s", "embedded"], cwd=ROOT, capture_output=True, text=True, timeout=1200,
                          stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc


def test_make_embedded_passes_the_selftest_on_both_targets(make_embedded):
    rows = ROW.findall(make_embedded.stdout)
    assert {(core, machine, real) for core, machine, real, *_ in rows} == CONFIGS, make_embedded.stdout
    for core, machine, real, passed, failed, _rest in rows:
        assert int(passed) >= 50 and int(failed) == 0, (core, real)
    assert re.search(r"^embedded: \d+ passed, 0 failed$", make_embedded.stdout, re.M)


def test_report_has_size_stack_and_instruction_figures(make_embedded):
    figures = {}
    for core, _machine, real, _p, _f, rest in ROW.findall(make_embedded.stdout):
        cells = [c.strip() for c in rest.rstrip(" |").split("|")]
        flash, ram, lib, frame, chain, stack, *insns = cells
        assert re.fullmatch(r"\d+ \(\w+\)", frame) and re.fullmatch(r"\d+ \(\d+\)", stack), cells
        per_call = [tuple(int(v) for v in cell.split(" / ")) for cell in insns]
        assert len(per_call) == 3 and all(0 < mean <= peak for mean, peak in per_call), cells
        figures[core, real] = dict(flash=int(flash), ram=int(ram), lib=int(lib), frame=int(frame.split()[0]),
                                   chain=int(chain), stack=int(stack.split()[0]), npid=per_call[0])
    m4f = figures["Cortex-M4F", "float"]
    assert m4f["flash"] < 4096, "goal: the controller's code under 4 KB of flash on the M4F"
    assert m4f["ram"] == 0  # no writable globals in the controller
    for f in figures.values():
        assert 0 < f["frame"] <= f["chain"] and f["stack"] > 0 and f["lib"] > 0
    # soft-float double on the M3 costs many times the M4F's hardware float
    assert figures["Cortex-M3", "double"]["npid"][0] > 5 * m4f["npid"][0]
    assert "instructions, not cycles" in make_embedded.stdout


def test_missing_toolchain_is_one_clear_error_not_a_traceback(tmp_path):
    env = {**os.environ, "PATH": str(tmp_path)}  # no arm-none-eabi-gcc, no qemu-system-arm
    proc = subprocess.run([sys.executable, "-m", "derive", "embedded"], cwd=ROOT, capture_output=True,
                          text=True, env=env, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("derive: error: derive embedded needs arm-none-eabi-gcc"), proc.stderr
    assert "install-system-deps.sh" in proc.stderr and "Traceback" not in proc.stderr


def _program(tmp_path: Path, target: embedded.Target, body: str) -> Path:
    src = tmp_path / f"{target.name}.c"
    src.write_text("#include <stdio.h>\n" + body)
    embedded.cc(target, [*embedded.LINK, f"-T{embedded.EMBEDDED_DIR / 'mps2.ld'}", "-O2", "-o", f"{target.name}.elf",
                         str(src), str(embedded.EMBEDDED_DIR / "startup.c"), "-lm"], tmp_path)
    return tmp_path / f"{target.name}.elf"


@pytest.mark.parametrize("target", embedded.TARGETS, ids=lambda t: t.name)
def test_board_support_passes_output_and_exit_status_through(tmp_path, target):
    elf = _program(tmp_path, target, 'int main(void) { volatile float x = 1.5f; printf("x=%g\\n", (double)(x * x));'
                                     ' printf("1 passed, 1 failed\\n"); return 3; }')
    status, output = embedded.run_qemu(target, elf, timeout=60)
    assert status == 3 and "x=2.25" in output, output
    assert embedded.parse_summary(output) == (1, 1)


@pytest.mark.parametrize("target", embedded.TARGETS, ids=lambda t: t.name)
def test_a_fault_prints_a_message_and_exits_nonzero(tmp_path, target):
    elf = _program(tmp_path, target, 'int main(void) { printf("before\\n"); fflush(stdout); __builtin_trap(); }')
    status, output = embedded.run_qemu(target, elf, timeout=60)
    assert status != 0 and "before" in output, output
    assert re.search(r"^FAULT: hard fault pc=0x[0-9a-f]{8} .*CFSR=0x00010000", output, re.M), output  # UNDEFINSTR


def test_measurement_parser():
    text = "\n".join(["stack npid_step bytes=176 far=620", "stack dobc_step bytes=170 far=600",
                      "stack gains bytes=32 far=500", "calibrate insns=40001 ticks=1000",
                      *(f"time {f} input={k} calls=256 ticks={5000 + 100 * k} baseline=100"
                        for f in embedded.FUNCTIONS for k in range(2)),
                      "measure done codes=0"])
    insns, stack, problem = embedded.parse_measure(text)
    assert problem == "" and stack == (176, 620)
    assert insns["gains"] == pytest.approx(((4900 * 40.001 / 256 + 5000 * 40.001 / 256) / 2, 5000 * 40.001 / 256))
    assert embedded.parse_measure(text.replace("measure done codes=0", ""))[2].startswith("measurement incomplete")


def test_ur5_controller_passes_its_selftest_on_the_cortex_m4f():
    """Issue 11: a 6-joint spatial arm from a URDF cross-compiled for the Cortex-M4F (float) and
    its self-test run on QEMU, with its figures in the report (no writable globals)."""
    proc = subprocess.run([sys.executable, "-m", "derive", "embedded", str(ROOT / "tests" / "data" / "urdf" / "ur5.toml"),
                           "--target", "m4f"], cwd=ROOT, capture_output=True, text=True, timeout=600,
                          stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = ROW.findall(proc.stdout)
    assert [(core, real) for core, _m, real, *_ in rows] == [("Cortex-M4F", "float")], proc.stdout
    _core, _machine, _real, passed, failed, rest = rows[0]
    assert int(passed) >= 50 and int(failed) == 0
    cells = [c.strip() for c in rest.rstrip(" |").split("|")]
    assert int(cells[1]) == 0   # RAM: no writable globals
    npid_mean, npid_peak = (int(v) for v in cells[6].split(" / "))
    assert 0 < npid_mean <= npid_peak
    assert "Arm `ur5`" in proc.stdout
