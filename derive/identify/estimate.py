"""The estimators of derive identify: weighted least squares of the base parameters with
their standard deviations, and the physically consistent estimate of the standard ones.

Least squares (M. Gautier, W. Khalil, "Exciting trajectories for the identification of
base inertial parameters of robots", IJRR 11(4), 1992; Gautier 1997): ordinary least
squares first; the residual of joint j gives its noise sigma_j^2 = |rho_j|^2 / (N - p/n);
then each joint's rows are weighted by 1 / sigma_j and solved again. The covariance is
s^2 (W_w^T W_w)^-1 with s^2 = |rho_w|^2 / (N n - p) (about 1 when the sigma_j are right),
its diagonal the variances; the relative standard deviation 100 sigma_k / |pi_k| is the
figure identification papers report.

Physically consistent estimate (P. M. Wensing, S. Kim, J.-J. E. Slotine, "Linear matrix
inequalities for physically consistent inertial parameter identification: a statistical
perspective on the mass distribution", IEEE RA-L 3(1), 2017): the standard parameters
phi minimising |W_w K phi - y_w|^2 (K: base from standard, derive.identify.regressor)
plus a regulariser toward the arm file's phi_0, in the scaled x = S^-1 (phi - phi_0) (S: each
parameter's scale, from the body's mass and the arm's reach): |x_0|^2 on the directions the
data does not see (the null space of W_w K S: what no torque depends on keeps the prior's
value), weighted UNSEEN (sigma_p / sigma_1)^2, and REGULARISATION (sigma_p / sigma_1)^2
|x_1|^2 on those it sees (sigma_1, sigma_p: the largest and smallest singular values of the
scaled fit): both weaker than the data in its least-excited direction, so that the prior
never outweighs a measured torque, subject to every body's
pseudo-inertia being positive semidefinite (the triangle inequality then holds), rotor
inertias >= 0, viscous friction >= 0 beside the back-EMF, Coulomb friction >= 0;
cvxpy with Clarabel. A planar [[link]] arm's bodies keep its model: each link a lamina
along its x axis (mass, centre of mass on the axis, inertia) with its point masses
fixed, so the LMI is that of the lamina, [[Izz, hx], [hx, m]] >= 0.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from derive.errors import DataError
from derive.identify.excite import condition
from derive.identify.parameters import pseudo_inertia

REGULARISATION = 1e-6      # weight of the prior on what the data sees, against its weakest direction
UNSEEN = 1e-2              # ... and on what it does not see: below every direction it sees
MARGIN = 1e-9              # each LMI holds with this margin times the body's scale (exact checks pass)


@dataclass(frozen=True)
class LeastSquares:
    """The weighted least-squares estimate: pi (p), its standard deviations, the joints'
    noise sigma_j [N m], cond of the stacked regressor, rows used, the R factor and
    Q^T y of the weighted regression (for the consistent estimate)."""

    pi: np.ndarray
    std: np.ndarray
    sigma: np.ndarray
    cond: float
    rows: int
    R: np.ndarray
    qty: np.ndarray

    @property
    def relative_std(self) -> np.ndarray:
        """100 std / |pi| [%] (inf where pi = 0)."""
        with np.errstate(divide="ignore"):
            return np.where(self.pi != 0, 100 * self.std / np.abs(self.pi), np.inf)


def least_squares(W: np.ndarray, y: np.ndarray, n: int, names, what: str) -> LeastSquares:
    """Weighted least squares of W pi = y (W: rows ordered sample by sample, n per sample).
    DataError naming the unexcited combinations when W does not have full column rank."""
    cond = condition(None, W, what, names)   # raises when rank deficient
    rows, p = W.shape
    N = rows // n
    pi0 = np.linalg.lstsq(W, y, rcond=None)[0]
    rho = (y - W @ pi0).reshape(N, n)
    scale = np.sqrt(np.mean(y.reshape(N, n) ** 2, axis=0))
    sigma = np.sqrt((rho ** 2).sum(axis=0) / max(N - p / n, 1.0))
    sigma = np.maximum(sigma, 1e-12 * np.maximum(scale, 1e-300))      # a noise-free log: no division by 0
    weight = np.tile(1.0 / sigma, N)
    Q, R = np.linalg.qr(W * weight[:, None])
    qty = Q.T @ (y * weight)
    pi = np.linalg.solve(R, qty)
    res = (y - W @ pi) * weight
    s2 = float(res @ res) / max(rows - p, 1)
    Rinv = np.linalg.inv(R)
    std = np.sqrt(s2 * (Rinv ** 2).sum(axis=1))
    return LeastSquares(pi=pi, std=std, sigma=sigma, cond=cond, rows=rows, R=R, qty=qty)


@dataclass(frozen=True)
class Model:
    """The standard parameters as an affine function phi = F z + g of the decision variables
    z (prior z0, scales S); lmis: per body, the indices of z and a function from those
    entries to the matrix that must be positive semidefinite; lower: (index, bound) of z."""

    F: np.ndarray
    g: np.ndarray
    z0: np.ndarray
    S: np.ndarray
    lmis: tuple
    lower: tuple[tuple[int, float], ...]


@dataclass(frozen=True)
class Consistent:
    """The physically consistent estimate: standard parameters phi, decision variables z,
    base parameters pi = K phi, the smallest eigenvalue of each body's LMI matrix, the solver's status."""

    phi: np.ndarray
    z: np.ndarray
    pi: np.ndarray
    min_eigenvalues: tuple[float, ...]
    status: str


def consistent(ls: LeastSquares, K: np.ndarray, model: Model) -> Consistent:
    """The estimate of the module docstring (cvxpy, Clarabel). DataError when the solver fails."""
    import cvxpy as cp

    M = ls.R @ K @ model.F * model.S[None, :]
    e = ls.qty - ls.R @ K @ (model.F @ model.z0 + model.g)
    U, sv, Vt = np.linalg.svd(M, full_matrices=True)
    r = int((sv > 1e-12 * sv[0]).sum())                       # the directions the data sees
    seen, unseen = Vt[:r].T, Vt[r:].T                          # orthonormal, scaled parameter space
    y = cp.Variable(r)
    w = cp.Variable(unseen.shape[1]) if unseen.shape[1] else None
    x = seen @ y + (unseen @ w if w is not None else 0)
    fit = cp.sum_squares(cp.multiply(sv[:r] / sv[0], y) - U[:, :r].T @ e / sv[0])
    weakest = (sv[r - 1] / sv[0]) ** 2
    prior = weakest * (REGULARISATION * cp.sum_squares(y) + (UNSEEN * cp.sum_squares(w) if w is not None else 0))
    z = model.z0 + cp.multiply(model.S, x)
    cons = []
    for idx, matrix, margin in model.lmis:
        block = matrix([z[k] for k in idx])
        size = len(block)
        P = cp.Variable((size, size), PSD=True)
        cons += [P[a, b] == block[a][b] for a in range(size) for b in range(a, size)]
        cons.append(P >> margin * np.eye(size))
    cons += [z[k] >= bound for k, bound in model.lower]
    problem = cp.Problem(cp.Minimize(fit + prior), cons)
    try:
        with warnings.catch_warnings():        # "may be inaccurate": the status says so, the LMIs are checked below
            warnings.simplefilter("ignore", UserWarning)
            problem.solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12, max_iter=400)
    except cp.error.SolverError as exc:
        raise DataError(f"the physically consistent estimate: Clarabel failed ({exc})") from None
    if problem.status not in ("optimal", "optimal_inaccurate") or y.value is None:
        raise DataError(f"the physically consistent estimate: the solver ended {problem.status}")
    xv = seen @ y.value + (unseen @ w.value if w is not None else 0)
    zv = model.z0 + model.S * xv
    phi = model.F @ zv + model.g
    eig = tuple(float(np.linalg.eigvalsh(np.array(matrix([zv[k] for k in idx]), dtype=float)).min())
                for idx, matrix, _ in model.lmis)
    return Consistent(phi=phi, z=zv, pi=K @ phi, min_eigenvalues=eig, status=problem.status)


def spatial_model(prior: np.ndarray, n: int, reach: float, emf: np.ndarray, coulomb: bool) -> Model:
    """Every body's ten parameters free (URDF and DH arms): z = phi."""
    size = len(prior)
    lmis, scales = [], np.zeros(size)
    total = max(float(sum(prior[10 * i] for i in range(n))), 1e-3)
    for i in range(n):
        sm = max(prior[10 * i], 1e-2 * total / n, 1e-3)
        scales[10 * i: 10 * i + 10] = [sm] + [sm * reach] * 3 + [sm * reach ** 2] * 6
        lmis.append((tuple(range(10 * i, 10 * i + 10)), pseudo_inertia, MARGIN * sm * reach ** 2))
    scales[10 * n:], lower = _drives(prior[10 * n:], n, emf, coulomb, float(scales[4::10].max()))
    return Model(F=np.eye(size), g=np.zeros(size), z0=prior.copy(), S=scales, lmis=tuple(lmis),
                 lower=tuple((10 * n + k, b) for k, b in lower))


def _drives(prior: np.ndarray, n: int, emf: np.ndarray, coulomb: bool, inertia: float):
    """(scales, bounds (index, lower bound)) of the drive parameters Ia (>= 0), fv (>= the
    back-EMF: the joint's viscous friction >= 0) and fc (>= 0), indices from 0."""
    scales, lower = np.zeros(len(prior)), []
    for j in range(n):
        scales[j] = max(prior[j], 1e-3 * inertia, 1e-9)
        scales[n + j] = max(prior[n + j], 1e-2)
        lower += [(j, 0.0), (n + j, float(emf[j]))]
        if coulomb:
            scales[2 * n + j] = max(prior[2 * n + j], 1e-2)
            lower.append((2 * n + j, 0.0))
    return scales, lower


def _lamina(z) -> list[list]:
    """The LMI of a lamina along x with z = (m, hx, Izz) about its joint: [[Izz, hx], [hx, m]]."""
    m, hx, izz = z
    return [[izz, hx], [hx, m]]


def planar_model(prior: np.ndarray, links: list[tuple[float, float, float]], fixed: list[np.ndarray],
                 reach: float, emf: np.ndarray, coulomb: bool) -> Model:
    """A planar arm's model: per link z = (m, hx, Izz) of the link alone (a lamina along x,
    about its joint), the point masses it carries fixed (``fixed``: their ten parameters)."""
    n = len(links)
    drives = len(prior) - 10 * n
    size = 3 * n + drives
    F = np.zeros((len(prior), size))
    g = np.zeros(len(prior))
    z0 = np.zeros(size)
    S = np.zeros(size)
    lmis = []
    total = max(sum(m for m, _, _ in links) + sum(f[0] for f in fixed), 1e-3)
    for i, ((m, hx, izz), f) in enumerate(zip(links, fixed)):
        F[10 * i, 3 * i] = 1.0                        # m
        F[10 * i + 1, 3 * i + 1] = 1.0                # hx
        F[10 * i + 7, 3 * i + 2] = 1.0                # Iyy = Izz for a lamina along x
        F[10 * i + 9, 3 * i + 2] = 1.0                # Izz
        g[10 * i: 10 * i + 10] = f
        z0[3 * i: 3 * i + 3] = (m, hx, izz)
        sm = max(m, 1e-2 * total / n, 1e-3)
        S[3 * i: 3 * i + 3] = (sm, sm * reach, sm * reach ** 2)
        lmis.append(((3 * i, 3 * i + 1, 3 * i + 2), _lamina, MARGIN * sm * reach ** 2))
    F[10 * n:, 3 * n:] = np.eye(drives)
    z0[3 * n:] = prior[10 * n:]
    S[3 * n:], lower = _drives(prior[10 * n:], n, emf, coulomb, float(S[2::3][:n].max()))
    return Model(F=F, g=g, z0=z0, S=S, lmis=tuple(lmis), lower=tuple((3 * n + k, b) for k, b in lower))
