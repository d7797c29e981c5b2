import numpy as np
from PIL import Image

from .registry import register
from .severity import interpolate

LEVELS = (0.6, 0.5, 0.4, 0.3, 0.25)


@register(("c",), LEVELS, deterministic=True, scaled=True)
def pixelate(x: np.ndarray, level: int, rng: np.random.Generator, scale: float | None = None) -> np.ndarray:
    """Shrink to ``(int(W * c), int(H * c))`` with Pillow's BOX filter, then enlarge back to
    W x H with NEAREST: blocks of ``1 / c`` pixels. With a severity size, the blocks are
    ``scale / c`` pixels: ``c`` is divided by its ``scale`` (at most 1: no blocks under a
    pixel).

    Between integer levels: ``c`` linear (the sizes are truncated as at every level)."""
    c = interpolate(LEVELS, level)
    if scale is not None:
        c = min(1.0, c / scale)
    h, w = x.shape[:2]
    im = Image.fromarray(x)
    small = im.resize((max(int(w * c), 1), max(int(h * c), 1)), Image.BOX)
    return np.asarray(small.resize((w, h), Image.NEAREST)).copy()
