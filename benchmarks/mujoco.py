"""MuJoCo in the loop (issue 21): simulated seconds per CPU second (the process's own, so another load on
the machine does not count; on an idle core it is the wall's) of the default experiment
(MPC, DOBC and NPID, 30 s each) with MuJoCo integrating the arm's URDF, beside derive's compiled
plant in the same run, for the default 2-link arm (its URDF, tests/data/urdf/glasgow_2link.urdf)
and the 7-joint Panda (tests/data/urdf/panda.toml, a starter file of derive init, at a 0.5 ms sample
time, below its 0.72 ms DOBC and NPID limit, one or two RK4 steps per sample), and the Menagerie Panda
integrated from its own MJCF (tests/data/mjcf/menagerie/panda.xml, one RK4 step per sample); and MuJoCo alone (mj_step of the same model, no controller) for scale. One
process, one core. Checked: the two plants agree (friction off) within the tests' tolerance."""
from __future__ import annotations

import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from . import Goal, Section, table

TITLE = "MuJoCo in the loop"
NAMES = ("mpc", "dobc", "npid")
DATA = Path(__file__).resolve().parent.parent / "tests" / "data" / "urdf"


MENAGERIE = DATA.parent / "mjcf" / "menagerie"


def _arm(folder: Path, name: str, simulation: str):
    """An arm file of tests/data/urdf (or the packaged default arm, or the Menagerie Panda from its own
    MJCF, tests/data/mjcf/menagerie/panda.xml) with a [simulation] table."""
    from derive.model.spec import ARMS_DIR, load_arm

    if name == "menagerie_panda":
        shutil.copy(MENAGERIE / "panda.xml", folder / "panda.xml")
        text = ('[arm]\nname = "menagerie_panda"\nmjcf = "panda.xml"\nbase_body = "link0"\ntip_body = "hand"\n'
                'gravity = 9.81\nactuation = "torque"\n\n[controller]\nT1 = 0.0\nT2 = 0.2\nw = [5.0, 5.0, 5.0, 5.0, '
                '5.0, 5.0, 5.0]\n')
    elif name == "glasgow_2link":
        text = (ARMS_DIR / "glasgow_2link.toml").read_text()
        simulation += f'mujoco_model = "{DATA / "glasgow_2link.urdf"}"\n'
    else:
        text = (DATA / f"{name}.toml").read_text()
        if "\n[simulation]" in text:   # a starter file's own table: replaced by the benchmark's
            head, _, rest = text.partition("\n[simulation]")
            tables = rest.split("\n[", 1)
            text = head + ("\n[" + tables[1] if len(tables) > 1 else "\n")
        shutil.copy(DATA / f"{name}.urdf", folder / f"{name}.urdf")
    (folder / f"{name}.toml").write_text(text + "\n[simulation]\n" + simulation)
    return load_arm(folder / f"{name}.toml")


def _rates(arm, substeps: int) -> dict:
    """Simulated s per CPU s (time.process_time: this process, one thread) of the three controllers on each
    plant, the build [wall s], MuJoCo alone."""
    import mujoco
    import numpy as np

    import derive
    from derive.sim.plants import DerivedPlant, build, compare, select

    arm = replace(arm, simulation=replace(arm.simulation, substeps=substeps))
    s = arm.simulation
    d = derive.derive(arm)
    mj, dv = select(arm, "mujoco", "off"), DerivedPlant()
    start = time.perf_counter()
    loop = build(d, sources=(mj, dv))
    out = {"build": time.perf_counter() - start}
    traces = {}
    for plant in (dv, mj):
        plant.run(d, loop, replace(s, duration=0.1), "npid")   # load the library, compile the model once
        start = time.process_time()
        traces[plant.name] = [plant.run(d, loop, s, name) for name in NAMES]
        out[plant.name] = s.duration * len(NAMES) / (time.process_time() - start)
    gap = compare(traces["mujoco"], traces["derive"], {})["max_theta_difference"]
    assert gap <= 1e-8, f"{arm.name}: MuJoCo's and derive's plants differ by {gap} rad (friction off)"
    c = mj.model(d, s)
    data = mujoco.MjData(c.model)
    steps = int(round(s.duration / c.model.opt.timestep))
    start = time.process_time()
    mujoco.mj_step(c.model, data, nstep=steps)
    out["alone"] = s.duration / (time.process_time() - start)
    out["gap"] = gap
    out["h"] = c.model.opt.timestep
    assert np.isfinite(data.qpos).all()
    return out


def run() -> Section:
    with tempfile.TemporaryDirectory(prefix="derive-bench-mujoco-") as tmp:
        # the Panda with the simspec default Coulomb friction (its URDF's <dynamics friction="0.0"> is
        # otherwise the default, derive.model.spec): MuJoCo's loop then runs derive's passive callback too
        panda = "sample_time = 0.0005\ncoulomb_friction = [0.05, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01]\n"
        cases = (("glasgow_2link", "", 4), ("panda", panda, 2), ("panda", panda, 1), ("menagerie_panda", panda, 1))
        results = []
        for name, simulation, substeps in cases:
            folder = Path(tmp) / f"{name}{substeps}"
            folder.mkdir()
            arm = _arm(folder, name, simulation)
            results.append((arm, substeps, _rates(arm, substeps)))
    rows = [(arm.name, arm.n, f"{arm.simulation.sample_time * 1e3:g} ms", f"{r['h'] * 1e3:g} ms ({n})",
             f"{r['derive']:.0f}", f"{r['mujoco']:.0f}", f"{r['mujoco'] / r['derive']:.2f}", f"{r['alone']:.0f}",
             f"{r['build']:.1f} s", f"{r['gap']:.1e}") for arm, n, r in results]
    speed = table(("arm", "joints", "sample", "RK4 step (per sample)", "derive's plant, compiled",
                   "MuJoCo in the loop", "ratio", "MuJoCo alone", "build", "max theta gap [rad]"), rows)
    note = ("Simulated seconds per CPU second of this process (time.process_time), three controllers of 30 s each, one process (one core); both plants "
            "in one compiled library (the controller compiled once), MuJoCo's model compiled once per run's settings "
            "(a few ms). MuJoCo in the loop: the generated controller at the sample time and mj_step (RK4) substeps "
            "times per sample, all in C (derive.sim.mujoco.loop); MuJoCo alone: mj_step of the same model with no "
            "controller. Friction off, so the two plants must agree: the gap is the largest |theta_MuJoCo - "
            "theta_derive| over the runs.")
    panda = {n: r for arm, n, r in results if arm.name == "panda"}
    own = next(r for arm, _, r in results if arm.name == "menagerie_panda")
    goals = (Goal("Panda (7 joints) with MuJoCo in the loop >= 50x real time on one core (RK4 at 0.5 ms, the "
                  "default step)", panda[1]["mujoco"] >= 50,
                  f"{panda[1]['mujoco']:.0f}x ({panda[1]['mujoco'] / panda[1]['derive']:.2f} of derive's plant, "
                  f"{panda[1]['alone']:.0f}x for MuJoCo alone); {panda[2]['mujoco']:.0f}x at 0.25 ms; "
                  f"the Menagerie Panda from its own MJCF {own['mujoco']:.0f}x"),)
    return Section(TITLE, (speed, note), goals)
