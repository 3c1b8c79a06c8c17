"""Dynamics benchmark: the recursive form against sympy.physics.mechanics.

For the default arm and planar chains of n = 2, 3, 4, 6 links: the time to
derive J and G (eq. 12) and their operation count after CSE with the arm's
values put in, for

* ours: :func:`derive.dynamics.equations.derive_dynamics` (CRBA for J, RNEA for G, over the arm's chain);
* Kane: :class:`sympy.physics.mechanics.KanesMethod`, generalized speeds
  u_i = theta_i';
* Lagrange: :class:`sympy.physics.mechanics.LagrangesMethod`.

The mechanics models carry the same links, point masses and gravity with the
arm's exact values; J is their mass matrix and G = -forcing (no inputs, so all
of it is the part that does not multiply theta''). The motor terms, which are
not multibody physics (reflected rotor inertia gr^2 Jm on J's diagonal, damping
diag(gr^2 Kt Kv / Ra + bv) theta' in G), are added to both identically. Every
Kane and Lagrange model is checked against ours at one numeric state.

Times are the best of 3 runs with SymPy's cache emptied before each (so a run
does not reuse the previous one's work); derive_dynamics' time is also split
off into that of J and G alone, since it builds the Coriolis matrix as well.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from typing import TypeVar

import sympy as sp
from sympy.core.cache import clear_cache
from sympy.core.function import AppliedUndef
from sympy.physics import mechanics as me

import derive
from derive.dynamics.crba import composites, crba
from derive.dynamics.equations import Dynamics, derive_dynamics, frames
from derive.dynamics.motors import motor_terms as chain_motor_terms
from derive.dynamics.program import matrix_xreplace
from derive.dynamics.regroup import base_parameters
from derive.dynamics.rnea import rnea
from derive.dynamics.spatial import ZERO, vec
from derive.dynamics.identities import count_ops_cse
from derive.model.examples import planar_chain_dict
from derive.model.spec import Arm, arm_from_dict
from derive.model.symbols import JointSymbols

from . import Goal, Section, best_of, seconds, table

TITLE = "Dynamics (eq. 12): recursive form vs sympy.physics.mechanics"
CHAINS = (2, 3, 4, 6)
REPEAT = 3
BUDGET = 5.0          # seconds: no further repeats once the runs so far took this long
DEFAULT_GOAL = 0.5    # seconds for the default arm
SPEEDUP_GOAL = 10.0   # n = 6: at least this many times faster than Kane

T = TypeVar("T")


def chain_dict(n: int, gravity: float = 9.81) -> dict:
    """The planar n-link test chain (derive.model.examples), with gravity by default."""
    return planar_chain_dict(n, gravity)


def chain(n: int, gravity: float = 9.81) -> Arm:
    """The validated :func:`chain_dict` arm."""
    return arm_from_dict(chain_dict(n, gravity), f"<chain{n}>")


def _exact(x: Fraction) -> sp.Rational:
    """A Fraction of the arm as a SymPy Rational."""
    return sp.Rational(x.numerator, x.denominator)


def mechanics_model(arm: Arm, kane: bool) -> tuple[sp.Matrix, sp.Matrix, list, list]:
    """Rigid-body J and G of ``arm`` by KanesMethod (``kane``) or LagrangesMethod.

    Returns (mass matrix, -forcing, q, speeds): q are the angle dynamicsymbols,
    speeds the u_i (Kane) or q_i' (Lagrange) the matrices are written in.
    """
    n = arm.n
    q = me.dynamicsymbols(f"q1:{n + 1}")
    speeds = me.dynamicsymbols(f"u1:{n + 1}") if kane else [qi.diff() for qi in q]
    g = _exact(arm.gravity)
    N = me.ReferenceFrame("N")
    origin = joint = me.Point("O")
    origin.set_vel(N, 0)
    parent, bodies, loads = N, [], []
    for i, link in enumerate(arm.links):
        A = me.ReferenceFrame(f"A{i + 1}")
        A.orient_axis(parent, parent.z, q[i])
        A.set_ang_vel(parent, speeds[i] * parent.z)
        parts = [(f"L{i + 1}", _exact(link.mass), _exact(link.com), _exact(link.inertia))]
        parts += [(f"P{k + 1}", _exact(pm.mass), _exact(pm.distance), _exact(pm.inertia))
                  for k, pm in enumerate(arm.point_masses) if pm.link == i]
        for name, m, r, inertia in parts:
            P = joint.locatenew(f"{name}o", r * A.x)
            P.v2pt_theory(joint, N, A)
            if inertia == 0:
                body = me.Particle(name, P, m)
            else:
                body = me.RigidBody(name, P, A, m, (me.inertia(A, 0, 0, inertia), P))
            if kane:
                loads.append((P, -m * g * N.y))
            else:
                body.potential_energy = m * g * P.pos_from(origin).dot(N.y)
            bodies.append(body)
        nxt = joint.locatenew(f"J{i + 2}", _exact(link.length) * A.x)
        nxt.v2pt_theory(joint, N, A)
        parent, joint = A, nxt
    if kane:
        km = me.KanesMethod(N, q_ind=q, u_ind=speeds, kd_eqs=[qi.diff() - ui for qi, ui in zip(q, speeds)])
        km.kanes_equations(bodies, loads)
        return km.mass_matrix, -km.forcing, q, speeds
    lm = me.LagrangesMethod(me.Lagrangian(N, *bodies), q, frame=N)
    lm.form_lagranges_equations()
    return lm.mass_matrix, -lm.forcing, q, speeds


@dataclass(frozen=True)
class Form:
    """One form's J and G of an arm in the symbols of our Dynamics, values put in."""

    seconds: float
    runs: int
    J: sp.Matrix
    G: sp.Matrix

    @property
    def ops(self) -> int:
        """Operations of J and G after CSE (derive.dynamics.identities.count_ops_cse)."""
        return count_ops_cse(list(self.J) + list(self.G))


def cold(fn: Callable[[], T]) -> Callable[[], T]:
    """``fn`` run with SymPy's cache emptied first, so repeats do not reuse earlier work."""
    def run() -> T:
        clear_cache()
        return fn()
    return run


def timed(fn: Callable[[], T]) -> tuple[float, int, T]:
    """Best of up to REPEAT cold runs of ``fn``, fewer once the runs took BUDGET seconds."""
    runs, best, result, total = 0, float("inf"), None, 0.0
    while runs < REPEAT and (runs == 0 or total < BUDGET):
        t, result = best_of(cold(fn), 1)
        best, total, runs = min(best, t), total + t, runs + 1
    return best, runs, result


def recursive_J_G(arm: Arm) -> tuple[sp.Matrix, sp.Matrix]:
    """J and G alone by the recursive form (CRBA, RNEA at theta'' = 0, damping), without
    the rest of derive_dynamics (Coriolis matrix, gravity vector): the work Kane does."""
    chain = arm.chain
    n, s = chain.n, JointSymbols.make(chain.n)
    motors = chain_motor_terms(chain.actuators, n)
    fr = frames(chain, s.theta)
    bodies = base_parameters(chain.bodies, chain.joints)
    J = crba(composites(bodies, fr), fr, motors.reflected)
    bias = rnea(bodies, fr, s.dtheta, [ZERO] * n, vec(chain.gravity))
    return J, bias + motors.damping * sp.Matrix(s.dtheta)


def ours(arm: Arm) -> tuple[Form, Dynamics, float]:
    """The recursive form: derive_dynamics timed (its J, G with the arm's values put
    in) and the time of J and G alone (checked equal to derive_dynamics')."""
    t, runs, dyn = timed(lambda: derive_dynamics(arm))
    t_core, _, (J, G) = timed(lambda: recursive_J_G(arm))
    assert J == dyn.J and G == dyn.G, f"{arm.name}: recursive_J_G differs from derive_dynamics"
    values = dyn.subs
    return Form(t, runs, matrix_xreplace(dyn.J, values), matrix_xreplace(dyn.G, values)), dyn, t_core


def mechanics(arm: Arm, dyn: Dynamics, kane: bool) -> Form:
    """Kane's or Lagrange's J and G, timed, plus the motor terms, in our state symbols."""
    t, runs, (M, F, q, speeds) = timed(lambda: mechanics_model(arm, kane))
    s = dyn.sym
    rename = {**dict(zip(speeds, s.dtheta)), **dict(zip(q, s.theta))}  # xreplace: q_i' before q_i
    M, F = M.xreplace(rename), F.xreplace(rename)
    left = (M.free_symbols | F.free_symbols) - set(s.theta + s.dtheta)
    left |= M.atoms(AppliedUndef, sp.Derivative) | F.atoms(AppliedUndef, sp.Derivative)
    assert not left, f"{arm.name}: the mechanics matrices still hold {left}"
    reflected, damping = motor_terms(arm)
    J = M + reflected
    G = F + damping * sp.Matrix(s.dtheta)
    return Form(t, runs, J, G)


def motor_terms(arm: Arm) -> tuple[sp.Matrix, sp.Matrix]:
    """diag(gr^2 Jm) (reflected rotor inertia) and diag(gr^2 Kt Kv / Ra + bv), from the arm."""
    reflected = [_exact(m.gear_ratio ** 2 * m.rotor_inertia) for m in arm.motors]
    damping = [_exact(m.gear_ratio ** 2 * m.torque_constant * m.voltage_constant / m.resistance
                      + link.viscous_friction) for m, link in zip(arm.motors, arm.links)]
    return sp.diag(*reflected), sp.diag(*damping)


def check_same(name: str, arm: Arm, dyn: Dynamics, mine: Form, other: Form) -> None:
    """Assert ``other``'s J and G equal ours at one state (a wrong model fails loudly)."""
    s = dyn.sym
    angles = [sp.Rational(3, 10) * (-1) ** i * (i + 1) for i in range(arm.n)]
    rates = [sp.Rational(7, 10) - sp.Rational(4, 10) * i for i in range(arm.n)]
    state = {x: sp.Float(v, 30) for x, v in zip(s.theta + s.dtheta, angles + rates)}
    for label, a, b in (("J", mine.J, other.J), ("G", mine.G, other.G)):
        diff = (a - b).xreplace(state).evalf(30)
        scale = max(abs(x) for x in a.xreplace(state).evalf(30))
        worst = max(abs(x) for x in diff)
        assert worst <= 1e-20 * scale, (
            f"{name} model of {arm.name} (n = {arm.n}): its {label} differs from derive_dynamics' "
            f"at theta, theta' = {[float(state[x]) for x in s.theta + s.dtheta]} by {float(worst):.3g} "
            f"(scale {float(scale):.3g}): the mechanics model or the recursive form is wrong")



@dataclass(frozen=True)
class Row:
    """The three forms of one arm: ours (and the time of J, G alone), Kane's, Lagrange's."""

    label: str
    arm: Arm
    ours: Form
    core_seconds: float
    kane: Form
    lagrange: Form

    def cells(self) -> list[object]:
        """The table cells of this row."""
        def when(form: Form) -> str:
            return seconds(form.seconds) + ("" if form.runs == REPEAT else f" ({form.runs}x)")
        return [self.label, self.arm.n, when(self.ours), seconds(self.core_seconds), self.ours.ops,
                when(self.kane), self.kane.ops, when(self.lagrange), self.lagrange.ops,
                f"{self.kane.seconds / self.ours.seconds:.1f}x",
                f"{self.kane.seconds / self.core_seconds:.0f}x"]


HEADERS = ("arm", "n", "ours: derive_dynamics", "ours: J, G alone", "ours ops", "Kane time", "Kane ops",
           "Lagrange time", "Lagrange ops", "Kane / derive_dynamics", "Kane / J, G alone")


def measure(label: str, arm: Arm) -> Row:
    """Derive ``arm`` three ways; Kane and Lagrange are checked against ours."""
    mine, dyn, core = ours(arm)
    kane = mechanics(arm, dyn, kane=True)
    check_same("KanesMethod", arm, dyn, mine, kane)
    lagrange = mechanics(arm, dyn, kane=False)
    check_same("LagrangesMethod", arm, dyn, mine, lagrange)
    return Row(label, arm, mine, core, kane, lagrange)


def goals(default: Row, big: Row) -> tuple[Goal, ...]:
    """The stated targets: the default arm's time; the largest chain against Kane."""
    n = big.arm.n
    speedup, core_speedup = big.kane.seconds / big.ours.seconds, big.kane.seconds / big.core_seconds
    return (
        Goal(f"default arm derived (derive_dynamics) in under {DEFAULT_GOAL} s",
             default.ours.seconds < DEFAULT_GOAL, seconds(default.ours.seconds)),
        Goal(f"n = {n}: derive_dynamics at least {SPEEDUP_GOAL:g}x faster than KanesMethod",
             speedup >= SPEEDUP_GOAL, f"{speedup:.1f}x"),
        Goal(f"n = {n}: J and G alone at least {SPEEDUP_GOAL:g}x faster than KanesMethod",
             core_speedup >= SPEEDUP_GOAL, f"{core_speedup:.0f}x"),
        Goal(f"n = {n}: fewer operations in J, G than KanesMethod's", big.ours.ops < big.kane.ops,
             f"{big.ours.ops} vs {big.kane.ops}"),
    )


def run() -> Section:
    """The table for the default arm and the chains, the pipeline time and the goals."""
    default_arm = derive.load_arm()
    default = measure(f"{default_arm.name} (default)", default_arm)
    rows = [default] + [measure(f"chain{n}", chain(n)) for n in CHAINS]
    pipeline, _, _ = timed(lambda: derive.derive(default_arm))
    note = (
        f"Times: best of {REPEAT} runs, each with SymPy's cache cleared (fewer runs, shown as (kx), "
        f"once they took {BUDGET:g} s). derive_dynamics also builds the gravity vector and the motor "
        "terms (the Coriolis matrix is computed on first use); 'J, G alone' is its CRBA + RNEA part, "
        "the work Kane and Lagrange do. ops: count_ops of J and G after CSE, arm values put in (a rational "
        "constant one literal). Chains have g = 9.81, "
        f"the default arm g = {float(default_arm.gravity):g}. Kane's and Lagrange's J and G agree "
        "with ours at a sampled state (asserted).\n\n"
        f"Full pipeline `derive.derive(derive.load_arm())` (dynamics, predictive law, observer, "
        f"NPID form), in-process after imports: {seconds(pipeline)} (best of {REPEAT}, cold cache).")
    return Section(TITLE, (table(HEADERS, [r.cells() for r in rows]), note), goals(default, rows[-1]))
