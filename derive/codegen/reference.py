"""High-precision reference evaluation of a Derivation (the oracle of the tests
and of the generated self-test vectors).

Each law is lambdified over mpmath at 40 digits straight from the SymPy
matrices (nothing from CasADi or the printers), and the step functions
replicate the documented discretisation of the generated code: forward Euler
for the integral of e (NPID) and for the observer state z (DOBC), the
integrator held while a voltage limit is active, the observer fed the
applied (limited) voltage.
"""
from __future__ import annotations

from collections.abc import Sequence

import mpmath
import sympy as sp

from derive.control.pipeline import Derivation

DIGITS = 40


class Reference:
    """mpmath callables of one derivation (arm values baked in)."""

    def __init__(self, d: Derivation, u_max: Sequence[float] | None = None):
        s = d.dynamics.sym
        self.n = n = d.n
        e, _ = d.tracking_error
        x = list(s.theta + s.dtheta + s.yd + s.dyd + s.ddyd)

        def fn(args, m):
            return sp.lambdify(args, d.measured(m), modules="mpmath")

        self._gains = fn(list(s.theta), sp.Matrix.vstack(d.P.reshape(n * n, 1), d.D.reshape(n * n, 1),
                                                         d.I.reshape(n * n, 1)))
        self._mpc = fn(x, d.u_star)
        self._npid = fn(x + list(s.int_e), d.u_npid)
        self._e = fn(x, e)
        self._dobc = fn(x + list(s.z), d.u_dobc)
        self._J = fn(list(s.theta), d.J)
        self._rhs = fn(list(s.theta + s.dtheta + s.z + s.u), d.numeric(d.observer.J_solve_rhs))
        self._W = mpmath.matrix(d.W.tolist())
        self._dhat = fn(list(s.dtheta + s.z), d.dhat)
        self._z0 = fn(x[: 4 * n], d.B * d.dhat0 - d.W * sp.Matrix(s.dtheta))
        limits = u_max if u_max is not None else [
            float(m.input_limit) if m.input_limit is not None else 0.0 for m in d.arm.motors]
        self.u_max = [mpmath.mpf(v) for v in limits]

    @staticmethod
    def _vec(m) -> list:
        return [m[i] for i in range(m.rows)] if hasattr(m, "rows") else list(m)

    def gains(self, theta):
        with mpmath.workdps(DIGITS):
            return self._vec(self._gains(*theta))

    def mpc(self, x):
        with mpmath.workdps(DIGITS):
            return self._vec(self._mpc(*x))

    def npid(self, x, int_e):
        with mpmath.workdps(DIGITS):
            return self._vec(self._npid(*x, *int_e))

    def dobc(self, x, z):
        with mpmath.workdps(DIGITS):
            return self._vec(self._dobc(*x, *z))

    def observer(self, theta, dtheta, z, u):
        with mpmath.workdps(DIGITS):
            y = mpmath.lu_solve(self._J(*theta), self._rhs(*theta, *dtheta, *z, *u))
            return self._vec(self._W * y)

    def dhat(self, x, z):
        """The estimate dhat = B^-1 (z + W theta') (eq. 22) at input x, state z."""
        with mpmath.workdps(DIGITS):
            n = self.n
            return self._vec(self._dhat(*x[n:2 * n], *z))

    def dobc_init(self, x):
        with mpmath.workdps(DIGITS):
            return self._vec(self._z0(*x[: 4 * self.n]))

    def saturate(self, u) -> tuple[list, list[bool]]:
        out, hit = [], []
        for v, lim in zip(u, self.u_max):
            limited = lim > 0 and abs(v) > lim
            out.append(mpmath.sign(v) * lim if limited else v)
            hit.append(limited)
        return out, hit

    def npid_step(self, int_e, x, dt):
        """(u, next int_e) of one NPID step (eq. 34), forward Euler, integrator held when limited."""
        with mpmath.workdps(DIGITS):
            u, hit = self.saturate(self.npid(x, int_e))
            e = self._vec(self._e(*x))
            return u, [i if h else i + dt * ei for i, ei, h in zip(int_e, e, hit)]

    def dobc_step(self, z, x, dt):
        """(u, next z) of one DOBC step (eq. 21, 22, 27), forward Euler, observer fed the applied u."""
        with mpmath.workdps(DIGITS):
            u, _ = self.saturate(self.dobc(x, z))
            n = self.n
            zdot = self.observer(x[:n], x[n:2 * n], z, u)
            return u, [zi + dt * r for zi, r in zip(z, zdot)]

    def mpc_step(self, x):
        with mpmath.workdps(DIGITS):
            return self.saturate(self.mpc(x))[0]
