/* Board support for running derive's generated controllers on QEMU's MPS2
 * boards: mps2-an385 (Cortex-M3, no FPU) and mps2-an386 (Cortex-M4F, single
 * precision FPU). Hand-written, not generated: the same file serves every arm.
 *
 * What it provides, with mps2.ld:
 *   - the vector table at 0x00000000 (initial stack pointer, then handlers);
 *   - Reset_Handler: enables the FPU when the code is built for one (CPACR,
 *     before any floating-point instruction runs), copies .data from flash,
 *     zeroes .bss, opens newlib's semihosting stdio, calls main() and exits
 *     through semihosting with main's return value as the exit status;
 *   - fault handlers (HardFault, and MemManage/BusFault/UsageFault should a
 *     program enable them) that print the fault, its status registers and
 *     the faulting pc through semihosting, then exit with a non-zero status;
 *   - SysTick_Handler counting timer wraps (embedded/measure.c uses it).
 *
 * Output and exit use Arm semihosting (bkpt 0xAB): run QEMU with
 * -semihosting-config enable=on,target=native, and link with
 * --specs=rdimon.specs -nostartfiles (newlib's librdimon supplies write() and
 * _exit(); its crt0 is not used, because it expects a debugger's memory map).
 * QEMU exits with the status passed to exit().
 */
#include <stdint.h>
#include <stdlib.h>

/* Linker script symbols (mps2.ld). */
extern uint32_t __data_load__, __data_start__, __data_end__, __bss_start__, __bss_end__;
extern uint32_t __StackTop;

extern int main(void);
extern void initialise_monitor_handles(void); /* librdimon: opens stdin/stdout/stderr */

/* System control block registers (Armv7-M ARM, B3.2). */
#define SCB_CPACR (*(volatile uint32_t *)0xE000ED88u)
#define SCB_HFSR (*(volatile uint32_t *)0xE000ED2Cu)
#define SCB_CFSR (*(volatile uint32_t *)0xE000ED28u)
#define SCB_MMFAR (*(volatile uint32_t *)0xE000ED34u)
#define SCB_BFAR (*(volatile uint32_t *)0xE000ED38u)

/* Semihosting operations (Arm semihosting specification v2). */
#define SYS_WRITE0 0x04u
#define SYS_EXIT 0x18u
#define ADP_STOPPED_RUN_TIME_ERROR 0x20023u /* QEMU exits with status 1 */

volatile uint32_t systick_wraps; /* incremented on each SysTick interrupt */

static uint32_t semihost(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

/* Write "label 0x%08x" into out; returns the position after it. */
static char *put_hex(char *out, const char *label, uint32_t value)
{
    static const char digits[] = "0123456789abcdef";
    int shift;
    while (*label) *out++ = *label++;
    *out++ = '0';
    *out++ = 'x';
    for (shift = 28; shift >= 0; shift -= 4) *out++ = digits[(value >> shift) & 0xFu];
    return out;
}

/* Report a fault without touching newlib (the fault may have hit inside it)
 * and stop the emulator with a non-zero status. ``frame`` is the stacked
 * exception frame: r0-r3, r12, lr, pc, xpsr. */
void fault_report(const uint32_t *frame, uint32_t exc_return)
{
    static char line[160];
    char *p = line;
    const char *name = "FAULT: hard fault";
    while (*name) *p++ = *name++;
    p = put_hex(p, " pc=", frame[6]);
    p = put_hex(p, " lr=", frame[5]);
    p = put_hex(p, " HFSR=", SCB_HFSR);
    p = put_hex(p, " CFSR=", SCB_CFSR);
    p = put_hex(p, " MMFAR=", SCB_MMFAR);
    p = put_hex(p, " BFAR=", SCB_BFAR);
    p = put_hex(p, " EXC_RETURN=", exc_return);
    *p++ = '\n';
    *p = '\0';
    (void)semihost(SYS_WRITE0, line);
    (void)semihost(SYS_EXIT, (const void *)ADP_STOPPED_RUN_TIME_ERROR);
    for (;;) {
    }
}

/* Every fault lands here: pick the stack the frame was pushed on (bit 2 of
 * EXC_RETURN) and hand it to fault_report. */
__attribute__((naked)) void HardFault_Handler(void)
{
    __asm__ volatile(
        "tst lr, #4\n"
        "ite eq\n"
        "mrseq r0, msp\n"
        "mrsne r0, psp\n"
        "mov r1, lr\n"
        "b fault_report\n");
}

void SysTick_Handler(void)
{
    ++systick_wraps;
}

/* Any other exception or interrupt is unexpected: report it as a fault. */
void Default_Handler(void)
{
    static const char msg[] = "FAULT: unexpected exception\n";
    (void)semihost(SYS_WRITE0, msg);
    (void)semihost(SYS_EXIT, (const void *)ADP_STOPPED_RUN_TIME_ERROR);
    for (;;) {
    }
}

/* Without crti.o (-nostartfiles) newlib's __libc_fini_array, reached from
 * exit(), still calls _fini: there is nothing to finalise in C. */
void _init(void) {}
void _fini(void) {}

void Reset_Handler(void)
{
    uint32_t *src, *dst;
#if defined(__ARM_FP)
    /* Full access to coprocessors 10 and 11 (the FPU), then make sure the
     * write has taken effect before any floating-point instruction. */
    SCB_CPACR |= 0xFu << 20;
    __asm__ volatile("dsb\n isb" ::: "memory");
#endif
    for (src = &__data_load__, dst = &__data_start__; dst < &__data_end__;) *dst++ = *src++;
    for (dst = &__bss_start__; dst < &__bss_end__;) *dst++ = 0;
    initialise_monitor_handles();
    exit(main()); /* flushes stdio; librdimon's _exit reports the status to QEMU */
}

typedef void (*vector)(void);

/* Cortex-M vector table: initial main stack pointer, then the 15 system
 * exceptions, then the board's 32 interrupts (unused here). */
__attribute__((section(".isr_vector"), used)) const vector vector_table[16 + 32] = {
    (vector)(uintptr_t)&__StackTop,
    Reset_Handler,
    Default_Handler,   /* NMI */
    HardFault_Handler, /* HardFault */
    HardFault_Handler, /* MemManage */
    HardFault_Handler, /* BusFault */
    HardFault_Handler, /* UsageFault */
    0, 0, 0, 0,        /* reserved */
    Default_Handler,   /* SVCall */
    Default_Handler,   /* DebugMonitor */
    0,                 /* reserved */
    Default_Handler,   /* PendSV */
    SysTick_Handler,   /* SysTick */
    Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler,
    Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler,
    Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler,
    Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler,
    Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler,
    Default_Handler, Default_Handler,
};
