#!/usr/bin/env python3
"""Writes the small committed seed inputs of the fuzz targets (all but parse_blob's, which
`cargo test -p depthor-core --test blob fuzz_seed` writes with the blob) from the shipped replay
recording `firmware-sim/images/default.dri` (8x8 zones, 120x160 RGB): its calibration, its first
frames' zones and a subsampled RGB. Each byte layout is the one documented at the top of its
target in fuzz_targets/. Run from anywhere: python3 core/fuzz/make_seeds.py
"""
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
SEEDS = os.path.join(HERE, "seeds")

img = open(os.path.join(ROOT, "firmware-sim/images/default.dri"), "rb").read()
assert img[:8] == b"DPTHRPLY"
H, W, ROWS, COLS = struct.unpack_from("<4H", img, 16)
KIND = img[24]
CAL = list(struct.unpack_from("<19f", img, 28))  # fx fy cx cy, fov h v, range, R (9), t (3)
Z = ROWS * COLS


def pad4(n):
    return (n + 3) & ~3


REC = pad4(pad4(4 + 3 * Z) + 3 * H * W)


def frame(i):
    at = 104 + i * REC
    dist = struct.unpack_from("<%dh" % Z, img, at + 4)
    status = img[at + 4 + 2 * Z : at + 4 + 3 * Z]
    rgb_at = at + pad4(4 + 3 * Z)
    rgb = img[rgb_at : rgb_at + 3 * H * W]
    return dist, status, rgb


def subsample(rgb, h, w):
    out = bytearray()
    for y in range(h):
        for x in range(w):
            sy, sx = y * H // h, x * W // w
            out += rgb[3 * (sy * W + sx) : 3 * (sy * W + sx) + 3]
    return bytes(out)


def write(target, name, data):
    d = os.path.join(SEEDS, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def replay_image(h, w, frames):
    """A replay image (firmware-sim/replay/src/format.rs) at h x w with the recording's zones
    and calibration, intrinsics scaled to the smaller image."""
    cal = CAL[:]
    sx, sy = w / W, h / H
    cal[0], cal[1], cal[2], cal[3] = cal[0] * sx, cal[1] * sy, (cal[2] + 0.5) * sx - 0.5, (cal[3] + 0.5) * sy - 0.5
    out = bytearray(b"DPTHRPLY")
    out += struct.pack("<HHIHHHHB3x", 1, 104, len(frames), h, w, ROWS, COLS, KIND)
    out += struct.pack("<19f", *cal)
    assert len(out) == 104
    for i in frames:
        dist, status, rgb = frame(i)
        rec = bytearray(struct.pack("<HH", Z, 0))
        rec += struct.pack("<%dh" % Z, *dist) + status
        rec += bytes(pad4(len(rec)) - len(rec))
        rec += subsample(rgb, h, w)
        rec += bytes(pad4(len(rec)) - len(rec))
        out += rec
    out += struct.pack("<I", zlib.crc32(bytes(out)) & 0xFFFFFFFF)
    return bytes(out)


# replay_image: `mode, image`; mode 0 keeps the CRC.
write("replay_image", "rec_8x8_2frames", b"\x00" + replay_image(8, 8, [0, 1]))
write("replay_image", "rec_12x16_1frame", b"\x00" + replay_image(12, 16, [2]))

# projection: rows, cols, kind, flags, width, height, 19 f32, per zone f32 mm + status [+ rect].
def projection(kind, flags, i, rows=ROWS, cols=COLS):
    dist, status, _ = frame(i)
    out = struct.pack("<6B", rows, cols, kind, flags, W, H) + struct.pack("<19f", *CAL)
    for z in range(rows * cols):
        out += struct.pack("<fB", float(dist[z]), status[z])
        if flags & 1:
            r, c = divmod(z, cols)
            out += struct.pack("<4f", r * H / rows, c * W / cols, (r + 1) * H / rows, (c + 1) * W / cols)
    return out


write("projection", "rec_frame0_z", projection(0, 0, 0))
write("projection", "rec_frame1_radial", projection(1, 0, 1))
write("projection", "rec_4x4_rects", projection(0, 1, 3, 4, 4))

# zone_bridge: cfg, then per transaction a control byte (0 = ok) and a read's data.
def bridge(cfg, frames, lazy):
    header = struct.pack("<4B2HBH", 0xDB, 1, ROWS, COLS, round(CAL[4] * 100), round(CAL[5] * 100), KIND, round(CAL[6] * 1000))
    out = bytearray([cfg])
    if not lazy:
        out += b"\x00" + header  # init
    for n, i in enumerate(frames):
        if lazy and n == 0:
            out += b"\x00" + header
        out += b"\x00\x00" * n + b"\x00\x01"  # n polls not ready, then DATA_READY
        dist, status, _ = frame(i)
        for c in range(0, Z, 16):
            out += b"\x00" + b"".join(struct.pack("<hB", dist[z], status[z]) for z in range(c, min(c + 16, Z)))
        out += b"\x00"  # release
        out += b"\x00" + bytes([n + 1])  # frame count
    return bytes(out)


# cfg: bit 0 init, bits 1-2 frames - 1, bit 3 64-zone frame, bits 4-7 polls - 1.
write("zone_bridge", "rec_init_2frames_big", bridge(0b0011_0011, [0, 1], False))
write("zone_bridge", "rec_lazy_1frame_64", bridge(0b0001_1000, [2], True))

# engine_run: mode (bits 4-5: size 4x4, 8x8, 4x16, 12x16), rgb (3*h*w), sparse; the
# recording's frame subsampled to h x w and a sparse map with a few points at the zone centres'
# depths.
SIZES = [(4, 4), (8, 8), (4, 16), (12, 16)]


def engine_frame(size):
    h, w = SIZES[size]
    _, _, rgb = frame(0)
    dist, status, _ = frame(0)
    sparse = [0.0] * (h * w)
    for z in range(Z):
        r, c = divmod(z, COLS)
        if status[z] in (5, 9) and dist[z] > 0:
            sparse[min(r * h // ROWS + 1, h - 1) * w + c * w // COLS] = dist[z] / 1000.0
    return size << 4, subsample(rgb, h, w), sparse


m, small, sparse = engine_frame(0)
write("engine_run", "rec_raw_f32", bytes([m]) + small + struct.pack("<%df" % len(sparse), *sparse))
m, small, sparse = engine_frame(1)
mm = struct.pack("<%dH" % len(sparse), *(round(v * 1000) for v in sparse))
write("engine_run", "rec_in_place_mm", bytes([m | 0x0D]) + small + mm)
m, small, sparse = engine_frame(2)
write("engine_run", "specials_palette", bytes([m | 0x04]) + small + bytes(range(16)) * (len(sparse) // 16))
m, small, sparse = engine_frame(3)
write("engine_run", "rec_raw_f32_12x16", bytes([m]) + small + struct.pack("<%df" % len(sparse), *sparse))
write("engine_run", "wrong_lengths", bytes([m | 0x02]) + struct.pack("<3H", 0, 1, 3) + small)
