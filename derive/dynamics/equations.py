"""Arm dynamics J(q) q'' + G(q, q') = B (u + d) of any serial chain (eq. 11-12).

The code is built from the recursive form: J by the composite-rigid-body
algorithm (:mod:`derive.dynamics.crba`), the bias (Coriolis, centrifugal and
gravity torques) and the gravity vector by the recursive Newton-Euler
algorithm (:mod:`derive.dynamics.rnea`) over the :class:`derive.model.chain.Chain`,
plus the motor terms (:mod:`derive.dynamics.motors`). The reference it is
proved equal to is the Euler-Lagrange form of :mod:`derive.dynamics.lagrange`.
Everything is in the chain's parameter symbols (so generated code may take
them at run time); :attr:`Dynamics.values` gives their exact values.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import sympy as sp

from derive.dynamics.coriolis import coriolis_matrix
from derive.dynamics.crba import composites, crba, gravity_torques
from derive.dynamics.motors import motor_terms
from derive.dynamics.regroup import base_parameters
from derive.dynamics.rnea import rnea
from derive.dynamics.spatial import ZERO, JointFrame, vec
from derive.model.chain import Chain
from derive.model.symbols import JointSymbols


@dataclass(frozen=True)
class Dynamics:
    """Symbolic dynamics of an n-joint chain, in its parameter symbols.

    J: n x n inertia matrix (eq. 12) with the reflected rotor inertia;
    bias: n x 1 Coriolis, centrifugal and gravity forces [N m or N];
    gravity: n x 1 g(q); damping: n x n motor and viscous damping;
    G = bias + damping q' (n x 1); B: n x n input matrix (eq. 12);
    coriolis: n x n C(q, q') (Christoffel), computed on first use, with
    coriolis q' = bias - gravity. ``sym.theta`` are the joint coordinates q
    (an angle [rad] for a revolute joint, a displacement [m] for a prismatic one).
    """

    sym: JointSymbols
    chain: Chain
    J: sp.Matrix
    bias: sp.Matrix
    damping: sp.Matrix
    G: sp.Matrix
    B: sp.Matrix
    gravity: sp.Matrix

    @property
    def n(self) -> int:
        return self.chain.n

    @property
    def values(self) -> tuple[tuple[sp.Symbol, sp.Rational], ...]:
        """(symbol, exact value) of every parameter, in the chain's canonical order."""
        return tuple((p.symbol, p.rational) for p in self.chain.parameters)

    @property
    def subs(self) -> dict[sp.Symbol, sp.Rational]:
        """symbol -> exact value, for ``expr.xreplace``."""
        return dict(self.values)

    @property
    def angles(self) -> tuple[sp.Symbol, ...]:
        """The coordinates of the revolute and continuous joints (those under sin/cos)."""
        return tuple(q for q, j in zip(self.sym.theta, self.chain.joints) if j.type.rotates)

    @cached_property
    def coriolis(self) -> sp.Matrix:
        """n x n Coriolis matrix C(q, q') (Christoffel symbols), computed on first use."""
        bodies = base_parameters(self.chain.bodies, self.chain.joints)
        return coriolis_matrix(bodies, frames(self.chain, self.sym.theta), self.sym.dtheta)


def frames(chain: Chain, q) -> tuple[JointFrame, ...]:
    """Every joint's transform at the coordinates q."""
    return tuple(JointFrame.of(j, qi) for j, qi in zip(chain.joints, q))


def chain_dynamics(chain: Chain) -> Dynamics:
    """J (CRBA), bias and g (RNEA), motor terms of ``chain`` (eq. 11-12).

    Raises DerivationError when the chain does not have one actuator per joint.
    """
    n = chain.n
    s = JointSymbols.make(n)
    motors = motor_terms(chain.actuators, n)
    fr = frames(chain, s.theta)
    grav = vec(chain.gravity)
    zero = [ZERO] * n
    bodies = base_parameters(chain.bodies, chain.joints)
    comp = composites(bodies, fr)
    J = crba(comp, fr, motors.reflected)
    gravity = gravity_torques(comp, fr, grav)
    bias = rnea(bodies, fr, s.dtheta, zero, grav)
    G = bias + motors.damping * sp.Matrix(s.dtheta)
    return Dynamics(sym=s, chain=chain, J=J, bias=bias, damping=motors.damping, G=G, B=motors.B,
                    gravity=gravity)
