"""Predictive gains (eq. 14-19), observer (eq. 21-25) and the PID form (eq. 27-38)."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest
import sympy as sp

from derive.control.mpc import T1, T2, gains, tbar
from derive.model.spec import packaged_arms


def test_eq18_tbar_entries():
    assert tbar(3, 3) == (T2 ** 5 - T1 ** 5) / 20
    assert tbar(3, 1) == (T2 ** 3 - T1 ** 3) / 6
    assert tbar(3, 2) == (T2 ** 4 - T1 ** 4) / 8
    assert tbar(1, 1) == T2 - T1


def test_eq16_eq17_paper_gains_for_T1_0_T2_1_over_1_2(paper):
    """Section 5.2: T1 = 0, T2 = 1/1.2 s gives K1 = 4.8 I and K2 = 3.0 I."""
    assert gains(sp.Integer(0), 1 / sp.Rational(12, 10)) == (sp.Rational(24, 5), sp.Integer(3))
    assert paper.K1 == sp.Rational(24, 5) * sp.eye(2)
    assert paper.K2 == 3 * sp.eye(2)


def test_eq15_closed_loop_polynomial_is_s2_plus_K2_s_plus_K1(paper):
    """Plant (12) with d = 0 under u* (15): e'' + K2 e' + K1 e = 0, so the
    characteristic polynomial of each output is s^2 + K2 s + K1 = s^2 + 3 s + 4.8."""
    s = paper.dynamics.sym
    e = sp.Matrix(s.yd) - paper.C * sp.Matrix(s.theta)
    de = sp.Matrix(s.dyd) - paper.C * sp.Matrix(s.dtheta)
    u = paper.u_star.xreplace({**dict(zip(s.e, e)), **dict(zip(s.de, de))})
    ddtheta = paper.J.LUsolve(paper.B * u - paper.G)
    dde = sp.Matrix(s.ddyd) - paper.C * ddtheta
    residual = dde + paper.K2 * de + paper.K1 * e
    assert residual.applyfunc(lambda x: sp.simplify(sp.cancel(x))) == sp.zeros(2, 1)
    lam = sp.Symbol("s")
    A = sp.Matrix([[0, 1], [-paper.K1[0, 0], -paper.K2[0, 0]]])
    assert sp.expand(A.charpoly(lam).as_expr()) == lam ** 2 + 3 * lam + sp.Rational(24, 5)


def test_eq25_observer_gain_matrix_and_eq23_p(paper):
    assert paper.W == sp.Matrix([[1, 0], [1, 2]])
    p = paper.numeric(paper.observer.p)
    assert p == sp.Matrix([paper.dtheta[0], paper.dtheta[0] + 2 * paper.dtheta[1]])


def test_eq24_observer_gain_is_W_J_inverse(paper):
    assert (paper.L * paper.J - paper.W).applyfunc(sp.cancel) == sp.zeros(2, 2)


def _printed_gains(d):
    """P, D, I, N exactly as printed in eq. (35)-(38)."""
    Binv, Cinv = d.B.inv(), d.C.inv()
    ddyd = sp.Matrix(d.dynamics.sym.ddyd)
    return (Binv * (d.J * Cinv * d.K1 + d.W * Cinv * d.K2), Binv * (d.J * Cinv * d.K2 + d.W * Cinv),
            Binv * d.W * Cinv * d.K1, Binv * (d.J * Cinv * ddyd + d.G))


def _same(a, b) -> bool:
    return (a - b).applyfunc(sp.expand) == sp.zeros(*a.shape)


def test_eq35_proportional_gain(packaged):
    assert _same(packaged.P, _printed_gains(packaged)[0])


def test_eq36_derivative_gain(packaged):
    assert _same(packaged.D, _printed_gains(packaged)[1])


def test_eq37_integral_gain(packaged):
    assert _same(packaged.I, _printed_gains(packaged)[2])
    assert packaged.I.free_symbols == set()


def test_eq38_nonlinear_term_depends_on_reference_acceleration(packaged):
    assert _same(packaged.N, _printed_gains(packaged)[3])
    assert set(packaged.dynamics.sym.ddyd) <= packaged.N.free_symbols


def test_eq33_composite_law_equals_pid_form_with_derived_initial_estimate(paper):
    """u* - dhat(t), dhat(t) from integrating (29) with the derived dhat(0), is
    P e + D e' + I int e + N identically (eq. 33-34)."""
    s = paper.dynamics.sym
    pid = (paper.P * sp.Matrix(s.e) + paper.D * sp.Matrix(s.de) + paper.I * sp.Matrix(s.int_e) + paper.N)
    dhat_t = paper.numeric(paper.npid.dhat_t).xreplace(
        dict(zip([sp.Symbol(f"dhat0_{i + 1}", real=True) for i in range(2)], paper.dhat0)))
    assert _same(paper.u_star - dhat_t, pid)


def test_eq30_derived_initial_estimate_differs_from_printed_eq31(paper):
    """The derived dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0)); printed (31) lacks K2."""
    s = paper.dynamics.sym
    M = paper.B.inv() * paper.W * paper.C.inv()
    e0, de0 = sp.Matrix(s.e0), sp.Matrix(s.de0)
    assert _same(paper.dhat0, -M * (de0 + paper.K2 * e0))
    printed31 = -M * de0 - M * e0
    assert not _same(paper.dhat0, printed31)


def test_eq22_dhat_and_eq27_composite_law(paper):
    s = paper.dynamics.sym
    dhat = paper.B.inv() * (sp.Matrix(s.z) + paper.W * sp.Matrix(s.dtheta))
    assert _same(paper.dhat, dhat)
    assert _same(paper.u_dobc, paper.u_star - dhat)


@pytest.mark.parametrize("arm", packaged_arms())
def test_derive_show_prints_every_attribute_of_each_packaged_arm(arm):
    out = subprocess.run([sys.executable, "-m", "derive", "show", arm], capture_output=True, text=True,
                         encoding="utf-8", timeout=120, env={**os.environ, "PYTHONIOENCODING": "utf-8"})
    assert out.returncode == 0, out.stderr
    for name in ("J(θ)", "G(θ, θ̇)", "K1", "K2", "P(θ)", "D(θ)", "N(θ, θ̇)", "d̂(0)"):
        assert f"\n{name}   " in out.stdout
    assert "Traceback" not in out.stderr


def test_derive_show_latex_of_the_default_arm():
    out = subprocess.run([sys.executable, "-m", "derive", "show", "--latex"], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert r"0.179297 + 0.0810084 \cos{\left(\theta_{2} \right)}" in out.stdout
    assert out.stdout.count(r"\label{derive:glasgow_2link:") >= 15
