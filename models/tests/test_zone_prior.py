"""The refinement's start from the zones (depthor_models/zone_prior.py): the splat interpolates
a regular grid of points exactly, its density is ≈ 1 inside the grid, and a network built with
`zone_prior=True` starts from trained weights where they were."""

import math

import pytest
import torch

from depthor_models import net as N
from depthor_models.zone_prior import GATE_BIAS0, ZonePrior, splat


def grid_points(value: float, h: int = 64, w: int = 48, step: int = 8) -> torch.Tensor:
    sparse = torch.zeros(1, 1, h, w)
    sparse[0, 0, step // 2::step, step // 2::step] = value
    return sparse


def test_splat_of_a_constant_grid_is_the_constant_with_unit_density_inside():
    z, rho = splat(grid_points(2.5), 32, 24)
    assert z.shape == (1, 1, 32, 24)
    assert torch.allclose(z, torch.full_like(z, 2.5), rtol=1e-5)
    inner = rho[0, 0, 8:-8, 8:-8]
    assert float(inner.min()) > 0.9 and float(inner.max()) < 1.1
    assert float(rho[0, 0, 0, 0]) < float(inner.min())


def test_splat_weights_points_by_distance():
    sparse = torch.zeros(1, 1, 16, 16)
    sparse[0, 0, 4, 4], sparse[0, 0, 4, 12] = 1.0, 3.0
    z, _ = splat(sparse, 16, 16)
    # the midpoint's column 8 lies half way: the average; nearer each point, its value wins
    assert math.isclose(float(z[0, 0, 4, 8]), 2.0, rel_tol=1e-4)
    # at a point: its own weight 1 against exp(−8² / 2σ²), σ = sqrt(16·16 / 2)
    other = math.exp(-64 / (2 * 128))
    assert math.isclose(float(z[0, 0, 4, 4]), (1.0 + 3.0 * other) / (1 + other), rel_tol=1e-4)
    assert math.isclose(float(z[0, 0, 4, 12]), (3.0 + 1.0 * other) / (1 + other), rel_tol=1e-4)


def test_splat_without_points_is_zero():
    z, rho = splat(torch.zeros(2, 1, 8, 8), 4, 4)
    assert torch.all(z == 0) and torch.all(rho == 0)


def test_gate_starts_near_zero_and_blends_toward_the_zones():
    zp = ZonePrior(4)
    d0 = torch.full((1, 1, 32, 24), 1.0)
    guidance = torch.zeros(1, 4, 32, 24)
    out = zp(d0, guidance, grid_points(2.0))
    g0 = 1 / (1 + math.exp(-GATE_BIAS0))
    assert torch.allclose(out, torch.full_like(out, 1.0 + g0), rtol=1e-4)
    with torch.no_grad():
        zp.gate.bias.fill_(20.0)  # gate fully open: D_0' = Z
    assert torch.allclose(zp(d0, guidance, grid_points(2.0)), torch.full_like(out, 2.0), rtol=1e-4)


def test_lite_network_with_zone_prior_keeps_the_other_weights():
    cfg = N.config("mcu_lite", zone_prior=True)
    torch.manual_seed(0)
    base = N.make_net(N.config("mcu_lite")).eval()
    with_zp = N.make_net(cfg).eval()
    missing, unexpected = with_zp.load_state_dict(base.state_dict(), strict=False)
    assert sorted(missing) == ["zone_prior.gate.bias", "zone_prior.gate.weight"]
    assert not unexpected
    with torch.no_grad():
        with_zp.zone_prior.gate.bias.fill_(-1e4)  # gate shut: the network alone
        rgb, sparse = torch.rand(1, 3, 120, 160), grid_points(1.5, 120, 160, 20)
        assert torch.allclose(with_zp(rgb, sparse), base(rgb, sparse), atol=1e-6)


def test_dense_network_refuses_the_zone_prior():
    with pytest.raises(ValueError):
        N.make_net(N.config("mcu", zone_prior=True))


def test_the_gate_learns_faster_without_weight_decay():
    from depthor_models import train as T

    net = N.make_net(N.config("mcu_lite", zone_prior=True))
    opt, sched = T.make_optim(net, 1e-4, 100)
    assert len(opt.param_groups) == 2
    rest, gate = opt.param_groups
    assert {id(p) for p in gate["params"]} == {id(p) for p in net.zone_prior.parameters()}
    assert gate["weight_decay"] == 0.0 and rest["weight_decay"] == 0.1
    for _ in range(30):
        opt.step()
        sched.step()
    assert gate["lr"] == pytest.approx(rest["lr"] * T.ZONE_PRIOR_LR_SCALE)
    # without a zone prior: one group, as before
    plain = N.make_net(N.config("mcu_lite"))
    assert len(T.make_optim(plain, 1e-4, 100)[0].param_groups) == 1
