"""The error contract of the generated C under flags that assume finite math (issue 10, item 3).

``-ffast-math`` (and ``-Ofast``, ``-ffinite-math-only``, clang's ``-fno-honor-nans`` and
``-fno-honor-infinities``) let the compiler assume no value is NaN or Inf, so it may fold
``isfinite(x)`` to 1: built so, ``npid_step`` returned OK for a NaN angle with u = NaN and a
corrupted integrator. The generated glue tests the IEEE exponent bits read through memcpy
instead, which no such flag may remove. Here the library is built with each flag set
(gcc and clang, double and float) and linked against tests/fuzz/nonfinite_cases.c, built
without them: every case (NaN or Inf in each input, NaN/Inf/0/negative dt, a non-finite
state, a result that overflows from finite inputs) must give the documented code and leave
state and u untouched; -Ofast is also run under the random fuzz driver.
"""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest
import sympy as sp

import derive
from derive.codegen.emit import write_tree
from derive.codegen.files import generate_files
from derive.codegen.kernels import ParamsMode
from derive.model.examples import planar_chain

from .cbuild import STRICT

ROOT = Path(__file__).resolve().parent.parent
CASES = ROOT / "tests" / "fuzz" / "nonfinite_cases.c"
FUZZ = ROOT / "tests" / "fuzz" / "fuzz_driver.c"
ARM = "glasgow_2link"

# every flag set of gcc and clang that assumes finite math, with LTO (the checks must not
# vanish when the glue, the kernels and the caller are optimised together)
FINITE_MATH = [
    ("gcc", "-O2 -ffast-math"), ("gcc", "-Ofast"), ("gcc", "-O2 -ffinite-math-only"),
    ("gcc", "-O3 -ffast-math -flto"),
    ("clang", "-O2 -ffast-math"), ("clang", "-Ofast"), ("clang", "-O2 -ffinite-math-only"),
    ("clang", "-O2 -fno-honor-nans"), ("clang", "-O2 -fno-honor-infinities"),
    ("clang", "-O3 -ffast-math -flto"),
]


def spin_joint(d) -> int | None:
    """The first joint whose velocity enters G(theta, theta') (eq. 11) squared, so that
    dtheta[j] = 1e200 (1e30 in float) makes the result overflow (nonfinite_cases.c's case of a
    result that overflows from finite inputs); None when no velocity does (a 1-joint arm; a
    prismatic joint's velocity never does)."""
    G, s = d.numeric(d.dynamics.G), d.dynamics.sym
    for j, dq in enumerate(s.dtheta):
        if any(sp.Poly(sp.expand(g), dq).degree() >= 2 for g in G):
            return j
    return None


@pytest.fixture(scope="module")
def trees(tmp_path_factory) -> dict[tuple[str, str], Path]:
    d = derive.derive(derive.load_arm(ARM))
    assert spin_joint(d) == 0
    root = tmp_path_factory.mktemp("finite_math")
    out = {}
    for real, mode in (("double", "baked"), ("float", "baked"), ("double", "runtime")):
        write_tree(root / f"{real}_{mode}", generate_files(d, b"", real, ParamsMode(mode)))
        out[real, mode] = root / f"{real}_{mode}" / "c"
    return out


def build(cc: str, flags: str, c_dir: Path, driver: Path, out: Path, runtime: bool = False, arm: str = ARM,
          spin: int | None = None) -> Path:
    """The library built with ``flags``, the driver without finite-math flags (same -flto);
    ``spin``: the driver's SPIN_JOINT (:func:`spin_joint`), when it has one."""
    lib_flags = flags.split()
    lto = ["-flto"] if "-flto" in lib_flags else []
    defines = [f"-DARM={arm}", f"-DARM_UPPER={arm.upper()}", f'-DARM_H="{arm}.h"', f"-I{c_dir}"]
    defines += ["-DRUNTIME"] if runtime else []
    defines += [] if spin is None else [f"-DSPIN_JOINT={spin}"]
    objects = []
    for src, own in ((driver, ["-O2", *lto, *defines]), (c_dir / f"{arm}.c", [*lib_flags, f"-I{c_dir}"]),
                     (c_dir / f"{arm}_kernels.c", [*lib_flags, f"-I{c_dir}"])):
        obj = out.parent / f"{out.name}_{src.stem}.o"
        cmd = [cc, *STRICT, *own, "-c", str(src), "-o", str(obj)]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, f"{' '.join(cmd)}\n{proc.stderr}"
        objects.append(str(obj))
    proc = subprocess.run([cc, *lib_flags, *objects, "-lm", "-o", str(out)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    return out


def run(exe: Path, *args: str) -> str:
    proc = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout


def cases(n: int, spin: bool = True) -> str:
    """The last line of tests/fuzz/nonfinite_cases.c for an n-joint arm when every case passes:
    56 cases of their own, 4 more with a SPIN_JOINT (the steps and mpc_step on a result that
    overflows), and 114 per joint (a NaN, Inf and -Inf in the joint's element of each of the 5
    input fields, 7 entry points each; of each step's state, 3 steps)."""
    return f"{56 + 4 * spin + 114 * n} cases, 0 failed"


@pytest.mark.parametrize("real", ["double", "float"])
@pytest.mark.parametrize("cc,flags", FINITE_MATH, ids=[f"{c} {f}" for c, f in FINITE_MATH])
def test_error_codes_hold_under_finite_math_flags(trees, tmp_path, cc, flags, real):
    exe = build(cc, flags, trees[real, "baked"], CASES, tmp_path / "cases", spin=0)
    assert run(exe).strip().splitlines()[-1] == cases(2)


def test_error_codes_hold_under_finite_math_flags_with_runtime_parameters(trees, tmp_path):
    for cc in ("gcc", "clang"):
        exe = build(cc, "-Ofast", trees["double", "runtime"], CASES, tmp_path / f"cases_{cc}", runtime=True, spin=0)
        assert run(exe).strip().splitlines()[-1] == cases(2)


@pytest.fixture(scope="module")
def chain5(tmp_path_factory) -> dict[str, Path]:
    """The 5-link chain (5 n = 25 input values, 5 state values: whole groups of the glue's lanes
    and a tail after them) in double and float."""
    d = derive.derive(planar_chain(5, gravity=9.81))
    assert spin_joint(d) == 0
    root = tmp_path_factory.mktemp("finite_math_chain5")
    for real in ("double", "float"):
        write_tree(root / real, generate_files(d, b"", real, ParamsMode.BAKED))
    return {real: root / real / "c" for real in ("double", "float")}


@pytest.mark.parametrize("real", ["double", "float"])
@pytest.mark.parametrize("cc,flags", [("gcc", "-O2"), ("gcc", "-Ofast"), ("clang", "-Ofast")])
def test_a_nonfinite_value_in_any_element_of_five_joints_gives_the_error_code(chain5, tmp_path, cc, flags, real):
    exe = build(cc, flags, chain5[real], CASES, tmp_path / "cases", arm="chain5", spin=0)
    assert run(exe).strip().splitlines()[-1] == cases(5)


ROUND3 = ROOT / "tests" / "data" / "urdf" / "round3"


@pytest.mark.parametrize("name, spin", [("tool", None), ("polar", 0)])
def test_the_cases_fit_a_one_joint_arm_and_a_prismatic_joint(tmp_path, name, spin):
    """The case of a result that overflows needs a joint whose velocity enters G squared: the
    1-joint tool arm has none (its u is linear in theta'), and of the polar arm's revolute and
    prismatic joints only the revolute one (the slider's r theta1'^2); the driver runs the case on
    that joint, or not at all, and every other case as on any arm."""
    d = derive.derive(derive.load_arm(ROUND3 / f"{name}.toml"))
    assert spin_joint(d) == spin
    if name == "polar":   # the prismatic joint's velocity: at most linear in every entry of G
        G, s = d.numeric(d.dynamics.G), d.dynamics.sym
        assert max(sp.Poly(sp.expand(g), s.dtheta[1]).degree() for g in G) < 2
    write_tree(tmp_path / "tree", generate_files(d, b"", "double", ParamsMode.BAKED))
    exe = build("gcc", "-O2", tmp_path / "tree" / "c", CASES, tmp_path / "cases", arm=d.arm.name, spin=spin)
    assert run(exe).strip().splitlines()[-1] == cases(d.n, spin is not None)


def test_the_cases_fail_where_isfinite_is_folded_away(trees, tmp_path):
    """The driver does see the fault: with isfinite() in the glue (as before), -ffast-math
    lets npid_step accept a NaN angle."""
    c_dir = tmp_path / "isfinite"
    c_dir.mkdir()
    for f in trees["double", "baked"].iterdir():
        (c_dir / f.name).write_text(f.read_text())
    glue = c_dir / f"{ARM}.c"
    text = glue.read_text()
    text = re.sub(r"static int finite_all\(const real \*x, size_t count\)\n\{.*?\n\}\n",
                  "static int finite_all(const real *x, size_t count)\n{\n    size_t i;\n"
                  "    for (i = 0; i < count; ++i) if (!isfinite(x[i])) return 0;\n    return 1;\n}\n",
                  text, flags=re.S)
    glue.write_text("#include <math.h>\n" + text)
    exe = build("gcc", "-O2 -ffast-math", c_dir, CASES, tmp_path / "cases", spin=0)
    proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60)
    assert proc.returncode != 0 and "FAIL npid_step, theta[0] = NaN" in proc.stdout, proc.stdout


@pytest.mark.parametrize("cc", ["gcc", "clang"])
def test_fuzz_driver_contract_holds_under_ofast(trees, tmp_path, cc):
    exe = build(cc, "-Ofast", trees["float", "baked"], FUZZ, tmp_path / "fuzz")
    out = run(exe, "20000")
    assert re.search(r"^20000 passed, 0 failed$", out, re.M), out
    assert int(re.search(r"(\d+) error codes returned", out).group(1)) > 2000


def test_no_c_template_tests_finiteness_with_the_math_library():
    """The kind, beyond the controller's glue: every C template (the FMU shells, plant and
    variable setters too, which an importer compiles with its own flags) tests finiteness
    on the exponent bits, never with <math.h>'s classification macros."""
    templates = sorted(p for p in (ROOT / "templates").rglob("*.jinja") if re.search(r"\.[ch]\.jinja$", p.name))
    assert len(templates) >= 10
    for path in templates:
        code = re.sub(r"/\*.*?\*/|\{#.*?#\}", " ", path.read_text(encoding="utf-8"), flags=re.S)
        found = re.findall(r"\b(isfinite|isnan|isinf|isnormal|fpclassify)\s*\(", code)
        assert not found, (path.relative_to(ROOT).as_posix(), found)


PLANT_CASES = r"""
#include <math.h>
#include <stdio.h>
#include "glasgow_2link_plant.h"
int main(void)
{
    const double ok[2] = {0.1, 0.2}, zero[2] = {0.0, 0.0};
    double bad[2] = {0.1, 0.2}, out[4] = {7, 7, 7, 7};
    int fails = 0, k;
    for (k = 0; k < 4; ++k) {
        bad[k / 2] = (k % 2) ? INFINITY : NAN;
        bad[1 - k / 2] = 0.2;
        if (glasgow_2link_mass_matrix(bad, out) != GLASGOW_2LINK_ENONFINITE || out[0] != 7) ++fails;
        if (glasgow_2link_forward_dynamics(ok, zero, bad, zero, out) != GLASGOW_2LINK_ENONFINITE || out[0] != 7)
            ++fails;
    }
    if (glasgow_2link_mass_matrix(ok, out) != GLASGOW_2LINK_OK || !(out[0] > 0)) ++fails;
    printf("%d failed\n", fails);
    return fails != 0;
}
"""


@pytest.mark.parametrize("cc", ["gcc", "clang"])
def test_plant_model_returns_enonfinite_under_ofast(trees, tmp_path, cc):
    """The plant's functions (main's <arm>_plant.c) keep their ENONFINITE under -Ofast:
    a NaN or Inf angle or input leaves the output untouched."""
    c_dir = trees["double", "baked"]
    lib = tmp_path / "plant.o"
    subprocess.run([cc, "-Ofast", f"-I{c_dir}", "-c", str(c_dir / f"{ARM}_plant.c"), "-o", str(lib)], check=True)
    src = tmp_path / "cases.c"
    src.write_text(PLANT_CASES)
    exe = tmp_path / "cases"
    subprocess.run([cc, *STRICT, "-O1", f"-I{c_dir}", str(src), str(lib), "-lm", "-o", str(exe)], check=True)
    proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout == "0 failed\n", proc.stdout
