"""One depth map from a file, in metres, for the depth-aware corruptions of ``corrupt`` and
``preview`` (``--depth FILE``).

- ``.npy``: a 2-D array of metres (float or integer), read without pickles;
- ``.png``: a 16-bit single-channel PNG whose values divided by ``--depth-scale`` are metres
  (256 for KITTI's depth maps, 1000 for millimetres as NYU's ``sync_depth`` files).

Zero, NaN and inf mark missing values and come back as NaN; the corruption fills them
(docs/depth-aware-corruptions.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import RobodepthError, os_reason


class DepthFileError(RobodepthError):
    """A depth file that cannot be read as metres."""


def read_depth(path: str | Path, scale: float | None = None) -> np.ndarray:
    """The depth map in ``path`` as float64 metres, NaN where missing.
    :class:`DepthFileError` naming the file otherwise."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            if scale is not None:
                raise DepthFileError(f"{path}: --depth-scale is for 16-bit PNGs; a .npy holds metres")
            d = np.load(path, allow_pickle=False)
        elif suffix == ".png":
            d = _png(path, scale)
        else:
            raise DepthFileError(f"{path}: a depth map is a .npy of metres or a 16-bit .png "
                                 f"(with --depth-scale)")
    except OSError as exc:
        raise DepthFileError(f"{path}: cannot read the depth map ({os_reason(exc)})") from None
    except ValueError as exc:
        if isinstance(exc, RobodepthError):
            raise
        raise DepthFileError(f"{path}: not a depth map ({exc})") from None
    if d.ndim == 3 and d.shape[2] == 1:
        d = d[:, :, 0]
    if d.ndim != 2 or d.size == 0 or not (np.issubdtype(d.dtype, np.integer) or np.issubdtype(d.dtype, np.floating)):
        raise DepthFileError(f"{path}: expected an H x W array of numbers, got {d.dtype} {d.shape}")
    d = d.astype(np.float64)
    d[~np.isfinite(d) | (d <= 0)] = np.nan
    return d


def _png(path: Path, scale: float | None) -> np.ndarray:
    from PIL import Image, UnidentifiedImageError

    if scale is None:
        raise DepthFileError(f"{path}: a 16-bit PNG needs --depth-scale (256 for KITTI, "
                             f"1000 for millimetres)")
    if not (np.isfinite(scale) and scale > 0):
        raise DepthFileError(f"--depth-scale {scale}: expected a number > 0")
    try:
        with Image.open(path) as im:
            if im.mode not in ("I;16", "I;16B", "I"):
                raise DepthFileError(f"{path}: a {im.mode} PNG; a depth map is a 16-bit single-channel PNG")
            d = np.asarray(im, dtype=np.float64)
    except UnidentifiedImageError:
        raise DepthFileError(f"{path}: not a PNG image") from None
    return d / float(scale)
