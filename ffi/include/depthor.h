/*
 * depthor.h: the C ABI of depthor-core (int8 depth completion: RGB + sparse dToF depth ->
 * dense depth). C99 without extensions; usable from C++ (extern "C").
 *
 * Written by hand and checked against the Rust side (ffi/src/lib.rs) by ffi/tests/header.rs:
 * every DEPTHOR_* constant's value, every prototype, and (through a compiled C program) the
 * structs' sizes and field offsets. The contract in full: docs/ffi.md.
 *
 * Memory: nothing allocates. The engine object lives in caller memory of
 * depthor_engine_size() bytes aligned to depthor_engine_align() (or a depthor_engine_storage),
 * the arena is caller memory of depthor_arena_bytes() bytes (any alignment). The engine
 * borrows the blob and the arena from depthor_engine_init until its last use: keep both
 * alive and do not write the arena yourself. There is nothing to free.
 *
 * Threads: one engine serves one thread at a time; distinct engines (own memory, own arena)
 * may run concurrently and may share one blob. The other functions are reentrant.
 *
 * Errors: every function that can fail returns 0 (DEPTHOR_OK) or a negative DEPTHOR_E_*
 * code, and on failure writes nothing the caller can see (a failed depthor_engine_init marks
 * the engine memory uninitialised). No function panics or unwinds into C.
 *
 * Stack (Cortex-M4F, the mcu_lite blob at 120x160, measured): depthor_arena_bytes 90 KB,
 * depthor_engine_init 148 KB (planner tables and a temporary engine object), a frame
 * (projection + run) 13 KB. Prepare once where the stack is deep.
 */
#ifndef DEPTHOR_H
#define DEPTHOR_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Status codes. */
#define DEPTHOR_OK 0
/* A required pointer is NULL. */
#define DEPTHOR_E_NULL (-1)
/* A pointer is misaligned for its type (engine memory: depthor_engine_align(); float buffers
 * and structs: their natural alignment). */
#define DEPTHOR_E_ALIGN (-2)
/* The model blob is malformed. */
#define DEPTHOR_E_BLOB (-3)
/* The model blob's payload CRC-32 does not match its header. */
#define DEPTHOR_E_BLOB_CHECKSUM (-4)
/* The model blob's format version is not supported. */
#define DEPTHOR_E_BLOB_VERSION (-5)
/* The network cannot run at this height x width (one side 0, too large, shapes do not fit). */
#define DEPTHOR_E_SIZE (-6)
/* The arena is smaller than depthor_arena_bytes() reports. */
#define DEPTHOR_E_ARENA (-7)
/* A buffer has the wrong length, or pointer + length overflows the address space. */
#define DEPTHOR_E_LENGTH (-8)
/* Buffers overlap where they must not. */
#define DEPTHOR_E_OVERLAP (-9)
/* The engine memory was not initialised by a successful depthor_engine_init. */
#define DEPTHOR_E_NOT_INIT (-10)
/* The calibration is unusable. */
#define DEPTHOR_E_CALIBRATION (-11)
/* Internal error (a bug): please report it with the blob. */
#define DEPTHOR_E_INTERNAL (-12)

/* depthor_calibration.distance_kind */
#define DEPTHOR_DISTANCE_Z 0u
#define DEPTHOR_DISTANCE_RADIAL 1u

/* Bytes of depthor_engine_storage: at least depthor_engine_size() on every target of its
 * pointer width (the engine object is 33 080 B on thumbv7em, 49 416 B on x86-64). */
#define DEPTHOR_ENGINE_STORAGE_BYTES_32 36864u
#define DEPTHOR_ENGINE_STORAGE_BYTES_64 53248u
#if UINTPTR_MAX <= 0xffffffffu
#define DEPTHOR_ENGINE_STORAGE_BYTES DEPTHOR_ENGINE_STORAGE_BYTES_32
#else
#define DEPTHOR_ENGINE_STORAGE_BYTES DEPTHOR_ENGINE_STORAGE_BYTES_64
#endif

/* The engine object: opaque, in caller memory. */
typedef struct depthor_engine depthor_engine;

/* Statically sized, suitably aligned engine memory (e.g. a static in firmware):
 *   static depthor_engine_storage mem;
 *   depthor_engine *engine = (depthor_engine *)&mem; */
typedef union depthor_engine_storage {
    unsigned char bytes[DEPTHOR_ENGINE_STORAGE_BYTES];
    uint64_t align_u64;
    double align_double;
    void *align_ptr;
} depthor_engine_storage;

/* Camera and dToF calibration for depthor_project_to_sparse. */
typedef struct depthor_calibration {
    uint32_t width;          /* camera image width, pixels */
    uint32_t height;         /* camera image height, pixels */
    float fx;                /* focal length x, pixels */
    float fy;                /* focal length y, pixels */
    float cx;                /* principal point x, pixels */
    float cy;                /* principal point y, pixels */
    uint16_t zone_rows;      /* dToF zone rows */
    uint16_t zone_cols;      /* dToF zone columns */
    uint32_t distance_kind;  /* DEPTHOR_DISTANCE_Z or DEPTHOR_DISTANCE_RADIAL */
    float fov_h_deg;         /* full horizontal field of view of the zone grid, degrees */
    float fov_v_deg;         /* full vertical field of view, degrees */
    float max_range_m;       /* largest distance the sensor reports, metres */
    float rotation[9];       /* dToF -> camera rotation, row-major 3x3 */
    float translation_m[3];  /* dToF -> camera translation, metres */
} depthor_calibration;

/* What depthor_project_to_sparse did. */
typedef struct depthor_projection_stats {
    uint32_t zones;          /* zones in the frame */
    uint32_t projected;      /* zones written into the sparse map */
    uint32_t invalid_status; /* skipped for their target status */
    uint32_t bad_distance;   /* skipped: distance <= 0, beyond range or not finite */
    uint32_t behind_camera;  /* skipped: behind the camera */
    uint32_t out_of_image;   /* skipped: outside the image */
    uint32_t collisions;     /* points on a pixel already written (the nearer kept) */
    uint32_t skipped;        /* sum of the four skip counters */
} depthor_projection_stats;

/* Bytes of engine memory depthor_engine_init needs. */
size_t depthor_engine_size(void);

/* Alignment of the engine memory, bytes (a power of two, at most 8). */
size_t depthor_engine_align(void);

/* Arena bytes the blob needs at height x width (0, 0: the blob's native size), into
 * *out_bytes. Parses and plans; runs nothing. */
int32_t depthor_arena_bytes(const uint8_t *blob, size_t blob_len, uint32_t height,
                            uint32_t width, size_t *out_bytes);

/* Prepares an engine in `engine` (depthor_engine_size() bytes, depthor_engine_align()
 * aligned) for height x width (0, 0: the blob's native size), with the fastest plan that fits
 * arena_len (at the depthor_arena_bytes() minimum the smallest; a larger arena may buy a less
 * fused, faster plan; the output bits are the same). `blob` and `arena` must stay valid while
 * the engine is used; the engine memory, arena and blob must not overlap.
 * Calling it again on the same memory re-initialises it (nothing to release). */
int32_t depthor_engine_init(depthor_engine *engine, const uint8_t *blob, size_t blob_len,
                            uint8_t *arena, size_t arena_len, uint32_t height, uint32_t width);

/* The input size the engine runs at. */
int32_t depthor_engine_input_size(const depthor_engine *engine, uint32_t *height,
                                  uint32_t *width);

/* Runs one frame: rgb888 is H*W*3 bytes (interleaved, row-major), sparse_m H*W floats
 * (metres, 0 = no point), depth_m receives H*W floats (metres). sparse_m == depth_m (same
 * pointer and length) runs in place; any other overlap is DEPTHOR_E_OVERLAP. Lengths are in
 * elements (bytes for RGB, floats for the depth maps). */
int32_t depthor_engine_run(depthor_engine *engine, const uint8_t *rgb888, size_t rgb_len,
                           const float *sparse_m, size_t sparse_len, float *depth_m,
                           size_t depth_len);

/* Projects one dToF frame (`zones` = zone_rows * zone_cols distances in mm and ST
 * target_status bytes, row-major) into the sparse map sparse_m (width * height floats,
 * zero-filled first). `stats` may be NULL. A frame with stats.projected == 0 has no metric
 * depth: do not run the engine on it. */
int32_t depthor_project_to_sparse(const depthor_calibration *cal, const float *distance_mm,
                                  const uint8_t *status, size_t zones, float *sparse_m,
                                  size_t sparse_len, depthor_projection_stats *stats);

/* A static English description of a status code; never NULL. */
const char *depthor_status_message(int32_t status);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* DEPTHOR_H */
