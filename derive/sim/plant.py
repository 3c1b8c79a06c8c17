"""The simulated plant: the arm's own derivation with changed parameter values
(the ``[simulation]`` mismatch), plus what the derivation does not model
(Coulomb friction, an input disturbance, the amplifier's voltage limits).

Mismatch is expressed as parameter values of the same Derivation wherever the
model has the parameter (the compiled loop reads them from a runtime parameter
vector, the Python reference puts them into the SymPy matrices):

* ``payload_scale`` multiplies the mass and inertia of the last link's point
  masses (a heavier payload of the same shape);
* ``viscous_friction`` is an extra viscous friction b theta' beside the model's;
* ``link_mass_scale`` multiplies each link's mass and its inertia about the
  centre of mass (the same shape, heavier; for a URDF or DH arm, the mass, first
  moment and inertia of the body joint i moves); ``torque_constant_scale``,
  ``voltage_constant_scale`` and ``resistance_scale`` the motors' constants.

A payload (``payload_mass`` > 0 at ``payload_com``, :func:`payload_values`) is a rigid body on
the tip the controller's model does not have: J_true = J + J_p, G_true = G + G_p
(derive.dynamics.payload), its ten parameters in F_n (``TruePlant.payload``) after the
parameter vector (the compiled loop built with ``payload=True``, derive.sim.compiled).

Coulomb friction tau_c tanh(theta'/eps) and the disturbance d (eq. 12) enter the
forward dynamics J theta'' = B (u + d) - G - tau_c tanh(theta'/eps) - b theta', eps each
joint's ``[simulation] coulomb_smoothing`` (default SMOOTH = 0.01 rad/s): a regularised Coulomb
law whose slope tau_c/eps at rest is the plant's stiffest damping on a light joint
(:func:`decay_mode`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from derive.control.pipeline import Derivation
from derive.dynamics.payload import NAMES as PAYLOAD_NAMES, PayloadTerms, payload_terms, sphere_inertia
from derive.dynamics.program import dag_xreplace, lambdify
from derive.model.payload import body_values
from derive.model.simspec import COULOMB_SMOOTHING, SimSettings, coulomb_widths

SMOOTH = COULOMB_SMOOTHING  # rad/s: the default width of the tanh that smooths Coulomb friction
BODY_UNITS = ("kg", "kg m", "kg m^2")   # the body parameters link_mass_scale multiplies


@dataclass(frozen=True)
class TruePlant:
    """The plant one run integrates: parameter values in the Derivation's order
    (``d.values``), Coulomb friction [N m], extra viscous friction [N m s/rad],
    disturbance d [V], input limits (inf = none); ``smoothing``: each joint's width eps
    [rad/s] of tau_c tanh(theta'/eps), () = SMOOTH for every joint."""

    values: tuple[float, ...]
    coulomb: tuple[float, ...]
    viscous: tuple[float, ...]
    disturbance: tuple[float, ...]
    u_max: tuple[float, ...]
    changed: dict = field(default_factory=dict, compare=False)  # parameter name -> (arm value, plant value)
    payload: tuple[float, ...] = (0.0,) * 10   # the payload's ten parameters in F_n (derive.dynamics.payload.NAMES)
    smoothing: tuple[float, ...] = ()   # rad/s (m/s prismatic) per joint; () = SMOOTH each

    @property
    def widths(self) -> tuple[float, ...]:
        """Each joint's eps [rad/s] of the smooth Coulomb law tau_c tanh(theta'/eps) (n)."""
        return self.smoothing if self.smoothing else (SMOOTH,) * len(self.coulomb)

    @property
    def has_payload(self) -> bool:
        """A payload of mass > 0 rides on the tip."""
        return self.payload[0] > 0

    def vector(self, payload: bool) -> tuple[float, ...]:
        """The compiled plant's parameter vector: ``values``, and with ``payload`` the ten after them."""
        return self.values + (self.payload if payload else ())


_TERMS: dict[int, tuple[Derivation, PayloadTerms]] = {}


def payload_terms_of(d: Derivation) -> PayloadTerms:
    """derive.dynamics.payload.payload_terms of ``d``'s dynamics, derived once per Derivation in a
    process (J_p n x n and G_p n x 1 in the joint symbols and the ten payload symbols; 0.06 s for
    the Panda)."""
    hit = _TERMS.get(id(d))
    if hit is None or hit[0] is not d:
        if len(_TERMS) > 8:
            _TERMS.clear()
        hit = _TERMS[id(d)] = (d, payload_terms(d.dynamics))
    return hit[1]


def payload_com(d: Derivation, s: SimSettings) -> tuple[float, float, float]:
    """The payload's centre of mass [m] in the tip link's frame: ``[simulation] payload_com``, else
    the ``[payload]`` table's com, else the origin."""
    if s.payload_com:
        return tuple(s.payload_com)
    stated = getattr(d.arm, "payload", None)
    return tuple(stated.com) if stated is not None else (0.0, 0.0, 0.0)


def payload_note(d: Derivation, s: SimSettings) -> str:
    """The payload of settings ``s`` in words (the metrics files' plant descriptions)."""
    stated = getattr(d.arm, "payload", None)
    shape = ("the [payload] table's inertia at that mass" if stated is not None and stated.inertia is not None
             else "a solid sphere of 5 cm radius")
    com = ", ".join(f"{x:g}" for x in payload_com(d, s))
    return f"a rigid payload of {s.payload_mass:g} kg at [{com}] m in the tip link's frame, {shape}"


def payload_values(d: Derivation, s: SimSettings) -> tuple[float, ...]:
    """The ten payload parameters (derive.dynamics.payload.NAMES; kg, m, kg m^2, in F_n) of
    ``[simulation] payload_mass`` at :func:`payload_com`, its inertia about its centre of mass the
    ``[payload]`` table's shape at that mass (derive.model.payload.PayloadRange.inertia_at) when the
    table states one, else the 5 cm solid sphere; all zero without a payload."""
    if s.payload_mass <= 0:
        return (0.0,) * 10
    return body_values(d.dynamics.chain, s.payload_mass, payload_com(d, s), payload_inertia(d, s))


def payload_inertia(d: Derivation, s: SimSettings) -> np.ndarray:
    """The payload's inertia about its centre of mass (3 x 3, kg m^2, the tip link's frame) at
    ``[simulation] payload_mass``: the ``[payload]`` table's shape when it states an inertia, else
    the solid sphere of 5 cm radius."""
    stated = getattr(d.arm, "payload", None)
    if stated is not None and stated.inertia is not None:
        return stated.inertia_at(s.payload_mass)
    return sphere_inertia(s.payload_mass)


def true_plant(d: Derivation, s: SimSettings) -> TruePlant:
    """The plant of ``d`` under settings ``s`` (a sweep sample is settings too).

    A factor applies to a parameter the arm file gives (a symbol of ``d.values``);
    a value the file leaves to its default (a uniform rod's inertia m l^2/12) is
    an expression in those symbols and follows them."""
    by_field = {p.field: p.symbol for p in d.dynamics.chain.parameters}
    values = {sym: float(v) for sym, v in d.values}
    scale: dict[sp.Symbol, float] = {}

    def put(field_name: str, factor: float) -> None:
        entry = by_field.get(field_name)
        if entry is not None and entry in values:
            scale[entry] = factor

    last = d.n - 1
    for k, pm in enumerate(d.arm.point_masses, 1):
        if pm.link == last:
            put(f"point_mass[{k}].mass", s.payload_scale)
            put(f"point_mass[{k}].inertia", s.payload_scale)
    for i, f in enumerate(s.link_mass_scale, 1):
        put(f"link[{i}].mass", f)
        put(f"link[{i}].inertia", f)
    if d.arm.spatial is not None:   # a URDF or DH body: its mass, first moment and inertia, the same shape
        units = {p.symbol: p.unit for p in d.dynamics.chain.parameters}
        for body, f in zip(d.dynamics.chain.bodies, s.link_mass_scale):
            used = body.mass.free_symbols | body.first_moment.free_symbols | body.inertia.free_symbols
            scale.update({sym: f for sym in used if units.get(sym) in BODY_UNITS and sym in values})
    for key, factors in (("torque_constant", s.torque_constant_scale), ("voltage_constant", s.voltage_constant_scale),
                         ("resistance", s.resistance_scale)):
        for i, f in enumerate(factors, 1):
            put(f"motor[{i}].{key}", f)
    changed = {}
    for sym, f in scale.items():
        if values[sym] * f != values[sym]:
            changed[str(sym)] = (values[sym], values[sym] * f)
            values[sym] *= f
    payload = payload_values(d, s)
    if payload[0] > 0:   # the arm file's arm carries none
        changed.update({name: (0.0, v) for name, v in zip(PAYLOAD_NAMES, payload)})
    u_max = tuple(float(m.input_limit) if m.input_limit else math.inf for m in d.arm.motors)
    return TruePlant(values=tuple(values[sym] for sym, _ in d.values), coulomb=tuple(s.coulomb_friction),
                     viscous=tuple(s.viscous_friction), disturbance=tuple(s.disturbance), u_max=u_max,
                     changed=changed, payload=payload, smoothing=coulomb_widths(s, d.n))


class Plant:
    """The Python reference plant: x' = f(x, u) for x = (theta, theta'), the
    SymPy J and G lambdified in the parameter symbols, solved by numpy; one row
    per run, so that several controllers step in lockstep (derive.sim.simulate.run_many).

    It is a :class:`derive.sim.plants.SteppedPlant`: ``reset``, ``step`` (classical RK4
    with u held), ``keep``, ``theta``, ``dtheta``."""

    def __init__(self, d: Derivation, plant: TruePlant):
        dyn = d.dynamics
        syms = [sym for sym, _ in d.values]
        self.n = n = d.n
        # the true plant's values put in (as 17-digit floats): the constants fold once, here
        rep = {sym: sp.Float(v, 17) for sym, v in zip(syms, plant.values)}
        J, G = dyn.J, dyn.G
        if plant.has_payload:   # J + J_p, G + G_p at the payload's ten values (eq. 12)
            terms = payload_terms_of(d)
            J, G = J + terms.J, G + terms.G
            rep.update({sym: sp.Float(v, 17) for sym, v in zip(terms.symbols, plant.payload)})
        exprs = dag_xreplace(list(J) + list(G), rep, keep_sums=False)  # as xreplace builds them
        self._jg = lambdify(list(dyn.sym.theta + dyn.sym.dtheta), exprs)  # each shared subexpression once
        self._p: list[float] = []
        self.B = np.array([float(b.xreplace(rep)) for b in dyn.B.diagonal()], dtype=float)
        self.coulomb = np.array(plant.coulomb)
        self.smoothing = np.array(plant.widths, dtype=float)
        self.viscous = np.array(plant.viscous)
        self.d = np.array(plant.disturbance)
        self.u_max = np.array(plant.u_max)
        self._n2 = n * n

    def matrices(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The true plant's J (rows x n x n) and G (rows x n) at (q, dq), each rows x n: the arm's
        (eq. 12) at the plant's values, with the payload's J_p and G_p when it carries one."""
        n, rows = self.n, q.shape[0]
        vals = self._jg(*q.T, *dq.T, *self._p)
        J = np.empty((rows, n, n))
        for k in range(self._n2):
            J[:, k // n, k % n] = vals[k]
        G = np.empty((rows, n))
        for i in range(n):
            G[:, i] = vals[self._n2 + i]
        return J, G

    def accel(self, q: np.ndarray, dq: np.ndarray, u: np.ndarray) -> np.ndarray:
        """theta'' at (q, dq) under voltages u, each (runs x n): one plant per row,
        J theta'' = B (u + d) - G - tau_c tanh(theta'/eps) - b theta', solved by numpy (LAPACK)."""
        J, G = self.matrices(q, dq)
        rhs = self.B * (u + self.d) - G - self.coulomb * np.tanh(dq / self.smoothing) - self.viscous * dq
        return np.linalg.solve(J, rhs[..., None])[..., 0]

    def reset(self, theta0, rows: int) -> None:
        """``rows`` copies at rest at the angles ``theta0`` (n)."""
        self.x = np.tile(np.concatenate([np.asarray(theta0, dtype=float), np.zeros(self.n)]), (rows, 1))

    def step(self, u: np.ndarray, dt: float, substeps: int) -> None:
        """Advance every row by dt under its u (rows x n, held): ``substeps`` classical RK4 steps."""
        n, h = self.n, dt / substeps

        def f(x):
            return np.concatenate([x[:, n:], self.accel(x[:, :n], x[:, n:], u)], axis=1)

        x = self.x
        for _ in range(substeps):
            k1 = f(x)
            k2 = f(x + h / 2 * k1)
            k3 = f(x + h / 2 * k2)
            k4 = f(x + h * k3)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        self.x = x

    def keep(self, rows: list[int]) -> None:
        """Keep only these rows (the runs that go on)."""
        self.x = self.x[rows]

    @property
    def theta(self) -> np.ndarray:
        return self.x[:, :self.n]

    @property
    def dtheta(self) -> np.ndarray:
        return self.x[:, self.n:]


RK4_REAL_LIMIT = 2.785293563405282   # the classical RK4 is stable for h lambda in [-2.785, 0] on the real axis


def stiffest_mode(d: Derivation, s: SimSettings, coulomb=None) -> dict:
    """The fastest decay rate lambda [1/s] of the plant's velocities at the initial pose, the
    largest eigenvalue of J^-1 D with D the damping of each joint (back-EMF, bv, [simulation]
    viscous_friction and the smooth Coulomb friction's slope tau_c / eps at rest, eps each joint's
    coulomb_smoothing), and h lambda
    for the RK4 step h = sample_time / substeps: above RK4_REAL_LIMIT the integration of either
    plant (derive's or MuJoCo's, the same scheme) is unstable in that mode and its trajectory
    wrong; ``substeps`` is then the smallest count that is stable. ``coulomb``: the tau_c [N m]
    per joint the plant applies as the smooth law (derive.sim.plants.PlantSource.coulomb;
    default [simulation] coulomb_friction, derive's plant; MuJoCo's leaves it out where the
    file's friction loss replaces it)."""
    plant = true_plant(d, s)
    rep = {sym: sp.Float(v, 17) for (sym, _), v in zip(d.values, plant.values)}
    return decay_mode(d.dynamics, rep, s, plant.viscous, plant.coulomb if coulomb is None else coulomb)


def decay_mode(dynamics, values: dict, s: SimSettings, viscous, coulomb, J=None) -> dict:
    """stiffest_mode's figures for ``dynamics`` (derive.dynamics.equations) at parameter
    ``values`` {symbol: number}: the nominal plant when they are the arm file's (derive init
    writes the substeps this asks for). ``J``: J at the initial pose (n x n) when the caller has it."""
    from derive.model.actuators import terms

    theta = list(dynamics.sym.theta)
    n = len(theta)
    if J is None:
        J = np.array(lambdify(theta, dag_xreplace(list(dynamics.J), values))(*s.initial_theta), dtype=float)
    damping = np.array([float(terms(a)[1].xreplace(values)) for a in dynamics.chain.actuators])
    damping += np.array(viscous, dtype=float) + np.array(coulomb, dtype=float) / np.array(coulomb_widths(s, n))
    rate = float(np.max(np.linalg.eigvals(np.linalg.solve(J.reshape(n, n), np.diag(damping))).real))
    h = s.sample_time / s.substeps
    return {"rate": rate, "h_rate": rate * h, "stable": rate * h <= RK4_REAL_LIMIT,
            "substeps": max(s.substeps, math.ceil(rate * s.sample_time / RK4_REAL_LIMIT))}
