/* Exact per-PC execution counts for qemu-system-arm 7.2 (TCG plugin API v1; Debian's QEMU
 * enables plugins but ships no header, so the few declarations it needs are written out here).
 *
 *   gcc -O2 -shared -fPIC -o libpcprof.so pcprof.c
 *   qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -icount shift=0 \
 *     -semihosting-config enable=on,target=native -nographic \
 *     -plugin ./libpcprof.so,out=counts.txt -kernel <firmware ELF>
 *   python3 symbolize.py <firmware ELF> counts.txt
 *
 * Every translated instruction gets an inline 64-bit counter (code below 4 MiB); at exit the
 * non-zero ones are written as "0xPC count" lines. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <stddef.h>
#include <string.h>
typedef uint64_t qemu_plugin_id_t;
struct qemu_plugin_tb; struct qemu_plugin_insn;
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*tb_trans_cb)(qemu_plugin_id_t, struct qemu_plugin_tb *);
typedef void (*udata_cb)(qemu_plugin_id_t, void *);
void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t, tb_trans_cb);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *, size_t);
uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *);
void qemu_plugin_register_vcpu_insn_exec_inline(struct qemu_plugin_insn *, enum qemu_plugin_op, void *, uint64_t);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t, udata_cb, void *);
__attribute__((visibility("default"))) int qemu_plugin_version = 1;
#define SPAN (1u << 21) /* halfword slots: 4 MiB of code from 0 */
static uint64_t *counts;
static const char *out = "pcprof.txt";
static void trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
  size_t n = qemu_plugin_tb_n_insns(tb);
  for (size_t i = 0; i < n; i++) {
    struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
    uint64_t pc = qemu_plugin_insn_vaddr(insn);
    if ((pc >> 1) < SPAN) qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, &counts[pc >> 1], 1);
  }
}
static void done(qemu_plugin_id_t id, void *u) {
  FILE *f = fopen(out, "w");
  for (uint32_t i = 0; i < SPAN; i++) if (counts[i]) fprintf(f, "0x%x %llu\n", i << 1, (unsigned long long)counts[i]);
  fclose(f);
}
__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id, const void *info, int argc, char **argv) {
  if (argc > 0 && strncmp(argv[0], "out=", 4) == 0) out = argv[0] + 4;
  counts = calloc(SPAN, sizeof(uint64_t));
  qemu_plugin_register_vcpu_tb_trans_cb(id, trans);
  qemu_plugin_register_atexit_cb(id, done, NULL);
  return 0;
}
