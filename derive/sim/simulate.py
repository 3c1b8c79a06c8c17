"""Closed-loop simulation of the paper's experiment (section 5) under the
generated controllers: MPC alone (eq. 15), DOBC (eq. 27) and NPID (eq. 34).

Plant: the arm's own dynamics with what the controller does not know
(derive.model.simspec): Coulomb friction (smoothed, tanh(theta'/eps), eps each joint's
coulomb_smoothing), extra viscous friction, a heavier tip, a constant input disturbance, optional sensor noise
with the tachometer low-pass filter of section 5.1, the motors' voltage limits.
Integrated with RK4 (``substeps`` per sample) under a zero-order hold on u.

Reference (section 5.2): each link's y_d is the output of
Gr(s) = 1 / (s^2 + 1.8 s + 1) driven by a sampled pulse train of the given
amplitude, starting at the link's start time (before it the link holds 0);
y_d' and y_d'' are the filter's states and its ODE, never differences. With
reference_start = "measured" y_d starts at the initial pose C theta(0) and the
pulse train is added to it (derive.sim.start).

Two loops run the same experiment: :func:`run_compiled` (the whole loop in C,
derive.sim.compiled: the default) and :func:`run_many` (the Python-stepped
reference, one numpy row per controller variant); they agree to 1e-9
(tests/test_compiled_loop.py). Either runs any plant of derive.sim.plants (this
derivation's, or MuJoCo's: :func:`run_compiled_with`, a SteppedPlant). A controller that refuses a sample ends its run
with a :class:`Failure` (time, error, joint, likely cause); the others go on.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from derive.errors import DeriveError
from derive.jsonio import Undefined
from derive.control.pipeline import Derivation
from derive.control.sampling.wrap import wrap_numeric
from derive.dynamics.program import lambdify
from derive.sim.backends import ControllerError
from derive.model.simspec import SimSettings, pulse_amplitudes
from derive.progress import progress
from derive.sim.plant import SMOOTH, Plant, TruePlant, true_plant  # noqa: F401 (re-exported)
from derive.sim.start import reference_offset

CONTROLLERS = ("mpc", "dobc", "npid", "mom")   # derive simulate's default list
VARIANTS = {"mpc": ("mpc", True), "dobc": ("dobc", True), "npid": ("npid", True),
            "npid_unprotected": ("npid", False),   # form, limits known to the controller
            "dobc_zero_init": ("dobc", True),      # dhat(0) = 0 instead of the derived estimate
            "mom": ("mom", True)}                  # the generalized-momentum observer (derive.control.momentum)
ERRORS = {1: "a non-finite input, state or result (ENONFINITE)", 2: "a bad sample time (EDT)"}


@dataclass(frozen=True)
class Failure:
    """Where and why a run stopped: the controller refused a sample."""

    time: float          # s
    step: int
    code: int
    error: str           # what the code means
    joint: int | None    # 1-based joint that went non-finite or moved fastest
    cause: str           # the likely cause, in words
    inputs: tuple[float, ...]  # theta, theta', yd, yd', yd'' it refused

    def message(self, name: str) -> str:
        joint = f" at joint {self.joint}" if self.joint is not None else ""
        return (f"{name}: the controller step returned {self.code} ({self.error}) at t = {self.time:.4g} s "
                f"(sample {self.step}){joint}; likely cause: {self.cause}")


@dataclass(frozen=True)
class Trace:
    """One controller's run: sample times (k), per-sample arrays (k x n); cut
    at ``failure`` when the controller refused a sample."""

    name: str
    t: np.ndarray
    theta: np.ndarray
    dtheta: np.ndarray
    yd: np.ndarray
    u: np.ndarray
    dhat: np.ndarray | None
    saturated: np.ndarray
    failure: Failure | None = None
    e: np.ndarray | None = None   # the tracking error yd - C theta (k x n), wrapped as the controllers wrap it

    @property
    def error(self) -> np.ndarray:
        """e = yd - C theta per sample (k x n): a continuous joint's output wrapped to (-pi, pi]
        (derive.control.sampling.wrap), as the generated controllers compute it."""
        return self.e if self.e is not None else self.yd - self.theta


def pulse(t: float, start: float, period: float, amplitude: float) -> float:
    """Pulse train: amplitude in the first half of each period after start."""
    if t < start:
        return 0.0
    return amplitude if ((t - start) % period) < period / 2 else 0.0


def pulses(s: SimSettings, n: int, steps: int) -> np.ndarray:
    """The sampled pulse trains r (steps x n), equal to :func:`pulse` at t = k dt, each joint's of its
    amplitude (derive.model.simspec.pulse_amplitudes: rad, m prismatic)."""
    t = np.arange(steps) * s.sample_time
    amp = pulse_amplitudes(s, n)
    r = np.zeros((steps, n))
    for i in range(n):
        on = (t >= s.start[i]) & (np.mod(t - s.start[i], s.pulse_period) < s.pulse_period / 2)
        r[on, i] = amp[i]
    return r


def noise(s: SimSettings, n: int, steps: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Position and velocity noise (steps x n each), the draws of the reference
    loop (rng.normal(0, 1, n) for theta then theta' at every sample); None when zero."""
    if not (any(s.position_noise) or any(s.velocity_noise)):
        return None, None
    draws = np.random.default_rng(s.seed).normal(0.0, 1.0, (steps, 2, n))
    return draws[:, 0, :] * np.array(s.position_noise), draws[:, 1, :] * np.array(s.velocity_noise)


def tacho_alpha(s: SimSettings) -> float:
    """Gain of the first-order tachometer filter at the sample time (1 = no filter)."""
    return 1.0 - math.exp(-2 * math.pi * s.tacho_filter_hz * s.sample_time) if s.tacho_filter_hz > 0 else 1.0


def diagnose(d: Derivation, s: SimSettings, name: str, step: int, code: int, inputs) -> Failure:
    """A failure named: time, error, joint, and the likely cause (the observer's
    forward Euler step unstable at this sample time, the arm driven off, ...)."""
    n = d.n
    x = np.array(inputs, dtype=float)
    bad = [i for i in range(n) if not (np.isfinite(x[i]) and np.isfinite(x[n + i]))]
    if bad:
        joint = bad[0] + 1
    else:
        joint = int(np.argmax(np.abs(x[n:2 * n]))) + 1
    causes = []
    form = VARIANTS.get(name, (name, True))[0]
    if not bad:
        J = np.array(lambdify(d.theta, d.J)(*x[:n]), dtype=float)
        W = np.array(d.W.tolist(), dtype=float)
        rho = float(max(abs(np.linalg.eigvals(W @ np.linalg.inv(J)))))
        gains = [float(dict(d.values)[k]) for k in d.momentum.k]
        if form == "mom" and max(gains) * s.sample_time >= 2:
            causes.append(f"the sample time {s.sample_time:g} s is too long for the momentum observer: dt K = "
                          f"{max(gains) * s.sample_time:.3g} >= 2, so its forward Euler step of m is unstable; use "
                          f"sample_time < {2 / max(gains):.3g} s or a smaller controller.momentum_gain")
        elif form == "dobc" and rho * s.sample_time >= 2:
            causes.append(f"the sample time {s.sample_time:g} s is too long for the observer: dt times the "
                          f"spectral radius of L = W J^-1 is {rho * s.sample_time:.3g} >= 2 at this pose, so its "
                          f"forward Euler step (eq. 21) is unstable; use sample_time < {2 / rho:.3g} s or smaller w")
        elif rho * s.sample_time >= 1:
            causes.append(f"the sample time {s.sample_time:g} s is long for the observer (dt times the spectral "
                          f"radius of W J^-1 is {rho * s.sample_time:.3g}); try a shorter sample_time")
    speed = float(np.max(np.abs(x[n:2 * n]))) if not bad else math.inf
    if bad or speed > 100:
        causes.append(f"the arm was driven off (joint {joint} at {speed:.3g} rad/s): the closed loop is unstable "
                      "at this sample time or under these limits")
    if not causes:
        causes.append("the control law's result was not finite at this input (a singular pose or an "
                      "unstable closed loop)")
    return Failure(time=step * s.sample_time, step=step, code=code, error=ERRORS.get(code, f"code {code}"),
                   joint=joint, cause="; ".join(causes), inputs=tuple(float(v) for v in x))


def tracking_error(d: Derivation, yd: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """e = yd - C theta (eq. 20) per sample (k x n), the outputs ``d.wrapped`` (moved by a continuous
    joint) wrapped to (-pi, pi] as the generated controllers wrap them (derive.control.sampling.wrap)."""
    e = yd - theta @ np.array(d.C.tolist(), dtype=float).T
    for i in d.wrapped:
        e[:, i] = wrap_numeric(e[:, i])
    return e


def _trace(name: str, s: SimSettings, u_max, form: str, theta, dtheta, yd, u, dhat,
           failure: Failure | None, d: Derivation) -> Trace:
    u_max = np.asarray(u_max, dtype=float)
    t = np.arange(len(theta)) * s.sample_time
    sat = np.abs(u) >= u_max * (1 - 1e-12)
    return Trace(name, t, theta, dtheta, yd, u, dhat if form in ESTIMATES else None, sat.astype(bool), failure,
                 tracking_error(d, yd, theta))


ESTIMATES = ("dobc", "mom")   # the forms whose traces carry the disturbance estimate each step used


def momentum_estimate(d: Derivation):
    """f(theta, theta', m) -> dhat = B^-1 K (J(theta) theta' - m) of the momentum observer
    (derive.control.momentum) for rows (k, n) of measured angles, velocities and states
    (k, n): what <arm>_mom_estimate returns, in double."""
    n = d.n
    J = lambdify(list(d.theta), list(d.J))   # each shared subexpression once, over arrays
    values = dict(d.values)
    gain = np.array([float(values[k]) for k in d.momentum.k]) / np.array(d.B.tolist(), dtype=float).diagonal()

    def f(theta, dtheta, m) -> np.ndarray:
        theta, dtheta, m = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (theta, dtheta, m))
        k = theta.shape[0]
        Jk = np.stack([np.broadcast_to(np.asarray(v, dtype=float), (k,)) for v in J(*theta.T)], axis=-1)
        return gain * (np.einsum("kij,kj->ki", Jk.reshape(k, n, n), dtheta) - m)
    return f


def run(d: Derivation, backend, plant, s: SimSettings, name: str, show: bool = False) -> Trace:
    """The Python-stepped reference run of one controller variant (see :func:`run_many`)."""
    return run_many(d, backend, plant, s, [name], show)[name]


def run_many(d: Derivation, backend, plant, s: SimSettings, names, show: bool = False) -> dict[str, Trace]:
    """The Python-stepped reference: simulate controller variants (see VARIANTS)
    for ``s.duration`` seconds, the controllers of ``backend`` (python or c) called
    once per sample, the plants (a :class:`derive.sim.plants.SteppedPlant`: derive's
    :class:`Plant`, integrated by numpy, or MuJoCo's) stepped in lockstep, one row per
    variant (each row does exactly the arithmetic of a run of its own). ``show``:
    a progress bar on a terminal (derive.progress)."""
    n, dt = d.n, s.sample_time
    runs = []
    for name in names:
        form, protected = VARIANTS[name]
        limits = [float(m.input_limit) if (m.input_limit and protected) else 0.0 for m in d.arm.motors]
        runs.append((name, form, backend.controller(form, limits)))
    steps = int(round(s.duration / dt))
    rng = np.random.default_rng(s.seed)
    alpha = tacho_alpha(s)
    W = np.array(d.W.tolist(), dtype=float)
    Binv = 1.0 / np.array(d.B.tolist(), dtype=float).diagonal()
    mom_dhat = momentum_estimate(d) if any(form == "mom" for _, form, _ in runs) else None
    y0 = reference_offset(d, s)    # y_d(0): 0, or the initial pose (simulation.reference_start)
    r_all = pulses(s, n, steps) + y0
    rows = len(runs)
    plant.reset(np.array(s.initial_theta, dtype=float), rows)   # at rest
    f = np.concatenate([y0, np.zeros(n)])   # reference filter states (y, y') per link, the same for every run
    dq_filtered = np.zeros((rows, n))
    out = {k: np.zeros((rows, steps, n)) for k in ("theta", "dtheta", "yd", "u", "dhat")}
    ended = [steps] * rows
    failures: list[Failure | None] = [None] * rows
    live = list(range(rows))       # rows of x that still run, in order
    h = dt / s.substeps
    bar = progress(total=steps, desc=f"simulating {', '.join(names)}", unit="sample", disable_bar=not show)
    for k in range(steps):
        bar.update()
        r = r_all[k]
        yd, dyd = f[:n], f[n:]
        ddyd = r - 1.8 * dyd - yd
        theta, dtheta = plant.theta, plant.dtheta
        q_meas = theta + rng.normal(0.0, 1.0, n) * np.array(s.position_noise)
        dq_meas = dtheta + rng.normal(0.0, 1.0, n) * np.array(s.velocity_noise)
        dq_filtered = dq_meas if k == 0 else dq_filtered + alpha * (dq_meas - dq_filtered)
        u = np.zeros((len(live), n))
        dead = []
        for row, j in enumerate(live):
            name, form, ctl = runs[j]
            inp = np.concatenate([q_meas[row], dq_filtered[row], yd, dyd, ddyd])
            try:
                if k == 0:
                    ctl.init(inp, dt)
                    if name == "dobc_zero_init":  # z(0) = B dhat(0) - W theta'(0) with dhat(0) = 0 (eq. 22)
                        ctl.state = list(-(W @ dq_filtered[row]))
                if form == "dobc":  # the estimate this step uses (eq. 22)
                    out["dhat"][j, k] = Binv * (np.array(ctl.state) + W @ dq_filtered[row])
                elif form == "mom":  # r = K (J theta' - m), dhat = B^-1 r (derive.control.momentum)
                    out["dhat"][j, k] = mom_dhat(q_meas[row], dq_filtered[row], ctl.state)[0]
                u[row] = np.clip(ctl.step(inp, dt), -plant.u_max, plant.u_max)  # the amplifier saturates anyway
            except ControllerError as exc:
                failures[j], ended[j] = diagnose(d, s, name, k, exc.code, inp), k
                dead.append(row)
                continue
            out["theta"][j, k], out["dtheta"][j, k], out["yd"][j, k], out["u"][j, k] = theta[row], dtheta[row], yd, u[row]
        if dead:
            keep = [row for row in range(len(live)) if row not in dead]
            live, u, dq_filtered = [live[row] for row in keep], u[keep], dq_filtered[keep]
            plant.keep(keep)
            if not live:
                break
        plant.step(u, dt, s.substeps)
        for _ in range(s.substeps):
            f = _reference_rk4(f, r, h)
    bar.close()
    return {name: _trace(name, s, plant.u_max, form, *(out[key][j, :ended[j]] for key in ("theta", "dtheta", "yd",
                                                                                          "u", "dhat")),
                         failures[j], d)
            for j, (name, form, _) in enumerate(runs)}


def run_compiled(d: Derivation, loop, plant: TruePlant, s: SimSettings, name: str) -> Trace:
    """One controller variant in compiled code (derive.sim.compiled): the same
    run as :func:`run`, with the whole loop in C and Python called once."""
    from derive.sim.compiled import run_loop

    with_payload = getattr(loop, "payload", False)
    if plant.has_payload and not with_payload:
        raise DeriveError(f"compiled simulation: expected a loop built with the payload's J_p and G_p for a plant "
                          f"carrying {plant.payload[0]:g} kg ([simulation] payload_mass), got one built without "
                          "(derive.sim.plants.build(..., payload=True))")
    values = plant.vector(with_payload)

    def call(form, protected, *rest, f0=None):
        return run_loop(loop, form, protected, values, plant.coulomb, plant.viscous, plant.disturbance,
                        plant.u_max, *rest, f0=f0, smoothing=plant.widths)
    return run_compiled_with(d, loop, plant.u_max, s, name, call)


def run_compiled_with(d: Derivation, loop, u_max, s: SimSettings, name: str, call) -> Trace:
    """One controller variant through a compiled loop ``call(form, protected, r, nq, ndq,
    alpha, x0, state0, dt, substeps, f0=...) -> derive.sim.compiled.RawRun`` of any plant
    (derive.sim.plants): inputs prepared and the trace made as :func:`run_compiled` does."""
    form, protected = VARIANTS[name]
    n, dt = d.n, s.sample_time
    steps = int(round(s.duration / dt))
    nq, ndq = noise(s, n, steps)
    x0 = np.concatenate([np.array(s.initial_theta, dtype=float), np.zeros(n)])
    W = np.array(loop.W)
    state0 = None
    if name == "dobc_zero_init":  # z(0) = -W theta'_measured(0), as the reference sets it
        state0 = -(W @ (x0[n:] + (ndq[0] if ndq is not None else 0.0)))
    y0 = reference_offset(d, s)    # y_d(0): 0, or the initial pose (simulation.reference_start)
    raw = call(form, protected, pulses(s, n, steps) + y0, nq, ndq, tacho_alpha(s), x0, state0, dt, s.substeps,
               f0=np.concatenate([y0, np.zeros(n)]))
    dhat = np.array(loop.Binv) * (raw.state + raw.filtered @ W.T) if form == "dobc" else None
    if form == "mom":
        measured = raw.theta + (nq[:len(raw.theta)] if nq is not None else 0.0)
        dhat = momentum_estimate(d)(measured, raw.filtered, raw.state)
    failure = diagnose(d, s, name, raw.fail_step, raw.code, raw.fail_input) if raw.code else None
    return _trace(name, s, u_max, form, raw.theta, raw.dtheta, raw.yd, raw.u, dhat, failure, d)


def _reference_rk4(f: np.ndarray, r: np.ndarray, h: float) -> np.ndarray:
    """One RK4 step of the reference filter f = (y_d, y_d') (2n), r held (section 5.2)."""
    n = len(f) // 2

    def deriv(f):
        return np.concatenate([f[n:], r - 1.8 * f[n:] - f[:n]])

    k1 = deriv(f)
    k2 = deriv(f + h / 2 * k1)
    k3 = deriv(f + h / 2 * k2)
    k4 = deriv(f + h * k3)
    return f + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def metrics(trace: Trace, s: SimSettings) -> list[dict[str, float | Undefined]]:
    """Per link: rms_error, max_error, steady_state_error [rad] of e = yd - C theta (Trace.error),
    control_effort (RMS of u) [V, or N m in torque mode], saturated_time [s]. steady_state_error is the mean |e| over
    the last 20% of each half-period of the pulse train (the settled parts); a figure
    that has no value (no settled sample in a short run, a non-finite trace) is an
    :class:`~derive.jsonio.Undefined` with the reason, never NaN."""
    e = trace.error
    out = []
    half = s.pulse_period / 2
    end = float(trace.t[-1]) if len(trace.t) else 0.0
    for i in range(e.shape[1]):
        phase = (trace.t - s.start[i]) % half
        settled = (trace.t >= s.start[i]) & (phase >= 0.8 * half)
        first = s.start[i] + 0.8 * half
        if i > 0:  # before its start the link must hold still: that counts as settled too
            settled |= (trace.t < s.start[i]) & (trace.t >= 0.8 * s.start[i])
            first = min(first, 0.8 * s.start[i]) if s.start[i] > 0 else first
        ei = np.abs(e[:, i])
        figures = {"rms_error": float(np.sqrt(np.mean(ei ** 2))), "max_error": float(np.max(ei)),
                   "steady_state_error": float(np.mean(ei[settled])) if settled.any() else Undefined(
                       f"no settled sample: the run ends at t = {end:g} s, before link {i + 1}'s first settled "
                       f"part (the last 20% of a half-period of the pulse train) begins at t = {first:g} s"),
                   "control_effort": float(np.sqrt(np.mean(trace.u[:, i] ** 2))),
                   "saturated_time": float(np.sum(trace.saturated[:, i]) * s.sample_time)}
        out.append({key: Undefined(f"not finite ({x}): the trace holds non-finite values")
                    if isinstance(x, float) and not math.isfinite(x) else x for key, x in figures.items()})
    return out
