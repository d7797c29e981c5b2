"""Shared test fixtures. Paths to the test data are constants in ``tests/helpers/paths.py``;
tree builders and the other plain helpers are in ``tests/helpers/``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result

from tests.helpers.builds import copy_build
from tests.helpers.evaluation import GT_SHAPES, KITTI_VARIANTS, kitti_preds, lidar_gt, write_form1
from tests.helpers.paths import FIXTURES, REFERENCE, SPLITS
from tests.helpers.readonly import read_only_directory
from tests.helpers.trees import fixture_kitti_with_scans

# Commands that draw a progress bar: the tests read only what the command reports.
_PROGRESS_COMMANDS = ("build", "verify", "gt")


def _require(path: Path) -> Path:
    if not path.exists():
        # tests/data is part of the repository: its absence is a broken checkout, not a
        # reason to skip.
        raise RuntimeError(f"test data missing: {path} (tests/data is part of the repository)")
    return path


@pytest.fixture(scope="session", autouse=True)
def user_cache(tmp_path_factory) -> Path:
    """The user's cache (generated splits, ground truth kept between evaluations) in a folder
    of the session's: no test reads or writes ``~/.cache/robodepth``."""
    where = tmp_path_factory.mktemp("user-cache")
    patch = pytest.MonkeyPatch()
    patch.setenv("ROBODEPTH_CACHE_DIR", str(where))
    patch.delenv("ROBODEPTH_GT_CACHE", raising=False)
    yield where
    patch.undo()


@pytest.fixture(scope="session")
def fixtures_dir() -> Path:
    return _require(FIXTURES)


@pytest.fixture(scope="session")
def reference_dir() -> Path:
    return _require(REFERENCE)


@pytest.fixture(scope="session")
def splits_dir() -> Path:
    return _require(SPLITS)


@pytest.fixture(scope="session")
def cli():
    """Run ``robodepth ARGS...`` in-process: ``cli("verify", out)`` returns click's ``Result``
    (``exit_code``, ``output`` with stdout and stderr).

    Each argument is passed as ``str(arg)``, so paths and numbers can be given as they are.
    ``build``, ``verify`` and ``gt`` get ``--no-progress`` appended. An exception the CLI lets escape
    is raised in the test with its traceback instead of becoming exit status 1, and the
    output of a run that returns never holds a traceback.
    """
    from robodepth_cli.cli import main

    def run(*args) -> Result:
        argv = [str(a) for a in args]
        if argv and argv[0] in _PROGRESS_COMMANDS:
            argv.append("--no-progress")
        result = CliRunner().invoke(main, argv, catch_exceptions=False)
        assert "Traceback" not in result.output, result.output
        return result

    return run


@pytest.fixture(scope="session")
def build_kitti(cli):
    """``build_kitti(root, split, out, *flags)``: ``robodepth build kitti-c`` on a tree."""
    def build(root, split, out, *flags) -> Result:
        return cli("build", "kitti-c", "--root", root, "--split", split, "--out", out, *flags)

    return build


@pytest.fixture(scope="session")
def frames_build(build_kitti, tmp_path_factory) -> Path:
    """A ``--frames -1,1`` build of six consecutive KITTI frames (test frames 0, 2 and 5) at
    48 x 64, fog at levels 2 and 3, no ground truth; made once per session, only read."""
    from tests.helpers.trees import kitti_drive

    base = tmp_path_factory.mktemp("frames")
    split = kitti_drive(base / "raw", range(6), [0, 2, 5])
    out = base / "OUT"
    res = build_kitti(base / "raw", split, out, "--size", "48x64", "--corruptions", "fog",
                      "--levels", "2,3", "--jobs", "1", "--no-gt", "--frames", "-1,1")
    assert res.exit_code == 0, res.output
    return out


@pytest.fixture(scope="session")
def kitti_scans_root(tmp_path_factory) -> Path:
    """The fixtures' KITTI frames with their velodyne scans, made once per session; tests only
    read it (one that changes a scan makes its own with ``fixture_kitti_with_scans``)."""
    return fixture_kitti_with_scans(tmp_path_factory.mktemp("kitti_scans"))


@pytest.fixture
def read_only_dir(tmp_path) -> Path:
    """A directory nothing can be written into, even by root (tests/helpers/readonly.py)."""
    with read_only_directory(tmp_path) as where:
        yield where


def _fixture_kitti_c(cli, fixtures_dir, where: Path, levels: str) -> Path:
    """``where/KITTI_C``: the fixtures' two KITTI frames at 64 x 96, brightness and contrast
    at ``levels``, no ground truth."""
    out = where / "KITTI_C"
    res = cli("build", "kitti-c", "--root", fixtures_dir / "kitti_raw", "--split",
              fixtures_dir / "kitti_split.txt", "--out", out, "--size", "64x96", "--corruptions",
              "brightness,contrast", "--levels", levels, "--jobs", "1")
    assert res.exit_code == 0, res.output
    return out


@pytest.fixture(scope="session")
def kitti_c_build(fixtures_dir, tmp_path_factory, cli) -> Path:
    """A small KITTI-C built from the fixtures (64 x 96; brightness and contrast at levels 1 and
    3; no ground truth), made once per session. Tests only read it: one that needs to
    change it works on ``copy_build(kitti_c_build, ...)``."""
    return _fixture_kitti_c(cli, fixtures_dir, tmp_path_factory.mktemp("kitti_c_build"), "1,3")


@pytest.fixture(scope="session")
def small_build(fixtures_dir, tmp_path_factory, cli) -> Path:
    """A KITTI-C built from the fixtures with brightness and contrast at level 3 alone (64 x
    96; no ground truth), made once per session for the report tests, which read it: the
    report's one-frame figure draws one level per corruption."""
    return _fixture_kitti_c(cli, fixtures_dir, tmp_path_factory.mktemp("small_build"), "3")


@pytest.fixture(scope="session")
def kitti_c(kitti_c_build, tmp_path_factory):
    """``(out, gts)``: ``kitti_c_build`` with ground truth written in the test in monodepth2's
    gt_depths.npz format (an object array of float32 maps, split order)."""
    out = copy_build(kitti_c_build, tmp_path_factory)
    gts = np.empty(2, object)
    for i, shape in enumerate(GT_SHAPES):
        gts[i] = lidar_gt(shape, i)
    np.savez_compressed(out / "gt_depths.npz", data=gts)
    return out, list(gts)


@pytest.fixture(scope="session")
def kitti_pred(kitti_c, tmp_path_factory):
    """Predictions for every variant of ``kitti_c`` in the folder's first form."""
    pred = tmp_path_factory.mktemp("pred") / "PRED"
    return write_form1(pred, {v: kitti_preds(k) for k, v in enumerate(KITTI_VARIANTS)})
