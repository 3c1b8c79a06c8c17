"""The grouped bound of the outer angles (derive.control.certificate.grouped, issue 23) and its branch and
bound over the inner angles' torus (derive.control.certificate.grouped_cells), for (*) of the appendix (a7).

The bound must be sound (J' <= B at every state, checked at random states it never saw, for every
vertex), its Fourier series in the inner angles must be B itself, and the branch and bound must
prove only what N itself allows.
"""
from __future__ import annotations

import numpy as np
import pytest

import derive
from derive.control import certificate as cert
from derive.control.certificate import report as cert_report
from derive.control.certificate.grouped import GroupedModel
from derive.control.certificate.grouped_cells import decide_grouped

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


# -- the grouped stage on cells shared by the vertices (derive.control.certificate.grouped_union) -----------------

def _full_series(shared_model, W):
    """Every vertex's B~ = T B T^T (S = W + W^T = L L^T, T = L^-1) and its gradient from the whole
    series (no term dropped): functions of points q (P x m) giving P x V x n x n and P x V x m x n x n."""
    H, C, basis = shared_model.series()
    T = np.linalg.inv(np.linalg.cholesky(W + W.T))
    Ct = np.einsum("ab,xrkbc,dc->xrkad", T, C, T)
    Hf = H.astype(float)

    def value(q):
        arg = q @ Hf.T
        Br = np.einsum("pk,rkab->prab", np.cos(arg), Ct[0]) + np.einsum("pk,rkab->prab", np.sin(arg), Ct[1])
        return np.einsum("vr,prab->pvab", basis, Br)

    def gradient(q):
        arg = q @ Hf.T
        Br = np.einsum("pk,kj,rkab->pjrab", -np.sin(arg), Hf, Ct[0]) \
            + np.einsum("pk,kj,rkab->pjrab", np.cos(arg), Hf, Ct[1])
        return np.einsum("vr,pjrab->pvjab", basis, Br)

    return value, gradient


@pytest.fixture(scope="module")
def ur5_shared(ur5):
    from derive.control.certificate.grouped_union import Shared

    d, model = ur5
    shape = np.array([2.0, 1.0, 1.5, 1.0, 3.0, 2.5])
    g = GroupedModel(model, (0, 1, 3), shape)
    rng = np.random.default_rng(11)
    A = rng.normal(size=(6, 6))
    W = 3.0 * np.eye(6) + 0.3 * A        # not symmetric, W + W^T positive definite
    return g, W, Shared(g, W)


def test_shared_values_are_the_whole_series_within_the_shift(ur5_shared):
    """Every vertex's value from the kept terms (products of two halves' exponentials, the basis
    combined) differs from the whole series by less than the vertex's shift, at 300 random points;
    and the shift is not vacuous (below a hundredth of the values' size)."""
    g, W, prep = ur5_shared
    value, _ = _full_series(g, W)
    q = np.random.default_rng(12).uniform(-np.pi, np.pi, (300, g.m))
    got = prep.values(q)                                                       # V x u x P
    want = value(q)                                                            # P x V x n x n
    iu = prep.iu
    diff = np.moveaxis(got, -1, 0) - want[..., iu[0], iu[1]]                   # P x V x u
    D = np.zeros(want.shape)
    D[..., iu[0], iu[1]] = diff
    D[..., iu[1], iu[0]] = diff
    err = np.abs(np.linalg.eigvalsh(D)).max(axis=(0, 2))                     # V
    assert np.all(err <= prep.shift)
    assert prep.shift.max() < 0.01 * np.abs(np.linalg.eigvalsh(want)).max()


def test_cell_remainder_bounds_hold_at_random_cells_and_a_smaller_one_is_caught(ur5_shared):
    """The cell test's bounds (grouped_union docstring) against the whole series at 400 random cells,
    a random theta* in each and every vertex: the first-order Taylor error from theta*,
    B~(theta*) + dB~(theta*)[c - theta*] - B~(c), has largest eigenvalue at most
    1/2 || sum_jk r_j r_k T2_jk ||_2 (Shared.quad), and |d_j B~| <= T1_j entrywise. The same check
    with T2 a quarter of its value fails somewhere: it can catch a wrong bound."""
    g, W, prep = ur5_shared
    value, gradient = _full_series(g, W)
    rng = np.random.default_rng(13)
    P = 400
    r = rng.uniform(0.05, 0.6, (P, g.m))
    c = rng.uniform(-np.pi, np.pi, (P, g.m))
    star = c + r * rng.uniform(-1, 1, (P, g.m))
    delta = c - star
    err = value(star) + np.einsum("pj,pvjab->pvab", delta, gradient(star)) - value(c)      # P x V x n x n
    top = np.linalg.eigvalsh(err)[..., -1]                                                   # P x V
    bound = np.stack([prep.quad(x) for x in r])                                              # P x V
    assert np.all(top <= bound)
    assert np.any(top > 0.25 * bound)       # a quarter of the bound is exceeded: the check has teeth
    assert np.all(np.abs(gradient(star)) <= prep.T1[None] * (1 + 1e-9))


def test_grouped_stage_proves_below_and_never_above_the_supremum():
    """planar_3link (one inner, one outer angle), W = Chen's: decide_shared proves half the grouped
    supremum's estimate; never 1.05 times N's own numeric supremum; the estimate is not above the
    sampled one of GroupedModel.supremum by more than sampling (it is locally optimised)."""
    from derive.control.certificate.grouped_union import Shared, decide_shared

    d = derive.derive(derive.load_arm("planar_3link"))
    model = cert_report.inertia_model(d)
    W = np.array(d.W.tolist(), dtype=float)
    g = GroupedModel(model, (0,), np.ones(d.n))
    prep = Shared(g, W)
    sup = prep.supremum()
    exact = cert.ObserverCertificate(model).speed_supremum(W, np.ones(d.n), exact=True)
    assert sup <= g.supremum(W, 1024) * (1 + 1e-6)
    assert sup <= exact * (1 + 1e-9)
    assert decide_shared(g, W, 0.5 * sup, prepared=prep).verdict is cert.Verdict.PROVED
    assert decide_shared(g, W, 0.9 * sup, prepared=prep).verdict is cert.Verdict.PROVED
    assert decide_shared(g, W, 1.05 * exact, budget=20_000, prepared=prep).verdict is cert.Verdict.UNPROVEN


def test_grouped_stage_is_deterministic_and_opt_in(ur5):
    """Two decisions of the same claim examine the same cells with the same verdict; the stage
    exists only with grouped=True, and is not used at a positive rate or on another box shape."""
    d, model = ur5
    W = 3.0 * np.eye(6)
    assert cert.ObserverCertificate(model).grouped is None
    c = cert.ObserverCertificate(model, np.ones(6), grouped=True)
    sup = c.grouped.supremum(W)
    a, b = c.grouped.decide(W, 0.6 * sup), c.grouped.decide(W, 0.6 * sup)
    assert a.verdict is b.verdict is cert.Verdict.PROVED and a.cells == b.cells and a.low == b.low
    assert c._grouped_for(np.ones(6), 0.0)
    assert not c._grouped_for(np.ones(6), 0.1) and not c._grouped_for(2 * np.ones(6), 0.0)
    plain = cert.ObserverCertificate(model, np.ones(6))
    at_rate = c.decide(W, np.ones(6), 0.6 * sup, 0.1, budget=300)
    assert at_rate.cells == plain.decide(W, np.ones(6), 0.6 * sup, 0.1, budget=300).cells


@pytest.mark.slow
def test_grouped_stage_proves_80_percent_of_the_panda_supremum_and_the_adversary_agrees():
    """Issue 23: the Panda's synthesised W (full, 1 rad/s box): largest_proved_speed with the grouped
    stage proves at least 80 % of N's own numeric supremum, and the adversarial search (L-BFGS-B from
    the worst of 10,000 random states) finds no state inside that box where lambda_min(N) <= 0."""
    from derive.control.certificate.adversary import search
    from derive.control.certificate.synthesis import synthesise

    from .test_spatial_dynamics import vendored_arm

    d = derive.derive(vendored_arm("panda"))
    model = cert_report.inertia_model(d)
    W = np.array([[float(x) for x in row] for row in synthesise(model, [1.0] * 7, structure="full").W])
    c = cert.ObserverCertificate(model, np.ones(7), grouped=True)
    proved, dec = cert_report.largest_proved_speed(c, W, np.ones(7))
    assert dec.verdict is cert.Verdict.PROVED
    assert proved >= 0.8 * c.speed_supremum(W, np.ones(7), exact=True)
    assert search(model, W, [proved] * 7).low > 0


def test_grouped_stage_reads_a_negative_scale_as_its_box_and_refuses_what_it_cannot_weigh(ur5):
    """A negative v is the box of |v| (the vertices are symmetric; I - v B~ holds the majorant only
    for v >= 0): beyond N's own numeric supremum -v proves nothing, below it the same cells as v. A
    non-finite v or W proves nothing, without an exception; a box shape with a joint J depends on at
    rest (0) gets no grouped stage (its vertex weights divide by the shape) and decides without it."""
    from derive.control.certificate.grouped_union import Shared, decide_shared

    d = derive.derive(derive.load_arm("planar_3link"))
    model = cert_report.inertia_model(d)
    W = np.array(d.W.tolist(), dtype=float)
    g = GroupedModel(model, (0,), np.ones(d.n))
    prep = Shared(g, W)
    exact = cert.ObserverCertificate(model).speed_supremum(W, np.ones(d.n), exact=True)
    assert decide_shared(g, W, -1.05 * exact, budget=20_000, prepared=prep).verdict is cert.Verdict.UNPROVEN
    up, down = decide_shared(g, W, 0.5 * exact, prepared=prep), decide_shared(g, W, -0.5 * exact, prepared=prep)
    assert up.verdict is down.verdict is cert.Verdict.PROVED and up.cells == down.cells
    for v, bad in ((np.nan, W), (np.inf, W), (0.5 * exact, np.where(np.eye(d.n) > 0, np.inf, W))):
        assert decide_shared(g, bad, v, prepared=None).verdict is cert.Verdict.UNPROVEN
    _, ur5_model = ur5
    shape = np.ones(6)
    shape[[c.index for c in ur5_model.deps][2]] = 0.0
    c = cert.ObserverCertificate(ur5_model, shape, grouped=True)
    assert c.grouped is None
    assert c.decide(3.0 * np.eye(6), shape, 0.1, budget=300).verdict in tuple(cert.Verdict)
