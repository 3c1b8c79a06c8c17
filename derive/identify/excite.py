"""Excitation trajectories: a finite Fourier series per joint, optimised for the condition
number of the stacked regressor within the joint limits (derive excite).

J. Swevers, C. Ganseman, D. B. Tukel, J. De Schutter, H. Van Brussel, "Optimal robot
excitation and identification", IEEE Trans. Robotics and Automation 13(5), 1997:

    q_i(t)   = q0_i + sum_l  a_il / (w l) sin(w l t) - b_il / (w l) cos(w l t)
    q'_i(t)  =        sum_l  a_il cos(w l t) + b_il sin(w l t)
    q''_i(t) =        sum_l  w l (b_il cos(w l t) - a_il sin(w l t)),   l = 1..L, w = 2 pi / P.

Periodic with period P, so the trajectory ends where it starts; at rest at t = 0 (and
every multiple of P) when sum_l a_il = 0 and sum_l l b_il = 0, which fix a_i1 and b_i1.
The limits hold at every instant by construction, through the bounds
|q - q0| <= sum_l r_l / (w l), |q'| <= sum_l r_l, |q''| <= w sum_l l r_l with
r_l = sqrt(a_l^2 + b_l^2) (Swevers' constraints). The coefficients minimise
log cond(W), W the regressor of the base parameters stacked at samples over one
period (SLSQP from a seeded start; gradient by forward differences of W, all
perturbations in one batch): deterministic for a seed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize
from threadpoolctl import threadpool_limits

from derive.errors import DataError
from derive.identify import HARMONICS
from derive.identify.regressor import Regressor
from derive.model.chain import Chain

MAX_PERIOD = 10.0           # s: the fundamental period is duration / k <= this
VELOCITY = {"rad": 2.0, "m": 0.5}           # rad/s, m/s when neither the file nor the command gives one
ACCELERATION = {"rad": 5.0, "m": 2.0}       # rad/s^2, m/s^2 (URDF has no acceleration limits)
POSITION = {"rad": math.pi, "m": 0.1}       # +- this when the file gives no position limits
EPS = 1e-9                                  # smooths sqrt(a^2 + b^2) at 0 (the bound only grows)


@dataclass(frozen=True)
class JointLimits:
    """One joint's limits for the excitation and where each came from."""

    name: str
    unit: str              # "rad" or "m"
    lower: float
    upper: float
    velocity: float
    acceleration: float
    sources: tuple[str, str, str]    # position, velocity, acceleration


def excitation_limits(chain: Chain, speeds=None, velocity=None, acceleration=None) -> tuple[JointLimits, ...]:
    """Each joint's limits: position and velocity from the URDF's <limit> (or the arm file's
    controller.max_joint_speed), ``velocity``/``acceleration`` (n numbers, from the command
    line) override; else the stated defaults. A URDF velocity of 0 is no limit (derive.model.urdf
    reads it as None, as every command does). DataError when a limit cannot be met (not > 0,
    an empty position range), naming the option that overrides it."""
    out, problems = [], []
    for i, j in enumerate(chain.joints):
        unit = "rad" if j.type.rotates else "m"
        lim = j.limits
        if lim.lower is not None and lim.upper is not None:
            lo, hi, src_p = float(lim.lower), float(lim.upper), f"{j.field} <limit lower/upper>"
        else:
            lo, hi, src_p = -POSITION[unit], POSITION[unit], f"default +-{POSITION[unit]:g} {unit}"
        if velocity is not None:
            v, src_v = float(velocity[i]), "--velocity-limit"
        elif lim.velocity is not None:
            v, src_v = float(lim.velocity), f"{j.field} <limit velocity>"
        elif speeds is not None:
            v, src_v = float(speeds[i]), f"controller.max_joint_speed[{i + 1}]"
        else:
            v, src_v = VELOCITY[unit], f"default {VELOCITY[unit]:g} {unit}/s"
        if acceleration is not None:
            a, src_a = float(acceleration[i]), "--acceleration-limit"
        else:
            a, src_a = ACCELERATION[unit], f"default {ACCELERATION[unit]:g} {unit}/s^2"
        label = f"joint {i + 1} ({j.name!r})"
        if not hi > lo:
            problems.append(f"{label}: position limits [{lo:g}, {hi:g}] {unit} ({src_p}): expected lower < upper")
        for what, x, src, u in (("velocity", v, src_v, f"{unit}/s"), ("acceleration", a, src_a, f"{unit}/s^2")):
            if not (math.isfinite(x) and x > 0):
                option = f"--{what}-limit"
                problems.append(f"{label}: {what} limit {x:g} {u} ({src}): expected a finite number > 0 "
                                "(the joint must move to be excited)"
                                + ("" if src == option else f"; {option} gives another"))
        out.append(JointLimits(j.name, unit, lo, hi, v, a, (src_p, src_v, src_a)))
    if problems:
        raise DataError("excitation limits that cannot be met:\n  - " + "\n  - ".join(problems))
    return tuple(out)


@dataclass(frozen=True)
class Excitation:
    """An excitation trajectory: q0 (n), a, b (n x L) of the series with period ``period``
    [s], run ``repeats`` times (duration = repeats period); ``limits`` it keeps;
    ``cond``: condition number of the stacked regressor at ``rate`` [Hz] over the duration."""

    period: float
    repeats: int
    q0: np.ndarray
    a: np.ndarray
    b: np.ndarray
    limits: tuple[JointLimits, ...]
    cond: float
    rate: float
    seed: int

    @property
    def duration(self) -> float:
        return self.period * self.repeats

    @property
    def harmonics(self) -> int:
        return self.a.shape[1]

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, q', q'') at times t, each len(t) x n."""
        return fourier(np.asarray(t, dtype=float), self.q0, self.a, self.b, 2 * math.pi / self.period)

    def times(self) -> np.ndarray:
        """The sample times of the CSV: 0, 1/rate, ..., duration."""
        count = int(round(self.duration * self.rate))
        return np.arange(count + 1) / self.rate

    def peaks(self) -> list[tuple[float, float, float, float]]:
        """Per joint (min q, max q, max |q'|, max |q''|) over the CSV's samples."""
        q, dq, ddq = self.sample(self.times())
        return [(float(q[:, i].min()), float(q[:, i].max()), float(np.abs(dq[:, i]).max()),
                 float(np.abs(ddq[:, i]).max())) for i in range(q.shape[1])]


def fourier(t: np.ndarray, q0: np.ndarray, a: np.ndarray, b: np.ndarray, w: float):
    """(q, q', q'') of the series at times t (module docstring), each len(t) x n."""
    harm = np.arange(1, a.shape[1] + 1, dtype=float)
    phase = w * np.outer(t, harm)                          # T x L
    s, c = np.sin(phase), np.cos(phase)
    q = q0 + s @ (a / (w * harm)).T - c @ (b / (w * harm)).T
    dq = c @ a.T + s @ b.T
    ddq = c @ (b * w * harm).T - s @ (a * w * harm).T
    return q, dq, ddq


def _coefficients(z: np.ndarray, n: int, L: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q0, a, b from the free variables (q0, a_l and b_l for l >= 2) with the rest constraints."""
    z = z.reshape(n, 2 * L - 1)
    q0, a_rest, b_rest = z[:, 0], z[:, 1:L], z[:, L:]
    harm = np.arange(2, L + 1, dtype=float)
    a = np.hstack([-a_rest.sum(axis=1, keepdims=True), a_rest])
    b = np.hstack([-(b_rest * harm).sum(axis=1, keepdims=True), b_rest])
    return q0, a, b


def _bounds(z: np.ndarray, n: int, L: int, w: float, limits) -> np.ndarray:
    """Every limit constraint as g(z) >= 0 (the conservative bounds of the module docstring)."""
    q0, a, b = _coefficients(z, n, L)
    harm = np.arange(1, L + 1, dtype=float)
    r = np.sqrt(a * a + b * b + EPS * EPS)
    lo = np.array([x.lower for x in limits])
    hi = np.array([x.upper for x in limits])
    reach = (r / (w * harm)).sum(axis=1)
    speed = r.sum(axis=1)
    accel = w * (r * harm).sum(axis=1)
    v = np.array([x.velocity for x in limits])
    acc = np.array([x.acceleration for x in limits])
    return np.concatenate([hi - q0 - reach, q0 - reach - lo, v - speed, acc - accel]) / np.concatenate(
        [hi - lo, hi - lo, v, acc])


def stacked(reg: Regressor, q, dq, ddq) -> np.ndarray:
    """The regressor stacked over samples: (samples n) x p."""
    return reg.evaluate(q, dq, ddq).reshape(-1, reg.p)


def optimise(reg: Regressor, limits: tuple[JointLimits, ...], duration: float,
             harmonics: int = HARMONICS, seed: int = 1, iterations: int = 100, rate: float = 1000.0,
             held: dict[int, float] | None = None) -> Excitation:
    """The excitation of ``duration`` seconds (module docstring). ``held``: {joint (0-based):
    position} of joints that stay still (derive excite --payload moves the wrist only); ``reg``
    may be any regressor with ``n``, ``p``, ``names`` and ``evaluate`` (the payload's,
    derive.identify.payload). DataError for a duration or rate that is not positive, or when
    the best trajectory still leaves base parameters unexcited (the combinations named)."""
    if not (math.isfinite(duration) and duration > 0):
        raise DataError(f"excitation: --duration {duration:g} s: expected a finite number > 0")
    if not (math.isfinite(rate) and rate > 0 and duration * rate >= 2):
        raise DataError(f"excitation: --rate {rate:g} Hz: expected a finite number > 0 giving at least 2 samples")
    if harmonics < 2:
        raise DataError(f"excitation: --harmonics {harmonics}: expected at least 2 (one harmonic cannot start "
                        "and end at rest)")
    with threadpool_limits(1, "blas"):        # thousands of small LAPACK calls (pyproject.toml)
        return _optimise(reg, limits, duration, harmonics, seed, iterations, rate, held or {})


def _optimise(reg: Regressor, limits: tuple[JointLimits, ...], duration: float, harmonics: int, seed: int,
              iterations: int, rate: float, held: dict[int, float]) -> Excitation:
    n, L = reg.n, harmonics
    repeats = max(1, math.ceil(duration / MAX_PERIOD - 1e-9))
    period = duration / repeats
    w = 2 * math.pi / period
    samples = max(60, 4 * reg.p // n + 20)
    t = np.arange(samples) * period / samples
    rng = np.random.default_rng(seed)
    z0 = np.zeros((n, 2 * L - 1))
    z0[:, 0] = [(x.lower + x.upper) / 2 for x in limits]
    z0[:, 1:] = rng.normal(size=(n, 2 * L - 2))
    for j, position in held.items():
        z0[j] = 0.0
        z0[j, 0] = position
    z0 = _feasible(z0.ravel(), n, L, w, limits)
    free = np.ones((n, 2 * L - 1), bool)
    free[list(held)] = False
    free = free.ravel()

    def full(zf: np.ndarray) -> np.ndarray:
        z = z0.copy()
        z[free] = zf
        return z

    def states(zs: np.ndarray):
        q, dq, ddq = [], [], []
        for z in zs:
            x = fourier(t, *_coefficients(z, n, L), w)
            q.append(x[0]), dq.append(x[1]), ddq.append(x[2])
        return np.vstack(q), np.vstack(dq), np.vstack(ddq)

    def objective(zf: np.ndarray) -> tuple[float, np.ndarray]:
        z = full(zf)
        h = 1e-7 * np.maximum(1.0, np.abs(zf))
        zs = np.vstack([z, z + np.diag(h) @ np.eye(len(z))[free]])
        Ws = stacked(reg, *states(zs)).reshape(len(zs), samples * n, reg.p)
        U, s, Vt = np.linalg.svd(Ws[0], full_matrices=False)
        if s[-1] <= 0:
            return 1e3, np.zeros_like(zf)
        d = (Ws[1:] - Ws[0]) / h[:, None, None]                         # dW/dz_k
        ds_max = np.einsum("i,kij,j->k", U[:, 0], d, Vt[0])
        ds_min = np.einsum("i,kij,j->k", U[:, -1], d, Vt[-1])
        return float(np.log(s[0] / s[-1])), ds_max / s[0] - ds_min / s[-1]

    result = minimize(objective, z0[free], jac=True, method="SLSQP",
                      constraints=[{"type": "ineq", "fun": lambda zf: _bounds(full(zf), n, L, w, limits)}],
                      options={"maxiter": iterations, "ftol": 1e-6})
    z = _feasible(full(result.x) if np.all(np.isfinite(result.x)) else z0, n, L, w, limits)
    q0, a, b = _coefficients(z, n, L)
    ex = Excitation(period, repeats, q0, a, b, limits, math.inf, rate, seed)
    W = stacked(reg, *ex.sample(ex.times()))
    return Excitation(period, repeats, q0, a, b, limits, condition(reg, W, "the excitation"), rate, seed)


def _feasible(z: np.ndarray, n: int, L: int, w: float, limits) -> np.ndarray:
    """z with q0 inside the position range and each joint's harmonics scaled down just
    enough that every bound holds (they are homogeneous of degree one in the harmonics)."""
    z = z.reshape(n, 2 * L - 1).copy()
    lo = np.array([x.lower for x in limits])
    hi = np.array([x.upper for x in limits])
    z[:, 0] = np.clip(z[:, 0], lo + 1e-3 * (hi - lo), hi - 1e-3 * (hi - lo))
    q0, a, b = _coefficients(z.ravel(), n, L)
    harm = np.arange(1, L + 1, dtype=float)
    r = np.sqrt(a * a + b * b)
    room = np.vstack([np.minimum(hi - q0, q0 - lo) / np.maximum((r / (w * harm)).sum(axis=1), 1e-300),
                      np.array([x.velocity for x in limits]) / np.maximum(r.sum(axis=1), 1e-300),
                      np.array([x.acceleration for x in limits]) / np.maximum(w * (r * harm).sum(axis=1), 1e-300)])
    z[:, 1:] *= np.minimum(1.0, room.min(axis=0) * (1 - 1e-9))[:, None]
    return z.ravel()


def condition(reg: Regressor, W: np.ndarray, what: str, names=None, tol: float = 1e-9) -> float:
    """cond(W) (2-norm); DataError naming the base-parameter combinations W leaves
    unexcited when its columns, scaled to unit norm, have a singular value below
    ``tol`` times the largest."""
    names = list(names if names is not None else reg.names)
    if W.shape[0] > 2 * W.shape[1]:
        W = np.linalg.qr(W, mode="r")          # the same singular values and column norms, p x p
    norms = np.linalg.norm(W, axis=0)
    dead = [names[k] for k in range(W.shape[1]) if norms[k] == 0]
    if dead:
        raise DataError(f"{what} leaves base parameters unidentifiable: {', '.join(dead)} (their regressor "
                        "columns are zero: the motion never excites them)")
    _, s, Vt = np.linalg.svd(W / norms, full_matrices=False)
    if s[-1] < tol * s[0]:
        combos = []
        for k in np.nonzero(s < tol * s[0])[0]:
            v = Vt[k] / norms                   # the unexcited direction in the parameters themselves
            v = v / np.abs(v).max()
            terms = [f"{c:+.3g} {names[j]}" for j, c in sorted(enumerate(v), key=lambda x: -abs(x[1]))
                     if abs(c) > 1e-3][:6]
            combos.append(" ".join(terms))
        raise DataError(f"{what} leaves base parameter combinations unidentifiable (not excited: the regressor's "
                        f"columns are dependent, relative singular value {s[-1] / s[0]:.1e}): "
                        + "; ".join(f"[{c}]" for c in combos))
    s = np.linalg.svd(W, compute_uv=False)
    return float(s[0] / s[-1])


def csv_text(ex: Excitation) -> str:
    """The trajectory as CSV: t, theta1..n, dtheta1..n, ddtheta1..n (17 significant digits)."""
    t = ex.times()
    q, dq, ddq = ex.sample(t)
    n = q.shape[1]
    head = ["t"] + [f"{k}{i}" for k in ("theta", "dtheta", "ddtheta") for i in range(1, n + 1)]
    rows = np.hstack([t[:, None], q, dq, ddq])
    lines = [",".join(head)] + [",".join(f"{x:.17g}" for x in row) for row in rows]
    return "\n".join(lines) + "\n"
