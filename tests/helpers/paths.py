"""Where the test data lives: ``tests/data`` inside the repository (see its README.md).

Import these constants (``from tests.helpers.paths import FIXTURES``); ``tests/conftest.py`` holds
fixtures only.
"""

from __future__ import annotations

from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]
REPO = TESTS.parent
DATA = TESTS / "data"
FIXTURES = DATA / "fixtures"    # small KITTI-raw and NYU trees, split files, style images
REFERENCE = DATA / "reference"  # outputs and statistics of the benchmark's own formulas
SPLITS = DATA / "splits"        # copies of the two public test splits and SOURCES.md

# Package folders (robodepth_cli/<name>/) another branch is making now, named ahead of them in
# docs/development.md's tree and mirrored by a tests/ folder; remove a name once its folder is
# on main (the layout tests then say so).
PENDING_PACKAGES: set[str] = set()
