"""A build's manifest read back: OUT/manifest.csv's rows."""

from __future__ import annotations

import csv
from pathlib import Path


def manifest_rows(out: Path) -> list[dict[str, str]]:
    """The rows of ``out/manifest.csv`` in the file's order, each a dict by column."""
    with open(Path(out) / "manifest.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def manifest_by_output(out: Path) -> dict[str, dict[str, str]]:
    """The rows of ``out/manifest.csv`` by their ``output`` path."""
    return {r["output"]: r for r in manifest_rows(out)}
