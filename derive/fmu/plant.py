"""The simulation plant of an arm's ``[simulation]`` section as an FMU (``derive fmu --plant``).

The plant is what ``derive simulate`` integrates (derive.sim.simulate): the true
arm (the last link's point masses scaled by ``payload_scale``) with Coulomb
friction tau_c tanh(theta'/0.01), extra viscous friction b theta', a constant
input disturbance d and the amplifier's voltage limits,

    J(theta) theta'' = B (u_a + d) - G(theta, theta') - tau_c tanh(theta'/0.01) - b theta'   (eq. 12)

with u_a = u clipped to the limits, together with the reference of section 5.2:
Gr(s) = 1/(s^2 + 1.8 s + 1) driven by a pulse train. Each communication step
of length H holds u and the pulse r(t) (zero-order hold) and takes
``substeps`` classical RK4 steps of length H/substeps of plant and filter, as
``derive simulate`` does. The outputs (theta, theta', y_d, y_d', y_d'') wire
one to one to a controller FMU's inputs. Sensor noise and the tachometer filter
are not part of the plant FMU (an importer adds its own).

Kernels (CasADi, printed to C double by derive.codegen.printing):

=============  ====================================  =========================================
kernel         inputs                                outputs
=============  ====================================  =========================================
pulse          t, start (n), period, amplitude       r (n): amplitude in each first half-period
amplifier      u, u_max (n)                          u_a: u clipped where u_max > 0
reference      f = (y_d, y_d') (2n), r               y_d'' = r - 1.8 y_d' - y_d
rk4            x, f, u_a, d, tau_c, b, r, H, p       one RK4 substep of length H/substeps
=============  ====================================  =========================================

J is never inverted: the forward dynamics solve J y = rhs numerically (a CasADi
linear solve printed as arithmetic).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import sympy as sp

from derive.codegen.casadi_bridge import to_function
from derive.codegen.kernels import KernelSpec, LinearSolve, Port
from derive.codegen.printing import print_function
from derive.dynamics.planar import Dynamics, derive_dynamics
from derive.model.simspec import SimSettings
from derive.model.spec import Arm
from derive.sim.simulate import SMOOTH, true_arm

GR_DAMPING = 1.8  # Gr(s) = 1 / (s^2 + 1.8 s + 1), section 5.2


@dataclass(frozen=True)
class PlantKernel:
    """One printed kernel: name, C parameters, register count, statements."""

    name: str
    doc: str
    c_args: tuple[str, ...]
    registers: int
    body: tuple[str, ...]
    operations: int
    unused: tuple[str, ...]   # inputs the maths does not read


def plant_dynamics(arm: Arm, s: SimSettings) -> tuple[Dynamics, tuple[tuple[sp.Symbol, float], ...]]:
    """The true arm's dynamics in its parameter symbols, and the symbols J, G
    and B use with their values: what ``derive simulate``'s plant substitutes."""
    dyn = derive_dynamics(true_arm(arm, s))
    used = set()
    for m in (dyn.J, dyn.G, dyn.B):
        used |= m.free_symbols
    return dyn, tuple((sym, float(v)) for sym, v in dyn.params.values if sym in used)


def _accel(dyn: Dynamics, params: tuple[sp.Symbol, ...]) -> ca.Function:
    """theta'' of the true plant with friction (module docstring), J solved numerically."""
    s, n = dyn.sym, len(dyn.sym.theta)
    vec = lambda prefix: tuple(sp.Symbol(f"{prefix}{i + 1}", real=True) for i in range(n))  # noqa: E731
    dist, tau_c, visc, y = vec("d"), vec("tauc"), vec("bx"), vec("ddtheta")
    friction = sp.Matrix([c * sp.tanh(v / sp.Rational(str(SMOOTH))) + b * v
                          for c, b, v in zip(tau_c, visc, s.dtheta)])
    rhs = dyn.B * (sp.Matrix(s.u) + sp.Matrix(dist)) - dyn.G - friction
    spec = KernelSpec("accel", (Port("theta", s.theta, "joint angles"), Port("dtheta", s.dtheta, "velocities"),
                                Port("u", s.u, "applied voltages"), Port("d", dist, "input disturbance"),
                                Port("tauc", tau_c, "Coulomb friction"), Port("bx", visc, "extra viscous friction"),
                                Port("p", params, "true plant parameters")),
                      (Port("ddtheta", y, "joint accelerations"),),
                      "J theta'' = B (u + d) - G - tau_c tanh(theta'/0.01) - b theta'", (LinearSolve(y, dyn.J, rhs),))
    return to_function(spec)


def plant_functions(dyn: Dynamics, params: tuple[sp.Symbol, ...], substeps: int) -> tuple[ca.Function, ...]:
    """pulse, amplifier, reference and rk4 (module docstring) as CasADi functions."""
    n, npar = len(dyn.sym.theta), len(params)
    F = _accel(dyn, params)
    sym = ca.SX.sym
    x, f = sym("x", 2 * n), sym("f", 2 * n)
    u, dist, tau_c, visc, r, u_max, start = (sym(k, n) for k in ("u", "d", "tauc", "bx", "r", "u_max", "start"))
    H, p, t, period, amp = sym("H"), sym("p", npar), sym("t"), sym("period"), sym("amplitude")
    on = ca.logic_and(start <= t, ca.fmod(t - start, period) < period / 2)
    pulse = ca.Function("pulse", [t, start, period, amp], [ca.if_else(on, amp, 0)],
                        ["t", "start", "period", "amplitude"], ["r"], {"cse": True})
    clipped = ca.if_else(u_max > 0, ca.fmin(ca.fmax(u, -u_max), u_max), u)
    amplifier = ca.Function("amplifier", [u, u_max], [clipped], ["u", "u_max"], ["u_a"], {"cse": True})
    reference = ca.Function("reference", [f, r], [r - GR_DAMPING * f[n:] - f[:n]], ["f", "r"], ["ddyd"],
                            {"cse": True})
    h = H / substeps

    def deriv(xs, fs):
        acc = F(xs[:n], xs[n:], u, dist, tau_c, visc, p)
        return ca.vertcat(xs[n:], acc), ca.vertcat(fs[n:], r - GR_DAMPING * fs[n:] - fs[:n])

    k1 = deriv(x, f)
    k2 = deriv(x + h / 2 * k1[0], f + h / 2 * k1[1])
    k3 = deriv(x + h / 2 * k2[0], f + h / 2 * k2[1])
    k4 = deriv(x + h * k3[0], f + h * k3[1])
    rk4 = ca.Function("rk4", [x, f, u, dist, tau_c, visc, r, H, p],
                      [x + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]),
                       f + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])],
                      ["x", "f", "u", "d", "tauc", "bx", "r", "H", "p"], ["x_next", "f_next"], {"cse": True})
    return pulse, amplifier, reference, rk4


_DOCS = {"pulse": "pulse train r(t) of section 5.2", "amplifier": "the amplifier's voltage limits",
         "reference": "Gr(s) = 1/(s^2 + 1.8 s + 1): y_d'' from the filter state and r",
         "rk4": "one classical RK4 substep of plant and reference filter (eq. 12, section 5.2)"}


def plant_kernels(dyn: Dynamics, params: tuple[sp.Symbol, ...], substeps: int) -> tuple[PlantKernel, ...]:
    """The plant's kernels printed as double C (static functions of the plant glue)."""
    out = []
    for fn in plant_functions(dyn, params, substeps):
        printed = print_function(fn, "c", "double")
        args = tuple(f"const double {fn.name_in(i)}[{fn.size1_in(i)}]" for i in range(fn.n_in()))
        args += tuple(f"double {fn.name_out(i)}[{fn.size1_out(i)}]" for i in range(fn.n_out()))
        out.append(PlantKernel(fn.name(), _DOCS[fn.name()], args, printed.registers, printed.statements,
                               printed.operations, printed.unused_inputs))
    return tuple(out)


def amplitude_rad(s: SimSettings) -> float:
    """The pulse amplitude in radians (the arm file gives degrees)."""
    return math.radians(s.amplitude_deg)
