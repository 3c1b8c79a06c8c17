"""What ``derive check`` reports about the observer certificate (derive.control.certificate, the
appendix's V of eq. a7 generalised to n joints): the obligations on the stated box and rate, and the
largest certified speed box and rate beside the numeric suprema."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from derive.control.certificate import DEFAULT_BUDGET, Decision, InertiaModel, ObserverCertificate, Verdict, \
    joint_coordinates

__all__ = ["Report", "TRIES", "inertia_model", "largest_proved_speed", "report"]

SEARCH_SHARE = 10           # the searches for the largest box and rate (figures, not obligations) get
                            # DEFAULT_BUDGET / SEARCH_SHARE cells per try: a try that does not prove costs its whole budget


@dataclass(frozen=True)
class Report:
    """What ``derive check`` says about the observer of one arm.

    shape: the box's shape (the stated max_joint_speed, or ones); stated: whether it was
    stated; speed: the largest certified scale v at rate 0 (box |theta'_k| <= v s_k) and
    speed_sup its numeric supremum; rate: the largest certified beta on the stated box
    (at rest when none is stated) and rate_sup its numeric supremum; stated_decision: (*)
    at beta = 0 on the stated box (None when none is stated); coords: the deps.
    """

    W: tuple[tuple[float, ...], ...]
    shape: tuple[float, ...]
    stated: bool
    speed: float
    speed_sup: float
    speed_decision: Decision | None
    rate: float
    rate_sup: float
    rate_decision: Decision | None
    stated_decision: Decision | None
    unbounded: tuple[str, ...]
    seconds: float
    constant: bool = False   # J depends on no coordinate: J' = 0, (*) is W + W^T - 2 beta J > 0, decided exactly
    one_bound: bool = False  # decided by one matrix bound for every theta and speed (derive.control.certificate.norm_bound)


TRIES = (0.99, 0.97, 0.9, 0.7, 0.5, 0.25, 0.1)
# with the grouped stage (ObserverCertificate(grouped=True)), whose supremum estimate is locally
# optimised: tried from the top down, the first that proves ends the search (a try close to the
# supremum costs the stage's whole budget, so 0.97 and 0.99 are not tried)
GROUPED_TRIES = (0.9, 0.85, 0.8, 0.7, 0.5, 0.25, 0.1)


def _best(decide, sup: float, cap: float | None = None, floor: float = 0.0,
          floor_decision: Decision | None = None) -> tuple[float, Decision | None]:
    """The largest fraction of ``sup`` (of TRIES) that ``decide`` proves, and its decision, found by
    bisection over TRIES (a box or rate that proves makes every smaller one provable: 3 decisions instead
    of up to 7, and a decision that does not prove costs its whole budget); tries at or below ``floor``
    (proved already, by ``floor_decision``) are not made: (floor, floor_decision) then. Every figure
    returned is a proof's."""
    if not (sup > 0):
        return (floor, floor_decision) if floor > 0 else (0.0, None)
    top = sup if cap is None or not math.isfinite(sup) else min(sup, cap)
    if not math.isfinite(top):
        return math.inf, None
    fs = [f for f in TRIES if not (floor > 0 and top * f <= floor)]
    left, right, best, last = 0, len(fs), None, None
    while left < right:
        mid = (left + right) // 2
        dec = decide(top * fs[mid])
        last = dec
        if dec.verdict is Verdict.PROVED:
            right, best = mid, (top * fs[mid], dec)
        else:
            left = mid + 1
    if best is not None:
        return best
    return (floor, floor_decision) if floor > 0 else (0.0, last)


def largest_proved_speed(cert: ObserverCertificate, W, shape, beta: float = 0.0, budget: int = DEFAULT_BUDGET,
                         samples: int = 4096) -> tuple[float, Decision | None]:
    """The largest box scale v (|theta'_k| <= v shape_k) that ``cert`` proves for W at rate beta, of
    TRIES fractions of the numeric supremum of what it can prove (its sound form with a split;
    GROUPED_TRIES from the top down with the grouped stage), and the decision (0 and the last
    decision when none proves)."""
    W = np.asarray(W, dtype=float)
    shape = np.asarray(shape, dtype=float)
    sup = cert.speed_supremum(W, shape, beta, samples)
    if cert._grouped_for(shape, beta) and 0 < sup < math.inf:
        last = None
        for f in GROUPED_TRIES:
            last = cert.decide(W, shape, sup * f, beta, budget)
            if last.verdict is Verdict.PROVED:
                return sup * f, last
        return 0.0, last
    return _best(lambda v: cert.decide(W, shape, v, beta, budget), sup)


def report(d, W=None, budget: int = DEFAULT_BUDGET, samples: int = 4096) -> Report:
    """Certified speed box (rate 0) and rate (on the stated box) for derivation ``d``."""
    start = time.perf_counter()
    model = inertia_model(d)
    Wn = np.array((d.W if W is None else W).tolist(), dtype=float)
    speeds = d.arm.controller.max_joint_speed
    stated = speeds is not None
    shape = np.array([float(x) for x in speeds]) if stated else np.ones(d.n)
    cert = ObserverCertificate(model, shape)
    unbounded = tuple(str(c.symbol) for c in model.unbounded)
    if model.m == 0:   # (*) does not depend on theta or theta': one matrix, decided exactly
        rate = cert.rate_supremum(Wn, shape, 0.0, 1)   # lambda_min(J^-1/2 (W + W^T) J^-1/2) / 2: every beta below it
        at_rest = cert.decide(Wn, shape, 1.0, 0.0, budget)
        return Report(W=tuple(map(tuple, Wn.tolist())), shape=tuple(shape.tolist()), stated=stated,
                      speed=math.inf if at_rest.verdict is Verdict.PROVED else 0.0,
                      speed_sup=math.inf if at_rest.verdict is Verdict.PROVED else 0.0, speed_decision=at_rest,
                      rate=max(rate, 0.0), rate_sup=max(rate, 0.0), rate_decision=at_rest,
                      stated_decision=at_rest if stated else None, unbounded=(),
                      seconds=time.perf_counter() - start, constant=True)
    # the search starts from the supremum of what the certificate can prove (the split's sound
    # form), the report states N's own numeric supremum
    # the obligations first, on the whole budget: the stated box at rate 0, and the stated observer_rate on it;
    # the searches for the largest box and rate (figures) start above what they proved, SEARCH_SHARE's budget a try
    search = max(1, budget // SEARCH_SHARE)
    sup_v = cert.speed_supremum(Wn, shape, 0.0, samples, exact=True)
    v_rate = 1.0 if stated else 0.0
    stated_dec = cert.decide(Wn, shape, 1.0, 0.0, budget) if stated else None
    proved = stated_dec is not None and stated_dec.verdict is Verdict.PROVED
    speed, sdec = _best(lambda v: cert.decide(Wn, shape, v, 0.0, search),
                        cert.speed_supremum(Wn, shape, 0.0, samples), floor=1.0 if proved else 0.0,
                        floor_decision=stated_dec)
    need = float(d.arm.controller.observer_rate)
    need_dec = cert.decide(Wn, shape, v_rate, need, budget) if need > 0 and (proved or not stated) else None
    need_ok = need_dec is not None and need_dec.verdict is Verdict.PROVED
    sup_b = cert.rate_supremum(Wn, shape, v_rate, samples, exact=True)
    rate, rdec = _best(lambda b: cert.decide(Wn, shape, v_rate, b, search),
                       cert.rate_supremum(Wn, shape, v_rate, samples), floor=need if need_ok else 0.0,
                       floor_decision=need_dec)
    return Report(W=tuple(map(tuple, Wn.tolist())), shape=tuple(shape.tolist()), stated=stated, speed=speed,
                  speed_sup=sup_v, speed_decision=sdec, rate=rate, rate_sup=sup_b, rate_decision=rdec,
                  stated_decision=stated_dec, unbounded=unbounded, seconds=time.perf_counter() - start,
                  one_bound=cert.norm)


_MODELS: dict = {}


def inertia_model(d) -> InertiaModel:
    """The InertiaModel of ``d``'s J (cached per derivation object)."""
    key = id(d)
    hit = _MODELS.get(key)
    if hit is not None and hit[0] is d:
        return hit[1]
    model = InertiaModel(d.J, joint_coordinates(d.arm, d.theta))
    _MODELS[key] = (d, model)
    return model
