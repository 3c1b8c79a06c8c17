"""Obligations on the project's own derivation (kind ``project``): each must be proved.

They read the Derivation (the arm's numbers put in) and check it against the
statements the paper's derivation gives (eq. 15-42), for any n. No J^-1 is
formed symbolically beyond what the project already holds: a statement
A x = 0 is decided through an equivalent residual, e.g. the statement
premultiplied by J W^-1 B (invertible: J > 0, W triangular with w_i > 0,
B diagonal), with J theta'' replaced by the plant's right side (J theta'' = B (u + d) - G,
eq. 12). A counterexample still shows both sides of the statement itself,
evaluated at the point with J inverted numerically.
"""
from __future__ import annotations

import functools
from dataclasses import replace
from typing import TYPE_CHECKING

import sympy as sp

from derive.proofs.exact import Field, evaluate
from derive.proofs.core import Counterexample, Kind, Obligation, Outcome, Status, combine, equal
from derive.proofs.paper_claims import minimiser

if TYPE_CHECKING:
    from derive.control.pipeline import Derivation


def vec(prefix: str, n: int) -> sp.Matrix:
    """Column of real symbols prefix1..prefixn."""
    return sp.Matrix([sp.Symbol(f"{prefix}{i + 1}", real=True) for i in range(n)])


class Env:
    """The derivation's matrices with the arm's numbers, its symbols, and a field for them."""

    def __init__(self, d: Derivation, *extra_exprs: sp.MatrixBase) -> None:
        s = d.dynamics.sym
        n = d.n
        self.d, self.n = d, n
        self.theta, self.dtheta = d.theta, sp.Matrix(d.dtheta)
        self.ddtheta = sp.Matrix(s.ddtheta)
        self.e, self.de, self.int_e = sp.Matrix(s.e), sp.Matrix(s.de), sp.Matrix(s.int_e)
        self.ddyd, self.z, self.u = sp.Matrix(s.ddyd), sp.Matrix(s.z), sp.Matrix(s.u)
        self.dist = vec("d", n)                 # constant disturbance d (eq. 12)
        self.Binv = sp.diag(*[1 / d.B[i, i] for i in range(n)])
        self.rho = d.numeric(d.observer.J_solve_rhs)   # J r = rho, z' = W r (eq. 21)
        mats = [d.J, d.G, d.B, d.C, d.W, d.K1, d.K2, d.dhat, d.u_star, d.u_dobc, self.rho, *extra_exprs]
        self.F = Field.for_exprs(mats, d.theta, extra=list(self.ddtheta) + list(self.dist) + list(self.u))
        self.m = self.F.matrix

    def Jinv_at(self, point: dict) -> sp.Matrix:
        """J^-1 at a point (exact numbers)."""
        return evaluate(self.d.J, point).inv()


# -- eq. 16-18, 15 / theorem 1 ------------------------------------------------------------------
def check_gains(d: Derivation) -> Outcome:
    """The project's k1(T1, T2), k2(T1, T2) and the arm's K1, K2 are the minimiser of (14)."""
    K1, K2, _, _ = minimiser()
    k1, k2 = d.k_formulas
    sym_ok = sp.cancel(k1 - K1[0, 0]) == 0 and sp.cancel(k2 - K2[0, 0]) == 0
    T1 = sp.Symbol("T1", nonnegative=True)
    T2 = sp.Symbol("T2", positive=True)
    ctl = d.arm.controller
    at = {T1: sp.Rational(ctl.T1.numerator, ctl.T1.denominator), T2: sp.Rational(ctl.T2.numerator, ctl.T2.denominator)}
    want1, want2 = (K1[0, 0].subs(at) * sp.eye(d.n), K2[0, 0].subs(at) * sp.eye(d.n))
    parts = [Outcome(Status.PROVED if sym_ok else Status.REFUTED,
                     "derive.control.mpc.gains(T1, T2) equals the minimiser of (14) for symbolic T1, T2"
                     if sym_ok else f"derive.control.mpc.gains gives {k1}, {k2}; the minimiser is {K1[0, 0]}, {K2[0, 0]}")]
    for name, got, want in (("K1", d.K1, want1), ("K2", d.K2, want2)):
        if got == want:
            parts.append(Outcome(Status.PROVED, f"{name} = {want[0, 0]} I at T1 = {at[T1]}, T2 = {at[T2]}"))
        else:
            cex = Counterexample(tuple(at.items()), got, want, f"derivation {name}", "minimiser")
            parts.append(Outcome(Status.REFUTED, f"{name} is not the minimiser; {cex.text()}",
                                 corrected=f"{name} = {want[0, 0]} I", counterexample=cex))
    return combine(parts, summary=f"K1 = {d.K1[0, 0]} I, K2 = {d.K2[0, 0]} I: the minimiser of (14) (also for symbolic T1, T2)")


def check_law(d: Derivation) -> Outcome:
    """Closed loop of (12) (d = 0) under the project's u*: e'' + K2 e' + K1 e = 0 (eq. 15, theorem 1)."""
    E = Env(d)
    m = E.m
    # J C^-1 (e'' + K2 e' + K1 e) with J C^-1 e'' = J C^-1 y_d'' - J theta'' = J C^-1 y_d'' - (B u* - G)
    residual = m(d.J * d.C.inv() * (E.ddyd + d.K2 * E.de + d.K1 * E.e) - (d.B * d.u_star - d.G))

    def sides(pt: dict) -> tuple[sp.Matrix, sp.Matrix]:
        """Both sides of the statement at a point (J inverted numerically)."""
        ddtheta = E.Jinv_at(pt) * evaluate(d.B * d.u_star - d.G, pt)
        err = evaluate(E.ddyd + d.K2 * E.de + d.K1 * E.e, pt) - d.C * ddtheta
        return err, sp.zeros(d.n, 1)

    loop = equal(E.F, residual, m(sp.zeros(d.n, 1)), residual=residual, sides=sides,
                 labels=("e'' + K2 e' + K1 e", "0"),
                 proved="(12) with d = 0 under the derived u* gives e'' + K2 e' + K1 e = 0",
                 refuted="the derived u* does not give e'' + K2 e' + K1 e = 0")
    k1, k2 = d.K1[0, 0], d.K2[0, 0]
    diag = d.K1 == k1 * sp.eye(d.n) and d.K2 == k2 * sp.eye(d.n)
    # exact roots, then evaluated: nroots' iteration fails to converge for gains such as k1 = 3e40
    roots = sp.roots(sp.Poly(sp.Symbol("s") ** 2 + k2 * sp.Symbol("s") + k1), multiple=True)
    ok = diag and k1 > 0 and k2 > 0
    hurwitz = Outcome(Status.PROVED if ok else Status.REFUTED,
                      f"k1 = {k1} > 0, k2 = {k2} > 0: s^2 + k2 s + k1 is Hurwitz (Routh)" if ok else
                      f"K1 = {list(d.K1)}, K2 = {list(d.K2)} are not positive multiples of I",
                      evidence="roots of s^2 + k2 s + k1: " + ", ".join(f"{complex(sp.N(r, 20)):.4g}" for r in roots))
    return combine([loop, hurwitz], summary="under the derived u*: e'' + K2 e' + K1 e = 0, s^2 + k2 s + k1 Hurwitz")


# -- eq. 21-25, 40 ----------------------------------------------------------------------------------
def _observer_structure(E: Env) -> list[Outcome]:
    """W of (25) (generalised), p = W theta' (23), L J = W (24, n = 2), dhat = B^-1 (z + p) (22)."""
    d, F, n = E.d, E.F, E.n
    w = d.observer.values
    if d.observer.full:   # a full W (stated, or synthesised with observer_structure = "full"): the arm's own
        W = sp.Matrix(n, n, [v for _, v in w])
        out = [Outcome(Status.PROVED if d.W == W else Status.REFUTED, "W = the arm's full n x n W (no pattern imposed)")]
    else:
        W25 = sp.Matrix(n, n, lambda i, j: w[j][1] if j <= i else 0)
        out = [Outcome(Status.PROVED if d.W == W25 else Status.REFUTED,
                       "W = [[w1, 0], [w1, w2]] (25)" if n == 2 else "W[i][j] = w_j (j <= i), (25) generalised")]
    out.append(equal(F, F.matrix(d.numeric(d.observer.p)), F.matrix(d.W * E.dtheta),
                     proved="p = W theta' (23)", refuted="p is not W theta' (23)"))
    if n <= 2:
        out.append(equal(F, F.matrix(d.L * d.J), F.matrix(d.W), proved="L J = W (24)", refuted="L J != W (24)"))
    out.append(equal(F, F.matrix(d.dhat), F.matrix(E.Binv * (E.z + d.W * E.dtheta)),
                     proved="dhat = B^-1 (z + p) (22)", refuted="dhat is not B^-1 (z + p) (22)"))
    return out


def check_observer(d: Derivation) -> Outcome:
    """Constant d: the project's observer error e1 = d - dhat obeys e1' = -B^-1 L B e1 (eq. 40)."""
    E = Env(d)
    m, n = E.m, E.n
    e1 = E.dist - d.dhat
    tau = d.B * (E.u + E.dist) - d.G                       # J theta'' (eq. 12)
    # e1' = -B^-1 W J^-1 (rho + tau) when dhat = B^-1 (z + W theta'); times J W^-1 B:
    residual = m(E.rho + tau - d.B * e1)
    Dz, Dv = d.dhat.jacobian(E.z), d.dhat.jacobian(E.dtheta)

    def sides(pt: dict) -> tuple[sp.Matrix, sp.Matrix]:
        """Both sides of the statement at a point (J inverted numerically)."""
        Ji, W = E.Jinv_at(pt), d.W
        lhs = -(evaluate(Dz, pt) * W * Ji * evaluate(E.rho, pt) + evaluate(Dv, pt) * Ji * evaluate(tau, pt))
        rhs = -E.Binv * W * Ji * d.B * evaluate(e1, pt)
        return lhs, rhs

    main = equal(E.F, residual, m(sp.zeros(n, 1)), residual=residual, sides=sides,
                 labels=("e1' (derived observer)", "-B^-1 L B e1"),
                 proved="with (12), d constant: e1' = -B^-1 L(theta) B e1 (J W^-1 B (e1' + B^-1 L B e1) = 0 "
                        "exactly; J W^-1 B invertible)",
                 refuted="the derived observer's error does not obey e1' = -B^-1 L B e1")
    return combine(_observer_structure(E) + [main], summary="W, p, L, dhat as (22)-(25); e1' = -B^-1 L B e1 for constant d")


# -- eq. 28-42 ---------------------------------------------------------------------------------------
def _dde_map(E: Env) -> dict:
    """e'' = y_d'' - C theta'' for the symbols dde_i of derive.control.npid."""
    dde = [sp.Symbol(f"dde{i + 1}", real=True) for i in range(E.n)]
    return dict(zip(dde, E.ddyd - E.d.C * E.ddtheta))


def check_dhat_rate(d: Derivation) -> Outcome:
    """The project's eq. (29) equals d/dt dhat along (21) under u = u* - dhat, theta'' free."""
    rate = d.numeric(d.npid.dhat_rate)
    E = Env(d, rate)
    rate = rate.xreplace(_dde_map(E))
    rho = E.rho.xreplace(dict(zip(E.u, d.u_dobc)))
    Winv = d.W.inv()
    Dz, Dv = d.dhat.jacobian(E.z), d.dhat.jacobian(E.dtheta)
    structure = [equal(E.F, E.m(Dz * d.W), E.m(E.Binv * d.W), proved="d dhat/dz W = B^-1 W",
                       refuted="d dhat/dz is not B^-1"),
                 equal(E.F, E.m(Dv), E.m(E.Binv * d.W), proved="d dhat/d theta' = B^-1 W",
                       refuted="d dhat/d theta' is not B^-1 W")]
    # dhat' = B^-1 W (r + theta''), J r = rho; times J W^-1 B: rho + J theta''
    residual = E.m(rho + d.J * E.ddtheta - d.J * Winv * d.B * rate)

    def sides(pt: dict) -> tuple[sp.Matrix, sp.Matrix]:
        """Both sides of the statement at a point (J inverted numerically)."""
        r = E.Jinv_at(pt) * evaluate(rho, pt)
        rhs = evaluate(Dz, pt) * d.W * r + evaluate(Dv, pt) * evaluate(E.ddtheta, pt)
        return evaluate(rate, pt), rhs

    main = equal(E.F, residual, E.m(sp.zeros(d.n, 1)), residual=residual, sides=sides,
                 labels=("derived (29)", "d/dt dhat"),
                 proved="dhat' = -B^-1 W C^-1 (e'' + K2 e' + K1 e) along the composite loop (e'' = y_d'' - C theta'')",
                 refuted="the derived (29) is not d/dt dhat along the loop")
    return combine(structure + [main], summary="dhat' = -B^-1 W C^-1 (e'' + K2 e' + K1 e) along the derived loop")


def check_dhat0(d: Derivation) -> Outcome:
    """The project's (30) is the printed (30); its dhat(0) turns (30) into (32)."""
    E = Env(d)
    n = E.n
    s = d.dynamics.sym
    e0, de0 = sp.Matrix(s.e0), sp.Matrix(s.de0)
    dhat0 = vec("dhat0_", n)
    M = E.Binv * d.W * d.C.inv()
    printed30 = -M * (E.de + d.K2 * E.e + d.K1 * E.int_e) + M * de0 + M * d.K2 * e0 + dhat0
    eq32 = -M * (E.de + d.K2 * E.e + d.K1 * E.int_e)
    mine = d.numeric(d.npid.dhat_t)
    syms = list(e0) + list(de0) + list(dhat0) + list(E.int_e) + list(E.e) + list(E.de)
    F = Field(syms, ())
    first = equal(F, F.matrix(mine), F.matrix(printed30), labels=("derived (30)", "printed (30)"),
                  proved="the derived dhat(t) is (30)", refuted="the derived dhat(t) differs from (30)")
    with0 = mine.xreplace(dict(zip(dhat0, d.dhat0)))
    second = equal(F, F.matrix(with0), F.matrix(eq32), labels=("(30) with derived dhat(0)", "(32)"),
                   proved="with the derived dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0)), (30) is (32)",
                   refuted="the derived dhat(0) does not turn (30) into (32)")
    printed31 = -M * de0 - M * e0
    same = F.is_zero(F.matrix(printed31 - d.dhat0))
    k2 = f"K2 = {d.K2[0, 0]} I" if d.K2 == d.K2[0, 0] * sp.eye(n) else "K2"
    third = Outcome(Status.PROVED, f"the printed (31) {'is' if same else 'is not'} this arm's dhat(0) ({k2}; "
                    "(31) holds only if K2 = I: derive check --paper, eq31)")
    return combine([first, second, third],
                   summary="derived (30) is printed (30); derived dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0)) gives (32)")


def check_pid(d: Derivation) -> Outcome:
    """The project's P, D, I, N are (35)-(38); u_npid = (34) = u* - dhat(32) (33)."""
    E = Env(d, d.P, d.D, d.I, d.N, d.u_npid)
    F, m = E.F, E.m
    Ci, Bi = d.C.inv(), E.Binv
    printed = {"P": Bi * (d.J * Ci * d.K1 + d.W * Ci * d.K2), "D": Bi * (d.J * Ci * d.K2 + d.W * Ci),
               "I": Bi * d.W * Ci * d.K1, "N": Bi * (d.J * Ci * E.ddyd + d.G)}
    parts = [equal(F, m(getattr(d, k)), m(v), labels=(f"derived {k}", f"printed {k}"),
                   proved=f"{k} = ({ref})", refuted=f"{k} differs from ({ref})")
             for (k, v), ref in zip(printed.items(), ("35", "36", "37", "38"))]
    pid = d.P * E.e + d.D * E.de + d.I * E.int_e + d.N
    parts.append(equal(F, m(d.u_npid), m(pid), proved="u = P e + D e' + I int e + N (34)", refuted="u is not (34)"))
    dhat32 = -Bi * d.W * Ci * (E.de + d.K2 * E.e + d.K1 * E.int_e)
    parts.append(equal(F, m(d.u_npid), m(d.u_star - dhat32), proved="u = u* - dhat(32) (33)",
                       refuted="u is not u* - dhat (33)"))
    return combine(parts, summary="P, D, I, N are (35)-(38); u = (34) = u* - dhat(32) (33)")


def check_loop(d: Derivation) -> Outcome:
    """Closed loop (12) + composite law + observer: J C^-1 (e'' + K2 e' + K1 e) + B e1 = 0 (eq. 42)."""
    E = Env(d)
    e1 = E.dist - d.dhat
    tau = d.B * (d.u_dobc + E.dist) - d.G                   # J theta'' (eq. 12, u = u* - dhat)
    residual = E.m(d.J * d.C.inv() * (E.ddyd + d.K2 * E.de + d.K1 * E.e) - tau + d.B * e1)

    def sides(pt: dict) -> tuple[sp.Matrix, sp.Matrix]:
        """Both sides of the statement at a point (J inverted numerically)."""
        ddtheta = E.Jinv_at(pt) * evaluate(tau, pt)
        lhs = evaluate(d.J, pt) * d.C.inv() * (evaluate(E.ddyd + d.K2 * E.de + d.K1 * E.e, pt) - d.C * ddtheta)
        return lhs + d.B * evaluate(e1, pt), sp.zeros(d.n, 1)

    return equal(E.F, residual, E.m(sp.zeros(d.n, 1)), residual=residual, sides=sides,
                 labels=("J C^-1 (e'' + K2 e' + K1 e) + B e1", "0"),
                 proved="the derived composite loop obeys (42), line 1 (line 2: see observer-error)",
                 refuted="the derived composite loop does not obey (42)")


FIELD_JOINTS = 12   # the identities over J and G are decided up to this many joints (snake12: all of them in check's 66 s)
FORMAL = ("; decided over placeholders J_ij = J_ji, G_i (derive.control.opaque): it holds for every symmetric "
          "J and every G, so for the arm's")


def formal_first(check, note: bool = True):
    """``check`` decided on the Derivation over placeholders (derive.control.opaque) first: a
    proof there is a proof for the arm (the laws are the same algebra over J and G, and an
    identity of symbols holds for their values). Anything else is decided on the arm's own
    matrices, so a refutation carries a real counterexample. ``note``: say so in the detail
    (not for a claim that involves neither J nor G, where the two forms are the same)."""
    def run(d: Derivation) -> Outcome:
        if note and d.n > FIELD_JOINTS:
            return Outcome(Status.UNPROVEN, f"not decided: past {FIELD_JOINTS} joints this identity over J and G is not "
                           f"attempted (n = {d.n}; it is decided in the field of J's and G's entries, whose "
                           "elements grow faster than any power of n: a 20-joint chain's eq. 29 passed 2.5 GB in its "
                           "conversion alone); the laws are the same algebra as for fewer joints, where it is proved",
                           summary=f"not attempted past {FIELD_JOINTS} joints")
        formal = d.formal_view
        if formal is not None:
            out = check(formal)
            if out.status is Status.PROVED:
                return replace(out, detail=out.detail + FORMAL) if note else out
        return check(d)
    return functools.wraps(check)(run)


OBLIGATIONS = (
    Obligation("K1-K2", "eq. 16-18", Kind.PROJECT, "the derived gains are the minimiser of (14)",
               formal_first(check_gains, note=False)),
    Obligation("u*-loop", "eq. 15, theorem 1", Kind.PROJECT,
               "under the derived u*, e'' + K2 e' + K1 e = 0 with a Hurwitz polynomial", formal_first(check_law)),
    Obligation("observer-error", "eq. 21-25, 40", Kind.PROJECT,
               "the derived observer's error obeys e1' = -B^-1 L B e1 (constant d)", formal_first(check_observer)),
    Obligation("dhat-rate", "eq. 28-29", Kind.PROJECT, "the derived (29) is d/dt dhat along the loop", formal_first(check_dhat_rate)),
    Obligation("dhat0", "eq. 30-32", Kind.PROJECT, "the derived (30) and dhat(0) give (32)",
               formal_first(check_dhat0, note=False)),
    Obligation("pid-gains", "eq. 33-38", Kind.PROJECT, "the derived P, D, I, N are (35)-(38) and u is (33)-(34)",
               formal_first(check_pid)),
    Obligation("closed-loop", "eq. 41-42", Kind.PROJECT, "the derived composite loop obeys (42)", formal_first(check_loop)),
)
