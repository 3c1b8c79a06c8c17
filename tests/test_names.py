"""Arm names that look like derived symbols (issue 19 item 6): the Unitree Z1 is `--name z1`.

An arm name is only ever a prefix ('<arm>_...', macros '<ARM>_...'), a file, module, CMake
project and target name in the generated code (derive.model.names): the ports, parameters,
statics and CSE registers it generates (theta, dt, u, z, e, w1, k1, a0, jsolve1, clip, pack)
are locals, struct fields or statics of a .c file, so such names are accepted, and the code
generated for them compiles with -Wshadow -Werror (no declaration hides another) and computes
what the same arm under its own name computes.
"""
from __future__ import annotations

import ctypes
import importlib.util
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.cli import main
from derive.codegen.files import library_files, python_files
from derive.codegen.kernels import ParamsMode
from derive.codegen.plant import plant_view
from derive.codegen.render import render
from derive.codegen.views import arm_view, kernel_functions
from derive.model.names import name_problem

from .cbuild import STRICT

# derived symbols, ports, locals of the glue, CSE registers and solve unknowns of the kernels,
# statics of the generated .c files, and the words the old rule refused
NAMES = ("z1", "e", "dt", "u", "theta1", "k1", "w1", "a0", "c0", "jsolve1", "xsolve1", "pv", "s", "clip", "real",
         "params", "dhat", "theta", "int_e", "sim")
IMPLICIT = ("z1", "e", "dt", "u", "a0", "jsolve1", "xsolve1", "theta1")   # the implicit build's extra ports
DATA = Path(__file__).parent / "data" / "urdf"


@pytest.fixture(scope="module")
def paper():
    d = derive.derive(derive.load_arm())
    return d, {o: kernel_functions(d, ParamsMode.RUNTIME, o) for o in ("explicit", "implicit")}


def _module(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(f"names_{name}", path)
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def _sources(d, functions, observer: str) -> dict[str, str]:
    """The C library with its plant, the closed loop's driver and the Python module of ``d``."""
    from derive.sim.compiled import loop_sources

    v = arm_view(d, "double", ParamsMode.RUNTIME, functions, observer=observer)
    a = d.arm.name
    pl = plant_view(d, "double", ParamsMode.RUNTIME)
    return {**library_files(d, "double", ParamsMode.RUNTIME, v),
            f"c/{a}_plant.h": render("c/plant.h.jinja", v=v, pl=pl),
            f"c/{a}_plant.c": render("c/plant.c.jinja", v=v, pl=pl),
            f"c/{a}_sim.c": loop_sources(d, observer)[f"{a}_sim.c"],
            **python_files(d, ParamsMode.RUNTIME, v)}




def test_names_like_derived_symbols_are_accepted():
    assert all(name_problem(n) is None for n in NAMES), [(n, name_problem(n)) for n in NAMES if name_problem(n)]
    # what stays refused: a C library name, a CasADi work vector, the cross-arm clash
    assert "C standard library" in name_problem("j1") and "CasADi" in name_problem("iw")
    assert "an arm named 'z1'" in name_problem("z1_kernel")


@pytest.mark.parametrize("observer", ["explicit", "implicit"])
def test_code_generated_under_a_derived_symbols_name_compiles_strictly_and_computes_the_same(paper, tmp_path,
                                                                                              observer):
    """Every name of NAMES (IMPLICIT in the implicit build): the C library, plant and compiled-loop
    driver compile together at -std=c99 -pedantic -Wall -Wextra -Wshadow -Werror, and their steps,
    like the Python module's, give the numbers of the same arm under its own name (to the last bit)."""
    d, functions = paper
    n, dt = d.n, 1e-3
    x = [0.3, -0.2, 0.5, 0.25, 0.1, 0.2, 0.0, 0.1, 0.0, 0.0]
    results = {}
    for name in ("glasgow_2link", *(NAMES if observer == "explicit" else IMPLICIT)):
        dn = replace(d, arm=replace(d.arm, name=name))
        files = _sources(dn, functions[observer], observer)
        root = tmp_path / f"{observer}_{name}"
        for path, text in files.items():
            (root / path).parent.mkdir(parents=True, exist_ok=True)
            (root / path).write_text(text)
        c = root / "c"
        so = root / f"lib{name}.so"
        cmd = ["gcc", *STRICT, "-Wshadow", "-O0", "-shared", "-fPIC", "-o", str(so),
               *(str(c / f) for f in (f"{name}.c", f"{name}_kernels.c", f"{name}_plant.c", f"{name}_sim.c")), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        assert proc.returncode == 0, f"{name}: {proc.stderr}"
        lib = ctypes.CDLL(str(so))
        real = ctypes.c_double
        params = (real * (len(d.values) + n))()
        getattr(lib, f"{name}_params_default")(params)
        inp, u = (real * (5 * n))(*x), (real * n)()
        out = []
        assert getattr(lib, f"{name}_mpc_step")(params, inp, u, None) == 0
        out += list(u)
        for form in ("npid", "dobc", "mom"):
            s = (real * (2 * n))()
            init_dt = (real(dt),) if form == "dobc" and observer == "implicit" else ()
            assert getattr(lib, f"{name}_{form}_init")(params, s, inp, *init_dt) == 0
            for _ in range(2):
                assert getattr(lib, f"{name}_{form}_step")(params, s, inp, real(dt), u, None) == 0
                out += list(u)
        m = _module(root / "python" / f"{name}.py", f"{observer}_{name}")
        p, i = m.Params(), m.Input(*(x[k * n:(k + 1) * n] for k in range(5)))
        py = list(m.mpc_step(p, i)[1])
        for form, state in (("npid", m.NpidState), ("dobc", m.DobcState), ("mom", m.MomState)):
            st = state()
            init_dt = (dt,) if form == "dobc" and observer == "implicit" else ()
            assert getattr(m, f"{form}_init")(p, st, i, *init_dt) == m.OK
            for _ in range(2):
                py += list(getattr(m, f"{form}_step")(p, st, i, dt)[1])
        results[name] = (np.array(out), np.array(py))
    base_c, base_py = results["glasgow_2link"]
    np.testing.assert_allclose(base_c, base_py, rtol=1e-12)
    for name, (c_out, py_out) in results.items():
        assert np.array_equal(c_out, base_c), name
        assert np.array_equal(py_out, base_py), name


def test_init_name_z1_generates_and_the_self_test_passes(tmp_path):
    """`derive init --name z1` (issue 19 item 6: the Unitree Z1), then `derive generate`: the
    C self-test compiles and passes, the Python module imports as z1."""
    for f in ("double_pendulum.urdf",):
        (tmp_path / f).write_bytes((DATA / f).read_bytes())
    assert main(["init", str(tmp_path / "double_pendulum.urdf"), "--name", "z1", "--out", str(tmp_path / "z1.toml")]) == 0
    assert main(["generate", str(tmp_path / "z1.toml"), "--out", str(tmp_path / "gen")]) == 0
    c = tmp_path / "gen" / "z1" / "c"
    exe = tmp_path / "st"
    subprocess.run(["gcc", *STRICT, "-Wshadow", "-O1", "-o", str(exe), str(c / "z1_selftest.c"), str(c / "z1.c"),
                    str(c / "z1_kernels.c"), "-lm"], check=True)
    proc = subprocess.run([str(exe)], capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout.endswith(" passed, 0 failed\n"), proc.stdout
    m = _module(tmp_path / "gen" / "z1" / "python" / "z1.py", "z1")
    assert m.N == 2
