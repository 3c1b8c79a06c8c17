"""Generated C under faults and static analysis; random valid arms end to end.

The fuzz driver (tests/fuzz/fuzz_driver.c) feeds random, extreme (1e6, 1e30),
tiny, NaN and Inf inputs and bad dt to every entry point and checks the
contract of the header: an error code leaves state and u untouched, success
gives finite results. It runs under -fsanitize=address,undefined and valgrind.
"""
from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import derive
from derive.codegen.files import generate_files, python_files
from derive.codegen.emit import write_tree
from derive.codegen.kernels import ParamsMode
from derive.codegen.reference import Reference
from derive.model.spec import arm_from_dict

from .cbuild import STRICT, compile_c, library_sources
from .hypothesis_profiles import examples

ROOT = Path(__file__).resolve().parent.parent
FUZZ = ROOT / "tests" / "fuzz" / "fuzz_driver.c"
SANITIZER_ITERATIONS = 100_000
VALGRIND_ITERATIONS = 20_000
VARIANTS = [("double", "baked"), ("float", "baked"), ("double", "runtime"), ("float", "runtime")]


@pytest.fixture(scope="module")
def trees(tmp_path_factory):
    """Generated C of the default and 3-link arms in every variant (built once)."""
    out = {}
    root = tmp_path_factory.mktemp("hardening")
    for arm in ("glasgow_2link", "planar_3link"):
        d = derive.derive(derive.load_arm(arm))
        for real, mode in VARIANTS:
            target = root / f"{arm}_{real}_{mode}"
            write_tree(target, generate_files(d, b"", real, ParamsMode(mode)))
            out[arm, real, mode] = target / "c"
    return out


def _fuzz(c_dir: Path, arm: str, runtime: bool, exe: Path, flags: list[str]) -> Path:
    defines = [f"-DARM={arm}", f"-DARM_UPPER={arm.upper()}", f'-DARM_H="{arm}.h"', f"-I{c_dir}"]
    if runtime:
        defines.append("-DRUNTIME")
    return compile_c("gcc", [FUZZ, *library_sources(c_dir, arm)], exe, [*defines, *flags])


def _passed(stdout: str, iterations: int) -> None:
    assert re.search(rf"^{iterations} passed, 0 failed$", stdout, re.M), stdout
    errors = int(re.search(r"(\d+) error codes returned", stdout).group(1))
    assert errors > iterations // 10, "the fuzzer hardly reached the error paths"


@pytest.mark.parametrize("arm", ["glasgow_2link", "planar_3link"])
@pytest.mark.parametrize("real,mode", VARIANTS)
def test_fuzz_driver_under_address_and_undefined_sanitizers(trees, tmp_path, arm, real, mode):
    exe = _fuzz(trees[arm, real, mode], arm, mode == "runtime", tmp_path / "fz",
                ["-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"])
    proc = subprocess.run([str(exe), str(SANITIZER_ITERATIONS)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr[-3000:]
    _passed(proc.stdout, SANITIZER_ITERATIONS)


def test_fuzz_driver_under_valgrind(trees, tmp_path):
    exe = _fuzz(trees["glasgow_2link", "double", "baked"], "glasgow_2link", False, tmp_path / "fz", ["-O0", "-g"])
    proc = subprocess.run(["valgrind", "--error-exitcode=3", "--leak-check=full", "--errors-for-leak-kinds=all",
                           str(exe), str(VALGRIND_ITERATIONS)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "ERROR SUMMARY: 0 errors" in proc.stderr
    _passed(proc.stdout, VALGRIND_ITERATIONS)


BROKEN = {
    # u written before the finiteness check
    "writes u first": ("    if (!input_finite(in)) return GLASGOW_2LINK_ENONFINITE;\n    glasgow_2link_kernel_mpc(",
                       "    u[0] = 0;\n    if (!input_finite(in)) return GLASGOW_2LINK_ENONFINITE;\n    glasgow_2link_kernel_mpc("),
    # npid_init accepts a non-finite input: OK with a finite (zero) state, caught by the code's check
    "accepts NaN": ("    if (!input_finite(in)) return GLASGOW_2LINK_ENONFINITE;\n    for (i = 0; i < N; ++i) s->int_e[i] = 0;",
                    "    (void)in;\n    for (i = 0; i < N; ++i) s->int_e[i] = 0;"),
}


@pytest.mark.parametrize("fault", sorted(BROKEN))
def test_fuzz_driver_detects_a_broken_contract(trees, tmp_path, fault):
    """The driver can fail: a library that writes u before its finiteness check, or returns OK for a
    non-finite input, is caught."""
    src = trees["glasgow_2link", "double", "baked"]
    broken = tmp_path / "broken"
    broken.mkdir()
    for f in src.iterdir():
        (broken / f.name).write_text(f.read_text())
    glue = broken / "glasgow_2link.c"
    text = glue.read_text()
    marker, replacement = BROKEN[fault]
    assert text.count(marker) == 1
    glue.write_text(text.replace(marker, replacement))
    exe = _fuzz(broken, "glasgow_2link", False, tmp_path / "fz", ["-O1"])
    proc = subprocess.run([str(exe), "2000"], capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0 and "FAIL" in proc.stdout


@pytest.mark.parametrize("arm", ["glasgow_2link", "planar_3link"])
@pytest.mark.parametrize("real,mode", VARIANTS)
def test_cppcheck_and_gcc_analyzer_report_nothing(trees, tmp_path, arm, real, mode):
    c_dir = trees[arm, real, mode]
    proc = subprocess.run(["cppcheck", "--enable=warning,style,performance,portability", "--std=c99",
                           "--error-exitcode=1", "--quiet", str(c_dir)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and not proc.stderr.strip(), proc.stderr
    for src in [*library_sources(c_dir, arm), c_dir / f"{arm}_selftest.c"]:
        compile_c("gcc", [src], tmp_path / (src.stem + ".o"), ["-c", "-fanalyzer", *STRICT])


def _valid_arm(n: int, draw) -> dict:
    # tiny magnitudes made 0: products of them could be subnormal, which derive refuses (test_ranges.py)
    pos = lambda lo, hi: draw(st.floats(lo, hi, allow_nan=False, allow_infinity=False)  # noqa: E731
                              .map(lambda x: 0.0 if abs(x) < 1e-100 else x))
    links = [{"length": pos(0.1, 1.0), "mass": pos(0.1, 3.0), "com": pos(0.02, 0.5),
              "inertia": pos(1e-4, 0.05), "viscous_friction": pos(0.0, 0.1)} for _ in range(n)]
    motors = [{"torque_constant": pos(0.01, 0.5), "voltage_constant": pos(0.0, 0.5), "resistance": pos(0.5, 10.0),
               "gear_ratio": pos(1.0, 50.0), "rotor_inertia": pos(0.0, 1e-4)} for _ in range(n)]
    w = sorted(pos(0.5, 5.0) for _ in range(n))
    t2 = pos(0.1, 2.0)
    return {"arm": {"name": "prop_arm", "gravity": draw(st.sampled_from([0.0, 9.81]))}, "link": links,
            "motor": motors, "point_mass": [{"link": n, "distance": links[-1]["length"], "mass": pos(0.01, 1.0)}],
            "controller": {"T1": pos(0.0, 0.05), "T2": t2, "w": w}}


@settings(max_examples=examples(8))
@given(st.data())
def test_random_valid_arms_derive_generate_and_match_the_symbolic_model(tmp_path_factory, data):
    n = data.draw(st.integers(1, 3))
    arm = arm_from_dict(_valid_arm(n, data.draw), "<hypothesis>")
    d = derive.derive(arm)
    target = tmp_path_factory.mktemp("prop") / "prop_arm"
    files = python_files(d, ParamsMode.BAKED)
    write_tree(target, files | {"MANIFEST.json": json.dumps({"files": sorted(files)})})
    import importlib.util

    spec = importlib.util.spec_from_file_location("prop_arm_mod", target / "python" / "prop_arm.py")
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    ref = Reference(d)
    rng = np.random.default_rng(n)
    for _ in range(3):
        x = list(rng.uniform(-2, 2, 5 * n))
        inp = m.Input(*(x[i * n:(i + 1) * n] for i in range(5)))
        state = m.NpidState()
        code, u, _ = m.npid_step(state, inp, 1e-3)
        want = np.array([float(v) for v in ref.npid_step([0] * n, x, 1e-3)[0]])
        assert code == 0
        assert np.max(np.abs(u - want)) <= 1e-12 * max(1.0, np.max(np.abs(want))), (u, want)
