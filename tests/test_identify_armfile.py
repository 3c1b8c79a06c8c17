"""The identified arm file (derive.identify.armfile): an estimate that holds its constraints to the
solver's tolerance only (a rotor inertia of -2e-11 kg m^2, as Clarabel gave the Panda's in `make
bench`) is written as a file that loads. Fast: no log, no solver."""
from __future__ import annotations

import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from derive.identify.armfile import identified_text
from derive.identify.parameters import standard_values
from derive.model.spec import load_arm

UR5 = Path(__file__).parent / "data" / "urdf" / "ur5.toml"


def test_a_rotor_inertia_below_zero_by_the_solver_tolerance_is_written_as_zero(tmp_path):
    arm = load_arm(UR5)
    n = arm.n
    phi = np.array([float(v) for v in standard_values(arm.chain)])
    phi[10 * n + 2] = -2.0e-11          # Ia of joint 3, the solver's side of 0
    idn = SimpleNamespace(arm=arm, cons=SimpleNamespace(phi=phi), emf=np.zeros(n))
    out = tmp_path / "ur5_identified.toml"    # identified_text validates the file: DerivationError if it does not load
    text = identified_text(idn, UR5.read_text(encoding="utf-8"), UR5, out, "log.csv")
    data = tomllib.loads(text)
    assert data["motor"][2]["rotor_inertia"] == 0.0
    assert data["motor"][1]["rotor_inertia"] == float(f"{phi[10 * n + 1] / float(arm.motors[1].gear_ratio) ** 2:.12g}")
