/* Shared by the case drivers of the generated controller's error contract (hand-written test
 * code, not generated): nonfinite_cases.c and constant_nonfinite.c. Include after ARM_H;
 * compile with -DARM=<arm> -DARM_UPPER=<ARM> -DARM_H='"<arm>.h"'. */
#ifndef DERIVE_TEST_CASES_H
#define DERIVE_TEST_CASES_H

#include <stdio.h>

#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)
#define T(name) CAT(ARM, CAT(_, name))
#define C(name) CAT(ARM_UPPER, CAT(_, name))
#define NJ C(N)

typedef T(real) real;

static int cases, failed;

/* One case: counted, and printed when it fails. */
static void expect(const char *what, int ok)
{
    ++cases;
    if (!ok) {
        ++failed;
        printf("FAIL %s\n", what);
    }
}

#endif
