"""A manifest row's params cell, parsed once by the manifest's owner into its parts."""

from __future__ import annotations

import pytest

from robodepth_cli.output.manifest import Params, Row

KEY = "kitti_data/2011_09_26/2011_09_26_drive_0001_sync/image_02/data/0000000000.png"


@pytest.mark.parametrize("text,parts", [
    ("", Params()),
    ("engine=torch;severity_size=192x640", Params("engine=torch;severity_size=192x640")),
    (f"neighbour_of={KEY}", Params("", KEY)),
    (f"neighbour_of={KEY};engine=torch", Params("engine=torch", KEY)),
    ("depth=kitti-lidar:1;map=ab12", Params("depth=kitti-lidar:1", depth_stamp="ab12")),
    ("sequence=2011_09_26_drive_0001", Params(sequence="2011_09_26_drive_0001")),
    (f"neighbour_of={KEY};engine=torch;sequence=s1;map=ff", Params("engine=torch", KEY, "s1", "ff")),
])
def test_params_parse_into_their_parts_and_back(text, parts):
    assert Params.parse(text) == parts
    assert parts.text() == text
    row = Row("o.png", "s.png", "fog", 1, 0, 4, 4, "0" * 64, "", text)
    assert row.parsed == parts


def test_the_fingerprint_keeps_its_own_parts():
    assert Params.parse("engine=torch;severity_size=192x640;map=ab").parts() == ["engine=torch",
                                                                             "severity_size=192x640"]
    assert Params().parts() == []
