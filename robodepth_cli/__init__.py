"""robodepth: build the RoboDepth robustness benchmark datasets."""

from pathlib import Path

__version__ = "0.1.0"


def data_dir(name: str) -> Path:
    """The ``configs`` or ``splits`` directory: inside the package when installed from a
    wheel, at the top of the repository in a checkout (and an editable install)."""
    here = Path(__file__).resolve().parent
    installed = here / name
    return installed if installed.is_dir() else here.parent / name


def __getattr__(name: str):
    # Lazily, so that `import robodepth_cli` (and `robodepth --help`) stays light.
    if name == "open_dataset":
        from .api import open_dataset

        return open_dataset
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
