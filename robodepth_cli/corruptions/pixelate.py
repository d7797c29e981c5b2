import numpy as np
from PIL import Image

from .registry import register
from .severity import interpolate

LEVELS = (0.6, 0.5, 0.4, 0.3, 0.25)


@register(("c",), LEVELS, deterministic=True)
def pixelate(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Shrink to ``(int(W * c), int(H * c))`` with Pillow's BOX filter, then enlarge back to
    W x H with NEAREST.

    Between integer levels: ``c`` linear (the sizes are truncated as at every level)."""
    c = interpolate(LEVELS, level)
    h, w = x.shape[:2]
    im = Image.fromarray(x)
    small = im.resize((int(w * c), int(h * c)), Image.BOX)
    return np.asarray(small.resize((w, h), Image.NEAREST)).copy()
