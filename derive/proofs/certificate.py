"""Obligations on the observer beyond the paper (kind ``project``): the certificate for n joints
and the exact two-link region.

* ``observer-certificate`` (every arm): the appendix's V = e'^T W^-T J W^-1 e' decays at rate
  beta wherever W + W^T - J'(theta, theta') - 2 beta J(theta) is positive definite
  (derive.control.certificate, decided soundly for every theta by branch and bound). Reported:
  the largest certified speed box at beta = 0 and the largest certified rate on the stated box
  (at rest when the arm states none). Proved when the stated box (and the stated
  ``observer_rate``) are covered; refuted, with a point, when N is not positive definite there;
  unproven when the cell budget runs out (numeric evidence given).
* ``exact-region`` (two links, W of eq. 25): for the V of (a7), dV/dt < 0 for every theta2 and
  |theta2'| <= theta2m exactly when w1 > X theta2m and 4 w2 > w1 + X theta2m; (26) implies it, and
  w2 < w1 is allowed (a counterexample point to (26) is certified).

Derivation of the exact region: with x = W^-1 e', dV/dt = -x^T N x, N = W + W^T - J' and, by (a6),
J' = -q [[2, 1], [1, 0]], q = X theta2' sin(theta2), so N = [[2 (w1 + q), w1 + q], [w1 + q, 2 w2]].
By Sylvester N > 0 iff w1 + q > 0 and det N = (w1 + q)(4 w2 - w1 - q) > 0, i.e. iff -w1 < q and
q < 4 w2 - w1. q ranges over [-a, a], a = X theta2m (theta2 = +-pi/2 reaches both ends), so the
condition for every state is w1 > a and 4 w2 > w1 + a.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import sympy as sp

from derive.control import certificate as cert

from derive.control.certificate import norm_bound
from derive.control.certificate import report as cert_report
from derive.dynamics.planar import a6_form
from derive.proofs.core import Counterexample, Kind, Obligation, Outcome, Status, combine, not_applicable, positive

if TYPE_CHECKING:
    from derive.control.pipeline import Derivation

w1, w2, X = sp.symbols("w1 w2 X", positive=True)
a = sp.Symbol("a", nonnegative=True)               # X theta2m
q = sp.Symbol("q", real=True)                      # X theta2' sin(theta2)
eta, zeta = sp.symbols("eta zeta", positive=True)  # slacks
t, u, c = sp.symbols("t u c", nonnegative=True)    # q = a (t - u), t + u = 1; c = w2 - w1 >= 0


def _fmt(x: float) -> str:
    return f"{x:.4g}"


def _box(shape, v: float) -> str:
    return "[" + ", ".join(_fmt(v * s) for s in shape) + "] rad/s"


def check_certificate(d: Derivation) -> Outcome:
    """The certificate (*) on the stated box and rate; the largest certified box and rate."""
    r = cert_report.report(d)
    if r.unbounded:
        return Outcome(Status.UNPROVEN, f"J depends on the prismatic coordinates {', '.join(r.unbounded)}, which have "
                       "no limits: the certificate needs their ranges (give the joints limits)")
    if r.constant:
        return _constant(d, r)
    shape = r.shape
    unit = "the stated max_joint_speed" if r.stated else "|theta'_k| <= v for every k"
    speed = (f"certified speed box (beta = 0): {_box(shape, r.speed)}" + (f" = {r.speed:.4g} x the stated box"
             if r.stated else "") + f" (numeric supremum {_box(shape, r.speed_sup)})")
    where = "on the stated box" if r.stated else "at rest (theta' = 0)"
    rate = f"certified rate beta = {r.rate:.4g} 1/s {where} (numeric supremum {r.rate_sup:.4g} 1/s)"
    evidence = (f"{speed}; {rate}; W = {[list(map(_fmt, row)) for row in r.W]}; "
                f"{r.speed_decision.cells if r.speed_decision else 0} cells at the speed bound, {r.seconds:.2f} s")
    summary = f"V of (a7), n = {d.n}: {speed.split(' (numeric')[0]}; {rate.split(' (numeric')[0]}"
    if r.stated:
        dec = r.stated_decision
        need = float(d.arm.controller.observer_rate)
        if dec.verdict is cert.Verdict.REFUTED:
            theta, dtheta = dec.point
            deps = cert_report.inertia_model(d).deps
            pt = tuple((sp.Symbol(str(c.symbol)), sp.Float(x, 6)) for c, x in zip(deps, theta))
            pt += tuple((sp.Symbol(f"dtheta{c.index + 1}"), sp.Float(x, 6))
                        for c, x in zip(deps, dtheta))
            cex = Counterexample(pt, sp.Matrix([dec.low]), sp.Matrix([0]), "lambda_min(W + W^T - J')", "0")
            return Outcome(Status.REFUTED, f"controller.max_joint_speed {_box(shape, 1.0)} is not covered by the observer "
                           f"certificate: W + W^T - J'(theta, theta') has eigenvalue {dec.low:.4g} < 0 at a vertex of the "
                           f"box; {speed}; lower max_joint_speed or raise W (w = 'auto' chooses one)",
                           counterexample=cex, evidence=evidence,
                           summary=f"stated max_joint_speed not covered: {speed.split(' (numeric')[0]}")
        if dec.verdict is cert.Verdict.UNPROVEN and r.one_bound:
            return Outcome(Status.UNPROVEN, "the stated box is beyond what the one-matrix bound proves (past "
                           f"{norm_bound.MAX_VERTEX_DEPS} coordinates without J's series: lambda_min(W + W^T) - "
                           "v ||sum_k s_k |dJ/dq_k| bound||_2 > 0, derive.control.certificate.norm_bound; sound, not exact); numeric "
                           f"evidence: smallest eigenvalue {dec.low:.4g} at the sampled points and vertices; {speed}",
                           evidence=evidence, summary="stated box: unproven (beyond the one-matrix bound)")
        if dec.verdict is cert.Verdict.UNPROVEN:
            return Outcome(Status.UNPROVEN, f"the certificate on the stated box was not decided in {dec.cells} cells; "
                           f"numeric evidence: smallest eigenvalue {dec.low:.4g} at the sampled centres; {speed}",
                           evidence=evidence, summary="stated box: unproven (cell budget)")
        if need > 0 and r.rate < need:
            return Outcome(Status.UNPROVEN if r.rate_sup >= need else Status.REFUTED,
                           f"controller.observer_rate = {need:g} 1/s is not certified on the stated box: {rate}",
                           evidence=evidence, summary=f"stated observer_rate {need:g} 1/s not certified")
        return Outcome(Status.PROVED, f"W + W^T - J' > 0 on the stated box {_box(shape, 1.0)} for every theta "
                       f"(margin {dec.margin:.3g}, {dec.cells} cells); {speed}; {rate}", evidence=evidence,
                       summary=summary)
    if r.speed_sup <= 0:
        return Outcome(Status.REFUTED, "W + W^T is not positive definite (or not beyond 2 beta J): V of (a7) does not "
                       "decrease even at rest; choose another W (w = 'auto' chooses one)", evidence=evidence,
                       summary="W + W^T not positive definite: no speed certified")
    if r.speed <= 0:
        return Outcome(Status.UNPROVEN, f"no speed box was decided within the cell budget; {speed}", evidence=evidence)
    return Outcome(Status.PROVED, f"{speed}; {rate} ({unit}; no max_joint_speed stated)", evidence=evidence,
                   summary=summary)


def _constant(d: Derivation, r: cert_report.Report) -> Outcome:
    """J depends on no joint coordinate (one joint, or J constant): J' = 0, so (*) is the single matrix
    inequality W + W^T - 2 beta J > 0, the same at every theta and speed: decided exactly."""
    W = [list(map(_fmt, row)) for row in r.W]
    need = float(d.arm.controller.observer_rate)
    head = (f"J does not depend on the joint coordinates, so J' = 0 and (*) is W + W^T - 2 beta J > 0 at every theta "
            f"and every speed (W = {W})")
    evidence = f"{head}; {r.seconds:.2f} s"
    if r.speed_decision.verdict is not cert.Verdict.PROVED:
        return Outcome(Status.REFUTED, f"{head}: W + W^T is not positive definite, so V of (a7) does not decrease "
                       "even at rest; choose another W", evidence=evidence,
                       summary="J constant: W + W^T not positive definite")
    rate = f"every rate beta < {r.rate:.4g} 1/s (the smallest eigenvalue of J^-1/2 (W + W^T) J^-1/2 over 2)"
    if need > 0 and not need < r.rate:
        return Outcome(Status.REFUTED, f"controller.observer_rate = {need:g} 1/s is not certified: {head}, which "
                       f"holds for {rate}", evidence=evidence, summary=f"stated observer_rate {need:g} 1/s not certified")
    return Outcome(Status.PROVED, f"{head}: holds at every speed, for {rate}", evidence=evidence,
                   summary=f"V of (a7), n = {d.n}, J constant: every speed, beta < {r.rate:.4g} 1/s")


# -- the exact two-link region ------------------------------------------------------------------
def n_matrix(qq: sp.Expr = q) -> sp.Matrix:
    """N = W + W^T - J' for W of (25) and J of (a6), J' = -q [[2, 1], [1, 0]]."""
    return sp.Matrix([[2 * (w1 + qq), w1 + qq], [w1 + qq, 2 * w2]])


def _form(d: Derivation) -> Outcome:
    """N = W + W^T - J' for (a6) in symbols: J' = theta2' dJ/dtheta2 = -q [[2, 1], [1, 0]]."""
    th2, dth2 = sp.symbols("theta2 dtheta2", real=True)
    j1, j2, j3 = sp.symbols("j1 j2 j3", positive=True)
    J = a6_form({"j1": j1, "j2": j2, "j3": j3, "X": X}, th2)
    W = sp.Matrix([[w1, 0], [w1, w2]])
    N = W + W.T - dth2 * J.diff(th2)
    ok = (N - n_matrix(X * dth2 * sp.sin(th2))).applyfunc(sp.expand) == sp.zeros(2, 2)
    return Outcome(Status.PROVED if ok else Status.REFUTED,
                   "N = W + W^T - J' = [[2 (w1 + q), w1 + q], [w1 + q, 2 w2]], q = X theta2' sin(theta2), for J of (a6)"
                   if ok else "N does not have the stated form")


def _sylvester() -> Outcome:
    """det N = (w1 + q)(4 w2 - w1 - q)."""
    ok = sp.expand(n_matrix().det() - (w1 + q) * (4 * w2 - w1 - q)) == 0
    return Outcome(Status.PROVED if ok else Status.REFUTED,
                   "N11 = 2 (w1 + q) and det N = (w1 + q)(4 w2 - w1 - q): by Sylvester N > 0 iff w1 + q > 0 and "
                   "4 w2 > w1 + q" if ok else "det N is not (w1 + q)(4 w2 - w1 - q)")


def _sufficient() -> Outcome:
    """w1 = a + eta, 4 w2 = w1 + a + zeta => N11 > 0 and det > 0 for every q in [-a, a]."""
    hyp = {w1: a + eta, w2: (2 * a + eta + zeta) / 4}
    first = sp.expand((w1 + q).xreplace(hyp).xreplace({q: a * (t - u)}) + a * (t + u - 1))
    second = sp.expand((4 * w2 - w1 - q).xreplace(hyp).xreplace({q: a * (t - u)}) + a * (t + u - 1))
    return combine([positive(first, what="w1 + q", proved=f"w1 + q = {first} > 0"),
                    positive(second, what="4 w2 - w1 - q", proved=f"4 w2 - w1 - q = {second} > 0")],
                   prefix="sufficient (w1 = a + eta, 4 w2 = w1 + a + zeta, q = a (t - u), t + u = 1): ")


def _necessary() -> Outcome:
    """At theta2 = pi/2, theta2' = -theta2m (q = -a): N11 = 2 (w1 - a); at q = +a: det = (w1 + a)(4 w2 - w1 - a)."""
    n11 = sp.expand(n_matrix(-a)[0, 0] - 2 * (w1 - a))
    det = sp.expand(n_matrix(a).det() - (w1 + a) * (4 * w2 - w1 - a))
    ok = n11 == 0 and det == 0
    return Outcome(Status.PROVED if ok else Status.REFUTED,
                   "necessary: q = -a (theta2 = pi/2, theta2' = -theta2m) gives N11 = 2 (w1 - a), so w1 > a; q = +a gives "
                   "det N = (w1 + a)(4 w2 - w1 - a) with w1 + a > 0, so 4 w2 > w1 + a" if ok else "the end points fail")


def _paper_implies() -> Outcome:
    """(26): w2 = w1 + c (c >= 0), w1 = a + eta => w1 > a and 4 w2 - w1 - a > 0."""
    hyp = {w1: a + eta, w2: a + eta + c}
    gap = sp.expand((4 * w2 - w1 - a).xreplace(hyp))
    return combine([positive(sp.expand((w1 - a).xreplace(hyp)), what="w1 - a", proved="w1 - a = eta > 0"),
                    positive(gap, what="4 w2 - w1 - a", proved=f"4 w2 - w1 - a = {gap} > 0")],
                   prefix="(26) implies the region (w2 = w1 + c, c >= 0; w1 = a + eta): ")


def counterexample_point(d: Derivation) -> tuple[sp.Rational, sp.Rational, sp.Expr]:
    """(w1, w2, theta2m): w1 = 1, w2 = 1/2 < w1, theta2m = 1 / (2 X) (a = 1/2): in the region, not in (26)."""
    return sp.Integer(1), sp.Rational(1, 2), 1 / (2 * d.lumped["X"])


def check_exact_region(d: Derivation) -> Outcome:
    """The exact region, (26) inside it, and a certified point outside (26)."""
    if d.n != 2 or d.observer.full:
        return not_applicable("the exact region is for two links with W of eq. (25)"
                              + (f"; this arm has {d.n} joints" if d.n != 2 else "; this arm has a full W"))
    if d.lumped is None:
        return not_applicable("the exact region rests on the planar 2-link form (a6); this arm is not a planar chain")
    Xa = d.lumped["X"]
    parts = [_form(d), _sylvester(), _sufficient(), _necessary(), _paper_implies()]
    if Xa > 0:
        p1, p2, top = counterexample_point(d)
        inside = p1 > Xa * top and 4 * p2 > p1 + Xa * top
        dec = cert.ObserverCertificate(cert_report.inertia_model(d)).decide(
            np.array([[1.0, 0.0], [1.0, 0.5]]), np.array([float(top), float(top)]), 1.0, 0.0)
        ok = inside and not (p2 >= p1) and dec.verdict is cert.Verdict.PROVED
        parts.append(Outcome(Status.PROVED if ok else Status.REFUTED,
                             f"w1 = 1, w2 = 1/2, theta2m = 1/(2X) = {float(top):.4g} rad/s: in the region (1 > 1/2, 2 > 3/2), "
                             f"not in (26) (w2 < w1); the certificate proves it ({dec.cells} cells)"))
        w1a, w2a = d.W[0, 0], d.W[1, 1]
        bound = sp.Min(w1a, 4 * w2a - w1a) / Xa
        parts.append(Outcome(Status.PROVED, f"for this arm (X = {float(Xa):.6g}, w1 = {w1a}, w2 = {w2a}): dV/dt < 0 exactly "
                             f"for |theta2'| < min(w1, 4 w2 - w1)/X = {float(bound):.6g} rad/s (26 gives w1/X)"))
    return combine(parts, summary="V of (a7): dV/dt < 0 for all states iff w1 > X theta2m and 4 w2 > w1 + X theta2m; "
                                  "(26) implies it; w2 < w1 allowed")


OBLIGATIONS = (
    Obligation("observer-certificate", "theorem 2, eq. a7, generalised", Kind.PROJECT,
               "W + W^T - J'(theta, theta') - 2 beta J(theta) > 0 for every theta and theta' in the stated box "
               "(V of (a7) decays at rate beta), decided soundly; the largest certified box and rate", check_certificate),
    Obligation("exact-region", "theorem 2, eq. 26, a7-a12", Kind.PROJECT,
               "two links: dV/dt < 0 for every state iff w1 > X theta2m and 4 w2 > w1 + X theta2m; (26) implies it",
               check_exact_region),
)
