"""The operating points the sample-time analysis linearises at, inside the arm's stated ranges.

Configurations lie within each joint's limits (derive.control.certificate.inertia.joint_coordinates, the
same spans the observer certificate covers): a revolute joint over its range [lower, upper], a
continuous joint, a revolute joint without limits or one whose range spans a turn or more over
one turn (-pi, pi] (J repeats there), a prismatic joint over its travel in metres (at 0 m when
its input states no travel: there is no range to take). A range of zero width (lower = upper,
which some URDFs write for "none") counts as no range.

Speeds cover the speed box: the arm file's ``controller.max_joint_speed``, else the velocity
limits its URDF states (a joint without one is held at rest), else none, and then the grid is at
rest only and every statement says so. Points at speed: every vertex of the box (a seeded
choice of 8 past three joints) and each joint alone at its bound, both signs.

Every configuration is also checked for J(theta) being positive definite: a configuration where
it is singular cannot be controlled (eq. 15 and the observer's L = W J^-1 need J^-1) and is
refused with the pose named. The grid's points are checked, then the smallest normalised
eigenvalue lambda_min(J) / lambda_max(J) found on 4096 seeded samples within the ranges is
minimised locally (a compass search within the ranges) from its three worst samples: a singularity
inside the ranges is found to 1e-9, one outside them is no error. The search moves only on a relative
improvement above CREEP (1e-6): a ratio that creeps down by less per step cannot reach 1e-9 within the
search's rounds (the iiwa's ill-conditioned J, ratio 2.3e-4, crept along theta2 for all 400 rounds, 0.15 s of
every command; now 42).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from derive.control.certificate.inertia import joint_coordinates
from derive.dynamics.sx import batched
from derive.errors import Problem, SpecError

SINGULAR = 1e-9        # lambda_min(J) / lambda_max(J) below this: J is singular there
SEARCH = 4096          # seeded samples searched for a singular configuration
MAX_VERTICES = 8       # box vertices past three joints: a seeded choice of this many
CREEP = 1e-6           # the singular-J search moves only on a relative improvement above this (module docstring)


@dataclass(frozen=True)
class SpeedBox:
    """The speed box the grid covers: ``bounds`` (n, rad/s or m/s; 0 for a joint held at rest)
    and where it comes from; ``bounds`` None: no box, the grid is at rest."""

    bounds: tuple[float, ...] | None
    source: str     # "controller.max_joint_speed", "the URDF's velocity limits", or "" (none)

    def describe(self) -> str:
        """Where the speeds come from, for the statements (header, show, check)."""
        if self.bounds is None:
            return ("at rest only (no speed box: the arm file states no controller.max_joint_speed and its input "
                    "no velocity limits)")
        values = ", ".join(f"{v:g}" for v in self.bounds)
        return f"at rest and up to {self.source} [{values}] (the box's vertices and each joint alone at its bound)"


def speed_box(d) -> SpeedBox:
    """The speed box of derivation ``d`` (module docstring)."""
    stated = d.arm.controller.max_joint_speed
    if stated is not None:
        return SpeedBox(tuple(float(x) for x in stated), "controller.max_joint_speed")
    chain = d.arm.chain
    velocity = [j.limits.velocity for j in chain.joints]
    if any(v is not None and v > 0 for v in velocity):
        return SpeedBox(tuple(float(v) if v is not None and v > 0 else 0.0 for v in velocity),
                        "the URDF's velocity limits")
    return SpeedBox(None, "")


def spans(d) -> list[tuple[float, float, bool]]:
    """(low, high, periodic) per joint coordinate: the range the grid covers (module docstring);
    low = high = 0 for a prismatic joint without a travel."""
    out = []
    for c in joint_coordinates(d.arm, d.theta):
        span = c.span
        if span is None:
            out.append((0.0, 0.0, False))
        elif c.angle and (span[1] - span[0] >= 2 * math.pi or (c.lower is None and c.upper is None)):
            out.append((-math.pi, math.pi, True))
        else:
            out.append((span[0], span[1], False))
    return out


def _axis(low: float, high: float, periodic: bool, count: int) -> np.ndarray:
    if periodic:
        return np.linspace(low, high, count, endpoint=False)
    return np.array([low]) if high <= low else np.linspace(low, high, count)


def configurations(d, count: int = 48, seed: int = 0) -> np.ndarray:
    """The grid's configurations (P x n): every combination of 8 values per coordinate for
    n <= 2, else the middle of the ranges and ``count`` - 1 seeded random points within them."""
    s = spans(d)
    if d.n <= 2:
        return np.array(list(itertools.product(*[_axis(lo, hi, per, 8) for lo, hi, per in s])), dtype=float)
    rng = np.random.default_rng(seed)
    lo = np.array([a for a, _, _ in s])
    hi = np.array([b for _, b, _ in s])
    home = np.where((lo <= 0) & (0 <= hi), 0.0, (lo + hi) / 2)
    return np.vstack([home[None, :], lo + (hi - lo) * rng.random((count - 1, d.n))])


def speeds(box: SpeedBox, n: int, seed: int = 0) -> np.ndarray:
    """Rest, the box's vertices (at most MAX_VERTICES) and each joint alone at +-its bound (S x n)."""
    out = [np.zeros(n)]
    if box.bounds is None:
        return np.array(out)
    s = np.array(box.bounds)
    rng = np.random.default_rng(seed)
    if n <= 20:   # the same seeded choice as ever, of indices into the 2^n vertices (never listed whole)
        picks = sorted(rng.choice(2 ** n, MAX_VERTICES, replace=False)) if 2 ** n > MAX_VERTICES else range(2 ** n)
    else:
        picks = sorted({int(x) for x in rng.integers(0, 2 ** n, MAX_VERTICES, dtype=np.uint64)})
    # vertex i of itertools.product((1, -1), repeat=n): bit n-1-k of i set means joint k at -1
    verts = [np.array([-1.0 if (int(i) >> (n - 1 - k)) & 1 else 1.0 for k in range(n)]) * s for i in picks]
    alone = [sign * s[i] * np.eye(n)[i] for i in range(n) if s[i] > 0 for sign in (1.0, -1.0)]
    if n == 1:
        alone = []   # the vertices already are
    seen, unique = set(), []
    for v in out + verts + alone:
        key = tuple(np.round(v, 12))
        if key not in seen:
            seen.add(key)
            unique.append(v)
    return np.array(unique)


@dataclass(frozen=True)
class Grid:
    """Operating points (theta, theta') of the sample-time analysis: every configuration times
    every speed; ``box`` the speed box they cover."""

    points: tuple[tuple[np.ndarray, np.ndarray], ...]
    configs: int
    speeds: int
    box: SpeedBox

    def describe(self) -> str:
        return (f"{len(self.points)} operating points: {self.configs} configurations within the joint limits, "
                f"speeds {self.box.describe()}")

    def join(self, extra: np.ndarray) -> "Grid":
        """This grid with the configurations ``extra`` (k x n) joined, each at every speed of the grid."""
        speeds = [dq for _, dq in self.points[:self.speeds]]
        points = self.points + tuple((q, dq) for q in np.asarray(extra, dtype=float) for dq in speeds)
        return Grid(points, self.configs + len(extra), self.speeds, self.box)


def grid(d, count: int = 48, seed: int = 0) -> Grid:
    """The operating points of derivation ``d``; raises SpecError when J is singular at a
    configuration within the joint ranges (module docstring)."""
    Q = configurations(d, count, seed)
    check_definite(d, Q)
    box = speed_box(d)
    S = speeds(box, d.n, seed)
    points = tuple((q, dq) for q in Q for dq in S)
    return Grid(points, Q.shape[0], S.shape[0], box)


# -- J positive definite within the ranges ---------------------------------------------------------
_MASS: dict = {}


def mass_function(d):
    """J of derivation ``d`` at a batch of configurations (P x n -> P x n x n), double precision
    (one per derivation: the sample-time analysis evaluates the same)."""
    hit = _MASS.get(id(d))
    if hit is not None and hit[0] is d:
        return hit[1]
    f = _mass(d)
    _MASS[id(d)] = (d, f)
    return f


def _mass(d):
    f = batched(list(d.theta), list(d.J))
    n = d.n

    def call(Q: np.ndarray) -> np.ndarray:
        return f(Q).reshape(Q.shape[0], n, n)

    return call


def _ratio(J: np.ndarray) -> np.ndarray:
    """lambda_min / lambda_max of symmetric matrices (P x n x n); -inf where J is not finite."""
    ok = np.isfinite(J).all(axis=(-1, -2))
    out = np.full(J.shape[0], -np.inf)
    if ok.any():
        lam = np.linalg.eigvalsh(J[ok])
        out[ok] = lam[:, 0] / np.maximum(np.abs(lam[:, -1]), 1e-300)
    return out


_CHECKED: dict = {}


def check_definite(d, extra: np.ndarray | None = None) -> None:
    """Raise SpecError naming a configuration within the joint ranges where J is singular (or not
    positive definite); ``extra``: configurations that must be checked too (the grid's). Searched
    once per derivation (module docstring)."""
    hit = _CHECKED.get(id(d))
    mass = mass_function(d)
    s = spans(d)
    lo = np.array([a for a, _, _ in s])
    hi = np.array([b for _, b, _ in s])
    if hit is None or hit[0] is not d:
        rng = np.random.default_rng(1)
        Q = lo + (hi - lo) * rng.random((SEARCH, d.n))
        Q = np.vstack([Q, (lo + hi)[None, :] / 2]) if extra is None else np.vstack([Q, extra])
        r = _ratio(mass(Q))
        worst = Q[np.argsort(r)[:3]]
        found = _refine(mass, worst, r[np.argsort(r)[:3]], lo, hi)
        _CHECKED[id(d)] = (d, True)
    else:
        found = None
        if extra is not None:
            r = _ratio(mass(extra))
            k = int(np.argmin(r))
            found = (extra[k], float(r[k])) if r[k] < SINGULAR else None
    if found is not None:
        raise SpecError(d.arm.source, [_problem(d, *found)], title="J(theta) singular within the joint limits of")


def compass(values, q: np.ndarray, f: np.ndarray, lo: np.ndarray, hi: np.ndarray, first: float, last: float,
            rounds: int, maximise: bool = True, axes=None, stop=None,
            rtol: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A compass search from every row of ``q`` (k x n, values ``f``) at once, within [lo, hi]: each round
    ``values`` takes the k x 2m x n neighbours at distance h (of each range's width) along ``axes`` (every
    coordinate when None) and returns their k x 2m values; each start moves to its best neighbour when
    that is better by more than ``rtol`` of its value (larger with ``maximise``, else smaller), else halves
    its h, from ``first`` until every h is below ``last``, ``rounds`` rounds, or ``stop(f)``. Returns the
    points and their values."""
    q, f = q.copy(), np.asarray(f, dtype=float).copy()
    k, n = q.shape
    width = np.where(hi > lo, hi - lo, 0.0)
    h = np.full(k, first)
    eye = np.eye(n) if axes is None else np.eye(n)[axes]
    steps = np.vstack([eye, -eye])                                                 # 2m x n
    for _ in range(rounds):
        if h.max() < last or (stop is not None and stop(f)):
            break
        trial = np.clip(q[:, None, :] + h[:, None, None] * steps[None] * width, lo, hi)   # k x 2m x n
        r = values(trial)
        best = r.argmax(axis=1) if maximise else r.argmin(axis=1)
        pick = r[np.arange(k), best]
        better = pick > f + rtol * np.abs(f) if maximise else pick < f - rtol * np.abs(f)
        q[better] = trial[np.arange(k), best][better]
        f[better] = pick[better]
        h[~better] /= 2
    return q, f


def _refine(mass, starts: np.ndarray, values: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """The smallest lambda_min / lambda_max found from ``starts`` by a compass search within [lo, hi]
    (:func:`compass`, from 1/8 of the ranges down to 1e-8, moving on relative improvements above CREEP):
    (theta, ratio) when below SINGULAR, else None."""
    n = starts.shape[1]
    q, f = compass(lambda T: _ratio(mass(T.reshape(-1, n))).reshape(T.shape[:2]), starts, values, lo, hi,
                   0.125, 1e-8, 400, maximise=False, stop=lambda f: f.min() < SINGULAR, rtol=CREEP)
    i = int(f.argmin())
    return (q[i], float(f[i])) if f[i] < SINGULAR else None


def _angle(x: float) -> str:
    """An angle in radians, with the multiple of pi/4 it is (to 1e-4) named."""
    k = round(x / (math.pi / 4))
    if abs(x - k * math.pi / 4) < 1e-4 and k != 0:
        names = {1: "pi/4", 2: "pi/2", 3: "3 pi/4", 4: "pi"}
        name = names.get(abs(k), f"{abs(k)} pi/4")
        return f"{'-' if k < 0 else ''}{name} ({x:.5g} rad)"
    return f"{x:.5g} rad"


def _problem(d, q: np.ndarray, ratio: float) -> Problem:
    """The problem, named by the fields of the joints whose coordinates J depends on (their limits
    or bodies are what to change), the pose in their coordinates."""
    coords = joint_coordinates(d.arm, d.theta)
    free = set().union(*(x.free_symbols for x in d.J))
    deps = [c for c in coords if c.symbol in free]
    parts = [f"{c.symbol} = {_angle(float(q[c.index])) if c.angle else f'{float(q[c.index]):.5g} m'}" for c in deps]
    pose = ", ".join(parts) or "every configuration"
    joints = d.arm.chain.joints
    field = ", ".join(joints[c.index].field for c in deps) if deps else joints[0].field
    return Problem(f"{field} (the inertia matrix J(theta) within the joint limits)",
                   "J positive definite at every configuration the joints can reach (eq. 15 and L = W J^-1 need "
                   "J^-1): limits that exclude a singular configuration, or inertia where a joint moves none",
                   f"J singular at {pose} (smallest / largest eigenvalue {max(ratio, 0.0):.2g})")
