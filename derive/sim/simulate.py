"""Closed-loop simulation of the paper's experiment (section 5) under the
generated controllers: MPC alone (eq. 15), DOBC (eq. 27) and NPID (eq. 34).

Plant: the arm's own dynamics with what the controller does not know
(derive.model.simspec): Coulomb friction (smoothed, tanh(theta'/0.01)), extra viscous
friction, a heavier tip, a constant input disturbance, optional sensor noise
with the tachometer low-pass filter of section 5.1, the motors' voltage limits.
Integrated with RK4 (``substeps`` per sample) under a zero-order hold on u.

Reference (section 5.2): each link's y_d is the output of
Gr(s) = 1 / (s^2 + 1.8 s + 1) driven by a sampled pulse train of the given
amplitude, starting at the link's start time (before it the link holds 0);
y_d' and y_d'' are the filter's states and its ODE, never differences.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace
from fractions import Fraction

import numpy as np
import sympy as sp

from derive.sim.backends import Backend
from derive.dynamics.planar import derive_dynamics
from derive.control.pipeline import Derivation
from derive.model.simspec import SimSettings
from derive.model.spec import Arm

CONTROLLERS = ("mpc", "dobc", "npid")
VARIANTS = {"mpc": ("mpc", True), "dobc": ("dobc", True), "npid": ("npid", True),
            "npid_unprotected": ("npid", False),   # form, limits known to the controller
            "dobc_zero_init": ("dobc", True)}      # dhat(0) = 0 instead of the derived estimate
SMOOTH = 0.01  # rad/s: width of the tanh that smooths Coulomb friction


def true_arm(arm: Arm, s: SimSettings) -> Arm:
    """The plant's arm: the last link's point masses scaled by payload_scale."""
    scale = Fraction(repr(s.payload_scale))
    masses = tuple(replace(p, mass=p.mass * scale) if p.link == arm.n - 1 else p for p in arm.point_masses)
    return replace(arm, point_masses=masses)


class Plant:
    """x' = f(x, u) for x = (theta, theta'), the true arm with friction."""

    def __init__(self, arm: Arm, s: SimSettings):
        dyn = derive_dynamics(true_arm(arm, s))
        rep = dict(dyn.params.values)
        args = list(dyn.sym.theta + dyn.sym.dtheta)
        n = self.n = arm.n
        exprs = list(dyn.J.xreplace(rep)) + list(dyn.G.xreplace(rep))
        self._jg = sp.lambdify(args, exprs, modules="math", cse=True)
        self.B = np.array(dyn.B.xreplace(rep).tolist(), dtype=float).diagonal()
        self.coulomb = np.array(s.coulomb_friction)
        self.viscous = np.array(s.viscous_friction)
        self.d = np.array(s.disturbance)
        self.u_max = np.array([float(m.input_limit) if m.input_limit else math.inf for m in arm.motors])
        self._n2 = n * n

    def accel(self, q: np.ndarray, dq: np.ndarray, u: np.ndarray) -> np.ndarray:
        vals = self._jg(*q, *dq)
        J = np.array(vals[: self._n2]).reshape(self.n, self.n)
        G = np.array(vals[self._n2:])
        friction = self.coulomb * np.tanh(dq / SMOOTH) + self.viscous * dq
        return np.linalg.solve(J, self.B * (u + self.d) - G - friction)


@dataclass(frozen=True)
class Trace:
    """One controller's run: sample times (k), per-sample arrays (k x n)."""

    name: str
    t: np.ndarray
    theta: np.ndarray
    dtheta: np.ndarray
    yd: np.ndarray
    u: np.ndarray
    dhat: np.ndarray | None
    saturated: np.ndarray


def pulse(t: float, start: float, period: float, amplitude: float) -> float:
    """Pulse train: amplitude in the first half of each period after start."""
    if t < start:
        return 0.0
    return amplitude if ((t - start) % period) < period / 2 else 0.0


def run(d: Derivation, backend: Backend, plant: Plant, s: SimSettings, name: str,
        progress: bool = False) -> Trace:
    """Simulate one controller variant (see VARIANTS) for ``s.duration`` seconds."""
    form, protected = VARIANTS[name]
    n, dt = d.n, s.sample_time
    limits = [float(m.input_limit) if (m.input_limit and protected) else 0.0 for m in d.arm.motors]
    ctl = backend.controller(form, limits)
    steps = int(round(s.duration / dt))
    amp = math.radians(s.amplitude_deg)
    rng = np.random.default_rng(s.seed)
    alpha = 1.0 - math.exp(-2 * math.pi * s.tacho_filter_hz * dt) if s.tacho_filter_hz > 0 else 1.0
    W = np.array(d.W.tolist(), dtype=float)
    Binv = 1.0 / np.array(d.B.tolist(), dtype=float).diagonal()
    x = np.concatenate([np.array(s.initial_theta, dtype=float), np.zeros(n)])  # plant state, at rest
    f = np.zeros(2 * n)            # reference filter states (y, y') per link
    dq_filtered = np.zeros(n)
    out = {k: np.zeros((steps, n)) for k in ("theta", "dtheta", "yd", "u", "dhat", "sat")}
    h = dt / s.substeps
    for k in range(steps):
        t = k * dt
        r = np.array([pulse(t, s.start[i], s.pulse_period, amp) for i in range(n)])
        yd, dyd = f[:n], f[n:]
        ddyd = r - 1.8 * dyd - yd
        q_meas = x[:n] + rng.normal(0.0, 1.0, n) * np.array(s.position_noise)
        dq_meas = x[n:] + rng.normal(0.0, 1.0, n) * np.array(s.velocity_noise)
        dq_filtered = dq_meas if k == 0 else dq_filtered + alpha * (dq_meas - dq_filtered)
        inp = np.concatenate([q_meas, dq_filtered, yd, dyd, ddyd])
        if k == 0:
            ctl.init(inp)
            if name == "dobc_zero_init":  # z(0) = B dhat(0) - W theta'(0) with dhat(0) = 0 (eq. 22)
                ctl.state = list(-(W @ dq_filtered))
        if form == "dobc":  # the estimate this step uses (eq. 22)
            out["dhat"][k] = Binv * (np.array(ctl.state) + W @ dq_filtered)
        u = np.clip(ctl.step(inp, dt), -plant.u_max, plant.u_max)  # the amplifier saturates anyway
        out["theta"][k], out["dtheta"][k], out["yd"][k], out["u"][k] = x[:n], x[n:], yd, u
        out["sat"][k] = np.abs(u) >= plant.u_max * (1 - 1e-12)
        for _ in range(s.substeps):
            x, f = _rk4(plant, x, f, u, r, h)
        if progress and k % max(1, steps // 20) == 0:
            print(f"\rsimulating {name}: {100 * k // steps:3d}%", end="", file=sys.stderr, flush=True)
    if progress:
        print(f"\rsimulating {name}: 100%", file=sys.stderr)
    t = np.arange(steps) * dt
    return Trace(name, t, out["theta"], out["dtheta"], out["yd"], out["u"],
                 out["dhat"] if form == "dobc" else None, out["sat"].astype(bool))


def _rk4(plant: Plant, x, f, u, r, h):
    n = plant.n

    def deriv(x, f):
        return (np.concatenate([x[n:], plant.accel(x[:n], x[n:], u)]),
                np.concatenate([f[n:], r - 1.8 * f[n:] - f[:n]]))

    k1 = deriv(x, f)
    k2 = deriv(x + h / 2 * k1[0], f + h / 2 * k1[1])
    k3 = deriv(x + h / 2 * k2[0], f + h / 2 * k2[1])
    k4 = deriv(x + h * k3[0], f + h * k3[1])
    return (x + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]),
            f + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]))


def metrics(trace: Trace, s: SimSettings) -> list[dict[str, float]]:
    """Per link: rms_error, max_error, steady_state_error [rad], control_effort
    (RMS voltage) [V], saturated_time [s]. steady_state_error is the mean |e| over
    the last 20% of each half-period of the pulse train (the settled parts)."""
    e = trace.yd - trace.theta
    out = []
    half = s.pulse_period / 2
    for i in range(e.shape[1]):
        phase = (trace.t - s.start[i]) % half
        settled = (trace.t >= s.start[i]) & (phase >= 0.8 * half)
        if i > 0:  # before its start the link must hold still: that counts as settled too
            settled |= (trace.t < s.start[i]) & (trace.t >= 0.8 * s.start[i])
        ei = np.abs(e[:, i])
        out.append({"rms_error": float(np.sqrt(np.mean(ei ** 2))), "max_error": float(np.max(ei)),
                    "steady_state_error": float(np.mean(ei[settled])) if settled.any() else float("nan"),
                    "control_effort": float(np.sqrt(np.mean(trace.u[:, i] ** 2))),
                    "saturated_time": float(np.sum(trace.saturated[:, i]) * s.sample_time)})
    return out
