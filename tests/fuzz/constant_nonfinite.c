/* The error contract when the non-finite value is a compile-time constant (hand-written test
 * code, not generated): built with link-time optimisation, the caller's constant can reach
 * the kernels' arithmetic, which -ffast-math (clang: the nnan/ninf flags) may fold to any
 * value. Each case is written out (no loop, no parameter) so that the constant is visible.
 * Compile with -DARM=<arm> -DARM_UPPER=<ARM> -DARM_H='"<arm>.h"'. Prints one line per
 * failed case and "N cases, N failed"; exits non-zero on any failure. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include ARM_H
#include "cases.h"

static void ordinary(T(input) *in)
{
    int i;
    for (i = 0; i < NJ; ++i) {
        in->theta[i] = (real)(0.1 * (i + 1));
        in->dtheta[i] = (real)(-0.2 * i);
        in->yd[i] = (real)0.5;
        in->dyd[i] = (real)0.0;
        in->ddyd[i] = (real)0.0;
    }
}

/* estimate: dobc_estimate or mom_estimate; state: dobc or mom; lvalue: the entry set to value */
#define ESTIMATE(estimate, state, init, lvalue, value, label) do { \
        T(input) in; T(state) s, s0; real d[NJ], d0[NJ]; int j; \
        ordinary(&in); T(init)(&s, &in); lvalue = (real)(value); s0 = s; \
        for (j = 0; j < NJ; ++j) d[j] = d0[j] = (real)12345; \
        expect(label, T(estimate)(&s, &in, d) == C(ENONFINITE) && !memcmp(d, d0, sizeof d) \
                      && !memcmp(&s, &s0, sizeof s)); \
    } while (0)

#define STEP(step, state, init, lvalue, value, label) do { \
        T(input) in; T(state) s, s0; real u[NJ], u0[NJ]; int j; \
        ordinary(&in); T(init)(&s, &in); lvalue = (real)(value); s0 = s; \
        for (j = 0; j < NJ; ++j) u[j] = u0[j] = (real)12345; \
        expect(label, T(step)(&s, &in, (real)1e-3, u, NULL) == C(ENONFINITE) && !memcmp(u, u0, sizeof u) \
                      && !memcmp(&s, &s0, sizeof s)); \
    } while (0)

int main(void)
{
    ESTIMATE(dobc_estimate, dobc_state, dobc_init, in.dtheta[0], NAN, "dobc_estimate, dtheta[0] = NaN");
    ESTIMATE(dobc_estimate, dobc_state, dobc_init, in.dtheta[0], INFINITY, "dobc_estimate, dtheta[0] = Inf");
    ESTIMATE(dobc_estimate, dobc_state, dobc_init, in.dtheta[NJ - 1], -INFINITY, "dobc_estimate, dtheta[n-1] = -Inf");
    ESTIMATE(dobc_estimate, dobc_state, dobc_init, s.z[0], NAN, "dobc_estimate, z[0] = NaN");
    ESTIMATE(mom_estimate, mom_state, mom_init, in.dtheta[0], NAN, "mom_estimate, dtheta[0] = NaN");
    ESTIMATE(mom_estimate, mom_state, mom_init, s.m[0], INFINITY, "mom_estimate, m[0] = Inf");
    STEP(npid_step, npid_state, npid_init, in.theta[0], NAN, "npid_step, theta[0] = NaN");
    STEP(npid_step, npid_state, npid_init, in.ddyd[NJ - 1], INFINITY, "npid_step, ddyd[n-1] = Inf");
    STEP(mom_step, mom_state, mom_init, in.theta[0], NAN, "mom_step, theta[0] = NaN");
    STEP(mom_step, mom_state, mom_init, s.m[0], INFINITY, "mom_step, m[0] = Inf");
    STEP(npid_step, npid_state, npid_init, s.int_e[0], -INFINITY, "npid_step, int_e[0] = -Inf");
    printf("%d cases, %d failed\n", cases, failed);
    return failed != 0;
}
