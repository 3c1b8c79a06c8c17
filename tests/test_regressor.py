"""The identification regressor (issue 22, item 1): J theta'' + G = Y(theta, theta', theta'') pi.

Checked against the 40-digit reference of the Derivation (derive.codegen.reference): Y pi
of the generated C and Python equals J theta'' + G at 1e-12 (norm-wise relative) at
seeded states; Y itself equals the 40-digit Y; Y has full column rank at random states
(the base parameters are identifiable); the base parameters of the planar two-link arm
are the textbook ones; the C self-test compiles strictly with gcc and clang and passes.
"""
from __future__ import annotations

import ctypes
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import derive
from derive.cli import main
from derive.codegen.emit import write_tree
from derive.codegen.files import generate_files
from derive.codegen.kernels import ParamsMode
from derive.codegen.balls import BallFunction, to_float, working_precision
from derive.codegen.reference import PRECISION, Reference, certified
from derive.dynamics.equations import derive_dynamics
from derive.dynamics.program import dag_xreplace
from derive.identify.regressor import derive_regressor
from derive.model.spec import load_arm

from .cbuild import compile_c, compilers, library_sources

STATES = 50
UR5 = Path(__file__).parent / "data" / "urdf" / "ur5.toml"


def _states(n: int, count: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-3, 3, (count, 3 * n))


def _reference_tau(d, x) -> np.ndarray:
    """J theta'' + G at 40 digits (the Derivation's matrices, derive.codegen.reference), as doubles."""
    ref, n = Reference(d), d.n
    J = np.array([float(v) for v in ref.mass_matrix(list(x[:n]))]).reshape(n, n)
    G = np.array([float(v) for v in ref.bias(list(x[:n]), list(x[n:2 * n]))])
    return J @ x[2 * n:] + G


def _dynamics_reference(arm):
    """J theta'' + G of the arm's dynamics stage (derive.dynamics: no controller derived) in
    ball arithmetic (derive.codegen.balls), 40 digits certified."""
    dyn = derive_dynamics(arm)
    s = dyn.sym
    tau = dag_xreplace(list(dyn.J * sp.Matrix(s.ddtheta) + dyn.G), dyn.subs)
    f = BallFunction(list(s.theta + s.dtheta + s.ddtheta), tau, "tau")

    def at(x) -> np.ndarray:
        with working_precision(PRECISION):
            out = f(*x)
        assert certified(out)
        return np.array([to_float(v) for v in out])
    return at


@pytest.mark.parametrize("name", ["glasgow_2link", "vertical_2link", "planar_3link", str(UR5)])
def test_y_pi_equals_j_ddtheta_plus_g_at_1e_12_and_full_rank(name):
    arm = load_arm(name)
    reg = derive_regressor(arm.chain)
    reference = _dynamics_reference(arm)
    pi = reg.base_values()
    n = arm.n
    for x in _states(n, 12, 3):
        Y = reg.evaluate(x[None, :n], x[None, n:2 * n], x[None, 2 * n:])[0]
        want = reference(x)
        err = np.abs(Y @ pi - want).max() / np.abs(want).max()
        assert err <= 1e-12, f"{name}: Y pi against J theta'' + G at {x}: {err:.3g}"
    W = reg.evaluate(*np.split(_states(n, 100, 5), 3, axis=1)).reshape(-1, reg.p)
    s = np.linalg.svd(W / np.linalg.norm(W, axis=0), compute_uv=False)
    assert s[-1] / s[0] > 1e-4, f"{name}: the base parameters' columns are dependent ({s[-1] / s[0]:.2g})"


def test_planar_two_link_base_parameters_are_the_textbook_ones():
    """Horizontal planar 2R: the joint 1 axis inertia regroups the rotor, link 1's inertia and
    m2 l1^2 (Khalil and Dombre, section 12.5); link 2 keeps its first moments and Izz."""
    reg = derive_regressor(load_arm("glasgow_2link").chain)
    s = {p.name: p.symbol for p in reg.standard}
    want = {"Izz1R": s["Izz1"] + s["Ia1"] + sp.Rational(38, 100) ** 2 * s["m2"], "hx2": s["hx2"],
            "hy2": s["hy2"], "Izz2": s["Izz2"], "Ia2": s["Ia2"], "fv1": s["fv1"], "fv2": s["fv2"]}
    assert {b.name: b.expression for b in reg.base} == want
    assert "hy1" in reg.absent and "Ixy2" in reg.absent
    exact = reg.exact_base_values()       # the paper's arm: uniform rods, point masses, Kt Kv / R damping
    assert exact[reg.names.index("fv1")] == sp.Rational(23, 100) * sp.Rational(29, 100) / sp.Rational(34, 10)


def test_vertical_arm_keeps_the_first_link_moments_and_ur5_folds_the_rotors():
    vertical = derive_regressor(load_arm("vertical_2link").chain)
    assert vertical.names[:3] == ("hx1R", "hy1", "Izz1R")          # gravity sees link 1's first moment
    ur5 = derive_regressor(load_arm(UR5).chain)
    assert ur5.p == 46 and "Ia1" not in ur5.names and "Ia2" not in ur5.names   # 36 inertial + 4 Ia + 6 fv
    izz1 = ur5.base[ur5.names.index("Izz1R")].expression
    assert izz1.coeff(sp.Symbol("Ia1", real=True)) == 1


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    d = derive.derive(load_arm("vertical_2link"))
    root = tmp_path_factory.mktemp("regressor")
    trees = {}
    for real, mode in (("double", ParamsMode.BAKED), ("float", ParamsMode.BAKED), ("double", ParamsMode.RUNTIME)):
        trees[real, mode] = root / f"{real}_{mode.value}"
        write_tree(trees[real, mode], generate_files(d, b"", real, mode, regressor=True))
    return d, trees


@pytest.mark.parametrize("cc", compilers())
@pytest.mark.parametrize("key", [("double", ParamsMode.BAKED), ("float", ParamsMode.BAKED),
                                 ("double", ParamsMode.RUNTIME)])
def test_regressor_selftest_compiles_strictly_and_passes(generated, tmp_path, cc, key):
    d, trees = generated
    c, a = trees[key] / "c", d.arm.name
    exe = compile_c(cc, [c / f"{a}_regressor_selftest.c", c / f"{a}_regressor.c", *library_sources(c, a)],
                    tmp_path / "selftest", ["-O2"])
    out = subprocess.run([str(exe)], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.strip() == "16 passed, 0 failed", out.stdout


def test_generated_c_and_python_regressors_equal_the_40_digit_reference(generated, tmp_path):
    d, trees = generated
    tree, a, n = trees["double", ParamsMode.BAKED], d.arm.name, d.n
    reg = derive_regressor(d.dynamics.chain)
    so = compile_c("gcc", [tree / "c" / f"{a}_regressor.c", *library_sources(tree / "c", a)], tmp_path / "lib.so",
                   ["-O2", "-shared", "-fPIC"])
    lib = ctypes.CDLL(str(so))
    sys.path.insert(0, str(tree / "python"))
    try:
        spec = importlib.util.spec_from_file_location(f"{a}_regressor", tree / "python" / f"{a}_regressor.py")
        py = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(py)
    finally:
        sys.path.remove(str(tree / "python"))
    values = np.array((ctypes.c_double * reg.p).in_dll(lib, f"{a}_base_values"))
    np.testing.assert_allclose(values, reg.base_values(), rtol=1e-15)
    assert py.BASE_VALUES == tuple(reg.base_values()) and [b[0] for b in py.BASE_PARAMETERS] == list(reg.names)
    names = (ctypes.c_char_p * reg.p).in_dll(lib, f"{a}_base_names")
    assert [x.decode() for x in names] == list(reg.names)
    s = reg.sym
    ball = BallFunction(list(s.theta + s.dtheta + s.ddtheta), list(reg.Y), "Y")
    for x in _states(n, STATES, 11):
        Y = (ctypes.c_double * (n * reg.p))()
        code = lib[f"{a}_regressor"]((ctypes.c_double * n)(*x[:n]), (ctypes.c_double * n)(*x[n:2 * n]),
                                     (ctypes.c_double * n)(*x[2 * n:]), Y)
        assert code == 0
        Yc = np.array(Y[:]).reshape(n, reg.p)
        code, Yp = py.regressor(list(x[:n]), list(x[n:2 * n]), list(x[2 * n:]))
        assert code == py.OK
        want = np.array([to_float(v) for v in ball(*x)]).reshape(n, reg.p)
        for got, what in ((Yc, "C"), (Yp, "Python")):
            assert np.abs(got - want).max() <= 1e-12 * np.abs(want).max(), what
            tau = _reference_tau(d, x)
            assert np.abs(got @ values - tau).max() <= 1e-12 * np.abs(tau).max(), what
    bad = list(x[:n])
    bad[0] = float("nan")
    assert py.regressor(bad, list(x[n:2 * n]), list(x[2 * n:])) == (py.ENONFINITE, None)
    with pytest.raises(ValueError, match=r"ddtheta: expected shape \(2,\)"):
        py.regressor(list(x[:n]), list(x[n:2 * n]), [0.0])


def test_generate_regressor_is_on_request_and_listed_in_the_manifest(tmp_path):
    assert main(["generate", "--out", str(tmp_path / "plain")]) == 0
    assert not list((tmp_path / "plain").rglob("*regressor*"))
    assert main(["generate", "--regressor", "--out", str(tmp_path / "with")]) == 0
    root = tmp_path / "with" / "glasgow_2link"
    manifest = json.loads((root / "MANIFEST.json").read_text())
    assert manifest["options"]["regressor"] is True
    assert [b["name"] for b in manifest["base_parameters"]] == ["Izz1R", "hx2", "hy2", "Izz2", "Ia2", "fv1", "fv2"]
    assert manifest["base_parameters"][0]["expression"] == "Ia1 + Izz1 + 361*m2/2500"
    header = (root / "c" / "glasgow_2link_regressor.h").read_text()
    assert "0 Izz1R = Ia1 + Izz1 + 361*m2/2500 [kg m^2]" in header and "#define GLASGOW_2LINK_NB 7" in header
    for name in ("glasgow_2link_regressor.c", "glasgow_2link_regressor_selftest"):
        assert name in (root / "c" / "CMakeLists.txt").read_text()
    # the other files are those of a plain run
    for path in (tmp_path / "plain" / "glasgow_2link").rglob("*"):
        rel = path.relative_to(tmp_path / "plain" / "glasgow_2link")
        if path.is_file() and rel.name not in ("MANIFEST.json", "CMakeLists.txt"):
            assert (root / rel).read_bytes() == path.read_bytes(), rel


def test_a_float_regressor_whose_reference_has_entries_below_floats_range_generates_and_passes(tmp_path):
    """The UR5's 40-digit regressor reference has an entry of 1.7e-48 (0 but for its last digits): the float
    self-test writes it 0 (derive.codegen.printing.expected_literal), where a constant of the code itself is
    still refused; the float regressor's self-test passes."""
    from derive.codegen.printing import c_literal, expected_literal
    from derive.errors import DerivationError

    assert expected_literal(1.7105694144590052e-48, "float") == "0.0f"
    assert expected_literal(-2.5e-7, "float") == c_literal(-2.5e-7, "float")
    with pytest.raises(DerivationError, match="underflows to 0 in float"):
        c_literal(1.7105694144590052e-48, "float")
    d = derive.derive(load_arm(UR5))
    write_tree(tmp_path / "f", generate_files(d, b"", "float", ParamsMode.BAKED, regressor=True))
    c, a = tmp_path / "f" / "c", d.arm.name
    exe = compile_c("gcc", [c / f"{a}_regressor_selftest.c", c / f"{a}_regressor.c", *library_sources(c, a)],
                    tmp_path / "selftest", ["-O2"])
    out = subprocess.run([str(exe)], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.strip() == "16 passed, 0 failed", out.stdout
