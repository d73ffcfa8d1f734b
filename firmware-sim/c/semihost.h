/* semihost.h: exit status under QEMU and stack measurement (startup.c). */
#ifndef DEPTHOR_SEMIHOST_H
#define DEPTHOR_SEMIHOST_H
void semihost_exit(int code);
/* Fills the free stack with a pattern (call with no interrupt enabled). */
void stack_paint(void);
/* Bytes of stack used since the last stack_paint (high-water mark from the top of RAM). */
unsigned long stack_high_water(void);
/* Starts SysTick as an instruction counter (QEMU -icount shift=0). */
void icount_start(void);
/* Instructions since icount_start (+-40). */
unsigned long long icount_instructions(void);
#endif
