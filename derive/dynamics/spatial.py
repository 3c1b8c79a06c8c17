"""Rigid-body algebra for the recursive dynamics, in SymPy, exact zeros kept.

Vectors are tuples of three SymPy expressions and 3 x 3 matrices tuples of
three rows, not ``sympy.Matrix``: products are written out term by term so a
structural zero (a planar chain's z components, an axis along a coordinate
axis) drops out when the term is built, and nothing is ever expanded. This is
what keeps a planar chain as small as the planar recursion it replaces and
what makes common subexpression elimination effective afterwards.

The joint kinematics follow :mod:`derive.model.chain`: joint i's frame F_i
sits at ``origin * Rot(axis, q_i)`` (revolute, continuous) or
``origin * Trans(axis q_i)`` (prismatic) in F_{i-1}. :class:`JointFrame`
carries that transform for one symbolic q_i and maps vectors both ways.
Sources: R. Featherstone, *Rigid Body Dynamics Algorithms* (2008), ch. 2-3
(the cross products of motion and force vectors); the classical
(non-spatial) form of the recursions is Luh, Walker, Paul (1980).
"""
from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

import sympy as sp
from sympy.core.parameters import distribute

from derive.model.chain import Joint, JointType

Vec = tuple[sp.Expr, sp.Expr, sp.Expr]
Mat = tuple[Vec, Vec, Vec]

T = TypeVar("T")

ZERO = sp.Integer(0)
ONE = sp.Integer(1)
ZERO_VEC: Vec = (ZERO, ZERO, ZERO)


def keep_sums(fn: Callable[..., T]) -> Callable[..., T]:
    """``fn`` run with SymPy's distribution of a number over a sum turned off:
    a constant offset, a -1 of a signed-permutation rotation or a 1/2 times a
    shared sum multiplies it (one operation) instead of being copied into each
    of its terms (a new sum, the shared one lost). The recursions build under it."""
    @functools.wraps(fn)
    def run(*args, **kwargs) -> T:
        with distribute(False):
            return fn(*args, **kwargs)
    return run


def vec(v: Sequence[sp.Expr]) -> Vec:
    """A 3-vector (any sequence, e.g. a 3 x 1 Matrix) as a tuple of sympified entries."""
    x = tuple(sp.sympify(e) for e in v)
    if len(x) != 3:
        raise ValueError(f"a 3-vector needs 3 entries, got {len(x)}")
    return x  # type: ignore[return-value]


def mat(m: sp.MatrixBase) -> Mat:
    """A 3 x 3 SymPy matrix as a tuple of rows."""
    return tuple(tuple(sp.sympify(m[i, j]) for j in range(3)) for i in range(3))  # type: ignore[return-value]


def mul(a: sp.Expr, b: sp.Expr) -> sp.Expr:
    """a b, with an exact zero factor short-cut (0 * x would ask whether x is
    finite, which walks the whole of x: the dominant cost of building a chain)."""
    return ZERO if a is ZERO or b is ZERO else a * b


def add(a: Vec, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def scale(k: sp.Expr, a: Vec) -> Vec:
    return (mul(k, a[0]), mul(k, a[1]), mul(k, a[2]))


def dot(a: Vec, b: Vec) -> sp.Expr:
    return mul(a[0], b[0]) + mul(a[1], b[1]) + mul(a[2], b[2])


def cross(a: Vec, b: Vec) -> Vec:
    """a x b (a motion vector's cross product with a vector; zeros drop out term by term)."""
    return (mul(a[1], b[2]) - mul(a[2], b[1]), mul(a[2], b[0]) - mul(a[0], b[2]),
            mul(a[0], b[1]) - mul(a[1], b[0]))


def matvec(m: Mat, v: Vec) -> Vec:
    """m v."""
    return (dot(m[0], v), dot(m[1], v), dot(m[2], v))


def tmatvec(m: Mat, v: Vec) -> Vec:
    """m^T v."""
    return tuple(mul(m[0][j], v[0]) + mul(m[1][j], v[1]) + mul(m[2][j], v[2])
                 for j in range(3))  # type: ignore[return-value]


def matmul(a: Mat, b: Mat) -> Mat:
    """a b."""
    return tuple(tuple(mul(a[i][0], b[0][j]) + mul(a[i][1], b[1][j]) + mul(a[i][2], b[2][j])
                       for j in range(3)) for i in range(3))  # type: ignore[return-value]


def congruence(r: Mat, inertia: Mat) -> Mat:
    """r I r^T for a symmetric I (the six distinct entries only, mirrored)."""
    ri = matmul(r, inertia)
    out = [[ZERO] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(i, 3):
            out[i][j] = out[j][i] = dot(ri[i], r[j])
    return tuple(tuple(row) for row in out)  # type: ignore[return-value]


def mat_add(a: Mat, b: Mat) -> Mat:
    return tuple(tuple(a[i][j] + b[i][j] for j in range(3)) for i in range(3))  # type: ignore[return-value]


def shift_inertia(inertia: Mat, mass: sp.Expr, h: Vec, r: Vec) -> Mat:
    """Rotational inertia about a point P of a body whose inertia about Q is
    ``inertia``, first moment about Q is ``h`` and Q = P + r (all in one frame):

        I_P = I_Q - S(r) S(h) - S(h) S(r) - m S(r)^2
            = I_Q + 2 (r.h) 1 - r h^T - h r^T + m (|r|^2 1 - r r^T)

    (parallel-axis theorem for a first moment not at Q; S(x) = [x]_x).
    """
    rh = dot(r, h)
    rr = dot(r, r)
    out = [[ZERO] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(i, 3):
            x = inertia[i][j] - mul(r[i], h[j]) - mul(h[i], r[j]) - mul(mass, mul(r[i], r[j]))
            if i == j:
                x = x + mul(2, rh) + mul(mass, rr)
            out[i][j] = out[j][i] = x
    return tuple(tuple(row) for row in out)  # type: ignore[return-value]


def spin_matrix(w: Vec, al: Vec) -> Mat:
    """U = S(al) + S(w) S(w), so that U r = al x r + w x (w x r) (the acceleration
    of a point at r in a frame turning at w, al; Khalil and Kleinfinger's U_j).

    One U serves both the acceleration of the next joint's origin and the
    body's force U h, sharing the products w_i w_j.
    """
    x, y, z = w
    xx, yy, zz = mul(x, x), mul(y, y), mul(z, z)
    xy, xz, yz = mul(x, y), mul(x, z), mul(y, z)
    return ((-(yy + zz), xy - al[2], xz + al[1]),
            (xy + al[2], -(xx + zz), yz - al[0]),
            (xz - al[1], yz + al[0], -(xx + yy)))


def unit_axis(axis: Vec) -> int | None:
    """k when the axis is +-e_k exactly, else None."""
    nonzero = [k for k in range(3) if axis[k] != 0]
    if len(nonzero) == 1 and abs(axis[nonzero[0]]) == 1:
        return nonzero[0]
    return None


def axis_rotation(axis: Vec, angle: sp.Expr) -> Mat:
    """The rotation by ``angle`` about the unit ``axis`` (Rodrigues:
    R = c 1 + s [a]_x + (1 - c) a a^T), with exact 0 and 1 entries when the
    axis is a coordinate axis (a rotation about -y is one about +y by -angle)."""
    c, s = sp.cos(angle), sp.sin(angle)
    k = unit_axis(axis)
    if k is not None:
        s = s if axis[k] == 1 else -s
        i, j = (k + 1) % 3, (k + 2) % 3
        out = [[ZERO] * 3 for _ in range(3)]
        out[k][k] = ONE
        out[i][i] = out[j][j] = c
        out[i][j], out[j][i] = -s, s
        return tuple(tuple(row) for row in out)  # type: ignore[return-value]
    a = axis
    v = 1 - c
    skew = ((ZERO, -a[2], a[1]), (a[2], ZERO, -a[0]), (-a[1], a[0], ZERO))
    return tuple(tuple((c if i == j else ZERO) + mul(s, skew[i][j]) + mul(v, mul(a[i], a[j])) for j in range(3))
                 for i in range(3))  # type: ignore[return-value]


def axis_congruence(k: int, angle: sp.Expr, inertia: Mat) -> Mat:
    """R I R^T for R the rotation by ``angle`` about e_k, with fewer products
    than R (I R^T): with (i, j, k) cyclic, u = I_ii - I_jj, t = s^2 u + 2 s c I_ij,

        I'_ii = I_ii - t,   I'_jj = I_jj + t,   I'_ij = s c u + (c^2 - s^2) I_ij,
        I'_ik = c I_ik - s I_jk,   I'_jk = s I_ik + c I_jk,   I'_kk = I_kk

    (no halves, which SymPy would distribute over the sums they multiply).
    """
    c, s = sp.cos(angle), sp.sin(angle)
    i, j = (k + 1) % 3, (k + 2) % 3
    I = inertia
    out = [[ZERO] * 3 for _ in range(3)]
    out[k][k] = I[k][k]
    out[i][k] = out[k][i] = mul(c, I[i][k]) - mul(s, I[j][k])
    out[j][k] = out[k][j] = mul(s, I[i][k]) + mul(c, I[j][k])
    u = I[i][i] - I[j][j]
    sc = s * c
    t = mul(s * s, u) + mul(2 * sc, I[i][j])
    out[i][i], out[j][j] = I[i][i] - t, I[j][j] + t
    out[i][j] = out[j][i] = mul(sc, u) + mul(c * c - s * s, I[i][j])
    return tuple(tuple(row) for row in out)  # type: ignore[return-value]


def _is_identity(m: Mat) -> bool:
    return all(m[i][j] == (ONE if i == j else ZERO) for i in range(3) for j in range(3))


@dataclass(frozen=True)
class JointFrame:
    """Joint i's transform F_{i-1} <- F_i at the coordinate ``q``.

    ``rotates``: revolute or continuous; ``axis``: the unit axis in F_i (and,
    for a prismatic joint, in F_{i-1} rotated by the origin's R); ``origin_R``,
    ``origin_p``: the fixed part; ``joint_R``: Rot(axis, q) (identity for a
    prismatic joint); ``p``: F_i's origin in F_{i-1} (moves with q for a
    prismatic joint).
    """

    rotates: bool
    axis: Vec
    origin_R: Mat
    origin_p: Vec
    joint_R: Mat
    p: Vec
    _origin_identity: bool
    _axis_index: int | None = None
    _angle: sp.Expr = ZERO

    @staticmethod
    def of(joint: Joint, q: sp.Expr) -> "JointFrame":
        axis = vec(joint.axis)
        R0 = mat(joint.origin.R)
        p0 = vec(joint.origin.p)
        rotates = joint.type is not JointType.PRISMATIC
        identity = _is_identity(R0)
        if rotates:
            k = unit_axis(axis)
            angle = q if k is None or axis[k] == 1 else -q
            return JointFrame(True, axis, R0, p0, axis_rotation(axis, q), p0, identity, k, angle)
        slide = scale(q, axis) if identity else scale(q, matvec(R0, axis))
        eye = ((ONE, ZERO, ZERO), (ZERO, ONE, ZERO), (ZERO, ZERO, ONE))
        return JointFrame(False, axis, R0, p0, eye, add(p0, slide), identity)  # type: ignore[arg-type]

    @property
    def R(self) -> Mat:
        """The whole rotation origin_R joint_R (F_i's axes in F_{i-1})."""
        if self._origin_identity:
            return self.joint_R
        if not self.rotates:
            return self.origin_R
        return matmul(self.origin_R, self.joint_R)

    def to_child(self, v: Vec) -> Vec:
        """A vector of F_{i-1} in F_i's axes: joint_R^T origin_R^T v."""
        w = v if self._origin_identity else tmatvec(self.origin_R, v)
        return w if not self.rotates else tmatvec(self.joint_R, w)

    def to_parent(self, v: Vec) -> Vec:
        """A vector of F_i in F_{i-1}'s axes: origin_R joint_R v."""
        w = v if not self.rotates else matvec(self.joint_R, v)
        return w if self._origin_identity else matvec(self.origin_R, w)

    def inertia_to_parent(self, inertia: Mat) -> Mat:
        """R I R^T: a symmetric tensor of F_i in F_{i-1}'s axes."""
        if not self.rotates:
            out = inertia
        elif self._axis_index is not None:
            out = axis_congruence(self._axis_index, self._angle, inertia)
        else:
            out = congruence(self.joint_R, inertia)
        return out if self._origin_identity else congruence(self.origin_R, out)


def backward_pass(frames, forces: Sequence[Vec], moments: Sequence[Vec]):
    """The recursions' backward pass (Featherstone 2008, the RNEA's second loop): yields, from the
    tip down, (i, F, N), the force and moment [about F_i's origin, in F_i] that bodies i..n-1 carry
    across joint i, given each body's own ``forces[i]`` and ``moments[i]`` in its frame and
    ``frames[i]`` (JointFrame: to_parent, p) from body i-1 to body i."""
    F: Vec = ZERO_VEC
    N: Vec = ZERO_VEC
    for i in reversed(range(len(forces))):
        if i + 1 < len(forces):
            f = frames[i + 1]
            F = f.to_parent(F)
            N = add(f.to_parent(N), cross(f.p, F))
        F = add(forces[i], F)
        N = add(moments[i], N)
        yield i, F, N

