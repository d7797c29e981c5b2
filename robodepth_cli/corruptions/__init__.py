"""The 18 corruptions of the RoboDepth benchmark and the depth-aware ones, at any severity
in [1, 5], alone or chained.

``REGISTRY`` maps each name, in benchmark order (the depth-aware ones last; ``NAMES`` is
the benchmarks' 18, ``DEPTH_NAMES`` the others), to its :class:`Corruption` record (category,
parameter table with its interpolation rules, function). :func:`corrupt` is the checked
entry point; :func:`corrupt_chain` applies a :class:`~.chains.Chain`.

Importing the package is light: levels (:mod:`.severity`) and chains (:mod:`.chains`) are
parsed and checked without loading the corruption engine (numba, OpenCV, SciPy), which
loads on first use of ``REGISTRY``, ``corrupt`` and the other engine names.
"""

from __future__ import annotations

import importlib

from ..benchmark_facts import ALL_CATEGORY, CATEGORIES, DATA, SENSOR, WEATHER
from .severity import LevelError, level_text, parse_level

_ENGINE = ("REGISTRY", "NAMES", "DEPTH_NAMES", "DepthError", "Corruption", "corrupt",
           "corrupt_chain", "render", "get", "check_level", "needs_depth",
           "depth_aware_variant", "is_scaled", "scaled_variant")

__all__ = ["CATEGORIES", "WEATHER", "SENSOR", "DATA", "LevelError", "level_text", "parse_level",
           *_ENGINE]


def __getattr__(name: str):
    if name in _ENGINE:
        return getattr(importlib.import_module("._engine", __name__), name)
    if name in ALL_CATEGORY:  # a corruption's own module
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_ENGINE))
