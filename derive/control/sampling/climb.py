"""The rest poses a grid misses where the sampled loop itself is least stable (issue 34).

derive.control.sampling.extremes joins the poses where one of three rates at rest is fastest. A form's
limit is set where its sampled loop's spectral radius first reaches 1, and that can be where two
modes meet rather than where either is fastest: the Tiago torso + arm's DOBC is unstable at rest from
1.217 ms at a pose with two wrist joints at their limits (+-2.09 rad), while the grid's worst
rest pose gives 1.373 ms and derive stated 0.9 of it, 1.236 ms: above the truth at a point where the
linearisation is exact (benchmarks/limits_truth.py). No rate is faster there than at the grid's poses
by more than 0.2 %.

So after each form's bisection on the grid (limit ``raw``, before the margin), the rest poses are
searched (derive.control.sampling._settled): the grid's rest poses and SCREEN seeded ones, with each
coordinate at its lower bound, its upper bound or between (the worst poses sit on the range box's faces:
the Tiago's has three coordinates at their limits), are ranked by their radius at PROBE x raw (past a
pose's own limit its fast mode's growth shows how far below raw that limit is; at raw every stable pose's
radius is its slowest mode's, about 1 - 1e-3 whatever the pose), and a compass search
(derive.control.sampling.grid.compass) from the STARTS first maximises that radius along the coordinates
J or G depends on. A pose found unstable at JOIN_AT x raw joins the grid (at every speed of it), and each
limit that a joined point fails is bisected again (a pose unstable only between 0.95 and 1 x raw leaves the
stated 0.9 x raw true there, and is not worth a new bisection: the Z1's MPC and DOBC-i by 3-5 %, 0.6 s). No search is made for a limit at which every rest pose of the
grid is stable at PROBE x raw.

On the Tiago this states DOBC 1.103 ms (true 1.217 ms, benchmarks/limits_truth.py) and adds about
1 s of CPU to its 2.4 s of limits (both observer steps); 0.1-0.3 s on the 7-joint corpus arms, where it
finds no pose.
At rest the frozen-time linearisation is the loop's own (an equilibrium); the search is local (the
margin covers what it misses: the pose it finds on the Tiago is unstable from 1.234 ms, the worst known
from 1.206 ms), and points in motion are left to the grid (their figures are frozen-time).
"""
from __future__ import annotations

import numpy as np

from derive.control.sampling.grid import compass

STARTS = 1            # poses each search starts from (the grid's and the screen's nearest to failing)
FIRST_STEP = 0.125    # of each coordinate's range
LAST_STEP = 1.0 / 32
ROUNDS = 16           # compass rounds at most per search
JOIN_AT = 0.95        # a pose joins when the loop is unstable there at this fraction of the grid's limit: the grid
                      # missed it by more than half the stated margin (a smaller miss leaves the statement true there)
SCREEN = 64           # seeded rest poses screened beside the grid's for the starts, each coordinate at its lower
SEED = 3              # bound, its upper bound or uniform between (a third each: the worst poses sit on the faces)


def screen(lo: np.ndarray, hi: np.ndarray, count: int = SCREEN, seed: int = SEED) -> np.ndarray:
    """``count`` seeded configurations within [lo, hi] (count x n), each coordinate at lo, at hi or uniform
    between with a third's chance each: the range box's faces, edges and corners among its inside."""
    rng = np.random.default_rng(seed)
    U, X = rng.random((count, lo.size)), lo + (hi - lo) * rng.random((count, lo.size))
    return np.where(U < 1 / 3, lo, np.where(U < 2 / 3, hi, X))


def rest_poses(points) -> np.ndarray:
    """Indices of the operating points (theta, theta') at rest (theta' = 0)."""
    return np.array([i for i, (_, dq) in enumerate(points) if not np.any(np.asarray(dq, dtype=float))], dtype=int)


def unstable_rest_poses(radius, Q: np.ndarray, rho: np.ndarray, dt: float, probe: float, lo: np.ndarray,
                        hi: np.ndarray, axes) -> list[np.ndarray]:
    """The configurations at rest where ``radius(T, JOIN_AT * dt)`` (the spectral radii of one form's sampled
    loop at the rest poses T, P x n) reaches 1, ``dt`` the grid's limit: a compass search maximising the radius at ``probe``
    from the STARTS poses of ``Q`` (k x n) with the largest ``rho`` (their radii at probe), along ``axes``
    (the coordinates J or G depends on) within [lo, hi] per coordinate (one with lo = hi is held). Empty
    when the search ends at none."""
    axes = [k for k in axes if hi[k] > lo[k]]
    if Q.shape[0] == 0 or not axes:
        return []
    top = np.argsort(-rho, kind="stable")[:STARTS]
    n = Q.shape[1]
    q, _ = compass(lambda T: radius(T.reshape(-1, n), probe).reshape(T.shape[:2]), Q[top], rho[top], lo, hi,
                   FIRST_STEP, LAST_STEP, ROUNDS, axes=axes)
    f = radius(q, JOIN_AT * dt)
    return [q[i] for i in range(q.shape[0]) if f[i] >= 1.0]
