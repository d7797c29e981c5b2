"""Shared test fixtures. Paths to the test data are constants in ``_paths.py``; tree
builders are in ``_trees.py``."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from _paths import FIXTURES, REFERENCE, SPLITS

# Commands that draw a progress bar: the tests read only what the command reports.
_PROGRESS_COMMANDS = ("build", "verify", "gt")


def _require(path: Path) -> Path:
    if not path.exists():
        # tests/data is part of the repository: its absence is a broken checkout, not a
        # reason to skip.
        raise RuntimeError(f"test data missing: {path} (tests/data is part of the repository)")
    return path


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
