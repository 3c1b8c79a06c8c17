"""A starter controller designed for a payload range (``derive init --payload MASS``, issue 38).

Why a payload breaks the nominal starter. The controller's model carries no payload. With the
disturbance observer, the inner loop of joint i behaves, in one joint's terms (the velocity-based
DOB of Sariyildiz and Ohnishi, IEEE TIE 62(3), 2015), like a first-order lag of bandwidth omega r,
r = J_nominal / J_true <= 1, around which the predictive law (eq. 15) closes a PD loop with gains
K1, K2 scaled by the same r; the characteristic polynomial

    s^3 + r (omega + K2) s^2 + r (K1 + omega K2) s + r omega K1

is stable iff r (omega + K2)(K1 + omega K2) > omega K1: the observer's rate under the payload,
omega r, must stay above about K1 / K2. On a wrist with no rotor inertia in its model the payload
is hundreds of times the link's own inertia about the axis (UR10, 12.5 kg 0.1 m off the flange:
J_p,66 / J_66 = 559; the generalised eigenvalues of (J + J_p, J) reach 589 over the ranges), so
the nominal starter's W = omega Jbar, whose rates on the wrist are those of the shoulder, loses the
wrist to a fraction of a kilogram. Scaling all of W up does not help: the shoulder's rates, not the
wrist's, then set the forward-Euler limit 2 / lambda_max(W J^-1), and the sample time runs out first
(UR10: 0.37 kg at 0.1 ms with W x 64).

The design: W = omega Jbar + rho Jp_bar, Jp_bar the mean of the payload's joint-space inertia J_p
at the stated mass over the operating points and the centres of mass the statement tries
(derive.control.payload.limits). The added term is shaped like the payload itself, coupling
included, so that under the full payload the observer's rates are about rho in the directions the
payload dominates, while with no payload they rise by the ratio above: rho is a rate [1/s], and the
sample time bounds it through rho lambda_max(J^-1 Jp_bar) dt <~ 0.81 (the starter's rule, 0.45 x
0.9 x 2 / rate). The momentum observer's K_i (diagonal) is raised likewise to rho (Jbar_ii +
Jp_bar,ii) / Jbar_ii, within the same bound. Adding a positive semidefinite term keeps the observer
certificate (2 W - J' grows). With the diagonal of J_p alone (no coupling) the UR10 held 6-7.6 kg
at 0.1 ms; the full Jp_bar holds 17 kg at rho = 100 1/s.

The search: for each round sample time from the nominal one down to MIN_SAMPLE_TIME, rho is the
largest the bound allows; the file is then restated (the sample time refitted to half of each
sampled-loop limit derive show states) and the payload limits of DOBC, NPID and MOM computed there.
The limits grow as the sample time shrinks, so the longest sample time that holds the range is found
from the shortest sample time's figures: the limits grow about linearly with rho, so the longest
sample time whose rho reaches the range's need is tried first, then its neighbours.

A range no sample time down to MIN_SAMPLE_TIME holds on the whole speed box is then tried on a
smaller one: the largest factor on the velocity limits (SPEED_FLOOR to 1, by bisection) on which the
shortest sample time's design holds it is written to max_joint_speed, and the file says so, with what
the whole box held. What limits such an arm (the IRB 120-like) is a slow continuous mode at the box's
corner, every joint at its velocity limit with the payload off-axis (its gyroscopic coupling); it does
not move with the sample time or T2. Failing that too, the file says the range is not held.

Nominal payload: none. The inertia ratio the observer must span is (J + J_p) / J whatever payload
the model carries (the midpoint or the largest only move the span), and a nominal model heavier than
the arm speeds the observer's true rate up with no payload, which the sample time must then cover;
the empty arm is what a tool changer most often runs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from derive.control.payload.limits import PayloadLimit, _rows, payload_limit
from derive.model.payload import PayloadRange

OBSERVER_FORMS = ("dobc", "npid", "mom")   # the forms whose payload limit the design must cover (MPC has no observer)
RATE_DT = 0.81          # fastest observer rate x sample time (the starter's HEADROOM 0.45 x 0.9 x 2)
MIN_SAMPLE_TIME = 2e-5  # s: the design's shortest sample time (50 kHz); the file states it when below 0.1 ms
SAFETY = 1.1            # rho is first raised to this x the rho the range needs, scaled from the shortest's
SPEED_FLOOR = 0.1       # the smallest factor on the velocity limits the design tries for the speed box
SPEED_STEPS = 4         # bisections of that factor (to 1/16 of the interval)
DIGITS = 4              # significant digits of W's and K's entries as written


@dataclass(frozen=True)
class PayloadDesign:
    """The designed starter: rho [1/s] (W = omega Jbar + rho Jp_bar; 0: the nominal starter holds the range),
    the gain (derive.control.starter.StarterGain, sample time refitted), the momentum gains K [1/s], the
    payload limits at its sample time (form -> PayloadLimit, forward-Euler step), whether they cover the
    range, the designs tried, the designed file's Derivation, and the speed box's factor on the velocity
    limits (< 1 when the range holds only on a smaller box, with what the full box held)."""

    rate: float
    gain: object
    momentum_gain: tuple[float, ...]
    limits: dict[str, PayloadLimit]
    holds: bool
    tries: int
    derivation: object = field(default=None, compare=False)   # the designed file's Derivation
    speed_scale: float = 1.0   # the factor on the velocity limits of the file's speed box (1: the limits)
    full_speed: float | None = None   # kg: what the design holds at the full speed box, when it scaled the box

    def held(self) -> float:
        """The smallest payload limit of the observer forms [kg]."""
        return min(self.limits[f].limit for f in OBSERVER_FORMS)


def _round(x: float) -> float:
    return float(f"{x:.{DIGITS}g}")


def ladder(start: float, floor: float = MIN_SAMPLE_TIME) -> list[float]:
    """Round sample times (1, 2, 2.5, 4, 5 x 10^k) from ``start`` [s] down to ``floor``, longest first."""
    out, k = [], math.floor(math.log10(start)) + 1
    while 5.0 * 10.0 ** k >= floor * (1 - 1e-12):
        out += [float(f"{m * 10.0 ** k:.3g}") for m in (5.0, 4.0, 2.5, 2.0, 1.0)]
        k -= 1
    return [x for x in out if floor * (1 - 1e-12) <= x <= start * (1 + 1e-12)]


class _Shape:
    """The nominal J at the statement's operating points and Jp_bar at the stated mass."""

    def __init__(self, d, rng: PayloadRange, W0, K0) -> None:
        rows = _rows(d, rng)
        J = rows.form("dobc")[0]["J"]
        self.Li = np.linalg.inv(np.linalg.cholesky((J + np.swapaxes(J, 1, 2)) / 2))
        Jp = rng.mass * rows.Jp.mean(axis=0)
        self.Jp = (Jp + Jp.T) / 2
        Jm = J.mean(axis=0)
        self.ratio = (np.diag(Jm) + np.diag(self.Jp)) / np.diag(Jm)
        self.W0, self.K0 = np.array(W0, dtype=float), np.array(K0, dtype=float)

    def gains(self, rho: float, dt: float) -> tuple[np.ndarray, tuple[float, ...]]:
        W = np.array([[_round(x) for x in row] for row in self.W0 + rho * self.Jp])
        K = np.minimum(np.maximum(self.K0, rho * self.ratio), RATE_DT / dt)
        return (W + W.T) / 2, tuple(_round(x) for x in K)

    def rates(self, W: np.ndarray) -> tuple[float, float]:
        lam = np.linalg.eigvalsh(np.einsum("pab,bc,pdc->pad", self.Li, W, self.Li))   # eigenvalues of W J^-1
        return float(lam[:, 0].min()), float(lam[:, -1].max())

    def rate_for(self, dt: float) -> float:
        """The largest rho [1/s] whose W's fastest rate is within RATE_DT / dt (0: none is)."""
        top = RATE_DT / dt
        if self.rates(self.gains(0.0, dt)[0])[1] > top:
            return 0.0
        lo, hi = 0.0, 1.0
        while self.rates(self.gains(hi, dt)[0])[1] <= top:
            lo, hi = hi, 2 * hi
        while hi / max(lo, 1e-300) > 1.01:
            mid = math.sqrt(lo * hi) if lo > 0 else hi / 2
            lo, hi = (mid, hi) if self.rates(self.gains(mid, dt)[0])[1] <= top else (lo, mid)
        return lo


def design(gain, d, base_k: tuple[float, ...], rng: PayloadRange,
           restate: Callable[..., tuple[object, object]], tick: Callable[[str], None] | None = None) -> PayloadDesign:
    """The payload design (module docstring). ``gain``: the nominal starter gain (fitted to its limits),
    ``d`` its Derivation; ``base_k``: the momentum gains it goes with [1/s]; ``restate(gain, K, scale=1.0) ->
    (gain refitted to the stated limits of the file with W = gain.W, K and the speed box at ``scale`` x the
    velocity limits, its Derivation)``; ``tick(what)``: called as each design is tried (progress)."""
    tick = tick or (lambda what: None)
    observer = getattr(gain, "observer", "explicit")
    lims = {f: payload_limit(d, f, observer, gain.sample_time, rng) for f in OBSERVER_FORMS}
    nominal = PayloadDesign(0.0, gain, tuple(base_k), lims, min(x.limit for x in lims.values()) >= rng.mass, 1)
    if nominal.holds:
        return nominal
    shape = _Shape(d, rng, gain.W, base_k)
    times = ladder(min(gain.sample_time, getattr(gain, "explicit_time", None) or gain.sample_time))
    tried: dict[int, PayloadDesign] = {}

    def attempt(i: int, full: bool = False) -> PayloadDesign | None:
        if i not in tried:
            dt = times[i]
            rho = shape.rate_for(dt)
            if rho <= 0:
                return None
            tick(f"sample time {dt * 1e6:g} us, rho {rho:.3g} 1/s")
            W, K = shape.gains(rho, dt)
            lo, hi = shape.rates(W)
            g = replace(gain, W=tuple(tuple(float(x) for x in row) for row in W), rates=(lo, hi), sample_time=dt,
                        observer_limit=0.9 * 2.0 / hi, momentum_limit=0.9 * 2.0 / max(K), observer="explicit",
                        explicit_time=None, floor=False, payload_rate=rho)
            g, dd = restate(g, K)
            out: dict[str, PayloadLimit] = {}
            for f in OBSERVER_FORMS:            # the weakest first: a miss stops the others
                out[f] = payload_limit(dd, f, "explicit", g.sample_time, rng)
                if out[f].limit < rng.mass:
                    break
            holds = len(out) == len(OBSERVER_FORMS) and min(x.limit for x in out.values()) >= rng.mass
            if not holds and full:
                out.update({f: payload_limit(dd, f, "explicit", g.sample_time, rng) for f in OBSERVER_FORMS if f not in out})
            tried[i] = PayloadDesign(rho, g, K, out, holds, 1 + len(tried) + 1, dd)
        return tried[i]

    last = attempt(len(times) - 1, full=True) if times else None
    if last is None:
        return nominal
    if not last.holds:
        slower = _slower(last, rng, restate, tick)
        return replace(slower or last, tries=1 + len(tried) + (slower.tries if slower else 0))
    # The limits grow about linearly with rho (UR10: 5.9, 8.7, 17 kg at rho = 30, 50, 100 1/s): the longest
    # sample time whose rho reaches SAFETY x the shortest's rho scaled to the range is tried first, then
    # longer ones while they hold and shorter ones until one does.
    need = SAFETY * last.rate * rng.mass / max(last.held(), 1e-12)
    good = len(times) - 1
    i = next((j for j in range(len(times)) if shape.rate_for(times[j]) >= need), good)
    step = -1 if (attempt(i) or last).holds else 1
    while 0 <= i < good:
        got = attempt(i)
        if got is not None and got.holds:
            good = i
            if step > 0:
                break
        elif step < 0:
            break
        i += step
    return replace(tried[good], tries=1 + len(tried))


def _slower(pd: PayloadDesign, rng: PayloadRange, restate, tick) -> PayloadDesign | None:
    """``pd`` (the shortest sample time's design, which does not hold the range) on the largest speed box,
    SPEED_STEPS bisections of the factor on the velocity limits, on which DOBC, NPID and MOM hold it; None when
    not even SPEED_FLOOR of the limits does. The observer certificate of W holds on a smaller box too."""
    def at(scale: float) -> PayloadDesign:
        tick(f"speed box {scale:.3g} x the velocity limits")
        g, dd = restate(pd.gain, pd.momentum_gain, scale)
        out: dict[str, PayloadLimit] = {}
        for f in OBSERVER_FORMS:            # a miss stops the others (only a design that holds is kept)
            out[f] = payload_limit(dd, f, "explicit", g.sample_time, rng)
            if out[f].limit < rng.mass:
                break
        holds = len(out) == len(OBSERVER_FORMS) and min(x.limit for x in out.values()) >= rng.mass
        return PayloadDesign(pd.rate, g, pd.momentum_gain, out, holds, 1, dd, scale, pd.held())

    lo, hi, best, tries = SPEED_FLOOR, 1.0, None, 0
    first = at(lo)
    tries += 1
    if not first.holds:
        return None
    best = first
    for _ in range(SPEED_STEPS):
        mid = (lo + hi) / 2
        got = at(mid)
        tries += 1
        if got.holds:
            lo, best = mid, got
        else:
            hi = mid
    return replace(best, tries=tries)


def describe(pd: PayloadDesign, rng: PayloadRange) -> list[str]:
    """Comment lines for the starter file: what the design holds and how it was made."""
    parts = ", ".join(f"{f.upper()} {pd.limits[f].limit:.3g} kg" for f in OBSERVER_FORMS)
    dt = pd.gain.sample_time
    if pd.holds and pd.speed_scale < 1.0:
        verdict = (f"holds the whole [payload] range ({rng.mass:g} kg) on a speed box of {pd.speed_scale:.3g} x the "
                   f"velocity limits (max_joint_speed; on the whole box it holds {pd.full_speed:.3g} kg at most, at the "
                   f"shortest sample time the design tries, {MIN_SAMPLE_TIME * 1e3:g} ms)")
    elif pd.holds:
        verdict = f"holds the whole [payload] range ({rng.mass:g} kg)"
    else:
        verdict = (f"does NOT hold the whole [payload] range ({rng.mass:g} kg): {pd.held():.3g} kg at most, at the "
                   f"shortest sample time the design tries ({MIN_SAMPLE_TIME * 1e3:g} ms) and down to {SPEED_FLOOR:g} x "
                   "the velocity limits; lower the payload, or give the wrist joints' rotor inertia")
    how = ("# The nominal starter's W and momentum gains hold it unchanged" if pd.rate == 0 else
           f"# W = omega Jbar + rho Jp_bar, rho = {pd.rate:.4g} 1/s, Jp_bar the payload's joint-space inertia at "
           f"{rng.mass:g} kg (mean over the ranges and the ball); K_i raised alike; sample time {dt * 1e3:.3g} ms"
           + (" (below 0.1 ms: what this payload on this arm's light wrist needs)" if dt < 1e-4 * (1 - 1e-12) else ""))
    return ["# Designed for [payload] (derive.control.payload.design).", how + ".",
            f"# At sample_time the linearised sampled loop {verdict}",
            f"# (largest payload, worst centre of mass in the ball: {parts}; 0.9 of the largest stable).",
            "# The controller's model carries no payload: the observer absorbs it (derive show and check state it)."]
