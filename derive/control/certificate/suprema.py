"""The numeric estimates of the observer certificate (derive.control.certificate): the largest speed box and
rate at which N = W + W^T - J'(theta, theta') - 2 beta J stays positive definite at sampled configurations
(the figures a proved box is compared with), computed in batches of at most ELEMENTS numbers; and the size
of the branch and bound's tree for W = omega D at rate 0 as omega varies
(derive.control.certificate.decision.TreeEstimate)."""
from __future__ import annotations

import math

import numpy as np

from derive.control.certificate.decision import TreeEstimate, estimate_tree
from derive.control.certificate.norm_bound import ELEMENTS, norm_rate_bound, norm_speed_bound, sample_count

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

    def tree_estimate(self, D, shape, lowest: float, cells: float) -> TreeEstimate:
        """derive.control.certificate.decision.TreeEstimate of the decisions for W = omega D (n x n, D + D^T
        positive definite; omega >= ``lowest`` [1/s]) on the box ``shape`` (rad/s, scale 1) at rate 0, over the
        levels of at most about ``cells`` cells: the decision's own bounds (:meth:`cell_bounds`)."""
        if self.norm or self.model.unbounded or self.target.m == 0:
            raise ValueError("tree_estimate: expected a branch and bound over at least one coordinate")
        return estimate_tree(self.cell_bounds(D, shape, 1.0, 0.0), self.target.spans, lowest, cells)

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
