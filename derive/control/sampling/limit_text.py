"""The sample-time limits of derive.control.sampling in the sentences that derive generate's
headers, derive check, derive show and derive simulate state (what the grid covers, each form's
largest sample time, why a sample time is refused)."""
from __future__ import annotations

import math

from derive.control.sampling import DT_MIN, FORMS, MARGIN, SHARED, SampleLimit, _grid, limits


def _ms(x: float, below: bool = False) -> str:
    """A limit [s] as the sentences embed it: a time, "below 1e-7 s" (``below``: SampleLimit.below),
    "none below 1 s" (inf), or, for 0, none with the reason."""
    if below:
        return f"below {_DT_MIN_TEXT}"
    if x == 0:
        return "none (the linearised loop is unstable as dt -> 0: not a sampling limit)"
    return "none below 1 s" if math.isinf(x) else f"{x * 1e3:.3g} ms"


_DT_MIN_TEXT = f"{DT_MIN:.0e}".replace("e-0", "e-") + " s"   # "1e-7 s"


def _limit(lim: SampleLimit) -> str:
    return _ms(lim.limit, lim.below)


def _how(d) -> str:
    return (f"sampled loop, zero-order hold, linearised at {_grid(d).describe()}, "
            f"{int(round((1 - MARGIN) * 100))} % margin")


def covered(d) -> str:
    """What the limits cover, in words: the grid's configurations and speeds (derive.control.sampling.grid)."""
    return _grid(d).describe()


def summary(d, observer: str = "explicit") -> str:
    """One line: the largest sample time of each form with ``observer``, as the generated headers state it."""
    lim = limits(d, observer)
    parts = ", ".join(f"{f.upper()} {_limit(lim[f])}" for f in FORMS)
    return f"largest sample time ({_how(d)}; {observer} observer step): {parts}"


def summary_all(d) -> str:
    """One line with both discretisations, as ``derive check`` and ``derive show`` print it."""
    e, i = limits(d, "explicit"), limits(d, "implicit")
    return (f"largest sample time ({_how(d)}): MPC {_limit(e['mpc'])}; MOM {_limit(e['mom'])} "
            f"(momentum observer, the same step in both builds); DOBC {_limit(e['dobc'])}, "
            f"NPID {_limit(e['npid'])} with the forward-Euler observer step (derive generate's default); "
            f"DOBC {_limit(i['dobc'])}, NPID {_limit(i['npid'])} with --observer implicit")


def too_slow(d, sample_time: float, forms=FORMS, observer: str = "explicit") -> list[str]:
    """Sentences for the forms whose limit (with ``observer``) ``sample_time`` [s] exceeds (empty when none),
    each with the form's limit and, for an explicit build, its limit with ``--observer implicit`` and
    whether that allows ``sample_time``."""
    lim = limits(d, observer)
    other = limits(d, "implicit") if observer == "explicit" else None
    out = []
    for f in forms:
        if f not in lim or not sample_time > lim[f].limit:
            continue
        how = "" if observer == "explicit" else f" with --observer {observer}"
        text = f"sample_time = {sample_time * 1e3:g} ms " + _beyond(f.upper(), lim[f], how)
        if other is not None and f not in SHARED:
            alt = other[f].limit
            text += (f"; with --observer implicit the {f.upper()} limit is {_limit(other[f])}, "
                     + ("which allows it" if sample_time <= alt else "which does not allow it either"))
        elif other is not None:
            text += f" (the same with --observer implicit: {f.upper()} has no observer step to change)" \
                if f == "mpc" else " (the same with --observer implicit: the momentum observer steps alike in both)"
        out.append(text)
    return out


def _beyond(form: str, lim: SampleLimit, how: str) -> str:
    """The rest of too_slow's sentence after "sample_time = ... ms ", for each kind of limit."""
    if lim.below:
        return (f"is above the {form} limit{how}, which is below {_DT_MIN_TEXT} (the sampled loop is unstable at "
                f"{_DT_MIN_TEXT} at some operating point, although the continuous loop is stable at every one: "
                "its fastest mode needs a shorter sample time)")
    if lim.limit == 0:
        return (f"is not a sampling question: the {form} loop{how} is unstable at every sample time (its "
                "linearisation is unstable as dt -> 0 at some operating point: not a sampling limit)")
    return (f"is above the {form} limit {_ms(lim.limit)}{how} (the sampled loop is unstable from {_ms(lim.raw)} at "
            "some operating point)")
