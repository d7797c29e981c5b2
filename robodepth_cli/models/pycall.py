"""A user's own model as a Python function: ``python:MODULE:CALLABLE`` (docs/predict.md).
``MODULE`` is an importable name (the current directory searched first) or a ``.py`` path,
``CALLABLE`` a name in it (dots reach into objects); it takes an ``N x H x W x 3`` uint8
batch and returns ``N`` maps. The record's identity holds the sha256 of the module's own
file only, so a PRED whose module was edited since is refused."""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path

import numpy as np

from ..errors import RobodepthError, reraise_interrupt
from .base import KINDS, Model, default_alignment
from .size import modules_of


def load(arg: str, spec: str, *, kind: str | None = None, metric: bool | None = None) -> Model:
    module_name, sep, attr = arg.rpartition(":")
    if not sep or not module_name or not attr:
        raise RobodepthError(f"--model {spec!r}: expected python:MODULE:CALLABLE")
    if kind is None:
        raise RobodepthError(f"{spec}: say what the function returns with --kind "
                             f"({', '.join(KINDS)}), and --metric if it is in metres")
    if kind not in KINDS:
        raise RobodepthError(f"--kind {kind!r}: valid: {', '.join(KINDS)}")
    module = _import(module_name, spec)
    fn = module
    for part in attr.split("."):
        try:
            fn = getattr(fn, part)
        except AttributeError:
            raise RobodepthError(f"{spec}: {module_name} has no {attr}") from None
    if not callable(fn):
        raise RobodepthError(f"{spec}: {attr} is a {type(fn).__name__}, not a function")

    def run(images: np.ndarray):
        try:
            return fn(images)
        except Exception as exc:  # the user's code: its failure is reported, not a crash of ours
            reraise_interrupt(exc)
            raise RobodepthError(f"{spec}: raised {type(exc).__name__}: "
                                 f"{str(exc).strip().splitlines()[0] if str(exc).strip() else ''}") from None

    frames = _frames(getattr(fn, "robodepth_frames", ()), spec)
    metric = bool(metric)
    align, space = default_alignment(metric)
    path = getattr(module, "__file__", None)
    identity = {"module": module_name, "callable": attr, "file": path,
                "sha256": _file_hash(path, spec)}
    return Model(spec=spec, adapter="python", kind=kind, metric=metric, align=align,
                 align_space=space, input_size=None, identity=identity, run=run,
                 device="the function's own device", frames=frames,
                 modules=modules_of(fn, spec))


def _frames(value, spec: str) -> tuple[int, ...]:
    """A callable's ``robodepth_frames``: distinct non-zero integer offsets.

    A multi-frame model declares the neighbour frames it takes so, ``fn.robodepth_frames =
    (-1, 1)`` (in the order it wants them): it is then called with ``N x F x H x W x 3``
    (``F`` = 1 + the offsets), ``[:, 0]`` the frame itself and ``[:, 1 + k]`` its neighbour
    at the k-th offset, read from a build made with ``--frames``; a neighbour the drive does
    not have is a black image, as ManyDepth's loader gives for a missing file."""
    offsets = tuple(value) if isinstance(value, (list, tuple)) else None
    if offsets is None or not all(isinstance(o, int) and not isinstance(o, bool) and o for o in offsets) \
            or len(set(offsets)) != len(offsets):
        raise RobodepthError(f"{spec}: robodepth_frames {value!r}: expected distinct non-zero integer "
                             f"frame offsets such as (-1, 1)")
    return offsets


def _file_hash(path: str | None, spec: str) -> str | None:
    """The sha256 of the module's source file (None for a module without one: a built-in
    or a namespace package)."""
    from ..errors import os_reason
    from ..files import sha256_file

    if not path or not Path(path).is_file():
        return None
    try:
        return sha256_file(path)
    except OSError as exc:
        raise RobodepthError(f"{spec}: {path}: cannot read ({os_reason(exc)})") from None


def _import(name: str, spec: str):
    if name.endswith(".py"):
        path = Path(name).expanduser()
        if not path.is_file():
            raise RobodepthError(f"{spec}: {path}: no such file")
        here = str(path.resolve().parent)
        if here not in sys.path:  # the modules beside the file, as for a script
            sys.path.insert(0, here)
        mod_spec = importlib.util.spec_from_file_location(path.stem, path)
        module = importlib.util.module_from_spec(mod_spec)
        loader = mod_spec.loader.exec_module
    else:
        module, loader = None, None
    try:
        if loader is not None:
            loader(module)
            return module
        if "" not in sys.path and str(Path.cwd()) not in sys.path:
            sys.path.insert(0, str(Path.cwd()))
        return importlib.import_module(name)
    except RobodepthError:
        raise
    except Exception as exc:  # ImportError, or whatever the user's module raises on import
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise RobodepthError(f"{spec}: cannot import {name} ({type(exc).__name__}: {text})") from None
