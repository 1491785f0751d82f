/* evcal's instruction counter: a QEMU 7.2 TCG plugin (plugin API version 1) that counts the
 * guest instructions executed between each call of the firmware's `bench_start` and the next
 * `bench_stop`, and in the whole run.
 *
 *   gcc -shared -fPIC -O2 -o target/libinsn_count.so firmware/tools/insn_count.c
 *   qemu-system-arm ... -plugin target/libinsn_count.so,start=0xADDR,stop=0xADDR -d plugin -D LOG
 *
 * LOG then has `bench[K]: N insns` per start..stop span and `total: N insns` at exit. With
 * `profile=on` as well, it also has `tb 0xADDR N` lines at exit: instructions executed inside
 * the spans per translated block, by the block's first address (map them to functions with
 * the ELF's symbol table; a block lies within one function, inlined code counting as its
 * caller's). A span
 * counts the instructions from the start marker's first instruction to the stop marker's
 * (give or take one, depending on the order QEMU runs a callback and an inline count of the
 * same instruction), so it includes the markers' call overhead, a few instructions. Debian ships QEMU with plugin support but without the plugin header, so the
 * few API functions used are declared here; their signatures are those of qemu-plugin.h in
 * QEMU 7.2. Counts are instructions, not cycles: QEMU has no timing model. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define API __attribute__((visibility("default")))

typedef uint64_t qemu_plugin_id_t;
typedef struct qemu_info_t qemu_info_t;
struct qemu_plugin_tb;
struct qemu_plugin_insn;
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_CB_R_REGS, QEMU_PLUGIN_CB_RW_REGS };
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*tb_trans_cb)(qemu_plugin_id_t, struct qemu_plugin_tb *);
typedef void (*insn_cb)(unsigned int vcpu, void *user);
typedef void (*exit_cb)(qemu_plugin_id_t, void *user);

void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t, tb_trans_cb);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *, size_t);
uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *);
void qemu_plugin_register_vcpu_insn_exec_inline(struct qemu_plugin_insn *, enum qemu_plugin_op, void *, uint64_t);
void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *, insn_cb, enum qemu_plugin_cb_flags, void *);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t, exit_cb, void *);
uint64_t qemu_plugin_tb_vaddr(const struct qemu_plugin_tb *);
void qemu_plugin_register_vcpu_tb_exec_cb(struct qemu_plugin_tb *, insn_cb, enum qemu_plugin_cb_flags, void *);
void qemu_plugin_outs(const char *);

API int qemu_plugin_version = 1;

/* One vCPU (a Cortex-M): no locking needed. */
static uint64_t executed;       /* instructions so far, counted inline before each one runs */
static uint64_t span_begin;     /* `executed` when the start marker ran */
static uint64_t spans;
static int in_span;
static uint64_t start_pc = UINT64_MAX, stop_pc = UINT64_MAX;

/* Profile: one record per translation (a block translated twice has two; they are summed
 * by address by whoever reads the log). */
struct block {
    uint64_t pc, insns, executed;
    struct block *next;
};
static int profiling;
static struct block *blocks;

static void on_block(unsigned int vcpu, void *user) {
    struct block *b = user;
    (void)vcpu;
    if (in_span) b->executed += b->insns;
}

static void at_start(unsigned int vcpu, void *user) {
    (void)vcpu; (void)user;
    span_begin = executed;
    in_span = 1;
}

static void at_stop(unsigned int vcpu, void *user) {
    char line[80];
    (void)vcpu; (void)user;
    if (!in_span) return; /* a stop without a start: nothing to report */
    in_span = 0;
    snprintf(line, sizeof line, "bench[%llu]: %llu insns\n", (unsigned long long)spans++,
             (unsigned long long)(executed - span_begin));
    qemu_plugin_outs(line);
}

static void on_translate(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
    (void)id;
    if (profiling) {
        struct block *b = calloc(1, sizeof *b);
        if (b) {
            b->pc = qemu_plugin_tb_vaddr(tb);
            b->insns = qemu_plugin_tb_n_insns(tb);
            b->next = blocks;
            blocks = b;
            qemu_plugin_register_vcpu_tb_exec_cb(tb, on_block, QEMU_PLUGIN_CB_NO_REGS, b);
        }
    }
    for (size_t i = 0, n = qemu_plugin_tb_n_insns(tb); i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uint64_t pc = qemu_plugin_insn_vaddr(insn);
        if (pc == start_pc) qemu_plugin_register_vcpu_insn_exec_cb(insn, at_start, QEMU_PLUGIN_CB_NO_REGS, NULL);
        if (pc == stop_pc) qemu_plugin_register_vcpu_insn_exec_cb(insn, at_stop, QEMU_PLUGIN_CB_NO_REGS, NULL);
        qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, &executed, 1);
    }
}

static void at_exit(qemu_plugin_id_t id, void *user) {
    char line[64];
    (void)id; (void)user;
    for (struct block *b = blocks; b; b = b->next) {
        if (!b->executed) continue;
        snprintf(line, sizeof line, "tb 0x%llx %llu\n", (unsigned long long)b->pc, (unsigned long long)b->executed);
        qemu_plugin_outs(line);
    }
    snprintf(line, sizeof line, "total: %llu insns\n", (unsigned long long)executed);
    qemu_plugin_outs(line);
}

API int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info, int argc, char **argv) {
    (void)info;
    for (int i = 0; i < argc; i++) {
        /* Thumb addresses from the symbol table have bit 0 set; instructions do not. */
        if (!strncmp(argv[i], "start=", 6)) start_pc = strtoull(argv[i] + 6, NULL, 0) & ~1ull;
        if (!strncmp(argv[i], "stop=", 5)) stop_pc = strtoull(argv[i] + 5, NULL, 0) & ~1ull;
        if (!strcmp(argv[i], "profile=on")) profiling = 1;
    }
    if (start_pc == UINT64_MAX || stop_pc == UINT64_MAX) {
        qemu_plugin_outs("insn_count: give start=ADDR,stop=ADDR\n");
        return -1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_translate);
    qemu_plugin_register_atexit_cb(id, at_exit, NULL);
    return 0;
}
