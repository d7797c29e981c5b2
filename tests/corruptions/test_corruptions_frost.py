"""frost beyond the statistics of test_fidelity.py: texture files found without importing
their package, a clear error without it, and pixel equality with the imagecorruptions oracle
when both make the same texture and crop choice."""

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
def test_matches_oracle_for_the_same_texture_and_crop(folder, key, texture):
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
    np.testing.assert_array_equal(ours, ref)


def test_only_the_first_five_textures_are_used(monkeypatch):
    picked = []
    real = fr.scaled_texture
    monkeypatch.setattr(fr, "scaled_texture", lambda i, hw: picked.append(i) or real(i, hw))
    x = np.zeros((32, 40, 3), np.uint8)
    for s in range(60):
        fr.frost(x, 3, np.random.default_rng(s))
    assert set(picked) == {0, 1, 2, 3, 4}


def test_resized_texture_is_cached_per_shape():
    a = fr.scaled_texture(1, (192, 640))
    assert fr.scaled_texture(1, (192, 640)) is a
    assert not a.flags.writeable
    assert fr.scaled_texture(1, (480, 640)).shape != a.shape


def test_blend_table_is_the_truncated_float64_formula():
    t = fr.blend_table(2)  # a = .8, b = .6
    assert t[5, 0] == 4 and t[0, 5] == 3 and t[255, 255] == 255
    v = np.arange(256.0)
    np.testing.assert_array_equal(t[100], np.floor(np.clip(80.0 + 0.6 * v, 0, 255)))
