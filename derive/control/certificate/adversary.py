"""An adversarial search for a state where the observer certificate's condition fails.

The certificate (derive.control.certificate) proves that

    N(theta, theta') = W + W^T - J'(theta, theta') - 2 beta J(theta),   J' = sum_k theta'_k dJ/dtheta_k,

is positive definite for every theta within the joint limits and every theta' in the box
|theta'_k| <= v s_k (the appendix's V decays, eq. a7; the observer of eq. 21-25 converges). This
module tries to break a proved claim: it samples random states, takes the worst ones as starts
and minimises lambda_min(N) over theta and theta' together with scipy's L-BFGS-B inside the
limits and the box, with the exact gradient (d lambda_min = u^T dN u for the unit eigenvector u
of a simple eigenvalue: dN/dtheta_k = -sum_l theta'_l d^2J/dtheta_l dtheta_k - 2 beta dJ/dtheta_k,
dN/dtheta'_l = -dJ/dtheta_l). It is evidence, not proof: a positive minimum found says the search
did not find a violation; a negative one is a counterexample (theta, theta') to the claim.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from derive.control.certificate.inertia import InertiaModel


@dataclass(frozen=True)
class Search:
    """The outcome of :func:`search`.

    low: the smallest lambda_min(N) found (unscaled, J's unit over time); theta (m, the deps'
    values, rad or m) and speed (m, rad/s) where; sampled: the smallest over the random states
    alone; starts: local searches run; states: random states sampled.
    """

    low: float
    theta: tuple[float, ...]
    speed: tuple[float, ...]
    sampled: float
    starts: int
    states: int


def _value_and_gradient(model: InertiaModel, S: np.ndarray, beta: float, x: np.ndarray):
    """lambda_min(N) at x = (theta, theta') (2m) and its gradient (module docstring)."""
    m = model.m
    q, w = x[None, :m], x[m:]
    dJ = model.dJ(q)[0]                                              # m x n x n
    N = S - np.einsum("k,kab->ab", w, dJ)
    if beta:
        N = N - 2.0 * beta * model.J(q)[0]
    lam, U = np.linalg.eigh(N)
    u = U[:, 0]
    d2J = model.d2J(q)[0]                                            # m x m x n x n
    dN = -np.einsum("l,lkab->kab", w, d2J)
    if beta:
        dN = dN - 2.0 * beta * dJ
    grad = np.concatenate([np.einsum("a,kab,b->k", u, dN, u), -np.einsum("a,kab,b->k", u, dJ, u)])
    return float(lam[0]), grad


def search(model: InertiaModel, W, box, beta: float = 0.0, states: int = 10_000, starts: int = 8,
           seed: int = 0) -> Search:
    """The smallest lambda_min(N) found for gain W (n x n) on the speed box (n speeds, rad/s,
    the scale included) at rate beta [1/s]: ``states`` random states within the limits and the
    box, then L-BFGS-B from the ``starts`` worst of them and from the worst speed vertex of each
    (module docstring). Raises ValueError when J depends on an unbounded coordinate."""
    from scipy.optimize import minimize

    if model.unbounded:
        raise ValueError("adversarial search: a coordinate J depends on has no limits")
    W = np.asarray(W, dtype=float)
    S = W + W.T
    m = model.m
    box = np.asarray(box, dtype=float)
    top = np.array([box[c.index] for c in model.deps])
    lo = np.array([span[0] for span in model.spans])
    hi = np.array([span[1] for span in model.spans])
    rng = np.random.default_rng(seed)
    q = lo + (hi - lo) * rng.random((states, m))
    w = top * rng.uniform(-1.0, 1.0, (states, m))
    N = S[None] - np.einsum("pk,pkab->pab", w, model.dJ(q)) - 2.0 * beta * model.J(q)
    lam = np.linalg.eigvalsh(N)[:, 0]
    sampled = float(lam.min())
    order = np.argsort(lam)[:starts]
    # N is affine in theta', so its smallest eigenvalue is least at a vertex of the box: each start
    # also from its own sign pattern's vertex
    firsts = np.vstack([np.hstack([q[order], w[order]]), np.hstack([q[order], np.sign(w[order]) * top])])
    bounds = list(zip(lo, hi)) + [(-t, t) for t in top]
    best = (sampled, q[order[0]], w[order[0]])
    for x0 in firsts:
        res = minimize(lambda x: _value_and_gradient(model, S, beta, x), x0, jac=True, method="L-BFGS-B",
                       bounds=bounds, options={"maxiter": 200})
        x = np.clip(res.x, [b[0] for b in bounds], [b[1] for b in bounds])
        value = _value_and_gradient(model, S, beta, x)[0]
        if value < best[0]:
            best = (value, x[:m], x[m:])
    return Search(low=best[0], theta=tuple(float(v) for v in best[1]), speed=tuple(float(v) for v in best[2]),
                  sampled=sampled, starts=int(firsts.shape[0]), states=states)
