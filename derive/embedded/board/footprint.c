/* Footprint probe: a program that only keeps every public function of one
 * generated controller, compiled with -DARM=<arm> -DARM_HEADER='"<arm>.h"' and
 * linked like the self-test (startup.c, mps2.ld, --gc-sections). It is never
 * run: derive/embedded/qemu.py reads its link map to find what the controller pulls
 * in from libm and libgcc (cosf, sinf, and on the Cortex-M3 the software
 * floating-point routines), which the controller's own objects do not show. */
#include ARM_HEADER

#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)
#define F(name) CAT(ARM, CAT(_, name))

typedef void (*any_fn)(void);

static any_fn volatile keep[] = {
    (any_fn)F(gains), (any_fn)F(mpc_step), (any_fn)F(npid_init), (any_fn)F(npid_step),
    (any_fn)F(dobc_init), (any_fn)F(dobc_step),
};

int main(void)
{
    return keep[0] == 0;
}
