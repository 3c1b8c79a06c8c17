"""Generated C and Python against the SymPy derivation (eq. 15, 21-27, 34-38).

Every comparison is with derive.codegen.reference (40-digit mpmath evaluation of the
SymPy matrices), never between two outputs of the same printer alone.
"""
from __future__ import annotations

import importlib.util
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.codegen import testvectors as tv
from derive.codegen.bounds import ApiBounds
from derive.codegen.files import generate_files
from derive.codegen.emit import write_tree
from derive.codegen.kernels import ParamsMode
from derive.codegen.reference import Reference
from derive.model.spec import resolve_arm_path

from .cbuild import STRICT, CLib, compile_c, compilers, library_sources

ROOT = Path(__file__).resolve().parent.parent
ARM = "glasgow_2link"
STATES = 200


def _generate(tmp: Path, real: str = "double", mode: ParamsMode = ParamsMode.BAKED, arm: str | None = None) -> Path:
    d = _derivation(arm)
    files = generate_files(d, resolve_arm_path(arm).read_bytes(), real, mode)
    target = tmp / f"{d.arm.name}_{real}_{mode.value}"
    write_tree(target, files)
    return target


_CACHE: dict = {}


def _derivation(arm=None):
    if arm not in _CACHE:
        _CACHE[arm] = derive.derive(derive.load_arm(arm))
    return _CACHE[arm]


@pytest.fixture(scope="module")
def paper_ref():
    return Reference(_derivation())


@pytest.fixture(scope="module")
def states(paper_ref):
    rng = np.random.default_rng(4242)
    n = paper_ref.n
    out = []
    for _ in range(STATES):
        x = list(np.concatenate([rng.uniform(-3, 3, 3 * n), rng.uniform(-2, 2, n), rng.uniform(-5, 5, n)]))
        out.append((x, list(rng.uniform(-1, 1, n)), list(rng.uniform(-1, 1, n))))
    return out


def _rel(got, want) -> float:
    want = np.asarray([float(w) for w in want])
    scale = np.max(np.abs(want))
    return float(np.max(np.abs(np.asarray(got, dtype=float) - want)) / (scale if scale > 0 else 1.0))


def _compare(impl, ref, states, tol, dt=1e-3):
    """Every output of ``impl`` against the reference; the message names the output."""
    n = ref.n
    worst: dict[str, float] = {}
    for k, (x, int_e, z) in enumerate(states):
        checks = {
            "gains P,D,I": (impl.gains(x[:n]), ref.gains(x[:n])),
            "mpc_step u": (impl.mpc_step(x)[1], ref.mpc_step(x)),
            "dobc_init z0": (impl.init("dobc", x)[1], ref.dobc_init(x)),
            "dobc_estimate dhat (eq. 22)": (impl.estimate(z, x)[1], ref.dhat(x, z)),
        }
        code, u, nxt = impl.step("npid", int_e, x, dt)
        ru, rn = ref.npid_step(int_e, x, dt)
        checks["npid_step u"], checks["npid_step int_e"] = (u, ru), (nxt, rn)
        code2, u, nxt = impl.step("dobc", z, x, dt)
        ru, rn = ref.dobc_step(z, x, dt)
        checks["dobc_step u"], checks["dobc_step z"] = (u, ru), (nxt, rn)
        assert code == 0 and code2 == 0
        for name, (got, want) in checks.items():
            err = _rel(got, want)
            worst[name] = max(worst.get(name, 0.0), err)
            assert err <= tol, f"{name} at state {k} ({x}): relative error {err:.3g} > {tol:.3g}"
    return worst


def _within_bounds(impl, ref, states, bounds: ApiBounds, real: str, dt=1e-3) -> float:
    """Every element of every output within its derived tolerance (derive.codegen.testvectors.tolerance:
    twice the first-order rounding bound + the rounding of the expected value); returns the largest
    error / tolerance."""
    n = ref.n
    xs = np.array([x for x, _, _ in states])
    ints, zs = np.array([s for _, s, _ in states]), np.array([z for _, _, z in states])
    npid, dobc = bounds.npid_step(ints, xs, dt), bounds.dobc_step(zs, xs, dt)
    limits = {"gains P,D,I": bounds.gains(xs[:, :n]), "mpc_step u": bounds.mpc_step(xs),
              "dobc_init z0": bounds.dobc_init(xs), "npid_step u": npid.u_bound, "npid_step int_e": npid.next_bound,
              "dobc_step u": dobc.u_bound, "dobc_step z": dobc.next_bound}
    worst = 0.0
    for k, (x, int_e, z) in enumerate(states):
        code, u, nxt = impl.step("npid", int_e, x, dt)
        code2, u2, nxt2 = impl.step("dobc", z, x, dt)
        assert code == 0 and code2 == 0
        ru, rn = ref.npid_step(int_e, x, dt)
        du, dn = ref.dobc_step(z, x, dt)
        checks = {"gains P,D,I": (impl.gains(x[:n]), ref.gains(x[:n])), "mpc_step u": (impl.mpc_step(x)[1],
                  ref.mpc_step(x)), "dobc_init z0": (impl.init("dobc", x)[1], ref.dobc_init(x)),
                  "npid_step u": (u, ru), "npid_step int_e": (nxt, rn), "dobc_step u": (u2, du), "dobc_step z": (nxt2, dn)}
        for name, (got, want) in checks.items():
            want = np.array([float(w) for w in want])
            tol = np.array(tv.tolerance(limits[name][k], want, real))
            err = np.abs(np.asarray(got, dtype=float) - want)
            assert np.all(err <= tol), f"{name} at state {k} ({x}): errors {err} > tolerances {tol}"
            worst = max(worst, float(np.max(err / np.maximum(tol, 1e-300))))
    return worst


class PyImpl:
    """The generated Python module behind the same small interface as CLib."""

    def __init__(self, path: Path):
        spec = importlib.util.spec_from_file_location(path.stem, path)
        self.m = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(self.m)
        self.n = self.m.N

    def _inp(self, x):
        n = self.n
        return self.m.Input(*(x[i * n:(i + 1) * n] for i in range(5)))

    def gains(self, theta):
        return np.concatenate([g.ravel() for g in self.m.gains(theta)])

    def mpc_step(self, x):
        code, u, self.clipped = self.m.mpc_step(self._inp(x))
        return code, u

    def estimate(self, values, x):
        state = self.m.DobcState()
        state.z = list(values)
        code, dhat = self.m.dobc_estimate(state, self._inp(x))
        assert list(state.z) == list(values)
        return code, dhat

    def init(self, form, x):
        state = self.m.NpidState() if form == "npid" else self.m.DobcState()
        code = getattr(self.m, f"{form}_init")(state, self._inp(x))
        return code, np.array(state.int_e if form == "npid" else state.z)

    def step(self, form, values, x, dt):
        state = self.m.NpidState() if form == "npid" else self.m.DobcState()
        setattr(state, "int_e" if form == "npid" else "z", list(values))
        code, u, self.clipped = getattr(self.m, f"{form}_step")(state, self._inp(x), dt)
        return code, u, np.array(state.int_e if form == "npid" else state.z)


def test_eq34_compiled_c_double_matches_sympy_at_200_states(tmp_path, paper_ref, states):
    """The README's 1e-12 holds, and every element is within its derived bound."""
    out = _generate(tmp_path)
    lib = CLib(out / "c", ARM, 2, "double", False, tmp_path)
    _compare(lib, paper_ref, states, tv.DOUBLE_TOL)
    _within_bounds(lib, paper_ref, states, ApiBounds(_derivation(), "double"), "double")


def test_eq34_python_module_matches_sympy_at_200_states(tmp_path, paper_ref, states):
    out = _generate(tmp_path)
    impl = PyImpl(out / "python" / f"{ARM}.py")
    _compare(impl, paper_ref, states, tv.DOUBLE_TOL)
    _within_bounds(impl, paper_ref, states, ApiBounds(_derivation(), "double"), "double")


def test_float_c_within_derived_bound(tmp_path, paper_ref, states):
    """Float results within the rounding bound derived for float at each state
    (inputs rounded to float too), which is also tight: errors reach a tenth of it."""
    out = _generate(tmp_path, "float")
    lib = CLib(out / "c", ARM, 2, "float", False, tmp_path)
    worst = _within_bounds(lib, paper_ref, states[:50], ApiBounds(_derivation(), "float", exact_inputs=False),
                           "float")
    assert worst > 0.01, worst  # a bound that means something, not one errors never approach
    errors = _compare(lib, paper_ref, states[:50], 1.0)
    assert max(errors.values()) > 1e-9  # really single precision, not double in disguise


def test_runtime_parameters_agree_with_baked_to_1e12(tmp_path, paper_ref, states):
    d = _derivation()
    baked = CLib(_generate(tmp_path) / "c", ARM, 2, "double", False, tmp_path)
    runtime = CLib(_generate(tmp_path, mode=ParamsMode.RUNTIME) / "c", ARM, 2, "double", True, tmp_path,
                   np_count=len(d.values))
    for x, int_e, z in states:
        for form, s in (("npid", int_e), ("dobc", z)):
            a, b = baked.step(form, s, x, 1e-3), runtime.step(form, s, x, 1e-3)
            assert _rel(b[1], a[1]) <= 1e-12 and _rel(b[2], a[2]) <= 1e-12, form
        assert _rel(runtime.gains(x[:2]), baked.gains(x[:2])) <= 1e-12


def test_runtime_parameters_really_change_the_law(tmp_path, states):
    d = _derivation()
    lib = CLib(_generate(tmp_path, mode=ParamsMode.RUNTIME) / "c", ARM, 2, "double", True, tmp_path,
               np_count=len(d.values))
    x = states[0][0]
    before = lib.mpc_step(x)[1]
    names = [str(s) for s, _ in d.values]
    lib.params[names.index("mp2")] *= 2  # a heavier tip
    assert _rel(lib.mpc_step(x)[1], before) > 1e-3


@pytest.mark.parametrize("cc", compilers())
@pytest.mark.parametrize("real,mode", [("double", "baked"), ("float", "baked"), ("double", "runtime"),
                                       ("float", "runtime")])
def test_selftest_compiles_strictly_and_passes(tmp_path, cc, real, mode):
    out = _generate(tmp_path, real, ParamsMode(mode)) / "c"
    exe = compile_c(cc, [out / f"{ARM}_selftest.c", *library_sources(out, ARM)], tmp_path / "st", ["-O2"])
    proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout
    assert re.search(r"^\d+ passed, 0 failed$", proc.stdout, re.M), proc.stdout


def test_committed_selftest_passes_under_address_and_undefined_sanitizers(tmp_path):
    c = ROOT / "generated" / ARM / "c"
    exe = compile_c("gcc", [c / f"{ARM}_selftest.c", *library_sources(c, ARM)], tmp_path / "st",
                    ["-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"])
    proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and "0 failed" in proc.stdout, proc.stdout + proc.stderr


def test_committed_selftest_passes_under_valgrind(tmp_path):
    c = ROOT / "generated" / ARM / "c"
    exe = compile_c("gcc", [c / f"{ARM}_selftest.c", *library_sources(c, ARM)], tmp_path / "st", ["-O0", "-g"])
    proc = subprocess.run(["valgrind", "--error-exitcode=3", "--leak-check=full", "--errors-for-leak-kinds=all",
                           str(exe)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "ERROR SUMMARY: 0 errors" in proc.stderr


def test_cmake_builds_the_static_library_and_runs_the_selftest(tmp_path):
    src = ROOT / "generated" / ARM / "c"
    build = tmp_path / "build"
    for cmd in (["cmake", "-S", str(src), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release"],
                ["cmake", "--build", str(build)], ["ctest", "--test-dir", str(build), "--output-on-failure"]):
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (build / f"lib{ARM}.a").is_file()


@pytest.mark.parametrize("real", ["double", "float"])
def test_library_objects_call_no_allocator_and_write_no_globals(tmp_path, real):
    out = _generate(tmp_path, real) / "c"
    allowed = {"sin", "cos", "sincos", "sinf", "cosf", "sincosf", "sqrt", "sqrtf"}  # libm only
    for src in library_sources(out, ARM):
        obj = compile_c("gcc", [src], tmp_path / (src.stem + ".o"), ["-O2", "-c"])
        undefined = subprocess.run(["nm", "-u", str(obj)], capture_output=True, text=True).stdout.split()
        names = {w for w in undefined if w not in ("U", "w")}
        names = {n for n in names if not n.startswith(f"{ARM}_")}
        assert names <= allowed, f"{src.name} calls {sorted(names - allowed)}"
        table = subprocess.run(["nm", str(obj)], capture_output=True, text=True).stdout
        writable = [line for line in table.splitlines() if re.search(r"\s[DdBbCG]\s", line)]
        assert not writable, f"{src.name} has writable data: {writable}"


def test_float_output_has_no_double_literal_or_double_libm_call(tmp_path):
    out = _generate(tmp_path, "float") / "c"
    literal = re.compile(r"(?<![\w.])(\d+\.\d*|\.\d+|\d+\.?\d*[eE][-+]?\d+)(?![\w.])(?!f)")
    call = re.compile(r"\b(sin|cos|tan|sqrt|fabs|pow|exp|log)\s*\(")
    for path in sorted(out.glob("*.[ch]")):
        text = re.sub(r"/\*.*?\*/", "", path.read_text(), flags=re.S)
        text = text.replace("(double)err, (double)tol", "")  # printf's own promotion, in the self-test
        assert not literal.findall(text), f"{path.name}: double literals {literal.findall(text)[:5]}"
        assert not call.findall(text), f"{path.name}: double libm calls {call.findall(text)[:5]}"
        assert "double" not in text, path.name


def test_double_output_really_is_double(tmp_path):
    out = _generate(tmp_path) / "c"
    text = (out / f"{ARM}_kernels.c").read_text()
    assert "cos(" in text and "cosf(" not in text


@pytest.mark.parametrize("impl", ["c", "python"])
def test_nonfinite_input_returns_error_and_leaves_state_untouched(tmp_path, states, impl):
    out = _generate(tmp_path)
    lib = CLib(out / "c", ARM, 2, "double", False, tmp_path) if impl == "c" else PyImpl(out / "python" / f"{ARM}.py")
    x, int_e, z = states[0]
    for bad in (float("nan"), float("inf"), -float("inf")):
        for i in range(10):
            xb = list(x)
            xb[i] = bad
            for form, s in (("npid", int_e), ("dobc", z)):
                code, _, nxt = lib.step(form, s, xb, 1e-3)
                assert code == 1 and list(nxt) == list(s), (form, i, bad)
            assert lib.mpc_step(xb)[0] == 1
            assert lib.init("dobc", xb)[0] == 1
            assert lib.estimate(z, xb)[0] == 1
        for dt in (0.0, -1e-3, bad):
            code, _, nxt = lib.step("npid", int_e, x, dt)
            assert code == 2 and list(nxt) == list(int_e)


# -- the clipped-joints mask (issue 15.4) ------------------------------------------------------------
def _mask(bits) -> int:
    return sum(1 << i for i, b in enumerate(bits) if b)


@pytest.mark.parametrize("impl", ["c", "python"])
def test_a_step_reports_the_joints_it_clipped_and_none_when_unclipped(tmp_path, paper_ref, states, impl):
    """Limits below / above the reference's unclipped u of each joint: the mask has exactly the
    joints whose limit is below (bit i for joint i + 1), u is at that limit, 0 when none is."""
    d = _derivation()
    out = _generate(tmp_path, mode=ParamsMode.RUNTIME)
    if impl == "c":
        lib = CLib(out / "c", ARM, 2, "double", True, tmp_path, np_count=len(d.values))
    else:
        spec = importlib.util.spec_from_file_location(f"{ARM}_rt", out / "python" / f"{ARM}.py")
        m = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(m)
        params = m.Params()
    x, int_e, z = states[0]
    raw = {"mpc": paper_ref.mpc(x), "npid": paper_ref.npid(x, int_e), "dobc": paper_ref.dobc(x, z)}
    for form, state in (("mpc", None), ("npid", int_e), ("dobc", z)):
        a = [abs(float(v)) for v in raw[form]]
        assert min(a) > 1e-3
        for scale in ((0.5, 2.0), (2.0, 0.5), (0.5, 0.5), (2.0, 2.0), (0.0, 0.0)):
            limits = [s * v for s, v in zip(scale, a)]
            want = _mask(0 < s < 1 for s in scale)
            if impl == "c":
                lib.params[len(d.values):len(d.values) + 2] = limits
                code, u = lib.mpc_step(x) if state is None else lib.step(form, state, x, 1e-3)[:2]
                clipped = lib.clipped
            else:
                params.u_max = limits
                inp = m.Input(*(x[i * 2:(i + 1) * 2] for i in range(5)))
                if state is None:
                    code, u, clipped = m.mpc_step(params, inp)
                else:
                    s = m.NpidState() if form == "npid" else m.DobcState()
                    setattr(s, "int_e" if form == "npid" else "z", list(state))
                    code, u, clipped = getattr(m, f"{form}_step")(params, s, inp, 1e-3)
            assert (code, clipped) == (0, want), (form, scale)
            for i in range(2):
                if want >> i & 1:
                    assert abs(u[i]) == limits[i], (form, scale, i)
    bad = [float("nan")] + list(x[1:])
    if impl == "c":
        assert lib.step("npid", int_e, bad, 1e-3)[0] == 1 and lib.clipped == 0xA5A50000   # untouched
    else:
        assert m.npid_step(params, m.NpidState(), m.Input(*(bad[i * 2:(i + 1) * 2] for i in range(5))), 1e-3) \
            == (1, None, None)


def test_my3_at_its_24_volt_limits_reports_the_clipped_joints(tmp_path):
    """The instance of the issue: the 3-link arm at rest, horizontal, 0.12 rad behind the
    reference in joint 1 asks 26.9, 23.7 and 21.4 V (the reference): joint 1 is clipped to
    its 24 V limit, the others are not; pointing up at the reference it asks for nothing."""
    import math

    from derive.codegen.files import python_files

    d = derive.derive(derive.load_arm(ROOT / "tests" / "data" / "my3.toml"))
    files = python_files(d, ParamsMode.BAKED)
    write_tree(tmp_path / "my3", files | {"MANIFEST.json": json.dumps({"files": sorted(files)})})
    spec = importlib.util.spec_from_file_location("my3_clip", tmp_path / "my3" / "python" / "my3.py")
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    ref = Reference(d)
    behind = [0.0] * 3 + [0.0] * 3 + [0.12, 0.0, 0.0] + [0.0] * 6
    raw = [float(v) for v in ref.npid(behind, [0, 0, 0])]
    assert 24 < raw[0] and max(raw[1:]) < 24 and _mask(ref.saturate(raw)[1]) == 0b001
    code, u, clipped = m.npid_step(m.NpidState(), m.Input(*(behind[i * 3:(i + 1) * 3] for i in range(5))), 1e-3)
    assert (code, clipped) == (0, 0b001) and u[0] == 24.0 and _rel(u[1:], raw[1:]) < 1e-12
    up = [math.pi / 2, 0.0, 0.0] + [0.0] * 3 + [math.pi / 2, 0.0, 0.0] + [0.0] * 6
    code, u, clipped = m.npid_step(m.NpidState(), m.Input(*(up[i * 3:(i + 1) * 3] for i in range(5))), 1e-3)
    assert (code, clipped) == (0, 0) and max(abs(u)) < 1e-9


def test_the_mask_type_holds_one_bit_per_joint():
    from derive.codegen.views import mask_type
    from derive.errors import SpecError

    assert (mask_type(2), mask_type(32), mask_type(33), mask_type(64)) == (
        "unsigned long", "unsigned long", "unsigned long long", "unsigned long long")
    with pytest.raises(SpecError, match=r"link: expected at most 64 links \(one bit each in the clipped-joints "
                                        r"mask\), got 65 links"):
        mask_type(65, "big.toml")
