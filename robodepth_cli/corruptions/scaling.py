"""The severity size: the image size ``H0 x W0`` at which the levels' spatial parameters are
defined. Every spatial parameter is multiplied by ``s = sqrt((H * W) / (H0 * W0))`` for an
``H x W`` image, exactly 1 at the severity size itself (the tabulated bytes); without one
(``none``) the parameters are used as tabulated at any size, the benchmark's behaviour
(docs/severity-and-chains.md).

This module is light (no engine imports): the configuration and the CLI parse the option here."""

from __future__ import annotations

import math

from ..errors import InvalidValueError

NONE = "none"
KITTI = (192, 640)  # the size KITTI-C's levels were tuned at
NYU = (480, 640)  # NYUDepth2-C's

def parse_severity_size(value) -> tuple[int, int] | None:
    """``value`` (``none``, ``HxW`` text, an ``[H, W]`` pair, or None) as ``(H, W)``, or None
    for ``none``; :class:`InvalidValueError` saying what is wrong otherwise (the caller
    names the flag or key)."""
    from ..imageio import parse_size

    if value is None or (isinstance(value, str) and value.strip().lower() == NONE):
        return None
    if isinstance(value, (list, tuple)) and len(value) == 2:
        value = f"{value[0]}x{value[1]}"
    if not isinstance(value, str):
        raise InvalidValueError(f"expected HxW such as 192x640, or none, got {value!r}")
    return parse_size(value)


def size_text(size: tuple[int, int] | None) -> str:
    """``192x640``, or ``none`` for no severity size: how build.json, the manifest's params,
    the dataset card and the report write it."""
    return NONE if size is None else f"{size[0]}x{size[1]}"


def scale_factor(shape: tuple[int, int], size: tuple[int, int] | None) -> float | None:
    """The factor ``s`` by which an image of ``shape`` (H, W) scales the spatial parameters
    defined at severity size ``size``: ``sqrt(H W / (H0 W0))``; None without a severity
    size (the parameters as tabulated)."""
    if size is None:
        return None
    h, w = shape[:2]
    return math.sqrt((h * w) / (size[0] * size[1]))
