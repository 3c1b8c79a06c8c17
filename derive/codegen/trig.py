"""The generated C's own sine and cosine, and the proof of their error bound.

The kernels' sin(q) and cos(q) are a large share of a control step's time when
they are libm calls (a third of the Panda's ``npid_step``: the call, and a
result the rest of the step waits for). The C printer
(:mod:`derive.codegen.printing`) calls instead a static ``trig_sincos`` (out
of line: one copy per file) of the real type, defined by :func:`c_helper` at the top of each C file that
needs it, and computes the sines and cosines of the kernel's input angles first so that the
processor overlaps them with the rest: a port's several angles in one ``trig_sincos_n``
call, which works on pairs of lanes that the compiler evaluates as one two-lane vector (SSE2
for double at gcc -O2), the same operations per lane, so the bound below holds for every lane.

Method (Cody and Waite's reduction with one constant; polynomials on the
reduced interval; Muller, *Elementary Functions*, 3rd ed., ch. 11):

    |x| <= PIO4:  k = 0, r = x       (no reduction needed)
    else:         t = x * TWO_OVER_PI,  k = (long)(t + copysign(0.5, t)),  r = x - k * PIO2
    z = r * r
    s = r + (r * z) * P(z)        P = S0 + z (S1 + z (...))   (Horner)
    c = (1 - 0.5 * z) + (z * z) * Q(z)
    sin x, cos x = (s, c), (c, -s), (-s, -c), (-c, s)  for k mod 4 = 0, 1, 2, 3

Every operation is exact in C's semantics under any flags (a conversion to an
integer, a selection, a sign change) or is one IEEE operation whose rounding
the bound below counts; no step relies on extra precision that -ffast-math's
reassociation could remove (no two-part constant, no rounding by adding and
subtracting 1.5 * 2^52). A contracted multiply-add (FMA) rounds once where the
analysis counts two roundings, so the bound covers it. For |x| > XMAX the
helper calls libm's sin and cos (1 ulp).

Error bound, proved with exact rational arithmetic by :func:`bound` (tests
check it and that it is not loose; ``tests/test_trig.py``):

* Reduction. |x| <= XMAX gives |r_hat| <= R (``reduced_range``), where the
  polynomials are certified. The exact r = x - k pi/2 and the computed one
  differ by eta(k) <= |k| (|PIO2 - pi/2| + u PIO2) + u R, 0 for k = 0 (then
  r = x exactly).
* Approximation. |P - S| and |Q - C| on [0, R^2] for S(z) = (sin r - r)/r^3,
  C(z) = (cos r - 1 + z/2)/z^2: the polynomial minus the series' first
  terms is bounded by its exact Taylor expansion on 32 pieces, the rest of
  the series by its first term (alternating, decreasing); relative to sin r >= r (1 - z/6)
  and cos r >= 1 - z/2.
* Evaluation. A relative-error running analysis of the printed operations
  over 32 pieces of z, each rounding |delta| <= u (Higham, *Accuracy and
  Stability of Numerical Algorithms*, 2nd ed., sec. 2.2).

So |sin_hat(x) - sin x| <= eps |sin x| + (1 + eps) eta(k) (the same for cos),
with eps = ``bound(real).relative`` (at least libm's 2u) and k the code's
quadrant count, which may differ by one from the integer nearest x 2/pi at a
boundary: |k| <= :func:`k_max` (x) covers both. The accuracy model of the
generated code (:mod:`derive.codegen.accuracy`, kind TRIG) uses exactly this.

Assumed, as by the rest of the accuracy model (Higham's standard model): round
to nearest and no underflow. Under -Ofast a subnormal x is flushed to zero (the
program runs with denormals-are-zero), so sin x = 0 there. A reviewer's attack
(4.5 million doubles, every float with 2^-12 <= |x| <= 2^14, 15 compiler and
flag settings, x87 included) found no other breach; the largest error over
bound was 0.998 (k PIO2 just above a power of two, where the rounding of k PIO2
reaches u |k PIO2|). gcc -Ofast on x87 (-m32) turns the libm fallback into the
fsincos instruction, wrong for |x| >= 2^63: as it does every libm sin and cos
call.
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import cache
import math
from math import factorial

import numpy as np

from derive.codegen.printing import c_literal

# Coefficients: weighted least squares on 200 Chebyshev nodes of z in [0, R^2]
# (mpmath, 50 digits), rounded to the real type; the bound is proved for these values.
R = Fraction(4, 5)
COEFFICIENTS = {
    "double": (
        ("-0x1.5555555555545p-3", "0x1.111111110f21cp-7", "-0x1.a01a019b47fe1p-13", "0x1.71de34c9e4a4dp-19",
         "-0x1.ae5dde9bfa828p-26", "0x1.5d6bc8d62e07ap-33"),
        ("0x1.5555555555547p-5", "-0x1.6c16c16c14882p-10", "0x1.a01a019bd7a58p-16", "-0x1.27e4f76fee955p-22",
         "0x1.1ee9852c97fedp-29", "-0x1.8f7a432d5ed09p-37")),
    "float": (
        ("-0x1.555556p-3", "0x1.111108p-7", "-0x1.a00e9cp-13", "0x1.6c9d78p-19"),
        ("0x1.555556p-5", "-0x1.6c16b6p-10", "0x1.a01008p-16", "-0x1.23f438p-22")),
}
UNIT = {"double": Fraction(1, 2 ** 53), "float": Fraction(1, 2 ** 24)}
XMAX = {"double": 2 ** 20, "float": 2 ** 14}        # beyond: libm's sin and cos
# the real type's nearest values of 2/pi and pi/2, and pi/2 itself to 40 digits
TWO_OVER_PI = {"double": "0x1.45f306dc9c883p-1", "float": "0x1.45f306p-1"}
PIO2_HEX = {"double": "0x1.921fb54442d18p+0", "float": "0x1.921fb6p+0"}
# the nearest value of pi/4 (|x| <= it: k = 0 and r = x, the case the polynomials start from)
PIO4_HEX = {"double": "0x1.921fb54442d18p-1", "float": "0x1.921fb6p-1"}
PI_OVER_2 = Fraction("1.570796326794896619231321691639751442098584699687552910487")
PI_OVER_2_ERR = Fraction(1, 10 ** 50)               # |PI_OVER_2 - pi/2| is below this
PIECES_APPROX, PIECES_EVAL = 32, 32


def _hex(text: str) -> Fraction:
    return Fraction(float.fromhex(text))


def _series(j: int, cos: bool) -> Fraction:
    """The z^j coefficient of S (sine) or C (cosine)."""
    return Fraction((-1) ** (j + 1 if not cos else j), factorial(2 * j + (4 if cos else 3)))


def _poly_bound(coefs: list[Fraction], lo: Fraction, hi: Fraction) -> Fraction:
    """max |sum c_j z^j| over [lo, hi]: its exact Taylor expansion at the centre."""
    m, h = (lo + hi) / 2, (hi - lo) / 2
    d = len(coefs)
    total = Fraction(0)
    for i in range(d):   # i-th Taylor coefficient at m: sum_j C(j, i) c_j m^(j-i)
        ti = sum(Fraction(factorial(j), factorial(i) * factorial(j - i)) * coefs[j] * m ** (j - i)
                 for j in range(i, d))
        total += abs(ti) * h ** i
    return total


def _approximation(real: str, cos: bool) -> Fraction:
    """sup over |r| <= R of |p(r) - f(r)| / |f(r)| for f = sin or cos."""
    coefs = [_hex(c) for c in COEFFICIENTS[real][1 if cos else 0]]
    d = len(coefs)
    Z = R * R
    extra = 8   # the series' next terms go into the exact polynomial (the fit compensates them)
    diff = [(coefs[j] if j < d else 0) - _series(j, cos) for j in range(d + extra)]
    worst = Fraction(0)
    for p in range(PIECES_APPROX):
        lo, hi = Z * p / PIECES_APPROX, Z * (p + 1) / PIECES_APPROX
        # tail sum_{j >= d + extra} of the series: alternating, terms decreasing (z <= 1): the first bounds it
        tail = hi ** (d + extra) / factorial(2 * (d + extra) + (4 if cos else 3))
        err = _poly_bound(diff, lo, hi) + tail
        if cos:   # |z^2 (Q - C)| / cos r, cos r >= 1 - z/2
            worst = max(worst, hi * hi * err / (1 - hi / 2))
        else:     # |r^3 (P - S)| / sin r, sin r >= r (1 - z/6)
            worst = max(worst, hi * err / (1 - hi / 6))
    return worst


class _Rel:
    """A computed quantity over a piece: the range of its exact-arithmetic value
    [lo, hi] and a bound rho of its relative error (computed = exact (1 + e), |e| <= rho)."""

    def __init__(self, lo: Fraction, hi: Fraction, rho: Fraction):
        self.lo, self.hi, self.rho = lo, hi, rho

    @property
    def absmax(self) -> Fraction:
        return max(abs(self.lo), abs(self.hi))

    @property
    def absmin(self) -> Fraction:
        return Fraction(0) if self.lo <= 0 <= self.hi else min(abs(self.lo), abs(self.hi))

    def mul(self, other: "_Rel", u: Fraction) -> "_Rel":
        ends = [a * b for a in (self.lo, self.hi) for b in (other.lo, other.hi)]
        return _Rel(min(ends), max(ends), (1 + self.rho) * (1 + other.rho) * (1 + u) - 1)

    def add(self, other: "_Rel", u: Fraction) -> "_Rel":
        lo, hi = self.lo + other.lo, self.hi + other.hi
        out = _Rel(lo, hi, Fraction(0))
        if out.absmin == 0:
            raise ArithmeticError("a sum that may vanish: no relative bound")
        err = self.rho * self.absmax + other.rho * other.absmax       # |error| before rounding
        out.rho = (err + u * (out.absmax + err)) / out.absmin
        return out


def _const(value: Fraction) -> _Rel:
    return _Rel(value, value, Fraction(0))


def _horner(coefs: list[Fraction], z: _Rel, u: Fraction) -> _Rel:
    h = _const(coefs[-1])
    for c in reversed(coefs[:-1]):
        h = _const(c).add(z.mul(h, u), u)
    return h


def _evaluation(real: str, cos: bool) -> Fraction:
    """sup over |r| <= R of the relative rounding error of the printed evaluation
    (r exact; symmetric in r: round to nearest is odd)."""
    u = UNIT[real]
    coefs = [_hex(c) for c in COEFFICIENTS[real][1 if cos else 0]]
    worst = Fraction(0)
    for p in range(PIECES_EVAL):
        zlo, zhi = R * R * p / PIECES_EVAL, R * R * (p + 1) / PIECES_EVAL
        z = _Rel(zlo, zhi, u)                        # r * r
        h = _horner(coefs, z, u)
        if cos:
            w = _const(Fraction(1)).add(_Rel(-zhi / 2, -zlo / 2, u), u)   # 1 - 0.5 z (0.5 z exact)
            t = z.mul(z, u).mul(h, u)
            out = w.add(t, u)
            worst = max(worst, out.rho)
        else:
            # s = r + (r z) h = r (1 + z h (1 + e)): relative to r, with r exact
            rz = _Rel(zlo, zhi, (1 + u) * (1 + u) - 1)      # (r * z) / r
            t = rz.mul(h, u)                                # ((r z) h) / r
            out = _const(Fraction(1)).add(t, u)             # s / r
            worst = max(worst, out.rho)
    return worst


@dataclass(frozen=True)
class TrigBound:
    """The proved error model of :func:`c_helper` for one real type:
    |f_hat(x) - f(x)| <= relative |f(x)| + (1 + relative) eta(k), f = sin or cos,
    eta(k) = |k| per_k + fixed for k != 0 and 0 for k = 0, |k| <= k_max(x)."""

    relative: float
    per_k: float
    fixed: float
    reduced: float       # the largest |r_hat| for |x| <= XMAX (at most R)


def _round_up(q: Fraction) -> float:
    f = float(q)
    return f if Fraction(f) >= q else math.nextafter(f, math.inf)


def reduced_range(real: str) -> Fraction:
    """An upper bound of |r_hat| over |x| <= XMAX."""
    u = UNIT[real]
    c2 = _hex(TWO_OVER_PI[real])
    pio2 = _hex(PIO2_HEX[real])
    x = Fraction(XMAX[real])
    t = x * c2 * (1 + u)                                       # |t| after its rounding
    # k = trunc(fl(t + 1/2)): |t - k| <= 1/2 + u (|t| + 1/2); |x 2/pi - t| <= |x| |c2 - 2/pi| + u |t|
    c2_err = abs(c2 - 1 / PI_OVER_2) + PI_OVER_2_ERR
    off = Fraction(1, 2) + u * (t + Fraction(1, 2)) + x * c2_err + u * t
    kmax = x * c2 + 1
    eta = kmax * (abs(pio2 - PI_OVER_2) + PI_OVER_2_ERR + u * pio2) + u * R
    return (PI_OVER_2 + PI_OVER_2_ERR) * off + eta


@cache
def bound(real: str) -> TrigBound:
    """The proved error model (see the module doc) of the real type's sine and cosine."""
    u = UNIT[real]
    rel = max(((1 + _approximation(real, cos)) * (1 + _evaluation(real, cos)) - 1 for cos in (False, True)))
    rel = max(rel, 2 * u)                                       # libm beyond XMAX: 1 ulp
    pio2 = _hex(PIO2_HEX[real])
    per_k = abs(pio2 - PI_OVER_2) + PI_OVER_2_ERR + u * pio2
    return TrigBound(_round_up(rel), _round_up(per_k), _round_up(u * R), _round_up(reduced_range(real)))


def k_max(x):
    """An upper bound of |k| for the argument(s) x (numpy arrays or floats): the
    integer nearest |x| 2/pi, allowing for the roundings of t (0 for |x| < pi/4 (1 - 1e-6))."""
    return np.floor(np.abs(x) * 0.6366197723675814 * (1 + 1e-6) + 0.5 + 1e-6)


def c_helper(real: str, real_type: str, needed: tuple[str, ...] = ("sin", "cos")) -> tuple[str, ...]:
    """The C text of the file's own sine and cosine for ``real`` ("double" or "float"),
    ``real_type`` the C name of the type (C99, <math.h>), the ``needed`` ones of (only those the
    file calls: compilers warn of an unused static function):

    * ``"sincos"``: ``static void trig_sincos(real x, real *s, real *c)``, one angle;
    * ``"sincos_n"``: ``static void trig_sincos_n(const real *x, real *s, real *c, int n)``,
      s[i] = sin x[i] and c[i] = cos x[i] for n lanes (n even, the arrays not overlapping);
    * ``"sin"``, ``"cos"``: ``trig_sin(x)``, ``trig_cos(x)``, wrappers of trig_sincos.

    trig_sincos_n goes in pairs of lanes: ``trig_poly`` evaluates the polynomials of lanes
    (i, i + 1) in a loop of exactly two iterations over ``restrict`` arrays, which gcc -O2 turns
    into one two-lane vector evaluation (SSE2 for double). Each lane is still the same IEEE
    operations in the same order as trig_sincos (a vector instruction rounds each lane as its
    scalar one does), so the proved bound holds lane by lane. When every |x[i]| <= PIO4 (k = 0,
    r = x: the common case of a controller's joint angles) the polynomials run straight on x;
    else up to eight lanes at a time are reduced (lane by lane, as trig_sincos does), evaluated
    in one trig_poly call, and turned by their quadrants, |x| > XMAX from libm (a pair at a time
    cost the Panda's npid_step 14 % at angles within +-2.88 rad, against 5 % less here). Each function holds one copy of the polynomials; the
    printer calls trig_sincos for a lone angle only in a file without trig_sincos_n (a one-lane
    pair would cost a scalar target a second polynomial; derive.codegen.views.kernel_views),
    so a file holds both only for a wrapper's computed angle or a one-entry port."""
    f = "f" if real == "float" else ""
    def lit(h: str) -> str:   # every value here is exact in the real type (a test checks the coefficients)
        return c_literal(float.fromhex(h), real)
    S, Q = COEFFICIENTS[real]
    T = real_type

    def horner(coefs):
        text = lit(coefs[-1])
        for c in reversed(coefs[:-1]):
            text = f"{lit(c)} + z * ({text})"
        return text

    def reduction(pad: str, x: str, k: str, r: str) -> tuple[str, ...]:   # x = k pi/2 + r
        return (f"{pad}t = {x} * {lit(TWO_OVER_PI[real])};",
                f"{pad}{k} = (long)(t + copysign{f}({lit('0x1p-1')}, t));",
                f"{pad}{r} = {x} - ({T}){k} * {lit(PIO2_HEX[real])};")

    def polynomials(pad: str, r: str, s: str, c: str) -> tuple[str, ...]:   # (sin r, cos r), z = r * r
        return (f"{pad}{s} = {r} + ({r} * z) * ({horner(S)});",
                f"{pad}{c} = ({lit('0x1p+0')} - {lit('0x1p-1')} * z) + (z * z) * ({horner(Q)});")

    def quadrant(pad: str, k: str, s: str, c: str) -> tuple[str, ...]:   # (sin r, cos r) -> (sin x, cos x)
        return (f"{pad}if ({k} & 1) {{   /* x = r + pi/2 (mod pi): sin x = cos r, cos x = -sin r */",
                f"{pad}    t = {s};", f"{pad}    {s} = {c};", f"{pad}    {c} = -t;", f"{pad}}}",
                f"{pad}if ({k} & 2) {{   /* x = r + pi (mod 2 pi): both change sign */",
                f"{pad}    {s} = -{s};", f"{pad}    {c} = -{c};", f"{pad}}}")

    b = bound(real)
    pio4, xmax = lit(PIO4_HEX[real]), lit(float(XMAX[real]).hex())
    one = "sincos" in needed or "sin" in needed or "cos" in needed
    head = (
        f"/* sin x and cos x (derive.codegen.trig): x = k pi/2 + r, |r| <= {float(R)}, polynomials in r;",
        f" * proved |error| <= {b.relative:.3g} |value| + {b.per_k:.3g} |k| + {b.fixed:.3g} (0 for k = 0),",
        " * for IEEE arithmetic in this order (a contracted multiply-add included; no underflow); no step",
        f" * needs extra precision that -ffast-math could remove. libm's sin{f} and cos{f} for |x| > {XMAX[real]}.",
    ) + ((
        " * One function for both (the polynomials are most of the code: one copy keeps a small",
        " * target's flash); trig_sin and trig_cos call it. */",
    ) if one else (
        " * trig_sincos_n takes n lanes (n even), in pairs: trig_poly's loop of two lanes is one vector",
        " * evaluation where the compiler vectorises it, the same operations in the same order in each",
        " * lane, so the bound holds for each. One copy of the polynomials (trig_poly): a small",
        " * target's flash. */",
    ))
    scalar = (
        f"static void trig_sincos({T} x, {T} *s, {T} *c)",
        "{",
        f"    {T} t, r = x, z, ps, pc;",
        "    long k = 0;",
        f"    if (!(fabs{f}(x) <= {pio4})) {{   /* else k = 0, r = x: no reduction */",
        f"        if (!(fabs{f}(x) <= {xmax})) {{",
        f"            *s = sin{f}(x);",
        f"            *c = cos{f}(x);",
        "            return;",
        "        }",
        *reduction("        ", "x", "k", "r"),
        "    }",
        "    z = r * r;",
        *polynomials("    ", "r", "ps", "pc"),
        *quadrant("    ", "k", "ps", "pc"),
        "    *s = ps;",
        "    *c = pc;",
        "}",
    )
    pairs = (
        ("/* trig_sincos_n: the same method for n lanes (n even) in pairs, trig_poly's loop of two lanes one",
         " * vector evaluation where the compiler vectorises it (the same operations in the same order",
         " * in each lane, so the bound holds for each). */") if one else ()) + (
        f"static void trig_poly(const {T} *restrict r, {T} *restrict s, {T} *restrict c, int n)",
        "{",
        f"    {T} z;",
        "    int i, j;",
        "    for (i = 0; i < n; i += 2)",
        "        for (j = i; j < i + 2; ++j) {   /* a pair of lanes */",
        "            z = r[j] * r[j];",
        *polynomials("            ", "r[j]", "s[j]", "c[j]"),
        "        }",
        "}",
        "",
        f"static void trig_sincos_n(const {T} *restrict x, {T} *restrict s, {T} *restrict c, int n)",
        "{",
        f"    {T} r[8], t;",
        "    long k[8];",
        "    int i, j, far = 0;",
        "    for (i = 0; i < n; ++i)",
        f"        far |= !(fabs{f}(x[i]) <= {pio4});",
        "    if (!far) {   /* every k = 0, r = x: no reduction */",
        "        trig_poly(x, s, c, n);",
        "        return;",
        "    }",
        "    for (i = 0; i < n; i += 8) {   /* up to eight lanes at a time: reduced, evaluated, turned */",
        "        int m = n - i < 8 ? n - i : 8;",
        "        for (j = 0; j < m; ++j) {",
        "            r[j] = x[i + j];",
        "            k[j] = 0;",
        f"            if (!(fabs{f}(r[j]) <= {pio4})) {{",
        f"                if (!(fabs{f}(r[j]) <= {xmax})) {{",
        "                    r[j] = 0;   /* libm below */",
        "                    continue;",
        "                }",
        *reduction("                ", "x[i + j]", "k[j]", "r[j]"),
        "            }",
        "        }",
        "        trig_poly(r, s + i, c + i, m);",
        "        for (j = i; j < i + m; ++j) {",
        f"            if (!(fabs{f}(x[j]) <= {xmax})) {{",
        f"                s[j] = sin{f}(x[j]);",
        f"                c[j] = cos{f}(x[j]);",
        "            }",
        *quadrant("            ", "k[j - i]", "s[j]", "c[j]"),
        "        }",
        "    }",
        "}",
    )
    text = head + (scalar if one else ()) + ((("",) if one else ()) + pairs if "sincos_n" in needed else ())
    return text + tuple(line for name in ("sin", "cos") if name in needed for line in (
        "", f"static {T} trig_{name}({T} x)", "{", f"    {T} s, c;", "    trig_sincos(x, &s, &c);",
        f"    return {name[0]};", "}"))
