"""zone_fill.nearest_fill: each pixel near a zone point takes its depth, pixels beyond the fill
radius stay 0, frames are independent."""

import pytest
import torch

from depthor_models.graph_export import trace
from depthor_models.net import build, random_inputs
from depthor_models.zone_fill import RADIUS_PITCH, nearest_fill


def test_fill_regular_grid_and_radius():
    s = torch.zeros(2, 1, 60, 80)
    # frame 0: a 4 × 4 grid, pitch 10 px, in the top-left 40 × 40 px; frame 1: no points
    for i in range(4):
        for j in range(4):
            s[0, 0, 5 + 10 * i, 5 + 10 * j] = 1.0 + i + 0.1 * j
    f = nearest_fill(s)
    assert torch.all(f[1] == 0)
    # a pixel inside a cell takes that cell's point
    assert f[0, 0, 12, 27] == s[0, 0, 15, 25]
    assert f[0, 0, 3, 1] == s[0, 0, 5, 5]
    # beyond RADIUS_PITCH pitches of every point: no fill
    pitch = (34 * 34 / 16) ** 0.5
    far_col = int(35 + RADIUS_PITCH * pitch) + 1
    assert torch.all(f[0, 0, :, far_col:] == 0)
    assert torch.all(f[0, 0, 5, 35:int(35 + RADIUS_PITCH * pitch)] == s[0, 0, 5, 35])


def test_fill_is_refused_where_it_would_be_ignored_or_lost():
    # the dense architecture does not apply the fill; the graph contract has no fill op
    with pytest.raises(ValueError, match="lite architecture only"):
        build("mcu", calibrate_bn=False, sparse_input="fill")
    net = build("mcu_lite", calibrate_bn=False, sparse_input="fill")
    with pytest.raises(ValueError, match="not a graph op"):
        trace(net, *random_inputs(net.cfg))
