/* Instruction counts and stack use of one generated controller on QEMU's MPS2
 * boards. Hand-written; compiled once per arm with
 *   -DARM=<arm> -DARM_HEADER='"<arm>.h"'
 * and linked with the controller's objects, startup.c and mps2.ld.
 *
 * Inputs: NINPUTS states from the self-test's sequence formula, except the
 * angles: each joint's take the NINPUTS values of a uniform grid over
 * +-2.93 rad (step 0.390625), so that libm's sin and cos take the paths an
 * arm's range takes, in proportion (argument reduction beyond pi/4 included).
 *
 * Instruction counts. Run QEMU with -icount shift=0: every guest instruction
 * then advances virtual time by exactly 1 ns, and SysTick, clocked from the
 * 25 MHz processor clock (CLKSOURCE = 1), counts down once per 40 executed
 * instructions. The counts are deterministic and are instructions, not cycles
 * (QEMU models no pipeline, wait states or FPU latency; DWT CYCCNT reads 0).
 * For each input, CALLS calls of a function through a volatile function
 * pointer are timed; the same loop calling a no-op of the same signature is
 * timed too and subtracted, so a figure is the instructions executed inside
 * one call, the libm and libgcc routines it calls included (to within the
 * one or two instructions of the adapter and the no-op). "calibrate" times a
 * hand-written loop of exactly CAL_INSNS instructions, so that the
 * instructions per SysTick tick are measured, not assumed.
 *
 * Stack use. Before the timer is started, the free stack below the caller is
 * filled with a pattern before each call, and the lowest word that changed
 * gives the bytes the call used: its own frames and everything it calls,
 * libm and libgcc included. Printed: the worst over the NINPUTS inputs, and
 * the use at one input with angles near 3e4 rad, which takes libm's
 * large-argument reduction. No interrupt is enabled meanwhile.
 *
 * Output, one line each, parsed by derive/embedded/qemu.py:
 *   stack <function> bytes=<b> far=<b>
 *   calibrate insns=<n> ticks=<t>
 *   time <function> input=<k> calls=<n> ticks=<t> baseline=<t0>
 *   measure done codes=<c>
 * The exit status is 0 unless a call returned an error code (c != 0).
 */
#include <stdint.h>
#include <stdio.h>

#include ARM_HEADER

#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)
#define F(name) CAT(ARM, CAT(_, name))

typedef F(real) real;
typedef F(input) input_t;
typedef F(npid_state) npid_state_t;
typedef F(dobc_state) dobc_state_t;

#define NJ ((int)(sizeof(((input_t *)0)->theta) / sizeof(real)))
#define NINPUTS 16
#define CALLS 256
#define CAL_LOOPS 1000
#define CAL_INSNS (CAL_LOOPS * 40 + 1)

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)

extern volatile uint32_t systick_wraps; /* startup.c */
extern uint32_t __StackLimit;           /* mps2.ld */

typedef int (*step_fn)(void *state, const input_t *in, real dt, real u[]);
typedef void (*gains_fn)(const real theta[], real P[], real D[], real I[]);

static input_t inputs[NINPUTS];

/* The self-test's sequence formula at steps k = 0 .. NINPUTS-1, angles on a grid. */
static void make_inputs(void)
{
    int k, block, i;
    for (k = 0; k < NINPUTS; ++k) {
        real *x[5];
        x[0] = inputs[k].theta;
        x[1] = inputs[k].dtheta;
        x[2] = inputs[k].yd;
        x[3] = inputs[k].dyd;
        x[4] = inputs[k].ddyd;
        for (block = 0; block < 5; ++block) {
            for (i = 0; i < NJ; ++i) {
                long m = ((long)k * (2 * i + 3 + block) + 17 * i + 5 * block) % 129;
                x[block][i] = (real)m / (real)128 - (real)0.5;
            }
        }
        for (i = 0; i < NJ; ++i) { /* a uniform grid of NINPUTS angles, permuted per joint */
            x[0][i] = ((real)((5 * k + 3 * i) % NINPUTS) - (real)7.5) * (real)0.390625;
        }
    }
}

/* Adapters with one signature, so that every timed loop is the same code. */
static int npid_step(void *s, const input_t *in, real dt, real u[])
{
    return F(npid_step)((npid_state_t *)s, in, dt, u, NULL);
}

static int dobc_step(void *s, const input_t *in, real dt, real u[])
{
    return F(dobc_step)((dobc_state_t *)s, in, dt, u, NULL);
}

static int noop_step(void *s, const input_t *in, real dt, real u[])
{
    (void)s, (void)in, (void)dt, (void)u;
    return 0;
}

static void noop_gains(const real theta[], real P[], real D[], real I[])
{
    (void)theta, (void)P, (void)D, (void)I;
}

/* Elapsed SysTick ticks since the timer was started (wraps counted). */
static uint32_t ticks(void)
{
    uint32_t wraps, value;
    do {
        wraps = systick_wraps;
        value = SYST_CVR;
    } while (wraps != systick_wraps);
    return wraps * 0x1000000u + (0xFFFFFFu - value);
}

static void timer_start(void)
{
    SYST_CSR = 0;
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0;
    systick_wraps = 0;
    SYST_CSR = 7u; /* enable, interrupt on wrap, processor clock */
    while (SYST_CVR == 0) {
        /* the first tick loads the reload value; no wrap before it */
    }
}

/* Ticks taken by CALLS calls of a step (fn = 0, 1, 2: npid, dobc, no-op) or of
 * the gains (fn = 3, 4: gains, no-op), all at one input. */
static uint32_t time_calls(int fn, void *state, const input_t *in, int *codes)
{
    static step_fn volatile steps[3] = { npid_step, dobc_step, noop_step };
    static gains_fn volatile gains[2] = { F(gains), noop_gains };
    const real dt = (real)0.0009765625;
    real u[NJ], g[3 * NJ * NJ];
    uint32_t t0;
    int k;
    if (fn < 3) {
        step_fn volatile *p = &steps[fn];
        t0 = ticks();
        for (k = 0; k < CALLS; ++k) *codes |= (*p)(state, in, dt, u);
    } else {
        gains_fn volatile *p = &gains[fn - 3];
        t0 = ticks();
        for (k = 0; k < CALLS; ++k) (*p)(in->theta, g, g + NJ * NJ, g + 2 * NJ * NJ);
    }
    return ticks() - t0;
}

#define PATTERN 0xA5C3E10Fu

/* Fill the stack from __StackLimit to just below this function's frame. */
static __attribute__((noinline)) void paint(void)
{
    uint32_t *p = &__StackLimit, *sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    while (p < sp - 8) *p++ = PATTERN;
}

/* Bytes between ``top`` and the lowest word that no longer holds the pattern. */
static uint32_t used_below(const uint32_t *top)
{
    const uint32_t *p = &__StackLimit;
    while (p < top && *p == PATTERN) ++p;
    return (uint32_t)((const char *)top - (const char *)p);
}

static __attribute__((noinline)) uint32_t *stack_pointer(void)
{
    uint32_t *sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    return sp;
}

int main(void)
{
    static const char *const names[3] = { "npid_step", "dobc_step", "gains" };
    const real dt = (real)0.0009765625;
    npid_state_t ns;
    dobc_state_t ds;
    input_t far;
    void *states[3];
    real u[NJ], g[3 * NJ * NJ];
    uint32_t base[2], t, t0, *top;
    int f, k, codes = 0;

    make_inputs();
    states[0] = &ns;
    states[1] = &ds;
    states[2] = 0;
    codes |= F(npid_init)(&ns, &inputs[0]);
    codes |= F(dobc_init)(&ds, &inputs[0]);

    /* Stack: each function called from a freshly painted stack at every
     * input, and at one with angles near 3e4 rad. */
    far = inputs[1];
    for (f = 0; f < NJ; ++f) far.theta[f] = (real)30000.25 + (real)f;
    top = stack_pointer();
    for (f = 0; f < 3; ++f) {
        uint32_t worst = 0, used = 0;
        for (k = 0; k <= NINPUTS; ++k) {
            const input_t *in = k < NINPUTS ? &inputs[k] : &far;
            paint();
            if (f == 0) codes |= F(npid_step)(&ns, in, dt, u, NULL);
            if (f == 1) codes |= F(dobc_step)(&ds, in, dt, u, NULL);
            if (f == 2) F(gains)(in->theta, g, g + NJ * NJ, g + 2 * NJ * NJ);
            used = used_below(top);
            if (k < NINPUTS && used > worst) worst = used;
        }
        printf("stack %s bytes=%lu far=%lu\n", names[f], (unsigned long)worst, (unsigned long)used);
    }

    timer_start();
    t0 = ticks();
    /* CAL_LOOPS iterations of 38 nops + subs + bne, after one movw: CAL_INSNS. */
    __asm__ volatile("movw r0, %0\n"
                     "1:\n"
                     ".rept 38\n nop\n .endr\n"
                     "subs r0, r0, #1\n"
                     "bne 1b\n"
                     :
                     : "i"(CAL_LOOPS)
                     : "r0", "cc", "memory");
    t = ticks() - t0;
    t0 = ticks();
    t -= ticks() - t0; /* less the cost of reading the timer */
    printf("calibrate insns=%d ticks=%lu\n", CAL_INSNS, (unsigned long)t);

    codes |= F(npid_init)(&ns, &inputs[0]);
    codes |= F(dobc_init)(&ds, &inputs[0]);
    base[0] = time_calls(2, &ns, &inputs[0], &codes);
    base[1] = time_calls(4, 0, &inputs[0], &codes);
    for (f = 0; f < 3; ++f) {
        for (k = 0; k < NINPUTS; ++k) {
            t = time_calls(f < 2 ? f : 3, states[f], &inputs[k], &codes);
            printf("time %s input=%d calls=%d ticks=%lu baseline=%lu\n", names[f], k, CALLS, (unsigned long)t,
                   (unsigned long)base[f < 2 ? 0 : 1]);
        }
    }
    printf("measure done codes=%d\n", codes);
    return codes != 0;
}
