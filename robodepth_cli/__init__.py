"""robodepth: build the RoboDepth robustness benchmark datasets."""

__version__ = "0.1.0"


def __getattr__(name: str):
    # Lazily, so that `import robodepth_cli` (and `robodepth --help`) stays light.
    if name == "open_dataset":
        from .api import open_dataset

        return open_dataset
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
