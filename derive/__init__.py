"""derive: symbolic derivation and code generation of disturbance-observer-based
control for robot arms (W.-H. Chen, nonlinear disturbance observer based control
and nonlinear PID; equation numbers refer to that paper).

The public names are imported on first use (PEP 562): ``import derive`` and a command
that needs no derivation (``derive show`` from its cache) do not pay for SymPy."""
from derive.errors import CoverageError, DerivationError, DeriveError, EmitError, Problem, SpecError
from derive.version import __version__

__all__ = ["Arm", "CoverageError", "Derivation", "DerivationError", "DeriveError", "EmitError",
           "Problem", "SpecError", "derive", "load_arm"]

_LAZY = {"Derivation": "derive.control.pipeline", "derive": "derive.control.pipeline",
         "Arm": "derive.model.spec", "load_arm": "derive.model.spec"}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'derive' has no attribute {name!r}")
