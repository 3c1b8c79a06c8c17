"""Dynamics (eq. 11-12, a6): the recursive form against the Lagrangian
reference, a textbook closed form and the structural properties of J and C."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import derive
from derive.dynamics.equations import derive_dynamics, lagrange_reference
from derive.dynamics.planar import a6_form, planar_reference
from derive.dynamics.identities import first_nonzero, matrix_is_zero
from derive.dynamics.program import matrix_xreplace

from .arms import chain


def _at(m, point: dict) -> np.ndarray:
    """m evaluated at ``point`` in 30-digit floats (substituted, each shared
    subexpression once, so no adaptive evalf)."""
    floats = {s: sp.Float(v, 30) for s, v in point.items()}
    return np.array(matrix_xreplace(m, floats).tolist(), dtype=float)


def _numeric(m, values, rng, syms):
    point = dict(values)
    point.update({s: rng.uniform(-3, 3) for s in syms})
    return _at(m, point)


def test_eq12_two_link_inertia_matches_spong_closed_form(paper):
    """J of the paper's arm equals Spong's planar 2-link M(q) with the same bodies.

    Spong, Hutchinson, Vidyasagar (2006), eq. 7.87: for bodies of mass m_i,
    centre-of-mass distance lc_i and central inertia I_i,
    d11 = m1 lc1^2 + m2 (l1^2 + lc2^2 + 2 l1 lc2 cos q2) + I1 + I2,
    d12 = m2 (lc2^2 + l1 lc2 cos q2) + I2, d22 = m2 lc2^2 + I2.
    """
    arm = paper.arm
    R = lambda f: sp.Rational(f.numerator, f.denominator)  # noqa: E731

    def body(i):
        # link i with the point masses it carries, as one body (mass, lc, central inertia)
        parts = [(R(arm.links[i].mass), R(arm.links[i].com), R(arm.links[i].inertia))]
        parts += [(R(p.mass), R(p.distance), R(p.inertia)) for p in arm.point_masses if p.link == i]
        m = sum(p[0] for p in parts)
        lc = sum(p[0] * p[1] for p in parts) / m
        inertia = sum(p[2] + p[0] * (p[1] - lc) ** 2 for p in parts)
        return m, lc, inertia

    (m1, lc1, I1), (m2, lc2, I2) = body(0), body(1)
    l1 = R(arm.links[0].length)
    c2 = sp.cos(paper.theta[1])
    d11 = m1 * lc1 ** 2 + m2 * (l1 ** 2 + lc2 ** 2 + 2 * l1 * lc2 * c2) + I1 + I2
    d12 = m2 * (lc2 ** 2 + l1 * lc2 * c2) + I2
    d22 = m2 * lc2 ** 2 + I2
    spong = sp.Matrix([[d11, d12], [d12, d22]])
    assert (paper.J - spong).applyfunc(sp.expand) == sp.zeros(2, 2)


def test_eqa6_lumped_parameters_of_the_paper_arm(paper):
    """J has the form (a6); X = l1 (m2 c2 + m_tip l2) from the appendix table."""
    lump = paper.lumped
    assert set(lump) == {"j1", "j2", "j3", "X"}
    assert lump["X"] == sp.Rational(38, 100) * (sp.Rational(361, 1000) * sp.Rational(19, 100)
                                                + sp.Rational(1, 10) * sp.Rational(38, 100))
    assert (paper.J - a6_form(lump, paper.theta[1])).applyfunc(sp.expand) == sp.zeros(2, 2)


def test_eq26_speed_bound_is_w1_over_X(paper):
    assert paper.speed_bound == 1 / paper.lumped["X"]
    assert 24.6 < float(paper.speed_bound) < 24.7


@pytest.mark.parametrize("n", [1, 2, 3])
def test_eq12_recursive_form_equals_lagrangian_symbolically(n):
    """CRBA J and RNEA G equal the Euler-Lagrange J and G, in symbols (a proof)."""
    arm = chain(n, gravity=9.81)
    dyn = derive_dynamics(arm)
    J_ref, G_ref = lagrange_reference(dyn)
    assert first_nonzero(dyn.J - J_ref, dyn.sym.theta) is None
    assert first_nonzero(dyn.G - G_ref, dyn.sym.theta) is None


@pytest.mark.parametrize("n", [4, 6])
def test_eq12_recursive_form_equals_lagrangian_at_sampled_states(n):
    arm = chain(n, gravity=9.81)
    dyn = derive_dynamics(arm)
    J_ref, G_ref = lagrange_reference(dyn, numeric=True)
    rng = np.random.default_rng(n)
    state = dyn.sym.theta + dyn.sym.dtheta
    for _ in range(5):
        point = dict(dyn.values)
        point.update({s: rng.uniform(-3, 3) for s in state})
        for mine, ref in ((dyn.J, J_ref), (dyn.G, G_ref)):
            np.testing.assert_allclose(_at(mine, point), _at(ref, point), rtol=1e-13, atol=1e-13)


def test_recursive_form_differs_from_a_wrong_reference():
    """The identity check can fail: a perturbed J is told apart from the reference."""
    arm = chain(2)
    dyn = derive_dynamics(arm)
    J_ref, _ = lagrange_reference(dyn)
    wrong = dyn.J.copy()
    wrong[0, 1] += sp.Rational(1, 10**6) * sp.cos(dyn.sym.theta[1])
    assert first_nonzero(wrong - J_ref, dyn.sym.theta) == (0, 1)


@pytest.mark.parametrize("n", [2, 3, 4])
def test_jdot_minus_2c_is_skew_symmetric(n):
    dyn = derive_dynamics(chain(n))
    q, dq = dyn.sym.theta, dyn.sym.dtheta
    Jdot = sum((dyn.J.diff(qi) * dqi for qi, dqi in zip(q, dq)), sp.zeros(n, n))
    S = Jdot - 2 * dyn.coriolis
    assert (S + S.T).applyfunc(sp.expand) == sp.zeros(n, n)
    assert S.applyfunc(sp.expand) != sp.zeros(n, n)  # not trivially zero


@pytest.mark.parametrize("n", [2, 3])
def test_coriolis_matrix_times_velocity_is_the_velocity_part_of_the_bias(n):
    dyn = derive_dynamics(chain(n, gravity=9.81))
    residual = dyn.coriolis * sp.Matrix(dyn.sym.dtheta) - (dyn.bias - dyn.gravity)
    assert matrix_is_zero(residual, dyn.sym.theta)


def test_inertia_symmetric_positive_definite_at_sampled_angles(packaged):
    rng = np.random.default_rng(7)
    J = packaged.J
    assert J == J.T
    for _ in range(50):
        Jn = _numeric(J, {}, rng, packaged.theta)
        assert np.all(np.linalg.eigvalsh(Jn) > 0)


def test_motor_model_gives_input_matrix_and_back_emf_damping(paper):
    """B = diag(Kt/R) and G contains diag(Kt Kv / R) theta-dot (direct drive, eq. 12)."""
    B = sp.diag(sp.Rational(23, 100) / sp.Rational(34, 10), sp.Rational(44, 1000) / 5)
    assert paper.B == B
    damping = paper.G.jacobian(paper.dtheta).xreplace({s: 0 for s in paper.theta + paper.dtheta})
    assert damping == sp.diag(sp.Rational(23, 100) * sp.Rational(29, 100) / sp.Rational(34, 10),
                              sp.Rational(44, 1000) * sp.Rational(47, 1000) / 5)


def test_vertical_arm_has_gravity_and_horizontal_arm_has_none():
    from .conftest import derivation
    vertical, horizontal = derivation("vertical_2link"), derivation("glasgow_2link")
    rest = {s: 0 for s in vertical.dtheta}
    assert vertical.G.xreplace(rest).xreplace({vertical.theta[0]: 0, vertical.theta[1]: 0}) != sp.zeros(2, 1)
    assert horizontal.G.xreplace(rest) == sp.zeros(2, 1)


def test_single_link_dynamics_is_a_pendulum():
    arm = chain(1, gravity=9.81)
    d = derive.derive(arm)
    assert d.J.shape == (1, 1) and d.lumped is None and d.speed_bound is None
    q = d.theta[0]
    # G = M g hx/M cos(q) + damping dq: the only angle dependence is cos(q)
    assert sp.expand(d.G[0].diff(q, 2) + d.G[0].xreplace({d.dtheta[0]: 0})) == 0
