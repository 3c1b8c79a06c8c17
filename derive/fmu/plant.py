"""The simulation plant of an arm's ``[simulation]`` section as an FMU (``derive fmu --plant``).

The plant is what ``derive simulate`` integrates, from the same kernels
(derive.sim.kernels) and the same true plant (derive.sim.plant.true_plant: every
mismatch of the ``[simulation]`` section applied to the parameter values): the
arm with Coulomb friction tau_c tanh(theta'/eps) (eps each joint's width, ``[simulation]
coulomb_smoothing``: the tunable ``coulomb_smoothing[i]``, > 0), extra viscous friction b theta',
a constant input disturbance d and the amplifier's voltage limits,

    J(theta) theta'' = B (u_a + d) - G(theta, theta') - tau_c tanh(theta'/eps) - b theta'   (eq. 12)

with u_a = u clipped to the limits, together with the reference of section 5.2:
Gr(s) = 1/(s^2 + 1.8 s + 1) driven by a pulse train added to y_d(0) = yd0 (0, or
C theta0 for ``reference_start = "measured"``, derive.sim.start). Each communication step
of length H holds u and the pulse r(t) (zero-order hold) and takes
``substeps`` classical RK4 steps of length H/substeps of plant and filter, as
``derive simulate`` does. The outputs (theta, theta', y_d, y_d', y_d'') wire
one to one to a controller FMU's inputs. Sensor noise and the tachometer filter
are not part of the plant FMU (an importer adds its own).

A rigid payload on the tip (derive.dynamics.payload: J + J_p, G + G_p) is set by the tunable
parameters ``payload_mass`` [kg] and ``payload_com[1..3]`` [m, the tip link's frame] (defaults:
``[simulation] payload_mass`` and the run's centre of mass, derive.sim.plant.payload_com); the
FMU computes the ten payload parameters from them (kernel ``payload``): the centre of mass turned
into F_n, the inertia about it ``payload_mass`` times the unit-mass shape of the arm file's
``[payload]`` inertia (its inertia over its mass), else of the 5 cm solid sphere.

Kernels (CasADi, printed to C double by derive.codegen.printing):

=============  ====================================  =========================================
kernel         inputs                                outputs
=============  ====================================  =========================================
pulse          t, start (n), period, amplitude (n),  r (n): yd0 + amplitude in each first half-period
               yd0
amplifier      u, u_max (n)                          u_a: u clipped where u_max > 0
reference      f = (y_d, y_d') (2n), r               y_d'' = r - 1.8 y_d' - y_d (derive.sim.kernels)
smoothing      eps (n)                               ieps = 1/eps (the widths of tau_c tanh(theta'/eps))
rk4            x, f, u_a, d, tau_c, ieps, b, r, H,   one RK4 substep of length H/substeps (derive.sim.kernels),
               p, payload_mass, payload_com (3)      p followed by payload(payload_mass, payload_com)
=============  ====================================  =========================================

(``payload``: payload_mass, payload_com (3) -> the ten parameters of derive.dynamics.payload.NAMES,
composed into ``rk4``.)

J is never inverted: the forward dynamics solve J y = rhs numerically (a CasADi
linear solve printed as arithmetic).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
import sympy as sp

from derive.codegen.printing import print_function
from derive.control.pipeline import Derivation
from derive.model.simspec import SimSettings
from derive.sim.kernels import plant_symbols, reference_function, rk4_function
from derive.sim.plant import TruePlant, true_plant


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


def plant_parameters(d: Derivation, s: SimSettings) -> tuple[tuple[tuple[sp.Symbol, float], ...], TruePlant]:
    """The plant's parameter symbols (those J, G and B use) with their values in the
    simulated plant (every mismatch of ``s`` applied, as derive simulate does), and that plant."""
    plant = true_plant(d, s)
    value = {sym: v for (sym, _), v in zip(d.values, plant.values)}
    return tuple((sym, value[sym]) for sym in plant_symbols(d)), plant


def payload_shape(d: Derivation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """R (3 x 3) and p (3) of the tip link's frame in F_n (derive.model.chain.Chain.tip; identity and
    0 when the tip is F_n), and the payload's inertia per kilogram about its centre of mass in F_n
    (3 x 3, m^2): the ``[payload]`` table's inertia over its mass, else the 5 cm solid sphere's."""
    from derive.dynamics.payload import sphere_inertia

    tip = d.dynamics.chain.tip
    R = np.eye(3) if tip is None else np.array(tip.R.tolist(), dtype=float)
    p = np.zeros(3) if tip is None else np.array(tip.p.tolist(), dtype=float).reshape(3)
    stated = getattr(d.arm, "payload", None)
    unit = (np.array(stated.inertia, dtype=float) / stated.mass if stated is not None and stated.inertia is not None
            else sphere_inertia(1.0))
    return R, p, R @ unit @ R.T


def payload_shape_words(d: Derivation) -> str:
    """What the payload's inertia is, in words (the payload_mass variable's description)."""
    stated = getattr(d.arm, "payload", None)
    if stated is not None and stated.inertia is not None:
        return f"the [payload] table's, {stated.mass:g} kg, scaled with the mass"
    return "a solid sphere of 5 cm radius"


def payload_function(d: Derivation) -> ca.Function:
    """payload(payload_mass [kg], payload_com (3) [m, tip link's frame]) -> the ten payload parameters
    (derive.dynamics.payload.NAMES, in F_n): mass, R com + p, mass times the unit shape
    (:func:`payload_shape`); what derive.sim.plant.payload_values gives for the same payload."""
    R, p, S = payload_shape(d)
    m, c = ca.SX.sym("payload_mass"), ca.SX.sym("payload_com", 3)
    com = ca.mtimes(ca.DM(R), c) + ca.DM(p)
    ten = ca.vertcat(m, com, *(m * float(S[i, j]) for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))))
    return ca.Function("payload", [m, c], [ten], ["payload_mass", "payload_com"], ["p"], {"cse": True})


def plant_functions(d: Derivation, params: tuple[sp.Symbol, ...], substeps: int) -> tuple[ca.Function, ...]:
    """pulse, amplifier, reference, smoothing and rk4 (module docstring) as CasADi functions;
    reference and the RK4 step are the simulator's own (derive.sim.kernels)."""
    n = d.n
    sym = ca.SX.sym
    x, f = sym("x", 2 * n), sym("f", 2 * n)
    u, dist, tau_c, ieps, visc, r, u_max, start = (sym(k, n) for k in ("u", "d", "tauc", "ieps", "bx", "r", "u_max",
                                                                       "start"))
    H, p, t, period, amp = sym("H"), sym("p", len(params)), sym("t"), sym("period"), sym("amplitude", n)
    on = ca.logic_and(start <= t, ca.fmod(t - start, period) < period / 2)
    yd0 = sym("yd0", n)
    pulse = ca.Function("pulse", [t, start, period, amp, yd0], [yd0 + ca.if_else(on, amp, 0)],
                        ["t", "start", "period", "amplitude", "yd0"], ["r"], {"cse": True})
    clipped = ca.if_else(u_max > 0, ca.fmin(ca.fmax(u, -u_max), u_max), u)
    amplifier = ca.Function("amplifier", [u, u_max], [clipped], ["u", "u_max"], ["u_a"], {"cse": True})
    step = rk4_function(d, params, payload=True)
    mass, com = sym("payload_mass"), sym("payload_com", 3)
    x_next, f_next = step(x, f, u, dist, tau_c, ieps, visc, r, H / substeps,
                          ca.vertcat(p, payload_function(d)(mass, com)))
    rk4 = ca.Function("rk4", [x, f, u, dist, tau_c, ieps, visc, r, H, p, mass, com], [x_next, f_next],
                      ["x", "f", "u", "d", "tauc", "ieps", "bx", "r", "H", "p", "payload_mass", "payload_com"],
                      ["x_next", "f_next"], {"cse": True})
    eps = sym("eps", n)
    smoothing = ca.Function("smoothing", [eps], [1 / eps], ["eps"], ["ieps"], {"cse": True})
    return pulse, amplifier, reference_function(n), smoothing, rk4


_DOCS = {"pulse": "pulse train r(t) of section 5.2 added to y_d(0)", "amplifier": "the amplifier's voltage limits",
         "reference": "Gr(s) = 1/(s^2 + 1.8 s + 1): y_d'' from the filter state and r",
         "smoothing": "1/eps of the widths eps of the smooth Coulomb law tau_c tanh(theta'/eps), as rk4 takes them",
         "rk4": "one classical RK4 substep of plant (with its payload) and reference filter (eq. 12, section 5.2)"}


def plant_kernels(d: Derivation, params: tuple[sp.Symbol, ...], substeps: int) -> tuple[PlantKernel, ...]:
    """The plant's kernels printed as double C (static functions of the plant glue)."""
    out = []
    for fn in plant_functions(d, params, substeps):
        printed = print_function(fn, "c", "double")
        args = tuple(f"const double {fn.name_in(i)}[{fn.size1_in(i)}]" for i in range(fn.n_in()))
        args += tuple(f"double {fn.name_out(i)}[{fn.size1_out(i)}]" for i in range(fn.n_out()))
        out.append(PlantKernel(fn.name(), _DOCS[fn.name()], args, printed.registers, printed.statements,
                               printed.operations, printed.unused_inputs))
    return tuple(out)

