"""Weighted least squares of the base parameters with their standard deviations (derive identify).

M. Gautier, W. Khalil, "Exciting trajectories for the identification of base inertial
parameters of robots", IJRR 11(4), 1992; Gautier 1997: ordinary least squares first; the
residual of joint j gives its noise sigma_j^2 = |rho_j|^2 / (N_j - p/n) (N_j: its
equations); then each joint's rows are weighted by 1 / sigma_j and solved again. The
covariance is s^2 (W_w^T W_w)^-1 with s^2 = |rho_w|^2 / (rows - p) (about 1 when the
sigma_j are right), its diagonal the variances; the relative standard deviation
100 sigma_k / |pi_k| is the figure identification papers report. The R factor and Q^T y of
the weighted regression carry the data into the physically consistent estimate
(derive.identify.consistent). Rows need not come n per sample: each has its joint
(a torque excluded by derive.identify.exclude leaves its row out).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from derive.identify.excite import condition


@dataclass(frozen=True)
class LeastSquares:
    """The weighted least-squares estimate: pi (p), its standard deviations, the joints'
    noise sigma_j [N m], cond of the stacked regressor, rows used, the R factor and
    Q^T y of the weighted regression (for the consistent estimate), the residual's s^2."""

    pi: np.ndarray
    std: np.ndarray
    sigma: np.ndarray
    cond: float
    rows: int
    R: np.ndarray
    qty: np.ndarray
    s2: float = 1.0

    @property
    def covariance(self) -> np.ndarray:
        """p x p: s^2 (W_w^T W_w)^-1 (its diagonal the variances std^2)."""
        Rinv = np.linalg.inv(self.R)
        return self.s2 * Rinv @ Rinv.T

    @property
    def relative_std(self) -> np.ndarray:
        """100 std / |pi| [%] (inf where pi = 0)."""
        with np.errstate(divide="ignore"):
            return np.where(self.pi != 0, 100 * self.std / np.abs(self.pi), np.inf)


def least_squares(W: np.ndarray, y: np.ndarray, joint: np.ndarray, n: int, names, what: str) -> LeastSquares:
    """Weighted least squares of W pi = y (``joint``: the joint, 0-based, of each row).
    DataError naming the unexcited combinations when W does not have full column rank."""
    cond = condition(None, W, what, names)   # raises when rank deficient
    rows, p = W.shape
    count = np.bincount(joint, minlength=n)
    pi0 = np.linalg.lstsq(W, y, rcond=None)[0]
    rho = y - W @ pi0
    scale = np.sqrt(np.bincount(joint, y ** 2, minlength=n) / np.maximum(count, 1))
    sigma = np.sqrt(np.bincount(joint, rho ** 2, minlength=n) / np.maximum(count - p / n, 1.0))
    sigma = np.maximum(sigma, 1e-12 * np.maximum(scale, 1e-300))      # a noise-free log: no division by 0
    weight = 1.0 / sigma[joint]
    Q, R = np.linalg.qr(W * weight[:, None])
    qty = Q.T @ (y * weight)
    pi = np.linalg.solve(R, qty)
    res = (y - W @ pi) * weight
    s2 = float(res @ res) / max(rows - p, 1)
    Rinv = np.linalg.inv(R)
    std = np.sqrt(s2 * (Rinv ** 2).sum(axis=1))
    return LeastSquares(pi=pi, std=std, sigma=sigma, cond=cond, rows=rows, R=R, qty=qty, s2=s2)
