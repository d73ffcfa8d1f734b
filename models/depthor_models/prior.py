"""The default monocular prior: a small encoder-decoder on RGB giving relative inverse depth D_inv
(1×H×W, relu) and features F_mde (C_mde × H/2 × W/2). Its nodes are named `prior.*` in graph.json,
and it is exported alone as its own NNEF (docs/design.md, pipeline step 2)."""

from __future__ import annotations

from dataclasses import dataclass

from torch import Tensor, nn

from . import ops
from .blocks import ConvBNAct


@dataclass(frozen=True)
class PriorConfig:
    """Widths of the prior's encoder stages (1/2, 1/4, …) and the F_mde channel count."""

    widths: tuple[int, ...] = (8, 16, 24, 32)
    mde_channels: int = 16
    # "dense": `Prior` below; "lite": `lite.LitePrior` (depthwise-separable encoder shared with
    # the RGB encoder, decoder to 1/4; the `mcu_lite` variant)
    kind: str = "dense"
    # lite only: inverted-residual blocks after the stride-2 separable conv of each encoder
    # stage (1/2 … 1/16; the 1/2 stage is the stem alone) and their expansion factor
    blocks: tuple[int, ...] = (0, 1, 1, 1)
    expand: int = 3


class PriorStage(nn.Module):
    """Stride-2 conv then a stride-1 conv, both conv-BN-relu."""

    def __init__(self, cin: int, cout: int):
        super().__init__()
        self.down = ConvBNAct(cin, cout, 3, 2)
        self.conv = ConvBNAct(cout, cout, 3, 1)

    def forward(self, x: Tensor) -> Tensor:
        return self.conv(self.down(x))


class Prior(nn.Module):
    """rgb [1,3,H,W] in [0,1] → (D_inv [1,1,H,W] ≥ 0, F_mde [1,C_mde,H/2,W/2])."""

    def __init__(self, cfg: PriorConfig):
        super().__init__()
        self.cfg = cfg
        w = cfg.widths
        self.enc = nn.ModuleList(PriorStage(cin, cout) for cin, cout in zip((3,) + w[:-1], w))
        # decoder output at scale i has width w[i], except the 1/2 scale which is F_mde
        outs = list(reversed(list(w[:-1])))
        outs[-1] = cfg.mde_channels
        dec, prev = [], w[-1]
        for skip, cout in zip(reversed(w[:-1]), outs):
            dec.append(ConvBNAct(prev + skip, cout, 3, 1))
            prev = cout
        self.dec = nn.ModuleList(dec)
        self.head = ops.Conv(cfg.mde_channels, 1, 3)

    def forward(self, rgb: Tensor) -> tuple[Tensor, Tensor]:
        h, w = int(rgb.shape[2]), int(rgb.shape[3])
        feats, x = [], rgb
        for stage in self.enc:
            x = stage(x)
            feats.append(x)
        for conv, skip in zip(self.dec, reversed(feats[:-1])):
            x = ops.upsample_bilinear(x, int(skip.shape[2]), int(skip.shape[3]))
            x = conv(ops.concat([x, skip]))
        f_mde = x
        d_inv = ops.relu(ops.upsample_bilinear(self.head(f_mde), h, w))
        return d_inv, f_mde
