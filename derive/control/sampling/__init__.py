"""The largest sample time of each generated controller form (MPC eq. 15, DOBC eq. 21-27, NPID eq. 34,
MOM: the generalized-momentum observer of derive.control.momentum).

The sampled closed loop is the plant J theta'' + G = B u (eq. 12) under a zero-order hold on u,
and the controller exactly as generated, in one of two discretisations (``derive generate
--observer``):

* ``explicit`` (the default, forward Euler): u_k from the law at the sample, then the form's state is stepped by
  forward Euler: the NPID integral int_e + dt e_k, the observer z + dt W y with
  J y = G - B u_k - W theta'_k - z_k.
* ``implicit``: DOBC first takes the backward-Euler step of eq. (21) over the interval that just
  ended, with the new measurement and the voltage u_{k-1} held over it,
  (J(theta_k) + dt W) y = G(theta_k, theta'_k) - B u_{k-1} - W theta'_k - z_{k-1},
  z_k = z_{k-1} + dt W y, and then applies u_k = u* - B^-1 (z_k + W theta'_k) (state: z and the
  applied u). NPID applies u = u* + B^-1 W x, (J + dt W) x = J xi, xi = C^-1 (e' + K2 e + K1 int e):
  the PID form with W replaced by W_dt = W (J + dt W)^-1 J, the gain the backward-Euler observer
  applies (derive.codegen.kernels); the integral stays forward Euler.

MOM is stepped the same way in both builds: u_k = u* - B^-1 K (J theta'_k - m_k), then
m_{k+1} = m_k + dt (B u_k + C^T theta'_k - g - F theta'_k + K (J theta'_k - m_k)) with the applied
u_k (forward Euler): the observer's own rate is the diagonal K, so dt K < 2 bounds it by itself, and
the sampled loop below gives the limit of the whole (the predictive law included).

Why the ordering matters: with s = z + W theta' = B dhat, the forward-Euler loop telescopes to
s_k = s_{k-1} + W (theta'_k - theta'_{k-1}) + dt W J^-1 (G - B u_{k-1} - s_{k-1}), and u holds the
velocity feedback -B^-1 W theta' over a sample: the error e' = B d - s steps by I - dt W J^-1, stable
only for dt < 2 / |lambda(W J^-1)| (2 J / w for one joint). A backward-Euler step of z that still
uses the measurement taken before the step ((J + dt W) y = G - B u_k - W theta'_k - z_k) leaves that
feedback as it is and the limit where it was (12.9 against 13.0 ms on the default arm;
``_Z_ONLY``). Evaluating eq. (21) at the end of the step, the new theta'_k included, makes the
estimate's own step implicit: the velocity feedback becomes W (J + dt W)^-1 J theta' and the error
steps by (I + dt W J^-1)^-1, stable for every dt when W J^-1 has its eigenvalues in the right
half-plane. What limits the sample time then is the predictive law (and, for NPID, the
proportional part of W_dt K2 e, about J K2 / dt at large dt).

Linearised at an operating point (theta0, theta0', reference y_d = C theta0, y_d' = C theta0',
y_d'' = 0, u0 the law's output): x = (theta, theta'), c the form's state,

    x_{k+1} = Phi x_k + Gamma u_k,  (Phi, Gamma) = ZOH of (df/dx, df/du) over dt,
    u_k = U_x x_k + U_c c_k,   c_{k+1} = S_x x_k + S_c c_k + S_u u_k   (explicit, and MOM),

(for the implicit DOBC the loop's state is (x_k, z_{k-1}, u_{k-1})), and the loop is stable at that
point when the spectral radius of its transition matrix is below 1. For MOM the transition is taken
in the residual's coordinates (x, r), r = K (J theta' - m), at the sample it maps from and the one it
maps to (``_residual``): m moves with J(theta) theta' at a moving point, and in m's own coordinates
the frozen-time linearisation has a mode of that motion's rate which the loop does not have
(r' = K (B d - r) for every state); it gave my3 (3 joints, box 3-5 rad/s) rho = 1 + 6.9 dt at every
dt, "MOM 0 ms", where the simulated loop tracks. The limit is the largest dt (found by doubling, then
bisection to 1 %) for which that holds at every operating point of derive.control.sampling.grid: configurations
within the joint limits times the speeds of the speed box (controller.max_joint_speed, else the URDF's
velocity limits, else at rest only; the box's vertices and each joint alone at its bound); the figure
reported is 0.9 of it: the stated margin for the frozen-time linearisation over a finite grid. The grid
holds the poses where a rate at rest is fastest (derive.control.sampling.extremes), and after the bisection
the rest poses are searched for one where the loop is unstable at the limit found; such a pose joins the
grid and the limits are bisected again (derive.control.sampling.climb).
A loop already unstable at DT_MIN (1e-7 s) has no limit in that search: when its continuous
linearisation (the limit dt -> 0 of every discretisation, :func:`_continuous_rate`) is stable at
every point, the limit is "below 1e-7 s" (extreme gains: T2 = 1e-20 puts the MPC poles at
-1.25e20 1/s), else there is none (the linearised loop is unstable as dt -> 0: not a sampling limit).
The Jacobians are exact (CasADi's automatic differentiation of the laws' graphs,
derive.control.sampling.linear_loop), evaluated in double precision at every point in one call.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np

from derive.control.sampling.extremes import with_extremes
from derive.control.sampling.climb import rest_poses, screen, unstable_rest_poses
from derive.control.sampling.grid import Grid, check_definite, grid, spans
from derive.control.sampling.linear_loop import SampledLoop
from derive.control.sampling.radius import spectral_radius
from derive.control.sampling.transition import _Z_ONLY, _continuous_rate, _radii, _transition
from derive.control.sampling.zoh import bound, zoh

FORMS = ("mpc", "dobc", "npid", "mom")
SHARED = ("mpc", "mom")   # the same step in both discretisations: one limit
OBSERVERS = ("explicit", "implicit")   # derive generate --observer
ENTRIES = tuple((o, f) for o in OBSERVERS for f in FORMS if o == "explicit" or f not in SHARED)   # distinct limits
MARGIN = 0.9
DT_MAX = 1.0      # s: no limit is reported beyond it
DT_MIN = 1e-7
DT_START = 1e-5   # s: where the doubling starts (after the loop is checked stable at DT_MIN)
TOLERANCE = 1.01  # the bisection's end: hi / lo at most this (1 %)
ACTIVE = 16       # at least this many points (and 5 %) are followed through the bisection
GROWTH = 4.0      # the bracket's growth per step from DT_START
SUBSET = 128      # about this many points (every k-th of the grid) carry the search; the whole grid checks its result
PROBE = 1.25      # the rest poses' radii are compared at this multiple of the limit (past it the fast mode's shows)
WHOLE = 4096      # the whole grid's radii this many points at a time (a caller's 20,000 points took 1.9 GB at once)


@dataclass(frozen=True)
class SampleLimit:
    """form, observer discretisation, limit [s] (``MARGIN`` of the largest stable dt; inf when stable
    up to DT_MAX; 0 when unstable at DT_MIN), raw [s], points: operating points checked, worst: the
    (theta, theta') that failed first beyond the raw limit (None when none did); ``below``: unstable at
    DT_MIN (raw = DT_MIN) while the continuous linearised loop is stable at every point (its fastest
    mode needs a shorter sample time: the limit is below DT_MIN); without it a limit of 0 means the
    linearised loop is unstable as dt -> 0 (not a sampling limit)."""

    form: str
    observer: str
    limit: float
    raw: float
    points: int
    worst: tuple[tuple[float, ...], tuple[float, ...]] | None
    below: bool = False   # unstable at DT_MIN though the continuous loop is stable at every point: limit < DT_MIN


def operating_points(d) -> list[tuple[np.ndarray, np.ndarray]]:
    """The operating points (theta, theta') of derivation ``d``: derive.control.sampling.grid (within the
    joint limits, speeds up to the speed box; SpecError for a singular J there)."""
    return list(_grid(d).points)


def _grid(d) -> Grid:
    """derive.control.sampling.grid's points with the fastest poses joined (derive.control.sampling.extremes)."""
    return _cached(_GRIDS, d, "grid", lambda: with_extremes(d, _loop(d), grid(d)))


def sample_limit(d, form: str, observer: str = "explicit", points=None, loop: SampledLoop | None = None,
                 holds: dict | None = None, tolerance: float = TOLERANCE) -> SampleLimit:
    """The largest stable sample time of ``form`` (FORMS) with the observer discretisation ``observer``
    (OBSERVERS; the module docstring), with the stated margin (``loop``: the derivation's SampledLoop
    when the caller has it; ``holds``: the plant's zero-order holds of the search's subsets per (dt, A,
    Bu), shared with the other forms' searches on the same points, :func:`limits`; ``tolerance``: the
    bisection ends when its bracket hi / lo is at most this). Raises ValueError for an unknown form or
    discretisation."""
    if form not in FORMS or observer not in OBSERVERS + (_Z_ONLY,):
        raise ValueError(f"sample_limit: expected a form of {FORMS} and an observer of {OBSERVERS}, "
                         f"got {form!r}, {observer!r}")
    pts = operating_points(d) if points is None else points
    lp = _loop(d) if loop is None else loop
    # both discretisations linearise the same laws at the default points: once per derivation and form
    loop, L = _linear(d, form) if points is None else (lp, _linearise(lp, form, pts))

    rows: list = [None, L]   # the linearisation at the points of the last idx (the same subset or
                             # active set is asked for at every dt of a bracket or bisection)
    # the plant's zero-order hold of a subset, per (dt, A, Bu): the forms' searches ask for the same dt on
    # the same points, and A, Bu are often the same bits for every form (the plant's linearisation at u0,
    # which is B^-1 G for every law at these points); the oldest go beyond zoh.HOLDS_BYTES
    holds = {} if holds is None else holds

    def radii(dt: float, idx: np.ndarray | None = None, rank: bool = False) -> np.ndarray:
        """The radii at dt (of the points idx, else all) as derive.control.sampling.radius.spectral_radius
        gives them without ``exact``: the search compares them with 1 and takes the worst of the
        failing ones; ``rank``: every one exact when one fails (the active set ranks them). At
        DT_MIN the loop's radii lie within about 1e-7 of 1, where stable_bound proves none: their
        eigenvalues come first (``eigen_first``)."""
        if idx is None and len(pts) > WHOLE:   # memory: the transitions of WHOLE points at a time
            parts = ({k: v[i:i + WHOLE] for k, v in L.items()} for i in range(0, len(pts), WHOLE))
            return np.concatenate([spectral_radius(_transition(loop, form, observer, dt, part), False, rank,
                                                   dt <= DT_MIN) for part in parts])
        if idx is not None and rows[0] is not idx:
            rows[:] = idx, {k: v[idx] for k, v in L.items()}
        M = L if idx is None else rows[1]
        hold = None
        if idx is not None:   # the whole grid's are not asked for twice (each at a bisection's result)
            key = (dt, M["A"].shape, M["A"].tobytes(), M["Bu"].tobytes())
            hold = holds.get(key)
            if hold is None:
                hold = holds[key] = zoh(M, dt)
                bound(holds)
        return spectral_radius(_transition(loop, form, observer, dt, M, hold), False, rank, dt <= DT_MIN)

    def done(lo: float, bad: int | None) -> SampleLimit:
        worst = None if bad is None else tuple(tuple(float(x) for x in v) for v in pts[bad])
        return SampleLimit(form, observer, MARGIN * lo, lo, len(pts), worst)

    # the search runs on a subset of the points (every k-th, SUBSET of them), and the whole grid is checked
    # at its result; points that fail there join the subset and the search starts again (it ends: the
    # subset grows each time, up to the whole grid). Stable up to DT_MAX is checked on the whole grid.
    P = len(pts)
    # points where another form's search failed on this grid join from the start (the fast modes are
    # often the same: the box's corners, a light joint's damping)
    hints = _cached(_HINTS, d, "hints", set) if points is None else set()
    subset, hi = _union(P, np.arange(0, P, max(1, P // SUBSET)), np.array(sorted(hints), dtype=int)), None
    while True:
        rho = radii(DT_MIN, subset)
        if rho.max() >= 1.0:   # the continuous loop unstable (not a sampling limit), or a limit below DT_MIN
            bad = int(subset[rho.argmax()])
            if _continuous_rate(loop, form, L).max() < 0.0:
                worst = tuple(tuple(float(x) for x in v) for v in pts[bad])
                return SampleLimit(form, observer, 0.0, DT_MIN, P, worst, below=True)
            return done(0.0, bad)
        # a bracket: growing by GROWTH from DT_START (or, after a restart, halving from the dt the whole
        # grid failed at), then bisection over the points nearest to failing at its upper end
        if hi is None:
            safe, dt = DT_MIN, DT_START
            while hi is None and safe < DT_MAX:
                rho = radii(dt, subset, rank=True)
                if rho.max() >= 1.0:
                    hi = dt
                else:
                    safe, dt = dt, min(dt * GROWTH, DT_MAX)
            if hi is None:
                failed = _first_failure(radii, P, DT_START, DT_MAX)
                if failed is None:
                    return SampleLimit(form, observer, math.inf, math.inf, P, None)
                subset = _union(P, subset, failed)
                hints.update(failed.tolist())
                continue
        else:
            safe = hi / 2
            while (rho := radii(safe, subset)).max() >= 1.0 and safe > DT_MIN:
                hi, safe = safe, max(safe / 2, DT_MIN)
            rho = radii(hi, subset, rank=True)
        lo, bad = safe, int(subset[rho.argmax()])
        active = subset[np.argsort(rho)[-max(ACTIVE, len(rho) // 20):]]
        while hi / lo > tolerance:
            mid = math.sqrt(lo * hi)
            r = radii(mid, active)
            if r.max() < 1.0:
                lo = mid
            else:
                hi, bad = mid, int(active[r.argmax()])
        rho = radii(lo)
        if rho.max() < 1.0:
            return done(lo, bad)
        hi = lo
        subset = _union(P, subset, np.flatnonzero(rho >= 1.0))
        hints.update(np.flatnonzero(rho >= 1.0).tolist())


def _union(P: int, *parts: np.ndarray) -> np.ndarray:
    """The sorted distinct indices of ``parts`` (each within 0..P-1): np.union1d's result, by a mask
    (np.union1d's np.unique imports numpy.ma, about 10 ms of ``derive show``)."""
    mask = np.zeros(P, dtype=bool)
    for part in parts:
        mask[part] = True
    return np.flatnonzero(mask)


def _first_failure(radii, P: int, start: float, stop: float) -> np.ndarray | None:
    """The points unstable at the first dt of the doubling from ``start`` to ``stop`` where any point
    of the whole grid is (None: stable at every one)."""
    dt = start
    while True:
        rho = radii(dt)
        if rho.max() >= 1.0:
            return np.flatnonzero(rho >= 1.0)
        if dt >= stop:
            return None
        dt = min(dt * 2, stop)


_LIMITS: dict = {}
_GRIDS: dict = {}
_LINEAR: dict = {}
_HINTS: dict = {}
_LOOPS: dict = {}


def _cached(store: dict, d, key, make):
    """``make()`` cached per derivation object (the entry keeps ``d`` alive, so ids stay unique)."""
    hit = store.get((id(d), key))
    if hit is not None and hit[0] is d:
        return hit[1]
    out = make()
    store[(id(d), key)] = (d, out)
    return out


def _loop(d) -> SampledLoop:
    """The derivation's SampledLoop (one per derivation, shared by the forms and discretisations)."""
    return _cached(_LOOPS, d, "loop", lambda: SampledLoop(d))


def limits(d, observer: str = "explicit") -> dict[str, SampleLimit]:
    """The sample-time limit of every form (FORMS) with the observer discretisation ``observer`` (OBSERVERS;
    ValueError for another), on the grid with the rest poses where a form's loop is least stable joined
    (:func:`_settled`); cached per derivation (MPC has no observer and MOM steps the same in both: their limits
    are shared)."""
    if observer not in OBSERVERS:
        raise ValueError(f"limits: expected an observer of {OBSERVERS}, got {observer!r}")
    return _cached(_LIMITS, d, "settled", lambda: _settled(d))[observer]


def _linearise(loop: SampledLoop, form: str, points) -> dict:
    """``loop.linearise`` of ``form`` at the operating points ``points`` ((theta, theta') pairs)."""
    return loop.linearise(form, np.array([q for q, _ in points], dtype=float),
                          np.array([dq for _, dq in points], dtype=float))


def _linear(d, form: str) -> tuple[SampledLoop, dict]:
    """The derivation's loop and ``form``'s linearisation at the grid's points (cached per derivation and form)."""
    return _cached(_LINEAR, d, form, lambda: (_loop(d), _linearise(_loop(d), form, operating_points(d))))


def _on_grid(d, loop: SampledLoop) -> dict[str, dict[str, SampleLimit]]:
    """Every form's limit in both discretisations on the current grid (_grid)."""
    holds: dict = {}   # the zero-order holds the forms' searches share (sample_limit), dropped after them
    own = {(o, form): sample_limit(d, form, o, loop=loop, holds=holds) for o, form in ENTRIES}
    return {o: {f: own[o, f] if (o, f) in own else own["explicit", f] for f in FORMS} for o in OBSERVERS}


def _settled(d) -> dict[str, dict[str, SampleLimit]]:
    """:func:`_on_grid`, then for each form and discretisation a search of the rest poses for one where the
    loop's radius reaches 1 at its limit (derive.control.sampling.climb; none when every rest pose of the
    grid is stable at PROBE x the limit). The poses found join the grid, their linearisations the cached
    ones, and a limit is bisected again when a joined point is unstable at it."""
    loop = _loop(d)
    s = spans(d)
    lo, hi = np.array([a for a, _, _ in s]), np.array([b for _, b, _ in s])
    out = _on_grid(d, loop)
    pts = _grid(d).points
    rest, S = rest_poses(pts), screen(lo, hi)
    Q = np.vstack([np.array([pts[i][0] for i in rest], dtype=float).reshape(-1, d.n), S])
    found: list[np.ndarray] = []
    screened: dict = {}   # the screen's linearisation per form
    for o, form in ENTRIES:
        lim, L = out[o][form], _linear(d, form)[1]
        if not 0.0 < lim.raw < math.inf or lim.below or \
                _radii(loop, form, o, PROBE * lim.raw, {k: v[rest] for k, v in L.items()}).max() < 1.0:
            continue
        if form not in screened:
            screened[form] = loop.linearise(form, S, np.zeros_like(S))
        rho = _radii(loop, form, o, PROBE * lim.raw, {k: np.concatenate([v[rest], screened[form][k]])
                                                       for k, v in L.items()})

        def radius(T, dt, form=form, o=o):
            return _radii(loop, form, o, dt, loop.linearise(form, T, np.zeros_like(T)))
        found += [q for q in unstable_rest_poses(radius, Q, rho, lim.raw, PROBE * lim.raw, lo, hi, loop.moving)
                  if not any(np.allclose(q, p, rtol=0.0, atol=1e-9) for p in found)]
    if found:
        _join(d, loop, out, np.array(found))
    return out


def _join(d, loop: SampledLoop, out: dict, extra: np.ndarray) -> None:
    """Join the configurations ``extra`` to the grid (at every speed; SpecError where J is singular) and their
    linearisations to the cached ones; bisect again each limit of ``out`` a joined point is unstable at."""
    check_definite(d, extra)
    before = len(_grid(d).points)
    grown = _grid(d).join(extra)
    _GRIDS[(id(d), "grid")] = (d, grown)
    holds: dict = {}
    for form in FORMS:
        lp, L = _linear(d, form)
        add = _linearise(lp, form, grown.points[before:])
        _LINEAR[(id(d), form)] = (d, (lp, {k: np.concatenate([v, add[k]]) for k, v in L.items()}))
    for o, form in ENTRIES:
        lim = out[o][form]
        add = {k: v[before:] for k, v in _LINEAR[(id(d), form)][1][1].items()}
        if 0.0 < lim.raw < math.inf and _radii(loop, form, o, lim.raw, add).max() >= 1.0:
            out[o][form] = sample_limit(d, form, o, loop=loop, holds=holds)
        else:
            out[o][form] = replace(lim, points=len(grown.points))
    for form in SHARED:
        out["implicit"][form] = out["explicit"][form]
