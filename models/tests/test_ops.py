"""Hand-computed cases for the docs/graph.md ops, in PyTorch (ops.py) and in the numpy interpreter."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from depthor_models import interp, ops


def test_neighbour_offsets_raster_order_skips_centre():
    offs = ops.neighbour_offsets(3)
    assert offs == [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]
    assert len(ops.neighbour_offsets(5)) == 24 and len(ops.neighbour_offsets(7)) == 48


def test_bin_centres_uniform():
    # zero logits: w_i = 0.1 each -> 1/4; range 0..4 m -> widths 1, centres 0.5 1.5 2.5 3.5
    c = ops.bin_centres(torch.zeros(1, 4, 1, 1), 0.0, 4.0).flatten().tolist()
    assert c == pytest.approx([0.5, 1.5, 2.5, 3.5])


def test_bin_centres_relu_and_floor():
    # logits [-5, 0.9, 0, 0]: w = [0.1, 1.0, 0.1, 0.1] / 1.3; range 1..14 m -> widths 1 10 1 1
    c = ops.bin_centres(torch.tensor([-5.0, 0.9, 0.0, 0.0]).view(1, 4, 1, 1), 1.0, 14.0)
    assert c.flatten().tolist() == pytest.approx([1.5, 7.0, 12.5, 13.5], abs=1e-5)


@pytest.mark.parametrize("bias, expected", [([0, 0, 0, 0], 2.0), ([100, 0, 0, 0], 0.5)])
def test_bins_head_expectation(bias, expected):
    feat = torch.randn(1, 3, 2, 2)
    w = torch.zeros(4, 3)
    b = torch.tensor(bias, dtype=torch.float32)
    out = ops.bins_head_math(feat, torch.zeros(1, 4, 1, 1), w, b, 0.0, 4.0)
    assert out.shape == (1, 1, 2, 2)
    assert torch.allclose(out, torch.full_like(out, expected), atol=1e-5)
    ref = interp.bins_head(feat[0].double().numpy(), np.zeros((4, 1, 1)), w.double().numpy(),
                           b.double().numpy(), 0.0, 4.0)
    assert np.allclose(ref, expected, atol=1e-6)


def _refine_case(tlogits):
    # 1×2 image d0 = [1, 3]; aff3 all 1; σ3 with g(d²=1) = 1/2; kmix picks the 3×3 kernel.
    d0 = torch.tensor([1.0, 3.0]).view(1, 1, 1, 2)
    affs = [torch.ones(1, n, 1, 2) for n in (8, 24, 48)]
    kmix = torch.tensor([100.0, 0.0, 0.0]).view(1, 3, 1, 1).expand(1, 3, 1, 2).contiguous()
    tmix = torch.tensor(tlogits).view(1, 3, 1, 1).expand(1, 3, 1, 2).contiguous()
    sigma3 = 1.0 / math.sqrt(2.0 * math.log(2.0))
    return d0, affs, kmix, tmix, [sigma3, 1.0, 1.0]


@pytest.mark.parametrize(
    "tlogits, expected",
    [
        # only the in-image neighbour counts: w = 0.5/1.5 = 1/3, w_c = 2/3
        # t=1: [5/3, 7/3]; t=2: [17/9, 19/9]
        ([0.0, 0.0, 100.0], [17 / 9, 19 / 9]),
        ([100.0, 0.0, 0.0], [1.0, 3.0]),
        # τ uniform: mean over t ∈ {0, 1, 2}
        ([0.0, 0.0, 0.0], [(1 + 5 / 3 + 17 / 9) / 3, (3 + 7 / 3 + 19 / 9) / 3]),
    ],
)
def test_refine_hand_computed(tlogits, expected):
    d0, affs, kmix, tmix, sig = _refine_case(tlogits)
    out = ops.refine_math(d0, affs, kmix, tmix, torch.tensor(sig), iterations=2)
    assert out.flatten().tolist() == pytest.approx(expected, abs=1e-5)
    ref = interp.refine(d0[0].double().numpy(), [a[0].double().numpy() for a in affs],
                        kmix[0].double().numpy(), tmix[0].double().numpy(), 2, sig)
    assert ref.flatten().tolist() == pytest.approx(expected, abs=1e-9)


def test_refine_torch_matches_interpreter_random():
    g = torch.Generator().manual_seed(3)
    h, w = 9, 11
    d0 = 1 + torch.rand(1, 1, h, w, generator=g)
    affs = [torch.randn(1, n, h, w, generator=g) for n in (8, 24, 48)]
    kmix, tmix = torch.randn(1, 3, h, w, generator=g), torch.randn(1, 3, h, w, generator=g)
    sig = [0.8, 1.7, 2.9]
    out = ops.refine_math(d0, affs, kmix, tmix, torch.tensor(sig), iterations=6)
    ref = interp.refine(d0[0].double().numpy(), [a[0].double().numpy() for a in affs],
                        kmix[0].double().numpy(), tmix[0].double().numpy(), 6, sig)
    assert np.abs(out[0].double().numpy() - ref).max() < 1e-5


def test_minmax_and_reciprocal():
    x = torch.tensor([1.0, 2.0, 3.0]).view(1, 1, 1, 3)
    assert ops.minmax_norm(x, 1e-6).flatten().tolist() == pytest.approx([0, 0.5, 1], abs=1e-5)
    assert ops.reciprocal(torch.zeros(1, 1, 1, 1), 1e-3).item() == pytest.approx(1000.0)


@pytest.mark.parametrize("stride, dilation, groups, kernel", [(1, 1, 1, 3), (2, 1, 1, 3),
                                                                (1, 2, 1, 5), (2, 1, 2, 1)])
def test_interpreter_conv_matches_torch(stride, dilation, groups, kernel):
    g = torch.Generator().manual_seed(0)
    x = torch.randn(1, 4, 7, 9, generator=g)
    w = torch.randn(6, 4 // groups, kernel, kernel, generator=g)
    b = torch.randn(6, generator=g)
    pad = dilation * (kernel // 2)
    y = torch.nn.functional.conv2d(x, w, b, stride, pad, dilation, groups)
    r = interp.conv2d(x[0].double().numpy(), w.double().numpy(), b.double().numpy(), stride,
                      dilation, (pad, pad), groups)
    assert r.shape == tuple(y.shape[1:])
    assert np.abs(r - y[0].double().numpy()).max() < 1e-5


def test_interpreter_upsample_and_pixel_shuffle_match_torch():
    x = torch.randn(1, 8, 3, 5)
    y = torch.nn.functional.interpolate(x, size=(6, 9), mode="bilinear", align_corners=True)
    assert np.abs(interp.upsample_bilinear(x[0].double().numpy(), 6, 9)
                  - y[0].double().numpy()).max() < 1e-5
    # align_corners: the corners are copied exactly
    assert np.allclose(interp.upsample_bilinear(x[0].double().numpy(), 6, 9)[:, 0, 0],
                       x[0, :, 0, 0].double().numpy())
    p = torch.nn.functional.pixel_shuffle(x, 2)
    assert np.array_equal(interp.pixel_shuffle(x[0].numpy(), 2), p[0].numpy())


def test_recorder_refuses_unrecorded_tensors():
    conv = ops.Conv(1, 1, 3)
    with ops.recording(conv) as rec:
        rec.add_input("x", torch.zeros(1, 1, 4, 4))
        with pytest.raises(RuntimeError, match="not produced by a recorded graph op"):
            conv(torch.ones(1, 1, 4, 4))


def test_dilated_neighbourhood_is_the_ring_of_each_window():
    for size in (3, 5, 7):
        r = size // 2
        offs = ops.neighbour_offsets(size, "dilated")
        assert offs == [(dy, dx) for dy in (-r, 0, r) for dx in (-r, 0, r) if (dy, dx) != (0, 0)]
        assert offs == interp.offsets(size, "dilated")
        assert set(offs) <= set(ops.neighbour_offsets(size))
    with pytest.raises(ValueError):
        ops.neighbour_offsets(5, "ring")


def test_dilated_refine_torch_matches_interpreter_and_ignores_the_rest_of_the_window():
    g = torch.Generator().manual_seed(5)
    h, w = 10, 13
    d0 = 1 + torch.rand(1, 1, h, w, generator=g)
    affs = [torch.randn(1, 8, h, w, generator=g) for _ in range(3)]
    kmix, tmix = torch.randn(1, 3, h, w, generator=g), torch.randn(1, 3, h, w, generator=g)
    sig = [0.9, 1.6, 2.4]
    out = ops.refine_math(d0, affs, kmix, tmix, torch.tensor(sig), iterations=4,
                          neighbourhood="dilated")
    ref = interp.refine(d0[0].double().numpy(), [a[0].double().numpy() for a in affs],
                        kmix[0].double().numpy(), tmix[0].double().numpy(), 4, sig, "dilated")
    assert np.abs(out[0].double().numpy() - ref).max() < 1e-5
    # The same as the whole window with the non-ring channels' affinities at zero (relu → 0).
    full = []
    for size, a in zip((3, 5, 7), affs):
        window, ring = ops.neighbour_offsets(size), ops.neighbour_offsets(size, "dilated")
        f = torch.full((1, len(window), h, w), -1.0)
        for c, o in enumerate(ring):
            f[:, window.index(o)] = a[:, c]
        full.append(f)
    same = ops.refine_math(d0, full, kmix, tmix, torch.tensor(sig), iterations=4)
    assert torch.allclose(out, same, atol=1e-6)
    with pytest.raises(ValueError):
        ops.refine_math(d0, full, kmix, tmix, torch.tensor(sig), iterations=4,
                        neighbourhood="dilated")
