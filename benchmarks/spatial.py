"""Spatial arms from URDF (issue 11): UR5 and Panda through the chain dynamics.

For each vendored arm file (tests/data/urdf/<arm>.toml): the time to derive its
dynamics (CRBA, composite gravity, RNEA) and, separately, the Coriolis matrix;
the operations after CSE (count_ops after sympy.cse, the arm's values put in,
a rational constant one literal) of J, the bias, g and C, and the instructions
of J and the bias as CasADi (the generated code) computes them; the whole
generation (``generate_files``: derivation, kernels, 40-digit reference
vectors, files) and the C compile time of the library at -O2. Anchors from
the issue: Panda derived in under 0.5 s with at most 1,400 operations for J
and the bias together; urdf2casadi's UR5 graphs have 1,026 nodes for M, 648
for C q' and 199 for g.

The generated C ``npid_step`` (gcc -O2, values baked in) per call, beside
Pinocchio's C++ ``rnea(q, v, a)`` of the same arm (benchmarks/pinocchio_rnea_urdf.cpp,
the model Python's pin.buildModelFromUrdf reads, fingers locked): rnea alone, the
dominant part of the same law (J a + bias), not the whole u; both over 16 varying
inputs, best of 5 repeats. Skipped, with the reason, when Pinocchio's C++ headers
are not installed.
"""
from __future__ import annotations

import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import derive
from derive.codegen.emit import write_tree
from derive.codegen.files import generate_files
from derive.codegen.casadi_bridge import to_function
from derive.codegen.kernels import KernelSpec, ParamsMode, Port
from derive.codegen.printing import print_function
from derive.dynamics.equations import derive_dynamics
from derive.dynamics.identities import count_ops_cse
from derive.dynamics.program import dag_xreplace
from derive.model.spec import load_arm

from . import Goal, Section, seconds, table
from .codegen import PIN_DEFINES, _cmeel_prefix

TITLE = "Spatial arms (issue 11): UR5 and Panda from URDF"
URDF = Path(__file__).resolve().parent.parent / "tests" / "data" / "urdf"
ARMS = ("ur5", "panda")
URDF2CASADI_UR5 = {"J": 1026, "C q'": 648, "g": 199}


ITERATIONS, REPEATS = 200_000, 5
HERE = Path(__file__).resolve().parent
C_DRIVER = r"""/* Timing driver of benchmarks/spatial.py (not product code). */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "@ARM@.h"

typedef @ARM@_real real;
enum { N = @N@, NS = 16 };
static volatile double sink;

int main(int argc, char **argv)
{
    long iterations = atol(argv[1]), i;
    int repeats = atoi(argv[2]), r, s, k, bad = 0;
    double best = 1e300, acc = 0, t;
    @ARM@_input ins[NS];
    @ARM@_npid_state ns;
    real u[N], dt = (real)1e-3;
    struct timespec a, b;
    (void)argc;
    for (s = 0; s < NS; ++s)
        for (k = 0; k < N; ++k) {
            ins[s].theta[k] = (real)(0.05 * ((s * 3 + k * 5) % 17 - 8));
            ins[s].dtheta[k] = (real)(0.1 * ((s * 7 + k * 3) % 11 - 5));
            ins[s].yd[k] = ins[s].theta[k] + (real)0.01;
            ins[s].dyd[k] = (real)0.0;
            ins[s].ddyd[k] = (real)(0.2 * ((s * 5 + k * 7) % 13 - 6));
        }
    for (r = 0; r < repeats; ++r) {
        bad |= @ARM@_npid_init(&ns, &ins[0]);
        clock_gettime(CLOCK_MONOTONIC, &a);
        for (i = 0; i < iterations; ++i) {
            bad |= @ARM@_npid_step(&ns, &ins[i & (NS - 1)], dt, u, NULL);
            acc += (double)u[0];
        }
        clock_gettime(CLOCK_MONOTONIC, &b);
        t = (double)(b.tv_sec - a.tv_sec) + 1e-9 * (double)(b.tv_nsec - a.tv_nsec);
        if (t < best) best = t;
    }
    sink = acc;
    printf("ns npid_step %.3f\nbad %d\n", best / (double)iterations * 1e9, bad);
    return 0;
}
"""


def _ns(out: str, label: str) -> float:
    return next(float(line.split()[2]) for line in out.splitlines() if line.startswith(f"ns {label} "))


def npid_step_ns(arm_name: str, n: int, c: Path, work: Path) -> float:
    """ns per call of the generated C npid_step (gcc -O2)."""
    (c / "bench_driver.c").write_text(C_DRIVER.replace("@ARM@", arm_name).replace("@N@", str(n)))
    exe = work / "bench_npid"
    subprocess.run(["gcc", "-std=c99", "-O2", "-o", str(exe), str(c / "bench_driver.c"), str(c / f"{arm_name}.c"),
                    str(c / f"{arm_name}_kernels.c"), "-lm"], check=True, capture_output=True)
    return _ns(subprocess.run([str(exe), str(ITERATIONS), str(REPEATS)], check=True, capture_output=True,
                              text=True).stdout, "npid_step")


def pinocchio_rnea_ns(name: str, arm, work: Path, label: str = "rnea") -> tuple[float | None, str]:
    """(ns per call of Pinocchio's C++ rnea for the arm, "") or (None, why not); ``label``
    "regressor": of computeJointTorqueRegressor instead (benchmarks/identify.py)."""
    try:
        import pinocchio as pin
    except ImportError:
        return None, "pinocchio is not installed"
    prefix = _cmeel_prefix()
    if prefix is None:
        return None, "no cmeel.prefix with Pinocchio headers"
    exe = work / "pin_rnea"
    proc = subprocess.run(["g++", "-std=c++17", "-O2", *PIN_DEFINES, f"-I{prefix / 'include'}",
                           f"-I{prefix / 'include' / 'eigen3'}", str(HERE / "pinocchio_rnea_urdf.cpp"), "-o", str(exe),
                           f"-L{prefix / 'lib'}", "-lpinocchio_default", f"-Wl,-rpath,{prefix / 'lib'}"],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        return None, f"g++ failed: {proc.stderr.strip().splitlines()[0][:200] if proc.stderr.strip() else '?'}"
    model = pin.buildModelFromUrdf(str(URDF / f"{name}.urdf"))
    moving = [j.name for j in arm.chain.joints]
    lock = [model.getJointId(n) for n in model.names[1:] if n not in moving]
    model = pin.buildReducedModel(model, lock, pin.neutral(model)) if lock else model
    basis = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}
    lines = []
    for j in range(1, model.njoints):
        short = model.joints[j].shortname()
        axis = basis[short[-1]] if short in ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRUBX",
                                             "JointModelRUBY", "JointModelRUBZ") else tuple(model.joints[j].extract().axis)
        P, inertia = model.jointPlacements[j], model.inertias[j]
        Ic = np.asarray(inertia.inertia)
        values = [*np.ravel(P.rotation), *P.translation, *axis, inertia.mass, *inertia.lever,
                  Ic[0, 0], Ic[0, 1], Ic[0, 2], Ic[1, 1], Ic[1, 2], Ic[2, 2], 0.0, 0.0, 0.0]
        lines.append(f"{model.parents[j]} " + " ".join(repr(float(v)) for v in values))
    text = work / "model.txt"
    text.write_text("\n".join(lines) + "\n")
    extra = [] if label == "rnea" else [label]
    out = subprocess.run([str(exe), str(text), str(ITERATIONS), str(REPEATS), *extra], check=True,
                         capture_output=True, text=True).stdout
    return _ns(out, label), ""


def _ops(dyn, exprs) -> int:
    return count_ops_cse(dag_xreplace(list(exprs), dyn.subs))


def _casadi_ops(dyn, exprs) -> int:
    """Operations of the expressions as the generated code computes them: the
    instructions of their CasADi function (derive.codegen.casadi_bridge, CSE on)."""
    s = dyn.sym
    spec = KernelSpec("ops", (Port("theta", s.theta, ""), Port("dtheta", s.dtheta, "")),
                      (Port("y", tuple(dag_xreplace(list(exprs), dyn.subs)), ""),), "")
    return print_function(to_function(spec), "c").operations


def measure(name: str) -> dict:
    arm = load_arm(URDF / f"{name}.toml")
    t = time.perf_counter()
    dyn = derive_dynamics(arm)
    t_dyn = time.perf_counter() - t
    t = time.perf_counter()
    C = dyn.coriolis
    t_c = time.perf_counter() - t
    ops = {"J": _ops(dyn, dyn.J), "bias": _ops(dyn, dyn.bias), "g": _ops(dyn, dyn.gravity), "C": _ops(dyn, C),
           "C q'": _ops(dyn, dyn.velocity_bias), "J + bias": _ops(dyn, list(dyn.J) + list(dyn.bias)),
           "CasADi J + bias": _casadi_ops(dyn, list(dyn.J) + list(dyn.bias))}
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
        npid = npid_step_ns(arm.name, dyn.n, c, Path(work))
        rnea, why = pinocchio_rnea_ns(name, arm, Path(work))
    return {"name": name, "n": dyn.n, "dyn": t_dyn, "C": t_c, "ops": ops, "generate": t_gen, "cc": t_cc,
            "npid": npid, "rnea": rnea, "why": why}


def run() -> Section:
    rows = [measure(name) for name in ARMS]
    headers = ("arm", "n", "derive_dynamics", "Coriolis matrix", "ops J", "ops bias", "ops g", "ops C", "ops C q'",
               "ops J + bias", "CasADi ops J + bias", "derive + generate_files", "gcc -O2 (library)", "C npid_step",
               "Pinocchio C++ rnea")
    cells = [[r["name"], r["n"], seconds(r["dyn"]), seconds(r["C"]), *(r["ops"][k] for k in (
        "J", "bias", "g", "C", "C q'", "J + bias", "CasADi J + bias")), seconds(r["generate"]), seconds(r["cc"]),
        f"{r['npid']:.0f} ns", f"{r['rnea']:.0f} ns" if r["rnea"] is not None else f"n/a ({r['why']})"] for r in rows]
    by = {r["name"]: r for r in rows}
    panda, ur5 = by["panda"], by["ur5"]
    goals = (Goal("Panda dynamics derived in under 0.5 s", panda["dyn"] < 0.5, seconds(panda["dyn"])),
             Goal("Panda: at most 1,400 operations for J and the bias together", panda["ops"]["J + bias"] <= 1400,
                  str(panda["ops"]["J + bias"])),
             *(Goal(f"UR5 {k} below urdf2casadi's {v} nodes", ur5["ops"][k] < v, str(ur5["ops"][k]))
               for k, v in URDF2CASADI_UR5.items()),
             Goal("Panda whole generation under 60 s", panda["generate"] < 60, seconds(panda["generate"])),
             Goal("Panda npid_step at least 4x faster than Pinocchio's rnea in the same run",
                  panda["rnea"] is not None and panda["rnea"] >= 4 * panda["npid"],
                  f"{panda['rnea'] / panda['npid']:.1f}x" if panda["rnea"] is not None else panda["why"]))
    note = ("ops: count_ops after sympy.cse with the arm's values put in, each rational constant one literal as in "
            "the generated code (derive.dynamics.identities.count_ops_cse); C q' is the RNEA bias without gravity; "
            "CasADi ops: the instructions of J and the bias as the generated code computes them "
            "(derive.codegen.casadi_bridge). Times: one run each on the shared machine.")
    return Section(TITLE, (table(headers, cells), note), goals)
