/*
 * replay.h: the replay flash image (DPTHRPLY v1, firmware-sim/replay/src/format.rs) read in
 * C99, and one frame of the firmware loop over depthor.h: zones -> depthor_project_to_sparse
 * -> depthor_engine_run (in place) -> the FNV-1a 64 hash line the Rust firmware and the host
 * print. Shared by the C firmware (firmware-sim/c/main.c), the C test program
 * (ffi/c/test_api.c) and the C++ host example (ffi/examples/host.cpp).
 */
#ifndef DEPTHOR_REPLAY_H
#define DEPTHOR_REPLAY_H

#include <stddef.h>
#include <stdint.h>

#include "depthor.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A validated image (replay_parse); it borrows the bytes. */
typedef struct replay_image {
    const uint8_t *bytes;
    size_t len;
    uint32_t frames;
    uint16_t height, width, rows, cols;
    size_t record_len;
    size_t rgb_offset;
    depthor_calibration cal;
} replay_image;

/* Validates `bytes` like the Rust parser: 0, or the Rust firmware's exit code (2 magic,
 * 3 version, 4 header, 5 truncated, 6 trailing bytes, 7 CRC, 8 zone count). */
int replay_parse(replay_image *img, const uint8_t *bytes, size_t len);

/* Zlib's CRC-32 (the image's and the model blob's checksum). */
uint32_t replay_crc32(const uint8_t *bytes, size_t len);

/* FNV-1a 64 over the little-endian bytes of each float's bits. */
uint64_t replay_fnv1a64_f32(const float *values, size_t n);

/* Caller buffers of one frame: `zones_mm` rows*cols floats, `depth_m` H*W floats (the
 * sparse map, then the dense depth: the engine runs in place on it). */
typedef struct replay_workspace {
    float *zones_mm;
    size_t zones_cap;
    float *depth_m;
    size_t depth_cap;
    /* Optional (may be NULL): called with REPLAY_STAGE_* as each stage of a frame begins. */
    void (*mark)(void *ctx, int stage);
    void *mark_ctx;
} replay_workspace;

#define REPLAY_STAGE_PROJECTION 0
#define REPLAY_STAGE_ENGINE 1
#define REPLAY_STAGE_DONE 2

/* Runs frame `index` through `engine` (prepared for the image's size) and writes the line
 * "frame I depth_fnv1a64=H points=P skipped=S collisions=C" into `line`. 0, or the Rust
 * firmware's exit code (13 zone capacity, 14 workspace, 15 projection, 16 engine, 17 no valid
 * zone); `*status` receives the depthor status of a 15 or 16. */
int replay_process(const replay_image *img, uint32_t index, depthor_engine *engine,
                   const replay_workspace *ws, char *line, size_t line_len, int32_t *status);

#ifdef __cplusplus
}
#endif

#endif /* DEPTHOR_REPLAY_H */
