"""Each benchmark's own corruptions and levels, and the light module that states them."""

from __future__ import annotations


import pytest

from robodepth_cli.building.config import ConfigError, resolve

from tests.helpers.imports import imported_by_command
from tests.helpers.trees import nyu_tree, tree

# Retyped from the benchmark's definition: every corruption in order, and NYUDepth2-C's
# subset (all but fog, frost and snow) at levels 1..4.
ALL_18 = ("brightness dark fog frost snow contrast defocus_blur glass_blur motion_blur zoom_blur "
          "elastic_transform color_quant gaussian_noise impulse_noise shot_noise iso_noise pixelate "
          "jpeg_compression").split()
NYU_15 = [n for n in ALL_18 if n not in ("fog", "frost", "snow")]


@pytest.mark.parametrize("flags", [{}, {"corruptions": "all", "levels": "all"}])
def test_nyu_all_means_its_own_15_corruptions_and_4_levels(flags):
    cfg = resolve("nyudepth2-c", flags=flags)
    assert list(cfg.variants) == NYU_15
    assert cfg.levels == (1, 2, 3, 4)


def test_kitti_all_means_18_corruptions_and_5_levels():
    cfg = resolve("kitti-c", flags={"corruptions": "all", "levels": "all"})
    assert list(cfg.variants) == ALL_18
    assert cfg.levels == (1, 2, 3, 4, 5)


DEPTH_AWARE_6 = ["fog_3d", "near_focus", "far_focus", "motion_3d", "zoom_3d", "rain_3d"]


@pytest.mark.parametrize("flags,message", [
    ({"levels": "5"}, "--levels: level 5 is out of range for nyudepth2-c; valid levels: 1..4"),
    ({"levels": "2,5"}, "--levels: level 5 is out of range for nyudepth2-c; valid levels: 1..4"),
    # NYU has depth, so the depth-aware corruptions are valid there after the benchmark's 15.
    ({"corruptions": "fog"}, "--corruptions: nyudepth2-c has no corruption 'fog'; valid: "
                             + ", ".join(NYU_15 + DEPTH_AWARE_6)),
    ({"corruptions": "dark,snow"}, "--corruptions: nyudepth2-c has no corruption 'snow'; valid: "
                                   + ", ".join(NYU_15 + DEPTH_AWARE_6)),
])
def test_nyu_refuses_what_it_does_not_have(flags, message):
    with pytest.raises(ConfigError) as err:
        resolve("nyudepth2-c", flags=flags)
    assert str(err.value) == message


def test_nyu_config_file_outside_the_set_names_the_file(tmp_path):
    f = tmp_path / "mine.yaml"
    f.write_text("corruptions: [frost]\n")
    with pytest.raises(ConfigError, match=f"^{f}: corruptions: nyudepth2-c has no corruption 'frost'; valid: brightness, dark, contrast,"):
        resolve("nyudepth2-c", f)


def test_nyu_build_with_level_5_is_refused_before_any_work(tmp_path, cli):
    root = tmp_path / "nyu"
    split = nyu_tree(root, ["bathroom/rgb_00045.jpg"])
    out = tmp_path / "out"
    res = cli("build", "nyudepth2-c", "--root", root, "--split", split, "--out", out,
              "--corruptions", "contrast", "--levels", "all", "--jobs", "1")
    assert res.exit_code == 0, res.output
    assert sorted(p.split("/")[1] for p in tree(out) if p.startswith("contrast/")) == ["1", "2", "3", "4"]

    res = cli("build", "nyudepth2-c", "--root", root, "--split", split, "--out", tmp_path / "out5",
              "--levels", "5")
    assert res.exit_code == 2
    assert res.output.strip() == ("robodepth: error: --levels: level 5 is out of range for nyudepth2-c; "
                                  "valid levels: 1..4")
    assert not (tmp_path / "out5").exists()


def test_score_does_not_load_the_corruption_engine(tmp_path):
    """Scoring a CSV needs the benchmark facts only, not numba or OpenCV (slow to import)."""
    rows = ["corruption,level,dee", "clean,0,0.1"]
    rows += [f"{n},{lv},0.2" for n in NYU_15 for lv in range(1, 5)]
    results = tmp_path / "r.csv"
    results.write_text("\n".join(rows) + "\n")
    argv = ["score", results, "--benchmark", "nyudepth2-c", "--json"]
    heavy = ["numba", "cv2", "torch", "robodepth_cli.corruptions"]
    assert imported_by_command(argv, heavy, stdout_has='"mce"') == []
