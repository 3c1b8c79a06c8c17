"""The payload limits (derive.control.payload.limits) as ``derive show`` and ``derive check`` state them,
text and JSON: per form, the largest payload the linearised sampled loop holds at the arm file's sample
time, the forward-Euler observer step (derive generate's default), over the ``[payload]`` ball."""
from __future__ import annotations

from derive.control.payload.design import OBSERVER_FORMS
from derive.control.payload.limits import CAP_FACTOR, MARGIN, PayloadLimit, payload_limit
from derive.control.sampling import FORMS

OBSERVER = "explicit"


def stated(d) -> dict[str, PayloadLimit] | None:
    """{form: PayloadLimit} at the arm file's sample time (cached on the derivation), or None without a
    [payload] range."""
    rng = d.arm.payload
    if rng is None:
        return None
    hit = _CACHE.get(id(d))
    if hit is not None and hit[0] is d:
        return hit[1]
    dt = d.arm.simulation.sample_time
    out = {f: payload_limit(d, f, OBSERVER, dt, rng) for f in FORMS}
    _CACHE.clear()
    _CACHE[id(d)] = (d, out)
    return out


_CACHE: dict = {}


def _kg(lim: PayloadLimit) -> str:
    if lim.raw == 0:
        return "none (unstable with no payload at this sample time)"
    return f"{'at least ' if lim.capped else ''}{lim.limit:.3g} kg"


def summary(d) -> str | None:
    """One line (None without [payload]): the range, each form's largest payload, and the verdict."""
    lims = stated(d)
    if lims is None:
        return None
    rng = d.arm.payload
    parts = ", ".join(f"{f.upper()} {_kg(lims[f])}" for f in FORMS)
    short = [f.upper() for f in OBSERVER_FORMS if lims[f].limit < rng.mass]
    verdict = (f"every observer form holds the stated {rng.mass:g} kg" if not short else
               f"{', '.join(short)} do{'es' if len(short) == 1 else ''} NOT hold the stated {rng.mass:g} kg")
    return (f"largest payload at sample_time = {d.arm.simulation.sample_time * 1e3:g} ms (linearised sampled loop, "
            f"forward-Euler observer step, worst of {lims['dobc'].centres} centres of mass in the [payload] ball, "
            f"{int(round((1 - MARGIN) * 100))} % margin; MPC has no observer): {parts}; {verdict}")


def record(d) -> dict | None:
    """The JSON record (strict: no NaN or inf) of the payload statement, or None without [payload]."""
    lims = stated(d)
    if lims is None:
        return None
    rng = d.arm.payload
    return {"range": {"mass": rng.mass, "com": list(rng.com), "com_radius": rng.com_radius},
            "sample_time": d.arm.simulation.sample_time, "observer": OBSERVER, "margin": MARGIN,
            "forms": {f: {"limit_kg": lim.limit, "largest_stable_kg": lim.raw, "at_least": lim.capped,
                          "cap_kg": CAP_FACTOR * max(rng.mass, 0.5) if lim.capped else None,
                          "holds": bool(lim.limit >= rng.mass),
                          "worst": None if lim.worst is None else {"theta": list(lim.worst[0]),
                                                                   "dtheta": list(lim.worst[1]),
                                                                   "com": list(lim.worst[2])}}
                      for f, lim in lims.items()},
            "holds": all(lims[f].limit >= rng.mass for f in OBSERVER_FORMS)}
