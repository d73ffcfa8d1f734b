"""Training data from `depthor-recording/1` folders (docs/recording.md), loaded into memory once.

A frame gives the network's inputs and target:
- rgb: `rgb.png` as float [3, H, W] in [0, 1];
- sparse S [1, H, W] in metres: each zone with a valid status puts its `distance_mm / 1000` at the
  pixel `floor(centre + 0.5)` of its rectangle in `recording.json` `dtof.zone_rects_px`
  (`[y0, x0, y1, x1]`, centre = ((y0 + y1) / 2, (x0 + x1) / 2)); zones whose pixel falls outside
  the image are dropped; everything else is 0;
- gt [1, H, W] in metres: `depth.png` (16-bit millimetres, 0 = unknown).

`load_recording` decodes the PNGs once (Pillow) and keeps numpy arrays; with `cache=True` it also
stores them as `<recording>/.depthor-train-cache.npz`, reused while recording.json is unchanged.
`FrameReader` / `FrameDataset` stream instead: only the headers are held, and each frame is
decoded (and resampled) when a DataLoader worker asks for it, so memory is bounded by the batches
in flight, not by the data set.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

CACHE_NAME = ".depthor-train-cache.npz"
CACHE_VERSION = 1


@dataclass
class Recording:
    """A recording in memory: rgb uint8 [N,H,W,3], depth_mm uint16 [N,H,W], zone distances
    float32 [N,Z] (metres), zone status uint8 [N,Z], zone pixels int64 [Z,2] (row, col; -1 when
    outside the image), zone grid shape (rows, cols), frame ids."""

    rgb: np.ndarray
    depth_mm: np.ndarray
    zone_m: np.ndarray
    status: np.ndarray
    zone_px: np.ndarray
    grid: tuple[int, int]
    ids: list[str]

    def __len__(self) -> int:
        return int(self.rgb.shape[0])

    @property
    def height(self) -> int:
        """Image height in pixels."""
        return int(self.rgb.shape[1])

    @property
    def width(self) -> int:
        """Image width in pixels."""
        return int(self.rgb.shape[2])


def zone_pixels(rects: list[list[float]], height: int, width: int) -> np.ndarray:
    """Pixel (row, col) = floor(centre + 0.5) of each `[y0, x0, y1, x1]` rectangle; (-1, -1) for
    a zone whose pixel is outside the image."""
    r = np.asarray(rects, dtype=np.float64).reshape(-1, 4)
    cy = (r[:, 0] + r[:, 2]) / 2.0
    cx = (r[:, 1] + r[:, 3]) / 2.0
    px = np.stack([np.floor(cy + 0.5), np.floor(cx + 0.5)], axis=1).astype(np.int64)
    inside = (px[:, 0] >= 0) & (px[:, 0] < height) & (px[:, 1] >= 0) & (px[:, 1] < width)
    px[~inside] = -1
    return px


def _read_png(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        if im.mode.startswith("I"):  # 16-bit grey ("I;16") or 32-bit ("I")
            return np.asarray(im).astype(np.uint16)
        return np.asarray(im if im.mode in ("L", "RGB") else im.convert("RGB"))


def _meta_key(meta_text: str) -> str:
    return hashlib.sha256(f"{CACHE_VERSION}:{meta_text}".encode()).hexdigest()


def _header(root: Path) -> tuple[str, dict, int, int, list, tuple[int, int]]:
    """(recording.json text, parsed header, H, W, zone rectangles, zone grid), checked."""
    meta_text = (root / "recording.json").read_text()
    meta = json.loads(meta_text)
    if meta.get("format") != "depthor-recording/1":
        raise ValueError(f"{root}: not a depthor-recording/1")
    cam, dtof = meta["camera"], meta["dtof"]
    h, w = int(cam["height"]), int(cam["width"])
    rects = dtof.get("zone_rects_px")
    if rects is None:
        raise ValueError(f"{root}: dtof.zone_rects_px is null (the loader needs zone rectangles)")
    grid = (int(dtof["rows"]), int(dtof["cols"]))
    if len(rects) != grid[0] * grid[1]:
        raise ValueError(f"{root}: {len(rects)} zone rectangles for a {grid} grid")
    return meta_text, meta, h, w, rects, grid


def _read_frame(fdir: Path, h: int, w: int) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                     np.ndarray]:
    """One frame folder: (rgb uint8 [H,W,3], depth_mm uint16 [H,W], zone distances float32 [Z]
    in metres, zone status uint8 [Z])."""
    im = _read_png(fdir / "rgb.png")
    dp = _read_png(fdir / "depth.png")
    if im.shape != (h, w, 3) or dp.shape != (h, w):
        raise ValueError(f"{fdir}: rgb {im.shape} / depth {dp.shape}, expected {h}x{w}")
    z = json.loads((fdir / "dtof.json").read_text())
    zone_m = np.asarray(z["distance_mm"], np.float32) / 1000.0
    status = np.asarray(z["status"], np.int64).clip(0, 255).astype(np.uint8)
    return im, dp, zone_m, status


def load_recording(path: str | Path, cache: bool = True,
                   size: tuple[int, int] | None = None) -> Recording:
    """Loads every frame of a recording (see module doc). With `size` = (H, W) different from
    the recording's, the frames are resampled to it as `depthor eval` does (`resample`), and
    the resampled arrays get their own cache. Raises ValueError for a recording without
    `zone_rects_px`, without reference depth, or with frames of another size."""
    root = Path(path)
    meta_text, meta, h, w, rects, grid = _header(root)
    if size is not None and tuple(size) != (h, w):
        return _load_resampled(root, cache, (int(size[0]), int(size[1])), (h, w), meta)
    zone_px = zone_pixels(rects, h, w)
    ids = [str(f["id"]) for f in meta["frames"]]
    key = _meta_key(meta_text)
    cache_path = root / CACHE_NAME
    if cache and cache_path.exists():
        with np.load(cache_path, allow_pickle=False) as z:
            if str(z["key"]) == key:
                return Recording(z["rgb"], z["depth_mm"], z["zone_m"], z["status"], zone_px,
                                 grid, ids)
    n, nz = len(ids), grid[0] * grid[1]
    rgb = np.empty((n, h, w, 3), np.uint8)
    depth = np.empty((n, h, w), np.uint16)
    zone_m = np.zeros((n, nz), np.float32)
    status = np.full((n, nz), 255, np.uint8)
    for i, fid in enumerate(ids):
        rgb[i], depth[i], zone_m[i], status[i] = _read_frame(root / "frames" / fid, h, w)
    if cache:
        tmp = root / (CACHE_NAME + ".tmp.npz")
        np.savez(tmp, key=np.array(key), rgb=rgb, depth_mm=depth, zone_m=zone_m, status=status)
        tmp.replace(cache_path)
    return Recording(rgb, depth, zone_m, status, zone_px, grid, ids)


def _load_resampled(root: Path, cache: bool, size: tuple[int, int], native: tuple[int, int],
                    meta: dict) -> Recording:
    h, w = size
    cache_path = root / f".depthor-train-cache-{h}x{w}.npz"
    key = _meta_key(f"{h}x{w}:" + (root / "recording.json").read_text())
    rects = resampled_rects(meta["dtof"]["zone_rects_px"], native, size)
    zone_px = zone_pixels(rects, h, w)
    grid = (int(meta["dtof"]["rows"]), int(meta["dtof"]["cols"]))
    ids = [str(f["id"]) for f in meta["frames"]]
    if cache and cache_path.exists():
        with np.load(cache_path, allow_pickle=False) as z:
            if str(z["key"]) == key:
                return Recording(z["rgb"], z["depth_mm"], z["zone_m"], z["status"], zone_px,
                                 grid, ids)
    full = load_recording(root, cache=False)
    rgb, depth = resample(full.rgb, full.depth_mm, size)
    del full.rgb, full.depth_mm
    if cache:
        tmp = root / (cache_path.name + ".tmp.npz")
        np.savez(tmp, key=np.array(key), rgb=rgb, depth_mm=depth, zone_m=full.zone_m,
                 status=full.status)
        tmp.replace(cache_path)
    return Recording(rgb, depth, full.zone_m, full.status, zone_px, grid, ids)


def _centre_crop(sh: int, sw: int, h: int, w: int) -> tuple[int, int, int, int]:
    """(y0, x0, ch, cw): the centred crop of an sh×sw image to the aspect ratio of h×w, as
    `depthor eval`'s resampling (host dataset::resample_frame) takes it."""
    target = w / h
    if sw / sh > target:
        cw, ch = min(max(round(sh * target), 1), sw), sh
    else:
        cw, ch = sw, min(max(round(sw / target), 1), sh)
    return (sh - ch) // 2, (sw - cw) // 2, ch, cw


def resample(rgb: np.ndarray, depth_mm: np.ndarray,
             size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Frames [N,sh,sw,3] / [N,sh,sw] → size (H, W) the way `depthor eval` resamples a recording
    for a model: centred crop to the aspect ratio, RGB by a triangle (bilinear, antialiased)
    filter, depth by the nearest source pixel (x0 + ((2x + 1)·cw) // (2W))."""
    from PIL import Image

    h, w = size
    n, sh, sw = depth_mm.shape
    y0, x0, ch, cw = _centre_crop(sh, sw, h, w)
    ys = np.minimum(y0 + ((2 * np.arange(h) + 1) * ch) // (2 * h), sh - 1)
    xs = np.minimum(x0 + ((2 * np.arange(w) + 1) * cw) // (2 * w), sw - 1)
    out_rgb = np.empty((n, h, w, 3), np.uint8)
    for i in range(n):
        im = Image.fromarray(rgb[i, y0:y0 + ch, x0:x0 + cw])
        out_rgb[i] = np.asarray(im.resize((w, h), Image.BILINEAR))
    return out_rgb, np.ascontiguousarray(depth_mm[:, ys][:, :, xs])


def resampled_rects(rects: list, native: tuple[int, int], size: tuple[int, int]) -> list:
    """Zone rectangles `[y0, x0, y1, x1]` mapped like eval maps projected points:
    v' = (v − y0c + 0.5)·s − 0.5 (pixel centres at integers) for the crop origin y0c."""
    (sh, sw), (h, w) = native, size
    cy0, cx0, ch, cw = _centre_crop(sh, sw, h, w)
    sy, sx = h / ch, w / cw
    r = np.asarray(rects, dtype=np.float64).reshape(-1, 4)
    out = np.empty_like(r)
    out[:, [0, 2]] = (r[:, [0, 2]] - cy0 + 0.5) * sy - 0.5
    out[:, [1, 3]] = (r[:, [1, 3]] - cx0 + 0.5) * sx - 0.5
    return out.tolist()


def load_recordings(paths: str | Path | list, cache: bool = True,
                    size: tuple[int, int] | None = None) -> Recording:
    """Several recordings of the same camera and zone layout as one (frames in order; ids
    prefixed with the folder name when more than one). `paths`: a list, or one string with
    comma-separated folders. Raises ValueError when sizes, grids or zone pixels differ."""
    if isinstance(paths, (str, Path)):
        paths = [p for p in str(paths).split(",") if p]
    recs = [load_recording(p, cache, size) for p in paths]
    if not recs:
        raise ValueError("no recording given")
    if len(recs) == 1:
        return recs[0]
    first = recs[0]
    for p, r in zip(paths[1:], recs[1:]):
        if (r.height, r.width, r.grid) != (first.height, first.width, first.grid) or \
                not np.array_equal(r.zone_px, first.zone_px):
            raise ValueError(f"{p}: frame size, zone grid or zone rectangles differ from {paths[0]}")
    ids = [f"{Path(p).name}/{i}" for p, r in zip(paths, recs) for i in r.ids]
    return Recording(np.concatenate([r.rgb for r in recs]),
                     np.concatenate([r.depth_mm for r in recs]),
                     np.concatenate([r.zone_m for r in recs]),
                     np.concatenate([r.status for r in recs]), first.zone_px, first.grid, ids)


def first_frames(paths: list[str], frames: int, size: tuple[int, int],
                 valid_status: tuple[int, ...] = (5,)) -> tuple[torch.Tensor, torch.Tensor]:
    """(rgb, sparse) of the first `frames` frames of each recording in `paths`, resampled to
    `size` = (H, W) as `depthor eval` does (for tools that measure a network on a few frames)."""
    rgbs, sps = [], []
    for p in paths:
        rec = load_recording(p, size=size)
        rgb, sp, _ = batch(rec, np.arange(min(frames, len(rec))), None, valid_status)
        rgbs.append(rgb)
        sps.append(sp)
    return torch.cat(rgbs), torch.cat(sps)


def sparse_maps(rec: Recording, idx: np.ndarray,
                valid_status: tuple[int, ...] = (5,)) -> np.ndarray:
    """Sparse depth maps float32 [len(idx), H, W] (metres) of the frames `idx`."""
    idx = np.asarray(idx, dtype=np.int64)
    out = np.zeros((len(idx), rec.height, rec.width), np.float32)
    ok_px = rec.zone_px[:, 0] >= 0
    valid = np.isin(rec.status[idx], valid_status) & ok_px[None, :] & (rec.zone_m[idx] > 0)
    b, z = np.nonzero(valid)
    out[b, rec.zone_px[z, 0], rec.zone_px[z, 1]] = rec.zone_m[idx][b, z]
    return out


def batch(rec: Recording, idx: np.ndarray, flip: np.ndarray | None = None,
          valid_status: tuple[int, ...] = (5,)) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(rgb [B,3,H,W] in [0,1], sparse [B,1,H,W] m, gt [B,1,H,W] m; 0 = unknown) for frames
    `idx`; frames with `flip[b]` are mirrored left-right (rgb, sparse and gt together)."""
    idx = np.asarray(idx, dtype=np.int64)
    rgb = rec.rgb[idx].astype(np.float32) / 255.0
    gt = rec.depth_mm[idx].astype(np.float32) / 1000.0
    sp = sparse_maps(rec, idx, valid_status)
    if flip is not None:
        f = np.asarray(flip, dtype=bool)
        rgb[f] = rgb[f][:, :, ::-1]
        gt[f] = gt[f][:, :, ::-1]
        sp[f] = sp[f][:, :, ::-1]
    return (torch.from_numpy(np.ascontiguousarray(rgb.transpose(0, 3, 1, 2))),
            torch.from_numpy(np.ascontiguousarray(sp[:, None])),
            torch.from_numpy(np.ascontiguousarray(gt[:, None])))


class RecordingDataset(Dataset):
    """torch Dataset over a Recording: item i = (rgb [3,H,W], sparse [1,H,W], gt [1,H,W]), with a
    random horizontal flip (probability `flip_p`, drawn from `generator`) when `augment`."""

    def __init__(self, rec: Recording, augment: bool = False, flip_p: float = 0.5,
                 generator: torch.Generator | None = None, valid_status: tuple[int, ...] = (5,)):
        self.rec, self.augment, self.flip_p = rec, augment, flip_p
        self.generator = generator
        self.valid_status = valid_status

    def __len__(self) -> int:
        return len(self.rec)

    def __getitem__(self, i: int):
        flip = None
        if self.augment:
            flip = np.array([float(torch.rand((), generator=self.generator)) < self.flip_p])
        rgb, sp, gt = batch(self.rec, np.array([i]), flip, self.valid_status)
        return rgb[0], sp[0], gt[0]


class FrameReader:
    """Streaming view of one or more recordings (the layouts `load_recordings` accepts): holds
    only the headers; `read(i)` decodes frame i from its PNG + JSON files, resampled to `size`
    as `load_recording` resamples. `zone_px`, `grid`, `ids`, `height` and `width` are those of
    the equivalent `load_recordings(paths, size=size)`."""

    def __init__(self, paths: str | Path | list, size: tuple[int, int] | None = None):
        if isinstance(paths, (str, Path)):
            paths = [p for p in str(paths).split(",") if p]
        if not paths:
            raise ValueError("no recording given")
        self.size = None if size is None else (int(size[0]), int(size[1]))
        self.frames: list[tuple[Path, int, int]] = []  # (frame folder, native H, native W)
        self.ids: list[str] = []
        self.zone_px = None
        for p in paths:
            root = Path(p)
            _, meta, h, w, rects, grid = _header(root)
            out = self.size or (h, w)
            if out != (h, w):
                rects = resampled_rects(rects, (h, w), out)
            px = zone_pixels(rects, *out)
            if self.zone_px is None:
                self.zone_px, self.grid, self.height, self.width = px, grid, out[0], out[1]
            elif (out, grid) != ((self.height, self.width), self.grid) or \
                    not np.array_equal(px, self.zone_px):
                raise ValueError(f"{p}: frame size, zone grid or zone rectangles differ from "
                                 f"{paths[0]}")
            for f in meta["frames"]:
                fid = str(f["id"])
                self.frames.append((root / "frames" / fid, h, w))
                self.ids.append(f"{root.name}/{fid}" if len(paths) > 1 else fid)

    def __len__(self) -> int:
        return len(self.frames)

    def read(self, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Frame i: (rgb uint8 [H,W,3], depth_mm uint16 [H,W], zone m float32 [Z], status
        uint8 [Z]) at the reader's size."""
        fdir, h, w = self.frames[i]
        rgb, depth, zone_m, status = _read_frame(fdir, h, w)
        if (self.height, self.width) != (h, w):
            rgb, depth = resample(rgb[None], depth[None], (self.height, self.width))
            rgb, depth = rgb[0], depth[0]
        return rgb, depth, zone_m, status

    def recording(self, idx) -> Recording:
        """The frames `idx` (in that order) as an in-memory Recording."""
        idx = [int(i) for i in idx]
        parts = [self.read(i) for i in idx]
        n, nz = len(idx), len(self.zone_px)
        rgb = np.stack([p[0] for p in parts]) if parts else \
            np.empty((0, self.height, self.width, 3), np.uint8)
        depth = np.stack([p[1] for p in parts]) if parts else \
            np.empty((0, self.height, self.width), np.uint16)
        zone_m = np.stack([p[2] for p in parts]) if parts else np.zeros((n, nz), np.float32)
        status = np.stack([p[3] for p in parts]) if parts else np.zeros((n, nz), np.uint8)
        return Recording(rgb, depth, zone_m, status, self.zone_px, self.grid,
                         [self.ids[i] for i in idx])


class FrameDataset(Dataset):
    """torch Dataset streaming frames from a `FrameReader`: item `(i, flip)` = (rgb [3,H,W],
    sparse [1,H,W], gt [1,H,W]) of frame i, mirrored left-right when `flip`, exactly as
    `batch(load_recordings(...), [i], [flip])[k][0]`. Meant for a DataLoader whose batch sampler
    yields lists of `(i, flip)` (training's step plan), with workers decoding in parallel."""

    def __init__(self, reader: FrameReader, valid_status: tuple[int, ...] = (5,)):
        self.reader, self.valid_status = reader, valid_status

    def __len__(self) -> int:
        return len(self.reader)

    def __getitem__(self, key):
        i, flip = key if isinstance(key, tuple) else (key, False)
        rec = self.reader.recording([i])
        rgb, sp, gt = batch(rec, np.array([0]), np.array([bool(flip)]), self.valid_status)
        return rgb[0], sp[0], gt[0]
