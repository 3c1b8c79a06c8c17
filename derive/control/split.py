"""The observer certificate for many joints: branch and bound over a few angles, a sound majorant for the rest.

Branch and bound over every angle J depends on (derive.control.certificate) needs a number of
cells exponential in their count: past four angles (a 6- or 7-joint arm) no budget suffices.
Here the angles are split into ``inner`` ones, decided by branch and bound as before, and
``outer`` ones, bounded for every value at once through J's exact Fourier series (every
coordinate an angle; derive.control.inertia):

    J(theta) = sum_f C_f exp(i f.theta) = J_A(theta_inner) + J_R(theta),

J_A the terms without an outer frequency (J averaged over the outer angles) and J_R the rest.
For a speed vertex theta'_v the rest enters N of (*) as M_R = 2 beta J_R + J_R'; pairing f with -f
(C_-f the conjugate of C_f = A_f + i B_f, A_f and B_f real symmetric),

    M_R = sum_{f in P} 2 Re((2 beta + i f.theta'_v) C_f exp(i f.theta))
        = sum_{f in P} 2 [2 beta (A_f cos - B_f sin) - (f.theta'_v) (B_f cos + A_f sin)](f.theta)
        <= U(v) = sum_{f in P} 2 (2 beta + |f.theta'_v|) (|A_f| + |B_f|)

for every theta, since c A <= |c| |A| for a number c and |A| the matrix absolute value (the
same eigenvectors, absolute eigenvalues). So (*) holds wherever

    N_A(theta_inner, v) = W + W^T - U(v) - J_A'(theta_inner, theta'_v) - 2 beta J_A(theta_inner)

is positive definite, which branch and bound decides over the inner angles alone (the vertices
of the inner speeds; the outer speeds' signs are covered inside U, see :meth:`SplitModel.majorant`). The split is
sound, not exact: failing it refutes nothing (the certificate then says ``unproven``), and a W
certified this way is larger than the smallest one (the synthesis works on the same condition,
so the W it returns is provable). The inner angles are chosen greedily to make U smallest.
"""
from __future__ import annotations

import itertools

import numpy as np

from derive.control.inertia import ROUNDING, InertiaModel, fourier_derivative_bounds

MAX_INNER = 3        # angles decided by branch and bound


def _abs_matrix(X: np.ndarray) -> np.ndarray:
    """|X| = V |Lambda| V^T of symmetric matrices (... x n x n)."""
    w, V = np.linalg.eigh(X)
    return np.einsum("...ij,...j,...kj->...ik", V, np.abs(w), V)


class SplitModel:
    """J_A over the inner angles (values, derivatives, bounds: the interface of InertiaModel) and
    the majorant U of the outer terms.

    full: the InertiaModel (every dep an angle, its ``fourier`` set); inner: indices into
    full.deps. ``deps``, ``m``, ``spans``, ``periodic``, ``second``, ``third`` refer to the inner
    angles; ``vertex_deps`` are all of full.deps (the speed box's vertices range over them).
    """

    def __init__(self, full: InertiaModel, inner: tuple[int, ...]) -> None:
        coef, F = full.fourier
        self.full, self.inner = full, tuple(inner)
        outer = [k for k in range(full.m) if k not in self.inner]
        self.n, self.m = full.n, len(self.inner)
        self.deps = tuple(full.deps[k] for k in self.inner)
        self.vertex_deps = full.deps
        self.unbounded = ()
        self.spans = [full.spans[k] for k in self.inner]
        self.periodic = [full.periodic[k] for k in self.inner]
        keep = ~np.any(F[:, outer] != 0, axis=1) if outer else np.ones(F.shape[0], bool)
        self._C = coef[keep].reshape(-1, self.n * self.n)
        self._F = F[keep][:, list(self.inner)].astype(float)
        # one of each pair f, -f among the rest: the first nonzero component positive
        rest = np.flatnonzero(~keep)
        first = F[rest][np.arange(rest.size), np.argmax(F[rest] != 0, axis=1)]
        rep = rest[first > 0]
        self._rest_F = F[rep].astype(float)                                         # P x m_full
        self._rest_abs = 2.0 * (_abs_matrix(coef[rep].real) + _abs_matrix(coef[rep].imag))   # P x n x n
        norms = np.sqrt((np.abs(coef) ** 2).sum(axis=(1, 2)))                       # Frobenius of every C_f
        self._all_F, self._all_norm = F.astype(float), norms
        self.second, self.third = fourier_derivative_bounds(coef[keep], F[keep][:, list(self.inner)])

    # -- J_A and its derivatives at inner points ---------------------------------------------
    def _weighted(self, q: np.ndarray, weights: list[np.ndarray]) -> np.ndarray:
        """Re sum_f w(f) C_f exp(i f.q) for each weight vector w (K): N x len(weights) x n^2."""
        E = np.exp(1j * (q @ self._F.T))                                    # N x K
        return np.stack([((E * w[None, :]) @ self._C).real for w in weights], axis=1)

    def J(self, q: np.ndarray) -> np.ndarray:
        """J_A at inner points q (N x m): N x n x n."""
        return self._weighted(q, [np.ones(self._F.shape[0])]).reshape(-1, self.n, self.n)

    def dJ(self, q: np.ndarray) -> np.ndarray:
        """dJ_A/dq_k: N x m x n x n (the derivative of exp(i f.q) is i f_k exp(i f.q))."""
        out = self._weighted(q, [1j * self._F[:, k] for k in range(self.m)])
        return out.reshape(-1, self.m, self.n, self.n)

    def d2J(self, q: np.ndarray) -> np.ndarray:
        """d^2 J_A/dq_j dq_k: N x m x m x n x n."""
        m = self.m
        out = self._weighted(q, [-self._F[:, j] * self._F[:, k] for j in range(m) for k in range(m)])
        return out.reshape(-1, m, m, self.n, self.n)

    # -- the outer terms ---------------------------------------------------------------------
    def majorant(self, speeds: np.ndarray, beta: float) -> np.ndarray:
        """U for each row of ``speeds`` (V x m_full, rad/s, the box's scale included; an outer
        column holds the box's half-width, whatever the sign): V x n x n. The outer signs are
        covered at once by |f.theta'| <= |f_inner.theta'_inner| + sum_outer |f_k| |theta'_k|, so
        the vertices range over the inner speeds only. The transform's rounding on every
        coefficient is added as a multiple of the identity."""
        outer = [k for k in range(self.full.m) if k not in self.inner]
        inner = list(self.inner)

        def weight(F: np.ndarray) -> np.ndarray:
            return np.abs(speeds[:, inner] @ F[:, inner].T) + np.abs(speeds[:, outer]) @ np.abs(F[:, outer]).T

        U = np.einsum("vp,pab->vab", 2.0 * beta + weight(self._rest_F), self._rest_abs)
        slack = ROUNDING * ((2.0 * beta + weight(self._all_F)) @ self._all_norm)   # V
        return U + slack[:, None, None] * np.eye(self.n)[None]


def split_model(full: InertiaModel, shape: np.ndarray, size: int = MAX_INNER) -> SplitModel:
    """The split of ``full`` with ``size`` inner angles whose majorant on the box of this shape
    (rate 0) is smallest, chosen greedily one angle at a time."""
    speeds = np.array([[shape[c.index] for c in full.deps]])   # the outer half-widths; inner set below
    inner: list[int] = []
    while len(inner) < min(size, full.m):
        best = None
        for k in range(full.m):
            if k in inner:
                continue
            trial = tuple(sorted(inner + [k]))
            signs = np.array(list(itertools.product((1.0, -1.0), repeat=len(trial))))
            vertices = np.repeat(speeds, signs.shape[0], axis=0)
            vertices[:, list(trial)] *= signs
            top = np.linalg.eigvalsh(SplitModel(full, trial).majorant(vertices, 0.0))[:, -1].max()
            if best is None or top < best[0]:
                best = (top, k)
        inner.append(best[1])
    return SplitModel(full, tuple(sorted(inner)))
