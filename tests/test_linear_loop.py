"""The sampled loop's linearisation (derive.control.sampling.linear_loop): CasADi's exact Jacobians of the
laws (eq. 15, 27, 34, MOM) and of the plant (eq. 11-12) agree with central differences of the same
functions, on the paper's arm and on a 6-joint URDF arm, at points of the sample-time grid."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import derive
from derive.control.sampling import FORMS, _loop, operating_points

ARMS = {"default": None, "ur5": Path(__file__).resolve().parent / "data" / "urdf" / "ur5.toml"}


@pytest.fixture(scope="module", params=sorted(ARMS))
def case(request):
    d = derive.derive(derive.load_arm(ARMS[request.param]))
    pts = operating_points(d)
    pick = np.linspace(0, len(pts) - 1, 6).astype(int)
    Q = np.array([pts[i][0] for i in pick], dtype=float)
    DQ = np.array([pts[i][1] for i in pick], dtype=float)
    return d, _loop(d), Q, DQ


def _central(f, X: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """P x m x k central differences of f: (P, k) -> (P, m)."""
    cols = []
    for i in range(X.shape[1]):
        step = h * (1.0 + np.abs(X[:, i]))
        E = np.zeros_like(X)
        E[:, i] = step
        cols.append((f(X + E) - f(X - E)) / (2 * step)[:, None])
    return np.stack(cols, axis=-1)


def _close(exact: np.ndarray, approx: np.ndarray) -> None:
    scale = 1.0 + np.abs(exact).max()
    assert np.abs(exact - approx).max() <= 1e-6 * scale, np.abs(exact - approx).max() / scale


@pytest.mark.parametrize("form", FORMS)
def test_law_jacobians_eq15_27_34_are_the_central_differences_of_the_laws(case, form):
    d, loop, Q, DQ = case
    n, P = d.n, Q.shape[0]
    L = loop.linearise(form, Q, DQ)
    ref = np.hstack([Q @ loop.C.T, DQ @ loop.C.T, np.zeros((P, n))])
    state = {"dobc": -DQ @ loop.W.T, "mom": np.einsum("pij,pj->pi", loop.mass(Q), DQ)}.get(form, np.zeros((P, n)))

    def u(XC):
        return loop.law(form, XC[:, :n], XC[:, n:2 * n], ref, XC[:, 2 * n:])[0]

    U = _central(u, np.hstack([Q, DQ, state]))
    _close(L["Ux"], U[:, :, :2 * n])
    if form != "mpc":
        _close(L["Uc"], U[:, :, 2 * n:])


def test_plant_and_momentum_jacobians_eq11_12_are_the_central_differences(case):
    d, loop, Q, DQ = case
    n = d.n
    L = loop.linearise("mom", Q, DQ)
    u0 = loop.law("mom", Q, DQ, np.hstack([Q @ loop.C.T, DQ @ loop.C.T, np.zeros_like(Q)]),
                  np.einsum("pij,pj->pi", loop.mass(Q), DQ))[0]

    def f(XU):
        q, dq, u = XU[:, :n], XU[:, n:2 * n], XU[:, 2 * n:]
        acc = np.linalg.solve(loop.mass(q), (u @ loop.B.T - loop.bias(q, dq)[0])[..., None])[..., 0]
        return np.hstack([dq, acc])

    F = _central(f, np.hstack([Q, DQ, u0]))
    _close(L["A"], F[:, :, :2 * n])
    _close(L["Bu"], F[:, :, 2 * n:])

    def momentum(X):
        return np.einsum("pij,pj->pi", loop.mass(X[:, :n]), X[:, n:])

    X0 = np.hstack([Q, DQ])
    _close(L["P"], _central(momentum, X0))
    f0 = f(np.hstack([X0, u0]))
    h = 1e-5 / (1.0 + np.abs(f0).max(axis=1, keepdims=True))
    Pdot = (_central(momentum, X0 + h * f0) - _central(momentum, X0 - h * f0)) / (2 * h[:, :, None])
    scale = 1.0 + np.abs(L["Pdot"]).max()
    assert np.abs(L["Pdot"] - Pdot).max() <= 1e-4 * scale
