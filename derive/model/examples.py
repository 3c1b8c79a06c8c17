"""Example arms built in code: planar chains of any length, for tests,
benchmarks and experiments beyond the packaged arm files."""
from __future__ import annotations

from derive.model.spec import Arm, arm_from_dict


def planar_chain_dict(n: int, gravity: float = 0.0, name: str = "chain") -> dict:
    """An n-link planar chain with varied, non-uniform parameters: geared motors
    with rotor inertia, a tip mass and a point mass (a carried motor) at each
    inner joint. The arm is named ``<name><n>``."""
    links = [{"length": 0.3 + 0.05 * i, "mass": 0.4 + 0.1 * i, "com": 0.12 + 0.02 * i,
              "inertia": 0.002 + 0.001 * i, "viscous_friction": 0.01 * i} for i in range(n)]
    motors = [{"torque_constant": 0.05 + 0.01 * i, "voltage_constant": 0.04 + 0.01 * i,
               "resistance": 2.0 + i, "gear_ratio": 1.0 + i, "rotor_inertia": 1e-5 * i} for i in range(n)]
    point_masses = [{"link": n, "distance": 0.3 + 0.05 * (n - 1), "mass": 0.15}]
    point_masses += [{"link": i, "distance": 0.3 + 0.05 * (i - 1), "mass": 0.2, "inertia": 1e-4}
                     for i in range(1, n)]
    return {"arm": {"name": f"{name}{n}", "gravity": gravity}, "link": links, "motor": motors,
            "point_mass": point_masses,
            "controller": {"T1": 0.0, "T2": 0.5, "w": [1.0 + i for i in range(n)]}}


def planar_chain(n: int, gravity: float = 0.0) -> Arm:
    """The validated :func:`planar_chain_dict` arm."""
    return arm_from_dict(planar_chain_dict(n, gravity), f"<chain{n}>")
