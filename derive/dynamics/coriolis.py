"""The Coriolis matrix C(q, q') of a serial chain, Christoffel-consistent, in O(n^2).

C is the matrix of the Christoffel symbols of J (C_kj = sum_i Gamma_kji q'_i,
Gamma_kji = 1/2 (dJ_kj/dq_i + dJ_ki/dq_j - dJ_ij/dq_k)), the one for which
J' - 2C is skew-symmetric and C q' is the velocity part of the bias. It is
computed without differentiating J, by the recursion of S. Echeandia and
P. M. Wensing, "Numerical methods to compute the Coriolis matrix and
Christoffel symbols for rigid-body systems", J. Comput. Nonlinear Dyn. 16
(2021) (the algorithm of Pinocchio's ``computeCoriolisMatrix``):

    C = sum_k J_k^T (I_k J_k' + B_k J_k),  B_k = 1/2 (I_k' + (I_k v_k) xbar*),

with J_k body k's Jacobian, v_k its spatial velocity, I_k' the ground-frame
rate of its spatial inertia (v x* I - I v x) and (f xbar*) m = m x* f. With
S_j the motion subspace of joint j, I^C, I^C' and h^C the composite inertia,
its rate and the composite momentum sum_k I_k v_k of the bodies from m on,
B^C_m = 1/2 (I^C_m' + h^C_m xbar*) and, for m = max(i, j),

    C_ij = S_i . (I^C_m S_j' + B^C_m S_j)
         = S_i . w_j                                  (i <= j),
         = S_j' . (I^C_i S_i) + S_j . (B^C_i^T S_i)   (i > j),

    w_j = I^C_j S_j' + 1/2 (I^C_j' S_j + S_j x* h^C_j),
    B^C_i^T S_i = 1/2 (I^C_i' S_i - S_i x* h^C_i),   S_j' = v_j x S_j.

Spatial vectors are kept as pairs of 3-vectors in each joint's frame:
motion (w, v) (angular velocity, velocity of the frame's origin), force
(n, f) (moment about the origin, force). Rates of inertia are kept as
(h', I') pairs: the ground-frame derivative of (M, h, I) at the instant,
M' = 0 (:class:`derive.dynamics.crba.Composite` with M = 0).
"""
from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from derive.dynamics.crba import Composite, composites
from derive.dynamics.spatial import (ZERO, ZERO_VEC, JointFrame, Mat, Vec, add, cross, dot, mat_add, matvec, mul,
                                     scale, shift_inertia, sub)

Motion = tuple[Vec, Vec]
Force = tuple[Vec, Vec]

HALF = sp.Rational(1, 2)


def _apply(c: Composite, m: Motion) -> Force:
    """Spatial inertia (M, h, I) times motion (w, v): (I w + h x v, M v - h x w)."""
    w, v = m
    return (add(matvec(c.I, w), cross(c.h, v)), sub(scale(c.M, v), cross(c.h, w)))


def _cross_force(m: Motion, f: Force) -> Force:
    """m x* f = (w x n + v x f, w x f)."""
    w, v = m
    n, fl = f
    return (add(cross(w, n), cross(v, fl)), cross(w, fl))


def _cross_motion(m: Motion, s: Motion) -> Motion:
    """m x s = (w x s_w, w x s_v + v x s_w)."""
    w, v = m
    return (cross(w, s[0]), add(cross(w, s[1]), cross(v, s[0])))


def _pair_dot(m: Motion, f: Force) -> sp.Expr:
    return dot(m[0], f[0]) + dot(m[1], f[1])


def _force_to_parent(fr: JointFrame, f: Force) -> Force:
    fl = fr.to_parent(f[1])
    return (add(fr.to_parent(f[0]), cross(fr.p, fl)), fl)


def _skew_sym_product(w: Vec, I: Mat) -> Mat:
    """S(w) I - I S(w) (symmetric for a symmetric I)."""
    wI = tuple(cross(w, tuple(I[r][c] for r in range(3))) for c in range(3))   # columns of S(w) I
    out = [[ZERO] * 3 for _ in range(3)]
    for r in range(3):
        for c in range(r, 3):
            out[r][c] = out[c][r] = wI[c][r] + wI[r][c]   # (S(w) I)_rc - (I S(w))_rc, (I S(w))_rc = -(S(w) I)_cr
    return tuple(tuple(row) for row in out)  # type: ignore[return-value]


def _inertia_rate(c: Composite, w: Vec, v: Vec) -> Composite:
    """Ground-frame rate of a rigid body's (M, h, I) moving at (w, v):
    h' = w x h + M v, I' = S(w) I - I S(w) - S(v) S(h) - S(h) S(v)."""
    hdot = add(cross(w, c.h), scale(c.M, v))
    rot = _skew_sym_product(w, c.I)
    shift = shift_inertia(((ZERO,) * 3,) * 3, ZERO, c.h, v)   # -S(v)S(h) - S(h)S(v), no mass term
    return Composite(ZERO, hdot, mat_add(rot, shift))


def _subspace(fr: JointFrame) -> Motion:
    return (fr.axis, ZERO_VEC) if fr.rotates else (ZERO_VEC, fr.axis)


def coriolis_matrix(bodies: Sequence[Composite], frames: Sequence[JointFrame], dq: Sequence[sp.Expr]) -> sp.Matrix:
    """C(q, q') (n x n) of the chain; ``frames[i]`` is joint i at q_i, ``dq`` the rates."""
    n = len(bodies)
    own = list(bodies)
    comp = composites(bodies, frames)
    # forward: velocities, S_j' = v_j x S_j, each body's momentum and inertia rate
    w, v = ZERO_VEC, ZERO_VEC
    S, Sdot, momentum, rate = [], [], [], []
    for j, fr in enumerate(frames):
        if j > 0:
            v = add(v, cross(w, fr.p))
        w, v = fr.to_child(w), fr.to_child(v)
        s = _subspace(fr)
        w, v = add(w, scale(dq[j], s[0])), add(v, scale(dq[j], s[1]))
        S.append(s)
        Sdot.append(_cross_motion((w, v), s))
        momentum.append(_apply(own[j], (w, v)))
        rate.append(_inertia_rate(own[j], w, v))
    # backward: composite momentum h^C and inertia rate I^C'
    hC: list[Force] = list(momentum)
    rC: list[Composite] = list(rate)
    for j in reversed(range(n - 1)):
        fr = frames[j + 1]
        m = _force_to_parent(fr, hC[j + 1])
        hC[j] = (add(hC[j][0], m[0]), add(hC[j][1], m[1]))
        child = rC[j + 1]
        hd = fr.to_parent(child.h)
        moved = shift_inertia(fr.inertia_to_parent(child.I), ZERO, hd, fr.p)
        rC[j] = Composite(ZERO, add(rC[j].h, hd), mat_add(rC[j].I, moved))
    C = sp.zeros(n, n)
    for j in range(n):
        IcSdot = _apply(comp[j], Sdot[j])
        rS = _apply(rC[j], S[j])
        Sh = _cross_force(S[j], hC[j])
        upper = tuple(add(IcSdot[k], scale(HALF, add(rS[k], Sh[k]))) for k in range(2))   # w_j
        lower = tuple(scale(HALF, sub(rS[k], Sh[k])) for k in range(2))                   # B^C_j^T S_j
        unit = _apply(comp[j], S[j])                                                      # I^C_j S_j
        C[j, j] = _pair_dot(S[j], upper)
        for i in reversed(range(j)):
            fr = frames[i + 1]
            upper, lower, unit = (_force_to_parent(fr, upper), _force_to_parent(fr, lower),
                                  _force_to_parent(fr, unit))
            C[i, j] = _pair_dot(S[i], upper)
            C[j, i] = _pair_dot(Sdot[i], unit) + _pair_dot(S[i], lower)
    return C


def christoffel(J: sp.Matrix, q: Sequence[sp.Symbol], dq: Sequence[sp.Symbol]) -> sp.Matrix:
    """The Christoffel matrix straight from its definition, differentiating J:
    C = 1/2 (J' + A - A^T), J' = sum_i dJ/dq_i q'_i, A_kj = sum_i dJ_ki/dq_j q'_i
    (A = d(J q')/dq). The reference :func:`coriolis_matrix` is tested against;
    slow beyond a few joints (SymPy differentiates every path through J)."""
    n = J.rows
    dJ = [J.diff(qi) for qi in q]
    Jdot = sp.zeros(n, n)
    A = sp.zeros(n, n)
    for k in range(n):
        for j in range(n):
            Jdot[k, j] = sp.Add(*[dJ[i][k, j] * dq[i] for i in range(n)])
            A[k, j] = sp.Add(*[dJ[j][k, i] * dq[i] for i in range(n)])
    return (Jdot + A - A.T) / 2
