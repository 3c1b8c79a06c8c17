"""The physically consistent estimate of derive identify: the standard parameters nearest the
data and the prior with every body physically possible.

P. M. Wensing, S. Kim, J.-J. E. Slotine, "Linear matrix inequalities for physically
consistent inertial parameter identification: a statistical perspective on the mass
distribution", IEEE RA-L 3(1), 2017: with the decision variables z (phi = F z + g,
derive.identify.prior) written as z = z0 + S x (x: each parameter's deviation from the
arm file's value in its prior standard deviations), the estimate minimises

    |W_w K (F z + g) - y_w|^2 + |x|^2

(W_w, y_w: the regression weighted by each joint's noise 1 / sigma_j, derive.identify.estimate,
so that both terms are chi-square: a maximum a posteriori estimate with a Gaussian prior)
subject to every body's pseudo-inertia [[tr(I)/2 1 - I, h], [h^T, m]] being positive
semidefinite (with a margin, MARGIN of the body's scale), rotor inertias >= 0, viscous
friction >= the back-EMF damping, Coulomb friction >= 0; cvxpy with Clarabel, the data
and prior terms as one second-order cone (the QR factor of the stacked [A; 1]).

The solver's status is reported in words (:data:`STATUS`): ``optimal`` is Clarabel's
``Solved`` (duality gap and feasibility within TOLERANCE); ``optimal_inaccurate`` its
``AlmostSolved``, only within its reduced tolerances: derive identify then writes no arm
file unless forced. :func:`posterior_share` tells per parameter how much of what is known
of it comes from the data (0: nothing, the prior holds it).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from derive.errors import DataError
from derive.identify.estimate import LeastSquares
from derive.identify.prior import MARGIN, Model

TOLERANCE = 1e-8          # Clarabel's gap (absolute and relative) and feasibility tolerances (its defaults)
DATA_CAP = 1e6            # the largest singular value of the data term in the prior-scaled x
MAX_ITER = 400

STATUS = {
    "optimal": "solved: Clarabel met its tolerances ({tol:.0e} on the duality gap and the constraints)",
    "optimal_inaccurate": ("solved to reduced accuracy only: Clarabel stopped ({iters} iterations) with the duality "
                           "gap or a constraint residual above its tolerance {tol:.0e} but within its reduced "
                           "ones ({reduced}); the estimate may be off by more than the stated accuracy. Usually a "
                           "problem the data leaves badly scaled: check the condition number and the relative "
                           "standard deviations, exclude samples that are not the joint torque (--exclude), "
                           "or state the prior's uncertainty (--prior-uncertainty); --force writes it anyway"),
}


@dataclass(frozen=True)
class Consistent:
    """The physically consistent estimate: standard parameters phi, decision variables z,
    base parameters pi = K phi, the smallest eigenvalue of each body's LMI matrix (scaled
    to its body: about 1 for a typical body, 0 on the boundary), the solver's status
    (cvxpy's word), its explanation, iterations, and x = S^-1 (z - z0) (0 where S = 0)."""

    phi: np.ndarray
    z: np.ndarray
    pi: np.ndarray
    min_eigenvalues: tuple[float, ...]
    status: str
    words: str
    iterations: int
    x: np.ndarray

    @property
    def accurate(self) -> bool:
        return self.status == "optimal"


def _reduced() -> str:
    import clarabel

    s = clarabel.DefaultSettings()
    return f"gap {s.reduced_tol_gap_rel:.0e}, constraints {s.reduced_tol_feas:.0e}"


def data_matrix(ls: LeastSquares, K: np.ndarray, model: Model) -> tuple[np.ndarray, np.ndarray]:
    """(A, e): the weighted data term |A x - e|^2 in the prior-scaled deviations x of the free z."""
    free = model.S > 0
    A = ls.R @ K @ model.F[:, free] * model.S[free][None, :]
    e = ls.qty - ls.R @ K @ (model.F @ model.z0 + model.g)
    top = float(np.linalg.norm(A, 2)) if A.size else 0.0
    if top > DATA_CAP:
        A, e = A * (DATA_CAP / top), e * (DATA_CAP / top)
    return A, e


def posterior_share(ls: LeastSquares, K: np.ndarray, model: Model) -> np.ndarray:
    """Per z, 1 - (posterior / prior variance) of the linear problem (no LMIs): the share of
    what is known of it that the data gives (0: the data does not see it; nan where S = 0)."""
    A, _ = data_matrix(ls, K, model)
    free = model.S > 0
    out = np.full(len(model.z0), np.nan)
    _, sv, Vt = np.linalg.svd(A, full_matrices=True)
    s2 = np.zeros(Vt.shape[0])
    s2[:len(sv)] = sv ** 2
    out[free] = 1.0 - ((Vt.T ** 2) / (1.0 + s2)[None, :]).sum(axis=1)     # 1 - diag((A^T A + 1)^-1)
    return np.clip(out, 0.0, 1.0)


def consistent(ls: LeastSquares, K: np.ndarray, model: Model) -> Consistent:
    """The estimate of the module docstring. DataError when the solver fails."""
    import cvxpy as cp

    free = np.flatnonzero(model.S > 0)
    A, e = data_matrix(ls, K, model)
    m = len(free)
    Q, R = np.linalg.qr(np.vstack([A, np.eye(m)]))
    c = Q.T @ np.concatenate([e, np.zeros(m)])
    scale = max(float(np.linalg.norm(c)), 1.0)
    x = cp.Variable(m)
    z = [model.z0[k] for k in range(len(model.z0))]
    for col, k in enumerate(free):
        z[k] = model.z0[k] + model.S[k] * x[col]
    cons = []
    for idx, matrix, D in model.lmis:
        block = matrix([z[k] for k in idx])
        size = len(block)
        if not any(isinstance(block[a][b], cp.Expression) for a in range(size) for b in range(size)):
            continue
        P = cp.Variable((size, size), PSD=True)
        cons += [P[a, b] == D[a] * D[b] * block[a][b] for a in range(size) for b in range(a, size)]
        cons.append(P >> MARGIN * np.eye(size))
    cons += [z[k] >= bound for k, bound in model.lower if isinstance(z[k], cp.Expression)]
    problem = cp.Problem(cp.Minimize(cp.norm(R @ x - c) / scale), cons)
    try:
        with warnings.catch_warnings():        # "may be inaccurate": the status says so
            warnings.simplefilter("ignore", UserWarning)
            problem.solve(solver=cp.CLARABEL, tol_gap_abs=TOLERANCE, tol_gap_rel=TOLERANCE, tol_feas=TOLERANCE,
                          max_iter=MAX_ITER)
    except cp.error.SolverError as exc:
        raise DataError(f"the physically consistent estimate: Clarabel failed ({exc})") from None
    if problem.status not in STATUS or x.value is None:
        why = {"user_limit": f"Clarabel stopped at its limit of {MAX_ITER} iterations without a solution",
               "infeasible": "the constraints cannot all hold (the bounds on friction and rotor inertia, each "
                             "body physically possible)"}.get(problem.status, "no solution")
        raise DataError(f"the physically consistent estimate: the solver ended {problem.status}: {why}")
    xs = np.zeros(len(model.z0))
    xs[free] = x.value
    zv = model.z0 + model.S * xs
    phi = model.F @ zv + model.g
    eig = tuple(float(np.linalg.eigvalsh(np.array(matrix([zv[k] for k in idx]), dtype=float) * np.outer(D, D)).min())
                for idx, matrix, D in model.lmis)
    iters = int(getattr(problem.solver_stats, "num_iters", 0) or 0)
    words = STATUS[problem.status].format(tol=TOLERANCE, iters=iters, reduced=_reduced())
    return Consistent(phi=phi, z=zv, pi=K @ phi, min_eigenvalues=eig, status=problem.status, words=words,
                      iterations=iters, x=xs)
