"""Quantisation-aware training (`depthor_models.qat`): the rounding plan follows the host
quantizer's folding, the fake-quantised forward stays near the float one and trains, and
detaching restores the float network exactly."""

from __future__ import annotations

import json

import pytest
import torch

from depthor_models import build, qat, random_inputs
from depthor_models.ops import Node


@pytest.fixture(scope="module")
def lite():
    net = build("mcu_lite", seed=0)
    rgb, sparse = random_inputs(net.cfg, torch.Generator().manual_seed(1))
    return net, rgb, sparse


def test_plan_folds_like_the_quantizer():
    """conv → batch_norm → relu stores one int8 value (the relu's); f32 heads stay f32."""
    conv = {"activation": "none"}
    nodes = [
        Node("conv2d", "c", ["rgb"], "c", conv),
        Node("batch_norm", "b", ["c"], "b"),
        Node("relu", "r", ["b"], "r"),
        Node("conv2d", "c2", ["r"], "c2", conv),  # read twice: stored
        Node("relu", "r2", ["c2"], "r2"),
        Node("add", "a", ["c2", "r2"], "a"),
        Node("conv2d", "s", ["a"], "s", {"activation": "sigmoid"}),
        Node("minmax_norm", "m", ["s"], "m"),
        Node("upsample_bilinear", "u", ["m"], "u"),
        Node("bins_head", "h", ["u", "a"], "h"),
        Node("upsample_bilinear", "hu", ["h"], "hu"),
    ]
    assert qat.int8_values(nodes) == [
        "fused", "fused", "int8", "int8", "int8", "int8", "unit", "unit", "same", "f32", "f32"]


def test_lite_plan_covers_every_node(lite):
    net, rgb, sparse = lite
    fq = qat.FakeQuant(net, rgb, sparse)
    assert fq.ops[-1] == "upsample_bilinear" and fq.kind[-1] == "f32"
    assert "refine" in fq.ops and fq.kind[fq.ops.index("refine")] == "f32"
    assert fq.kind.count("fused") >= 10
    assert fq.kind.count("int8") >= 20


def _float_then_attached(lite):
    """(net, rgb, sparse, the float output, an attached FakeQuant)."""
    net, rgb, sparse = lite
    net.eval()
    with torch.no_grad():
        ref = net(rgb, sparse)
    return net, rgb, sparse, ref, qat.FakeQuant(net, rgb, sparse).attach()


def test_fake_quant_forward_trains_and_detaches(lite):
    net, rgb, sparse, ref, fq = _float_then_attached(lite)
    try:
        net.train()
        out = net(rgb, sparse)  # first training pass sets the ranges
        out.mean().backward()
        grads = [p.grad for p in net.parameters() if p.grad is not None]
        assert grads and any(float(g.abs().sum()) > 0 for g in grads)
        net.zero_grad(set_to_none=True)
        net.eval()
        with torch.no_grad():
            q = net(rgb, sparse)
        # batch norm was kept on its running statistics: only rounding separates q from ref
        assert not torch.equal(q, ref)
        rel = float((q - ref).abs().mean() / ref.abs().mean())
        assert rel < 0.05, rel
        assert len(fq.seen) == len(fq.kind) and any(fq.seen)
        with pytest.raises(ValueError):
            fq.load_state_dict({**fq.state_dict(), "ops": ["conv2d"]})
    finally:
        fq.detach()
    with torch.no_grad():
        assert torch.equal(net(rgb, sparse), ref)


def test_weight_rounding_is_per_channel_symmetric():
    w = torch.randn(4, 3, 3, 3) * torch.tensor([1e-3, 1.0, 10.0, 0.5]).view(4, 1, 1, 1)
    q = qat.FakeQuant.weight(w)
    for o in range(4):
        m = w[o].abs().max()
        assert torch.isclose(q[o].abs().max(), m)
        codes = torch.round(q[o] / (m / 127))
        assert torch.allclose(codes * (m / 127), q[o], atol=1e-6 * float(m))
        assert float((q[o] - w[o]).abs().max()) <= float(m) / 254 * 1.0001


def test_qat_training_keeps_its_ranges_across_a_resume(tmp_path):
    """`train --qat` writes the tracked ranges into the checkpoint and a resume picks them up."""
    from depthor_models import train as T
    from test_train import _args, write_recording

    rec_dir = write_recording(tmp_path / "rec", n=4)
    out = tmp_path / "run"
    T.main(_args(rec_dir, out, "--qat", "--stop-after", "2"))
    ck = torch.load(out / "ckpt.pt", weights_only=False)
    st = ck["qat"]
    assert ck["step"] == 2 and any(st["seen"])
    assert bool((st["hi"] >= st["lo"]).all()) and float(st["hi"].max()) > 0
    T.main(_args(rec_dir, out, "--qat", "--resume"))
    ck = torch.load(out / "ckpt.pt", weights_only=False)
    assert ck["step"] == 3 and ck["qat"]["ops"] == st["ops"]
    assert (out / "model_final.pt").exists()
    # the ranges the quantizer takes (`depthor quantize --ranges-file`): by value name, int8 only
    ranges = json.loads((out / "qat_ranges.json").read_text())
    assert ranges and all(lo <= hi for lo, hi in ranges.values())
    names = [n for n, k in zip(ck["qat"]["ops"], ck["qat"]["seen"]) if k]
    assert len(ranges) <= len(names)


def test_float_steps_are_a_reproducible_share():
    """`--qat-float-p`: a draw from (seed, step), near the asked share, none at 0."""
    from depthor_models.train import float_step

    draws = [float_step(7, s, 0.5) for s in range(2000)]
    assert draws == [float_step(7, s, 0.5) for s in range(2000)]
    assert 0.45 < sum(draws) / len(draws) < 0.55
    assert draws != [float_step(8, s, 0.5) for s in range(2000)]
    assert not any(float_step(7, s, 0.0) for s in range(200))
    assert all(float_step(7, s, 1.0) for s in range(200))


def test_disabled_fake_quant_is_the_float_network(lite):
    """`enabled = False` (a float step of `--qat-float-p`): no rounding, batch norm on its
    running statistics even in training mode, nothing tracked."""
    net, rgb, sparse, ref, fq = _float_then_attached(lite)
    try:
        fq.enabled = False
        net.train()
        with torch.no_grad():
            out = net(rgb, sparse)
        assert torch.equal(out, ref)
        assert not any(fq.seen) and fq.ranges_by_name() == {}
        fq.enabled = True
        with torch.no_grad():
            net(rgb, sparse)
        assert any(fq.seen)
        named = fq.ranges_by_name()
        assert named and all(fq.kind[fq.names.index(n)] == "int8" for n in named)
    finally:
        fq.detach()
        net.eval()


def test_int8_sensitivity_ranks_every_int8_value(lite):
    """`int8_sensitivity.rank`: one row per asked int8 value, sorted; with every value left in
    float only the weights' rounding remains."""
    from depthor_models import int8_sensitivity

    net, rgb, sparse, ref, fq = _float_then_attached(lite)
    try:
        net.train()
        with torch.no_grad():
            net(rgb, sparse)  # ranges from one training-mode pass
        ranges = fq.ranges_by_name()
        fq.unrounded = {i for i, k in enumerate(fq.kind) if k == "int8"}
        net.eval()
        with torch.no_grad():
            # weights are still rounded: only values are left in float
            assert float((net(rgb, sparse) - ref).abs().max()) < 0.05 * float(ref.abs().max())
    finally:
        fq.detach()
    some = sorted(ranges)[:3]
    base, rows = int8_sensitivity.rank(net, rgb, sparse, ranges, only=some)
    assert base > 0 and [r.name for r in rows] != [] and {r.name for r in rows} == set(some)
    assert [r.rms_m for r in rows] == sorted(r.rms_m for r in rows)
    # a kept value is float in every run: not ranked, and the base moves to its row's figure
    kept_base, kept_rows = int8_sensitivity.rank(net, rgb, sparse, ranges, only=some,
                                                 kept=[rows[0].name])
    assert {r.name for r in kept_rows} == set(some) - {rows[0].name}
    assert kept_base == pytest.approx(rows[0].rms_m, rel=1e-5)
    with pytest.raises(ValueError):
        int8_sensitivity.rank(net, rgb, sparse, ranges, kept=["no.such.value"])
    with pytest.raises(ValueError):
        int8_sensitivity.rank(net, rgb, sparse, {"no.such.value": [0.0, 1.0]})
