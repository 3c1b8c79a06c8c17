"""Obligations on the arm's derived dynamics and theorem 2 for it (kind ``project``).

* theorem 2 for the arm (n = 2 only; n/a otherwise): J has the form (a6) and
  is positive definite for every theta2 (so V of (a7) is), the derivative of
  V along the derived observer's error is the final form of the proof with the
  arm's X, w1, w2, and (26) holds for |theta2'| < w1 / X (printed);
* J' - 2 C is skew-symmetric (C the Christoffel matrix of the derivation);
* energy: d/dt (1/2 theta'^T J theta') = theta'^T (B u - G_nc) along (12) with
  d = 0, where G_nc = g(theta) + F_v theta' is the part of G that does work
  (gravity and damping; G - G_nc = C theta' is workless).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import flint
import sympy as sp

from derive.dynamics.planar import a6_form
from derive.proofs.exact import Field
from derive.proofs.torus import Torus, torus_for
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


def _witness(d: Derivation, exprs: list, labels: tuple[str, str], k: int) -> str:
    """The two sides of a refuted identity at a seeded state (numbers, for the message)."""
    import numpy as np

    from derive.dynamics.program import free_symbols, lambdify

    syms = sorted(free_symbols(exprs), key=sp.default_sort_key)
    rng = np.random.default_rng(0)
    point = rng.uniform(-1.0, 1.0, len(syms))
    values = lambdify(syms, exprs)(*point)
    at = ", ".join(f"{x} = {v:.3g}" for x, v in zip(syms, point))
    return f"at {at}: {labels[0]} = {float(values[k]):.10g}, {labels[1]} = {float(values[k + len(exprs) // 2]):.10g}"


def _rates(T: Torus, d: Derivation) -> dict:
    """q_i' for every coordinate: through c_i, s_i for an angle, the variable otherwise."""
    return {q: T.var(dq) for q, dq in zip(d.theta, d.dtheta)}


def check_skew(d: Derivation) -> Outcome:
    """J' - 2 C is skew-symmetric for the derived J and its Coriolis matrix C (J' = C + C^T).

    Decided exactly on the torus of the angles (:mod:`derive.proofs.torus`)."""
    C = d.numeric(d.dynamics.coriolis)
    n = d.n
    T = torus_for([d.J, C], d.dynamics.angles, d.dtheta)
    J, Cc = T.convert(list(d.J)), T.convert(list(C))
    rates = _rates(T, d)
    for i in range(n):
        for j in range(i, n):
            lhs = T.d_dt(J[i * n + j], rates)
            if not T.is_zero(lhs - Cc[i * n + j] - Cc[j * n + i]):
                Jdot = sp.Matrix(n, n, lambda a, b: sum(sp.diff(d.J[a, b], q) * dq for q, dq in zip(d.theta, d.dtheta)))
                witness = _witness(d, [Jdot[i, j], C[i, j] + C[j, i]], ("J'", "C + C^T"), 0)
                return Outcome(Status.REFUTED, f"J' - 2C is not skew-symmetric: J'[{i + 1}][{j + 1}] != (C + C^T)"
                               f"[{i + 1}][{j + 1}]; {witness}")
    return Outcome(Status.PROVED, f"N = J' - 2C satisfies N + N^T = 0 (n = {n}, J' = C + C^T decided exactly on "
                   "the torus of the angles)")


def check_energy(d: Derivation) -> Outcome:
    """d/dt (1/2 theta'^T J theta') = theta'^T (B u - G_nc) along (12), d = 0, with
    G_nc = g(theta) + F_v theta' (the part of G that does work); J = J^T; g a gradient."""
    n = d.n
    dth = sp.Matrix(d.dtheta)
    u = sp.Matrix(d.dynamics.sym.u)
    grav = d.numeric(d.dynamics.gravity)
    G_nc = grav + d.numeric(d.dynamics.damping) * dth
    T = torus_for([d.J, d.G, G_nc, d.B], d.dynamics.angles, list(d.dtheta) + list(u))
    J, G, Gnc, g = (T.convert(list(m)) for m in (d.J, d.G, G_nc, grav))
    Bu = T.convert(list(d.B * u))
    parts = []
    sym = all(T.is_zero(J[i * n + j] - J[j * n + i]) for i in range(n) for j in range(i + 1, n))
    parts.append(Outcome(Status.PROVED, "J = J^T") if sym else Outcome(Status.REFUTED, "J is not symmetric"))
    rates = _rates(T, d)
    qd = [T.var(x) for x in d.dtheta]
    # chain rule: dT/dt = theta'^T J theta'' + 1/2 theta'^T J' theta', and J theta'' = B u - G (12)
    dT = T.zero
    for i in range(n):
        dT = dT + qd[i] * (Bu[i] - G[i])
        for j in range(n):
            dT = dT + T.d_dt(J[i * n + j], rates) * qd[i] * qd[j] * flint.fmpq(1, 2)
    power = T.zero
    for i in range(n):
        power = power + qd[i] * (Bu[i] - Gnc[i])
    main = T.is_zero(dT - power)
    parts.append(Outcome(Status.PROVED, f"d/dt (1/2 theta'^T J theta') = theta'^T (B u - g(theta) - F_v theta') "
                                        f"(n = {n})") if main else
                 Outcome(Status.REFUTED, "the energy identity fails: G - G_nc is not workless"))
    grad = all(T.is_zero(T.diff(g[i], d.theta[j]) - T.diff(g[j], d.theta[i])) for i in range(n) for j in range(i + 1, n))
    parts.append(Outcome(Status.PROVED, "g(theta) is a gradient (d g/d theta symmetric)") if grad else
                 Outcome(Status.REFUTED, "g(theta) is not a gradient"))
    return combine(parts, summary=f"d/dt (1/2 theta'^T J theta') = theta'^T (B u - g - F_v theta') (n = {n})")


def check_rnea_law(d: Derivation) -> Outcome:
    """The law the kernels compute, u* = B^-1 (J a + G) by one recursive Newton-Euler pass
    at a = C^-1 (K1 e + K2 e' + yd'') (derive.control.mpc.u_star_rnea), is eq. (15)'s u*."""
    n = d.n
    rnea = d.numeric(d.mpc.u_star_rnea)
    s = d.dynamics.sym
    extra = list(d.dtheta) + list(s.e) + list(s.de) + list(s.ddyd)
    T = torus_for([rnea, d.u_star], d.dynamics.angles, extra)
    for i, (a, b) in enumerate(zip(T.convert(list(rnea)), T.convert(list(d.u_star)))):
        if not T.is_zero(a - b):
            witness = _witness(d, [rnea[i], d.u_star[i]], ("RNEA law", "eq. 15"), 0)
            return Outcome(Status.REFUTED, f"the RNEA law differs from eq. (15) in u*[{i + 1}]; {witness}")
    return Outcome(Status.PROVED, f"B^-1 RNEA(theta, theta', a) = B^-1 (J a + G) = u* of (15) (n = {n}), "
                   "decided exactly: the generated law is the derived one")


OBLIGATIONS = (
    Obligation("theorem2-arm", "theorem 2, eq. 26, a6-a8", Kind.PROJECT,
               "for this arm: J of (a6) form and > 0, dV/dt of the derived observer, the speed bound of (26)",
               check_theorem2_arm),
    Obligation("skew-symmetry", "eq. 12", Kind.PROJECT, "J' - 2C is skew-symmetric", check_skew),
    Obligation("energy", "eq. 12", Kind.PROJECT, "d/dt (1/2 theta'^T J theta') = theta'^T (B u - G_nc)", check_energy),
    Obligation("rnea-law", "eq. 15", Kind.PROJECT,
               "the generated law (one RNEA pass) equals u* of (15): RNEA(theta, theta', a) = J a + G", check_rnea_law),
)
