"""Every name an export writes into ``--to DIR`` (nothing else in the package spells them;
docs/export.md shows the tree): the card, ``data/<config>/<split>-NNNNN-of-NNNNN`` shards,
and under ``robodepth/`` the build's own files, the export record (:data:`RECORD`) and the
journal of the shards done."""

from __future__ import annotations

from ..corruptions.severity import level_text

SCHEMA = "robodepth-export"  # the export record's (its version: robodepth_cli/formats.py)
CARD = "README.md"
DATA = "data"
META = "robodepth"  # the folder with the build's record and manifest and the export record
RECORD = "export.json"
JOURNAL = ".shards.jsonl"  # in META: the shards written so far, while an export runs
GT_CONFIG = "ground_truth"
NO_LEVEL = "test"  # the split of a variant without levels
NEIGHBOURS = "_neighbours"  # a split's neighbour frames (a build with --frames): level_3_neighbours
FORMATS = {"parquet": "parquet", "webdataset": "tar"}  # format -> shard extension


def split_name(level) -> str:
    """``level_3``, ``level_2.5``, or ``test`` (no level): the names the Hub accepts."""
    return NO_LEVEL if level is None else f"level_{level_text(level)}"


def shard_name(config: str, split: str, index: int, count: int, ext: str) -> str:
    """``data/<config>/<split>-00000-of-00002.<ext>``, the Hub's sharded-file naming."""
    return f"{DATA}/{config}/{split}-{index:05d}-of-{count:05d}.{ext}"
