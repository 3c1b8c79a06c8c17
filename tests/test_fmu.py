"""The controller as an FMU (issue 14): validated by fmpy, simulated by fmpy
against the generated Python module, error handling of the C API, sources that
compile on their own, deterministic archives, bad options.

Each FMU variant is built once per session (fixture ``fmus``); simulations are
short (100 samples)."""
from __future__ import annotations

import hashlib
import importlib.util
import math
import re
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from derive import jsonio
import derive
from derive.cli import main
from derive.codegen import testvectors as tv
from derive.codegen.files import python_files
from derive.codegen.forms import FORMS
from derive.codegen.kernels import ParamsMode
from derive.codegen.views import arm_view
from derive.errors import DeriveError, EmitError
from derive.fmu import FmuOptions, check_options, controller_fmu, write_fmus
from derive.fmu.units import fmi_unit

from .cbuild import STRICT, compilers

ROOT = Path(__file__).resolve().parent.parent
STEPS = 100
DT = 0.002
# (FMI version, real, form, params): every version x real, every form, both parameter modes
VARIANTS = [(3, "double", "npid", "runtime"), (3, "float", "dobc", "baked"), (2, "double", "dobc", "runtime"),
            (2, "float", "npid", "baked"), (3, "double", "mpc", "runtime"), (3, "double", "dobc", "runtime")]
MOM = (3, "double", "mom", "runtime")   # the generalized-momentum observer (issue 12 item 6)


def _id(v) -> str:
    return "fmi{}-{}-{}-{}".format(*v)


@pytest.fixture(scope="session")
def paper():
    return derive.derive(derive.load_arm())


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fmus")


_BUILT: dict = {}


def _fmu(paper, fmu_dir, variant) -> Path:
    """Build ``variant`` once per session; the path of its .fmu."""
    if variant not in _BUILT:
        fmi, real, form, params = variant
        name, data = controller_fmu(paper, FmuOptions(fmi, form, real, ParamsMode(params)))
        path = fmu_dir / _id(variant) / name
        path.parent.mkdir()
        path.write_bytes(data)
        _BUILT[variant] = path
    return _BUILT[variant]


def _plant(paper, fmu_dir, fmi: int) -> Path:
    """The plant FMU of FMI ``fmi``, built once per session."""
    from derive.fmu import plant_fmu

    if ("plant", fmi) not in _BUILT:
        name, data = plant_fmu(paper, fmi)
        path = fmu_dir / f"plant{fmi}" / name
        path.parent.mkdir()
        path.write_bytes(data)
        _BUILT["plant", fmi] = path
    return _BUILT["plant", fmi]


@pytest.fixture(scope="session")
def module(tmp_path_factory, paper):
    """The generated Python module (double, runtime parameters): the reference."""
    folder = tmp_path_factory.mktemp("py")
    path = folder / "paper_runtime.py"
    path.write_text(python_files(paper, ParamsMode.RUNTIME)[f"python/{paper.arm.name}.py"])
    spec = importlib.util.spec_from_file_location("paper_runtime", path)
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def _inputs(n: int, steps: int, seed: int = 14) -> np.ndarray:
    """steps x 5n inputs (theta, theta', yd, yd', yd'') as the codegen tests draw them."""
    rng = np.random.default_rng(seed)
    return np.hstack([rng.uniform(-3, 3, (steps, 3 * n)), rng.uniform(-2, 2, (steps, n)),
                      rng.uniform(-5, 5, (steps, n))])


def _reference(m, form: str, X: np.ndarray, dt: float, params=None):
    """u, dhat (None for forms without an estimate) and the clipped-joints masks
    (None where the API reports none) of the Python module along X."""
    n = m.N
    p = params or m.Params()
    s = {"npid": m.NpidState, "dobc": m.DobcState, "mom": m.MomState}.get(form)
    s = s() if s else None
    us, dhats, masks = [], [], []
    for k, x in enumerate(X):
        inp = m.Input(*(list(x[i * n:(i + 1) * n]) for i in range(5)))
        if s is None:
            code, u, *clipped = m.mpc_step(p, inp)
        else:
            if k == 0:
                assert getattr(m, f"{form}_init")(p, s, inp) == 0
            if FORMS[form].estimate:
                code, dhat = getattr(m, f"{form}_estimate")(p, s, inp)
                assert code == 0
                dhats.append(dhat)
            code, u, *clipped = getattr(m, f"{form}_step")(p, s, inp, dt)
        assert code == 0
        us.append(u)
        masks.append(clipped[0] if clipped else None)
    return np.array(us), (np.array(dhats) if dhats else None), masks


def _signal(md, X: np.ndarray, dt: float) -> np.ndarray:
    names = [v.name for v in md.modelVariables if v.causality == "input"]
    rows = [tuple([k * dt, *X[min(k, len(X) - 1)]]) for k in range(len(X) + 1)]
    return np.array(rows, dtype=[("time", float)] + [(name, float) for name in names])


@pytest.mark.parametrize("variant", VARIANTS[:4] + [MOM], ids=_id)
def test_fmpy_validates_the_fmu(paper, fmu_dir, variant):
    path = _fmu(paper, fmu_dir, variant)
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    assert md.fmiVersion == f"{variant[0]}.0"
    names = {v.name: v for v in md.modelVariables}
    assert {f"{p}[{i}]" for p in ("theta", "dtheta", "yd", "dyd", "ddyd") for i in (1, 2)} <= set(names)
    assert names["u[1]"].causality == "output" and names["u[1]"].unit == "V"
    assert ("dhat[1]" in names) == FORMS[variant[2]].estimate
    assert FORMS[variant[2]].estimate_law in names["dhat[1]"].description if "dhat[1]" in names else True
    assert names["m1"].unit == "kg" and names["m1"].start == "0.361"
    assert names["m1"].causality == ("parameter" if variant[3] == "runtime" else "local")
    assert float(md.defaultExperiment.stepSize) == paper.arm.simulation.sample_time
    if variant[0] == 3:
        real = "Float32" if variant[1] == "float" else "Float64"
        assert names["u[1]"].type == real and names["time"].causality == "independent"


@pytest.mark.parametrize("variant", VARIANTS[:4] + [MOM], ids=_id)
def test_fmu_simulated_by_fmpy_equals_the_generated_python_module(paper, fmu_dir, module, variant):
    """Same inputs, 100 samples: double to 1e-12, float within the stated bound
    16 (K + steps) 2^-24 for the form's K kernel operations (derive.codegen.testvectors).
    A tunable parameter set through FMI is the module's parameter."""
    fmi, real, form, params = variant
    path = _fmu(paper, fmu_dir, variant)
    md = read_model_description(str(path))
    X = _inputs(paper.n, STEPS)
    start = {"Kt1": 0.25, "u_max[2]": 30.0} if params == "runtime" else {}
    p = module.Params()
    p.Kt1, p.u_max = start.get("Kt1", p.Kt1), [p.u_max[0], start.get("u_max[2]", p.u_max[1])]
    outputs = ["u[1]", "u[2]"] + (["dhat[1]", "dhat[2]"] if FORMS[form].estimate else [])
    flags = [f"clipped[{i}]" for i in (1, 2) if f"clipped[{i}]" in {v.name for v in md.modelVariables}]
    res = simulate_fmu(str(path), start_time=0.0, stop_time=STEPS * DT, output_interval=DT,
                       input=_signal(md, X, DT), output=outputs + flags, start_values=start,
                       fmi_type="CoSimulation")
    u_ref, dhat_ref, masks = _reference(module, form, X, DT, p)
    if masks[0] is not None:  # the API reports the clipped joints (issue 15 item 4): so does the FMU
        clipped = np.column_stack([res["clipped[1]"], res["clipped[2]"]])[1:]
        assert [int(a) + 2 * int(b) for a, b in clipped] == masks  # the API's mask, joint by joint
        if params == "runtime":
            assert clipped[:, 1].any() and not clipped[:, 0].any()  # u_max[2] = 30 V set through FMI
    # row k + 1 holds what the step at t_k computed (held over [t_k, t_k+1]); row 0 the start value 0
    got = np.column_stack([res[name] for name in outputs])
    assert np.all(got[0] == 0)
    want = u_ref if dhat_ref is None else np.hstack([u_ref, dhat_ref])
    if real == "double":
        bound = tv.DOUBLE_TOL
    else:
        ops = {k.name: k.operations for k in arm_view(paper, "float", ParamsMode(params)).kernels}
        kernels = {"npid": ("npid",), "dobc": ("dobc", "observer", "dhat"), "mpc": ("mpc",),
                   "mom": ("mom", "mom_next")}[form]
        bound = tv.float_bound(sum(ops[k] for k in kernels), STEPS)
    for k in range(STEPS):
        for cols, name in ((slice(0, 2), "u"), (slice(2, 4), "dhat")):
            w = want[k, cols]
            if w.size == 0:
                continue
            err = np.max(np.abs(got[k + 1, cols] - w)) / max(np.max(np.abs(w)), 1e-300)
            assert err <= bound, f"{_id(variant)}: {name} at step {k}: relative error {err:.3g} > {bound:.3g}"


@pytest.mark.parametrize("fmi", [3, 2])
def test_nonfinite_input_gives_an_error_status_and_leaves_state_and_outputs_unchanged(paper, fmu_dir, module,
                                                                                       fmi, tmp_path):
    variant = (fmi, "double", "dobc", "runtime")
    path = _fmu(paper, fmu_dir, variant)
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    inputs = [vr[f"{p}[{i}]"] for p in ("theta", "dtheta", "yd", "dyd", "ddyd") for i in (1, 2)]
    outputs = [vr[name] for name in ("u[1]", "u[2]", "dhat[1]", "dhat[2]")]
    folder = tmp_path / "unzipped"
    with zipfile.ZipFile(path) as z:
        z.extractall(folder)
    kind = FMU3Slave if fmi == 3 else FMU2Slave
    fmu = kind(guid=md.guid, unzipDirectory=str(folder),
               modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bad")
    set_real = fmu.setFloat64 if fmi == 3 else fmu.setReal
    get_real = fmu.getFloat64 if fmi == 3 else fmu.getReal
    fmu.instantiate()
    if fmi == 3:
        fmu.enterInitializationMode(startTime=0.0)
    else:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    X = _inputs(paper.n, 3, seed=7)
    u_ref, dhat_ref, _ = _reference(module, "dobc", X, DT)
    set_real(inputs, list(X[0]))
    fmu.doStep(0.0, DT)
    before = get_real(outputs)
    for bad in (math.nan, math.inf):
        for i in range(len(inputs)):
            x = list(X[1])
            x[i] = bad
            set_real(inputs, x)
            with pytest.raises(Exception, match="fmi[23]DoStep|status|Error|error"):
                fmu.doStep(DT, DT)
            after = get_real(outputs)
            assert after == before and all(map(math.isfinite, after)), (bad, i)
    with pytest.raises(Exception):  # a step size that is no sample time
        fmu.doStep(DT, 0.0)
    set_real(inputs, list(X[1]))
    fmu.doStep(DT, DT)  # the state was left as it was: the reference's second step
    got = get_real(outputs)
    np.testing.assert_allclose(got, list(u_ref[1]) + list(dhat_ref[1]), rtol=1e-12, atol=1e-12)
    with pytest.raises(Exception):  # a parameter refuses a non-finite value
        set_real([vr["m1"]], [math.nan])
    fmu.terminate()
    fmu.freeInstance()


def test_wrong_instantiation_token_is_refused(paper, fmu_dir, tmp_path):
    path = _fmu(paper, fmu_dir, VARIANTS[0])
    md = read_model_description(str(path))
    with zipfile.ZipFile(path) as z:
        z.extractall(tmp_path)
    fmu = FMU3Slave(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=str(tmp_path), modelIdentifier=md.coSimulation.modelIdentifier, instanceName="x")
    with pytest.raises(Exception, match="[Ff]ailed to instantiate"):
        fmu.instantiate()
    fmu.freeLibrary()


@pytest.mark.parametrize("cc", compilers())
@pytest.mark.parametrize("variant", [VARIANTS[1], VARIANTS[2], "plant2"], ids=lambda v: v if isinstance(v, str)
                         else _id(v))
def test_fmu_sources_compile_on_their_own_with_the_strict_flags(paper, fmu_dir, variant, cc, tmp_path):
    path = _plant(paper, fmu_dir, 2) if variant == "plant2" else _fmu(paper, fmu_dir, variant)
    with zipfile.ZipFile(path) as z:
        z.extractall(tmp_path)
    src = tmp_path / "sources"
    if (src / "buildDescription.xml").exists():
        listed = re.findall(r'<SourceFile name="([^"]+)"', (src / "buildDescription.xml").read_text())
    else:
        listed = re.findall(r'<File name="([^"]+)"', (tmp_path / "modelDescription.xml").read_text())
    assert sorted(listed) == sorted(p.name for p in src.glob("*.c"))
    cmd = [cc, *STRICT, "-shared", "-fPIC", "-o", str(tmp_path / "own.so"), *listed, "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=src)
    assert proc.returncode == 0, proc.stderr


def test_same_input_gives_the_same_bytes_and_the_token_follows_the_content(paper, fmu_dir):
    variant = VARIANTS[0]
    first = _fmu(paper, fmu_dir, variant).read_bytes()
    name, again = controller_fmu(paper, FmuOptions(3, "npid", "double", ParamsMode.RUNTIME))
    assert again == first
    with zipfile.ZipFile(_fmu(paper, fmu_dir, variant)) as z:
        infos = z.infolist()
        assert [i.filename for i in infos] == sorted(i.filename for i in infos)
        assert {i.date_time for i in infos} == {(1980, 1, 1, 0, 0, 0)}
        manifest = jsonio.loads(z.read("documentation/MANIFEST.json"))
        for entry, digest in manifest["files"].items():
            assert hashlib.sha256(z.read(entry)).hexdigest() == digest, entry
        assert manifest["options"] == {"fmi": 3, "form": "npid", "real": "double", "params": "runtime",
                                       "sample_time": None}
        assert "binaries/x86_64-linux/glasgow_2link_npid.so" in manifest["files"]
    tokens = {read_model_description(str(_fmu(paper, fmu_dir, v))).instantiationToken for v in VARIANTS[:2]}
    assert len(tokens) == 2 and all(re.fullmatch(r"\{[0-9a-f]{8}(-[0-9a-f]{4}){3}-[0-9a-f]{12}\}", t)
                                    for t in tokens)


def test_fmi_headers_are_the_ones_the_readme_names():
    folder = ROOT / "derive" / "fmu" / "headers"
    table = dict(re.findall(r"\| `(fmi\d/\w+\.h)` \| [^|]+ \| `([0-9a-f]{64})` \|", (folder / "README.md").read_text()))
    assert len(table) == 6
    for rel, digest in table.items():
        assert hashlib.sha256((folder / rel).read_bytes()).hexdigest() == digest, rel
    assert "BSD" in (folder / "LICENSE.txt").read_text()


def test_units_are_fmi_units_with_their_si_base():
    assert fmi_unit("kg m^2").name == "kg.m2" and dict(fmi_unit("kg m^2").base) == {"kg": 1, "m": 2}
    assert dict(fmi_unit("N m s/rad").base) == {"kg": 1, "m": 2, "s": -1, "rad": -1}
    assert fmi_unit("V s/rad").name == "V.s/rad" and fmi_unit("1/s").name == "1/s"
    assert fmi_unit("") is None
    odd = fmi_unit("furlong")
    assert odd.name == "furlong" and odd.base == () and not odd.known


# --- bad input: one clear error, exit 2, nothing written ---------------------------------------

@pytest.mark.parametrize("option, value, message", [
    ("--form", "pid", r"--form: expected one of npid, dobc, mpc, mom, got 'pid'"),
    ("--fmi", "4", r"--fmi: expected 2 or 3, got '4'"),
    ("--real", "half", r"--real: expected one of double, float, got 'half'"),
    ("--params", "lazy", r"--params: expected one of baked, runtime, got 'lazy'"),
    ("--sample-time", "-0.001", r"--sample-time: expected a finite number of seconds > 0, got -0.001"),
])
def test_bad_option_is_one_clear_error_exit_2_nothing_written(option, value, message, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["fmu", option, value, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err) and err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()
    with pytest.raises(DeriveError, match=message):
        check_options(**{"fmi": 3, "form": "npid", "real": "double", "params": "baked",
                         option[2:].replace("-", "_"): float(value) if option == "--sample-time" else value})


def test_output_folder_that_is_a_file_is_one_clear_error(tmp_path, capsys):
    out = tmp_path / "taken"
    out.write_text("mine")
    assert main(["fmu", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--out {out}: expected a folder, got a file" in err and err.count("\n") == 1
    assert out.read_text() == "mine" and sorted(p.name for p in tmp_path.iterdir()) == ["taken"]
    with pytest.raises(EmitError, match="expected a folder, got a file"):
        write_fmus(out, {"x.fmu": b"data"})
    (tmp_path / "dir" / "x.fmu").mkdir(parents=True)
    with pytest.raises(EmitError, match="expected x.fmu to be a file or absent, got a folder"):
        write_fmus(tmp_path / "dir", {"x.fmu": b"data"})


def test_missing_compiler_is_one_clear_error(paper):
    with pytest.raises(DeriveError, match="--cc: expected a C compiler on PATH, got 'no-such-cc'"):
        controller_fmu(paper, FmuOptions(), cc="no-such-cc")


def test_cli_writes_the_controller_and_plant_fmus(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["fmu", "--form", "mpc", "--fmi", "2", "--plant", "--out", str(out)]) == 0
    assert capsys.readouterr().err.count("derive: wrote") == 2
    assert sorted(p.name for p in out.iterdir()) == ["glasgow_2link_mpc.fmu", "glasgow_2link_plant.fmu"]
    for path in out.iterdir():
        assert validate_fmu(str(path)) == [], path.name
    md = read_model_description(str(out / "glasgow_2link_plant.fmu"))
    names = {v.name: v for v in md.modelVariables}
    assert names["u[1]"].causality == "input" and names["theta[1]"].causality == "output"
    assert names["coulomb[1]"].unit == "N.m" and float(names["coulomb[1]"].start) == 0.05
    assert float(names["mp2"].start) == pytest.approx(0.12)  # the tip mass times payload_scale 1.2


# --- closing the loop: controller FMUs and the plant FMU in fmpy ------------------------------

def _slave(path: Path, folder: Path, name: str):
    """An instantiated, initialised co-simulation instance of ``path`` and its value references."""
    md = read_model_description(str(path))
    with zipfile.ZipFile(path) as z:
        z.extractall(folder)
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=str(folder), modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=name)
    fmu.instantiate()
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    return fmu, {v.name: v.valueReference for v in md.modelVariables}


def test_controller_and_plant_fmus_reproduce_derive_simulate_default_metrics(paper, fmu_dir, tmp_path):
    """The paper's experiment (30 s, MPC, DOBC and NPID) closed in fmpy: the plant
    FMU's outputs wired to the controller FMU's inputs of the same name, u back;
    controller then plant at each communication step (as derive simulate orders a
    sample). Every metric of generated/glasgow_2link/sim/metrics.json (written by
    derive simulate, make generate) within 1e-6 relative (1e-9 absolute for zeros)."""
    from derive.sim.simulate import Trace, metrics

    committed = jsonio.loads((ROOT / "generated" / "glasgow_2link" / "sim" / "metrics.json").read_text())
    s = paper.arm.simulation
    plant_path = _plant(paper, fmu_dir, 3)
    assert validate_fmu(str(plant_path)) == []
    n, steps, dt = paper.n, int(round(s.duration / s.sample_time)), s.sample_time
    signals = [f"{p}[{i + 1}]" for p in ("theta", "dtheta", "yd", "dyd", "ddyd") for i in range(n)]
    for form in ("mpc", "dobc", "npid"):
        ctl, cvr = _slave(_fmu(paper, fmu_dir, (3, "double", form, "runtime")), tmp_path / form, form)
        plant, pvr = _slave(plant_path, tmp_path / f"plant_{form}", "plant")
        c_in, p_out = [cvr[k] for k in signals], [pvr[k] for k in signals]
        c_u, p_u = [cvr[f"u[{i + 1}]"] for i in range(n)], [pvr[f"u[{i + 1}]"] for i in range(n)]
        X, U = np.zeros((steps, 5 * n)), np.zeros((steps, n))
        for k in range(steps):
            t = k * dt
            X[k] = plant.getFloat64(p_out)
            ctl.setFloat64(c_in, list(X[k]))
            ctl.doStep(t, dt)
            U[k] = ctl.getFloat64(c_u)
            plant.setFloat64(p_u, list(U[k]))
            plant.doStep(t, dt)
        for fmu in (ctl, plant):
            fmu.terminate()
            fmu.freeInstance()
        trace = Trace(form, np.arange(steps) * dt, X[:, :n], X[:, n:2 * n], X[:, 2 * n:3 * n], U, None,
                      np.zeros((steps, n), dtype=bool))
        for i, (got, want) in enumerate(zip(metrics(trace, s), committed["controllers"][form]["links"])):
            for key, value in want.items():
                assert got[key] == pytest.approx(value, rel=1e-6, abs=1e-9), (form, i + 1, key, got[key], value)


def test_plant_fmu_refuses_a_nonfinite_voltage_and_keeps_its_state(paper, fmu_dir, tmp_path):
    plant, vr = _slave(_plant(paper, fmu_dir, 3), tmp_path, "plant")
    u = [vr["u[1]"], vr["u[2]"]]
    out = [vr[f"{p}[{i}]"] for p in ("theta", "dtheta", "yd", "dyd", "ddyd") for i in (1, 2)]
    plant.setFloat64(u, [1.0, -1.0])
    plant.doStep(0.0, DT)
    before = plant.getFloat64(out)
    assert before[2] > 0 and before[3] < 0  # the voltages moved the joints
    plant.setFloat64(u, [math.nan, 0.0])
    with pytest.raises(Exception):
        plant.doStep(DT, DT)
    assert plant.getFloat64(out) == before
    plant.terminate()
    plant.freeInstance()


def test_unknown_platform_and_failing_compiler_are_one_clear_error_each(paper, monkeypatch, tmp_path):
    import platform as host

    with pytest.raises(DeriveError, match="compiling the FMU's sources with false failed"):
        controller_fmu(paper, FmuOptions(form="mpc"), cc="false")
    monkeypatch.setattr(host, "machine", lambda: "aarch64")
    with pytest.raises(DeriveError, match="--fmi 2: FMI 2.0 names no binary folder for aarch64; use --fmi 3"):
        controller_fmu(paper, FmuOptions(fmi=2, form="mpc"))
    monkeypatch.setattr(host, "machine", lambda: "sparc64")
    with pytest.raises(DeriveError, match=r"binary FMU: expected a platform of .*linux/x86_64.*, got linux/sparc64"):
        controller_fmu(paper, FmuOptions(form="mpc"))
    (tmp_path / "file").write_text("")
    with pytest.raises(EmitError, match="cannot create the folder"):
        write_fmus(tmp_path / "file" / "sub", {"x.fmu": b""})


def test_default_step_is_the_arm_sample_time_unless_overridden(paper):
    from derive.fmu.package import controller_sources

    for override, want in ((None, paper.arm.simulation.sample_time), (0.001, 0.001)):
        _, _, top = controller_sources(paper, FmuOptions(form="mpc", sample_time=override), "derive test")
        step = re.search(r'stepSize="([^"]+)"', top["modelDescription.xml"]).group(1)
        assert float(step) == want


def test_plant_fmu_applies_every_mismatch_of_the_simulation_section(tmp_path):
    """The plant FMU is derive simulate's true plant (derive.sim.plant.true_plant): link
    masses, motor constants and payload all scaled, not only the payload."""
    from dataclasses import replace

    from derive.fmu import plant_fmu
    from derive.sim.plant import true_plant

    arm = derive.load_arm()
    s = replace(arm.simulation, link_mass_scale=(1.25, 0.5), torque_constant_scale=(0.9, 1.1),
                voltage_constant_scale=(1.05, 0.95), resistance_scale=(1.5, 0.75), payload_scale=1.4)
    d = derive.derive(replace(arm, simulation=s))
    name, data = plant_fmu(d, 3)
    path = tmp_path / name
    path.write_bytes(data)
    assert validate_fmu(str(path)) == []
    starts = {v.name: float(v.start) for v in read_model_description(str(path)).modelVariables
              if v.causality == "parameter"}
    want = dict(zip((str(sym) for sym, _ in d.values), true_plant(d, s).values))
    for key, factor in (("m1", 1.25), ("m2", 0.5), ("Kt1", 0.9), ("Kt2", 1.1), ("Kv1", 1.05), ("Ra1", 1.5),
                        ("Ra2", 0.75), ("mp2", 1.4)):
        arm_value = float(dict(d.values)[next(sym for sym, _ in d.values if str(sym) == key)])
        assert starts[key] == want[key] == pytest.approx(arm_value * factor, rel=1e-15), key
    assert "T1" not in starts and "w1" not in starts   # controller parameters are not the plant's


def test_implicit_observer_dobc_fmu_equals_the_implicit_python_module(paper, tmp_path):
    """derive fmu --observer implicit (issue 20 item 7): the DOBC FMU runs dobc_init with its step
    (dhat(0) with W_dt) and the backward-Euler step, as the implicit Python module does (1e-12);
    its dhat output is the estimate each step applied (read after the step, which moves z first)."""
    from derive.codegen.emit import write_tree
    from derive.codegen.files import generate_files

    name, data = controller_fmu(paper, FmuOptions(3, "dobc", "double", ParamsMode.RUNTIME, observer="implicit"))
    path = tmp_path / name
    path.write_bytes(data)
    md = read_model_description(str(path))
    assert validate_fmu(str(path)) == [] and "implicit (backward-Euler) observer step" in md.description
    write_tree(tmp_path / "py", generate_files(paper, None, "double", ParamsMode.RUNTIME, observer="implicit"))
    spec = importlib.util.spec_from_file_location("implicit_fmu_ref", tmp_path / "py" / "python" /
                                                  f"{paper.arm.name}.py")
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    X = _inputs(paper.n, 40)
    res = simulate_fmu(str(path), start_time=0.0, stop_time=40 * DT, output_interval=DT, input=_signal(md, X, DT),
                       output=["u[1]", "u[2]", "dhat[1]", "dhat[2]"], fmi_type="CoSimulation")
    p, s, want = m.Params(), m.DobcState(), []
    for k, x in enumerate(X):
        inp = m.Input(*(list(x[i * 2:(i + 1) * 2]) for i in range(5)))
        if k == 0:
            assert m.dobc_init(p, s, inp, DT) == m.OK
        code, u, _ = m.dobc_step(p, s, inp, DT)
        want.append([*u, *m.dobc_estimate(p, s, inp)[1]])
    got = np.column_stack([res[k] for k in ("u[1]", "u[2]", "dhat[1]", "dhat[2]")])[1:]
    np.testing.assert_allclose(got, np.array(want), rtol=1e-12, atol=1e-12 * np.max(np.abs(want)))
    with pytest.raises(DeriveError, match=r"--observer: expected one of explicit, implicit, got 'trapezoid'"):
        check_options(3, "dobc", "double", "runtime", None, "trapezoid")


def test_plant_fmu_starts_the_reference_at_the_pose_when_the_arm_file_says_so(tmp_path):
    """[simulation] reference_start = "measured": the plant FMU's y_d starts at C theta0 (its
    tunable yd0) and the pulse train adds to it, as derive simulate's reference does."""
    from derive.fmu import plant_fmu
    from derive.model.spec import resolve_arm_path

    text = resolve_arm_path(None).read_text() + '\n[simulation]\ninitial_theta = [0.3, -0.2]\nreference_start = ' \
                                                '"measured"\nduration = 2.0\n'
    (tmp_path / "arm.toml").write_text(text)
    d = derive.derive(derive.load_arm(tmp_path / "arm.toml"))
    name, data = plant_fmu(d, 3)
    path = tmp_path / name
    path.write_bytes(data)
    plant, vr = _slave(path, tmp_path / "plant", "plant")
    yd = [vr["yd[1]"], vr["yd[2]"]]
    assert plant.getFloat64(yd) == [0.3, -0.2] and plant.getFloat64([vr["yd0[1]"], vr["yd0[2]"]]) == [0.3, -0.2]
    for k in range(500):   # u = 0: the reference alone, 1 s
        plant.doStep(k * DT, DT)
    got = plant.getFloat64(yd)
    plant.terminate()
    plant.freeInstance()
    from derive.sim.simulate import pulses
    s = d.arm.simulation
    r = pulses(s, 2, 500)  # the zero-start reference by the same RK4 steps, offset by the pose
    f = np.zeros(4)
    h = DT / s.substeps
    for k in range(500):
        for _ in range(s.substeps):
            def deriv(f):
                return np.concatenate([f[2:], r[k] - 1.8 * f[2:] - f[:2]])
            k1 = deriv(f)
            k2 = deriv(f + h / 2 * k1)
            k3 = deriv(f + h / 2 * k2)
            k4 = deriv(f + h * k3)
            f = f + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    np.testing.assert_allclose(np.array(got) - [0.3, -0.2], f[:2], atol=1e-12)
