"""The paper's two-link equations as printed, in generic symbols (sections 4.1-4.4, appendix).

Everything here is transcribed from the paper, not taken from the project's
derivation: J of (a6) with j1, j2, j3, X; G = (G1, G2) (values of G at the
state: no claim differentiates G); B and C generic full-rank 2 x 2 matrices
(b11..b22, c11..c22, as section 4.1 allows); K1 = k1 I, K2 = k2 I (eq. 16-19);
W of (25). The tracking error e = y_d - C theta (eq. 20) is a variable, so
y_d = e + C theta and y_d' = e' + C theta', and e'' = y_d'' - C theta''.

Objects are exact matrices over :class:`derive.proofs.exact.Field` (theta2 under
sin/cos); each ``eqNN``/``aNN`` function returns what the paper prints, line
by line where a derivation has several lines.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import sympy as sp
from sympy.polys.fields import FracElement
from sympy.polys.matrices import DomainMatrix

from derive.proofs.exact import Field

Mat = DomainMatrix


def _vec(prefix: str, **assumptions: bool) -> tuple[sp.Symbol, sp.Symbol]:
    """(prefix1, prefix2)."""
    return tuple(sp.Symbol(f"{prefix}{i}", **assumptions) for i in (1, 2))


@dataclass(frozen=True, eq=False)
class Paper:
    """The generic two-link objects (all 2 x 2 or 2 x 1 over the field ``F``)."""

    F: Field
    theta2: sp.Symbol
    syms: dict
    J: Mat
    G: Mat
    B: Mat
    C: Mat
    W: Mat
    K1: Mat
    K2: Mat
    L: Mat

    def v(self, name: str) -> Mat:
        """Column of the symbol pair ``name`` (e.g. 'z', 'dtheta')."""
        return self.F.column(self.syms[name])

    def s(self, name: str) -> FracElement:
        """Field element of a scalar symbol (e.g. 'w1', 'X')."""
        return self.F(self.syms[name])

    @functools.cached_property
    def Ji(self) -> Mat:
        """J^-1 (computed once)."""
        return self.J.inv()

    @functools.cached_property
    def Bi(self) -> Mat:
        """B^-1."""
        return self.B.inv()

    @functools.cached_property
    def Ci(self) -> Mat:
        """C^-1."""
        return self.C.inv()

    @functools.cached_property
    def p(self) -> Mat:
        """p(theta') = W theta' (eq. 23)."""
        return self.W * self.v("dtheta")

    @functools.cached_property
    def M(self) -> Mat:
        """B^-1 W C^-1, the matrix of eq. (29)-(33)."""
        return self.Bi * self.W * self.Ci

    def const(self, x: int | sp.Rational) -> FracElement:
        """A number as a field element."""
        return self.F.K(x)


@functools.lru_cache(maxsize=1)
def paper() -> Paper:
    """The paper's generic two-link objects (built once)."""
    real = {"real": True}
    pos = {"positive": True}
    theta2 = sp.Symbol("theta2", **real)
    syms = {name: _vec(name, **real) for name in (
        "dtheta", "ddtheta", "z", "u", "d", "e", "de", "dde", "ddyd", "int_e", "ep", "G")}
    syms.update({name: _vec(name + "_", **real) for name in ("e0", "de0", "dhat0")})
    for name in ("j1", "j2", "j3", "X", "b11", "b12", "b21", "b22", "c11", "c12", "c21", "c22"):
        syms[name] = sp.Symbol(name, **real)
    for name in ("k1", "k2", "w1", "w2"):
        syms[name] = sp.Symbol(name, **pos)
    flat = [theta2]
    for v in syms.values():
        flat += list(v) if isinstance(v, tuple) else [v]
    F = Field(flat, (theta2,))
    S = {k: (F(v) if not isinstance(v, tuple) else None) for k, v in syms.items()}
    c = F(sp.cos(theta2))
    two = F.K(2)
    J = Mat([[S["j1"] + two * S["X"] * c, S["j2"] + S["X"] * c], [S["j2"] + S["X"] * c, S["j3"]]], (2, 2), F.K)
    B = Mat([[S["b11"], S["b12"]], [S["b21"], S["b22"]]], (2, 2), F.K)
    C = Mat([[S["c11"], S["c12"]], [S["c21"], S["c22"]]], (2, 2), F.K)
    W = Mat([[S["w1"], F.K.zero], [S["w1"], S["w2"]]], (2, 2), F.K)
    I2 = F.eye(2)
    return Paper(F=F, theta2=theta2, syms=syms, J=J, G=F.column(syms["G"]), B=B, C=C, W=W,
                 K1=I2 * S["k1"], K2=I2 * S["k2"], L=W * J.inv())


# -- section 4.1-4.2 -------------------------------------------------------------------------
@functools.lru_cache(maxsize=None)
def eq15_ustar(P: Paper) -> Mat:
    """u* = -(C J^-1 B)^-1 {K1 (y - y_d) + K2 (y' - y_d') - C J^-1 G - y_d''} (eq. 15), y - y_d = -e."""
    Ji = P.Ji
    return -(P.C * Ji * P.B).inv() * (P.K1 * (-P.v("e")) + P.K2 * (-P.v("de")) - P.C * Ji * P.G - P.v("ddyd"))


def eq12_ddtheta(P: Paper, u: Mat, d: Mat) -> Mat:
    """theta'' from J theta'' + G = B (u + d) (eq. 12)."""
    return P.Ji * (P.B * (u + d) - P.G)


def eq21_zdot(P: Paper, u: Mat) -> Mat:
    """z' = -L z + L (G - B u - p) (eq. 21)."""
    z = P.v("z")
    return -P.L * z + P.L * (P.G - P.B * u - P.p)


@functools.lru_cache(maxsize=None)
def eq22_dhat(P: Paper) -> Mat:
    """dhat = B^-1 (z + p) (eq. 22)."""
    return P.Bi * (P.v("z") + P.p)


def tracking_dde(P: Paper, ddtheta: Mat) -> Mat:
    """e'' = y_d'' - C theta'' (eq. 20 differentiated twice, C constant)."""
    return P.v("ddyd") - P.C * ddtheta


@functools.lru_cache(maxsize=None)
def composite_u(P: Paper) -> Mat:
    """u = u* - dhat (eq. 27)."""
    return eq15_ustar(P) - eq22_dhat(P)


# -- section 4.3 -----------------------------------------------------------------------------
def eq28_lines(P: Paper, u: Mat) -> list[tuple[str, Mat]]:
    """The four printed lines of (28) (theta'' free, z' from (21) with input u)."""
    Bi, zd, dd = P.Bi, eq21_zdot(P, u), P.v("ddtheta")
    dp = P.F.jacobian(P.p, P.syms["dtheta"])
    return [("line 1", Bi * (zd + dp * dd)), ("line 2", Bi * (zd + P.W * dd)),
            ("line 3", Bi * (zd + P.L * P.J * dd)),
            ("line 4", Bi * P.L * (-P.v("z") + P.G - P.B * u - P.p + P.J * dd))]


def eq29_lines(P: Paper, yd_rate: str = "printed") -> list[tuple[str, Mat]]:
    """The five printed lines of (29); line 3 carries y_d' as printed, y_d'' if ``yd_rate`` is 'corrected'."""
    Bi, u, dd = P.Bi, composite_u(P), P.v("ddtheta")
    e, de, ddyd = P.v("e"), P.v("de"), P.v("ddyd")
    dyd = de + P.C * P.v("dtheta")
    target = dyd if yd_rate == "printed" else ddyd
    bracket = tracking_dde(P, dd) + P.K2 * de + P.K1 * e
    Ji = P.Ji
    return [
        ("line 1", Bi * P.L * (-P.B * eq22_dhat(P) + P.G - P.B * u + P.J * dd)),
        ("line 2", Bi * P.L * (-P.B * eq15_ustar(P) + P.G + P.J * dd)),
        # printed with one parenthesis missing: -B^-1 L (J C^-1 (K1 e + K2 e' + C J^-1 G + y_d') - G - J theta'')
        ("line 3", -Bi * P.L * (P.J * P.Ci * (P.K1 * e + P.K2 * de + P.C * Ji * P.G + target) - P.G - P.J * dd)),
        ("line 4", -Bi * P.L * P.J * P.Ci * bracket),
        ("line 5", -P.M * bracket),
    ]


def eq30(P: Paper, e: Mat, de: Mat, int_e: Mat, dhat0: Mat) -> Mat:
    """dhat(t) = -M [I K2 K1][e'; e; int e] + M e'(0) + M K2 e(0) + dhat(0) (eq. 30), M = B^-1 W C^-1."""
    M = P.M
    return -M * (de + P.K2 * e + P.K1 * int_e) + M * P.v("de0") + M * P.K2 * P.v("e0") + dhat0


def eq31_dhat0(P: Paper) -> Mat:
    """dhat(0) = -B^-1 W C^-1 e'(0) - B^-1 W C^-1 e(0) (eq. 31, as printed)."""
    return -P.M * P.v("de0") - P.M * P.v("e0")


def derived_dhat0(P: Paper) -> Mat:
    """The initial estimate that removes the constant of (30): -M (e'(0) + K2 e(0))."""
    return -P.M * (P.v("de0") + P.K2 * P.v("e0"))


@functools.lru_cache(maxsize=None)
def eq32(P: Paper) -> Mat:
    """dhat(t) = -B^-1 W C^-1 (e' + K2 e + K1 int e) (eq. 32)."""
    return -P.M * (P.v("de") + P.K2 * P.v("e") + P.K1 * P.v("int_e"))


@functools.lru_cache(maxsize=None)
def eq33(P: Paper) -> Mat:
    """Printed (33), second line: (C J^-1 B)^-1 (K1 e + K2 e' + y_d'') + B^-1 G + M (e' + K2 e + K1 int e)."""
    e, de, ie = P.v("e"), P.v("de"), P.v("int_e")
    return ((P.C * P.Ji * P.B).inv() * (P.K1 * e + P.K2 * de + P.v("ddyd")) + P.Bi * P.G
            + P.M * (de + P.K2 * e + P.K1 * ie))


def eq35_38(P: Paper) -> dict[str, Mat]:
    """The printed gains P, D, I (eq. 35-37) and N (eq. 38)."""
    Bi, Ci = P.Bi, P.Ci
    return {"P": Bi * (P.J * Ci * P.K1 + P.W * Ci * P.K2), "D": Bi * (P.J * Ci * P.K2 + P.W * Ci),
            "I": Bi * P.W * Ci * P.K1, "N": Bi * (P.J * Ci * P.v("ddyd") + P.G)}


def eq34(P: Paper) -> Mat:
    """u = P e + D e' + I int e + N (eq. 34) with the printed gains."""
    g = eq35_38(P)
    return g["P"] * P.v("e") + g["D"] * P.v("de") + g["I"] * P.v("int_e") + g["N"]


# -- section 4.4 and appendix ------------------------------------------------------------------
def observer_error(P: Paper) -> Mat:
    """e1 = d - dhat (eq. 39)."""
    return P.v("d") - eq22_dhat(P)


def eq41_rhs(P: Paper) -> Mat:
    """Right side of (41) as printed: B (u* - e1)."""
    return P.B * (eq15_ustar(P) - observer_error(P))


def eq42_first(P: Paper, ddtheta: Mat) -> Mat:
    """Left side of the first line of (42): J C^-1 (e'' + K2 e' + K1 e) + B e1."""
    bracket = tracking_dde(P, ddtheta) + P.K2 * P.v("de") + P.K1 * P.v("e")
    return P.J * P.Ci * bracket + P.B * observer_error(P)


def a14_second_block(P: Paper, sign: int = 1) -> Mat:
    """Second block of (a14): -K1 e - K2 e' + sign C J^-1 B e1 (printed: sign = +1)."""
    return -P.K1 * P.v("e") - P.K2 * P.v("de") + P.C * P.Ji * P.B * observer_error(P) * P.const(sign)


def quad(P: Paper, x: Mat, m: Mat, y: Mat | None = None) -> Mat:
    """x^T m y (1 x 1), y = x by default."""
    return x.transpose() * m * (x if y is None else y)


def a7_V(P: Paper) -> Mat:
    """V = e'^T W^-T J W^-1 e' (eq. a7)."""
    Wi = P.W.inv()
    return quad(P, P.v("ep"), Wi.transpose() * P.J * Wi)


def dV_lines(P: Paper) -> list[tuple[str, Mat]]:
    """The four printed lines of dV/dt between (a7) and (a8)."""
    ep, Wi, J, L, K = P.v("ep"), P.W.inv(), P.J, P.L, P.const
    w1, w2, X = P.s("w1"), P.s("w2"), P.s("X")
    q = X * P.F(P.syms["dtheta"][1]) * P.F(sp.sin(P.theta2))   # X theta2' sin(theta2)
    Jhat = Mat([[K(-2) * q, -q], [-q, K(0)]], (2, 2), P.F.K)
    m2 = Mat([[K(-2) * w2 * (w2 - w1), -w1 * w2], [-w1 * w2, K(0)]], (2, 2), P.F.K)
    m3a = Mat([[K(2) * w2, -w1], [-w1, K(2) * w1]], (2, 2), P.F.K)
    m3b = Mat([[K(-2) * (w2 / w1 - 1), K(-1)], [K(-1), K(0)]], (2, 2), P.F.K)
    line1 = (-quad(P, ep, Wi.transpose() * J * Wi * L) - quad(P, ep, Wi.transpose() * L.transpose() * J * Wi)
             + quad(P, ep, Wi.transpose() * Jhat * Wi))
    line2 = (-quad(P, ep, Wi.transpose()) - quad(P, ep, Wi)
             + quad(P, ep, m2) * (q / (w1 * w2) ** 2))
    line3 = quad(P, ep, m3a) * (K(-1) / (w1 * w2)) + quad(P, ep, m3b) * (q / (w1 * w2))
    return [("line 1", line1), ("line 2", line2), ("line 3", line3), ("line 4", quad(P, ep, a8_matrix(P, q)) * (K(-1) / (w1 * w2)))]


def dV_line1_corrected(P: Paper) -> Mat:
    """Line 1 with its second term as derived: -e'^T L^T W^-T J W^-1 e'."""
    ep, Wi, J, L = P.v("ep"), P.W.inv(), P.J, P.L
    q = P.s("X") * P.F(P.syms["dtheta"][1]) * P.F(sp.sin(P.theta2))
    Jhat = Mat([[P.const(-2) * q, -q], [-q, P.const(0)]], (2, 2), P.F.K)
    return (-quad(P, ep, Wi.transpose() * J * Wi * L) - quad(P, ep, L.transpose() * Wi.transpose() * J * Wi)
            + quad(P, ep, Wi.transpose() * Jhat * Wi))


def a8_matrix(P: Paper, q: FracElement) -> Mat:
    """The matrix of the last line before (a8), q = X theta2' sin(theta2)."""
    w1, w2, K = P.s("w1"), P.s("w2"), P.const
    return Mat([[K(2) * w2 + K(2) * (w2 / w1 - 1) * q, -w1 + q], [-w1 + q, K(2) * w1]], (2, 2), P.F.K)
