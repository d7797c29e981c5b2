"""Make docs/images/severity-size.png, the figure of docs/severity-and-chains.md:

    PYTHONPATH=. python docs/images/severity_size.py

One KITTI frame of the fixtures (tests/data/fixtures) at 192 x 640 and at 10x that,
1920 x 6400 (both Lanczos from the 375 x 1242 frame), at level 3 of five spatial
corruptions: at 192 x 640; at 1920 x 6400 with ``--severity-size none``; at 1920 x 6400 with
``--severity-size 192x640``. The large ones are shrunk to 192 x 640 (area) for display.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from robodepth_cli.corruptions import render
from robodepth_cli.imageio import load_clean, write_png

HERE = Path(__file__).resolve().parent
FRAME = (HERE.parents[1] / "tests" / "data" / "fixtures" / "kitti_raw" / "2011_09_26"
         / "2011_09_26_drive_0002_sync" / "image_02" / "data" / "0000000069.png")
NAMES = ("defocus_blur", "motion_blur", "glass_blur", "snow", "frost")
SMALL, LARGE = (192, 640), (1920, 6400)
COLUMNS = ("192 x 640", "1920 x 6400, severity size none", "1920 x 6400, severity size 192x640")
LABEL_W, HEAD_H, PAD = 110, 18, 4


def cell(clean: np.ndarray, name: str, severity_size) -> np.ndarray:
    out = render(clean, name, 3, seed=0, dataset="image", key=FRAME.name, severity_size=severity_size)
    if out.shape[:2] != SMALL:
        out = cv2.resize(out, (SMALL[1], SMALL[0]), interpolation=cv2.INTER_AREA)
    return out


def main() -> None:
    small, large = (load_clean(FRAME, size) for size in (SMALL, LARGE))
    rows = [("clean", [small, cv2.resize(large, (SMALL[1], SMALL[0]), interpolation=cv2.INTER_AREA),
                       None])]
    for name in NAMES:
        rows.append((name, [cell(small, name, None), cell(large, name, None), cell(large, name, SMALL)]))
    w = LABEL_W + 3 * (SMALL[1] + PAD) + PAD
    h = HEAD_H + len(rows) * (SMALL[0] + PAD) + PAD
    sheet = Image.new("RGB", (w, h), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    font = ImageFont.load_default()
    for j, title in enumerate(COLUMNS):
        draw.text((LABEL_W + j * (SMALL[1] + PAD) + PAD, 3), title, fill=(20, 20, 20), font=font)
    for i, (name, cells) in enumerate(rows):
        y = HEAD_H + i * (SMALL[0] + PAD)
        draw.text((PAD, y + SMALL[0] // 2 - 12), name, fill=(20, 20, 20), font=font)
        draw.text((PAD, y + SMALL[0] // 2 + 2), "level 3" if i else "", fill=(110, 110, 110), font=font)
        for j, img in enumerate(cells):
            if img is not None:
                sheet.paste(Image.fromarray(img), (LABEL_W + j * (SMALL[1] + PAD) + PAD, y))
    write_png(HERE / "severity-size.png", np.asarray(sheet))


if __name__ == "__main__":
    main()
