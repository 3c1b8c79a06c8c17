"""MuJoCo as the plant of derive's closed loops (``derive simulate --plant mujoco``).

The plant is MuJoCo's integration of the arm's own URDF (the file the arm file names
under ``[arm] urdf``) or of an MJCF/URDF the arm file names under ``[simulation]
mujoco_model``, never a model rebuilt from derive's derivation:

* :mod:`.source`: the file read safely and stripped of what the dynamics do not need
  (visual and collision geometry, meshes, transmissions);
* :mod:`.model`: the MuJoCo model of one run: derive's joints mapped by name and
  checked, every other joint held where derive holds it, derive's drives
  (DC motor or torque) as MuJoCo actuators, rotor inertia as ``armature``, the
  ``[simulation]`` mismatch, RK4 at the sample time / ``substeps``;
* :mod:`.loop`: the closed loop in C (the generated controller and ``mj_step``
  linked with MuJoCo's own library), and the plant stepped from Python.

``mujoco`` is an optional dependency (``pip install 'derive[mujoco]'``); it is imported
here only, through :func:`require`; :func:`compile_flags` finds the C headers and the
``libmujoco`` its wheel ships (derive.sim.compiled links the loop with them).
"""
from __future__ import annotations

import sys
from pathlib import Path

from derive.errors import DeriveError

INSTALL = "pip install 'derive[mujoco]'"


def require():
    """The ``mujoco`` module; DeriveError (exit 2) with the install command when it is missing."""
    try:
        import mujoco
    except ImportError as exc:
        raise DeriveError(f"--plant mujoco: expected the mujoco package (MuJoCo's Python bindings; install it "
                          f"with {INSTALL}), got {type(exc).__name__}: {exc}") from None
    return mujoco


def compile_flags() -> list[str]:
    """Include path, library and run path of MuJoCo's C library from the installed wheel."""
    mj = require()
    folder = Path(mj.__file__).resolve().parent
    names = ("libmujoco.so*", "libmujoco*.dylib") if sys.platform == "darwin" else ("libmujoco.so*",)
    libs = sorted(p for pattern in names for p in folder.glob(pattern))
    if not (folder / "include" / "mujoco" / "mujoco.h").is_file() or not libs:
        raise DeriveError(f"--plant mujoco: expected MuJoCo's C headers and library in the mujoco package "
                          f"({folder}/include/mujoco/mujoco.h, {folder}/libmujoco.so*), got none; reinstall it "
                          "(pip install --force-reinstall mujoco) or use --backend python")
    return [f"-I{folder / 'include'}", str(libs[-1]), f"-Wl,-rpath,{folder}"]
