"""The proved radius bound that spares the sample-time search most eigenvalue problems
(derive.control.sampling.radius.stable_bound, spectral_radius): where it proves a radius below 1 the
radius is below 1 and below the bound; where a radius is 1 or more it proves nothing, and the search
sees the radius itself; the limits it finds are those of the eigenvalues alone."""
from __future__ import annotations

import numpy as np

import derive
from derive.control import sampling
from derive.control.sampling.radius import balancing, spectral_radius, stable_bound


def _stack(seed: int, count: int = 4000, k: int = 9) -> np.ndarray:
    """Matrices of every kind the search meets: radii from 0.1 to 1.5, near 1 on both sides,
    normal and strongly non-normal (a transient growth of up to 1e4 before the decay)."""
    rng = np.random.default_rng(seed)
    out = np.empty((count, k, k))
    for p in range(count):
        Q, R = np.linalg.qr(rng.standard_normal((k, k)))
        T = np.triu(rng.standard_normal((k, k)) * 10.0 ** rng.uniform(-3, 4), 1)
        radius = rng.choice([rng.uniform(0.1, 1.5), 1 - 10.0 ** rng.uniform(-12, -1), 1 + 10.0 ** rng.uniform(-12, -1)])
        angles = rng.uniform(0, np.pi, k)
        T[np.arange(k), np.arange(k)] = radius * rng.uniform(0.2, 1.0, k) * np.sign(np.cos(angles))
        T[0, 0] = radius * np.sign(T[0, 0] or 1.0)
        S = rng.standard_normal((k, k)) * 10.0 ** rng.uniform(-2, 1) + np.eye(k) * 3
        out[p] = S @ Q @ T @ Q.T @ np.linalg.inv(S)
    return out


def test_a_proved_bound_is_below_1_and_above_the_radius():
    M = _stack(0)
    bound = stable_bound(M)
    rho = np.abs(np.linalg.eigvals(M)).max(axis=-1)
    proved = bound < 1.0
    assert proved[rho < 0.8].mean() > 0.6              # not vacuous: most radii well below 1 are proved
    assert np.all(rho[proved] < 1.0)
    assert np.all(rho[proved] <= bound[proved] * (1 + 1e-12))
    assert np.all(np.isinf(bound[~proved]))


def test_the_balancing_is_an_exact_similarity_that_lets_badly_scaled_loops_be_proved():
    """States in units 1e4 apart (rad, rad/s, N m): D^-1 M D with D of powers of two has the very
    eigenvalues of M, bit for bit its entries times powers of two, and the bound proves far more
    of the stable ones than without the scaling."""
    M = _stack(3, count=1500)
    scale = 10.0 ** np.repeat([0, 2, 4], 3)
    M = M * (scale[:, None] / scale[None, :])
    f = balancing(M)
    assert f is not None and np.all(np.log2(f) == np.round(np.log2(f)))
    B = M * (f[None, :] / f[:, None])
    assert np.array_equal(B / (f[None, :] / f[:, None]), M)
    rho = np.abs(np.linalg.eigvals(M)).max(axis=-1)
    with_scaling = (stable_bound(M) < 1)[rho < 0.95].mean()
    import derive.control.sampling.radius as radius
    plain = radius.balancing
    try:
        radius.balancing = lambda P, sweeps=2: None
        without = (stable_bound(M) < 1)[rho < 0.95].mean()
    finally:
        radius.balancing = plain
    assert with_scaling > without + 0.2, (with_scaling, without)
    assert np.all(rho[stable_bound(M) < 1] < 1)


def test_a_radius_of_1_or_more_is_never_proved():
    M = _stack(1)
    rho = np.abs(np.linalg.eigvals(M)).max(axis=-1)
    assert (rho >= 1.0).sum() > 500
    assert np.all(np.isinf(stable_bound(M[rho >= 1.0])))


def test_the_search_sees_every_radius_of_1_or_more_and_every_radius_when_ranking():
    M = _stack(2)
    exact = spectral_radius(M)
    fast = spectral_radius(M, exact=False)
    assert np.array_equal(fast >= 1.0, exact >= 1.0)
    assert np.array_equal(fast[exact >= 1.0], exact[exact >= 1.0])
    assert np.argmax(fast) == np.argmax(exact)
    assert np.array_equal(spectral_radius(M, exact=False, rank=True), exact)
    stable = M[exact < 0.999]
    assert np.all(spectral_radius(stable, exact=False, rank=True) < 1.0)


def test_sample_limits_are_those_of_the_eigenvalues_alone(monkeypatch):
    """my3-like 3-joint chain and the default arm: every limit, raw value and worst point of both
    discretisations equal to the search with every radius from its eigenvalues."""
    from derive.control.sampling import radius
    from derive.model.examples import planar_chain

    for arm in (derive.load_arm(), planar_chain(3)):
        d = derive.derive(arm)
        fast = {obs: sampling.limits(d, obs) for obs in sampling.OBSERVERS}
        for kept in (sampling._LIMITS, sampling._HINTS):    # the search again, the linearisation kept
            kept.clear()
        monkeypatch.setattr(radius, "stable_bound", lambda M: np.full(M.shape[:-2], np.inf))
        slow = {obs: sampling.limits(d, obs) for obs in sampling.OBSERVERS}
        monkeypatch.undo()
        assert fast == slow
