"""Continuous joints: the tracking error on the circle (issue 19 item 5).

A continuous joint's angle q and q - 2 pi are one pose, and encoders and ROS joint states
often report it in (-pi, pi]. The error of an output y = C theta (eq. 13, 20) that moves
with such a joint is therefore taken on the circle: e_i = wrap(yd_i - (C theta)_i) with

    wrap(x) = x + 2 pi floor((pi - x) / (2 pi))   in (-pi, pi],

so that theta_j and theta_j - 2 pi give the same command in every form (u*, the observer's
initial estimate, the PID form's integral, which integrates the wrapped error). The
derivative e' = yd' - C theta' is not wrapped. This is the ``angle_wraparound`` of
ros_controllers for continuous joints, generalised to an output matrix:

* output i is wrapped when some continuous joint j moves it (C[i][j] != 0);
* a turn of joint j moves output i by 2 pi C[i][j], so the command is the same for
  theta_j - 2 pi only when every C[i][j] of a continuous joint is an integer: any other
  entry is refused (no wrapping makes such an output's error single-valued);
* a wrapped output must not also move with a prismatic joint (an angle plus a length
  has no period): refused.

Revolute joints with limits and prismatic joints are never wrapped (their coordinate is
the pose). With C the identity this wraps exactly the continuous joints' own errors.
"""
from __future__ import annotations

import math

import sympy as sp

from derive.errors import Problem, SpecError


def wrap(x: sp.Expr) -> sp.Expr:
    """x + 2 pi floor((pi - x) / (2 pi)): x moved by whole turns into (-pi, pi]."""
    return x + 2 * sp.pi * sp.floor((sp.pi - x) / (2 * sp.pi))


def wrap_numeric(x):
    """:func:`wrap` of a float or numpy array (the same formula, in double)."""
    import numpy as np

    return x + 2 * math.pi * np.floor((math.pi - x) / (2 * math.pi))


def wrapped_outputs(C: sp.Matrix, joints, source: str = "") -> tuple[int, ...]:
    """The 0-based outputs whose error is wrapped, for output matrix ``C`` (n x n, exact) and
    the chain's ``joints`` (derive.model.chain.Joint, base to tip). Raises SpecError naming
    controller.C for a non-integer entry in a continuous joint's column, or a wrapped output
    that a prismatic joint moves too."""
    kinds = [j.type.value for j in joints]
    continuous = [j for j, k in enumerate(kinds) if k == "continuous"]
    if not continuous:
        return ()
    problems = []
    rows = []
    for i in range(C.rows):
        moved = [j for j in continuous if C[i, j] != 0]
        for j in moved:
            if not C[i, j].is_integer:
                problems.append(Problem(
                    f"controller.C[{i + 1}][{j + 1}]",
                    f"an integer (joint {j + 1} '{joints[j].name}' is continuous: a turn of it moves output "
                    f"{i + 1} by 2 pi C[{i + 1}][{j + 1}], which must be whole turns for its error to be wrapped "
                    "to (-pi, pi] so that theta and theta - 2 pi give the same command)",
                    f"{C[i, j]}"))
        if not moved:
            continue
        lengths = [k for k in range(C.cols) if kinds[k] == "prismatic" and C[i, k] != 0]
        if lengths:
            k = lengths[0]
            problems.append(Problem(
                f"controller.C[{i + 1}][{k + 1}]",
                f"0 (output {i + 1} moves with continuous joint {moved[0] + 1} '{joints[moved[0]].name}', so its "
                f"error is an angle wrapped to (-pi, pi]; prismatic joint {k + 1} '{joints[k].name}' would add a "
                "length to it)", f"{C[i, k]}"))
        rows.append(i)
    if problems:
        raise SpecError(source, problems)
    return tuple(rows)
