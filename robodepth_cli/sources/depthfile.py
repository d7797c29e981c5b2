"""One depth map from a file, in metres, for the depth-aware corruptions of ``corrupt`` and
``preview`` (``--depth FILE``) and a build's scene depth: :func:`.depth_io.read_depth`, with
the two flags' rules.

- ``.npy``: a 2-D array, read without pickles: floats are metres, integers are divided by
  ``--depth-scale``;
- ``.png``: a 16-bit single-channel PNG whose values divided by ``--depth-scale`` are metres
  (256 for KITTI's depth maps, 1000 for millimetres as NYU's ``sync_depth`` files).

``--depth-scale`` follows the scale rule of :mod:`.depth_io`: required for integer maps,
refused for float ones.

Zero, NaN and inf mark missing values and come back as NaN; the corruption fills them
(docs/depth-aware-corruptions.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .depth_io import DepthError, read_depth as read_any


class DepthFileError(DepthError):
    """A depth file that cannot be read as metres."""


def read_depth(path: str | Path, scale: float | None = None) -> np.ndarray:
    """The depth map in ``path`` as float64 metres, NaN where missing.
    :class:`DepthFileError` (or :class:`DepthError`) naming the file otherwise."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".npy", ".png"):
        raise DepthFileError(f"{path}: a depth map is a .npy of metres or a 16-bit .png "
                             f"(with --depth-scale)")
    depth = read_any(path, scale=scale).astype(np.float64)
    if not np.isfinite(depth).any():
        # A build fails such a map's image; a corruption would take it as 1 km away.
        raise DepthFileError(f"{path}: no valid depth (every pixel is 0, negative, NaN or "
                             "infinite)")
    return depth
