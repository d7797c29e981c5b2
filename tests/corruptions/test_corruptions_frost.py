"""frost beyond the statistics of test_fidelity.py: texture files found without importing
their package, a clear error without it, and pixel agreement with the imagecorruptions oracle
when both make the same texture and crop choice; the texture's bicubic resize is OpenCV's
fixed-point formula computed exactly."""

from __future__ import annotations

import subprocess
import sys
from importlib import metadata

import numpy as np
import pytest
from PIL import Image

import robodepth_cli.corruptions.frost as fr
from tests.helpers.paths import REFERENCE


class ScriptedRng:
    """Stands in for the generator: hands out given integers and records the calls."""

    def __init__(self, values):
        self.values = list(values)
        self.calls = []

    def integers(self, *args):
        self.calls.append(args)
        return self.values.pop(0)


def _input(folder: str, key: str) -> np.ndarray:
    with Image.open(REFERENCE / folder / f"{key}__input.png") as im:
        return np.asarray(im.convert("RGB")).copy()


def test_textures_found_without_importing_the_package():
    code = (
        "import sys\n"
        "from robodepth_cli.corruptions import frost\n"
        "paths = [frost.texture_path(i) for i in range(5)]\n"
        "assert [p.name for p in paths] == list(frost.TEXTURES), paths\n"
        "assert all(p.is_file() for p in paths)\n"
        "frost.texture_bgr(0)\n"
        "assert 'imagecorruptions' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_missing_package_gives_an_install_hint(monkeypatch):
    def missing(name):
        raise metadata.PackageNotFoundError(name)

    fr.texture_path.cache_clear()
    monkeypatch.setattr(fr.metadata, "distribution", missing)
    try:
        with pytest.raises(fr.FrostTextureError, match="make install"):
            fr.texture_path(2)
    finally:
        fr.texture_path.cache_clear()


@pytest.mark.parametrize("folder,key", [("kitti", "kitti_like_md2"), ("nyu", "nyu_1")])
@pytest.mark.parametrize("texture", range(5))
def test_matches_oracle_for_the_same_texture_and_crop(folder, key, texture, opencv_reference_path):
    import imagecorruptions

    x = _input(folder, key)
    level = 1 + texture % 5
    # A seed for which the oracle picks this texture, and the crop it then draws.
    seed = next(s for s in range(1000) if np.random.RandomState(s).randint(6) == texture)
    width, height = fr.scaled_size(fr.texture_bgr(texture).shape[:2], x.shape[:2])
    replay = np.random.RandomState(seed)
    replay.randint(6)
    top = replay.randint(0, height - x.shape[0])
    left = replay.randint(0, width - x.shape[1])
    np.random.seed(seed)
    ref = imagecorruptions.corrupt(x, severity=level, corruption_name="frost")

    rng = ScriptedRng([texture, top, left])
    ours = fr.frost(x, level, rng)
    assert rng.calls == [(5,), (0, height - x.shape[0]), (0, width - x.shape[1])]
    # The oracle resizes the texture with OpenCV, whose SIMD vertical pass rounds a float
    # sum and lands one level off the fixed-point formula on about 1 texel in 100,000.
    diff = np.abs(ours.astype(int) - ref)
    assert diff.max() <= 1 and (diff > 0).mean() < 1e-4, (diff.max(), (diff > 0).mean())


@pytest.fixture
def opencv_reference_path():
    """OpenCV without IPP, whose resize (on ~4 % of texels one level off) depends on the CPU."""
    import cv2

    cv2.ipp.setUseIPP(False)
    yield
    cv2.ipp.setUseIPP(True)


@pytest.mark.parametrize("texture", range(5))
@pytest.mark.parametrize("image_hw", [(192, 640), (37, 53), (1024, 2048)])
def test_texture_resize_is_opencvs_fixed_point_bicubic(texture, image_hw, opencv_reference_path):
    import cv2

    bgr = fr.texture_bgr(texture)
    size = fr.scaled_size(bgr.shape[:2], image_hw)
    ours = fr.scaled_texture(texture, image_hw)[..., ::-1]
    diff = np.abs(ours.astype(int) - cv2.resize(bgr, size, interpolation=cv2.INTER_CUBIC))
    assert ours.shape[1::-1] == size
    assert diff.max() <= 1 and (diff > 0).mean() < 1e-4, (diff.max(), (diff > 0).mean())


def test_texture_resize_by_hand():
    """Columns 0, 0, 200, 200... of a 2-pixel-wide picture grown to 4 (scale 1/2). Output
    column 1 samples source 0.25: taps at sources -1..2, replicated to 0, 0, 200, 200, with
    Keys' cubic (A = -0.75) weights at distances 1.25, 0.25, 0.75, 1.75 = -0.10546875,
    0.87890625, 0.26171875, -0.03515625, i.e. -216, 1800, 536, -72 in 1/2048: the row value
    is 200 * (536 - 72) = 92800. Every row is the same, and the row weights (-72, 536, 1800,
    -216) sum to 2048, so the pixel is (92800 * 2048 + 2^21) >> 22 = 45 (45.31 rounded).
    Output column 0 (taps 0, 0, 0, 200 weighted -72, 536, 1800, -216) is negative: 0."""
    from robodepth_cli.corruptions._exact import resize_cubic

    img = np.array([[0, 200], [0, 200]], np.uint8)[:, :, None]
    out = resize_cubic(img, (4, 4))[:, :, 0]
    assert out.shape == (4, 4)
    assert out[:, 0].tolist() == [0] * 4 and out[:, 1].tolist() == [45] * 4
