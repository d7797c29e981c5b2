import io

import numpy as np
from PIL import Image

from .registry import register
from .severity import ROUND, interpolate

LEVELS = (25, 18, 15, 10, 7)


@register(("quality",), LEVELS, rules=(ROUND,), deterministic=True)
def jpeg_compression(x: np.ndarray, level: int, rng: np.random.Generator) -> np.ndarray:
    """Encode as JPEG at ``quality`` with Pillow's defaults (4:2:0 chroma subsampling,
    standard tables) and decode again.

    Between integer levels: ``quality`` linear, rounded to the nearest integer (halves up):
    level 1.5 encodes at quality 22 (21.5 rounded)."""
    quality = interpolate(LEVELS, level, (ROUND,))
    buf = io.BytesIO()
    Image.fromarray(x).save(buf, format="JPEG", quality=quality)
    buf.seek(0)
    with Image.open(buf) as im:
        return np.asarray(im.convert("RGB")).copy()
