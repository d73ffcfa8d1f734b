"""Shared fixtures: the models/ folder on sys.path, built variants, and a network guard."""

from __future__ import annotations

import socket
import sys
import warnings
from pathlib import Path

import pytest

MODELS = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(MODELS))

import torch  # noqa: E402

from depthor_models import build, random_inputs  # noqa: E402
from depthor_models import graph_export  # noqa: E402

torch.set_num_threads(2)
warnings.filterwarnings("ignore", category=torch.jit.TracerWarning)



@pytest.fixture(scope="session")
def nets():
    """Both variants, seeded random weights with calibrated BN, built once per session."""
    return {v: build(v, seed=0) for v in ("mcu", "phone")}


@pytest.fixture(scope="session")
def traced(nets):
    """Each variant traced on its fixed-seed inputs."""
    out = {}
    for v, net in nets.items():
        rgb, sparse = random_inputs(net.cfg, torch.Generator().manual_seed(1))
        out[v] = graph_export.trace(net, rgb, sparse)
    return out


class NetworkUsed(AssertionError):
    """Raised when code under test opens a network connection."""


@pytest.fixture
def no_network(monkeypatch):
    """Fails the test if anything connects a socket or tries to fetch a tract CLI."""

    def refuse(*_args, **_kwargs):
        raise NetworkUsed("network access attempted")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket.socket, "connect_ex", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    from torch_to_nnef.inference_target import tract as t2n_tract

    monkeypatch.setattr(t2n_tract.TractBinaryDownloader, "dl_tract", refuse)
    monkeypatch.setattr(t2n_tract.TractCli, "download", classmethod(refuse))
