"""The numbers ``derive init`` writes into a starter file (derive.cli.init): the observer gain W and
the sample time (derive.control.starter), the sampled loop's limits for the file as written
(derive.control.sampling), and the RK4 substeps its plant needs (derive.sim.plant.decay_mode)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from derive.errors import DeriveError

DEFAULT_SPEED = 2.0          # rad/s: the speed box of a joint whose URDF gives no velocity limit (assumption)
DEFAULT_TRAVEL_SPEED = 0.5   # m/s: the same for a prismatic joint


def stated_limits(text: str, out: Path):
    """The sampled loop's limits of every form and observer step (derive.control.sampling) for the arm
    file ``text`` read as it will be written at ``out``, and its derivation."""
    import tomllib

    from derive.control.pipeline import derive
    from derive.control.sampling import OBSERVERS, limits
    from derive.model.spec import arm_from_dict

    d = derive(arm_from_dict(tomllib.loads(text), str(out), base_dir=out.resolve().parent))
    return {observer: limits(d, observer) for observer in OBSERVERS}, d


def speed_box(chain) -> tuple[tuple[float, ...], tuple[bool, ...]]:
    """The speed box a starter file states: each joint's URDF velocity limit (as written, 6
    significant digits), else DEFAULT_SPEED (rad/s; DEFAULT_TRAVEL_SPEED m/s for a prismatic
    joint), with whether it was assumed."""
    values, assumed = [], []
    for joint in chain.joints:
        v = joint.limits.velocity
        given = v is not None and v > 0
        values.append(float(f"{float(v):g}") if given else (DEFAULT_SPEED if joint.type.rotates else DEFAULT_TRAVEL_SPEED))
        assumed.append(not given)
    return tuple(values), tuple(assumed)


def choose_gain(draft: str, out: Path, chain):
    """The starter W and sample time (derive.control.starter) for the arm of the ``draft`` text,
    read as it will be written at ``out``."""
    import tomllib

    from derive.control.certificate.inertia import joint_coordinates
    from derive.control.starter import starter_gain
    from derive.dynamics.dag import matrix_xreplace
    from derive.dynamics.equations import derive_dynamics
    from derive.model.spec import arm_from_dict

    arm = arm_from_dict(tomllib.loads(draft), str(out), base_dir=out.resolve().parent)
    dyn = derive_dynamics(arm)
    model_J = matrix_xreplace(dyn.J, dict(dyn.values))    # each shared subexpression once
    from derive.control.certificate.inertia import InertiaModel

    model = InertiaModel(model_J, joint_coordinates(arm, dyn.sym.theta))
    if model.unbounded:
        names = ", ".join(repr(chain.joints[c.index].name) for c in model.unbounded)
        raise DeriveError(f"joint {names}: expected a prismatic joint with <limit lower upper> (the observer "
                          "certificate and the sample-time analysis range over its travel), got none")
    box, _ = speed_box(chain)
    return starter_gain(model, box), dyn


MAX_SUBSTEPS = 8   # RK4 steps per sample a starter accepts before it widens a joint's smooth Coulomb law: the
# plant's integration is most of derive simulate's CPU, which grows with the substeps (the xArm6's starter: 92 took
# 134-181 s CPU, 6 took 21-25 s); 8, twice the default 4, aims at issue 34 item 1, every corpus arm's starter
# simulated in < 30 s CPU
WIDEST = 1.0       # rad/s (m/s prismatic): the widest eps the starter writes; wider, the law is viscous friction
# over the experiment's speeds rather than Coulomb's


def round_widths(start: float):
    """The 1-2-5 series above ``start`` (0.01: 0.02, 0.05, 0.1, 0.2, ...) up to WIDEST."""
    k = math.floor(math.log10(start) + 1e-9)
    while True:
        for m in (1, 2, 5):
            w = float(f"{m}e{k}")
            if w > WIDEST * (1 + 1e-12):
                return
            if w > start * (1 + 1e-9):
                yield w
        k += 1


@dataclass(frozen=True)
class Widening:
    """The RK4 substeps of a starter's plant and the widths eps [rad/s; m/s prismatic] of its smooth
    Coulomb law tau_c tanh(theta'/eps) (:func:`rk4_substeps`); ``sharp``: the substeps the default
    width (derive.model.simspec.COULOMB_SMOOTHING) needs."""

    substeps: int
    widths: tuple[float, ...]
    sharp: int

    @property
    def widened(self) -> tuple[int, ...]:
        """The joints (0-based) whose width is not the default."""
        from derive.model.simspec import COULOMB_SMOOTHING

        return tuple(i for i, w in enumerate(self.widths) if w != COULOMB_SMOOTHING)


def rk4_substeps(d, sample_time: float, initial_theta=None, coulomb=None) -> Widening:
    """The RK4 steps per sample the simulation of derivation ``d``'s arm file needs at its nominal
    parameters and ``sample_time`` [s] (derive.sim.plant.decay_mode: the stiffest mode at the initial
    pose, a light joint's URDF friction as the smooth Coulomb law's slope tau_c / eps included), at least
    its own, and the widths eps that keep them at most MAX_SUBSTEPS.

    When the default eps = 0.01 rad/s needs more, joints are widened one step of the 1-2-5 series at a
    time (:func:`round_widths`, at most WIDEST), each time the joint whose step lowers the stiffest
    rate most, until the substeps are at most MAX_SUBSTEPS (or no step lowers them); then each widened
    joint is narrowed back as far as the substeps stay so: the smallest round widths that do. This is the
    regularised Coulomb friction of a velocity threshold, the practice of Simscape's Rotational Friction
    block (its "Coulomb friction velocity threshold", default 0.1 rad/s): below eps the friction acts as
    a viscous damper of slope tau_c / eps, above it as Coulomb's tau_c sign(theta')."""
    from dataclasses import replace

    import numpy as np

    from derive.control.sampling.grid import mass_function
    from derive.model.simspec import coulomb_widths
    from derive.sim.plant import decay_mode

    s = replace(d.arm.simulation, sample_time=sample_time,
                **({"initial_theta": tuple(initial_theta)} if initial_theta is not None else {}),
                **({"coulomb_friction": tuple(coulomb)} if coulomb is not None else {}))
    J = mass_function(d)(np.array([s.initial_theta], dtype=float))[0]

    def mode(widths) -> dict:
        return decay_mode(d.dynamics, dict(d.dynamics.values), replace(s, coulomb_smoothing=tuple(widths)),
                          s.viscous_friction, s.coulomb_friction, J=J)

    widths = list(coulomb_widths(s, d.n))
    best = mode(widths)
    sharp = best["substeps"]
    while best["substeps"] > MAX_SUBSTEPS:
        trials = []
        for i, c in enumerate(s.coulomb_friction):
            wider = next(round_widths(widths[i]), None)
            if c > 0 and wider is not None:
                trials.append((mode(widths[:i] + [wider] + widths[i + 1:]), i, wider))
        trials = [t for t in trials if t[0]["rate"] < best["rate"] * (1 - 1e-9)]
        if not trials:
            break
        best, i, wider = min(trials, key=lambda t: (t[0]["rate"], t[1]))
        widths[i] = wider
    bound, start = max(best["substeps"], MAX_SUBSTEPS), coulomb_widths(s, d.n)
    for i in range(d.n):   # the narrowest round width of each widened joint that keeps the substeps within bound
        for narrower in (w for w in (start[i], *round_widths(start[i])) if w < widths[i]):
            trial = mode(widths[:i] + [narrower] + widths[i + 1:])
            if trial["substeps"] <= bound:
                widths[i], best = narrower, trial
                break
    return Widening(substeps=best["substeps"], widths=tuple(widths), sharp=sharp)


POSE_LOAD = 0.8        # the starter experiment's gravity torques at most this fraction of each effort limit
POSE_CANDIDATES = 512  # seeded poses within the joint ranges tried when the zero pose does not do
POSE_MARGIN = 0.05     # the start pose at least this fraction of each joint's travel inside its limits
PULSE_ROOM = 0.8       # each pulse at most this fraction of the room between its start and its upper limit
PULSE_CAP = math.radians(90.0)   # rad: the paper's pulse (section 5.2); a prismatic joint's cap is half its travel
PULSE_SCALES = (1.0, 0.8, 0.6, 0.45, 0.3, 1 / 6)   # fractions of the pulses tried, down to 15 deg of 90


def starter_pose(d) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    """A start pose and each joint's pulse amplitude, in the joint's own unit (rad; m prismatic), for
    the starter file's experiment (section 5.2: each joint's reference steps up by its amplitude from
    where it starts), or None when the defaults do: every joint revolute, the zero pose POSE_MARGIN of
    each joint's travel inside its limits, the 90 deg pulses inside them with the same room, and the
    gravity torques g(theta) (eq. 12) within POSE_LOAD of the URDF's effort limits all along the
    experiment (the pulses that are up together at each time of the run, and the moves between,
    sampled). Else, of POSE_CANDIDATES seeded poses POSE_MARGIN inside the ranges (the zero pose
    moved inside and the ranges' middles among them), each joint's amplitude the smaller of its cap
    (90 deg; half the travel of a prismatic joint) and PULSE_ROOM of the room up to its upper limit,
    all of them scaled by the largest of PULSE_SCALES for which the worst load over the pose and its
    pulses is within POSE_LOAD: the pose whose smallest scaled amplitude-to-cap ratio is the largest
    (then the lightest; the least loaded with the smallest pulses when none holds). A joint without
    a range (continuous, or a zero-width one: derive.control.certificate.inertia.joint_coordinates) starts
    anywhere and takes the 90 deg pulse. Baxter's arm at the zero pose needs
    56 N m on its shoulder, whose effort limit is 50 N m: it sagged, and no form could track; the
    Fetch's torso (0 to 0.386 m) started at its lower limit and left its range, and its travel
    set one amplitude for every joint (0.309 "rad"), issue 34 item 5."""
    import numpy as np

    from derive.dynamics.sx import batched

    from derive.control.certificate.inertia import joint_coordinates

    n = d.n
    coords = joint_coordinates(d.arm, d.theta)   # a zero-width range (URDF 0, 0) is none, as everywhere
    bounded = np.array([c.lower is not None and c.upper is not None for c in coords])
    lo = np.array([c.lower if b else -math.pi for c, b in zip(coords, bounded)])
    hi = np.array([c.upper if b else math.pi for c, b in zip(coords, bounded)])
    prismatic = np.array([not c.angle for c in coords])
    cap = np.where(prismatic, (hi - lo) / 2, PULSE_CAP)
    margin = np.where(bounded, POSE_MARGIN * (hi - lo), 0.0)
    effort = np.array([float(m.input_limit) * float(m.gear_ratio) if m.input_limit else np.inf
                       for m in d.arm.motors])
    # the parameters' values as CasADi constants, not substituted by SymPy: its substitution of decimal values into
    # the whole tree (each node re-evaluated, with its assumptions) cost 20 s on a 7-joint arm written in decimals;
    # as constants CasADi folds them (passed as arguments they were computed again at every pose)
    gravity = batched(list(d.dynamics.sym.theta), list(d.dynamics.gravity),
                      {s: float(v) for s, v in d.dynamics.values})

    def amplitude(Q: np.ndarray) -> np.ndarray:
        return np.where(bounded, np.minimum(cap, PULSE_ROOM * (hi - Q)), cap)

    sim = d.arm.simulation
    starts = sim.start or tuple(5.0 * i for i in range(n))
    masks = []                         # which pulses are up, over the run (section 5.2: period, starts)
    for t in np.arange(0.0, sim.duration, 0.25):
        up = tuple(bool(t >= s0 and (t - s0) % sim.pulse_period < sim.pulse_period / 2) for s0 in starts)
        if not masks or masks[-1] != up:
            masks.append(up)
    steps = np.array([np.array(m, dtype=float) for m in masks])
    path = np.vstack([steps[k] + f * (steps[k + 1] - steps[k]) for k in range(len(steps) - 1)
                      for f in np.linspace(0.0, 1.0, 9)] or [steps[0]])   # the reference's moves, sampled

    def load(Q: np.ndarray, amp: np.ndarray) -> np.ndarray:
        """The worst |g_i| / effort_i along each pose's experiment (the pulses as they rise and fall)."""
        worst = np.zeros(Q.shape[0])
        for offset in path:
            worst = np.maximum(worst, np.abs(gravity(Q + amp * offset[None, :]) / effort).max(axis=1))
        return worst

    low, high = lo + margin, hi - margin
    zero = np.zeros((1, n))
    inside = bool(np.all((low <= 0) & (0 <= high)))
    if (inside and not prismatic.any() and np.all(amplitude(zero)[0] >= PULSE_CAP - 1e-12)
            and load(zero, amplitude(zero))[0] <= POSE_LOAD):
        return None
    rng = np.random.default_rng(20261202)
    Q = np.vstack([np.clip(zero, low, high), (lo + hi)[None] / 2, low + (high - low) * rng.random((POSE_CANDIDATES, n))])
    amp = amplitude(Q)
    ratio = (amp / cap).min(axis=1)
    scale, score = np.zeros(len(Q)), np.full(len(Q), np.inf)
    for s in PULSE_SCALES:    # each pose's largest pulses (a common fraction of its amplitudes) within the limits
        todo = np.flatnonzero(scale == 0)
        if not len(todo):
            break
        worst = load(Q[todo], s * amp[todo])
        fit = worst <= POSE_LOAD
        scale[todo[fit]], score[todo[fit]] = s, worst[fit]
    light = scale > 0
    if light.any():   # the largest pulses among the poses the effort limits hold, then the lightest
        best = min(np.flatnonzero(light), key=lambda k: (-round(float(scale[k] * ratio[k]), 3), float(score[k])))
    else:             # none holds: the least loaded with the smallest pulses
        worst = load(Q, PULSE_SCALES[-1] * amp)
        best = min(range(len(Q)), key=lambda k: (float(worst[k]), -float(ratio[k])))
        scale[best] = PULSE_SCALES[-1]
    pose = tuple(float(f"{x:.4g}") for x in Q[best])
    return pose, tuple(float(f"{x:.3g}") for x in scale[best] * amplitude(np.array([pose]))[0])


DISTURBANCE_ACCEL = 5.0   # rad/s^2 (m/s^2): the starter's input disturbance accelerates no joint faster than this alone


def starter_loads(d, theta0=None) -> dict[str, tuple[float, ...]]:
    """The constant input disturbance d (eq. 12) and the Coulomb friction of the starter experiment where
    the defaults (derive.model.simspec: 0.3, 0.1, ... and 0.05, 0.01, ... N m, the paper's arm's scale)
    do not fit the arm: each joint's default at most DISTURBANCE_ACCEL times its inertia J_ii at the
    start pose, so that a light joint is not thrown by a load of the paper's size (the SO-100's 20 g
    jaw, J = 1e-5 kg m^2: 0.1 N m is 1e4 rad/s^2; it spun to 52 rad under MPC, 9.7 rad under DOBC before
    the estimate caught up). A URDF's own <dynamics friction> is kept. Only the keys that change."""
    import numpy as np

    from derive.control.sampling.grid import mass_function
    from derive.model.simspec import default_settings

    n = d.n
    pose = np.array([theta0 if theta0 is not None else (0.0,) * n], dtype=float)
    J = np.diag(mass_function(d)(pose)[0])
    defaults = default_settings(n)
    out = {}
    for key, now in (("disturbance", defaults.disturbance), ("coulomb_friction", d.arm.simulation.coulomb_friction)):
        given = getattr(defaults, key)
        new = tuple(float(f"{min(x, DISTURBANCE_ACCEL * j):.3g}") if x == g else x for x, g, j in zip(now, given, J))
        if new != tuple(now):
            out[key] = new
    return out
