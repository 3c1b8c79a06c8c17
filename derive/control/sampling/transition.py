"""The sampled closed loop's transition matrix at many operating points (derive.control.sampling's module
docstring gives the loop, the discretisations and the residual coordinates of MOM): its spectral radius
decides a sample time, its continuous limit (dt -> 0) tells a limit below DT_MIN from none."""
from __future__ import annotations

import numpy as np

from derive.control.sampling.linear_loop import SampledLoop
from derive.control.sampling.radius import spectral_radius
from derive.control.sampling.zoh import zoh

_Z_ONLY = "z-only"   # backward Euler of z before the measurement moves: an analysis variant (derive.control.sampling)


def _radii(loop: SampledLoop, form: str, observer: str, dt: float, L: dict, exact: bool = True,
           rank: bool = False, eigen_first: bool = False) -> np.ndarray:
    """Spectral radius of the sampled closed loop at every operating point (derive.control.sampling's
    docstring; not ``exact``: as spectral_radius gives it, ``eigen_first`` passed on)."""
    return spectral_radius(_transition(loop, form, observer, dt, L), exact, rank, eigen_first)


def _transition(loop: SampledLoop, form: str, observer: str, dt: float, L: dict,
                hold: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The sampled closed loop's transition matrix at every operating point (P x k x k;
    derive.control.sampling's docstring); ``hold``: :func:`derive.control.sampling.zoh.zoh` of L at dt
    when the caller has it."""
    n, m = loop.n, 2 * loop.n
    P = L["A"].shape[0]
    Phi, Gam = zoh(L, dt) if hold is None else hold
    Ux, Uc = L["Ux"], L["Uc"]
    eye = np.broadcast_to(np.eye(n), (P, n, n))
    if form == "mpc":
        return Phi + Gam @ Ux
    if form == "mom":                       # m + dt m'(x, m, u), the same in both discretisations
        R = dt * L["R"]
        Sx, Sc, Su = R[:, :, :m], eye + R[:, :, m:m + n], R[:, :, m + n:]
        M = np.concatenate([np.concatenate([Phi + Gam @ Ux, Gam @ Uc], axis=-1),
                            np.concatenate([Sx + Su @ Ux, Sc + Su @ Uc], axis=-1)], axis=-2)
        return _residual(M, L, loop.K, dt)
    elif form == "npid":                      # int_e + dt (yd - C theta)
        if observer == "implicit":          # W -> W_dt = W (J + dt W)^-1 J in u = u* + B^-1 W xi
            BW = np.linalg.solve(loop.B, loop.W)
            Wdt = loop.W @ np.linalg.solve(L["J"] + dt * loop.W, L["J"])
            F = np.linalg.solve(loop.B, Wdt) - BW                      # B^-1 (W_dt - W)
            Ux, Uc = Ux + F @ L["Xi"][:, :, :m], Uc + F @ L["Xi"][:, :, m:]
        Sx = np.broadcast_to(np.hstack([-dt * loop.C, np.zeros((n, n))]), (P, n, m))
        Sc, Su = eye, np.zeros((P, n, n))
    elif observer == "implicit":            # DOBC, state (x_k, z_{k-1}, u_{k-1}): z_k first, then u_k
        K = dt * loop.W @ np.linalg.inv(L["J"] + dt * loop.W)
        Zx, Zz, Zu = K @ L["dr"], eye - K, -K @ loop.B                 # z_k = Zx x_k + Zz z_{k-1} + Zu u_{k-1}
        Vx, Vz, Vu = Ux + Uc @ Zx, Uc @ Zz, Uc @ Zu                    # u_k in the same
        M = np.concatenate([np.concatenate([Phi + Gam @ Vx, Gam @ Vz, Gam @ Vu], axis=-1),
                            np.concatenate([Zx, Zz, Zu], axis=-1),
                            np.concatenate([Vx, Vz, Vu], axis=-1)], axis=-2)
        return M
    else:                                   # explicit, or the z-only backward step (_Z_ONLY)
        A = L["J"] + (dt * loop.W if observer == _Z_ONLY else 0.0)
        K = dt * loop.W @ np.linalg.inv(A)
        Sx, Sc, Su = K @ L["dr"], eye - K, -K @ loop.B
    M = np.concatenate([np.concatenate([Phi + Gam @ Ux, Gam @ Uc], axis=-1),
                        np.concatenate([Sx + Su @ Ux, Sc + Su @ Uc], axis=-1)], axis=-2)
    return M


def _continuous_rate(loop: SampledLoop, form: str, L: dict) -> np.ndarray:
    """The largest real part of the eigenvalues of the continuous linearised closed loop (the limit
    dt -> 0 of every discretisation: M(dt) = I + dt A_cl + O(dt^2)) at every operating point: x' = A x
    + Bu u, u = Ux x + Uc c, and the form's c' (DOBC z' = W J^-1 (dr x - B u - z); NPID int_e' = -C
    theta; MOM in the residual's coordinates, as :func:`_residual`). Negative at every point: the
    continuous loop is stable there, so a loop unstable at DT_MIN has a limit below it."""
    n, m = loop.n, 2 * loop.n
    P = L["A"].shape[0]
    top = np.concatenate([L["A"] + L["Bu"] @ L["Ux"], L["Bu"] @ L["Uc"]], axis=-1)
    if form == "mpc":
        return np.linalg.eigvals(top[:, :, :m]).real.max(axis=-1)
    if form == "dobc":
        WJ = loop.W @ np.linalg.inv(L["J"])
        bottom = np.concatenate([WJ @ (L["dr"] - loop.B @ L["Ux"]), -WJ @ (np.eye(n) + loop.B @ L["Uc"])], axis=-1)
    elif form == "npid":
        bottom = np.broadcast_to(np.hstack([-loop.C, np.zeros((n, 2 * n))]), (P, n, m + n))
    else:                                     # mom: (x, m) -> (x, r), r = K (P x - m), with T' T^-1
        R = L["R"]
        bottom = np.concatenate([R[:, :, :m] + R[:, :, m + n:] @ L["Ux"], R[:, :, m:m + n] + R[:, :, m + n:] @ L["Uc"]],
                                axis=-1)
        A = np.concatenate([top, bottom], axis=-2)
        K = loop.K
        eye, zero = np.broadcast_to(np.eye(m), (P, m, m)), np.zeros((P, m, n))
        T = np.concatenate([np.concatenate([eye, zero], axis=-1),
                            np.concatenate([K @ L["P"], np.broadcast_to(-K, (P, n, n))], axis=-1)], axis=-2)
        Tinv = np.concatenate([np.concatenate([eye, zero], axis=-1),
                               np.concatenate([L["P"], np.broadcast_to(-np.linalg.inv(K), (P, n, n))], axis=-1)], axis=-2)
        Tdot = np.zeros((P, m + n, m + n))
        Tdot[:, m:, :m] = K @ L["Pdot"]
        return np.linalg.eigvals(T @ A @ Tinv + Tdot @ Tinv).real.max(axis=-1)
    return np.linalg.eigvals(np.concatenate([top, bottom], axis=-2)).real.max(axis=-1)


def _residual(M: np.ndarray, L: dict, K: np.ndarray, dt: float) -> np.ndarray:
    """The MOM transition M over (x, m) in the residual's coordinates (x, r), r = K (J theta' - m),
    taken at the sample it maps from (P_k) and at the one it maps to (P_k+1 = P_k + dt P', the
    nominal motion to first order): T_k+1^-1 M T_k, m = P x - K^-1 r. At a moving operating point m
    moves with J(theta) theta'; in m's own coordinates the frozen-time linearisation shows a mode
    of the rate of that motion (P' K-terms: my3 at 3-5 rad/s, rho = 1 + 6.9 dt at every dt) that
    the loop does not have: r' = K (B d - r) whatever the state (derive.control.momentum)."""
    n = K.shape[0]
    P = M.shape[0]
    P0, P1 = L["P"], L["P"] + dt * L["Pdot"]
    eye = np.broadcast_to(np.eye(2 * n), (P, 2 * n, 2 * n))
    zero = np.zeros((P, 2 * n, n))
    T0 = np.concatenate([np.concatenate([eye, zero], axis=-1),
                         np.concatenate([P0, np.broadcast_to(-np.linalg.inv(K), (P, n, n))], axis=-1)], axis=-2)
    T1 = np.concatenate([np.concatenate([eye, zero], axis=-1),
                         np.concatenate([K @ P1, np.broadcast_to(-K, (P, n, n))], axis=-1)], axis=-2)
    return T1 @ M @ T0
