"""The compiled closed loop: the generated controller (runtime parameters), the
simulator's kernels (derive.sim.kernels) and the loop driver
(templates/sim/loop.c.jinja), built with the host compiler at -O2 into one
shared library and called through ctypes once per run.

:func:`build` renders and compiles (in the parent process); the resulting
:class:`LoopBuild` is plain data (sources, the library's bytes, the numbers the
runs need), so it can be sent to worker processes or Dask workers, where
:func:`load` writes the bytes to a private temporary folder (or recompiles the
sources when the library cannot be loaded there) once per process.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from derive.codegen.forms import FORMS, init_takes_dt
from derive.errors import DeriveError


FLAGS = ("-std=c99", "-O2", "-shared", "-fPIC")


@dataclass(frozen=True)
class LoopForm:
    """One controller form in the loop template."""

    name: str
    state_type: str
    state_field: str
    init_dt: bool = False   # its init takes dt (derive.codegen.forms.init_takes_dt)


@dataclass(frozen=True)
class LoopBuild:
    """Everything a run needs, as plain data: C sources, the compiled library,
    and from the Derivation the controller's parameter vector, W and B^-1."""

    key: str
    arm: str
    n: int
    sources: tuple[tuple[str, str], ...]
    library: bytes
    forms: tuple[str, ...]
    ctl_values: tuple[float, ...]
    limits: tuple[float, ...]        # the motors' voltage limits, 0 = none
    W: tuple[tuple[float, ...], ...]
    Binv: tuple[float, ...]
    observer: str = "explicit"       # the controller's observer step (derive generate --observer)
    plants: tuple[str, ...] = ("derive",)   # the loops it holds: derive's plant, MuJoCo's (derive.sim.mujoco.loop)
    payload: bool = False   # derive's plant carries J_p, G_p: its parameter vector ends with the payload's ten


def loop_sources(d, observer: str = "explicit", plants: tuple[str, ...] = ("derive",),
                 payload: bool = False) -> dict[str, str]:
    """The controller's C (double, runtime parameters, the observer step ``observer``) and the loop driver
    of each of ``plants`` (derive's: templates/sim/loop.c.jinja; MuJoCo's: templates/sim/mujoco_loop.c.jinja);
    ``payload``: derive's plant with a payload's J_p and G_p (derive.sim.kernels.accel_spec)."""
    from derive.codegen.kernels import ParamsMode
    from derive.codegen.render import render
    from derive.codegen.views import arm_view
    from derive.sim.kernels import external_plant_functions, sim_kernels

    a = d.arm.name
    v = arm_view(d, "double", ParamsMode.RUNTIME, observer=observer)
    out = {f"{a}.h": render("c/arm.h.jinja", v=v), f"{a}.c": render("c/arm.c.jinja", v=v),
           f"{a}_kernels.h": render("c/kernels.h.jinja", v=v), f"{a}_kernels.c": render("c/kernels.c.jinja", v=v)}
    forms = tuple(LoopForm(f.name, f.state.type if f.state else "", f.state.field if f.state else "",
                           init_takes_dt(f, observer))
                  for f in FORMS.values())  # every form of the registry derive.codegen.forms
    if "mujoco" in plants:
        out[f"{a}_mj.c"] = render("sim/mujoco_loop.c.jinja", v=v, kernels=sim_kernels(d, external_plant_functions(d.n)),
                                  forms=forms)
    if "derive" in plants:
        out[f"{a}_sim.c"] = render("sim/loop.c.jinja", v=v, kernels=sim_kernels(d, payload=payload), forms=forms)
    return out


def _flags(plants: tuple[str, ...]) -> list[str]:
    """Compiler and linker flags beyond FLAGS for the loops of ``plants``."""
    if "mujoco" in plants:
        from derive.sim.mujoco import compile_flags

        return compile_flags()
    return []


def _compile(folder: Path, sources: dict[str, str], arm: str, plants: tuple[str, ...] = ("derive",)) -> Path:
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        raise DeriveError("compiled simulation: expected a C compiler (cc, gcc or clang) on PATH, found none")
    for name, text in sources.items():
        (folder / name).write_text(text)
    so = folder / f"lib{arm}_sim.so"
    cmd = [cc, *FLAGS, "-o", str(so), *(str(folder / name) for name in sorted(sources) if name.endswith(".c")),
           *_flags(plants), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode:
        raise DeriveError(f"compiled simulation: compiling the loop failed:\n{proc.stderr[-2000:]}")
    return so


def build(d, observer: str = "explicit", plants: tuple[str, ...] = ("derive",), payload: bool = False) -> LoopBuild:
    """Render and compile the loop of derivation ``d`` with the controller's observer step
    ``observer`` (derive.codegen.kernels.OBSERVER_STEPS; about a second for two joints) around
    each of ``plants`` (derive's, MuJoCo's: one library, the controller compiled once); ``payload``:
    derive's plant carries a payload's J_p and G_p (its runs pass the payload's ten parameters)."""
    payload = payload and "derive" in plants
    sources = loop_sources(d, observer, plants, payload)
    key = hashlib.sha256("\0".join(f"{k}\0{v}" for k, v in sorted(sources.items())).encode()).hexdigest()
    with tempfile.TemporaryDirectory(prefix="derive-loop-") as tmp:
        library = _compile(Path(tmp), sources, d.arm.name, plants).read_bytes()
    W = np.array(d.W.tolist(), dtype=float)
    return LoopBuild(key=key, arm=d.arm.name, n=d.n, sources=tuple(sorted(sources.items())), library=library,
                     forms=tuple(FORMS), ctl_values=tuple(float(v) for _, v in d.values),
                     limits=tuple(float(m.input_limit) if m.input_limit else 0.0 for m in d.arm.motors),
                     W=tuple(map(tuple, W)), Binv=tuple(1.0 / np.array(d.B.tolist(), dtype=float).diagonal()),
                     observer=observer, plants=tuple(plants), payload=payload)


_LOADED: dict[str, tuple[tempfile.TemporaryDirectory, ctypes.CDLL]] = {}


def load(b: LoopBuild) -> ctypes.CDLL:
    """The loop library of ``b`` in this process (written or compiled once per process)."""
    hit = _LOADED.get(b.key)
    if hit is not None:
        return hit[1]
    tmp = tempfile.TemporaryDirectory(prefix="derive-loop-")
    so = Path(tmp.name) / f"lib{b.arm}_sim_{os.getpid()}.so"
    so.write_bytes(b.library)
    try:
        lib = ctypes.CDLL(str(so))
    except OSError:  # another platform than the one that built it (a remote worker): build here
        lib = ctypes.CDLL(str(_compile(Path(tmp.name), dict(b.sources), b.arm, b.plants)))
    dp = ctypes.POINTER(ctypes.c_double)
    if "derive" in b.plants:
        fn = getattr(lib, f"{b.arm}_sim_run")
        fn.argtypes = [ctypes.c_int, ctypes.c_long, ctypes.c_int, ctypes.c_double, ctypes.c_double, dp, dp, dp, dp,
                       dp, dp, dp, dp, dp, dp, ctypes.c_double, dp, dp, dp, dp, dp, dp, dp, dp, dp,
                       ctypes.POINTER(ctypes.c_long), dp]
        fn.restype = ctypes.c_int
    _LOADED[b.key] = (tmp, lib)
    return lib


def _ptr(a: np.ndarray | None):
    if a is None:
        return None
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


@dataclass(frozen=True)
class RawRun:
    """Arrays of one compiled run (steps x n), cut at a failure; ``code`` 0 or the
    controller's error code at ``fail_step`` with the input it refused."""

    theta: np.ndarray
    dtheta: np.ndarray
    yd: np.ndarray
    u: np.ndarray
    state: np.ndarray
    filtered: np.ndarray
    code: int
    fail_step: int
    fail_input: np.ndarray


def _f64(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def run_loop(b: LoopBuild, form: str, protected: bool, values, coulomb, viscous, disturbance, u_clip, r: np.ndarray,
             nq: np.ndarray | None, ndq: np.ndarray | None, alpha: float, x0, state0, dt: float,
             substeps: int, f0=None, smoothing=None) -> RawRun:
    """One whole run in compiled code (see templates/sim/loop.c.jinja for the order of a sample);
    ``f0``: the reference filter's start (y_d, y_d'), None: at rest at 0; ``smoothing``: each joint's
    width eps of the smooth Coulomb law tau_c tanh(theta'/eps) [rad/s], None: derive.sim.plant.SMOOTH."""
    from derive.sim.plant import SMOOTH

    ieps = 1.0 / _f64([SMOOTH] * b.n if smoothing is None else smoothing)   # the kernel's 1/eps (derive.sim.kernels)
    plant = [_ptr(_f64(a)) for a in (values, coulomb, ieps, viscous, disturbance, u_clip)]
    return run_entry(b, f"{b.arm}_sim_run", plant, form, protected, r, nq, ndq, alpha, x0, state0, dt, substeps,
                     f0)


def run_entry(b: LoopBuild, entry: str, plant_args: list, form: str, protected: bool, r: np.ndarray,
              nq: np.ndarray | None, ndq: np.ndarray | None, alpha: float, x0, state0, dt: float,
              substeps: int, f0=None) -> RawRun:
    """One whole run of the loop function ``entry`` of ``b``, its plant's arguments ``plant_args``
    (ctypes values that stay alive during the call) between the step sizes and the controller's
    parameters (templates/sim/loop.c.jinja); ``f0``: the reference filter's start (y_d, y_d'),
    None: at rest at 0."""
    if form not in b.forms:
        raise DeriveError(f"compiled simulation: controller form {form!r} is not in the registry "
                          f"derive.codegen.forms (known: {', '.join(b.forms)})")
    lib = load(b)
    n, steps = b.n, r.shape[0]
    limits = [lim if protected else 0.0 for lim in b.limits]
    cp = _f64(list(b.ctl_values) + limits)
    out = {k: np.zeros((steps, n)) for k in ("theta", "dtheta", "yd", "u", "state", "filtered")}
    fail_step = ctypes.c_long(-1)
    fail_input = np.zeros(5 * n)
    args = [cp, _f64(r), None if nq is None else _f64(nq), None if ndq is None else _f64(ndq)]
    keep = list(args)  # the arrays must outlive the call
    code = getattr(lib, entry)(
        b.forms.index(form), steps, substeps, dt, dt / substeps, *plant_args, *map(_ptr, args), alpha,
        _ptr(_f64(x0)), _ptr(None if f0 is None else _f64(f0)), _ptr(None if state0 is None else _f64(state0)),
        *(_ptr(out[k]) for k in out), ctypes.byref(fail_step), _ptr(fail_input))
    del keep
    cut = fail_step.value if code else steps
    return RawRun(*(out[k][:cut] for k in ("theta", "dtheta", "yd", "u", "state", "filtered")), code=int(code),
                  fail_step=int(fail_step.value), fail_input=fail_input)
