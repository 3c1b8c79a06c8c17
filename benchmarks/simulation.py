"""Closed-loop simulation speed: simulated seconds per wall second of the
default run (``derive simulate``: MPC, DOBC and NPID, 30 s each), with the
generated Python module and with the compiled C library as controller."""
from __future__ import annotations

import time

from . import Section

TITLE = "closed-loop simulation (default arm)"


def run() -> Section:
    """Time the default simulation with both backends; check they agree."""
    import numpy as np

    import derive
    from derive.sim.backends import Backend
    from derive.sim.simulate import CONTROLLERS, Plant
    from derive.sim.simulate import run as simulate

    arm = derive.load_arm()
    d = derive.derive(arm)
    s = arm.simulation
    rows, traces = [], {}
    for kind in ("python", "c"):
        backend = Backend(d, kind)
        plant = Plant(arm, s)
        start = time.perf_counter()
        traces[kind] = [simulate(d, backend, plant, s, name) for name in CONTROLLERS]
        wall = time.perf_counter() - start
        backend.close()
        simulated = s.duration * len(CONTROLLERS)
        rows.append(f"| {kind} | {simulated:g} s | {wall:.2f} s | {simulated / wall:.1f} |")
    for p, c in zip(traces["python"], traces["c"]):
        gap = float(np.max(np.abs(p.theta - c.theta)))
        assert gap < 1e-9, f"{p.name}: Python and C backends differ by {gap}"
    table = "\n".join(["| backend | simulated | wall | simulated s per wall s |", "| --- | --: | --: | --: |",
                       *rows])
    note = (f"Sample time {s.sample_time * 1e3:g} ms, {s.substeps} RK4 substeps of the plant per sample; "
            "most of the time is the plant (lambdified SymPy dynamics), not the controller.")
    return Section(TITLE, (table, note))
