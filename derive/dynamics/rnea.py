"""Inverse dynamics of a serial chain: the recursive Newton-Euler algorithm.

Luh, Walker, Paul, "On-line computational scheme for mechanical
manipulators" (1980), in body coordinates (Featherstone, *Rigid Body Dynamics
Algorithms*, 2008, section 5.3, written with 3-vectors): a forward pass
carries each frame's angular velocity w, angular acceleration al and the
linear acceleration a of its origin from the base to the tip, a backward
pass the wrench each body needs from the tip to the base, projected on each
joint's axis. Gravity enters as an upward acceleration of the base,
a_0 = -gravity, so tau = J(q) q'' + C(q, q') q' + g(q) (eq. 12's rigid part).

Per body (mass m, first moment h, inertia I about F_i's origin, in F_i):

    f = m a + al x h + w x (w x h)
    n = I al + w x (I w) + h x a

Passing q'' = 0 gives the bias (Coriolis, centrifugal, gravity); passing
q' = 0 as well gives the gravity vector g(q).
"""
from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from derive.dynamics.crba import Composite
from derive.dynamics.spatial import (ZERO, ZERO_VEC, backward_pass, Mat, Vec, add, cross, dot, keep_sums, matvec, scale, spin_matrix,
                                     JointFrame)


def _is_zero(v: Vec) -> bool:
    return all(x == 0 for x in v)


@keep_sums
def rnea(bodies: Sequence[Composite], frames: Sequence[JointFrame], dq: Sequence[sp.Expr],
         ddq: Sequence[sp.Expr], gravity: Vec) -> sp.Matrix:
    """tau (n x 1) = J_rigid(q) q'' + C(q, q') q' + g(q) for the rigid chain
    (no motor terms); ``bodies[i]`` is body i in F_i (mass, first moment,
    inertia about the origin), ``frames[i]`` joint i at q_i, ``gravity`` the
    free-fall acceleration in the base frame [m/s^2]."""
    n = len(bodies)
    w: Vec = ZERO_VEC
    al: Vec = ZERO_VEC
    a: Vec = scale(-1, gravity)
    forces: list[Vec] = []
    moments: list[Vec] = []
    U: Mat | None = None
    for i in range(n):
        f = frames[i]
        if U is not None:   # acceleration of the point at F_i's origin, fixed in body i-1
            a = add(a, matvec(U, f.p))
        w, al, a = f.to_child(w), f.to_child(al), f.to_child(a)
        qd, qdd = dq[i], ddq[i]
        if f.rotates:
            al = add(al, add(scale(qdd, f.axis), scale(qd, cross(w, f.axis))))
            w = add(w, scale(qd, f.axis))
        else:
            a = add(a, add(scale(qdd, f.axis), scale(2 * qd, cross(w, f.axis))))
        U = spin_matrix(w, al)
        c = bodies[i]
        Iw = tuple(dot(row, w) for row in c.I)
        Ial = tuple(dot(row, al) for row in c.I)
        forces.append(add(scale(c.M, a), matvec(U, c.h)))
        moments.append(add(Ial, add(cross(w, Iw), cross(c.h, a))))  # type: ignore[arg-type]
    tau = [ZERO] * n
    for i, F, N in backward_pass(frames, forces, moments):
        axis = frames[i].axis
        tau[i] = dot(axis, N) if frames[i].rotates else dot(axis, F)
    return sp.Matrix(tau)
