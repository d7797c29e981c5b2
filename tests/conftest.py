"""Shared test fixtures. Paths to the test data are constants in ``_paths.py``."""

from __future__ import annotations

from pathlib import Path

import pytest

from _paths import FIXTURES, REFERENCE, SPLITS


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
