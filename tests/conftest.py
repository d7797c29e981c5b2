"""Shared test fixtures: paths into ../shared (read-only) and small helpers."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("ROBODEPTH_SHARED", REPO.parent / "shared")).resolve()
FIXTURES = SHARED / "fixtures"
REFERENCE = SHARED / "reference"
SPLITS = SHARED / "splits"


def _require(path: Path) -> Path:
    if not path.exists():
        # ../shared sits beside the clone in CI and on every developer machine; its absence
        # is a broken checkout, not a reason to skip.
        raise RuntimeError(f"test data missing: {path} (expected ../shared beside the repository)")
    return path


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    return _require(SHARED)


@pytest.fixture(scope="session")
def fixtures_dir() -> Path:
    return _require(FIXTURES)


@pytest.fixture(scope="session")
def reference_dir() -> Path:
    return _require(REFERENCE)


@pytest.fixture(scope="session")
def splits_dir() -> Path:
    return _require(SPLITS)
