"""The generalized-momentum observer, controller form ``mom`` (issue 12 item 6).

r = K (J theta' - m), m' = B u + C^T theta' - g - F theta' + r, m(0) = J(theta0) theta0', so
r' = K (B d - r) for any state; dhat = B^-1 r and u = u* - dhat (eq. 27) (derive.control.momentum).
"""
from __future__ import annotations

import importlib.util
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import derive
from derive.cli import main
from derive.codegen.balls import to_float
from derive.codegen.emit import write_tree
from derive.codegen.files import generate_files
from derive.codegen.forms import FORMS
from derive.codegen.kernels import ParamsMode
from derive.codegen.reference import Reference
from derive.control.sampling.limit_text import summary_all
from derive.control.momentum import coriolis_rate
from derive.control.sampling import limits
from derive.errors import SpecError
from derive.model.spec import ARMS_DIR
from derive.sim.compiled import build, run_loop
from derive.sim.simulate import CONTROLLERS, VARIANTS, momentum_estimate, pulses, run_compiled, true_plant

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def paper():
    arm = derive.load_arm()
    return arm, derive.derive(arm)


@pytest.fixture(scope="module")
def loop(paper):
    return build(paper[1])


def _close(got, want, rel: float = 1e-12) -> bool:
    want = np.array([to_float(w) for w in want])
    return bool(np.max(np.abs(np.asarray(got) - want)) <= rel * max(1.0, float(np.max(np.abs(want)))))


def _module(d, folder: Path, observer: str):
    write_tree(folder, generate_files(d, None, "double", ParamsMode.BAKED, observer=observer))
    spec = importlib.util.spec_from_file_location(f"mom_{observer}", folder / "python" / f"{d.arm.name}.py")
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


def test_issue12_6_the_residual_obeys_r_dot_equal_k_of_b_d_minus_r(paper):
    """Symbolically, at an exact rational state: with J theta'' = B (u + d) - G (eq. 12),
    d/dt (J theta') - m' + r = B d, so r' = K (B d - r), beta = C^T theta' - g - F theta'
    from the chain's Coriolis matrix (the reference) and from the recursion (the derivation's m')."""
    _, d = paper
    mom, s = d.momentum, d.dynamics.sym
    n = d.n
    dist = sp.Matrix(sp.symbols(f"dist1:{n + 1}", real=True))
    ddq = d.dynamics.J.LUsolve(d.dynamics.B * (sp.Matrix(s.u) + dist) - d.dynamics.G)
    rate = {**dict(zip(s.theta, s.dtheta)), **{q: ddq[i] for i, q in enumerate(s.dtheta)}}
    pdot = sp.Matrix([sum(mom.p[i].diff(v) * rate[v] for v in list(s.theta) + list(s.dtheta)) for i in range(n)])
    want = mom.K * (d.dynamics.B * dist - mom.r)
    point = {**{q: sp.Rational(3, 7) * (i + 1) for i, q in enumerate(s.theta)},
             **{v: sp.Rational(-5, 3) + i for i, v in enumerate(s.dtheta)},
             **{u: sp.Rational(1, 2) - i for i, u in enumerate(s.u)}, **{x: sp.Rational(1, 5) for x in dist},
             **{m: sp.Rational(2, 3) * (i + 1) for i, m in enumerate(mom.m)}, **dict(d.values)}
    for m_rate in (coriolis_rate(d.dynamics, mom), mom.m_rate):
        diff = (mom.K * (pdot - m_rate) - want).xreplace(point)
        assert all(abs(sp.N(x, 30)) < 1e-25 for x in diff)
    assert any(abs(sp.N(x, 30)) > 1e-3 for x in want.xreplace(point))   # not a trivially zero comparison


def test_issue12_6_mom_is_a_registered_form_simulated_by_default_beside_the_others(loop):
    assert FORMS["mom"].state.field == "m" and FORMS["mom"].estimate
    assert VARIANTS["mom"] == ("mom", True)
    assert CONTROLLERS == ("mpc", "dobc", "npid", "mom")
    assert "mom" in loop.forms


def test_issue12_6_generated_python_and_c_mom_equal_the_symbolic_law_at_1e_12(paper, tmp_path):
    """mom_init, mom_step (u and the next m), mom_estimate of the generated Python module
    (baked; both observer builds: the momentum observer's step is the same in both) and of the
    C library (runtime parameters, through the simulator's backend) against the 40-digit reference."""
    from derive.sim.backends import Backend

    _, d = paper
    mods = [_module(d, tmp_path / o, o) for o in ("explicit", "implicit")]
    ref = Reference(d, u_max=[0.0] * d.n)
    backend = Backend(d, "c")
    c = backend.controller("mom", [0.0] * d.n)
    rng = np.random.default_rng(6)
    n = d.n
    try:
        for _ in range(6):
            x = list(np.round(rng.uniform(-2, 2, 5 * n) * 1024) / 1024)
            mvec = list(np.round(rng.uniform(-1, 1, n) * 1024) / 1024)
            dt = float(rng.choice([1e-3, 1e-2]))
            want_u, want_m = ref.mom_step(mvec, x, dt)
            c.init(x, dt)
            assert _close(c.state, ref.mom_init(x))
            c.state = mvec
            assert _close(c.step(x, dt), want_u) and _close(c.state, want_m)
            for m in mods:
                inp = m.Input(*(x[i * n:(i + 1) * n] for i in range(5)))
                state = m.MomState()
                assert m.mom_init(state, inp) == m.OK and _close(state.m, ref.mom_init(x))
                state.m = list(mvec)
                code, dhat = m.mom_estimate(state, inp)
                assert code == m.OK and _close(dhat, ref.mom_dhat(x, mvec))
                code, u, clipped = m.mom_step(state, inp, dt)
                assert code == m.OK and clipped == 0 and _close(u, want_u) and _close(state.m, want_m)
    finally:
        backend.close()


def test_issue12_6_mom_step_clips_reports_the_mask_and_feeds_the_observer_the_clipped_u(paper, tmp_path):
    """With voltage limits (runtime parameters, 2 and 3 V): the clipped joints' bitmask as the
    other steps give it, and the next m from the applied (clipped) u; a bad dt or a non-finite
    state leaves m untouched."""
    _, d = paper
    write_tree(tmp_path / "g", generate_files(d, None, "double", ParamsMode.RUNTIME))
    spec = importlib.util.spec_from_file_location("mom_runtime", tmp_path / "g" / "python" / f"{d.arm.name}.py")
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    p = m.Params()
    p.u_max = [2.0, 3.0]
    ref = Reference(d, u_max=p.u_max)
    n = d.n
    x = [0.5, -0.25, 3.0, -3.0, 1.0, 0.5, 0.0, 0.0, 5.0, -5.0]   # far from the reference: u* beyond the limits
    inp = m.Input(*(x[i * n:(i + 1) * n] for i in range(5)))
    state = m.MomState()
    state.m = [0.125, -0.25]
    want_u, want_m = ref.mom_step(state.m, x, 1e-3)
    raw, _ = Reference(d, u_max=[0.0] * n).mom_step(state.m, x, 1e-3)
    assert all(abs(to_float(v)) > lim for v, lim in zip(raw, p.u_max))   # both joints beyond their limit
    code, u, clipped = m.mom_step(p, state, inp, 1e-3)
    assert code == m.OK and clipped == 0b11 and _close(u, want_u) and _close(state.m, want_m)
    assert list(np.abs(u)) == p.u_max
    before = list(state.m)
    assert m.mom_step(p, state, inp, 0.0) == (m.EDT, None, None) and state.m == before
    state.m = [math.nan, 0.0]
    assert m.mom_step(p, state, inp, 1e-3) == (m.ENONFINITE, None, None) and math.isnan(state.m[0])


def _estimate_error(d, loop, arm, dt: float, duration: float, x0: np.ndarray, dm: np.ndarray) -> np.ndarray:
    """|dhat - d| per sample (max over the joints) of a compiled MOM run of the arm's experiment,
    the plant equal to the model plus a constant input disturbance d, from the plant state x0 and
    the observer state m0 = J(theta0) theta0' + dm (so r(0) = -K dm, not the r = 0 of mom_init)."""
    s = replace(arm.simulation, duration=duration, sample_time=dt, substeps=4, payload_scale=1.0,
                coulomb_friction=(0.0, 0.0), viscous_friction=(0.0, 0.0), disturbance=(0.4, -0.25), start=(0.0, 0.0))
    plant = true_plant(d, s)
    steps = int(round(duration / dt))
    J0 = np.array(d.J.xreplace(dict(zip(d.theta, x0[:d.n]))).tolist(), dtype=float)
    raw = run_loop(loop, "mom", True, plant.values, plant.coulomb, plant.viscous, plant.disturbance, plant.u_max,
                   pulses(s, d.n, steps), None, None, 1.0, x0, J0 @ x0[d.n:] + dm, dt, s.substeps)
    assert raw.code == 0 and len(raw.theta) == steps
    assert np.max(np.abs(raw.dtheta[0] - x0[d.n:])) == 0.0
    dhat = momentum_estimate(d)(raw.theta, raw.filtered, raw.state)
    return np.max(np.abs(dhat - np.array(s.disturbance)), axis=1)


def _rate(err: np.ndarray, dt: float, t1: float, t2: float) -> float:
    return float(np.log(err[int(round(t1 / dt))] / err[int(round(t2 / dt))]) / (t2 - t1))


def test_issue12_6_with_a_constant_disturbance_r_tends_to_b_d_exponentially_from_any_state(paper, loop):
    """r -> B d (dhat -> d) in the compiled loop, the reference moving, from an observer state
    with r(0) != 0 (errors of 11.6 V): forward Euler of m gives r_{k+1} - B d = (1 - K dt)(r_k - B d)
    + O(dt^2), so the error shrinks at -ln(1 - K dt)/dt (-> K = 50 1/s as dt -> 0) down to an O(dt)
    remainder. From rest: that rate within 0.5 %, the remainder below 1 % of max |d| and halving with dt.
    From an arm spinning at 40 rad/s at joint 2, beyond the speed w1/X = 24.7 rad/s of condition
    (26) that Chen's observer needs: the same convergence, the remainder (larger: beta = C^T theta'
    - g - F theta' moves fast while the arm is braked) and the rate's deviation halving with dt."""
    arm, d = paper
    K = float(dict(d.values)[d.momentum.k[0]])
    dm = np.array([0.003, -0.002])
    tails = []
    for dt in (2e-3, 1e-3):
        err = _estimate_error(d, loop, arm, dt, 1.0, np.zeros(4), dm)
        assert err[0] > 10.0
        assert _rate(err, dt, 0.01, 0.05) == pytest.approx(-math.log(1 - K * dt) / dt, rel=0.005)
        tails.append(float(np.max(err[int(0.5 / dt):])))
    assert tails[0] < 0.01 * 0.4 and tails[1] / tails[0] == pytest.approx(0.5, abs=0.05), tails
    assert float(d.speed_bound) < 40.0
    spin = np.array([0.0, 0.0, 0.0, 40.0])
    deviation, tails = [], []
    for dt in (5e-4, 2.5e-4):
        err = _estimate_error(d, loop, arm, dt, 0.2, spin, dm)
        deviation.append(abs(_rate(err, dt, 0.01, 0.05) / (-math.log(1 - K * dt) / dt) - 1))
        tails.append(float(np.max(err[int(0.15 / dt):])))
    assert deviation[1] < 0.03 and deviation[1] / deviation[0] == pytest.approx(0.5, abs=0.15), deviation
    assert tails[1] < 0.05 and tails[1] / tails[0] == pytest.approx(0.5, abs=0.1), tails


def test_issue12_6_the_sample_time_limit_of_mom_is_that_of_its_forward_euler_step(paper, loop):
    """The sampled-loop analysis (derive.control.sampling) gives MOM 0.9 x 2/K on the default arm
    (K = 50 1/s: the observer's own forward-Euler bound dt K < 2 is what limits it, the predictive
    law allows 600 ms), the same with --observer implicit; a run just below the raw limit tracks,
    one at 1.5 times it diverges."""
    arm, d = paper
    K = float(dict(d.values)[d.momentum.k[0]])
    lim = limits(d)["mom"]
    assert lim.raw == pytest.approx(2 / K, rel=0.01) and lim.limit == pytest.approx(0.9 * lim.raw)
    assert limits(d, "implicit")["mom"] == lim and limits(d)["mpc"].limit > 10 * lim.limit
    plant_s = replace(arm.simulation, duration=3.0)
    ok = run_compiled(d, loop, true_plant(d, replace(plant_s, sample_time=lim.limit)),
                      replace(plant_s, sample_time=lim.limit), "mom")
    assert ok.failure is None and np.max(np.abs(ok.yd - ok.theta)[-100:]) < 0.05
    fast = replace(plant_s, sample_time=1.5 * lim.raw)
    bad = run_compiled(d, loop, true_plant(d, fast), fast, "mom")
    assert bad.failure is not None or not np.all(np.isfinite(bad.theta)) or np.max(np.abs(bad.yd - bad.theta)) > 1.0


def test_issue12_6_simulate_refuses_a_sample_time_above_the_mom_limit_exit_2(tmp_path, capsys, monkeypatch):
    """K = 2000 1/s: the MOM limit is 0.9 x 2/K = 0.9 ms (to the bisection's 1 %), below the arm's 2 ms; derive simulate
    refuses it (exit 2, one message, nothing written), and check/show's line states it."""
    text = (ARMS_DIR / "glasgow_2link.toml").read_text()
    arm = tmp_path / "fast_gain.toml"
    arm.write_text(text.replace("[controller]", "[controller]\nmomentum_gain = [2000.0, 2000.0]", 1))
    d = derive.derive(derive.load_arm(arm))
    lim = limits(d)["mom"].limit
    assert lim == pytest.approx(0.9 * 2 / 2000, rel=0.01)
    shown = f"{lim * 1e3:.3g} ms"
    assert f"MOM {shown} (momentum observer, the same step in both builds)" in summary_all(d)
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", str(arm), "--controllers", "npid,mom", "--out", str(tmp_path / "sim")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert f"sample_time = 2 ms is above the MOM limit {shown}" in err and "NPID" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fast_gain.toml"]


@pytest.mark.parametrize("value, field, expected", [
    ("[50.0, 0.0]", r"controller\.momentum_gain\[2\]", r"a finite number > 0 \(1/s\)"),
    ("[50.0, -3]", r"controller\.momentum_gain\[2\]", r"a finite number > 0 \(1/s\)"),
    ("[50.0]", r"controller\.momentum_gain", r"an array of 2 numbers, one per joint"),
    ('"fast"', r"controller\.momentum_gain", r"an array of 2 numbers, one per joint"),
    ('[50.0, "x"]', r"controller\.momentum_gain\[2\]", r"a finite number > 0"),
])
def test_issue12_6_a_bad_momentum_gain_is_one_clear_message(tmp_path, value, field, expected):
    text = (ARMS_DIR / "glasgow_2link.toml").read_text()
    path = tmp_path / "bad.toml"
    path.write_text(text.replace("[controller]", f"[controller]\nmomentum_gain = {value}", 1))
    with pytest.raises(SpecError, match=rf"{field}: expected {expected}"):
        derive.load_arm(path)


def test_issue12_6_cli_names_a_bad_momentum_gain_exit_2(tmp_path, capsys, monkeypatch):
    text = (ARMS_DIR / "glasgow_2link.toml").read_text()
    path = tmp_path / "bad.toml"
    path.write_text(text.replace("[controller]", "[controller]\nmomentum_gain = [50.0, 0.0]", 1))
    monkeypatch.chdir(tmp_path)
    assert main(["generate", str(path), "--out", str(tmp_path / "out")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "Traceback" not in err and err.startswith("derive: error: invalid arm description ")
    assert "  - controller.momentum_gain[2]: expected a finite number > 0 (1/s), got 0.0" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


def test_issue12_6_the_arm_files_momentum_gain_reaches_the_law(tmp_path, paper):
    text = (ARMS_DIR / "glasgow_2link.toml").read_text()
    path = tmp_path / "glasgow_2link.toml"
    path.write_text(text.replace("[controller]", "[controller]\nmomentum_gain = [20, 80]", 1))
    d = derive.derive(derive.load_arm(path))
    values = {str(k): v for k, v in d.values}
    assert (values["kr1"], values["kr2"]) == (20, 80)
    assert paper[1].values[-2:] == tuple((k, sp.Integer(50)) for k in d.momentum.k)   # the default K
