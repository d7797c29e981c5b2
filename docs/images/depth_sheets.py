"""Make the contact sheets of docs/depth-aware-corruptions.md:

    PYTHONPATH=. python docs/images/depth_sheets.py

The fixture frames (tests/data/fixtures) carry no depth that matches their pictures (the
NYU sync_depth PNGs and the KITTI scans there are synthetic, made for other tests), so each
frame gets a depth map built here by hand from its visible geometry, in metres: planes and
boxes with the camera's focal length and height. Each sheet is ``robodepth preview`` with
that depth; depth-aware-depths.png shows the two maps (near = bright, inverse depth).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from robodepth_cli.imageio import load_clean, write_png
from robodepth_cli.preview import contact_sheet

HERE = Path(__file__).resolve().parent
FIXTURES = HERE.parents[1] / "tests" / "data" / "fixtures"
NAMES = ("fog_3d", "near_focus", "far_focus", "motion_3d", "zoom_3d", "rain_3d")


def polygon_mask(shape, points) -> np.ndarray:
    im = Image.new("L", (shape[1], shape[0]), 0)
    ImageDraw.Draw(im).polygon(points, fill=1)
    return np.asarray(im, bool)


def kitti_depth(h: int = 192, w: int = 640) -> np.ndarray:
    """The street of the KITTI-layout frame at 192 x 640: a road plane seen from 1.65 m
    (KITTI's camera height) with KITTI's focal length scaled to this size (fy = 369 px),
    horizon at row 74; the sea wall and its walkers standing 28 m away; the car a box about
    7 m away; the left house fronts 25-60 m; the skyline and sky 600 m."""
    fy, height, horizon = 721.5 * h / 375, 1.65, 74.0
    y = np.arange(h, dtype=np.float64)[:, None] + np.zeros((1, w))
    x = np.zeros((h, 1)) + np.arange(w)[None, :]
    with np.errstate(divide="ignore"):
        ground = np.where(y > horizon, fy * height / (y - horizon), np.inf)
    d = np.minimum(ground, 600.0)
    wall = (x > 275) & (y < 96) & (y > 78)
    d[wall] = np.minimum(d[wall], 28.0)
    houses = x < 100 - 0.5 * (y - 10).clip(0)  # the row of house fronts along the left
    d[houses & (y < 90)] = np.minimum(d[houses & (y < 90)], 25.0 + 0.35 * x[houses & (y < 90)])
    car = polygon_mask((h, w), [(166, 76), (285, 74), (300, 100), (338, 108), (338, 150),
                                (318, 162), (150, 162), (136, 128), (140, 100), (160, 96)])
    # the car's body recedes from its front (right, 6.5 m) to its rear (left, 8 m)
    d[car] = (8.0 - 1.5 * (x[car] - 136) / 202)
    return d.astype(np.float32)


def nyu_depth(h: int = 480, w: int = 640) -> np.ndarray:
    """The bedroom of NYU frame 119 (fx = fy = 519 px, NYU's): two walls meeting 4.2 m away
    in the corner at column 300, 2.6 m at the left edge and 2.4 m at the right; a floor seen
    from 1.4 m (horizon row 175); the bed a slab from 2.0 m (footboard) to 3.5 m
    (headboard); the picture leaning on the right wall, 0.15 m in front of it."""
    y = np.arange(h, dtype=np.float64)[:, None] + np.zeros((1, w))
    x = np.zeros((h, 1)) + np.arange(w)[None, :]
    inv_left = 1 / 2.6 + (1 / 4.2 - 1 / 2.6) * x / 300  # planes: inverse depth is affine
    inv_right = 1 / 4.2 + (1 / 2.4 - 1 / 4.2) * (x - 300) / 340
    wall = 1 / np.where(x < 300, inv_left, inv_right)
    with np.errstate(divide="ignore"):
        floor = np.where(y > 175, 519 * 1.4 / (y - 175), np.inf)
    d = np.minimum(wall, floor)
    bed = polygon_mask((h, w), [(27, 173), (260, 147), (460, 273), (480, 273), (473, 473),
                                (253, 473), (40, 387)])
    d[bed] = 1 / (1 / 3.5 + (1 / 2.0 - 1 / 3.5) * (y[bed] - 147) / 326)
    picture = polygon_mask((h, w), [(527, 213), (640, 220), (640, 373), (527, 347)])
    d[picture] = wall[picture] - 0.15
    return d.astype(np.float32)


def main() -> None:
    frames = [
        ("kitti", FIXTURES / "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png",
         (192, 640), kitti_depth(), 320),
        ("nyu", FIXTURES / "nyu/bedroom/rgb_00119.jpg", None, nyu_depth(), 320),
    ]
    views = []
    for name, path, size, depth, thumb in frames:
        clean = load_clean(path, size)
        # Drawn as these figures always were (dataset "preview", the file's name), not as
        # robodepth preview now draws (the pixels' key): the figures keep their bytes.
        sheet = contact_sheet(clean, NAMES, range(1, 6), dataset="preview", key=path.name,
                              thumb_width=thumb, depth=depth)
        write_png(HERE / f"depth-aware-{name}.png", np.asarray(sheet), 9)
        inv = 1 / depth
        view = (255 * (inv - inv.min()) / (inv.max() - inv.min())).astype(np.uint8)
        views.append(Image.fromarray(np.concatenate([clean, np.repeat(view[:, :, None], 3, 2)], 1)))
    width = max(v.width for v in views)
    views = [v.resize((width, round(v.height * width / v.width))) for v in views]
    both = np.concatenate([np.asarray(v) for v in views], 0)
    write_png(HERE / "depth-aware-depths.png", np.asarray(Image.fromarray(both).resize((width // 2, both.shape[0] // 2))), 9)


if __name__ == "__main__":
    main()
