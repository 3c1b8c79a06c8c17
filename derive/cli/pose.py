"""``derive show ARM --at theta=...,dtheta=...``: the plant's numbers at one pose.

J(theta), G(theta, theta'), gravity g(theta), B, the free acceleration theta''
(u = d = 0) and the PID gains P(theta), D(theta) (eq. 12, 35-36), evaluated by the
40-digit reference of the derivation (derive.codegen.reference) and printed
with 6 significant digits.
"""
from __future__ import annotations

import math
import re

import numpy as np

from derive.control.pipeline import Derivation
from derive.errors import DeriveError

_ITEM = re.compile(r"(theta|dtheta)=([^=]*?)(?=,(?:theta|dtheta)=|$)")


def parse_pose(text: str, n: int) -> tuple[list[float], list[float]]:
    """(theta, theta') from ``theta=a,b,...,dtheta=c,d,...`` (radians, rad/s;
    theta' defaults to zeros). One DeriveError naming the option otherwise."""
    expected = f"theta=<{n} numbers>[,dtheta=<{n} numbers>] (rad, rad/s), e.g. theta={','.join(['0.1'] * n)}"
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
            if len(theta) == n and len(dtheta) == n and all(map(math.isfinite, theta + dtheta)):
                return theta, dtheta
    raise DeriveError(f"--at: expected {expected}, got {text!r}")


def _matrix(name: str, m: np.ndarray) -> list[str]:
    rows = np.atleast_2d(m)
    width = max(len(f"{x:.6g}") for x in rows.ravel())
    lines = [f"{name} ="]
    lines += ["  [" + "  ".join(f"{x:>{width}.6g}" for x in row) + "]" for row in rows]
    return lines


def pose_text(d: Derivation, theta: list[float], dtheta: list[float]) -> str:
    """The numbers at one pose, readable at 100 columns."""
    from derive.codegen.reference import Reference

    ref = Reference(d)
    n = d.n
    f = lambda v: np.array([float(x) for x in v])  # noqa: E731
    zero = [0.0] * n
    lines = [f"{d.arm.name} at theta = {theta} rad, dtheta = {dtheta} rad/s", ""]
    blocks = [
        ("J(theta)  (eq. 12) [kg m^2]", f(ref.mass_matrix(theta)).reshape(n, n)),
        ("G(theta, dtheta)  (eq. 12) [N m]", f(ref.bias(theta, dtheta))[:, None]),
        ("g(theta), gravity torques [N m]", f(ref.gravity(theta))[:, None]),
        ("B  (eq. 12) [N m/V]", f(ref.input_matrix()).reshape(n, n)),
        ("ddtheta at u = d = 0  (J ddtheta = -G) [rad/s^2]",
         f(ref.forward_dynamics(theta, dtheta, zero, zero))[:, None]),
    ]
    gains = f(ref.gains(theta))
    blocks += [("P(theta)  (eq. 35) [V/rad]", gains[: n * n].reshape(n, n)),
               ("D(theta)  (eq. 36) [V s/rad]", gains[n * n: 2 * n * n].reshape(n, n))]
    for title, m in blocks:
        lines += _matrix(title, m) + [""]
    return "\n".join(lines)
