"""A starter controller designed for a payload range (``derive init --payload MASS``, issue 38).

Why a payload breaks the nominal starter, and what is raised. The controller's model carries no
payload. With the disturbance observer, the inner loop of joint i behaves, in one joint's terms
(the velocity-based DOB of Sariyildiz and Ohnishi, IEEE TIE 62(3), 2015), like a first-order lag
of bandwidth omega_i r_i, r_i = J_nominal / J_true <= 1, around which the predictive law (eq. 15)
closes a PD loop with gains K1, K2 scaled by the same r_i; the characteristic polynomial

    s^3 + r (omega + K2) s^2 + r (K1 + omega K2) s + r omega K1

is stable iff r (omega + K2)(K1 + omega K2) > omega K1, so for a payload several times the wrist's
own inertia (r << 1) the observer bandwidth omega must grow roughly as 1 / r: a light wrist
(UR5's starter: observer rates down to 4.4 1/s) loses stability to a 0.5 kg tool 10 cm off its
axis (derive.control.payload.limits: DOBC 0.54 kg). A larger T2 (softer predictive law) does not
help: it lowers K2 faster than K1 (0.24 kg at T2 = 0.4 s). The momentum observer's residual obeys
r' = K (B d - r) (its rate K, not W) and needs K raised likewise.

Nominal payload: none. With J_nominal <= J_true the observer's fastest rate, and so the
forward-Euler sample-time limit 2 / lambda_max(W J^-1), is the nominal loop's (a heavier true arm
only slows it), and the continuous loop is stable for every r > 0 once omega is large enough;
a nominal model heavier than the arm (the midpoint or the largest payload carried into the model)
speeds the observer's true rate up by J_nominal / J_true with no payload, which the sample time
must then cover, and it is the empty arm that a tool changer most often runs.

The design: the nominal starter (derive.control.starter: W = omega Jbar, certified, and the
sample time fitted to the stated limits) is scaled by k >= 1, W -> k W and K -> k K (the observer
certificate holds for k W when it holds for W: 2 k W - J' >= 2 W - J' > 0 for k >= 1), and the
sample time refitted to the scaled file's stated limits, until the payload limit of every observer
form (DOBC, NPID, MOM, the forward-Euler step) at the file's sample time covers the stated mass.
k is estimated from the shortfall (the limits grow about linearly with k: UR5 DOBC 0.54, 1.6, 6.0 kg
at k = 1, 4, 16) and at most TRIES designs are tried; a sample time below MIN_SAMPLE_TIME stops it,
and the file then says what the design holds.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

from derive.control.payload.limits import PayloadLimit, payload_limit
from derive.model.payload import PayloadRange

OBSERVER_FORMS = ("dobc", "npid", "mom")   # the forms whose payload limit the design must cover (MPC has no observer)
TRIES = 5
SAFETY = 1.25          # k is raised to about SAFETY x the shortfall
MIN_STEP, MAX_STEP = 1.5, 8.0
MIN_SAMPLE_TIME = 1e-4   # s: below this the design stops (issue 34: no starter sample time below 0.1 ms unsaid)


@dataclass(frozen=True)
class PayloadDesign:
    """The scaled starter: factor k (W and K multiplied by it), the gain (derive.control.starter.StarterGain,
    its W scaled and its sample time refitted), the momentum gains K [1/s], the payload limits at its sample
    time (form -> PayloadLimit, forward-Euler step), whether they cover the range, and the designs tried."""

    factor: float
    gain: object
    momentum_gain: tuple[float, ...]
    limits: dict[str, PayloadLimit]
    holds: bool
    tries: int

    def held(self) -> float:
        """The smallest payload limit of the observer forms [kg]."""
        return min(self.limits[f].limit for f in OBSERVER_FORMS)


def scaled(gain, k: float, digits: int = 4):
    """``gain`` (StarterGain) with W, omega and the rates multiplied by k (W rounded as the starter writes it)."""
    W = tuple(tuple(float(f"{x * k:.{digits}g}") for x in row) for row in gain.W)
    return replace(gain, W=W, omega=gain.omega * k, rates=(gain.rates[0] * k, gain.rates[1] * k),
                   observer_limit=gain.observer_limit / k, floor=False)


def design(gain, d, base_k: tuple[float, ...], rng: PayloadRange,
           restate: Callable[[object, tuple[float, ...]], tuple[object, object]]) -> PayloadDesign:
    """The payload design (module docstring). ``gain``: the nominal starter gain (fitted to its limits),
    ``d`` its Derivation; ``base_k``: the momentum gains it goes with [1/s]; ``restate(gain, K) -> (gain
    refitted to the stated limits of the file with W = gain.W and K, its Derivation)``."""
    k, tries = 1.0, 0
    current = gain
    while True:
        tries += 1
        dt = current.sample_time
        lims = {f: payload_limit(d, f, getattr(current, "observer", "explicit"), dt, rng) for f in OBSERVER_FORMS}
        held = min(lim.limit for lim in lims.values())
        K = tuple(x * k for x in base_k)
        if held >= rng.mass or tries >= TRIES or dt < 2 * MIN_SAMPLE_TIME:
            return PayloadDesign(k, current, K, lims, held >= rng.mass, tries)
        short = rng.mass / held if held > 0 else MAX_STEP
        k *= min(MAX_STEP, max(MIN_STEP, SAFETY * short))
        candidate, cd = restate(scaled(gain, k), tuple(x * k for x in base_k))
        if candidate.sample_time < MIN_SAMPLE_TIME:
            return PayloadDesign(k, current, K, lims, False, tries)
        current, d = candidate, cd


def describe(pd: PayloadDesign, rng: PayloadRange) -> list[str]:
    """Comment lines for the starter file: what the design holds and how it was made."""
    parts = ", ".join(f"{f.upper()} {pd.limits[f].limit:.3g} kg" for f in OBSERVER_FORMS)
    verdict = (f"holds the whole [payload] range ({rng.mass:g} kg)" if pd.holds else
               f"does NOT hold the whole [payload] range ({rng.mass:g} kg): {pd.held():.3g} kg at most at this sample "
               "time; lower the payload, or shorten the sample time below 0.1 ms knowingly")
    return ["# Designed for [payload] (derive.control.payload.design): W and the momentum gains are the nominal",
            f"# starter's times {pd.factor:.3g}, the sample time refitted; at sample_time the linearised sampled loop",
            f"# {verdict} (largest payload, worst centre of mass in the ball: {parts}; 0.9 of the largest stable).",
            "# The controller's model carries no payload: the observer absorbs it (derive show and check state it)."]
