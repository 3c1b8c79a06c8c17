"""Kernel specifications: the typed ports between the Derivation and emission.

A :class:`KernelSpec` names its input ports (each a tuple of SymPy symbols) and
its output ports (each a SymPy matrix over those symbols), as CasADi's
``Function(name, [x], [y], ['x'], ['y'])`` and SymForce's ``Codegen`` do. The
argument coverage is checked before anything is printed: every free symbol of
an output must lie in exactly one input port (pydy's ``MatrixGenerator``).

Kernels take the raw controller inputs (theta, theta', yd, yd', yd''), so the
error e = yd - C theta (eq. 20) is part of the maths, not of the glue. A
kernel may declare linear solves A y = b whose unknowns y its outputs use:
J^-1 is never formed (design: the generated code solves numerically).
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import sympy as sp

from derive.codegen.ldl import factor_symbols, ldl_factor, ldl_solve
from derive.dynamics.dag import Memo, free_symbols, times
from derive.dynamics.program import dag_xreplace, postorder
from derive.errors import CoverageError
from derive.control.pipeline import Derivation


class ParamsMode(str, Enum):
    """Where the arm's parameters live in generated code."""

    BAKED = "baked"      # folded into constants
    RUNTIME = "runtime"  # read from a caller-owned params struct


@dataclass(frozen=True)
class Port:
    """A named vector of symbols (input) or expressions (output), with its shape."""

    name: str
    items: tuple
    doc: str

    @property
    def size(self) -> int:
        return len(self.items)


@dataclass(frozen=True)
class LinearSolve:
    """Intermediate unknowns y (n symbols) with A y = b; A is n x n, b is n x 1."""

    unknowns: tuple[sp.Symbol, ...]
    A: sp.Matrix
    b: sp.Matrix


@dataclass(frozen=True)
class KernelSpec:
    """One generated function: name, ports, optional linear solves and a docstring."""

    name: str
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]
    doc: str
    solves: tuple[LinearSolve, ...] = ()

    def __post_init__(self) -> None:
        check_coverage(self)


def check_coverage(spec: KernelSpec) -> None:
    """Every free symbol of every output (and solve) lies in exactly one input port."""
    owner: dict[sp.Symbol, str] = {}
    for port in spec.inputs:
        for s in port.items:
            if s in owner:
                raise CoverageError(f"kernel {spec.name}: symbol {s} is in input ports "
                                    f"{owner[s]} and {port.name}")
            owner[s] = port.name
    unknowns = {y for solve in spec.solves for y in solve.unknowns}
    memo = Memo()  # free symbols of each shared subexpression, computed once
    used = free_symbols([v for solve in spec.solves for v in (*solve.A, *solve.b)], memo)
    used |= free_symbols([v for port in spec.outputs for v in port.items], memo)
    missing = sorted(map(str, used - set(owner) - unknowns))
    if missing:
        raise CoverageError(f"kernel {spec.name}: outputs use symbols no input port provides: "
                            f"{', '.join(missing)}")


def _flat(m: sp.Matrix) -> tuple:
    """Row-major entries of a matrix (C order)."""
    return tuple(m[i, j] for i in range(m.rows) for j in range(m.cols))


OBSERVER_STEPS = ("explicit", "implicit")   # derive generate --observer (derive.control.sampling.OBSERVERS)


def kernel_specs(d: Derivation, mode: ParamsMode, observer: str = "explicit") -> tuple[KernelSpec, ...]:
    """The kernels of an arm's controller (shapes for n joints, row-major).

    gains(theta) -> P, D, I (eq. 35-37); mpc(x) -> u (eq. 15);
    npid(x, int_e, dt) -> u, int_next (eq. 34); dobc(x, z) -> u (eq. 27, 22), with the law's
    acceleration a and the sines and cosines J needs; dobc_factor(theta, trig) -> the LDL^T factor
    of J; observer(z, a, ldl, u_law, u, dt)
    -> z_next (eq. 21, fed the applied u: :func:`explicit_observer_specs`); dobc_init(x) -> z(0)
    from the derived dhat(0) (implicit: dobc_init(x, dt) -> z(0), u0); dhat(theta', z) -> the estimate dhat (eq. 22);
    x = (theta, theta', yd, yd', yd''), p = parameters
    (runtime). The discretisation is part of the maths: forward Euler,
    int_next = int_e + dt e and z_next = z + dt z'; the glue only chooses
    (an integrator held at a voltage limit keeps int_e).

    ``observer = "implicit"`` (derive.control.sampling's module docstring): the
    observer kernel (theta, theta', z, u, dt) takes the backward-Euler step of eq. (21) over the interval
    that just ended, (J + dt W) y = G - B u - W theta' - z with the new
    measurement and the voltage u held over the interval, z_next = z + dt W y,
    and the glue applies the DOBC law to z_next. The NPID law matched to it is
    u = u* + B^-1 W x with (J + dt W) x = J xi, xi = C^-1 (e' + K2 e + K1 int e):
    the PID form with W replaced by W_dt = W (J + dt W)^-1 J (derive.control.npid),
    solved numerically like every J system. Its initial estimate is the same
    substitution in the derived dhat(0): dhat(0) = -B^-1 W_dt C^-1 (e'(0) + K2 e(0)),
    so dobc_init(x, dt) takes the sample time, returns z0 = B dhat(0) - W theta'
    and u0 = B^-1 (G - W theta' - z0), the held voltage that leaves z0 in place at
    the first sample: both forms give the same u at t = 0. Raises ValueError for
    another ``observer``.
    """
    if observer not in OBSERVER_STEPS:
        raise ValueError(f"kernel_specs: expected an observer step of {OBSERVER_STEPS}, got {observer!r}")
    implicit = observer == "implicit"
    s = d.dynamics.sym
    n = d.n
    runtime = mode is ParamsMode.RUNTIME
    value = (lambda m: m) if runtime else d.numeric
    params = (Port("p", tuple(sym for sym, _ in d.values), "arm parameters and gains"),) if runtime else ()
    e, _ = d.tracking_error

    def law(m: sp.Matrix) -> sp.Matrix:
        return d.measured(value(m))

    theta = Port("theta", s.theta, "joint angles [rad]")
    dtheta = Port("dtheta", s.dtheta, "joint velocities [rad/s]")
    x = (theta, dtheta, Port("yd", s.yd, "reference y_d"), Port("dyd", s.dyd, "reference y_d'"),
         Port("ddyd", s.ddyd, "reference y_d''"))
    z = Port("z", s.z, "observer state (eq. 21)")
    dt_sym = sp.Symbol("dt", positive=True)
    dt = Port("dt", (dt_sym,), "sample time [s]")
    npid = d.npid
    dhat0 = law(d.dhat0)   # expanded once the values are in (derive.control.pipeline)
    W, B = d.observer.W, d.dynamics.B
    J = value(d.dynamics.J)
    A = J + dt_sym * value(W)      # backward Euler: J + dt W
    z0 = times(value(B), dhat0) - value(W) * sp.Matrix(s.dtheta)
    if implicit:
        # (J + dt W) x = J xi is solved as x = xi + y, (J + dt W) y = -dt W xi: the same x, and no
        # symbolic product J xi (with W constant it is n^2 products of J's entries, each a large
        # expression: SymPy's evaluation of them took over 11 min of a 16-joint chain's generate)
        ys = tuple(sp.Symbol(f"xsolve{i + 1}", real=True) for i in range(n))
        Binv = value(B).inv()   # B is diagonal (eq. 12)
        Wv = value(W)
        xi = law(value(npid.xi))
        npid_u = law(d.mpc.u_star_rnea) + Binv * Wv * (xi + sp.Matrix(ys))
        npid_solves = (LinearSolve(ys, A, -dt_sym * (Wv * xi)),)
        npid_doc = ("u = u* + B^-1 W x, x = xi + y, (J + dt W) y = -dt W xi, so (J + dt W) x = J xi: eq. 34 with "
                    "W_dt = W (J + dt W)^-1 J")
        # dhat(0) of the sampled form: -B^-1 W_dt C^-1 (e'(0) + K2 e(0)) = -B^-1 W x0 with
        # (J + dt W) x0 = J xi(0), xi(0) = C^-1 (e'(0) + K2 e(0)) (derive.control.npid): the NPID
        # form's u at the first sample, so both forms give the same u from t = 0; x0 = xi(0) + y0 as above
        y0 = tuple(sp.Symbol(f"xsolve{i + 1}", real=True) for i in range(n))
        xi0 = law(value(npid.xi).xreplace({v: 0 for v in s.int_e}))
        init_solves = (LinearSolve(y0, A, -dt_sym * (Wv * xi0)),)
        Wx0 = Wv * (xi0 + sp.Matrix(y0))
        z0_outputs = (Port("z0", _flat(-Wx0 - value(W) * sp.Matrix(s.dtheta)),
                           "z(0) = B dhat(0) - W theta'(0), dhat(0) = -B^-1 W x0, (J + dt W) x0 = J xi(0)"),
                      Port("u0", _flat(times(Binv, value(d.dynamics.G) + Wx0)),
                           "u0 = B^-1 (G - W theta' - z0): the first backward-Euler step leaves z0"))
        init_inputs = (*x[:4], dt, *params)
        init_doc = ("Observer state giving the sampled initial estimate dhat(0) = -B^-1 W_dt C^-1 (e'(0) + K2 e(0)), "
                    "W_dt = W (J + dt W)^-1 J (eq. 30 for the backward-Euler step, not 31)")
    else:
        npid_u, npid_solves, npid_doc = law(npid.u_npid_rnea), (), "u = P e + D e' + I int e + N, eq. 34"
        z0_outputs = (Port("z0", _flat(z0), "z(0) = B dhat(0) - W theta'(0)"),)
        init_solves, init_inputs = (), (*x[:4], *params)
        init_doc = "Observer state giving the derived initial estimate dhat(0) (eq. 30, not 31)"
    return (
        KernelSpec("gains", (theta, *params), (
            # not P, D, I: C99's <complex.h> defines I (generated names are never one capital)
            Port("gain_p", _flat(value(npid.P)), "proportional gain P(theta), eq. 35"),
            Port("gain_d", _flat(value(npid.D)), "derivative gain D(theta), eq. 36"),
            Port("gain_i", _flat(value(npid.I)), "integral gain I, eq. 37")),
            "PID gains of the nonlinear PID predictive controller (eq. 35-37)"),
        KernelSpec("mpc", (*x, *params), (Port("u", _flat(law(d.mpc.u_star_rnea)), "u*, eq. 15"),),
                   "Nonlinear predictive control law u* (eq. 15)"),
        KernelSpec("npid", (*x, Port("int_e", s.int_e, "integral of e (eq. 34)"), dt, *params), (
            Port("u", _flat(npid_u), npid_doc),
            Port("int_next", _flat(sp.Matrix(s.int_e) + dt_sym * e), "int_e + dt e, e = yd - C theta (eq. 20)")),
            "Nonlinear PID predictive control law (eq. 34-38) and its integrator step", npid_solves),
        *(observer_specs(d, mode, x, z, dt, params) if implicit else explicit_observer_specs(d, mode, x, z, dt, params)),
        KernelSpec("dobc_init", init_inputs, z0_outputs, init_doc, init_solves),
        KernelSpec("dhat", (dtheta, z, *params), (
            Port("dhat", _flat(value(d.observer.dhat)), "dhat = B^-1 (z + W theta'), eq. 22"),),
            "Disturbance estimate of the observer state (eq. 22)"),
        *momentum_specs(d, mode, x, dt, params),
    )


def observer_specs(d: Derivation, mode: ParamsMode, x: tuple[Port, ...], z: Port, dt: Port,
                   params: tuple[Port, ...]) -> tuple[KernelSpec, ...]:
    """The DOBC's law and backward-Euler observer step (``--observer implicit``, kernel_specs):
    dobc(x, z) -> u; observer(theta, theta', z, u, dt) -> z + dt W y, (J + dt W) y = G - B u - W theta' - z
    (J + dt W is not symmetric for a full W: a general solve)."""
    value = (lambda m: m) if mode is ParamsMode.RUNTIME else d.numeric
    s, n, dts = d.dynamics.sym, d.n, dt.items[0]
    W = value(d.observer.W)
    y = tuple(sp.Symbol(f"jsolve{i + 1}", real=True) for i in range(n))
    solve = LinearSolve(y, value(d.dynamics.J) + dts * W, value(d.observer.J_solve_rhs))
    return (
        KernelSpec("dobc", (*x, z, *params), (Port("u", _flat(d.measured(value(d.npid.u_dobc_rnea))),
                                                   "u* - dhat, eq. 27"),),
                   "Composite law u = u* - dhat, dhat = B^-1 (z + W theta') (eq. 22, 27)"),
        KernelSpec("observer", (x[0], x[1], z, Port("u", s.u, "applied voltages"), dt, *params), (
            Port("z_next", _flat(sp.Matrix(s.z) + dts * W * sp.Matrix(y)),
                 "z + dt W y, (J + dt W) y = G - B u - p - z, eq. 21"),),
            "Disturbance observer step (eq. 21, 24), backward Euler over the interval that ended: "
            "(J + dt W) y = G - B u - W theta' - z solved numerically", (solve,)),
    )


def trig_atoms(exprs, angles) -> tuple[sp.Expr, ...]:
    """The sin(q) and cos(q) of the ``angles`` that occur in ``exprs``, joint by joint, sin first."""
    present = {e for e in postorder(exprs) if isinstance(e, (sp.sin, sp.cos))}
    return tuple(f(q) for q in angles for f in (sp.sin, sp.cos) if f(q) in present)


def explicit_observer_specs(d: Derivation, mode: ParamsMode, x: tuple[Port, ...], z: Port, dt: Port,
                            params: tuple[Port, ...]) -> tuple[KernelSpec, ...]:
    """The DOBC's law and forward-Euler observer step: dobc(x, z) -> u, a, trig;
    dobc_factor(theta, trig) -> ldl; observer(z, a, ldl, u_law, u, dt) -> z_next.

    The observer step z + dt W y, J y = G - B u - W theta' - z (eq. 21, 24), fed the applied u,
    is computed from the law's quantities: under the composite law u_law = B^-1 (J a + G) - B^-1
    (z + W theta') (eq. 22, 27, a = C^-1 (K1 e + K2 e' + yd'')) the right-hand side is
    G - B u_law - W theta' - z = -J a (the step behind eq. 28-29), so

        y = -a - J^-1 B (u - u_law),

    the second term the voltage limit's share. J^-1 is applied by the LDL^T factor of the
    symmetric positive definite J (derive.codegen.ldl), its own kernel: no general solve. The
    glue computes the factor only on a step where a joint is clipped; on any other step
    u = u_law exactly, so B (u - u_law) = 0 and every entry of the factor multiplies zero: it
    passes a zero factor (the same z_next, but for the sign of a zero), and the step costs the
    law (one RNEA pass, eq. 27's u* by the recursion) and W y alone. The law's kernel passes on
    the sines and cosines of the angles J depends on (``trig``, :func:`trig_atoms`; no port when
    there are none), so a clipped step does not call libm for them twice."""
    value = (lambda m: m) if mode is ParamsMode.RUNTIME else d.numeric
    s, n, dts = d.dynamics.sym, d.n, dt.items[0]
    W, B = value(d.observer.W), value(d.dynamics.B)
    a = tuple(sp.Symbol(f"accel{i + 1}", real=True) for i in range(n))
    law = tuple(sp.Symbol(f"ulaw{i + 1}", real=True) for i in range(n))
    factor = factor_symbols(n)
    y = -sp.Matrix(a) - ldl_solve(factor, B * (sp.Matrix(s.u) - sp.Matrix(law)))
    J = value(d.dynamics.J)
    atoms = trig_atoms(list(J), d.dynamics.angles)
    trig = tuple(sp.Symbol(f"trig{k + 1}", real=True) for k in range(len(atoms)))
    J_trig = sp.Matrix(n, n, dag_xreplace(list(J), dict(zip(atoms, trig))))
    said = "sin and cos of the angles J depends on, joint by joint"
    trig_out, trig_in = ((Port("trig", atoms, said),), (Port("trig", trig, "the dobc kernel's trig: " + said),)
                         ) if atoms else ((), ())
    return (
        KernelSpec("dobc", (*x, z, *params), (
            Port("u", _flat(d.measured(value(d.npid.u_dobc_rnea))), "u* - dhat, eq. 27"),
            Port("a", _flat(d.measured(value(d.mpc.a))), "a = C^-1 (K1 e + K2 e' + yd''): B u* = J a + G"),
            *trig_out),
            "Composite law u = u* - dhat, dhat = B^-1 (z + W theta') (eq. 22, 27), the law's acceleration a "
            "for the observer step and the sines and cosines J(theta) needs"),
        KernelSpec("dobc_factor", (x[0], *trig_in, *params), (
            Port("ldl", ldl_factor(J_trig), "J = L D L^T: -L's lower entries by rows, -D^-1"),),
            "The LDL^T factor of J(theta) (eq. 12) for the observer step's share of the limits on u, "
            "J^-1 B (u - u_law): computed on a step where a joint is clipped"),
        KernelSpec("observer", (z, Port("a", a, "the dobc kernel's a"), Port("ldl", factor, "the dobc kernel's ldl"),
                                Port("u_law", law, "the dobc kernel's u (before the limits)"),
                                Port("u", s.u, "applied voltages"), dt, *params), (
            Port("z_next", _flat(sp.Matrix(s.z) + dts * W * y),
                 "z + dt z', z' = W J^-1 (G - B u - p - z) = W (-a - J^-1 B (u - u_law)), eq. 21"),),
            "Disturbance observer step (eq. 21, 24), forward Euler with the applied u: "
            "J y = G - B u - W theta' - z = -J a - B (u - u_law), solved with the law's LDL^T factor of J"),
    )


def momentum_specs(d: Derivation, mode: ParamsMode, x: tuple[Port, ...], dt: Port,
                   params: tuple[Port, ...]) -> tuple[KernelSpec, ...]:
    """The generalized-momentum observer's kernels (derive.control.momentum), form mom,
    J theta' and C^T theta' by one recursion (derive.dynamics.momentum), neither J nor C formed:
    mom(x, m) -> u = u* - B^-1 r, r = K (J theta' - m) (eq. 27 with its estimate), that
    estimate dhat = B^-1 r, and m_rate = B u* + C^T theta' - g - F theta', the rate
    m' = B u + C^T theta' - g - F theta' + r at the law's u (B u + r = B u*); one kernel for
    mom_step and mom_estimate (the M4F's 4 KB of flash);
    mom_next(m, m_rate, u_law, u, dt) -> m + dt (m_rate + B (u - u_law)), forward Euler with the
    applied u (B (u - u_law): the voltage limit's share); mom_init(theta, theta') -> m(0) = J theta'
    (so r(0) = 0)."""
    mom = d.momentum
    value = (lambda m: m) if mode is ParamsMode.RUNTIME else d.numeric
    s = d.dynamics.sym
    n = d.n
    theta, dtheta = x[0], x[1]
    m = Port("m", mom.m, "momentum observer state: the integral m of derive.control.momentum")
    B = value(d.dynamics.B)
    u_star = d.measured(value(d.mpc.u_star_rnea))
    rate = tuple(sp.Symbol(f"mrate{i + 1}", real=True) for i in range(n))
    law = tuple(sp.Symbol(f"ulaw{i + 1}", real=True) for i in range(n))
    step = sp.Matrix(mom.m) + dt.items[0] * (sp.Matrix(rate) + B * (sp.Matrix(s.u) - sp.Matrix(law)))
    return (
        KernelSpec("mom", (*x, m, *params), (
            Port("u", _flat(u_star - value(mom.dhat_rnea)),
                 "u* - B^-1 r, r = K (J theta' - m): eq. 27 with the momentum estimate"),
            Port("dhat", _flat(value(mom.dhat_rnea)), "dhat = B^-1 K (J theta' - m)"),
            Port("m_rate", _flat(times(B, u_star) + value(mom.beta_rnea)),
                 "B u* + C^T theta' - g - F theta': m' at the law's u")),
            "Composite law u = u* - dhat with the generalized-momentum observer's dhat = B^-1 r, dhat, "
            "and the observer's rate m' at that u"),
        KernelSpec("mom_next", (m, Port("m_rate", rate, "the mom kernel's m_rate"),
                                Port("u_law", law, "the mom kernel's u (before the limits)"),
                                Port("u", s.u, "applied voltages"), dt, *params), (
            Port("m_next", _flat(step),
                 "m + dt (m_rate + B (u - u_law)) = m + dt (B u + C^T theta' - g - F theta' + K (J theta' - m))"),),
            "Momentum observer step with the applied u: forward Euler of m' = B u + C^T theta' - g - F theta' + r"),
        KernelSpec("mom_init", (theta, dtheta, *params), (
            Port("m0", _flat(value(mom.p_rnea)), "m(0) = J(theta0) theta0': r(0) = 0"),),
            "Momentum observer state at the first sample: the generalized momentum J theta'"),
    )
