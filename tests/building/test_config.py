"""Build configurations: presets, the user's YAML, flags, and strict checking."""

from __future__ import annotations

import pytest

from robodepth_cli.building.config import CONFIG_DIR, ConfigError, presets, resolve
from robodepth_cli.corruptions import NAMES


def test_presets():
    assert {"kitti-c", "kitti-c-hr", "nyudepth2-c"} <= set(presets())
    kc = resolve("kitti-c")
    assert (kc.dataset, kc.split, kc.size, kc.variants, kc.levels, kc.jobs, kc.limit) == (
        "kitti-c", "eigen_test", (192, 640), NAMES, (1, 2, 3, 4, 5), 2, None)
    hr = resolve("kitti-c-hr")
    assert (hr.dataset, hr.size, hr.variants, hr.levels) == ("kitti-c", (320, 1024), NAMES, (1, 2, 3, 4, 5))
    ny = resolve("nyudepth2-c")
    assert (ny.dataset, ny.split, ny.size, ny.levels) == ("nyudepth2-c", "nyu_test", (480, 640), (1, 2, 3, 4))
    assert ny.variants == tuple(n for n in NAMES if n not in ("fog", "frost", "snow"))


def test_flags_override_the_preset(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = resolve("kitti-c", flags={"corruptions": "contrast,brightness", "levels": "3,1", "size": "64x96",
                                    "jobs": "1", "seed": "5", "limit": "2", "split": "my.txt"})
    assert cfg.variants == ("contrast", "brightness")  # the order given
    assert (cfg.levels, cfg.size, cfg.jobs, cfg.seed, cfg.limit) == ((1, 3), (64, 96), 1, 5, 2)
    assert cfg.split == "my.txt"  # as typed: messages show what the user wrote


def test_user_file_over_preset_and_flags_over_file(tmp_path):
    sub = tmp_path / "conf"
    sub.mkdir()
    f = sub / "mine.yaml"
    f.write_text("dataset: kitti-c\nsplit: ../lists/few.txt\ncorruptions: [dark, contrast]\nlevels: 2\n"
                 "size: [96, 320]\nseed: 11\njobs: 3\n")
    cfg = resolve("kitti-c", f, {"seed": "12", "corruptions": None})
    assert cfg.split == str(sub / ".." / "lists" / "few.txt")  # relative to the YAML file
    assert (cfg.variants, cfg.levels, cfg.size, cfg.seed, cfg.jobs) == (("dark", "contrast"), (2,), (96, 320), 12, 3)
    assert resolve("kitti-c-hr", f).size == (96, 320)  # the file wins over the preset it is applied to


@pytest.mark.parametrize("text, expected", [
    ("levles: [1]\n", "unknown key 'levles'; valid keys: dataset, split, size, levels, seed, jobs, limit, png, corruptions"),
    ("seed: abc\n", ": seed: expected an integer >= 0, got 'abc'"),
    ("seed: true\n", ": seed: expected an integer >= 0, got True"),
    ("jobs: 0\n", ": jobs: expected an integer >= 1, got 0"),
    ("corruptions: [fog, fgo]\n", ": corruptions: unknown corruption 'fgo'; valid: brightness, dark, fog,"),
    ("corruptions: []\n", ": corruptions: expected a non-empty list or 'all', got []"),
    ("corruptions: brightness\nlevels: [0, 1]\n", ": levels: level 0 is out of range for kitti-c; valid levels: 1..5"),
    ("corruptions: brightness\nlevels: [1, 6]\n", ": levels: level 6 is out of range for kitti-c; valid levels: 1..5"),
    ("size: 192\n", ": size: expected HxW such as 192x640, or [H, W], got 192"),
    ("size: 16x640\n", ": size: size '16x640': both sides must be at least 32"),
    ("split: nyu_test\n", ": split: 'nyu_test' is not a split of kitti-c; valid: eigen_test, kitti_sequences or a split file"),
    ("split: 3\n", ": split: expected a standard split name or a file, got 3"),
    ("dataset: nyudepth2-c\n", ": dataset: 'nyudepth2-c' does not match 'kitti-c'"),
    ("dataset: kitti-x\n", ": dataset: unknown dataset 'kitti-x'; valid: kitti-c, nyudepth2-c"),
    ("seed: [1\n", ": not valid YAML (line 2, column 1:"),
    ("- seed\n", ": expected a mapping of keys to values, got list"),
])
def test_bad_values_name_file_key_and_choices(tmp_path, text, expected):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError) as err:
        resolve("kitti-c", f)
    assert str(err.value).startswith(str(f))
    assert expected in str(err.value)


@pytest.mark.parametrize("flags, expected", [
    ({"corruptions": "brightness,nope"}, "--corruptions: unknown corruption 'nope'; valid: brightness,"),
    ({"corruptions": "contrast", "levels": "1,x"}, "--levels: 'x' is not a number; levels are 1..5"),
    ({"jobs": "0"}, "--jobs: expected an integer >= 1, got 0"),
    ({"size": "640"}, "--size: size '640' is not of the form HxW"),
    ({"limit": "0"}, "--limit: expected an integer >= 1, got 0"),
    # Text that only looks like an integer to a digit test (int() refuses it) is refused,
    # not a traceback.
    ({"seed": "--5"}, "--seed: expected an integer >= 0, got '--5'"),
    ({"jobs": "\u00b2"}, "--jobs: expected an integer >= 1, got '\u00b2'"),
])
def test_bad_flags_name_the_flag(flags, expected):
    with pytest.raises(ConfigError) as err:
        resolve("kitti-c", flags=flags)
    assert str(err.value).startswith(expected)


def test_unknown_preset():
    with pytest.raises(ConfigError, match="unknown dataset 'kitti'; valid: .*kitti-c, kitti-c-hr, kitti-s, nyudepth2-c"):
        resolve("kitti")


def test_presets_use_only_known_keys():
    """Each preset sets every key, so a user's file only needs what it changes."""
    for p in ("kitti-c", "kitti-c-hr", "nyudepth2-c"):
        text = (CONFIG_DIR / f"{p}.yaml").read_text()
        for key in ("dataset", "split", "size", "corruptions", "levels", "seed", "jobs", "limit"):
            assert f"\n{key}:" in "\n" + text, (p, key)


def test_cli_config_error_is_one_line_exit_2(tmp_path, cli):
    f = tmp_path / "bad.yaml"
    f.write_text("corruptions: [snow, sleet]\n")
    res = cli("build", "kitti-c", "--root", tmp_path, "--out", tmp_path / "o", "--config", f)
    assert res.exit_code == 2
    assert res.output.startswith(f"robodepth: error: {f}: corruptions: unknown corruption 'sleet'; valid: ")
    assert len(res.output.strip().splitlines()) == 1 and "Traceback" not in res.output
    assert not (tmp_path / "o").exists()


def test_presets_and_split_records_ship_inside_a_wheel(tmp_path):
    """`pip install .` (not only the editable `make install`) must find configs/ and splits/."""
    import subprocess
    import sys
    import zipfile

    from tests.helpers.paths import REPO

    import shutil

    # Built from a copy: a build writes build/ and *.egg-info next to its sources.
    src = tmp_path / "src"
    for name in ("robodepth_cli", "configs", "splits"):
        shutil.copytree(REPO / name, src / name, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, src / name)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                    "-q", "-w", str(tmp_path), str(src)], check=True, capture_output=True)
    (wheel,) = tmp_path.glob("robodepth_cli-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {"robodepth_cli/configs/kitti-c.yaml", "robodepth_cli/configs/kitti-c-hr.yaml",
            "robodepth_cli/configs/nyudepth2-c.yaml", "robodepth_cli/configs/kitti-s.yaml",
            "robodepth_cli/splits/splits.json", "robodepth_cli/report/published/kitti-c.csv",
            "robodepth_cli/report/published/nyudepth2-c.csv",
            "robodepth_cli/report/published/kitti-s.csv",
            "robodepth_cli/report/published/README.md"} <= names
    # Every module of the source tree, subpackages included (the package list is explicit).
    modules = {p.relative_to(REPO).as_posix() for p in (REPO / "robodepth_cli").rglob("*.py")
               if "__pycache__" not in p.parts}
    assert modules - names == set()
