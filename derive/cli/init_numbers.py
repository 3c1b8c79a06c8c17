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
    from derive.dynamics.equations import derive_dynamics
    from derive.model.spec import arm_from_dict

    arm = arm_from_dict(tomllib.loads(draft), str(out), base_dir=out.resolve().parent)
    dyn = derive_dynamics(arm)
    model_J = dyn.J.xreplace(dict(dyn.values))
    from derive.control.inertia import InertiaModel

    model = InertiaModel(model_J, joint_coordinates(arm, dyn.sym.theta))
    if model.unbounded:
        names = ", ".join(repr(chain.joints[c.index].name) for c in model.unbounded)
        raise DeriveError(f"joint {names}: expected a prismatic joint with <limit lower upper> (the observer "
                          "certificate and the sample-time analysis range over its travel), got none")
    box, _ = speed_box(chain)
    return starter_gain(model, box), dyn


def rk4_substeps(d, sample_time: float) -> int:
    """The RK4 steps per sample the simulation of derivation ``d``'s arm file needs at its nominal
    parameters and ``sample_time`` [s] (derive.sim.plant.decay_mode: the stiffest mode at the initial
    pose, a light joint's URDF friction as the smooth Coulomb law's slope included), at least its own."""
    from dataclasses import replace

    import numpy as np

    from derive.control.grid import mass_function
    from derive.sim.plant import decay_mode

    s = replace(d.arm.simulation, sample_time=sample_time)
    J = mass_function(d)(np.array([s.initial_theta], dtype=float))[0]
    return decay_mode(d.dynamics, dict(d.dynamics.values), s, s.viscous_friction, s.coulomb_friction,
                      J=J)["substeps"]
