"""Run a generated controller from Python: the generated Python module, or the
compiled C library through ctypes. Both are generated with runtime parameters
(``--params runtime``), so the voltage limits can be changed per run.

Both backends expose the same small interface, :class:`Controller`:
``init(x, dt)``, ``step(x, dt) -> u`` and ``state`` for one form ('mpc', 'npid' or
'dobc'), with x = theta, theta', yd, yd', yd'' concatenated (5 n floats). ``observer``:
the observer step the controller was generated with (derive generate --observer).
"""
from __future__ import annotations

import ctypes
import importlib.util
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Protocol

import numpy as np

from derive.codegen.files import generate_files
from derive.codegen.forms import FORMS, init_takes_dt
from derive.codegen.emit import write_tree
from derive.errors import DeriveError
from derive.codegen.kernels import ParamsMode
from derive.control.pipeline import Derivation


class ControllerError(DeriveError):
    """A generated controller returned a non-zero code (``code``)."""

    def __init__(self, message: str, code: int):
        super().__init__(message)
        self.code = code


class Controller(Protocol):
    """One form of a generated controller; raises DeriveError on a non-zero code."""

    form: str
    n: int

    def init(self, x, dt: float) -> None:
        """Initialise the form's state from the first input (derived dhat(0) for DOBC; ``dt``, the
        sample time of the steps, enters the implicit build's dhat(0): derive.codegen.forms.init_takes_dt)."""

    def step(self, x, dt: float) -> np.ndarray:
        """One sample: the applied voltages u (n)."""

    @property
    def state(self) -> list[float]:
        """int_e (NPID), z (DOBC) or [] (MPC); settable."""


class PythonController:
    def __init__(self, module, form: str, u_max, observer: str = "explicit"):
        self.m, self.form, self.n = module, form, module.N
        self._init_dt = form in FORMS and init_takes_dt(FORMS[form], observer)
        self.params = module.Params()
        self.params.u_max = list(u_max)
        self.s = {"npid": module.NpidState, "dobc": module.DobcState, "mom": module.MomState}.get(
            form, lambda: None)()
        self._field = FORMS[form].state.field if FORMS[form].state else None

    def _inp(self, x):
        n = self.n
        return self.m.Input(*(list(x[i * n:(i + 1) * n]) for i in range(5)))

    def init(self, x, dt: float) -> None:
        if self.s is not None:
            code = getattr(self.m, f"{self.form}_init")(self.params, self.s, self._inp(x),
                                                         *((dt,) if self._init_dt else ()))
            if code:
                raise ControllerError(f"{self.form}_init returned {code}", code)

    def step(self, x, dt: float) -> np.ndarray:
        if self.s is None:
            code, u, _ = self.m.mpc_step(self.params, self._inp(x))
        else:
            code, u, _ = getattr(self.m, f"{self.form}_step")(self.params, self.s, self._inp(x), dt)
        if code:
            raise ControllerError(f"{self.form}_step returned {code}", code)
        return u

    @property
    def state(self) -> list[float]:
        if self.s is None:
            return []
        return list(getattr(self.s, self._field))

    @state.setter
    def state(self, values) -> None:
        setattr(self.s, self._field, [float(v) for v in values])


class CController:
    def __init__(self, lib: ctypes.CDLL, arm: str, n: int, n_params: int, form: str, u_max, state_size: int,
                 observer: str = "explicit"):
        self.lib, self.arm, self.n, self.form = lib, arm, n, form
        self._init_dt = form in FORMS and init_takes_dt(FORMS[form], observer)
        real = ctypes.c_double
        self.params = (real * (n_params + n))()
        getattr(lib, f"{arm}_params_default")(self.params)
        for i, v in enumerate(u_max):
            self.params[n_params + i] = v
        self.s = (real * state_size)()   # the form's state struct: N reals (z and u: 2 N, implicit DOBC)
        self.u = (real * n)()
        self.x = (real * (5 * n))()
        self.dt = real

    def _call(self, name: str, *args) -> int:
        return getattr(self.lib, f"{self.arm}_{name}")(self.params, *args)

    def init(self, x, dt: float) -> None:
        self.x[:] = list(x)
        if self.form != "mpc":
            code = self._call(f"{self.form}_init", self.s, self.x, *((self.dt(dt),) if self._init_dt else ()))
            if code:
                raise ControllerError(f"{self.form}_init returned {code}", code)

    def step(self, x, dt: float) -> np.ndarray:
        self.x[:] = list(x)
        if self.form == "mpc":
            code = self._call("mpc_step", self.x, self.u, None)          # None: no clipped mask
        else:
            code = self._call(f"{self.form}_step", self.s, self.x, self.dt(dt), self.u, None)
        if code:
            raise ControllerError(f"{self.form}_step returned {code}", code)
        return np.array(self.u[:])

    @property
    def state(self) -> list[float]:
        return [] if self.form == "mpc" else list(self.s[:self.n])

    @state.setter
    def state(self, values) -> None:
        self.s[:self.n] = [float(v) for v in values]


class Backend:
    """The generated controller of one derivation, built once in a temp folder."""

    def __init__(self, d: Derivation, kind: str, arm_bytes: bytes = b"", observer: str = "explicit"):
        if kind not in ("python", "c"):
            raise DeriveError(f"--backend: expected python or c, got {kind!r}")
        self.d, self.kind, self.observer = d, kind, observer
        self._tmp = tempfile.TemporaryDirectory(prefix="derive-sim-")
        root = Path(self._tmp.name) / d.arm.name
        write_tree(root, generate_files(d, arm_bytes, "double", ParamsMode.RUNTIME, observer=observer))
        name = d.arm.name
        if kind == "python":
            spec = importlib.util.spec_from_file_location(f"{name}_sim", root / "python" / f"{name}.py")
            self.module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(self.module)
        else:
            cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
            if cc is None:
                raise DeriveError("--backend c: expected a C compiler (cc, gcc or clang) on PATH, found none")
            so = root / f"lib{name}.so"
            cmd = [cc, "-std=c99", "-O2", "-shared", "-fPIC", "-o", str(so), str(root / "c" / f"{name}.c"),
                   str(root / "c" / f"{name}_kernels.c"), "-lm"]
            proc = subprocess.run(cmd, capture_output=True, text=True)
            if proc.returncode:
                raise DeriveError(f"--backend c: compiling the controller failed:\n{proc.stderr}")
            self.lib = ctypes.CDLL(str(so))

    def controller(self, form: str, u_max) -> Controller:
        if self.kind == "python":
            return PythonController(self.module, form, u_max, self.observer)
        size = 2 * self.d.n if form == "dobc" and self.observer == "implicit" else self.d.n
        return CController(self.lib, self.d.arm.name, self.d.n, len(self.d.values), form, u_max, size,
                           self.observer)

    def close(self) -> None:
        self._tmp.cleanup()
