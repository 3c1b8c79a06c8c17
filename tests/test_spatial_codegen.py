"""Generated C and Python of the UR5 and the Panda (issue 11): the C controller and plant
self-tests (the 40-digit reference vectors, per-element tolerances from the rounding
analysis) pass under strict gcc flags, and the Python module's laws and plant agree with
the 40-digit reference to 1e-12 relative. Each arm is generated once for the module."""
from __future__ import annotations

import importlib.util
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.codegen.emit import write_tree
from derive.codegen.files import generate_files
from derive.codegen.kernels import ParamsMode
from derive.codegen.reference import Reference
from derive.model.spec import load_arm

from .cbuild import compile_c, library_sources

URDF = Path(__file__).parent / "data" / "urdf"
STATES = 10


@pytest.fixture(scope="module", params=["ur5", "panda"])
def generated(request, tmp_path_factory):
    """(derivation, generated tree) of the arm, generated once (double, values baked in)."""
    d = derive.derive(load_arm(URDF / f"{request.param}.toml"))
    out = tmp_path_factory.mktemp(request.param)
    write_tree(out, generate_files(d, b"", "double", ParamsMode.BAKED))
    return d, out


@pytest.mark.parametrize("selftest", ["selftest", "plant_selftest"])
def test_generated_c_selftest_passes_under_strict_flags(generated, tmp_path, selftest: str) -> None:
    d, out = generated
    c, name = out / "c", d.arm.name
    exe = compile_c("gcc", [c / f"{name}_{selftest}.c", *library_sources(c, name)], tmp_path / "st", ["-O2"])
    proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert re.search(r"^(\d+) passed, 0 failed$", proc.stdout, re.M), proc.stdout[-3000:]


def _rel(got, want) -> float:
    want = np.array([float(w) for w in want])
    return float(np.max(np.abs(np.ravel(np.asarray(got, dtype=float)) - want)) / max(np.max(np.abs(want)), 1e-300))


def test_generated_python_module_is_within_1e12_of_the_40_digit_reference(generated) -> None:
    d, out = generated
    path = out / "python" / f"{d.arm.name}.py"
    spec = importlib.util.spec_from_file_location(f"gen_{d.arm.name}", path)
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    ref = Reference(d)
    rng = np.random.default_rng(11)
    n = d.n
    worst = 0.0
    for _ in range(STATES):
        th, dth, yd, dyd, ddyd, ie = (list(rng.uniform(-1.5, 1.5, n)) for _ in range(6))
        x = th + dth + yd + dyd + ddyd
        pairs = [(m._kernel_mpc(th, dth, yd, dyd, ddyd), ref.mpc(x)),
                 (m._kernel_npid(th, dth, yd, dyd, ddyd, ie, [1e-3])[0], ref.npid(x, ie)),
                 (m.mass_matrix(th)[1], ref.mass_matrix(th)), (m.bias(th, dth)[1], ref.bias(th, dth)),
                 (m.gravity(th)[1], ref.gravity(th))]
        for got, want in pairs:
            worst = max(worst, _rel(got, want))
    assert worst <= 1e-12, worst


FUZZ = Path(__file__).resolve().parent / "fuzz" / "fuzz_driver.c"


def _fuzz_exe(generated, tmp_path: Path, flags: list[str]) -> Path:
    d, out = generated
    c, name = out / "c", d.arm.name
    defines = [f"-DARM={name}", f"-DARM_UPPER={name.upper()}", f'-DARM_H="{name}.h"', f"-I{c}"]
    return compile_c("gcc", [FUZZ, *library_sources(c, name)], tmp_path / "fz", [*defines, *flags])


def _fuzz_passed(stdout: str, iterations: int) -> None:
    assert re.search(rf"^{iterations} passed, 0 failed$", stdout, re.M), stdout
    assert int(re.search(r"(\d+) error codes returned", stdout).group(1)) > iterations // 10


def test_generated_c_fuzz_driver_under_address_and_undefined_sanitizers(generated, tmp_path) -> None:
    """The header's contract (an error code leaves state and u untouched, success gives finite
    results) under random, extreme, NaN and Inf inputs, with -fsanitize=address,undefined."""
    iterations = 20_000
    exe = _fuzz_exe(generated, tmp_path, ["-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"])
    proc = subprocess.run([str(exe), str(iterations)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    _fuzz_passed(proc.stdout, iterations)


def test_generated_c_fuzz_driver_under_valgrind(generated, tmp_path) -> None:
    iterations = 2_000
    exe = _fuzz_exe(generated, tmp_path, ["-O0", "-g"])
    proc = subprocess.run(["valgrind", "--error-exitcode=3", "--leak-check=full", "--errors-for-leak-kinds=all",
                           str(exe), str(iterations)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0 and "ERROR SUMMARY: 0 errors" in proc.stderr, proc.stderr[-3000:]
    _fuzz_passed(proc.stdout, iterations)


def test_ur5_with_runtime_parameters_passes_its_selftest(tmp_path) -> None:
    """Issue 11 item 4: body parameters keep --params runtime working on a spatial arm; the
    parameters are read at run time (the header declares the parameter struct)."""
    d = derive.derive(load_arm(URDF / "ur5.toml"))
    write_tree(tmp_path / "ur5", generate_files(d, b"", "double", ParamsMode.RUNTIME))
    c = tmp_path / "ur5" / "c"
    assert "ur5_params" in (c / "ur5.h").read_text()
    exe = compile_c("gcc", [c / "ur5_selftest.c", *library_sources(c, "ur5")], tmp_path / "st", ["-O2"])
    proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert re.search(r"^(\d+) passed, 0 failed$", proc.stdout, re.M), proc.stdout[-3000:]
