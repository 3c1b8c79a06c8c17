"""The observer certificate for many joints: branch and bound over a few angles, a sound majorant for the rest.

Branch and bound over every angle J depends on (derive.control.certificate) needs a number of
cells exponential in their count: past four angles (a 6- or 7-joint arm) no budget suffices.
Here the angles are split into ``inner`` ones, decided by branch and bound as before, and
``outer`` ones, bounded for every value at once through J's exact Fourier series (every
coordinate an angle; derive.control.certificate.inertia):

    J(theta) = sum_f C_f exp(i f.theta) = J_A(theta_inner) + J_R(theta),

J_A the terms without an outer frequency (J averaged over the outer angles) and J_R the rest.
For a speed vertex theta'_v the rest enters N of (*) as M_R = 2 beta J_R + J_R'; pairing f with -f
(C_-f the conjugate of C_f = A_f + i B_f, A_f and B_f real symmetric),

    M_R = sum_{f in P} 2 Re((2 beta + i f.theta'_v) C_f exp(i f.theta))
        = sum_{f in P} 2 [2 beta (A_f cos - B_f sin) - (f.theta'_v) (B_f cos + A_f sin)](f.theta)
        <= U(v) = sum_{f in P} 2 (2 beta + |f.theta'_v|) (|A_f|_T + |B_f|_T)

for every theta, since c A <= |c| |A|_T for a number c and |A|_T = T |T^-1 A T^-T| T^T with |X| the
matrix absolute value (the same eigenvectors, absolute eigenvalues), for any invertible T. Two are
kept: J's own scale, T T^T = C_0 (J averaged over every angle), and T = I. With T = I the absolute
values mix the base's large terms into a light wrist's directions (the Panda's U is 2.3 times
larger relative to J), which a W shaped like J (derive.control.starter) pays for; a W of small norm
(derive tune) does better with T = I. Each decision takes the one that is smaller relative to its
W + W^T (ObserverCertificate.scale_for). So (*) holds wherever

    N_A(theta_inner, v) = W + W^T - U(v) - J_A'(theta_inner, theta'_v) - 2 beta J_A(theta_inner)

is positive definite, which branch and bound decides over the inner angles alone (the vertices
of the inner speeds; the outer speeds' signs are covered inside U, see :meth:`SplitModel.majorant`). The split is
sound, not exact: failing it refutes nothing (the certificate then says ``unproven``), and a W
certified this way is larger than the smallest one (the synthesis works on the same condition,
so the W it returns is provable). The inner angles are the choice that makes U + J_A' smallest
relative to C_0 (every choice is tried).
"""
from __future__ import annotations

import itertools

import numpy as np

from derive.control.certificate.inertia import ROUNDING, InertiaModel, fourier_derivative_bounds

MAX_INNER = 3        # angles decided by branch and bound
NOISE = 1e-13        # a series term this small against the largest is majorised by its Frobenius norm (pair_parts)


def _abs_matrix(X: np.ndarray) -> np.ndarray:
    """|X| = V |Lambda| V^T of symmetric matrices (... x n x n)."""
    w, V = np.linalg.eigh(X)
    return np.einsum("...ij,...j,...kj->...ik", V, np.abs(w), V)


def metric(full: InertiaModel) -> np.ndarray:
    """T with T T^T = C_0, J's mean over every angle (its constant Fourier term, positive definite
    as a mean of positive definite matrices): the metric the majorant's absolute values are taken
    in (J's own scale, so a light wrist's small terms are not outweighed by the base's)."""
    C0 = full.fourier[0][np.flatnonzero(~np.any(full.fourier[1] != 0, axis=1))[0]].real
    return np.linalg.cholesky((C0 + C0.T) / 2)


def pair_parts(full: InertiaModel, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(indices, majorants): one frequency f of each pair f, -f (its first nonzero component
    positive) and 2 (|A_f|_T + |B_f|_T) for it, C_f = A_f + i B_f, |X|_T = T |T^-1 X T^-T| T^T."""
    coef, F = full.fourier
    nonzero = np.any(F != 0, axis=1)
    first = F[np.arange(F.shape[0]), np.argmax(F != 0, axis=1)]
    rep = np.flatnonzero(nonzero & (first > 0))
    Ti = np.linalg.inv(T)

    def absolute(X: np.ndarray) -> np.ndarray:
        Y = Ti @ X @ Ti.T                                     # matmul: einsum's loops took 0.2 s on 7 joints
        # a term at the transform's rounding (most of a 6-angle series' 7,812 pairs, below 1e-15 of the largest):
        # |Y| <= ||Y||_2 I <= ||Y||_F I, a majorant without its eigenvalues
        size = np.sqrt((Y * Y).sum(axis=(-1, -2)))
        small = size <= NOISE * size.max(initial=0.0)
        out = np.empty_like(Y)
        out[~small] = _abs_matrix(Y[~small])
        out[small] = size[small][:, None, None] * np.eye(Y.shape[-1])
        return T @ out @ T.T

    return rep, 2.0 * (absolute(coef[rep].real) + absolute(coef[rep].imag))


def coefficient_norms(full: InertiaModel) -> np.ndarray:
    """The Frobenius norm of every C_f of J's series (K), computed once per model (every split tried shares it)."""
    norms = getattr(full, "_coefficient_norms", None)
    if norms is None:
        coef = full.fourier[0]
        norms = full._coefficient_norms = np.sqrt((np.abs(coef) ** 2).sum(axis=(1, 2)))
    return norms


def both_parts(full: InertiaModel) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """:func:`pair_parts` in J's scale ("J") and in the identity's ("I")."""
    return {"J": pair_parts(full, metric(full)), "I": pair_parts(full, np.eye(full.n))}


class SplitModel:
    """J_A over the inner angles (values, derivatives, bounds: the interface of InertiaModel) and
    the majorant U of the outer terms.

    full: the InertiaModel (every dep an angle, its ``fourier`` set); inner: indices into
    full.deps; parts: :func:`pair_parts` when the caller has them. ``deps``, ``m``, ``spans``,
    ``periodic``, ``second``, ``third`` refer to the inner angles; ``vertex_deps`` are all of
    full.deps (the speed box's vertices range over them).
    """

    def __init__(self, full: InertiaModel, inner: tuple[int, ...], parts=None) -> None:
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
        # J_A's coefficients C_f in real arithmetic over the upper triangle (every C_f is symmetric, as J is):
        # [Re C; Im C] (2K x n(n+1)/2), and where each of the n^2 entries is found in it
        upper = np.triu_indices(self.n)
        kept = coef[keep][:, upper[0], upper[1]]
        self._AB = np.vstack([kept.real, kept.imag])
        column = np.zeros((self.n, self.n), dtype=int)
        column[upper] = np.arange(upper[0].size)
        self._mirror = np.maximum(column, column.T).reshape(-1)
        self._F = F[keep][:, list(self.inner)].astype(float)
        # one of each pair f, -f among the rest (the first nonzero component positive), majorised in J's scale
        # ("J") and in the identity's ("I")
        parts = both_parts(full) if parts is None else parts
        rep = parts["J"][0]
        rest = ~keep[rep]
        self._rest_F = F[rep[rest]].astype(float)                                   # P x m_full
        self._rest_abs = {key: absolute[rest] for key, (_, absolute) in parts.items()}   # P x n x n each
        self._all_F, self._all_norm = F.astype(float), coefficient_norms(full)
        self._keep = keep
        self._bounds: tuple[np.ndarray, ...] | None = None
        self._products: dict = {}   # _weighted's coefficient matrices per (weights, scale)

    @property
    def second(self) -> np.ndarray:
        return self._derivative_bounds()[0]

    @property
    def third(self) -> np.ndarray:
        return self._derivative_bounds()[1]

    @property
    def fourth(self) -> np.ndarray:
        return self._derivative_bounds()[2]

    def _derivative_bounds(self) -> tuple[np.ndarray, ...]:
        if self._bounds is None:
            coef, F = self.full.fourier
            self._bounds = fourier_derivative_bounds(coef[self._keep], F[self._keep][:, list(self.inner)],
                                                     fourth=True)
        return self._bounds

    # -- J_A and its derivatives at inner points ---------------------------------------------
    def _weighted(self, q: np.ndarray, weights: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
        """Re sum_f w(f) C_f exp(i f.q) for each row w of ``weights`` (W x K): N x W x n^2, one real
        matrix product (N x 2K by 2K x W n(n+1)/2: half the work of the complex one it replaced)."""
        phase = q @ self._F.T                                               # N x K
        K, up = self._F.shape[0], self._AB.shape[1]
        key = (weights.tobytes(), None if scale is None else scale.tobytes())
        M = self._products.get(key)
        if M is None:   # the same weights and scale at every batch of a decision: made once
            AB = self._AB if scale is None else self._AB * scale[np.triu_indices(self.n)][None]
            A, B = AB[:K], AB[K:]
            wr, wi = weights.real.T[:, :, None], weights.imag.T[:, :, None]    # K x W x 1
            # Re(w e^{i phase} (A + i B)) = cos(phase) (wr A - wi B) - sin(phase) (wi A + wr B): the weights go into
            # the coefficients (2K x W n(n+1)/2), so one real matrix product of [cos, sin] does every row, upper
            # triangle
            M = np.concatenate([wr * A[:, None] - wi * B[:, None],
                                -(wi * A[:, None] + wr * B[:, None])]).reshape(2 * K, -1)
            if len(self._products) > 8:
                self._products.clear()
            self._products[key] = M
        out = np.concatenate([np.cos(phase), np.sin(phase)], axis=1) @ M
        return out.reshape(phase.shape[0], weights.shape[0], up)[..., self._mirror]

    def _powers(self, order: int) -> np.ndarray:
        """The weights (i f)^alpha of every order-th derivative, index tuples in row-major order: m^order x K
        (each distinct tuple computed once)."""
        tuples = list(itertools.product(range(self.m), repeat=order))
        unique = sorted({tuple(sorted(t)) for t in tuples})
        rows = np.array([np.prod([1j * self._F[:, k] for k in idx], axis=0) if idx else np.ones(self._F.shape[0], complex)
                         for idx in unique])
        return rows, np.array([unique.index(tuple(sorted(t))) for t in tuples])

    def _derivative(self, q: np.ndarray, order: int) -> np.ndarray:
        rows, where = self._powers(order)
        return self._weighted(q, rows)[:, where]

    def jet(self, q: np.ndarray, order: int, scale: np.ndarray | None = None) -> list[np.ndarray]:
        """[J_A, dJ_A, d2J_A, d3J_A][:order + 1] at inner points q (shapes as :meth:`J` ... :meth:`d3J`):
        one exponential and one matrix product for all of them; each entry (a, b) times ``scale[a, b]``
        when given (n x n, symmetric: folded into the coefficients)."""
        parts = [self._powers(k) for k in range(order + 1)]
        values = self._weighted(q, np.vstack([rows for rows, _ in parts]), scale)
        out, start, m, n = [], 0, self.m, self.n
        for k, (rows, where) in enumerate(parts):
            out.append(values[:, start + where].reshape(-1, *(m,) * k, n, n))
            start += rows.shape[0]
        return out

    def J(self, q: np.ndarray) -> np.ndarray:
        """J_A at inner points q (N x m): N x n x n."""
        return self._derivative(q, 0).reshape(-1, self.n, self.n)

    def dJ(self, q: np.ndarray) -> np.ndarray:
        """dJ_A/dq_k: N x m x n x n (the derivative of exp(i f.q) is i f_k exp(i f.q))."""
        return self._derivative(q, 1).reshape(-1, self.m, self.n, self.n)

    def d2J(self, q: np.ndarray) -> np.ndarray:
        """d^2 J_A/dq_j dq_k: N x m x m x n x n."""
        m = self.m
        return self._derivative(q, 2).reshape(-1, m, m, self.n, self.n)

    def d3J(self, q: np.ndarray) -> np.ndarray:
        """d^3 J_A/dq_i dq_j dq_k: N x m x m x m x n x n."""
        m = self.m
        return self._derivative(q, 3).reshape(-1, m, m, m, self.n, self.n)

    # -- the outer terms ---------------------------------------------------------------------
    def majorant(self, speeds: np.ndarray, beta: float, scale: str = "J") -> np.ndarray:
        """U for each row of ``speeds`` (V x m_full, rad/s, the box's scale included; an outer
        column holds the box's half-width, whatever the sign): V x n x n, the absolute values taken
        in J's scale (``scale`` "J", T T^T = C_0) or the identity's ("I"; either is a majorant).
        The outer signs are covered at once by |f.theta'| <= |f_inner.theta'_inner| + sum_outer
        |f_k| |theta'_k|, so the vertices range over the inner speeds only. The transform's rounding
        on every coefficient is added as a multiple of the identity."""
        outer = [k for k in range(self.full.m) if k not in self.inner]
        inner = list(self.inner)

        def weight(F: np.ndarray) -> np.ndarray:
            return np.abs(speeds[:, inner] @ F[:, inner].T) + np.abs(speeds[:, outer]) @ np.abs(F[:, outer]).T

        U = np.einsum("vp,pab->vab", 2.0 * beta + weight(self._rest_F), self._rest_abs[scale])
        slack = ROUNDING * ((2.0 * beta + weight(self._all_F)) @ self._all_norm)   # V
        return U + slack[:, None, None] * np.eye(self.n)[None]


def split_model(full: InertiaModel, shape: np.ndarray, size: int = MAX_INNER) -> SplitModel:
    """The split of ``full`` with ``size`` inner angles whose majorant on the box of this shape
    (rate 0), with J_A's own worst speed term at sampled inner angles, is smallest relative to J's
    mean (largest eigenvalue of T^-1 (U + J_A') T^-T over the inner vertices): every choice is
    tried (at most 35 for 7 angles)."""
    T = metric(full)
    Ti = np.linalg.inv(T)
    parts = both_parts(full)
    speeds = np.array([[shape[c.index] for c in full.deps]])   # the outer half-widths; inner signs below
    size = min(size, full.m)
    best = None
    for trial in itertools.combinations(range(full.m), size):
        rng = np.random.default_rng(0)
        model = SplitModel(full, trial, parts)
        signs = np.array(list(itertools.product((1.0, -1.0), repeat=size)))
        vertices = np.repeat(speeds, signs.shape[0], axis=0)
        vertices[:, list(trial)] *= signs
        lo = np.array([span[0] for span in model.spans])
        hi = np.array([span[1] for span in model.spans])
        q = lo + (hi - lo) * rng.random((64, size))
        M = model.majorant(vertices, 0.0)[None] + np.einsum("vk,pkab->pvab", vertices[:, list(trial)], model.dJ(q))
        top = np.linalg.eigvalsh(Ti @ M @ Ti.T)[..., -1].max()
        if best is None or top < best[0]:
            best = (top, model)
    return best[1]
