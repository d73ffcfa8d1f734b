#!/usr/bin/env python3
"""Conceals one effect in a copy of a recording's zones, by code independent of the simulator.

A check of `depthor gap` as a user would run it (issue 19): take a recording whose zones were
simulated on real RGB-D frames (e.g. three sets imported at native resolution, `depthor sim
--preset l5 --from`, joined with per-frame cameras), change its zones here, run `depthor gap` on
the copy and read the first finding. Zone facts are computed here from the frame's own files
(mean reference depth and mean HSV value over the zone rectangle, grid radius, the measured
distance), never from the simulator.

    python3 inject.py SRC DST EFFECT [--amp A] [--seed S]

EFFECTS lists the forms (each other than the library's own form of its family).
"""
import argparse
import json
import math
import os
import random
import shutil

import numpy as np
from PIL import Image

VALID = (5, 9)


def zone_facts(frame_dir, rects, rows, cols):
    depth = np.asarray(Image.open(f"{frame_dir}/depth.png"), dtype=np.float64) / 1000.0
    rgb = np.asarray(Image.open(f"{frame_dir}/rgb.png").convert("RGB"), dtype=np.float64)
    v = rgb.max(axis=2) / 255.0
    h, w = depth.shape
    out = []
    for z, (y0, x0, y1, x1) in enumerate(rects):
        ya, yb = max(0, math.floor(y0)), min(h, math.ceil(y1))
        xa, xb = max(0, math.floor(x0)), min(w, math.ceil(x1))
        d = depth[ya:yb, xa:xb]
        d = d[d > 0]
        vv = v[ya:yb, xa:xb]
        gy = (z // cols - (rows - 1) / 2) / ((rows - 1) / 2)
        gx = (z % cols - (cols - 1) / 2) / ((cols - 1) / 2)
        out.append({
            "range": float(d.mean()) if d.size else 0.0,
            "v": float(vv.mean()) if vv.size else 0.0,
            "radius": math.sqrt((gy * gy + gx * gx) / 2),
        })
    return out


def sigmoid(x):
    return 1.0 / (1.0 + math.exp(-x))


# name: (kind, function of (zone facts, measured m, thresholds) -> value at unit amplitude)
EFFECTS = {
    "range_loss_logistic": ("loss", lambda z, m, t: sigmoid((z["range"] - t["d75"]) / 0.1)),
    "dark_loss_threshold": ("loss", lambda z, m, t: float(z["v"] < t["v25"])),
    "border_loss_outer_ring": ("loss", lambda z, m, t: float(z["radius"] > 0.8)),
    "noise_d2": ("noise", lambda z, m, t: m * m),
    "noise_d3": ("noise", lambda z, m, t: m ** 3),
    "bias_offset": ("bias", lambda z, m, t: 1.0),
    "bias_far_sqrt": ("bias", lambda z, m, t: math.sqrt(max(m - t["d50"], 0.0))),
    "wiggle_cos": ("bias", lambda z, m, t: math.cos(2 * math.pi * m / 0.3)),
    "wiggle_minus_sin": ("bias", lambda z, m, t: -math.sin(2 * math.pi * m / 0.3)),
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("effect", choices=sorted(EFFECTS))
    ap.add_argument("--amp", type=float, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--frames", type=int, default=0, help="keep only the first N frames")
    a = ap.parse_args()
    rng = random.Random(a.seed)
    head = json.load(open(f"{a.src}/recording.json"))
    rows, cols = head["dtof"]["rows"], head["dtof"]["cols"]
    rects = head["dtof"]["zone_rects_px"]
    frames = head["frames"][: a.frames] if a.frames else head["frames"]
    shutil.rmtree(a.dst, ignore_errors=True)
    os.makedirs(f"{a.dst}/frames")
    facts, zones = [], []
    for f in frames:
        shutil.copytree(f"{a.src}/frames/{f['id']}", f"{a.dst}/frames/{f['id']}")
        facts.append(zone_facts(f"{a.src}/frames/{f['id']}", rects, rows, cols))
        zones.append(json.load(open(f"{a.src}/frames/{f['id']}/dtof.json")))
    valid = [(z, d) for fz, dz in zip(facts, zones) for z, s, d in
             zip(fz, dz["status"], dz["distance_mm"]) if s in VALID and z["range"] > 0]
    q = lambda xs, p: float(np.quantile(np.array(xs), p))
    t = {"d75": q([z["range"] for z, _ in valid], 0.75), "d50": q([d / 1000 for _, d in valid], 0.5),
         "v25": q([z["v"] for z, _ in valid], 0.25)}
    kind, fn = EFFECTS[a.effect]
    for f, fz, dz in zip(frames, facts, zones):
        for i, z in enumerate(fz):
            if dz["status"][i] not in VALID:
                continue
            m = dz["distance_mm"][i] / 1000.0
            u = fn(z, m, t)
            if kind == "loss":
                if rng.random() < min(a.amp * u, 1.0):
                    dz["status"][i], dz["distance_mm"][i] = 255, 0.0
            elif kind == "noise":
                dz["distance_mm"][i] = max(1.0, 1000 * (m + a.amp * u * rng.gauss(0, 1)))
            else:
                dz["distance_mm"][i] = max(1.0, 1000 * (m + a.amp * u))
        json.dump(dz, open(f"{a.dst}/frames/{f['id']}/dtof.json", "w"))
    head["frames"] = frames
    json.dump(head, open(f"{a.dst}/recording.json", "w"), indent=1)
    print(f"{a.effect} amp {a.amp}: {len(frames)} frames, thresholds {t}")


if __name__ == "__main__":
    main()
