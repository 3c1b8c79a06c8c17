"""derive: symbolic derivation and code generation of disturbance-observer-based
control for robot arms (W.-H. Chen, nonlinear disturbance observer based control
and nonlinear PID; equation numbers refer to that paper)."""
from derive.errors import CoverageError, DerivationError, DeriveError, EmitError, Problem, SpecError
from derive.control.pipeline import Derivation, derive
from derive.model.spec import Arm, load_arm

__all__ = ["Arm", "CoverageError", "Derivation", "DerivationError", "DeriveError", "EmitError",
           "Problem", "SpecError", "derive", "load_arm"]
__version__ = "0.1.0"
