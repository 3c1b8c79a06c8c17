"""Observer certificate for n joints: the appendix's Lyapunov argument (proof of theorem 2), generalised.

With the observer error e' = B d - dhat' (a1, a5): e'' = -W J^-1(theta) e'. For
V = e'^T W^-T J(theta) W^-1 e' (a7) and x = W^-1 e',

    dV/dt = -x^T (W + W^T - J'(theta, theta')) x,   J' = sum_k theta'_k dJ/dtheta_k,

so V decays at least as exp(-2 beta t) (the estimate converges exponentially at rate beta) when

    N(theta, theta') = W + W^T - J'(theta, theta') - 2 beta J(theta)  is positive definite     (*)

for every theta (within joint limits where the arm has them) and every theta' in the box
|theta'_k| <= v s_k (s: the box's shape, v its scale). J' is linear in theta', so N is affine in
theta' and its smallest eigenvalue is concave there: the box is covered exactly by its 2^m
vertices (m: the joints whose angle J depends on; the others' speeds do not enter J').

Over theta the claim is decided by branch and bound, sound for every theta: on a cell with centre
c and half-widths r, each entry of N moves by at most sum_k r_k sup |dN_ij/dtheta_k| (mean value
theorem), where the supremum is bounded symbolically: dN/dtheta_k is a polynomial in cos, sin of
the angles (and in the coordinates of prismatic joints, bounded by their limits), and the sum of
the absolute values of its coefficients bounds it (|cos|, |sin| <= 1). With R the matrix of these
entry bounds, ||N(theta) - N(c)||_2 <= ||R||_2 (R is nonnegative), so Weyl's inequality gives
lambda_min(N(theta)) >= lambda_min(N(c)) - ||R||_2 on the whole cell. A cell where that is above
a floating-point margin is proved; otherwise it is split along its widest contribution. A centre
where N itself is not positive definite refutes (*) at that point. A cell budget bounds the work:
past it the claim is ``unproven`` with the numeric evidence.
"""
from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass
from enum import Enum
from fractions import Fraction

import numpy as np
import sympy as sp
from sympy.polys.rings import ring

from derive.dynamics.trigpoly import constant_angles

FLOAT_MARGIN = 1e-9   # relative to 1 + ||W + W^T||: covers eigvalsh's rounding (~ n eps ||N||)
DEFAULT_BUDGET = 20_000   # cells per decision
MAX_ENUMERATED = 4          # cells' vertices are enumerated for m <= this (2^m affine corners)


class Verdict(str, Enum):
    PROVED = "proved"
    REFUTED = "refuted"
    UNPROVEN = "unproven"


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


@dataclass(frozen=True)
class Decision:
    """The outcome of (*) for one W, box and rate.

    verdict: proved / refuted / unproven; cells: cells examined; margin: the
    smallest lambda_min(N(c)) - ||R||_2 over the proved cells (proved) ; point: a
    (theta, theta') where N is not positive definite (refuted), or the worst
    centre found; low: the smallest lambda_min(N) seen at a centre.
    """

    verdict: Verdict
    cells: int
    margin: float | None
    point: tuple[tuple[float, ...], tuple[float, ...]] | None
    low: float
    seconds: float


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

    ``deps``: the coordinates J depends on (m of them); numeric J and dJ/dq_k (k in deps)
    evaluate on batches of points; ``first[k]`` and ``second[j][k]`` are n x n matrices of
    upper bounds of |dJ/dq_k| and |d^2 J/dq_j dq_k| valid for every q in the coordinates' spans.
    """

    def __init__(self, J: sp.Matrix, coords: tuple[Coordinate, ...]) -> None:
        self.n = J.rows
        free = set().union(*(sp.sympify(x).free_symbols for x in J))
        self.deps = tuple(c for c in coords if c.symbol in free)
        self.unbounded = tuple(c for c in self.deps if c.span is None)
        self.m = len(self.deps)
        syms = [c.symbol for c in self.deps]
        n = self.n
        Jt = J.applyfunc(_trig_ready)
        self._J = sp.lambdify(syms, list(Jt), modules="numpy", cse=True)
        dJ = [Jt.diff(q) for q in syms]
        self._dJ = sp.lambdify(syms, [x for M in dJ for x in M], modules="numpy", cse=True)
        d2J = [dJ[j].diff(q) for j in range(self.m) for q in syms]
        self._d2J = sp.lambdify(syms, [x for M in d2J for x in M], modules="numpy", cse=True)
        self.second = np.zeros((self.m, self.m, n, n))
        self.third = np.zeros((self.m, self.m, self.m, n, n))
        if self.unbounded:
            return
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
        if all(c.angle for c in self.deps):
            self._fourier_bounds(polys)
            return
        first = [[[op(x) for x in row] for row in polys] for op in ops]
        m = self.m
        for j in range(m):
            for k in range(j, m):
                second = [[ops[k](x) for x in row] for row in first[j]]
                self.second[j, k] = self.second[k, j] = [[bound(x) for x in row] for row in second]
                for i in range(k, m):
                    third = np.array([[bound(ops[i](x)) for x in row] for row in second])
                    for a_, b_, c_ in set(itertools.permutations((j, k, i))):
                        self.third[a_, b_, c_] = third

    def _fourier_bounds(self, polys) -> None:
        """Bounds of the 2nd and 3rd derivatives from J's Fourier coefficients (every dep an angle).

        J is a trigonometric polynomial of degree d_k in angle k (d_k: the largest total degree
        in cos, sin of that angle), so J(q) = sum_f C_f exp(i f.q) over integer frequencies
        |f_k| <= d_k, and J's values on the grid of 2 d_k + 1 points per angle give the C_f
        exactly by the discrete Fourier transform (up to rounding, covered by the inflation
        below). Then |d^3 J/dq_i dq_j dq_k| <= sum_f |C_f| |f_i f_j f_k| for every q: tight
        where the sum-of-coefficients bound in cos, sin counts cos(a + b) as 2 terms.
        """
        n, m = self.n, self.m
        deg = [0] * m
        for row in polys:
            for p in row:
                for monom, _ in p.terms():
                    for k in range(m):
                        deg[k] = max(deg[k], monom[2 * k] + monom[2 * k + 1])
        sizes = [2 * d + 1 for d in deg]
        axes = [2 * np.pi * np.arange(L) / L for L in sizes]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, m)
        values = self.J(grid).reshape(*sizes, n, n)
        coef = np.fft.fftn(values, axes=tuple(range(m))) / np.prod(sizes)
        mag = np.abs(coef)
        mag = mag + (1e-12 * mag.sum(axis=tuple(range(m)), keepdims=True) + 1e-300)   # rounding of the transform
        freqs = [np.fft.fftfreq(L, 1.0 / L) for L in sizes]   # 0, 1, .., d, -d, .., -1
        F = np.stack(np.meshgrid(*freqs, indexing="ij"), axis=-1)   # sizes x m
        absF = np.abs(F)
        for j in range(m):
            for k in range(m):
                w2 = absF[..., j] * absF[..., k]
                self.second[j, k] = np.tensordot(w2, mag, axes=(tuple(range(m)), tuple(range(m))))
                for i in range(m):
                    self.third[i, j, k] = np.tensordot(w2 * absF[..., i], mag, axes=(tuple(range(m)), tuple(range(m))))

    def _stack(self, values: list, count: int, shape: tuple[int, ...]) -> np.ndarray:
        return np.stack([np.broadcast_to(np.asarray(v, dtype=float), (count,)) for v in values], axis=-1).reshape(
            (count, *shape))

    def J(self, q: np.ndarray) -> np.ndarray:
        """J at points q (N x m, the deps' values): N x n x n."""
        return self._stack(self._J(*q.T), q.shape[0], (self.n, self.n))

    def dJ(self, q: np.ndarray) -> np.ndarray:
        """dJ/dq_k at points q: N x m x n x n."""
        return self._stack(self._dJ(*q.T), q.shape[0], (self.m, self.n, self.n))

    def d2J(self, q: np.ndarray) -> np.ndarray:
        """d^2 J/dq_j dq_k at points q: N x m x m x n x n."""
        return self._stack(self._d2J(*q.T), q.shape[0], (self.m, self.m, self.n, self.n))


def _spectral_norm(R: np.ndarray) -> np.ndarray:
    """||R||_2 of symmetric nonnegative matrices (... x n x n), rounded up."""
    return np.abs(np.linalg.eigvalsh(R)).max(axis=-1) * (1 + 1e-12) + 1e-300


class ObserverCertificate:
    """Decides (*) for an arm's J: give W, the box shape s (n), its scale v and the rate beta."""

    def __init__(self, model: InertiaModel) -> None:
        self.model = model
        m = model.m
        self.signs = np.array(list(itertools.product((1.0, -1.0), repeat=m))) if m else np.zeros((1, 0))

    # -- numbers at points -------------------------------------------------------------------
    def matrices(self, W: np.ndarray, shape: np.ndarray, v: float, beta: float, q: np.ndarray) -> np.ndarray:
        """N at every box vertex for points q (N x m): N x 2^m x n x n."""
        md = self.model
        S = W + W.T
        J = md.J(q)
        dJ = md.dJ(q)
        speeds = self.signs * np.array([shape[c.index] for c in md.deps])[None, :]   # 2^m x m
        Jdot = np.einsum("vk,pkij->pvij", speeds, dJ) * v
        return S[None, None] - Jdot - 2.0 * beta * J[:, None]

    def lowest(self, W, shape, v, beta, q) -> tuple[np.ndarray, np.ndarray]:
        """Smallest eigenvalue of N over the vertices at each point, and the worst vertex index."""
        lam = np.linalg.eigvalsh(self.matrices(W, shape, v, beta, q))[..., 0]
        return lam.min(axis=1), lam.argmin(axis=1)

    def samples(self, count: int, seed: int = 0) -> np.ndarray:
        """A grid over the deps' spans (at most ``count`` points) plus as many random points."""
        md = self.model
        if md.m == 0:
            return np.zeros((1, 0))
        per = max(2, int(count ** (1.0 / md.m)))
        if md.m <= 2:
            per = max(4, per - per % 4)   # holds the quarter turns, where sin is +-1
        axes = [np.linspace(*c.span, per, endpoint=not c.angle) for c in md.deps]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, md.m)
        rng = np.random.default_rng(seed)
        lo = np.array([c.span[0] for c in md.deps])
        hi = np.array([c.span[1] for c in md.deps])
        return np.vstack([grid, lo + (hi - lo) * rng.random((count, md.m))])

    # -- the sound decision ------------------------------------------------------------------
    def decide(self, W: np.ndarray, shape, v: float, beta: float = 0.0, budget: int = DEFAULT_BUDGET,
               batch: int = 512) -> Decision:
        """Branch and bound over the deps' spans: proved, refuted or unproven (module docstring).

        On a cell (centre c, half-widths r), for each box vertex: Taylor's theorem per entry gives
        N(c + delta) = N(c) + sum_k delta_k dN/dq_k(c) + E with |E| <= 1/2 sum_jk r_j r_k T_jk
        (T_jk: the symbolic bounds of |d^2 N/dq_j dq_k|), so by Weyl lambda_min(N) >= (the smallest
        eigenvalue of the affine part, concave in delta, so least at a vertex of the cell) - ||E||_2.
        A cheaper lower bound of the affine part is tried first:
        lambda_min(N(c)) - || sum_k r_k |dN/dq_k(c)| ||_2.
        """
        start = time.perf_counter()
        md = self.model
        W = np.asarray(W, dtype=float)
        shape = np.asarray(shape, dtype=float)
        tol = FLOAT_MARGIN * (1 + np.linalg.norm(W + W.T, 2))

        def done(verdict, cells, margin=None, point=None, low=math.nan):
            return Decision(verdict, cells, margin, point, low, time.perf_counter() - start)

        if md.unbounded:
            return done(Verdict.UNPROVEN, 0)
        if md.m == 0:
            lam, _ = self.lowest(W, shape, v, beta, np.zeros((1, 0)))
            ok = lam[0] > tol
            return done(Verdict.PROVED if ok else Verdict.REFUTED, 1, float(lam[0]) if ok else None,
                        None if ok else ((), ()), float(lam[0]))
        m, n = md.m, md.n
        s = np.array([shape[c.index] for c in md.deps])
        speeds = self.signs * s[None, :]                                        # V x m
        S = W + W.T
        # T_jk bounds |d^2 N / dq_j dq_k| for every vertex: v sum_i s_i |d3 J| + 2 beta |d2 J|
        T = v * np.einsum("i,ijkab->jkab", s, md.third) + 2.0 * beta * md.second
        Tn = np.array([[_spectral_norm(T[j, k]) for k in range(m)] for j in range(m)])
        deltas = np.array(list(itertools.product((1.0, -1.0), repeat=m)))      # 2^m x m
        lo = np.array([c.span[0] for c in md.deps])
        hi = np.array([c.span[1] for c in md.deps])
        centres, halves = ((lo + hi) / 2)[None, :], ((hi - lo) / 2)[None, :]
        cells, margin, low, worst = 0, math.inf, math.inf, None
        while centres.shape[0]:
            c, h = centres[:batch], halves[:batch]
            centres, halves = centres[batch:], halves[batch:]
            cells += c.shape[0]
            P = c.shape[0]
            J, dJ, d2J = md.J(c), md.dJ(c), md.d2J(c)
            N = S[None, None] - v * np.einsum("vi,piab->pvab", speeds, dJ) - 2.0 * beta * J[:, None]
            dN = -v * np.einsum("vi,pikab->pvkab", speeds, d2J) - 2.0 * beta * dJ[:, None]   # P x V x m x n x n
            lam = np.linalg.eigvalsh(N)[..., 0]                                               # P x V
            i, vi = np.unravel_index(int(lam.argmin()), lam.shape)
            if lam[i, vi] < low:
                low, worst = float(lam[i, vi]), (c[i], vi)
            if lam[i, vi] <= 0:
                theta = tuple(float(x) for x in c[i])
                return done(Verdict.REFUTED, cells, None, (theta, tuple(float(x) * v for x in speeds[vi])),
                            float(lam[i, vi]))
            rem = _spectral_norm(0.5 * np.einsum("pj,pk,jkab->pab", h, h, T))                # P
            lin = _spectral_norm(np.einsum("pk,pvkab->pvab", h, np.abs(dN)))                 # P x V
            bound = lam - lin                                                                  # P x V
            hard = np.argwhere(bound - rem[:, None] <= tol) if m <= MAX_ENUMERATED else np.zeros((0, 2), int)
            for chunk in range(0, hard.shape[0], max(1, 65536 // (deltas.shape[0] * n * n))):
                pv = hard[chunk:chunk + max(1, 65536 // (deltas.shape[0] * n * n))]
                A = N[pv[:, 0], pv[:, 1]][:, None] + np.einsum("dk,qk,qkab->qdab", deltas, h[pv[:, 0]],
                                                                 dN[pv[:, 0], pv[:, 1]])
                bound[pv[:, 0], pv[:, 1]] = np.linalg.eigvalsh(A)[..., 0].min(axis=1)
            slack = bound.min(axis=1) - rem
            ok = slack > tol
            if ok.any():
                margin = min(margin, float(slack[ok].min()))
            split = ~ok
            if split.any():
                if cells + centres.shape[0] + 2 * int(split.sum()) > budget:
                    theta = tuple(float(x) for x in worst[0])
                    return done(Verdict.UNPROVEN, cells, None, (theta, tuple(float(x) * v for x in speeds[worst[1]])),
                                low)
                cs, hs = c[split], h[split].copy()
                grow = np.sqrt((dN[split] ** 2).sum(axis=(-1, -2))).max(axis=1)              # P' x m
                axis = np.argmax(hs * (grow + hs @ Tn), axis=1)
                rows = np.arange(cs.shape[0])
                hs[rows, axis] /= 2
                left, right = cs.copy(), cs.copy()
                left[rows, axis] -= hs[rows, axis]
                right[rows, axis] += hs[rows, axis]
                centres = np.vstack([centres, left, right])
                halves = np.vstack([halves, hs, hs])
        return done(Verdict.PROVED, cells, margin, None, low)

    # -- numeric suprema ---------------------------------------------------------------------
    def speed_supremum(self, W, shape, beta: float = 0.0, count: int = 4096) -> float:
        """Numeric estimate (an upper bound up to sampling) of the largest v for which (*) holds:
        min over samples and vertices of 1 / lambda_max(A^-1/2 K A^-1/2), A = W + W^T - 2 beta J,
        K = J' at the vertex for v = 1; 0 when A itself fails somewhere."""
        md = self.model
        q = self.samples(count)
        W = np.asarray(W, dtype=float)
        A = self.matrices(W, shape, 0.0, beta, q)[:, 0]
        if np.linalg.eigvalsh(A)[:, 0].min() <= 0:
            return 0.0
        if md.m == 0:
            return math.inf
        K = -(self.matrices(W, shape, 1.0, 0.0, q) - self.matrices(W, shape, 0.0, 0.0, q))   # J' at v = 1
        L = np.linalg.cholesky(A)
        Li = np.linalg.inv(L)
        C = np.einsum("pab,pvbc,pdc->pvad", Li, K, Li)
        top = np.linalg.eigvalsh(C)[..., -1].max()
        return math.inf if top <= 0 else float(1.0 / top)

    def rate_supremum(self, W, shape, v: float, count: int = 4096) -> float:
        """Numeric estimate of the largest beta for which (*) holds on the box of scale v:
        min over samples and vertices of lambda_min(J^-1/2 (W + W^T - J') J^-1/2) / 2."""
        q = self.samples(count)
        N0 = self.matrices(np.asarray(W, dtype=float), shape, v, 0.0, q)
        J = self.model.J(q)
        Li = np.linalg.inv(np.linalg.cholesky(J))
        C = np.einsum("pab,pvbc,pdc->pvad", Li, N0, Li)
        return float(np.linalg.eigvalsh(C)[..., 0].min() / 2)


@dataclass(frozen=True)
class Report:
    """What ``derive check`` says about the observer of one arm.

    shape: the box's shape (the stated max_joint_speed, or ones); stated: whether it was
    stated; speed: the largest certified scale v at rate 0 (box |theta'_k| <= v s_k) and
    speed_sup its numeric supremum; rate: the largest certified beta on the stated box
    (at rest when none is stated) and rate_sup its numeric supremum; stated_decision: (*)
    at beta = 0 on the stated box (None when none is stated); coords: the deps.
    """

    W: tuple[tuple[float, ...], ...]
    shape: tuple[float, ...]
    stated: bool
    speed: float
    speed_sup: float
    speed_decision: Decision | None
    rate: float
    rate_sup: float
    rate_decision: Decision | None
    stated_decision: Decision | None
    unbounded: tuple[str, ...]
    seconds: float


TRIES = (0.99, 0.97, 0.9, 0.7, 0.5, 0.25, 0.1)


def _best(decide, sup: float, cap: float | None = None) -> tuple[float, Decision | None]:
    """The largest fraction of ``sup`` (of TRIES) that ``decide`` proves, and its decision."""
    if not (sup > 0):
        return 0.0, None
    top = sup if cap is None or not math.isfinite(sup) else min(sup, cap)
    if not math.isfinite(top):
        return math.inf, None
    last = None
    for f in TRIES:
        dec = decide(top * f)
        last = dec
        if dec.verdict is Verdict.PROVED:
            return top * f, dec
    return 0.0, last


def report(d, W=None, budget: int = DEFAULT_BUDGET, samples: int = 4096) -> Report:
    """Certified speed box (rate 0) and rate (on the stated box) for derivation ``d``."""
    start = time.perf_counter()
    model = inertia_model(d)
    cert = ObserverCertificate(model)
    Wn = np.array((d.W if W is None else W).tolist(), dtype=float)
    speeds = d.arm.controller.max_joint_speed
    stated = speeds is not None
    shape = np.array([float(x) for x in speeds]) if stated else np.ones(d.n)
    unbounded = tuple(str(c.symbol) for c in model.unbounded)
    sup_v = cert.speed_supremum(Wn, shape, 0.0, samples)
    speed, sdec = _best(lambda v: cert.decide(Wn, shape, v, 0.0, budget), sup_v)
    v_rate = 1.0 if stated else 0.0
    stated_dec = cert.decide(Wn, shape, 1.0, 0.0, budget) if stated else None
    sup_b = cert.rate_supremum(Wn, shape, v_rate, samples)
    rate, rdec = _best(lambda b: cert.decide(Wn, shape, v_rate, b, budget), sup_b)
    return Report(W=tuple(map(tuple, Wn.tolist())), shape=tuple(shape.tolist()), stated=stated, speed=speed,
                  speed_sup=sup_v, speed_decision=sdec, rate=rate, rate_sup=sup_b, rate_decision=rdec,
                  stated_decision=stated_dec, unbounded=unbounded, seconds=time.perf_counter() - start)


_MODELS: dict = {}


def inertia_model(d) -> InertiaModel:
    """The InertiaModel of ``d``'s J (cached per derivation object)."""
    key = id(d)
    hit = _MODELS.get(key)
    if hit is not None and hit[0] is d:
        return hit[1]
    model = InertiaModel(d.J, joint_coordinates(d.arm, d.theta))
    _MODELS[key] = (d, model)
    return model
