"""The observer certificate's verdicts and the numeric tests its cells share (derive.control.certificate and
its grouped stages): Verdict, Decision, FLOAT_MARGIN, the cells' halving, the Perron bound of a spectral
norm and the stacked Cholesky test; the bounds branch and bound takes on a cell (CellBounds) and, from the
same bounds, Knuth's estimate of its tree for W = omega D as omega varies (TreeEstimate, which
derive.control.starter chooses omega with)."""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

FLOAT_MARGIN = 1e-9   # relative to 1 + ||W + W^T||: covers eigvalsh's rounding (~ n eps ||N||)
MAX_ENUMERATED = 4    # cells' vertices are enumerated for m <= this (2^m affine corners)


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
    return _cholesky_passes(np.moveaxis(A.reshape(-1, n, n), 0, -1).copy()).reshape(A.shape[:-2])


def _cholesky_passes(L: np.ndarray) -> np.ndarray:
    """:func:`_positive_definite` of the stack laid out n x n x B (each step one array operation), overwritten."""
    n = L.shape[0]
    ok = np.ones(L.shape[-1], dtype=bool)
    for k in range(n):
        pivot = L[k, k]
        ok &= pivot > 0
        if k + 1 < n:
            col = L[k + 1:, k] / np.where(pivot > 0, pivot, 1.0)
            L[k + 1:, k + 1:] -= col[:, None, :] * L[k, k + 1:][None, :, :]
    return ok


class CellBounds:
    """The bounds branch and bound takes on its cells (derive.control.certificate.ObserverCertificate._decide,
    whose docstring derives them), shared with the estimate of its tree (derive.control.certificate.suprema).

    md: the model decided over (an InertiaModel, or the split's SplitModel: m coordinates, n joints); speeds:
    the box's vertices over those coordinates (V x m, rad/s, the scale included); S: W + W^T, offset: the
    split's majorant U (1 or V x n x n, zero without a split), sc: J's diagonal scale (n x n), every matrix
    in that scale (D^-1 N D^-1); beta: the rate [1/s]. T bounds |d^2 N / dq_j dq_k| (m x m x n x n), Tn its
    spectral norms, T3 |d^3 N| (None without the model's fourth-derivative bounds); at rate 0 the vertices
    come in pairs v, -v (``paired``: vertex V - 1 - i is -vertex i), where |dN| and |H| are the same: their
    bounds are taken on the first ``lead`` vertices and mirrored."""

    def __init__(self, md, speeds: np.ndarray, S: np.ndarray, offset: np.ndarray, beta: float, sc: np.ndarray):
        m = md.m
        self.md, self.speeds, self.S, self.offset, self.beta, self.sc = md, speeds, S, offset, beta, sc
        self.T = (np.einsum("i,ijkab->jkab", np.abs(speeds[0]), md.third) + 2.0 * beta * md.second) * sc
        self.Tn = np.array([[_spectral_norm(self.T[j, k]) for k in range(m)] for j in range(m)])
        fourth = getattr(md, "fourth", None) if m else None
        self.T3 = None if fourth is None else (np.einsum("l,lijkab->ijkab", np.abs(speeds[0]), fourth)
                                               + 2.0 * beta * md.third) * sc
        V = speeds.shape[0]
        self.paired = beta == 0.0 and V % 2 == 0 and V > 1 and bool(np.all(speeds[::-1][:V // 2] == -speeds[:V // 2]))
        self.lead = V // 2 if self.paired else V

    def mirrored(self, x: np.ndarray) -> np.ndarray:
        """A bound of the first ``lead`` vertices (P x lead) for all of them (P x V)."""
        return np.concatenate([x, x[:, ::-1]], axis=1) if self.paired else x

    def terms(self, c: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """On the cells of centres c and half-widths h (P x m): N at the centres (P x V x n x n), dN/dq there
        (P x V x m x n x n), the Taylor remainder's bound rem and the linear term's lin (P x V each)."""
        N, dN, _, state = self.centre(c, h)
        rem, lin = self.finish(state, np.arange(c.shape[0]))
        return N, dN, rem, lin

    def centre(self, c: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple]:
        """:meth:`terms`' N and dN, a lower bound of rem for each cell (P: the smaller of the remainder's first
        form and the cubic term of its second), and what :meth:`finish` takes."""
        md, speeds, beta, T, T3 = self.md, self.speeds, self.beta, self.T, self.T3
        m, n, P = md.m, md.n, c.shape[0]
        J, dJ, d2J, *d3J = md.jet(c, 2 if T3 is None else 3, self.sc)
        # the contractions as matrix products (numpy's einsum loops took a third of the decision's time)
        # (at rate 0 the rate's terms are left out: 0 J adds nothing)
        N = self.S[None, None] - self.offset[None] - (speeds @ dJ.reshape(P, m, -1)).reshape(P, -1, n, n)
        dN = -(speeds @ d2J.reshape(P, m, -1)).reshape(P, -1, m, n, n)                     # P x V x m x n x n
        if beta:
            N, dN = N - 2.0 * beta * J[:, None], dN - 2.0 * beta * dJ[:, None]
        hh = (h[:, :, None] * h[:, None, :]).reshape(P, m * m)                              # h_j h_k
        rem = _spectral_norm(0.5 * (hh @ T.reshape(m * m, -1)).reshape(P, n, n))              # P
        cubic = None
        if T3 is not None:   # N(c + delta) = affine + 1/2 delta^T H(c) delta + E3, |E3| <= 1/6 sum h h h T3
            hhh = (hh[:, :, None] * h[:, None, :]).reshape(P, m ** 3)
            cubic = _spectral_norm((hhh @ T3.reshape(m ** 3, -1)).reshape(P, n, n) / 6.0)
        floor = rem if cubic is None else np.minimum(rem, cubic)
        return N, dN, floor, (h, hh, dN, d2J, d3J, rem, cubic)

    def finish(self, state: tuple, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """rem and lin (len(rows) x V) of the cells ``rows`` of :meth:`centre`'s."""
        h, hh, dN, d2J, d3J, rem, cubic = state
        h, hh, dN, rem = h[rows], hh[rows], dN[rows], rem[rows]
        speeds, beta, lead, m, n, P = self.speeds, self.beta, self.lead, self.md.m, self.md.n, rows.size
        rem = np.broadcast_to(rem[:, None], dN.shape[:2])                                     # P x V
        if cubic is not None:
            # one product for every cell: (V' x m) by (m x P m^2 n^2), then cells first
            H = -(speeds[:lead] @ np.moveaxis(d3J[0][rows].reshape(P, m, -1), 1, 0).reshape(m, -1)) \
                .reshape(lead, P, m * m, n * n).transpose(1, 0, 2, 3)                        # P x V' x m^2 x n^2
            if beta:
                H = H - 2.0 * beta * d2J[rows].reshape(P, 1, m * m, n * n)
            quad = self.mirrored(_spectral_norm(0.5 * (hh[:, None, None, :] @ np.abs(H)).reshape(P, -1, n, n)))
            rem = np.minimum(rem, quad + cubic[rows][:, None])
        lin = self.mirrored(_spectral_norm((h[:, None, None, :] @ np.abs(dN[:, :lead]).reshape(P, -1, m, n * n))
                                           .reshape(P, -1, n, n)))
        return rem, lin

    def axis(self, dN: np.ndarray, h: np.ndarray) -> np.ndarray:
        """The coordinate each cell (dN and h of :meth:`terms`' cells) is halved along: its widest contribution."""
        grow = np.sqrt((dN ** 2).sum(axis=(-1, -2))).max(axis=1)                            # P x m
        return np.argmax(h * (grow + h @ self.Tn), axis=1)


TREE_PATHS = 32   # random root-to-leaf paths of the tree estimate (Knuth's estimator: each gives an unbiased count)


class TreeEstimate:
    """Knuth's estimate of the cells branch and bound examines for W = omega D at rate 0 (D. E. Knuth, Estimation
    of the size of a backtrack tree, Math. Comp. 29, 1975): along random paths from the root, each step to one of
    the two halves at random (each halved along the axis the decision takes), a cell at level d stands for the 2^d
    cells of its level, so sum_d 2^d [the path's cells above level d are all split] counts the tree without bias.

    At rate 0 N = omega S - X(theta, theta') with S = D + D^T and X free of omega, so a cell passes the decision's
    test (:class:`CellBounds`, up to its floating-point margin) for every omega above its own threshold: lambda_min
    of N at each corner of the cell (the vertices of its affine part, m <= MAX_ENUMERATED) above rem, or past that
    at its centre above lin + rem, that is omega > lambda_max(L^-1 (X + r I) L^-T), L L^T = S. ``centre`` (paths x
    levels) [1/s] holds each cell's threshold at its centre (for the enumeration a lower bound of the corners',
    lambda_min being concave; inf where the path was not followed: it passed at ``lowest``, or lay past the levels
    followed); the corners' are computed when an omega at or above the centre's asks. It chooses which omega to
    decide; only the decision proves."""

    def __init__(self, centre: np.ndarray, lowest: float, corners):
        self.centre, self.lowest, self._corners = centre, lowest, corners
        self.scales = np.full(centre.shape, math.inf)   # the thresholds: nan where the corners' are not computed yet

    def _scales(self, omega: float) -> np.ndarray:
        """The thresholds, the corners' computed wherever the centre's is at most omega."""
        ask = np.isnan(self.scales) & (self.centre <= omega)
        for level in np.flatnonzero(ask.any(axis=0)):
            paths = np.flatnonzero(ask[:, level])
            self.scales[paths, level] = self._corners(level, paths)
        return self.scales

    def cells(self, omega: float) -> float:
        """The estimated cells examined at omega (>= ``lowest``; inf when a path needs more levels than followed)."""
        passed = self._scales(omega) <= omega
        first = np.where(passed.any(axis=1), passed.argmax(axis=1), -1)
        return math.inf if np.any(first < 0) else float(np.mean(2.0 ** (first + 1) - 1.0))

    def smallest(self, cells: float, above: float, highest: float, digits: int = 3) -> float | None:
        """The smallest omega > ``above`` (>= ``lowest``) whose estimate is at most ``cells``, by doubling up to
        ``highest`` and bisection to ``digits`` significant digits (the estimate does not grow with omega); None
        when none up to ``highest`` is."""
        lo = max(above, self.lowest)
        hi = lo * 1.001
        while self.cells(hi) > cells:
            if hi >= highest:
                return None
            lo, hi = hi, min(2.0 * hi, highest)
        while hi / lo > 1.0 + 10.0 ** -digits:
            mid = math.sqrt(lo * hi)
            lo, hi = (lo, mid) if self.cells(mid) <= cells else (mid, hi)
        return hi


def estimate_tree(cb: CellBounds, spans, lowest: float, cells: float, seed: int = 0) -> TreeEstimate:
    """:class:`TreeEstimate` of branch and bound over ``spans`` with the bounds ``cb`` of W = omega D (its S: D + D^T),
    for omega >= ``lowest`` [1/s], over ceil(log2(cells)) + 1 levels (seeded: the same paths every run)."""
    md, n, m = cb.md, cb.md.n, cb.md.m
    Li = np.linalg.inv(np.linalg.cholesky(cb.S))
    cb.S = np.zeros_like(cb.S)   # terms' N is then -X
    eye = np.eye(n)
    lo = np.array([span[0] for span in spans])
    hi = np.array([span[1] for span in spans])
    levels = math.ceil(math.log2(max(cells, 2))) + 1
    rng = np.random.default_rng(seed)
    centres = np.repeat(((lo + hi) / 2)[None], TREE_PATHS, axis=0)
    halves = np.repeat(((hi - lo) / 2)[None], TREE_PATHS, axis=0)
    centre = np.full((TREE_PATHS, levels), math.inf)
    kept: dict = {}   # level -> (the paths followed there, -X, dN, rem, h): the corners' data

    def top(X: np.ndarray) -> np.ndarray:
        return np.linalg.eigvalsh(Li @ X @ Li.T)[..., -1]

    def corners(level: int, paths: np.ndarray) -> np.ndarray:
        rows, N, dN, rem, h = kept[level]
        at = np.searchsorted(rows, paths)
        deltas = np.array(list(itertools.product((1.0, -1.0), repeat=m)))
        X = -(N[at][:, :, None] + np.einsum("dk,pk,pvkab->pvdab", deltas, h[at], dN[at])) \
            + rem[at][:, :, None, None, None] * eye
        return top(X).max(axis=(1, 2))

    estimate = TreeEstimate(centre, lowest, corners if m <= MAX_ENUMERATED else None)
    live = np.arange(TREE_PATHS)
    for level in range(levels):
        c, h = centres[live], halves[live]
        N, dN, rem, lin = cb.terms(c, h)
        centre[live, level] = top(-N + (rem if m <= MAX_ENUMERATED else lin + rem)[..., None, None] * eye).max(axis=1)
        if m <= MAX_ENUMERATED:
            kept[level] = (live, N, dN, rem, h)
        estimate.scales[live, level] = np.nan if m <= MAX_ENUMERATED else centre[live, level]
        axis = cb.axis(dN, h)
        rows = np.arange(live.size)
        h = h.copy()
        h[rows, axis] /= 2
        c = c.copy()
        c[rows, axis] += np.where(rng.random(live.size) < 0.5, -1.0, 1.0) * h[rows, axis]
        centres[live], halves[live] = c, h
        live = live[~(estimate._scales(lowest)[live, level] <= lowest)]   # a path ends where its cell passes
        if not live.size:
            break
    return estimate
