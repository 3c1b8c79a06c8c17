"""The simulator's kernels: the plant's forward dynamics with Coulomb friction,
one RK4 substep of plant and reference filter, the measurement and the
reference outputs, as CasADi functions printed to C (derive.codegen.printing).

All of the simulator's maths is here; the loop template (templates/sim/loop.c.jinja)
only sequences the kernels and the generated controller's steps.

* accel(theta, theta', u, d, tau_c, ieps, b, p) = theta'' with
  J theta'' = B (u + d) - G - tau_c tanh(theta'/eps) - b theta' (eq. 12 plus the
  plant's extra Coulomb and viscous friction; eps each joint's width of the smooth
  Coulomb law, [simulation] coulomb_smoothing, passed as ieps = 1/eps: tanh(ieps theta'),
  at the default eps = 0.01 the very product 100 theta' the kernel had when the width was a constant),
  J and G of the Derivation in its parameter symbols p (the true plant's values
  at run time), solved numerically (CasADi's linear solve), never J^-1; with a
  payload, J + J_p and G + G_p (derive.dynamics.payload), the payload's ten
  parameters appended to p;
* rk4(x, f, u, d, tau_c, ieps, b, r, h, p) -> (x', f'): one classical RK4 step of length h
  of the plant x = (theta, theta') and the reference filter
  Gr(s) = 1 / (s^2 + 1.8 s + 1) with states f = (y_d, y_d') driven by r (section 5.2);
  u, d and r are held over the step (zero-order hold);
* measure(x, n_q, n_dq, v, alpha) -> (theta_m, v'): measured angles theta + n_q and
  the tachometer filter v' = v + alpha (theta' + n_dq - v) (section 5.1);
* reference(f, r) -> y_d'' = r - 1.8 y_d' - y_d;
* reference_rk4(f, r, h) -> f': the RK4 step of the reference filter alone, and
  friction(dtheta, tauc, eps) -> tau_c tanh(theta'/eps): what a plant that is not derived
  here (MuJoCo's, derive.sim.mujoco) takes from the simulator.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import sympy as sp

from derive.codegen.casadi_bridge import to_function
from derive.codegen.kernels import KernelSpec, LinearSolve, Port
from derive.codegen.printing import print_function
from derive.control.pipeline import Derivation
from derive.sim.plant import payload_terms_of

GR_DAMPING = 1.8  # Gr(s) = 1 / (s^2 + 1.8 s + 1), section 5.2


def plant_symbols(d: Derivation) -> tuple[sp.Symbol, ...]:
    """The parameter symbols J, G and B use, in the order of ``d.values`` (the plant's
    parameters: the controller's T1, T2, w are not among them)."""
    from derive.dynamics.dag import free_symbols

    # each distinct subexpression once: SymPy's own free_symbols walks the shared DAG as a tree
    # (SO-100's plant FMU spent two minutes here)
    used = free_symbols([x for m in (d.dynamics.J, d.dynamics.G, d.dynamics.B) for x in m])
    return tuple(sym for sym, _ in d.values if sym in used)


def accel_spec(d: Derivation, params: tuple[sp.Symbol, ...] | None = None, payload: bool = False) -> KernelSpec:
    """Forward dynamics of the true plant with Coulomb friction, in parameter
    symbols ``params`` (default: every symbol of ``d.values``, the compiled loop's vector);
    ``payload``: J + J_p and G + G_p of a payload on the last body (eq. 12 with the plant's
    payload, derive.dynamics.payload), its ten symbols appended to ``params``."""
    s, dyn, n = d.dynamics.sym, d.dynamics, d.n
    J, G = dyn.J, dyn.G
    params = tuple(sym for sym, _ in d.values) if params is None else params
    if payload:
        terms = payload_terms_of(d)
        J, G, params = J + terms.J, G + terms.G, params + terms.symbols
    dist = tuple(sp.Symbol(f"d{i + 1}", real=True) for i in range(n))
    tau_c = tuple(sp.Symbol(f"tauc{i + 1}", real=True) for i in range(n))
    ieps = tuple(sp.Symbol(f"ieps{i + 1}", positive=True) for i in range(n))   # 1/eps [s/rad]
    visc = tuple(sp.Symbol(f"bx{i + 1}", real=True) for i in range(n))
    y = tuple(sp.Symbol(f"ddtheta{i + 1}", real=True) for i in range(n))
    friction = sp.Matrix([c * sp.tanh(k * v) + b * v for c, k, b, v in zip(tau_c, ieps, visc, s.dtheta)])
    rhs = dyn.B * (sp.Matrix(s.u) + sp.Matrix(dist)) - G - friction
    return KernelSpec(
        "accel", (Port("theta", s.theta, "joint angles"), Port("dtheta", s.dtheta, "joint velocities"),
                  Port("u", s.u, "applied voltages"), Port("d", dist, "input disturbance"),
                  Port("tauc", tau_c, "Coulomb friction"),
                  Port("ieps", ieps, "reciprocal Coulomb smoothing widths 1/eps"),
                  Port("bx", visc, "extra viscous friction"),
                  Port("p", params, "plant")),
        (Port("ddtheta", y, "joint accelerations"),),
        "J theta'' = B (u + d) - G - tau_c tanh(theta'/eps) - b theta'", (LinearSolve(y, J, rhs),))


def rk4_function(d: Derivation, params: tuple[sp.Symbol, ...] | None = None, payload: bool = False) -> ca.Function:
    """rk4(x, f, u, d, tauc, ieps, bx, r, h, p) -> (x_next, f_next): one classical RK4 step of
    length h of plant and reference filter, u, d and r held (see the module docstring);
    ``payload``: p ends with the payload's ten parameters (:func:`accel_spec`)."""
    n = d.n
    F = to_function(accel_spec(d, params, payload))
    npar = F.size1_in(7)
    x, f = ca.SX.sym("x", 2 * n), ca.SX.sym("f", 2 * n)
    u, dist, tau_c, ieps, visc, r = (ca.SX.sym(name, n) for name in ("u", "d", "tauc", "ieps", "bx", "r"))
    h, p = ca.SX.sym("h"), ca.SX.sym("p", npar)

    def deriv(xs, fs):
        acc = F(xs[:n], xs[n:], u, dist, tau_c, ieps, visc, p)
        return ca.vertcat(xs[n:], acc), _filter(fs, r)

    k1 = deriv(x, f)
    k2 = deriv(x + h / 2 * k1[0], f + h / 2 * k1[1])
    k3 = deriv(x + h / 2 * k2[0], f + h / 2 * k2[1])
    k4 = deriv(x + h * k3[0], f + h * k3[1])
    x_next = x + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
    f_next = f + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return ca.Function("rk4", [x, f, u, dist, tau_c, ieps, visc, r, h, p], [x_next, f_next],
                       ["x", "f", "u", "d", "tauc", "ieps", "bx", "r", "h", "p"], ["x_next", "f_next"], {"cse": True})


def _filter(f, r):
    """f' of the reference filter Gr(s) = 1 / (s^2 + 1.8 s + 1), states f = (y_d, y_d')."""
    n = f.shape[0] // 2
    return ca.vertcat(f[n:], r - GR_DAMPING * f[n:] - f[:n])


def reference_rk4_function(n: int) -> ca.Function:
    """reference_rk4(f, r, h) -> f_next: the classical RK4 step of length h of the reference
    filter alone, r held (the same stages as :func:`rk4_function` gives f)."""
    f, r, h = ca.SX.sym("f", 2 * n), ca.SX.sym("r", n), ca.SX.sym("h")
    k1 = _filter(f, r)
    k2 = _filter(f + h / 2 * k1, r)
    k3 = _filter(f + h / 2 * k2, r)
    k4 = _filter(f + h * k3, r)
    return ca.Function("reference_rk4", [f, r, h], [f + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)], ["f", "r", "h"],
                       ["f_next"], {"cse": True})


def friction_function(n: int) -> ca.Function:
    """friction(dtheta, tauc, eps) -> tau_c tanh(theta'/eps): the plant's smooth Coulomb friction
    (eps each joint's width, [simulation] coulomb_smoothing), as :func:`accel_spec` subtracts it."""
    v, tau_c, eps = ca.SX.sym("dtheta", n), ca.SX.sym("tauc", n), ca.SX.sym("eps", n)
    return ca.Function("friction", [v, tau_c, eps], [tau_c * ca.tanh(v / eps)], ["dtheta", "tauc", "eps"], ["tau"],
                       {"cse": True})


def reference_function(n: int) -> ca.Function:
    """reference(f, r) -> y_d'' = r - 1.8 y_d' - y_d of Gr(s) (section 5.2)."""
    f, r = ca.SX.sym("f", 2 * n), ca.SX.sym("r", n)
    return ca.Function("reference", [f, r], [r - GR_DAMPING * f[n:] - f[:n]], ["f", "r"], ["ddyd"], {"cse": True})


def measure_function(n: int) -> ca.Function:
    """measure(x, nq, ndq, v, alpha) -> (theta_m, v_next) (see the module docstring)."""
    x = ca.SX.sym("x", 2 * n)
    nq, ndq, v, alpha = ca.SX.sym("nq", n), ca.SX.sym("ndq", n), ca.SX.sym("v", n), ca.SX.sym("alpha")
    return ca.Function("measure", [x, nq, ndq, v, alpha], [x[:n] + nq, v + alpha * (x[n:] + ndq - v)],
                       ["x", "nq", "ndq", "v", "alpha"], ["theta_m", "v_next"], {"cse": True})


def sim_functions(d: Derivation, payload: bool = False) -> tuple[ca.Function, ...]:
    """rk4, measure and reference as CasADi functions (see the module docstring); ``payload``:
    the plant carries J_p and G_p, p the payload's ten parameters at its end."""
    return rk4_function(d, payload=payload), measure_function(d.n), reference_function(d.n)


def external_plant_functions(n: int) -> tuple[ca.Function, ...]:
    """measure, reference, reference_rk4 and friction: the kernels of a loop whose plant is
    integrated elsewhere (derive.sim.mujoco)."""
    return measure_function(n), reference_function(n), reference_rk4_function(n), friction_function(n)


@dataclass(frozen=True)
class SimKernel:
    """One printed simulator kernel: name, C parameters, registers, statements."""

    name: str
    c_args: tuple[str, ...]
    registers: int
    body: tuple[str, ...]
    operations: int


def sim_kernels(d: Derivation, functions: tuple[ca.Function, ...] | None = None,
                payload: bool = False) -> tuple[SimKernel, ...]:
    """The simulator kernels (default: :func:`sim_functions` with ``payload``) printed as double C
    (static functions of the loop)."""
    out = []
    for fn in sim_functions(d, payload) if functions is None else functions:
        printed = print_function(fn, "c", "double")
        args = tuple(f"const double {fn.name_in(i)}[{fn.size1_in(i)}]" for i in range(fn.n_in()))
        args += tuple(f"double {fn.name_out(i)}[{fn.size1_out(i)}]" for i in range(fn.n_out()))
        out.append(SimKernel(fn.name(), args, printed.registers, printed.statements, printed.operations))
    return tuple(out)
