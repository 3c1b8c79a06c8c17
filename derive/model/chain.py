"""The normalised kinematic chain that every arm input becomes.

A planar arm file, a DH table and a URDF all load into one :class:`Chain`;
the dynamics (:mod:`derive.dynamics`) read nothing else.

Frames and conventions (URDF's, so that a URDF maps one to one):

* The base frame is frame 0. Moving joint i (1-based) has a frame F_i fixed to
  body i, the rigid body that joint i moves (with everything rigidly attached
  to it: links merged over fixed joints, carried motors, point masses).
* ``origin`` of joint i is the fixed transform from F_{i-1} (the base for
  i = 1) to F_i at q_i = 0: a point x given in F_i is ``R x + p`` in F_{i-1}
  (URDF's ``<origin xyz rpy>``, R = Rz(yaw) Ry(pitch) Rx(roll)).
* The joint moves F_i about (revolute, continuous) or along (prismatic) its
  unit ``axis``, given in F_i: F_{i-1} <- F_i is ``origin * Rot(axis, q_i)``
  or ``origin * Trans(axis * q_i)``. A continuous joint is one angle q_i.
* Body i is described in F_i by its mass m, first moment h = m c (c: the
  centre of mass in F_i) and rotational inertia I_o about F_i's origin
  (I_o = I_c + m (|c|^2 1 - c c^T), I_c about the centre of mass and already
  rotated into F_i as R I_c R^T). These are SymPy expressions in parameter
  symbols (so a runtime parameter changes everything derived from it).
* ``gravity`` is the acceleration of free fall in the base frame (e.g.
  (0, -g, 0) for a planar arm whose gravity acts along -y).
* ``actuators[i]`` drives joint i (:class:`Actuator`): the input u_i is a motor
  voltage (the paper's DC motor, eq. 11-12) or a motor torque (section 4.1).

Entries are exact (SymPy Integers, Rationals, and exact values such as
cos(pi/3)) wherever the input is exact; parameter symbols stand for the
values in :attr:`Chain.parameters`.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from fractions import Fraction

import sympy as sp


class JointType(str, Enum):
    """The moving joints a chain may have (URDF names)."""

    REVOLUTE = "revolute"
    CONTINUOUS = "continuous"   # a revolute joint without limits: one angle, not a cos/sin pair
    PRISMATIC = "prismatic"

    @property
    def rotates(self) -> bool:
        return self is not JointType.PRISMATIC


@dataclass(frozen=True)
class Parameter:
    """One physical value of the arm, named once.

    symbol: the SymPy symbol the derivation uses (its name is the C and Python
    field of a runtime parameter struct: a plain identifier such as ``m2``);
    value: the exact value the input gave; unit: SI unit (``kg``, ``m``,
    ``kg m^2``, ``N m/A``, ``""`` for a ratio); field: where the input gave it
    (``link[2].mass``, ``urdf link 'forearm' <inertial><mass>``); doc: a short
    description for generated headers.
    """

    symbol: sp.Symbol
    value: Fraction
    unit: str
    field: str
    doc: str

    @property
    def rational(self) -> sp.Rational:
        return sp.Rational(self.value.numerator, self.value.denominator)


@dataclass(frozen=True)
class Transform:
    """A rigid transform: x_parent = R x_child + p (R 3 x 3 rotation, p 3 x 1)."""

    R: sp.ImmutableMatrix
    p: sp.ImmutableMatrix

    @staticmethod
    def identity() -> "Transform":
        return Transform(sp.ImmutableMatrix.eye(3), sp.ImmutableMatrix.zeros(3, 1))

    def compose(self, child: "Transform") -> "Transform":
        """self * child: the child's frame expressed through this one."""
        return Transform(sp.ImmutableMatrix(self.R * child.R), sp.ImmutableMatrix(self.R * child.p + self.p))


@dataclass(frozen=True)
class Limits:
    """Joint limits as the input stated them (None: not stated). Units: rad or
    m for position, rad/s or m/s for velocity, N m or N for effort."""

    lower: Fraction | None = None
    upper: Fraction | None = None
    velocity: Fraction | None = None
    effort: Fraction | None = None


@dataclass(frozen=True)
class Joint:
    """Moving joint i: its name in the input, type, fixed origin, unit axis, limits."""

    name: str
    type: JointType
    origin: Transform
    axis: sp.ImmutableMatrix   # 3 x 1, unit length, in the joint's own frame
    limits: Limits
    field: str                 # where the input describes it ("link[2]", "urdf joint 'elbow'")


@dataclass(frozen=True)
class Body:
    """Rigid body moved by one joint, in that joint's frame.

    mass: m [kg]; first_moment: h = m c (3 x 1) [kg m]; inertia: I_o about the
    frame's origin (3 x 3, symmetric) [kg m^2]. Expressions in parameter symbols.
    """

    mass: sp.Expr
    first_moment: sp.ImmutableMatrix
    inertia: sp.ImmutableMatrix


class Actuation(str, Enum):
    """What the input u_i of a joint is."""

    VOLTAGE = "voltage"   # armature voltage of a DC motor, inductance neglected (the paper's model)
    TORQUE = "torque"     # motor torque before the gear (section 4.1 allows u to be a torque)


@dataclass(frozen=True)
class Actuator:
    """The drive of one moving joint, in parameter symbols.

    A motor behind a gear of ratio gr (joint torque = gr x motor torque,
    motor speed = gr x joint speed), rotor inertia Jm (reflected as gr^2 Jm
    onto the joint), viscous joint friction bv [N m s/rad, or N s/m for a
    prismatic joint]. VOLTAGE: torque constant Kt [N m/A], back-EMF constant
    Kv [V s/rad], armature resistance Ra [ohm], so the joint torque is
    gr Kt (u - gr Kv q') / Ra: B_ii = gr Kt / Ra, damping gr^2 Kt Kv / Ra + bv.
    TORQUE: the three are None; B_ii = gr, damping bv.
    """

    actuation: Actuation
    gear_ratio: sp.Expr
    rotor_inertia: sp.Expr
    viscous_friction: sp.Expr
    torque_constant: sp.Expr | None = None
    voltage_constant: sp.Expr | None = None
    resistance: sp.Expr | None = None


@dataclass(frozen=True)
class Chain:
    """A serial chain of n >= 1 moving joints from a base to a tip.

    joints[i] moves bodies[i] and is driven by actuators[i]; gravity: 3 x 1 in
    the base frame [m/s^2]; parameters: every symbol the joints, bodies,
    actuators and gravity use, in canonical order, with its value; notes: what
    normalisation did to the input (axes normalised, fixed joints merged,
    off-chain joints locked), one sentence each, for the user. For a chain read
    from a file (URDF, MJCF), what a plant integrating that file must do to be
    this chain (derive.sim.mujoco): ``held``, every moving joint of the file that
    is not a chain joint, with the value it is held at [rad or m] (locked, a
    mimic's rule, else 0); ``repaired``, the links whose inertia derive repaired,
    with the tensor used (ixx, ixy, ixz, iyy, iyz, izz about the centre of mass,
    in the inertial frame) [kg m^2]. ``tip``: the tip link's frame expressed in F_n (where a
    payload's centre of mass is given, derive.model.payload), None when it is F_n itself.
    """

    joints: tuple[Joint, ...]
    bodies: tuple[Body, ...]
    gravity: sp.ImmutableMatrix
    parameters: tuple[Parameter, ...]
    notes: tuple[str, ...] = ()
    actuators: tuple[Actuator, ...] = ()
    held: tuple[tuple[str, float], ...] = ()
    repaired: tuple[tuple[str, tuple[Fraction, ...]], ...] = ()
    tip: Transform | None = None   # the tip link's frame in F_n (a URDF's fixed joints below the last moving one); None: F_n

    @property
    def n(self) -> int:
        return len(self.joints)

    @property
    def planar(self) -> bool:
        """Every axis is +z, every origin a rotation about z with p_z = 0, and
        no body has a z first moment or xz/yz products: motion in the xy plane."""
        z = sp.ImmutableMatrix([0, 0, 1])
        for j, b in zip(self.joints, self.bodies):
            R, p = j.origin.R, j.origin.p
            if j.type is JointType.PRISMATIC or j.axis != z or p[2] != 0:
                return False
            if R[2, 2] != 1 or R[0, 2] != 0 or R[1, 2] != 0:
                return False
            if b.first_moment[2] != 0 or b.inertia[0, 2] != 0 or b.inertia[1, 2] != 0:
                return False
        return self.gravity[2] == 0

    def values(self) -> dict[sp.Symbol, sp.Rational]:
        """symbol -> exact value, for ``expr.xreplace``."""
        return {p.symbol: p.rational for p in self.parameters}
