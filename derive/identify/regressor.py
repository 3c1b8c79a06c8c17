"""The identification regressor: J(q) q'' + G(q, q') = Y(q, q', q'') pi (eq. 12's left side),
linear in the base parameters pi.

Derived from the same recursion as J and the bias (:mod:`derive.dynamics.rnea`):

1. each body's ten standard parameters (:mod:`derive.identify.parameters`) are
   regrouped towards the base as :func:`derive.dynamics.regroup.base_parameters`
   does (Khalil and Bennis 1995), which leaves per body at most ten linear
   combinations of the standard parameters (the kinematics' values put in);
2. the recursive Newton-Euler torque of the chain whose bodies are those
   combinations, as symbols, is linear in them: its Jacobian with respect to
   them (:func:`derive.dynamics.dag.jacobian`) is the regressor of the regrouped
   parameters; the rotor inertias add q''_j and the damping q'_j on row j;
3. the columns that vanish everywhere (parameters the dynamics do not see) are
   dropped, and a column that is a constant combination of earlier ones (the
   first joint's rotor inertia against its body's inertia about the axis, and
   any other such case of a special geometry) is folded into them, the numeric
   base-parameter step of Gautier ("Numerical calculation of the base inertial
   parameters of robots", J. Robotic Systems 8(4), 1991), at seeded random states.

What is left are the base parameters: each a linear combination of standard
parameters with exact coefficients (geometry, gravity) where they are exact.
The regressor depends on the kinematics and gravity only; its values are the
arm file's.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from fractions import Fraction
from functools import cached_property

import casadi as ca
import numpy as np
import sympy as sp

from derive.dynamics.crba import Composite
from derive.dynamics.dag import Memo, jacobian
from derive.dynamics.equations import frames
from derive.dynamics.regroup import base_parameters
from derive.dynamics.rnea import rnea
from derive.dynamics.spatial import ZERO, vec
from derive.dynamics.sx import to_sx
from derive.errors import DerivationError
from derive.identify.batch import Batch
from derive.identify.parameters import (BODY_NAMES, INERTIA_INDEX, StandardParameter, body_entries,
                                        standard_parameters, standard_values)
from derive.model.chain import Body, Chain
from derive.model.symbols import JointSymbols

SEED = 20260522            # the random states of the base-parameter step (deterministic)
ZERO_COLUMN = 1e-10        # a column this small against the largest is zero
DEPENDENT = 1e-8           # a column this close to the span of the kept ones depends on them
INDEPENDENT = 1e-5         # ... and one this far from it is independent; between is refused


@dataclass(frozen=True)
class BaseParameter:
    """One base parameter: name (``Izz1R`` when regrouped, else the standard name),
    its exact expression in the standard parameters, SI unit."""

    name: str
    expression: sp.Expr
    unit: str

    def text(self) -> str:
        """The expression as plain text (exact rationals, ``*`` for products)."""
        return str(self.expression)


@dataclass(frozen=True)
class Regressor:
    """Y (n x p) of an n-joint chain in its p base parameters, over ``sym``'s theta,
    dtheta, ddtheta; ``standard``: the standard parameters; ``K`` (p x s): pi = K phi for
    the standard values phi; ``absent``: the standard parameters (or regrouped
    combinations) that no torque depends on; ``seconds``: derivation time."""

    n: int
    sym: JointSymbols
    standard: tuple[StandardParameter, ...]
    base: tuple[BaseParameter, ...]
    Y: sp.Matrix
    K: np.ndarray = field(compare=False)
    absent: tuple[str, ...]
    prior: tuple[sp.Expr, ...]            # the arm file's standard values, exact
    seconds: float = field(default=0.0, compare=False)

    @property
    def p(self) -> int:
        return len(self.base)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(b.name for b in self.base)

    def base_values(self, phi=None) -> np.ndarray:
        """pi = K phi (p,), phi the standard values (default: the arm file's)."""
        phi = np.array([float(v) for v in (self.prior if phi is None else phi)])
        return self.K @ phi

    def exact_base_values(self) -> tuple[sp.Expr, ...]:
        """pi of the arm file's values, exact."""
        rule = {s.symbol: v for s, v in zip(self.standard, self.prior)}
        return tuple(b.expression.xreplace(rule) for b in self.base)

    @cached_property
    def function(self) -> ca.Function:
        """CasADi Function x = (theta, dtheta, ddtheta) (3n) -> Y row-major (n p)."""
        return sx_function(self.sym, [self.Y[i, j] for i in range(self.n) for j in range(self.p)], "regressor")

    @cached_property
    def batch(self) -> Batch:
        """:attr:`function` at many states at once (derive.identify.batch)."""
        return Batch(self.function)

    def evaluate(self, theta: np.ndarray, dtheta: np.ndarray, ddtheta: np.ndarray) -> np.ndarray:
        """Y at N states (each argument N x n): an array N x n x p."""
        x = np.hstack([np.atleast_2d(theta), np.atleast_2d(dtheta), np.atleast_2d(ddtheta)]).T
        return self.batch(x)[0].T.reshape(-1, self.n, self.p)


def sx_function(sym: JointSymbols, exprs: list, name: str) -> ca.Function:
    x = ca.SX.sym("x", 3 * len(sym.theta))
    env = {s: x[i] for i, s in enumerate(sym.theta + sym.dtheta + sym.ddtheta)}
    memo = Memo()
    out = ca.vertcat(*[to_sx(sp.sympify(e), env, memo) for e in exprs])
    return ca.Function(name, [x], [out], ["x"], ["Y"], {"cse": True})


def kinematics(chain: Chain) -> Chain:
    """``chain`` with the arm's values put into its joints and gravity (the regressor's
    constants); bodies and parameters as they were."""
    values = chain.values()
    joints = tuple(replace(j, origin=replace(j.origin, R=j.origin.R.xreplace(values), p=j.origin.p.xreplace(values)))
                   for j in chain.joints)
    return replace(chain, joints=joints, gravity=chain.gravity.xreplace(values))


def _symbolic_bodies(standard: tuple[StandardParameter, ...], n: int) -> list[Body]:
    out = []
    for i in range(n):
        s = [p.symbol for p in standard[10 * i: 10 * i + 10]]
        inertia = sp.Matrix(3, 3, lambda a, b: s[4 + INERTIA_INDEX.index((min(a, b), max(a, b)))])
        out.append(Body(s[0], sp.ImmutableMatrix(s[1:4]), sp.ImmutableMatrix(inertia)))
    return out


def _states(rng: np.random.Generator, chain: Chain, count: int) -> np.ndarray:
    """count x 3n random states: angles over a turn, displacements +-0.5 m, speeds and accelerations +-2."""
    n = chain.n
    spread = np.array([np.pi if j.type.rotates else 0.5 for j in chain.joints] + [2.0] * 2 * n)
    return rng.uniform(-1.0, 1.0, (count, 3 * n)) * spread


def _rational(x: float) -> sp.Expr:
    """An exact coefficient: the nearby small-denominator rational when x is one to 1e-12, else x."""
    f = Fraction(x).limit_denominator(10 ** 6)
    return sp.Rational(f.numerator, f.denominator) if abs(float(f) - x) <= 1e-12 * max(1.0, abs(x)) else sp.Float(x, 17)


def derive_regressor(chain: Chain, seed: int = SEED) -> Regressor:
    """The regressor of ``chain`` in its base parameters (module docstring).

    Raises DerivationError when the numeric base-parameter step cannot decide whether a
    column depends on the others (a geometry close to, but not at, a special one)."""
    started = time.perf_counter()
    n = chain.n
    kin = kinematics(chain)
    sym = JointSymbols.make(n)
    standard = standard_parameters(chain)
    regrouped = base_parameters(_symbolic_bodies(standard, n), kin.joints)
    # 1. the regrouped combinations, one symbol each, as the bodies of the recursion
    slots: list[tuple[sp.Symbol, sp.Expr, str, str]] = []     # (symbol, combination, standard name, unit)
    bodies = []
    for i, c in enumerate(regrouped, 1):
        entries = []
        for name, unit, e in zip(BODY_NAMES, (p.unit for p in standard[10 * (i - 1):]), body_entries(_as_body(c))):
            e = sp.expand(e)
            if e == 0:
                entries.append(ZERO)
                continue
            s = sp.Symbol(f"_slot_{name}{i}", real=True)
            slots.append((s, e, f"{name}{i}", unit))
            entries.append(s)
        I = tuple(tuple(entries[4 + INERTIA_INDEX.index((min(a, b), max(a, b)))] for b in range(3)) for a in range(3))
        bodies.append(Composite(entries[0], tuple(entries[1:4]), I))
    tau = rnea(bodies, frames(kin, sym.theta), sym.dtheta, list(sym.ddtheta), vec(kin.gravity))
    # 2. the regressor of the combinations, then rotor inertia and damping columns
    columns = list(jacobian(tau, [s for s, _, _, _ in slots]).T.tolist())
    by_name = {p.name: p for p in standard}
    for prefix, rate in (("Ia", sym.ddtheta), ("fv", sym.dtheta)):
        for j in range(n):
            p = by_name[f"{prefix}{j + 1}"]
            slots.append((p.symbol, p.symbol, p.name, p.unit))
            columns.append([rate[j] if i == j else ZERO for i in range(n)])
    # 3. drop vanishing columns, fold dependent ones (seeded random states)
    kept, folded, absent = _base_columns(sym, kin, columns, seed)
    base = []
    for k in kept:
        expression = slots[k][1] + sum((coef * slots[d][1] for d, coef in folded.get(k, ())), sp.Integer(0))
        name = slots[k][2] if expression == by_name[slots[k][2]].symbol else slots[k][2] + "R"
        base.append(BaseParameter(name, _tidy(sp.expand(expression), standard), slots[k][3]))
    Y = sp.Matrix([[columns[k][i] for k in kept] for i in range(n)])
    K = np.array([[float(b.expression.coeff(p.symbol)) for p in standard] for b in base])
    return Regressor(n=n, sym=sym, standard=standard, base=tuple(base), Y=Y, K=K,
                     absent=tuple(str(slots[k][1]) for k in absent), prior=standard_values(chain),
                     seconds=time.perf_counter() - started)


def _tidy(expression: sp.Expr, standard: tuple[StandardParameter, ...]) -> sp.Expr:
    """A linear combination of standard parameters with each coefficient a rational where
    it is one to 30 digits (cos(a)^2 + sin(a)^2 of an angle a URDF did not snap is 1),
    else its value to 17 digits."""
    out = sp.Integer(0)
    for p in standard:
        c = expression.coeff(p.symbol)
        if c == 0:
            continue
        if not c.is_Rational:
            value = sp.N(c, 40)
            f = Fraction(str(value)).limit_denominator(10 ** 9)
            exact = sp.Rational(f.numerator, f.denominator)
            c = exact if abs(value - exact) <= sp.Float("1e-30", 40) * max(1, abs(value)) else sp.Float(value, 17)
        out += c * p.symbol
    return out


def _as_body(c: Composite) -> Body:
    return Body(c.M, sp.ImmutableMatrix(c.h), sp.ImmutableMatrix(c.I))


def _base_columns(sym: JointSymbols, chain: Chain, columns: list, seed: int):
    """(kept column indices, {kept: ((dependent, coefficient), ...)}, vanishing indices):
    columns in order, each kept unless it vanishes or lies in the span of the kept ones."""
    n = chain.n
    f = Batch(sx_function(sym, [e for col in columns for e in col], "columns"))
    rng = np.random.default_rng(seed)
    count = max(12, 3 * len(columns) // n + 4)

    def sample() -> np.ndarray:   # (count n) x columns
        flat = f(_states(rng, chain, count).T)[0]        # (columns * n, count)
        return flat.reshape(len(columns), n, count).transpose(2, 1, 0).reshape(count * n, len(columns))

    W, check = sample(), sample()
    norms = np.linalg.norm(W, axis=0)
    scale = norms.max() if norms.size else 1.0
    kept: list[int] = []
    folded: dict[int, list] = {}
    absent = [k for k in range(len(columns)) if norms[k] <= ZERO_COLUMN * scale]
    Q = np.zeros((W.shape[0], 0))
    for k in range(len(columns)):
        if k in absent:
            continue
        v = W[:, k] / norms[k]
        r = v - Q @ (Q.T @ v)
        r = r - Q @ (Q.T @ r)                       # twice is enough (Kahan-Parlett)
        gap = np.linalg.norm(r)
        if DEPENDENT < gap < INDEPENDENT:
            raise DerivationError(f"base parameters: column {k + 1} is neither clearly independent of the others nor "
                                  f"a combination of them (distance {gap:.2e} at random states)")
        if gap >= INDEPENDENT:
            kept.append(k)
            Q = np.hstack([Q, (r / gap)[:, None]])
            continue
        beta = np.linalg.lstsq(W[:, kept], W[:, k], rcond=None)[0]
        coefs = [(kk, _rational(float(b))) for kk, b in zip(kept, beta) if abs(b) > 1e-12 * max(1.0, abs(beta).max())]
        miss = check[:, k] - sum((float(c) * check[:, kk] for kk, c in coefs), np.zeros(check.shape[0]))
        if np.linalg.norm(miss) > 1e-9 * np.linalg.norm(check[:, k]):
            raise DerivationError(f"base parameters: column {k + 1} depends on others at some states only")
        for kk, c in coefs:
            folded.setdefault(kk, []).append((k, c))
    return kept, folded, absent
