"""The reference form of eq. (11-12): Euler-Lagrange equations of the chain's Lagrangian.

Independent of the recursions it checks (no composite bodies, no recursive
Newton-Euler pass, no regrouped parameters): each body's pose in the base
frame is the product of the joint transforms, (R_k(q), p_k(q)); its
velocities are time derivatives of that pose, in the body's axes
v = R^T p', [w]_x = R^T R'; with the body's mass M, first moment h and
inertia I about its frame's origin (its own axes),

    T = sum_k 1/2 M |v|^2 + v . (w x h) + 1/2 w . I w + 1/2 sum_i gr_i^2 Jm_i q_i'^2,
    V = -sum_k gravity . (M p_k + R_k h)   (gravity: free fall, base frame),

and J = d^2 T / dq'^2, rigid G = d/dq (dT/dq') q' - d(T - V)/dq (eq. 12 with
d = 0, without the motor damping). Everything is computed in
:class:`derive.dynamics.trigpoly.TrigRing` (polynomials in sin/cos of the
angles, reduced modulo s^2 + c^2 = 1 as they are formed), so the reference
is canonical: the symbolic proofs compare it with the recursive form there.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import sympy as sp
from sympy.polys.rings import PolyElement

from derive.dynamics.program import free_symbols
from derive.dynamics.spatial import unit_axis
from derive.dynamics.trigpoly import TrigRing, constant_angles
from derive.model.chain import Chain, JointType

PMat = list[list[PolyElement]]
PVec = list[PolyElement]


def _matmul(F: TrigRing, A: PMat, B: PMat) -> PMat:
    return [[F.reduce(sum((A[i][k] * B[k][j] for k in range(3)), F.zero)) for j in range(3)] for i in range(3)]


def _tmatvec(F: TrigRing, A: PMat, v: PVec) -> PVec:
    return [F.reduce(sum((A[k][i] * v[k] for k in range(3)), F.zero)) for i in range(3)]


def _dot(F: TrigRing, a: PVec, b: PVec) -> PolyElement:
    return F.reduce(sum((x * y for x, y in zip(a, b)), F.zero))


def _cross(F: TrigRing, a: PVec, b: PVec) -> PVec:
    return [F.reduce(a[1] * b[2] - a[2] * b[1]), F.reduce(a[2] * b[0] - a[0] * b[2]),
            F.reduce(a[0] * b[1] - a[1] * b[0])]


def _rotation(F: TrigRing, axis: Sequence[PolyElement], k: int | None, sign: int, angle: sp.Symbol) -> PMat:
    """Rot(axis, angle) in the ring (Rodrigues: c 1 + s [a]_x + (1 - c) a a^T)."""
    c, s = F.cos(angle), F.sin(angle)
    if k is not None:
        out = [[F.zero] * 3 for _ in range(3)]
        i, j = (k + 1) % 3, (k + 2) % 3
        out[k][k] = F.one
        out[i][i] = out[j][j] = c
        out[i][j], out[j][i] = -sign * s, sign * s
        return out
    a = axis
    skew = [[F.zero, -a[2], a[1]], [a[2], F.zero, -a[0]], [-a[1], a[0], F.zero]]
    return [[F.reduce((c if i == j else F.zero) + s * skew[i][j] + (1 - c) * a[i] * a[j]) for j in range(3)]
            for i in range(3)]


def lagrangian(F: TrigRing, chain: Chain, q: Sequence[sp.Symbol], dq: Sequence[sp.Symbol],
               reflected: Sequence[sp.Expr], values: Mapping[sp.Symbol, sp.Expr] | None = None
               ) -> tuple[PolyElement, PolyElement]:
    """(T, V) of the chain in the ring ``F`` (with ``values`` put into the chain's entries first)."""
    def conv(x) -> PolyElement:
        x = sp.sympify(x)
        return F(x.xreplace(dict(values)) if values else x)

    R: PMat = [[F.one if i == j else F.zero for j in range(3)] for i in range(3)]
    p: PVec = [F.zero] * 3
    gravity = [conv(x) for x in chain.gravity]
    T = V = F.zero
    for joint, body, qi in zip(chain.joints, chain.bodies, q):
        R0 = [[conv(joint.origin.R[i, j]) for j in range(3)] for i in range(3)]
        p0 = [conv(x) for x in joint.origin.p]
        axis = [conv(x) for x in joint.axis]
        p = [F.reduce(p[i] + sum((R[i][k] * p0[k] for k in range(3)), F.zero)) for i in range(3)]
        R = _matmul(F, R, R0)
        if joint.type is JointType.PRISMATIC:
            slide = F(qi)
            p = [F.reduce(p[i] + slide * sum((R[i][k] * axis[k] for k in range(3)), F.zero)) for i in range(3)]
        else:
            k = unit_axis(tuple(joint.axis))
            sign = 1 if k is None else int(joint.axis[k])
            R = _matmul(F, R, _rotation(F, axis, k, sign, qi))
        Rdot = [[F.d_dt(x, q, dq) for x in row] for row in R]
        W = _matmul(F, [list(col) for col in zip(*R)], Rdot)            # R^T R' = [w]_x in body axes
        w = [W[2][1], W[0][2], W[1][0]]
        v = _tmatvec(F, R, [F.d_dt(x, q, dq) for x in p])              # R^T p'
        M = conv(body.mass)
        h = [conv(x) for x in body.first_moment]
        I = [[conv(body.inertia[i, j]) for j in range(3)] for i in range(3)]
        Iw = [F.reduce(sum((I[i][k] * w[k] for k in range(3)), F.zero)) for i in range(3)]
        T += F.reduce(M * _dot(F, v, v) * sp.QQ(1, 2) + _dot(F, v, _cross(F, w, h)) + _dot(F, w, Iw) * sp.QQ(1, 2))
        centre = [F.reduce(M * p[i] + sum((R[i][k] * h[k] for k in range(3)), F.zero)) for i in range(3)]
        V -= _dot(F, gravity, centre)
    for r, d in zip(reflected, dq):
        T += F.reduce(conv(r) * F(d) ** 2 * sp.QQ(1, 2))
    return T, V


def reference_ring(chain: Chain, q: Sequence[sp.Symbol], dq: Sequence[sp.Symbol], reflected: Sequence[sp.Expr],
                   values: Mapping[sp.Symbol, sp.Expr] | None = None
                   ) -> tuple[TrigRing, list[list[PolyElement]], list[PolyElement]]:
    """(ring, J, rigid G) of the Euler-Lagrange equations, in canonical form."""
    angles = [qi for qi, j in zip(q, chain.joints) if j.type.rotates]
    entries = list(chain.gravity) + list(reflected)
    for joint, body in zip(chain.joints, chain.bodies):
        entries += list(joint.origin.R) + list(joint.origin.p) + list(joint.axis)
        entries += [body.mass] + list(body.first_moment) + list(body.inertia)
    symbols = free_symbols(sp.sympify(e).xreplace(dict(values)) if values else e for e in entries)
    symbols |= set(dq) | {qi for qi, j in zip(q, chain.joints) if not j.type.rotates}
    F = TrigRing(angles, symbols, constant_angles(entries))
    T, V = lagrangian(F, chain, q, dq, reflected, values)
    n = len(q)
    dT = [F.diff(T, v) for v in dq]
    J = [[F.diff(dT[i], dq[j]) for j in range(n)] for i in range(n)]
    G = []
    for i in range(n):
        g = F.diff(V, q[i]) - F.diff(T, q[i])
        for j in range(n):
            g += F.mul(F.diff(dT[i], q[j]), F(dq[j]))
        G.append(F.reduce(g))
    return F, J, G


def lagrange_equations(chain: Chain, q: Sequence[sp.Symbol], dq: Sequence[sp.Symbol],
                       reflected: Sequence[sp.Expr], values: Mapping[sp.Symbol, sp.Expr] | None = None
                       ) -> tuple[sp.Matrix, sp.Matrix]:
    """(J, rigid G) of the Euler-Lagrange equations as SymPy matrices (n x n, n x 1),
    expanded polynomials in sin/cos; ``values``: parameter values put in first."""
    F, J, G = reference_ring(chain, q, dq, reflected, values)
    return sp.Matrix([[F.to_expr(x) for x in row] for row in J]), sp.Matrix([F.to_expr(x) for x in G])
