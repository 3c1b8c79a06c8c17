"""The plant model exported beside the controller: J(theta), G(theta, theta'),
gravity g(theta), B and the forward dynamics (eq. 11-12), as kernels and views.

Kernels (shapes for n joints, row-major; p = parameters in runtime mode):

=================  =============================  ==============================================
kernel             inputs                         output
=================  =============================  ==============================================
mass_matrix        theta                          J (n x n), eq. 12
bias               theta, theta'                  G (n): Coriolis, centrifugal, gravity, damping
gravity            theta                          g (n): the gravity part of G (theta' = 0)
input_matrix       (none)                         B (n x n), eq. 12
forward_dynamics   theta, theta', u, d            theta'' with J theta'' = B (u + d) - G
=================  =============================  ==============================================

The forward dynamics solve J y = B (u + d) - G numerically (a CasADi linear
solve printed as arithmetic, as the observer's J solve): J is never inverted
symbolically. Every quantity comes from the Derivation (``d.dynamics``), never
re-derived here.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derive.codegen.kernels import KernelSpec, LinearSolve, ParamsMode, Port
from derive.codegen.views import ArmView, KernelView, kernel_views, trig_helper
from derive.control.pipeline import Derivation

# Name of each exported function and what it returns, for headers and docstrings.
QUANTITIES = (
    ("mass_matrix", "J", "inertia matrix J(theta), n x n (eq. 12) [kg m^2]"),
    ("bias", "G", "G(theta, theta'): Coriolis, centrifugal, gravity and damping torques (eq. 12) [N m]"),
    ("gravity", "g", "gravity torques g(theta) = G(theta, 0) without damping [N m]"),
    ("input_matrix", "B", "input matrix B, n x n (eq. 12) [N m/V]"),
    ("forward_dynamics", "ddtheta", "joint accelerations theta'' [rad/s^2] with J theta'' = B (u + d) - G"),
)


def _flat(m: sp.Matrix) -> tuple:
    return tuple(m[i, j] for i in range(m.rows) for j in range(m.cols))


def quantities(d: Derivation) -> dict[str, str]:
    """QUANTITIES' docs with B's unit and the input's as the actuation has them: N m/V for a DC
    motor, N m/(N m) (the gear ratio) in torque mode (derive.model.actuators.input_unit)."""
    from derive.model.actuators import units_text

    docs = {name: doc for name, _, doc in QUANTITIES}
    u = units_text(d.arm.input_units)
    if u != "V":
        docs["input_matrix"] = f"input matrix B, n x n (eq. 12) [N m per unit of u; u in {u}]"
    return docs


def plant_specs(d: Derivation, mode: ParamsMode) -> tuple[KernelSpec, ...]:
    """The plant's kernels (see the module docstring), in the order of QUANTITIES."""
    from derive.model.actuators import input_word, units_text
    s, dyn, n = d.dynamics.sym, d.dynamics, d.n
    runtime = mode is ParamsMode.RUNTIME
    value = (lambda m: m) if runtime else d.numeric
    params = (Port("p", tuple(sym for sym, _ in d.values), "arm parameters and gains"),) if runtime else ()
    theta = Port("theta", s.theta, "joint angles [rad]")
    dtheta = Port("dtheta", s.dtheta, "joint velocities [rad/s]")
    unit, word = units_text(d.arm.input_units), input_word(d.arm.input_units)
    u = Port("u", s.u, f"motor {word}s [{unit}]")
    dist = tuple(sp.Symbol(f"d{i + 1}", real=True) for i in range(n))
    y = tuple(sp.Symbol(f"ddtheta{i + 1}", real=True) for i in range(n))
    rhs = value(dyn.B) * (sp.Matrix(s.u) + sp.Matrix(dist)) - value(dyn.G)
    docs = quantities(d)
    return (
        KernelSpec("mass_matrix", (theta, *params), (Port("J", _flat(value(dyn.J)), docs["mass_matrix"]),),
                   "Inertia matrix J(theta) (eq. 12, a6)"),
        KernelSpec("bias", (theta, dtheta, *params), (Port("G", _flat(value(dyn.G)), docs["bias"]),),
                   "G(theta, theta') of J theta'' + G = B (u + d) (eq. 12)"),
        KernelSpec("gravity", (theta, *params), (Port("g", _flat(value(dyn.gravity)), docs["gravity"]),),
                   "Gravity torques g(theta)"),
        KernelSpec("input_matrix", params, (Port("B", _flat(value(dyn.B)), docs["input_matrix"]),),
                   "Input matrix B = diag(gear Kt / R) (eq. 12)"),
        KernelSpec("forward_dynamics", (theta, dtheta, u, Port("d", dist, f"input disturbance [{unit}] (eq. 12)"),
                                        *params),
                   (Port("ddtheta", y, docs["forward_dynamics"]),),
                   "Forward dynamics: J theta'' = B (u + d) - G solved numerically (eq. 12)",
                   (LinearSolve(y, value(dyn.J), rhs),)),
    )


# The public header names no parameter with a single capital (J, G, B): C99's <complex.h>
# defines I, and a later standard header may take another letter (issue 10, item 4).
C_OUTPUTS = {"J": "mass", "G": "bias", "g": "gravity", "B": "input_gain"}


@dataclass(frozen=True)
class PlantFunction:
    """One exported function: its name, output port, output size, inputs, doc."""

    name: str
    output: str
    c_output: str                # the C parameter the result is written to (no single capital: see below)
    size: int
    inputs: tuple[str, ...]
    c_args: tuple[str, ...]      # the public signature after the params argument
    matrix: bool                 # an n x n output (row-major in C, an array of shape (n, n) in Python)
    doc: str


@dataclass(frozen=True)
class PlantView:
    """What the plant templates need beside the arm's view (plain data)."""

    kernels: tuple[KernelView, ...]
    functions: tuple[PlantFunction, ...]
    trig_helper: tuple[str, ...] = ()     # the file's own sin and cos (derive.codegen.trig), when used


def plant_view(d: Derivation, real: str, mode: ParamsMode) -> PlantView:
    """Kernels and exported functions of the plant for one real type and mode."""
    specs = plant_specs(d, mode)
    docs = quantities(d)
    ctype = f"{d.arm.name}_real"

    def function(k: KernelSpec) -> PlantFunction:
        inputs = tuple(p for p in k.inputs if p.name != "p")
        out = k.outputs[0]
        c_out = C_OUTPUTS.get(out.name, out.name)
        c_args = tuple(f"const {ctype} {p.name}[{p.size}]" for p in inputs) + (f"{ctype} {c_out}[{out.size}]",)
        return PlantFunction(name=k.name, output=out.name, c_output=c_out, size=out.size,
                             inputs=tuple(p.name for p in inputs), c_args=c_args,
                             matrix=k.name in ("mass_matrix", "input_matrix"), doc=docs[k.name])

    functions = tuple(function(k) for k in specs)
    kernels = kernel_views(specs, real, d.arm.name)
    return PlantView(kernels=kernels, functions=functions, trig_helper=trig_helper(kernels, real, d.arm.name))


def plant_c_files(d: Derivation, v: ArmView, mode: ParamsMode) -> dict[str, str]:
    """``c/<arm>_plant.h``, ``c/<arm>_plant.c`` and the plant's self-test."""
    from derive.codegen.render import render

    pv = plant_view(d, v.real, mode)
    a = d.arm.name
    return {
        f"c/{a}_plant.h": render("c/plant.h.jinja", v=v, pl=pv),
        f"c/{a}_plant.c": render("c/plant.c.jinja", v=v, pl=pv),
        f"c/{a}_plant_selftest.c": render("c/plant_selftest.c.jinja", v=v, pl=pv,
                                          t=plant_selftest_view(d, v, pv)),
    }


CONDITION_FACTOR = 16.0   # the forward dynamics' tolerance per unit roundoff and unit of J's condition number


@dataclass(frozen=True)
class PlantCase:
    """One state (theta, theta', u, d) and the reference quantities at it (floats)."""

    x: tuple[float, ...]
    J: tuple[float, ...]
    G: tuple[float, ...]
    g: tuple[float, ...]
    B: tuple[float, ...]
    ddtheta: tuple[float, ...]


def plant_cases(ref, count: int, seed: int = 20261129) -> tuple[PlantCase, ...]:
    """``count`` seeded states, dyadic (exact in float and double), with the
    40-digit reference (derive.codegen.reference.Reference) of every quantity."""
    import numpy as np

    rng = np.random.default_rng(seed)
    n = ref.n

    def dyadic(low: float, high: float) -> list[float]:
        return [round(v * 1024) / 1024 for v in rng.uniform(low, high, n)]

    out = []
    for _ in range(count):
        theta, dtheta, u, dist = dyadic(-3, 3), dyadic(-3, 3), dyadic(-10, 10), dyadic(-1, 1)
        f = lambda v: tuple(float(a) for a in v)  # noqa: E731
        out.append(PlantCase(tuple(theta + dtheta + u + dist), f(ref.mass_matrix(theta)),
                             f(ref.bias(theta, dtheta)), f(ref.gravity(theta)), f(ref.input_matrix()),
                             f(ref.forward_dynamics(theta, dtheta, u, dist))))
    return tuple(out)


@dataclass(frozen=True)
class PlantSelftestView:
    """Test vectors (C literals of the real type) and the stated tolerance per quantity."""

    rule: str
    cases: tuple[PlantCase, ...]
    tol: tuple[tuple[str, str], ...]   # (function name, C literal)
    fabs: str
    ddtheta_tol: tuple[str, ...] = ()   # per case: forward dynamics' tolerance (C literals; see plant_selftest_view)


def plant_selftest_view(d: Derivation, v: ArmView, pv: PlantView, count: int = 8) -> PlantSelftestView:
    """Reference vectors at ``count`` states; double 1e-12, float 16 (K) 2^-24 per kernel of K operations;
    the forward dynamics (a linear solve with J) at each case at least CONDITION_FACTOR kappa(J) u, kappa the
    infinity-norm condition number of the reference J there and u the unit roundoff: the solve's relative
    error grows with J's conditioning (Higham, Accuracy and Stability, thm. 7.2), and a vendor arm's J is
    far from the packaged arms' (Tiago's torso and arm: kappa up to 3.8e4, errors 2.1e-12)."""
    import numpy as np

    from derive.codegen import testvectors as tv
    from derive.codegen.printing import c_literal
    from derive.codegen.reference import Reference

    ref = Reference(d)
    raw = plant_cases(ref, count)
    lit = lambda xs: tuple(c_literal(x, v.real) for x in xs)  # noqa: E731
    cases = tuple(PlantCase(*(lit(getattr(c, f)) for f in c.__dataclass_fields__)) for c in raw)
    ops = {k.name: k.operations for k in pv.kernels}
    unit = 2.0 ** -53 if v.real == "double" else 2.0 ** -24
    if v.real == "double":
        tol = tuple((f.name, c_literal(tv.DOUBLE_TOL, "double")) for f in pv.functions)
        rule = f"double {tv.DOUBLE_TOL:g}"
    else:
        tol = tuple((f.name, c_literal(tv.float_bound(max(ops[f.name], 1)), "float")) for f in pv.functions)
        rule = "float 16 K 2^-24 for a kernel of K operations (derive.codegen.testvectors)"
    base = dict(tol)["forward_dynamics"]
    fd = []
    for c in raw:
        J = np.array(c.J, dtype=float).reshape(d.n, d.n)
        kappa = float(np.linalg.norm(J, np.inf) * np.linalg.norm(np.linalg.inv(J), np.inf))
        fd.append(max(float(base.rstrip("f")), CONDITION_FACTOR * kappa * unit))
    rule += (f"; forward_dynamics at least {CONDITION_FACTOR:g} kappa(J) u per case (kappa: J's infinity-norm "
             f"condition number there, u = 2^{-53 if v.real == 'double' else -24})")
    return PlantSelftestView(rule=rule, cases=cases, tol=tol, fabs="fabsf" if v.real == "float" else "fabs",
                             ddtheta_tol=tuple(c_literal(x, v.real) for x in fd))
