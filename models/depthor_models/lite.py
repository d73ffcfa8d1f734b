"""`mcu_lite` (issue 16): the DEPTHOR structure at ≤ 40 M MACs / ≤ 256 KiB int8 weights.

The paper's structure is kept — monocular prior (D_inv, F_mde) → depth encoder over
cat(n = minmax(D_inv), D_rel = minmax(1/(n+0.1)), S) with CBAM on its deepest stage → fusing
decoder to 1/2 → bins head (global bins from the deepest decoder feature, per-pixel weights on
F_unet) → guidance cat(F_unet, F_mde) → CBAM → affinity heads (3/5/7 + kernel and time mixing) →
mixed-affinity refine with outputs at t ∈ {0, T/2, T} — with these changes (models/README.md,
"mcu_lite", has the MAC and weight figures of each):

- every 3×3 conv except the two strided stems is depthwise-separable (`SepConv`) or a MobileNetV2
  inverted residual (`InvertedResidual`);
- the prior's encoder *is* the RGB encoder at 1/2 … 1/16 (`LitePrior` keeps its features; one
  more stage gives 1/32); the prior's decoder stops at 1/4, D_inv and F_mde are upsampled from
  there (the paper also interpolates F_mde, from a ViT's 1/14, to 1/2);
- the depth encoder starts with a stride-2 3×3 stem (the dense one runs a 5×5 dilated conv at
  full resolution) and its separable stages use 5×5 depthwise kernels to spread the 64 zone
  samples;
- `refine_scale = 2`: guidance, affinities and the refinement run at 1/2 resolution on d_half
  directly, and the refined map is upsampled to the input size (the last node is then an
  `upsample_bilinear` of an f32 map, which the quantizer keeps in f32); `refine_scale = 1` keeps
  the paper's full-resolution refinement (pixel_shuffle of the guidance);
- affinity and mixing heads are 1×1 convs on the guidance (3×3 in the dense network), N = 64 bins.

Only docs/graph.md ops are used (conv2d with `groups`, batch_norm, relu/leaky_relu, add, mul, concat,
upsample_bilinear, pixel_shuffle, pooling, minmax_norm, reciprocal, linear, bins_head, refine).
"""

from __future__ import annotations

from torch import Tensor, nn

from . import ops
from .blocks import CBAM, ConvBNAct, InvertedResidual, SepConv


def _stage(cin: int, cout: int, blocks: int, expand: int) -> nn.Sequential:
    """A stride-2 separable conv cin → cout, then `blocks` inverted residuals at cout."""
    layers = [SepConv(cin, cout, 2)]
    layers += [InvertedResidual(cout, cout, 1, expand) for _ in range(blocks)]
    return nn.Sequential(*layers)


class LitePrior(nn.Module):
    """rgb → (D_inv [1,1,H,W] ≥ 0, F_mde [1,C_mde,H/2,W/2]), as `prior.Prior`; the encoder
    features (1/2 … 1/16) of the last call are kept in `self.features` for the RGB branch."""

    def __init__(self, cfg):
        super().__init__()
        self.cfg = cfg
        w = cfg.widths
        if len(w) != 4 or len(cfg.blocks) != 4:
            raise ValueError("LitePrior: widths and blocks need 4 entries (1/2 … 1/16)")
        enc = [ConvBNAct(3, w[0], 3, 2)]
        enc += [_stage(w[i - 1], w[i], cfg.blocks[i], cfg.expand) for i in range(1, 4)]
        self.enc = nn.ModuleList(enc)
        # decoder: 1/16 → 1/8 (width w[2]) → 1/4 (F_mde channels)
        self.dec = nn.ModuleList([
            SepConv(w[3] + w[2], w[2]),
            SepConv(w[2] + w[1], cfg.mde_channels, order="pw_dw"),
        ])
        self.head = ops.Conv(cfg.mde_channels, 1, 3)
        self.features: list[Tensor] = []

    def forward(self, rgb: Tensor) -> tuple[Tensor, Tensor]:
        h, w = int(rgb.shape[2]), int(rgb.shape[3])
        feats, x = [], rgb
        for stage in self.enc:
            x = stage(x)
            feats.append(x)
        self.features = feats
        for conv, skip in zip(self.dec, (feats[2], feats[1])):
            x = ops.upsample_bilinear(x, int(skip.shape[2]), int(skip.shape[3]))
            x = conv(ops.concat([x, skip]))
        d_inv = ops.relu(ops.upsample_bilinear(self.head(x), h, w))
        f_mde = ops.upsample_bilinear(x, int(feats[0].shape[2]), int(feats[0].shape[3]))
        return d_inv, f_mde


class LiteDepthEncoder(nn.Module):
    """Stride-2 3×3 stem (BN + LeakyReLU) to 1/2, separable stride-2 stages (k×k depthwise)
    to 1/32, CBAM on the deepest."""

    def __init__(self, widths, alpha, reduction, kernel):
        super().__init__()
        self.stem = ConvBNAct(3, widths[0], 3, 2, act="leaky_relu", alpha=alpha)
        self.stages = nn.ModuleList(
            SepConv(cin, cout, 2, kernel, act="leaky_relu", alpha=alpha)
            for cin, cout in zip(widths[:-1], widths[1:])
        )
        self.cbam = CBAM(widths[-1], reduction)

    def forward(self, x: Tensor) -> list[Tensor]:
        x = self.stem(x)
        out = [x]
        for stage in self.stages:
            x = stage(x)
            out.append(x)
        out[-1] = self.cbam(out[-1])
        return out


class DepthorLite(nn.Module):
    """(rgb [1,3,H,W] in [0,1], sparse [1,1,H,W] metres) → depth [1,1,H,W] m; see module doc."""

    def __init__(self, cfg):
        super().__init__()
        self.cfg = cfg
        a = cfg.leaky_alpha
        pc = cfg.prior
        if pc.kind != "lite":
            raise ValueError("DepthorLite needs a lite prior (PriorConfig(kind='lite'))")
        rw, dw, cw = cfg.rgb_widths, cfg.depth_widths, cfg.dec_widths
        if tuple(rw[:4]) != tuple(pc.widths) or tuple(cfg.rgb_blocks[:4]) != tuple(pc.blocks):
            raise ValueError("mcu_lite shares the prior encoder: rgb_widths[:4] / rgb_blocks[:4] "
                             "must equal prior.widths / prior.blocks")
        if cfg.refine_scale not in (1, 2):
            raise ValueError("refine_scale must be 1 or 2")
        self.prior = LitePrior(pc)
        self.rgb_top = _stage(rw[3], rw[4], cfg.rgb_blocks[4], pc.expand)  # 1/32
        self.depth_enc = LiteDepthEncoder(dw, a, cfg.cbam_reduction, cfg.depth_kernel)
        dec = [SepConv(rw[4] + dw[4], cw[0], act="leaky_relu", alpha=a)]
        for i in range(1, 5):
            s = 4 - i
            cin = cw[i - 1] + rw[s] + dw[s]
            order = "pw_dw" if s <= 1 else "dw_pw"  # 1/4 and 1/2: narrow first
            dec.append(SepConv(cin, cw[i], act="leaky_relu", alpha=a, order=order))
        self.dec = nn.ModuleList(dec)
        self.bins_fc1 = ops.Linear(cw[0], cfg.mlp_hidden, activation="relu")
        self.bins_fc2 = ops.Linear(cfg.mlp_hidden, cfg.n_bins)
        self.bins_head = ops.BinsHead(cw[4], cfg.n_bins, cfg.min_depth_m, cfg.max_depth_m)
        guide = cw[4] + pc.mde_channels
        c = cfg.cspn_channels
        self.guide_cbam = CBAM(guide, cfg.cbam_reduction)
        gout = c if cfg.refine_scale == 2 else 4 * c
        self.guide_conv = SepConv(guide, gout, act="leaky_relu", alpha=a, order="pw_dw")
        n3, n5, n7 = (len(ops.neighbour_offsets(s, cfg.refine_neighbourhood)) for s in (3, 5, 7))
        self.aff3 = ops.Conv(c, n3, 1, padding=0)
        self.aff5 = ops.Conv(c, n5, 1, padding=0)
        self.aff7 = ops.Conv(c, n7, 1, padding=0)
        self.kmix = ops.Conv(c, 3, 1, padding=0)
        self.tmix = ops.Conv(c, 3, 1, padding=0)
        self.refine = ops.Refine(cfg.iterations, cfg.sigmas, cfg.refine_neighbourhood)
        if cfg.zone_prior:
            from .zone_prior import ZonePrior

            self.zone_prior = ZonePrior(c)

    def backbone(self, rgb: Tensor, sparse: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """The conv trunk before the bins head and refinement: (F_unet [1,C,H/2,W/2], F_mde
        [1,C_mde,H/2,W/2], bin logits [1,N])."""
        if self.cfg.sparse_input == "fill":
            from .zone_fill import nearest_fill

            sparse = nearest_fill(sparse)
        d_inv, f_mde = self.prior(rgb)
        rgbf = list(self.prior.features) + [self.rgb_top(self.prior.features[3])]
        n = ops.minmax_norm(d_inv, 1e-6)
        d_rel = ops.minmax_norm(ops.reciprocal(n, 0.1), 1e-6)
        dep = self.depth_enc(ops.concat([n, d_rel, sparse]))
        x = self.dec[0](ops.concat([rgbf[4], dep[4]]))
        bin_logits = self.bins_fc2(self.bins_fc1(ops.global_avg_pool(x)))
        for i in range(1, 5):
            s = 4 - i
            x = ops.upsample_bilinear(x, int(rgbf[s].shape[2]), int(rgbf[s].shape[3]))
            x = self.dec[i](ops.concat([x, rgbf[s], dep[s]]))
        return x, f_mde, bin_logits

    def forward(self, rgb: Tensor, sparse: Tensor) -> Tensor:
        h, w = int(rgb.shape[2]), int(rgb.shape[3])
        points = sparse
        f_unet, f_mde, bin_logits = self.backbone(rgb, sparse)
        d_half = self.bins_head(f_unet, bin_logits)
        g = self.guide_conv(self.guide_cbam(ops.concat([f_unet, f_mde])))
        if self.cfg.refine_scale == 1:
            g = ops.pixel_shuffle(g, 2)
            d0 = ops.upsample_bilinear(d_half, h, w)
        else:
            d0 = d_half
        if self.cfg.zone_prior:
            d0 = self.zone_prior(d0, g, points)
        d = self.refine(d0, self.aff3(g), self.aff5(g), self.aff7(g), self.kmix(g), self.tmix(g))
        if self.cfg.refine_scale == 2:
            d = ops.upsample_bilinear(d, h, w)
        return d
