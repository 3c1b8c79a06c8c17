"""The closed loop around MuJoCo's plant.

Compiled (the default): the generated controller (runtime parameters), the simulator's
kernels and templates/sim/mujoco_loop.c.jinja, compiled with the host compiler and linked
with the ``libmujoco`` of the installed ``mujoco`` wheel (its headers ship with it): one
C call per run steps the controller at the sample time and ``mj_step`` ``substeps``
times per sample, with no Python in between (derive.sim.compiled builds and loads it).

Stepped from Python (``--backend python`` or ``c``): :class:`MujocoStepped`, a
:class:`derive.sim.plants.SteppedPlant` over MuJoCo's Python bindings.

:class:`MujocoPlant` is the plant as ``simulate`` and ``sweep`` see it
(derive.sim.plants): plain data (the stripped file, the friction mode), so that sweeps
ship it to their workers; each process compiles the MuJoCo model of a run's settings
once (a few ms) and keeps it.
"""
from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass

import numpy as np

from derive.errors import DeriveError
from derive.sim.mujoco import require
from derive.sim.mujoco.model import Compiled, build as build_model
from derive.sim.mujoco.source import MujocoSource
from derive.sim.plant import true_plant

TAG = 1684370025.0   # d->userdata[0] of derive's models (templates/sim/mujoco_loop.c.jinja)


_CACHE: dict = {}


def _argtypes(lib, arm: str):
    fn = getattr(lib, f"{arm}_mj_run")
    if fn.argtypes is None:
        dp, ip = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
        fn.argtypes = [ctypes.c_int, ctypes.c_long, ctypes.c_int, ctypes.c_double, ctypes.c_double, ctypes.c_void_p,
                       ctypes.c_void_p, ip, ip, dp, dp, dp, dp, dp, dp, dp, dp, ctypes.c_double, dp, dp, dp, dp, dp, dp,
                       dp, dp, dp, ctypes.POINTER(ctypes.c_long), dp]
        fn.restype = ctypes.c_int
    return fn


@dataclass(frozen=True)
class MujocoPlant:
    """MuJoCo's integration of the arm's file (derive.sim.plants.PlantSource); ``friction``:
    "file" (the file's damping, friction loss, limits) or "off" (derive's parameters)."""

    source: MujocoSource
    friction: str = "file"
    name: str = "mujoco"

    def model(self, d, s) -> Compiled:
        """The compiled model of a run under settings ``s`` (once per process and settings)."""
        values = true_plant(d, s).values
        key = (self, s, values, d.arm.name)
        hit = _CACHE.get(key)
        if hit is None or hit[0] is not d:
            if len(_CACHE) > 16:
                _CACHE.clear()
            hit = _CACHE[key] = (d, build_model(self.source, d, values, s, self.friction))
        return hit[1]

    def run(self, d, loop, s, name: str):
        """One controller variant in compiled code (derive.sim.simulate.Trace)."""
        from derive.sim.compiled import load, run_entry
        from derive.sim.simulate import run_compiled_with

        mj = require()
        plant = true_plant(d, s)
        c = self.model(d, s)
        data = mj.MjData(c.model)
        _argtypes(load(loop), loop.arm)
        f64 = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
        arrays = [f64(c.coulomb), f64(plant.widths), f64(plant.disturbance), f64(plant.u_max)]
        ints = [np.ascontiguousarray(c.qadr, dtype=np.int32), np.ascontiguousarray(c.dadr, dtype=np.int32)]
        args = [ctypes.c_void_p(c.model._address), ctypes.c_void_p(data._address),
                *(a.ctypes.data_as(ctypes.POINTER(ctypes.c_int)) for a in ints),
                *(a.ctypes.data_as(ctypes.POINTER(ctypes.c_double)) for a in arrays)]

        def call(form, protected, *rest, f0=None):
            return run_entry(loop, f"{loop.arm}_mj_run", args, form, protected, *rest, f0=f0)
        return run_compiled_with(d, loop, plant.u_max, s, name, call)

    def stepped(self, d, s) -> "MujocoStepped":
        """The plant stepped from Python (derive.sim.plants.SteppedPlant)."""
        plant = true_plant(d, s)
        c = self.model(d, s)
        return MujocoStepped(c, plant.u_max, plant.disturbance, c.coulomb, plant.widths)

    def describe(self, d, s) -> dict:
        """What the metrics file says of the plant (derive.sim.mujoco.model)."""
        return self.model(d, s).description

    def coulomb(self, d, s) -> np.ndarray:
        """The smooth Coulomb friction the loop adds: [simulation] coulomb_friction except on the
        joints whose file's friction loss replaces it (derive.sim.mujoco.model, step 5)."""
        return np.array(self.model(d, s).coulomb, dtype=float)


def _passive(model, data) -> None:
    """derive's smooth Coulomb friction on derive's models (the C loop's derive_passive)."""
    u = data.userdata
    if len(u) < 2 or u[0] != TAG:
        return
    n = int(u[1])
    adr = u[2:2 + n].astype(int)
    data.qfrc_passive[adr] -= u[2 + n:2 + 2 * n] * np.tanh(data.qvel[adr] / u[2 + 2 * n:2 + 3 * n])


class MujocoStepped:
    """MuJoCo's plant stepped from Python: one ``MjData`` per row, ``mj_step`` with ctrl = u + d."""

    def __init__(self, compiled: Compiled, u_max, disturbance, coulomb, widths):
        self.c, self.n = compiled, len(compiled.qadr)
        self.u_max = np.asarray(u_max, dtype=float)
        self.d = np.asarray(disturbance, dtype=float)
        self.tauc = np.asarray(coulomb, dtype=float)
        self.eps = np.asarray(widths, dtype=float)   # rad/s: the smooth law's widths tau_c tanh(theta'/eps)
        self.data: list = []

    def reset(self, theta0, rows: int) -> None:
        mj = require()
        self.data = []
        for _ in range(rows):
            data = mj.MjData(self.c.model)
            data.userdata[:2 + 3 * self.n] = [TAG, self.n, *self.c.dadr, *self.tauc, *self.eps]
            data.qpos[self.c.qadr] = theta0
            self.data.append(data)

    def step(self, u: np.ndarray, dt: float, substeps: int) -> None:
        mj = require()
        h = self.c.model.opt.timestep
        if not math.isclose(h * substeps, dt, rel_tol=1e-12):
            raise DeriveError(f"MuJoCo plant: built for steps of {h:g} s, asked for {substeps} steps of {dt:g} s")
        mj.set_mjcb_passive(_passive)   # only while stepping: a Python callback breaks MuJoCo's compiler
        try:
            for row, data in zip(u, self.data):
                data.ctrl[:] = row + self.d
                mj.mj_step(self.c.model, data, nstep=substeps)
        finally:
            mj.set_mjcb_passive(None)   # the compiled loop installs its own at each run

    def keep(self, rows: list[int]) -> None:
        self.data = [self.data[r] for r in rows]

    @property
    def theta(self) -> np.ndarray:
        return np.array([data.qpos[self.c.qadr] for data in self.data]).reshape(len(self.data), self.n)

    @property
    def dtheta(self) -> np.ndarray:
        return np.array([data.qvel[self.c.dadr] for data in self.data]).reshape(len(self.data), self.n)
