"""A copy of a recording with camera-like photometric changes on every RGB frame.

    python -m depthor_models.photo_recording --recording rec/val --out rec/val_photo --seed 5

Frame `i` gets `train.photometric` with probability 1 (exposure gain, white balance, contrast,
saturation, gamma, and with their own probabilities vignetting, blur, JPEG re-encoding and
shot/read noise), drawn from (seed, i); depth, zones, labels and calibration are copied
unchanged. Made from rendered frames, such a copy is a real-like check set for int8 fidelity or
a calibration set (`depthor quantize --calibration-recording`) that covers the colour statistics
real cameras give, without touching the real evaluation sets (issue 16, item 4).
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from .train import photometric


def write(src: str | Path, out: str | Path, seed: int, overwrite: bool = False) -> int:
    """Writes the photometric copy of recording `src` to `out`; returns the frame count."""
    src, out = Path(src), Path(out)
    meta = json.loads((src / "recording.json").read_text())
    if out.exists():
        if not overwrite:
            raise FileExistsError(f"{out}: exists (pass --overwrite to replace it)")
        shutil.rmtree(out)
    shutil.copytree(src, out, ignore=shutil.ignore_patterns(".depthor-train-cache*"))
    ids = [str(f["id"]) for f in meta["frames"]]
    for i, fid in enumerate(ids):
        path = out / "frames" / fid / "rgb.png"
        with Image.open(path) as im:
            rgb = np.asarray(im.convert("RGB"), np.float32) / 255.0
        x = torch.from_numpy(rgb).permute(2, 0, 1)[None]
        y = photometric(x, seed, i, p=1.0)[0]
        arr = (y.permute(1, 2, 0).numpy() * 255.0).round().clip(0, 255).astype(np.uint8)
        Image.fromarray(arr).save(path)
    return len(ids)


def main(argv: list[str] | None = None) -> int:
    """CLI entry point."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--recording", required=True, help="source recording folder")
    ap.add_argument("--out", required=True, help="output recording folder")
    ap.add_argument("--seed", type=int, required=True, help="draws of frame i: (seed, i)")
    ap.add_argument("--overwrite", action="store_true")
    a = ap.parse_args(argv)
    n = write(a.recording, a.out, a.seed, a.overwrite)
    print(f"wrote {a.out}: {n} frames with photometric changes (seed {a.seed})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
