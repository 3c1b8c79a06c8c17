"""Plants behind one interface, so that ``simulate``, ``sweep`` and their metrics do not
know which one runs: derive's plant (the arm's own derivation with the ``[simulation]``
mismatch, derive.sim.plant) or MuJoCo's (the arm's URDF or an MJCF integrated by MuJoCo,
derive.sim.mujoco).

Two levels, the same interface:

* :class:`SteppedPlant`, stepped from Python by derive.sim.simulate.run_many: ``reset``,
  ``step`` with u held over dt (zero-order hold), read ``theta`` and ``dtheta``;
* :class:`PlantSource`, what a command holds: ``run`` one controller in the compiled loop
  :func:`build` makes (the plant steps in C between samples, templates/sim/loop.c.jinja and
  mujoco_loop.c.jinja), ``stepped`` for the Python-stepped loop, ``describe`` for the
  metrics file. A plant source is plain data: sweeps ship it to their workers.

:func:`compare` holds two plants' traces of the same experiment against each other
(``derive simulate --compare``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from derive.errors import DeriveError

PLANTS = ("derive", "mujoco")


class SteppedPlant(Protocol):
    """A plant stepped from Python: ``rows`` independent copies (one per controller variant)."""

    n: int
    u_max: np.ndarray          # the amplifier's bound on |u| per joint (inf: none)

    def reset(self, theta0, rows: int) -> None:
        """``rows`` copies at rest at the angles ``theta0`` (n) [rad or m]."""

    def step(self, u: np.ndarray, dt: float, substeps: int) -> None:
        """Advance each row by ``dt`` [s] under its input u (rows x n, held over dt), in
        ``substeps`` steps of the plant's integrator."""

    def keep(self, rows: list[int]) -> None:
        """Keep only these rows (runs that failed stop)."""

    @property
    def theta(self) -> np.ndarray:
        """Joint angles (rows x n)."""

    @property
    def dtheta(self) -> np.ndarray:
        """Joint velocities (rows x n)."""


class PlantSource(Protocol):
    """A plant as a command holds it (module docstring)."""

    name: str

    def run(self, d, loop, s, name: str): ...

    def stepped(self, d, s) -> SteppedPlant: ...

    def describe(self, d, s) -> dict: ...

    def coulomb(self, d, s) -> np.ndarray:
        """The smooth Coulomb friction tau_c tanh(theta'/eps) per joint [N m] the plant applies
        under settings ``s`` (derive.sim.plant.stiffest_mode takes its slope)."""


@dataclass(frozen=True)
class DerivedPlant:
    """derive's plant: the arm's own J, G, B at the ``[simulation]`` values (derive.sim.plant)."""

    name: str = "derive"

    def run(self, d, loop, s, name: str):
        from derive.sim.simulate import run_compiled, true_plant

        return run_compiled(d, loop, true_plant(d, s), s, name)

    def stepped(self, d, s) -> SteppedPlant:
        from derive.sim.plant import Plant, true_plant

        return Plant(d, true_plant(d, s))

    def describe(self, d, s) -> dict:
        from derive.sim.plant import SMOOTH, payload_note, true_plant

        plant = true_plant(d, s)
        widths = ("" if all(w == SMOOTH for w in plant.widths) else " (tau_c tanh(theta'/eps), eps = ["
                  + ", ".join(f"{w:g}" for w in plant.widths) + "] rad/s: [simulation] coulomb_smoothing)")
        out = {"name": "derive", "model": "the arm's own derivation: J theta'' + G = B (u + d) (eq. 11-12) at the "
               f"[simulation] parameter values, plus its Coulomb{widths} and viscous friction",
               "integrator": "RK4", "timestep": s.sample_time / s.substeps, "steps_per_sample": s.substeps,
               "changed": {k: {"arm": a, "plant": b} for k, (a, b) in sorted(plant.changed.items())}}
        if plant.has_payload:
            out["payload"] = payload_note(d, s) + ": J + J_p, G + G_p (eq. 12), in the plant only"
        return out

    def coulomb(self, d, s) -> np.ndarray:
        """[simulation] coulomb_friction, as derive's plant applies it (derive.sim.plant)."""
        from derive.sim.plant import true_plant

        return np.array(true_plant(d, s).coulomb, dtype=float)


def build(d, observer: str = "explicit", sources=(DerivedPlant(),), payload: bool = False):
    """The compiled loop (derive.sim.compiled.LoopBuild) of derivation ``d``'s controller with the
    observer step ``observer`` around each plant of ``sources``: one library, the controller
    compiled once. ``payload``: derive's plant carries a payload's J_p and G_p (a run or sweep with
    ``payload_mass`` > 0; without, the loop leaves them out: they cost the Panda's runs 13 %)."""
    from derive.sim.compiled import build as build_loop

    return build_loop(d, observer, tuple(dict.fromkeys(src.name for src in sources)), payload)


def select(arm, name: str, friction: str = "file") -> PlantSource:
    """The plant ``name`` ("derive" or "mujoco") of ``arm``; DeriveError when MuJoCo is
    missing or the arm has no model file for it (derive.sim.mujoco.source)."""
    if name == "derive":
        return DerivedPlant()
    if name != "mujoco":
        raise DeriveError(f"--plant: expected one of {', '.join(PLANTS)}, got {name!r}")
    from derive.sim.mujoco import require
    from derive.sim.mujoco.loop import MujocoPlant
    from derive.sim.mujoco.model import FRICTION, check
    from derive.sim.mujoco.source import load_source

    require()
    if friction not in FRICTION:
        raise DeriveError(f"--mujoco-friction: expected one of {', '.join(FRICTION)}, got {friction!r}")
    source = load_source(arm)
    check(source, arm.chain)   # the file fits the arm: one clear error now, before any derivation
    return MujocoPlant(source, friction)


def compare(traces, others, other: dict) -> dict:
    """The difference of two plants' traces of the same runs (``traces`` minus ``others``,
    matched by controller): per link the largest |difference| of theta [rad], theta' [rad/s]
    and u over the samples both runs have, and the overall largest theta difference."""
    by_name = {tr.name: tr for tr in others}
    out: dict = {"against": other, "controllers": {}}
    worst = 0.0
    for tr in traces:
        o = by_name.get(tr.name)
        if o is None:
            continue
        k = min(len(tr.t), len(o.t))
        entry = {key: [float(x) for x in np.max(np.abs(getattr(tr, key)[:k] - getattr(o, key)[:k]), axis=0)]
                 if k else [] for key in ("theta", "dtheta", "u")}
        entry = {f"max_{key}_difference": v for key, v in entry.items()}
        entry["samples"] = k
        if tr.failure is not None or o.failure is not None:
            entry["note"] = "compared up to the first failure"
        worst = max([worst, *entry["max_theta_difference"]])
        out["controllers"][tr.name] = entry
    out["max_theta_difference"] = worst
    return out
