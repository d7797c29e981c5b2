"""Contact sheets: the picture a person looks at to judge the corruptions."""

from __future__ import annotations

from typing import Iterable

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from .corruptions import REGISTRY, level_text, render
from .corruptions.chains import expand_chain, looks_like_chain, parse_chain
from .errors import RobodepthError

_BG = (255, 255, 255)
_FG = (20, 20, 20)
_PAD = 4


def contact_sheet(clean: np.ndarray, names: Iterable[str], levels: Iterable, *,
                  seed: int = 0, dataset: str = "image", key: str = "image", thumb_width: int = 320,
                  depth=None, severity_size=None) -> Image.Image:
    """One row per corruption or chain (label, then one cell per level) under a first row
    holding the clean image. Cells are the corrupted images scaled to ``thumb_width`` pixels
    wide. A chain's steps written without a level take the column's level
    (``fog+gaussian_noise``); the others keep theirs. A chain whose steps all have their
    level (``fog:3+gaussian_noise:2.5``) is the same image in every column, so it is drawn
    once, in the first column, labelled "fixed levels". Each cell is ``render`` of (``seed``,
    ``dataset``, ``key``): what ``corrupt`` writes for the same job. ``depth`` (metres) is the scene's,
    for the depth-aware corruptions; ``severity_size`` as
    :func:`~robodepth_cli.corruptions.corrupt` takes it."""
    names, levels = list(names), list(levels)
    h, w = clean.shape[:2]
    tw = min(thumb_width, w)
    th = max(1, round(h * tw / w))
    font = ImageFont.load_default()
    label_w = max([150] + [8 + 6 * len(n) for n in names if looks_like_chain(n)])
    head_h = 18
    cols = len(levels)
    sheet_w = label_w + cols * (tw + _PAD) + _PAD
    sheet_h = head_h + (len(names) + 1) * (th + _PAD) + _PAD
    sheet = Image.new("RGB", (sheet_w, sheet_h), _BG)
    draw = ImageDraw.Draw(sheet)

    def thumb(img: np.ndarray) -> Image.Image:
        return Image.fromarray(img).resize((tw, th), Image.BILINEAR)

    for j, level in enumerate(levels):
        draw.text((label_w + j * (tw + _PAD) + _PAD, 3), f"level {level_text(level)}", fill=_FG, font=font)
    y = head_h
    draw.text((_PAD, y + th // 2 - 6), "clean", fill=_FG, font=font)
    sheet.paste(thumb(clean), (label_w + _PAD, y))
    for name in names:
        y += th + _PAD
        chained = looks_like_chain(name)
        fixed = chained and _fixed(name)
        draw.text((_PAD, y + th // 2 - 12), name, fill=_FG, font=font)
        kind = ("chain, fixed levels" if fixed else "chain") if chained else REGISTRY[name].category
        draw.text((_PAD, y + th // 2 + 2), kind, fill=(110, 110, 110), font=font)
        for j, level in enumerate(levels):
            if fixed and j > 0:
                break
            job = dict(seed=seed, dataset=dataset, key=key, depth=depth, severity_size=severity_size)
            if chained:
                out = render(clean, expand_chain(name, [level])[0].text, None, **job)
            elif level <= REGISTRY[name].n_levels:
                out = render(clean, name, level, **job)
            else:
                continue
            sheet.paste(thumb(out), (label_w + j * (tw + _PAD) + _PAD, y))
    return sheet


def _fixed(chain: str) -> bool:
    """Whether every step of ``chain`` has its own level (no column's level to take)."""
    try:
        parse_chain(chain)
    except RobodepthError:
        return False
    return True
