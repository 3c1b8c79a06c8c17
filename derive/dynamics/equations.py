"""Arm dynamics J(q) q'' + G(q, q') = B (u + d) of any serial chain (eq. 11-12).

The code is built from the recursive form over the arm's
:class:`derive.model.chain.Chain`, in its base parameters
(:mod:`derive.dynamics.regroup`): J by the composite-rigid-body algorithm and
g(q) from the same composite bodies (:mod:`derive.dynamics.crba`), the bias
(Coriolis, centrifugal and gravity forces) by the recursive Newton-Euler
algorithm (:mod:`derive.dynamics.rnea`), the Coriolis matrix on demand
(:mod:`derive.dynamics.coriolis`), plus the motor terms
(:mod:`derive.dynamics.motors`). The reference it is proved equal to is the
Euler-Lagrange form (:func:`lagrange_reference`). Everything is in the
chain's parameter symbols (generated code may take them at run time);
:attr:`Dynamics.values` gives their exact values. Entries are shared
subexpressions (a DAG): never expand or simplify them whole; walk them with
:mod:`derive.dynamics.program`.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import sympy as sp

from derive.dynamics.coriolis import coriolis_matrix
from derive.dynamics.crba import Composite, composites, crba, gravity_torques
from derive.dynamics.lagrange import lagrange_equations, reference_ring
from derive.dynamics.momentum import momentum_terms
from derive.dynamics.motors import motor_terms
from derive.dynamics.program import dag_xreplace
from derive.dynamics.regroup import base_parameters
from derive.dynamics.rnea import rnea
from derive.dynamics.spatial import ZERO, ZERO_VEC, JointFrame, mul, vec
from derive.model.chain import Chain
from derive.model.spec import Arm
from derive.model.symbols import JointSymbols
from derive.summary import compact_repr


@compact_repr
@dataclass(frozen=True)
class Dynamics:
    """Symbolic dynamics of an n-joint chain, in its parameter symbols.

    J: n x n inertia matrix (eq. 12) with the reflected rotor inertia;
    bias: n x 1 Coriolis, centrifugal and gravity forces [N m or N];
    gravity: n x 1 g(q); damping: n x n motor and viscous damping;
    G = bias + damping q' (n x 1); B: n x n input matrix (eq. 12);
    reflected: the n rotor inertias gr^2 Jm on J's diagonal. ``sym.theta``
    are the joint coordinates q (an angle [rad] for a revolute or continuous
    joint, a displacement [m] for a prismatic one).
    """

    sym: JointSymbols
    chain: Chain
    J: sp.Matrix
    bias: sp.Matrix
    damping: sp.Matrix
    G: sp.Matrix
    B: sp.Matrix
    gravity: sp.Matrix
    reflected: tuple[sp.Expr, ...]

    @property
    def n(self) -> int:
        return self.chain.n

    @property
    def values(self) -> tuple[tuple[sp.Symbol, sp.Rational], ...]:
        """(symbol, exact value) of every parameter, in the chain's canonical order."""
        return tuple((p.symbol, p.rational) for p in self.chain.parameters)

    @property
    def subs(self) -> dict[sp.Symbol, sp.Rational]:
        """symbol -> exact value, for ``xreplace``."""
        return dict(self.values)

    @property
    def angles(self) -> tuple[sp.Symbol, ...]:
        """The coordinates under sin/cos: those of the revolute and continuous joints."""
        return tuple(q for q, j in zip(self.sym.theta, self.chain.joints) if j.type.rotates)

    @cached_property
    def frames(self) -> tuple[JointFrame, ...]:
        """Every joint's transform at q = sym.theta."""
        return frames(self.chain, self.sym.theta)

    @cached_property
    def bodies(self) -> tuple[Composite, ...]:
        """The bodies in base parameters (what the recursions use)."""
        return base_parameters(self.chain.bodies, self.chain.joints)

    @cached_property
    def coriolis(self) -> sp.Matrix:
        """n x n Coriolis matrix C(q, q') (Christoffel-consistent: J' - 2C is
        skew-symmetric and C q' = bias - gravity), computed on first use."""
        return coriolis_matrix(self.bodies, self.frames, self.sym.dtheta)

    def inverse_dynamics(self, ddq) -> sp.Matrix:
        """n x 1 J(q) ddq + G(q, q') (eq. 12's left side at the accelerations ``ddq``,
        n expressions) by one recursive Newton-Euler pass, plus the motor terms:
        a law of the form J a + G without J or the product J a formed (about 1,100
        operations for the Panda where J a + G takes about 1,600)."""
        a = sp.Matrix(list(ddq))
        if a.shape != (self.n, 1):
            raise ValueError(f"inverse_dynamics: expected {self.n} accelerations, got {len(a)}")
        rigid = rnea(self.bodies, self.frames, self.sym.dtheta, list(a), vec(self.chain.gravity))
        reflected = sp.Matrix([mul(r, x) for r, x in zip(self.reflected, a)])
        return rigid + reflected + self.damping * sp.Matrix(self.sym.dtheta)

    @cached_property
    def momentum(self) -> tuple[sp.Matrix, sp.Matrix]:
        """(J(q) q', C(q, q')^T q'), n x 1 each: the generalized momentum (with the reflected
        rotor inertias) and the transposed Coriolis matrix times q', by one recursive pass
        (:mod:`derive.dynamics.momentum`), neither J nor C formed."""
        p, ct = momentum_terms(self.bodies, self.frames, self.sym.dtheta)
        rotor = sp.Matrix([mul(r, dq) for r, dq in zip(self.reflected, self.sym.dtheta)])
        return p + rotor, ct

    @cached_property
    def velocity_bias(self) -> sp.Matrix:
        """n x 1 C(q, q') q': the Coriolis and centrifugal forces alone (RNEA without gravity)."""
        return rnea(self.bodies, self.frames, self.sym.dtheta, [ZERO] * self.n, ZERO_VEC)


def frames(chain: Chain, q) -> tuple[JointFrame, ...]:
    """Every joint's transform at the coordinates q."""
    return tuple(JointFrame.of(j, qi) for j, qi in zip(chain.joints, q))


def chain_dynamics(chain: Chain) -> Dynamics:
    """J (CRBA), g (composites), bias (RNEA) and motor terms of ``chain`` (eq. 11-12).

    Raises DerivationError when the chain does not have one actuator per joint.
    """
    n = chain.n
    s = JointSymbols.make(n)
    motors = motor_terms(chain.actuators, n)
    fr = frames(chain, s.theta)
    grav = vec(chain.gravity)
    bodies = base_parameters(chain.bodies, chain.joints)
    comp = composites(bodies, fr)
    J = crba(comp, fr, motors.reflected)
    gravity = gravity_torques(comp, fr, grav)
    bias = rnea(bodies, fr, s.dtheta, [ZERO] * n, grav)
    G = bias + motors.damping * sp.Matrix(s.dtheta)
    return Dynamics(sym=s, chain=chain, J=J, bias=bias, damping=motors.damping, G=G, B=motors.B,
                    gravity=gravity, reflected=motors.reflected)


_LAST: list = []   # [(chain, its Dynamics)]: derive_dynamics' last result in this process


def derive_dynamics(arm: Arm) -> Dynamics:
    """Symbolic dynamics of ``arm`` (eq. 11-12), from its chain (:attr:`Arm.chain`). The last chain's
    dynamics are kept for the process: an equal chain (every joint, body, parameter value and drive) has the
    same, and ``derive init`` derives its arm twice (the draft it certifies W on, the file it states the
    sample-time limits of: 0.13 s each for a 7-joint arm)."""
    chain = arm.chain
    if _LAST and _LAST[0][0] == chain:
        return _LAST[0][1]
    dyn = chain_dynamics(chain)
    _LAST[:] = [(chain, dyn)]
    return dyn


def lagrange_reference(dyn: Dynamics, numeric: bool = False) -> tuple[sp.Matrix, sp.Matrix]:
    """(J, G) of the Euler-Lagrange equations of ``dyn``'s chain: the reference
    form (eq. 11-12) the recursive form is proved equal to. In its parameter
    symbols, expanded; ``numeric``: with the parameter values put in, unexpanded
    (sampled states of longer chains)."""
    values = dyn.subs if numeric else None
    J, G_rigid = lagrange_equations(dyn.chain, dyn.sym.theta, dyn.sym.dtheta, dyn.reflected, values)
    damping = dyn.damping.xreplace(values) if numeric else dyn.damping
    return J, G_rigid + damping * sp.Matrix(dyn.sym.dtheta)


def reference_mismatch(dyn: Dynamics, numeric: bool = False) -> str | None:
    """None when J and the bias of ``dyn`` equal the Euler-Lagrange reference
    identically in q, q' (and in the parameters unless ``numeric``): a proof,
    by canonical forms modulo sin^2 + cos^2 = 1 (:mod:`derive.dynamics.trigpoly`);
    else the first differing entry, named."""
    s = dyn.sym
    values = dyn.subs if numeric else None
    F, J_ref, G_ref = reference_ring(dyn.chain, s.theta, s.dtheta, dyn.reflected, values)
    n = dyn.n
    mine = list(dyn.J) + list(dyn.bias)
    if values:
        mine = dag_xreplace(mine, values)
    conv = F.convert(mine)
    for k, (got, want) in enumerate(zip(conv, [x for row in J_ref for x in row] + G_ref)):
        if got != want:
            return f"J[{k // n + 1}][{k % n + 1}]" if k < n * n else f"bias[{k - n * n + 1}]"
    return None
