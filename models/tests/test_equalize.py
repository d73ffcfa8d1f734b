"""Per-channel equalisation (`depthor_models.equalize`): the float network is unchanged, the
equalised value's channels span more alike ranges, and a reader that does not commute with a
channel scale is refused."""

from __future__ import annotations

import pytest
import torch

from depthor_models import build, equalize, random_inputs


@pytest.fixture(scope="module")
def lite():
    net = build("mcu_lite", seed=0)
    rgb, sparse = random_inputs(net.cfg, torch.Generator().manual_seed(3))
    return net.eval(), rgb, sparse


def test_channel_scales_lift_small_channels_up_to_the_cap():
    v = torch.ones(2, 4, 8, 8) * torch.tensor([4.0, 1.0, 0.1, 4.0]).view(1, 4, 1, 1)
    s = equalize.channel_scales(v, quantile=0.999, max_scale=8.0)
    assert torch.allclose(s, torch.tensor([1.0, 4.0, 8.0, 1.0]))


def test_equalised_network_computes_the_same_depth(lite):
    net, rgb, sparse = lite
    value = "depth_enc.stages.0.pw.act"
    with torch.no_grad():
        ref = net(rgb, sparse)
    state, s, changed = equalize.equalize(net, rgb, sparse, value, max_scale=8.0)
    assert changed[0] == value and all(c.startswith("concat") for c in changed[1:])
    assert bool((s >= 1).all()) and bool((s <= 8).all()) and float(s.max()) > 1
    eq = build("mcu_lite", seed=0, calibrate_bn=False)
    eq.load_state_dict(state)
    eq.eval()
    with torch.no_grad():
        out = eq(rgb, sparse)
    assert float((out - ref).abs().max()) < 1e-3 * float(ref.abs().max())
    # the equalised channels' spread shrank: the smallest channel maximum moved up
    from depthor_models.graph_export import trace

    before = trace(net, rgb, sparse).values[value].abs().amax(dim=(0, 2, 3))
    after = trace(eq, rgb, sparse).values[value].abs().amax(dim=(0, 2, 3))
    assert float((after / after.max()).min()) > float((before / before.max()).min())


def test_a_reader_that_does_not_commute_is_refused(lite):
    net, rgb, sparse = lite
    # an inverted residual's output is read by an add (x + f(x)) and is not an activation
    with pytest.raises(ValueError):
        equalize.equalize(net, rgb, sparse, "prior.enc.3.1.add")
    # the deepest depth stage feeds CBAM's pools and multiplies
    with pytest.raises(ValueError, match="does not commute"):
        equalize.equalize(net, rgb, sparse, "depth_enc.stages.3.pw.act")
