"""The start of the paper's experiment: where the reference begins, and the initial estimate
the observer forms take there (issue 20 items 6 and 7).

``[simulation] reference_start`` (``derive simulate --reference-from-pose``):

* ``"zero"`` (default, the paper's section 5.2): y_d starts at 0 and the pulse train (each
  joint's ``amplitude``, or ``amplitude_deg`` for all) drives Gr(s) from there. An arm started elsewhere
  (``initial_theta``) sees a step e(0) = -C theta(0) at t = 0;
* ``"measured"``: y_d starts at the measured pose, y_d(0) = C theta(0), and the pulse train
  is an offset added to it: y_d = C theta(0) + Gr * r (Gr has unit gain at 0, so the filter
  starts at rest at y_d(0)). Then e(0) = 0 and e'(0) = 0 (the arm starts at rest), so the
  derived initial estimate is 0 too: a smooth start.

The derived initial estimate dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0)) (derive.control.npid;
W_dt = W (J + dt W)^-1 J in place of W for the implicit observer step) makes DOBC and NPID
equal from t = 0; on a light wrist it is large for a modest step (87.5 N m on the iiwa's
wrist for 0.2 rad). :func:`start_warnings` says so when it exceeds an input limit.
"""
from __future__ import annotations

import numpy as np

from derive.control.pipeline import Derivation
from derive.control.sampling.wrap import wrap_numeric
from derive.dynamics.program import lambdify
from derive.model.simspec import SimSettings


def reference_offset(d: Derivation, s: SimSettings) -> np.ndarray:
    """y_d(0) (n): C theta(0) for reference_start = "measured", else zeros; the pulse train adds to it."""
    if s.reference_start == "measured":
        return np.array(d.C.tolist(), dtype=float) @ np.array(s.initial_theta, dtype=float)
    return np.zeros(d.n)


def initial_estimate(d: Derivation, theta, dtheta, e, de, dt: float | None = None) -> np.ndarray:
    """dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0)) in double (n; the input's unit, V or N m), e the
    (wrapped) tracking error and e' its rate; with ``dt``, the implicit step's W_dt = W (J + dt W)^-1 J
    with J at ``theta`` (``dtheta`` unused: the estimate does not depend on the speed)."""
    n = d.n
    W = np.array(d.W.tolist(), dtype=float)
    K2 = np.array(d.K2.tolist(), dtype=float)
    C = np.array(d.C.tolist(), dtype=float)
    xi = np.linalg.solve(C, np.asarray(de, dtype=float) + K2 @ np.asarray(e, dtype=float))
    if dt is not None:
        J = np.array(lambdify(list(d.theta), d.J)(*theta), dtype=float).reshape(n, n)
        xi = np.linalg.solve(J + dt * W, J @ xi)
    return -(W @ xi) / np.array(d.B.tolist(), dtype=float).diagonal()


def start_estimate(d: Derivation, s: SimSettings, observer: str = "explicit") -> np.ndarray:
    """dhat(0) at the experiment's start: the arm at rest at initial_theta, y_d(0) as reference_start
    says (y_d'(0) = 0), e(0) wrapped for the outputs of continuous joints (derive.control.sampling.wrap)."""
    theta0 = np.array(s.initial_theta, dtype=float)
    e = reference_offset(d, s) - np.array(d.C.tolist(), dtype=float) @ theta0
    for i in d.wrapped:
        e[i] = wrap_numeric(e[i])
    return initial_estimate(d, theta0, np.zeros(d.n), e, np.zeros(d.n),
                            s.sample_time if observer == "implicit" else None)


def start_warnings(d: Derivation, s: SimSettings, observer: str = "explicit") -> list[str]:
    """A sentence when the initial estimate at the start exceeds an input limit (voltage or torque)
    of some joint: the DOBC and NPID forms then start with a saturated command."""
    dhat = start_estimate(d, s, observer)
    units = d.arm.input_units
    over = [(i, float(dhat[i]), float(m.input_limit)) for i, m in enumerate(d.arm.motors)
            if m.input_limit and abs(dhat[i]) > float(m.input_limit)]
    if not over:
        return []
    joints = ", ".join(f"{abs(v):.3g} {units[i]} at joint {i + 1} (limit {lim:g} {units[i]})" for i, v, lim in over)
    step = "W_dt = W (J + dt W)^-1 J, " if observer == "implicit" else ""
    return [f"simulation of {d.arm.name}: the initial estimate dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0)) "
            f"({step}e(0) = y_d(0) - C theta(0) from simulation.initial_theta and reference_start = "
            f"{s.reference_start!r}) is {joints}: the DOBC and NPID forms start with that command, clipped; "
            "start the reference at the measured pose for a smooth start ([simulation] reference_start = "
            "\"measured\" or derive simulate --reference-from-pose), or see derive show --at"]
