"""Frost: a frost texture blended over the image.

The textures are read from the installed ``imagecorruptions-imaug`` distribution's files,
located through its metadata: the package itself is never imported (it would pull in its
own dependencies and our test oracle into the build).
"""

from __future__ import annotations

import math
from functools import lru_cache
from importlib import metadata
from pathlib import Path

import cv2
import numpy as np

from ._exact import resize_cubic
from ._jit import njit
from .registry import register
from .severity import interpolate
from ..errors import RobodepthError

# (a, b): weights of the image and of the frost texture
LEVELS = ((1.0, 0.4), (0.8, 0.6), (0.7, 0.7), (0.65, 0.7), (0.6, 0.75))

DISTRIBUTION = "imagecorruptions-imaug"
# The package ships six; the benchmark only ever picks among the first five.
TEXTURES = ("frost1.png", "frost2.png", "frost3.png", "frost4.jpg", "frost5.jpg")
_INSTALL_HINT = (f"run `make install` (or `pip install --no-deps {DISTRIBUTION}`): "
                 "frost needs its texture files")


class FrostTextureError(RobodepthError):
    """The frost textures cannot be found or read."""


@lru_cache(maxsize=None)
def texture_path(index: int) -> Path:
    """Path of texture ``TEXTURES[index]`` inside the installed distribution."""
    name = TEXTURES[index]
    try:
        dist = metadata.distribution(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        raise FrostTextureError(f"{DISTRIBUTION} is not installed; {_INSTALL_HINT}") from None
    for f in dist.files or ():
        if f.parts[-2:] == ("frost", name):
            path = Path(dist.locate_file(f))
            if path.is_file():
                return path
    raise FrostTextureError(f"{name} is missing from the installed {DISTRIBUTION}; {_INSTALL_HINT}")


@lru_cache(maxsize=None)
def texture_bgr(index: int) -> np.ndarray:
    """Texture ``index`` decoded as 3-channel BGR uint8 (OpenCV's ``imread`` default:
    an alpha channel is dropped). Read-only."""
    path = texture_path(index)
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise FrostTextureError(f"cannot decode frost texture {path}; {_INSTALL_HINT}")
    img.flags.writeable = False
    return img


def _factor(texture_hw, image_hw) -> float:
    (th, tw), (h, w) = texture_hw, image_hw
    ratios = [n / t for n, t in ((h, th), (w, tw)) if t < n]
    q = max(ratios) if ratios else 1
    return q * 1.1


def scaled_size(texture_hw, image_hw, scale: float | None = None) -> tuple[int, int]:
    """``(width, height)`` the texture is resized to: ``q = 1`` if it is at least as large
    as the image in both dimensions, else the larger of ``image / texture`` over the
    dimensions where it is smaller; ``q *= 1.1``; ``(ceil(w_t * q), ceil(h_t * q))``.

    With a severity size's ``scale``: the larger of that ``q`` and ``scale`` times the ``q``
    of the image at the severity size (``image / scale``), so that the grain is that of the
    severity size, grown with the image, and the texture still covers it."""
    q = _factor(texture_hw, image_hw)
    if scale is not None:
        q = max(q, scale * _factor(texture_hw, (image_hw[0] / scale, image_hw[1] / scale)))
    (th, tw) = texture_hw
    return int(math.ceil(tw * q)), int(math.ceil(th * q))


# One image size's five textures: a preset build has one size (one resize per process);
# a build of mixed sizes re-resizes (~15 ms) instead of holding ~30 MB per large texture.
@lru_cache(maxsize=5)
def scaled_texture(index: int, image_hw: tuple[int, int]) -> np.ndarray:
    """Texture ``index`` resized for an image of ``image_hw`` (OpenCV's bicubic, by its exact
    fixed-point formula: :func:`~._exact.resize_cubic`) and converted to RGB (channel order
    does not affect the resize). Read-only."""
    bgr = texture_bgr(index)
    resized = resize_cubic(bgr, scaled_size(bgr.shape[:2], image_hw))
    rgb = np.ascontiguousarray(resized[..., ::-1])
    rgb.flags.writeable = False
    return rgb


@lru_cache(maxsize=None)
def blend_table(level) -> np.ndarray:
    """``T[v, u] = uint8(floor(clip(a * v + b * u, 0, 255)))`` for image value ``v`` and
    texture value ``u``, in float64 as the benchmark computes it."""
    a, b = interpolate(LEVELS, level)
    v = np.arange(256, dtype=np.float64)
    table = np.clip(a * v[:, None] + b * v[None, :], 0, 255).astype(np.uint8)
    table.flags.writeable = False
    return table


@njit
def _blend(x, crop, table):
    out = np.empty(x.shape, dtype=np.uint8)
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            for c in range(x.shape[2]):
                out[i, j, c] = table[x[i, j, c], crop[i, j, c]]
    return out


@register(("a", "b"), LEVELS, scaled=True)
def frost(x: np.ndarray, level: int, rng: np.random.Generator, scale: float | None = None) -> np.ndarray:
    """Frost: pick texture ``k`` uniformly among the first five (``rng.integers(5)``),
    read it as BGR, resize it to :func:`scaled_size` with bicubic interpolation, take the
    H x W crop at row ``rng.integers(0, h' - H)`` and column ``rng.integers(0, w' - W)``
    (drawn in that order), convert it to RGB; result ``clip(a * x + b * crop, 0, 255)``
    in the 0..255 domain, truncated to uint8 (through the exact table
    :func:`blend_table`).

    Size rule: a texture smaller than the image in either dimension is scaled up by the
    larger of the ratios so that it covers the image (e.g. all five for 1024 x 2048), with
    a 1.1 margin always applied, so the crop offsets always have room (as
    imagecorruptions-imaug 1.1.5 does); frost's grain therefore grows with the image
    beyond the texture's size. With a severity size, the texture is scaled as for the
    image at the severity size, times its ``scale`` (:func:`scaled_size`), and only the crop
    is resampled (:func:`scaled_crop`): the grain is the same share of the image at any size.

    Between integer levels: ``a`` and ``b`` linear. The texture and the crop are drawn the
    same way at every level (the level does not choose the texture), so a decimal level
    changes only the blend weights.

    Raises :class:`FrostTextureError` if the ``imagecorruptions-imaug`` textures are not
    installed.
    """
    height, width = x.shape[:2]
    index = int(rng.integers(len(TEXTURES)))
    if scale is not None and scale != 1:  # at 1, the enlarged texture is the tabulated one
        return _blend(x, scaled_crop(index, (height, width), scale, rng), blend_table(level))
    tex = scaled_texture(index, (height, width))
    top = int(rng.integers(0, tex.shape[0] - height))
    left = int(rng.integers(0, tex.shape[1] - width))
    crop = tex[top:top + height, left:left + width]
    return _blend(x, crop, blend_table(level))


def scaled_crop(index: int, image_hw: tuple[int, int], scale: float, rng: np.random.Generator) -> np.ndarray:
    """The H x W crop of texture ``index`` enlarged to :func:`scaled_size` at a severity
    size's ``scale``, its offsets drawn as :func:`frost` draws them; only the crop is
    resampled (:func:`~._exact.resize_cubic` of that window: the same bytes as the crop of
    the whole enlarged texture, on any CPU): the enlarged texture of a
    large frame would be several hundred MB per texture. RGB, read-only."""
    height, width = image_hw
    bgr = texture_bgr(index)
    tw, th = scaled_size(bgr.shape[:2], image_hw, scale)
    top = int(rng.integers(0, th - height))
    left = int(rng.integers(0, tw - width))
    crop = resize_cubic(bgr, (tw, th), (top, left, height, width))
    return np.ascontiguousarray(crop[..., ::-1])
