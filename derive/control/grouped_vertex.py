"""Branch and bound over the inner angles for the grouped bound, one speed vertex at a time (issue 23).

The claim is that of derive.control.grouped_cells (appendix, eq. a7: V decays when W + W^T - J' > 0
on the box of scale v; B the grouped majorant of J' over the outer angles, derive.control.grouped):
in the coordinates of S = W + W^T = L L^T (T = L^-1),

    G_sigma(theta) = I - v B~_sigma(theta) > 0 for every inner theta and every vertex sigma,

B~ = T B T^T, a trigonometric polynomial in the inner angles with exactly known coefficients
C~_{sigma,h} (amplitude |C~_{sigma,h}| entrywise: the term is c cos(h.theta) + s sin(h.theta), at
most sqrt(c^2 + s^2) in absolute value and so are its derivatives times |h_j h_k|).

The claim is a conjunction over the vertices, so each vertex is decided on its own: it has its own
minimiser theta*_sigma of lambda_min(G_sigma) and its own cells, and a vertex refined near its own
worst angles costs nothing elsewhere. The cell test is the zero-gradient argument of
grouped_cells (phi(theta) = u*^T G_sigma(theta) u*, u* the unit eigenvector of lambda_min at
theta*, minimised at theta*, its gradient zero along every angle where theta* is not on a limit),
with the second-order remainder bounded on the whole domain at once from the coefficients:

    |d_jk B~_sigma(theta)| <= T2_{sigma,jk} = sum_h |C~_{sigma,h}| |h_j h_k|      (entrywise, every theta)

so on the cell (centre c, half-widths r) holding theta* (|c - theta*|_j <= r_j)

    lambda_min(G_sigma(c)) <= phi(c) <= phi(theta*) + v || sum_{j in F} r_j T1_{sigma,j} ||_2
                                        + v/2 || sum_jk r_j r_k T2_{sigma,jk} ||_2,

F: the angles along which the cell touches a limit, T1_{sigma,j} = sum_h |C~_{sigma,h}| |h_j|. A
cell whose centre value minus these bounds is positive cannot hold theta* unless phi(theta*) > 0;
if every cell passes, G_sigma is positive definite everywhere. The remainder depends on the
half-widths only (cached): a cell costs the value of one vertex's series at its centre (one
product of the cells' cos/sin by the vertex's kept coefficients, n(n+1)/2 columns) and one small
eigenvalue problem, against the 22 basis matrices' values and ten Hessian entries of
grouped_cells. Values come from the leading frequencies (the dropped terms' absolute sum bounds
their value, T1 and T2 keep every term), with the coefficients' and the evaluation's rounding and
the transform's (GroupedModel.rounding) subtracted. A centre where G_sigma is not positive definite
ends the decision (unproven: the grouped bound refutes nothing).
"""
from __future__ import annotations

import math
import time

import numpy as np

from derive.control.certificate import FLOAT_MARGIN, Decision, Verdict, _spectral_norm, halve_cells
from derive.control.grouped import GroupedModel

TAIL = 1e-3              # the dropped terms' spectral bound per vertex, relative to || sum_h |C~_h| ||_2
SERIES_ROUNDING = 1e-11  # relative rounding of B's coefficients (grid values, transform, the vertex's sum)
EVAL_ROUNDING = 1e-12    # relative rounding of a value from the kept terms (cos/sin of |h.theta| <= 50, the sums)
PIECES = 4               # the first cells: PIECES per angle


class VertexSeries:
    """One vertex's series in S's scale: the kept frequencies and coefficients (upper triangle),
    the tail and rounding to subtract from a value, and T1, T2 over every term."""

    def __init__(self, H: np.ndarray, Ct: np.ndarray, weights: np.ndarray, rounding: float) -> None:
        n = Ct.shape[-1]
        cos = np.tensordot(weights, Ct[0], axes=(0, 0))                    # K x n x n
        sin = np.tensordot(weights, Ct[1], axes=(0, 0))
        mag = np.sqrt(cos ** 2 + sin ** 2)
        mag = mag * (1 + SERIES_ROUNDING) + SERIES_ROUNDING * mag.sum(axis=0, keepdims=True)
        scale = float(_spectral_norm(mag.sum(axis=0)))
        size = mag.reshape(mag.shape[0], -1).max(axis=1)
        order = np.argsort(-size, kind="stable")
        # the fewest leading frequencies whose dropped rest is below TAIL (bisection on the exact tail)
        tails = np.cumsum(mag[order[::-1]], axis=0)[::-1]                    # tails[i]: sum of order[i:]

        def tail(cut: int) -> float:
            return float(_spectral_norm(tails[cut])) if cut < order.size else 0.0

        lo, hi = 1, order.size
        while lo < hi:
            mid = (lo + hi) // 2
            lo, hi = (lo, mid) if tail(mid) <= TAIL * scale else (mid + 1, hi)
        kept = order[:lo]
        iu = np.triu_indices(n)
        self.iu, self.n = iu, n
        self.H = H[kept].astype(float)
        # the cos and the sin coefficients of each kept term: u x K' each
        self.cos, self.sin = cos[kept][:, iu[0], iu[1]].T.copy(), sin[kept][:, iu[0], iu[1]].T.copy()
        # exp(i h.theta) as a product of two factors, each over half of the angles' frequencies
        Hk = H[kept].astype(int)
        m = Hk.shape[1]
        self.halves = (list(range(m // 2)), list(range(m // 2, m)))
        self.deg = int(np.abs(H).max()) if H.size else 0
        self.index = [np.ravel_multi_index(tuple(Hk[:, j] + self.deg for j in part), (2 * self.deg + 1,) * len(part))
                      if part else np.zeros(kept.size, int) for part in self.halves]
        self.shift = tail(lo) + (EVAL_ROUNDING + SERIES_ROUNDING) * scale + rounding
        Ha = np.abs(H.astype(float))
        self.T1 = np.einsum("kj,kab->jab", Ha, mag)                                          # m x n x n
        self.T2 = np.einsum("kj,kl,kab->jlab", Ha, Ha, mag, optimize=True)                  # m x m x n x n
        self.T1n = np.sqrt((self.T1 ** 2).sum(axis=(-1, -2)))                               # m
        self.T2n = np.sqrt((self.T2 ** 2).sum(axis=(-1, -2)))                               # m x m
        self._quad: dict = {}

    def values(self, c: np.ndarray) -> np.ndarray:
        """B~_sigma at centres c (P x m) from the kept terms, the points last: n x n x P."""
        # cos and sin of h.theta from the two halves' factors (frequency-major: row gathers, contiguous)
        a, b = self._half(c, 0).T, self._half(c, 1).T
        ar, ai = a.real.copy()[self.index[0]], a.imag.copy()[self.index[0]]
        br, bi = b.real.copy()[self.index[1]], b.imag.copy()[self.index[1]]
        up = self.cos @ (ar * br - ai * bi) + self.sin @ (ar * bi + ai * br)                     # u x P
        out = np.empty((self.n, self.n, c.shape[0]))
        out[self.iu[0], self.iu[1]] = up
        out[self.iu[1], self.iu[0]] = up
        return out

    def _half(self, c: np.ndarray, part: int) -> np.ndarray:
        """exp(i sum_j k_j theta_j) over the angles of one half, every k_j in [-deg, deg]: P x (2 deg + 1)^|half|."""
        idx = self.halves[part]
        k = np.arange(-self.deg, self.deg + 1)
        out = np.ones((c.shape[0], 1), dtype=complex)
        for j in idx:
            z = np.exp(1j * c[:, j, None] * k[None, :])                                     # P x (2 deg + 1)
            out = (out[:, :, None] * z[:, None, :]).reshape(c.shape[0], -1)
        return out

    def quad(self, r: np.ndarray) -> float:
        """1/2 || sum_jk r_j r_k T2_jk ||_2 (cached per half-widths: spans over powers of two)."""
        key = r.tobytes()
        if key not in self._quad:
            self._quad[key] = float(_spectral_norm(0.5 * np.einsum("j,k,jkab->ab", r, r, self.T2)))
        return self._quad[key]


def positive_definite(A: np.ndarray) -> np.ndarray:
    """Whether each A[:, :, p] (n x n x P, symmetric) is positive definite: Cholesky without pivoting,
    each step one array operation over the points (A is overwritten). In floating point a success
    proves A + E positive definite with ||E||_2 <= n (n + 1) eps n ||A||_2 (Demmel's bound, Higham,
    Accuracy and Stability of Numerical Algorithms, thm 10.5): below 1e-13 ||A|| for n = 7, which
    the caller's shift by FLOAT_MARGIN covers (the matrices here are near I in norm)."""
    n = A.shape[0]
    ok = np.ones(A.shape[-1], dtype=bool)
    for k in range(n):
        pivot = A[k, k]
        ok &= pivot > 0
        if k + 1 < n:
            col = A[k + 1:, k] / np.where(pivot > 0, pivot, 1.0)
            A[k + 1:, k + 1:] -= col[:, None, :] * A[k, k + 1:][None, :, :]
    return ok


class Vertices:
    """The W-dependent part of a decision: every vertex's series (built when first asked)."""

    def __init__(self, model: GroupedModel, W: np.ndarray) -> None:
        H, C, basis = model.series()
        S = W + W.T
        T = np.linalg.inv(np.linalg.cholesky(S))
        self.Ct = np.einsum("ab,xrkbc,dc->xrkad", T, C, T, optimize=True)                   # 2 x R x K x n x n
        self.H, self.basis, self.model = H, basis, model
        self.rounding = model.rounding * np.linalg.norm(T, 2) ** 2 * (1 + 1e-12)          # V
        self._series: dict[int, VertexSeries] = {}

    def __len__(self) -> int:
        return self.basis.shape[0]

    def series(self, vertex: int) -> VertexSeries:
        if vertex not in self._series:
            self._series[vertex] = VertexSeries(self.H, self.Ct, self.basis[vertex],
                                                float(self.rounding[vertex]))
        return self._series[vertex]


def domain(model: GroupedModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lo, hi, bounded): an inner angle whose limits span less than a turn ranges over them (its
    faces need the first-order term), any other over a whole turn."""
    bounded = np.array([not model.full.periodic[k] and span[1] - span[0] < 2 * math.pi
                        for k, span in zip(model.inner, model.spans)], dtype=bool)
    lo = np.array([span[0] if b else -math.pi for span, b in zip(model.spans, bounded)])
    hi = np.array([span[1] if b else math.pi for span, b in zip(model.spans, bounded)])
    return lo, hi, bounded


def first_cells(lo: np.ndarray, hi: np.ndarray, pieces: int = PIECES) -> tuple[np.ndarray, np.ndarray]:
    m = lo.size
    axes = [lo[j] + (2 * np.arange(pieces) + 1) * (hi[j] - lo[j]) / (2 * pieces) for j in range(m)]
    centres = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, m)
    return centres, np.broadcast_to((hi - lo) / (2 * pieces), centres.shape).copy()


def decide_vertex(vs: VertexSeries, v: float, lo: np.ndarray, hi: np.ndarray, bounded: np.ndarray,
                  budget: int, batch: int = 4096) -> tuple[bool, int, float, float]:
    """One vertex's branch and bound (module docstring): (proved, cells, margin, low)."""
    n = vs.n
    tol = FLOAT_MARGIN * 2
    edge = 1e-9 * (1 + np.abs(lo) + np.abs(hi))
    centres, halves = first_cells(lo, hi)
    cells, margin, low = 0, math.inf, math.inf
    diag = np.arange(n)
    while centres.shape[0]:
        c, h = centres[-batch:], halves[-batch:]          # depth first: the open cells stay few
        centres, halves = centres[:-batch], halves[:-batch]
        cells += c.shape[0]
        Bv = -v * vs.values(c)                                                              # n x n x P
        quad = np.array([vs.quad(r) for r in h])
        face = bounded[None] & ((c - h <= lo + edge) | (c + h >= hi - edge))                 # P x m
        grad = _spectral_norm(np.einsum("pj,jab->pab", h * face, vs.T1)) if face.any() else 0.0
        # the cell passes when G(c) - (the bounds) I is positive definite (a Cholesky test)
        need = v * vs.shift + v * quad + v * grad + tol                                      # P
        A = Bv.copy()
        A[diag, diag] += 1.0 - need[None]
        ok = positive_definite(A)
        if not ok.all():   # the others' own smallest eigenvalue: G(c) itself fails, or the margin
            lam = np.linalg.eigvalsh(np.moveaxis(Bv[:, :, ~ok], -1, 0))[:, 0] + 1.0 - v * vs.shift
            low = min(low, float(lam.min()))
            if lam.min() <= tol:
                return False, cells, math.nan, low
        if ok.any():   # a passed cell's slack is above tol (the Cholesky test says no more)
            margin = min(margin, tol)
        todo = ~ok
        if todo.any():
            if cells + centres.shape[0] + 2 * int(todo.sum()) > budget:
                return False, cells, math.nan, low
            cs, hs = c[todo], h[todo]
            pull = hs @ vs.T2n + 2.0 * face[todo] * vs.T1n[None]                              # P' x m
            kids, kid_halves = halve_cells(cs, hs, np.argmax(hs * pull, axis=1))
            centres, halves = np.vstack([centres, kids]), np.vstack([halves, kid_halves])
    return True, cells, margin, low


def decide_vertices(model: GroupedModel, W, v: float, budget: int = 2_000_000,
                    prepared: Vertices | None = None) -> Decision:
    """(*) by the grouped bound, vertex by vertex: proved or unproven (the grouped bound refutes
    nothing). W: n x n [N m s/rad]; v: the box's scale (the box is v times the model's shape, rad/s);
    budget: cells examined at most, over every vertex. The vertices are taken hardest first (their
    smallest value on the first cells), so a box too large is usually found at the first vertex."""
    start = time.perf_counter()
    W = np.asarray(W, dtype=float)
    try:
        prep = Vertices(model, W) if prepared is None else prepared
    except np.linalg.LinAlgError:
        return Decision(Verdict.UNPROVEN, 0, None, None, math.nan, time.perf_counter() - start)
    lo, hi, bounded = domain(model)
    probe, _ = first_cells(lo, hi)
    top = [float(np.linalg.eigvalsh(prep.series(k).values(probe))[:, -1].max()) for k in range(len(prep))]
    cells, margin, low = 0, math.inf, math.inf
    for k in np.argsort(top)[::-1]:
        ok, used, mk, lk = decide_vertex(prep.series(int(k)), v, lo, hi, bounded, budget - cells)
        cells += used
        low = min(low, lk)
        if not ok:
            return Decision(Verdict.UNPROVEN, cells, None, None, low, time.perf_counter() - start)
        margin = min(margin, mk)
    return Decision(Verdict.PROVED, cells, margin, None, low, time.perf_counter() - start)
