"""One error path: what the user can cause is a RobodepthError subclass (a one-line refusal,
exit 2); anything else, a ValueError from a bug included, stays an exception with its
traceback instead of being dressed up as a refusal."""

from __future__ import annotations

import numpy as np
import pytest

from robodepth_cli.errors import InvalidValueError, RobodepthError
from robodepth_cli.imageio import ImageError


def _checks(tmp_path):
    from robodepth_cli import corruptions
    from robodepth_cli.benchmark_facts import get_benchmark
    from robodepth_cli.imageio import as_rgb, parse_size
    from robodepth_cli.sourcekeys import relative_parts
    from robodepth_cli.sources import splits
    from robodepth_cli.sources.custom import check_list, compile_pattern
    from robodepth_cli.sources.datasets import get_dataset, parse_eigen, parse_nyu
    from robodepth_cli.styles.inputs import check_alpha, check_option as style_option, check_style_size

    return {
        "dataset name": (lambda: get_dataset("kitti"), InvalidValueError, "unknown dataset 'kitti'"),
        "benchmark name": (lambda: get_benchmark("kitti"), InvalidValueError, "unknown benchmark 'kitti'"),
        "corruption name": (lambda: corruptions.get("fogg"), InvalidValueError, "unknown corruption 'fogg'"),
        "size": (lambda: parse_size("640"), InvalidValueError, "size '640' is not of the form HxW"),
        "path": (lambda: relative_parts("../a.png", "path"), InvalidValueError, "'..' component"),
        "eigen line": (lambda: parse_eigen(["2011_09_26/d", "x", "l"]), InvalidValueError, "frame 'x'"),
        "nyu line": (lambda: parse_nyu(["a.jpg", "b.png", "f"]), InvalidValueError, "focal length 'f'"),
        "pattern": (lambda: compile_pattern("{a,b}.png"), InvalidValueError, "braces"),
        "custom option": (lambda: check_list(3, tmp_path), InvalidValueError, "got 3"),
        "split choice": (lambda: splits.check_choice("eigen", "eigen", tmp_path), InvalidValueError,
                         "no standard split named 'eigen'"),
        "alpha": (lambda: check_alpha(1.5), InvalidValueError, "alpha must be between 0 and 1"),
        "style size": (lambda: check_style_size(8), InvalidValueError, "style size must be"),
        "style option": (lambda: style_option("vgg", "none.pth", tmp_path), InvalidValueError, "no such file"),
        "style device": (lambda: style_option("device", "gpu", tmp_path), InvalidValueError, "got 'gpu'"),
        "image array": (lambda: as_rgb(np.zeros((20, 40, 3), np.uint8)), ImageError, "too small"),
    }


@pytest.mark.parametrize("name", ["dataset name", "benchmark name", "corruption name", "size", "path",
                                  "eigen line", "nyu line", "pattern", "custom option", "split choice",
                                  "alpha", "style size", "style option", "style device", "image array"])
def test_checks_raise_the_package_errors(name, tmp_path):
    call, cls, message = _checks(tmp_path)[name]
    with pytest.raises(cls, match=message) as info:
        call()
    assert isinstance(info.value, RobodepthError)


def _tiny_kitti(tmp_path, fixtures_dir):
    return ("build", "kitti-c", "--root", fixtures_dir / "kitti_raw", "--split",
            fixtures_dir / "kitti_split.txt", "--out", tmp_path / "out", "--corruptions", "brightness",
            "--levels", "1")


def test_a_bug_in_a_renderer_stays_a_traceback(tmp_path, fixtures_dir, cli, monkeypatch):
    """Before, the builder turned any ValueError of a renderer into 'robodepth: error: ...'."""
    from robodepth_cli.building import pipeline

    def broken(ds, config, depth=None):
        raise ValueError("a bug, not the user's doing")

    monkeypatch.setattr(pipeline, "renderer_of", broken)
    with pytest.raises(ValueError, match="a bug") as info:
        cli(*_tiny_kitti(tmp_path, fixtures_dir))
    assert not isinstance(info.value, RobodepthError)


def test_a_bug_in_a_config_check_stays_a_traceback(tmp_path, fixtures_dir, cli, monkeypatch):
    """Before, the configuration turned any ValueError of a check into a ConfigError."""
    from robodepth_cli.sources import splits

    def broken(*args, **kwargs):
        raise ValueError("a bug, not the user's doing")

    monkeypatch.setattr(splits, "check_choice", broken)
    with pytest.raises(ValueError, match="a bug") as info:
        cli(*_tiny_kitti(tmp_path, fixtures_dir))
    assert not isinstance(info.value, RobodepthError)


def test_the_same_refusal_still_names_the_flag(tmp_path, fixtures_dir, cli):
    args = list(_tiny_kitti(tmp_path, fixtures_dir))
    args[args.index("--split") + 1] = "eigen"
    res = cli(*args)
    assert res.exit_code == 2
    assert res.output.startswith("robodepth: error: --split: no standard split named 'eigen'")


def test_a_refusal_names_its_place_once_and_keeps_it_through_pickling():
    import pickle

    from robodepth_cli.errors import InvalidValueError, RobodepthError

    exc = InvalidValueError("expected HxW such as 192x640, got 'x'")
    assert exc.at("--severity-size") is exc and exc.where == "--severity-size"
    assert str(exc) == "--severity-size: expected HxW such as 192x640, got 'x'"
    assert str(exc.at("config.yaml")) == str(exc)  # its place, once
    assert str(pickle.loads(pickle.dumps(exc))) == str(exc)  # as a worker's refusal comes back
    assert isinstance(exc, RobodepthError) and str(RobodepthError("plain")) == "plain"
