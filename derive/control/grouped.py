"""The observer certificate's outer angles bounded group by group (issue 23): a sharper split.

WORK IN PROGRESS (branch cert2-grouped-wip): not used by the certificate yet; the cell test is sound
but far too slow for the Panda (see the commit message).

derive.control.split bounds every Fourier term of J with an outer frequency by a constant
majorant, so the terms' dependence on the inner angles and their cancellations are lost (the
Panda: 26 % of the numeric supremum). Here the terms are grouped by their outer frequency g,

    J' (theta, theta'_v) = M_0(theta_in, v) + sum_{g in P} 2 Re(Z_g(theta_in, v) exp(i g.theta_out)),
    Z_g = sum_{f_out = g} (i f.theta'_v) C_f exp(i f_in.theta_in),

(M_0: the terms without an outer frequency, P: one of each pair g, -g) and each group is bounded
for every outer angle at once by the matrix inequality 2 Re(A) <= A P^-1 A^H + P (from
(A - P) P^-1 (A - P)^H >= 0, any P > 0), with A = Z_g exp(i g.theta_out), whose phase cancels:

    2 Re(Z_g exp(i g.theta_out)) <= Re(Z_g P_g^-1 Z_g^H) + P_g = Y_g Y_g^T + P_g,
    Y_g = [Re(Z_g Q_g), Im(Z_g Q_g)],  Q_g Q_g^T = P_g^-1.

With P_g fixed (the scale of Z_g over the inner angles, see :meth:`GroupedModel.__init__`),
(*) of derive.control.certificate holds on the box of scale v wherever

    S - v B(theta_in, s) > 0,   B = M_0(theta_in, s) + sum_g P_g + Y(theta_in, s) Y(theta_in, s)^T,

Y = [Y_g]_g (n x 2 n G), s a vertex of the unit box (N is affine in theta', so its vertices cover
the box; Z_g is linear in s, P_g scales with v), S = W + W^T. B is smooth in the inner angles and
the branch and bound decides it (:mod:`derive.control.grouped_cells`). Sound, not exact: failing
it refutes nothing.
"""
from __future__ import annotations

import itertools

import numpy as np

from derive.control.inertia import ROUNDING, InertiaModel

P_FACTOR = 2.0     # P_g = P_FACTOR (mean of Re(Z_g Z_g^H))^1/2: the sampled optimum on the Panda lies near 2
P_SAMPLES = 256    # inner points the mean is taken over


def _sqrtm(M: np.ndarray) -> np.ndarray:
    w, V = np.linalg.eigh(M)
    return np.einsum("...ij,...j,...kj->...ik", V, np.sqrt(np.maximum(w, 0.0)), V)


class GroupedModel:
    """The grouped bound for one arm, inner angles and box shape (independent of W and of v).

    full: the InertiaModel (every dep an angle, ``fourier`` set); inner: indices into full.deps;
    shape: the box's shape over the joints (n). ``signs``: the unit box's vertices over the deps
    (2^m x m, the shape included); ``groups``: per g of P, (frequencies of its terms over the inner
    angles K_g x m_in, coefficients K_g x n x n, g.s_out per vertex); ``zero``: the same for M_0.
    """

    def __init__(self, full: InertiaModel, inner: tuple[int, ...], shape) -> None:
        coef, F = full.fourier
        self.full, self.inner, self.n = full, tuple(inner), full.n
        self.outer = tuple(k for k in range(full.m) if k not in self.inner)
        self.m = len(self.inner)
        self.spans = [full.spans[k] for k in self.inner]
        shape = np.asarray(shape, dtype=float)
        self.signs = np.array(list(itertools.product((1.0, -1.0), repeat=full.m))) * \
            np.array([shape[c.index] for c in full.deps])[None, :]
        nonzero = np.abs(coef).reshape(coef.shape[0], -1).max(axis=1) > 0
        coef, F = coef[nonzero], F[nonzero]
        Fin, Fout = F[:, list(self.inner)].astype(float), F[:, list(self.outer)]
        keys: dict[tuple[int, ...], list[int]] = {}
        for i, g in enumerate(map(tuple, Fout)):
            keys.setdefault(g, []).append(i)
        zero = (0,) * len(self.outer)
        reps = sorted(g for g in keys if g != zero and next(x for x in g if x != 0) > 0)
        sout = self.signs[:, list(self.outer)]
        self.zero = (Fin[keys[zero]], coef[keys[zero]]) if zero in keys else (np.zeros((0, self.m)),
                                                                               np.zeros((0, self.n, self.n)))
        self.groups = [(Fin[keys[g]], coef[keys[g]], sout @ np.array(g, dtype=float)) for g in reps]
        # the discrete transform's rounding: |J'_computed - J'| <= ROUNDING sum_f |f.s| ||C_f||_F (as split)
        self.rounding = ROUNDING * (np.abs(self.signs @ F.T.astype(float)) @ np.sqrt((np.abs(coef) ** 2).sum(axis=(1, 2))))
        rng = np.random.default_rng(0)
        lo = np.array([span[0] for span in self.spans])
        hi = np.array([span[1] for span in self.spans])
        q = lo + (hi - lo) * rng.random((P_SAMPLES, self.m))
        self.P = []
        for Fg, Cg, gs in self.groups:
            Z = self._Z(q, Fg, Cg, gs)                                                  # N x V x n x n
            mean = np.einsum("pvab,pvcb->ac", Z, Z.conj()).real / (Z.shape[0] * Z.shape[1])
            P = P_FACTOR * _sqrtm((mean + mean.T) / 2)
            P = (P + P.T) / 2 + 1e-6 * max(np.trace(P) / self.n, 1e-300) * np.eye(self.n)
            self.P.append(P)

    def _Z(self, q: np.ndarray, Fg: np.ndarray, Cg: np.ndarray, gs: np.ndarray) -> np.ndarray:
        """Z_g at inner points q for every unit vertex: N x V x n x n (Z_g is linear in s: the
        sums weighted by f_k of each inner angle and by 1, combined per vertex)."""
        E = np.exp(1j * (q @ Fg.T))                                                     # N x K
        weights = np.vstack([Fg.T, np.ones((1, Fg.shape[0]))])                          # (m_in + 1) x K
        sums = ((E[:, None, :] * weights[None]).reshape(-1, Fg.shape[0]) @ Cg.reshape(Cg.shape[0], -1))
        sums = sums.reshape(q.shape[0], weights.shape[0], -1)                             # N x (m_in + 1) x n^2
        coeff = np.hstack([self.signs[:, list(self.inner)], gs[:, None]])               # V x (m_in + 1)
        return 1j * (coeff @ sums).reshape(q.shape[0], -1, self.n, self.n)

    def bound(self, q: np.ndarray) -> np.ndarray:
        """B(theta_in, s) at inner points q (N x m_in) for every unit vertex: N x V x n x n (the
        module docstring; without the rounding term)."""
        B = self._Z(q, *self.zero, np.zeros(self.signs.shape[0])).real
        for (Fg, Cg, gs), P in zip(self.groups, self.P):
            Z = self._Z(q, Fg, Cg, gs)
            B = B + np.einsum("pvab,bc,pvdc->pvad", Z, np.linalg.inv(P), Z.conj(), optimize=True).real + P
        return B

    def supremum(self, W, count: int = 4096, seed: int = 0) -> float:
        """Numeric estimate of the largest v the grouped bound can prove for W: min over sampled
        inner points and vertices of 1 / lambda_max(S^-1/2 B S^-1/2)."""
        W = np.asarray(W, dtype=float)
        Li = np.linalg.inv(np.linalg.cholesky(W + W.T))
        rng = np.random.default_rng(seed)
        lo = np.array([span[0] for span in self.spans])
        hi = np.array([span[1] for span in self.spans])
        top = 0.0
        for at in range(0, count, 256):
            q = lo + (hi - lo) * rng.random((min(256, count - at), self.m))
            B = self.bound(q) + self.rounding[None, :, None, None] * np.eye(self.n)
            top = max(top, float(np.linalg.eigvalsh(np.einsum("ab,pvbc,dc->pvad", Li, B, Li))[..., -1].max()))
        return np.inf if top <= 0 else 1.0 / top
