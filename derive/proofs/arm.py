"""Obligations on the arm's derived dynamics and theorem 2 for it (kind ``project``).

* theorem 2 for the arm (n = 2 only; n/a otherwise): J has the form (a6) and
  is positive definite for every theta2 (so V of (a7) is), the derivative of
  V along the derived observer's error is the final form of the proof with the
  arm's X, w1, w2, and (26) holds for |theta2'| < w1 / X (printed);
* (J' - 2C skew, the energy balance and the RNEA law: derive.proofs.dynamics.)
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import sympy as sp

from derive.dynamics.planar import a6_form
from derive.proofs.exact import Field
from derive.proofs.core import Kind, Obligation, Outcome, Status, combine, equal, not_applicable, positive
from derive.proofs.project import Env, vec

if TYPE_CHECKING:
    from derive.control.pipeline import Derivation


def inertia_positive(lumped: dict, theta2: sp.Symbol) -> Outcome:
    """J of (a6) is positive definite for every theta2: j3 > 0 and det J > 0 on c = cos(theta2) in [-1, 1].

    det J = f(c) is a polynomial of degree <= 2 with leading coefficient -kappa
    (kappa = X^2 >= 0), so f(c) = f(-1) al/2 + f(1) be/2 + kappa al be with
    al = 1 - c >= 0, be = 1 + c >= 0, al + be = 2; hence
    f = m + (f(-1) - m) al/2 + (f(1) - m) be/2 + kappa al be, m = min f(+-1),
    whose sign SymPy reads off.
    """
    c = sp.Symbol("c", real=True)
    al, be = sp.symbols("alpha beta", nonnegative=True)
    J = a6_form(lumped, theta2).xreplace({sp.cos(theta2): c})
    f = sp.expand(J.det())
    fm, fp = f.subs(c, -1), f.subs(c, 1)
    poly = sp.Poly(f, c)
    kappa = -poly.coeff_monomial(c ** 2)
    low = sp.Min(fm, fp)
    form = low + (fm - low) * al / 2 + (fp - low) * be / 2 + kappa * al * be
    same = poly.degree() <= 2 and sp.expand(form.xreplace({al: 1 - c, be: 1 + c}) - f) == 0
    if not same:
        return Outcome(Status.UNPROVEN, "det J is not a concave quadratic in cos(theta2); positivity not settled")
    det = positive(form, what="det J(theta)",
                   proved=f"det J = {sp.N(fm, 6)} (1 - c)/2 + {sp.N(fp, 6)} (1 + c)/2 + {sp.N(kappa, 6)} (1 - c^2) > 0 "
                          "for c = cos(theta2) in [-1, 1]")
    j3 = positive(J[1, 1], what="j3", proved=f"j3 = {sp.N(J[1, 1], 6)} > 0")
    return combine([j3, det], prefix="J(theta) > 0 for every theta2 (so V of (a7) is positive definite): ")


def _speed_evidence(X: sp.Expr, w1: sp.Expr, w2: sp.Expr, bound: sp.Expr) -> str:
    """Smallest eigenvalue of the matrix of (a8) over sampled theta2 and |theta2'| < bound."""
    lows = []
    for k in range(400):
        th = -math.pi + 2 * math.pi * (k % 40) / 40
        v = float(bound) * (-0.999 + 1.998 * (k // 40) / 9)
        qn = float(X) * v * math.sin(th)
        a11, a12, a22 = float(2 * w2) + 2 * (float(w2 / w1) - 1) * qn, -float(w1) + qn, float(2 * w1)
        tr, det = a11 + a22, a11 * a22 - a12 ** 2
        lows.append((tr - math.sqrt(max(tr * tr - 4 * det, 0.0))) / 2)
    return f"400 samples of theta2 and |theta2'| < 0.999 w1/X: smallest eigenvalue of M is {min(lows):.4g} > 0"


def check_theorem2_arm(d: Derivation) -> Outcome:
    """Theorem 2 for this arm: (a6), J > 0, dV/dt of the derived observer, bound of (26)."""
    if d.n != 2:
        return not_applicable(f"theorem 2 is stated for two links; this arm has {d.n}")
    if d.lumped is None:
        return not_applicable("theorem 2's proof rests on the planar 2-link form (a6); this arm is not a planar chain")
    if d.observer.full:
        return not_applicable("theorem 2 is stated for W of eq. (25); this arm has a full W (see observer-certificate)")
    if not d.W[1, 1] >= d.W[0, 0] > 0:
        return not_applicable(f"(26) needs w2 >= w1 > 0; this arm has w1 = {d.W[0, 0]}, w2 = {d.W[1, 1]}: theorem 2 as "
                              "printed does not apply (exact-region and observer-certificate decide)")
    ep = vec("ep", 2)
    E = Env(d, ep, d.L)
    F = E.F
    th2, lump = d.theta[1], d.lumped
    X, w1, w2 = lump["X"], d.W[0, 0], d.W[1, 1]
    parts = [equal(F, F.matrix(d.J), F.matrix(a6_form(lump, th2)),
                   proved="J has the form (a6): " + ", ".join(f"{k} = {sp.N(v, 6)}" for k, v in lump.items()),
                   refuted="J does not have the form (a6)"),
             inertia_positive(lump, th2)]
    Wi = d.W.inv()
    V = F.matrix(ep.T * Wi.T * d.J * Wi * ep)
    rates = {**dict(zip(ep, F.entries(F.matrix(-d.L * ep)))), th2: F(d.dtheta[1])}
    q = X * d.dtheta[1] * sp.sin(th2)
    M = sp.Matrix([[2 * w2 + 2 * (w2 / w1 - 1) * q, -w1 + q], [-w1 + q, 2 * w1]])
    parts.append(equal(F, F.d_dt(V, rates), F.matrix(-(ep.T * M * ep) / (w1 * w2)),
                       labels=("dV/dt (derived observer)", "final form before (a8)"),
                       proved="along the derived observer's e' = B e1 (e'' = -L e'), dV/dt = -(e')^T M e' / (w1 w2), "
                              "M of (a8) with this arm's X, w1, w2",
                       refuted="dV/dt of the derived observer differs from the form of the proof"))
    hyp = (Outcome(Status.PROVED, f"(26): w2 = {w2} >= w1 = {w1} > 0") if w2 >= w1 > 0 else
           Outcome(Status.UNPROVEN, f"(26) needs w2 >= w1 > 0; this arm has w1 = {w1}, w2 = {w2}"))
    if not X > 0:
        return combine(parts + [hyp, Outcome(Status.UNPROVEN, f"X = {X} is not positive: (26) gives no speed bound")])
    bound = w1 / X
    parts += [hyp, Outcome(Status.PROVED, f"(26) holds, so dV/dt < 0 (theorem 2), for every theta2 and "
                                 f"|theta2'| < w1/X = {sp.N(bound, 6)} rad/s",
                                 evidence=_speed_evidence(X, w1, w2, bound),
                                 latex=(rf"|\dot\theta_2| < \frac{{w_1}}{{X}} = {sp.latex(bound)} \approx "
                                        rf"{float(bound):.6g}\ \mathrm{{rad/s}}",))]
    speeds = d.arm.controller.max_joint_speed
    if speeds is not None:
        top = sp.Rational(speeds[1].numerator, speeds[1].denominator)
        parts.append(Outcome(Status.PROVED, f"the stated max |theta2'| = {top} rad/s is below it") if top < bound else
                     Outcome(Status.UNPROVEN, f"the stated max |theta2'| = {top} rad/s is not below w1/X: (26) fails "
                             "there and theorem 2 does not cover it"))
    return combine(parts, summary=f"J > 0, (a6) form, dV/dt = -(e')^T M e' / (w1 w2); (26) for |theta2'| < w1/X = {sp.N(bound, 6)} rad/s")


OBLIGATIONS = (
    Obligation("theorem2-arm", "theorem 2, eq. 26, a6-a8", Kind.PROJECT,
               "for this arm: J of (a6) form and > 0, dV/dt of the derived observer, the speed bound of (26)",
               check_theorem2_arm),
)
