"""Per-channel equalisation of one stored value (the cross-layer equalisation of Nagel et al.,
"Data-Free Quantization", 2019, driven by activation ranges): the same float network, with each
channel of the value on more of its int8 codes.

The blob stores a value per tensor in int8, so a channel whose values span a fifth of the
tensor's range gets a fifth of its codes. For a value `v = act(bn(conv(x)))` with a positively
homogeneous activation (ReLU, leaky ReLU: `act(s·y) = s·act(y)` for `s > 0`), scaling the batch
norm's `gamma` and `beta` of channel c by `s_c` scales `v`'s channel c by `s_c`; dividing every
reader's weights on that channel by `s_c` (a 1×1 or k×k conv's input channel, a depthwise conv's
channel, through concatenations and bilinear upsampling, which commute with a channel scale)
leaves the network's output unchanged up to float rounding. `s_c` lifts each channel's
`--quantile` of |v| (over frames of a recording, never a check or test set) towards the largest
channel's, at most `--max-scale` times.

    python -m depthor_models.equalize --weights mcu_lite/train/model_final.pt --variant mcu_lite \\
        --value depth_enc.stages.0.pw.act --recording ../rec/mcu_train_a --out W.pt \\
        --ranges mcu_lite/qat_ranges.json --ranges-out R.json

The values whose int8 range the scaling changes (`v` and the concatenations it flows into) are
dropped from `--ranges` into `--ranges-out`, so `depthor quantize --ranges-file R.json`
calibrates those and keeps the trained ranges of every other value. A reader that does not
commute with a channel scale (an add, a pool, CBAM's multiplies…) is an error.

Measured on the quantisation-aware mcu_lite of 2026-12-05, it made int8 worse, not better (its
network had adapted to the rounding it trained with): docs/results/models_mcu_lite_qat.md.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import torch
from torch import Tensor

from . import data
from .graph_export import trace
from .net import build, parse_overrides
from .train import load_weights

_HOMOGENEOUS = ("relu", "leaky_relu")
_CHANNELWISE = ("upsample_bilinear",)


def channel_scales(v: Tensor, quantile: float = 0.999, max_scale: float = 8.0) -> Tensor:
    """Per channel of `v` [N, C, H, W]: `min(max_scale, top / q_c)` (at least 1), with `q_c` the
    channel's `quantile` of |v| and `top` the largest `q_c`."""
    flat = v.detach().abs().transpose(0, 1).reshape(v.shape[1], -1).float()
    q = torch.quantile(flat[:, :: max(1, flat.shape[1] // 200_000)], quantile, dim=1)
    top = q.max()
    return (top / q.clamp_min(top / max_scale)).clamp(1.0, max_scale)


def equalize(net, rgb: Tensor, sparse: Tensor, value: str, quantile: float = 0.999,
             max_scale: float = 8.0) -> tuple[dict[str, Tensor], Tensor, list[str]]:
    """(`net`'s state dict with `value` equalised, the channel scales, the values whose range
    changes). `rgb`/`sparse`: the frames the ranges are measured on (eval mode)."""
    tr = trace(net, rgb, sparse)
    nodes = tr.graph["nodes"]
    by_output = {n["output"]: n for n in nodes}
    act = by_output.get(value)
    if act is None or act["op"] not in _HOMOGENEOUS:
        raise ValueError(f"{value}: not the output of a ReLU or leaky ReLU")
    bn = by_output.get(act["inputs"][0])
    if bn is None or bn["op"] != "batch_norm":
        raise ValueError(f"{value}: its activation does not read a batch norm")
    s = channel_scales(tr.values[value], quantile, max_scale)
    state = {k: t.clone() for k, t in net.state_dict().items()}
    state[bn["params"]["gamma"]] *= s
    state[bn["params"]["beta"]] *= s
    changed = [value]

    def scale_readers(name: str, offset: int) -> None:
        for n in nodes:
            if name not in n["inputs"]:
                continue
            if n["op"] == "conv2d":
                w = state[n["params"]["weight"]]
                if n["attrs"]["groups"] == 1:
                    w[:, offset:offset + len(s)] /= s.view(1, -1, 1, 1)
                elif n["attrs"]["groups"] == w.shape[0] == tr.values[name].shape[1]:
                    w[offset:offset + len(s)] /= s.view(-1, 1, 1, 1)
                else:
                    raise ValueError(f"{value}: read by the grouped conv {n['name']}")
            elif n["op"] == "concat":
                before = n["inputs"][: n["inputs"].index(name)]
                scale_readers(n["output"],
                              offset + sum(tr.values[i].shape[1] for i in before))
                changed.append(n["output"])
            elif n["op"] in _CHANNELWISE:
                scale_readers(n["output"], offset)
            else:
                raise ValueError(f"{value}: read by {n['op']} {n['name']}, which does not "
                                 f"commute with a channel scale")

    scale_readers(value, 0)
    return state, s, changed


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--weights", required=True, help="trained checkpoint or state dict")
    ap.add_argument("--variant", required=True)
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="NetConfig overrides (as for train/export)")
    ap.add_argument("--value", action="append", required=True,
                    help="graph value to equalise (repeatable; in order)")
    ap.add_argument("--recording", action="append", required=True,
                    help="frames the channel ranges are measured on (repeatable)")
    ap.add_argument("--frames", type=int, default=32, help="first frames of each recording")
    ap.add_argument("--quantile", type=float, default=0.999)
    ap.add_argument("--max-scale", type=float, default=8.0)
    ap.add_argument("--out", required=True, help="state-dict file to write")
    ap.add_argument("--ranges", help="qat_ranges.json to copy without the changed values")
    ap.add_argument("--ranges-out", help="where that copy goes")
    a = ap.parse_args(argv)
    net = build(a.variant, seed=0, calibrate_bn=False, **parse_overrides(a.set))
    net.load_state_dict(load_weights(a.weights))
    net.eval()
    rgb, sp = data.first_frames(a.recording, a.frames, (net.cfg.height, net.cfg.width))
    changed: list[str] = []
    for v in a.value:
        state, s, ch = equalize(net, rgb, sp, v, a.quantile, a.max_scale)
        net.load_state_dict(state)
        changed += ch
        print(f"{v}: channel scales {[round(float(x), 2) for x in s]}; ranges changed: "
              f"{', '.join(ch)}")
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    torch.save({"model": net.state_dict()}, a.out)
    if a.ranges and a.ranges_out:
        kept = {k: v for k, v in json.loads(Path(a.ranges).read_text()).items()
                if k not in changed}
        Path(a.ranges_out).write_text(json.dumps(kept, indent=1) + "\n")
        print(f"wrote {a.ranges_out}: {len(kept)} ranges (dropped {', '.join(changed)})")
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
