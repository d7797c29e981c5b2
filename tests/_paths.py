"""Where the test data lives: ``tests/data`` inside the repository (see its README.md).

Import these constants (``from _paths import FIXTURES``); ``conftest.py`` holds fixtures only.
"""

from __future__ import annotations

from pathlib import Path

TESTS = Path(__file__).resolve().parent
REPO = TESTS.parent
DATA = TESTS / "data"
FIXTURES = DATA / "fixtures"    # small KITTI-raw and NYU trees, split files, style images
REFERENCE = DATA / "reference"  # outputs and statistics of the benchmark's own formulas
SPLITS = DATA / "splits"        # copies of the two public test splits and SOURCES.md
