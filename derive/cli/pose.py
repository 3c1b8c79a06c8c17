"""``derive show ARM --at theta=...,dtheta=...[,e=...,de=...]``: the plant's numbers at one pose.

J(theta), G(theta, theta'), gravity g(theta), B, the free acceleration theta''
(u = d = 0), the PID gains P(theta), D(theta) (eq. 12, 35-36) and the initial
estimate dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0)) the DOBC and NPID forms start with
for the tracking error e(0) and its rate e'(0) given (default 0; also with the
implicit observer step's W_dt = W (J + dt W)^-1 J at the arm's sample time),
evaluated by the 40-digit reference of the derivation (derive.codegen.reference) and
printed with 6 significant digits. Units follow the actuation (V, or N m in torque mode).
"""
from __future__ import annotations

import math
import re
import textwrap

import numpy as np

from derive.control.pipeline import Derivation
from derive.errors import DeriveError

_ITEM = re.compile(r"(dtheta|theta|de|e)=([^=]*?)(?=,(?:dtheta|theta|de|e)=|$)")


def parse_pose(text: str, n: int) -> tuple[list[float], list[float], list[float], list[float]]:
    """(theta, theta', e(0), e'(0)) from ``theta=a,b,...,dtheta=c,d,...,e=...,de=...``
    (radians, rad/s; theta', e(0) and e'(0) default to zeros). One DeriveError naming the
    option otherwise."""
    expected = (f"theta=<{n} numbers>[,dtheta=<{n} numbers>][,e=<{n} numbers>][,de=<{n} numbers>] "
                f"(rad, rad/s), e.g. theta={','.join(['0.1'] * n)},e={','.join(['0.2'] * n)}")
    items = {}
    pos = 0
    for match in _ITEM.finditer(text.replace(" ", "")):
        if match.start() != pos or match.group(1) in items:
            break
        items[match.group(1)] = match.group(2)
        pos = match.end() + 1
    else:
        if pos >= len(text.replace(" ", "")) and "theta" in items:
            try:
                values = {k: [float(x) for x in v.split(",")] for k, v in items.items()}
            except ValueError:
                values = {}
            theta, dtheta = values.get("theta", []), values.get("dtheta", [0.0] * n)
            e, de = values.get("e", [0.0] * n), values.get("de", [0.0] * n)
            if all(len(v) == n for v in (theta, dtheta, e, de)) and all(map(math.isfinite, theta + dtheta + e + de)):
                return theta, dtheta, e, de
    raise DeriveError(f"--at: expected {expected}, got {text!r}")


def _matrix(name: str, m: np.ndarray) -> list[str]:
    rows = np.atleast_2d(m)
    width = max(len(f"{x:.6g}") for x in rows.ravel())
    lines = [f"{name} ="]
    lines += ["  [" + "  ".join(f"{x:>{width}.6g}" for x in row) + "]" for row in rows]
    return lines


def pose_text(d: Derivation, theta: list[float], dtheta: list[float], e: list[float] | None = None,
              de: list[float] | None = None) -> str:
    """The numbers at one pose (and the initial estimate at e(0), e'(0)), readable at 100 columns."""
    from derive.codegen.balls import to_float
    from derive.codegen.reference import Reference
    from derive.model.actuators import units_text

    ref = Reference(d)
    n = d.n
    f = lambda v: np.array([float(x) for x in v])  # noqa: E731
    zero = [0.0] * n
    e, de = e if e is not None else zero, de if de is not None else zero
    u = units_text(d.arm.input_units)
    lines = [f"{d.arm.name} at theta = {theta} rad, dtheta = {dtheta} rad/s", ""]
    blocks = [
        ("J(theta)  (eq. 12) [kg m^2]", f(ref.mass_matrix(theta)).reshape(n, n)),
        ("G(theta, dtheta)  (eq. 12) [N m]", f(ref.bias(theta, dtheta))[:, None]),
        ("g(theta), gravity torques [N m]", f(ref.gravity(theta))[:, None]),
        (f"B  (eq. 12) [N m per {u}]", f(ref.input_matrix()).reshape(n, n)),
        ("ddtheta at u = d = 0  (J ddtheta = -G) [rad/s^2]",
         f(ref.forward_dynamics(theta, dtheta, zero, zero))[:, None]),
    ]
    gains = f(ref.gains(theta))
    blocks += [(f"P(theta)  (eq. 35) [{u}/rad]", gains[: n * n].reshape(n, n)),
               (f"D(theta)  (eq. 36) [{u} s/rad]", gains[n * n: 2 * n * n].reshape(n, n))]
    # the controller's input at the first sample with these e(0), e'(0): yd = C theta + e, yd' = C theta' + e'
    C = np.array(d.C.tolist(), dtype=float)
    x = [*theta, *dtheta, *(C @ np.array(theta) + np.array(e)), *(C @ np.array(dtheta) + np.array(de)), *zero]
    dt = d.arm.simulation.sample_time
    explicit = np.array([to_float(v) for v in ref.initial_estimate(x)])
    implicit = np.array([to_float(v) for v in ref.initial_estimate(x, dt)])
    for title, m in blocks:
        lines += _matrix(title, m) + [""]
    lines += textwrap.wrap(f"The initial estimate the DOBC and NPID forms start with, at e(0) = {e} rad, "
                           f"e'(0) = {de} rad/s:", 100)
    lines += _matrix(f"dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0))  (derive.control.npid) [{u}]", explicit[:, None])
    lines += _matrix(f"dhat(0) with the implicit observer step, W_dt = W (J + dt W)^-1 J, dt = {dt:g} s [{u}]",
                     implicit[:, None]) + [""]
    over = [f"joint {i + 1}: {abs(explicit[i]):.3g} > {float(m.input_limit):g}" for i, m in enumerate(d.arm.motors)
            if m.input_limit and abs(explicit[i]) > float(m.input_limit)]
    if over:
        lines += textwrap.wrap(f"dhat(0) exceeds the input limit at {'; '.join(over)} {u}: the first command is "
                               "clipped; a reference that starts at the measured pose (e(0) = 0, [simulation] "
                               "reference_start = \"measured\") starts smoothly.", 100) + [""]
    return "\n".join(lines)
