/* semihost.h: exit status under QEMU and stack measurement (startup.c). */
#ifndef DEPTHOR_SEMIHOST_H
#define DEPTHOR_SEMIHOST_H
void semihost_exit(int code);
/* Fills the free stack with a pattern (call with no interrupt enabled). */
void stack_paint(void);
/* Bytes of stack used since the last stack_paint (high-water mark from the top of RAM). */
unsigned long stack_high_water(void);
#endif
