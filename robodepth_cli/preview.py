"""Contact sheets: the picture a person looks at to judge the corruptions."""

from __future__ import annotations

from typing import Iterable

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from .corruptions import REGISTRY, corrupt
from .seeding import job_rng

_BG = (255, 255, 255)
_FG = (20, 20, 20)
_PAD = 4


def contact_sheet(clean: np.ndarray, names: Iterable[str], levels: Iterable[int], *,
                  seed: int = 0, key: str = "image", thumb_width: int = 320) -> Image.Image:
    """One row per corruption (label, then one cell per level) under a first row holding the
    clean image. Cells are the corrupted images scaled to ``thumb_width`` pixels wide."""
    names, levels = list(names), list(levels)
    h, w = clean.shape[:2]
    tw = min(thumb_width, w)
    th = max(1, round(h * tw / w))
    font = ImageFont.load_default()
    label_w = 150
    head_h = 18
    cols = len(levels)
    sheet_w = label_w + cols * (tw + _PAD) + _PAD
    sheet_h = head_h + (len(names) + 1) * (th + _PAD) + _PAD
    sheet = Image.new("RGB", (sheet_w, sheet_h), _BG)
    draw = ImageDraw.Draw(sheet)

    def thumb(img: np.ndarray) -> Image.Image:
        return Image.fromarray(img).resize((tw, th), Image.BILINEAR)

    for j, level in enumerate(levels):
        draw.text((label_w + j * (tw + _PAD) + _PAD, 3), f"level {level}", fill=_FG, font=font)
    y = head_h
    draw.text((_PAD, y + th // 2 - 6), "clean", fill=_FG, font=font)
    sheet.paste(thumb(clean), (label_w + _PAD, y))
    for name in names:
        y += th + _PAD
        c = REGISTRY[name]
        draw.text((_PAD, y + th // 2 - 12), name, fill=_FG, font=font)
        draw.text((_PAD, y + th // 2 + 2), c.category, fill=(110, 110, 110), font=font)
        for j, level in enumerate(levels):
            if level > c.n_levels:
                continue
            out = corrupt(clean, name, level, job_rng(seed, "preview", name, level, key))
            sheet.paste(thumb(out), (label_w + j * (tw + _PAD) + _PAD, y))
    return sheet
