"""The identification regressor as generated code (``derive generate --regressor``).

One kernel, ``regressor(theta, theta', theta'') -> Y`` (n x p, row-major), of
:func:`derive.identify.regressor.derive_regressor`, printed like every other
kernel (CasADi graph, then C and Python statements), with:

* ``c/<arm>_regressor.h``, ``.c``: ``int <arm>_regressor(theta, dtheta, ddtheta, Y)``,
  ``<ARM>_NB`` base parameters, their names and the arm file's values as
  read-only arrays, each parameter's expression in the standard ones in the header;
* ``c/<arm>_regressor_selftest.c``: Y at seeded dyadic states against the 40-digit
  reference of Y, and Y pi against the 40-digit J theta'' + G of the Derivation;
* ``python/<arm>_regressor.py``: ``regressor(theta, dtheta, ddtheta) -> (code, Y)``,
  ``BASE_PARAMETERS`` and ``BASE_VALUES``; it imports the arm's module for N and its checks.

The kinematics and gravity are baked in (also with ``--params runtime``): the
regressor is what identification holds fixed. Generated only on request: the
controller does not use it, and for a 7-joint arm it adds a kernel of about
2,300 operations and an n x p self-test table (see README, Identification).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from derive.codegen.balls import BallFunction, to_float, working_precision
from derive.codegen.kernels import KernelSpec, Port
from derive.codegen.printing import c_literal, expected_literal, py_literal
from derive.codegen.reference import PRECISION, Reference, certified
from derive.codegen.render import render
from derive.codegen.testvectors import DOUBLE_TOL, float_bound
from derive.codegen.views import ArmView, KernelView, comment_text, kernel_view, trig_helper
from derive.control.pipeline import Derivation
from derive.errors import DerivationError
from derive.identify.regressor import Regressor, derive_regressor


def regressor_spec(reg: Regressor) -> KernelSpec:
    """The kernel: theta, dtheta, ddtheta (n each) -> Y (n p, row-major)."""
    s = reg.sym
    return KernelSpec("regressor", (Port("theta", s.theta, "joint angles [rad]"),
                                    Port("dtheta", s.dtheta, "joint velocities [rad/s]"),
                                    Port("ddtheta", s.ddtheta, "joint accelerations [rad/s^2]")),
                      (Port("Y", tuple(reg.Y[i, j] for i in range(reg.n) for j in range(reg.p)),
                            "regressor Y, n x p row-major: J theta'' + G = Y pi"),),
                      "Identification regressor Y(theta, theta', theta''): J theta'' + G = Y pi (eq. 12)")


@dataclass(frozen=True)
class RegressorCase:
    """One state (theta, theta', theta''), the 40-digit Y and J theta'' + G (floats)."""

    x: tuple[float, ...]
    Y: tuple[float, ...]
    tau: tuple[float, ...]


def regressor_cases(d: Derivation, reg: Regressor, count: int, seed: int = 20260601) -> tuple[RegressorCase, ...]:
    """``count`` seeded dyadic states (exact in float and double) with Y in ball arithmetic
    (certified to 40 digits) and J theta'' + G of the Derivation (derive.codegen.reference)."""
    s, n = reg.sym, reg.n
    f = BallFunction(list(s.theta + s.dtheta + s.ddtheta), list(reg.Y), "regressor")
    ref = Reference(d)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        x = [round(v * 1024) / 1024 for v in rng.uniform(-3, 3, 3 * n)]
        for bits in (PRECISION, 2 * PRECISION, 4 * PRECISION):
            with working_precision(bits):
                Y = f(*x)
            if certified(Y):
                break
        else:
            raise DerivationError("regressor reference not certified to 40 digits")
        J = ref.mass_matrix(x[:n])
        G = ref.bias(x[:n], x[n:2 * n])
        tau = [G[i] + sum(J[i * n + j] * x[2 * n + j] for j in range(n)) for i in range(n)]
        out.append(RegressorCase(tuple(x), tuple(to_float(y) for y in Y), tuple(float(t) for t in tau)))
    return tuple(out)


@dataclass(frozen=True)
class RegressorView:
    """What the regressor templates need beside the arm's view (plain data)."""

    kernel: KernelView
    p: int
    names: tuple[str, ...]
    lines: tuple[str, ...]             # "k name = expression [unit]" per base parameter, for comments
    py_params: tuple[tuple[str, str, str], ...]   # (name, expression, unit)
    values: tuple[str, ...]            # the arm file's pi, C literals of the real type
    py_values: tuple[str, ...]
    absent: tuple[str, ...]            # standard combinations the dynamics do not see
    trig_helper: tuple[str, ...] = ()  # the file's own sin and cos (derive.codegen.trig), when used


@dataclass(frozen=True)
class RegressorSelftest:
    """Test vectors (C literals) and the tolerances of Y and of Y pi (norm-wise, relative)."""

    rule: str
    cases: tuple[RegressorCase, ...]
    tol_Y: str
    tol_tau: str
    fabs: str


def regressor_view(reg: Regressor, real: str, prefix: str) -> RegressorView:
    """The regressor's kernel and documentation for one real type."""
    pi = reg.base_values()
    lines, py = [], []
    for k, b in enumerate(reg.base):
        lines.append(comment_text(f"{k:2d} {b.name} = {b.text()} [{b.unit}]"))
        py.append((b.name, comment_text(b.text()), b.unit))
    kernel = kernel_view(regressor_spec(reg), real, prefix)
    return RegressorView(kernel=kernel, trig_helper=trig_helper((kernel,), real, prefix), p=reg.p, names=reg.names,
                         lines=tuple(lines), py_params=tuple(py), values=tuple(c_literal(v, real) for v in pi),
                         py_values=tuple(py_literal(v) for v in pi),
                         absent=tuple(comment_text(a) for a in reg.absent))


def regressor_selftest(d: Derivation, reg: Regressor, rv: RegressorView, real: str, count: int = 8) -> RegressorSelftest:
    """Vectors at ``count`` states; double 1e-12, float 16 (K + p) 2^-24 for a kernel of K operations."""
    lit = lambda xs: tuple(c_literal(x, real) for x in xs)  # noqa: E731
    want = lambda xs: tuple(expected_literal(x, real) for x in xs)  # noqa: E731
    cases = tuple(RegressorCase(lit(c.x), want(c.Y), want(c.tau)) for c in regressor_cases(d, reg, count))
    if real == "double":
        tol_Y = tol_tau = c_literal(DOUBLE_TOL, "double")
        rule = f"double {DOUBLE_TOL:g}"
    else:
        tol_Y = c_literal(float_bound(rv.kernel.operations), "float")
        tol_tau = c_literal(float_bound(rv.kernel.operations + rv.p), "float")
        rule = "float 16 K 2^-24 for K operations (derive.codegen.testvectors)"
    return RegressorSelftest(rule=rule, cases=cases, tol_Y=tol_Y, tol_tau=tol_tau,
                             fabs="fabsf" if real == "float" else "fabs")


def regressor_files(d: Derivation, v: ArmView, reg: Regressor | None = None) -> dict[str, str]:
    """``c/<arm>_regressor.h``, ``.c``, ``_selftest.c`` and ``python/<arm>_regressor.py``."""
    reg = derive_regressor(d.dynamics.chain) if reg is None else reg
    a = d.arm.name
    rv = regressor_view(reg, v.real, a)
    py = rv if v.real == "double" else regressor_view(reg, "double", a)
    return {
        f"c/{a}_regressor.h": render("c/regressor.h.jinja", v=v, rv=rv),
        f"c/{a}_regressor.c": render("c/regressor.c.jinja", v=v, rv=rv),
        f"c/{a}_regressor_selftest.c": render("c/regressor_selftest.c.jinja", v=v, rv=rv,
                                              t=regressor_selftest(d, reg, rv, v.real)),
        f"python/{a}_regressor.py": render("python/regressor.py.jinja", v=v, rv=py),
    }


def base_parameter_manifest(reg: Regressor) -> list[dict]:
    """The base parameters for MANIFEST.json: name, expression, unit, the arm file's value."""
    return [{"name": b.name, "expression": b.text(), "unit": b.unit, "value": float(v)}
            for b, v in zip(reg.base, reg.base_values())]
