"""The largest sample time of each generated controller form (MPC eq. 15, DOBC eq. 21-27, NPID eq. 34,
MOM: the generalized-momentum observer of derive.control.momentum).

The sampled closed loop is the plant J theta'' + G = B u (eq. 12) under a zero-order hold on u,
and the controller exactly as generated, in one of two discretisations (``derive generate
--observer``):

* ``explicit`` (the default, forward Euler): u_k from the law at the sample, then the form's state is stepped by
  forward Euler: the NPID integral int_e + dt e_k, the observer z + dt W y with
  J y = G - B u_k - W theta'_k - z_k.
* ``implicit``: DOBC first takes the backward-Euler step of eq. (21) over the interval that just
  ended, with the new measurement and the voltage u_{k-1} held over it,
  (J(theta_k) + dt W) y = G(theta_k, theta'_k) - B u_{k-1} - W theta'_k - z_{k-1},
  z_k = z_{k-1} + dt W y, and then applies u_k = u* - B^-1 (z_k + W theta'_k) (state: z and the
  applied u). NPID applies u = u* + B^-1 W x, (J + dt W) x = J xi, xi = C^-1 (e' + K2 e + K1 int e):
  the PID form with W replaced by W_dt = W (J + dt W)^-1 J, the gain the backward-Euler observer
  applies (derive.codegen.kernels); the integral stays forward Euler.

MOM is stepped the same way in both builds: u_k = u* - B^-1 K (J theta'_k - m_k), then
m_{k+1} = m_k + dt (B u_k + C^T theta'_k - g - F theta'_k + K (J theta'_k - m_k)) with the applied
u_k (forward Euler): the observer's own rate is the diagonal K, so dt K < 2 bounds it by itself, and
the sampled loop below gives the limit of the whole (the predictive law included).

Why the ordering matters: with s = z + W theta' = B dhat, the forward-Euler loop telescopes to
s_k = s_{k-1} + W (theta'_k - theta'_{k-1}) + dt W J^-1 (G - B u_{k-1} - s_{k-1}), and u holds the
velocity feedback -B^-1 W theta' over a sample: the error e' = B d - s steps by I - dt W J^-1, stable
only for dt < 2 / |lambda(W J^-1)| (2 J / w for one joint). A backward-Euler step of z that still
uses the measurement taken before the step ((J + dt W) y = G - B u_k - W theta'_k - z_k) leaves that
feedback as it is and the limit where it was (12.9 against 13.0 ms on the default arm;
``_Z_ONLY``). Evaluating eq. (21) at the end of the step, the new theta'_k included, makes the
estimate's own step implicit: the velocity feedback becomes W (J + dt W)^-1 J theta' and the error
steps by (I + dt W J^-1)^-1, stable for every dt when W J^-1 has its eigenvalues in the right
half-plane. What limits the sample time then is the predictive law (and, for NPID, the
proportional part of W_dt K2 e, about J K2 / dt at large dt).

Linearised at an operating point (theta0, theta0', reference y_d = C theta0, y_d' = C theta0',
y_d'' = 0, u0 the law's output): x = (theta, theta'), c the form's state,

    x_{k+1} = Phi x_k + Gamma u_k,  (Phi, Gamma) = ZOH of (df/dx, df/du) over dt,
    u_k = U_x x_k + U_c c_k,   c_{k+1} = S_x x_k + S_c c_k + S_u u_k   (explicit, and MOM),

(for the implicit DOBC the loop's state is (x_k, z_{k-1}, u_{k-1})), and the loop is stable at that
point when the spectral radius of its transition matrix is below 1. For MOM the transition is taken
in the residual's coordinates (x, r), r = K (J theta' - m), at the sample it maps from and the one it
maps to (``_residual``): m moves with J(theta) theta' at a moving point, and in m's own coordinates
the frozen-time linearisation has a mode of that motion's rate which the loop does not have
(r' = K (B d - r) for every state); it gave my3 (3 joints, box 3-5 rad/s) rho = 1 + 6.9 dt at every
dt, "MOM 0 ms", where the simulated loop tracks. The limit is the largest dt (found by doubling, then
bisection to 1 %) for which that holds at every operating point of derive.control.grid: configurations
within the joint limits times the speeds of the speed box (controller.max_joint_speed, else the URDF's
velocity limits, else at rest only; the box's vertices and each joint alone at its bound); the figure
reported is 0.9 of it: the stated margin for the frozen-time linearisation over a finite grid.
A loop already unstable at DT_MIN (1e-7 s) has no limit in that search: when its continuous
linearisation (the limit dt -> 0 of every discretisation, :func:`_continuous_rate`) is stable at
every point, the limit is "below 1e-7 s" (extreme gains: T2 = 1e-20 puts the MPC poles at
-1.25e20 1/s), else there is none (the linearised loop is unstable as dt -> 0: not a sampling limit).
Jacobians are central differences of the laws evaluated in double precision (numbers to 1e-6
relative, far below the margin).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import sympy as sp

from derive.control.grid import Grid, grid, mass_function
from derive.dynamics.sx import batched

FORMS = ("mpc", "dobc", "npid", "mom")
SHARED = ("mpc", "mom")   # the same step in both discretisations: one limit
OBSERVERS = ("explicit", "implicit")   # derive generate --observer
_Z_ONLY = "z-only"   # backward Euler of z before the measurement moves: an analysis variant (docstring)
MARGIN = 0.9
DT_MAX = 1.0      # s: no limit is reported beyond it
DT_MIN = 1e-7
DT_START = 1e-5   # s: where the doubling starts (after the loop is checked stable at DT_MIN)
ACTIVE = 16       # at least this many points (and 5 %) are followed through the bisection


@dataclass(frozen=True)
class SampleLimit:
    """form, observer discretisation, limit [s] (``MARGIN`` of the largest stable dt; inf when stable
    up to DT_MAX; 0 when unstable at DT_MIN), raw [s], points: operating points checked, worst: the
    (theta, theta') that failed first beyond the raw limit (None when none did); ``below``: unstable at
    DT_MIN (raw = DT_MIN) while the continuous linearised loop is stable at every point (its fastest
    mode needs a shorter sample time: the limit is below DT_MIN); without it a limit of 0 means the
    linearised loop is unstable as dt -> 0 (not a sampling limit)."""

    form: str
    observer: str
    limit: float
    raw: float
    points: int
    worst: tuple[tuple[float, ...], tuple[float, ...]] | None
    below: bool = False   # unstable at DT_MIN though the continuous loop is stable at every point: limit < DT_MIN


def _jac(f, X: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central-difference Jacobians of a batched vector function f: (P, k) -> (P, m) at the P rows
    of X (P x k): P x m x k, the step h (1 + |x_i|) per row and coordinate."""
    cols = []
    for i in range(X.shape[1]):
        step = h * (1.0 + np.abs(X[:, i]))
        E = np.zeros_like(X)
        E[:, i] = step
        cols.append((f(X + E) - f(X - E)) / (2 * step)[:, None])
    return np.stack(cols, axis=-1)


def _batched(args, exprs):
    """A numpy function of the P x len(args) array of arguments, one row per point: P x len(exprs)
    (CasADi, each shared subexpression computed once: derive.dynamics.sx.batched)."""
    return batched(list(args), list(exprs))


class SampledLoop:
    """Numeric laws of a derivation for the linearisation (double precision, evaluated at all
    operating points at once: every function takes and returns one row per point)."""

    def __init__(self, d) -> None:
        s = d.dynamics.sym
        self.n = d.n
        x = list(s.theta + s.dtheta + s.yd + s.dyd + s.ddyd)
        th, dth = list(s.theta), list(s.dtheta)
        mass = mass_function(d)               # P x n x n
        self.J = lambda Q: mass(Q).reshape(Q.shape[0], -1)   # P x n*n, row-major
        self.G = _batched(th + dth, d.measured(d.G))
        self.B = np.array(d.B.tolist(), dtype=float)
        self.W = np.array(d.W.tolist(), dtype=float)
        self.C = np.array(d.C.tolist(), dtype=float)
        mom = d.momentum
        self.laws = {"mpc": _batched(x, d.measured(d.u_star)), "dobc": _batched(x + list(s.z), d.measured(d.u_dobc)),
                     "npid": _batched(x + list(s.int_e), d.measured(d.u_npid)),
                     "mom": _batched(x + list(mom.m), d.measured(d.u_mom))}
        # the momentum observer's m' = B u + C^T theta' - g - F theta' + K (J theta' - m) (forward Euler)
        self.mom_rate = _batched(th + dth + list(mom.m) + list(s.u), d.numeric(mom.m_rate))
        self.K = np.array(d.numeric(mom.K).tolist(), dtype=float)
        # u_npid = u* + B^-1 W xi (derive.control.npid): the implicit NPID replaces W by W_dt there
        self.xi = _batched(x + list(s.int_e), d.measured(d.numeric(d.npid.xi)))

    def mass(self, Q: np.ndarray) -> np.ndarray:
        """J at the rows of Q: P x n x n."""
        return self.J(Q).reshape(-1, self.n, self.n)

    def accel(self, Q, DQ, U) -> np.ndarray:
        """theta'' at each row: J theta'' = B u - G, solved (P x n)."""
        rhs = U @ self.B.T - self.G(np.hstack([Q, DQ]))
        return np.linalg.solve(self.mass(Q), rhs[..., None])[..., 0]

    def linearise(self, form: str, Q: np.ndarray, DQ: np.ndarray) -> dict[str, np.ndarray]:
        """Jacobians at the operating points (rows of Q, DQ), stacked over the points: A = df/dx,
        Bu = df/du, Ux = du/dx, Uc = du/dc (the form's state c), J, dr = d(G - W theta')/dx,
        Xi = dxi/d(x, c) for NPID (xi of derive.control.npid, u_npid = u* + B^-1 W xi), else zeros;
        R = dm'/d(x, m, u) for MOM (at m = J theta', where r = 0), else absent."""
        n, P = self.n, Q.shape[0]
        ref = np.hstack([Q @ self.C.T, DQ @ self.C.T, np.zeros((P, n))])
        law = self.laws[form]

        def u_of(XC):
            return law(np.hstack([XC[:, :2 * n], ref, XC[:, 2 * n:]]))

        def xi_of(XC):
            return self.xi(np.hstack([XC[:, :2 * n], ref, XC[:, 2 * n:]]))

        p0 = np.einsum("pij,pj->pi", self.mass(Q), DQ)   # m = J theta': r = 0, dhat = 0 at the point
        XC0 = np.hstack([Q, DQ] + ([-DQ @ self.W.T] if form == "dobc" else [np.zeros((P, n))] if form == "npid"
                                   else [p0] if form == "mom" else []))
        Uxc = _jac(u_of, XC0)

        def f(XU):
            return np.hstack([XU[:, n:2 * n], self.accel(XU[:, :n], XU[:, n:2 * n], XU[:, 2 * n:])])

        F = _jac(f, np.hstack([Q, DQ, u_of(XC0)]))
        # the observer's r = G - B u - W theta' - z vanishes at the point (z0 = -W theta0', u0 = B^-1 G),
        # so z_{k+1} = z + dt W A^-1 r has the Jacobian dt W A^-1 dr (A = J, or J + dt W)
        dr = _jac(self.G, np.hstack([Q, DQ])) - np.hstack([np.zeros((n, n)), self.W])
        Xi = _jac(xi_of, XC0) if form == "npid" else np.zeros((P, n, 3 * n))
        out = {"A": F[:, :, :2 * n], "Bu": F[:, :, 2 * n:], "Ux": Uxc[:, :, :2 * n], "Uc": Uxc[:, :, 2 * n:],
               "J": self.mass(Q), "dr": dr, "Xi": Xi}
        if form == "mom":
            out["R"] = _jac(self.mom_rate, np.hstack([XC0, u_of(XC0)]))
            # the residual's coordinates r = K (J(theta) theta' - m): P = d(J theta')/dx at the point and its
            # rate along the nominal motion x' = (theta', theta'') (central differences)
            X0 = np.hstack([Q, DQ])
            momentum = self.momentum
            out["P"] = _jac(momentum, X0)
            f0 = f(np.hstack([X0, u_of(XC0)]))
            h = 1e-6 / (1.0 + np.abs(f0).max(axis=1, keepdims=True))
            out["Pdot"] = (_jac(momentum, X0 + h * f0) - _jac(momentum, X0 - h * f0)) / (2 * h[:, :, None])
        return out

    def momentum(self, X: np.ndarray) -> np.ndarray:
        """The generalized momentum J(theta) theta' at the rows of X = (theta, theta'): P x n."""
        n = self.n
        return np.einsum("pij,pj->pi", self.mass(X[:, :n]), X[:, n:])


def operating_points(d) -> list[tuple[np.ndarray, np.ndarray]]:
    """The operating points (theta, theta') of derivation ``d``: derive.control.grid (within the
    joint limits, speeds up to the speed box; SpecError for a singular J there)."""
    return list(_grid(d).points)


def _grid(d) -> Grid:
    return _cached(_GRIDS, d, "grid", lambda: grid(d))


def sample_limit(d, form: str, observer: str = "explicit", points=None, loop: SampledLoop | None = None) -> SampleLimit:
    """The largest stable sample time of ``form`` (FORMS) with the observer discretisation ``observer``
    (OBSERVERS; the module docstring), with the stated margin (``loop``: the derivation's SampledLoop
    when the caller has it). Raises ValueError for an unknown form or discretisation."""
    if form not in FORMS or observer not in OBSERVERS + (_Z_ONLY,):
        raise ValueError(f"sample_limit: expected a form of {FORMS} and an observer of {OBSERVERS}, "
                         f"got {form!r}, {observer!r}")
    pts = operating_points(d) if points is None else points

    def linearise() -> tuple[SampledLoop, dict]:
        lp = _loop(d) if loop is None else loop
        return lp, lp.linearise(form, np.array([q for q, _ in pts], dtype=float),
                                np.array([dq for _, dq in pts], dtype=float))

    # both discretisations linearise the same laws at the default points: once per derivation and form
    loop, L = _cached(_LINEAR, d, form, linearise) if points is None else linearise()

    def radii(dt: float, idx: np.ndarray | None = None) -> np.ndarray:
        return _radii(loop, form, observer, dt, L if idx is None else {k: v[idx] for k, v in L.items()})

    def done(lo: float, bad: int | None) -> SampleLimit:
        worst = None if bad is None else tuple(tuple(float(x) for x in v) for v in pts[bad])
        return SampleLimit(form, observer, MARGIN * lo, lo, len(pts), worst)

    rho = radii(DT_MIN)
    if rho.max() >= 1.0:   # the continuous loop unstable (not a sampling limit), or a limit below DT_MIN
        if _continuous_rate(loop, form, L).max() < 0.0:
            worst = tuple(tuple(float(x) for x in v) for v in pts[int(rho.argmax())])
            return SampleLimit(form, observer, 0.0, DT_MIN, len(pts), worst, below=True)
        return done(0.0, int(rho.argmax()))
    # doubling over every point from DT_START, then bisection over the points nearest to failing at the
    # bracket's upper end, then the whole grid at the result (again if a point fails there)
    safe, dt, hi = DT_MIN, DT_START, None
    while hi is None and safe < DT_MAX:
        rho = radii(dt)
        if rho.max() >= 1.0:
            hi = dt
        else:
            safe, dt = dt, min(dt * 2, DT_MAX)
    if hi is None:
        return SampleLimit(form, observer, math.inf, math.inf, len(pts), None)
    lo, bad = safe, int(rho.argmax())
    active = np.argsort(rho)[-max(ACTIVE, len(rho) // 20):]
    while True:
        while hi / lo > 1.01:
            mid = math.sqrt(lo * hi)
            r = radii(mid, active)
            if r.max() < 1.0:
                lo = mid
            else:
                hi, bad = mid, int(active[r.argmax()])
        rho = radii(lo)
        if rho.max() < 1.0:
            return done(lo, bad)
        hi, bad, lo = lo, int(rho.argmax()), safe
        active = np.union1d(active, np.flatnonzero(rho >= 1.0))


def _expm(M: np.ndarray) -> np.ndarray:
    """exp of a stack of square matrices (... x k x k): scaling and squaring of a degree-18 Taylor
    polynomial (relative error below 1e-15 at norms <= 1/2 after scaling)."""
    norm = np.abs(M).sum(axis=-1).max(axis=-1).max()
    s = max(0, int(math.ceil(math.log2(norm / 0.5)))) if norm > 0.5 else 0
    A = M / (2.0 ** s)
    E = np.broadcast_to(np.eye(M.shape[-1]), M.shape).copy()
    term = E.copy()
    for k in range(1, 19):
        term = term @ A / k
        E = E + term
    for _ in range(s):
        E = E @ E
    return E


def _radii(loop: SampledLoop, form: str, observer: str, dt: float, L: dict) -> np.ndarray:
    """Spectral radius of the sampled closed loop at every operating point (module docstring)."""
    n, m = loop.n, 2 * loop.n
    P = L["A"].shape[0]
    aug = np.zeros((P, m + n, m + n))
    aug[:, :m, :m], aug[:, :m, m:] = L["A"], L["Bu"]
    E = _expm(aug * dt)
    Phi, Gam = E[:, :m, :m], E[:, :m, m:]
    Ux, Uc = L["Ux"], L["Uc"]
    eye = np.broadcast_to(np.eye(n), (P, n, n))
    if form == "mpc":
        return np.abs(np.linalg.eigvals(Phi + Gam @ Ux)).max(axis=-1)
    if form == "mom":                       # m + dt m'(x, m, u), the same in both discretisations
        R = dt * L["R"]
        Sx, Sc, Su = R[:, :, :m], eye + R[:, :, m:m + n], R[:, :, m + n:]
        M = np.concatenate([np.concatenate([Phi + Gam @ Ux, Gam @ Uc], axis=-1),
                            np.concatenate([Sx + Su @ Ux, Sc + Su @ Uc], axis=-1)], axis=-2)
        return np.abs(np.linalg.eigvals(_residual(M, L, loop.K, dt))).max(axis=-1)
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
        return np.abs(np.linalg.eigvals(M)).max(axis=-1)
    else:                                   # explicit, or the z-only backward step (_Z_ONLY)
        A = L["J"] + (dt * loop.W if observer == _Z_ONLY else 0.0)
        K = dt * loop.W @ np.linalg.inv(A)
        Sx, Sc, Su = K @ L["dr"], eye - K, -K @ loop.B
    M = np.concatenate([np.concatenate([Phi + Gam @ Ux, Gam @ Uc], axis=-1),
                        np.concatenate([Sx + Su @ Ux, Sc + Su @ Uc], axis=-1)], axis=-2)
    return np.abs(np.linalg.eigvals(M)).max(axis=-1)


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


_LIMITS: dict = {}
_GRIDS: dict = {}
_LINEAR: dict = {}
_LOOPS: dict = {}


def _cached(store: dict, d, key, make):
    """``make()`` cached per derivation object (the entry keeps ``d`` alive, so ids stay unique)."""
    hit = store.get((id(d), key))
    if hit is not None and hit[0] is d:
        return hit[1]
    out = make()
    store[(id(d), key)] = (d, out)
    return out


def _loop(d) -> SampledLoop:
    """The derivation's SampledLoop (one per derivation, shared by the forms and discretisations)."""
    return _cached(_LOOPS, d, "loop", lambda: SampledLoop(d))


def limits(d, observer: str = "explicit") -> dict[str, SampleLimit]:
    """The sample-time limit of every form (FORMS) with the observer discretisation ``observer``
    (cached per derivation; MPC has no observer and MOM steps the same in both: their limits are shared)."""
    def make() -> dict[str, SampleLimit]:
        loop = _loop(d)
        out = {form: sample_limit(d, form, observer, loop=loop) for form in FORMS
               if form not in SHARED or observer == "explicit"}
        if observer != "explicit":
            shared = limits(d, "explicit")
            out = {f: out[f] if f in out else shared[f] for f in FORMS}
        return out

    return _cached(_LIMITS, d, observer, make)
