"""Continuous joints (issue 19 item 5; case continuous_wrap, ros_controllers#275's kind): the
tracking error of an output a continuous joint moves is wrapped to (-pi, pi] (derive.control.sampling.wrap),
so a joint reported at theta or at theta - 2 pi gives the same command, in every form: the
40-digit reference, the generated C and Python, the FMU, the compiled loop and the Python-stepped
backend, and derive simulate's metrics. The integral of e (NPID) integrates the wrapped error."""
from __future__ import annotations

import importlib.util
import math
import subprocess
import zipfile
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import derive
from derive.cli import main
from derive.codegen.emit import write_tree
from derive.codegen.files import generate_files
from derive.codegen.kernels import ParamsMode
from derive.codegen.reference import Reference
from derive.codegen.balls import to_float
from derive.control.sampling.wrap import wrap_numeric, wrapped_outputs
from derive.errors import SpecError
from derive.model.chain import JointType

from .cbuild import STRICT, CLib

DATA = Path(__file__).parent / "data" / "urdf"
TWO_PI = 2 * math.pi


@pytest.fixture(scope="module")
def contarm(tmp_path_factory):
    """The case's arm: two continuous joints, generated with runtime parameters (C and Python)."""
    arm = derive.load_arm(DATA / "continuous.toml")
    d = derive.derive(arm)
    root = tmp_path_factory.mktemp("contarm")
    write_tree(root / "contarm", generate_files(d, None, "double", ParamsMode.RUNTIME))
    spec = importlib.util.spec_from_file_location("contarm_wrap", root / "contarm" / "python" / "contarm.py")
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    lib = CLib(root / "contarm" / "c", "contarm", 2, "double", True, root, np_count=len(d.values))
    return arm, d, m, lib, root / "contarm"


def _x(theta, yd=(math.pi - 0.01, 0.0), dtheta=(0.4, -0.3), dyd=(0.1, 0.0), ddyd=(0.0, 0.2)) -> list[float]:
    return [float(v) for v in (*theta, *dtheta, *yd, *dyd, *ddyd)]


POSE = (math.pi + 0.01, 0.3)       # 0.02 rad past yd1 = pi - 0.01 (the case's numbers)
TURNS = ((-TWO_PI, 0.0), (0.0, TWO_PI), (-TWO_PI, -2 * TWO_PI), (2 * TWO_PI, 0.0))


def _runs(m, x, dt=2e-3, steps=3) -> dict[str, np.ndarray]:
    """u of every form of the generated Python module at x: mpc, and npid, dobc, mom from their init
    over ``steps`` steps (and the final int_e)."""
    n = m.N
    p, inp = m.Params(), m.Input(*(x[i * n:(i + 1) * n] for i in range(5)))
    out = {"mpc": m.mpc_step(p, inp)[1]}
    for form, state in (("npid", m.NpidState), ("dobc", m.DobcState), ("mom", m.MomState)):
        s = state()
        assert getattr(m, f"{form}_init")(p, s, inp) == m.OK
        out[form] = np.array([getattr(m, f"{form}_step")(p, s, inp, dt)[1] for _ in range(steps)])
        if form == "npid":
            out["int_e"] = np.array(s.int_e)
    return out


def test_the_case_same_pose_reported_wrapped_gives_the_same_command_in_python_and_c(contarm):
    """The case: yd1 = pi - 0.01, joint 1 at pi + 0.01 reported unwrapped or as -pi + 0.01 (and
    either joint a turn or two off): MPC gave 3.25 against 61.97 N m, NPID 2.00 against 453.4 N m.
    Now every form gives the same u (and NPID the same int_e) to 1e-12, in Python and C."""
    _, d, m, lib, _ = contarm
    zero = (0.0, 0.0)
    for theta1 in (math.pi + 0.01, -math.pi + 0.01):   # the case's inputs: the unwrapped value for both
        case = _x((theta1, 0.0), dtheta=zero, dyd=zero, ddyd=zero)
        assert m.mpc_step(m.Params(), m.Input(*(case[i * 2:(i + 1) * 2] for i in range(5))))[1] == pytest.approx(
            [3.2474, 0.4538], abs=1e-3)
    base = _runs(m, _x(POSE))
    for turn in TURNS:
        other = _runs(m, _x(np.add(POSE, turn)))
        for key, u in base.items():
            np.testing.assert_allclose(other[key], u, rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(u))),
                                       err_msg=f"{key} {turn}")
    assert np.allclose(base["int_e"], 3 * 2e-3 * np.array([-0.02, -0.3]), atol=1e-15)   # the wrapped e integrated
    for turn in TURNS:   # the C library: mpc_step and one step of each form from its init
        for x in (_x(POSE), _x(np.add(POSE, turn))):
            code, u = lib.mpc_step(x)
            assert code == 0 and u == pytest.approx(base["mpc"], rel=1e-12, abs=1e-12)
        for form in ("npid", "dobc", "mom"):
            got = []
            for x in (_x(POSE), _x(np.add(POSE, turn))):
                code, s0 = lib.init(form, x)
                code2, u, _ = lib.step(form, s0, x, 2e-3)
                assert code == code2 == 0
                got.append(u)
            np.testing.assert_allclose(got[1], got[0], rtol=0, atol=1e-12 * np.max(np.abs(got[0])), err_msg=form)
            np.testing.assert_allclose(got[0], base[form][0], rtol=1e-12, atol=1e-12, err_msg=form)


def test_the_40_digit_reference_wraps_and_the_c_self_test_passes(contarm, tmp_path):
    """The reference (ball arithmetic, floor of a ball) gives the same u at theta and theta - 2 pi;
    the generated self-test (its inputs put |e| beyond pi in about a third of its cases) passes."""
    _, d, _, _, root = contarm
    ref = Reference(d)
    for turn in TURNS:
        a, b = ref.mpc(_x(POSE)), ref.mpc(_x(np.add(POSE, turn)))
        assert max(abs(to_float(u) - to_float(v)) for u, v in zip(a, b)) < 1e-12
    c = root / "c"
    exe = tmp_path / "st"
    subprocess.run(["gcc", *STRICT, "-O1", "-o", str(exe), str(c / "contarm_selftest.c"), str(c / "contarm.c"),
                    str(c / "contarm_kernels.c"), "-lm"], check=True)
    proc = subprocess.run([str(exe)], capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout.endswith(" passed, 0 failed\n"), proc.stdout
    header = (c / "contarm.h").read_text()
    assert "Continuous joints 1 (j1), 2 (j2): the tracking error e = yd - C theta of" in header
    assert "wrapped to (-pi, pi]" in header and "wrapped to (-pi, pi]" in (root / "python" / "contarm.py").read_text()


def test_compiled_loop_python_backend_and_metrics_are_the_same_a_turn_off(contarm):
    """derive simulate's run started at theta0 and at theta0 with each joint a turn off: the compiled
    loop and the Python-stepped backend give the same commands (1e-9), and the metrics (of the
    wrapped error) are equal; the arm tracks."""
    from derive.sim.backends import Backend
    from derive.sim.compiled import build
    from derive.sim.simulate import Plant, metrics, run_compiled, run_many, true_plant

    arm, d, _, _, _ = contarm
    loop = build(d)
    runs = {}
    for name, start in (("plain", (0.2, -0.1)), ("turned", (0.2 - TWO_PI, -0.1 + 2 * TWO_PI))):
        s = replace(arm.simulation, duration=2.0, initial_theta=start)
        plant = true_plant(d, s)
        runs[name] = {f: run_compiled(d, loop, plant, s, f) for f in ("npid", "dobc", "mom")}
        if name == "turned":
            backend = Backend(d, "python")
            try:
                runs["python"] = run_many(d, backend, Plant(d, plant), s, ["npid", "dobc", "mom"])
            finally:
                backend.close()
    for f in ("npid", "dobc", "mom"):
        a, b, p = runs["plain"][f], runs["turned"][f], runs["python"][f]
        assert a.failure is None and b.failure is None and p.failure is None
        np.testing.assert_allclose(b.u, a.u, rtol=0, atol=1e-9 * np.max(np.abs(a.u)), err_msg=f)
        np.testing.assert_allclose(p.u, b.u, rtol=0, atol=1e-9 * np.max(np.abs(a.u)), err_msg=f)
        np.testing.assert_allclose(b.error, a.error, atol=1e-9, err_msg=f)
        ma, mb = metrics(a, s), metrics(b, s)
        for la, lb in zip(ma, mb):
            assert lb["max_error"] == pytest.approx(la["max_error"], abs=1e-9)
        assert max(m["max_error"] for m in ma) < 0.5   # tracks (unwrapped it would see errors of 2 pi)


def test_controller_fmu_gives_the_same_command_a_turn_off(contarm, tmp_path):
    """The FMU (FMI 3, NPID) wraps as the C does: the same u at theta and theta - 2 pi."""
    from fmpy import read_model_description
    from fmpy.fmi3 import FMU3Slave

    from derive.fmu.package import FmuOptions, controller_fmu

    _, d, m, _, _ = contarm
    name, data = controller_fmu(d, FmuOptions(3, "npid", "double", ParamsMode.RUNTIME))
    path = tmp_path / name
    path.write_bytes(data)
    md = read_model_description(str(path))
    refs = {v.name: v.valueReference for v in md.modelVariables}
    us = []
    for k, x in enumerate((_x(POSE), _x(np.add(POSE, (-TWO_PI, TWO_PI))))):
        folder = tmp_path / f"unzipped{k}"
        with zipfile.ZipFile(path) as z:
            z.extractall(folder)
        fmu = FMU3Slave(guid=md.guid, unzipDirectory=str(folder), modelIdentifier=md.coSimulation.modelIdentifier,
                        instanceName=f"c{k}")
        fmu.instantiate()
        fmu.enterInitializationMode(startTime=0.0)
        fmu.exitInitializationMode()
        names = [f"{f}[{i + 1}]" for f in ("theta", "dtheta", "yd", "dyd", "ddyd") for i in range(2)]
        fmu.setFloat64([refs[v] for v in names], x)
        fmu.doStep(0.0, 2e-3)
        us.append(np.array(fmu.getFloat64([refs["u[1]"], refs["u[2]"]])))
        fmu.terminate()
        fmu.freeInstance()
    np.testing.assert_allclose(us[1], us[0], rtol=0, atol=1e-12 * np.max(np.abs(us[0])))
    assert us[0] == pytest.approx(_runs(m, _x(POSE), steps=1)["npid"][0], rel=1e-12)


def _joints(*kinds):
    return tuple(SimpleNamespace(type=JointType(k), name=f"j{i + 1}") for i, k in enumerate(kinds))


def test_an_output_matrix_that_mixes_joints_is_wrapped_by_rows_or_refused():
    """C mixing joints: an output moved by a continuous joint is wrapped; each continuous joint's
    column must be integers (a turn must move every output by whole turns), and a wrapped output
    must not move with a prismatic joint; the others are not wrapped."""
    import sympy as sp

    I3 = sp.eye(3)
    assert wrapped_outputs(I3, _joints("revolute", "continuous", "prismatic")) == (1,)
    assert wrapped_outputs(I3, _joints("revolute", "revolute", "prismatic")) == ()
    assert wrapped_outputs(sp.Matrix([[1, 1, 0], [0, 1, 0], [0, 0, 1]]), _joints("revolute", "continuous",
                                                                                 "revolute")) == (0, 1)
    assert wrapped_outputs(sp.Matrix([[1, 0, 0], [0, -2, 0], [0, 0, 1]]), _joints("continuous", "continuous",
                                                                                  "revolute")) == (0, 1)
    with pytest.raises(SpecError, match=r"controller\.C\[1\]\[2\]: expected an integer \(joint 2 'j2' is "
                                        r"continuous: a turn of it moves output 1 by 2 pi C\[1\]\[2\].*got 1/2"):
        wrapped_outputs(sp.Matrix([[1, sp.Rational(1, 2), 0], [0, 1, 0], [0, 0, 1]]),
                        _joints("revolute", "continuous", "revolute"), "arm.toml")
    with pytest.raises(SpecError, match=r"controller\.C\[1\]\[3\]: expected 0 \(output 1 moves with continuous "
                                        r"joint 1 'j1'.*prismatic joint 3 'j3' would add a length"):
        wrapped_outputs(sp.Matrix([[1, 0, 1], [0, 1, 0], [0, 0, 1]]), _joints("continuous", "revolute",
                                                                               "prismatic"), "arm.toml")


def test_a_mixing_output_matrix_on_the_case_arm(tmp_path, capsys):
    """On the case's arm: C = [[1, 1], [0, 1]] (y1 the absolute angle of link 2) wraps both outputs
    and gives the same u a turn off (Python module); C = [[1, 0.5], [0, 1]] is one clear error, exit 2."""
    from derive.codegen.files import python_files

    text = (DATA / "continuous.toml").read_text().replace("w = [5.0, 5.0]", "w = [5.0, 5.0]\nC = [[1, 1], [0, 1]]")
    for f in ("continuous.urdf",):
        (tmp_path / f).write_bytes((DATA / f).read_bytes())
    (tmp_path / "mixed.toml").write_text(text)
    d = derive.derive(derive.load_arm(tmp_path / "mixed.toml"))
    assert d.wrapped == (0, 1)
    (tmp_path / "mixed.py").write_text(python_files(d, ParamsMode.RUNTIME)["python/contarm.py"])
    spec = importlib.util.spec_from_file_location("contarm_mixed", tmp_path / "mixed.py")
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    base = _runs(m, _x(POSE))
    for turn in TURNS:
        other = _runs(m, _x(np.add(POSE, turn)))
        for key, u in base.items():
            np.testing.assert_allclose(other[key], u, rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(u))))
    (tmp_path / "half.toml").write_text(text.replace("C = [[1, 1], [0, 1]]", "C = [[1, 0.5], [0, 1]]"))
    capsys.readouterr()
    assert main(["generate", str(tmp_path / "half.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "controller.C[1][2]: expected an integer (joint 2 'j2' is continuous" in err and "got 1/2" in err
    assert not (tmp_path / "out").exists()


def test_wrap_numeric_is_the_symbolic_wrap():
    x = np.array([-7.0, -math.pi, -3.0, 0.0, 3.0, math.pi, 3.2, 7.0, 20.0])
    w = wrap_numeric(x)
    assert np.all(w > -math.pi) and np.all(w <= math.pi)
    assert np.allclose(np.sin(w), np.sin(x)) and np.allclose(np.cos(w), np.cos(x))
    assert w[1] == pytest.approx(math.pi) and w[5] == pytest.approx(math.pi)
