/* The documented error contract of a generated controller, case by case (hand-written
 * test code, not generated): a non-finite input, state or dt gives the error code and
 * leaves the state and u untouched; a result that overflows from finite inputs too.
 *
 * Built WITHOUT finite-math flags and linked against a library built WITH them
 * (-ffast-math, -Ofast, -ffinite-math-only, -fno-honor-nans, ...): the library's checks
 * must survive those flags (issue 10, item 3). Compile with -DARM=<arm>
 * -DARM_UPPER=<ARM> -DARM_H='"<arm>.h"' [-DRUNTIME] [-DSPIN_JOINT=<j>: a joint whose velocity
 * enters G squared, for the case of a result that overflows]. Prints one line per failed case
 * and "N cases, N failed" (the count depends on the arm's n); exits non-zero on any failure. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include ARM_H
#include "cases.h"

#ifdef RUNTIME
#define P &params,
static T(params) params;
#else
#define P
#endif

static T(input) ordinary(void)
{
    T(input) in;
    int i;
    for (i = 0; i < NJ; ++i) {
        in.theta[i] = (real)(0.1 * (i + 1));
        in.dtheta[i] = (real)(-0.2 * i);
        in.yd[i] = (real)0.5;
        in.dyd[i] = (real)0.0;
        in.ddyd[i] = (real)0.0;
    }
    return in;
}

/* Every step (and, when code_in != -1, mpc_step and dobc_init) with `in`: code_dt from the
 * steps, code_in from the others, state and u untouched. */
static void all_refuse(const char *what, T(input) in, real dt, int code_in, int code_dt)
{
    T(npid_state) ns, ns0;
    T(dobc_state) ds, ds0;
    T(mom_state) ms, ms0;
    T(input) good = ordinary();
    real u[NJ], u0[NJ];
    char label[160];
    int i;
    for (i = 0; i < NJ; ++i) u[i] = u0[i] = (real)12345.0;
    T(npid_init)(P &ns, &good);
    T(dobc_init)(P &ds, &good);
    T(mom_init)(P &ms, &good);
    ns0 = ns;
    ds0 = ds;
    ms0 = ms;
    snprintf(label, sizeof label, "npid_step, %s", what);
    expect(label, T(npid_step)(P &ns, &in, dt, u, NULL) == code_dt && !memcmp(&ns, &ns0, sizeof ns)
                  && !memcmp(u, u0, sizeof u));
    snprintf(label, sizeof label, "dobc_step, %s", what);
    expect(label, T(dobc_step)(P &ds, &in, dt, u, NULL) == code_dt && !memcmp(&ds, &ds0, sizeof ds)
                  && !memcmp(u, u0, sizeof u));
    snprintf(label, sizeof label, "mom_step, %s", what);
    expect(label, T(mom_step)(P &ms, &in, dt, u, NULL) == code_dt && !memcmp(&ms, &ms0, sizeof ms)
                  && !memcmp(u, u0, sizeof u));
    if (code_in != -1) {
        snprintf(label, sizeof label, "mpc_step, %s", what);
        expect(label, T(mpc_step)(P &in, u, NULL) == code_in && !memcmp(u, u0, sizeof u));
    }
    if (code_in != -1 && strstr(what, "overflows") == NULL) { /* z(0) is linear in theta', no overflow */
        snprintf(label, sizeof label, "dobc_init, %s", what);
        expect(label, T(dobc_init)(P &ds, &in) == code_in && !memcmp(&ds, &ds0, sizeof ds));
        snprintf(label, sizeof label, "npid_init, %s", what);
        expect(label, T(npid_init)(P &ns, &in) == code_in && !memcmp(&ns, &ns0, sizeof ns));
        snprintf(label, sizeof label, "mom_init, %s", what);
        expect(label, T(mom_init)(P &ms, &in) == code_in && !memcmp(&ms, &ms0, sizeof ms));
    }
}

/* A NaN, Inf and -Inf in each element of each input field and of each step's state, one at
 * a time: the glue reads the input as one array of 5 n reals and the values in lanes, so
 * that no position (a lane, the tail after the last whole group of lanes) goes unread. */
static void every_element(real dt, real nan_, real inf)
{
    const real bad[3] = { nan_, inf, -inf };
    const char *bad_name[3] = { "NaN", "Inf", "-Inf" }, *field_name[5] = { "theta", "dtheta", "yd", "dyd", "ddyd" };
    T(input) in, good = ordinary();
    T(npid_state) ns, ns0;
    T(dobc_state) ds, ds0;
    T(mom_state) ms, ms0;
    real u[NJ], u0[NJ], *field[5];
    char label[160];
    int f, i, b;
    for (i = 0; i < NJ; ++i) u[i] = u0[i] = (real)12345.0;
    for (f = 0; f < 5; ++f)
        for (i = 0; i < NJ; ++i)
            for (b = 0; b < 3; ++b) {
                in = ordinary();
                field[0] = in.theta; field[1] = in.dtheta; field[2] = in.yd; field[3] = in.dyd; field[4] = in.ddyd;
                field[f][i] = bad[b];
                snprintf(label, sizeof label, "%s[%d] = %s", field_name[f], i, bad_name[b]);
                all_refuse(label, in, dt, C(ENONFINITE), C(ENONFINITE));
            }
    for (i = 0; i < NJ; ++i)
        for (b = 0; b < 3; ++b) {
            T(npid_init)(P &ns, &good);
            T(dobc_init)(P &ds, &good);
            T(mom_init)(P &ms, &good);
            ns.int_e[i] = bad[b];
            ds.z[i] = bad[b];
            ms.m[i] = bad[b];
            ns0 = ns;
            ds0 = ds;
            ms0 = ms;
            snprintf(label, sizeof label, "npid_step, int_e[%d] = %s", i, bad_name[b]);
            expect(label, T(npid_step)(P &ns, &good, dt, u, NULL) == C(ENONFINITE) && !memcmp(&ns, &ns0, sizeof ns)
                          && !memcmp(u, u0, sizeof u));
            snprintf(label, sizeof label, "dobc_step, z[%d] = %s", i, bad_name[b]);
            expect(label, T(dobc_step)(P &ds, &good, dt, u, NULL) == C(ENONFINITE) && !memcmp(&ds, &ds0, sizeof ds)
                          && !memcmp(u, u0, sizeof u));
            snprintf(label, sizeof label, "mom_step, m[%d] = %s", i, bad_name[b]);
            expect(label, T(mom_step)(P &ms, &good, dt, u, NULL) == C(ENONFINITE) && !memcmp(&ms, &ms0, sizeof ms)
                          && !memcmp(u, u0, sizeof u));
        }
}

int main(void)
{
    volatile real zero = 0;
    const real nan_ = zero / zero, inf = (real)1 / zero;
#ifdef SPIN_JOINT
    /* dtheta[SPIN_JOINT] = huge: that joint's velocity enters G squared (the test finds such a
     * joint in the derivation; a 1-joint arm, or a prismatic joint, has none), which overflows */
    const real huge = sizeof(real) == sizeof(double) ? (real)1e200 : (real)1e30;
#endif
    const real dt = (real)1e-3;
    const real bad_dt[] = { nan_, inf, -inf, 0, -dt };
    const char *bad_dt_name[] = { "dt = NaN", "dt = Inf", "dt = -Inf", "dt = 0", "dt < 0" };
    T(input) in;
    T(npid_state) ns, ns0;
    T(dobc_state) ds, ds0;
    T(mom_state) ms;
    real u[NJ], u0[NJ];
    int i, k;
#ifdef RUNTIME
    T(params_default)(&params);
#endif
    for (i = 0; i < NJ; ++i) u[i] = u0[i] = (real)12345.0;

    in = ordinary(); in.theta[0] = nan_;
    all_refuse("theta[0] = NaN", in, dt, C(ENONFINITE), C(ENONFINITE));
    in = ordinary(); in.dtheta[NJ - 1] = inf;
    all_refuse("dtheta[n-1] = Inf", in, dt, C(ENONFINITE), C(ENONFINITE));
    in = ordinary(); in.yd[0] = -inf;
    all_refuse("yd[0] = -Inf", in, dt, C(ENONFINITE), C(ENONFINITE));
    in = ordinary(); in.dyd[NJ - 1] = nan_;
    all_refuse("dyd[n-1] = NaN", in, dt, C(ENONFINITE), C(ENONFINITE));
    in = ordinary(); in.ddyd[0] = nan_;
    all_refuse("ddyd[0] = NaN", in, dt, C(ENONFINITE), C(ENONFINITE));
    for (k = 0; k < 5; ++k) all_refuse(bad_dt_name[k], ordinary(), bad_dt[k], -1, C(EDT));
#ifdef SPIN_JOINT
    /* finite inputs whose results overflow */
    in = ordinary(); in.dtheta[SPIN_JOINT] = huge;
    all_refuse("dtheta[SPIN_JOINT] = huge (the result overflows)", in, dt, C(ENONFINITE), C(ENONFINITE));
#endif

    /* a non-finite state */
    in = ordinary();
    T(npid_init)(P &ns, &in);
    ns.int_e[0] = nan_;
    ns0 = ns;
    expect("npid_step, int_e[0] = NaN", T(npid_step)(P &ns, &in, dt, u, NULL) == C(ENONFINITE)
           && !memcmp(&ns, &ns0, sizeof ns) && !memcmp(u, u0, sizeof u));
    T(dobc_init)(P &ds, &in);
    ds.z[NJ - 1] = -inf;
    ds0 = ds;
    expect("dobc_step, z[n-1] = -Inf", T(dobc_step)(P &ds, &in, dt, u, NULL) == C(ENONFINITE)
           && !memcmp(&ds, &ds0, sizeof ds) && !memcmp(u, u0, sizeof u));

    every_element(dt, nan_, inf);

    /* and the ordinary case still succeeds with finite results */
    T(npid_init)(P &ns, &in);
    T(dobc_init)(P &ds, &in);
    expect("npid_step, ordinary input", T(npid_step)(P &ns, &in, dt, u, NULL) == C(OK) && isfinite(u[0]));
    expect("dobc_step, ordinary input", T(dobc_step)(P &ds, &in, dt, u, NULL) == C(OK) && isfinite(u[0]));
    expect("mpc_step, ordinary input", T(mpc_step)(P &in, u, NULL) == C(OK) && isfinite(u[0]));
    T(mom_init)(P &ms, &in);
    expect("mom_step, ordinary input", T(mom_step)(P &ms, &in, dt, u, NULL) == C(OK) && isfinite(u[0]));

    printf("%d cases, %d failed\n", cases, failed);
    return failed != 0;
}
