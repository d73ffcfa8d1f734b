"""`--set` overrides and the bin-merging starting point of the `n_bins` ablation."""
import pytest
import torch

from depthor_models.net import build, parse_overrides
from depthor_models.rebin import merge_bins


def test_overrides_parse_literals_and_reject_unknown_fields():
    assert parse_overrides(["n_bins=32", "iterations=4"]) == {"n_bins": 32, "iterations": 4}
    with pytest.raises(ValueError):
        parse_overrides(["no_such_field=1"])
    with pytest.raises(ValueError):
        parse_overrides(["n_bins"])


def test_merged_bins_keep_widths_and_probabilities_of_the_groups():
    torch.manual_seed(0)
    net = build("mcu_lite", seed=3, n_bins=64)
    state = net.state_dict()
    merged = merge_bins(state, 32)
    small = build("mcu_lite", seed=3, n_bins=32)
    small.load_state_dict(merged)  # the shapes of a 32-bin network
    # Widths: with positive member logits, the merged width is the sum of the members'.
    h = torch.rand(5, state["bins_fc2.weight"].shape[1])
    w64 = torch.relu(h @ state["bins_fc2.weight"].T + state["bins_fc2.bias"]) + 0.1
    l32 = h @ merged["bins_fc2.weight"].T + merged["bins_fc2.bias"]
    pos = (h @ state["bins_fc2.weight"].T + state["bins_fc2.bias"] > 0).reshape(5, 32, 2).all(2)
    assert pos.any(), "no group with positive member logits to compare"
    sums = w64.reshape(5, 32, 2).sum(2)
    assert torch.allclose((torch.relu(l32) + 0.1)[pos], sums[pos], atol=1e-5)
    # Logits: the mean of each pair.
    assert torch.allclose(merged["bins_head.bias"], state["bins_head.bias"].reshape(32, 2).mean(1))
    with pytest.raises(ValueError):
        merge_bins(state, 48)


def test_export_applies_the_overrides(tmp_path):
    import json

    from depthor_models.export import export_variant

    # Values other than mcu_lite's own (16 bins, T = 4).
    export_variant("mcu_lite", tmp_path, nnef=False, overrides={"n_bins": 24, "iterations": 2})
    nodes = json.loads((tmp_path / "graph.json").read_text())["nodes"]
    attrs = {n["op"]: n["attrs"] for n in nodes if n["op"] in ("bins_head", "refine")}
    assert attrs["bins_head"]["n_bins"] == 24 and attrs["refine"]["iterations"] == 2


def test_dilated_heads_keep_the_ring_channels_and_export(tmp_path):
    import json

    from depthor_models import ops
    from depthor_models.dilate import dilated_heads
    from depthor_models.export import export_variant

    assert parse_overrides(["refine_neighbourhood=dilated"]) == {"refine_neighbourhood": "dilated"}
    state = build("mcu_lite", seed=4, refine_neighbourhood="window").state_dict()
    cut = dilated_heads(state)
    net = build("mcu_lite", seed=4, refine_neighbourhood="dilated")
    net.load_state_dict(cut)  # the shapes of the dilated network
    window, ring = ops.neighbour_offsets(7), ops.neighbour_offsets(7, "dilated")
    for c, o in enumerate(ring):
        assert torch.equal(cut["aff7.weight"][c], state["aff7.weight"][window.index(o)])
        assert cut["aff7.bias"][c] == state["aff7.bias"][window.index(o)]
    with pytest.raises(ValueError):
        dilated_heads(cut)
    export_variant("mcu_lite", tmp_path, nnef=False, overrides={"refine_neighbourhood": "dilated"})
    # mcu_lite itself is dilated (net.VARIANTS).
    assert build("mcu_lite").refine.neighbourhood == "dilated"
    nodes = json.loads((tmp_path / "graph.json").read_text())["nodes"]
    refine = next(n for n in nodes if n["op"] == "refine")
    assert refine["attrs"]["neighbourhood"] == "dilated"


def test_prior_overrides_and_removed_blocks():
    from depthor_models.net import config, random_inputs
    from depthor_models.shrink import shrink

    over = parse_overrides(["prior.blocks=(0,0,1,2)", "rgb_blocks=(0,0,1,2,1)"])
    assert over == {"prior.blocks": (0, 0, 1, 2), "rgb_blocks": (0, 0, 1, 2, 1)}
    cfg = config("mcu_lite", **over)
    assert cfg.prior.blocks == (0, 0, 1, 2)
    assert cfg.prior.widths == config("mcu_lite").prior.widths  # the other prior fields kept
    with pytest.raises(ValueError):
        parse_overrides(["prior.no_such_field=1"])

    # mcu_lite before its blocks were removed (the 2026-12-05 network).
    before = {"prior.blocks": (0, 1, 1, 2), "rgb_blocks": (0, 1, 1, 2, 1)}
    full = build("mcu_lite", seed=5, **before)
    state = full.state_dict()
    # The block to remove computes x + f(x); with its projection at zero it is the identity.
    for part in ("weight", "bias"):
        state[f"prior.enc.1.1.project.{part}"].zero_()
    full.load_state_dict(state)
    small = build("mcu_lite", seed=6, **over)
    kept, dropped = shrink(state, small.state_dict())
    assert dropped and all(n.startswith("prior.enc.1.1.") for n in dropped)
    small.load_state_dict(kept)
    full.eval(), small.eval()
    x = random_inputs(config("mcu_lite"))
    with torch.no_grad():
        assert torch.equal(full(*x), small(*x))
    # The other way (a block the trained network lacks) is an error.
    with pytest.raises(KeyError):
        shrink(small.state_dict(), full.state_dict())
