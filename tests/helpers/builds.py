"""Builds shared between tests: copies of a session's build that a test may change."""

from __future__ import annotations

import shutil
from pathlib import Path


def copy_build(build: Path, tmp_path_factory) -> Path:
    """A copy of ``build`` in a new temporary folder, under the same folder name."""
    out = tmp_path_factory.mktemp(build.name.lower()) / build.name
    shutil.copytree(build, out, symlinks=True)
    return out
