/* semihost.h: ends the firmware under QEMU with an exit status (startup.c). */
#ifndef DEPTHOR_SEMIHOST_H
#define DEPTHOR_SEMIHOST_H
void semihost_exit(int code);
#endif
