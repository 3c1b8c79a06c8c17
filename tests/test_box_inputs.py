"""Issue 34 item 2, second half: "stable" says nothing about tracking. Where the speed box's operating points
need inputs beyond the motors' limits, derive show and derive check say so, naming the joint, the input
needed and the limit (derive.control.effort)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import derive
from derive.cli import main
from derive.control.effort import beyond_limits, box_inputs

ARM = Path(derive.__file__).parent / "model" / "arms" / "vertical_2link.toml"


def _fast(tmp_path: Path, box: str) -> Path:
    text = ARM.read_text(encoding="utf-8").replace("max_joint_speed = [6.0, 8.0]", f"max_joint_speed = {box}", 1)
    path = tmp_path / "v.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_operating_point_inputs_are_B_inverse_G_of_eq_12_at_rest_acceleration(tmp_path):
    """u0 = B^-1 G(theta0, theta0') (eq. 12, theta'' = 0) from the CasADi graph against SymPy's G evaluated
    at every operating point, to 1e-9 relative."""
    d = derive.derive(derive.load_arm(_fast(tmp_path, "[60.0, 60.0]")))
    U, Q, DQ = box_inputs(d)
    s = d.dynamics.sym
    G = sp.lambdify([*s.theta, *s.dtheta], d.G.xreplace(dict(d.values)), "numpy")
    B = np.array(d.B.tolist(), dtype=float)
    for k in range(0, len(Q), max(1, len(Q) // 25)):
        want = np.linalg.solve(B, np.array(G(*Q[k], *DQ[k]), dtype=float).ravel())
        np.testing.assert_allclose(U[k], want, rtol=1e-9, atol=1e-9, err_msg=f"u0 at point {k}")


def test_a_60_rad_per_s_box_is_named_beyond_the_24_V_limit_and_the_stated_box_is_not(tmp_path, capsys):
    """The vertical two-link arm at [60, 60] rad/s: both joints need hundreds of volts (635 V and 671 V)
    against 24 V, and derive show says so; at its own box [6, 8] rad/s nothing is said."""
    over = beyond_limits(derive.derive(derive.load_arm(_fast(tmp_path, "[60.0, 60.0]"))))
    assert [e.joint for e in over] == [1, 2] and all(e.needed > 10 * e.limit and e.limit == 24 for e in over)
    assert all(e.unit == "V" for e in over)
    assert beyond_limits(derive.derive(derive.load_arm(ARM))) == []
    assert main(["show", str(_fast(tmp_path, "[60.0, 60.0]"))]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "Inputs: the speed box is beyond what the motors can drive" in out
    assert f"joint 2 needs {over[1].needed:.3g} V against its limit 24 V" in out
    assert main(["show", str(ARM)]) == 0
    assert "Inputs:" not in capsys.readouterr().out
