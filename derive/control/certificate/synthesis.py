"""Observer gain synthesis: the smallest W that the certificate proves for a speed box and a rate.

``w = "auto"`` in an arm's [controller] (and ``derive tune ARM``) chooses W by a semidefinite
program over the condition of derive.control.certificate,

    W + W^T - J'(theta, theta'_v) - 2 beta J(theta) >= margin    at sampled theta, box vertices v,

minimising the spectral norm ||W||_2 (the gain from velocity noise to the estimate, eq. 22:
dhat = B^-1 (z + W theta')). The structure is Chen's (W[i][j] = w_j for j <= i, eq. 25
generalised) or a full matrix. The samples grow by cutting planes: after each solve the worst
(theta, vertex) pairs of a dense numeric check join the program, until none is violated. The
result is then rounded to 6 significant digits and re-checked by the sound certificate
(branch and bound over every theta); if that does not prove it, the program is solved again with
a larger headroom on the box and the rate (the gain grows), at most ``ROUNDS`` times.

cvxpy models the program and Clarabel (an interior-point conic solver, maintained, no licence)
solves it.
"""
from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import sympy as sp

from derive.control.certificate import Decision, InertiaModel, ObserverCertificate, Verdict, joint_coordinates
from derive.errors import DerivationError

STRUCTURES = ("chen", "full")
HEADROOMS = (0.02, 0.1, 0.3)   # box and rate scaled by 1 + h for the program
CUTS = 12   # (theta, vertex) pairs added per cutting-plane round
MAX_ROUNDS = 60
SEED = 24   # random (theta, vertex) pairs of the first program


@dataclass(frozen=True)
class Synthesis:
    """A synthesised gain and how it was certified.

    W: n x n exact (6 significant digits); structure: 'chen' or 'full'; box: the speed box
    |theta'_k| <= box_k [rad/s]; rate: beta [1/s]; decision: the sound certificate's verdict
    (proved) for W on the box at the rate; headroom: the program's extra margin; samples: (theta,
    vertex) pairs in the last program; rounds: cutting-plane solves; seconds: total time;
    norm: ||W||_2.
    """

    W: tuple[tuple[Fraction, ...], ...]
    structure: str
    box: tuple[float, ...]
    rate: float
    decision: Decision
    headroom: float
    samples: int
    rounds: int
    seconds: float
    norm: float


def _round6(x: float) -> Fraction:
    """x to 6 significant digits, as the exact decimal written."""
    return Fraction(f"{x:.6g}") if x != 0 else Fraction(0)


def _structure(W, n: int, structure: str) -> list:
    """Linear constraints that give the n x n variable W its structure."""
    if structure == "full":
        return []
    cons = []
    for i in range(n):
        for j in range(n):
            if j > i:
                cons.append(W[i, j] == 0)
            elif j < i:
                cons.append(W[i, j] == W[j, j])
    return cons


def _solve(n: int, structure: str, consts: np.ndarray) -> np.ndarray:
    """min ||W||_2 s.t. W + W^T - consts[i] >= 0 for every i (consts: k x n x n, symmetric)."""
    import cvxpy as cp

    W = cp.Variable((n, n))
    S = W + W.T
    cons = _structure(W, n, structure) + [S - consts[i] >> 0 for i in range(consts.shape[0])]
    prob = cp.Problem(cp.Minimize(cp.sigma_max(W)), cons)
    try:
        prob.solve(solver=cp.CLARABEL)
    except cp.error.SolverError as exc:
        raise DerivationError(f"observer synthesis: the SDP solver failed ({exc})") from None
    if prob.status not in ("optimal", "optimal_inaccurate") or W.value is None:
        raise DerivationError(f"observer synthesis: the SDP is {prob.status}")
    out = np.array(W.value, dtype=float)
    if structure == "chen":   # exactly the pattern, whatever the solver's rounding
        out = np.tril(np.tile(np.diag(out), (n, 1)))
    return out


def synthesise(model: InertiaModel, box, rate: float = 0.0, structure: str = "chen",
               budget: int = 20_000, seed: int = 0, check_samples: int = 4096) -> Synthesis:
    """The smallest ||W||_2 of the given structure certified on ``box`` at ``rate`` (module docstring).

    box: n speeds [rad/s]; rate: beta >= 0 [1/s]. The first headroom whose W the sound certificate
    proves wins; when it proves none within ``budget`` cells, the W of the largest headroom is
    returned with its ``unproven`` decision (its numeric check passed). Raises DerivationError when
    the program itself fails."""
    if structure not in STRUCTURES:
        raise DerivationError(f"observer synthesis: structure {structure!r} is not one of {STRUCTURES}")
    start = time.perf_counter()
    n = model.n
    if model.m == 0 and not rate > 0:
        raise DerivationError("observer synthesis: J depends on no joint coordinate, so J' = 0 and the certificate "
                              "W + W^T - 2 beta J > 0 holds at every speed for any W with W + W^T > 0: there is no "
                              "smallest W at rate 0; give a rate beta > 0 (derive tune --rate, controller.observer_rate) "
                              "to get the smallest W for it, about beta J")
    cert = ObserverCertificate(model, box)
    box = np.asarray(box, dtype=float)
    rng = np.random.default_rng(seed)
    dense = cert.samples(check_samples, seed=seed + 1)
    nv = cert.signs.shape[0]
    J0 = model.J(np.zeros((1, model.m)))[0]
    scale = float(np.abs(J0).max()) or 1.0
    rounds, tried, last = 0, [], None
    seed_points = cert.samples(SEED, seed=seed)[-SEED:]
    seed_points = seed_points[np.arange(SEED) % seed_points.shape[0]]   # one point when J is constant
    seed_vertices = rng.integers(nv, size=SEED)
    for h in HEADROOMS:
        v, beta = 1.0 + h, rate * (1.0 + h) + h * 1e-3
        consts = -cert.matrices(np.zeros((n, n)), box, v, beta, seed_points)[np.arange(SEED), seed_vertices]
        for _ in range(MAX_ROUNDS):
            rounds += 1
            W = _solve(n, structure, consts + 1e-9 * scale * np.eye(n))
            N = cert.matrices(W, box, v, beta, dense)
            lam = np.linalg.eigvalsh(N)[..., 0]   # P x V
            bad = np.argwhere(lam < 0)
            if bad.size:
                rows = bad[np.argsort(lam[bad[:, 0], bad[:, 1]])[:CUTS]]
                consts = np.concatenate([consts, (W + W.T)[None] - N[rows[:, 0], rows[:, 1]]])
                # fresh random points, so the check set is not the only source of cuts
                dense = np.vstack([dense, cert.samples(256, seed=int(rng.integers(1 << 30)))[-256:]])
                continue
            exact = tuple(tuple(_round6(float(x)) for x in row) for row in W)
            Wq = np.array([[float(x) for x in row] for row in exact])
            dec = cert.decide(Wq, box, 1.0, rate, budget)
            if dec.verdict is Verdict.REFUTED:   # the sound check found a point the samples missed: a cut
                q = cert.project(np.array(dec.point[0])[None, :])
                Nq = cert.matrices(W, box, v, beta, q)[0]
                consts = np.concatenate([consts, (W + W.T)[None] - Nq])
                dense = np.vstack([dense, q])
                continue
            tried.append(f"headroom {h:g}: {dec.verdict.value} ({dec.cells} cells)")
            last = Synthesis(W=exact, structure=structure, box=tuple(box.tolist()), rate=rate, decision=dec,
                             headroom=h, samples=int(consts.shape[0]), rounds=rounds,
                             seconds=time.perf_counter() - start, norm=float(np.linalg.norm(Wq, 2)))
            if dec.verdict is Verdict.PROVED:
                return Synthesis(W=exact, structure=structure, box=tuple(box.tolist()), rate=rate, decision=dec,
                                 headroom=h, samples=int(consts.shape[0]), rounds=rounds,
                                 seconds=time.perf_counter() - start, norm=float(np.linalg.norm(Wq, 2)))
            break
        else:
            tried.append(f"headroom {h:g}: no W passed the samples in {MAX_ROUNDS} rounds")
    if last is not None:   # unproven: the sound check ran out of cells at every headroom
        return last
    raise DerivationError("observer synthesis: no synthesised W was proved by the certificate on the box "
                          f"{tuple(box.tolist())} rad/s at rate {rate:g} 1/s; tried " + "; ".join(tried))


@functools.lru_cache(maxsize=32)
def _cached(J: sp.ImmutableMatrix, theta: tuple, coords_key: tuple, box: tuple, rate: float,
            structure: str) -> Synthesis:
    from derive.control.certificate import Coordinate

    coords = tuple(Coordinate(*c) for c in coords_key)
    return synthesise(InertiaModel(sp.Matrix(J), coords), box, rate, structure)


def synthesise_for(arm, J: sp.Matrix, theta: tuple[sp.Symbol, ...]) -> Synthesis:
    """The W of an arm with ``w = "auto"``: its stated box and rate, J with its numbers put in."""
    ctl = arm.controller
    coords = joint_coordinates(arm, theta)
    key = tuple((c.index, c.symbol, c.angle, c.lower, c.upper) for c in coords)
    box = tuple(float(x) for x in ctl.max_joint_speed)
    return _cached(sp.ImmutableMatrix(J), tuple(theta), key, box, float(ctl.observer_rate), ctl.observer_structure)


def norm_of(W) -> float:
    """||W||_2 of an exact or float matrix."""
    return float(np.linalg.norm(np.array([[float(x) for x in row] for row in W]), 2)) if len(W) else math.nan
