/*
 * test_api.c: depthor.h from C, driven by ffi/tests/c_api.rs (which compiles it with
 * gcc -std=c99 -Wall -Wextra -Werror -pedantic, plain and under -fsanitize=address,undefined,
 * and checks its output).
 *
 * Usage: test_api BLOB IMAGE
 * Prints the structs' layout ("layout ..."), one line per error-path check ("check NAME got=X
 * want=Y"), then the replay image's frames through the library ("frame ..." lines, compared with
 * the Rust host by the test) and "errors FAILED-COUNT". Exit status 0 only when every check
 * passed and every frame ran.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "depthor.h"
#include "replay.h"

static int failures = 0;

/* The address `off` bytes past `p` as an integer, cast straight to the pointer type: an
 * integer-to-pointer conversion of a misaligned address is implementation-defined (C99
 * 6.3.2.3p5), a pointer-to-pointer one would be undefined (p7). The library must refuse the
 * pointer without dereferencing it. */
#define MISALIGN(p, off) ((uintptr_t)(const void *)(p) + (uintptr_t)(off))

static void check(const char *name, int32_t got, int32_t want) {
    printf("check %s got=%d want=%d%s\n", name, (int)got, (int)want, got == want ? "" : " FAIL");
    if (got != want) failures++;
}

static uint8_t *read_file(const char *path, size_t *len) {
    FILE *f = fopen(path, "rb");
    uint8_t *buf;
    long n;
    if (!f) return NULL;
    if (fseek(f, 0, SEEK_END) != 0 || (n = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        return NULL;
    }
    buf = (uint8_t *)malloc((size_t)n + 1);
    if (buf && fread(buf, 1, (size_t)n, f) != (size_t)n) {
        free(buf);
        buf = NULL;
    }
    fclose(f);
    *len = (size_t)n;
    return buf;
}

#define OFF(type, field) printf(" %s=%lu", #field, (unsigned long)offsetof(type, field))

static void print_layout(void) {
    printf("layout depthor_calibration size=%lu", (unsigned long)sizeof(depthor_calibration));
    OFF(depthor_calibration, width);
    OFF(depthor_calibration, height);
    OFF(depthor_calibration, fx);
    OFF(depthor_calibration, fy);
    OFF(depthor_calibration, cx);
    OFF(depthor_calibration, cy);
    OFF(depthor_calibration, zone_rows);
    OFF(depthor_calibration, zone_cols);
    OFF(depthor_calibration, distance_kind);
    OFF(depthor_calibration, fov_h_deg);
    OFF(depthor_calibration, fov_v_deg);
    OFF(depthor_calibration, max_range_m);
    OFF(depthor_calibration, rotation);
    OFF(depthor_calibration, translation_m);
    printf("\n");
    printf("layout depthor_projection_stats size=%lu",
           (unsigned long)sizeof(depthor_projection_stats));
    OFF(depthor_projection_stats, zones);
    OFF(depthor_projection_stats, projected);
    OFF(depthor_projection_stats, invalid_status);
    OFF(depthor_projection_stats, bad_distance);
    OFF(depthor_projection_stats, behind_camera);
    OFF(depthor_projection_stats, out_of_image);
    OFF(depthor_projection_stats, collisions);
    OFF(depthor_projection_stats, skipped);
    printf("\n");
    printf("layout depthor_engine_storage size=%lu engine_size=%lu engine_align=%lu\n",
           (unsigned long)sizeof(depthor_engine_storage), (unsigned long)depthor_engine_size(),
           (unsigned long)depthor_engine_align());
}

/* A copy of `blob` with byte `at` xor-ed with `x`. */
static uint8_t *corrupt(const uint8_t *blob, size_t len, size_t at, uint8_t x) {
    uint8_t *c = (uint8_t *)malloc(len);
    memcpy(c, blob, len);
    c[at] ^= x;
    return c;
}

static void status_messages(void) {
    static const int32_t codes[] = {
        DEPTHOR_OK,          DEPTHOR_E_NULL,         DEPTHOR_E_ALIGN,
        DEPTHOR_E_BLOB,      DEPTHOR_E_BLOB_CHECKSUM, DEPTHOR_E_BLOB_VERSION,
        DEPTHOR_E_SIZE,      DEPTHOR_E_ARENA,        DEPTHOR_E_LENGTH,
        DEPTHOR_E_OVERLAP,   DEPTHOR_E_NOT_INIT,     DEPTHOR_E_CALIBRATION,
        DEPTHOR_E_INTERNAL};
    const size_t n = sizeof codes / sizeof codes[0];
    const char *unknown = depthor_status_message(12345);
    size_t i, j;
    int bad = 0;
    for (i = 0; i < n; i++) {
        const char *m = depthor_status_message(codes[i]);
        if (m == NULL || m[0] == '\0' || strcmp(m, unknown) == 0) bad++;
        for (j = 0; j < i; j++) {
            if (strcmp(m, depthor_status_message(codes[j])) == 0) bad++;
        }
    }
    if (strcmp(unknown, "unknown status code") != 0) bad++;
    if (depthor_status_message(-13) == NULL || strcmp(depthor_status_message(-13), unknown) != 0)
        bad++;
    check("status_messages_distinct_nonnull", bad, 0);
}

static void error_paths(const uint8_t *blob, size_t blob_len, const replay_image *img) {
    const uint32_t H = img->height, W = img->width;
    const size_t n = (size_t)H * W;
    size_t need = 0, out = 0;
    uint8_t *arena, *bad;
    unsigned char *mem_bytes;
    depthor_engine *eng;
    uint8_t *rgb = (uint8_t *)calloc(3 * n, 1);
    float *sparse = (float *)calloc(n + 1, sizeof(float));
    float *depth = (float *)calloc(2 * n + 1, sizeof(float));
    float zones_mm[64];
    uint8_t status[64];
    depthor_calibration cal = img->cal;
    depthor_projection_stats stats;
    uint32_t h = 0, w = 0;
    size_t zones = (size_t)img->rows * img->cols;
    size_t i;

    for (i = 0; i < 3 * n; i++) rgb[i] = (uint8_t)(i * 7 % 251);
    for (i = 0; i < n; i += 97) sparse[i] = 1.5f;

    /* depthor_arena_bytes */
    check("arena_ok", depthor_arena_bytes(blob, blob_len, H, W, &need), DEPTHOR_OK);
    check("arena_native_equal", depthor_arena_bytes(blob, blob_len, 0, 0, &out) == DEPTHOR_OK &&
                                        out == need ? 0 : 1, 0);
    check("arena_null_blob", depthor_arena_bytes(NULL, blob_len, H, W, &out), DEPTHOR_E_NULL);
    check("arena_null_out", depthor_arena_bytes(blob, blob_len, H, W, NULL), DEPTHOR_E_NULL);
    check("arena_zero_side", depthor_arena_bytes(blob, blob_len, 0, W, &out), DEPTHOR_E_SIZE);
    check("arena_huge", depthor_arena_bytes(blob, blob_len, 0xffffffffu, 0xffffffffu, &out),
          DEPTHOR_E_SIZE);
    check("arena_truncated_blob", depthor_arena_bytes(blob, 20, H, W, &out), DEPTHOR_E_BLOB);
    check("arena_length_overflow", depthor_arena_bytes(blob, SIZE_MAX, H, W, &out),
          DEPTHOR_E_LENGTH);
    bad = corrupt(blob, blob_len, 0, 0xff);
    check("arena_bad_magic", depthor_arena_bytes(bad, blob_len, H, W, &out), DEPTHOR_E_BLOB);
    free(bad);
    bad = corrupt(blob, blob_len, 4, 0x01);
    check("arena_bad_version", depthor_arena_bytes(bad, blob_len, H, W, &out),
          DEPTHOR_E_BLOB_VERSION);
    free(bad);
    bad = corrupt(blob, blob_len, blob_len - 1, 0x5a);
    check("arena_bad_checksum", depthor_arena_bytes(bad, blob_len, H, W, &out),
          DEPTHOR_E_BLOB_CHECKSUM);

    /* depthor_engine_init */
    mem_bytes = (unsigned char *)calloc(1, depthor_engine_size() + 8);
    eng = (depthor_engine *)(void *)mem_bytes;
    arena = (uint8_t *)malloc(need);
    check("run_never_initialised", depthor_engine_run(eng, rgb, 3 * n, sparse, n, depth, n),
          DEPTHOR_E_NOT_INIT);
    check("input_size_never_initialised", depthor_engine_input_size(eng, &h, &w),
          DEPTHOR_E_NOT_INIT);
    check("init_null_engine", depthor_engine_init(NULL, blob, blob_len, arena, need, H, W),
          DEPTHOR_E_NULL);
    check("init_null_blob", depthor_engine_init(eng, NULL, blob_len, arena, need, H, W),
          DEPTHOR_E_NULL);
    check("init_null_arena", depthor_engine_init(eng, blob, blob_len, NULL, need, H, W),
          DEPTHOR_E_NULL);
    check("init_misaligned_engine",
          depthor_engine_init((depthor_engine *)MISALIGN(mem_bytes, 1), blob, blob_len, arena,
                              need, H, W),
          DEPTHOR_E_ALIGN);
    check("init_arena_too_small", depthor_engine_init(eng, blob, blob_len, arena, need - 16, H, W),
          DEPTHOR_E_ARENA);
    check("init_arena_overlaps_engine",
          depthor_engine_init(eng, blob, blob_len, mem_bytes + 8, depthor_engine_size(), H, W),
          DEPTHOR_E_OVERLAP);
    check("init_bad_checksum", depthor_engine_init(eng, bad, blob_len, arena, need, H, W),
          DEPTHOR_E_BLOB_CHECKSUM);
    free(bad);
    check("init_zero_side", depthor_engine_init(eng, blob, blob_len, arena, need, H, 0),
          DEPTHOR_E_SIZE);
    check("init_ok", depthor_engine_init(eng, blob, blob_len, arena, need, H, W), DEPTHOR_OK);
    check("input_size_ok", depthor_engine_input_size(eng, &h, &w), DEPTHOR_OK);
    check("input_size_values", h == H && w == W ? 0 : 1, 0);
    check("input_size_null", depthor_engine_input_size(eng, NULL, &w), DEPTHOR_E_NULL);

    /* depthor_engine_run */
    check("run_ok", depthor_engine_run(eng, rgb, 3 * n, sparse, n, depth, n), DEPTHOR_OK);
    check("run_null_engine", depthor_engine_run(NULL, rgb, 3 * n, sparse, n, depth, n),
          DEPTHOR_E_NULL);
    check("run_null_rgb", depthor_engine_run(eng, NULL, 3 * n, sparse, n, depth, n),
          DEPTHOR_E_NULL);
    check("run_null_sparse", depthor_engine_run(eng, rgb, 3 * n, NULL, n, depth, n),
          DEPTHOR_E_NULL);
    check("run_null_depth", depthor_engine_run(eng, rgb, 3 * n, sparse, n, NULL, n),
          DEPTHOR_E_NULL);
    check("run_misaligned_engine",
          depthor_engine_run((depthor_engine *)MISALIGN(mem_bytes, 4), rgb, 3 * n, sparse, n,
                             depth, n),
          DEPTHOR_E_ALIGN);
    check("run_misaligned_sparse",
          depthor_engine_run(eng, rgb, 3 * n, (const float *)MISALIGN(sparse, 1),
                             n, depth, n),
          DEPTHOR_E_ALIGN);
    check("run_misaligned_depth",
          depthor_engine_run(eng, rgb, 3 * n, sparse, n, (float *)MISALIGN(depth, 2), n),
          DEPTHOR_E_ALIGN);
    check("run_short_rgb", depthor_engine_run(eng, rgb, 3 * n - 1, sparse, n, depth, n),
          DEPTHOR_E_LENGTH);
    check("run_short_sparse", depthor_engine_run(eng, rgb, 3 * n, sparse, n - 1, depth, n),
          DEPTHOR_E_LENGTH);
    check("run_short_depth", depthor_engine_run(eng, rgb, 3 * n, sparse, n, depth, n - 1),
          DEPTHOR_E_LENGTH);
    check("run_long_depth", depthor_engine_run(eng, rgb, 3 * n, sparse, n, depth, n + 1),
          DEPTHOR_E_LENGTH);
    check("run_depth_overlaps_sparse",
          depthor_engine_run(eng, rgb, 3 * n, depth, n, depth + 1, n), DEPTHOR_E_OVERLAP);
    check("run_depth_overlaps_rgb",
          depthor_engine_run(eng, (const uint8_t *)depth, 3 * n, sparse, n, depth + n / 2, n),
          DEPTHOR_E_OVERLAP);
    check("run_depth_in_arena",
          depthor_engine_run(eng, rgb, 3 * n, sparse, n, (float *)(void *)(arena + 16), n),
          DEPTHOR_E_OVERLAP);
    memcpy(depth, sparse, n * sizeof(float));
    check("run_in_place_ok", depthor_engine_run(eng, rgb, 3 * n, depth, n, depth, n), DEPTHOR_OK);
    check("init_failed_leaves_uninitialised",
          depthor_engine_init(eng, blob, blob_len, arena, 16, H, W), DEPTHOR_E_ARENA);
    check("run_after_failed_init", depthor_engine_run(eng, rgb, 3 * n, sparse, n, depth, n),
          DEPTHOR_E_NOT_INIT);

    /* depthor_project_to_sparse */
    if (zones <= 64) {
        for (i = 0; i < zones; i++) {
            zones_mm[i] = 1000.0f;
            status[i] = 5;
        }
        check("project_ok",
              depthor_project_to_sparse(&cal, zones_mm, status, zones, sparse, n, &stats),
              DEPTHOR_OK);
        check("project_counts", stats.zones == zones && stats.projected > 0 ? 0 : 1, 0);
        check("project_null_stats_ok",
              depthor_project_to_sparse(&cal, zones_mm, status, zones, sparse, n, NULL),
              DEPTHOR_OK);
        check("project_null_cal",
              depthor_project_to_sparse(NULL, zones_mm, status, zones, sparse, n, NULL),
              DEPTHOR_E_NULL);
        check("project_null_distance",
              depthor_project_to_sparse(&cal, NULL, status, zones, sparse, n, NULL),
              DEPTHOR_E_NULL);
        check("project_null_status",
              depthor_project_to_sparse(&cal, zones_mm, NULL, zones, sparse, n, NULL),
              DEPTHOR_E_NULL);
        check("project_null_out",
              depthor_project_to_sparse(&cal, zones_mm, status, zones, NULL, n, NULL),
              DEPTHOR_E_NULL);
        check("project_zone_count",
              depthor_project_to_sparse(&cal, zones_mm, status, zones - 1, sparse, n, NULL),
              DEPTHOR_E_LENGTH);
        check("project_short_out",
              depthor_project_to_sparse(&cal, zones_mm, status, zones, sparse, n - 1, NULL),
              DEPTHOR_E_LENGTH);
        check("project_out_overlaps_distances",
              depthor_project_to_sparse(&cal, sparse, status, zones, sparse, n, NULL),
              DEPTHOR_E_OVERLAP);
        cal.distance_kind = 9;
        check("project_bad_distance_kind",
              depthor_project_to_sparse(&cal, zones_mm, status, zones, sparse, n, NULL),
              DEPTHOR_E_CALIBRATION);
        cal = img->cal;
        cal.fx = 0.0f;
        check("project_bad_focal_length",
              depthor_project_to_sparse(&cal, zones_mm, status, zones, sparse, n, NULL),
              DEPTHOR_E_CALIBRATION);
    } else {
        check("project_image_has_at_most_64_zones", 1, 0);
    }
    status_messages();

    free(arena);
    free(mem_bytes);
    free(rgb);
    free(sparse);
    free(depth);
}

int main(int argc, char **argv) {
    size_t blob_len = 0, image_len = 0, need = 0;
    uint8_t *blob, *image, *arena;
    replay_image img;
    replay_workspace ws;
    depthor_engine *eng;
    char line[160];
    uint32_t f;
    int code;
    int32_t st;

    if (argc != 3) {
        fprintf(stderr, "usage: %s BLOB IMAGE\n", argv[0]);
        return 2;
    }
    blob = read_file(argv[1], &blob_len);
    image = read_file(argv[2], &image_len);
    if (!blob || !image) {
        fprintf(stderr, "cannot read %s or %s\n", argv[1], argv[2]);
        return 2;
    }
    code = replay_parse(&img, image, image_len);
    if (code != 0) {
        printf("ERROR %d: replay image\n", code);
        return code;
    }
    print_layout();
    error_paths(blob, blob_len, &img);

    /* The replay image's frames, as the firmware runs them. */
    st = depthor_arena_bytes(blob, blob_len, img.height, img.width, &need);
    eng = (depthor_engine *)malloc(depthor_engine_size());
    arena = (uint8_t *)malloc(need);
    ws.zones_cap = (size_t)img.rows * img.cols;
    ws.zones_mm = (float *)malloc(ws.zones_cap * sizeof(float));
    ws.depth_cap = (size_t)img.height * img.width;
    ws.depth_m = (float *)malloc(ws.depth_cap * sizeof(float));
    ws.mark = NULL;
    ws.mark_ctx = NULL;
    if (st == DEPTHOR_OK) {
        st = depthor_engine_init(eng, blob, blob_len, arena, need, img.height, img.width);
    }
    if (st != DEPTHOR_OK) {
        printf("ERROR 16: %s\n", depthor_status_message(st));
        return 16;
    }
    for (f = 0; f < img.frames; f++) {
        code = replay_process(&img, f, eng, &ws, line, sizeof line, &st);
        if (code != 0) {
            printf("ERROR %d: %s\n", code, depthor_status_message(st));
            return code;
        }
        printf("%s\n", line);
    }
    printf("errors %d\n", failures);
    free(ws.zones_mm);
    free(ws.depth_m);
    free(arena);
    free(eng);
    free(blob);
    free(image);
    return failures == 0 ? 0 : 1;
}
