"""The stated sample-time limits beside the true ones (issue 34, "How it is shown"; ``make corpus``).

derive states, per controller form (MPC eq. 15, DOBC eq. 21-27, NPID eq. 34, MOM) and observer step
(explicit, implicit), MARGIN = 0.9 of the largest sample time [s] at which the linearised sampled
closed loop has spectral radius < 1 at every operating point of its grid
(derive.control.sampling.grid: 48 configurations, 64 for two joints, and the poses its searches join,
times rest, the box's vertices and each joint alone at its bound), bisected to 1 %.

The "true" limit here is the same criterion, the spectral radius of the sampled loop (no
simulation: a 200-sample run of the two-link arm at 60 rad/s looks stable up to 3.8 ms where the
loop grows from 1.3 ms), but

* on a denser set of operating points (:func:`dense_points`): the grid's own configurations and
  FACTOR - 1 times as many more, seeded random within the joint ranges (grid.spans), times the
  grid's speeds and, for the joints whose angle neither J nor G depends on (``cyclic``: a base yaw,
  a vertical lift), their constant spins, each alone at SPIN_FRACTIONS of its bound and several
  together at their bounds: steady motions, where the frozen-time linearisation is exact; and SCREEN
  more seeded configurations at rest (equilibria: exact too; the configuration matters most: J^-1
  sets the observer's and the law's fast modes);
* then a local search (:func:`_climb`) from the CLIMB_STARTS configurations nearest to failing,
  for one that fails below the limit found (random points alone keep finding lower limits: the
  Piper's at-rest 2 / max |eig(W J^-1)| is 5.1 ms over 48 configurations, 1.86 ms over 288, 1.16 ms
  over 2,000 and 1.15 ms over 200,000);
* without the 0.9 margin;
* bisected to TOLERANCE (0.2 %).

The dense set holds derive's grid, so true <= derive's raw figure (up to the bisections' widths)
and true / stated is at most about 1 / 0.9 * 1.01: the ratio measures the grid's sparsity against
the margin, and the 1.5x goal is met by construction unless the stated limit is above the true.
Sampling gives an upper bound of the true limit over the ranges (a point not sampled may fail
sooner). What it cannot measure is the frozen-time linearisation at a point that is not a steady
motion (a joint with J or G depending on it, moving): there "true" is the frozen-time figure as
well (the worst point's ``kind`` says which: "rest" and "spin" are exact, "moving" is frozen-time).
derive's claim is stated <= true: :func:`truth` checks the stated limit stable at every point
(``rho_stated`` < 1), and that the true limit is the edge: rho >= 1 at ABOVE x true at its worst
point (``rho_above``).

Cost (2-core machine, CPU time of the whole command): 3 s for the two-link arm, 21-40 s for the corpus's
6-7 joint arms (9,300-11,600 points), 57 s for Tiago's 8 joints, 165 s and 1,062 MiB for snake12: the
linearisation of the laws at every point (CasADi, about 0.25 ms a point at 7 joints), the whole set's
radii and the local searches take most of it.

``python -m benchmarks.limits_truth ARM.toml [--json OUT]`` prints the table (and writes it as
JSON); benchmarks/corpus.py runs it for every arm after ``derive init``, in a process of its own.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np

FACTOR = 4            # dense configurations per configuration of derive's grid
SCREEN = 4096         # more configurations, at rest only
SEED = 1              # the dense set's random configurations (the grid's own use seed 0)
TOLERANCE = 1.002     # the true limit's bisection: hi / lo at most this (0.2 %)
ABOVE = 1.01          # the true limit is the edge: rho >= 1 at ABOVE x true at its worst point
SPIN_FRACTIONS = (0.25, 0.5, 0.75, 1.0)   # of a cyclic joint's speed bound
MAX_SPIN_SIGNS = 4    # sign patterns of several cyclic joints spinning together (a seeded choice past this)
CYCLIC_SAMPLES = 16   # states at which a cyclic joint's coordinate is moved (cyclic)
CYCLIC_TOL = 1e-12    # J and G unchanged to this, relative to their largest entry
CHUNK = 2048          # points per batch of the exact radii over the dense set (memory)
NEAR = 0.99           # radii over the dense set are exact from this up (below it: stable_bound's bound)
CLIMB_STARTS = 6      # the local search's starts: the dense configurations nearest to failing
CLIMB_ROUNDS = 60     # its rounds at most
CLIMB_STEP = 1e-3     # its last step, of each range's width (its first: 1/8, then 1/32 from a point it reached)
CLIMB_PASSES = 4      # searches (each at the limit the last one left) at most
CLIMB_GAIN = 1.01     # and no more once one lowers the limit by less than this factor
ENTRIES = (("mpc", "explicit"), ("dobc", "explicit"), ("npid", "explicit"), ("mom", "explicit"),
           ("dobc", "implicit"), ("npid", "implicit"))   # MPC and MOM: the same step in both builds
_ORDER = sorted(ENTRIES, key=lambda e: e[0])   # computed a form at a time (_Kept keeps one form's linearisation)


@dataclass(frozen=True)
class Truth:
    """One form and observer step: ``stated`` [s] (derive's SampleLimit.limit), ``raw`` [s] (derive's
    bisected figure on its grid, no margin), ``true`` [s] (dense, no margin, TOLERANCE), ``ratio`` =
    true / stated (nan when either is 0 or inf), ``points`` (dense operating points), ``worst`` (theta,
    theta') unstable first beyond ``true`` and its ``kind`` ("rest", "spin": exact; "moving":
    frozen-time), ``rho_stated``: the largest spectral radius over the dense points at the stated limit
    (< 1: stable there; below NEAR an upper bound of it, derive.control.sampling.radius.stable_bound),
    ``rho_above``: the radius at ABOVE x true at the worst point (>= 1: the edge)."""

    form: str
    observer: str
    stated: float
    raw: float
    true: float
    ratio: float
    points: int
    worst: tuple[tuple[float, ...], tuple[float, ...]] | None
    kind: str
    rho_stated: float
    rho_above: float
    rho_steady: float = float("nan")   # rho_stated over the exact kinds' points only (rest, spin)

    @property
    def label(self) -> str:
        """MPC, DOBC, NPID, MOM, and DOBC-i, NPID-i for the implicit observer step."""
        return self.form.upper() + ("-i" if self.observer == "implicit" else "")

    @property
    def violation(self) -> bool:
        """The stated limit above the true one, or unstable at a dense point (derive's claim broken)."""
        return self.stated > self.true or not self.rho_stated < 1.0

    @property
    def steady_violation(self) -> bool:
        """The stated limit unstable at a steady point (rest or spin), where the frozen-time loop is exact:
        derive's statement false for a motion the arm can hold. A violation at moving points alone compares
        two frozen-time figures (the two-link arm at 60 rad/s, docs/background/equations.md: there the
        generated loop tracks in simulation far beyond both)."""
        return not self.rho_steady < 1.0


def cyclic(d) -> list[int]:
    """The joints (0-based) whose coordinate neither J nor G depends on: a constant spin of them alone is
    a steady motion of the arm. Found numerically (SymPy's free_symbols over J and G took a minute for
    the decimal 7-joint chain): J(theta) and G(theta, theta') at CYCLIC_SAMPLES seeded states, and again
    with coordinate k moved within its range, agree to CYCLIC_TOL of their size."""
    from derive.control.sampling import _loop
    from derive.control.sampling.grid import spans

    loop = _loop(d)
    lo, hi = (np.array([x[i] for x in spans(d)]) for i in (0, 1))
    rng = np.random.default_rng(SEED)
    Q = lo + (hi - lo) * rng.random((CYCLIC_SAMPLES, d.n))
    V = rng.uniform(-1.0, 1.0, (CYCLIC_SAMPLES, d.n))

    def values(Q: np.ndarray) -> np.ndarray:
        return np.hstack([loop.mass(Q).reshape(len(Q), -1), loop.bias(Q, V)[0]])

    ref = values(Q)
    scale = np.abs(ref).max()
    out = []
    for k in range(d.n):
        if hi[k] <= lo[k]:
            continue
        moved = Q.copy()
        moved[:, k] = lo[k] + (hi[k] - lo[k]) * rng.random(CYCLIC_SAMPLES)
        if np.abs(values(moved) - ref).max() <= CYCLIC_TOL * scale:
            out.append(k)
    return out


def _spins(bounds: np.ndarray, joints: list[int], n: int) -> list[np.ndarray]:
    """Speeds [rad/s or m/s] of the cyclic ``joints`` alone (the others at rest) within the box: each
    alone at SPIN_FRACTIONS of its bound and, for several, together at their bounds (signs: all, or
    MAX_SPIN_SIGNS seeded)."""
    joints = [k for k in joints if bounds[k] > 0]
    alone = [f * s * bounds * np.eye(n)[k] for k in joints for s in (1.0, -1.0) for f in SPIN_FRACTIONS]
    signs = []
    if len(joints) > 1:
        patterns = list(np.array(p) for p in np.ndindex(*(2,) * len(joints)))
        if len(patterns) > MAX_SPIN_SIGNS:
            rng = np.random.default_rng(SEED)
            patterns = [patterns[i] for i in sorted(rng.choice(len(patterns), MAX_SPIN_SIGNS, replace=False))]
        for p in patterns:
            v = np.zeros(n)
            v[joints] = 1.0 - 2.0 * p
            signs.append(v)
    return alone + [s * bounds for s in signs]


@dataclass(frozen=True)
class Dense:
    """Operating points (theta, theta') [rad or m, rad/s or m/s], each one's kind (rest, spin,
    moving: module docstring) and the index of its configuration."""

    points: list
    kinds: list
    config: np.ndarray
    cyclic: list      # the cyclic joints (0-based)


def dense_points(d, factor: int = FACTOR, screen: int = SCREEN) -> Dense:
    """The dense operating points of ``d``: derive's grid configurations (its searches' poses joined) and (factor
    - 1) x as many seeded random ones within the joint ranges, times the grid's speeds and the cyclic joints'
    spins; then ``screen`` more seeded configurations at rest."""
    from derive.control.sampling import _grid, limits
    from derive.control.sampling.grid import check_definite, speed_box, speeds, spans

    limits(d)
    g = _grid(d)   # as derive's statements cover it
    Q0 = np.array([q for q, _ in g.points[::g.speeds]], dtype=float)
    s = spans(d)
    lo, hi = np.array([a for a, _, _ in s]), np.array([b for _, b, _ in s])
    rng = np.random.default_rng(SEED)
    Q = np.vstack([Q0, lo + (hi - lo) * rng.random(((factor - 1) * Q0.shape[0], d.n))])
    R = lo + (hi - lo) * rng.random((screen, d.n))
    check_definite(d, np.vstack([Q, R]))
    box = speed_box(d)
    S = list(speeds(box, d.n))
    cyc = cyclic(d)
    if box.bounds is not None and cyc:
        seen = {tuple(np.round(v, 12)) for v in S}
        for v in _spins(np.array(box.bounds, dtype=float), cyc, d.n):
            if tuple(np.round(v, 12)) not in seen:
                seen.add(tuple(np.round(v, 12)))
                S.append(v)
    moving = [k for k in range(d.n) if k not in cyc]
    kinds = ["rest" if not v.any() else "spin" if not v[moving].any() else "moving" for v in S]
    rest = np.zeros(d.n)
    points = [(q, v) for q in Q for v in S] + [(q, rest) for q in R]
    config = np.concatenate([np.repeat(np.arange(len(Q)), len(S)), len(Q) + np.arange(len(R))])
    return Dense(points, [k for _ in Q for k in kinds] + ["rest"] * len(R), config, cyc)


class _Kept:
    """The derivation's SampledLoop with the last form's linearisation at the dense points kept
    (sample_limit, the check at the stated limit and the ranking all ask for it; both observer steps
    of DOBC and NPID linearise the same laws); every other attribute is the loop's."""

    def __init__(self, loop, points) -> None:
        self._loop, self._kept = loop, {}
        self._Q = np.array([q for q, _ in points], dtype=float)
        self._V = np.array([v for _, v in points], dtype=float)

    def __getattr__(self, name: str):
        return getattr(self._loop, name)

    def linearise(self, form: str, Q, DQ) -> dict:
        Q, DQ = np.asarray(Q, dtype=float), np.asarray(DQ, dtype=float)
        if Q.shape != self._Q.shape or not (np.array_equal(Q, self._Q) and np.array_equal(DQ, self._V)):
            return self._loop.linearise(form, Q, DQ)
        if form not in self._kept:   # one form at a time (truth takes each form's two steps in turn), CHUNK
            self._kept = {}          # points at a time: memory
            parts = [self._loop.linearise(form, Q[i:i + CHUNK], DQ[i:i + CHUNK]) for i in range(0, len(Q), CHUNK)]
            self._kept = {form: {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}}
        return self._kept[form]

    def radii(self, form: str, observer: str, dt: float, exact: bool = True, idx=None) -> np.ndarray:
        """The spectral radius at ``dt`` [s] at every dense point (those of ``idx``), CHUNK at a time
        (memory); not ``exact``: where derive.control.sampling.radius.stable_bound proves it below 1, that
        bound instead."""
        from derive.control.sampling import _radii

        L = self.linearise(form, self._Q, self._V)
        idx = np.arange(self._Q.shape[0]) if idx is None else np.asarray(idx, dtype=int)
        return np.concatenate([_radii(self._loop, form, observer, dt, {k: v[idx[i:i + CHUNK]] for k, v in L.items()},
                                      exact) for i in range(0, len(idx), CHUNK)] or [np.zeros(0)])

    def near(self, form: str, observer: str, dt: float) -> np.ndarray:
        """The radii at ``dt`` [s] at every dense point, exact from NEAR up (below it an upper bound:
        stable_bound's, where the eigenvalues would cost most of the time)."""
        rho = self.radii(form, observer, dt, exact=False)
        close = np.flatnonzero(rho >= NEAR)
        rho[close] = self.radii(form, observer, dt, idx=close)
        return rho


def _rho(loop, form: str, observer: str, dt: float, points) -> np.ndarray:
    """The exact spectral radius of the sampled loop at ``dt`` [s] at each of a few ``points``."""
    from derive.control.sampling import _radii

    Q = np.array([q for q, _ in points], dtype=float)
    L = loop.linearise(form, Q, np.array([v for _, v in points], dtype=float))
    return _radii(loop, form, observer, dt, L)


def _climb(loop, form: str, observer: str, dt: float, starts, box: tuple, h0: float = 0.125):
    """A compass search of the configuration, within the joint ranges ``box`` = (lo, hi, axes: the
    coordinates J and G depend on, with a range), for the largest spectral radius at ``dt`` from each of
    ``starts`` ((theta, theta') with theta' held): each round moves each start to the best of its
    neighbours at distance h (of the ranges' widths) along the axes when that is larger, else halves h,
    from ``h0`` down to CLIMB_STEP. Returns the configurations (k x n), the speeds and radii."""
    from derive.control.sampling.grid import compass

    lo, hi, axes = box
    Q = np.array([q for q, _ in starts], dtype=float)
    V = np.array([v for _, v in starts], dtype=float)
    n = Q.shape[1]
    f = _rho(loop, form, observer, dt, list(zip(Q, V)))
    if not axes:
        return Q, V, f

    def values(T: np.ndarray) -> np.ndarray:
        return _rho(loop, form, observer, dt, list(zip(T.reshape(-1, n), np.repeat(V, T.shape[1], axis=0)))) \
            .reshape(T.shape[:2])

    Q, f = compass(values, Q, f, lo, hi, h0, CLIMB_STEP, CLIMB_ROUNDS, axes=axes)
    return Q, V, f


def truth(d, factor: int = FACTOR) -> list[Truth]:
    """Stated against true limits of every form and observer step (ENTRIES) of derivation ``d``: the
    dense points' limit (sample_limit to TOLERANCE), then a local search (:func:`_climb`) from the
    CLIMB_STARTS configurations nearest to failing there for a configuration that fails below it; the
    points it finds join, and the limit is bisected again on them, until a search finds none that
    lowers it by CLIMB_GAIN (at most CLIMB_PASSES)."""
    from derive.control.sampling import _loop, limits, sample_limit

    from derive.control.sampling.grid import spans

    dense = dense_points(d, factor)
    points, kinds = dense.points, dense.kinds
    lo, hi = (np.array([x[i] for x in spans(d)]) for i in (0, 1))
    box = lo, hi, [k for k in range(d.n) if hi[k] > lo[k] and k not in dense.cyclic]
    loop = _Kept(_loop(d), points)
    holds: dict = {}
    out = []
    for form, observer in _ORDER:
        stated = limits(d, observer)[form]
        lim = sample_limit(d, form, observer, points=points, loop=loop, holds=holds, tolerance=TOLERANCE)
        true, worst, kind = lim.raw, lim.worst, kinds[_find(points, lim.worst)] if lim.worst else ""
        found: list = []    # (theta, theta') the searches reached, and their kinds
        found_kinds: list = []
        if 0 < true < math.inf:
            rho = loop.near(form, observer, true)
            starts = [points[i] for i in _firsts(rho, dense.config)]
            start_kinds = [kinds[i] for i in _firsts(rho, dense.config)]
            for k in range(CLIMB_PASSES):
                Q, V, f = _climb(loop, form, observer, true, starts, box, 0.125 if k == 0 else 1 / 32)
                if f.max() < 1.0:
                    break
                starts = list(zip(Q, V))
                found += starts
                found_kinds += start_kinds
                sub = sample_limit(d, form, observer, points=found, loop=loop, tolerance=TOLERANCE)
                if not sub.raw < true:
                    break
                gain, (true, worst, kind) = true / sub.raw, (sub.raw, sub.worst, found_kinds[_find(found, sub.worst)])
                if gain < CLIMB_GAIN:
                    break
        ratio = true / stated.limit if 0 < stated.limit < math.inf and 0 < true < math.inf else math.nan
        rho_stated = rho_steady = math.nan
        if 0 < stated.limit < math.inf:
            more = _rho(loop, form, observer, stated.limit, found) if found else np.zeros(0)
            every = np.concatenate([loop.near(form, observer, stated.limit), more])
            rho_stated = float(every.max())
            steady = np.array([k in STEADY for k in list(kinds) + found_kinds], dtype=bool)
            rho_steady = float(every[steady].max()) if steady.any() else 0.0
        rho_above = math.nan
        if worst is not None and 0 < true < math.inf:
            rho_above = float(_rho(loop, form, observer, ABOVE * true, [tuple(np.array(x) for x in worst)])[0])
        out.append(Truth(form, observer, stated.limit, stated.raw, true, ratio, len(points) + len(found), worst,
                         kind, rho_stated, rho_above, rho_steady))
    return sorted(out, key=lambda t: ENTRIES.index((t.form, t.observer)))


STEADY = ("rest", "spin")   # the kinds of point where the frozen-time loop is exact


def _firsts(rho: np.ndarray, config: np.ndarray) -> list[int]:
    """The CLIMB_STARTS points of largest radius ``rho`` (_Kept.near), one per configuration (at its worst
    speed)."""
    out, seen = [], set()
    for i in np.argsort(rho)[::-1]:
        if config[i] not in seen:
            seen.add(config[i])
            out.append(int(i))
            if len(out) == CLIMB_STARTS:
                break
    return out


def _find(points, worst) -> int:
    """The index of the point ``worst`` ((theta, theta') as SampleLimit.worst gives it) in ``points``."""
    q, v = np.array(worst[0]), np.array(worst[1])
    return next(i for i, (a, b) in enumerate(points) if np.array_equal(a, q) and np.array_equal(b, v))


def _ms(x: float) -> str:
    return "-" if x == 0 or math.isnan(x) else "inf" if math.isinf(x) else f"{x * 1e3:.4g}"


def cell(rows: list[Truth]) -> str:
    """The corpus column: per form "stated / true (ratio)" in ms, a violation marked."""
    return "; ".join(f"{t.label} {_ms(t.stated)} / {_ms(t.true)} ({t.ratio:.3g})"
                     + (" ABOVE" if t.steady_violation else " above (moving)" if t.violation else "") for t in rows)


def main(argv: list[str]) -> int:
    """``ARM.toml [--json OUT]``: the table on stdout (and JSON in OUT); exit 3 when a stated limit is
    above the true one or unstable at a point (an error exits 1, as Python does)."""
    import derive
    from benchmarks import table
    from derive.jsonio import dumps

    start = time.process_time()
    d = derive.derive(derive.load_arm(argv[0]))
    rows = truth(d)
    cpu = time.process_time() - start
    print(table(("form", "stated ms", "true ms", "ratio", "points", "worst kind", "rho at stated", "rho at 1.01 true"),
                [(t.label, _ms(t.stated), _ms(t.true), f"{t.ratio:.3f}", t.points, t.kind, f"{t.rho_stated:.6f}",
                  f"{t.rho_above:.6f}") for t in rows]))
    print(f"{d.n} joints, cyclic {[k + 1 for k in cyclic(d)]}, {cpu:.1f} s CPU")
    bad = [t.label for t in rows if t.violation]
    if bad:
        print(f"VIOLATION: stated limit above the true one (or unstable at a dense point): {', '.join(bad)}",
              file=sys.stderr)
    if argv[1:2] == ["--json"]:
        with open(argv[2], "w", encoding="utf-8") as f:
            f.write(dumps({"cpu_seconds": cpu, "joints": d.n, "cyclic": [k + 1 for k in cyclic(d)],
                           "sample_time": d.arm.simulation.sample_time, "observer": d.arm.controller.observer,
                           "rows": [asdict(t) for t in rows]}))
    return 3 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
