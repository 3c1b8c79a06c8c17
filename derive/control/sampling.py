"""The largest sample time of each generated controller form (MPC eq. 15, DOBC eq. 21-27, NPID eq. 34).

The sampled closed loop is the plant J theta'' + G = B u (eq. 12) under a zero-order hold on u,
and the controller exactly as generated: u_k from the law at the sample, and its state stepped
once per sample, the NPID integral by forward Euler (int_e + dt e) and the observer state by
forward Euler (z + dt W y, J y = G - B u - W theta' - z) or backward Euler (the same with
(J + dt W) y = G - B u - W theta' - z: z_{k+1} = z_k + dt W J^-1 (... - z_{k+1})).

Linearised at an operating point (theta0, theta0', reference y_d = C theta0, y_d' = C theta0',
y_d'' = 0, u0 the law's output): x = (theta, theta'), c the form's state,

    x_{k+1} = Phi x_k + Gamma u_k,  (Phi, Gamma) = ZOH of (df/dx, df/du) over dt,
    u_k = U_x x_k + U_c c_k,   c_{k+1} = S_x x_k + S_c c_k + S_u u_k,

and the loop is stable at that point when the spectral radius of
[[Phi + Gamma U_x, Gamma U_c], [S_x + S_u U_x, S_c + S_u U_c]] is below 1. The limit is the
largest dt (found by doubling, then bisection to 1 %) for which that holds at every operating
point of a grid of configurations and speeds (every angle on a grid, the stated speed box's
vertices and rest); the figure reported is 0.9 of it: the stated margin for the frozen-time
linearisation over a finite grid. Jacobians are central differences of the laws evaluated in
double precision (numbers to 1e-6 relative, far below the margin).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import sympy as sp

from derive.dynamics.program import lambdify

FORMS = ("mpc", "dobc", "npid")
OBSERVERS = ("explicit", "implicit")
MARGIN = 0.9
DT_MAX = 1.0      # s: no limit is reported beyond it
DT_MIN = 1e-7


@dataclass(frozen=True)
class SampleLimit:
    """form, observer discretisation, limit [s] (``MARGIN`` of the largest stable dt; inf when stable
    up to DT_MAX), raw [s], points: operating points checked, worst: the (theta, theta') that failed
    first beyond the raw limit (None when none did)."""

    form: str
    observer: str
    limit: float
    raw: float
    points: int
    worst: tuple[tuple[float, ...], tuple[float, ...]] | None


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
    (constant entries broadcast; each shared subexpression computed once, derive.dynamics.program)."""
    f = lambdify(args, list(exprs))

    def call(X: np.ndarray) -> np.ndarray:
        P = X.shape[0]
        return np.stack([np.broadcast_to(np.asarray(v, dtype=float), (P,)) for v in f(*X.T)], axis=-1)

    return call


class SampledLoop:
    """Numeric laws of a derivation for the linearisation (double precision, evaluated at all
    operating points at once: every function takes and returns one row per point)."""

    def __init__(self, d) -> None:
        s = d.dynamics.sym
        self.n = d.n
        x = list(s.theta + s.dtheta + s.yd + s.dyd + s.ddyd)
        th, dth = list(s.theta), list(s.dtheta)
        self.J = _batched(th, d.J)            # P x n*n, row-major
        self.G = _batched(th + dth, d.measured(d.G))
        self.B = np.array(d.B.tolist(), dtype=float)
        self.W = np.array(d.W.tolist(), dtype=float)
        self.C = np.array(d.C.tolist(), dtype=float)
        self.laws = {"mpc": _batched(x, d.measured(d.u_star)), "dobc": _batched(x + list(s.z), d.measured(d.u_dobc)),
                     "npid": _batched(x + list(s.int_e), d.measured(d.u_npid))}

    def mass(self, Q: np.ndarray) -> np.ndarray:
        """J at the rows of Q: P x n x n."""
        return self.J(Q).reshape(-1, self.n, self.n)

    def accel(self, Q, DQ, U) -> np.ndarray:
        """theta'' at each row: J theta'' = B u - G, solved (P x n)."""
        rhs = U @ self.B.T - self.G(np.hstack([Q, DQ]))
        return np.linalg.solve(self.mass(Q), rhs[..., None])[..., 0]

    def linearise(self, form: str, Q: np.ndarray, DQ: np.ndarray) -> dict[str, np.ndarray]:
        """Jacobians at the operating points (rows of Q, DQ), stacked over the points: A = df/dx,
        Bu = df/du, Ux = du/dx, Uc = du/dc (the form's state c), J, dr = d(G - W theta')/dx."""
        n, P = self.n, Q.shape[0]
        ref = np.hstack([Q @ self.C.T, DQ @ self.C.T, np.zeros((P, n))])
        law = self.laws[form]

        def u_of(XC):
            return law(np.hstack([XC[:, :2 * n], ref, XC[:, 2 * n:]]))

        XC0 = np.hstack([Q, DQ] + ([-DQ @ self.W.T] if form == "dobc" else [np.zeros((P, n))] if form == "npid"
                                   else []))
        Uxc = _jac(u_of, XC0)

        def f(XU):
            return np.hstack([XU[:, n:2 * n], self.accel(XU[:, :n], XU[:, n:2 * n], XU[:, 2 * n:])])

        F = _jac(f, np.hstack([Q, DQ, u_of(XC0)]))
        # the observer's r = G - B u - W theta' - z vanishes at the point (z0 = -W theta0', u0 = B^-1 G),
        # so z_{k+1} = z + dt W A^-1 r has the Jacobian dt W A^-1 dr (A = J, or J + dt W)
        dr = _jac(self.G, np.hstack([Q, DQ])) - np.hstack([np.zeros((n, n)), self.W])
        return {"A": F[:, :, :2 * n], "Bu": F[:, :, 2 * n:], "Ux": Uxc[:, :, :2 * n], "Uc": Uxc[:, :, 2 * n:],
                "J": self.mass(Q), "dr": dr}


def operating_points(d, count: int = 48, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """Configurations (a grid of every angle for n <= 2, else seeded random ones and 0) times the
    speeds (rest and the stated box's vertices, at most 8 of them)."""
    n = d.n
    rng = np.random.default_rng(seed)
    if n <= 2:
        axis = np.linspace(-np.pi, np.pi, 8, endpoint=False)
        configs = [np.array(p) for p in itertools.product(axis, repeat=n)]
    else:
        configs = [np.zeros(n)] + [rng.uniform(-np.pi, np.pi, n) for _ in range(count - 1)]
    speeds = [np.zeros(n)]
    box = d.arm.controller.max_joint_speed
    if box is not None:
        s = np.array([float(x) for x in box])
        verts = [np.array(v) * s for v in itertools.product((1.0, -1.0), repeat=n)]
        if len(verts) > 8:
            verts = [verts[i] for i in rng.choice(len(verts), 8, replace=False)]
        speeds += verts
    return [(q, dq) for q in configs for dq in speeds]


def sample_limit(d, form: str, observer: str = "explicit", points=None, loop: SampledLoop | None = None) -> SampleLimit:
    """The largest stable sample time of ``form`` (module docstring), with the stated margin
    (``loop``: the derivation's SampledLoop when the caller has it)."""
    loop = SampledLoop(d) if loop is None else loop
    pts = operating_points(d) if points is None else points
    L = loop.linearise(form, np.array([q for q, _ in pts], dtype=float), np.array([dq for _, dq in pts], dtype=float))

    def stable(dt: float) -> tuple[bool, int | None]:
        rho = _radii(loop, form, observer, dt, L)
        k = int(rho.argmax())
        return (True, None) if rho[k] < 1.0 else (False, k)

    lo, hi, bad = DT_MIN, None, None
    ok, _ = stable(lo)
    if not ok:
        return SampleLimit(form, observer, 0.0, 0.0, len(pts), None)
    dt = lo
    while dt < DT_MAX:
        dt = min(dt * 2, DT_MAX)
        ok, k = stable(dt)
        if not ok:
            hi, bad = dt, k
            break
        lo = dt
    if hi is None:
        return SampleLimit(form, observer, math.inf, math.inf, len(pts), None)
    while hi / lo > 1.01:
        mid = math.sqrt(lo * hi)
        ok, k = stable(mid)
        if ok:
            lo = mid
        else:
            hi, bad = mid, k
    q0, dq0 = pts[bad]
    return SampleLimit(form, observer, MARGIN * lo, lo, len(pts),
                       (tuple(float(x) for x in q0), tuple(float(x) for x in dq0)))


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
    top = Phi + Gam @ L["Ux"]
    if form == "mpc":
        return np.abs(np.linalg.eigvals(top)).max(axis=-1)
    if form == "npid":                      # int_e + dt (yd - C theta)
        Sx = np.broadcast_to(np.hstack([-dt * loop.C, np.zeros((n, n))]), (P, n, m))
        Sc = np.broadcast_to(np.eye(n), (P, n, n))
        Su = np.zeros((P, n, n))
    else:
        A = L["J"] + (dt * loop.W if observer == "implicit" else 0.0)
        K = dt * loop.W @ np.linalg.inv(A)
        Sx, Sc, Su = K @ L["dr"], np.eye(n) - K, -K @ loop.B
    M = np.concatenate([np.concatenate([top, Gam @ L["Uc"]], axis=-1),
                        np.concatenate([Sx + Su @ L["Ux"], Sc + Su @ L["Uc"]], axis=-1)], axis=-2)
    return np.abs(np.linalg.eigvals(M)).max(axis=-1)


_LIMITS: dict = {}


def limits(d, observer: str = "explicit") -> dict[str, SampleLimit]:
    """The sample-time limit of every form (FORMS) for one derivation (cached per derivation)."""
    key = (id(d), observer)
    hit = _LIMITS.get(key)
    if hit is not None and hit[0] is d:
        return hit[1]
    loop = SampledLoop(d)
    out = {form: sample_limit(d, form, observer, loop=loop) for form in FORMS}
    _LIMITS[key] = (d, out)
    return out


def _ms(x: float) -> str:
    return "none below 1 s" if math.isinf(x) else f"{x * 1e3:.3g} ms"


def summary(d, observer: str = "explicit") -> str:
    """One line: the largest sample time of each form, as check, show and the headers print it."""
    lim = limits(d, observer)
    parts = ", ".join(f"{f.upper()} {_ms(lim[f].limit)}" for f in FORMS)
    return (f"largest sample time (sampled loop, zero-order hold, {observer} observer step, linearised over "
            f"{lim['dobc'].points} operating points, {int(round((1 - MARGIN) * 100))} % margin): {parts}")


def too_slow(d, sample_time: float, forms=FORMS, observer: str = "explicit") -> list[str]:
    """Sentences for the forms whose limit ``sample_time`` [s] exceeds (empty when none)."""
    lim = limits(d, observer)
    return [f"sample_time = {sample_time * 1e3:g} ms is above the {f.upper()} limit {_ms(lim[f].limit)} "
            f"(the sampled loop is unstable from {_ms(lim[f].raw)} at some configuration)"
            for f in forms if f in lim and sample_time > lim[f].limit]
