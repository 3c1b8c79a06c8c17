"""The generated C's own sine and cosine (derive.codegen.trig): the proof's figures, that
the proof is sharp enough to catch a wrong coefficient, and the compiled helper against a
long-double reference at 3 million points per real type (dense in [-8, 8], 64 values
either side of k pi/4 and k 64 pi for |k| <= 4096, 2,000 either side of the libm limit), under gcc and clang at -O0, -O2, -Ofast
and -O2 -march=native with FMA contraction: its error within the proved
eps |f| + (1 + eps) eta(k), and at least a quarter of it reached (the bound is not vacuous)."""
from __future__ import annotations

import shutil
import subprocess
from fractions import Fraction

import mpmath as mp
import pytest

from derive.codegen import trig

DRIVER = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
typedef REAL real;
#define NEXT NEXTAFTER
HELPER

static long double worst[2];
static double where[2];

static real last[3];   /* the last three arguments: the other lanes of each call */

/* x through trig_sincos, and in six lanes (both chunks of eight) of a trig_sincos_n call of ten
 * lanes with the last three arguments (so that a lane's result is checked whichever way its
 * neighbours go: reduced or not, libm or not) */
static void check(real x, double rel, double per_k, double fixed)
{
    static const int at[6] = { 0, 1, 4, 7, 8, 9 };
    real xs10[10], s[11], c[11];
    long double xs = (long double)x, ref[2], got[2], k, bound;
    int f, lane, j;
    ref[0] = sinl(xs); ref[1] = cosl(xs);
    k = floorl(fabsl(xs) * 0.63661977236758134308L * (1 + 1e-6L) + 0.5L + 1e-6L);
    for (lane = 0; lane < 7; ++lane) {
        if (lane == 6) {
            trig_sincos(x, &s[10], &c[10]);
            got[0] = s[10]; got[1] = c[10];
        } else {
            for (j = 0; j < 10; ++j) xs10[j] = last[(j + lane) % 3];
            xs10[at[lane]] = x;
            trig_sincos_n(xs10, s, c, 10);
            got[0] = s[at[lane]]; got[1] = c[at[lane]];
        }
        for (f = 0; f < 2; ++f) {
            bound = rel * fabsl(ref[f]) + (k > 0 ? (1 + rel) * (k * per_k + fixed) : 0) + 4e-19L * fabsl(ref[f]);
            if (fabsl(got[f] - ref[f]) / bound > worst[f]) { worst[f] = fabsl(got[f] - ref[f]) / bound; where[f] = x; }
        }
    }
    last[2] = last[1]; last[1] = last[0]; last[0] = x;
}

int main(int argc, char **argv)
{
    double rel = argc > 4 ? atof(argv[1]) : 0, per_k = atof(argv[2]), fixed = atof(argv[3]), xmax = atof(argv[4]);
    unsigned long long state = 88172645463325252ULL;
    long i, j;
    for (i = 0; i < 2000000; ++i) {              /* dense: [-8, 8] */
        state ^= state << 13; state ^= state >> 7; state ^= state << 17;
        check((real)(16.0 * ((double)(state >> 11) / 9007199254740992.0) - 8.0), rel, per_k, fixed);
    }
    check(0, rel, per_k, fixed);
    for (i = -4096; i <= 4096; ++i) {             /* 64 values either side of k pi/4 and of k 64 pi, 0 < |k| <= 4096 */
        real x[2] = { (real)(i * 0.78539816339744830962), (real)(i * 201.06192982974676726) };
        int side, m, p;
        if (i == 0) continue;   /* subnormals: outside the standard model (no underflow), flushed under -Ofast */
        for (p = 0; p < 2; ++p)
            for (side = -1; side <= 1; side += 2) {
                real z = x[p];
                for (m = 0; m < 64; ++m) {
                    if (fabs((double)z) <= 2 * xmax) check(z, rel, per_k, fixed);
                    z = NEXT(z, side * (real)1e30);
                }
            }
    }
    for (j = 0; j < 2; ++j) {                     /* 2,000 values either side of the libm limit */
        real x = (real)xmax, y = (real)xmax;
        int m;
        for (m = 0; m < 2000; ++m) {
            check(x, rel, per_k, fixed); check(-x, rel, per_k, fixed);
            check(y, rel, per_k, fixed); check(-y, rel, per_k, fixed);
            x = NEXT(x, (real)0); y = NEXT(y, (real)1e30);
        }
    }
    printf("%.6Lg %.17g %.6Lg %.17g\n", worst[0], where[0], worst[1], where[1]);
    return 0;
}
"""

# -std=gnu99: GCC contracts a * b + c into an FMA only outside ISO mode
BUILDS = [("gcc", "-O0"), ("gcc", "-O2"), ("gcc", "-Ofast"), ("gcc", "-O2 -march=native -std=gnu99"),
          ("clang", "-O2"), ("clang", "-Ofast"), ("clang", "-O2 -march=native -ffp-contract=fast")]


@pytest.mark.parametrize("real", ["double", "float"])
def test_trig_proved_bound(real):
    """The proof's figures: a relative error of about 2.6 unit roundoffs (libm: 2), a reduction
    error of about 2.1-2.3 u per quadrant, and every |x| <= XMAX reduced into |r| <= R."""
    b = trig.bound(real)
    u = float(trig.UNIT[real])
    assert 2 * u <= b.relative <= 2.7 * u
    assert b.per_k <= 2.4 * u and b.fixed <= u
    assert b.reduced <= float(trig.R)


@pytest.mark.parametrize("real", ["double", "float"])
def test_trig_approximation_bound_is_sharp(real):
    """The certified approximation error against the polynomial's error at 400 points (mpmath,
    40 digits): never above, and at least 75 % of the bound is reached."""
    mp.mp.dps = 40
    for cos in (False, True):
        coefs = [mp.mpf(float.fromhex(c)) for c in trig.COEFFICIENTS[real][1 if cos else 0]]
        worst = mp.mpf(0)
        for i in range(1, 401):
            r = mp.mpf(float(trig.R)) * i / 400
            z = r * r
            poly = sum(c * z ** j for j, c in enumerate(coefs))
            value, exact = ((1 - z / 2 + z * z * poly), mp.cos(r)) if cos else (r + r * z * poly, mp.sin(r))
            worst = max(worst, abs(value - exact) / abs(exact))
        proved = trig._approximation(real, cos)
        assert float(worst) <= float(proved) and float(worst) >= 0.75 * float(proved), (cos, worst, proved)


def test_trig_proof_catches_a_wrong_coefficient(monkeypatch):
    """The proof fails a polynomial with one coefficient off in its last place but one (a
    rounding to float of a double coefficient): its bound grows past the limit tested above."""
    good = trig.COEFFICIENTS["double"]
    sine = list(good[0])
    sine[3] = float(float.fromhex(sine[3]) * (1 + 2 ** -24)).hex()
    monkeypatch.setitem(trig.COEFFICIENTS, "double", (tuple(sine), good[1]))
    assert trig._approximation("double", False) > 10 * trig.UNIT["double"]


def test_trig_evaluation_analysis_counts_every_rounding():
    """The running error analysis of the printed order: with u = 0 it proves no error, and its
    bound grows with u (each rounding is counted)."""
    saved = dict(trig.UNIT)
    try:
        trig.UNIT["double"] = Fraction(0)
        assert trig._evaluation("double", False) == 0 and trig._evaluation("double", True) == 0
    finally:
        trig.UNIT.update(saved)
    assert trig._evaluation("double", True) > trig._evaluation("double", False) > trig.UNIT["double"]


# float at 3 million points under every build is a slow check (make fuzz); double runs in make test
@pytest.mark.parametrize("real", ["double", pytest.param("float", marks=pytest.mark.slow)])
def test_trig_compiled_within_proved_bound(real, tmp_path):
    """The compiled helper at 3 million points (see the module doc) within the proved bound
    under every build; the largest ratio error / bound at least 1/4 (x86-64 long double
    reference, 64-bit significand: its own error is added to the bound)."""
    b = trig.bound(real)
    src = DRIVER.replace("NEXTAFTER", "nextafterf" if real == "float" else "nextafter").replace(
        "REAL", real).replace("HELPER", "\n".join(trig.c_helper(real, "real", ("sincos", "sincos_n"))))
    (tmp_path / "trig.c").write_text(src)
    worst = []
    for cc, flags in BUILDS:
        if shutil.which(cc) is None:
            pytest.fail(f"{cc} is not installed (make system-deps installs it)")
        exe = tmp_path / f"trig_{cc}_{flags.replace(' ', '_')}"
        subprocess.run([cc, "-std=c99", "-Wall", "-Wextra", "-Werror", *flags.split(), "-o", str(exe),
                        str(tmp_path / "trig.c"), "-lm"], check=True)
        out = subprocess.run([str(exe), repr(b.relative), repr(b.per_k), repr(b.fixed), repr(float(trig.XMAX[real]))],
                             check=True, capture_output=True, text=True).stdout.split()
        ratio_sin, x_sin, ratio_cos, x_cos = float(out[0]), out[1], float(out[2]), out[3]
        print(real, cc, flags, out)
        assert ratio_sin <= 1 and ratio_cos <= 1, (cc, flags, out)
        worst.append(max(ratio_sin, ratio_cos))
    assert max(worst) >= 0.25, worst


def test_printer_computes_the_trig_of_inputs_first_and_drops_dead_loads():
    """own_trig: the sines and cosines of a port's input entries become one trig_sincos_n call
    at the top per run of lanes, straight from the input array into the arrays ts0, tc0
    (declared in Printed.arrays); a port's lone angle one trig_sincos call into two registers;
    the entry's load is printed only when something else reads it, and the sine of a computed
    value calls the trig_sin wrapper; without own_trig, libm as before."""
    import casadi as ca

    from derive.codegen.printing import print_function

    x = ca.SX.sym("x", 3)
    q = ca.SX.sym("q", 2)
    f = ca.Function("k", [x, q], [ca.vertcat(ca.sin(x[0]) * ca.cos(x[0]) + ca.cos(x[1]) + ca.cos(q[1]),
                                             ca.sin(x[0] + x[2]))], ["x", "q"], ["y"])
    printed = print_function(f, "c", "double", own_trig=True)
    body = printed.statements
    calls = [line for line in body if line.startswith("trig_sincos")]
    regs = f.sz_w()
    assert calls == ["trig_sincos_n(x, ts0, tc0, 2);", f"trig_sincos(q[1], &a{regs}, &a{regs + 1});"]
    assert body[:2] == tuple(calls) and printed.registers == regs + 2
    assert printed.arrays == ("ts0[2]", "tc0[2]")
    assert sum("= ts0[0];" in line for line in body) == 1 and sum("= tc0[0];" in line for line in body) == 1
    assert sum("= tc0[1];" in line for line in body) == 1 and not any("= ts0[1];" in line for line in body)
    assert sum(f"= a{regs + 1};" in line for line in body) == 1   # cos q1
    assert sum("= x[0];" in line for line in body) == 1      # read by the sum x0 + x2
    assert not any("= x[1];" in line or "= q[1];" in line for line in body)   # only their cosines are taken
    assert any("trig_sin(" in line for line in body)
    plain = print_function(f, "c", "double").statements
    assert not any("trig_" in line for line in plain) and any("sin(" in line for line in plain)


def test_trig_runs_cover_the_entries_in_pairs_within_the_port():
    """The runs of lanes: even counts, inside the port, covering every entry asked for."""
    from derive.codegen.printing import trig_runs

    assert trig_runs([2, 1, 3, 4, 5, 6], 7) == [(1, 6)]       # the Panda: joints 2..7
    assert trig_runs(list(range(7)), 7) == [(0, 6), (5, 2)]   # the last entry with its neighbour
    assert trig_runs([6], 7) == [(5, 2)]
    assert trig_runs([0, 3], 7) == [(0, 2), (3, 2)]
    for size in range(2, 9):
        for mask in range(1, 2 ** size):
            if bin(mask).count('1') < 2:
                continue   # a lone angle goes to trig_sincos
            wanted = [i for i in range(size) if mask >> i & 1]
            runs = trig_runs(wanted, size)
            assert all(n % 2 == 0 and 0 <= a and a + n <= size for a, n in runs)
            assert all(any(a <= i < a + n for a, n in runs) for i in wanted)


@pytest.mark.parametrize("real", ["double", "float"])
def test_trig_constants_are_exact_in_the_real_type(real):
    """Every number the helper prints (coefficients, 2/pi, pi/2, pi/4) is a value of the real type,
    so the C literal is the value the proof used."""
    import numpy as np

    kind = np.float32 if real == "float" else np.float64
    texts = [*trig.COEFFICIENTS[real][0], *trig.COEFFICIENTS[real][1], trig.TWO_OVER_PI[real],
             trig.PIO2_HEX[real], trig.PIO4_HEX[real]]
    for text in texts:
        value = float.fromhex(text)
        assert float(kind(value)) == value, (real, text)


def test_a_file_holds_one_copy_of_the_polynomials():
    """A lone angle calls trig_sincos, unless another kernel of the same file calls
    trig_sincos_n: then it goes through a pair too (derive.codegen.views.kernel_views), so the
    file's helper holds the polynomials once; a file of lone angles keeps trig_sincos alone."""
    import sympy as sp

    from derive.codegen.kernels import KernelSpec, Port
    from derive.codegen.views import kernel_views, trig_helper

    q0, q1 = sp.symbols("q0 q1")
    lone = KernelSpec("lone", (Port("theta", (q0, q1), "angles"),), (Port("y", (sp.sin(q1),), "out"),), "one angle")
    both = KernelSpec("both", (Port("theta", (q0, q1), "angles"),),
                      (Port("y", (sp.sin(q0) * sp.cos(q1),), "out"),), "two angles")
    alone = kernel_views((lone,), "double", "arm")
    assert alone[0].c_body[0] == "trig_sincos(theta[1], &a1, &a2);"
    helper = trig_helper(alone, "double", "arm")
    assert sum(line.startswith("static void trig_sincos(") for line in helper) == 1
    assert not any(line.startswith("static void trig_sincos_n(") for line in helper)
    mixed = kernel_views((lone, both), "double", "arm")
    assert mixed[0].c_body[0] == "trig_sincos_n(theta, ts0, tc0, 2);"
    assert mixed[1].c_body[0] == "trig_sincos_n(theta, ts0, tc0, 2);"
    helper = trig_helper(mixed, "double", "arm")
    assert not any(line.startswith("static void trig_sincos(") for line in helper)
    assert sum("z = r[j] * r[j];" in line for line in helper) == 1   # the polynomials once
