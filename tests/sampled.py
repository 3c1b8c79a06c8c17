"""The sampled closed loop simulated at one operating point, to hold the sample-time analysis
(derive.control.sampling) against the generated controller.

The plant is the arm's own model (no friction, no disturbance, no input limit), integrated by
RK4 (8 substeps) under a zero-order hold; the controller is the generated Python module of the
derivation (derive.sim.backends), stepped as ``derive simulate`` steps it. The loop starts at the
operating point (theta0, theta0') with the reference moving with it, y_d = C (theta0 + theta0' t),
y_d' = C theta0', y_d'' = 0: at rest, and along a relative equilibrium (a joint on which J and G do
not depend spinning at a constant speed: joint 1 of a horizontal arm), that reference is followed
exactly, so the loop's linearisation there is the time-invariant one the analysis computes. Two
runs go in lockstep, one from the point and one from the point with every angle moved by
``offset``; the growth of their difference tells whether the loop is stable there.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from derive.errors import DeriveError
from derive.sim.plant import Plant, true_plant


def nominal_plant(d) -> Plant:
    """The derivation's own plant: no friction, no disturbance, no payload change."""
    n = d.n
    s = replace(d.arm.simulation, coulomb_friction=(0.0,) * n, viscous_friction=(0.0,) * n, payload_scale=1.0,
                disturbance=(0.0,) * n, link_mass_scale=(1.0,) * n)
    return Plant(d, true_plant(d, s))


def growth(d, backend, plant: Plant, form: str, dt: float, q0, dq0, steps: int, offset: float = 1e-6) -> float:
    """max |theta_perturbed - theta_nominal| over the last fifth of ``steps`` samples, over ``offset``;
    inf when a run diverges or a controller refuses a sample."""
    n = d.n
    C = np.array(d.C.tolist(), dtype=float)
    q0, dq0 = np.asarray(q0, dtype=float), np.asarray(dq0, dtype=float)
    x = np.array([np.concatenate([q0, dq0]), np.concatenate([q0 + offset, dq0])])
    ctls = [backend.controller(form, [0.0] * n) for _ in range(2)]
    h = dt / 8
    diffs = []
    with np.errstate(all="ignore"):
        for k in range(steps):
            t = k * dt
            ref = np.concatenate([C @ (q0 + dq0 * t), C @ dq0, np.zeros(n)])
            u = np.zeros((2, n))
            try:
                for row, ctl in enumerate(ctls):
                    inp = np.concatenate([x[row], ref])
                    if k == 0:
                        ctl.init(inp, dt)
                    u[row] = ctl.step(inp, dt)
            except DeriveError:
                return np.inf
            for _ in range(8):
                x = _rk4(plant, x, u, h)
            diff = float(np.max(np.abs(x[1, :n] - x[0, :n])))
            if not np.isfinite(diff) or diff > 1.0:
                return np.inf
            diffs.append(diff)
    return max(diffs[-max(1, steps // 5):]) / offset


def _rk4(plant: Plant, x: np.ndarray, u: np.ndarray, h: float) -> np.ndarray:
    n = plant.n

    def f(x):
        return np.concatenate([x[:, n:], plant.accel(x[:, :n], x[:, n:], u)], axis=1)

    k1 = f(x)
    k2 = f(x + h / 2 * k1)
    k3 = f(x + h / 2 * k2)
    k4 = f(x + h * k3)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
