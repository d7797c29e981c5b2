"""Builds shared between tests (and the benches): copies of a session's build that a test
may change, and minimal builds that only evaluate reads."""

from __future__ import annotations

import json
import shutil
from pathlib import Path


def copy_build(build: Path, tmp_path_factory) -> Path:
    """A copy of ``build`` in a new temporary folder, under the same folder name."""
    out = tmp_path_factory.mktemp(build.name.lower()) / build.name
    shutil.copytree(build, out, symlinks=True)
    return out


def minimal_build(root: Path, name: str, keys: list[str], variants: list[tuple[str, int | None]],
                  size: tuple[int, int] = (192, 640)) -> Path:
    """A build folder of dataset ``name`` with no image in it: a build.json (split ``keys``,
    ``size``) and a manifest with a row per variant ``(corruption, level)`` and key, as
    ``robodepth evaluate`` reads them. Its ground truth and the predictions are the caller's."""
    from robodepth_cli.formats import stamp
    from robodepth_cli.output import manifest
    from robodepth_cli.output.record import SCHEMA

    root.mkdir(parents=True)
    # stamped with the format version this tree reads (older code ignores the stamp)
    record = {"dataset": name, "split": {"keys": keys}, "config": {"size": list(size)}, **stamp(SCHEMA)}
    (root / "build.json").write_text(json.dumps(record))
    rows = [manifest.Row(f"{v}/{lv}/{k}" if lv else f"{v}/{k}", k, v, lv, 0, 1, 1, "0" * 64)
            for v, lv in variants for k in keys]
    (root / "manifest.csv").write_text(manifest.HEADER + manifest.format_rows(rows))
    return root
