"""Cost polynomial in the joints (issue 33): the bounds that replace J's exact series past its budget
are sound, a 12-joint chain goes through init's numbers, and show states what it shows.

No timing assertions (benchmarks/scaling.py measures); the slow ones run by make fuzz (-m slow).
"""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import sympy as sp

from benchmarks.chains import snake_urdf
from derive.cli.display import TERM_CAP, shown, term_bound
from derive.control.certificate import report as cert_report, inertia
from derive.control.certificate import ObserverCertificate, Verdict
from derive.control.certificate.interval import interval_bounds, markov_factor
from derive.control.certificate.norm_bound import norm_lower_bound, norm_speed_bound, sign_patterns
from derive.dynamics.dag import matrix_xreplace
from derive.dynamics.equations import derive_dynamics
from derive.model.spec import load_arm


def _arm(tmp_path, n: int, **kw):
    (tmp_path / "a.urdf").write_text(snake_urdf(n, **kw), encoding="utf-8")
    text = "\n".join(['[arm]', f'name = "snake{n}"', 'urdf = "a.urdf"', 'base_link = "base"', f'tip_link = "l{n}"',
                      'gravity = 9.81', 'gravity_direction = [0, 0, -1]', 'actuation = "torque"',
                      *(['[[motor]]', 'gear_ratio = 1.0'] * n), '[controller]', 'T1 = 0.0', 'T2 = 0.2',
                      f'w = {[0.5] * n}', ''])
    (tmp_path / "a.toml").write_text(text, encoding="utf-8")
    return load_arm(tmp_path / "a.toml")


def _model(arm, budget=None, monkeypatch=None):
    dyn = derive_dynamics(arm)
    J = matrix_xreplace(dyn.J, dict(dyn.values))
    if budget is not None:
        monkeypatch.setattr(inertia, "SERIES_BUDGET", budget)
    return inertia.InertiaModel(J, inertia.joint_coordinates(arm, dyn.sym.theta))


def test_interval_bounds_hold_sin_cos_products():
    x, y = sp.symbols("x y")
    (lo, hi), = interval_bounds([sp.cos(x) * sp.sin(y) + 2 * sp.cos(x) ** 2], {x: (-4, 4), y: (-4, 4)})
    assert lo <= -1 and hi >= 3
    with pytest.raises(ValueError, match="no rule for"):
        interval_bounds([sp.exp(x)], {x: (0, 1)})
    assert markov_factor(2, 1) == 4 and markov_factor(2, 3) == 0


def test_interval_gradients_enclose_sampled_derivatives():
    """Forward-mode interval differentiation: every sampled derivative lies in its enclosure (sums,
    products, integer powers, 1/x, sin, cos of sums), and a constant has a zero gradient."""
    from derive.control.certificate.interval import interval_gradients

    a, b, x = sp.symbols("a b x", real=True)
    exprs = [sp.sin(a) * sp.cos(b) * x + 3 * x ** 2, sp.cos(a + b) ** 2, 1 / (2 + sp.sin(a)), sp.Integer(4)]
    boxes = {a: (-1.5, 1.5), b: (-1.5, 1.5), x: (0.5, 1.0)}
    G = interval_gradients(exprs, boxes, [a, b, x])
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-1.5, 1.5, 4000), rng.uniform(-1.5, 1.5, 4000), rng.uniform(0.5, 1, 4000)])
    for i, e in enumerate(exprs):
        for k, c in enumerate((a, b, x)):
            v = np.broadcast_to(sp.lambdify((a, b, x), sp.diff(e, c), "numpy")(*pts.T), (4000,))
            assert G[i, k, 0] <= v.min() + 1e-12 and v.max() <= G[i, k, 1] + 1e-12, (i, k)
    assert np.all(G[3] == 0) and G[0, 2, 0] > 2.0   # d/dx >= 3 x 2 x 0.5 - 1 > 2: not merely a sign


def test_degree_bounds_sound_against_the_series(tmp_path, monkeypatch):
    """Past the budget (forced here on 5 joints) the bounds from sup |J| and the degrees hold wherever
    the exact series' do (they are larger), and 0 where an entry does not depend on a coordinate."""
    arm = _arm(tmp_path, 5)
    exact = _model(arm)
    cheap = _model(arm, 0, monkeypatch)
    assert exact.bounded_by == "series" and cheap.bounded_by == "degrees" and cheap.fourier is None
    for a, b in ((exact.second, cheap.second), (exact.third, cheap.third), (exact.fourth, cheap.fourth)):
        big = a > 1e-6 * a.max()
        assert np.all(b[big] >= a[big] * (1 - 1e-9))
    q = np.random.default_rng(1).uniform(-np.pi, np.pi, (2000, cheap.m))
    assert np.all(np.abs(cheap.J(q)).max(axis=0) <= cheap.supremum * (1 + 1e-9))
    lo, hi = np.array(cheap.spans).T   # |dJ/dq_k|: within the joint limits (interval arithmetic there)
    q = lo + (hi - lo) * np.random.default_rng(2).random((2000, cheap.m))
    assert np.all(np.abs(cheap.dJ(q)).max(axis=0) <= cheap.first() * (1 + 1e-9))


def test_norm_bound_sound_at_samples(tmp_path, monkeypatch):
    """What the one-matrix bound proves holds at sampled states and vertices (N itself)."""
    arm = _arm(tmp_path, 5)
    model = _model(arm, 0, monkeypatch)
    W = 40.0 * model.J(np.zeros((1, model.m)))[0]
    shape = np.full(5, 2.0)
    v = 0.5 * norm_speed_bound(model, W, shape, 0.0)
    bound = norm_lower_bound(model, W, shape, v, 0.0)
    assert bound > 0
    cert = ObserverCertificate(model, shape)
    q = cert.samples(256, exact=True)
    sc = np.outer(model.scale, model.scale)
    lam = np.linalg.eigvalsh(cert.matrices(W, shape, v, 0.0, q, exact=True) * sc)[..., 0]
    assert lam.min() >= bound * (1 - 1e-9)


def test_sign_patterns_paired_and_capped():
    for m in (3, 12):
        s = sign_patterns(m)
        assert s.shape[0] <= 256 and np.array_equal(s[::-1], -s)


def test_twelve_joints_certificate_states_a_sound_box(tmp_path):
    """A 12-joint chain: J's bounds from its degrees (5^11 x 144 series values are past the budget),
    the largest certified box proved and below the numeric supremum; the speed box's vertices sampled."""
    arm = _arm(tmp_path, 12)
    model = _model(arm)
    assert model.bounded_by == "degrees" and model.m == 11
    shape = np.full(12, 2.0)
    W = 100.0 * model.J(np.zeros((1, model.m)))[0]
    cert = ObserverCertificate(model, shape)
    assert cert.norm and cert.all_signs.shape[0] <= 256
    v, dec = cert_report.largest_proved_speed(cert, W, shape, samples=256)
    assert dec is not None and dec.verdict is Verdict.PROVED and dec.cells == 1
    assert 0 < v < cert.speed_supremum(W, shape, 0.0, 256, exact=True)


def test_show_states_the_zero_pose_past_the_cap():
    x = sp.symbols("x0:9")
    big = sp.Mul(*[sp.cos(a) + sp.sin(a) for a in x]) ** 2   # degree 2 in 9 angles: 5^9 terms at most
    assert term_bound([big], x) > TERM_CAP
    out = shown(sp.Matrix([[big]]), x, exact=False)
    assert "at θ = 0" in out.note and float(out.value[0, 0]) == 1.0


def test_an_unproven_stated_box_past_the_one_matrix_bound_says_so(monkeypatch):
    """Decided by the one-matrix bound (one cell), an unproven stated box says what bound it is beyond,
    not "not decided in 1 cells" nor "cell budget"."""
    from types import SimpleNamespace

    from derive.control.certificate import Decision
    from derive.proofs import certificate as proof

    dec = Decision(Verdict.UNPROVEN, 1, None, ((0.0,) * 11, (2.0,) * 11), 41.0, 0.1)
    report = cert_report.Report(W=((1.0,),), shape=(2.0,) * 12, stated=True, speed=0.0031, speed_sup=8.2,
                                speed_decision=dec, rate=0.0, rate_sup=1.0, rate_decision=None,
                                stated_decision=dec, unbounded=(), seconds=0.1, one_bound=True)
    monkeypatch.setattr(cert_report, "report", lambda d: report)
    d = SimpleNamespace(n=12, arm=SimpleNamespace(controller=SimpleNamespace(observer_rate=0.0)))
    out = proof.check_certificate(d)
    assert out.status.value == "unproven"
    assert "one-matrix bound" in out.detail and "cells" not in out.detail.split(";")[0]
    assert "cell budget" not in out.summary and "0.0031 x the stated box" in out.detail


@pytest.mark.slow
def test_twelve_joint_init_and_show(tmp_path):
    """derive init and show on the 12-joint chain exit 0 (minutes on a loaded machine)."""
    (tmp_path / "s.urdf").write_text(snake_urdf(12), encoding="utf-8")
    for argv in (["init", "s.urdf", "--out", "s.toml"], ["show", "s.toml", "--no-cache"]):
        run = subprocess.run([sys.executable, "-m", "derive", *argv], cwd=tmp_path, capture_output=True, text=True)
        assert run.returncode == 0, run.stderr[-2000:]


def test_simulate_refuses_a_run_past_its_samples_before_it_starts():
    """600 million steps of 12 joints (snake12's starter sample time, 5e-08 s, over 30 s) are refused with
    the numbers and the ways on, not a MemoryError; a 7-joint arm's 1 ms over 30 s passes."""
    from types import SimpleNamespace

    from derive.cli.simulate import too_many
    from derive.errors import DeriveError

    with pytest.raises(DeriveError, match=r"600,000,000 steps of 12 joints.*raise sample_time.*at most 0\.14 s"):
        too_many(SimpleNamespace(duration=30.0, sample_time=5e-8), 12)
    too_many(SimpleNamespace(duration=30.0, sample_time=1e-3), 7)


def test_identities_over_j_and_g_are_not_attempted_past_field_joints():
    """Past FIELD_JOINTS the field identities (eq. 15, 21-25, 29, 33-38, 41-42) are unproven with the limit
    stated, before any conversion; the gains' (no J, no G) are still decided."""
    from types import SimpleNamespace

    from derive.proofs import project

    called = []
    heavy = project.formal_first(lambda d: called.append(d))
    out = heavy(SimpleNamespace(n=project.FIELD_JOINTS + 1))
    assert not called and out.status.value == "unproven"
    assert f"past {project.FIELD_JOINTS} joints" in out.detail and "not attempted" in out.summary
    light = project.formal_first(lambda d: called.append(d) or "decided", note=False)
    assert light(SimpleNamespace(n=20, formal_view=None)) == "decided" and called


def test_expm_in_chunks_gives_the_bits_of_one_pass(monkeypatch):
    """The zero-order hold's exp of a stack in chunks, each at the whole stack's scaling: the same bits as
    one pass (a stack whose norms differ by 1e4, so one matrix sets the scaling of all), and e^A itself."""
    import scipy.linalg

    import importlib

    zoh = importlib.import_module("derive.control.sampling.zoh")   # the package's name zoh is the function

    rng = np.random.default_rng(3)
    M = rng.standard_normal((37, 6, 6)) * np.logspace(-2, 2, 37)[:, None, None]
    whole = zoh.expm(M)
    monkeypatch.setattr(zoh, "CHUNK_ELEMENTS", 5 * 36)
    chunked = zoh.expm(M)
    assert np.array_equal(whole, chunked)
    np.testing.assert_allclose(chunked[0], scipy.linalg.expm(M[0]), rtol=1e-12, atol=1e-14)


def test_simulate_stiffest_mode_walks_the_dynamics_dag_not_its_tree(tmp_path, monkeypatch):
    """Issue 33: simulate's stiffest mode (the RK4 substeps) put the values into J with SymPy's
    ``xreplace``, a walk of J's tree: the 7-joint chain in 4-digit decimal frames did not finish in
    12 min (3.9 million node visits on 5 joints). It now rebuilds each shared subexpression once
    (derive.dynamics.program.dag_xreplace), and its J is the plant's."""
    from derive.control.pipeline import derive as derive_arm
    from derive.sim.plant import Plant, stiffest_mode, true_plant

    d = derive_arm(_arm(tmp_path, 5, decimal=True))
    visits = []
    tree_walk = sp.Basic._xreplace
    monkeypatch.setattr(sp.Basic, "_xreplace", lambda self, rule: visits.append(1) or tree_walk(self, rule))
    mode = stiffest_mode(d, d.arm.simulation)
    monkeypatch.undo()
    assert not visits
    plant = Plant(d, true_plant(d, d.arm.simulation))
    q = np.array([d.arm.simulation.initial_theta], dtype=float)
    J = plant.matrices(q, np.zeros_like(q))[0][0]
    damping = plant.viscous + plant.coulomb / 0.01   # the torque-driven arm: no back-EMF
    assert np.isclose(mode["rate"], np.max(np.linalg.eigvals(np.linalg.solve(J, np.diag(damping))).real), rtol=1e-9)


def test_the_corpus_decimal_chain_is_the_benchmarks_text():
    """tests/data/urdf/corpus/snake7_decimal.urdf (make corpus) is benchmarks.chains' 7-joint chain in 4-digit
    decimal frames, the arm the scaling section measures (issue 33)."""
    from pathlib import Path

    corpus = Path(__file__).parent / "data" / "urdf" / "corpus"
    assert (corpus / "snake7_decimal.urdf").read_text(encoding="utf-8") == snake_urdf(7, decimal=True)
