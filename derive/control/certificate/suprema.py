"""The numeric estimates of the observer certificate (derive.control.certificate): the largest speed box and
rate at which N = W + W^T - J'(theta, theta') - 2 beta J stays positive definite at sampled configurations
(the figures a proved box is compared with), computed in batches of at most ELEMENTS numbers; and the size
of the branch and bound's tree for W = omega D at rate 0 as omega varies (:class:`TreeEstimate`)."""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from derive.control.certificate.decision import MAX_ENUMERATED
from derive.control.certificate.norm_bound import ELEMENTS, norm_rate_bound, norm_speed_bound, sample_count

TREE_PATHS = 32   # random root-to-leaf paths of the tree estimate (Knuth's estimator: each gives an unbiased count)


@dataclass(frozen=True)
class TreeEstimate:
    """Knuth's estimate of the cells branch and bound (ObserverCertificate._decide) examines for W = omega D
    at rate 0 on a box (D. E. Knuth, Estimation of the size of a backtrack tree, Math. Comp. 29, 1975): along
    random paths from the root, each step to one of the two halves at random, a cell at level d stands for
    the 2^d cells of its level, so sum_d 2^d [the path's cells above level d are all split] is an unbiased
    count of the tree. ``scales`` (paths x levels) [1/s]: the smallest omega at which each path's cell at
    each level passes the decision's own test (the same bounds, derive.control.certificate.decision.CellBounds;
    up to its floating-point margin), inf where the path was not followed (it passed at ``lowest``, or lay past
    the levels followed). A decision that examines no more cells than its budget proves; this estimate only
    chooses which omega to decide, it proves nothing."""

    scales: np.ndarray
    lowest: float

    def cells(self, omega: float) -> float:
        """The estimated cells examined at omega (>= ``lowest``; inf when a path needs more levels than followed)."""
        passed = self.scales <= omega
        first = np.where(passed.any(axis=1), passed.argmax(axis=1), -1)
        if np.any(first < 0):
            return math.inf
        return float(np.mean(2.0 ** (first + 1) - 1.0))

    def smallest(self, cells: float, above: float = 0.0) -> float | None:
        """The smallest omega > ``above`` (and >= ``lowest``) whose estimate is at most ``cells`` (None: none of the
        omegas where the estimate changes, up to the largest followed)."""
        marks = np.unique(np.concatenate([[self.lowest], self.scales[np.isfinite(self.scales)]]))
        marks = marks[(marks >= self.lowest) & (marks > above)]
        left, right = 0, marks.size   # the estimate does not grow with omega: bisection for the first within ``cells``
        while left < right:
            mid = (left + right) // 2
            if self.cells(float(marks[mid])) <= cells:
                right = mid
            else:
                left = mid + 1
        return float(marks[left]) if left < marks.size else None


class Suprema:
    """Mixin of ObserverCertificate: speed_supremum and rate_supremum (it supplies model, split, signs,
    all_signs, norm, samples, speeds and matrices)."""

    def speed_supremum(self, W, shape, beta: float = 0.0, count: int = 4096, exact: bool = False) -> float:
        """Numeric estimate (an upper bound up to sampling) of the largest v for which (*) holds
        (with a split and not ``exact``: its sound form N_A - U, which is affine in v as N is; the
        largest of the split's, the ``wider`` split's and, at rate 0, the ``grouped`` stage's, whose
        estimate is its own, derive.control.certificate.grouped_union.Shared.supremum): min over samples and
        vertices of 1 / lambda_max(A^-1/2 K A^-1/2), A = N at v = 0, K = A - N at v = 1; 0 when A
        itself fails somewhere."""
        if self.norm and not exact:   # what the one-matrix bound proves (derive.control.certificate.norm_bound)
            return norm_speed_bound(self.model, np.asarray(W, dtype=float), np.asarray(shape, dtype=float), beta)
        own = self._speed_supremum(W, shape, beta, count, exact)
        if exact:
            return own
        if self.wider is not None:
            own = max(own, self.wider._speed_supremum(W, shape, beta, count, exact))
        if self._grouped_for(shape, beta):
            own = max(own, self.grouped.supremum(W))
        return own

    def _chunks(self, q: np.ndarray, exact: bool):
        """``q`` in batches whose N at every vertex holds at most ELEMENTS numbers (the estimates are
        minima over points: the same numbers, batch by batch; an 8-joint chain's 8,192 points x 128
        vertices x 64 were 0.5 GB an array, 2.3 GB in check)."""
        V = self.all_signs.shape[0] if exact or self.split is None else self.signs.shape[0]
        step = max(1, ELEMENTS // max(1, V * self.model.n ** 2))
        return (q[i:i + step] for i in range(0, q.shape[0], step))

    def _speed_supremum(self, W, shape, beta: float, count: int, exact: bool) -> float:
        q = self.samples(sample_count(self.all_signs.shape[0], self.model.n, count) if self.norm else count, exact=exact)
        W = np.asarray(W, dtype=float)
        top = -math.inf
        md = self.model if exact or self.split is None else self.split
        for qc in self._chunks(q, exact):
            jets = (md.dJ(qc), md.J(qc))   # shared by the matrices below
            M0 = self.matrices(W, shape, 0.0, beta, qc, exact, jets)
            A = M0[:, 0]
            if np.linalg.eigvalsh(A)[:, 0].min() <= 0:
                return 0.0
            if self.model.m == 0:
                return math.inf
            Li = np.linalg.inv(np.linalg.cholesky(A))
            LiT = Li.transpose(0, 2, 1)[:, None]
            if exact or self.split is None:
                # K = J'(theta, s) at the vertices s, linear in s: the vertices -s give -K, so half of them
                # and both ends of the spectrum give every lambda_max
                half = self.speeds(shape, 1.0, True)[self.all_signs[:, 0] > 0]
                K = np.einsum("vk,pkij->pvij", half, jets[0])
                lam = np.linalg.eigvalsh(Li[:, None] @ K @ LiT)
                top = max(top, lam[..., -1].max(), -lam[..., 0].min())
            else:   # at v = 0 every vertex's N is A's (M0's, at rate 0)
                K = -(self.matrices(W, shape, 1.0, 0.0, qc, exact, jets)
                      - (M0 if beta == 0.0 else self.matrices(W, shape, 0.0, 0.0, qc, exact, jets)))
                top = max(top, np.linalg.eigvalsh(Li[:, None] @ K @ LiT)[..., -1].max())
        return math.inf if top <= 0 else float(1.0 / top)

    def tree_estimate(self, D, shape, lowest: float, highest: float, cells: float, seed: int = 0) -> TreeEstimate:
        """:class:`TreeEstimate` of the decisions for W = omega D (n x n, D + D^T positive definite) on the box
        ``shape`` (rad/s, scale 1) at rate 0, for omega in [lowest, highest] [1/s], over the levels whose cells
        number at most ``cells``. At rate 0 N = omega (D + D^T) - X(theta, theta') with X free of omega, and a
        cell passes when lambda_min(N) - rem > 0 at each of its vertices' corners (the enumeration, m <=
        MAX_ENUMERATED) or at its centre less the linear term (past it): omega > lambda_max(L^-1 (X + r I) L^-T)
        for each, L L^T = D + D^T. The centre's value (at most the corners', lambda_min being concave) comes
        first, the corners only where it is below ``highest``."""
        if self.norm or self.model.unbounded or self.target.m == 0:
            raise ValueError("tree_estimate: expected a branch and bound over at least one coordinate")
        md = self.target
        cb = self.cell_bounds(D, shape, 1.0, 0.0)   # the split's majorant as W = omega D takes it (scale_for)
        Li = np.linalg.inv(np.linalg.cholesky(cb.S))
        cb.S = np.zeros_like(cb.S)                   # terms' N is then -X
        m, n = md.m, md.n
        deltas = np.array(list(itertools.product((1.0, -1.0), repeat=m)))
        lo = np.array([span[0] for span in md.spans])
        hi = np.array([span[1] for span in md.spans])
        levels = math.ceil(math.log2(max(cells, 2))) + 1
        rng = np.random.default_rng(seed)
        centres = np.repeat(((lo + hi) / 2)[None], TREE_PATHS, axis=0)
        halves = np.repeat(((hi - lo) / 2)[None], TREE_PATHS, axis=0)
        scales = np.full((TREE_PATHS, levels), math.inf)
        live = np.arange(TREE_PATHS)

        def top(X: np.ndarray) -> np.ndarray:
            return np.linalg.eigvalsh(Li @ X @ Li.T)[..., -1]

        for level in range(levels):
            c, h = centres[live], halves[live]
            N, dN, rem, lin = cb.terms(c, h)                     # N = -X (S = 0)
            eye = np.eye(n)
            if m <= MAX_ENUMERATED:
                at = top(-N + rem[..., None, None] * eye).max(axis=1)
                near = np.flatnonzero(at < highest)
                if near.size:
                    corners = np.einsum("dk,pk,pvkab->pvdab", deltas, h[near], dN[near])
                    X = -(N[near][:, :, None] + corners) + rem[near][:, :, None, None, None] * eye
                    at[near] = top(X).max(axis=(1, 2))
            else:
                at = top(-N + (lin + rem)[..., None, None] * eye).max(axis=1)
            scales[live, level] = at
            axis = cb.axis(dN, h)
            rows = np.arange(live.size)
            h = h.copy()
            h[rows, axis] /= 2
            c = c.copy()
            c[rows, axis] += np.where(rng.random(live.size) < 0.5, -1.0, 1.0) * h[rows, axis]
            centres[live], halves[live] = c, h
            live = live[at > lowest]
            if not live.size:
                break
        return TreeEstimate(scales, lowest)

    def rate_supremum(self, W, shape, v: float, count: int = 4096, exact: bool = False) -> float:
        """Numeric estimate of the largest beta for which (*) holds on the box of scale v:
        min over samples and vertices of lambda_min(R^-1/2 N(beta = 0) R^-1/2) / 2, R = J (with a
        split and not ``exact``: N_A - U is affine in beta too, R = J_A + U(0, 1/2); the larger of
        the split's and the ``wider`` split's)."""
        if self.norm and not exact:
            return norm_rate_bound(self.model, np.asarray(W, dtype=float), np.asarray(shape, dtype=float), v)
        own = self._rate_supremum(W, shape, v, count, exact)
        if exact or self.wider is None:
            return own
        return max(own, self.wider._rate_supremum(W, shape, v, count, exact))

    def _rate_supremum(self, W, shape, v: float, count: int, exact: bool) -> float:
        q = self.samples(sample_count(self.all_signs.shape[0], self.model.n, count) if self.norm else count, exact=exact)
        W = np.asarray(W, dtype=float)
        low = math.inf
        for qc in self._chunks(q, exact):
            N0 = self.matrices(W, shape, v, 0.0, qc, exact)
            R = -(self.matrices(W, shape, 0.0, 0.5, qc, exact) - self.matrices(W, shape, 0.0, 0.0, qc, exact))[:, 0]
            Li = np.linalg.inv(np.linalg.cholesky(R))
            C = np.einsum("pab,pvbc,pdc->pvad", Li, N0, Li)
            low = min(low, float(np.linalg.eigvalsh(C)[..., 0].min() / 2))
        return low
