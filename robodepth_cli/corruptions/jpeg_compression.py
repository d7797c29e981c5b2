import io

import numpy as np
from PIL import Image

from .registry import register

LEVELS = (25, 18, 15, 10, 7)


@register(("quality",), LEVELS, deterministic=True)
def jpeg_compression(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Encode as JPEG at ``quality`` with Pillow's defaults (4:2:0 chroma subsampling,
    standard tables) and decode again."""
    quality = LEVELS[level - 1]
    buf = io.BytesIO()
    Image.fromarray(x).save(buf, format="JPEG", quality=quality)
    buf.seek(0)
    with Image.open(buf) as im:
        return np.asarray(im.convert("RGB")).copy()
