"""The numeric laws of a derivation and their exact Jacobians at many operating points at once:
what the sampled loop's linearisation (derive.control.sampling) needs.

Every law (MPC eq. 15, DOBC eq. 27, NPID eq. 34, MOM) is converted once to a CasADi SX graph
(derive.dynamics.sx.to_sx: each shared subexpression once), with the tracking error (eq. 20) and
the arm's values bound as SX values rather than substituted into the SymPy trees; its Jacobian
is CasADi's automatic differentiation of that graph, exact to rounding. One mapped call gives a
law and its Jacobian at P points: P x n and P x n x k, where central differences needed 2k calls
and were good to 1e-6. The plant's Jacobian comes from the same parts:

    theta'' = J^-1 (B u - G),   d theta''/d theta = -J^-1 (dG/d theta + d(J a)/d theta |a=theta''),
    d theta''/d theta' = -J^-1 dG/d theta',   d theta''/du = J^-1 B,

d(J a)/d theta the Jacobian of J(theta) a at a fixed a. The momentum observer's coordinates use
P = d(J theta')/d(theta, theta') and its rate along the motion (theta', theta''), the directional
derivative of that Jacobian (CasADi's ``jtimes``).
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import sympy as sp

from derive.control.sampling.grid import mass_function
from derive.dynamics.dag import Memo
from derive.dynamics.sx import to_sx


def _rows(m: ca.SX) -> ca.SX:
    """A matrix as one column, row by row (numpy's order)."""
    return ca.reshape(m.T, -1, 1)


class _Mapped:
    """A CasADi function of one input vector (k) with several outputs, evaluated at the P rows of
    a P x k array: each output comes back as P x shape (row-major)."""

    def __init__(self, x: ca.SX, outputs: list[tuple[ca.SX, tuple[int, ...]]]) -> None:
        self.shapes = [shape for _, shape in outputs]
        self.f = ca.Function("f", [x], [_rows(o) if len(s) == 2 else o for o, s in outputs])
        self.maps: dict[int, ca.Function] = {}

    def __call__(self, X: np.ndarray) -> list[np.ndarray]:
        X = np.asarray(X, dtype=float)
        P = X.shape[0]
        if P not in self.maps:
            self.maps[P] = self.f.map(P)
        out = self.maps[P](X.T)
        out = out if isinstance(out, (list, tuple)) else [out]
        return [np.asarray(o).T.reshape((P,) + s) for o, s in zip(out, self.shapes)]


class LinearisedLaws:
    """The laws of derivation ``d`` as numeric functions with their Jacobians (double precision,
    one row per operating point). n joints; B, W, C, K (the momentum observer's gain) as arrays;
    ``moving``: the joint coordinates J or G depends on."""

    def __init__(self, d) -> None:
        s = d.dynamics.sym
        n = self.n = d.n
        self.B = np.array(d.B.tolist(), dtype=float)
        self.W = np.array(d.W.tolist(), dtype=float)
        self.C = np.array(d.C.tolist(), dtype=float)
        mom = d.momentum
        self.K = np.array(d.numeric(mom.K).tolist(), dtype=float)
        mass = mass_function(d)
        self.mass = mass                                  # P x n -> P x n x n
        memo = Memo()
        sx = ca.SX.sym("x", 7 * n)                        # theta, theta', yd, yd', yd'', c, (u or a)
        th, dth, c, last = sx[:n], sx[n:2 * n], sx[5 * n:6 * n], sx[6 * n:]
        env = {v: ca.SX(float(x)) for v, x in d.values}
        symbols = list(s.theta) + list(s.dtheta) + list(s.yd) + list(s.dyd) + list(s.ddyd)
        env.update({v: sx[i] for i, v in enumerate(symbols)})
        e, de = d.tracking_error                         # eq. 20: e, e' and e(0), e'(0) at the sample
        for i in range(n):
            ei, dei = to_sx(e[i], env, memo), to_sx(de[i], env, memo)
            env.update({s.e[i]: ei, s.e0[i]: ei, s.de[i]: dei, s.de0[i]: dei})

        def conv(exprs, state=()) -> ca.SX:
            local = dict(env)
            local.update({v: c[i] for i, v in enumerate(state)})
            local.update({v: last[i] for i, v in enumerate(s.u)})
            return ca.vertcat(*[to_sx(sp.sympify(x), local, memo) for x in exprs])

        x5 = sx[:5 * n]
        xc = ca.vertcat(th, dth, c)          # what a law's Jacobian is taken in: the state and the form's
        self.laws = {}
        for form, law, state in (("mpc", d.u_star, ()), ("dobc", d.u_dobc, s.z), ("npid", d.u_npid, s.int_e),
                                 ("mom", d.u_mom, mom.m)):
            u = conv(law, state)
            arg = ca.vertcat(x5, c)
            self.laws[form] = _Mapped(arg, [(u, (n,)), (ca.jacobian(u, xc), (n, 3 * n))])
        xi = conv(d.npid.xi, s.int_e)                     # u_npid = u* + B^-1 W xi (derive.control.npid)
        self._xi = _Mapped(ca.vertcat(x5, c), [(xi, (n,)), (ca.jacobian(xi, xc), (n, 3 * n))])
        x2 = sx[:2 * n]
        G = conv(d.G)
        self._G = _Mapped(x2, [(G, (n,)), (ca.jacobian(G, x2), (n, 2 * n))])
        # J(theta) a and its Jacobian in theta at a fixed a (a: the last n inputs)
        Jsx = conv(list(d.J))
        Ja = ca.mtimes(ca.reshape(Jsx, n, n).T, last)    # d.J row-major -> SX column-major
        # the joint coordinates J or G depends on (structurally: CasADi's which_depends)
        self.moving = tuple(k for k, b in enumerate(ca.which_depends(ca.vertcat(Jsx, G), th, 1, False)) if b)
        self._Ja = _Mapped(ca.vertcat(th, last), [(ca.jacobian(Ja, th), (n, n))])
        # the momentum J theta': P = its Jacobian in x = (theta, theta'), and P's rate along v = last 2n
        v = ca.SX.sym("v", 2 * n)
        p = ca.substitute(Ja, last, dth)
        Pm = ca.jacobian(p, x2)
        self._P = _Mapped(ca.vertcat(x2, v), [(Pm, (n, 2 * n)),
                                             (ca.reshape(ca.jtimes(_rows(Pm), x2, v), 2 * n, n).T, (n, 2 * n))])
        # the momentum observer's m' = B u + C^T theta' - g - F theta' + K (J theta' - m), in (theta, theta', m, u)
        rate = conv(mom.m_rate, mom.m)
        xmu = ca.vertcat(th, dth, c, last)
        self._rate = _Mapped(ca.vertcat(x5, c, last), [(ca.jacobian(rate, xmu), (n, 4 * n))])

    def law(self, form: str, Q, DQ, ref, state) -> tuple[np.ndarray, np.ndarray]:
        """u of ``form`` (P x n) and its Jacobian in (theta, theta', the form's state) (P x n x 3n)."""
        return tuple(self.laws[form](np.hstack([Q, DQ, ref, state])))

    def xi(self, Q, DQ, ref, state) -> np.ndarray:
        """d xi / d(theta, theta', int e) of the NPID form (P x n x 3n)."""
        return self._xi(np.hstack([Q, DQ, ref, state]))[1]

    def bias(self, Q, DQ) -> tuple[np.ndarray, np.ndarray]:
        """G (P x n) and dG/d(theta, theta') (P x n x 2n)."""
        return tuple(self._G(np.hstack([Q, DQ])))

    def mass_jacobian(self, Q, A) -> np.ndarray:
        """d(J(theta) a)/d theta at a = the rows of A: P x n x n."""
        return self._Ja(np.hstack([Q, A]))[0]

    def momentum_jacobian(self, Q, DQ, V) -> tuple[np.ndarray, np.ndarray]:
        """P = d(J theta')/d(theta, theta') (P x n x 2n) and its directional derivative along the rows
        of V (P x 2n)."""
        return tuple(self._P(np.hstack([Q, DQ, V])))

    def rate_jacobian(self, Q, DQ, M, U) -> np.ndarray:
        """d m'/d(theta, theta', m, u) of the momentum observer (P x n x 4n)."""
        P = Q.shape[0]
        return self._rate(np.hstack([Q, DQ, np.zeros((P, 3 * self.n)), M, U]))[0]


class SampledLoop(LinearisedLaws):
    """The linearisation of the sampled loop of each form at many operating points
    (derive.control.sampling's module docstring)."""

    _plant_key: tuple | None = None   # the points _plant_at was last asked for
    _accel: tuple | None = None       # (theta'' bytes, its block of A) at those points (_position_block)

    def _plant_at(self, Q: np.ndarray, DQ: np.ndarray) -> tuple[np.ndarray, ...]:
        """J, G, dG/d(theta, theta') at the points and what the linearisation takes from them alone:
        J^-1 B, -J^-1 dG/d theta' and dr (the same for every form: kept for the last points)."""
        key = (Q.shape, Q.tobytes(), DQ.tobytes())
        if self._plant_key != key:
            n, P = self.n, Q.shape[0]
            J = self.mass(Q)
            G0, dG = self.bias(Q, DQ)
            JB = np.linalg.solve(J, np.broadcast_to(self.B, (P, n, n)))
            velocity = -np.linalg.solve(J, dG[:, :, n:])
            # the observer's r = G - B u - W theta' - z vanishes at the point (z0 = -W theta0', u0 = B^-1 G),
            # so z_{k+1} = z + dt W A^-1 r has the Jacobian dt W A^-1 dr (A = J, or J + dt W)
            dr = dG - np.concatenate([np.zeros((P, n, n)), np.broadcast_to(self.W, (P, n, n))], axis=-1)
            self._plant_key, self._plant, self._accel = key, (J, G0, dG, JB, velocity, dr), None
        return self._plant

    def _position_block(self, Q: np.ndarray, acc: np.ndarray) -> np.ndarray:
        """d theta''/d theta = -J^-1 (dG/d theta + d(J a)/d theta |a=theta'') at the points of the last
        _plant_at: kept for the last theta'' (the laws' u0 often give every form the same bits)."""
        key = acc.tobytes()
        if self._accel is None or self._accel[0] != key:
            J, _, dG = self._plant[:3]
            self._accel = key, -np.linalg.solve(J, dG[:, :, :self.n] + self.mass_jacobian(Q, acc))
        return self._accel[1]

    def linearise(self, form: str, Q: np.ndarray, DQ: np.ndarray) -> dict[str, np.ndarray]:
        """Jacobians at the operating points (rows of Q, DQ: theta0, theta0', with the reference
        y_d = C theta0, y_d' = C theta0', y_d'' = 0, and the form's state where dhat = 0), stacked over
        the points: A = df/dx, Bu = df/du (x' = f(x, u) = (theta', J^-1 (B u - G))), Ux = du/dx,
        Uc = du/dc (the form's state c; none for MPC), J, dr = d(G - W theta')/dx, Xi = dxi/d(x, c)
        for NPID (u_npid = u* + B^-1 W xi), else zeros; for MOM also R = dm'/d(x, m, u) at m = J theta'
        (r = 0), P = d(J theta')/dx and Pdot, P's rate along the motion (theta', theta'')."""
        Q, DQ = np.asarray(Q, dtype=float), np.asarray(DQ, dtype=float)
        n, P = self.n, Q.shape[0]
        ref = np.hstack([Q @ self.C.T, DQ @ self.C.T, np.zeros((P, n))])
        J, G0, dG, JB, velocity, dr = self._plant_at(Q, DQ)
        p0 = np.einsum("pij,pj->pi", J, DQ)               # m = J theta': r = 0, dhat = 0 at the point
        state = {"dobc": -DQ @ self.W.T, "mom": p0}.get(form, np.zeros((P, n)))
        u0, U = self.law(form, Q, DQ, ref, state)
        acc = np.linalg.solve(J, (u0 @ self.B.T - G0)[..., None])[..., 0]
        A = np.zeros((P, 2 * n, 2 * n))
        A[:, :n, n:] = np.eye(n)
        A[:, n:, :n] = self._position_block(Q, acc)
        A[:, n:, n:] = velocity
        Bu = np.zeros((P, 2 * n, n))
        Bu[:, n:, :] = JB
        out = {"A": A, "Bu": Bu, "Ux": U[:, :, :2 * n], "Uc": U[:, :, 2 * n:] if form != "mpc" else U[:, :, :0],
               "J": J, "dr": dr.copy(),
               "Xi": self.xi(Q, DQ, ref, state) if form == "npid" else np.zeros((P, n, 3 * n))}
        if form == "mom":
            out["R"] = self.rate_jacobian(Q, DQ, p0, u0)
            out["P"], out["Pdot"] = self.momentum_jacobian(Q, DQ, np.hstack([DQ, acc]))
        return out
