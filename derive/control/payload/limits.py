"""The largest payload each controller form holds at a sample time (issue 38's statement).

For a form (derive.control.sampling.FORMS) and observer discretisation, at the arm file's sample
time dt, the largest payload mass m such that the sampled closed loop, linearised as
derive.control.sampling does (zero-order hold, every operating point of derive.control.grid) but
with the plant carrying the payload (derive.control.payload.loop), has every eigenvalue inside the
unit circle at every operating point and for every centre of mass the search tries: the ``[payload]``
ball's centre, its six axis points and its eight diagonal points (com_radius from the centre; the
centre alone when com_radius is 0), with the payload's shape (its inertia about the centre of mass
scales with the mass, derive.model.payload).

The mass is found by doubling from START (or the stated mass) up to CAP, then bisection to 5 %; the
search runs on a subset of the grid (every k-th point, about SUBSET of them, with every centre of
mass), the whole grid checks its result, and points that fail there join the subset (as the
sample-time search does). The figure stated is MARGIN of the largest stable mass found: the margin
for the frozen-time linearisation over a finite grid and a finite set of centres of mass. A loop
unstable with no payload at dt holds none (limit 0: dt is beyond the form's sample-time limit).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from derive.control import sampling
from derive.control.payload.loop import PayloadPlant, plant_rows
from derive.control.zoh import zoh
from derive.control.radius import spectral_radius
from derive.model.payload import PayloadRange, body_values

MARGIN = 0.9
START = 0.5       # kg: the first mass tried when the file states none above it
CAP_FACTOR = 64   # the search stops at CAP_FACTOR x max(stated mass, START): "at least" that
SUBSET = 96       # grid points (every k-th) the search runs on
TOLERANCE = 1.05  # bisection's relative bracket
HOLDS = 64        # zero-order holds kept for the other forms' searches


@dataclass(frozen=True)
class PayloadLimit:
    """form, observer, dt [s]; limit [kg] (MARGIN x raw; 0: unstable with no payload at dt); raw [kg]
    the largest stable mass found; capped: stable up to raw = the search's cap (the limit is at least
    that); worst: (theta, theta', com in the tip link's frame) that failed first above raw (None if none
    did); points: operating points x centres of mass checked; centres: centres of mass tried."""

    form: str
    observer: str
    dt: float
    limit: float
    raw: float
    capped: bool
    worst: tuple | None
    points: int
    centres: int = 1


def centres(rng: PayloadRange) -> list[tuple[float, float, float]]:
    """The centres of mass tried (module docstring), in the tip link's frame."""
    c = np.array(rng.com, dtype=float)
    if rng.com_radius <= 0:
        return [tuple(c)]
    dirs = [np.eye(3)[i] * s for i in range(3) for s in (1, -1)]
    dirs += [np.array(v) / math.sqrt(3) for v in ((1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1),
                                                   (-1, 1, 1), (-1, 1, -1), (-1, -1, 1), (-1, -1, -1))]
    return [tuple(c)] + [tuple(c + rng.com_radius * v) for v in dirs]


class _Rows:
    """Every operating point with every centre of mass, linearised once: the loop's L (nominal laws),
    the nominal dG and the unit payload's J_p, dG_p, per form."""

    def __init__(self, d, rng: PayloadRange) -> None:
        self.d = d
        self.loop = sampling._loop(d)
        self.pts = sampling.operating_points(d)
        self.coms = centres(rng)
        unit = rng.inertia_at(1.0) if rng.mass > 0 or rng.inertia is None else None
        self.pis = np.array([body_values(d.arm.chain, 1.0, c, unit) for c in self.coms])
        self.Q = np.array([q for q, _ in self.pts], dtype=float)
        self.DQ = np.array([dq for _, dq in self.pts], dtype=float)
        C = len(self.coms)
        self.plant = PayloadPlant(d)
        self.Jp, self.dGp = self.plant.unit(np.repeat(self.Q, C, axis=0), np.repeat(self.DQ, C, axis=0),
                                            np.tile(self.pis, (len(self.pts), 1)))
        self._forms: dict[str, tuple[dict, np.ndarray]] = {}
        self._holds: dict = {}   # (dt, mass, rows) -> the loaded plant's zero-order hold, shared by the forms

    def form(self, form: str) -> tuple[dict, np.ndarray]:
        if form not in self._forms:
            L = self.loop.linearise(form, self.Q, self.DQ)
            dG = self.loop._plant[2]
            C = len(self.coms)
            self._forms[form] = ({k: np.repeat(v, C, axis=0) for k, v in L.items()}, np.repeat(dG, C, axis=0))
        return self._forms[form]

    def radii(self, form: str, observer: str, dt: float, mass: float, idx: np.ndarray) -> np.ndarray:
        L, dG = self.form(form)
        Li = {k: v[idx] for k, v in L.items()}
        if mass == 0.0:
            return spectral_radius(sampling._transition(self.loop, form, observer, dt, Li), False)
        key = (dt, mass, idx.tobytes())
        hit = self._holds.get(key)
        if hit is None:
            A, Bu = plant_rows(Li["J"], dG[idx], self.loop.B, self.Jp[idx], self.dGp[idx], mass)
            hit = self._holds[key] = zoh({"A": A, "Bu": Bu}, dt)
            while len(self._holds) > HOLDS:
                self._holds.pop(next(iter(self._holds)))
        return spectral_radius(sampling._transition(self.loop, form, observer, dt, Li, hit), False)


_ROWS: dict = {}


def _rows(d, rng: PayloadRange) -> _Rows:
    key = (id(d), rng)
    hit = _ROWS.get(key)
    if hit is None or hit.d is not d:
        _ROWS.clear()
        hit = _ROWS[key] = _Rows(d, rng)
    return hit


def payload_limit(d, form: str, observer: str, dt: float, rng: PayloadRange) -> PayloadLimit:
    """The largest payload ``form`` with ``observer`` holds at sample time ``dt`` [s] over the centres of
    mass of ``rng`` (module docstring). Raises ValueError for an unknown form, discretisation or dt <= 0."""
    if form not in sampling.FORMS or observer not in sampling.OBSERVERS or not dt > 0:
        raise ValueError(f"payload_limit: expected a form of {sampling.FORMS}, an observer of {sampling.OBSERVERS} "
                         f"and dt > 0, got {form!r}, {observer!r}, {dt!r}")
    rows = _rows(d, rng)
    C, P = len(rows.coms), len(rows.pts)
    every = np.arange(P * C)

    def expand(points: np.ndarray) -> np.ndarray:
        return (points[:, None] * C + np.arange(C)[None, :]).reshape(-1)

    def done(raw: float, bad: int | None, capped: bool = False) -> PayloadLimit:
        worst = None
        if bad is not None:
            q, dq = rows.pts[bad // C]
            worst = (tuple(map(float, q)), tuple(map(float, dq)), tuple(map(float, rows.coms[bad % C])))
        return PayloadLimit(form, observer, dt, MARGIN * raw, raw, capped, worst, P * C, C)

    zero = rows.radii(form, observer, dt, 0.0, every[::C])
    if zero.max() >= 1.0:
        return done(0.0, int(np.argmax(zero)) * C)
    subset = expand(np.arange(0, P, max(1, P // SUBSET)))
    cap = CAP_FACTOR * max(rng.mass, START)
    lo, hi, bad = 0.0, None, None
    m = max(rng.mass, START)
    while True:
        if hi is None:                       # doubling on the subset
            while m <= cap:
                r = rows.radii(form, observer, dt, m, subset)
                if r.max() >= 1.0:
                    hi, bad = m, int(subset[np.argmax(r)])
                    break
                lo, m = m, 2 * m
            if hi is None:
                r = rows.radii(form, observer, dt, lo, every)
                if r.max() < 1.0:
                    return done(lo, None, capped=True)
                hi, bad = lo, int(np.argmax(r))
                subset = np.union1d(subset, expand(np.unique(np.flatnonzero(r >= 1.0) // C)))
                lo = 0.0
        while hi / max(lo, 1e-12) > TOLERANCE and hi - lo > 1e-6:
            mid = math.sqrt(lo * hi) if lo > 0 else hi / 2
            r = rows.radii(form, observer, dt, mid, subset)
            if r.max() < 1.0:
                lo = mid
            else:
                hi, bad = mid, int(subset[np.argmax(r)])
        if lo == 0.0:
            return done(0.0, bad)
        r = rows.radii(form, observer, dt, lo, every)
        if r.max() < 1.0:
            return done(lo, bad)
        hi, bad = lo, int(np.argmax(r))
        subset = np.union1d(subset, expand(np.unique(np.flatnonzero(r >= 1.0) // C)))
        lo = 0.0


def payload_limits(d, dt: float, rng: PayloadRange) -> dict[str, dict[str, PayloadLimit]]:
    """{observer: {form: PayloadLimit}} for both discretisations (MPC and MOM step alike in both: one
    search each, shared)."""
    out: dict[str, dict[str, PayloadLimit]] = {"explicit": {}, "implicit": {}}
    for form in sampling.FORMS:
        out["explicit"][form] = payload_limit(d, form, "explicit", dt, rng)
        out["implicit"][form] = (out["explicit"][form] if form in sampling.SHARED
                                 else payload_limit(d, form, "implicit", dt, rng))
    return out
