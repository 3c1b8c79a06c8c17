"""J(theta) for the observer certificate: numeric values and derivatives, and symbolic bounds.

The certificate (derive.control.certificate) evaluates J, dJ/dtheta_k and d^2 J/dtheta_j dtheta_k
at many points, and needs upper bounds of |d^2 J| and |d^3 J| valid for every theta. Values and
derivatives come from one CasADi graph of J (automatic differentiation, evaluated in batches):
SymPy's own differentiation of a 7-joint J takes tens of seconds. The bounds come from J as a
trigonometric polynomial (its exact Fourier coefficients, every coordinate an angle), or from
the sum of the absolute values of the coefficients of its derivatives as polynomials in cos, sin
of the angles and in prismatic coordinates (bounded by their limits).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from fractions import Fraction

import casadi as ca
import numpy as np
import sympy as sp
from sympy.polys.rings import ring

from derive.dynamics.dag import Memo
from derive.dynamics.sx import to_sx
from derive.dynamics.trigpoly import TrigRing, constant_angles

FULL_TURN = 2.0 * math.pi
ROUNDING = 1e-12   # relative rounding of the discrete Fourier transform's coefficients


def fourier_derivative_bounds(coef: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of |d^2 J/dq_j dq_k| and |d^3 J/dq_i dq_j dq_k| (m x m x n x n, m x m x m x n x n)
    valid for every q, from J's Fourier coefficients C_f (coef: K x n x n) at integer
    frequencies f (F: K x m): sum_f |C_f| |f_j f_k| and sum_f |C_f| |f_i f_j f_k|, each |C_f|
    inflated by ROUNDING times the sum of all of them (the transform's rounding). One matrix
    product over the K frequencies for every (j, k) and (i, j, k) at once."""
    m, n = F.shape[1], coef.shape[1]
    second, third = np.zeros((m, m, n, n)), np.zeros((m, m, m, n, n))
    if m == 0:
        return second, third
    mag = np.abs(coef).reshape(coef.shape[0], n * n)
    mag = mag + (ROUNDING * mag.sum(axis=0, keepdims=True) + 1e-300)
    absF = np.abs(F).astype(float)
    pairs = [(j, k) for j in range(m) for k in range(j, m)]
    triples = [(j, k, i) for j, k in pairs for i in range(k, m)]
    weights = np.array([absF[:, j] * absF[:, k] for j, k in pairs]
                       + [absF[:, j] * absF[:, k] * absF[:, i] for j, k, i in triples])
    sums = (weights @ mag).reshape(-1, n, n)
    for (j, k), s in zip(pairs, sums[:len(pairs)]):
        second[j, k] = second[k, j] = s
    for (j, k, i), t in zip(triples, sums[len(pairs):]):
        for a_, b_, c_ in set(itertools.permutations((j, k, i))):
            third[a_, b_, c_] = t
    return second, third


@dataclass(frozen=True)
class Coordinate:
    """A joint coordinate J may depend on: an angle (revolute, continuous) or a length
    (prismatic). ``lower``/``upper``: its limits (rad or m); None: unlimited (an angle
    then ranges over a whole turn; a prismatic coordinate cannot be certified)."""

    index: int
    symbol: sp.Symbol
    angle: bool
    lower: float | None = None
    upper: float | None = None

    @property
    def span(self) -> tuple[float, float] | None:
        if self.lower is not None and self.upper is not None:
            return float(self.lower), float(self.upper)
        return (-math.pi, math.pi) if self.angle else None


def joint_coordinates(arm, theta: tuple[sp.Symbol, ...]) -> tuple[Coordinate, ...]:
    """The coordinates of an arm's joints (symbols ``theta``) with their kind and limits
    (planar arm files: revolute joints without limits; a chain's joints with the limits its
    input states: a revolute joint's range, a prismatic joint's travel)."""
    chain = getattr(arm, "chain", None)
    out = []
    for i, q in enumerate(theta):
        lower = upper = None
        angle = True
        if chain is not None and i < len(chain.joints):
            j = chain.joints[i]
            angle = j.type.rotates
            if getattr(j.type, "value", "") == "revolute" or not angle:
                lower, upper = j.limits.lower, j.limits.upper
        out.append(Coordinate(i, q, angle, None if lower is None else float(lower),
                              None if upper is None else float(upper)))
    return tuple(out)


def _trig_ready(expr: sp.Expr) -> sp.Expr:
    """sin/cos of sums expanded, so that every trig function has a single angle."""
    if any(len(f.args[0].free_symbols) > 1 or not f.args[0].is_Symbol for f in expr.atoms(sp.sin, sp.cos)):
        return sp.expand_trig(expr)
    return expr


class InertiaModel:
    """J(theta) of a derivation, its derivatives and their symbolic bounds.

    ``deps``: the coordinates J depends on (m of them); ``spans``: the interval each ranges over
    (its limits; a whole turn (-pi, pi] when J is a trigonometric polynomial in that angle and the
    limits span a turn or more: J repeats there); ``periodic[k]``: whether span k is that whole
    turn. J, dJ/dq_k and d^2 J/dq_j dq_k evaluate on batches of points; ``second[j][k]`` and
    ``third[i][j][k]`` are n x n matrices of upper bounds of |d^2 J/dq_j dq_k| and
    |d^3 J/dq_i dq_j dq_k| valid for every q in the spans.
    """

    def __init__(self, J: sp.Matrix, coords: tuple[Coordinate, ...]) -> None:
        self.n = n = J.rows
        free = set().union(*(sp.sympify(x).free_symbols for x in J))
        self.deps = tuple(c for c in coords if c.symbol in free)
        self.unbounded = tuple(c for c in self.deps if c.span is None)
        self.m = m = len(self.deps)
        syms = [c.symbol for c in self.deps]
        self._numeric(J, syms)
        self.second = np.zeros((m, m, n, n))
        self.third = np.zeros((m, m, m, n, n))
        self.spans = [c.span for c in self.deps]
        self.periodic = [False] * m
        self.fourier: tuple[np.ndarray, np.ndarray] | None = None   # (C_f: K x n x n, f: K x m)
        if self.unbounded:
            return
        if m == 0:   # J constant (one joint, or joints that move no inertia's shape): its own mean, no derivatives
            self.fourier = (self.J(np.zeros((1, 0))).astype(complex), np.zeros((1, 0), dtype=int))
            return
        trig = self._trig_polys(J, syms) if all(c.angle for c in self.deps) else None
        if trig is not None:
            for k, c in enumerate(self.deps):
                lo, hi = c.span
                if hi - lo >= FULL_TURN or (c.lower is None and c.upper is None):
                    self.spans[k], self.periodic[k] = (-math.pi, math.pi), True
            self._fourier_bounds(trig)
        else:
            self._coefficient_bounds(J)

    # -- numbers -----------------------------------------------------------------------------
    def _numeric(self, J: sp.Matrix, syms: list[sp.Symbol]) -> None:
        """CasADi functions of J, dJ/dq (n^2 m) and d^2 J/dq^2 (n^2 m^2), batched by ``map``."""
        n, m = self.n, len(syms)
        x = ca.SX.sym("q", m)
        env = {s: x[k] for k, s in enumerate(syms)}
        memo = Memo()
        Jx = ca.SX(n, n)
        for i in range(n):
            for j in range(i, n):
                Jx[i, j] = to_sx(sp.sympify(J[i, j]), env, memo)
                Jx[j, i] = Jx[i, j]
        v = ca.vec(Jx)
        d1 = ca.jacobian(v, x)                  # n^2 x m
        d2 = ca.jacobian(ca.vec(d1), x)         # n^2 m x m
        opts = {"cse": True}
        self._fun = {"J": ca.Function("J", [x], [v], opts), "dJ": ca.Function("dJ", [x], [ca.vec(d1)], opts),
                     "d2J": ca.Function("d2J", [x], [ca.vec(d2)], opts)}
        self._maps: dict = {}

    def _eval(self, name: str, q: np.ndarray) -> np.ndarray:
        """Function ``name`` at the rows of q (N x m): N x (its output size), in batches of a
        power of two (one CasADi map per size)."""
        count = q.shape[0]
        size = self._fun[name].size1_out(0)
        if self.m == 0:
            return np.broadcast_to(np.array(self._fun[name](ca.DM(0, 1))).reshape(-1), (count, size)).copy()
        out = np.empty((count, size))
        for at in range(0, count, 4096):
            chunk = q[at:at + 4096]
            width = 1 << max(0, (chunk.shape[0] - 1).bit_length())
            f = self._maps.get((name, width))
            if f is None:
                f = self._maps[(name, width)] = self._fun[name].map(width)
            pad = np.zeros((width, self.m))
            pad[:chunk.shape[0]] = chunk
            out[at:at + chunk.shape[0]] = np.array(f(pad.T)).T[:chunk.shape[0]]
        return out

    def J(self, q: np.ndarray) -> np.ndarray:
        """J at points q (N x m, the deps' values): N x n x n."""
        return self._eval("J", q).reshape(-1, self.n, self.n)

    def dJ(self, q: np.ndarray) -> np.ndarray:
        """dJ/dq_k at points q: N x m x n x n."""
        return self._eval("dJ", q).reshape(q.shape[0], self.m, self.n, self.n)

    def d2J(self, q: np.ndarray) -> np.ndarray:
        """d^2 J/dq_j dq_k at points q: N x m x m x n x n."""
        return self._eval("d2J", q).reshape(q.shape[0], self.m, self.m, self.n, self.n)

    # -- bounds ------------------------------------------------------------------------------
    def _trig_polys(self, J: sp.Matrix, syms: list[sp.Symbol]):
        """J's entries as polynomials in cos, sin of the angles (TrigRing, reduced), or None when
        J is not one (a number that is not rational, another function)."""
        n = self.n
        exprs = [sp.sympify(J[i, j]) for i in range(n) for j in range(i, n)]
        try:
            ring_ = TrigRing(syms, (), constant_angles(exprs))
            return ring_, ring_.convert(exprs)
        except ValueError:
            return None

    def _fourier_bounds(self, trig) -> None:
        """Bounds of the 2nd and 3rd derivatives from J's Fourier coefficients (every dep an angle).

        J is a trigonometric polynomial of degree d_k in angle k (d_k: the largest total degree
        in cos, sin of that angle in the reduced polynomials, exact), so J(q) = sum_f C_f
        exp(i f.q) over integer frequencies |f_k| <= d_k, and J's values on the grid of 2 d_k + 1
        points per angle give the C_f exactly by the discrete Fourier transform (up to rounding,
        covered by the inflation below). Then |d^3 J/dq_i dq_j dq_k| <= sum_f |C_f| |f_i f_j f_k|
        for every q: tight where the sum-of-coefficients bound in cos, sin counts cos(a + b) as
        2 terms.
        """
        ring_, polys = trig
        n, m = self.n, self.m
        deg = [0] * m
        for p in polys:
            for monom in p.monoms():
                for k in range(m):
                    deg[k] = max(deg[k], monom[k] + monom[len(ring_.angles) + k])
        sizes = [2 * d + 1 for d in deg]
        axes = [2 * np.pi * np.arange(L) / L for L in sizes]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, m)
        values = self.J(grid).reshape(*sizes, n, n)
        coef = np.fft.fftn(values, axes=tuple(range(m))) / np.prod(sizes)
        freqs = [np.fft.fftfreq(L, 1.0 / L) for L in sizes]   # 0, 1, .., d, -d, .., -1
        F = np.stack(np.meshgrid(*freqs, indexing="ij"), axis=-1)   # sizes x m
        self.fourier = (coef.reshape(-1, n, n), F.reshape(-1, m).astype(int))
        self.second, self.third = fourier_derivative_bounds(*self.fourier)

    def _coefficient_bounds(self, J: sp.Matrix) -> None:
        """Bounds of the 2nd and 3rd derivatives as sums of absolute coefficients (some dep a
        prismatic coordinate): sup |p| <= sum |coefficient| prod radius^e, |cos|, |sin| <= 1."""
        n, m = self.n, self.m
        Jt = J.applyfunc(_trig_ready)
        names = []
        for c in self.deps:
            names += [f"c{c.index}", f"s{c.index}"] if c.angle else [f"q{c.index}"]
        # sin/cos of a constant angle (a URDF rpy that is not a multiple of pi/2): generators
        # after the deps', bounded by 1 like any cos, sin; the derivatives do not act on them
        constants = constant_angles(list(Jt))
        names += [f"{t}{k}_const" for k in range(len(constants)) for t in ("kc", "ks")]
        R, *gens = ring(",".join(names), sp.QQ)
        g = iter(gens)
        ops, radius, repl = [], {}, {}
        for c in self.deps:
            if c.angle:
                cg, sg = next(g), next(g)
                repl[sp.cos(c.symbol)], repl[sp.sin(c.symbol)] = cg.as_expr(), sg.as_expr()
                ops.append(lambda p, cg=cg, sg=sg: cg * p.diff(sg) - sg * p.diff(cg))
            else:
                qg = next(g)
                repl[c.symbol] = qg.as_expr()
                lo, hi = c.span
                radius[R.gens.index(qg)] = Fraction(max(abs(lo), abs(hi)))
                ops.append(lambda p, qg=qg: p.diff(qg))
        for a in constants:
            kc, ks = next(g), next(g)
            repl[sp.cos(a)], repl[sp.sin(a)] = kc.as_expr(), ks.as_expr()

        def bound(p) -> float:
            """sup |p| <= sum |coefficient| prod radius^e (|cos|, |sin| <= 1), rounded up."""
            total = Fraction(0)
            for monom, coef in p.terms():
                term = abs(Fraction(int(coef.numerator), int(coef.denominator)))
                for idx, e in enumerate(monom):
                    if e and idx in radius:
                        term *= radius[idx] ** e
                total += term
            return float(total) * (1 + 1e-12)

        polys = [[R.from_expr(Jt[i, j].xreplace(repl)) if Jt[i, j] != 0 else R.zero for j in range(n)]
                 for i in range(n)]
        first = [[[op(x) for x in row] for row in polys] for op in ops]
        for j in range(m):
            for k in range(j, m):
                second = [[ops[k](x) for x in row] for row in first[j]]
                self.second[j, k] = self.second[k, j] = [[bound(x) for x in row] for row in second]
                for i in range(k, m):
                    third = np.array([[bound(ops[i](x)) for x in row] for row in second])
                    for a_, b_, c_ in set(itertools.permutations((j, k, i))):
                        self.third[a_, b_, c_] = third
