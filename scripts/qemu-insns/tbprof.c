/* Per-translation-block execution counts for qemu-aarch64 (QEMU 7.2, TCG plugin API v1, declared
 * without a header as in insns.c): at exit, one "vaddr instructions" line per block that ran, to
 * the file given as out=PATH (default tbprof.txt). profile.py turns two such files (3 frames and
 * 1 frame) into instructions per frame and function.
 *
 *   gcc -O2 -shared -fPIC -o libtbprof.so tbprof.c
 *   qemu-aarch64 -L /usr/aarch64-linux-gnu -plugin ./libtbprof.so,out=tb3.txt <program> ... */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <stddef.h>
#include <string.h>
typedef uint64_t qemu_plugin_id_t;
struct qemu_plugin_tb;
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*tb_trans_cb)(qemu_plugin_id_t, struct qemu_plugin_tb *);
typedef void (*udata_cb)(qemu_plugin_id_t, void *);
void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t, tb_trans_cb);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *);
uint64_t qemu_plugin_tb_vaddr(const struct qemu_plugin_tb *);
void qemu_plugin_register_vcpu_tb_exec_inline(struct qemu_plugin_tb *, enum qemu_plugin_op, void *, uint64_t);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t, udata_cb, void *);
__attribute__((visibility("default"))) int qemu_plugin_version = 1;
struct block { uint64_t vaddr, insns; struct block *next; };
static struct block *blocks;
static const char *out = "tbprof.txt";
static void trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
  struct block *b = calloc(1, sizeof *b);
  b->vaddr = qemu_plugin_tb_vaddr(tb);
  b->next = blocks;
  blocks = b;
  qemu_plugin_register_vcpu_tb_exec_inline(tb, QEMU_PLUGIN_INLINE_ADD_U64, &b->insns, qemu_plugin_tb_n_insns(tb));
}
static void done(qemu_plugin_id_t id, void *u) {
  FILE *f = fopen(out, "w");
  for (struct block *b = blocks; b; b = b->next)
    if (b->insns) fprintf(f, "%llx %llu\n", (unsigned long long)b->vaddr, (unsigned long long)b->insns);
  fclose(f);
}
__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id, const void *info, int argc, char **argv) {
  if (argc > 0 && strncmp(argv[0], "out=", 4) == 0) out = argv[0] + 4;
  qemu_plugin_register_vcpu_tb_trans_cb(id, trans);
  qemu_plugin_register_atexit_cb(id, done, NULL);
  return 0;
}
