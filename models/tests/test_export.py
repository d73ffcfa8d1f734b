"""NNEF export with torch-to-nnef, offline, checked by loading the archive in tract (Python
bindings of the same tract version) against PyTorch."""

from __future__ import annotations

import tarfile

import numpy as np
import pytest
import torch

from depthor_models.export import export_nnef, export_variant


def _tract_run(path, inputs):
    import tract

    model = tract.nnef().load(str(path)).into_runnable()
    return [o.to_numpy() for o in model.run([np.ascontiguousarray(i) for i in inputs])]


def test_exports_are_offline_and_tract_matches_torch(no_network, tmp_path, nets, traced):
    net, t = nets["mcu"], traced["mcu"]
    rgb, sparse = t.values["rgb"], t.values["sparse"]
    full = export_nnef(net, (rgb, sparse), tmp_path / "depthor.nnef.tgz", ["rgb", "sparse"],
                       ["depth"])
    prior = export_nnef(net.prior, (rgb,), tmp_path / "prior.nnef.tgz", ["rgb"],
                        ["d_inv", "f_mde"])
    for p in (full, prior):
        with tarfile.open(p) as tar:
            assert "graph.nnef" in tar.getnames()
    (depth,) = _tract_run(full, [rgb.numpy(), sparse.numpy()])
    diff = float(np.abs(depth - t.values["depth"].numpy()).max())
    print(f"mcu: max |tract - torch| on depth = {diff:.3g} m")
    assert diff <= 1e-4
    d_inv, f_mde = _tract_run(prior, [rgb.numpy()])
    with torch.no_grad():
        ref_inv, ref_mde = net.prior(rgb)
    assert np.abs(d_inv - ref_inv.numpy()).max() <= 1e-4
    assert np.abs(f_mde - ref_mde.numpy()).max() <= 1e-4


def test_export_refuses_other_suffix(nets, tmp_path):
    with pytest.raises(ValueError):
        export_nnef(nets["mcu"].prior, (torch.zeros(1, 3, 120, 160),), tmp_path / "p.onnx",
                    ["rgb"], ["d_inv", "f_mde"])


@pytest.mark.slow
def test_phone_export_tract_matches_torch(no_network, tmp_path, nets, traced):
    s = export_variant("phone", tmp_path, net=nets["phone"])
    t = traced["phone"]
    (depth,) = _tract_run(tmp_path / "depthor.nnef.tgz",
                          [t.values["rgb"].numpy(), t.values["sparse"].numpy()])
    diff = float(np.abs(depth - t.values["depth"].numpy()).max())
    print(f"phone: max |tract - torch| on depth = {diff:.3g} m, summary macs {s['macs']}")
    assert diff <= 1e-4
