"""Branch and bound over the inner angles for the grouped bound of derive.control.grouped.

The claim (appendix, eq. a7: V decays when W + W^T - J' > 0 on the box of scale v): in the
coordinates of S = W + W^T = L L^T (T = L^-1, S becomes I),

    G_sigma(theta) = I - v B~_sigma(theta) is positive definite for every inner theta and vertex sigma,

B~ = T B T^T (B: derive.control.grouped, a trigonometric polynomial in the inner angles with
exactly known coefficients). It is decided over the whole torus of the inner angles (the joint
limits are not used: a larger set, so still sound), which has no boundary, and that is what
makes the cell test cheap: let theta* minimise lambda_min(G(theta)) over the torus and u* be a
unit eigenvector of its smallest eigenvalue. phi(theta) = u*^T G(theta) u* is at least
lambda_min(G(theta)) everywhere and equal to it at theta*, so theta* minimises the smooth phi
and its gradient vanishes there. For a cover of the torus by cells (centre c, half-widths r),
the cell holding theta* (delta = c - theta*, |delta_j| <= r_j) has, by Taylor's theorem without
the first-order term,

    lambda_min(G(c)) <= phi(c) = phi(theta*) + 1/2 delta^T (d^2 phi)(xi) delta
                     <= phi(theta*) + v/2 || sum_jk r_j r_k (|d_jk B~(c)| + sum_i r_i T_ijk) ||_2,

xi in the cell, |X| entrywise, T_ijk = sum_h |C~_h| |h_i h_j h_k| (entrywise, from the series: a
bound of |d_ijk B~| valid everywhere) and ||X||_2 <= || |X| ||_2. So if on every cell

    lambda_min(G(c)) - v/2 || sum_jk r_j r_k (|d_jk B~(c)| + sum_i r_i T_ijk) ||_2 > 0,

then phi(theta*) > 0: G is positive definite everywhere and (*) holds. Cells that fail are split
along the angle of the largest term; a centre where G(c) itself is not positive definite ends the
search (unproven: the grouped bound refutes nothing). Values and Hessians at the centres come from
the series, truncated to the frequencies that matter; the dropped terms' absolute sums are added
(value: to the spectral norm subtracted, Hessian: entrywise), as is the transform's rounding.

Not used by derive.control.certificate: too slow yet. Measured on the Panda (W synthesised for
the 1 rad/s box, inner angles theta2..theta5, outer theta6, theta7; one core): the grouped bound's
sampled supremum on the torus is 3.67, 94 % of N's own numeric supremum 3.92 (the constant
majorant of derive.control.split: 26 %), but the branch and bound proves 30 % of it in 18,318
cells (72 s CPU) and 40 % in 32,460 cells (134 s). B has degree 4 in each inner angle, and the
third-derivative bound T (its coefficients times |h|^3) outweighs the Hessian at the centres on
cells wider than about 0.2 rad: the cells needed at 80 % are about 60,000 (sampled estimate).
"""
from __future__ import annotations

import math
import time

import numpy as np

from derive.control.certificate import FLOAT_MARGIN, Decision, Verdict, _spectral_norm
from derive.control.grouped import GroupedModel

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
    """Branch and bound over the inner angles' torus (module docstring): proved or unproven (the
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
    pieces = 4
    axes = [(-math.pi + (2 * np.arange(pieces) + 1) * math.pi / pieces) for _ in range(m)]
    centres = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, m)
    halves = np.full(centres.shape, math.pi / pieces)
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
        curv = np.abs(E[:, :, 1:]) + prep.tail2[None]                                      # P x V x pairs x n x n
        third = np.einsum("pi,vijkab->pvjkab", (2.0 / 3.0) * h, prep.T3)                                 # P x V x m x m x n x n
        full = curv[:, :, pos] + third                                                      # P x V x m x m x n x n
        weight = np.einsum("pj,pk->pjk", h, h)
        quad = _spectral_norm(np.einsum("pjk,pvjkab->pvab", weight, full))                  # P x V
        slack = (lam - 0.5 * v * quad).min(axis=1)
        ok = slack > tol
        if ok.any():
            margin = min(margin, float(slack[ok].min()))
        todo = ~ok
        if todo.any():
            if cells + centres.shape[0] + 2 * int(todo.sum()) > budget:
                return Decision(Verdict.UNPROVEN, cells, None, None, low, time.perf_counter() - start)
            cs, hs = c[todo], h[todo].copy()
            size = np.sqrt((full[todo] ** 2).sum(axis=(-1, -2))).max(axis=1)               # P' x m x m
            axis = np.argmax(hs * np.einsum("pjk,pk->pj", size, hs), axis=1)
            rows = np.arange(cs.shape[0])
            hs[rows, axis] /= 2
            left, right = cs.copy(), cs.copy()
            left[rows, axis] -= hs[rows, axis]
            right[rows, axis] += hs[rows, axis]
            centres = np.vstack([centres, left, right])
            halves = np.vstack([halves, hs, hs])
    return Decision(Verdict.PROVED, cells, margin, None, low, time.perf_counter() - start)
