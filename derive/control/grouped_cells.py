"""Branch and bound over the inner angles for the grouped bound of derive.control.grouped.

WORK IN PROGRESS (branch cert2-grouped-wip): not used by the certificate yet; the cell test is sound
but far too slow for the Panda (see the commit message).

In the coordinates of S = W + W^T = L L^T (T = L^-1, so S becomes I), the claim is
lambda_min(I - v B~(theta_in, s)) > 0 for every inner theta in the spans and every unit vertex s,
B~ = M_0~ + sum_g P_g~ + Y~ Y~^T, Y~ = T Y, P~ = T P T^T, M_0~ = T M_0 T^T. On a cell (centre c,
half-widths r, theta = c + delta), per vertex:

    M_0~(theta) = M_0~(c) + sum_j delta_j dM_0~/dq_j(c) + R_M,    |R_M| <= 1/2 sum_jk r_j r_k T^M_jk (entrywise),
    Y~(theta)   = Y~(c) + sum_j delta_j D_j + R_Y = A(delta) + R_Y,  |R_Y| <= 1/2 sum_jk r_j r_k T^Y_jk,

(Taylor per real entry, T^M, T^Y: sums of |coefficient| |f.s| |f_j f_k| over the Fourier terms,
valid for every angle), and Y Y^T = A A^T + A R^T + R A^T + R R^T <= A A^T + (2 ||A|| ||R|| + ||R||^2) I,
A A^T = Y(c) Y(c)^T + sum_j delta_j (Y(c) D_j^T + D_j Y(c)^T) + L L^T, ||L L^T|| <= (sum_j r_j ||D_j||_F)^2,
||A|| <= ||Y(c)||_F + sum_j r_j ||D_j||_F. So by Weyl

    lambda_min(I - v B~(theta)) >= lambda_min(C - sum_j delta_j L_j) - v (quadratic + remainders),

C = I - v (M_0~(c) + sum P~ + Y(c) Y(c)^T + rounding I), L_j = v (dM_0~/dq_j + Y D_j^T + D_j Y^T): the
first term is concave in delta, so at least its smallest value over the cell's vertices, and at
least lambda_min(C) - || sum_j r_j |L_j| ||_2 (the cheap test, tried first). A cell proved when
the bound exceeds the floating-point margin; otherwise split along its largest contribution.
"""
from __future__ import annotations

import itertools
import math
import time

import numpy as np

from derive.control.certificate import FLOAT_MARGIN, Decision, Verdict, _spectral_norm
from derive.control.grouped import GroupedModel


def _weighted_sums(E: np.ndarray, w: np.ndarray, C: np.ndarray) -> np.ndarray:
    """sum_f w_r(f) C_f E_pf for every point p and weight row r: P x R x (C's columns), one matrix product."""
    K = E.shape[1]
    return ((E[:, None, :] * w[None]).reshape(-1, K) @ C).reshape(E.shape[0], w.shape[0], -1)


def _pairs(m: int) -> list[tuple[int, int]]:
    return [(j, k) for j in range(m) for k in range(j, m)]


class _Prepared:
    """The W-dependent arrays of one decision (transformed coefficients, remainder bounds)."""

    def __init__(self, model: GroupedModel, W: np.ndarray) -> None:
        n, m = model.n, model.m
        S = W + W.T
        self.T = T = np.linalg.inv(np.linalg.cholesky(S))
        si = model.signs[:, list(model.inner)]                                          # V x m
        pairs = _pairs(m)
        Fz, Cz = model.zero
        # M_0: sum_k s_k Re sum_f i f_k C~_f e^{i f.q}; derivatives j: i f_j more
        self.Fz = Fz
        self.Cz = np.einsum("ab,kbc,dc->kad", T, Cz, T).reshape(Fz.shape[0], -1)
        self.wz = np.vstack([Fz.T] + [Fz[:, j] * Fz[:, k] for j, k in pairs])          # (m + pairs) x K
        self.groups = []
        Pt = np.zeros((n, n))
        for (Fg, Cg, gs), P in zip(model.groups, model.P):
            # any P > 0 bounds the group: the one used is (Q Q^T)^-1 = R^T R for the Q computed (R = Q^-1)
            Q = np.linalg.inv(np.linalg.cholesky(P)).T
            R = np.linalg.inv(Q)
            P = R.T @ R
            C = np.einsum("ab,kbc,cd->kad", T, Cg, Q).reshape(Fg.shape[0], -1)           # T C_f Q
            w = np.vstack([np.ones(Fg.shape[0]), Fg.T] + [Fg[:, j] * Fg[:, k] for j, k in pairs])
            self.groups.append((Fg, C, w, gs))
            Pt += T @ P @ T.T
        self.Pt = Pt
        # remainder bounds per vertex and pair (spectral norms of the entrywise bounds)
        V = si.shape[0]
        self.nM = np.zeros((V, m, m))
        self.nY = np.zeros((V, m, m))
        absz = np.abs(self.Cz)
        infl = 1 + 1e-12
        TY = np.zeros((V, len(pairs), n, 0))
        for Fg, C, w, gs in self.groups:
            speed = np.abs(si @ Fg.T + gs[:, None])                                       # V x K
            block = np.stack([(speed * np.abs(Fg[:, j] * Fg[:, k])[None]) @ np.abs(C) for j, k in pairs], 1)
            block = block.reshape(V, len(pairs), n, n)
            TY = np.concatenate([TY, block, block], axis=-1)                              # Re and Im columns
        speed = np.abs(si @ Fz.T)
        TM = np.stack([(speed * np.abs(Fz[:, j] * Fz[:, k])[None]) @ absz for j, k in pairs], 1).reshape(V, len(pairs), n, n)
        nM = _spectral_norm(TM) * infl
        nY = np.sqrt(_spectral_norm(np.einsum("vpab,vpcb->vpac", TY, TY))) * infl
        for i, (j, k) in enumerate(pairs):
            self.nM[:, j, k] = self.nM[:, k, j] = nM[:, i]
            self.nY[:, j, k] = self.nY[:, k, j] = nY[:, i]
        self.si = si
        self.rounding = model.rounding * np.linalg.norm(T, 2) ** 2

    def evaluate(self, model: GroupedModel, c: np.ndarray):
        """At centres c (P x m): M_0~ and its derivatives (P x V x (1 + m) x n x n), Y~ and its
        derivatives (P x V x (1 + m) x n x 2 n G)."""
        n, m = model.n, model.m
        Pn = c.shape[0]
        E = np.exp(1j * (c @ self.Fz.T))
        sums = _weighted_sums(E, self.wz, self.Cz).reshape(Pn, -1, n, n)          # P x (m + pairs) x n x n
        first = 1j * sums[:, :m]                                                          # i f_k
        pair_index = {p: m + i for i, p in enumerate(_pairs(m))}
        second = np.stack([np.stack([-sums[:, pair_index[tuple(sorted((k, j)))]] for j in range(m)], 1)
                           for k in range(m)], 1)                                         # P x k x j x n x n
        M = np.einsum("vk,pkab->pvab", self.si, first.real)
        dM = np.einsum("vk,pkjab->pvjab", self.si, second.real)
        M = np.concatenate([M[:, :, None], dM], axis=2)
        Ys = []
        for Fg, C, w, gs in self.groups:
            E = np.exp(1j * (c @ Fg.T))
            s = _weighted_sums(E, w, C).reshape(Pn, -1, n, n)                     # 1, f_k, f_j f_k
            base = np.concatenate([1j * s[:, :1], -s[:, 1:1 + m]], axis=1)                # value, d/dq_j of sum C e
            inner = np.stack([np.concatenate([1j * s[:, 1 + k][:, None],
                                              np.stack([-s[:, 1 + pair_index[tuple(sorted((k, j)))]]
                                                        for j in range(m)], 1)], axis=1) for k in range(m)], 1)
            coeff = np.hstack([self.si, gs[:, None]])                                     # V x (m + 1)
            Z = np.einsum("vb,pbdac->pvdac", coeff, np.concatenate([inner, base[:, None]], axis=1), optimize=True)
            Ys.append(np.concatenate([Z.real, Z.imag], axis=-1))
        return M, np.concatenate(Ys, axis=-1)


def decide_grouped(model: GroupedModel, W, v: float, budget: int = 200_000, batch: int = 16) -> Decision:
    """Branch and bound over the inner angles (module docstring): proved or unproven (the grouped
    bound refutes nothing)."""
    start = time.perf_counter()
    W = np.asarray(W, dtype=float)
    n, m = model.n, model.m
    tol = FLOAT_MARGIN * 2
    try:
        prep = _Prepared(model, W)
    except np.linalg.LinAlgError:
        return Decision(Verdict.UNPROVEN, 0, None, None, math.nan, time.perf_counter() - start)
    const = (prep.T @ (W + W.T) @ prep.T.T)[None] - v * (prep.Pt[None] + prep.rounding[:, None, None] * np.eye(n)[None])   # V x n x n
    deltas = np.array(list(itertools.product((1.0, -1.0), repeat=m)))
    lo = np.array([span[0] for span in model.spans])
    hi = np.array([span[1] for span in model.spans])
    centres, halves = ((lo + hi) / 2)[None, :], ((hi - lo) / 2)[None, :]
    cells, margin, low = 0, math.inf, math.inf
    while centres.shape[0]:
        c, h = centres[:batch], halves[:batch]
        centres, halves = centres[batch:], halves[batch:]
        cells += c.shape[0]
        M, Y = prep.evaluate(model, c)                                                   # P x V x (1+m) x ...
        Y0, D = Y[:, :, 0], Y[:, :, 1:]
        G = np.einsum("pvac,pvbc->pvab", Y0, Y0)
        X = np.einsum("pvac,pvjbc->pvjab", Y0, D)
        Lj = v * (M[:, :, 1:] + X + np.swapaxes(X, -1, -2))                               # P x V x m x n x n
        C = const[None] - v * (M[:, :, 0] + G)
        lam = np.linalg.eigvalsh(C)[..., 0]                                               # P x V
        low = min(low, float(lam.min()))
        Dn = np.sqrt((D ** 2).sum(axis=(-1, -2)))                                         # P x V x m
        rD = np.einsum("pj,pvj->pv", h, Dn)
        Yn = np.sqrt((Y0 ** 2).sum(axis=(-1, -2)))
        rr = 0.5 * np.einsum("pj,pk->pjk", h, h)
        rM = np.einsum("pjk,vjk->pv", rr, prep.nM)
        rY = np.einsum("pjk,vjk->pv", rr, prep.nY)
        rem = v * (rD ** 2 + 2 * (Yn + rD) * rY + rY ** 2 + rM)
        lin = _spectral_norm(np.einsum("pj,pvjab->pvab", h, np.abs(Lj)))
        bound = lam - lin
        hard = np.argwhere((bound - rem <= tol) & (lam - rem > tol))
        for chunk in range(0, hard.shape[0], 256):
            pv = hard[chunk:chunk + 256]
            A = C[pv[:, 0], pv[:, 1]][:, None] - np.einsum("dj,qj,qjab->qdab", deltas, h[pv[:, 0]], Lj[pv[:, 0], pv[:, 1]])
            bound[pv[:, 0], pv[:, 1]] = np.linalg.eigvalsh(A)[..., 0].min(axis=1)
        slack = (bound - rem).min(axis=1)
        ok = slack > tol
        if ok.any():
            margin = min(margin, float(slack[ok].min()))
        todo = ~ok
        if todo.any():
            if (lam[todo] <= tol).any() or cells + centres.shape[0] + 2 * int(todo.sum()) > budget:
                return Decision(Verdict.UNPROVEN, cells, None, None, low, time.perf_counter() - start)
            cs, hs = c[todo], h[todo].copy()
            grow = np.sqrt((Lj[todo] ** 2).sum(axis=(-1, -2))).max(axis=1) + \
                np.einsum("pk,vjk->pvj", hs, prep.nM + prep.nY).max(axis=1) * v
            axis = np.argmax(hs * grow, axis=1)
            rows = np.arange(cs.shape[0])
            hs[rows, axis] /= 2
            left, right = cs.copy(), cs.copy()
            left[rows, axis] -= hs[rows, axis]
            right[rows, axis] += hs[rows, axis]
            centres = np.vstack([centres, left, right])
            halves = np.vstack([halves, hs, hs])
    return Decision(Verdict.PROVED, cells, margin, None, low, time.perf_counter() - start)
