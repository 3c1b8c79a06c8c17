"""Obligations on the paper's printed equations, sections 4.1, 4.3 and 4.4 (kind ``paper``).

Each check transcribes the equation as printed (:mod:`derive.proofs.paper`) and
compares it with what follows from the equations it cites; a refuted one is an
erratum, reported with the statement that holds. The checks are arm-independent
(generic two-link symbols): ``check(None)`` decides them once (``derive check
--paper``); given an arm, its values only seed the counterexample search and
never change a status. Section 4.2 and the proof of
theorem 2 are in :mod:`derive.proofs.observer`.
"""
from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import sympy as sp

from derive.proofs import paper as pp
from derive.proofs.core import Kind, Line, Obligation, Outcome, Status, combine, equal, lines, positive

if TYPE_CHECKING:
    from derive.control.pipeline import Derivation

T1, T2 = sp.Symbol("T1", nonnegative=True), sp.Symbol("T2", positive=True)
GAP = sp.Symbol("h", positive=True)   # T2 = T1 + h: the hypothesis T1 < T2 as a sign fact


def paper_base(d: Derivation | None) -> dict:
    """The arm's values for the paper's generic symbols (n = 2), used for counterexamples
    ({} without an arm)."""
    if d is None or d.n != 2 or d.lumped is None:
        return {}
    P = pp.paper()
    S = P.syms
    base = {S[k]: d.lumped[k] for k in ("j1", "j2", "j3", "X")}
    for i in range(2):
        for j in range(2):
            base[S[f"b{i + 1}{j + 1}"]] = d.B[i, j]
            base[S[f"c{i + 1}{j + 1}"]] = d.C[i, j]
    base.update({S["k1"]: d.K1[0, 0], S["k2"]: d.K2[0, 0], S["w1"]: d.W[0, 0], S["w2"]: d.W[1, 1]})
    return base


# -- eq. 14-19 and theorem 1 ---------------------------------------------------------------
def tbar(i: int, j: int) -> sp.Expr:
    """Tbar_ij of (18) as printed (the diagonal entry; eq. 19 makes Tbar_i = T_i I)."""
    k = i + j - 1
    return (T2 ** k - T1 ** k) / (sp.factorial(i - 1) * sp.factorial(j - 1) * k)


@functools.lru_cache(maxsize=1)
def minimiser() -> tuple[sp.Matrix, sp.Matrix, sp.Expr, bool]:
    """(K1, K2, h, exact) derived from the index (14): y(t + tau) predicted by its second-order
    Taylor expansion, y_d likewise; the decision variable is e'' (set by u through
    y'' = C J^-1 (B u - G), C J^-1 B invertible); h is the Hessian's diagonal; ``exact``:
    the stationary point is e'' = -(K1 e + K2 e') with a Hessian h I."""
    tau = sp.Symbol("tau", real=True)
    e = sp.symbols("e1:3", real=True)
    de = sp.symbols("de1:3", real=True)
    v = sp.symbols("v1:3", real=True)        # e'' = y_d'' - y''
    index = sum(sp.integrate((e[i] + tau * de[i] + tau ** 2 / 2 * v[i]) ** 2, (tau, T1, T2)) for i in range(2)) / 2
    grad = [sp.diff(index, x) for x in v]
    hess = sp.Matrix(2, 2, lambda i, j: sp.diff(index, v[i], v[j]))
    sol = sp.solve(grad, v, dict=True)[0]
    vstar = sp.Matrix([sol[x] for x in v])
    K1 = -vstar.jacobian(e).applyfunc(sp.factor)
    K2 = -vstar.jacobian(de).applyfunc(sp.factor)
    exact = (hess == hess[0, 0] * sp.eye(2)
             and (vstar + K1 * sp.Matrix(e) + K2 * sp.Matrix(de)).applyfunc(sp.cancel) == sp.zeros(2, 1))
    return K1, K2, sp.factor(hess[0, 0]), exact


def check_eq16_18(d: Derivation | None) -> Outcome:
    """K1 = Tbar33^-1 Tbar31, K2 = Tbar33^-1 Tbar32 (eq. 16-19) are the minimiser of (14)."""
    K1, K2, h, exact = minimiser()
    printed = [tbar(3, 1) / tbar(3, 3) * sp.eye(2), tbar(3, 2) / tbar(3, 3) * sp.eye(2)]
    ok = exact and all(sp.cancel(x) == 0 for m, p in zip((K1, K2), printed) for x in (m - p))
    convex = positive(sp.expand(sp.numer(sp.together(h.subs(T2, T1 + GAP)))), what="the Hessian of (14)",
                      proved="the Hessian (T2^5 - T1^5)/20 I is positive for 0 <= T1 < T2, so the minimiser is unique")
    ex = [sp.latex(sp.Eq(sp.Symbol("K_1"), sp.factor(K1[0, 0]) * sp.Symbol("I"))),
          sp.latex(sp.Eq(sp.Symbol("K_2"), sp.factor(K2[0, 0]) * sp.Symbol("I")))]
    if not ok:
        return Outcome(Status.REFUTED, f"the minimiser of (14) is K1 = {K1[0, 0]} I, K2 = {K2[0, 0]} I",
                       corrected=f"K1 = {K1[0, 0]} I, K2 = {K2[0, 0]} I", latex=tuple(ex))
    first = Outcome(Status.PROVED, f"derived from (14): K1 = {sp.factor(K1[0, 0])} I, K2 = {sp.factor(K2[0, 0])} I, "
                    "equal to the printed Tbar33^-1 Tbar31, Tbar33^-1 Tbar32 for symbolic T1, T2", latex=tuple(ex))
    return combine([first, convex], summary="the printed K1, K2 are the minimiser of (14), derived for symbolic 0 <= T1 < T2")


def check_eq15(d: Derivation | None) -> Outcome:
    """u* of (15) makes y'' = C J^-1 (B u* - G) equal y_d'' + K1 e + K2 e' (the minimiser; d = 0)."""
    P = pp.paper()
    yddot = P.C * P.Ji * (P.B * pp.eq15_ustar(P) - P.G)
    want = P.v("ddyd") + P.K1 * P.v("e") + P.K2 * P.v("de")
    return equal(P.F, yddot, want, base=paper_base(d), labels=("y'' under (15)", "y_d'' + K1 e + K2 e'"),
                 proved="u* of (15) gives e'' = -(K1 e + K2 e'), the minimiser of (14); under (12) with d = 0, "
                        "y'' = y_d'' + K1 e + K2 e'",
                 refuted="(15) does not realise the minimiser of (14)")


def check_theorem1(d: Derivation | None) -> Outcome:
    """Theorem 1: e'' + K2 e' + K1 e = 0 is exponentially stable for all 0 <= T1 < T2 (Routh-Hurwitz)."""
    k1, k2 = (sp.cancel(tbar(3, j) / tbar(3, 3)) for j in (1, 2))
    parts = []
    for name, k in (("k1", k1), ("k2", k2)):
        num, den = sp.fraction(sp.together(k.subs(T2, T1 + GAP)))
        parts.append(positive(sp.expand(num) * sp.Pow(sp.expand(den), -1), what=name,
                              proved=f"{name} > 0 for all 0 <= T1 < T2 (numerator and denominator positive with T2 = T1 + h, h > 0)"))
    s, a1, a0 = sp.symbols("s a1 a0")
    A = sp.Matrix(sp.BlockMatrix([[sp.zeros(2), sp.eye(2)], [-a0 * sp.eye(2), -a1 * sp.eye(2)]]))
    charpoly = sp.expand((s * sp.eye(4) - A).det())
    ok = sp.expand(charpoly - (s ** 2 + a1 * s + a0) ** 2) == 0
    parts.append(Outcome(Status.PROVED if ok else Status.REFUTED,
                         "det(sI - A) = (s^2 + k2 s + k1)^2; Routh-Hurwitz: a monic quadratic is Hurwitz iff both "
                         "coefficients are positive, so every root has negative real part (exponential stability)"))
    P = pp.paper()
    ddtheta = pp.eq12_ddtheta(P, pp.eq15_ustar(P), P.F.column([0, 0]))
    err = pp.tracking_dde(P, ddtheta) + P.K2 * P.v("de") + P.K1 * P.v("e")
    parts.append(equal(P.F, err, P.F.column([0, 0]), base=paper_base(d), labels=("e'' + K2 e' + K1 e", "0"),
                       proved="(12) with d = 0 under (15) gives e'' + K2 e' + K1 e = 0",
                       refuted="(15) does not give e'' + K2 e' + K1 e = 0"))
    return combine(parts, summary="k1, k2 > 0 for all 0 <= T1 < T2, so e'' + K2 e' + K1 e = 0 is Hurwitz; (15) gives it")


# -- eq. 28-38 -------------------------------------------------------------------------------
def _dhat_rate(P: pp.Paper, u: pp.Mat) -> pp.Mat:
    """d/dt dhat of (22) along the observer (21) with input u, theta'' free (chain rule)."""
    F = P.F
    rates = {**dict(zip(P.syms["z"], F.entries(pp.eq21_zdot(P, u)))),
             **{v: F(a) for v, a in zip(P.syms["dtheta"], P.syms["ddtheta"])}}
    return F.d_dt(pp.eq22_dhat(P), rates)


def check_eq28(d: Derivation | None) -> Outcome:
    """Each printed line of (28) equals d/dt dhat along (21) (theta'' free)."""
    P = pp.paper()
    truth = _dhat_rate(P, P.v("u"))
    return lines(P.F, truth, [Line(l, m) for l, m in pp.eq28_lines(P, P.v("u"))], base=paper_base(d),
                 what="d/dt of (22) along (21)")


def check_eq29(d: Derivation | None) -> Outcome:
    """Each printed line of (29) equals d/dt dhat along (21) with u = u* - dhat (27)."""
    P = pp.paper()
    truth = _dhat_rate(P, pp.composite_u(P))
    fixed = dict(pp.eq29_lines(P, "corrected"))
    fixed_text = "-B^-1 L (J C^-1 (K1 e + K2 e' + C J^-1 G + y_d'') - G - J theta''): y_d'' where y_d' is printed"
    printed = [Line(l, m, fixed_text if l == "line 3" else None,
                    fixed[l] if l == "line 3" else None) for l, m in pp.eq29_lines(P)]
    fix = (r"\text{line 3 as derived: } -B^{-1}L\,(JC^{-1}(K_1e + K_2\dot e + CJ^{-1}G + \ddot y_d) - G - J\ddot\theta)",)
    return lines(P.F, truth, printed, base=paper_base(d), what="d/dt of (22) along (21) under u = u* - dhat",
                 latex=fix)


def check_eq30(d: Derivation | None) -> Outcome:
    """(30) is the integral of (29): same derivative and value dhat(0) at t = 0."""
    P = pp.paper()
    F = P.F
    dhat0 = P.v("dhat0")
    rhs = pp.eq30(P, P.v("e"), P.v("de"), P.v("int_e"), dhat0)
    rates = {**{a: F(b) for a, b in zip(P.syms["int_e"], P.syms["e"])},
             **{a: F(b) for a, b in zip(P.syms["e"], P.syms["de"])},
             **{a: F(b) for a, b in zip(P.syms["de"], P.syms["dde"])}}
    rate29 = -P.M * (P.v("dde") + P.K2 * P.v("de") + P.K1 * P.v("e"))
    base = paper_base(d)
    first = equal(F, F.d_dt(rhs, rates), rate29, base=base, labels=("d/dt (30)", "(29)"),
                  proved="d/dt of (30) is (29)", refuted="d/dt of (30) is not (29)")
    at0 = pp.eq30(P, P.v("e0"), P.v("de0"), F.column([0, 0]), dhat0)
    second = equal(F, at0, dhat0, base=base, labels=("(30) at t = 0", "dhat(0)"),
                   proved="(30) at t = 0 gives dhat(0)", refuted="(30) at t = 0 is not dhat(0)")
    return combine([first, second], summary="(30) is the integral of (29): same derivative, value dhat(0) at t = 0")


def check_eq31(d: Derivation | None) -> Outcome:
    """With dhat(0) of (31) as printed, (30) becomes (32)."""
    P = pp.paper()
    with31 = pp.eq30(P, P.v("e"), P.v("de"), P.v("int_e"), pp.eq31_dhat0(P))
    fixed = pp.eq30(P, P.v("e"), P.v("de"), P.v("int_e"), pp.derived_dhat0(P))
    ok = P.F.is_zero(fixed - pp.eq32(P))
    gap = P.F.is_zero(with31 - pp.eq32(P) - P.M * (P.K2 - P.F.eye(2)) * P.v("e0"))
    k2 = d.K2[0, 0] if d is not None and d.K2.is_diagonal() else None
    note = f"; this arm has K2 = {k2} I" + (" = I, so (31) happens to hold here" if k2 == 1 else "") if k2 is not None else ""
    out = equal(P.F, with31, pp.eq32(P), base=paper_base(d), labels=("(30) with (31)", "(32)"),
                proved="(31) turns (30) into (32)",
                refuted=f"(30) with (31) is (32) + B^-1 W C^-1 (K2 - I) e(0) ({'proved' if gap else 'NOT proved'}): "
                        "(31) lacks K2 and is right only if K2 = I"
                        f"{note}; the derived dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0)) gives (32) "
                        f"({'proved' if ok else 'NOT proved'})",
                corrected="dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0))",
                latex=(r"\hat d(t)\big|_{(31)} - \hat d(t)\big|_{(32)} = B^{-1}WC^{-1}(K_2 - I)\,e(0)",
                       r"\text{derived: } \hat d(0) = -B^{-1}WC^{-1}\big(\dot e(0) + K_2 e(0)\big)"))
    return out


def check_eq33(d: Derivation | None) -> Outcome:
    """(33) = u* of (15) - dhat of (32)."""
    P = pp.paper()
    u = pp.eq15_ustar(P) - pp.eq32(P)
    return equal(P.F, pp.eq33(P), u, base=paper_base(d), labels=("(33)", "u* - dhat(32)"),
                 proved="(33) equals u* of (15) minus dhat of (32)", refuted="(33) is not u* - dhat")


def check_eq34_38(d: Derivation | None) -> Outcome:
    """(34) with the printed gains (35)-(38) equals (33)."""
    P = pp.paper()
    return equal(P.F, pp.eq34(P), pp.eq33(P), base=paper_base(d), labels=("(34) with (35-38)", "(33)"),
                 proved="P e + D e' + I int e + N with the printed P, D, I, N equals (33)",
                 refuted="the PID form with the printed gains differs from (33)")


# -- eq. 41-42, a14 -------------------------------------------------------------------------------
def _loop_ddtheta(P: pp.Paper) -> pp.Mat:
    """theta'' of (12) under u = u* - dhat (27) with a constant disturbance d."""
    return pp.eq12_ddtheta(P, pp.composite_u(P), P.v("d"))


def check_eq41(d: Derivation | None) -> Outcome:
    """(41) as printed, J theta'' + G = B (u* - e1), against (12), (27), (39)."""
    P = pp.paper()
    truth = P.B * (pp.composite_u(P) + P.v("d"))      # J theta'' + G = B (u + d), u = u* - dhat
    return equal(P.F, pp.eq41_rhs(P), truth, base=paper_base(d), labels=("B (u* - e1)", "B (u + d)"),
                 proved="(41) follows from (12), (27), (39)",
                 refuted="sign of e1: with u = u* - dhat (27) and e1 = d - dhat (39), (12) gives J theta'' + G = "
                         "B (u* + e1), consistent with (42)",
                 corrected="J(theta) theta'' + G = B (u* + e1)",
                 latex=(r"J\ddot\theta + G = B(u + d) = B(u^* - \hat d + d) = B(u^* + e_1)",))


def check_eq42(d: Derivation | None) -> Outcome:
    """Both lines of (42) along the loop (12), (15), (21), (22), (27) with a constant d."""
    P = pp.paper()
    F = P.F
    first = equal(F, pp.eq42_first(P, _loop_ddtheta(P)), F.column([0, 0]), base=paper_base(d),
                  labels=("J C^-1 (e'' + K2 e' + K1 e) + B e1", "0"),
                  proved="line 1 holds along (12), (15), (27) with e1 = d - dhat",
                  refuted="line 1 of (42) does not hold along the loop")
    rates = {**dict(zip(P.syms["z"], F.entries(pp.eq21_zdot(P, pp.composite_u(P))))),
             **dict(zip(P.syms["dtheta"], F.entries(_loop_ddtheta(P))))}
    e1dot = -F.d_dt(pp.eq22_dhat(P), rates)
    second = equal(F, e1dot, -P.Bi * P.L * P.B * pp.observer_error(P), base=paper_base(d),
                   labels=("e1'", "-B^-1 L B e1"), proved="line 2 (= 40) holds along the loop",
                   refuted="line 2 of (42) does not hold along the loop")
    return combine([first, second], summary="both lines of (42) hold along (12), (15), (21), (27)")


def check_a14(d: Derivation | None) -> Outcome:
    """The second block of (a14) as printed against e'' from (42)."""
    P = pp.paper()
    truth = pp.tracking_dde(P, _loop_ddtheta(P))
    return equal(P.F, pp.a14_second_block(P, +1), truth, base=paper_base(d),
                 labels=("(a14): -K1 e - K2 e' + C J^-1 B e1", "e'' from (42)"),
                 proved="(a14) follows from (42)",
                 refuted="sign of the e1 term: (42) gives e'' = -K1 e - K2 e' - C J^-1 B e1 (harmless for the "
                         "norm bound (a18), which uses ||C J^-1 B||)",
                 corrected="e-bar' = A e-bar + [0; -C J^-1(theta) B e1]",
                 latex=(r"\dot{\bar e} = A\bar e + \begin{bmatrix} 0 \\ -CJ^{-1}(\theta)Be_1 \end{bmatrix}",))


OBLIGATIONS = (
    Obligation("eq16-18", "eq. 14, 16-19", Kind.PAPER,
               "K1 = Tbar33^-1 Tbar31, K2 = Tbar33^-1 Tbar32 minimise (14) under second-order Taylor prediction, 0 <= T1 < T2",
               check_eq16_18, r"K_1 = \bar T_{33}^{-1}\bar T_{31},\quad K_2 = \bar T_{33}^{-1}\bar T_{32},\quad "
               r"\bar T_{ij} = \frac{\bar T_2^{i+j-1} - \bar T_1^{i+j-1}}{(i-1)!\,(j-1)!\,(i+j-1)}"),
    Obligation("eq15", "eq. 15", Kind.PAPER, "u* of (15) realises the minimiser of (14)", check_eq15,
               r"u^* = -(CJ^{-1}B)^{-1}\{K_1(y - y_d) + K_2(\dot y - \dot y_d) - CJ^{-1}G - \ddot y_d\}"),
    Obligation("theorem1", "theorem 1", Kind.PAPER,
               "for all 0 <= T1 < T2, e'' + K2 e' + K1 e = 0 is exponentially stable (k1 > 0, k2 > 0)", check_theorem1,
               r"\ddot e + K_2\dot e + K_1 e = 0 \text{ exponentially stable for all } 0 \le T_1 < T_2"),
    Obligation("eq28", "eq. 28", Kind.PAPER, "the four lines of (28) equal d/dt dhat along (21)", check_eq28,
               r"\dot{\hat d} = B^{-1}(\dot z + \tfrac{\partial p}{\partial\dot\theta}\ddot\theta) = B^{-1}(\dot z + W\ddot\theta)"
               r" = B^{-1}(\dot z + LJ\ddot\theta) = B^{-1}L(-z + G - Bu - p + J\ddot\theta)"),
    Obligation("eq29", "eq. 29", Kind.PAPER, "the five lines of (29) equal d/dt dhat along the composite loop", check_eq29,
               r"\dot{\hat d} = B^{-1}L(-B\hat d + G - Bu + J\ddot\theta) = B^{-1}L(-Bu^* + G + J\ddot\theta)"
               r" = -B^{-1}L\,(JC^{-1}(K_1e + K_2\dot e + CJ^{-1}G + \dot y_d) - G - J\ddot\theta)"
               r" = -B^{-1}LJC^{-1}(\ddot e + K_2\dot e + K_1e) = -B^{-1}WC^{-1}(\ddot e + K_2\dot e + K_1e)"),
    Obligation("eq30", "eq. 30", Kind.PAPER, "(30) is the integral of (29) from 0 to t", check_eq30,
               r"\hat d(t) = -B^{-1}WC^{-1}\big(\dot e(t) + K_2e(t) + K_1\textstyle\int_0^t e\big) + B^{-1}WC^{-1}\dot e(0)"
               r" + B^{-1}WC^{-1}K_2e(0) + \hat d(0)"),
    Obligation("eq31", "eq. 31-32", Kind.PAPER, "the initial estimate (31) turns (30) into (32)", check_eq31,
               r"\hat d(0) = -B^{-1}WC^{-1}\dot e(0) - B^{-1}WC^{-1}e(0) \;\Rightarrow\; "
               r"\hat d(t) = -B^{-1}WC^{-1}\big(\dot e + K_2e + K_1\textstyle\int_0^t e\big)"),
    Obligation("eq33", "eq. 33", Kind.PAPER, "(33) = u* (15) - dhat (32)", check_eq33,
               r"u = (CJ^{-1}B)^{-1}(K_1e + K_2\dot e + \ddot y_d) + B^{-1}G + B^{-1}WC^{-1}"
               r"\big(\dot e + K_2e + K_1\textstyle\int_0^t e\big)"),
    Obligation("eq34-38", "eq. 34-38", Kind.PAPER, "(34) with the printed P, D, I, N equals (33)", check_eq34_38,
               r"P = B^{-1}(JC^{-1}K_1 + WC^{-1}K_2),\ D = B^{-1}(JC^{-1}K_2 + WC^{-1}),\ I = B^{-1}WC^{-1}K_1,\ "
               r"N = B^{-1}(JC^{-1}\ddot y_d + G)"),
    Obligation("eq41", "eq. 41", Kind.PAPER, "J theta'' + G = B (u* - e1) under (27)", check_eq41,
               r"J(\theta)\ddot\theta + G(\theta, \dot\theta) = B(u^* - e_1)"),
    Obligation("eq42", "eq. 42", Kind.PAPER, "the closed-loop error dynamics (42)", check_eq42,
               r"J C^{-1}(\ddot e + K_2\dot e + K_1 e) + Be_1 = 0,\quad \dot e_1 = -B^{-1}L(\theta)Be_1"),
    Obligation("a14", "eq. a14", Kind.PAPER, "(a14): e-bar' = A e-bar + [0; C J^-1 B e1] from (42)", check_a14,
               r"\dot{\bar e} = A\bar e + \begin{bmatrix} 0 \\ CJ^{-1}(\theta)Be_1 \end{bmatrix}"),
)
