"""The arm file's rules on the FMU's tunable parameters (issue 34 item 10, the case fmu_tunables).

A value the arm-file validator refuses is refused by the FMU: a parameter's own range at the set
call (fmi2SetReal / fmi3SetFloat64 return an error, logged, and the value is kept), a rule on
several parameters (T1 < T2, a full W's determinant, a body's pseudo-inertia) at the next step
or at exitInitializationMode; min="0" in the model description where a range exists. The rules
are derive.model.rules, the validator's own (derive.fmu.rules prints them)."""
from __future__ import annotations

import copy
import shutil
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

import derive
from derive.codegen.kernels import ParamsMode
from derive.errors import SpecError
from derive.fmu import FmuOptions, controller_fmu, plant_fmu
from derive.fmu.rules import rule_function
from derive.model.chain import Parameter
from derive.model.rules import all_rules, division_free_det, physical
from derive.model.spec import T1_SYMBOL, T2_SYMBOL, arm_from_dict
from derive.paths import packaged_arms

ROOT = Path(__file__).resolve().parent.parent
DT = 1e-3


_BUILT: dict = {}


def _build(tmp_path: Path, arm: str, fmi: int, form: str, plant: bool = False) -> Path:
    """The runtime-parameter FMU (the plant's with ``plant``), built once per session."""
    key = (arm, fmi, form, plant)
    if key not in _BUILT:
        d = derive.derive(derive.load_arm(arm))
        name, data = plant_fmu(d, fmi) if plant else controller_fmu(d, FmuOptions(fmi, form, "double",
                                                                                  ParamsMode.RUNTIME))
        path = tmp_path / name
        path.write_bytes(data)
        _BUILT[key] = path
    return _BUILT[key]


class Instance:
    """An fmpy slave of ``path`` in step mode: set(name, value) -> None or the error, step() likewise."""

    def __init__(self, path: Path, folder: Path) -> None:
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        with zipfile.ZipFile(path) as z:
            z.extractall(folder)
        self.folder = folder
        fmi3 = self.md.fmiVersion.startswith("3")
        self.fmu = (FMU3Slave if fmi3 else FMU2Slave)(guid=self.md.guid, unzipDirectory=str(folder),
                                                      modelIdentifier=self.md.coSimulation.modelIdentifier,
                                                      instanceName="rules")
        self.fmu.instantiate()
        if fmi3:
            self.fmu.enterInitializationMode(startTime=0.0)
        else:
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()
        self._set, self.get = (self.fmu.setFloat64, self.fmu.getFloat64) if fmi3 else (self.fmu.setReal,
                                                                                         self.fmu.getReal)
        self.k = 0

    def set(self, name: str, value: float) -> Exception | None:
        try:
            self._set([self.vr[name]], [value])
        except Exception as exc:  # noqa: BLE001 - fmpy raises a plain Exception for an error status
            return exc
        return None

    def exit_init(self) -> Exception | None:
        try:
            self.fmu.exitInitializationMode()
        except Exception as exc:  # noqa: BLE001
            return exc
        return None

    def step(self) -> Exception | None:
        try:
            self.fmu.doStep(currentCommunicationPoint=self.k * DT, communicationStepSize=DT)
        except Exception as exc:  # noqa: BLE001
            return exc
        self.k += 1
        return None

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.folder, ignore_errors=True)


def _inputs(m: Instance, k: int) -> None:
    t = k * DT
    for key, val in dict(theta=[0.1 + 0.2 * np.sin(3 * t), -0.2], dtheta=[0.6 * np.cos(3 * t), 0.1],
                         yd=[0.3, 0.1], dyd=[0, 0], ddyd=[0, 0]).items():
        for i, x in enumerate(val):
            assert m.set(f"{key}[{i + 1}]", float(x)) is None


@pytest.mark.parametrize("fmi, form", [(2, "npid"), (3, "dobc")])
def test_the_case_fmu_tunables_is_refused_and_the_model_keeps_its_values(tmp_path, capsys, fmi, form):
    """set_invalid.py: T1 > T2, w1 = 0, m2 = -5, T2 = 0 at sample 100 of vertical_2link (FMI 2 NPID,
    FMI 3 DOBC, --params runtime). Each single value: the set call's error, logged with the range;
    T1 = 0.6 > T2 = 0.5: the next step's error, logged with the rule and the values. After a refused
    set the FMU steps on with the values it had: u as without the set; after T1 = 0.6, setting T1
    back lets it step again."""
    path = _build(tmp_path, "vertical_2link", fmi, form)
    assert validate_fmu(str(path)) == []

    def run(changes: dict, steps: int = 120) -> tuple[list, list]:
        m = Instance(path, tmp_path / f"x{len(changes)}{sorted(changes)}")
        _inputs(m, 0)
        assert m.exit_init() is None
        log, u = [], None
        for k in range(steps):
            for name, val in changes.get(k, {}).items():
                log.append((name, m.set(name, val)))
            _inputs(m, k)
            log.append(("step", m.step()))
            u = m.get([m.vr["u[1]"], m.vr["u[2]"]])
        m.close()
        return u, log

    u_ref, _ = run({})
    for name, value, rng in (("w1", 0.0, "> 0 N.m.s/rad"), ("m2", -5.0, ">= 0 kg"), ("T2", 0.0, "> 0 s"),
                             ("T1", -0.1, ">= 0 s")):
        capsys.readouterr()
        u, log = run({100: {name: value}})
        assert isinstance(log[-21][1], Exception) and log[-21][0] == name
        assert all(e is None for what, e in log if what == "step")
        assert u == u_ref, name   # the value was kept
        assert f"({name}): value refused: expected {rng}" in capsys.readouterr().out
    capsys.readouterr()
    u, log = run({100: {"T1": 0.6}, 105: {"T1": 0.0}})
    steps = [e for what, e in log if what == "step"]
    assert all(e is None for e in steps[:100]) and all(isinstance(e, Exception) for e in steps[100:105])
    assert all(e is None for e in steps[105:]) and u is not None
    out = capsys.readouterr().out
    assert ("DoStep: parameters refused: expected T1 < T2 (s; the prediction horizon [T1, T2] of eq. 14), "
            "got T1 = 0.6, T2 = 0.5") in out


def test_exit_initialization_refuses_start_values_that_break_a_rule(tmp_path, capsys):
    path = _build(tmp_path, "vertical_2link", 3, "dobc")
    m = Instance(path, tmp_path / "x")
    assert m.set("T1", 0.5) is None    # T1 = T2 = 0.5: each value in its range, the pair not
    assert isinstance(m.exit_init(), Exception)
    assert "fmi3ExitInitializationMode: parameters refused: expected T1 < T2" in capsys.readouterr().out
    m.close()


def test_model_description_states_min_where_the_validator_has_a_range(tmp_path):
    path = _build(tmp_path, "vertical_2link", 2, "npid")
    md = read_model_description(str(path))
    arm = derive.load_arm("vertical_2link")
    params = {str(p.symbol): p for p in arm.parameters}
    seen = 0
    for v in md.modelVariables:
        if v.causality != "parameter":
            continue
        p = params.get(v.name)
        bounded = v.name.startswith("u_max") or (p is not None and bool(p.symbol.is_positive or p.symbol.is_nonnegative))
        assert (v.min == "0.0") == bounded, v.name
        seen += bounded
    assert seen >= 20 and {v.name: v.min for v in md.modelVariables}["T1"] == "0.0"


def _field_path(field: str) -> list:
    """The TOML path of a parameter's field ("link[2].mass" -> ["link", 1, "mass"])."""
    out: list = []
    for part in field.split("."):
        name, *idx = part.replace("]", "").split("[")
        out.append(name)
        out += [int(i) - 1 for i in idx]
    return out


def test_every_tunable_parameter_is_refused_by_the_fmu_exactly_where_the_validator_refuses_it(tmp_path):
    """vertical_2link: each parameter of its arm file set to -1, 0 and 0.001 in the file (the
    validator) and through fmi3SetFloat64 (the FMU): the same verdict for every one."""
    arm_path = ROOT / "derive" / "model" / "arms" / "vertical_2link.toml"
    data = tomllib.loads(arm_path.read_text())
    arm = derive.load_arm("vertical_2link")
    path = _build(tmp_path, "vertical_2link", 3, "dobc")
    m = Instance(path, tmp_path / "x")
    checked = 0
    for p in arm.parameters:
        keys = _field_path(p.field)
        for value in (-1.0, 0.0, 0.001):
            edited = copy.deepcopy(data)
            node = edited
            for at, key in enumerate(keys[:-1]):
                if isinstance(key, str) and key not in node:   # a default array the file leaves out
                    prefix = ".".join(str(k) for k in keys[:at + 1])
                    node[key] = [float(q.value) for q in arm.parameters if q.field.startswith(prefix + "[")]
                node = node[key]
            if p.field.endswith(".com") and "com" not in node:
                continue      # com = l/2 when left out: the parameter is l's, no field of its own
            node[keys[-1]] = value
            try:
                arm_from_dict(edited, str(arm_path), arm_path.parent)
                valid = True
            except SpecError:
                valid = False
            refused = m.set(str(p.symbol), value) is not None
            if not refused:
                assert m.set(str(p.symbol), float(p.value)) is None
            assert refused == (not valid), (p.field, value)
            checked += 1
    m.close()
    assert checked >= 60


def _rules_at_defaults(a: str):
    arm = derive.load_arm(a)
    d = derive.derive(arm)
    known = {p.symbol for p in arm.parameters}
    every = arm.parameters + tuple(Parameter(s, v, "", "", "") for s, v in d.values if s not in known)
    rules = [r for r in all_rules(every, horizon_symbols=(T1_SYMBOL, T2_SYMBOL), W=d.observer.W,
                                  bodies=arm.spatial.bodies if arm.spatial is not None else ())
             if not sp.sympify(r.value).is_Symbol]
    fn, used = rule_function(rules, every)
    return rules, fn, [dict(d.values)[s] for s in used]


@pytest.mark.parametrize("arm", ["tests/data/urdf/panda.toml", "tests/data/urdf/ur5.toml", "tests/data/urdf/iiwa.toml",
                                 "tests/data/urdf/synthetic.toml", "tests/data/urdf/round3/tool.toml", *packaged_arms()])
def test_every_rule_holds_at_the_arm_files_own_values_in_double_and_float(arm):
    """No false refusal: the printed rules at the file's values (exact: each holds) in double and in
    float (the values rounded to float, the allowance of a float FMU), every arm's bodies and W."""
    rules, fn, exact = _rules_at_defaults(arm)
    for real, u in (("double", 2.0 ** -53), ("float", 2.0 ** -24)):
        p = np.array([float(x) for x in exact])
        p = p.astype(np.float32).astype(float) if real == "float" else p
        value, slack = (np.array(x).ravel() for x in fn(p))
        for k, r in enumerate(rules):
            ok = {">": value[k] > 0, "!=": abs(value[k]) > slack[k] * u, ">=": value[k] >= -slack[k] * u}[r.relation]
            assert ok, (arm, real, r.expected, value[k], slack[k] * u)


def test_the_rules_are_the_validators():
    """The determinant and the body rule the validator decides with (derive.model.rules) are exact:
    Berkowitz's det equals SymPy's, a body with a negative principal minor is not physical."""
    from fractions import Fraction as F

    rng = np.random.default_rng(4)
    for n in (1, 2, 5, 8):
        A = [[F(int(x)) for x in row] for row in rng.integers(-6, 7, (n, n))]
        assert division_free_det(A, F(0)) == sp.Matrix(A).det()
    assert physical([F(1), 0, 0, 0, F(1), 0, 0, F(1), 0, F(1)])
    assert not physical([F(1), F(10), 0, 0, F(1, 10), 0, 0, F(1, 10), 0, F(1, 10)])   # |h| beyond m and I


def test_a_urdf_arms_w_and_bodies_are_refused_at_the_next_step_and_the_plant_checks_its_own(tmp_path, capsys):
    """synthetic.toml (4 joints, a full W, URDF bodies): a singular W (rows 1 and 3 equal) and a body
    whose first moment its mass cannot carry are refused at the next fmi3DoStep, named; set back,
    the FMU steps again. The plant FMU refuses a negative mass at the set and the same body at
    its next step."""
    path = _build(tmp_path, "tests/data/urdf/synthetic.toml", 3, "dobc")
    m = Instance(path, tmp_path / "c")
    start = {v.name: float(v.start) for v in m.md.modelVariables if v.causality == "parameter"}
    assert m.exit_init() is None and m.step() is None
    assert start["W1_3"] > 0
    for j in range(1, 5):     # row 3 = row 1: W singular, its diagonal still positive
        assert m.set(f"W3_{j}", start[f"W1_{j}"]) is None
    assert isinstance(m.step(), Exception)
    assert "parameters refused: expected det W != 0" in capsys.readouterr().out
    for j in range(1, 5):
        assert m.set(f"W3_{j}", start[f"W3_{j}"]) is None
    assert m.step() is None
    assert m.set("hx2", 1e3) is None and isinstance(m.step(), Exception)
    assert "body 2: a physically consistent body" in capsys.readouterr().out
    m.close()
    plant = _build(tmp_path, "tests/data/urdf/synthetic.toml", 2, "", plant=True)
    assert validate_fmu(str(plant)) == []
    p = Instance(plant, tmp_path / "p")
    assert p.exit_init() is None and p.step() is None
    assert isinstance(p.set("m2", -1.0), Exception)
    assert p.set("hx2", 1e3) is None and isinstance(p.step(), Exception)
    assert "body 2: a physically consistent body" in capsys.readouterr().out
    p.close()
