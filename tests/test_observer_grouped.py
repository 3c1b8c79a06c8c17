"""The grouped bound of the outer angles (derive.control.grouped, issue 23) and its branch and
bound over the inner angles' torus (derive.control.grouped_cells), for (*) of the appendix (a7).

The bound must be sound (J' <= B at every state, checked at random states it never saw, for every
vertex), its Fourier series in the inner angles must be B itself, and the branch and bound must
prove only what N itself allows.
"""
from __future__ import annotations

import numpy as np
import pytest

import derive
from derive.control import certificate as cert
from derive.control import cert_report
from derive.control.grouped import GroupedModel
from derive.control.grouped_cells import decide_grouped

from .test_spatial_dynamics import vendored_arm


@pytest.fixture(scope="module")
def ur5():
    d = derive.derive(vendored_arm("ur5"))
    return d, cert_report.inertia_model(d)


def test_grouped_bound_is_a_majorant_of_j_dot_at_random_states(ur5):
    """B(theta_in, s) - J'(theta, s) >= 0 at 2,000 random angles (whole turns) and every vertex of a
    box of uneven shape, the exact J' from J's series at the state (the outer angles random)."""
    d, model = ur5
    coef, F = model.fourier
    shape = np.array([2.0, 1.0, 1.5, 1.0, 3.0, 2.5])
    g = GroupedModel(model, (0, 1, 3), shape)
    rng = np.random.default_rng(7)
    q = rng.uniform(-np.pi, np.pi, (2000, model.m))
    B = g.bound(q[:, [0, 1, 3]])
    Jd = np.einsum("pk,vk,kab->pvab", np.exp(1j * (q @ F.T)), 1j * (g.signs @ F.T), coef, optimize=True).real
    gap = np.linalg.eigvalsh(B - Jd)[..., 0]
    assert gap.min() >= -1e-9
    assert gap.min() < 0.5 * np.abs(np.linalg.eigvalsh(Jd)).max()   # not vacuous


def test_grouped_series_is_the_bound_itself(ur5):
    """B_sigma from its Fourier series in the inner angles (the basis of sign monomials) equals B
    from the groups at 200 random inner angles, every vertex, to rounding."""
    d, model = ur5
    shape = np.array([2.0, 1.0, 1.5, 1.0, 3.0, 2.5])
    g = GroupedModel(model, (0, 1, 3), shape)
    H, C, basis = g.series()
    q = np.random.default_rng(8).uniform(-np.pi, np.pi, (200, 3))
    arg = q @ H.T
    Br = np.einsum("pk,rkab->prab", np.cos(arg), C[0]) + np.einsum("pk,rkab->prab", np.sin(arg), C[1])
    B = g.bound(q)
    assert np.abs(np.einsum("vr,prab->pvab", basis, Br) - B).max() <= 1e-10 * np.abs(B).max()


def test_grouped_branch_and_bound_proves_below_and_never_above_the_supremum():
    """planar_3link (one inner, one outer angle), W = Chen's of the paper's default: proved at half
    the grouped bound's sampled supremum; never proved above N's own numeric supremum."""
    d = derive.derive(derive.load_arm("planar_3link"))
    model = cert_report.inertia_model(d)
    W = np.array(d.W.tolist(), dtype=float)
    g = GroupedModel(model, (0,), np.ones(d.n))
    sup = g.supremum(W, 1024)
    exact = cert.ObserverCertificate(model).speed_supremum(W, np.ones(d.n), exact=True)
    assert sup <= exact * (1 + 1e-9)
    assert decide_grouped(g, W, 0.5 * sup).verdict is cert.Verdict.PROVED
    assert decide_grouped(g, W, 1.05 * exact, budget=2000).verdict is cert.Verdict.UNPROVEN
