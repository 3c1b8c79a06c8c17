"""The sampled loop's linearisation (derive.control.sampling) when the plant carries a payload.

The controller is the nominal one (its laws, its observer's J and G); the plant is the arm with a
rigid payload on its last body, J_true = J + J_p, G_true = G + G_p (derive.dynamics.payload).
At an operating point of derive.control.sampling.grid the loop is in equilibrium with the payload once the
observer holds the disturbance the payload makes (the static part of G_p - (J_p theta'' = 0)): the
observer's state and the integral sit elsewhere, but every law is affine in its state (u = u* -
B^-1 (z + W theta'), u* + B^-1 W xi, u* - B^-1 K (J theta' - m)), so the laws' Jacobians, the
observer's dr and the momentum observer's rate Jacobian are the nominal ones. What changes is the
plant's row of the linearisation:

    d theta''/d theta  = -J_true^-1 (dG_true/d theta + d(J a)/d theta),
    d theta''/d theta' = -J_true^-1 dG_true/d theta',     d theta''/du = J_true^-1 B,

at a = theta'' = 0: the operating points have y_d'' = 0 and e = 0, where every law gives theta'' = 0
to rounding (4e-14 rad/s^2 on the UR5's grid), so d(J_true a)/d theta vanishes there and the
loaded plant's rows are the same for every form (their zero-order hold is shared); with no payload
the nominal linearisation is used as derive.control.sampling computes it.

The payload's ten parameters are linear in its mass at a fixed centre of mass and shape (h = m c,
I_o = m (Ic/m + |c|^2 1 - c c^T)), so J_p and dG_p are evaluated once per centre of mass at unit
mass (CasADi, exact Jacobians) and scaled: each mass the search tries costs a solve, not a
derivation.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import sympy as sp

from derive.dynamics.dag import Memo
from derive.dynamics.payload import payload_terms
from derive.dynamics.sx import to_sx


class PayloadPlant:
    """J_p and dG_p/d(theta, theta') of derivation ``d``'s payload at many points and payloads."""

    def __init__(self, d) -> None:
        n = self.n = d.n
        terms = payload_terms(d.dynamics)
        s = d.dynamics.sym
        x = ca.SX.sym("x", 2 * n)
        p = ca.SX.sym("p", len(terms.symbols))
        env = {v: ca.SX(float(val)) for v, val in d.values}
        env.update({v: x[i] for i, v in enumerate(list(s.theta) + list(s.dtheta))})
        env.update({v: p[i] for i, v in enumerate(terms.symbols)})
        memo = Memo()
        J = ca.vertcat(*[to_sx(sp.sympify(e), env, memo) for e in terms.J])     # row-major
        G = ca.vertcat(*[to_sx(sp.sympify(e), env, memo) for e in terms.G])
        self._f = ca.Function("payload", [ca.vertcat(x, p)], [J, ca.reshape(ca.jacobian(G, x).T, -1, 1)])
        self._maps: dict[int, ca.Function] = {}

    def unit(self, Q: np.ndarray, DQ: np.ndarray, pi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """J_p (R x n x n) and dG_p/d(theta, theta') (R x n x 2n) at the rows of Q, DQ (R x n) with the
        payload parameters of the rows of ``pi`` (R x 10; derive.dynamics.payload.NAMES)."""
        n, R = self.n, Q.shape[0]
        if R not in self._maps:
            self._maps[R] = self._f.map(R)
        J, dG = self._maps[R](np.hstack([Q, DQ, pi]).T)
        return np.asarray(J).T.reshape(R, n, n), np.asarray(dG).T.reshape(R, n, 2 * n)


def plant_rows(J: np.ndarray, dG: np.ndarray, B: np.ndarray, Jp: np.ndarray, dGp: np.ndarray,
               mass: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, Bu) of the loaded plant at theta'' = 0 (R x 2n x 2n, R x 2n x n): the same for every form,
    so that the forms' searches share its zero-order hold."""
    R, n = J.shape[0], J.shape[-1]
    rhs = np.concatenate([dG + mass * dGp, -np.broadcast_to(B, (R, n, n))], axis=-1)
    sol = np.linalg.solve(J + mass * Jp, rhs)
    A = np.zeros((R, 2 * n, 2 * n))
    A[:, :n, n:] = np.eye(n)
    A[:, n:, :] = -sol[:, :, :2 * n]
    Bu = np.zeros((R, 2 * n, n))
    Bu[:, n:, :] = -sol[:, :, 2 * n:]
    return A, Bu
