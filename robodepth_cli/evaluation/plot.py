"""Bar chart of CE per corruption against the baseline's 100% line, drawn with Pillow.

matplotlib is deliberately not a dependency; the chart is simple enough for ImageDraw.
Horizontal bars keep the corruption names horizontal (Pillow's default font cannot be
drawn rotated without a detour through a rotated image) and readable.
"""

from __future__ import annotations

import math

from PIL import Image, ImageDraw, ImageFont

from ..benchmarks import CATEGORIES
from .scores import Scores

# One colour per category, in CATEGORIES order (colour-blind-safe Okabe-Ito hues).
COLOURS = {cat: c for cat, c in zip(CATEGORIES, ((0, 114, 178), (230, 159, 0), (0, 158, 115)))}
BACKGROUND = (255, 255, 255)
INK = (30, 30, 30)
GRID = (225, 225, 225)
MUTED = (130, 130, 130)

WIDTH = 960
LABEL_W = 170  # corruption names
VALUE_W = 70  # numbers right of the bars
MARGIN = 20
BAR_H = 18
BAR_GAP = 6
HEAD_H = 26  # category heading row
FONT_SIZE = 14


def _font(size: int = FONT_SIZE):
    return ImageFont.load_default(size=size)


def axis_max(values: list[float]) -> float:
    """Right end of the CE axis: the next multiple of 25 above the largest CE, at least 125,
    so the 100% line and some room past the longest bar are always on the chart."""
    top = max(values, default=0.0)
    return max(125.0, 25.0 * (math.floor(top / 25.0) + 1))


def _tick_step(xmax: float) -> float:
    for step in (25.0, 50.0, 100.0, 250.0, 500.0):
        if xmax / step <= 8:
            return step
    return 10 ** math.ceil(math.log10(xmax / 8))


def ce_chart(s: Scores) -> Image.Image:
    """Render ``s`` as an RGB image: one bar per corruption (CE in percent), grouped and
    coloured by category, a dashed line at the baseline's 100%, values at the bar ends."""
    font, small, big = _font(), _font(FONT_SIZE - 2), _font(FONT_SIZE + 3)
    ces = [c.ce for c in s.corruptions if c.ce is not None]
    xmax = axis_max(ces)
    plot_x0 = MARGIN + LABEL_W
    plot_x1 = WIDTH - MARGIN - VALUE_W
    title_h = 68
    rows_h = sum(HEAD_H + sum(BAR_H + BAR_GAP for c in s.corruptions if c.category == cat)
                 for cat in CATEGORIES)
    axis_h = 40
    height = MARGIN + title_h + rows_h + axis_h + MARGIN
    img = Image.new("RGB", (WIDTH, height), BACKGROUND)
    draw = ImageDraw.Draw(img)

    def x_of(v: float) -> int:
        return round(plot_x0 + (plot_x1 - plot_x0) * min(v, xmax) / xmax)

    o = s.overall
    summary = "  ".join(f"{k} {v:.2f}" for k, v in (("mCE", o.ce), ("mRR", o.rr)) if v is not None)
    draw.text((MARGIN, MARGIN), f"Corruption error (CE, %) on {s.benchmark}", fill=INK, font=big)
    draw.text((MARGIN, MARGIN + 24),
              f"baseline {s.baseline.name} = 100%   {summary}"
              + ("   (partial)" if s.missing else ""), fill=MUTED, font=font)

    top = MARGIN + title_h
    bottom = top + rows_h
    step = _tick_step(xmax)
    ticks = [i * step for i in range(int(xmax // step) + 1)]
    for t in ticks:
        draw.line([(x_of(t), top), (x_of(t), bottom)], fill=GRID, width=1)

    y = top
    for cat, group in zip(CATEGORIES, s.categories):
        members = [c for c in s.corruptions if c.category == cat]
        colour = COLOURS[cat]
        draw.rectangle([MARGIN, y + 8, MARGIN + 10, y + 18], fill=colour)
        draw.text((MARGIN + 16, y + 5), cat, fill=INK, font=font)
        if group.ce is not None:
            draw.text((MARGIN + 16 + draw.textlength(cat, font=font) + 10, y + 6),
                      f"mean CE {group.ce:.2f}", fill=MUTED, font=small)
        y += HEAD_H
        for c in members:
            cy = y + BAR_H // 2
            draw.text((plot_x0 - 8, cy), c.name, fill=INK, font=font, anchor="rm")
            if c.ce is None:
                draw.text((plot_x0 + 4, cy), "n/a (missing)", fill=MUTED, font=small, anchor="lm")
            else:
                draw.rectangle([plot_x0, y, x_of(c.ce), y + BAR_H - 1], fill=colour)
                label = f"{c.ce:.1f}" + ("" if c.ce <= xmax else " >")
                if len(c.level_dee) < s.n_levels:
                    label += f"  ({len(c.level_dee)} of {s.n_levels} levels)"
                draw.text((x_of(c.ce) + 5, cy), label, fill=INK, font=small, anchor="lm")
            y += BAR_H + BAR_GAP

    # Baseline line over the bars, dashed so the bars stay visible through it.
    x100 = x_of(100.0)
    for y0 in range(top - 6, bottom, 8):
        draw.line([(x100, y0), (x100, min(y0 + 4, bottom))], fill=INK, width=2)
    draw.text((x100, top - 8), "baseline 100%", fill=INK, font=small, anchor="mb")

    draw.line([(plot_x0, bottom), (plot_x1, bottom)], fill=INK, width=1)
    for t in ticks:
        draw.line([(x_of(t), bottom), (x_of(t), bottom + 4)], fill=INK, width=1)
        draw.text((x_of(t), bottom + 7), f"{t:g}", fill=INK, font=small, anchor="mt")
    draw.text(((plot_x0 + plot_x1) // 2, bottom + 24), "CE (%)  lower is better",
              fill=MUTED, font=small, anchor="mt")
    return img
