"""The payload range obligation (kind ``project``, issue 38): every observer form holds the arm file's
``[payload]`` range at its sample time (derive.control.payload)."""
from __future__ import annotations

from typing import TYPE_CHECKING

from derive.proofs.core import Kind, Obligation, Outcome, Status

if TYPE_CHECKING:
    from derive.control.pipeline import Derivation


def check_payload(d: "Derivation") -> Outcome:
    """Proved when the payload limit of DOBC, NPID and MOM (the forward-Euler observer step, at the file's
    sample time, the worst centre of mass of the ball) is at least [payload] mass; refuted otherwise, with
    each form's limit; n/a without a [payload] table."""
    from derive.control.payload.design import OBSERVER_FORMS
    from derive.control.payload.text import stated, summary

    if d.arm.payload is None:
        return Outcome(Status.NOT_APPLICABLE, "the arm file states no [payload] range (derive init --payload MASS "
                       "writes one)")
    lims = stated(d)
    text = summary(d)
    short = [f for f in OBSERVER_FORMS if lims[f].limit < d.arm.payload.mass]
    if not short:
        return Outcome(Status.PROVED, text, summary=f"{d.arm.payload.mass:g} kg held: " + ", ".join(
            f"{f.upper()} {lims[f].limit:.3g} kg" for f in OBSERVER_FORMS))
    worst = lims[short[0]].worst
    where = "" if worst is None else (f"; {short[0].upper()} first fails at theta = "
                                      f"{[round(x, 4) for x in worst[0]]}, theta' = {[round(x, 4) for x in worst[1]]}, "
                                      f"centre of mass {[round(x, 4) for x in worst[2]]} m")
    return Outcome(Status.REFUTED, f"{text}{where}; derive init --payload designs W, the momentum gains and the sample "
                   "time for the range, or lower [payload] mass",
                   summary=f"{', '.join(f.upper() for f in short)} below the stated {d.arm.payload.mass:g} kg: "
                   + ", ".join(f"{f.upper()} {lims[f].limit:.3g} kg" for f in OBSERVER_FORMS))


OBLIGATIONS = (
    Obligation("payload-range", "eq. 12, 21-27 with the true J + J_p, G + G_p", Kind.PROJECT,
               "the linearised sampled loop of DOBC, NPID and MOM is stable at the file's sample time for every "
               "payload of the [payload] range (mass 0 to mass, the worst centre of mass of the ball)", check_payload),
)
