"""The generalized momentum J(q) q' and C(q, q')^T q' of a serial chain, by one recursion.

No inertia matrix and no Coriolis matrix is formed. In spatial-vector terms
(Featherstone, *Rigid Body Dynamics Algorithms*, 2008, ch. 2 and sec. 5.3), with
v_i body i's velocity, S_i joint i's motion axis and H_i = sum over the bodies j
that joint i carries of their momenta I_j v_j (all in one inertial frame):

    p_i = S_i^T H_i = (J q')_i,
    p_i' = S_i^T H_i' + S_i'^T H_i,   S_i' = v_i x S_i,
    S_i^T H_i' = S_i^T sum_j (I_j a_j + v_j x* I_j v_j) = (J q'' + C q')_i  (RNEA without gravity),

so, since p' = J q'' + J' q' and J' = C + C^T (Christoffel C),

    (C^T q')_i = (J' q' - C q')_i = (v_i x S_i)^T H_i.

This is the momentum form of De Luca and Ferrajoli, "A modified Newton-Euler
method for dynamic computations in robot fault detection and control" (ICRA 2009),
where the generalized-momentum residual needs C^T q' without C; see also
Echeandia and Wensing, "Numerical methods to compute the Coriolis matrix and
Christoffel symbols for rigid-body systems" (J. Comput. Nonlinear Dyn., 2021).

In the classical form of :mod:`derive.dynamics.rnea` (body i's frame F_i, its
origin O_i moving at v, turning at w; body mass M, first moment h, inertia I about
O_i): body momentum L = M v + w x h (linear), A = I w + h x v (about O_i), carried
to the parent as a force is; for a revolute joint (S_i = (a; 0))
(v_i x S_i)^T H_i = (w x a).A + (v x a).L, for a prismatic one (S_i = (0; a))
(w x a).L.
"""
from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from derive.dynamics.crba import Composite
from derive.dynamics.spatial import ZERO_VEC, JointFrame, Vec, backward_pass, add, cross, dot, keep_sums, scale


@keep_sums
def momentum_terms(bodies: Sequence[Composite], frames: Sequence[JointFrame],
                   dq: Sequence[sp.Expr]) -> tuple[sp.Matrix, sp.Matrix]:
    """(J_rigid(q) q', C(q, q')^T q'), each n x 1, of the rigid chain (no motor terms;
    the reflected rotor inertias add diag(gr^2 Jm) q' to the first and nothing to the
    second, J' being the rigid chain's alone): ``bodies[i]`` is body i in F_i,
    ``frames[i]`` joint i at q_i (as :func:`derive.dynamics.rnea.rnea` takes them)."""
    n = len(bodies)
    w: Vec = ZERO_VEC
    v: Vec = ZERO_VEC
    ws: list[Vec] = []
    vs: list[Vec] = []
    lin: list[Vec] = []
    ang: list[Vec] = []
    for i in range(n):
        f = frames[i]
        if i > 0:   # velocity of F_i's origin, a point of body i-1
            v = add(v, cross(w, f.p))
        w, v = f.to_child(w), f.to_child(v)
        if f.rotates:
            w = add(w, scale(dq[i], f.axis))
        else:
            v = add(v, scale(dq[i], f.axis))
        c = bodies[i]
        ws.append(w)
        vs.append(v)
        lin.append(add(scale(c.M, v), cross(w, c.h)))
        ang.append(add(tuple(dot(row, w) for row in c.I), cross(c.h, v)))  # type: ignore[arg-type]
    p = [sp.S.Zero] * n
    ct = [sp.S.Zero] * n
    for i, L, A in backward_pass(frames, lin, ang):   # the momenta of bodies i..n-1 about F_i's origin
        a = frames[i].axis
        if frames[i].rotates:
            p[i] = dot(a, A)
            ct[i] = dot(cross(ws[i], a), A) + dot(cross(vs[i], a), L)
        else:
            p[i] = dot(a, L)
            ct[i] = dot(cross(ws[i], a), L)
    return sp.Matrix(p), sp.Matrix(ct)
