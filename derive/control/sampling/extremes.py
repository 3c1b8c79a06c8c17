"""The configurations a seeded grid can miss: the poses where a mode of the arm at rest is fastest.

derive.control.sampling.grid draws 48 seeded configurations past two joints (8 per coordinate for one or
two). A sampled loop's limit is set where a mode is fastest, and a random draw can miss that pose by far:
my3 (3 joints, vertical) is most unstable upright, where gravity's rate is 193 1/s^2 against 139 at the
grid's fastest; there NPID with the implicit observer step is unstable from 47.2 ms, while the grid gave
52.8 ms and derive stated 0.9 of it, 47.55 ms: above the truth (issue 34, found by
benchmarks/limits_truth.py's denser check; the Piper's DOBC limit at rest, 2 / max eig(W J^-1), is 5.1 ms
over the 48 configurations and 1.15 ms over 200,000). Three rates at rest are maximised within the joint
ranges, each from the two fastest of the grid's configurations and SCREEN seeded ones, by a compass search
(each round tries every coordinate +-h of its range and moves to the best that is faster, else halves h;
as derive.control.sampling.grid searches for a singular J):

* gravity: the largest real part of the eigenvalues of -J^-1 dG/dtheta at rest (1/s^2: the square of
  an inverted pendulum's rate; the upright pose);
* damping: the largest real part of the eigenvalues of J^-1 dG/dtheta' at rest (1/s: viscous friction
  and the motors' back-EMF over the inertia, which the law compensates within a sample);
* the observer: the largest real part of the eigenvalues of J^-1 W (1/s: eq. 24's rate, whose
  2 / rate bounds the forward-Euler observer step).

A configuration found joins the grid, at every speed of the box, when its rate is above the grid's
fastest by more than JOIN (else the grid already holds the pose to within that).
"""
from __future__ import annotations

import numpy as np

from derive.control.sampling.grid import Grid, check_definite, compass, spans

JOIN = 1.01        # a found rate must exceed the grid's fastest by this factor to join
STARTS = 2         # the fastest screened configurations each search starts from
ROUNDS = 60        # compass rounds at most per search
SCREEN = 1024      # seeded configurations within the ranges screened for the searches' starts
SEED = 2
FIRST_STEP = 0.125   # of each coordinate's range
LAST_STEP = 1.0 / 512


def _gravity(loop, Q: np.ndarray) -> np.ndarray:
    """max Re eig(-J^-1 dG/dtheta) at rest at configurations Q (P x n) [1/s^2]."""
    J = loop.mass(Q)
    _, dG = loop.bias(Q, np.zeros_like(Q))
    return np.linalg.eigvals(-np.linalg.solve(J, dG[:, :, :loop.n])).real.max(axis=1)


def _damping(loop, Q: np.ndarray) -> np.ndarray:
    """max Re eig(J^-1 dG/dtheta') at rest at configurations Q (P x n) [1/s]: viscous friction and, with
    voltage input, the back-EMF over the inertia (a light wrist's fast mode, compensated by the law)."""
    J = loop.mass(Q)
    _, dG = loop.bias(Q, np.zeros_like(Q))
    return np.linalg.eigvals(np.linalg.solve(J, dG[:, :, loop.n:])).real.max(axis=1)


def _observer(loop, Q: np.ndarray) -> np.ndarray:
    """max Re eig(J^-1 W) at configurations Q (P x n) [1/s]."""
    J = loop.mass(Q)
    return np.linalg.eigvals(np.linalg.solve(J, np.broadcast_to(loop.W, J.shape))).real.max(axis=1)


def _ascend(rate, starts: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """The fastest configuration a compass search (derive.control.sampling.grid.compass) from ``starts``
    (k x n) finds within [lo, hi]."""
    n = starts.shape[1]
    q, f = compass(lambda T: rate(T.reshape(-1, n)).reshape(T.shape[:2]), starts, rate(starts), lo, hi,
                   FIRST_STEP, LAST_STEP, ROUNDS)
    i = int(f.argmax())
    return q[i], float(f[i])


def with_extremes(d, loop, g: Grid) -> Grid:
    """``g`` with the configurations of the module docstring joined (each at every speed of ``g``); raises
    SpecError when J is singular at one (derive.control.sampling.grid.check_definite)."""
    n = d.n
    configs = np.array([q for q, _ in g.points[::g.speeds]])
    s = spans(d)
    lo = np.array([a for a, _, _ in s])
    hi = np.array([b for _, b, _ in s])
    if not np.any(hi > lo):
        return g
    found = []
    rng = np.random.default_rng(SEED)
    screen = np.vstack([configs, lo + (hi - lo) * rng.random((SCREEN, n))])
    for rate in (_gravity, _damping, _observer):
        values = rate(loop, screen)
        top = np.argsort(-values, kind="stable")[:STARTS]
        q, value = _ascend(lambda Q: rate(loop, Q), screen[top], lo, hi)
        if value > 0 and value > JOIN * float(values[:configs.shape[0]].max()) \
                and not any(np.allclose(q, other, rtol=0.0, atol=1e-9) for other in found):
            found.append(q)
    if not found:
        return g
    extra = np.array(found).reshape(-1, n)
    check_definite(d, extra)
    return g.join(extra)
