"""Branch and bound over the inner angles for the grouped bound, every speed vertex on shared cells (issue 23).

The claim (appendix, eq. a7: V = e'^T W^-T J W^-1 e' decays when W + W^T - J' > 0 on the box of
scale v; B the grouped majorant of J' over the outer angles, derive.control.certificate.grouped): in the
coordinates of S = W + W^T = L L^T (T = L^-1),

    G_sigma(theta) = I - v B~_sigma(theta) > 0 for every inner theta and every vertex sigma,

B~ = T B T^T, a trigonometric polynomial in the inner angles with exactly known coefficients
C~_{sigma,h} (the term c cos(h.theta) + s sin(h.theta) is at most |C~_h| = sqrt(c^2 + s^2)
entrywise, and its derivatives d_j, d_jk at most |h_j| |C~_h|, |h_j h_k| |C~_h|), over the inner
angles' limits where they span less than a turn and their whole turn otherwise (the outer angles:
every value).

The claim is a conjunction over the vertices, and each vertex has its own minimiser theta*_sigma of
lambda_min(G_sigma) over the domain and u* a unit eigenvector of that smallest eigenvalue.
phi(theta) = u*^T G_sigma(theta) u* is at least lambda_min(G_sigma(theta)) everywhere and equal to it
at theta*, so theta* minimises phi and d_j phi(theta*) = 0 along every angle j where theta* is not on
a limit. With the second derivatives bounded on the whole domain at once from the coefficients,

    |d_jk B~_sigma(theta)| <= T2_{sigma,jk} = sum_h |C~_{sigma,h}| |h_j h_k|      (entrywise, every theta),

Taylor's theorem from theta* on the cell (centre c, half-widths r) holding it (|c - theta*|_j <= r_j)
gives (||X||_2 <= || |X| ||_2, monotone in the entries of a nonnegative matrix)

    lambda_min(G_sigma(c)) <= phi(c) <= phi(theta*) + v || sum_{j in F} r_j T1_{sigma,j} ||_2
                                        + v/2 || sum_jk r_j r_k T2_{sigma,jk} ||_2,

F: the angles along which the cell touches a limit (there theta* may sit on it), T1_{sigma,j} =
sum_h |C~_{sigma,h}| |h_j|. So a cell where lambda_min(G_sigma(c)) exceeds these bounds cannot hold
theta*_sigma unless lambda_min(G_sigma(theta*)) > 0, and neither can any part of it: when every
cell of a cover passes for sigma, G_sigma is positive definite everywhere. The test is a Cholesky
factorisation of G_sigma(c) minus the bounds (and the shift below) times I.

The cells are shared by the vertices: a cell carries the vertices still open on it (those that
passed on a larger cell holding it are done), the values of B's R basis matrices (constant,
sigma_l, sigma_l sigma_l') at the centres come from one product of the centres' cos and sin (from
products of two halves' exponentials) by the kept coefficients, and each open vertex's value is
their combination. The vertices' landscapes are alike (the same terms with other signs), so most
cells are needed by many of them (the Panda: 34 open vertices a cell on average): a cell costs 22
basis matrices' values, not 64 vertices'. A failed cell is halved along the angle of its largest
term. Values come from the leading frequencies of every vertex (the dropped terms' absolute sum
bounds their value; T1 and T2 keep every term); the shift subtracted from a value holds that tail,
the coefficients' and the products' rounding and the transform's (GroupedModel.rounding), and the
test subtracts T S T^T's computed distance from I. A centre
where G_sigma itself (past the shift) is not positive definite ends the decision: unproven (the
grouped bound refutes nothing).

Measured on the Panda (W synthesised for the 1 rad/s box, inner theta2..theta5, outer theta6,
theta7; one core): the grouped bound's supremum is about 92 % of N's own numeric supremum, and the
decision proves 80 % of N's supremum in 105,000 cells (22 s CPU) and 85 % in 156,000 (33 s), about
0.2 ms a cell. The alternatives measured: one branch and bound per vertex (the same test, one
vertex's series a cell) needs 45,000-57,000 cells for each of the 64 vertices at 80 % (about 110 s at 32 us a cell);
the Hessian at each centre from the series (derive.control.certificate.grouped_cells) costs 4 ms a cell for a
remainder no smaller on cells of 0.1-0.3 rad.
"""
from __future__ import annotations

import math
import time

import numpy as np

from derive.control.certificate.decision import FLOAT_MARGIN, Decision, Verdict, _positive_definite, _spectral_norm, \
    halve_cells
from derive.control.certificate.grouped import GroupedModel

TAIL = 1e-3              # the dropped terms' spectral bound per vertex, relative to || sum_h |C~_h| ||_2
SERIES_ROUNDING = 1e-11  # relative rounding of B's coefficients (grid values, transform, the vertex's sum)
EVAL_ROUNDING = 1e-12    # relative rounding of a value from the kept terms (the exponentials of |h.theta| <= 50)
PIECES = 4               # the first cells: PIECES per angle


def domain(model: GroupedModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lo, hi, bounded): an inner angle whose limits span less than a turn ranges over them (its
    faces need the first-order term), any other over a whole turn."""
    bounded = np.array([not model.full.periodic[k] and span[1] - span[0] < 2 * math.pi
                        for k, span in zip(model.inner, model.spans)], dtype=bool)
    lo = np.array([span[0] if b else -math.pi for span, b in zip(model.spans, bounded)])
    hi = np.array([span[1] if b else math.pi for span, b in zip(model.spans, bounded)])
    return lo, hi, bounded


def first_cells(lo: np.ndarray, hi: np.ndarray, pieces: int = PIECES) -> tuple[np.ndarray, np.ndarray]:
    """The first cover of the box [lo, hi] (m angles): pieces^m cells, (centres, half-widths), each P x m."""
    m = lo.size
    axes = [lo[j] + (2 * np.arange(pieces) + 1) * (hi[j] - lo[j]) / (2 * pieces) for j in range(m)]
    centres = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, m)
    return centres, np.broadcast_to((hi - lo) / (2 * pieces), centres.shape).copy()


class Shared:
    """The W-dependent arrays of a decision: the basis matrices' kept terms in S's scale (upper
    triangles), and per vertex the shift (tail of the dropped terms, rounding), T1 and T2."""

    def __init__(self, model: GroupedModel, W: np.ndarray) -> None:
        H, C, basis = model.series()
        n, m = model.n, model.m
        S = W + W.T
        T = np.linalg.inv(np.linalg.cholesky(S))
        Ct = np.einsum("ab,xrkbc,dc->xrkad", T, C, T, optimize=True)                    # 2 x R x K x n x n
        # T is L^-1 up to rounding: T S T^T >= (1 - gap) I, gap its computed distance from I plus that
        # product's own rounding (the cell test takes I for T S T^T and subtracts gap)
        self.gap = float(np.linalg.norm(T @ S @ T.T - np.eye(S.shape[0]))) \
            + 4 * S.shape[0] ** 2 * 1.2e-16 * float(np.linalg.norm(T)) ** 2 * float(np.linalg.norm(S))
        V, R, K = basis.shape[0], basis.shape[1], H.shape[0]
        Ha = np.abs(H.astype(float))
        rounding = model.rounding * np.linalg.norm(T, 2) ** 2 * (1 + 1e-12)
        self.T1 = np.empty((V, m, n, n))
        self.T2 = np.empty((V, m, m, n, n))
        mags, scales = [], np.empty(V)
        keep = np.zeros(K, dtype=bool)
        for k in range(V):
            cos = np.tensordot(basis[k], Ct[0], axes=(0, 0))
            sin = np.tensordot(basis[k], Ct[1], axes=(0, 0))
            mag = np.sqrt(cos ** 2 + sin ** 2)
            mag = mag * (1 + SERIES_ROUNDING) + SERIES_ROUNDING * mag.sum(axis=0, keepdims=True)
            scales[k] = float(_spectral_norm(mag.sum(axis=0)))
            self.T1[k] = np.einsum("kj,kab->jab", Ha, mag)
            self.T2[k] = np.einsum("kj,kl,kab->jlab", Ha, Ha, mag, optimize=True)
            # this vertex's fewest leading terms whose dropped rest is below TAIL (bisection on the exact tail)
            order = np.argsort(-mag.reshape(K, -1).max(axis=1), kind="stable")
            tails = np.cumsum(mag[order[::-1]], axis=0)[::-1]
            lo, hi = 1, K
            while lo < hi:
                mid = (lo + hi) // 2
                lo, hi = (lo, mid) if float(_spectral_norm(tails[mid])) <= TAIL * scales[k] else (mid + 1, hi)
            keep[order[:lo]] = True
            mags.append(mag)
        kept = np.flatnonzero(keep)
        # a value's rounding: the products' sums over 2K' terms (gamma_{2K'} sum |coef|, |cos|, |sin| <= 1
        # up to the exponentials' own few ulps) for every basis matrix, and the vertex's sum of R of them
        every = np.sqrt(Ct[0] ** 2 + Ct[1] ** 2).sum(axis=(0, 1))                             # n x n
        products = (2 * kept.size + R + 16) * 2.3e-16 * float(np.sqrt((every ** 2).sum())) * 1.5
        self.shift = np.array([float(_spectral_norm(mag[~keep].sum(axis=0))) if (~keep).any() else 0.0
                               for mag in mags]) + (EVAL_ROUNDING + SERIES_ROUNDING) * scales + rounding \
            + products                                                                        # V
        self.T2n = np.sqrt((self.T2 ** 2).sum(axis=(-1, -2))).max(axis=0)                   # m x m, the largest
        self.T1n = np.sqrt((self.T1 ** 2).sum(axis=(-1, -2))).max(axis=0)                   # m
        iu = np.triu_indices(n)
        self.iu, self.n, self.m, self.R = iu, n, m, R
        # every basis matrix's kept cos and sin coefficients, basis-major: (R u) x K'
        self.cos = Ct[0][:, kept][..., iu[0], iu[1]].transpose(0, 2, 1).reshape(R * iu[0].size, -1).copy()
        self.sin = Ct[1][:, kept][..., iu[0], iu[1]].transpose(0, 2, 1).reshape(R * iu[0].size, -1).copy()
        self.basis = basis
        Hk = H[kept].astype(int)
        self.halves = (list(range(m // 2)), list(range(m // 2, m)))
        self.deg = int(np.abs(H).max()) if H.size else 0
        self.index = [np.ravel_multi_index(tuple(Hk[:, j] + self.deg for j in part), (2 * self.deg + 1,) * len(part))
                      if part else np.zeros(kept.size, int) for part in self.halves]
        self._quad: dict = {}
        self.lo, self.hi, self.bounded = domain(model)

    def _half(self, c: np.ndarray, part: int) -> np.ndarray:
        """exp(i sum_j k_j theta_j) over one half of the angles, every k_j in [-deg, deg]: (2 deg + 1)^|half| x P."""
        k = np.arange(-self.deg, self.deg + 1)
        out = np.ones((1, c.shape[0]), dtype=complex)
        for j in self.halves[part]:
            z = np.exp(1j * k[:, None] * c[None, :, j])                                   # (2 deg + 1) x P
            out = (out[:, None, :] * z[None, :, :]).reshape(-1, c.shape[0])   # this angle the fastest index
        return out

    def values(self, c: np.ndarray) -> np.ndarray:
        """Every vertex's B~ at centres c (P x m) from the kept terms, upper triangles: V x u x P."""
        a, b = self._half(c, 0), self._half(c, 1)
        ar, ai = a.real[self.index[0]], a.imag[self.index[0]]
        br, bi = b.real[self.index[1]], b.imag[self.index[1]]
        up = self.cos @ (ar * br - ai * bi) + self.sin @ (ar * bi + ai * br)                    # (R u) x P
        return (self.basis @ up.reshape(self.R, -1)).reshape(self.basis.shape[0], -1, c.shape[0])

    def lowest(self, q: np.ndarray, v: float) -> np.ndarray:
        """lambda_min(G_sigma) at points q (P x m) past each vertex's shift, the smallest over the vertices: P."""
        vals = self.values(q)                                                                # V x u x P
        B = np.empty((q.shape[0], vals.shape[0], self.n, self.n))
        up = np.moveaxis(vals, -1, 0)
        B[..., self.iu[0], self.iu[1]] = up
        B[..., self.iu[1], self.iu[0]] = up
        top = np.linalg.eigvalsh(B)[..., -1] + self.shift[None]
        return (1.0 - self.gap - v * top).min(axis=1)

    def supremum(self, count: int = 2048, starts: int = 6, seed: int = 0) -> float:
        """Numeric estimate of the largest v the grouped bound can prove (an upper bound of it, up to
        the search): the smallest 1 / (lambda_max(B~_sigma) + shift) over ``count`` random inner points
        and the first cells' centres, then Nelder-Mead (scipy) from the ``starts`` worst, each vertex's
        own value, within the domain."""
        from scipy.optimize import minimize

        lo, hi = self.lo, self.hi
        rng = np.random.default_rng(seed)
        q = np.vstack([first_cells(lo, hi)[0], lo + (hi - lo) * rng.random((count, self.m))])
        tops = np.concatenate([1.0 - self.gap - self.lowest(q[i:i + 512], 1.0) for i in range(0, q.shape[0], 512)])
        best = float(tops.max())
        for i in np.argsort(-tops)[:starts]:
            def f(x):
                return float(self.lowest(np.clip(x, lo, hi)[None], 1.0)[0]) - 1.0 + self.gap

            res = minimize(f, q[i], method="Nelder-Mead", options={"xatol": 1e-5, "fatol": 1e-9, "maxiter": 600})
            best = max(best, -float(res.fun))
        return math.inf if best <= 0 else 1.0 / best

    def quad(self, r: np.ndarray) -> np.ndarray:
        """1/2 || sum_jk r_j r_k T2_{sigma,jk} ||_2 per vertex (V), cached per half-widths."""
        key = r.tobytes()
        if key not in self._quad:
            self._quad[key] = _spectral_norm(0.5 * np.einsum("j,k,vjkab->vab", r, r, self.T2))
        return self._quad[key]


def decide_shared(model: GroupedModel, W, v: float, budget: int = 1_000_000, batch: int = 2048,
                  prepared: Shared | None = None) -> Decision:
    """(*) by the grouped bound on cells shared by the vertices: proved or unproven (the grouped
    bound refutes nothing). W: n x n [N m s/rad]; v: the box's scale (v times the model's shape,
    rad/s); budget: cells examined at most. The margin is FLOAT_MARGIN's: a passed cell's slack
    is only known to exceed it (a Cholesky test); low: the smallest lambda_min(G_sigma) (past the
    shift) at the first cells' centres, or at the centre that ends an unproven decision. The box
    is symmetric, so v and -v are the same box (as derive.control.certificate reads them: G = I -
    v B~ holds B~'s bound only for v >= 0); a non-finite v or W proves nothing."""
    start = time.perf_counter()
    W = np.asarray(W, dtype=float)
    if not (math.isfinite(v) and np.all(np.isfinite(W))):
        return Decision(Verdict.UNPROVEN, 0, None, None, math.nan, time.perf_counter() - start)
    v = abs(float(v))
    try:
        prep = Shared(model, W) if prepared is None else prepared
    except np.linalg.LinAlgError:
        return Decision(Verdict.UNPROVEN, 0, None, None, math.nan, time.perf_counter() - start)
    n, V = prep.n, prep.basis.shape[0]
    tol = FLOAT_MARGIN * 2
    lo, hi, bounded = domain(model)
    edge = 1e-9 * (1 + np.abs(lo) + np.abs(hi))
    centres, halves = first_cells(lo, hi)
    opened = np.ones((centres.shape[0], V), dtype=bool)
    cells = 0
    low = float(prep.lowest(centres, v).min())   # the first cells' centres
    iu = prep.iu
    while centres.shape[0]:
        c, h, o = centres[-batch:], halves[-batch:], opened[-batch:]      # depth first: the open cells stay few
        centres, halves, opened = centres[:-batch], halves[:-batch], opened[:-batch]
        cells += c.shape[0]
        vals = prep.values(c)                                                                # V x u x P
        p, k = np.nonzero(o)                                                                 # the open pairs
        quad = np.stack([prep.quad(r) for r in h])                                           # P x V
        face = bounded[None] & ((c - h <= lo + edge) | (c + h >= hi - edge))                 # P x m
        need = v * prep.shift[k] + v * quad[p, k] + prep.gap + tol                           # Q
        if face.any():
            fp = face[p].any(axis=1)
            need[fp] += v * _spectral_norm(np.einsum("qj,qjab->qab", (h * face)[p[fp]], prep.T1[k[fp]]))
        A = np.empty((n, n, p.size))
        up = -v * vals[k, :, p].T                                                             # u x Q
        A[iu[0], iu[1]] = up
        A[iu[1], iu[0]] = up
        base = A.copy()
        A[np.arange(n), np.arange(n)] += 1.0 - need[None]
        # a Cholesky test (certificate._positive_definite; its rounding is below 1e-13 ||A||, A near I here)
        ok = _positive_definite(np.moveaxis(A, -1, 0))
        if not ok.all():   # the failed pairs: is G_sigma(c) itself positive definite (past the shift)?
            F = base[:, :, ~ok]
            F[np.arange(n), np.arange(n)] += 1.0 - (v * prep.shift[k[~ok]] + prep.gap + tol)[None]
            bad = ~_positive_definite(np.moveaxis(F, -1, 0))
            if bad.any():
                lam = np.linalg.eigvalsh(np.moveaxis(F[:, :, bad], -1, 0))[:, 0] + tol
                return Decision(Verdict.UNPROVEN, cells, None, None, min(low, float(lam.min())),
                                time.perf_counter() - start)
        still = np.zeros_like(o)
        still[p[~ok], k[~ok]] = True
        todo = still.any(axis=1)
        if todo.any():
            if cells + centres.shape[0] + 2 * int(todo.sum()) > budget:
                return Decision(Verdict.UNPROVEN, cells, None, None, low, time.perf_counter() - start)
            cs, hs = c[todo], h[todo]
            pull = hs @ prep.T2n + 2.0 * face[todo] * prep.T1n[None]                              # P' x m
            kids, kid_halves = halve_cells(cs, hs, np.argmax(hs * pull, axis=1))
            centres, halves = np.vstack([centres, kids]), np.vstack([halves, kid_halves])
            opened = np.vstack([opened, still[todo], still[todo]])
    return Decision(Verdict.PROVED, cells, tol, None, low, time.perf_counter() - start)


GROUPED_INNER = 4         # inner angles of the grouped stage: the deps nearest the base (the wrist's outer)
GROUPED_BUDGET = 400_000  # cells per decision of the grouped stage (about 0.2 ms a cell on one core)


def _one_thread():
    """BLAS on one thread (threadpoolctl): the stage's products are a few hundred rows by a few thousand,
    which a second thread speeds by less than it costs in CPU time (as derive's commands do)."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(1, "blas")


class GroupedStage:
    """The grouped bound as a stage of derive.control.certificate.ObserverCertificate (opt-in,
    rate 0 only: B majorises J', not 2 beta J): the model of the arm's box shape, the W-dependent
    arrays and the supremum estimate cached for the last W (a search decides one W many times)."""

    def __init__(self, full, shape, inner: tuple[int, ...] | None = None, budget: int = GROUPED_BUDGET) -> None:
        inner = tuple(range(min(GROUPED_INNER, full.m))) if inner is None else tuple(inner)
        self.model = GroupedModel(full, inner, np.asarray(shape, dtype=float))
        self.budget = budget
        self._last: tuple[bytes, Shared, list] | None = None

    def _shared(self, W: np.ndarray) -> tuple[Shared, list]:
        key = np.ascontiguousarray(W, dtype=float).tobytes()
        if self._last is None or self._last[0] != key:
            self._last = (key, Shared(self.model, W), [])
        return self._last[1], self._last[2]

    def decide(self, W, v: float) -> Decision:
        """(*) at rate 0 on the box of scale v by the grouped bound (decide_shared)."""
        W = np.asarray(W, dtype=float)
        start = time.perf_counter()
        with _one_thread():
            try:
                prep, _ = self._shared(W)
            except np.linalg.LinAlgError:   # W + W^T not positive definite: nothing to prove with
                return Decision(Verdict.UNPROVEN, 0, None, None, math.nan, time.perf_counter() - start)
            dec = decide_shared(self.model, W, v, self.budget, prepared=prep)
        return Decision(dec.verdict, dec.cells, dec.margin, dec.point, dec.low, time.perf_counter() - start)

    def supremum(self, W) -> float:
        """Shared.supremum for W (cached): 0 when W + W^T is not positive definite."""
        W = np.asarray(W, dtype=float)
        with _one_thread():
            try:
                prep, memo = self._shared(W)
            except np.linalg.LinAlgError:
                return 0.0
            if not memo:
                memo.append(prep.supremum())
        return memo[0]
