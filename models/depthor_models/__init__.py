"""depthor models: the DEPTHOR network in docs/graph.md ops, its NNEF / graph.json exporters, golden
tensors and a numpy interpreter of graph.json (the spec the Rust core engine implements).

The names below are imported on first use (PEP 562), so that torch-free modules of the package
(`bench_common`, the LiteRT worker of `bench_litert`) import in an environment without PyTorch."""

from importlib import import_module

__all__ = ["VARIANTS", "Depthor", "NetConfig", "Prior", "PriorConfig", "build", "config",
           "random_inputs"]
_HOME = {"Prior": "prior", "PriorConfig": "prior"}  # the rest live in .net


def __getattr__(name: str):
    if name in __all__:
        return getattr(import_module(f".{_HOME.get(name, 'net')}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
