"""Spectral radii of stacks of small matrices for the sample-time search (derive.control.sampling):
exact (LAPACK's eigenvalues), or proved below 1 without them.

The search asks of thousands of sampled closed loops (9 x 9 for 3 joints, 21 x 21 for 7) whether
their spectral radius is below 1, and needs the radius itself only where it is not. An eigenvalue
problem costs about 15 us at k = 9, a matrix product 0.3 us, so :func:`stable_bound` first tries
to prove rho < 1 by a few squarings, and only the matrices it leaves get their eigenvalues.
"""
from __future__ import annotations

import numpy as np

SQUARINGS = 16   # stable_bound: M, M^2, ..., M^65536 (a radius 1 - 1e-4 needs about 2^14)
_HOPELESS = 1e8  # a power this large (or an error bound above 1) is left to the eigenvalues


def spectral_radius(M: np.ndarray, exact: bool = True, rank: bool = False,
                    eigen_first: bool = False) -> np.ndarray:
    """The spectral radius of each matrix of a stack (... x k x k), by its eigenvalues (LAPACK's
    geev). Not ``exact``: where :func:`stable_bound` proves the radius below 1, that bound (< 1)
    stands in for it, and only the rest get their eigenvalues: a value >= 1 is always the radius
    itself; ``rank``: every one exact when any is >= 1.

    ``eigen_first`` (not ``exact``, not ``rank``; for a stack stable_bound is not expected to prove,
    radii within 1e-6 of 1): every matrix's eigenvalues first. When all radii are below 1 they are
    returned: below 1 where the usual way is (it gives the same eigenvalues to the matrices it does
    not prove, and a bound below 1 to those it does), so the same matrices are >= 1 (none) and each
    value >= 1 is the same radius; the values below 1 are radii instead of bounds. Else the usual
    way gives the result."""
    if exact:
        return np.abs(np.linalg.eigvals(M)).max(axis=-1)
    if eigen_first and not rank:
        rho = np.abs(np.linalg.eigvals(M)).max(axis=-1)
        if rho.max(initial=0.0) < 1.0:
            return rho
    out = stable_bound(M)
    todo = ~(out < 1.0)
    if todo.any():
        out[todo] = np.abs(np.linalg.eigvals(M[todo])).max(axis=-1)
        if rank and out.max() >= 1.0 and not todo.all():
            out[~todo] = np.abs(np.linalg.eigvals(M[~todo])).max(axis=-1)
    return out


def stable_bound(M: np.ndarray) -> np.ndarray:
    """Where the spectral radius of a matrix of the stack (... x k x k) is proved below 1, a bound
    of it (below 1; up to the rounding of the last root), inf elsewhere.

    rho(M) = rho(D^-1 M D) <= ||(D^-1 M D)^(2^j)||_F^(1/2^j): D is one diagonal scaling of the
    whole stack by powers of two (:func:`balancing`: exact, so the radius is unchanged; the
    sampled loops mix radians, rad/s and N m, and unscaled their powers grow by orders of magnitude
    before they decay), the Frobenius norm is submultiplicative and at least the spectral norm,
    and the powers come by repeated squaring, whose rounding is carried (Higham, Accuracy and
    Stability of Numerical Algorithms, 2002, sec. 3.5: fl(A B) = A B + E, |E| <= gamma_k |A| |B|,
    so ||E||_F <= gamma_k ||A||_F ||B||_F, gamma_k = k u / (1 - k u)): with a_j the norm of the
    computed power and e_j a bound of its distance to the exact one, e_j+1 <= gamma_k a_j^2 +
    2 a_j e_j + e_j^2, and rho < 1 when a_j + e_j < 1. A matrix leaves the squaring once proved,
    or once its power or error bound is too large to prove anything (_HOPELESS)."""
    k = M.shape[-1]
    u = np.finfo(float).eps / 2
    gamma = k * u / (1 - k * u)
    widen = 1 + 2 * k * k * u                   # the norm's own rounding (a sum of k^2 squares, a root)
    out = np.full(M.shape[:-2], np.inf)
    flat = out.reshape(-1)
    P = M.reshape(-1, k, k)
    if P.shape[0] == 0:
        return out
    f = balancing(P)
    if f is not None:
        P = P * (f[None, :] / f[:, None])[None]
    idx = np.arange(flat.size)
    e = np.zeros(flat.size)
    with np.errstate(over="ignore", invalid="ignore"):
        for j in range(SQUARINGS + 1):
            a = np.sqrt(np.einsum("pij,pij->p", P, P)) * widen
            top = a + e
            ok = top < 1.0
            if ok.any():
                flat[idx[ok]] = top[ok] ** (1.0 / 2 ** j)
            keep = ~ok & (e < 1.0) & (a < _HOPELESS)
            if not keep.all():
                idx, P, a, e = idx[keep], P[keep], a[keep], e[keep]
            if j == SQUARINGS or idx.size == 0:
                break
            e = gamma * a * a + 2 * a * e + e * e
            P = P @ P
    return out


def balancing(P: np.ndarray, sweeps: int = 2) -> np.ndarray | None:
    """One diagonal scaling f (k, powers of two) for a stack P (N x k x k), D = diag(f): Osborne's
    balancing (as LAPACK's gebal, here every state at once) of the entrywise largest magnitude
    over the stack, off the diagonal, so that each state's row and column of D^-1 |P| D weigh
    alike. None when a scaled entry could leave the normal range (the scaling would round there
    and no longer be a similarity)."""
    magnitude = np.abs(P)                  # once: the stack can hold thousands of matrices
    A = magnitude.max(axis=0)
    A[np.diag_indices_from(A)] = 0.0
    f = np.ones(A.shape[-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(sweeps):            # every state at once (Jacobi's order), half a step each
            B = A * (f[None, :] / f[:, None])
            step = np.round(0.25 * np.log2(B.sum(axis=1) / B.sum(axis=0)))
            f *= np.exp2(np.where(np.isfinite(step), step, 0.0))
    ratio = f[None, :] / f[:, None]
    nonzero = magnitude > 0                # the smallest and largest non-zero magnitudes, without a copy
    tiny = np.finfo(float).tiny
    if nonzero.any() and (magnitude.min(where=nonzero, initial=np.inf) * ratio.min() < tiny * 2 ** 60
                          or magnitude.max(where=nonzero, initial=0.0) * ratio.max() > np.finfo(float).max / 2 ** 60):
        return None
    return f
