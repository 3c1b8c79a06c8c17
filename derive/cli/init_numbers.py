"""The numbers ``derive init`` writes into a starter file (derive.cli.init): the observer gain W and
the sample time (derive.control.starter), the sampled loop's limits for the file as written
(derive.control.sampling), and the RK4 substeps its plant needs (derive.sim.plant.decay_mode)."""
from __future__ import annotations

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

    from derive.control.inertia import joint_coordinates
    from derive.control.starter import starter_gain
    from derive.dynamics.dag import matrix_xreplace
    from derive.dynamics.equations import derive_dynamics
    from derive.model.spec import arm_from_dict

    arm = arm_from_dict(tomllib.loads(draft), str(out), base_dir=out.resolve().parent)
    dyn = derive_dynamics(arm)
    model_J = matrix_xreplace(dyn.J, dict(dyn.values))    # each shared subexpression once
    from derive.control.inertia import InertiaModel

    model = InertiaModel(model_J, joint_coordinates(arm, dyn.sym.theta))
    if model.unbounded:
        names = ", ".join(repr(chain.joints[c.index].name) for c in model.unbounded)
        raise DeriveError(f"joint {names}: expected a prismatic joint with <limit lower upper> (the observer "
                          "certificate and the sample-time analysis range over its travel), got none")
    box, _ = speed_box(chain)
    return starter_gain(model, box), dyn


def rk4_substeps(d, sample_time: float, initial_theta=None, coulomb=None) -> int:
    """The RK4 steps per sample the simulation of derivation ``d``'s arm file needs at its nominal
    parameters and ``sample_time`` [s] (derive.sim.plant.decay_mode: the stiffest mode at the initial
    pose, a light joint's URDF friction as the smooth Coulomb law's slope included), at least its own."""
    from dataclasses import replace

    import numpy as np

    from derive.control.grid import mass_function
    from derive.sim.plant import decay_mode

    s = replace(d.arm.simulation, sample_time=sample_time,
                **({"initial_theta": tuple(initial_theta)} if initial_theta is not None else {}),
                **({"coulomb_friction": tuple(coulomb)} if coulomb is not None else {}))
    J = mass_function(d)(np.array([s.initial_theta], dtype=float))[0]
    return decay_mode(d.dynamics, dict(d.dynamics.values), s, s.viscous_friction, s.coulomb_friction,
                      J=J)["substeps"]


POSE_LOAD = 0.8        # the starter experiment's gravity torques at most this fraction of each effort limit
POSE_CANDIDATES = 512  # seeded poses within the joint ranges tried when the zero pose does not do
MIN_AMPLITUDE_DEG = 15.0


def starter_pose(d) -> tuple[tuple[float, ...], float] | None:
    """A start pose and pulse amplitude [deg] for the starter file's experiment (section 5.2: each joint's
    reference steps up by the amplitude from where it starts), or None when the defaults do: the zero pose
    within every joint range with the 90 deg pulse inside it too, and the gravity torques g(theta) (eq. 12)
    within POSE_LOAD of the URDF's effort limits all along the experiment (the pulses that are up together
    at each time of the run, and the moves between, sampled). Else the pose of
    POSE_CANDIDATES seeded ones within the ranges (the zero pose and the ranges' middles among them)
    with the largest amplitude (at most 90 deg, at least MIN_AMPLITUDE_DEG, every pulse 20 % short of its
    joint's upper limit) among those whose worst load over the pose and its pulses is within POSE_LOAD
    (the least loaded when none is). Baxter's
    arm at the zero pose needs 56 N m on its shoulder, whose effort limit is 50 N m: it sagged, and no
    form could track."""
    import math

    import numpy as np

    from derive.dynamics.sx import batched

    n = d.n
    joints = d.dynamics.chain.joints
    lo = np.array([float(j.limits.lower) if j.limits.lower is not None else -math.pi for j in joints])
    hi = np.array([float(j.limits.upper) if j.limits.upper is not None else math.pi for j in joints])
    effort = np.array([float(m.input_limit) * float(m.gear_ratio) if m.input_limit else np.inf
                       for m in d.arm.motors])
    gravity = batched(list(d.dynamics.sym.theta), list(d.dynamics.gravity.xreplace(dict(d.dynamics.values))))

    def amplitude(Q: np.ndarray) -> np.ndarray:
        return np.minimum(math.radians(90.0), 0.8 * (hi - Q).min(axis=1))

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
            worst = np.maximum(worst, np.abs(gravity(Q + amp[:, None] * offset[None, :]) / effort).max(axis=1))
        return worst

    zero = np.zeros((1, n))
    inside = bool(np.all((lo <= 0) & (0 <= hi)))
    if inside and amplitude(zero)[0] >= math.radians(90.0) - 1e-12 and load(zero, amplitude(zero))[0] <= POSE_LOAD:
        return None
    rng = np.random.default_rng(20261202)
    Q = np.vstack([np.clip(zero, lo, hi), (lo + hi)[None] / 2, lo + (hi - lo) * rng.random((POSE_CANDIDATES, n))])
    amp = amplitude(Q)
    score = load(Q, amp)
    ok = amp >= math.radians(MIN_AMPLITUDE_DEG)
    if not ok.any():
        return None
    light = ok & (score <= POSE_LOAD)
    if light.any():   # the largest pulses among the poses the effort limits hold, then the lightest
        best = min(np.flatnonzero(light), key=lambda k: (-round(float(amp[k]), 3), float(score[k])))
    else:
        best = min(np.flatnonzero(ok), key=lambda k: (float(score[k]), -float(amp[k])))
    return tuple(float(f"{x:.4g}") for x in Q[best]), float(f"{math.degrees(amp[best]):.3g}")


DISTURBANCE_ACCEL = 5.0   # rad/s^2 (m/s^2): the starter's input disturbance accelerates no joint faster than this alone


def starter_loads(d, theta0=None) -> dict[str, tuple[float, ...]]:
    """The constant input disturbance d (eq. 12) and the Coulomb friction of the starter experiment where
    the defaults (derive.model.simspec: 0.3, 0.1, ... and 0.05, 0.01, ... N m, the paper's arm's scale)
    do not fit the arm: each joint's default at most DISTURBANCE_ACCEL times its inertia J_ii at the
    start pose, so that a light joint is not thrown by a load of the paper's size (the SO-100's 20 g
    jaw, J = 1e-5 kg m^2: 0.1 N m is 1e4 rad/s^2; it spun to 52 rad under MPC, 9.7 rad under DOBC before
    the estimate caught up). A URDF's own <dynamics friction> is kept. Only the keys that change."""
    import numpy as np

    from derive.control.grid import mass_function
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
