"""Building blocks written only with docs/graph.md ops (see ops.py)."""

from __future__ import annotations

from torch import Tensor, nn

from . import ops


class Act(nn.Module):
    """A standalone activation node (relu or leaky_relu) following a batch_norm."""

    def __init__(self, kind: str, alpha: float = 0.1):
        super().__init__()
        if kind not in ("relu", "leaky_relu"):
            raise ValueError(f"Act: unsupported {kind!r}")
        self.kind, self.alpha = kind, alpha

    def forward(self, x: Tensor) -> Tensor:
        if self.kind == "relu":
            return ops.relu(x, owner=self)
        return ops.leaky_relu(x, self.alpha, owner=self)


class ConvBNAct(nn.Module):
    """conv2d (no bias, no activation) → batch_norm → relu / leaky_relu: the foldable triple."""

    def __init__(self, cin, cout, kernel=3, stride=1, dilation=1, act="relu", alpha=0.1,
                 groups=1):
        super().__init__()
        self.conv = ops.Conv(cin, cout, kernel, stride, dilation, groups=groups, bias=False)
        self.bn = ops.BatchNorm(cout)
        self.act = Act(act, alpha)

    def forward(self, x: Tensor) -> Tensor:
        return self.act(self.bn(self.conv(x)))


class BasicBlock(nn.Module):
    """ResNet BasicBlock in the docs/graph.md form.

    docs/graph.md lets a batch_norm sit only between a conv2d and an activation, so the second conv and
    the projection shortcut carry a bias instead of a BN: conv-BN-relu → conv(+b) ; shortcut =
    identity or 1×1 conv(+b, stride) ; add → relu.
    """

    def __init__(self, cin: int, cout: int, stride: int = 1):
        super().__init__()
        self.conv1 = ConvBNAct(cin, cout, 3, stride, act="relu")
        self.conv2 = ops.Conv(cout, cout, 3)
        self.short = None
        if stride != 1 or cin != cout:
            self.short = ops.Conv(cin, cout, 1, stride, padding=0)

    def forward(self, x: Tensor) -> Tensor:
        y = self.conv2(self.conv1(x))
        s = x if self.short is None else self.short(x)
        return ops.relu(ops.add(y, s))


class CBAM(nn.Module):
    """CBAM written out in docs/graph.md ops: channel attention (shared 1×1-conv MLP over avg and max
    pools, add, sigmoid, mul) then spatial attention (channel mean/max, concat, 7×7 sigmoid conv,
    mul)."""

    def __init__(self, channels: int, reduction: int = 4, spatial_kernel: int = 7):
        super().__init__()
        hidden = max(channels // reduction, 4)
        self.mlp1 = ops.Conv(channels, hidden, 1, padding=0, activation="relu")
        self.mlp2 = ops.Conv(hidden, channels, 1, padding=0)
        self.spatial = ops.Conv(2, 1, spatial_kernel, activation="sigmoid")

    def forward(self, x: Tensor) -> Tensor:
        a = self.mlp2(self.mlp1(ops.global_avg_pool(x)))
        m = self.mlp2(self.mlp1(ops.global_max_pool(x)))
        x = ops.mul(x, ops.sigmoid(ops.add(a, m)))
        s = ops.concat([ops.channel_mean(x), ops.channel_max(x)])
        return ops.mul(x, self.spatial(s))


class SepConv(nn.Module):
    """Depthwise-separable conv (MobileNetV1 / FastDepth): a k×k depthwise conv-BN-act (carrying
    the stride) and a 1×1 pointwise conv-BN-act. `order="pw_dw"` runs the pointwise conv first
    (cheaper where cout < cin: the depthwise conv then works on the narrower tensor)."""

    def __init__(self, cin: int, cout: int, stride: int = 1, kernel: int = 3, act: str = "relu",
                 alpha: float = 0.1, order: str = "dw_pw"):
        super().__init__()
        if order not in ("dw_pw", "pw_dw"):
            raise ValueError(f"SepConv: unknown order {order!r}")
        self.order = order
        if order == "dw_pw":
            self.dw = ConvBNAct(cin, cin, kernel, stride, act=act, alpha=alpha, groups=cin)
            self.pw = ConvBNAct(cin, cout, 1, 1, act=act, alpha=alpha)
        else:
            self.pw = ConvBNAct(cin, cout, 1, 1, act=act, alpha=alpha)
            self.dw = ConvBNAct(cout, cout, kernel, stride, act=act, alpha=alpha, groups=cout)

    def forward(self, x: Tensor) -> Tensor:
        if self.order == "dw_pw":
            return self.pw(self.dw(x))
        return self.dw(self.pw(x))


class InvertedResidual(nn.Module):
    """MobileNetV2 inverted residual in the docs/graph.md form: 1×1 expand conv-BN-relu, 3×3
    depthwise conv-BN-relu, 1×1 projection conv(+bias, no activation: docs/graph.md allows a
    batch_norm only before an activation, so the linear bottleneck carries a bias instead of a
    BN, like BasicBlock's second conv), identity add when stride 1 and cin == cout."""

    def __init__(self, cin: int, cout: int, stride: int = 1, expand: int = 3, kernel: int = 3):
        super().__init__()
        hidden = cin * expand
        self.expand = ConvBNAct(cin, hidden, 1, 1) if expand != 1 else None
        self.dw = ConvBNAct(hidden, hidden, kernel, stride, groups=hidden)
        self.project = ops.Conv(hidden, cout, 1, padding=0)
        self.residual = stride == 1 and cin == cout

    def forward(self, x: Tensor) -> Tensor:
        y = x if self.expand is None else self.expand(x)
        y = self.project(self.dw(y))
        return ops.add(y, x) if self.residual else y
