/* replay.c: see replay.h. C99. */
#include "replay.h"

#include <stdio.h>
#include <string.h>

#define HEADER_LEN 104u
#define CRC_LEN 4u
#define MAX_SIDE 4096u
#define MAX_ZONE_SIDE 255u

static uint16_t u16_at(const uint8_t *b, size_t at) {
    return (uint16_t)(b[at] | (b[at + 1] << 8));
}

static uint32_t u32_at(const uint8_t *b, size_t at) {
    return (uint32_t)b[at] | ((uint32_t)b[at + 1] << 8) | ((uint32_t)b[at + 2] << 16) |
           ((uint32_t)b[at + 3] << 24);
}

static float f32_at(const uint8_t *b, size_t at) {
    uint32_t bits = u32_at(b, at);
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

uint32_t replay_crc32(const uint8_t *bytes, size_t len) {
    uint32_t crc = 0xffffffffu;
    size_t i;
    int k;
    for (i = 0; i < len; i++) {
        crc ^= bytes[i];
        for (k = 0; k < 8; k++) {
            crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
        }
    }
    return ~crc;
}

uint64_t replay_fnv1a64_f32(const float *values, size_t n) {
    uint64_t h = 0xcbf29ce484222325ull;
    size_t i;
    int k;
    for (i = 0; i < n; i++) {
        uint32_t bits;
        memcpy(&bits, &values[i], sizeof bits);
        for (k = 0; k < 4; k++) {
            h ^= (bits >> (8 * k)) & 0xffu;
            h *= 0x00000100000001b3ull;
        }
    }
    return h;
}

/* n rounded up to a multiple of 4; 0 on overflow. */
static size_t pad4(size_t n) {
    return n > SIZE_MAX - 3 ? 0 : ((n + 3) & ~(size_t)3);
}

int replay_parse(replay_image *img, const uint8_t *b, size_t len) {
    static const uint8_t magic[8] = {'D', 'P', 'T', 'H', 'R', 'P', 'L', 'Y'};
    uint32_t frames, f;
    uint16_t h, w, rows, cols;
    size_t zones, rgb_off, rgb, record, expected;
    int i;

    if (len < HEADER_LEN + CRC_LEN) {
        return (len >= 8 && memcmp(b, magic, 8) != 0) ? 2 : 5;
    }
    if (memcmp(b, magic, 8) != 0) return 2;
    if (u16_at(b, 8) != 1) return 3;
    if (u16_at(b, 10) != HEADER_LEN) return 4;
    frames = u32_at(b, 12);
    h = u16_at(b, 16);
    w = u16_at(b, 18);
    rows = u16_at(b, 20);
    cols = u16_at(b, 22);
    if (frames == 0) return 4;
    if (h < 1 || h > MAX_SIDE || w < 1 || w > MAX_SIDE) return 4;
    if (rows < 1 || rows > MAX_ZONE_SIDE || cols < 1 || cols > MAX_ZONE_SIDE) return 4;
    if (b[24] > 1) return 4;
    if (b[25] != 0 || b[26] != 0 || b[27] != 0) return 4;
    zones = (size_t)rows * cols;
    rgb_off = pad4(zones * 3 + 4);
    rgb = (size_t)h * w * 3;
    if (rgb_off == 0 || rgb > SIZE_MAX - rgb_off) return 4;
    record = pad4(rgb_off + rgb);
    if (record == 0 || frames > (SIZE_MAX - HEADER_LEN - CRC_LEN) / record) return 4;
    expected = (size_t)frames * record + HEADER_LEN + CRC_LEN;
    if (len < expected) return 5;
    if (len > expected) return 6;
    if (u32_at(b, expected - CRC_LEN) != replay_crc32(b, expected - CRC_LEN)) return 7;
    for (f = 0; f < frames; f++) {
        size_t at = HEADER_LEN + (size_t)f * record;
        if (u16_at(b, at + 2) != 0) return 4;
        if (u16_at(b, at) != zones) return 8;
    }
    img->bytes = b;
    img->len = len;
    img->frames = frames;
    img->height = h;
    img->width = w;
    img->rows = rows;
    img->cols = cols;
    img->record_len = record;
    img->rgb_offset = rgb_off;
    img->cal.width = w;
    img->cal.height = h;
    img->cal.fx = f32_at(b, 28);
    img->cal.fy = f32_at(b, 32);
    img->cal.cx = f32_at(b, 36);
    img->cal.cy = f32_at(b, 40);
    img->cal.zone_rows = rows;
    img->cal.zone_cols = cols;
    img->cal.distance_kind = b[24] ? DEPTHOR_DISTANCE_RADIAL : DEPTHOR_DISTANCE_Z;
    img->cal.fov_h_deg = f32_at(b, 44);
    img->cal.fov_v_deg = f32_at(b, 48);
    img->cal.max_range_m = f32_at(b, 52);
    for (i = 0; i < 9; i++) img->cal.rotation[i] = f32_at(b, 56 + 4 * (size_t)i);
    for (i = 0; i < 3; i++) img->cal.translation_m[i] = f32_at(b, 92 + 4 * (size_t)i);
    return 0;
}

int replay_process(const replay_image *img, uint32_t index, depthor_engine *engine,
                   const replay_workspace *ws, char *line, size_t line_len, int32_t *status) {
    size_t zones = (size_t)img->rows * img->cols;
    size_t pixels = (size_t)img->height * img->width;
    const uint8_t *record, *st, *rgb;
    depthor_projection_stats stats;
    size_t z;
    int32_t s;
    uint64_t hash;

    *status = DEPTHOR_OK;
    if (index >= img->frames) return 14;
    if (ws->zones_cap < zones) return 13;
    if (ws->depth_cap < pixels) return 14;
    record = img->bytes + HEADER_LEN + (size_t)index * img->record_len;
    for (z = 0; z < zones; z++) {
        long mm = (long)u16_at(record, 4 + 2 * z);
        ws->zones_mm[z] = (float)(mm >= 0x8000 ? mm - 0x10000 : mm); /* i16, little endian */
    }
    if (ws->mark) ws->mark(ws->mark_ctx, REPLAY_STAGE_PROJECTION);
    st = record + 4 + 2 * zones;
    rgb = record + img->rgb_offset;
    s = depthor_project_to_sparse(&img->cal, ws->zones_mm, st, zones, ws->depth_m, pixels,
                                  &stats);
    if (s != DEPTHOR_OK) {
        *status = s;
        return 15;
    }
    if (stats.projected == 0) return 17;
    if (ws->mark) ws->mark(ws->mark_ctx, REPLAY_STAGE_ENGINE);
    s = depthor_engine_run(engine, rgb, pixels * 3, ws->depth_m, pixels, ws->depth_m, pixels);
    if (s != DEPTHOR_OK) {
        *status = s;
        return 16;
    }
    if (ws->mark) ws->mark(ws->mark_ctx, REPLAY_STAGE_DONE);
    hash = replay_fnv1a64_f32(ws->depth_m, pixels);
    /* Two 32-bit halves: newlib's inttypes.h lacks PRIx64 under -std=c99 on arm-none-eabi. */
    snprintf(line, line_len,
             "frame %lu depth_fnv1a64=%08lx%08lx points=%lu skipped=%lu collisions=%lu",
             (unsigned long)index, (unsigned long)(hash >> 32),
             (unsigned long)(hash & 0xffffffffu), (unsigned long)stats.projected,
             (unsigned long)stats.skipped, (unsigned long)stats.collisions);
    return 0;
}
