"""Spatial arms from URDF (issue 11): UR5 and Panda through the chain dynamics.

For each vendored arm file (tests/data/urdf/<arm>.toml): the time to derive its
dynamics (CRBA, composite gravity, RNEA) and, separately, the Coriolis matrix;
the operations after CSE (count_ops after sympy.cse, the arm's values put in)
of J, the bias, g and C; the whole generation (``generate_files``: derivation,
kernels, 40-digit reference vectors, files) and the C compile time of the
library at -O2. Anchors from the issue: Panda derived in under 0.5 s with at
most 1,400 operations for J and the bias together; urdf2casadi's UR5 graphs
have 1,026 nodes for M, 648 for C q' and 199 for g.

Not measured here: the generated ``npid_step`` beside Pinocchio's C++ ``rnea``
for these arms (benchmarks/codegen.py does it for the planar default arm; its
C++ driver builds a planar model and would need a URDF loader).
"""
from __future__ import annotations

import subprocess
import tempfile
import time
from pathlib import Path

import derive
from derive.codegen.emit import write_tree
from derive.codegen.files import generate_files
from derive.codegen.kernels import ParamsMode
from derive.dynamics.equations import derive_dynamics
from derive.dynamics.identities import count_ops_cse
from derive.dynamics.program import dag_xreplace
from derive.model.spec import load_arm

from . import Goal, Section, seconds, table

TITLE = "Spatial arms (issue 11): UR5 and Panda from URDF"
URDF = Path(__file__).resolve().parent.parent / "tests" / "data" / "urdf"
ARMS = ("ur5", "panda")
URDF2CASADI_UR5 = {"J": 1026, "C q'": 648, "g": 199}


def _ops(dyn, exprs) -> int:
    return count_ops_cse(dag_xreplace(list(exprs), dyn.subs))


def measure(name: str) -> dict:
    arm = load_arm(URDF / f"{name}.toml")
    t = time.perf_counter()
    dyn = derive_dynamics(arm)
    t_dyn = time.perf_counter() - t
    t = time.perf_counter()
    C = dyn.coriolis
    t_c = time.perf_counter() - t
    ops = {"J": _ops(dyn, dyn.J), "bias": _ops(dyn, dyn.bias), "g": _ops(dyn, dyn.gravity), "C": _ops(dyn, C),
           "C q'": _ops(dyn, dyn.velocity_bias), "J + bias": _ops(dyn, list(dyn.J) + list(dyn.bias))}
    t = time.perf_counter()
    d = derive.derive(arm)
    files = generate_files(d, (URDF / f"{name}.toml").read_bytes(), "double", ParamsMode.BAKED)
    t_gen = time.perf_counter() - t
    with tempfile.TemporaryDirectory() as work:
        out = Path(work) / "out"
        write_tree(out, files)
        c = out / "c"
        t = time.perf_counter()
        proc = subprocess.run(["gcc", "-std=c99", "-O2", "-c", f"{arm.name}.c", f"{arm.name}_kernels.c",
                               f"{arm.name}_plant.c"], cwd=c, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        t_cc = time.perf_counter() - t
    return {"name": name, "n": dyn.n, "dyn": t_dyn, "C": t_c, "ops": ops, "generate": t_gen, "cc": t_cc}


def run() -> Section:
    rows = [measure(name) for name in ARMS]
    headers = ("arm", "n", "derive_dynamics", "Coriolis matrix", "ops J", "ops bias", "ops g", "ops C", "ops C q'",
               "ops J + bias", "derive + generate_files", "gcc -O2 (library)")
    cells = [[r["name"], r["n"], seconds(r["dyn"]), seconds(r["C"]), *(r["ops"][k] for k in (
        "J", "bias", "g", "C", "C q'", "J + bias")), seconds(r["generate"]), seconds(r["cc"])] for r in rows]
    by = {r["name"]: r for r in rows}
    panda, ur5 = by["panda"], by["ur5"]
    goals = (Goal("Panda dynamics derived in under 0.5 s", panda["dyn"] < 0.5, seconds(panda["dyn"])),
             Goal("Panda: at most 1,400 operations for J and the bias together", panda["ops"]["J + bias"] <= 1400,
                  str(panda["ops"]["J + bias"])),
             *(Goal(f"UR5 {k} below urdf2casadi's {v} nodes", ur5["ops"][k] < v, str(ur5["ops"][k]))
               for k, v in URDF2CASADI_UR5.items()),
             Goal("Panda whole generation under 60 s", panda["generate"] < 60, seconds(panda["generate"])))
    note = ("ops: count_ops after sympy.cse with the arm's values put in (derive.dynamics.identities.count_ops_cse); "
            "C q' is the RNEA bias without gravity. Times: one run each on the shared machine.")
    return Section(TITLE, (table(headers, cells), note), goals)
