"""The observer certificate's verdicts and the numeric tests its cells share (derive.control.certificate and
its grouped stages): Verdict, Decision, FLOAT_MARGIN, the cells' halving, the Perron bound of a spectral
norm and the stacked Cholesky test."""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

FLOAT_MARGIN = 1e-9   # relative to 1 + ||W + W^T||: covers eigvalsh's rounding (~ n eps ||N||)


class Verdict(str, Enum):
    PROVED = "proved"
    REFUTED = "refuted"
    UNPROVEN = "unproven"


@dataclass(frozen=True)
class Decision:
    """The outcome of (*) for one W, box and rate.

    verdict: proved / refuted / unproven; cells: cells examined; margin: a lower
    bound of the smallest lambda_min(N) - ||R||_2 over the proved cells (proved; a cell
    whose vertices passed the Cholesky test at half its centre's slack counts that half,
    the rest their vertices' own eigenvalues, so the smallest is exact where it matters); point: a
    (theta, theta') where N is not positive definite (refuted), or the worst
    centre found; low: the smallest lambda_min(N) seen at a centre (N itself when
    refuted; else, like margin, in J's diagonal scale D^-1 N D^-1 the cells are decided in).
    """

    verdict: Verdict
    cells: int
    margin: float | None
    point: tuple[tuple[float, ...], tuple[float, ...]] | None
    low: float
    seconds: float


def halve_cells(centres: np.ndarray, halves: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two children of each cell (rows of ``centres``, half-widths ``halves``, P x m) split in half
    along its ``axis`` (P): (2P x m centres, 2P x m half-widths), the left children first."""
    rows = np.arange(centres.shape[0])
    hs = halves.copy()
    hs[rows, axis] /= 2
    left, right = centres.copy(), centres.copy()
    left[rows, axis] -= hs[rows, axis]
    right[rows, axis] += hs[rows, axis]
    return np.vstack([left, right]), np.vstack([hs, hs])


def _spectral_norm(R: np.ndarray) -> np.ndarray:
    """An upper bound of ||R||_2 of symmetric nonnegative matrices (... x n x n): the Perron root,
    bounded by Collatz-Wielandt, rho(R) <= max_i (R x)_i / x_i for any positive x, with x a few
    power iterations from ones (nearly tight; matrix-vector products instead of eigenvalues), rounded up."""
    x = np.ones(R.shape[:-1])
    for _ in range(4):
        x = np.einsum("...ij,...j->...i", R, x)
        x = x / np.maximum(x.max(axis=-1, keepdims=True), 1e-300)
    x = x + 1e-9
    return (np.einsum("...ij,...j->...i", R, x) / x).max(axis=-1) * (1 + 1e-12) + 1e-300


def _positive_definite(A: np.ndarray) -> np.ndarray:
    """Whether each symmetric matrix of ``A`` (... x n x n) is positive definite: Cholesky without
    pivoting, vectorised over the stack (all pivots positive; NaN fails). In floating point a
    success proves A + E positive definite with ||E||_2 <= n (n + 1) eps n ||A||_2 (Demmel's bound
    of Cholesky's backward error, Higham, Accuracy and Stability of Numerical Algorithms, thm 10.5):
    the caller's shift by FLOAT_MARGIN (1 + ||W + W^T||) covers it, as it covers eigvalsh's."""
    n = A.shape[-1]
    L = np.moveaxis(A.reshape(-1, n, n), 0, -1).copy()        # n x n x B: each step one array operation
    ok = np.ones(L.shape[-1], dtype=bool)
    for k in range(n):
        pivot = L[k, k]
        ok &= pivot > 0
        if k + 1 < n:
            col = L[k + 1:, k] / np.where(pivot > 0, pivot, 1.0)
            L[k + 1:, k + 1:] -= col[:, None, :] * L[k, k + 1:][None, :, :]
    return ok.reshape(A.shape[:-2])
