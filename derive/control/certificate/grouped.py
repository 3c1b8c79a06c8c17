"""The observer certificate's outer angles bounded group by group (issue 23): a sharper split.

derive.control.certificate.split bounds every Fourier term of J with an outer frequency by a constant
majorant, so the terms' dependence on the inner angles and their cancellations are lost (the
Panda: 26 % of the numeric supremum). Here the terms of J' (appendix, eq. a7: the derivative of
V = e'^T W^-T J W^-1 e' needs W + W^T - J' > 0) are grouped by their outer frequency g,

    J'(theta, theta'_v) = M_0(theta_in, v) + sum_{g in P} 2 Re(Z_g(theta_in, v) exp(i g.theta_out)),
    Z_g = sum_{f_out = g} (i f.theta'_v) C_f exp(i f_in.theta_in)

(C_f: J's exact Fourier coefficients, derive.control.certificate.inertia, n x n, C_-f the conjugate of C_f;
M_0: the terms without an outer frequency; P: one of each pair g, -g), and each group is bounded
for every outer angle at once by the matrix inequality 2 Re(A) = A + A^H <= A P^-1 A^H + P (A
complex symmetric; from (A - P) P^-1 (A - P)^H >= 0, any P > 0) with A = Z_g exp(i g.theta_out),
whose phase cancels:

    J' <= B(theta_in, s) = M_0(theta_in, s) + sum_g (P_g + Re(Z_g P_g^-1 Z_g^H))       (n x n, kg m^2/s)

at every vertex s of the speed box (N of derive.control.certificate is affine in theta', so its
vertices cover the box). Z_g is linear in s: with sigma the vertex's signs (one per dep, the box's
shape sh in s_k = sh_k sigma_k) B is a quadratic polynomial in sigma,

    B_sigma = K_0 + sum_l sigma_l M_l + sum_{l < l'} sigma_l sigma_l' Q_ll'           (sigma_l^2 = 1),

and every basis matrix is a trigonometric polynomial in the inner angles of twice Z's degree.
:meth:`GroupedModel.series` gives their exact Fourier coefficients (values on a grid of 4 d + 1
angles per inner angle, d: Z's degree, and the discrete Fourier transform), from which the branch
and bound (:mod:`derive.control.certificate.grouped_cells`) takes values, Hessians and third-derivative bounds.
P_g is fixed once per arm and box (W-independent): P_FACTOR times the square root of the mean of
Re(Z_g Z_g^H) over the inner angles' torus and the vertices (exact, by Parseval). Sound, not
exact: failing it refutes nothing.
"""
from __future__ import annotations

import itertools

import numpy as np

from derive.control.certificate.inertia import ROUNDING, InertiaModel

P_FACTOR = 2.0     # P_g = P_FACTOR (mean of Re(Z_g Z_g^H))^1/2: the sampled optimum on the Panda lies near 2


def _sqrtm(M: np.ndarray) -> np.ndarray:
    w, V = np.linalg.eigh(M)
    return np.einsum("...ij,...j,...kj->...ik", V, np.sqrt(np.maximum(w, 0.0)), V)


class GroupedModel:
    """The grouped bound for one arm, inner angles and box shape (independent of W and of v).

    full: the InertiaModel (every dep an angle, ``fourier`` set); inner: indices into full.deps;
    shape: the box's shape over the joints (n, rad/s). ``signs``: the unit box's vertices over the
    deps (2^m x m, the shape included); ``groups``: per g of P, (frequencies of its terms over the
    inner angles K_g x m_in, coefficients K_g x n x n, g (m_out)); ``zero``: the frequencies and
    coefficients of M_0; ``P``: P_g per group (n x n); ``rounding``: per vertex, a bound of the
    spectral norm of J' computed minus J' exact (the transform's rounding).
    """

    def __init__(self, full: InertiaModel, inner: tuple[int, ...], shape) -> None:
        coef, F = full.fourier
        self.full, self.inner, self.n = full, tuple(inner), full.n
        self.outer = tuple(k for k in range(full.m) if k not in self.inner)
        self.m = len(self.inner)
        self.spans = [full.spans[k] for k in self.inner]
        self.shape = np.array([float(np.asarray(shape, dtype=float)[c.index]) for c in full.deps])   # per dep
        self.signs = np.array(list(itertools.product((1.0, -1.0), repeat=full.m))) * self.shape[None, :]
        nonzero = np.abs(coef).reshape(coef.shape[0], -1).max(axis=1) > 0
        coef, F = coef[nonzero], F[nonzero]
        Fin, Fout = F[:, list(self.inner)].astype(float), F[:, list(self.outer)]
        keys: dict[tuple[int, ...], list[int]] = {}
        for i, g in enumerate(map(tuple, Fout)):
            keys.setdefault(g, []).append(i)
        zero = (0,) * len(self.outer)
        reps = sorted(g for g in keys if g != zero and next(x for x in g if x != 0) > 0)
        self.zero = (Fin[keys[zero]], coef[keys[zero]]) if zero in keys else (np.zeros((0, self.m)),
                                                                               np.zeros((0, self.n, self.n)))
        self.groups = [(Fin[keys[g]], coef[keys[g]], np.array(g, dtype=float)) for g in reps]
        # |J'_computed - J'| <= ROUNDING sum_f |f.s| ||C_f||_F (as derive.control.certificate.split)
        self.rounding = ROUNDING * (np.abs(self.signs @ F.T.astype(float)) @ np.sqrt((np.abs(coef) ** 2).sum(axis=(1, 2))))
        self.P = []
        for Fg, Cg, g in self.groups:
            # the mean of Re(Z_g Z_g^H) over the torus and the vertices (Parseval: the f_in of a group are distinct)
            speed = self.signs[:, list(self.inner)] @ Fg.T + (self.signs[:, list(self.outer)] @ g)[:, None]   # V x K
            mean = np.einsum("k,kab,kcb->ac", (speed ** 2).mean(axis=0), Cg, Cg.conj()).real
            P = P_FACTOR * _sqrtm((mean + mean.T) / 2)
            P = (P + P.T) / 2 + 1e-6 * max(np.trace(P) / self.n, 1e-300) * np.eye(self.n)
            self.P.append(P)
        self._series = None

    def _Z(self, q: np.ndarray, Fg: np.ndarray, Cg: np.ndarray, g: np.ndarray) -> np.ndarray:
        """Z_g at inner points q for every vertex: N x V x n x n."""
        E = np.exp(1j * (q @ Fg.T))                                                     # N x K
        speed = self.signs[:, list(self.inner)] @ Fg.T + (self.signs[:, list(self.outer)] @ g)[:, None]   # V x K
        return 1j * np.einsum("pk,vk,kab->pvab", E, speed, Cg, optimize=True)

    def bound(self, q: np.ndarray) -> np.ndarray:
        """B(theta_in, s) at inner points q (N x m_in) for every vertex: N x V x n x n (the module
        docstring; without the rounding term), from the groups directly."""
        Fz, Cz = self.zero
        B = self._Z(q, Fz, Cz, np.zeros(len(self.outer))).real
        for (Fg, Cg, g), P in zip(self.groups, self.P):
            Z = self._Z(q, Fg, Cg, g)
            B = B + np.einsum("pvab,bc,pvdc->pvad", Z, np.linalg.inv(P), Z.conj(), optimize=True).real + P
        return B

    # -- B's own series in the inner angles ------------------------------------------------
    def series(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """B_sigma's exact Fourier series in the inner angles (cached): (H, C, basis) with H the
        frequencies (K x m_in, integers, one of each pair h, -h and 0), C the coefficients in real
        form (2 x R x K x n x n: B_r(theta) = sum_h C[0, r, h] cos(h.theta) + C[1, r, h] sin(h.theta))
        of the R = 1 + m + m (m - 1) / 2 basis matrices (constant, sigma_l, sigma_l sigma_l', l < l'),
        and basis (V x R): each vertex's weights, so B_sigma = sum_r basis[v, r] B_r."""
        if self._series is None:
            self._series = self._compute_series()
        return self._series

    def _compute_series(self):
        n, mi, mf = self.n, self.m, self.full.m
        every = [self.zero[0]] + [Fg for Fg, _, _ in self.groups]
        deg = np.max(np.abs(np.vstack(every)), axis=0).astype(int) if mi else np.zeros(0, int)
        L = tuple(int(4 * d + 1) for d in deg)                 # B has degree 2 d: 4 d + 1 points are exact
        size = int(np.prod(L)) if mi else 1
        pairs = [(a, b) for a in range(mf) for b in range(a + 1, mf)]
        R = 1 + mf + len(pairs)
        values = np.zeros((R,) + L + (n, n))

        def on_grid(freqs: np.ndarray, mats: np.ndarray) -> np.ndarray:
            """sum_f mats_f exp(i f.theta) on the grid theta_j = 2 pi t / L_j (the inverse transform)."""
            X = np.zeros(L + (n, n), dtype=complex)
            idx = tuple((freqs[:, j].astype(int) % L[j]) for j in range(mi))
            np.add.at(X, idx, mats)
            return np.fft.ifftn(X, axes=tuple(range(mi))) * size

        Fz, Cz = self.zero
        for k in range(mi):   # M_0 = sum_k sigma_k sh_k Re(sum_f i f_k C_f e^{i f.theta})
            values[1 + self.inner[k]] += self.shape[self.inner[k]] * on_grid(Fz, 1j * Fz[:, k, None, None] * Cz).real
        for (Fg, Cg, g), P in zip(self.groups, self.P):
            Q = np.linalg.inv(np.linalg.cholesky(P)).T                                # Q Q^T = P^-1
            Pq = np.linalg.inv(Q @ Q.T)                                               # the P the bound is exact for
            values[0] += Pq
            # Y_l = sum_a Lg[a, l] Z_a Q over the sign variables l: Z_g Q = sum_l sigma_l Y_l
            Y = np.zeros((mf,) + L + (n, n), dtype=complex)
            for k in range(mi):
                l = self.inner[k]
                Y[l] = self.shape[l] * on_grid(Fg, 1j * Fg[:, k, None, None] * Cg) @ Q
            base = on_grid(Fg, 1j * Cg) @ Q
            for o, l in enumerate(self.outer):
                Y[l] = g[o] * self.shape[l] * base
            for l in range(mf):
                values[0] += (Y[l] @ np.swapaxes(Y[l], -1, -2).conj()).real
            for r, (a, b) in enumerate(pairs):
                X = (Y[a] @ np.swapaxes(Y[b], -1, -2).conj()).real
                values[1 + mf + r] += X + np.swapaxes(X, -1, -2)
        C = np.fft.fftn(values, axes=tuple(range(1, 1 + mi))) / size
        freq = np.stack(np.meshgrid(*[np.fft.fftfreq(Lj, 1.0 / Lj) for Lj in L], indexing="ij"),
                        axis=-1).reshape(-1, mi).astype(int) if mi else np.zeros((1, 0), int)
        C = C.reshape(R, -1, n, n)
        first = freq[np.arange(freq.shape[0]), np.argmax(freq != 0, axis=1)] if mi else np.zeros(1)
        half = np.flatnonzero(first > 0)
        origin = np.flatnonzero(~np.any(freq != 0, axis=1))
        keep = np.concatenate([origin, half])
        real = np.concatenate([C[:, origin].real, 2.0 * C[:, half].real], axis=1)
        imag = np.concatenate([np.zeros_like(C[:, origin].real), -2.0 * C[:, half].imag], axis=1)
        sig = self.signs / self.shape[None, :]
        basis = np.hstack([np.ones((sig.shape[0], 1)), sig] + [sig[:, [a]] * sig[:, [b]] for a, b in pairs])
        return freq[keep], np.stack([real, imag]), basis

    def supremum(self, W, count: int = 4096, seed: int = 0) -> float:
        """Numeric estimate of the largest v the grouped bound can prove for W: min over sampled
        inner points and vertices of 1 / lambda_max(S^-1/2 B S^-1/2), from :meth:`series`."""
        W = np.asarray(W, dtype=float)
        Li = np.linalg.inv(np.linalg.cholesky(W + W.T))
        H, C, basis = self.series()
        rng = np.random.default_rng(seed)
        lo = np.array([span[0] for span in self.spans])
        hi = np.array([span[1] for span in self.spans])
        top = 0.0
        for at in range(0, count, 256):
            q = lo + (hi - lo) * rng.random((min(256, count - at), self.m))
            arg = q @ H.T
            Br = np.einsum("pk,rkab->prab", np.cos(arg), C[0]) + np.einsum("pk,rkab->prab", np.sin(arg), C[1])
            B = np.einsum("vr,prab->pvab", basis, Br) + self.rounding[None, :, None, None] * np.eye(self.n)
            top = max(top, float(np.linalg.eigvalsh(np.einsum("ab,pvbc,dc->pvad", Li, B, Li))[..., -1].max()))
        return np.inf if top <= 0 else 1.0 / top
