"""Build generated C in a temporary folder and call it through ctypes."""
from __future__ import annotations

import ctypes
import shutil
import subprocess
from pathlib import Path

import numpy as np

STRICT = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-Wvla"]  # -Wvla: no variable-length arrays


def compilers() -> list[str]:
    """gcc and clang: both must be there (scripts/install-system-deps.sh)."""
    return ["gcc", "clang"]


def compile_c(cc: str, sources: list[Path], out: Path, flags: list[str]) -> Path:
    cmd = [cc, *STRICT, *flags, "-o", str(out), *map(str, sources), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, f"{' '.join(cmd)}\n{proc.stderr}"
    return out


def library_sources(c_dir: Path, arm: str) -> list[Path]:
    return [c_dir / f"{arm}.c", c_dir / f"{arm}_kernels.c", c_dir / f"{arm}_plant.c"]


UNSET = 0xA5A50000   # a clipped-joints mask no step writes (bits of joints 17 and up)


class CLib:
    """ctypes view of a generated controller library (structs are arrays of reals);
    ``clipped``: the clipped-joints mask of the last step (UNSET when it wrote none)."""

    def __init__(self, c_dir: Path, arm: str, n: int, real: str, runtime: bool, workdir: Path, np_count: int = 0):
        so = compile_c("gcc", library_sources(c_dir, arm), workdir / f"lib{arm}_{real}_{int(runtime)}.so",
                       ["-O2", "-shared", "-fPIC"])
        self.lib = ctypes.CDLL(str(so))
        self.arm, self.n, self.runtime = arm, n, runtime
        self.ct = ctypes.c_float if real == "float" else ctypes.c_double
        self.dtype = np.float32 if real == "float" else np.float64
        self.params = None
        self.mask_t = ctypes.c_ulong if n <= 32 else ctypes.c_ulonglong
        self.clipped = UNSET
        if runtime:
            self.params = (self.ct * (np_count + n))()
            self.fn("params_default")(self.params)

    def fn(self, name: str):
        f = getattr(self.lib, f"{self.arm}_{name}")
        return f

    def _arr(self, values, size=None):
        values = list(values)
        return (self.ct * (size or len(values)))(*values)

    def _p(self):
        return (self.params,) if self.runtime else ()

    def gains(self, theta):
        n = self.n
        P, D, I = (self.ct * (n * n))(), (self.ct * (n * n))(), (self.ct * (n * n))()
        self.fn("gains")(*self._p(), self._arr(theta), P, D, I)
        return np.concatenate([np.array(P[:]), np.array(D[:]), np.array(I[:])])

    def mpc_step(self, x):
        return self._call_u("mpc_step", x)

    def _call_u(self, name, x, state=None, dt=None):
        u = (self.ct * self.n)()
        args = [*self._p()] + ([state] if state is not None else []) + [self._arr(x)]
        if dt is not None:
            args.append(self.ct(dt))
        mask = self.mask_t(UNSET)
        code = self.fn(name)(*args, u, ctypes.byref(mask))
        self.clipped = mask.value
        return code, np.array(u[:])

    def step(self, form: str, state_values, x, dt):
        """(code, u, next state) of npid_step/dobc_step from the given state."""
        state = self._arr(state_values)
        code, u = self._call_u(f"{form}_step", x, state, dt)
        return code, u, np.array(state[:])

    def estimate(self, state_values, x):
        """(code, dhat) of dobc_estimate at DOBC state z = state_values (eq. 22)."""
        dhat = (self.ct * self.n)()
        code = self.fn("dobc_estimate")(*self._p(), self._arr(state_values), self._arr(x), dhat)
        return code, np.array(dhat[:])

    def init(self, form: str, x):
        state = (self.ct * self.n)()
        code = self.fn(f"{form}_init")(*self._p(), state, self._arr(x))
        return code, np.array(state[:])


def have(tool: str) -> bool:
    return shutil.which(tool) is not None
