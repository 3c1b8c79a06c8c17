"""The observer gain and the sample time of a starter arm file (``derive init``).

W is scaled by the arm's inertia so that the observer rates, the eigenvalues of W J^-1(theta)
(eq. 24: the observer error e' = B (d - dhat) obeys e'' = -W J^-1 e', eq. a5), spread over the
joint ranges only as far as J itself does (a light wrist no longer gets the base's gain):

    W = omega Jbar,   Jbar = the mean of J(theta) over configurations within the joint limits,

symmetric and positive definite (a full W, which ``controller.w`` accepts as an n x n array). Its
unit is J's over time, kg m^2/s = N m s/rad: p = W theta' is a joint torque (eq. 21 adds it to
G - B u; B dhat = z + p, eq. 22). W J^-1 = omega Jbar J^-1 is similar to a symmetric positive definite
matrix, so the rates are real and positive, omega at J = Jbar, and spread only as far as J varies
over the ranges (a constant W cannot do better: the Panda's J varies 228-fold in some direction,
and the W that minimises the largest rate for the same certificate is within 3 % of this one).

omega is the smallest that the observer certificate (derive.control.certificate, with its split
past four angles) proves on the speed box, times MARGIN, and at least what puts the geometric mean
of the smallest and largest rate at FLOOR (rates spread as J does; the largest sets the sample
time, the smallest how slowly the estimate may follow in the worst pose): the appendix's V
decays when 2 omega Jbar - J'(theta, theta') > 0 over the box, so the box's numeric supremum for
W = Jbar (the certificate's own sound form, derive.control.certificate.split for 6-7 joints) gives omega_0.

The sound decision of W = omega Jbar, rounded as the file writes it, is branch and bound whose cells
(FIRST_BUDGET of them, derive check's budget) must cover the angles at a size where the bounds hold, and
at rate 0 its tree only shrinks as omega grows (N = omega (Jbar + Jbar^T) - X(theta, theta'), X free of
omega: a cell that passes at omega passes above it). So before any decision the tree is estimated for
every omega at once (derive.control.certificate.decision.TreeEstimate: Knuth's estimator along 32 random
paths, each cell's own threshold omega from the decision's bounds, about 0.1 s; within 10 % of the cells on
the Jaco 2 and the KUKA iiwa): omega_0 itself is decided when its tree is estimated within ACCEPT x
FIRST_BUDGET cells (as before: most arms prove it in a few hundred cells, the iiwa in 17,000), else the
smallest omega whose tree is estimated within TARGET cells, a decision of about 1 s on 7 joints. A decision
that is not proved within the budget (the estimate was short) or refuted at a point the samples missed
is followed by one at least RAISE times larger (at most TRIES decisions). The file states the decision
made: deterministic, with derive check's budget, so check makes the same. The Jaco 2 (omega_0 = 21.3 1/s,
a tree of about 80,000 cells there): one decision at omega = 90.5 1/s (8,427 cells), where raising omega
1.3-fold on 5,000-cell tries took nine decisions and wrote 133.7 1/s.

The sample time: with the forward-Euler observer step the fast mode steps by I - dt W J^-1, stable
for dt < 2 / rate_max (derive.control.sampling: the DOBC and NPID limit), and the momentum
observer's by 1 - dt K (dt < 2 / K); the value written is a round number (1, 2, 2.5, 4 or 5 x 10^k s)
at most HEADROOM of the smaller of 0.9 x those bounds, and at most 2 ms. These are the limits at
rest and without the arm's own fast modes; at speed, and with a light joint's viscous damping b (the
URDF's <dynamics damping>, in G: a mode of rate b / J that the sampled law compensates) the sampled
loop's limits can be far lower (the xArm6, b = 1 N m s/rad on a 1e-4 kg m^2 wrist: DOBC 0.464 ms
against 2.73 ms estimated, MOM 0.743 ms against 36 ms). So :func:`fit_to_limits` then takes the limits
``derive show`` and ``derive check`` state (derive.control.sampling: the sampled loop of every form, both
observer steps, over the speed box) for the W written, and the sample time is at most STATED_HEADROOM of
the smallest of the observer step's own limits.

Where that leaves less than USABLE (0.1 ms) with the forward-Euler observer step, :func:`choose_observer`
takes the backward-Euler step (``--observer implicit``, ``controller.observer = "implicit"``) when its
limits allow a longer sample time: its DOBC and NPID have no 2 / rate_max bound (the Kinova Jaco 2, whose
J varies 3000-fold over the ranges: 0.035 ms forward-Euler, DOBC 6.48 ms and NPID 35.5 ms implicit, issue 34).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from derive.control.certificate import Decision, InertiaModel, ObserverCertificate, Verdict

MARGIN = 1.3         # omega over the smallest the certificate's numeric supremum allows
RAISE = 1.3          # omega's least factor after a try that did not prove within FIRST_BUDGET cells
TRIES = 8            # certificate decisions at most
USABLE = 1e-4        # s: below this sample time the starter takes the implicit observer step where it allows more
FIRST_BUDGET = 20_000   # cells of a try (derive check's budget: what proves here proves there, the same decision)
ACCEPT = 1.25        # the first omega is decided when its tree is estimated within ACCEPT x FIRST_BUDGET cells
TARGET = 8192        # else the omega decided is the smallest whose tree is estimated within TARGET cells
FLOOR = 20.0         # 1/s: the rates' geometric mean at least (the predictive law with T2 = 0.2 s: poles near 9 rad/s)
HEADROOM = 0.45      # the sample time written is at most this fraction of the smallest estimated limit
STATED_HEADROOM = 0.5   # ... and at most this fraction of the smallest limit derive show states (fit_to_limits)
MAX_SAMPLE_TIME = 2e-3
SAMPLES = 1024
DIGITS = 4           # significant digits of W's entries as written


@dataclass(frozen=True)
class StarterGain:
    """The starter W (n x n, exact as written: DIGITS significant digits) and what it gives.

    omega [1/s]; rates: the smallest and largest eigenvalue of W J^-1 over the samples [1/s];
    decision: the certificate's on the box at rate 0 (proved, or the last try's); sample_time [s]
    and the estimated limits it was chosen from (observer [s], momentum [s]); seconds: time taken;
    floor: omega was set by FLOOR, not raised for the certificate."""

    W: tuple[tuple[float, ...], ...]
    omega: float
    rates: tuple[float, float]
    decision: Decision
    sample_time: float
    observer_limit: float
    momentum_limit: float
    seconds: float
    floor: bool = False   # omega is FLOOR's (the rates' geometric mean), not the certificate's need
    stated: tuple[tuple[str, str, float], ...] = ()   # (observer, form, limit [s]) of the sampled loop (fit_to_limits)
    observer: str = "explicit"    # the observer step the sample time is fitted to (choose_observer)
    explicit_time: float | None = None   # s: the forward-Euler step's sample time, when the implicit step was chosen
    payload_rate: float = 0.0    # 1/s: rho of W = omega Jbar + rho Jp_bar (derive.control.payload.design); 0: no payload term


def _round(x: float) -> float:
    return float(f"{x:.{DIGITS}g}")


def round_sample_time(x: float) -> float:
    """The largest of 1, 2, 2.5, 4, 5 x 10^k not above x (x > 0)."""
    k = math.floor(math.log10(x))
    for m in (5.0, 4.0, 2.5, 2.0, 1.0):
        if m * 10.0 ** k <= x * (1 + 1e-12):
            return float(f"{m * 10.0 ** k:.3g}")
    return float(f"{10.0 ** (k - 1) * 5:.3g}")


def _rounded(Jbar: np.ndarray, omega: float) -> np.ndarray:
    """omega Jbar with DIGITS significant digits, as the file writes it (symmetric: Jbar is)."""
    W = np.array([[_round(omega * x) for x in row] for row in Jbar])
    return (W + W.T) / 2


def _search(cert: ObserverCertificate, Jbar: np.ndarray, box: np.ndarray,
            start: float) -> tuple[float, np.ndarray, Decision]:
    """(omega [1/s], W as written, its decision) of the certificate's search from ``start`` (module docstring)."""
    tree = None
    if not cert.norm and cert.target.m > 0 and not cert.model.unbounded:
        tree = cert.tree_estimate(Jbar, box, start, ACCEPT * FIRST_BUDGET)
    highest = start * RAISE ** TRIES

    def ahead(omega: float) -> float | None:   # the smallest omega above, estimated within TARGET (else the budget)
        return tree.smallest(TARGET, omega, highest) or tree.smallest(FIRST_BUDGET, omega, highest)

    omega = start
    if tree is not None and tree.cells(start) > ACCEPT * FIRST_BUDGET:
        omega = ahead(start) or start * RAISE
    for attempt in range(TRIES):
        W = _rounded(Jbar, omega)
        dec = cert.decide(W, box, 1.0, 0.0, FIRST_BUDGET)
        if dec.verdict is Verdict.PROVED or attempt == TRIES - 1:
            break
        # not within the budget though estimated so (or refuted at a point the samples missed): at least RAISE more
        more = ahead(omega) if tree is not None and dec.verdict is Verdict.UNPROVEN else None
        omega = max(more or 0.0, omega * RAISE)
    return omega, W, dec


def starter_gain(model: InertiaModel, box, momentum_gain: float = 50.0) -> StarterGain:
    """W = omega Jbar certified on ``box`` (n speeds, rad/s or m/s), and the sample time (module docstring).
    ``momentum_gain``: the largest K_i of the momentum observer [1/s]."""
    start = time.perf_counter()
    box = np.asarray(box, dtype=float)
    cert = ObserverCertificate(model, box)
    q = cert.samples(SAMPLES, exact=True)
    Js = model.J(q)
    Jbar = Js.mean(axis=0)
    Jbar = (Jbar + Jbar.T) / 2
    Li = np.linalg.inv(np.linalg.cholesky(Js))
    spread = np.linalg.eigvalsh(np.einsum("pab,bc,pdc->pad", Li, Jbar, Li))   # eigenvalues of Jbar J^-1
    middle = math.sqrt(float(spread[:, 0].min()) * float(spread[:, -1].max()))
    sup = cert.speed_supremum(Jbar, box, 0.0, SAMPLES)
    need = MARGIN / sup if sup > 0 and math.isfinite(sup) else 0.0
    omega = max(FLOOR / middle, need)
    floor = omega > need
    omega, W, dec = _search(cert, Jbar, box, omega)
    lam = np.linalg.eigvalsh(np.einsum("pab,bc,pdc->pad", Li, W, Li))      # eigenvalues of W J^-1
    rates = (float(lam[:, 0].min()), float(lam[:, -1].max()))
    observer = 0.9 * 2.0 / rates[1]
    momentum = 0.9 * 2.0 / momentum_gain
    dt = round_sample_time(min(MAX_SAMPLE_TIME, HEADROOM * min(observer, momentum)))
    return StarterGain(W=tuple(tuple(float(x) for x in row) for row in W), omega=omega, rates=rates, decision=dec,
                       sample_time=dt, observer_limit=observer, momentum_limit=momentum,
                       seconds=time.perf_counter() - start, floor=floor and omega == max(FLOOR / middle, need))


def fit_to_limits(gain: StarterGain, stated: dict[str, dict]) -> StarterGain:
    """``gain`` with its sample time at most STATED_HEADROOM of the smallest positive finite limit of
    ``stated`` ({observer: {form: derive.control.sampling.SampleLimit}}, the sampled loop of the arm file
    as written) with ``gain.observer``'s step, and no larger than before; every limit kept in
    ``gain.stated``. A form without a positive finite limit (unstable as dt -> 0, or stable at every dt)
    sets none."""
    rows = tuple((observer, form, lim.limit) for observer, forms in stated.items() for form, lim in forms.items())
    usable = [x for o, _, x in rows if o == gain.observer and 0 < x < math.inf]
    dt = gain.sample_time if not usable else min(gain.sample_time, round_sample_time(STATED_HEADROOM * min(usable)))
    return replace(gain, sample_time=dt, stated=rows)


def choose_observer(gain: StarterGain, stated: dict[str, dict]) -> StarterGain:
    """The observer step and the sample time of the starter file (module docstring): the forward-Euler
    step's (fit_to_limits) when it is at least USABLE, else the backward-Euler step's (limits: the
    momentum observer's estimate, MAX_SAMPLE_TIME and STATED_HEADROOM of its stated limits) when that is
    longer, with the forward-Euler sample time kept in ``explicit_time`` for the file to state."""
    explicit = fit_to_limits(replace(gain, observer="explicit"), stated)
    if explicit.sample_time >= USABLE * (1 - 1e-12):
        return explicit
    base = round_sample_time(min(MAX_SAMPLE_TIME, HEADROOM * gain.momentum_limit))
    implicit = fit_to_limits(replace(gain, observer="implicit", sample_time=base), stated)
    if implicit.sample_time > explicit.sample_time:
        return replace(implicit, explicit_time=explicit.sample_time)
    return explicit
