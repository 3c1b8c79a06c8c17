"""Exact rigid-body algebra for building a :class:`~derive.model.chain.Chain`.

Rotations from roll-pitch-yaw (URDF: extrinsic X-Y-Z, R = Rz(yaw) Ry(pitch)
Rx(roll)), from an axis and angle (Rodrigues), and from DH parameters. Bodies
are the ten inertial parameters (m, h = m c, I_o about the frame's origin),
linear in the mass distribution, so moving a body to another frame and
merging two bodies are exact and stay linear in the parameter symbols.

Numbers enter as rationals, so that the cost of everything downstream (the
derivation, its proofs, its display) does not depend on how a file writes them:

* a decimal is the Rational of its shortest decimal (the file's own text);
* an angle within ``SNAP_TOLERANCE`` (1e-8 rad, a 10 nm displacement at a metre,
  far below any machining tolerance) of a multiple of pi/2 is that multiple: ROS
  files write pi/2 with 8 to 12 decimals (1.57079632679 is 4.9e-12 rad off,
  1.57079633 3.2e-9), so their rotations have exact 0 and +-1 entries;
  :func:`angle_note` says what was snapped and which near miss was kept as written
  (1.5708, 3.7e-6 rad off, or 1.57079: a rounding that cannot be told from a
  deliberate angle, so it is not snapped);
* a constant rotation whose entries are not all rational (cos and sin of a
  decimal angle, of pi/3, a rotation about a non-unit-rational axis) is the
  rotation of the integer quaternion nearest its own scaled by 2^60
  (:func:`rational_rotation`): exactly orthogonal with rational entries, within
  4e-18 of the stated rotation (double precision resolves 2.2e-16), so every
  identity of rigid-body mechanics holds exactly and no cos/sin of a constant
  reaches the dynamics;
* a unit vector (a joint axis, a gravity direction) whose length is not
  rational is the nearest rational point of the unit sphere (stereographic
  coordinates rounded to 2^-60, :func:`rational_unit`): exactly unit, within
  4e-18 of the direction given.

Sources: URDF specification (ros.org wiki, ``urdf/XML/joint``, ``link``);
R. Featherstone, Rigid Body Dynamics Algorithms (2008), sec. 2.13 (inertia
transformation) and the parallel-axis theorem; rational rotations from integer
quaternions (Euler-Rodrigues; e.g. Cayley, and Shepperd 1978 for the
quaternion of a rotation matrix).
"""
from __future__ import annotations

import math
import re
from fractions import Fraction

import mpmath
import sympy as sp

from derive.model.chain import Body, Transform
from derive.model.snap import NEAR_MISS, SNAP_TOLERANCE, _SNAP, snap_choice, snap_tolerance, snapping  # noqa: F401

ROTATION_BITS = 60       # integer quaternions and stereographic coordinates to 2^-60
ROTATION_ERROR = 4e-18   # the stated bound of a rationalised rotation or unit vector (entry-wise)
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
    """An angle in radians, exact: k pi/2 when within the snapping tolerance of it (``SNAP_TOLERANCE``,
    or :func:`snapping`'s), else the exact decimal (its rotation is then made rational,
    :func:`rational_rotation`)."""
    value = float(x)
    k = round(value / _HALF_PI)
    if abs(value - k * _HALF_PI) <= _SNAP.get():
        return k * sp.pi / 2
    return rational(x)


def angle_note(x: Fraction | int | float) -> tuple[str, str, float] | None:
    """('snapped' | 'kept', text, distance [rad]) for an angle near a multiple of pi/2, else None: what
    :func:`exact_angle` did with it, for the chain's notes (a small angle near 0 only when it was
    snapped to 0: a deliberate small angle is no near miss)."""
    value = float(x)
    k = round(value / _HALF_PI)
    off = abs(value - k * _HALF_PI)
    if off == 0.0 or off > NEAR_MISS or (k == 0 and off > _SNAP.get()):
        return None
    target = {0: "0", 1: "pi/2", -1: "-pi/2", 2: "pi", -2: "-pi"}.get(k, f"{k}*pi/2")
    if off <= _SNAP.get():
        return "snapped", f"{_text(x)} -> {target} ({off:.2g} rad off)", off
    return "kept", f"{_text(x)} ({off:.2g} rad from {target})", off


def _text(x: Fraction | int | float) -> str:
    return repr(float(x)) if not isinstance(x, float) else repr(x)


def _rational_entries(M: sp.MatrixBase) -> bool:
    return all(sp.sympify(e).is_Rational for e in M)


def rational_rotation(R: sp.MatrixBase) -> sp.ImmutableMatrix:
    """A constant 3 x 3 rotation with rational entries: ``R`` itself when its entries are
    rational, else the rotation of the integer quaternion nearest 2^60 q(R) (q(R) by
    Shepperd's method at 50 digits): R(q) = (1/|q|^2) [[w^2 + x^2 - y^2 - z^2, 2 (x y - w z),
    ...]], exactly orthogonal, entry-wise within ``ROTATION_ERROR`` of ``R``."""
    R = sp.Matrix(R)
    if _rational_entries(R):
        return sp.ImmutableMatrix(R)
    with mpmath.workdps(50):
        m = [[mpmath.mpf(str(sp.N(R[i, j], 60))) for j in range(3)] for i in range(3)]
        tr = m[0][0] + m[1][1] + m[2][2]
        cand = [tr, m[0][0], m[1][1], m[2][2]]
        k = max(range(4), key=lambda i: cand[i])
        if k == 0:
            w = mpmath.sqrt(1 + tr) / 2
            q = [w, (m[2][1] - m[1][2]) / (4 * w), (m[0][2] - m[2][0]) / (4 * w), (m[1][0] - m[0][1]) / (4 * w)]
        elif k == 1:
            x = mpmath.sqrt(1 + 2 * m[0][0] - tr) / 2
            q = [(m[2][1] - m[1][2]) / (4 * x), x, (m[0][1] + m[1][0]) / (4 * x), (m[0][2] + m[2][0]) / (4 * x)]
        elif k == 2:
            y = mpmath.sqrt(1 + 2 * m[1][1] - tr) / 2
            q = [(m[0][2] - m[2][0]) / (4 * y), (m[0][1] + m[1][0]) / (4 * y), y, (m[1][2] + m[2][1]) / (4 * y)]
        else:
            z = mpmath.sqrt(1 + 2 * m[2][2] - tr) / 2
            q = [(m[1][0] - m[0][1]) / (4 * z), (m[0][2] + m[2][0]) / (4 * z), (m[1][2] + m[2][1]) / (4 * z), z]
        w, x, y, z = (int(mpmath.nint(c * 2 ** ROTATION_BITS)) for c in q)
    n = w * w + x * x + y * y + z * z
    rows = [[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]]
    return sp.ImmutableMatrix([[sp.Rational(e, n) for e in row] for row in rows])


def rational_unit(v: sp.MatrixBase) -> sp.ImmutableMatrix:
    """The unit vector of a non-zero rational 3-vector ``v``, rational: exact when |v| is
    rational, else the point of the unit circle (two non-zero entries) or sphere (three)
    whose stereographic coordinates, from the pole opposite v, are those of v/|v| rounded
    to 2^-60: exactly unit, zero entries kept, entry-wise within ``ROTATION_ERROR`` of v/|v|."""
    v = sp.Matrix(v)
    root = sp.sqrt((v.T * v)[0, 0])
    if root.is_Rational:
        return sp.ImmutableMatrix(v / root)
    live = [i for i in range(3) if v[i] != 0]
    s = 2 ** ROTATION_BITS
    with mpmath.workdps(50):
        u = [mpmath.mpf(str(sp.N(v[i] / root, 60))) for i in live]
        sign = 1 if u[-1] >= 0 else -1       # project from the pole opposite v: 1 + |u_last| >= 1
        X = [int(mpmath.nint(c / (1 + sign * u[-1]) * s)) for c in u[:-1]]
    den = s * s + sum(x * x for x in X)
    point = [sp.Rational(2 * x * s, den) for x in X] + [sign * sp.Rational(s * s - sum(x * x for x in X), den)]
    out = [sp.Integer(0)] * 3
    for i, value in zip(live, point):
        out[i] = value
    return sp.ImmutableMatrix(out)


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


def _constant(angle: sp.Expr) -> bool:
    return not sp.sympify(angle).free_symbols


def _settle(R: sp.MatrixBase, angles: tuple[sp.Expr, ...]) -> sp.ImmutableMatrix:
    """A rotation of constant angles made rational (:func:`rational_rotation`); symbolic ones as they are."""
    return rational_rotation(R) if all(_constant(a) for a in angles) else sp.ImmutableMatrix(R)


def rot_x(a: sp.Expr) -> sp.ImmutableMatrix:
    c, s = sp.cos(a), sp.sin(a)
    return _settle(sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]]), (a,))


def rot_y(a: sp.Expr) -> sp.ImmutableMatrix:
    c, s = sp.cos(a), sp.sin(a)
    return _settle(sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]]), (a,))


def rot_z(a: sp.Expr) -> sp.ImmutableMatrix:
    c, s = sp.cos(a), sp.sin(a)
    return _settle(sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]]), (a,))


def rpy(roll: sp.Expr, pitch: sp.Expr, yaw: sp.Expr) -> sp.ImmutableMatrix:
    """URDF's fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll) (3 x 3); for
    constant angles rational (:func:`rational_rotation` of the product, one rounding)."""
    def raw(f, a):
        c, s = sp.cos(a), sp.sin(a)
        return {"x": sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]]),
                "y": sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
                "z": sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[f]
    return _settle(raw("z", yaw) * raw("y", pitch) * raw("x", roll), (roll, pitch, yaw))


def axis_angle(axis: sp.Matrix, q: sp.Expr) -> sp.ImmutableMatrix:
    """Rotation by q about the unit ``axis`` (3 x 1): c 1 + s [a]x + (1 - c) a a^T; for a
    constant q rational (:func:`rational_rotation`)."""
    a = sp.Matrix(axis)
    c, s = sp.cos(q), sp.sin(q)
    cross = sp.Matrix([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    R = (c * sp.eye(3) + s * cross + (1 - c) * a * a.T).applyfunc(sp.expand)
    return _settle(R, (q,))


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


# -- rotations and directions given as doubles (MuJoCo's compiled model) ---------------------

_ROUNDING = 1e-12     # a compiled double this close to an exact 0 or +-1 is that number, unsaid


def quaternion_rotation(q) -> tuple[sp.ImmutableMatrix, float | None]:
    """An exact rotation of a quaternion (w, x, y, z; doubles, as MuJoCo's compiler gives them)
    and how far it was moved: the signed permutation (a rotation of multiples of pi/2) when the
    quaternion's rotation is within ``SNAP_TOLERANCE`` of one, with the distance moved (the largest
    entry-wise difference, about the angle in rad); else R(q) / |q|^2 of the quaternion's entries as
    exact decimals (:func:`rational`): exactly orthogonal, the quaternion's own rotation, with the
    distance to the nearest signed permutation when within ``NEAR_MISS`` of one (kept), else None."""
    w, x, y, z = (float(c) for c in q)
    n = w * w + x * x + y * y + z * z
    R = [[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
         [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
         [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]]
    R = [[e / n for e in row] for row in R]
    P = [[float(round(e)) for e in row] for row in R]
    off = max(abs(R[i][j] - P[i][j]) for i in range(3) for j in range(3))
    permutation = all(sorted(abs(e) for e in row) == [0.0, 0.0, 1.0] for row in P) and \
        all(sum(abs(P[i][j]) for i in range(3)) == 1.0 for j in range(3))
    if permutation and sp.Matrix(P).det() == 1 and off <= SNAP_TOLERANCE:
        return sp.ImmutableMatrix([[int(e) for e in row] for row in P]), off
    a, b, c, d = (rational(float(v)) for v in q)
    m = a * a + b * b + c * c + d * d
    rows = [[a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
            [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
            [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d]]
    return sp.ImmutableMatrix([[e / m for e in row] for row in rows]), (off if permutation and off <= NEAR_MISS
                                                                           else None)


def unit_axis(v) -> tuple[sp.ImmutableMatrix, bool]:
    """An exact unit vector of a unit 3-vector of doubles (a compiled joint axis): +-e_k when within
    1e-12 of it, else :func:`rational_unit` of its exact decimals; and whether it was exact already."""
    values = [float(x) for x in v]
    k = max(range(3), key=lambda i: abs(values[i]))
    if abs(abs(values[k]) - 1.0) <= _ROUNDING and all(abs(values[i]) <= _ROUNDING for i in range(3) if i != k):
        out = [0, 0, 0]
        out[k] = 1 if values[k] > 0 else -1
        return sp.ImmutableMatrix(out), True
    exact = sp.Matrix([rational(x) for x in values])
    root = sp.sqrt((exact.T * exact)[0, 0])
    return rational_unit(exact), bool(root == 1)
