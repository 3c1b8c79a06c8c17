"""Dynamics (eq. 11-12) against Pinocchio, an independent rigid-body engine.

The Pinocchio model is built in code from the same Arm: revolute-Z joints, joint
i+1 placed at (l_i, 0, 0) in the frame of joint i, each link's inertia (mass,
centre of mass on the link x axis, Izz = Ic about the centre of mass; Ixx, Iyy
are arbitrary, planar motion does not see them), each point mass appended to
its link's body, the reflected rotor inertia gr^2 Jm as ``model.armature`` and
gravity along -y of the base. Then, at seeded random states,

* ``pin.crba`` (upper triangle, symmetrised) must equal J(theta), and
* ``pin.rnea(q, v, 0)`` plus the motor and viscous damping
  diag(gr^2 Kt Kv / Ra + bv) v must equal G(theta, theta').
"""
from __future__ import annotations

import functools
from collections.abc import Callable
from fractions import Fraction

import numpy as np
import pytest
import sympy as sp

pin = pytest.importorskip("pinocchio")

from derive.dynamics.equations import Dynamics, derive_dynamics  # noqa: E402
from derive.model.spec import Arm, load_arm, packaged_arms  # noqa: E402

from .arms import chain  # noqa: E402

RTOL = 1e-10
ATOL = 0.0     # purely relative: the worst seen is ~2e-12, smallest |entry| ~2e-5
STATES = 24
SEED = 20240612
CASES = [(n, g) for n in (2, 3, 4) for g in (9.81, 0.0)]

Matrices = tuple[Callable[..., np.ndarray], Callable[..., np.ndarray]]


def _f(x: Fraction) -> float:
    """The double nearest to an exact arm value."""
    return float(x)


def pinocchio_model(arm: Arm, mass_scale: tuple[float, ...] | None = None) -> "pin.Model":
    """Pinocchio model of the planar chain ``arm``; ``mass_scale[i]`` multiplies
    link i's mass (a deliberately wrong model when not all ones)."""
    model = pin.Model()
    model.name = arm.name
    parent = 0
    for i, link in enumerate(arm.links):
        offset = np.zeros(3) if i == 0 else np.array([_f(arm.links[i - 1].length), 0.0, 0.0])
        placement = pin.SE3(np.eye(3), offset)
        joint = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint{i + 1}")
        mass = _f(link.mass) * (mass_scale[i] if mass_scale else 1.0)
        rot = np.diag([1e-3, 2e-3, _f(link.inertia)])  # Ixx, Iyy arbitrary positive
        model.appendBodyToJoint(joint, pin.Inertia(mass, np.array([_f(link.com), 0.0, 0.0]), rot),
                                pin.SE3.Identity())
        for pm in arm.point_masses:
            if pm.link == i:
                rot = np.diag([1e-5, 1e-5, _f(pm.inertia)])
                lever = np.array([_f(pm.distance), 0.0, 0.0])
                model.appendBodyToJoint(joint, pin.Inertia(_f(pm.mass), lever, rot), pin.SE3.Identity())
        parent = joint
    model.armature = np.array([_f(m.gear_ratio ** 2 * m.rotor_inertia) for m in arm.motors])
    model.gravity.linear = np.array([0.0, -_f(arm.gravity), 0.0])
    return model


def motor_damping(arm: Arm) -> np.ndarray:
    """Diagonal of the back-EMF and viscous damping, gr^2 Kt Kv / Ra + bv (eq. 12)."""
    return np.array([_f(m.gear_ratio ** 2 * m.torque_constant * m.voltage_constant / m.resistance
                        + link.viscous_friction) for m, link in zip(arm.motors, arm.links)])


@functools.lru_cache(maxsize=None)
def derived(n: int, gravity: float) -> tuple[Arm, Dynamics, Matrices]:
    """The chain's arm, its symbolic dynamics and fast numeric J(q), G(q, v)."""
    return numeric(chain(n, gravity=gravity))


def numeric(arm: Arm) -> tuple[Arm, Dynamics, Matrices]:
    """``arm``, its symbolic dynamics and J(q, v), G(q, v) lambdified with its values put in."""
    dyn = derive_dynamics(arm)
    values = dyn.subs
    args = [list(dyn.sym.theta), list(dyn.sym.dtheta)]
    J = sp.lambdify(args, dyn.J.xreplace(values), modules="numpy")
    G = sp.lambdify(args, dyn.G.xreplace(values), modules="numpy")
    return arm, dyn, (J, G)


def states(n: int, seed: int = SEED) -> list[tuple[np.ndarray, np.ndarray]]:
    """``STATES`` seeded random (theta, theta') pairs: angles in [-pi, pi], rates in [-3, 3]."""
    rng = np.random.default_rng(seed + n)
    return [(rng.uniform(-np.pi, np.pi, n), rng.uniform(-3.0, 3.0, n)) for _ in range(STATES)]


def pin_inertia(model: "pin.Model", q: np.ndarray) -> np.ndarray:
    """pin.crba fills the upper triangle only: symmetrise it."""
    M = pin.crba(model, model.createData(), q).copy()
    return np.triu(M) + np.triu(M, 1).T


def pin_bias(model: "pin.Model", arm: Arm, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """rnea at zero acceleration plus the motor and viscous damping: G(q, v)."""
    tau = pin.rnea(model, model.createData(), q, v, np.zeros(model.nv))
    return tau + motor_damping(arm) * v


def _tag(name: str, n: int, gravity: float, k: int, q: np.ndarray, v: np.ndarray) -> str:
    """Failure message naming the matrix, the chain and the state."""
    return (f"{name} (eq. 12) of the {n}-link chain, g = {gravity}, state #{k}: "
            f"theta = {np.array2string(q, precision=4)}, dtheta = {np.array2string(v, precision=4)}")


def assert_inertia_matches(n: int, gravity: float, model: "pin.Model", k: int,
                           q: np.ndarray, v: np.ndarray) -> None:
    """Our J(q) against pin.crba of ``model`` at state #k."""
    _, _, (J, _) = derived(n, gravity)
    np.testing.assert_allclose(np.asarray(J(q, v), dtype=float), pin_inertia(model, q),
                               rtol=RTOL, atol=ATOL, err_msg=_tag("J", n, gravity, k, q, v))


def assert_bias_matches(n: int, gravity: float, model: "pin.Model", k: int,
                        q: np.ndarray, v: np.ndarray) -> None:
    """Our G(q, v) against pin.rnea(q, v, 0) of ``model`` plus the damping, at state #k."""
    arm, _, (_, G) = derived(n, gravity)
    np.testing.assert_allclose(np.asarray(G(q, v), dtype=float).ravel(), pin_bias(model, arm, q, v),
                               rtol=RTOL, atol=ATOL, err_msg=_tag("G", n, gravity, k, q, v))


@pytest.mark.parametrize("n, gravity", CASES)
def test_eq12_inertia_matches_pinocchio_crba(n: int, gravity: float) -> None:
    """J(theta) equals Pinocchio's composite-rigid-body inertia (with armature)."""
    model = pinocchio_model(derived(n, gravity)[0])
    for k, (q, v) in enumerate(states(n)):
        assert_inertia_matches(n, gravity, model, k, q, v)


@pytest.mark.parametrize("n, gravity", CASES)
def test_eq12_bias_matches_pinocchio_rnea_plus_motor_damping(n: int, gravity: float) -> None:
    """G(theta, theta') equals rnea(q, v, 0) + diag(gr^2 Kt Kv / Ra + bv) v."""
    model = pinocchio_model(derived(n, gravity)[0])
    for k, (q, v) in enumerate(states(n)):
        assert_bias_matches(n, gravity, model, k, q, v)


@pytest.mark.parametrize("name", packaged_arms())
def test_eq12_packaged_arms_match_pinocchio(name: str) -> None:
    """The shipped arm files too: J against crba, G against rnea + damping."""
    arm, _, (J, G) = numeric(load_arm(name))
    model = pinocchio_model(arm)
    for k, (q, v) in enumerate(states(arm.n)[:8]):
        np.testing.assert_allclose(np.asarray(J(q, v), dtype=float), pin_inertia(model, q), rtol=RTOL,
                                   atol=ATOL, err_msg=f"{name}: " + _tag("J", arm.n, float(arm.gravity), k, q, v))
        np.testing.assert_allclose(np.asarray(G(q, v), dtype=float).ravel(), pin_bias(model, arm, q, v),
                                   rtol=RTOL, atol=ATOL,
                                   err_msg=f"{name}: " + _tag("G", arm.n, float(arm.gravity), k, q, v))


@pytest.mark.parametrize("matrix", ["J", "G"])
def test_eq12_comparison_fails_for_a_perturbed_pinocchio_mass(matrix: str) -> None:
    """The comparison can fail: link 2 heavier by 0.1 % in Pinocchio is told apart."""
    n, gravity = 3, 9.81
    arm = derived(n, gravity)[0]
    wrong = pinocchio_model(arm, mass_scale=tuple(1.001 if i == 1 else 1.0 for i in range(n)))
    check = assert_inertia_matches if matrix == "J" else assert_bias_matches
    q, v = states(n)[0]
    with pytest.raises(AssertionError, match=f"{matrix} \\(eq. 12\\)"):
        check(n, gravity, wrong, 0, q, v)


def test_eq12_comparison_fails_with_the_wrong_gravity() -> None:
    """The G comparison sees gravity: a Pinocchio model with g = 0 disagrees with G at g = 9.81."""
    wrong = pinocchio_model(derived(3, 9.81)[0])
    wrong.gravity.linear = np.zeros(3)
    q, v = states(3)[0]
    with pytest.raises(AssertionError, match="G \\(eq. 12\\)"):
        assert_bias_matches(3, 9.81, wrong, 0, q, v)


def test_eq12_comparison_fails_without_the_armature() -> None:
    """Dropping model.armature (the reflected rotor inertia gr^2 Jm) changes exactly crba's diagonal."""
    arm, _, (J, _) = derived(3, 0.0)
    model = pinocchio_model(arm)
    model.armature = np.zeros(model.nv)
    q, v = states(3)[0]
    diff = np.asarray(J(q, v), dtype=float) - pin_inertia(model, q)
    expected = [_f(m.gear_ratio ** 2 * m.rotor_inertia) for m in arm.motors]
    assert max(expected) > 0
    np.testing.assert_allclose(diff, np.diag(expected), rtol=0, atol=1e-13)  # off-diagonal: 0
