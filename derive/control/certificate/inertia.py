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

from derive.dynamics.dag import Memo, free_symbols
from derive.dynamics.sx import to_sx
from derive.dynamics.program import postorder
from derive.dynamics.trigpoly import constant_angles
from derive.control.certificate.derivative_bounds import ROUNDING, fourier_derivative_bounds  # noqa: F401 (re-exported)

FULL_TURN = 2.0 * math.pi
# J's exact series costs prod(2 d_k + 1) n^2 values (5^m n^2 for a chain): past this many, the bounds
# come from J's supremum and its degrees (derive.control.certificate.interval: cost polynomial in n, looser)
SERIES_BUDGET = 1 << 23
FOURTH_BUDGET = 1 << 22   # m^4 n^2 numbers of the fourth-derivative bounds from the degrees


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
    input states: a revolute joint's range, a prismatic joint's travel; a range of zero width,
    lower >= upper, counts as none)."""
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
                if lower is not None and upper is not None and lower >= upper:
                    lower = upper = None   # a zero-width range (some URDFs write 0, 0 for none): no range
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
    |d^3 J/dq_i dq_j dq_k| valid for every q in the spans; ``scale``: 1 / sqrt(J_ii) at the middle
    of the spans (n), the diagonal scale the certificate decides in.
    """

    def __init__(self, J: sp.Matrix, coords: tuple[Coordinate, ...]) -> None:
        self.n = n = J.rows
        free = free_symbols(sp.sympify(x) for x in J)    # each shared subexpression once
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
        self._series = None   # (coefficients, frequencies or powers, polynomial flags, half-widths)
        self._fourth: np.ndarray | None = None
        self._first: np.ndarray | None = None   # bounds of |dJ/dq_k| (first(): degrees, intervals)
        self.bounded_by = "series"   # how second, third are bounded: "series", "coefficients", "degrees"
        self.scale = np.ones(n)   # D^-1: 1 / sqrt of J's diagonal at the middle of the spans (the certificate's scale)
        if self.unbounded:
            return
        middle = np.array([[(lo + hi) / 2 for lo, hi in self.spans]]).reshape(1, m)
        diag = np.diag(self.J(middle)[0])
        if np.all(np.isfinite(diag)) and np.all(diag > 0):
            self.scale = 1.0 / np.sqrt(diag)
        if m == 0:   # J constant (one joint, or joints that move no inertia's shape): its own mean, no derivatives
            self.fourier = (self.J(np.zeros((1, 0))).astype(complex), np.zeros((1, 0), dtype=int))
            return
        degrees = self._degrees(J)
        if degrees is not None:
            for k, c in enumerate(self.deps):
                lo, hi = c.span
                if c.angle and (hi - lo >= FULL_TURN or (c.lower is None and c.upper is None)):
                    self.spans[k], self.periodic[k] = (-math.pi, math.pi), True
            points = math.prod(d + 1 if not c.angle else 2 * d + 1 for d, c in zip(degrees, self.deps))
            if points * n * n <= SERIES_BUDGET:
                self._series_bounds(degrees)
            else:
                self._degree_bounds(J, degrees)
        else:
            self.bounded_by = "coefficients"
            self._coefficient_bounds(J)

    # -- numbers -----------------------------------------------------------------------------
    def _numeric(self, J: sp.Matrix, syms: list[sp.Symbol]) -> None:
        """CasADi functions of J, dJ/dq (n^2 m) and d^2 J/dq^2 (n^2 m^2, made on first use: a split certificate
        takes J's series instead; its CSE took 0.19 s of a 7-joint init), batched by ``map``."""
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
        self._fun = {"J": ca.Function("J", [x], [v], opts), "dJ": ca.Function("dJ", [x], [ca.vec(d1)], opts)}
        self._maps: dict = {}
        self._x, self._d2 = x, d2

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
        """d^2 J/dq_j dq_k at points q: N x m x m x n x n (its CasADi function made on first use)."""
        if "d2J" not in self._fun:
            self._fun["d2J"] = ca.Function("d2J", [self._x], [ca.vec(self._d2)], {"cse": True})
        return self._eval("d2J", q).reshape(q.shape[0], self.m, self.m, self.n, self.n)

    def jet(self, q: np.ndarray, order: int, scale: np.ndarray | None = None) -> list[np.ndarray]:
        """[J, dJ, d2J, d3J][:order + 1] at points q (shapes as each method's), each entry (a, b) times
        ``scale[a, b]`` when given."""
        return [f(q) if scale is None else f(q) * scale for f in (self.J, self.dJ, self.d2J, self.d3J)[:order + 1]]

    def d3J(self, q: np.ndarray) -> np.ndarray:
        """d^3 J/dq_i dq_j dq_k at points q: N x m x m x m x n x n (its CasADi function made on first use)."""
        if "d3J" not in self._fun:
            x = self._x
            self._fun["d3J"] = ca.Function("d3J", [x], [ca.vec(ca.jacobian(ca.vec(self._d2), x))], {"cse": True})
        m, n = self.m, self.n
        return self._eval("d3J", q).reshape(q.shape[0], m, m, m, n, n)

    # -- bounds ------------------------------------------------------------------------------
    def _degrees(self, J: sp.Matrix) -> list[int] | None:
        """An upper bound of J's degree in each dep (m): in cos, sin of an angle (a trigonometric
        polynomial of that degree), in a prismatic coordinate (a polynomial), read off J's
        expression graph (a sum takes the largest, a product adds, a power multiplies; sin, cos of
        k q + c count |k|), each distinct subexpression once. An upper bound is all the series
        needs (its higher coefficients are then 0, each exact); a serial chain's J has degree 2
        in every coordinate, and the graph of the recursive dynamics gives 2. None when J is not
        such a polynomial (an angle outside sin, cos; a coordinate under another function)."""
        deps = [c.symbol for c in self.deps]
        angle = {c.symbol: c.angle for c in self.deps}
        zero = (0,) * len(deps)
        memo: dict = {}
        depset = set(deps)
        moves: dict = {}   # whether a subexpression holds a dep (children first: linear in the graph)
        for e in postorder([sp.sympify(x) for x in J]):
            moves[e] = e in depset if e.is_Symbol else any(moves[a] for a in e.args)
            if not moves[e]:
                memo[e] = zero
            elif e.is_Symbol:
                memo[e] = None if angle[e] else tuple(int(q == e) for q in deps)
            elif isinstance(e, (sp.sin, sp.cos)):
                coeffs = [sp.sympify(e.args[0]).coeff(q) for q in deps]
                rest = sp.expand(e.args[0] - sum(c * q for c, q in zip(coeffs, deps)))
                ok = all(c.is_Integer and (c == 0 or angle[q]) for c, q in zip(coeffs, deps))
                memo[e] = tuple(abs(int(c)) for c in coeffs) if ok and not (rest.free_symbols & depset) else None
            elif any(memo[a] is None for a in e.args):
                memo[e] = None
            elif e.is_Add:
                memo[e] = tuple(max(memo[a][k] for a in e.args) for k in range(len(deps)))
            elif e.is_Mul:
                memo[e] = tuple(sum(memo[a][k] for a in e.args) for k in range(len(deps)))
            elif e.is_Pow and e.exp.is_Integer and e.exp >= 0:
                memo[e] = tuple(int(e.exp) * d for d in memo[e.base])
            else:
                memo[e] = None
        degs = [memo[sp.sympify(x)] for x in J]
        if any(d is None for d in degs):
            return None
        self.entry_degrees = np.array(degs, dtype=int).reshape(self.n, self.n, len(deps))   # per entry (n x n x m)
        return [max(d[k] for d in degs) for k in range(len(deps))]

    def _series_bounds(self, deg: list[int]) -> None:
        """Bounds of the 2nd and 3rd derivatives from J's exact series in its coordinates.

        J is a trigonometric polynomial of degree at most d_k in each angle k and a polynomial of
        degree at most d_k in each prismatic coordinate (d_k: :meth:`_degrees`), so J(q) = sum_f C_f
        prod_angles exp(i f_k q_k) prod_lengths t_k^(f_k) over |f_k| <= d_k (t_k = (q_k - mid_k) /
        half_k in [-1, 1] over the span), and J's values on a grid of 2 d_k + 1 equispaced angles and
        d_k + 1 Chebyshev points per length give the C_f exactly: the discrete Fourier transform
        along the angles, the Vandermonde solve along the lengths (up to rounding, covered by the
        inflation of fourier_derivative_bounds). Then |d^3 J/dq_i dq_j dq_k| <= sum_f |C_f| prod
        (the derivative's factor per coordinate) for every q: tight where the sum-of-coefficients
        bound in cos, sin counts cos(a + b) as 2 terms. With every coordinate an angle the series
        is ``fourier`` (the split, derive.control.certificate.split, works on it).
        """
        n, m = self.n, self.m
        poly = [not c.angle for c in self.deps]
        mid = np.array([0.0 if not p else sum(c.span) / 2 for c, p in zip(self.deps, poly)])
        half = np.array([1.0 if not p else max((c.span[1] - c.span[0]) / 2, 1e-300) for c, p in zip(self.deps, poly)])
        sizes = [d + 1 if p else 2 * d + 1 for d, p in zip(deg, poly)]
        nodes = [np.cos(np.pi * (np.arange(L) + 0.5) / L) if p else 2 * np.pi * np.arange(L) / L
                 for L, p in zip(sizes, poly)]
        axes = [mid[k] + half[k] * t if poly[k] else t for k, t in enumerate(nodes)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, m)
        # J is symmetric: the transform of its upper triangle's entries, mirrored (each entry's is its own)
        upper = np.triu_indices(n)
        coef = self.J(grid)[:, upper[0], upper[1]].reshape(*sizes, -1).astype(complex)
        for k in range(m):
            if poly[k]:   # t^e coefficients: solve the Vandermonde system along axis k
                V = np.vander(nodes[k], sizes[k], increasing=True)
                coef = np.moveaxis(np.tensordot(np.linalg.inv(V), coef, axes=(1, k)), 0, k)
            else:
                coef = np.fft.fft(coef, axis=k)
                coef /= sizes[k]
        freqs = [np.arange(L) if p else np.fft.fftfreq(L, 1.0 / L) for L, p in zip(sizes, poly)]
        F = np.stack(np.meshgrid(*freqs, indexing="ij"), axis=-1).reshape(-1, m).astype(int)
        column = np.zeros((n, n), dtype=int)
        column[upper] = np.arange(upper[0].size)
        coef = np.ascontiguousarray(coef.reshape(-1, upper[0].size)[:, np.maximum(column, column.T)])
        if not any(poly):
            self.fourier = (coef, F)
        self._series = (coef, F, poly, half)
        self.second, self.third = fourier_derivative_bounds(coef, F, poly, half)

    def _degree_bounds(self, J: sp.Matrix, deg: list[int]) -> None:
        """Bounds of the 2nd and 3rd derivatives from sup |J| and J's degrees (Bernstein, Markov:
        derive.control.certificate.interval), for a J whose series is past SERIES_BUDGET. Cost: one pass over
        J's graph and m^3 n^2 numbers."""
        from derive.control.certificate.interval import degree_bounds, supremum_matrix

        self.bounded_by = "degrees"
        angle = [c.angle for c in self.deps]
        half = [1.0 if a else max((c.span[1] - c.span[0]) / 2, 1e-300) for a, c in zip(angle, self.deps)]
        self.supremum = supremum_matrix(J, self.deps, self.spans)
        self._degree_args = (self.supremum, self.entry_degrees, angle, half)
        self._J = J
        self.second, self.third = degree_bounds(*self._degree_args)

    def first(self) -> np.ndarray:
        """Bounds of |dJ/dq_k| valid for every q within the spans (m x n x n): the smaller of the
        degrees' (Bernstein, Markov) and interval arithmetic's on J's graph (only after
        :meth:`_degree_bounds`; snake12: the bound of the norm certificate's J' halved)."""
        from derive.control.certificate.interval import markov_factor

        if self._first is not None:
            return self._first
        S, deg, angle, half = self._degree_args
        f = [deg[..., k] if a else np.vectorize(markov_factor)(deg[..., k], 1) / h
             for k, (a, h) in enumerate(zip(angle, half))]
        bernstein = np.array(f, dtype=float) * S[None] * (1 + 1e-12)
        self._first = np.minimum(bernstein, self._gradient_bounds())
        return self._first

    def _gradient_bounds(self) -> np.ndarray:
        """|dJ_ab/dq_k| over the spans (within the joint limits) by interval arithmetic on J's graph
        (derive.control.certificate.interval.interval_gradients): m x n x n."""
        from derive.control.certificate.interval import interval_gradients

        n, m = self.n, self.m
        pairs = [(i, j) for i in range(n) for j in range(i, n)]
        boxes = {c.symbol: span for c, span in zip(self.deps, self.spans)}
        G = interval_gradients([self._J[i, j] for i, j in pairs], boxes, [c.symbol for c in self.deps])
        out = np.zeros((m, n, n))
        for (i, j), g in zip(pairs, np.abs(G).max(axis=-1)):
            out[:, i, j] = out[:, j, i] = g
        return out

    @property
    def fourth(self) -> np.ndarray | None:
        """Bounds of |d^4 J/dq_h dq_i dq_j dq_k| valid for every q (m x m x m x m x n x n), from
        the series or the degrees (None without either, or past FOURTH_BUDGET numbers: the
        coefficient bounds stop at the third derivative)."""
        if self._fourth is None and self._series is not None:
            self._fourth = fourier_derivative_bounds(*self._series, fourth=True)[2]
        if self._fourth is None and self.bounded_by == "degrees" and self.m ** 4 * self.n ** 2 <= FOURTH_BUDGET:
            from derive.control.certificate.interval import degree_bounds

            self._fourth = degree_bounds(*self._degree_args, fourth=True)[2]
        return self._fourth

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
        for a in constants:   # |cos a|, |sin a| of a constant: their values, rounded up (sound, and far tighter than 1)
            kc, ks = next(g), next(g)
            repl[sp.cos(a)], repl[sp.sin(a)] = kc.as_expr(), ks.as_expr()
            for gen, value in ((kc, sp.cos(a)), (ks, sp.sin(a))):
                radius[R.gens.index(gen)] = Fraction(abs(float(sp.N(value, 30)))) * (1 + Fraction(1, 10 ** 12))

        def bound(p) -> float:
            """sup |p| <= sum |coefficient| prod radius^e (|cos|, |sin| <= 1 of a joint angle), rounded up."""
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
