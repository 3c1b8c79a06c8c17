"""Branch and bound over the inner angles for the grouped bound of derive.control.certificate.grouped.

The claim (appendix, eq. a7: V decays when W + W^T - J' > 0 on the box of scale v): in the
coordinates of S = W + W^T = L L^T (T = L^-1, S becomes I),

    G_sigma(theta) = I - v B~_sigma(theta) is positive definite for every inner theta and vertex sigma,

B~ = T B T^T (B: derive.control.certificate.grouped, a trigonometric polynomial in the inner angles with
exactly known coefficients), over the inner angles' limits where they span less than a turn and
their whole turn otherwise (the outer angles: every value). The cell test needs no first-order
term inside the domain: let theta* minimise lambda_min(G(theta)) over the domain and u* be a unit
eigenvector of its smallest eigenvalue. phi(theta) = u*^T G(theta) u* is at least
lambda_min(G(theta)) everywhere and equal to it at theta*, so theta* minimises the smooth phi and
its partial derivative vanishes along every angle where theta* is not on a limit. For a cover of
the domain by cells (centre c, half-widths r), the cell holding theta* (delta = c - theta*,
|delta_j| <= r_j) has, by Taylor's theorem with the integral remainder,

    lambda_min(G(c)) <= phi(c) = phi(theta*) + sum_{j in F} delta_j d_j phi(theta*)
                                 + int_0^1 (1 - t) delta^T (d^2 phi)(theta* + t delta) delta dt
                     <= phi(theta*) + v || sum_{j in F} r_j T1_j ||_2
                        + v || 1/2 sum_jk r_j r_k |d_jk B~(c)| + sum_h |C~_h| a_h^2 w(a_h) ||_2,

F: the angles along which the cell touches a limit (elsewhere d_j phi(theta*) = 0), T1_j =
sum_h |C~_h| |h_j| (entrywise: a bound of |d_j B~| everywhere), a_h = sum_j |h_j| r_j, and
w(a) = int_0^1 s min(2, s a) ds (a / 3 for a <= 2, 1 - 4 / (3 a^2) above): the Hessian's term h
moves by at most |C~_h| |h_j h_k| min(2, |h.(xi - c)|) between c and xi (|X| entrywise, C~_h the
coefficient of exp(i h.theta), and ||X||_2 <= || |X| ||_2). So if on every cell

    lambda_min(G(c)) - (the two bounds above) > 0,

then phi(theta*) > 0: G is positive definite everywhere and (*) holds. Cells that fail are split
along the angle of the largest term; a centre where G(c) itself is not positive definite ends the
search (unproven: the grouped bound refutes nothing). Values and Hessians at the centres come from
the series, truncated to the frequencies that matter; the dropped terms' absolute sums are added
(value: to the spectral norm subtracted, Hessian: entrywise), as is the transform's rounding.

Not used by derive.control.certificate: too slow; derive.control.certificate.grouped_union decides the same
claim with a cell test from the coefficients alone (no Hessian series per cell), and is the stage
ObserverCertificate(grouped=True) uses. Measured on the Panda (W synthesised for
the 1 rad/s box, inner angles theta2..theta5, outer theta6, theta7; one core): the grouped bound's
sampled supremum is 3.67, 94 % of N's own numeric supremum 3.92 (the constant majorant of
derive.control.certificate.split: 26 %), but one decision proves 30 % of it in 6,016 cells (23 s CPU) and 40 %
in 11,246 cells (45 s; plus 13 s for the series and the W-dependent arrays). B has degree 4 in
each inner angle and its curvature is large against the slack: about 4 ms a cell, and cells of
about 0.2 rad near the worst states, so 80 % would need tens of thousands of cells.
"""
from __future__ import annotations

import math
import time

import numpy as np

from derive.control.certificate.decision import FLOAT_MARGIN, Decision, Verdict, _spectral_norm, halve_cells
from derive.control.certificate.grouped import GroupedModel
from derive.control.certificate.grouped_union import domain, first_cells

TAIL = 2e-3          # the dropped terms' spectral bound, relative to || sum_h |C~_h| ||_2: what the truncation may cost
SERIES_ROUNDING = 1e-11   # relative rounding of B's coefficients (the grid values and the transform)


def _pairs(m: int) -> list[tuple[int, int]]:
    return [(j, k) for j in range(m) for k in range(j, m)]


class Prepared:
    """The W-dependent arrays of one decision: the truncated series in S's scale (upper triangles),
    the tails, and the third-derivative bounds per vertex."""

    def __init__(self, model: GroupedModel, W: np.ndarray) -> None:
        n, m = model.n, model.m
        H, C, basis = model.series()
        S = W + W.T
        T = np.linalg.inv(np.linalg.cholesky(S))
        Ct = np.einsum("ab,xrkbc,dc->xrkad", T, C, T)                                  # 2 x R x K x n x n
        V = basis.shape[0]
        mag = np.sqrt(np.einsum("vr,rkab->vkab", basis, Ct[0]) ** 2 + np.einsum("vr,rkab->vkab", basis, Ct[1]) ** 2)
        mag = mag * (1 + SERIES_ROUNDING) + SERIES_ROUNDING * mag.sum(axis=1, keepdims=True)   # V x K x n x n
        top = mag.reshape(V, mag.shape[1], -1).max(axis=(0, 2))                        # K
        order = np.argsort(-top)
        scale = max(float(_spectral_norm(mag.sum(axis=1)).max()), 1e-300)
        # the fewest leading frequencies whose dropped rest is below TAIL (bisection on the exact tail)
        def tail(cut: int) -> float:
            return float(_spectral_norm(mag[:, order[cut:]].sum(axis=1)).max()) if cut < order.size else 0.0

        lo_cut, hi_cut = 1, order.size
        while lo_cut < hi_cut:
            mid = (lo_cut + hi_cut) // 2
            lo_cut, hi_cut = (lo_cut, mid) if tail(mid) <= TAIL * scale else (mid + 1, hi_cut)
        cut = lo_cut
        kept, dropped = order[:cut], order[cut:]
        Hf = H.astype(float)
        self.H = Hf[kept]
        self.tail0 = _spectral_norm(mag[:, dropped].sum(axis=1)) if dropped.size else np.zeros(V)      # V
        self.pairs = _pairs(m)
        weights = np.array([Hf[:, j] * Hf[:, k] for j, k in self.pairs]).reshape(len(self.pairs), -1)    # pairs x K
        self.tail2 = np.einsum("xk,vkab->vxab", np.abs(weights[:, dropped]), mag[:, dropped])          # V x pairs x n x n
        triples = np.abs(Hf)
        self.T3 = np.einsum("ki,kj,kl,vkab->vijlab", triples, triples, triples, mag, optimize=True)    # V x m x m x m x n x n
        self.T1 = np.einsum("kj,vkab->vjab", triples, mag)                                             # V x m x n x n
        self.T1_size = np.sqrt((self.T1 ** 2).sum(axis=(-1, -2))).max(axis=0)                         # m
        self.T3_size = np.sqrt((self.T3 ** 2).sum(axis=(-1, -2))).max(axis=0)                         # m x m x m
        self.mag, self.absH = mag, triples                                                             # every term
        self._cap: dict = {}
        iu = np.triu_indices(n)
        self.iu = iu
        cols = []
        for w in [np.ones(Hf.shape[0])] + [-wk for wk in weights]:      # value, then d_jk of cos/sin: -h_j h_k
            cols.append(np.concatenate([w[kept, None, None] * Ct[0][:, kept][..., iu[0], iu[1]].transpose(1, 0, 2),
                                        w[kept, None, None] * Ct[1][:, kept][..., iu[0], iu[1]].transpose(1, 0, 2)]))
        self.big = np.stack(cols, axis=1).reshape(2 * kept.size, -1)                   # 2K' x ((1 + pairs) R u)
        self.basis = basis
        self.R = basis.shape[1]
        self.rounding = model.rounding * np.linalg.norm(T, 2) ** 2                      # V
        self.n, self.m = n, m

    def cap(self, r: np.ndarray) -> np.ndarray:
        """The Hessian's variation over a cell of half-widths r (m), integrated (module docstring):
        sum_h |C~_h| a_h^2 w(a_h), a_h = |h|.r, w(a) = a / 3 (a <= 2), 1 - 4 / (3 a^2) (a > 2): V x n x n
        (cached per r: the cells' half-widths are the spans over powers of two)."""
        key = r.tobytes()
        if key not in self._cap:
            a = self.absH @ r
            w = np.where(a <= 2.0, a / 3.0, 1.0 - 4.0 / (3.0 * np.maximum(a, 2.0) ** 2))
            self._cap[key] = np.einsum("k,vkab->vab", a * a * w, self.mag) * (1 + 1e-12)
        return self._cap[key]

    def evaluate(self, c: np.ndarray) -> np.ndarray:
        """B~ and its second derivatives at centres c (P x m): P x V x (1 + pairs) x n x n."""
        arg = c @ self.H.T
        vals = np.hstack([np.cos(arg), np.sin(arg)]) @ self.big                           # P x ((1 + pairs) R u)
        u = self.iu[0].size
        vals = vals.reshape(c.shape[0], 1 + len(self.pairs), self.R, u)
        per = np.einsum("vr,pxru->pvxu", self.basis, vals)
        out = np.zeros(per.shape[:3] + (self.n, self.n))
        out[..., self.iu[0], self.iu[1]] = per
        out[..., self.iu[1], self.iu[0]] = per
        return out


def decide_grouped(model: GroupedModel, W, v: float, budget: int = 200_000, batch: int = 256,
                   prepared: Prepared | None = None) -> Decision:
    """Branch and bound over the inner angles (module docstring): proved or unproven (the
    grouped bound refutes nothing). W: n x n [N m s/rad]; v: the box's scale (the box is v times
    the model's shape, rad/s); budget: cells examined at most."""
    start = time.perf_counter()
    W = np.asarray(W, dtype=float)
    m = model.m
    try:
        prep = Prepared(model, W) if prepared is None else prepared
    except np.linalg.LinAlgError:
        return Decision(Verdict.UNPROVEN, 0, None, None, math.nan, time.perf_counter() - start)
    n = prep.n
    tol = FLOAT_MARGIN * 2
    pairs = prep.pairs
    index = {p: i for i, p in enumerate(pairs)}
    pos = np.array([[index[(min(j, k), max(j, k))] for k in range(m)] for j in range(m)])      # m x m
    shift = v * (prep.rounding + prep.tail0)                                                      # V
    lo, hi, bounded = domain(model)
    centres, halves = first_cells(lo, hi)
    edge = 1e-9 * (1 + np.abs(lo) + np.abs(hi))
    cells, margin, low = 0, math.inf, math.inf
    eye = np.eye(n)
    while centres.shape[0]:
        c, h = centres[:batch], halves[:batch]
        centres, halves = centres[batch:], halves[batch:]
        cells += c.shape[0]
        E = prep.evaluate(c)                                                              # P x V x (1 + pairs) x n x n
        G = eye - v * E[:, :, 0]
        lam = np.linalg.eigvalsh(G)[..., 0] - shift[None]                                   # P x V
        low = min(low, float(lam.min()))
        if lam.min() <= tol:
            return Decision(Verdict.UNPROVEN, cells, None, None, low, time.perf_counter() - start)
        curv = (np.abs(E[:, :, 1:]) + prep.tail2[None])[:, :, pos]                       # P x V x m x m x n x n
        quad = 0.5 * np.einsum("pj,pk,pvjkab->pvab", h, h, curv)
        quad = _spectral_norm(quad + np.stack([prep.cap(r) for r in h]))                   # P x V
        # at a face: the minimiser may sit on it, its gradient there is at most T1 (first order)
        face = bounded[None] & ((c - h <= lo + edge) | (c + h >= hi - edge))                      # P x m
        grad = _spectral_norm(np.einsum("pj,vjab->pvab", h * face, prep.T1)) if face.any() else 0.0
        slack = (lam - v * quad - v * grad).min(axis=1)
        ok = slack > tol
        if ok.any():
            margin = min(margin, float(slack[ok].min()))
        todo = ~ok
        if todo.any():
            if cells + centres.shape[0] + 2 * int(todo.sum()) > budget:
                return Decision(Verdict.UNPROVEN, cells, None, None, low, time.perf_counter() - start)
            cs, hs = c[todo], h[todo]
            size = np.sqrt((curv[todo] ** 2).sum(axis=(-1, -2))).max(axis=1) + \
                (2.0 / 3.0) * np.einsum("pi,ijk->pjk", hs, prep.T3_size)                          # P' x m x m
            pull = np.einsum("pjk,pk->pj", size, hs) + 2.0 * face[todo] * prep.T1_size[None]
            kids, kid_halves = halve_cells(cs, hs, np.argmax(hs * pull, axis=1))
            centres, halves = np.vstack([centres, kids]), np.vstack([halves, kid_halves])
    return Decision(Verdict.PROVED, cells, margin, None, low, time.perf_counter() - start)
