"""A custom build's source images that are gone from the root since an earlier build into
the same OUT (:func:`prune`).

A custom build's sources are what the root holds: an image deleted there leaves the
build. Its outputs, their manifest rows (failures included) and its key in the record's
requests go, so that the build, the manifest and the record agree with the sources as
they are now, and ``verify``, ``predict`` and ``export`` see the same images. An image
still in the root but left out of this request (``--limit``, another ``--pattern``) stays:
only a file that no longer exists drops its image. (A benchmark's split says which images
there are: one missing from its root is that image's failure, and what was made from it
stays.)
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ..output.folder import OutputFolder
from ..output.manifest import Row
from ..output.record import BuildRecord


def vanished(rows: dict[str, Row], root: Path, current: set[str]) -> dict[str, str]:
    """key -> source path (relative to ``root``) of every image whose clean output the
    manifest ``rows`` list, that is not among the ``current`` sources' keys, and whose
    source file (as its row names it) is no longer there."""
    from ..sources.datasets import CLEAN, Job

    prefix = Job(CLEAN, None).path("")
    gone = {}
    for path, row in rows.items():
        key = path[len(prefix):]
        if (path.startswith(prefix) and key not in current and row.source
                and not (Path(root) / row.source).exists()):
            gone[key] = row.source
    return gone


def prune(ds, folder: OutputFolder, root: Path, sources, previous: BuildRecord | None
          ) -> tuple[BuildRecord | None, str]:
    """Drop the images of a custom build in ``folder`` whose source files are gone
    (:func:`vanished`; ``sources``: this build's): first their keys from the record's
    requests (written at once), then their outputs and manifest rows, so a build stopped
    half-way finishes the job when rerun. Returns ``previous`` without those keys and the
    summary's note saying what was dropped ("" when nothing was). Call with the lock held."""
    if not ds.discovers_sources or previous is None:
        return previous, ""
    rows = folder.rows()
    gone = vanished(rows, root, {s.key for s in sources})
    if not gone:
        return previous, ""
    plans = [{**p, "keys": [k for k in p["keys"] if k not in gone]} for p in previous.requests()]
    previous = replace(previous, plans=[p for p in plans if p["keys"]])
    folder.write_record(previous)
    files = set(gone.values())
    dropped = {path for path, row in rows.items() if row.source in files}
    for path in dropped:
        (folder.path / path).unlink(missing_ok=True)
    folder.compact(dropped)
    names = sorted(files)
    shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
    images = "1 source image" if len(names) == 1 else f"{len(names)} source images"
    return previous, (f"dropped {images} no longer in the root ({shown}): "
                      f"{len(dropped)} outputs, their manifest rows and "
                      f"{'its key' if len(names) == 1 else 'their keys'} in the record")
