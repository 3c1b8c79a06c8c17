/* Fuzz driver for a generated controller (hand-written test code, not generated).
 *
 * Compile with -DARM=<arm> -DARM_H='"<arm>.h"' [-DRUNTIME] and the library sources.
 * For ITER iterations it builds inputs from a small PRNG in several regimes (ordinary,
 * extreme: |x| up to 1e6 and 1e300, NaN, +-Inf, tiny dt, negative dt), calls every
 * entry point and checks the contract: a dt that is not finite and > 0 gives EDT from the
 * steps, else a non-finite input or state ENONFINITE (the code is checked, not only its
 * being non-zero: a library that returned OK with a finite u fails); a non-zero code leaves
 * the state bit-for-bit untouched and u and the clipped mask unwritten; a zero code gives
 * finite u, a finite state and a mask with bits of existing joints only (mpc_step takes a
 * NULL mask).
 * Prints "N passed, N failed"; exits non-zero on any failure. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include ARM_H

#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)
#define FN(name) CAT(ARM, CAT(_, name))
#define T(name) CAT(ARM, CAT(_, name))
#define NJ CAT(ARM_UPPER, _N)
#define ENONFINITE CAT(ARM_UPPER, _ENONFINITE)
#define EDT CAT(ARM_UPPER, _EDT)

#ifdef RUNTIME
#define P &params,
#else
#define P
#endif

typedef T(real) real;

static unsigned long long rng_state = 0x9E3779B97F4A7C15ull;

static unsigned long long next_u64(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return rng_state;
}

static double uniform(double lo, double hi)
{
    return lo + (hi - lo) * (double)(next_u64() >> 11) / 9007199254740992.0;
}

static real sample(int regime)
{
    switch (regime) {
    case 0: return (real)uniform(-3.0, 3.0);
    case 1: return (real)uniform(-1e6, 1e6);
    case 2: return (next_u64() & 1) ? (real)1e30 : (real)-1e30;
    case 3: return (real)NAN;
    case 4: return (next_u64() & 1) ? (real)INFINITY : (real)-INFINITY;
    default: return (real)uniform(-1e-300, 1e-300);
    }
}

static int finite_all(const real *x, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        if (!isfinite(x[i])) return 0;
    }
    return 1;
}

int main(int argc, char **argv)
{
    long iterations = argc > 1 ? atol(argv[1]) : 10000, k;
    long passed = 0, failed = 0, errors = 0;
#ifdef RUNTIME
    T(params) params;
    T(params_default)(&params);
#endif
    for (k = 0; k < iterations; ++k) {
        T(input) in;
        T(npid_state) ns, ns0;
        T(dobc_state) ds, ds0;
        real u[NJ], u0[NJ], P_[NJ * NJ], D_[NJ * NJ], I_[NJ * NJ], dt;
        const T(mask) unset = (T(mask))0xA5A5u << NJ;   /* bits no joint owns */
        T(mask) clip = unset;
        int i, code, regime = (int)(next_u64() % 6), ok = 1, bad_in, bad_dt;
        for (i = 0; i < NJ; ++i) { /* mostly ordinary values, some fields in another regime */
            in.theta[i] = sample((next_u64() % 4 == 0) ? regime : 0);
            in.dtheta[i] = sample((next_u64() % 4 == 0) ? regime : 0);
            in.yd[i] = sample((next_u64() % 4 == 0) ? regime : 0);
            in.dyd[i] = sample((next_u64() % 4 == 0) ? regime : 0);
            in.ddyd[i] = sample((next_u64() % 4 == 0) ? regime : 0);
            ns.int_e[i] = sample((next_u64() % 8 == 0) ? regime : 0);
            ds.z[i] = sample((next_u64() % 8 == 0) ? regime : 0);
            u[i] = u0[i] = (real)12345.0;
        }
        dt = (next_u64() % 10 == 0) ? sample((int)(next_u64() % 6)) : (real)1e-3;
        bad_in = !(finite_all(in.theta, NJ) && finite_all(in.dtheta, NJ) && finite_all(in.yd, NJ)
                   && finite_all(in.dyd, NJ) && finite_all(in.ddyd, NJ));
        bad_dt = !(isfinite(dt) && dt > 0);
        ns0 = ns;
        ds0 = ds;
        FN(gains)(P in.theta, P_, D_, I_);
        code = FN(npid_step)(P &ns, &in, dt, u, &clip);
        if (bad_dt) ok &= code == EDT;
        else if (bad_in || !finite_all(ns0.int_e, NJ)) ok &= code == ENONFINITE;
        if (code != 0) {
            ok &= memcmp(&ns, &ns0, sizeof ns) == 0 && memcmp(u, u0, sizeof u) == 0 && clip == unset;
            ++errors;
        } else {
            ok &= finite_all(u, NJ) && finite_all(ns.int_e, NJ) && (clip >> NJ) == 0;
        }
        memcpy(u, u0, sizeof u);
        clip = unset;
        code = FN(dobc_step)(P &ds, &in, dt, u, &clip);
        if (bad_dt) ok &= code == EDT;
        else if (bad_in || !finite_all(ds0.z, NJ)) ok &= code == ENONFINITE;
        if (code != 0) {
            ok &= memcmp(&ds, &ds0, sizeof ds) == 0 && memcmp(u, u0, sizeof u) == 0 && clip == unset;
            ++errors;
        } else {
            ok &= finite_all(u, NJ) && finite_all(ds.z, NJ) && (clip >> NJ) == 0;
        }
        memcpy(u, u0, sizeof u);
        code = FN(mpc_step)(P &in, u, NULL);
        ok &= !bad_in || code == ENONFINITE;
        ok &= code != 0 ? memcmp(u, u0, sizeof u) == 0 : finite_all(u, NJ);
        ds0 = ds;
        code = FN(dobc_init)(P &ds, &in);
        ok &= !bad_in || code == ENONFINITE;
        ok &= code != 0 ? memcmp(&ds, &ds0, sizeof ds) == 0 : finite_all(ds.z, NJ);
        code = FN(npid_init)(P &ns, &in);
        ok &= !bad_in || code == ENONFINITE;
        ok &= code != 0 || (finite_all(ns.int_e, NJ) && ns.int_e[0] == 0);
        if (ok) {
            ++passed;
        } else {
            ++failed;
            if (failed <= 5) printf("FAIL iteration %ld (regime %d)\n", k, regime);
        }
    }
    printf("fuzz: %ld iterations, %ld error codes returned\n", iterations, errors);
    printf("%ld passed, %ld failed\n", passed, failed);
    return failed != 0;
}
