"""High-precision reference evaluation of a Derivation (the oracle of the tests
and of the generated self-test vectors).

Each law is compiled straight from the SymPy matrices of the Derivation
(nothing from CasADi or the printers) into a ball-arithmetic function
(:mod:`derive.codegen.balls`), and the step functions replicate the documented
discretisation of the generated code: forward Euler for the integral of e
(NPID) and for the observer state z (DOBC), the integrator held while a
voltage limit is active, the observer fed the applied (limited) voltage; with
``observer="implicit"`` the backward-Euler steps of derive.codegen.kernels.

Every result is a ball (python-flint ``arb``) whose radius bounds its error:
:func:`certified` proves that a vector carries ``DIGITS`` correct digits
(norm-wise), and the callers raise the working precision when it does not.
"""
from __future__ import annotations

from collections.abc import Sequence

import mpmath
import sympy as sp
from flint import arb, arb_mat

from derive.codegen.balls import BallFunction, ball, working_precision
from derive.dynamics.dag import times
from derive.dynamics.program import lambdify
from derive.control.momentum import coriolis_rate
from derive.control.pipeline import Derivation

DIGITS = 40               # proved correct digits of every reference vector (norm-wise)
PRECISION = 160           # first working precision [bits] (48 digits)


def certified(values, digits: int = DIGITS) -> bool:
    """True when every ball's radius is at most 10^-digits times the vector's
    largest magnitude (an exactly zero vector is certified); anything but a
    sequence of balls (a result already proved otherwise) is taken as it is."""
    if not isinstance(values, (list, tuple)):
        return True
    scale = max((abs(v).upper() for v in values), default=arb(0))
    worst = max((v.rad() for v in values), default=arb(0))
    if scale == 0:
        return worst == 0
    return bool(worst <= scale * arb(10) ** (-digits))


class Reference:
    """Ball-arithmetic callables of one derivation (arm values baked in).

    Vectors in and out are sequences of numbers or balls; ``prec`` is the
    working precision in bits (raise it when :func:`certified` fails)."""

    def __init__(self, d: Derivation, u_max: Sequence[float] | None = None, prec: int = PRECISION,
                 observer: str = "explicit"):
        s = d.dynamics.sym
        self._d = d
        self.n = n = d.n
        self.prec = prec
        self.implicit = observer == "implicit"   # the backward-Euler step (derive.codegen.kernels)
        e, _ = d.tracking_error
        x = list(s.theta + s.dtheta + s.yd + s.dyd + s.ddyd)

        def fn(name, args, *matrices):
            exprs = [d.measured(v) for m in matrices for v in m]
            return BallFunction(args, exprs, name)

        self._gains = fn("gains", list(s.theta), d.P.reshape(n * n, 1), d.D.reshape(n * n, 1),
                         d.I.reshape(n * n, 1))
        self._mpc = fn("mpc", x, d.u_star)
        self._npid = fn("npid", x + list(s.int_e), d.u_npid, e)
        self._dobc = fn("dobc", x + list(s.z), d.u_dobc)
        self._observer = fn("observer", list(s.theta + s.dtheta + s.z + s.u), d.J,
                            d.numeric(d.observer.J_solve_rhs))
        self._W = d.W
        self._dhat = fn("dhat", list(s.dtheta + s.z), d.dhat)
        self._z0 = fn("dobc_init", x[: 4 * n], times(d.B, d.dhat0) - d.W * sp.Matrix(s.dtheta))
        self._J = fn("J", list(s.theta), d.J)
        self._xi = fn("xi", x + list(s.int_e), d.numeric(d.npid.xi))   # u_npid = u* + B^-1 W xi
        self._Binv_G = fn("Binv_G", list(s.theta + s.dtheta), times(d.B.inv(), d.G))
        mom = d.momentum   # the generalized-momentum observer (derive.control.momentum)
        self._mom = fn("mom", x + list(mom.m), d.u_mom)
        # the reference m' from the chain's Coriolis matrix, not the recursion the kernels use
        self._mom_rate = fn("mom_rate", list(s.theta + s.dtheta) + list(mom.m) + list(s.u),
                            d.numeric(coriolis_rate(d.dynamics, mom)))
        self._mom_init = fn("mom_init", list(s.theta + s.dtheta), d.numeric(mom.p))
        self._mom_dhat = fn("mom_dhat", list(s.theta + s.dtheta) + list(mom.m), d.numeric(mom.dhat))
        limits = u_max if u_max is not None else [
            float(m.input_limit) if m.input_limit is not None else 0.0 for m in d.arm.motors]
        self.u_max = [float(v) for v in limits]

    def _run(self, f: BallFunction, *vectors) -> list[arb]:
        with working_precision(self.prec):
            return f(*(v for vec in vectors for v in vec))

    def gains(self, theta) -> list[arb]:
        """P, D, I row-major (3 n^2), eq. 35-37."""
        return self._run(self._gains, theta)

    def mpc(self, x) -> list[arb]:
        return self._run(self._mpc, x)

    def npid(self, x, int_e) -> list[arb]:
        return self._run(self._npid, x, int_e)[: self.n]

    def dobc(self, x, z) -> list[arb]:
        return self._run(self._dobc, x, z)

    def inertia(self, theta) -> list[arb]:
        """J(theta) row-major (n^2), eq. 12."""
        return self._run(self._J, theta)

    def observer(self, theta, dtheta, z, u) -> list[arb]:
        """z' = W y with J y = G - B u - W theta' - z (eq. 21), solved in balls."""
        n = self.n
        with working_precision(self.prec):
            out = self._observer(*theta, *dtheta, *z, *u)
            J = arb_mat(n, n, out[: n * n])
            y = J.solve(arb_mat(n, 1, out[n * n:]))
            return [sum((ball(self._W[i, j]) * y[j, 0] for j in range(n)), arb(0)) for i in range(n)]

    def _solve_implicit(self, J: list, rhs: list, dt) -> list:
        """y with (J + dt W) y = rhs, in balls (J row-major n^2, rhs n; the working precision set)."""
        n, step = self.n, ball(dt)
        A = arb_mat(n, n, [J[i * n + j] + step * ball(self._W[i, j]) for i in range(n) for j in range(n)])
        y = A.solve(arb_mat(n, 1, list(rhs)))
        return [y[i, 0] for i in range(n)]

    def observer_implicit(self, theta, dtheta, z, u, dt) -> list[arb]:
        """The backward-Euler step of eq. (21): z + dt W y, (J + dt W) y = G - B u - W theta' - z."""
        n = self.n
        with working_precision(self.prec):
            out = self._observer(*theta, *dtheta, *z, *u)
            y = self._solve_implicit(out[: n * n], out[n * n:], dt)
            step = ball(dt)
            return [ball(z[i]) + step * sum((ball(self._W[i, j]) * y[j] for j in range(n)), arb(0))
                    for i in range(n)]

    def npid_implicit(self, x, int_e, dt) -> list[arb]:
        """u = u* + B^-1 W x_s, (J + dt W) x_s = J xi: eq. (34) with W_dt = W (J + dt W)^-1 J."""
        n, d = self.n, self._d
        with working_precision(self.prec):
            ustar, xi, J = self._mpc(*x), self._xi(*x, *int_e), self._J(*x[:n])
            Jxi = [sum((J[i * n + j] * xi[j] for j in range(n)), arb(0)) for i in range(n)]
            xs = self._solve_implicit(J, Jxi, dt)
            BW = d.B.inv() * d.W
            return [ustar[i] + sum((ball(BW[i, j]) * xs[j] for j in range(n)), arb(0)) for i in range(n)]

    def dhat(self, x, z) -> list[arb]:
        """The estimate dhat = B^-1 (z + W theta') (eq. 22) at input x, state z."""
        n = self.n
        return self._run(self._dhat, x[n:2 * n], z)

    def dobc_init(self, x, dt=None) -> list[arb]:
        """z(0) = B dhat(0) - W theta'(0) (eq. 22) with the derived dhat(0) (derive.control.npid);
        for the implicit step dhat(0) = -B^-1 W x0, (J + dt W) x0 = J xi(0): W_dt in place of W."""
        n = self.n
        if not self.implicit:
            return self._run(self._z0, x[: 4 * n])
        with working_precision(self.prec):
            Wx0 = self._W_x0(x, dt)
            return [-Wx0[i] - sum((ball(self._W[i, j]) * x[n + j] for j in range(n)), arb(0)) for i in range(n)]

    def _W_x0(self, x, dt) -> list[arb]:
        """W x0 with (J + dt W) x0 = J xi(0), xi(0) = C^-1 (e' + K2 e) (int e = 0); the precision set."""
        n = self.n
        xi, J = self._xi(*x, *([0] * n)), self._J(*x[:n])
        Jxi = [sum((J[i * n + j] * xi[j] for j in range(n)), arb(0)) for i in range(n)]
        x0 = self._solve_implicit(J, Jxi, dt)
        return [sum((ball(self._W[i, j]) * x0[j] for j in range(n)), arb(0)) for i in range(n)]

    def initial_estimate(self, x, dt=None) -> list[arb]:
        """dhat(0) = -B^-1 W C^-1 (e'(0) + K2 e(0)) at input x (derive.control.npid; e, e' from x as the
        controller takes them, wrapped for continuous joints); with ``dt``, the implicit step's W_dt =
        W (J + dt W)^-1 J in place of W (J at x's theta)."""
        n = self.n
        with working_precision(self.prec):
            if dt is None:
                xi = self._xi(*x, *([0] * n))
                Wxi = [sum((ball(self._W[i, j]) * xi[j] for j in range(n)), arb(0)) for i in range(n)]
            else:
                Wxi = self._W_x0(x, dt)
            return [-ball(1 / self._d.B[i, i]) * Wxi[i] for i in range(n)]

    def dobc_held(self, x, dt) -> list[arb]:
        """The implicit step's initial held voltage B^-1 (G - W theta' - z0) = B^-1 (G + W x0)."""
        n = self.n
        with working_precision(self.prec):
            bg, Wx0 = self._Binv_G(*x[: 2 * n]), self._W_x0(x, dt)
            return [bg[i] + ball(1 / self._d.B[i, i]) * Wx0[i] for i in range(n)]

    def saturate(self, u) -> tuple[list, list[bool]]:
        out, hit = [], []
        for v, lim in zip(u, self.u_max):
            limited = lim > 0 and abs(v) > lim
            out.append((ball(lim) if v > 0 else -ball(lim)) if limited else v)
            hit.append(limited)
        return out, hit

    def npid_step(self, int_e, x, dt):
        """(u, next int_e) of one NPID step (eq. 34), forward Euler, integrator held when limited;
        the implicit observer's NPID law (W_dt) when the reference was made for it."""
        n = self.n
        with working_precision(self.prec):
            out = self._npid(*x, *int_e)
            raw = self.npid_implicit(x, int_e, dt) if self.implicit else out[:n]
            u, hit = self.saturate(raw)
            step = ball(dt)
            return u, [ball(i) if h else ball(i) + step * ei for i, ei, h in zip(int_e, out[n:], hit)]

    def dobc_step(self, z, x, dt):
        """(u, next z) of one DOBC step (eq. 21, 22, 27), forward Euler, observer fed the applied u."""
        n = self.n
        with working_precision(self.prec):
            u, _ = self.saturate(self._dobc(*x, *z))
            zdot = self.observer(x[:n], x[n:2 * n], z, u)
            step = ball(dt)
            return u, [ball(zi) + step * r for zi, r in zip(z, zdot)]

    def dobc_step_implicit(self, z, held, x, dt):
        """(u, next z) of one implicit DOBC step: the backward-Euler observer step over the interval
        that ended with the held voltage, then u = u* - B^-1 (z_next + W theta') limited (eq. 21, 22, 27);
        the next held voltage is that u."""
        n = self.n
        with working_precision(self.prec):
            z_next = self.observer_implicit(x[:n], x[n:2 * n], z, held, dt)
            u, _ = self.saturate(self._dobc(*x, *z_next))
            return u, z_next

    def mom_init(self, x) -> list[arb]:
        """m(0) = J(theta) theta' (derive.control.momentum)."""
        return self._run(self._mom_init, x[: 2 * self.n])

    def mom_dhat(self, x, m) -> list[arb]:
        """dhat = B^-1 K (J theta' - m) at input x, state m."""
        return self._run(self._mom_dhat, x[: 2 * self.n], m)

    def mom_step(self, m, x, dt):
        """(u, next m) of one momentum-observer step: u = u* - B^-1 K (J theta' - m) limited, then
        m + dt (B u + C^T theta' - g - F theta' + r) with the applied u (forward Euler)."""
        n = self.n
        with working_precision(self.prec):
            u, _ = self.saturate(self._mom(*x, *m))
            rate = self._mom_rate(*x[: 2 * n], *m, *u)
            step = ball(dt)
            return u, [ball(mi) + step * ri for mi, ri in zip(m, rate)]

    def mpc_step(self, x):
        return self.saturate(self.mpc(x))[0]

    # The plant (eq. 12), for the exported plant functions and `derive show --at`: mpmath at
    # DIGITS + 10 digits (SymPy's own dependency), the matrices lambdified from the Derivation.

    @staticmethod
    def _mp_vec(m) -> list:
        return [m[i] for i in range(m.rows)]

    def _plant(self):
        if not hasattr(self, "_plant_fns"):
            d = self._d
            s = d.dynamics.sym
            th, dth = list(s.theta), list(s.dtheta)
            n = self.n
            J = lambdify(th, list(d.J), modules="mpmath")       # each shared subexpression once
            G = lambdify(th + dth, list(d.G), modules="mpmath")
            g = lambdify(th, list(d.numeric(d.dynamics.gravity)), modules="mpmath")
            self._plant_fns = {
                "J": lambda *a: (lambda v: mpmath.matrix([v[i * n:(i + 1) * n] for i in range(n)]))(J(*a)),
                "G": lambda *a: mpmath.matrix(G(*a)), "g": lambda *a: mpmath.matrix(g(*a)), "B": d.B}
        return self._plant_fns

    def mass_matrix(self, theta):
        """J(theta), row-major (n * n)."""
        with mpmath.workdps(DIGITS + 10):
            J = self._plant()["J"](*theta)
            return [J[i, j] for i in range(self.n) for j in range(self.n)]

    def bias(self, theta, dtheta):
        with mpmath.workdps(DIGITS + 10):
            return self._mp_vec(self._plant()["G"](*theta, *dtheta))

    def gravity(self, theta):
        with mpmath.workdps(DIGITS + 10):
            return self._mp_vec(self._plant()["g"](*theta))

    def input_matrix(self):
        B = self._plant()["B"]
        with mpmath.workdps(DIGITS + 10):
            return [mpmath.mpf(sp.Rational(B[i, j]).p) / sp.Rational(B[i, j]).q
                    for i in range(self.n) for j in range(self.n)]

    def forward_dynamics(self, theta, dtheta, u, d):
        """theta'' with J theta'' = B (u + d) - G, solved at 40 digits."""
        with mpmath.workdps(DIGITS + 10):
            f = self._plant()
            n = self.n
            B = mpmath.matrix(self.input_matrix())
            B = mpmath.matrix([[B[i * n + j] for j in range(n)] for i in range(n)])
            ud = mpmath.matrix([mpmath.mpf(a) + mpmath.mpf(b) for a, b in zip(u, d)])
            rhs = B * ud - f["G"](*theta, *dtheta)
            return self._mp_vec(mpmath.lu_solve(f["J"](*theta), rhs))
