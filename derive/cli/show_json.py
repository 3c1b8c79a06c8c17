"""``derive show --json FILE``: the numbers ``derive show`` states, as a strict JSON record (no NaN or inf).

{"arm", "n", "sample_time" [s] (the file's), "sample_time_limits": {observer: {form: {"limit_s",
"largest_stable_s", "below_minimum", "points", "worst": {"theta", "dtheta"} | null}}} (derive.control.sampling:
0.9 of the largest stable sample time of the linearised sampled loop over the speed box; "limit_s" null when
the loop is stable up to the search's largest, 1 s), "inputs_beyond_limits": [{"joint", "needed", "limit",
"unit", "theta", "dtheta"}] (derive.control.effort: where the speed box needs inputs beyond the effort
limits), "payload": derive.control.payload.text.record or null (without a [payload] range)}.
"""
from __future__ import annotations

import math

from derive import jsonio


def _limit(lim) -> dict:
    return {"limit_s": lim.limit if math.isfinite(lim.limit) else None,
            "largest_stable_s": lim.raw if math.isfinite(lim.raw) else None,
            "below_minimum": bool(lim.below), "points": lim.points,
            "worst": None if lim.worst is None else {"theta": list(lim.worst[0]), "dtheta": list(lim.worst[1])}}


def record(d) -> dict:
    """The JSON record of derivation ``d`` (module docstring)."""
    from derive.control.effort import beyond_limits
    from derive.control.payload.text import record as payload_record
    from derive.control.sampling import OBSERVERS, limits

    return {"arm": d.arm.name, "n": d.n, "sample_time": d.arm.simulation.sample_time,
            "sample_time_limits": {o: {f: _limit(lim) for f, lim in limits(d, o).items()} for o in OBSERVERS},
            "inputs_beyond_limits": [{"joint": e.joint, "needed": e.needed, "limit": e.limit, "unit": e.unit,
                                      "theta": list(e.theta), "dtheta": list(e.dtheta)} for e in beyond_limits(d)],
            "payload": payload_record(d)}


def render(d) -> str:
    """The record as strict JSON text."""
    return jsonio.dumps(record(d), sort_keys=False)
