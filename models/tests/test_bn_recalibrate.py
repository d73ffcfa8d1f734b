"""bn_recalibrate: batch-norm statistics replaced by their average over training frames, every
weight unchanged."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from depthor_models import bn_recalibrate, data
from depthor_models import train as T

from test_train import write_recording


def _bns(net):
    return [m for m in net.modules() if isinstance(m, nn.BatchNorm2d)]


def test_one_batch_gives_that_batchs_statistics_and_keeps_the_weights(tmp_path):
    rec = data.load_recording(write_recording(tmp_path / "rec", n=4), size=(120, 160))
    net = T.make_model("mcu_lite", 0)
    for m in _bns(net):  # stale statistics, as a training run's last batches leave them
        m.running_mean.fill_(3.0)
        m.running_var.fill_(7.0)
    weights = {k: v.clone() for k, v in net.state_dict().items() if "running" not in k
               and "num_batches" not in k}
    assert bn_recalibrate.recalibrate(net, rec, frames=4, batch=4, seed=0) == len(_bns(net))
    assert not net.training
    # Reference: the same 4 frames as one train-mode batch with momentum 1 (stats = that batch's).
    ref = T.make_model("mcu_lite", 0)
    ref.load_state_dict(net.state_dict())
    for m in _bns(ref):
        m.momentum = 1.0
    order = np.random.default_rng(0).permutation(4)
    ref.train()
    with torch.no_grad():
        ref(*data.batch(rec, order)[:2])
    for a, b in zip(_bns(net), _bns(ref)):
        assert torch.allclose(a.running_mean, b.running_mean, atol=1e-5)
        assert torch.allclose(a.running_var, b.running_var, rtol=1e-4, atol=1e-6)
        assert a.momentum == 0.1  # restored
    for k, v in net.state_dict().items():
        if k in weights:
            assert torch.equal(v, weights[k]), k


def test_cli_writes_the_state_dict(tmp_path, capsys):
    rec_dir = write_recording(tmp_path / "rec", n=3)
    w = tmp_path / "w.pt"
    torch.save(T.make_model("mcu_lite", 0).state_dict(), w)
    out = tmp_path / "bn.pt"
    assert bn_recalibrate.main(["--variant", "mcu_lite", "--weights", str(w), "--train",
                                str(rec_dir), "--frames", "9", "--batch", "2", "--out",
                                str(out), "--threads", "1"]) == 0
    assert "over 3 frames" in capsys.readouterr().out
    sd = torch.load(out)
    means = [v for k, v in sd.items() if k.endswith("running_mean")]
    assert means and all(v.abs().sum() > 0 for v in means)  # fresh ones are all zero
