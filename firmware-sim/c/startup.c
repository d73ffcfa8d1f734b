/* startup.c: the Cortex-M4F vector table and reset handler of the C firmware, and the
 * semihosting exit. Not C99-pure (GCC attributes and inline asm): firmware glue. */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "semihost.h"

extern uint32_t __stack_top, __data_start__, __data_end__, __data_load__, __bss_start__,
    __bss_end__, end;
extern void initialise_monitor_handles(void);
int main(void);

/* Semihosting SYS_EXIT_EXTENDED (0x20) with {ADP_Stopped_ApplicationExit, code}: QEMU exits
 * with `code` (plain SYS_EXIT only tells success from failure on 32-bit Arm). */
static void semihost_call(uint32_t op, uint32_t *block) {
    register uint32_t r0 __asm__("r0") = op;
    register uint32_t *r1 __asm__("r1") = block;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
}

void semihost_exit(int code) {
    uint32_t block[2] = {0x20026u, (uint32_t)code};
    fflush(stdout);
    semihost_call(0x20u, block);
    for (;;) {
        __asm__ volatile("bkpt 0");
    }
}

/* Stack painting (as firmware-sim/src/memory.rs): the words between the heap's first 64 KiB
 * (newlib's stdio buffers) and 64 bytes below the stack pointer get STACK_PAINT; the high-water
 * mark is the lowest word no longer holding it (a lower bound, exact to the first overwritten
 * word). */
#define STACK_PAINT 0xDEADC0DEu
#define HEAP_RESERVE (64u * 1024u)

static uint32_t *paint_bottom(void) {
    return (uint32_t *)((char *)&end + HEAP_RESERVE);
}

void stack_paint(void) {
    uint32_t *sp;
    volatile uint32_t *p;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    for (p = paint_bottom(); p + 16 < sp; p++) *p = STACK_PAINT;
}

unsigned long stack_high_water(void) {
    volatile uint32_t *p = paint_bottom();
    while (p < &__stack_top && *p == STACK_PAINT) p++;
    return (unsigned long)((char *)&__stack_top - (char *)p);
}

/* Instruction counts from SysTick under QEMU's -icount shift=0 (as firmware-sim/src/cycles.rs):
 * each instruction advances the virtual clock 1 ns and SysTick, on the 25 MHz core clock,
 * ticks every 40 ns, so instructions = 40 * ticks (+-40). SysTick runs free with the largest
 * reload; its exception counts wraps. */
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SCB_ICSR (*(volatile uint32_t *)0xE000ED04u)
#define SYST_PERIOD (1ull << 24)
static volatile uint32_t systick_wraps;

void SysTick_Handler(void) {
    systick_wraps++;
}

void icount_start(void) {
    SYST_CSR = 0;
    SYST_RVR = (uint32_t)(SYST_PERIOD - 1);
    SYST_CVR = 0;
    SYST_CSR = 1u | 4u; /* enable, processor clock */
    while (SYST_CVR == 0) {
    }
    SCB_ICSR = 1u << 25; /* PENDSTCLR */
    systick_wraps = 0;
    SYST_CSR = 1u | 2u | 4u; /* and the wrap interrupt */
}

unsigned long long icount_instructions(void) {
    for (;;) {
        uint32_t w0 = systick_wraps;
        uint32_t c0 = SYST_CVR;
        uint32_t pending = (SCB_ICSR >> 26) & 1u;
        uint32_t c1 = SYST_CVR;
        uint32_t w1 = systick_wraps;
        if (w0 == w1 && c1 <= c0) {
            unsigned long long ticks =
                ((unsigned long long)w0 + pending) * SYST_PERIOD + (SYST_PERIOD - 1 - c0);
            return ticks * 40u;
        }
    }
}

/* Faults (a panic in the no_std library executes `udf`, which lands here): exit 101 like the
 * Rust firmware's panic. */
void HardFault_Handler(void) {
    printf("PANIC: HardFault\n");
    semihost_exit(101);
}

void Default_Handler(void) {
    printf("PANIC: unexpected exception\n");
    semihost_exit(101);
}

void Reset_Handler(void) {
    volatile uint32_t *cpacr = (volatile uint32_t *)0xE000ED88u;
    memcpy(&__data_start__, &__data_load__,
           (size_t)((char *)&__data_end__ - (char *)&__data_start__));
    memset(&__bss_start__, 0, (size_t)((char *)&__bss_end__ - (char *)&__bss_start__));
    /* CP10/CP11 full access: the library and this code are built for the hard-float ABI. */
    *cpacr |= 0xFu << 20;
    __asm__ volatile("dsb\n isb" ::: "memory");
    initialise_monitor_handles();
    semihost_exit(main());
}

__attribute__((section(".vectors"), used)) void (*const vectors[16])(void) = {
    (void (*)(void))(&__stack_top),
    Reset_Handler,
    Default_Handler,   /* NMI */
    HardFault_Handler, /* HardFault */
    HardFault_Handler, /* MemManage */
    HardFault_Handler, /* BusFault */
    HardFault_Handler, /* UsageFault */
    0, 0, 0, 0,
    Default_Handler, /* SVCall */
    Default_Handler, /* DebugMon */
    0,
    Default_Handler, /* PendSV */
    SysTick_Handler, /* SysTick */
};
