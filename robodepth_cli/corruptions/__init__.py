"""The 18 corruptions of the RoboDepth benchmark, at any severity in [1, 5], alone or chained.

``REGISTRY`` maps each name, in benchmark order, to its :class:`Corruption` record (category,
parameter table with its interpolation rules, function). :func:`corrupt` is the checked
entry point; :func:`corrupt_chain` applies a :class:`~.chains.Chain`.

Importing the package is light: levels (:mod:`.severity`) and chains (:mod:`.chains`) are
parsed and checked without loading the corruption engine (numba, OpenCV, SciPy), which
loads on first use of ``REGISTRY``, ``corrupt`` and the other engine names.
"""

from __future__ import annotations

import importlib

from ..benchmarks import CATEGORIES, CATEGORY, DATA, SENSOR, WEATHER
from .severity import LevelError, level_text, parse_level

_ENGINE = ("REGISTRY", "NAMES", "Corruption", "corrupt", "corrupt_chain", "render", "get", "check_level")

__all__ = ["CATEGORIES", "WEATHER", "SENSOR", "DATA", "LevelError", "level_text", "parse_level",
           *_ENGINE]


def __getattr__(name: str):
    if name in _ENGINE:
        return getattr(importlib.import_module("._engine", __name__), name)
    if name in CATEGORY:  # a corruption's own module
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_ENGINE))
