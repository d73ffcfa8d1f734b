"""The DEPTHOR network (docs/design.md "Pipeline"), variants `mcu` and `phone`.

rgb → prior → (D_inv, F_mde); depth input cat(n = minmax(D_inv), minmax(1/(n+0.1)), S) → depth
encoder; RGB encoder; fusing decoder → F_unet (1/2); bin logits MLP; bins_head → d_half;
refinement guidance cat(F_unet, F_mde) → CBAM → conv → pixel_shuffle → affinity heads; refine.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import torch
from torch import Tensor, nn

from . import ops
from .blocks import CBAM, BasicBlock, ConvBNAct
from .prior import Prior, PriorConfig


@dataclass(frozen=True)
class NetConfig:
    """Widths, depths and ranges of one variant. Encoder tuples have 5 entries: scales 1/2…1/32;
    `dec_widths` runs from 1/32 up to 1/2 (its last entry is the F_unet channel count)."""

    variant: str
    height: int
    width: int
    prior: PriorConfig = field(default_factory=PriorConfig)
    rgb_widths: tuple[int, ...] = (16, 24, 32, 48, 64)
    rgb_blocks: tuple[int, ...] = (0, 1, 1, 1, 1)
    depth_stem: int = 8
    depth_widths: tuple[int, ...] = (8, 16, 24, 32, 48)
    dec_widths: tuple[int, ...] = (48, 32, 24, 16, 16)
    mlp_hidden: int = 64
    n_bins: int = 128
    min_depth_m: float = 0.1
    max_depth_m: float = 10.0
    cspn_channels: int = 8
    iterations: int = 6
    sigmas: tuple[float, float, float] = (1.0, 2.0, 3.0)
    # refine's neighbours per window: "window" (8/24/48, the paper's) or "dilated" (8 each)
    refine_neighbourhood: str = "window"
    cbam_reduction: int = 4
    leaky_alpha: float = 0.1
    # "dense": `Depthor` below (the paper's blocks); "lite": `lite.DepthorLite` (depthwise-
    # separable / inverted-residual blocks, prior shared with the RGB encoder; models/README.md
    # "mcu_lite"). The fields below are read by the lite architecture only.
    arch: str = "dense"
    refine_scale: int = 1  # 1: guidance, affinities and refine at full resolution; 2: at 1/2
    depth_kernel: int = 5  # depthwise kernel of the depth encoder's separable stages
    # the depth input: "points" (one pixel per zone, the graph contract's `sparse`) or "fill"
    # (zone_fill.nearest_fill applied in PyTorch first; the issue-39 ablation, float only)
    sparse_input: str = "points"
    # The refinement starts from D_0 blended with a gated interpolation of the zones
    # (zone_prior.ZonePrior; the issue-39 item-3 ablation, lite architecture, float only)
    zone_prior: bool = False

    def __post_init__(self):
        for name in ("rgb_widths", "rgb_blocks", "depth_widths", "dec_widths"):
            if len(getattr(self, name)) != 5:
                raise ValueError(f"{name} needs 5 entries (1/2 … 1/32)")
        # dense: a stage's first block is its strided one; lite: blocks after a strided conv
        if self.arch == "dense" and any(b < 1 for b in self.rgb_blocks[1:]):
            raise ValueError("rgb_blocks[1:] must be >= 1 (the strided block)")
        if any(b < 0 for b in self.rgb_blocks):
            raise ValueError("rgb_blocks must be >= 0")
        if self.sparse_input not in ("points", "fill"):
            raise ValueError("sparse_input must be 'points' or 'fill'")
        if self.refine_neighbourhood not in ("window", "dilated"):
            raise ValueError("refine_neighbourhood must be 'window' or 'dilated'")
        if self.height % 2 or self.width % 2:
            raise ValueError("height and width must be even (pixel_shuffle(2) back to full size)")


VARIANTS: dict[str, NetConfig] = {
    # docs/design.md: 120×160, all weights ≤ 512 KiB int8.
    "mcu": NetConfig(variant="mcu", height=120, width=160),
    # docs/design.md: 320×240 portrait, ≥ 30 fps int8 on one x86 core (≲ 1.5 GMAC).
    "phone": NetConfig(
        variant="phone",
        height=320,
        width=240,
        prior=PriorConfig(widths=(8, 16, 32, 48), mde_channels=16),
        rgb_widths=(16, 32, 48, 64, 96),
        rgb_blocks=(0, 1, 2, 2, 1),
        depth_stem=8,
        depth_widths=(12, 16, 32, 48, 64),
        dec_widths=(64, 48, 32, 24, 16),
        mlp_hidden=96,
        cspn_channels=6,
    ),
    # issue 16: ≤ 40 M MACs at 120×160 and ≤ 256 KiB int8 weights (models/README.md "mcu_lite").
    "mcu_lite": (_MCU_LITE := NetConfig(
        variant="mcu_lite",
        height=120,
        width=160,
        arch="lite",
        # No extra inverted residual after the 1/4 and 1/8 strided blocks of the shared
        # encoder, none at 1/32, and 16 bins: 97.9 M instead of 125.6 M Cortex-M4
        # instructions for 3 % RMSE on the check sets (docs/results/models_mcu_lite_budget.md).
        prior=PriorConfig(widths=(16, 24, 32, 48), mde_channels=16, kind="lite",
                          blocks=(0, 0, 0, 2), expand=3),
        rgb_widths=(16, 24, 32, 48, 64),
        rgb_blocks=(0, 0, 0, 2, 0),
        depth_stem=0,
        depth_widths=(8, 16, 24, 32, 48),
        dec_widths=(48, 32, 24, 16, 12),
        mlp_hidden=64,
        # T = 4 and 8 dilated neighbours per window: 21 M fewer Cortex-M4 instructions for 1 %
        # RMSE on the check sets (docs/results/models_mcu_lite_budget.md).
        n_bins=16,
        iterations=4,
        refine_neighbourhood="dilated",
        cspn_channels=8,
        refine_scale=2,
    )),
    # issue 16: ≤ 250 M MACs at 320×240 (40×30 zones). mcu_lite's network at the phone's size:
    # trained from mcu_lite's weights (no GPU was lent for the wider network that was defined
    # here before, whose training from random weights does not fit a CPU session;
    # models/phone_lite/MODEL_CARD.md).
    "phone_lite": replace(
        _MCU_LITE, variant="phone_lite", height=320, width=240),
}


def make_net(cfg: NetConfig) -> nn.Module:
    """The network class of `cfg.arch` built from `cfg` (default PyTorch init, train mode)."""
    if cfg.arch == "lite":
        from .lite import DepthorLite

        return DepthorLite(cfg)
    if cfg.arch != "dense":
        raise ValueError(f"unknown arch {cfg.arch!r}")
    if cfg.sparse_input != "points" or cfg.zone_prior:
        raise ValueError("sparse_input 'fill' and zone_prior are built into the lite architecture only")
    return Depthor(cfg)


def config(variant: str, **overrides) -> NetConfig:
    """The named variant's config, with optional field overrides (`prior.FIELD` keys override
    fields of its `PriorConfig`)."""
    if variant not in VARIANTS:
        raise KeyError(f"unknown variant {variant!r} (have {sorted(VARIANTS)})")
    base = VARIANTS[variant]
    prior = {k.partition(".")[2]: v for k, v in overrides.items() if k.startswith("prior.")}
    own = {k: v for k, v in overrides.items() if not k.startswith("prior.")}
    if prior:
        own["prior"] = replace(own.get("prior", base.prior), **prior)
    return replace(base, **own)


def parse_overrides(items: list[str]) -> dict:
    """`FIELD=VALUE` strings (int/float/tuple literals, or a bare word for a string field) →
    NetConfig overrides for `config` (FIELD a NetConfig field, or `prior.F` with F a PriorConfig
    field); unknown fields are errors."""
    import ast
    fields = set(NetConfig.__dataclass_fields__)
    fields |= {f"prior.{f}" for f in PriorConfig.__dataclass_fields__}
    out = {}
    for kv in items:
        k, sep, v = kv.partition("=")
        if not sep or k not in fields:
            raise ValueError(f"--set {kv!r}: expected FIELD=VALUE with FIELD a NetConfig field "
                             "or prior.FIELD")
        try:
            out[k] = ast.literal_eval(v)
        except (ValueError, SyntaxError):
            out[k] = v  # a bare word: a string field such as refine_neighbourhood
    return out


class RgbEncoder(nn.Module):
    """Stem conv-BN-relu (stride 2) then BasicBlock stages: features at 1/2 … 1/32."""

    def __init__(self, widths, blocks):
        super().__init__()
        self.stem = ConvBNAct(3, widths[0], 3, 2)
        stages, prev = [], widths[0]
        for i, (w, n) in enumerate(zip(widths, blocks)):
            layers = []
            for b in range(n):
                layers.append(BasicBlock(prev, w, 2 if (i > 0 and b == 0) else 1))
                prev = w
            stages.append(nn.Sequential(*layers))
        self.stages = nn.ModuleList(stages)

    def forward(self, x: Tensor) -> list[Tensor]:
        out, x = [], self.stem(x)
        for stage in self.stages:
            x = stage(x)
            out.append(x)
        return out


class DepthEncoder(nn.Module):
    """5×5 dilation-2 stem at full resolution, stride-2 3×3 stages (BN + LeakyReLU) to 1/32,
    CBAM on the deepest."""

    def __init__(self, stem, widths, alpha, reduction):
        super().__init__()
        self.stem = ConvBNAct(3, stem, 5, 1, dilation=2, act="leaky_relu", alpha=alpha)
        chans = (stem,) + tuple(widths)
        self.stages = nn.ModuleList(
            ConvBNAct(cin, cout, 3, 2, act="leaky_relu", alpha=alpha)
            for cin, cout in zip(chans[:-1], chans[1:])
        )
        self.cbam = CBAM(widths[-1], reduction)

    def forward(self, x: Tensor) -> list[Tensor]:
        out, x = [], self.stem(x)
        for stage in self.stages:
            x = stage(x)
            out.append(x)
        out[-1] = self.cbam(out[-1])
        return out


class Depthor(nn.Module):
    """The full network: (rgb [1,3,H,W] in [0,1], sparse [1,1,H,W] metres) → depth [1,1,H,W] m."""

    def __init__(self, cfg: NetConfig):
        super().__init__()
        self.cfg = cfg
        a = cfg.leaky_alpha
        self.prior = Prior(cfg.prior)
        self.rgb_enc = RgbEncoder(cfg.rgb_widths, cfg.rgb_blocks)
        self.depth_enc = DepthEncoder(cfg.depth_stem, cfg.depth_widths, a, cfg.cbam_reduction)
        rw, dw, cw = cfg.rgb_widths, cfg.depth_widths, cfg.dec_widths
        dec = [ConvBNAct(rw[4] + dw[4], cw[0], 3, 1, act="leaky_relu", alpha=a)]
        for i in range(1, 5):
            s = 4 - i  # encoder index of this decoder scale
            dec.append(ConvBNAct(cw[i - 1] + rw[s] + dw[s], cw[i], 3, 1, act="leaky_relu", alpha=a))
        self.dec = nn.ModuleList(dec)
        self.bins_fc1 = ops.Linear(cw[0], cfg.mlp_hidden, activation="relu")
        self.bins_fc2 = ops.Linear(cfg.mlp_hidden, cfg.n_bins)
        self.bins_head = ops.BinsHead(cw[4], cfg.n_bins, cfg.min_depth_m, cfg.max_depth_m)
        guide = cw[4] + cfg.prior.mde_channels
        self.guide_cbam = CBAM(guide, cfg.cbam_reduction)
        self.guide_conv = ConvBNAct(guide, 4 * cfg.cspn_channels, 3, 1, act="leaky_relu", alpha=a)
        c = cfg.cspn_channels
        n3, n5, n7 = (len(ops.neighbour_offsets(s, cfg.refine_neighbourhood)) for s in (3, 5, 7))
        self.aff3 = ops.Conv(c, n3, 3)
        self.aff5 = ops.Conv(c, n5, 3)
        self.aff7 = ops.Conv(c, n7, 3)
        self.kmix = ops.Conv(c, 3, 3)
        self.tmix = ops.Conv(c, 3, 3)
        self.refine = ops.Refine(cfg.iterations, cfg.sigmas, cfg.refine_neighbourhood)

    def backbone(self, rgb: Tensor, sparse: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """The conv trunk before the bins head and refinement: (F_unet [1,C,H/2,W/2], F_mde
        [1,C_mde,H/2,W/2], bin logits [1,N])."""
        d_inv, f_mde = self.prior(rgb)
        # Normalise first, then invert with ε = 0.1: 1/(n + 0.1) spans [1/1.1, 10] whatever the
        # prior's scale, so the int8 reciprocal table and the minmax after it keep their
        # resolution (1/(D_inv + 1e-3) on the raw ReLU output reached 1000 at D_inv = 0).
        n = ops.minmax_norm(d_inv, 1e-6)
        d_rel = ops.minmax_norm(ops.reciprocal(n, 0.1), 1e-6)
        d_in = ops.concat([n, d_rel, sparse])
        dep = self.depth_enc(d_in)
        rgbf = self.rgb_enc(rgb)
        x = self.dec[0](ops.concat([rgbf[4], dep[4]]))
        bin_logits = self.bins_fc2(self.bins_fc1(ops.global_avg_pool(x)))
        for i in range(1, 5):
            s = 4 - i
            x = ops.upsample_bilinear(x, int(rgbf[s].shape[2]), int(rgbf[s].shape[3]))
            x = self.dec[i](ops.concat([x, rgbf[s], dep[s]]))
        return x, f_mde, bin_logits

    def forward(self, rgb: Tensor, sparse: Tensor) -> Tensor:
        h, w = int(rgb.shape[2]), int(rgb.shape[3])
        f_unet, f_mde, bin_logits = self.backbone(rgb, sparse)
        d_half = self.bins_head(f_unet, bin_logits)
        g = self.guide_conv(self.guide_cbam(ops.concat([f_unet, f_mde])))
        f_cspn = ops.pixel_shuffle(g, 2)
        d0 = ops.upsample_bilinear(d_half, h, w)
        return self.refine(
            d0, self.aff3(f_cspn), self.aff5(f_cspn), self.aff7(f_cspn),
            self.kmix(f_cspn), self.tmix(f_cspn),
        )


class Backbone(nn.Module):
    """`net` without its bins head, guidance and refinement (the benchmarks' "backbone" cut):
    (rgb, sparse) → (F_unet, bin logits), the two inputs of the bins head; F_mde, which only the
    guidance reads, is left out. Shares `net`'s modules (no copy)."""

    def __init__(self, net: nn.Module):
        super().__init__()
        self.net = net
        self.cfg = net.cfg

    def forward(self, rgb: Tensor, sparse: Tensor) -> tuple[Tensor, Tensor]:
        f_unet, _f_mde, bin_logits = self.net.backbone(rgb, sparse)
        return f_unet, bin_logits


def build(variant: str, seed: int = 0, calibrate_bn: bool = True, **overrides) -> Depthor:
    """Builds a variant with seeded random weights in eval mode.

    With `calibrate_bn`, BN affine parameters are randomised and running statistics are gathered
    from a few train-mode passes on random inputs, so BN folding is exercised by the exporters.
    """
    cfg = config(variant, **overrides)
    g = torch.Generator().manual_seed(seed)
    torch.manual_seed(seed)
    net = make_net(cfg)
    if calibrate_bn:
        with torch.no_grad():
            for m in net.modules():
                if isinstance(m, ops.BatchNorm):
                    m.weight.copy_(0.5 + torch.rand(m.weight.shape, generator=g))
                    m.bias.copy_(0.2 * (torch.rand(m.bias.shape, generator=g) - 0.5))
                    m.momentum = None  # cumulative average over the calibration passes
            net.train()
            for _ in range(3):
                rgb, sparse = random_inputs(cfg, generator=g)
                net(rgb, sparse)
    net.eval()
    return net


def random_inputs(cfg: NetConfig, generator: torch.Generator | None = None,
                  n_points: int = 64) -> tuple[Tensor, Tensor]:
    """A smooth-ish random rgb in [0,1] and a sparse depth map with `n_points` points in range."""
    g = generator if generator is not None else torch.Generator().manual_seed(0)
    h, w = cfg.height, cfg.width
    low = torch.rand(1, 3, h // 8, w // 8, generator=g)
    rgb = torch.nn.functional.interpolate(low, size=(h, w), mode="bilinear", align_corners=True)
    rgb = (0.8 * rgb + 0.2 * torch.rand(1, 3, h, w, generator=g)).clamp(0.0, 1.0)
    sparse = torch.zeros(1, 1, h, w)
    idx = torch.randperm(h * w, generator=g)[:n_points]
    depth = cfg.min_depth_m + (cfg.max_depth_m - cfg.min_depth_m) * torch.rand(n_points, generator=g)
    sparse.view(-1)[idx] = depth
    return rgb, sparse
