"""depthor models: the DEPTHOR network in docs/graph.md ops, its NNEF / graph.json exporters, golden
tensors and a numpy interpreter of graph.json (the spec the Rust core engine implements)."""

from .net import VARIANTS, Depthor, NetConfig, build, config, random_inputs
from .prior import Prior, PriorConfig

__all__ = ["VARIANTS", "Depthor", "NetConfig", "Prior", "PriorConfig", "build", "config",
           "random_inputs"]
