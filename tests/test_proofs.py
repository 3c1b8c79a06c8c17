"""``derive check``: the paper's claims as proof obligations (issue 3).

Every project obligation is proved for the default arm; the printed equations
that are wrong are refuted with counterexamples that these tests re-evaluate
independently; deliberately wrong statements are refuted; an undecidable claim
is ``unproven``; the CLI writes JSON and Markdown and sets the exit code.
"""
from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import pytest
import sympy as sp

from derive import jsonio
from derive.cli import check
from derive.proofs import arm as proofs_arm, dynamics as proofs_dynamics, paper as pp, project as proofs_project
from derive.proofs.exact import Field, Undecidable
from derive.dynamics.identities import is_zero
from derive.proofs.core import Kind, Obligation, Outcome, Result, Status, equal, exit_code, positive, run

from .conftest import derivation

REPO = Path(__file__).resolve().parents[1]
ERRATA = {"eq29", "eq31", "eq41", "a14", "a7-a8"}


@pytest.fixture(scope="module")
def results(paper):
    """All obligations on the default arm, run once."""
    return {r.obligation.id: r for r in check.check(paper)}


def _project_only(d) -> tuple[Result, ...]:
    return run(proofs_project.OBLIGATIONS + proofs_arm.OBLIGATIONS + proofs_dynamics.OBLIGATIONS, d)


def _point(cex) -> dict:
    return {s: v for s, v in cex.point}


def _num(m: sp.MatrixBase, point: dict) -> sp.Matrix:
    """Exact value of m at point (sin/cos of sums expanded first)."""
    return sp.Matrix(m).applyfunc(lambda x: sp.expand_trig(sp.sympify(x)).xreplace(point))


# -- the default arm -------------------------------------------------------------------------------
def test_every_project_obligation_is_proved_for_the_default_arm(results):
    project = [r for r in results.values() if r.obligation.kind is Kind.PROJECT]
    assert len(project) == 14
    # the paper's arm states no [payload] range: payload-range does not apply (tests/test_payload_limit.py)
    expected = {r.obligation.id: Status.NOT_APPLICABLE if r.obligation.id == "payload-range" else Status.PROVED
                for r in project}
    assert {r.obligation.id: r.outcome.status for r in project} == expected
    assert exit_code(tuple(results.values())) == 0


def test_paper_errata_are_the_refuted_printed_equations_and_the_rest_is_proved(results):
    paper = {k: r.outcome.status for k, r in results.items() if r.obligation.kind is Kind.PAPER}
    assert {k for k, s in paper.items() if s is Status.REFUTED} == ERRATA
    assert all(s is Status.PROVED for k, s in paper.items() if k not in ERRATA)
    for k in ERRATA:
        assert results[k].erratum and not results[k].fails_run
        assert results[k].outcome.corrected and results[k].outcome.counterexample is not None


def test_eq31_printed_initial_estimate_is_refuted(results, paper):
    """(30) with (31) differs from (32) by B^-1 W C^-1 (K2 - I) e(0); the arm's K2 = 3 I."""
    out = results["eq31"].outcome
    assert out.status is Status.REFUTED
    assert "K2 e(0)" in out.corrected and "K2 = 3 I" in out.detail
    P, pt = pp.paper(), _point(out.counterexample)
    S = P.syms
    v = lambda name: sp.Matrix([pt.get(s, 7) for s in S[name]])  # absent: any value  # noqa: E731
    B = sp.Matrix(2, 2, [pt[S[f"b{i}{j}"]] for i in (1, 2) for j in (1, 2)])
    C = sp.Matrix(2, 2, [pt[S[f"c{i}{j}"]] for i in (1, 2) for j in (1, 2)])
    W = sp.Matrix([[pt[S["w1"]], 0], [pt[S["w1"]], pt[S["w2"]]]])
    k1, k2 = pt[S["k1"]], pt[S["k2"]]
    assert (B, C, k2) == (paper.B, paper.C, 3)
    M = B.inv() * W * C.inv()
    dhat0 = -M * v("de0") - M * v("e0")                                           # (31)
    eq30 = -M * (v("de") + k2 * v("e") + k1 * v("int_e")) + M * v("de0") + M * k2 * v("e0") + dhat0
    eq32 = -M * (v("de") + k2 * v("e") + k1 * v("int_e"))
    assert eq30 != eq32
    assert eq30 - eq32 == M * (k2 - 1) * v("e0")
    assert (eq30, eq32) == (out.counterexample.lhs, out.counterexample.rhs)


def test_eq29_line3_printed_yd_dot_is_refuted_and_yd_ddot_proved(results):
    out = results["eq29"].outcome
    assert out.status is Status.REFUTED
    assert out.detail.startswith("line 3 refuted (corrected: -B^-1 L (J C^-1 (K1 e + K2 e' + C J^-1 G + y_d'')")
    assert "y_d'' where y_d' is printed: proved)" in out.detail
    assert "line 1, line 2, line 4, line 5 proved" in out.detail


def test_a7_dV_line1_is_refuted_and_lines_2_to_4_are_proved(results):
    """Printed second term W^-T L^T J W^-1 versus the derived L^T W^-T J W^-1, evaluated by hand."""
    out = results["a7-a8"].outcome
    assert out.status is Status.REFUTED and "line 2, line 3, line 4 proved" in out.detail
    P, pt = pp.paper(), _point(out.counterexample)
    S = P.syms
    th2, dth2 = P.theta2, S["dtheta"][1]
    c = sp.cos(th2)
    J = sp.Matrix([[S["j1"] + 2 * S["X"] * c, S["j2"] + S["X"] * c], [S["j2"] + S["X"] * c, S["j3"]]])
    W = sp.Matrix([[S["w1"], 0], [S["w1"], S["w2"]]])
    ep = sp.Matrix(S["ep"])
    Wi, L = W.inv(), W * J.inv()
    Jdot = J.diff(th2) * dth2
    printed = (-ep.T * Wi.T * J * Wi * L * ep - ep.T * Wi.T * L.T * J * Wi * ep + ep.T * Wi.T * Jdot * Wi * ep)
    derived = 2 * ep.T * Wi.T * J * Wi * (-L * ep) + ep.T * Wi.T * Jdot * Wi * ep    # M symmetric
    lhs, rhs = _num(printed, pt), _num(derived, pt)
    assert lhs != rhs
    assert (lhs, rhs) == (out.counterexample.lhs, out.counterexample.rhs)


def test_eq41_and_a14_signs_of_e1_are_refuted_and_eq42_is_proved(results):
    assert results["eq41"].outcome.corrected == "J(theta) theta'' + G = B (u* + e1)"
    assert "-C J^-1(theta) B e1" in results["a14"].outcome.corrected
    assert results["eq42"].outcome.status is Status.PROVED
    for k in ("eq41", "a14"):
        cex = results[k].outcome.counterexample
        assert cex.lhs != cex.rhs


def test_theorem2_and_a8_to_a12_are_proved_symbolically(results):
    for k in ("a8", "a9", "a10", "a11", "a12", "theorem2", "theorem1"):
        assert results[k].outcome.status is Status.PROVED, results[k].outcome.detail
    assert "M22 = 2 w1 > 0" in results["a8"].outcome.detail
    assert results["theorem2"].outcome.evidence is None           # a proof, not samples
    arm = results["theorem2-arm"].outcome
    assert "w1/X = 24.6888 rad/s" in arm.detail and "smallest eigenvalue" in arm.evidence


# -- deliberately wrong statements -------------------------------------------------------------------
def test_eq16_perturbed_gain_is_refuted_with_a_counterexample_that_violates_it(paper):
    wrong = dataclasses.replace(paper, K1=paper.K1 * sp.Rational(101, 100))
    res = {r.obligation.id: r for r in run(proofs_project.OBLIGATIONS[:2], wrong)}
    gains, loop = res["K1-K2"].outcome, res["u*-loop"].outcome
    assert gains.status is Status.REFUTED and gains.counterexample.lhs != gains.counterexample.rhs
    assert loop.status is Status.REFUTED and exit_code(tuple(res.values())) == 1
    # e'' + K2 e' + K1 e of the real closed loop (12), d = 0, at the point, with the perturbed K1
    pt = _point(loop.counterexample)
    s = paper.dynamics.sym
    ddtheta = _num(paper.J, pt).inv() * _num(paper.B * paper.u_star - paper.G, pt)
    err = _num(sp.Matrix(s.ddyd) + paper.K2 * sp.Matrix(s.de) + wrong.K1 * sp.Matrix(s.e), pt) - paper.C * ddtheta
    assert err != sp.zeros(2, 1) and err == loop.counterexample.lhs


def test_eq21_observer_with_a_flipped_sign_is_refuted_with_a_counterexample(paper):
    s = paper.dynamics.sym
    obs = paper.observer
    flipped = obs.J_solve_rhs + 2 * obs.p                          # G - B u + p - z
    wrong = dataclasses.replace(paper, observer=dataclasses.replace(obs, J_solve_rhs=flipped))
    out = run([o for o in proofs_project.OBLIGATIONS if o.id == "observer-error"], wrong)[0].outcome
    assert out.status is Status.REFUTED
    pt = _point(out.counterexample)
    Ji, W, B = _num(paper.J, pt).inv(), paper.W, paper.B
    d = sp.Matrix([sp.Symbol(f"d{i + 1}", real=True) for i in range(2)])
    zdot = W * Ji * _num(paper.numeric(flipped), pt)
    ddtheta = Ji * _num(B * (sp.Matrix(s.u) + d) - paper.G, pt)
    e1dot = -B.inv() * (zdot + W * ddtheta)                        # dhat = B^-1 (z + W theta')
    rhs = -B.inv() * W * Ji * B * _num(d - paper.dhat, pt)
    assert e1dot != rhs and (e1dot, rhs) == (out.counterexample.lhs, out.counterexample.rhs)


def test_undecidable_claim_is_unproven_and_fails_the_run(paper):
    x = sp.Symbol("x", real=True)
    t = sp.Symbol("t", real=True)
    F = Field([x], ())

    def sqrt_claim(d) -> Outcome:     # sqrt(x^2) = |x|: true, outside the rational class
        return equal(F, F.matrix([[sp.sqrt(x ** 2)]]), F.matrix([[sp.Abs(x)]]), proved="", refuted="")

    def sign_claim(d) -> Outcome:     # 2 + sin t cos t > 0: true, not settled by assumptions
        return positive(2 + sp.sin(t) * sp.cos(t), what="2 + sin t cos t", proved="",
                        sampler=lambda k: {t: sp.Rational(k, 7)})

    obs = [Obligation("sqrt", "test", Kind.PROJECT, "sqrt(x^2) = |x|", sqrt_claim),
           Obligation("sign", "test", Kind.PAPER, "2 + sin t cos t > 0", sign_claim)]
    res = run(obs, paper)
    assert [r.outcome.status for r in res] == [Status.UNPROVEN, Status.UNPROVEN]
    assert "cannot decide" in res[0].outcome.detail
    assert "min 1.5" in res[1].outcome.evidence                    # evidence, apart from the status
    assert all(r.fails_run for r in res) and exit_code(res) == 1
    with pytest.raises(Undecidable, match="not a rational function"):
        F(sp.sqrt(x))
    with pytest.raises(Undecidable, match="outside sin/cos"):
        Field([t], (t,))(t * sp.sin(t))


def test_exit_code_counts_paper_refutations_as_errata_only():
    ok = Outcome(Status.PROVED, "")
    bad = Outcome(Status.REFUTED, "")
    ob = lambda kind: Obligation("x", "eq. 1", kind, "", lambda d: ok)  # noqa: E731
    assert exit_code([Result(ob(Kind.PAPER), bad, 0.0), Result(ob(Kind.PROJECT), ok, 0.0)]) == 0
    assert exit_code([Result(ob(Kind.PROJECT), bad, 0.0)]) == 1
    assert exit_code([Result(ob(Kind.PROJECT), Outcome(Status.NOT_APPLICABLE, "n = 3"), 0.0)]) == 0


# -- other arms ------------------------------------------------------------------------------------
def test_three_links_theorem2_not_applicable_energy_and_skew_symmetry_proved():
    res = {r.obligation.id: r.outcome for r in _project_only(derivation("planar_3link"))}
    assert res["theorem2-arm"].status is Status.NOT_APPLICABLE and "two links" in res["theorem2-arm"].detail
    assert res["energy"].status is Status.PROVED and "(n = 3)" in res["energy"].detail
    assert res["skew-symmetry"].status is Status.PROVED
    assert all(o.status is Status.PROVED for k, o in res.items() if k != "theorem2-arm")


def test_vertical_arm_project_obligations_are_proved_with_gravity():
    res = _project_only(derivation("vertical_2link"))
    assert exit_code(res) == 0 and all(r.outcome.status is Status.PROVED for r in res)


def test_eq26_hypothesis_failing_for_an_arm_is_unproven_and_fails_the_run(paper):
    ctl = dataclasses.replace(paper.arm.controller, max_joint_speed=(Fraction(0), Fraction(30)))
    wrong = dataclasses.replace(paper, arm=dataclasses.replace(paper.arm, controller=ctl))
    out = proofs_arm.check_theorem2_arm(wrong)
    assert out.status is Status.UNPROVEN and "30 rad/s is not below w1/X" in out.detail


# -- the decision procedure --------------------------------------------------------------------------
@pytest.mark.parametrize("expr", [
    "sin(2*a) - 2*sin(a)*cos(a)", "cos(a + b) - cos(a)*cos(b) + sin(a)*sin(b)", "sin(a)**2 + cos(a)**2 - 1",
    "x*sin(a)/(1 + x**2) - sin(a)", "(sin(a) - cos(b))**3 / (2 + x**2)", "cos(a)**4 - (1 - sin(a)**2)**2"])
def test_field_zero_test_agrees_with_identities_trig_normal(expr):
    a, b, x = sp.symbols("a b x", real=True)
    e = sp.sympify(expr, locals={"a": a, "b": b, "x": x})
    F = Field([a, b, x], (a, b))
    assert F.is_zero(F(e)) == is_zero(e, (a, b))


# -- rendering and the command line --------------------------------------------------------------------


def _cli_check(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "derive", "check", *args], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(REPO)},
                          preexec_fn=lambda: os.umask(0o022))


def test_cli_check_paper_writes_json_and_report_without_an_arm(tmp_path):
    """The printed equations are decided once, in generic symbols: no arm's value in any counterexample."""
    out_json, out_md = tmp_path / "check.json", tmp_path / "check.md"
    proc = _cli_check(tmp_path, "--paper", "--json", str(out_json), "--report", str(out_md))
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    doc = jsonio.loads(out_json.read_text(encoding="utf-8"))
    assert doc["seconds"] >= 0 and doc["exit_code"] == 0 and doc["arm"] is None
    obs = {o["id"]: o for o in doc["obligations"]}
    assert {o["kind"] for o in obs.values()} == {"paper"} and len(obs) == 22
    assert {"id", "paper_ref", "status", "detail", "corrected"} <= set(obs["eq31"])
    assert obs["eq31"]["status"] == "refuted" and "K2 e(0)" in obs["eq31"]["corrected"]
    assert "this arm has" not in obs["eq31"]["detail"]
    assert obs["eq31"]["counterexample"]["lhs_float"] != obs["eq31"]["counterexample"]["rhs_float"]
    assert all(not o["counterexample"]["from_arm"] for o in obs.values() if o["counterexample"])
    assert {k for k, o in obs.items() if o["status"] == "refuted"} == ERRATA
    assert obs["theorem1"]["paper_ref"] == "theorem 1" and obs["theorem1"]["corrected"] is None
    report = out_md.read_text(encoding="utf-8")
    assert report.startswith("# derive check: the paper\n")
    assert "| `eq31` | eq. 31-32 | paper | **refuted** |" in report and "$$" in report
    assert proc.stdout.startswith("derive check --paper (the paper's printed equations): 22 obligations: "
                                  "17 proved, 5 refuted (5 errata in the paper), 0 unproven, 0 n/a")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["check.json", "check.md"]
    assert [out_json.stat().st_mode & 0o777, out_md.stat().st_mode & 0o777] == [0o644, 0o644]   # the umask's


def test_cli_check_arm_runs_only_its_own_obligations(tmp_path):
    """derive check ARM: the project obligations (the paper's are arm-independent: --paper)."""
    out_json = tmp_path / "check.json"
    proc = _cli_check(tmp_path, str(REPO / "tests" / "data" / "my3.toml"), "--json", str(out_json))
    assert proc.returncode == 0, proc.stderr
    doc = jsonio.loads(out_json.read_text(encoding="utf-8"))
    assert (doc["arm"], doc["n"], doc["exit_code"]) == ("my3", 3, 0)
    obs = {o["id"]: o for o in doc["obligations"]}
    assert {o["kind"] for o in obs.values()} == {"project"} and len(obs) == 14
    assert obs["theorem2-arm"]["status"] == "n/a" and obs["exact-region"]["status"] == "n/a"
    assert obs["observer-certificate"]["status"] == "proved"
    assert "the printed (31) is not this arm's dhat(0) (K2 = 25/2 I;" in obs["dhat0"]["detail"]
    assert proc.stdout.startswith("derive check my3 (3 joints): 14 obligations: 11 proved, 0 refuted, "
                                  "0 unproven, 3 n/a")
    assert "derive check --paper decides them" in proc.stdout


def test_check_without_an_arm_runs_the_paper_obligations_generically():
    """check(None) selects the paper's obligations; an arm-dependent remark needs an arm."""
    from derive.proofs import paper_claims

    assert paper_claims.paper_base(None) == {}
    out = paper_claims.check_eq31(None)
    assert out.status is Status.REFUTED and "this arm" not in out.detail
