"""Obligations on the observer and theorem 2 as printed (section 4.2, eq. 8-10, 21-26, 40, a2-a12).

Kind ``paper``: generic two-link symbols (:mod:`derive.proofs.paper`). The sign facts
of theorem 2 are proved from SymPy's assumptions on an explicit
parametrisation of the hypotheses, never by sampling:

* (26) => |q| < w1 for q = X theta2' sin(theta2): with m = |theta2'|,
  theta2m = m + mu, w1 = X theta2m + eta, |sin| = 1 - zeta (mu, zeta >= 0,
  eta > 0, X >= 0): w1 - |q| = X mu + eta + X m zeta > 0;
* |q| < w1 <=> a = w1 + q > 0 and b = w1 - q > 0, so w1 = (a + b)/2,
  q = (a - b)/2, and w2 = w1 + c with c >= 0 ((26)); every quantity of
  (a8)-(a12) is then a polynomial in a, b, c whose sign SymPy reads off.
"""
from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import sympy as sp

from derive.proofs import paper as pp
from derive.proofs.core import Kind, Line, Obligation, Outcome, Status, combine, equal, lines, positive
from derive.proofs.paper_claims import paper_base

if TYPE_CHECKING:
    from derive.control.pipeline import Derivation

# symbols of the sign arguments
q = sp.Symbol("q", real=True)                              # X theta2' sin(theta2)
w1, w2 = sp.symbols("w1 w2", positive=True)
a, b = sp.symbols("a b", positive=True)                    # w1 + q, w1 - q
c = sp.Symbol("c", nonnegative=True)                       # w2 - w1
ON_HYPOTHESES = {w1: (a + b) / 2, q: (a - b) / 2, w2: (a + b) / 2 + c}


def a8_matrix() -> sp.Matrix:
    """The matrix of (a8) in q (sympy)."""
    return sp.Matrix([[2 * w2 + 2 * (w2 / w1 - 1) * q, -w1 + q], [-w1 + q, 2 * w1]])


def a9_lhs() -> sp.Expr:
    """Left side of (a9) as printed."""
    return 4 * (w1 * w2 + (w2 - w1) * q) - (-w1 + q) ** 2


def a10_lhs() -> sp.Expr:
    """Left side of (a10) as printed."""
    return 4 * (w1 + q) * (w2 - w1) + 4 * w1 ** 2 - (-w1 + q) ** 2


def on_hypotheses(expr: sp.Expr) -> sp.Expr:
    """``expr`` with w1, q, w2 written in a, b > 0, c >= 0 (i.e. |q| < w1 <= w2), expanded."""
    return sp.expand(sp.together(expr.xreplace(ON_HYPOTHESES)))


def speed_lemma() -> Outcome:
    """(26) and |theta2'| <= theta2m give |q| < w1 for every theta2 (X >= 0)."""
    m, mu, zeta, X = sp.symbols("m mu zeta X", nonnegative=True)
    eta = sp.Symbol("eta", positive=True)
    w1_ = X * (m + mu) + eta                      # (26): w1 > X theta2m, theta2m = m + mu
    slack = sp.expand(w1_ - X * m * (1 - zeta))   # w1 - |q| with |sin| = 1 - zeta
    return positive(slack, what="w1 - |X theta2' sin(theta2)|",
                    proved="(26) gives |q| < w1 for every theta2 and |theta2'| <= theta2m (X >= 0, |sin| <= 1): "
                           f"w1 - |q| = {slack} > 0")


# -- eq. 8-10, 40, a2-a5 -------------------------------------------------------------------------
def check_eq8_10(d: Derivation) -> Outcome:
    """(21)-(22) are the observer (8)-(9) with p(x) = B^-1 p(theta'); (10) is then (40)."""
    P = pp.paper()
    F, K = P.F, P.F.K
    zero = F.eye(2) * K.zero
    p8 = P.Bi * P.p                                          # p(theta) does not depend on theta
    l = zero.hstack(F.jacobian(p8, P.syms["dtheta"]))        # (9), x = (theta, theta')
    g2 = zero.vstack(P.Ji * P.B)                             # d enters as B d in (12)
    f = P.v("dtheta").vstack(-P.Ji * P.G)
    z8 = P.Bi * P.v("z")
    z8dot = -l * g2 * z8 - l * (g2 * p8 + f + g2 * P.v("u"))   # (8), g1 = g2
    base = paper_base(d)
    parts = [
        equal(F, z8dot, P.Bi * pp.eq21_zdot(P, P.v("u")), base=base, labels=("(8)", "B^-1 (21)"),
              proved="with z8 = B^-1 z and p(x) = B^-1 W theta', (8)-(9) are (21)", refuted="(21) is not (8)"),
        equal(F, z8 + p8, pp.eq22_dhat(P), base=base, labels=("(8) dhat", "(22)"),
              proved="and dhat = z8 + p(x) is (22)", refuted="(22) is not the estimate of (8)"),
        equal(F, -l * g2, -P.Bi * P.L * P.B, base=base, labels=("-l g2 (10)", "-B^-1 L B (40)"),
              proved="(10): -l(x) g2(x) = -B^-1 L B, the matrix of (40)", refuted="(10) does not give (40)"),
    ]
    return combine(parts, summary="(21)-(22) are (8)-(9) with p(x) = B^-1 W theta'; (10) is (40)")


def _e1dot(P: pp.Paper, u: pp.Mat) -> pp.Mat:
    """e1' = -d/dt dhat along (21) and (12) with a constant d (eq. 39)."""
    F = P.F
    rates = {**dict(zip(P.syms["z"], F.entries(pp.eq21_zdot(P, u)))),
             **dict(zip(P.syms["dtheta"], F.entries(pp.eq12_ddtheta(P, u, P.v("d")))))}
    return -F.d_dt(pp.eq22_dhat(P), rates)


def check_eq40(d: Derivation) -> Outcome:
    """(40): e1' = -B^-1 L B e1 along (12), (21), (22), d constant."""
    P = pp.paper()
    return equal(P.F, -P.Bi * P.L * P.B * pp.observer_error(P), _e1dot(P, P.v("u")), base=paper_base(d),
                 labels=("-B^-1 L B e1", "e1'"),
                 proved="e1' = -B^-1 L(theta) B e1 along (12), (21), (22) for every input u and constant d",
                 refuted="(40) does not follow from (12), (21), (22)")


def check_a2_a5(d: Derivation) -> Outcome:
    """(a2), the printed lines of (a3), and (a4)-(a5) with d' = B d, dhat' = z + p (a1)."""
    P = pp.paper()
    F, base = P.F, paper_base(d)
    dd = P.v("ddtheta")
    dp = F.d_dt(P.p, {v: F(x) for v, x in zip(P.syms["dtheta"], P.syms["ddtheta"])})
    a2 = equal(F, P.W * dd, dp, base=base, proved="(a2) holds", refuted="(a2) fails")
    z, u, G, dprime = P.v("z"), P.v("u"), P.G, P.B * P.v("d")
    dhat_p = z + P.p                                         # (a1)
    zdot = pp.eq21_zdot(P, u)
    truth = -(zdot + P.W * dd)                               # -d/dt (z + p), theta'' free
    a3 = lines(F, truth, [Line("(a3) line 2", -zdot - dp),
                          Line("(a3) line 3", P.L * (z - G + P.B * u + P.p) - P.W * dd),
                          Line("(a3) line 4", P.L * (dhat_p - G + P.B * u - P.J * dd))],
               what="-d/dt (z + p)", base=base)
    on_plant = -(zdot + P.W * pp.eq12_ddtheta(P, u, P.v("d")))
    a4 = equal(F, -P.L * (dprime - dhat_p), on_plant, base=base, labels=("-L (B d - dhat')", "e''"),
               proved="(a4) holds with (12), i.e. (a5) e'' = -L e' for e' = d' - dhat'",
               refuted="(a4)-(a5) fail")
    return combine([a2, a3, a4], summary="(a2), the lines of (a3), (a4) and (a5) hold as printed")


# -- theorem 2: a7-a12 -------------------------------------------------------------------------------
@functools.lru_cache(maxsize=1)
def dV_truth() -> pp.Mat:
    """dV/dt of (a7) along e'' = -L e' (a5), by the chain rule in e' and theta2."""
    P = pp.paper()
    F = P.F
    rates = {**dict(zip(P.syms["ep"], F.entries(-P.L * P.v("ep")))), P.theta2: F(P.syms["dtheta"][1])}
    return F.d_dt(pp.a7_V(P), rates)


def check_dV_lines(d: Derivation) -> Outcome:
    """Each printed line of dV/dt between (a7) and (a8) against the derived dV/dt."""
    P = pp.paper()
    printed = dict(pp.dV_lines(P))
    ls = [Line("line 1", printed["line 1"], "second term -(e')^T L^T W^-T J W^-1 e' where W^-T L^T J W^-1 is printed",
               pp.dV_line1_corrected(P))] + [Line(k, printed[k]) for k in ("line 2", "line 3", "line 4")]
    fix = (r"\text{line 1 as derived: } \dot V = -e'^TW^{-T}JW^{-1}Le' - e'^T L^T W^{-T} J W^{-1} e'"
           r" + e'^TW^{-T}\dot J W^{-1}e'",)
    return lines(P.F, dV_truth(), ls, base=paper_base(d), what="dV/dt of (a7) along (a5)", latex=fix)


def check_a8(d: Derivation) -> Outcome:
    """(a8): det M > 0 gives dV/dt < 0 only with a positive diagonal entry (Sylvester)."""
    M = a8_matrix()
    diag = positive(M[1, 1], what="M22 = 2 w1", proved="M22 = 2 w1 > 0")
    if diag.status is not Status.PROVED:
        return diag
    return Outcome(Status.PROVED,
                   "dV/dt = -(e')^T M e' / (w1 w2) with w1 w2 > 0; det M > 0 alone does not make M positive definite "
                   "(a negative definite M has det > 0 too), but with M22 = 2 w1 > 0 (w1 > 0) Sylvester's criterion "
                   "does: then dV/dt < 0 for every e' != 0")


def check_a9(d: Derivation) -> Outcome:
    """(a9) is det M of (a8)."""
    ok = sp.expand(a8_matrix().det() - a9_lhs()) == 0
    return Outcome(Status.PROVED if ok else Status.REFUTED, "(a9) is the determinant of (a8), expanded"
                   if ok else f"det of (a8) is {sp.expand(a8_matrix().det())}")


def check_a10(d: Derivation) -> Outcome:
    """(a10) is (a9) rewritten."""
    ok = sp.expand(a10_lhs() - a9_lhs()) == 0
    return Outcome(Status.PROVED if ok else Status.REFUTED, "(a10) equals (a9)" if ok else "(a10) differs from (a9)")


def check_a11(d: Derivation) -> Outcome:
    """(26) implies (a11)."""
    term = on_hypotheses(4 * (w1 + q) * (w2 - w1))
    return combine([speed_lemma(), positive(term, strict=False, what="4 (w1 + q)(w2 - w1)",
                                            proved=f"4 (w1 + q)(w2 - w1) = {sp.factor(term)} >= 0 (w2 >= w1 by (26))")],
                   summary="(26) gives |q| < w1, so 4 (w1 + q)(w2 - w1) >= 0")


def check_a12(d: Derivation) -> Outcome:
    """(a12): the factorisation, and its sign under (26)."""
    printed = 4 * w1 ** 2 - (-w1 + q) ** 2
    ok = sp.expand(printed - (w1 + q) * (3 * w1 - q)) == 0
    ident = Outcome(Status.PROVED if ok else Status.REFUTED, "4 w1^2 - (q - w1)^2 = (w1 + q)(3 w1 - q)"
                    if ok else "the factorisation of (a12) is wrong")
    rest = on_hypotheses(printed)
    return combine([ident, speed_lemma(), positive(rest, what="(w1 + q)(3 w1 - q)",
                                                   proved=f"(w1 + q)(3 w1 - q) = {sp.factor(rest)} > 0")],
                   summary="4 w1^2 - (q - w1)^2 = (w1 + q)(3 w1 - q) > 0 under (26)")


def check_theorem2(d: Derivation) -> Outcome:
    """(26) implies dV/dt < 0 for every theta2, every |theta2'| <= theta2m < w1/X and e' != 0."""
    P = pp.paper()
    F = P.F
    qf = P.s("X") * F(P.syms["dtheta"][1]) * F(sp.sin(P.theta2))
    last = pp.quad(P, P.v("ep"), pp.a8_matrix(P, qf)) * (P.const(-1) / (P.s("w1") * P.s("w2")))
    form = equal(F, last, dV_truth(), base=paper_base(d), proved="dV/dt = -(e')^T M e' / (w1 w2) (derived)",
                 refuted="the final form of dV/dt is wrong")
    M = a8_matrix()
    det_m = on_hypotheses(M.det())
    det = positive(det_m, what="det M", proved=f"det M = {det_m} > 0 for all w2 >= w1 > |q|")
    m22 = positive(M[1, 1], what="M22", proved="M22 = 2 w1 > 0")
    note = Outcome(Status.PROVED, "so M is positive definite (Sylvester) and dV/dt < 0 for e' != 0; V > 0 as J > 0 "
                   "(section 4.1); the proof's '(54)' and '(51)' mean (a8) and (a7)",
                   latex=(r"a = w_1 + q > 0,\ b = w_1 - q > 0,\ c = w_2 - w_1 \ge 0:\quad \det M = "
                          + sp.latex(det_m) + r" > 0,\quad M_{22} = 2w_1 > 0",))
    return combine([speed_lemma(), form, det, m22, note],
                   summary="(26) => M > 0 => dV/dt < 0 for all e' != 0, theta2 and |theta2'| <= theta2m")


OBLIGATIONS = (
    Obligation("eq8-10", "eq. 8-10, 21-25", Kind.PAPER,
               "(21)-(22) are the observer (8) with gain (9); its error dynamics (10) are (40)", check_eq8_10,
               r"\dot e_d = -l(x)g_2(x)e_d,\quad l(x) = \frac{\partial p(x)}{\partial x}"),
    Obligation("eq40", "eq. 40", Kind.PAPER, "constant d: e1' = -B^-1 L(theta) B e1 from (12), (21), (22)", check_eq40,
               r"\dot e_1 = -B^{-1}L(\theta)B(d - \hat d) = -B^{-1}L(\theta)Be_1"),
    Obligation("a2-a5", "eq. a1-a5", Kind.PAPER, "the lines of (a2)-(a5) as printed", check_a2_a5,
               r"\dot e' = -\dot z - \tfrac{dp}{dt} = L(z - G + Bu + p) - W\ddot\theta = L(\hat d' - G + Bu - J\ddot\theta)"
               r" = -L(Bd - \hat d') = -Le'"),
    Obligation("a7-a8", "eq. a7-a8", Kind.PAPER, "the four printed lines of dV/dt along (a5)", check_dV_lines,
               r"\dot V = -e'^TW^{-T}JW^{-1}Le' - e'^TW^{-T}L^TJW^{-1}e' + e'^TW^{-T}\dot J W^{-1}e' = \dots"
               r" = -\tfrac{1}{w_1w_2}e'^T M e'"),
    Obligation("a8", "eq. a8", Kind.PAPER, "det M > 0 makes dV/dt < 0 for all e'", check_a8,
               r"\det\begin{bmatrix} 2w_2 + 2(\frac{w_2}{w_1} - 1)q & -w_1 + q \\ -w_1 + q & 2w_1\end{bmatrix} > 0,"
               r"\quad q = X\dot\theta_2\sin\theta_2"),
    Obligation("a9", "eq. a9", Kind.PAPER, "(a9) is the determinant of (a8)", check_a9,
               r"4(w_1w_2 + (w_2 - w_1)q) - (-w_1 + q)^2 > 0"),
    Obligation("a10", "eq. a10", Kind.PAPER, "(a10) equals (a9)", check_a10,
               r"4(w_1 + q)(w_2 - w_1) + 4w_1^2 - (-w_1 + q)^2 > 0"),
    Obligation("a11", "eq. a11, 26", Kind.PAPER, "(26) implies 4 (w1 + q)(w2 - w1) >= 0", check_a11,
               r"4(w_1 + q)(w_2 - w_1) \ge 0"),
    Obligation("a12", "eq. a12, 26", Kind.PAPER, "4 w1^2 - (q - w1)^2 = (w1 + q)(3 w1 - q) > 0 under (26)", check_a12,
               r"4w_1^2 - (-w_1 + q)^2 = (w_1 + q)(3w_1 - q) > 0"),
    Obligation("theorem2", "theorem 2, eq. 26", Kind.PAPER,
               "(26) implies dV/dt < 0 for every theta2 and |theta2'| <= theta2m", check_theorem2,
               r"w_2 \ge w_1 > X\dot\theta_{2m} \;\Rightarrow\; \dot V < 0"),
)
