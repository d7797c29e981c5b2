"""`robodepth_cli.torch.KittiC(..., frames=...)`: the neighbour frames of a --frames build."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from robodepth_cli.torch import KittiC, TorchAPIError

from tests.helpers.trees import kitti_key


@pytest.fixture
def built(frames_build):
    return frames_build


def test_items_hold_the_neighbours_in_order(built):
    ds = KittiC(built, "fog", 2, frames=(1, -1))
    item = ds[1]  # test frame 2
    assert item["key"] == kitti_key(2)
    want = [np.asarray(Image.open(built / "fog/2" / kitti_key(n))) for n in (3, 1)]
    assert [n.permute(1, 2, 0).numpy().tolist() for n in item["neighbours"]] == [w.tolist() for w in want]
    # Test frame 0 has no frame -1: black.
    first = ds[0]["neighbours"]
    assert first[0].any() and not first[1].any()


def test_frames_need_a_build_with_them(built, tmp_path):
    with pytest.raises(TorchAPIError, match=r"no neighbour frames at -2 \(build it with --frames -2\)"):
        KittiC(built, "fog", 2, frames=(-2,))
    with pytest.raises(TorchAPIError, match="read from the build"):
        KittiC(built, "fog", 2, on_the_fly=True, frames=(-1,))
