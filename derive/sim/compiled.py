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


def loop_sources(d, observer: str = "explicit") -> dict[str, str]:
    """The controller's C (double, runtime parameters, the observer step ``observer``) and the loop driver."""
    from derive.codegen.kernels import ParamsMode
    from derive.codegen.render import render
    from derive.codegen.views import arm_view
    from derive.sim.kernels import sim_kernels

    a = d.arm.name
    v = arm_view(d, "double", ParamsMode.RUNTIME, observer=observer)
    out = {f"{a}.h": render("c/arm.h.jinja", v=v), f"{a}.c": render("c/arm.c.jinja", v=v),
           f"{a}_kernels.h": render("c/kernels.h.jinja", v=v), f"{a}_kernels.c": render("c/kernels.c.jinja", v=v)}
    forms = tuple(LoopForm(f.name, f.state.type if f.state else "", f.state.field if f.state else "",
                           init_takes_dt(f, observer))
                  for f in FORMS.values())  # every form of the registry derive.codegen.forms
    out[f"{a}_sim.c"] = render("sim/loop.c.jinja", v=v, kernels=sim_kernels(d), forms=forms)
    return out


def _compile(folder: Path, sources: dict[str, str], arm: str) -> Path:
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        raise DeriveError("compiled simulation: expected a C compiler (cc, gcc or clang) on PATH, found none")
    for name, text in sources.items():
        (folder / name).write_text(text)
    so = folder / f"lib{arm}_sim.so"
    cmd = [cc, *FLAGS, "-o", str(so), *(str(folder / name) for name in sorted(sources) if name.endswith(".c")), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode:
        raise DeriveError(f"compiled simulation: compiling the loop failed:\n{proc.stderr[-2000:]}")
    return so


def build(d, observer: str = "explicit") -> LoopBuild:
    """Render and compile the loop of derivation ``d`` with the controller's observer step
    ``observer`` (derive.codegen.kernels.OBSERVER_STEPS; about a second for two joints)."""
    sources = loop_sources(d, observer)
    key = hashlib.sha256("\0".join(f"{k}\0{v}" for k, v in sorted(sources.items())).encode()).hexdigest()
    with tempfile.TemporaryDirectory(prefix="derive-loop-") as tmp:
        library = _compile(Path(tmp), sources, d.arm.name).read_bytes()
    W = np.array(d.W.tolist(), dtype=float)
    return LoopBuild(key=key, arm=d.arm.name, n=d.n, sources=tuple(sorted(sources.items())), library=library,
                     forms=tuple(FORMS), ctl_values=tuple(float(v) for _, v in d.values),
                     limits=tuple(float(m.input_limit) if m.input_limit else 0.0 for m in d.arm.motors),
                     W=tuple(map(tuple, W)), Binv=tuple(1.0 / np.array(d.B.tolist(), dtype=float).diagonal()),
                     observer=observer)


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
        lib = ctypes.CDLL(str(_compile(Path(tmp.name), dict(b.sources), b.arm)))
    fn = getattr(lib, f"{b.arm}_sim_run")
    dp = ctypes.POINTER(ctypes.c_double)
    fn.argtypes = [ctypes.c_int, ctypes.c_long, ctypes.c_int, ctypes.c_double, ctypes.c_double, dp, dp, dp, dp, dp,
                   dp, dp, dp, dp, ctypes.c_double, dp, dp, dp, dp, dp, dp, dp, dp, dp, ctypes.POINTER(ctypes.c_long), dp]
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


def run_loop(b: LoopBuild, form: str, protected: bool, values, coulomb, viscous, disturbance, u_clip, r: np.ndarray,
             nq: np.ndarray | None, ndq: np.ndarray | None, alpha: float, x0, state0, dt: float,
             substeps: int, f0=None) -> RawRun:
    """One whole run in compiled code (see templates/sim/loop.c.jinja for the order of a sample);
    ``f0``: the reference filter's start (y_d, y_d'), None: at rest at 0."""
    if form not in b.forms:
        raise DeriveError(f"compiled simulation: controller form {form!r} is not in the registry "
                          f"derive.codegen.forms (known: {', '.join(b.forms)})")
    lib = load(b)
    n, steps = b.n, r.shape[0]
    f64 = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    limits = [lim if protected else 0.0 for lim in b.limits]
    cp = f64(list(b.ctl_values) + limits)
    out = {k: np.zeros((steps, n)) for k in ("theta", "dtheta", "yd", "u", "state", "filtered")}
    fail_step = ctypes.c_long(-1)
    fail_input = np.zeros(5 * n)
    args = [f64(values), f64(coulomb), f64(viscous), f64(disturbance), f64(u_clip), cp, f64(r),
            None if nq is None else f64(nq), None if ndq is None else f64(ndq)]
    keep = list(args)  # the arrays must outlive the call
    code = getattr(lib, f"{b.arm}_sim_run")(
        b.forms.index(form), steps, substeps, dt, dt / substeps, *map(_ptr, args), alpha, _ptr(f64(x0)),
        _ptr(None if f0 is None else f64(f0)),
        _ptr(None if state0 is None else f64(state0)), *(_ptr(out[k]) for k in out), ctypes.byref(fail_step),
        _ptr(fail_input))
    del keep
    cut = fail_step.value if code else steps
    return RawRun(*(out[k][:cut] for k in ("theta", "dtheta", "yd", "u", "state", "filtered")), code=int(code),
                  fail_step=int(fail_step.value), fail_input=fail_input)
