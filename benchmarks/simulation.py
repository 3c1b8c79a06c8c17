"""Closed-loop simulation speed (issue 13): simulated seconds per wall second of
the default experiment (MPC, DOBC and NPID, 30 s each) in the compiled loop and
in the Python-stepped reference; the same for 6- and 7-joint planar chains
(derive.model.examples; spatial arms once the spatial dynamics land); sweep
throughput in runs per minute with 1 and 2 local workers, and a 1,000-sample
sweep of the default experiment."""
from __future__ import annotations

import time
from dataclasses import replace

from . import Goal, Section, table

TITLE = "closed-loop simulation and sweeps"
NAMES = ("mpc", "dobc", "npid")
SHOW_RUNS = 3   # alternated runs of each `derive show` measure, the best kept
FLOOR = "`import sympy, numpy` (floor)"


def _compiled_speed(arm, duration: float | None = None) -> tuple[float, float, dict]:
    """(simulated s per wall s, build seconds, traces) of the three controllers, compiled."""
    import derive
    from derive.sim.compiled import build
    from derive.sim.simulate import run_compiled, true_plant

    if duration is not None:
        arm = replace(arm, simulation=replace(arm.simulation, duration=duration))
    d = derive.derive(arm)
    s = arm.simulation
    start = time.perf_counter()
    loop = build(d)
    built = time.perf_counter() - start
    plant = true_plant(d, s)
    run_compiled(d, loop, plant, s, "npid")  # load the library once
    start = time.perf_counter()
    traces = {name: run_compiled(d, loop, plant, s, name) for name in NAMES}
    wall = time.perf_counter() - start
    return s.duration * len(NAMES) / wall, built, traces


def _sweep_rate(samples: int, workers: int) -> tuple[float, float]:
    """(runs per minute, wall seconds) of a sweep of the default arm's [sweep]."""
    import argparse

    import derive
    from derive.cli.sweep import _executor
    from derive.sim.compiled import build
    from derive.sim.sweep import Payload, run_sweep

    arm = derive.load_arm()
    d = derive.derive(arm)
    payload = Payload(arm=arm, loop=build(d), names=arm.sweep.controllers)
    args = argparse.Namespace(dask=None, workers=workers)
    start = time.perf_counter()
    executor, count, scatter, close = _executor(args, samples)
    try:
        run_sweep(payload, arm.simulation, arm.sweep, samples, executor, count, None, scatter)
    finally:
        close()
    wall = time.perf_counter() - start
    return 60 * samples * len(NAMES) / wall, wall


def _command(args: list[str], env: dict) -> tuple[float, float]:
    """Wall and CPU seconds (user + system, os.wait4) of the command ``args``; it must succeed."""
    import os
    import subprocess

    start = time.perf_counter()
    proc = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    assert os.waitstatus_to_exitcode(status) == 0, err.decode()
    return wall, usage.ru_utime + usage.ru_stime


def _simulate_cold_warm() -> dict[str, tuple[float, float]]:
    """`derive simulate` of the default arm as a whole process (issue 23): without the cache, with an empty
    cache (cold: derives, compiles, keeps) and from it (warm: best wall of 3); (wall, CPU) seconds each. Python's
    own bytecode cache is on, as for a user, and primed by a first untimed run."""
    import os
    import sys
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory(prefix="derive-bench-") as tmp:
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["DERIVE_CACHE_DIR"] = str(Path(tmp) / "cache")
        cmd = [sys.executable, "-m", "derive", "simulate", "--out", str(Path(tmp) / "out")]
        _command([*cmd, "--no-cache"], env)
        out = {"--no-cache": _command([*cmd, "--no-cache"], env), "cold": _command(cmd, env)}
        out["warm"] = min((_command(cmd, env) for _ in range(3)), key=lambda x: x[0])
    return out


def _show_cold_warm() -> dict[str, tuple[float, float]]:
    """`derive show` of tests/data/my3.toml (../shared/cases/round2/my3.toml, 3 joints) as a whole process
    (issue 23: under 1 s): `--no-cache`, cold (an empty cache each time) and warm (from the cache), each the best of
    SHOW_RUNS runs alternated with the others (the noise of a shared machine only ever adds time), and `python -c
    "import derive"` in the same run as the anchor (the interpreter's own start), and FLOOR: importing SymPy and
    NumPy, which a cold `derive show` cannot do without (it derives with SymPy); (wall, CPU) seconds each."""
    import os
    import sys
    import tempfile
    from pathlib import Path

    from derive.cli import BLAS_THREAD_VARIABLES

    arm = str(Path(__file__).resolve().parents[1] / "tests" / "data" / "my3.toml")
    with tempfile.TemporaryDirectory(prefix="derive-bench-") as tmp:
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        cmd = [sys.executable, "-m", "derive", "show", arm]
        env["DERIVE_CACHE_DIR"] = str(Path(tmp) / "warm")
        _command(cmd, env)   # bytecode written, and the cache the warm runs read
        runs: dict[str, list[tuple[float, float]]] = {"`import derive` (anchor)": [], FLOOR: [], "--no-cache": [],
                                                      "cold": [], "warm": []}
        for k in range(SHOW_RUNS):
            runs["`import derive` (anchor)"].append(_command([sys.executable, "-c", "import derive"], env))
            runs[FLOOR].append(_command([sys.executable, "-c", "import gc; gc.disable(); import sympy, numpy"],
                                        env | {k: "1" for k in BLAS_THREAD_VARIABLES}))   # as show runs
            runs["--no-cache"].append(_command([*cmd, "--no-cache"], env))
            runs["cold"].append(_command(cmd, env | {"DERIVE_CACHE_DIR": str(Path(tmp) / f"cold{k}")}))
            runs["warm"].append(_command(cmd, env))
    return {k: min(v, key=lambda x: x[1]) for k, v in runs.items()}


def run() -> Section:
    """Measure; check that compiled and Python-stepped agree (1e-9) on the default run's first 5 s."""
    import numpy as np

    import derive
    from derive.model.examples import planar_chain
    from derive.sim.backends import Backend
    from derive.sim.simulate import Plant, run_many, true_plant

    arm = derive.load_arm()
    rate, built, compiled = _compiled_speed(arm)
    # the Python-stepped reference, on the first 5 s (it runs at a few simulated s per wall s)
    short = replace(arm, simulation=replace(arm.simulation, duration=5.0))
    d = derive.derive(short)
    backend = Backend(d, "python")
    start = time.perf_counter()
    ref = run_many(d, backend, Plant(d, true_plant(d, short.simulation)), short.simulation, NAMES)
    py_rate = 5.0 * len(NAMES) / (time.perf_counter() - start)
    backend.close()
    for name in NAMES:
        k = len(ref[name].t)
        gap = float(np.max(np.abs(ref[name].theta - compiled[name].theta[:k])))
        assert gap < 1e-9, f"{name}: compiled and Python-stepped differ by {gap}"
    rows = [("glasgow_2link", 2, "Python-stepped reference", f"{py_rate:.1f}", "-"),
            ("glasgow_2link", 2, "compiled", f"{rate:.0f}", f"{built:.1f} s")]
    chain_rates = {}
    for n in (6, 7):
        r, b, _ = _compiled_speed(planar_chain(n), duration=10.0)
        chain_rates[n] = r
        rows.append((f"chain{n} (planar)", n, "compiled", f"{r:.0f}", f"{b:.1f} s"))
    speed = table(("arm", "joints", "loop", "simulated s per wall s (3 controllers)", "build"), rows)
    sweeps = []
    rates = {}
    for workers in (1, 2):
        per_min, wall = _sweep_rate(40, workers)
        rates[workers] = per_min
        sweeps.append((f"40 samples x 3 controllers, 30 s each", workers, f"{per_min:.0f}", f"{wall:.1f} s"))
    _, big = _sweep_rate(1000, 2)
    sweeps.append(("1000 samples x 3 controllers, 30 s each", 2, f"{60 * 3000 / big:.0f}", f"{big:.1f} s"))
    sweep_table = table(("sweep of the default arm", "workers", "runs per minute", "wall"), sweeps)
    whole = _simulate_cold_warm()
    cold, warm = whole["cold"], whole["warm"]
    process = table(("`derive simulate` (default arm, 4 x 30 s), whole process", "wall", "CPU", "wall / cold"),
                    [(k, f"{w:.2f} s", f"{c:.2f} s", f"{w / cold[0]:.2f}") for k, (w, c) in whole.items()])
    shown = _show_cold_warm()
    show_table = table(("`derive show tests/data/my3.toml`, whole process", "wall", "CPU", "CPU / anchor"),
                       [(k, f"{w:.2f} s", f"{c:.2f} s", f"{c / shown['`import derive` (anchor)'][1]:.1f}")
                        for k, (w, c) in shown.items()])
    note = (f"Sample time {arm.simulation.sample_time * 1e3:g} ms, {arm.simulation.substeps} RK4 substeps per "
            "sample. Compiled: the whole loop in C (derive.sim.compiled), Python called once per run; the build "
            "(render and gcc -O2) is paid once per arm. Checked: compiled and Python-stepped agree within 1e-9 "
            "over the first 5 s. The 6- and 7-joint arms are planar chains (derive.model.examples) until spatial "
            "arms simulate.")
    goals = (Goal("default experiment >= 300x real time compiled", rate >= 300, f"{rate:.0f}x"),
             Goal("7-joint arm >= 30x real time compiled", chain_rates[7] >= 30, f"{chain_rates[7]:.0f}x (planar)"),
             Goal("1,000-sample sweep of the 30 s default experiment under 2 minutes (2 workers)", big < 120,
                  f"{big:.0f} s"))
    goals += (Goal("derive simulate default, whole process, warm < 2 s (cache: derive.sim.cache)", warm[0] < 2,
                   f"{warm[0]:.2f} s wall, {warm[1]:.2f} s CPU; cold {cold[0]:.2f} s wall; warm / cold "
                   f"{warm[0] / cold[0]:.2f} wall, {warm[1] / cold[1]:.2f} CPU"),)
    goals += (Goal("derive show my3, whole process, cold (an empty cache: derived anew), under 1 s of CPU",
                   shown["cold"][1] < 1, f"cold {shown['cold'][1]:.2f} s CPU, warm {shown['warm'][1]:.2f} s, "
                   f"--no-cache {shown['--no-cache'][1]:.2f} s (`import derive` {shown['`import derive` (anchor)'][1]:.2f} s, "
                   f"SymPy and NumPy {shown[FLOOR][1]:.2f} s; best of {SHOW_RUNS} alternated runs each)"),)
    return Section(TITLE, (speed, sweep_table, process, show_table, note), goals)
