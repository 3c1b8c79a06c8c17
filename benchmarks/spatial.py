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

The generated C ``npid_step``, ``dobc_step`` and ``mom_step`` (gcc -O2, values baked in)
per call, timed in turns in one process, beside Pinocchio's C++ ``rnea(q, v, a)`` of the
same arm (benchmarks/pinocchio_rnea_urdf.cpp, the model Python's pin.buildModelFromUrdf
reads, fingers locked), in alternated runs (Pinocchio, steps, ..., steps, Pinocchio: ROUNDS of
the steps), each side the best of its runs: rnea alone, the dominant part of the
same law (J a + bias), not the whole u; all over 16 varying inputs, best of 5 repeats, each
step from the state its init gives at its input (no joint clipped: the driver counts and the run
refuses a clipped step; carried from call to call over unrelated inputs the states drifted to the
limits, and most timed steps were clipped ones). A second run, with yd'' 100 times as large so
that most steps clip, gives the clipped steps' figures (no goal).
Goals (issue 23): the Panda's npid_step at least 6x faster than rnea, its dobc_step and
mom_step each at most 1.5x its npid_step. Pinocchio is skipped, with the reason, when its
C++ headers are not installed. The operations of every generated kernel are listed too.
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
from derive.codegen.kernels import KernelSpec, ParamsMode, Port, kernel_specs
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
PIN_GOAL = 6.0       # npid_step at least this many times faster than Pinocchio's rnea (issue 23)
STEP_GOAL = 1.5      # dobc_step and mom_step at most this many times npid_step (issue 23)
CLIP_SCALE = 20.0    # yd'' of the inputs that clip (the timed inputs: 0.2)
WIDE_ANGLES = 0.36   # angle step of the wide inputs, +-2.88 rad (the timed inputs: 0.05, +-0.4 rad)


ITERATIONS, REPEATS = 200_000, 5
ROUNDS = 3           # runs of the steps, alternated with ROUNDS + 1 of Pinocchio (alternated)
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

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* The three steps take turns within each repeat, so that the ratios between them see the
 * same load on a shared machine. Every call starts from the state its init gives at its input:
 * carried over 200,000 calls of these unrelated inputs the states drift to the limits (the
 * integrator winds up on e = 0.01, the observers follow the jumps of theta' between inputs),
 * and a clipped step is not what is timed here; the clipped steps are counted. A third argument
 * scales yd'' (0.2 by default) so that most steps clip, for the clipped steps' own figures. */
int main(int argc, char **argv)
{
    long iterations = atol(argv[1]), i;
    double scale = argc > 3 ? atof(argv[3]) : 0.2;   /* yd'' per unit; large: most steps clip */
    double angle = argc > 4 ? atof(argv[4]) : 0.05;  /* angles within +-8 of these */
    int repeats = atoi(argv[2]), r, s, k, f, bad = 0;
    double best[3] = { 1e300, 1e300, 1e300 }, acc = 0, t0, t;
    long clipped[3] = { 0, 0, 0 };
    @ARM@_mask hit;
    const char *names[3] = { "npid_step", "dobc_step", "mom_step" };
    @ARM@_input ins[NS];
    @ARM@_npid_state ns, ns0[NS];
    @ARM@_dobc_state ds, ds0[NS];
    @ARM@_mom_state ms, ms0[NS];
    real u[N], dt = (real)1e-3;
    for (s = 0; s < NS; ++s)
        for (k = 0; k < N; ++k) {
            ins[s].theta[k] = (real)(angle * ((s * 3 + k * 5) % 17 - 8));
            ins[s].dtheta[k] = (real)(0.1 * ((s * 7 + k * 3) % 11 - 5));
            ins[s].yd[k] = ins[s].theta[k] + (real)0.01;
            ins[s].dyd[k] = (real)0.0;
            ins[s].ddyd[k] = (real)(scale * ((s * 5 + k * 7) % 13 - 6));
        }
    for (r = 0; r < repeats; ++r)
        for (f = 0; f < 3; ++f) {
            for (s = 0; s < NS; ++s)
                bad |= @ARM@_npid_init(&ns0[s], &ins[s]) | @ARM@_dobc_init(&ds0[s], &ins[s])
                    | @ARM@_mom_init(&ms0[s], &ins[s]);
            t0 = now();
            for (i = 0; i < iterations; ++i) {
                const @ARM@_input *in = &ins[i & (NS - 1)];
                if (f == 0) { ns = ns0[i & (NS - 1)]; bad |= @ARM@_npid_step(&ns, in, dt, u, &hit); }
                else if (f == 1) { ds = ds0[i & (NS - 1)]; bad |= @ARM@_dobc_step(&ds, in, dt, u, &hit); }
                else { ms = ms0[i & (NS - 1)]; bad |= @ARM@_mom_step(&ms, in, dt, u, &hit); }
                clipped[f] += hit != 0;
                acc += (double)u[0];
            }
            t = now() - t0;
            if (t < best[f]) best[f] = t;
        }
    sink = acc;
    for (f = 0; f < 3; ++f) printf("ns %s %.3f\n", names[f], best[f] / (double)iterations * 1e9);
    printf("bad %d clipped %ld %ld %ld\n", bad, clipped[0], clipped[1], clipped[2]);
    return 0;
}
"""


def _ns(out: str, label: str) -> float:
    return next(float(line.split()[2]) for line in out.splitlines() if line.startswith(f"ns {label} "))


STEPS = ("npid_step", "dobc_step", "mom_step")


def build_steps(arm_name: str, n: int, c: Path, work: Path) -> Path:
    """The timing driver (:data:`C_DRIVER`) built with the generated C library of ``c`` (gcc -O2)."""
    (c / "bench_driver.c").write_text(C_DRIVER.replace("@ARM@", arm_name).replace("@N@", str(n)))
    exe = work / f"bench_steps_{arm_name}"
    subprocess.run(["gcc", "-std=c99", "-O2", "-o", str(exe), str(c / "bench_driver.c"), str(c / f"{arm_name}.c"),
                    str(c / f"{arm_name}_kernels.c"), "-lm"], check=True, capture_output=True)
    return exe


def step_ns(arm_name: str, n: int, c: Path, work: Path, scale: float | None = None,
            angles: float | None = None, exe: Path | None = None) -> dict[str, float]:
    """ns per call of the generated C npid_step, dobc_step and mom_step (gcc -O2), the three
    timed in turns in one process (:data:`C_DRIVER`): no step clipped (AssertionError otherwise),
    or with ``scale`` times the inputs' yd'' (most steps clipped), the clipped share of each
    step's calls under ``"<step> clipped"``; ``angles``: the angle step of the inputs (angles
    within +-8 steps; default 0.05, where no sine needs an argument reduction); ``exe``: the
    driver :func:`build_steps` built (else built here)."""
    exe = build_steps(arm_name, n, c, work) if exe is None else exe
    extra = [] if scale is None and angles is None else [repr(0.2 if scale is None else scale)]
    extra += [] if angles is None else [repr(angles)]
    out = subprocess.run([str(exe), str(ITERATIONS), str(REPEATS), *extra],
                         check=True, capture_output=True, text=True).stdout
    if "bad 0 " not in out:
        raise AssertionError(f"{arm_name}: a step returned an error code in the timing driver:\n{out}")
    if scale is None and angles is None and "clipped 0 0 0" not in out:
        raise AssertionError(f"{arm_name}: a timed step clipped a joint (the timings are of unclipped steps):\n{out}")
    counts = next(line.split()[3:] for line in out.splitlines() if line.startswith("bad "))
    share = {f"{name} clipped": int(k) / (ITERATIONS * REPEATS) for name, k in zip(STEPS, counts)}
    return {name: _ns(out, name) for name in STEPS} | ({} if scale is None and angles is None else share)


def alternated(arm_name: str, n: int, c: Path, work: Path, anchor) -> tuple[dict[str, float], float | None, list]:
    """The steps (:func:`step_ns`) and the anchor (``anchor()``: Pinocchio's ns or None) timed in
    ROUNDS alternated runs, anchor first and last (anchor, steps, anchor, ..., steps, anchor): each
    figure the best of its runs, so that both sides are sampled alike on a shared machine (one
    disturbed run of either no longer decides the ratio); and each round's (npid_step, best anchor
    beside it) pair, for the spread."""
    exe = build_steps(arm_name, n, c, work)
    pins, runs = [anchor()], []
    for _ in range(ROUNDS):
        runs.append(step_ns(arm_name, n, c, work, exe=exe))
        pins.append(anchor())
    steps = {k: min(r[k] for r in runs) for k in STEPS}
    known = [p for p in pins if p is not None]
    rounds = [(r["npid_step"], min(p for p in pins[i:i + 2] if p is not None)) for i, r in enumerate(runs)] if known else []
    return steps, (min(known) if known else None), rounds


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
    if not exe.exists():   # built once per work folder
        proc = subprocess.run(["g++", "-std=c++17", "-O2", *PIN_DEFINES, f"-I{prefix / 'include'}",
                               f"-I{prefix / 'include' / 'eigen3'}", str(HERE / "pinocchio_rnea_urdf.cpp"), "-o",
                               str(exe), f"-L{prefix / 'lib'}", "-lpinocchio_default", f"-Wl,-rpath,{prefix / 'lib'}"],
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
        why = pinocchio_rnea_ns(name, arm, Path(work))[1]   # builds it once; why not, if it cannot
        steps, rnea, rounds = alternated(arm.name, dyn.n, c, Path(work),
                                         lambda: pinocchio_rnea_ns(name, arm, Path(work))[0])
        clipping = step_ns(arm.name, dyn.n, c, Path(work), CLIP_SCALE)
        wide = step_ns(arm.name, dyn.n, c, Path(work), angles=WIDE_ANGLES)
    kernels = {k.name: print_function(to_function(k), "c").operations for k in kernel_specs(d, ParamsMode.BAKED)}
    return {"name": name, "n": dyn.n, "dyn": t_dyn, "C": t_c, "ops": ops, "generate": t_gen, "cc": t_cc,
            "npid": steps["npid_step"], "steps": steps, "clipping": clipping, "wide": wide, "kernels": kernels, "rnea": rnea,
            "why": why, "rounds": rounds}


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
             Goal(f"Panda npid_step at least {PIN_GOAL:g}x faster than Pinocchio's rnea in the same run",
                  panda["rnea"] is not None and panda["rnea"] >= PIN_GOAL * panda["npid"],
                  f"{panda['rnea'] / panda['npid']:.1f}x" if panda["rnea"] is not None else panda["why"]),
             *(Goal(f"Panda {step} at most {STEP_GOAL:g}x npid_step per call in the same run",
                    panda["steps"][step] <= STEP_GOAL * panda["npid"],
                    f"{panda['steps'][step] / panda['npid']:.2f}x ({panda['steps'][step]:.0f} vs "
                    f"{panda['npid']:.0f} ns)") for step in STEPS[1:]))
    steps = table(["arm", *(f"C `{k}`" for k in STEPS), "Pinocchio C++ rnea", "rnea / npid_step",
                   *(f"{k} / npid_step" for k in STEPS[1:])],
                  [[r["name"], *(f"{r['steps'][k]:.0f} ns" for k in STEPS),
                    f"{r['rnea']:.0f} ns" if r["rnea"] is not None else f"n/a ({r['why']})",
                    f"{r['rnea'] / r['npid']:.2f}x" if r["rnea"] is not None else "-",
                    *(f"{r['steps'][k] / r['npid']:.2f}x" for k in STEPS[1:])] for r in rows]
                  + [[f"{r['name']}, inputs that clip", *(f"{r['clipping'][k]:.0f} ns" for k in STEPS), "-", "-",
                      *(f"{r['clipping'][k] / r['clipping']['npid_step']:.2f}x" for k in STEPS[1:])] for r in rows]
                  + [[f"{r['name']}, angles within ±{8 * WIDE_ANGLES:.2f} rad", *(f"{r['wide'][k]:.0f} ns" for k in STEPS),
                      "-", f"{r['rnea'] / r['wide']['npid_step']:.2f}x" if r["rnea"] is not None else "-",
                      *(f"{r['wide'][k] / r['wide']['npid_step']:.2f}x" for k in STEPS[1:])] for r in rows])
    names = list(rows[0]["kernels"])
    kernel_ops = table(["kernel", *(r["name"] for r in rows)], [[k, *(r["kernels"][k] for r in rows)] for k in names])
    note = ("ops: count_ops after sympy.cse with the arm's values put in, each rational constant one literal as in "
            "the generated code (derive.dynamics.identities.count_ops_cse); C q' is the RNEA bias without gravity; "
            "CasADi ops: the instructions of J and the bias as the generated code computes them "
            "(derive.codegen.casadi_bridge). Derivation, generation and compile times: one run each on the shared machine.")
    note += (f" Steps: gcc -O2, values baked in, {ITERATIONS:,} calls over 16 varying inputs (no joint at a limit), "
             f"each from the state its init gives at its input, best of {REPEATS} repeats, the three steps in turns; "
             f"{ROUNDS} such runs alternated with {ROUNDS + 1} of Pinocchio (first and last), each figure the best of "
             "its runs (rnea / npid_step of each run beside the better Pinocchio run next to it: "
             + "; ".join(f"{r['name']} " + ", ".join(f"{p / s:.2f}x" for s, p in r["rounds"]) for r in rows if r["rounds"])
             + "). Inputs that clip: yd'' "
             f"{CLIP_SCALE / 0.2:g} times as large, clipped steps (npid, dobc, mom): "
             + "; ".join(f"{r['name']} " + ", ".join(f"{r['clipping'][k + ' clipped']:.0%}" for k in STEPS)
                         for r in rows) + " (not a goal: J's factor is computed on a clipped DOBC step only). "
             f"Wide angles: the timed inputs' angles (within ±0.4 rad, where the kernels' sine and cosine "
             f"need no argument reduction) times {WIDE_ANGLES / 0.05:g}, within ±{8 * WIDE_ANGLES:.2f} rad; "
             "clipped steps " + "; ".join(f"{r['name']} " + ", ".join(f"{r['wide'][k + ' clipped']:.0%}" for k in STEPS)
                                          for r in rows) + ". "
             "Kernel operations: the instructions of each generated kernel (double, after CasADi's CSE).")
    return Section(TITLE, (table(headers, cells), steps, kernel_ops, note), goals)
