"""Exact rigid-body algebra for building a :class:`~derive.model.chain.Chain`.

Rotations from roll-pitch-yaw (URDF: extrinsic X-Y-Z, R = Rz(yaw) Ry(pitch)
Rx(roll)), from an axis and angle (Rodrigues), and from DH parameters; angles
that are multiples of pi/2 to within 1e-12 (1.5707963267948966) become exact
multiples of pi/2, so their rotations have exact 0 and +-1 entries. Bodies are
the ten inertial parameters (m, h = m c, I_o about the frame's origin), linear
in the mass distribution, so moving a body to another frame and merging two
bodies are exact and stay linear in the parameter symbols.

Sources: URDF specification (ros.org wiki, ``urdf/XML/joint``, ``link``);
R. Featherstone, Rigid Body Dynamics Algorithms (2008), sec. 2.13 (inertia
transformation) and the parallel-axis theorem.
"""
from __future__ import annotations

import math
import re
from fractions import Fraction

import sympy as sp

from derive.model.chain import Body, Transform

SNAP_TOLERANCE = 1e-12   # rad: an angle this close to k pi/2 is k pi/2 exactly
_HALF_PI = math.pi / 2
_PI_TEXT = re.compile(r"\s*([-+]?)\s*(\d+(?:\.\d*)?)?\s*\*?\s*pi\s*(?:/\s*(\d+(?:\.\d*)?))?\s*\Z")


def rational(x: Fraction | int | float) -> sp.Rational:
    """An exact SymPy number: a Fraction or int as is, a float as the shortest
    decimal that reads back as it (the decimal a file wrote, up to 15 digits)."""
    if isinstance(x, float):
        x = Fraction(repr(x))
    x = Fraction(x)
    return sp.Rational(x.numerator, x.denominator)


def exact_angle(x: Fraction | int | float) -> sp.Expr:
    """An angle in radians, exact: k pi/2 when within ``SNAP_TOLERANCE`` of it,
    else the exact decimal (then cos and sin stay exact symbolic values)."""
    value = float(x)
    k = round(value / _HALF_PI)
    if abs(value - k * _HALF_PI) <= SNAP_TOLERANCE:
        return k * sp.pi / 2
    return rational(x)


def parse_pi(text: str) -> sp.Expr | None:
    """An angle written with pi ("pi/2", "-pi/4", "2*pi/3", "0.5pi"), exact; else None."""
    m = _PI_TEXT.match(text) if len(text) <= 60 else None
    if m is None:
        return None
    sign = -1 if m[1] == "-" else 1
    num = Fraction(m[2]) if m[2] else Fraction(1)
    den = Fraction(m[3]) if m[3] else Fraction(1)
    if den == 0:
        return None
    return sign * rational(num / den) * sp.pi


def rot_x(a: sp.Expr) -> sp.ImmutableMatrix:
    c, s = sp.cos(a), sp.sin(a)
    return sp.ImmutableMatrix([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: sp.Expr) -> sp.ImmutableMatrix:
    c, s = sp.cos(a), sp.sin(a)
    return sp.ImmutableMatrix([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a: sp.Expr) -> sp.ImmutableMatrix:
    c, s = sp.cos(a), sp.sin(a)
    return sp.ImmutableMatrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rpy(roll: sp.Expr, pitch: sp.Expr, yaw: sp.Expr) -> sp.ImmutableMatrix:
    """URDF's fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll) (3 x 3)."""
    return sp.ImmutableMatrix(rot_z(yaw) * rot_y(pitch) * rot_x(roll))


def axis_angle(axis: sp.Matrix, q: sp.Expr) -> sp.ImmutableMatrix:
    """Rotation by q about the unit ``axis`` (3 x 1): c 1 + s [a]x + (1 - c) a a^T."""
    a = sp.Matrix(axis)
    c, s = sp.cos(q), sp.sin(q)
    cross = sp.Matrix([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return sp.ImmutableMatrix((c * sp.eye(3) + s * cross + (1 - c) * a * a.T).applyfunc(sp.expand))


def translation(x: sp.Expr, y: sp.Expr, z: sp.Expr) -> Transform:
    return Transform(sp.ImmutableMatrix.eye(3), sp.ImmutableMatrix([x, y, z]))


def rotation(R: sp.Matrix) -> Transform:
    return Transform(sp.ImmutableMatrix(R), sp.ImmutableMatrix.zeros(3, 1))


def tidy(T: Transform) -> Transform:
    """``T`` with every entry expanded (products of exact rotations stay short)."""
    return Transform(sp.ImmutableMatrix(T.R.applyfunc(sp.expand)), sp.ImmutableMatrix(T.p.applyfunc(sp.expand)))


def inverse(T: Transform) -> Transform:
    """T^-1: x_child = R^T (x_parent - p)."""
    Rt = T.R.T
    return Transform(sp.ImmutableMatrix(Rt), sp.ImmutableMatrix(-(Rt * T.p)))


# -- bodies --------------------------------------------------------------------------------

def skew_square(v: sp.Matrix) -> sp.Matrix:
    """|v|^2 1 - v v^T (the parallel-axis term of a unit mass at v)."""
    v = sp.Matrix(v)
    return (v.T * v)[0, 0] * sp.eye(3) - v * v.T


def body_from_com(mass: sp.Expr, com: sp.Matrix, inertia_com: sp.Matrix,
                  rotation_com: sp.Matrix | None = None) -> Body:
    """A body from its mass, centre of mass c and inertia about c.

    ``inertia_com`` is given in a frame at c rotated by ``rotation_com``
    (URDF's inertial origin rpy; None = identity) and is rotated as R I R^T;
    then I_o = R I R^T + m (|c|^2 1 - c c^T) and h = m c (all 3 x 1 / 3 x 3).
    """
    c = sp.Matrix(com)
    Ic = sp.Matrix(inertia_com)
    if rotation_com is not None:
        R = sp.Matrix(rotation_com)
        Ic = R * Ic * R.T
    return _tidy(Body(mass, sp.ImmutableMatrix(mass * c), sp.ImmutableMatrix(Ic + mass * skew_square(c))))


def move(body: Body, T: Transform) -> Body:
    """``body`` given in a child frame, expressed in the parent frame of T
    (x_parent = R x_child + p): h' = R h + m p,
    I' = R I R^T + 2 (h_r . p) 1 - h_r p^T - p h_r^T + m (|p|^2 1 - p p^T), h_r = R h."""
    R, p, m = sp.Matrix(T.R), sp.Matrix(T.p), body.mass
    hr = R * sp.Matrix(body.first_moment)
    cross = 2 * (hr.T * p)[0, 0] * sp.eye(3) - hr * p.T - p * hr.T
    inertia = R * sp.Matrix(body.inertia) * R.T + cross + m * skew_square(p)
    return _tidy(Body(m, sp.ImmutableMatrix(hr + m * p), sp.ImmutableMatrix(inertia)))


def merge(a: Body, b: Body) -> Body:
    """Two bodies in the same frame as one rigid body: every parameter adds."""
    return _tidy(Body(a.mass + b.mass, sp.ImmutableMatrix(a.first_moment + b.first_moment),
                      sp.ImmutableMatrix(a.inertia + b.inertia)))


def empty_body() -> Body:
    return Body(sp.Integer(0), sp.ImmutableMatrix.zeros(3, 1), sp.ImmutableMatrix.zeros(3, 3))


def _tidy(b: Body) -> Body:
    return Body(sp.expand(b.mass), sp.ImmutableMatrix(b.first_moment.applyfunc(sp.expand)),
                sp.ImmutableMatrix(b.inertia.applyfunc(sp.expand)))


def inertia_problem(I: sp.Matrix) -> str | None:
    """Why a numeric 3 x 3 inertia tensor (about a centre of mass) is not physical, or None.

    Physical: symmetric, positive semi-definite, and its principal moments obey
    the triangle inequality (each at most the sum of the other two). Decided in
    exact arithmetic on the entries (Rationals or exact reals).
    """
    I = sp.Matrix(I)
    if I != I.T:
        return "a symmetric tensor"
    # principal moments: eigenvalues of a real symmetric matrix; PSD and triangle checked
    # through the characteristic polynomial's coefficients (exact, no eigen-solve):
    # l_i >= 0 for all i  <=>  trace, sum of principal 2x2 minors, det >= 0;
    # l_i <= l_j + l_k     <=>  the moments of (tr/2) 1 - I (the "second moments" of the
    # mass distribution, (l_j + l_k - l_i)/2) are >= 0, by the same test.
    def nonnegative_definite(M: sp.Matrix) -> bool:
        minors = (M.trace(), M[0, 0] * M[1, 1] - M[0, 1] ** 2 + M[0, 0] * M[2, 2] - M[0, 2] ** 2
                  + M[1, 1] * M[2, 2] - M[1, 2] ** 2, M.det())
        return all(_sign(x) >= 0 for x in minors)
    if not nonnegative_definite(I):
        return "a positive semi-definite tensor"
    if not nonnegative_definite(I.trace() / 2 * sp.eye(3) - I):
        return "principal moments that satisfy the triangle inequality (each <= the sum of the other two)"
    return None


def _sign(x: sp.Expr) -> int:
    """The sign of an exact real number (exact for rationals; 50 digits otherwise, with
    an absolute tolerance of 1e-40 for round-off in transcendental entries)."""
    x = sp.sympify(x)
    if x.is_Rational:
        return 1 if x > 0 else (-1 if x < 0 else 0)
    v = sp.N(x, 50)
    return 0 if abs(v) < sp.Float("1e-40") else (1 if v > 0 else -1)
