"""The joint-space inertia matrix J(q) of a serial chain: composite-rigid-body algorithm.

Featherstone, *Rigid Body Dynamics Algorithms* (2008), section 6.2, in the
classical form: the composite body j (body j and everything it carries) is
described in frame F_j by its mass M, first moment h and rotational inertia I
about F_j's origin. Unit acceleration of joint j at rest (no gravity) makes
the composite exert, at F_j's origin,

* revolute, axis a: angular acceleration a, so force a x h and moment I a;
* prismatic, axis a: linear acceleration a, so force M a and moment h x a;

column j of J is that wrench carried down the chain to each joint i <= j and
projected on joint i's axis (eq. 12's J; J_ij = J_ji). Entries are built term
by term (:mod:`derive.dynamics.spatial`), never expanded.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import sympy as sp

from derive.dynamics.spatial import (Mat, Vec, add, cross, dot, keep_sums, mat, mat_add, mul, scale, shift_inertia, vec,
                                     JointFrame)
from derive.model.chain import Body


@dataclass(frozen=True)
class Composite:
    """A composite rigid body in its joint's frame: mass M [kg], first moment
    h = M c [kg m], rotational inertia I about the frame's origin [kg m^2]."""

    M: sp.Expr
    h: Vec
    I: Mat


def body_composite(body: Body) -> Composite:
    """The chain's body as a :class:`Composite` (tuples of expressions)."""
    return Composite(sp.sympify(body.mass), vec(body.first_moment), mat(body.inertia))


@keep_sums
def composites(bodies: Sequence[Composite], frames: Sequence[JointFrame]) -> list[Composite]:
    """Composite body of every joint, tip to base: body j plus composite j+1
    moved into F_j (rotated by R_{j+1}, shifted by p_{j+1})."""
    n = len(bodies)
    out: list[Composite] = list(bodies)
    for j in reversed(range(n - 1)):
        child, f = out[j + 1], frames[j + 1]
        h_child = f.to_parent(child.h)              # first moment about F_{j+1}'s origin, F_j axes
        I_child = shift_inertia(f.inertia_to_parent(child.I), child.M, h_child, f.p)
        own = out[j]
        out[j] = Composite(own.M + child.M, add(own.h, add(h_child, scale(child.M, f.p))),
                           mat_add(own.I, I_child))
    return out


def _unit_wrench(c: Composite, f: JointFrame) -> tuple[Vec, Vec]:
    """(force, moment) at F_j's origin of composite j under unit joint acceleration."""
    if f.rotates:
        return cross(f.axis, c.h), tuple(dot(row, f.axis) for row in c.I)  # type: ignore[return-value]
    return scale(c.M, f.axis), cross(c.h, f.axis)


def _project(f: JointFrame, force: Vec, moment: Vec) -> sp.Expr:
    """The generalized force of a wrench at joint F's origin: a.n or a.f."""
    return dot(f.axis, moment) if f.rotates else dot(f.axis, force)


@keep_sums
def gravity_torques(comp: Sequence[Composite], frames: Sequence[JointFrame], gravity: Vec) -> sp.Matrix:
    """g(q) (n x 1) from the composite bodies: gravity on composite i exerts the
    moment h_i x gravity and the force M_i gravity at F_i's origin, so
    g_i = a_i . (h_i x gamma_i) (revolute) or M_i a_i . gamma_i (prismatic),
    gamma_i = -gravity in F_i's axes (the base's upward acceleration)."""
    gamma = scale(-1, gravity)
    out = []
    for c, f in zip(comp, frames):
        gamma = f.to_child(gamma)
        out.append(dot(f.axis, cross(c.h, gamma)) if f.rotates else mul(c.M, dot(f.axis, gamma)))
    return sp.Matrix(out)


@keep_sums
def crba(comp: Sequence[Composite], frames: Sequence[JointFrame],
         reflected: Sequence[sp.Expr] | None = None) -> sp.Matrix:
    """J(q) (n x n, symmetric) of the chain from its :func:`composites`;
    ``frames[i]`` is joint i at q_i; ``reflected``: added to J's diagonal (a
    motor's gr^2 Jm), or None.
    """
    n = len(comp)
    J = sp.zeros(n, n)
    for j in range(n):
        force, moment = _unit_wrench(comp[j], frames[j])
        J[j, j] = _project(frames[j], force, moment) + (reflected[j] if reflected is not None else 0)
        for i in reversed(range(j)):
            f = frames[i + 1]
            force = f.to_parent(force)
            moment = add(f.to_parent(moment), cross(f.p, force))
            J[i, j] = J[j, i] = _project(frames[i], force, moment)
    return J
