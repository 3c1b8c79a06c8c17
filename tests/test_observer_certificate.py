"""The observer for n joints (issue 12, items 1-3): the certificate of the appendix's V for any
arm, the exact two-link region, and the gain synthesis (w = "auto").

Each claim is checked against an independent evaluation: exact region against the closed form
w1 > X theta2m, 4 w2 > w1 + X theta2m; certificates against random states never used by the
branch and bound; convergence by running the generated observer.
"""
from __future__ import annotations

import importlib.util
import tomllib
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import derive
from derive.cli import check as check_cli
from derive.codegen.emit import write_tree
from derive.codegen.files import generate_files
from derive.control import certificate as cert
from derive.control.certificate import report as cert_report
from derive.control.certificate.synthesis import synthesise
from derive.errors import DerivationError
from derive.model.examples import planar_chain_dict
from derive.model.spec import arm_from_dict, resolve_arm_path
from derive.proofs import arm as proofs_arm, certificate as proofs_cert
from derive.proofs.core import Status

from .conftest import derivation


def _arm(name: str | None = None, **controller) -> derive.Arm:
    data = tomllib.loads(resolve_arm_path(name).read_text())
    data["controller"].update(controller)
    return arm_from_dict(data, f"<{name}>")


def _random_states(d, W, box, count: int = 10_000, seed: int = 7) -> float:
    """Smallest eigenvalue of W + W^T - J'(theta, theta') at random theta and theta' inside the box
    (not on its vertices), evaluated from the SymPy J, independently of the certificate's code."""
    q, dq = d.theta, d.dtheta
    Jdot = sum((d.J.diff(a) * b for a, b in zip(q, dq)), sp.zeros(d.n, d.n))
    f = sp.lambdify(q + dq, list(Jdot), "numpy")
    rng = np.random.default_rng(seed)
    th = rng.uniform(-np.pi, np.pi, (count, d.n))
    om = rng.uniform(-1, 1, (count, d.n)) * np.asarray(box)
    entries = [np.broadcast_to(np.asarray(v, dtype=float), (count,)) for v in f(*th.T, *om.T)]
    Jd = np.stack(entries, axis=-1).reshape(count, d.n, d.n)
    W = np.asarray(W, dtype=float)
    return float(np.linalg.eigvalsh(W + W.T - Jd)[:, 0].min())


# -- item 1: the certificate -----------------------------------------------------------------------------
def test_theorem2_certificate_reproduces_the_speed_bound_w1_over_X_for_the_default_arm(paper):
    r = cert_report.report(paper)
    bound = float(paper.speed_bound)                          # w1 / X of (26)
    assert abs(r.speed_sup - bound) < 1e-3 * bound           # the exact region: min(w1, 4 w2 - w1)/X = w1/X here
    assert 0.97 * bound <= r.speed <= bound
    assert r.speed_decision.verdict is cert.Verdict.PROVED
    c = cert.ObserverCertificate(cert_report.inertia_model(paper))
    W = np.array(paper.W.tolist(), dtype=float)
    assert c.decide(W, np.ones(2), 1.01 * bound).verdict is cert.Verdict.REFUTED


def test_symbolic_derivative_bounds_hold_at_random_angles():
    """The Fourier bounds of |d^2 J| (used by the branch and bound) exceed the true values."""
    d = derivation("planar_3link")
    model = cert_report.inertia_model(d)
    q = np.random.default_rng(3).uniform(-np.pi, np.pi, (2000, model.m))
    d2 = np.abs(model.d2J(q)).max(axis=0)
    assert np.all(d2 <= model.second + 1e-12)
    assert np.max(d2 / np.maximum(model.second, 1e-300)) > 0.5   # and not wildly loose


def test_planar_3link_certified_speed_box_is_between_6_and_10_rad_s():
    d = derivation("planar_3link")
    r = cert_report.report(d)
    assert 6.0 < r.speed <= r.speed_sup < 10.0
    assert r.speed_decision.verdict is cert.Verdict.PROVED
    assert _random_states(d, d.W, [r.speed] * 3, count=3000) > 0
    out = proofs_cert.check_certificate(d)
    assert out.status is Status.PROVED and "certified speed box (beta = 0): [6." in out.detail


def test_planar_3link_with_max_joint_speed_above_the_certificate_fails_check_clearly(tmp_path):
    text = resolve_arm_path("planar_3link").read_text().replace("w = [1.0, 2.0, 3.0]",
                                                                "w = [1.0, 2.0, 3.0]\nmax_joint_speed = [10.0, 10.0, 10.0]")
    path = tmp_path / "fast3.toml"
    path.write_text(text)
    d = derive.derive(derive.load_arm(path))
    out = proofs_cert.check_certificate(d)
    assert out.status is Status.REFUTED
    assert "controller.max_joint_speed [10, 10, 10] rad/s is not covered" in out.detail
    theta = [float(v) for s, v in out.counterexample.point if str(s).startswith("theta")]
    assert theta and out.counterexample.lhs[0] < 0
    from derive.proofs.core import exit_code, run
    from derive.proofs.report import render_text

    results = run(proofs_cert.OBLIGATIONS, d)
    assert exit_code(results) == 1
    text = render_text(d, results, 0.0, 1)
    assert "Not proved (these fail the run)" in text and "is not covered by the observer certificate" in text


def test_stated_observer_rate_must_be_certified():
    d = derive.derive(_arm(max_joint_speed=[5.0, 5.0], observer_rate=100.0))
    out = proofs_cert.check_certificate(d)
    assert out.status is Status.REFUTED and "observer_rate = 100 1/s is not certified" in out.detail


def test_a_gain_without_positive_definite_w_plus_wt_is_refuted_even_at_rest():
    d = derive.derive(_arm(w=[1.0, 0.2]))        # 4 w2 < w1: W + W^T is indefinite
    assert proofs_cert.check_certificate(d).status is Status.REFUTED


# -- item 3: the exact two-link region ---------------------------------------------------------------------
def test_exact_region_is_proved_for_the_default_arm(paper):
    out = proofs_cert.check_exact_region(paper)
    assert out.status is Status.PROVED
    assert "iff w1 > X theta2m and 4 w2 > w1 + X theta2m" in out.headline
    assert "(26) implies the region" in out.detail


def test_exact_region_counterexample_point_is_outside_26_and_inside_the_region(paper):
    w1, w2, top = proofs_cert.counterexample_point(paper)
    X = paper.lumped["X"]
    assert w2 < w1 and w1 > X * top and 4 * w2 > w1 + X * top
    # the closed form against the certificate, on both sides of the region's edge 4 w2 = w1 + X theta2m
    c = cert.ObserverCertificate(cert_report.inertia_model(paper))
    W = np.array([[1.0, 0.0], [1.0, 0.5]])
    edge = float(min(w1, 4 * w2 - w1) / X)
    assert c.decide(W, np.ones(2), 0.98 * edge).verdict is cert.Verdict.PROVED
    assert c.decide(W, np.ones(2), 1.02 * edge).verdict is cert.Verdict.REFUTED


def test_w2_below_w1_inside_the_exact_region_is_certified_and_the_observer_converges(tmp_path):
    """w = [1, 0.5] (not (26)), |theta2'| <= 10 rad/s: certified (theorem 2 n/a), and along a
    trajectory at that speed the generated observer's V (a7) of the error e' = B (d - dhat) decays at
    least at the certified rate: V(t) <= V(0) exp(-2 beta t), down to the floor forward Euler leaves."""
    arm = _arm(w=[1.0, 0.5], max_joint_speed=[10.0, 10.0])
    d = derive.derive(arm)
    assert proofs_cert.check_certificate(d).status is Status.PROVED
    assert proofs_cert.check_exact_region(d).status is Status.PROVED
    assert proofs_arm.check_theorem2_arm(d).status is Status.NOT_APPLICABLE
    beta = cert_report.report(d).rate
    assert beta > 1.0
    write_tree(tmp_path / "g", generate_files(d, b""))
    spec = importlib.util.spec_from_file_location("g2", tmp_path / "g" / "python" / f"{arm.name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    q, dq = d.theta, d.dtheta
    Jf = sp.lambdify(q, d.J, "numpy")
    Gf = sp.lambdify(q + dq, d.G, "numpy")
    B = np.array(d.B.tolist(), dtype=float).diagonal()
    W = np.array(d.W.tolist(), dtype=float)
    Wi = np.linalg.inv(W)
    dist = np.array([0.4, -0.25])
    dt, z, V = 2.5e-4, [0.0, 0.0], []
    for k in range(int(5.0 / dt)):
        t = k * dt
        th = np.array([0.5 * np.sin(t), 1.0 - 5.0 * np.cos(2 * t)])          # |theta2'| <= 10 rad/s
        om = np.array([0.5 * np.cos(t), 10.0 * np.sin(2 * t)])
        al = np.array([-0.5 * np.sin(t), 20.0 * np.cos(2 * t)])
        J = np.array(Jf(*th), dtype=float)
        u = (J @ al + np.array(Gf(*th, *om), dtype=float).ravel()) / B - dist   # J theta'' + G = B (u + d)
        e = B * (dist - (np.array(z) + W @ om) / B)                            # e' = B d - (z + p), eq. 22, a1
        V.append(e @ Wi.T @ J @ Wi @ e)
        # the observer step fed u (eq. 21): the dobc kernel at yd = theta, yd' = theta', yd'' = 0 gives
        # a = 0, the dobc_factor kernel the LDL^T factor of J, so the step is z + dt W J^-1 (G - B u - W theta' - z)
        law, a, trig = mod._kernel_dobc(list(th), list(om), list(th), list(om), [0.0, 0.0], z)
        (ldl,) = (mod._kernel_dobc_factor(list(th), trig),)
        (z,) = (mod._kernel_observer(z, a, ldl, law, list(u), (dt,)),)
    V = np.array(V)
    t = np.arange(len(V)) * dt
    floor = V[len(V) // 2:].max()
    assert floor < 1e-6 * V[0]
    assert np.all(V <= 1.02 * V[0] * np.exp(-2 * beta * t) + floor)


# -- item 2: synthesis -----------------------------------------------------------------------------------
def test_w_auto_certifies_the_stated_box_of_planar_3link():
    d = derive.derive(_arm("planar_3link", w="auto", max_joint_speed=[5.0, 5.0, 5.0]))
    syn = d.synthesis
    assert syn is not None and syn.structure == "chen" and syn.decision.verdict is cert.Verdict.PROVED
    W = np.array(d.W.tolist(), dtype=float)
    assert np.allclose(W, np.tril(np.tile(np.diag(W), (3, 1))))         # eq. 25 pattern
    assert proofs_cert.check_certificate(d).status is Status.PROVED
    assert _random_states(d, W, [5.0] * 3, count=3000) > 0
    from derive.codegen.files import observer_manifest
    from derive.codegen.views import observer_notes

    manifest = observer_manifest(d)
    assert manifest["source"] == "synthesised" and manifest["box_rad_per_s"] == [5.0, 5.0, 5.0]
    assert manifest["certificate"]["verdict"] == "proved"
    assert "W synthesised (w = 'auto')" in observer_notes(d)[1] and "[5, 5, 5] rad/s" in observer_notes(d)[1]


def test_synthesis_reaches_the_exact_region_boundary_for_two_links(paper):
    """For two links the smallest ||W||_2 of Chen's structure sits at the exact region's edge:
    w1 -> X theta2m and 4 w2 -> w1 + X theta2m (up to the program's headroom)."""
    syn = synthesise(cert_report.inertia_model(paper), [10.0, 10.0])
    a = float(paper.lumped["X"]) * 10.0
    w1, w2 = float(syn.W[0][0]), float(syn.W[1][1])
    assert a < w1 < 1.1 * a and w1 + a < 4 * w2 < 1.1 * (w1 + a)
    assert w2 < w1 and syn.decision.verdict is cert.Verdict.PROVED


def test_full_w_is_synthesised_and_runs_through_the_generated_code(tmp_path):
    arm = _arm(w="auto", max_joint_speed=[10.0, 10.0], observer_structure="full")
    d = derive.derive(arm)
    assert d.observer.full and d.synthesis.decision.verdict is cert.Verdict.PROVED
    assert [str(s) for s in d.observer.w] == ["W1_1", "W1_2", "W2_1", "W2_2"]
    assert _random_states(d, d.W, [10.0, 10.0], count=2000) > 0
    from derive.codegen.kernels import ParamsMode
    from derive.codegen.reference import Reference

    write_tree(tmp_path / "g", generate_files(d, b"", "double", ParamsMode.RUNTIME))
    spec = importlib.util.spec_from_file_location("gf", tmp_path / "g" / "python" / f"{arm.name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert "W1_2" in mod.PARAMS
    ref = Reference(d)
    x = [0.3, -0.7, 0.1, 0.2, 1.1, -0.4, 0.5, 0.0, 0.2, -0.3]
    state = mod.DobcState()
    state.z = [0.2, -0.1]
    code, u, _ = mod.dobc_step(mod.Params(), state, mod.Input(x[0:2], x[2:4], x[4:6], x[6:8], x[8:10]), 1e-3)
    ru, rz = ref.dobc_step([0.2, -0.1], x, 1e-3)
    assert code == 0
    assert np.allclose(u, [float(v) for v in ru], rtol=1e-12, atol=1e-12)
    assert np.allclose(state.z, [float(v) for v in rz], rtol=1e-12, atol=1e-12)


def test_synthesised_w_for_a_planar_4_link_chain_holds_at_10000_random_states():
    data = planar_chain_dict(4)
    arm = arm_from_dict(data, "<chain4>")
    d = derive.derive(arm)
    box = [2.0] * 4
    syn = synthesise(cert_report.inertia_model(d), box, budget=4000)
    W = np.array([[float(x) for x in row] for row in syn.W])
    assert syn.decision.verdict in (cert.Verdict.PROVED, cert.Verdict.UNPROVEN)   # budget-bound in this test
    assert _random_states(d, W, box, count=10_000) > 0


def test_synthesis_rejects_an_unknown_structure(paper):
    with pytest.raises(DerivationError, match="structure 'diagonal' is not one of"):
        synthesise(cert_report.inertia_model(paper), [1.0, 1.0], structure="diagonal")


def test_check_lists_the_new_obligations():
    ids = [ob.id for ob in check_cli.obligations()]
    assert "observer-certificate" in ids and "exact-region" in ids


# -- derive tune ---------------------------------------------------------------------------------------------
def test_tune_prints_the_w_line_and_writes_json(tmp_path, capsys):
    from derive.cli import main

    out = tmp_path / "tune.json"
    assert main(["tune", "--speed", "10,10", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "certificate: proved" in text and "[controller] w = [0.41" in text
    from derive import jsonio

    doc = jsonio.loads(out.read_text())  # strict RFC 8259 (issue 10, item 6)
    assert doc["certificate"] == "proved" and doc["box_rad_per_s"] == [10.0, 10.0]


@pytest.mark.parametrize("args, fragment", [
    (["tune", "planar_3link"], "expected a speed box, from --speed or the arm's controller.max_joint_speed"),
    (["tune", "--speed", "1,x"], "--speed: expected 2 comma-separated finite numbers > 0"),
    (["tune", "--speed", "1,2,3"], "--speed: expected 2 comma-separated"),
    (["tune", "--speed", "1,1", "--rate", "-1"], "--rate: expected a finite number >= 0"),
    (["tune", "--speed", "1,1", "--json", "/nonexistent-folder/x.json"], "expected a file in an existing folder"),
])
def test_tune_rejects_bad_options_with_exit_2(args, fragment, capsys):
    from derive.cli import main

    assert main(args) == 2
    assert fragment in capsys.readouterr().err


def test_synthesised_w_for_the_6_joint_ur5_is_proved_and_holds_at_10000_random_states():
    """Item 2 on a spatial 6-joint URDF arm: W synthesised for |theta'_k| <= 1 rad/s (full
    structure), then W + W^T - J'(theta, theta') > 0 at 10,000 random states inside the box,
    with J' from CasADi's automatic differentiation of the derived J (not the certificate's code)."""
    from .test_spatial_dynamics import casadi_function, vendored_arm

    arm = vendored_arm("ur5")
    d = derive.derive(arm)
    box = [1.0] * 6
    syn = synthesise(cert_report.inertia_model(d), box, structure="full")
    assert syn.decision.verdict is cert.Verdict.PROVED   # by the split certificate (5 angles: 3 inner)
    W = np.array([[float(x) for x in row] for row in syn.W])
    f = casadi_function(d.dynamics).map(10_000)
    rng = np.random.default_rng(17)
    th, om = rng.uniform(-np.pi, np.pi, (10_000, 6)), rng.uniform(-1, 1, (10_000, 6))
    Jd = np.array(f(th.T, om.T)[4]).reshape(6, 10_000, 6).transpose(1, 0, 2)   # 10,000 x 6 x 6
    low = np.linalg.eigvalsh(W + W.T - (Jd + Jd.transpose(0, 2, 1)) / 2)[:, 0].min()
    assert low > 0
    assert np.linalg.eigvalsh(-(Jd + Jd.transpose(0, 2, 1)) / 2)[:, 0].min() < 0   # W is needed: J' alone fails


# -- issue 19 item 5: one-joint arms, prismatic coordinates; the bounds the decisions rest on ---------------------
CASES = Path(__file__).parent / "data" / "urdf" / "round3"
URDF = Path(__file__).parent / "data" / "urdf"


@pytest.mark.parametrize("path", [Path(__file__).parent / "data" / "f6_small_arm.toml", CASES / "tool.toml"])
def test_one_joint_arm_certificate_is_decided_exactly(path, capsys):
    """J constant (one joint): J' = 0, so (*) is 2 w - 2 beta J > 0 at every speed; the rate is w / J exactly."""
    d = derive.derive(derive.load_arm(path))
    out = proofs_cert.check_certificate(d)
    rate = float(d.W[0, 0] / d.J[0, 0])
    assert out.status is Status.PROVED and "J does not depend on the joint coordinates" in out.detail
    assert f"every rate beta < {rate:.4g} 1/s" in out.detail
    assert check_cli.run(check_cli_args(path)) == 0
    assert "observer-certificate" in capsys.readouterr().out


def check_cli_args(path):
    import argparse

    return argparse.Namespace(arm=str(path), paper=False, report=None, json=None, strict=False)


def test_one_joint_arm_certificate_refutes_a_stated_rate_above_w_over_j():
    d = derive.derive(_arm_file(CASES / "tool.toml", observer_rate=50.0))
    out = proofs_cert.check_certificate(d)
    assert out.status is Status.REFUTED and "observer_rate = 50 1/s is not certified" in out.detail


def _arm_file(path: Path, **controller) -> derive.Arm:
    data = tomllib.loads(path.read_text())
    data["controller"].update(controller)
    return arm_from_dict(data, str(path), base_dir=path.parent)


def test_tune_on_a_one_joint_arm_needs_a_rate_and_then_gives_about_beta_j(capsys):
    from derive.cli import main

    assert main(["tune", str(CASES / "tool.toml"), "--speed", "5"]) == 2
    assert "there is no smallest W at rate 0; give a rate beta > 0" in capsys.readouterr().err
    assert main(["tune", str(CASES / "tool.toml"), "--speed", "5", "--rate", "2"]) == 0
    out = capsys.readouterr().out
    J = float(derive.derive(derive.load_arm(CASES / "tool.toml")).J[0, 0])
    w = float(out.split("w = [")[1].split("]")[0])
    assert 2 * J < w <= 2 * J * 1.03 and "N m s/rad" in out and "certificate: proved" in out


@pytest.mark.parametrize("name", ["polar", "synthetic"])
def test_prismatic_coordinates_are_certified_over_their_travel(name):
    """J depends on a prismatic coordinate (metres, over its limits): J's series is exact in powers of the travel,
    the bounds hold at random states, and the certificate proves what the random states do not refute."""
    path = CASES / "polar.toml" if name == "polar" else URDF / "synthetic.toml"
    d = derive.derive(derive.load_arm(path))
    model = cert_report.inertia_model(d)
    assert any(not c.angle for c in model.deps) and model.fourier is None
    rng = np.random.default_rng(3)
    lo = np.array([s[0] for s in model.spans])
    hi = np.array([s[1] for s in model.spans])
    q = lo + (hi - lo) * rng.random((500, model.m))
    d2 = np.abs(model.d2J(q)).max(axis=0)
    assert np.all(d2 <= model.second + 1e-12) and np.max(d2 / np.maximum(model.second, 1e-300)) > 0.3
    out = proofs_cert.check_certificate(d)
    assert out.status is Status.PROVED
    r = cert_report.report(d)
    assert 0.9 * r.speed_sup <= r.speed <= r.speed_sup


def test_fourth_derivative_bounds_hold_at_random_angles(paper):
    """The second-order remainder of the branch and bound rests on |d^4 J| bounds from J's series."""
    model = cert_report.inertia_model(derivation("planar_3link"))
    rng = np.random.default_rng(5)
    q = rng.uniform(-np.pi, np.pi, (400, model.m))
    h = 1e-4
    for k in range(model.m):   # d^4 J / dq_k dq_i dq_j dq_l by central differences of d^3 J
        step = h * np.eye(model.m)[k]
        fourth = np.abs((model.d3J(q + step) - model.d3J(q - step)) / (2 * h)).max(axis=0)
        assert np.all(fourth <= model.fourth[k] * (1 + 1e-6) + 1e-9)
        assert np.max(fourth / np.maximum(model.fourth[k], 1e-300)) > 0.5   # and not wildly loose


# -- issue 23: the adversarial search against a proved box --------------------------------------------------
def test_adversarial_search_finds_no_violation_inside_the_proved_box_of_planar_3link_and_one_above_its_supremum():
    """Eq. 40's obligation (the appendix's V decays): at the largest box the certificate proves for
    planar_3link's W, L-BFGS-B from the worst of 10,000 random states finds N positive definite; at
    1.05 times the numeric supremum it finds a state where N is not (the search can fail)."""
    from derive.control.certificate.adversary import search

    d = derive.derive(derive.load_arm("planar_3link"))
    r = cert_report.report(d)
    assert r.speed_decision.verdict is cert.Verdict.PROVED
    model = cert_report.inertia_model(d)
    inside = search(model, r.W, [r.speed * s for s in r.shape])
    assert inside.low > 0 and inside.low <= inside.sampled
    above = search(model, r.W, [1.05 * r.speed_sup * s for s in r.shape])
    assert above.low < 0
