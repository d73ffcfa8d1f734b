/*
 * main.c: the C firmware (Cortex-M4F, QEMU mps2-an386): the Rust firmware's replay scenario
 * over depthor.h. Prepares the engine once in static memory, replays every frame of the
 * embedded image (zones -> projection -> int8 engine in place) and prints one hash line per
 * frame, identical to the Rust firmware's and the host's, then "TEST OK". A bad image or a
 * library error prints "ERROR <code>: <what>" and exits with the Rust firmware's code.
 * C99 (the startup code in startup.c is the only non-standard part).
 */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "depthor.h"
#include "replay.h"
#include "semihost.h"

extern const uint8_t depthor_model_blob[], depthor_model_blob_end[];
extern const uint8_t replay_image_bytes[], replay_image_bytes_end[];
extern const char __flash_used[];

/* 384 KiB, the Rust firmware's arena budget (the default mcu_lite blob needs 366 015 B). */
#define ARENA_BYTES (384u * 1024u)
#define MAX_PIXELS (120u * 160u)
#define MAX_ZONES 64u

static depthor_engine_storage engine_memory;
static union {
    uint8_t bytes[ARENA_BYTES];
    uint64_t align;
} arena;
static float zones_mm[MAX_ZONES];
static float depth_m[MAX_PIXELS];

/* Instruction count at each stage mark of the current frame. */
static unsigned long long stage_at[3];

static void mark(void *ctx, int stage) {
    (void)ctx;
    if (stage >= 0 && stage < 3) stage_at[stage] = icount_instructions();
}

int main(void) {
    const size_t blob_len = (size_t)(depthor_model_blob_end - depthor_model_blob);
    const size_t image_len = (size_t)(replay_image_bytes_end - replay_image_bytes);
    depthor_engine *engine = (depthor_engine *)(void *)&engine_memory;
    replay_workspace ws;
    replay_image img;
    size_t need = 0;
    char line[160];
    uint32_t f;
    unsigned long stack_plan, stack_init;
    int32_t st;
    int code;

#ifdef DEPTHOR_PANIC_PROBE
    /* Test build (ffi/tests/c_firmware.rs): a panic inside the library must end in the
     * HardFault handler (exit 101), never return. */
    {
        extern int32_t depthor_probe_panic(void);
        printf("probe: calling depthor_probe_panic\n");
        printf("probe: returned %d\n", (int)depthor_probe_panic());
        return 1;
    }
#endif
    code = replay_parse(&img, replay_image_bytes, image_len);
    if (code != 0) {
        printf("ERROR %d: replay image refused\n", code);
        return code;
    }
    printf("replay image: %lu frames, %ux%u RGB, %ux%u zones, %lu bytes\n",
           (unsigned long)img.frames, (unsigned)img.height, (unsigned)img.width,
           (unsigned)img.rows, (unsigned)img.cols, (unsigned long)image_len);
    if (depthor_engine_size() > sizeof engine_memory) {
        printf("ERROR 16: engine memory too small\n");
        return 16;
    }
    stack_paint();
    st = depthor_arena_bytes(depthor_model_blob, blob_len, img.height, img.width, &need);
    stack_plan = stack_high_water();
    if (st == DEPTHOR_OK) {
        stack_paint();
        st = depthor_engine_init(engine, depthor_model_blob, blob_len, arena.bytes,
                                 sizeof arena.bytes, img.height, img.width);
    }
    if (st != DEPTHOR_OK) {
        printf("ERROR 16: engine: %s (arena need %lu of %lu B)\n", depthor_status_message(st),
               (unsigned long)need, (unsigned long)sizeof arena.bytes);
        return 16;
    }
    stack_init = stack_high_water();
    printf("engine: blob %lu B, arena %lu B needed at least, %lu B given, engine object %lu B\n",
           (unsigned long)blob_len, (unsigned long)need, (unsigned long)sizeof arena.bytes,
           (unsigned long)depthor_engine_size());
    stack_paint();

    ws.zones_mm = zones_mm;
    ws.zones_cap = MAX_ZONES;
    ws.depth_m = depth_m;
    ws.depth_cap = MAX_PIXELS;
    ws.mark = mark;
    ws.mark_ctx = NULL;
    icount_start();
    for (f = 0; f < img.frames; f++) {
        code = replay_process(&img, f, engine, &ws, line, sizeof line, &st);
        if (code != 0) {
            printf("ERROR %d: %s\n", code, depthor_status_message(st));
            return code;
        }
        printf("%s\n", line);
        printf("icount frame %lu projection=%lu engine=%lu\n", (unsigned long)f,
               (unsigned long)(stage_at[1] - stage_at[0]),
               (unsigned long)(stage_at[2] - stage_at[1]));
    }
    printf("frames %lu\n", (unsigned long)img.frames);
    printf("stack high-water: depthor_arena_bytes %lu B, depthor_engine_init %lu B, frames "
           "(projection + depthor_engine_run) %lu B\n",
           stack_plan, stack_init, stack_high_water());
    printf("flash: %lu B (firmware + model blob %lu B + replay image %lu B)\n",
           (unsigned long)(uintptr_t)__flash_used, (unsigned long)blob_len,
           (unsigned long)image_len);
    printf("TEST OK\n");
    return 0;
}
