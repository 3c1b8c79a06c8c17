"""Runtime parameters are the arm file's own values (issue 15, item 3).

With --params runtime, setting the third link's mass of my3.toml at run time
must equal regenerating with that mass: its uniform-rod inertia m l^2/12 and
its default centre of mass l/2 are computed from it in the kernels, and k1, k2
from T1, T2 (eq. 16-18). Checked through the generated Python module and the
compiled C, for the gains (eq. 35-37) and u of every form (eq. 15, 27, 34).
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import derive
from derive.codegen.kernels import ParamsMode
from derive.codegen.plant import plant_view
from derive.codegen.render import render
from derive.codegen.views import arm_view

from .cbuild import CLib

DATA = Path(__file__).parent / "data" / "arms"
HEAVIER = "0.45"   # link 3's mass at run time, instead of the file's 0.3 kg


def _emit(d, mode: ParamsMode, folder: Path) -> Path:
    """The C library (controller and plant, as tests.cbuild.CLib links them) and the Python
    module of one derivation (no self-test: not needed here)."""
    v = arm_view(d, "double", mode)
    pl = plant_view(d, "double", mode)   # the Python module also holds the plant model
    a = d.arm.name
    (folder / "c").mkdir(parents=True)
    (folder / "python").mkdir()
    for name, template in ((f"c/{a}.h", "c/arm.h.jinja"), (f"c/{a}.c", "c/arm.c.jinja"),
                           (f"c/{a}_kernels.h", "c/kernels.h.jinja"), (f"c/{a}_kernels.c", "c/kernels.c.jinja"),
                           (f"c/{a}_plant.h", "c/plant.h.jinja"), (f"c/{a}_plant.c", "c/plant.c.jinja"),
                           (f"python/{a}.py", "python/arm.py.jinja")):
        (folder / name).write_text(render(template, v=v, pl=pl), encoding="utf-8")
    return folder


def _module(path: Path):
    spec = importlib.util.spec_from_file_location(f"{path.stem}_{path.parent.parent.name}", path)
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def _outputs_py(m, params, x: np.ndarray) -> np.ndarray:
    """Gains and u of every form, and the states they leave, from the generated Python module."""
    n = m.N
    p = (params,) if params is not None else ()
    inp = m.Input(*(list(x[i * n:(i + 1) * n]) for i in range(5)))
    P, D, I = m.gains(*p, list(x[:n]))
    out = [np.ravel(P), np.ravel(D), np.ravel(I), m.mpc_step(*p, inp)[1]]
    for form, State in (("npid", m.NpidState), ("dobc", m.DobcState)):
        s = State()
        getattr(m, f"{form}_init")(*p, s, inp)
        code, u, _ = getattr(m, f"{form}_step")(*p, s, inp, 1e-3)
        assert code == m.OK
        out += [u, s.int_e if form == "npid" else s.z]
    return np.concatenate([np.ravel(np.asarray(o, float)) for o in out])


def _outputs_c(lib: CLib, x: np.ndarray) -> np.ndarray:
    n = lib.n
    out = [lib.gains(x[:n]), lib.mpc_step(x)[1]]
    for form in ("npid", "dobc"):
        _, s0 = lib.init(form, x)
        code, u, s1 = lib.step(form, s0, x, 1e-3)
        assert code == 0
        out += [u, s1]
    return np.concatenate([np.ravel(o) for o in out])


@pytest.fixture(scope="module")
def builds(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("runtime")
    text = (DATA / "my3.toml").read_text(encoding="utf-8")
    third = text.index("mass = 0.3\n", text.index("length = 0.15"))
    heavier = tmp / "my3.toml"
    heavier.write_text(text[:third] + f"mass = {HEAVIER}\n" + text[third + len("mass = 0.3\n"):], encoding="utf-8")
    runtime = derive.derive(derive.load_arm(DATA / "my3.toml"))
    regenerated = derive.derive(derive.load_arm(heavier))
    assert [str(s) for s, _ in runtime.values] == [str(s) for s, _ in regenerated.values]
    return (runtime, _emit(runtime, ParamsMode.RUNTIME, tmp / "rt"), regenerated,
            _emit(regenerated, ParamsMode.BAKED, tmp / "baked"), tmp)


def _states(n: int) -> list[np.ndarray]:
    rng = np.random.default_rng(15)
    return [np.concatenate([rng.uniform(-2, 2, 3 * n), rng.uniform(-1, 1, 2 * n)]) for _ in range(6)]


def test_runtime_params_are_exactly_the_arm_files_values(builds):
    """No uniform-rod inertia, no default centre of mass, no k1, k2 among them: T1, T2 are."""
    runtime = builds[0]
    names = [str(s) for s, _ in runtime.values]
    assert names == [str(p.symbol) for p in runtime.arm.parameters]
    assert "m3" in names and "T1" in names and "T2" in names
    assert not {"Ic1", "Ic2", "Ic3", "c1", "c2", "c3", "k1", "k2"} & set(names)


def test_runtime_mass_equals_regenerated_python(builds):
    runtime, rt_dir, regenerated, baked_dir, _ = builds
    rt, new = _module(rt_dir / "python" / "my3.py"), _module(baked_dir / "python" / "my3.py")
    default, changed = rt.Params(), rt.Params()
    changed.m3 = float(HEAVIER)
    for x in _states(3):
        want = _outputs_py(new, None, x)
        assert _rel(_outputs_py(rt, changed, x), want) <= 1e-12
        assert _rel(_outputs_py(rt, default, x), want) > 1e-4   # the mass really matters


def test_runtime_mass_equals_regenerated_c(builds):
    runtime, rt_dir, regenerated, baked_dir, tmp = builds
    names = [str(s) for s, _ in runtime.values]
    rt = CLib(rt_dir / "c", "my3", 3, "double", True, tmp, np_count=len(names))
    new = CLib(baked_dir / "c", "my3", 3, "double", False, tmp)
    x0 = _states(3)[0]
    before = _outputs_c(rt, x0)
    rt.params[names.index("m3")] = float(HEAVIER)
    assert _rel(before, _outputs_c(new, x0)) > 1e-4
    for x in _states(3):
        assert _rel(_outputs_c(rt, x), _outputs_c(new, x)) <= 1e-12
