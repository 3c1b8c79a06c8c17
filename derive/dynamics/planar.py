"""Arm dynamics J(theta) theta'' + G(theta, theta') = B (u + d)  (eq. 11-12).

Two forms, proved equal (tests; ``derive check``):

* the reference: Euler-Lagrange equations of the arm's Lagrangian, the form
  the paper uses; expanded, it grows fast with n and serves as an oracle;
* the recursive form the code is built from: a planar composite-rigid-body
  pass for J and a planar recursive Newton-Euler pass (theta'' = 0) for the
  Coriolis, centrifugal and gravity bias. Each body is lumped to (M, hx, Io):
  total mass, first moment along the link and inertia about its joint.

The drives are the arm's actuators (derive.model.actuators): B = diag(gain),
G gains diag(damping) theta' and J gains diag(reflected_inertia); for DC
motors (inductance neglected) tau = gr Kt (u - gr Kv theta') / Ra, so
B = diag(gr Kt / Ra) and damping gr^2 Kt Kv / Ra + bv; rotor inertia enters as
gr^2 Jm (the rotor's gyroscopic coupling with the carrying link is neglected).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import sympy as sp

from derive.dynamics.identities import matrix_is_zero
from derive.model.actuators import terms
from derive.model.spec import Arm
from derive.model.symbols import JointSymbols, ParamSymbols
from derive.summary import compact_repr


@dataclass(frozen=True)
class Body:
    """Planar rigid body in its link frame (origin at its joint, x along the link)."""

    M: sp.Expr   # total mass
    hx: sp.Expr  # first moment of mass along x (M times the centre-of-mass distance)
    Io: sp.Expr  # moment of inertia about the joint


@compact_repr
@dataclass(frozen=True)
class Dynamics:
    """Symbolic dynamics in the parameter symbols of ``params`` (shapes for n joints).

    J: n x n inertia matrix (recursive form), bias: n x 1 Coriolis, centrifugal
    and gravity torques, damping: n x n back-EMF and viscous damping,
    G = bias + damping theta' (n x 1), B: n x n input matrix (eq. 12),
    coriolis: n x n Christoffel matrix with coriolis theta' = velocity part of bias,
    gravity: n x 1. The Euler-Lagrange reference is :func:`lagrange_reference`.
    """

    sym: JointSymbols
    params: ParamSymbols
    bodies: tuple[Body, ...]
    J: sp.Matrix
    bias: sp.Matrix
    damping: sp.Matrix
    G: sp.Matrix
    B: sp.Matrix
    gravity: sp.Matrix

    @cached_property
    def coriolis(self) -> sp.Matrix:
        """n x n Christoffel matrix C(theta, theta'), computed on first use."""
        return christoffel(self.J, self.sym.theta, self.sym.dtheta)


def lumped_bodies(arm: Arm, p: ParamSymbols) -> tuple[Body, ...]:
    """(M, hx, Io) of each link with the point masses it carries."""
    bodies = []
    for i in range(arm.n):
        M = p.mass[i]
        hx = p.mass[i] * p.com[i]
        Io = p.inertia[i] + p.mass[i] * p.com[i] ** 2
        for k, pm in enumerate(arm.point_masses):
            if pm.link == i:
                M += p.pm_mass[k]
                hx += p.pm_mass[k] * p.pm_distance[k]
                Io += p.pm_inertia[k] + p.pm_mass[k] * p.pm_distance[k] ** 2
        bodies.append(Body(M, hx, Io))
    return tuple(bodies)


def _rot(theta: sp.Symbol, v: tuple[sp.Expr, sp.Expr]) -> tuple[sp.Expr, sp.Expr]:
    """Vector v of a child frame (rotated by theta) expressed in its parent frame."""
    c, s = sp.cos(theta), sp.sin(theta)
    return c * v[0] - s * v[1], s * v[0] + c * v[1]


def _rot_t(theta: sp.Symbol, v: tuple[sp.Expr, sp.Expr]) -> tuple[sp.Expr, sp.Expr]:
    """Vector v of a parent frame expressed in the child frame rotated by theta."""
    c, s = sp.cos(theta), sp.sin(theta)
    return c * v[0] + s * v[1], -s * v[0] + c * v[1]


def crba(bodies: tuple[Body, ...], q, lengths, reflected) -> sp.Matrix:
    """Planar composite-rigid-body algorithm: the n x n inertia matrix J(q).

    Composite (M, h, Io) of the subtree from joint j, in frame j; column j of J
    is the torque at each joint i <= j that unit acceleration of joint j needs.
    """
    n = len(bodies)
    J = sp.zeros(n, n)
    comp: list = [None] * n
    for j in reversed(range(n)):
        b = bodies[j]
        M, h, Io = b.M, (b.hx, sp.Integer(0)), b.Io
        if j + 1 < n:  # child composite at (l_j, 0), rotated by q[j+1]
            cM, ch, cIo = comp[j + 1]
            rh = _rot(q[j + 1], ch)
            l = lengths[j]
            M = M + cM
            h = (h[0] + rh[0] + cM * l, h[1] + rh[1])
            Io = Io + cIo + 2 * l * rh[0] + cM * l ** 2
        comp[j] = (M, h, Io)
    for j in range(n):
        M, h, Io = comp[j]
        F = (-h[1], h[0])          # force of the subtree under unit acceleration of joint j
        nmom = Io
        J[j, j] = Io + reflected[j]
        for i in reversed(range(j)):
            F = _rot(q[i + 1], F)
            nmom = nmom + lengths[i] * F[1]
            J[i, j] = J[j, i] = nmom
    return J


def rnea(bodies: tuple[Body, ...], q, dq, ddq, lengths, g, down=(0, -1)) -> sp.Matrix:
    """Planar recursive Newton-Euler inverse dynamics (rigid part, no motor terms).

    Returns tau (n x 1) with tau = J_rigid ddq + bias; gravity g acts along the
    unit vector ``down`` of the base frame (default -y), put in as an
    acceleration -g down of the base.
    """
    n = len(bodies)
    w = a = sp.Integer(0)
    acc = (-g * down[0], -g * down[1])  # acceleration of the current joint's origin, current frame
    forces, moments = [], []
    for i in range(n):
        if i > 0:
            l = lengths[i - 1]
            acc = (acc[0] - w ** 2 * l, acc[1] + a * l)
        acc = _rot_t(q[i], acc)
        w, a = w + dq[i], a + ddq[i]
        b = bodies[i]
        f = (b.M * acc[0] - w ** 2 * b.hx, b.M * acc[1] + a * b.hx)
        forces.append(f)
        moments.append(b.Io * a + b.hx * acc[1])
    tau = [sp.Integer(0)] * n
    F, N = (sp.Integer(0), sp.Integer(0)), sp.Integer(0)
    for i in reversed(range(n)):
        if i + 1 < n:
            F = _rot(q[i + 1], F)
            N = N + lengths[i] * F[1]
        F = (forces[i][0] + F[0], forces[i][1] + F[1])
        N = moments[i] + N
        tau[i] = N
    return sp.Matrix(tau)


def _down(arm: Arm) -> tuple[sp.Expr, sp.Expr]:
    """The unit direction of free fall in the base plane (arm.gravity_direction, normalised)."""
    g = arm.chain.gravity
    symbol = next(p.symbol for p in arm.chain.parameters if p.field == "arm.gravity")
    return sp.expand(g[0] / symbol), sp.expand(g[1] / symbol)


def lagrange(arm: Arm, s: JointSymbols, p: ParamSymbols) -> tuple[sp.Matrix, sp.Matrix]:
    """Reference J and rigid G (Coriolis, centrifugal, gravity) from the Lagrangian.

    Kinetic energy of every link and point mass (translation of the centre of
    mass, rotation at the absolute angle rate) and potential energy g y.
    """
    n = arm.n
    q, dq = s.theta, s.dtheta
    phi = [sum(q[: i + 1]) for i in range(n)]
    joint = [(sp.Integer(0), sp.Integer(0))]
    for i in range(n):
        x, y = joint[-1]
        joint.append((x + p.length[i] * sp.cos(phi[i]), y + p.length[i] * sp.sin(phi[i])))
    down = _down(arm)
    masses = [(p.mass[i], i, p.com[i], p.inertia[i]) for i in range(n)]
    masses += [(p.pm_mass[k], pm.link, p.pm_distance[k], p.pm_inertia[k])
               for k, pm in enumerate(arm.point_masses)]
    T = V = sp.Integer(0)
    for m, i, r, inertia in masses:
        x = joint[i][0] + r * sp.cos(phi[i])
        y = joint[i][1] + r * sp.sin(phi[i])
        vx = sum(sp.diff(x, qj) * dqj for qj, dqj in zip(q, dq))
        vy = sum(sp.diff(y, qj) * dqj for qj, dqj in zip(q, dq))
        wi = sum(dq[: i + 1])
        T += m * (vx ** 2 + vy ** 2) / 2 + inertia * wi ** 2 / 2
        V -= m * p.g * (down[0] * x + down[1] * y)
    T += sum(terms(a)[2] * dq[i] ** 2 for i, a in enumerate(arm.actuators)) / 2
    dT = sp.Matrix([sp.diff(T, v) for v in dq])
    J = dT.jacobian(dq).applyfunc(sp.expand)
    G = dT.jacobian(q) * sp.Matrix(dq) - sp.Matrix([sp.diff(T - V, v) for v in q])
    return J, G.applyfunc(sp.expand)


def christoffel(J: sp.Matrix, q, dq) -> sp.Matrix:
    """Coriolis matrix C(q, dq) from the Christoffel symbols of J, so that
    J' - 2C is skew-symmetric: C_kj = sum_i 1/2 (dJ_kj/dq_i + dJ_ki/dq_j - dJ_ij/dq_k) dq_i."""
    n = J.rows
    dJ = [J.diff(qi) for qi in q]
    C = sp.zeros(n, n)
    for k in range(n):
        for j in range(n):
            C[k, j] = sum((dJ[i][k, j] + dJ[j][k, i] - dJ[k][i, j]) * dq[i] for i in range(n)) / 2
    return C


def derive_dynamics(arm: Arm) -> Dynamics:
    """Symbolic dynamics of ``arm`` in its parameter symbols (eq. 11-12)."""
    n = arm.n
    s = JointSymbols.make(n)
    p = ParamSymbols.make(arm)
    bodies = lumped_bodies(arm, p)
    if arm.spatial is not None:
        from derive.errors import DerivationError
        raise DerivationError(f"arm {arm.name}: the planar dynamics take [[link]] arms only; a DH or URDF "
                              "chain needs the spatial dynamics")
    drives = [terms(a) for a in arm.actuators]
    reflected = [t[2] for t in drives]
    J = crba(bodies, s.theta, p.length, reflected)
    zero = [sp.Integer(0)] * n
    down = _down(arm)
    bias = rnea(bodies, s.theta, s.dtheta, zero, p.length, p.g, down)
    gravity = rnea(bodies, s.theta, zero, zero, p.length, p.g, down)
    damping = sp.diag(*[t[1] for t in drives])
    G = bias + damping * sp.Matrix(s.dtheta)
    B = sp.diag(*[t[0] for t in drives])
    return Dynamics(sym=s, params=p, bodies=bodies, J=J, bias=bias, damping=damping, G=G, B=B,
                    gravity=gravity)


def lagrange_reference(arm: Arm, dyn: Dynamics) -> tuple[sp.Matrix, sp.Matrix]:
    """(J, G) of the Euler-Lagrange equations, in the symbols of ``dyn``: the
    reference form (eq. 11-12) the recursive form is proved equal to."""
    J, G_rigid = lagrange(arm, dyn.sym, dyn.params)
    return J, G_rigid + dyn.damping * sp.Matrix(dyn.sym.dtheta)


def lumped_2link(dyn: Dynamics) -> dict[str, sp.Expr]:
    """The paper's inertial parameters j1, j2, j3, X of eq. (a6), for n = 2.

    Read off J at theta2 = pi/2 and 0, then J is checked to have exactly the
    form [[j1 + 2X cos t2, j2 + X cos t2], [j2 + X cos t2, j3]]; a DerivationError
    otherwise.
    """
    from derive.errors import DerivationError

    t2 = dyn.sym.theta[1]
    J = dyn.J
    at = {t2: sp.pi / 2}
    lumped = {"j1": J[0, 0].subs(at), "j2": J[0, 1].subs(at), "j3": J[1, 1].subs(at),
              "X": sp.expand(J[0, 1].subs(t2, 0) - J[0, 1].subs(at))}
    if not matrix_is_zero(J - a6_form(lumped, t2), dyn.sym.theta):
        raise DerivationError("the 2-link inertia matrix does not have the form (a6)")
    return {k: sp.expand(v) for k, v in lumped.items()}


def a6_form(lumped: dict[str, sp.Expr], theta2: sp.Symbol) -> sp.Matrix:
    """J(theta) of eq. (a6) from j1, j2, j3, X."""
    c = sp.cos(theta2)
    j1, j2, j3, X = (lumped[k] for k in ("j1", "j2", "j3", "X"))
    return sp.Matrix([[j1 + 2 * X * c, j2 + X * c], [j2 + X * c, j3]])
