"""The format version of every file robodepth writes for another command to read, and the
one check of it.

Each such file carries ``schema`` (what it is), ``schema_version`` (its layout) and
``robodepth`` (the release that wrote it): build.json, the manifest (through the build.json
beside it), predictions.json, the results CSV (in its sidecar ``RESULTS.csv.json``, so the
rows stay plain CSV), the export record, scores.json and the ground-truth cache's entries
(which are read around, not refused, when they are of another release). A reader meets a file of another
layout with one line naming the file and the release that reads it, never a guess at what
its keys meant. The layout version changes when a reader of the old version would read the
new file wrongly; the release alone changing keeps the layout.
"""

from __future__ import annotations

from .errors import RobodepthError

RELEASE = "0.1.0"  # robodepth's version (``robodepth_cli.__version__``; pyproject.toml's too)

# schema -> the layout version this release writes and reads
VERSIONS = {
    "robodepth-build": 1,  # build.json and the manifest.csv beside it
    "robodepth-predictions": 1,  # predictions.json
    "robodepth-results": 1,  # a results CSV's sidecar
    "robodepth-export": 2,  # an export's robodepth/export.json (2: the ground truth one map a row)
    "robodepth-report": 1,  # scores.json
    "robodepth-gt-cache": 1,  # an entry of the ground-truth cache (groundtruth/cache.py)
}


class FormatError(RobodepthError):
    """A file of a layout this release does not read."""


def stamp(schema: str) -> dict:
    """The fields a file of ``schema`` carries first: ``schema``, ``schema_version``,
    ``robodepth``."""
    return {"schema": schema, "schema_version": VERSIONS[schema], "robodepth": RELEASE}


def check(doc: dict, schema: str, where: str, redo: str) -> None:
    """Refuse ``doc`` (a file's parsed JSON, named ``where``) unless it is of ``schema`` at
    this release's version: one line saying which release wrote it and what to do
    (``redo``: "rebuild", "run predict again", ...)."""
    if doc.get("schema") == schema and doc.get("schema_version") == VERSIONS[schema]:
        return
    made = doc.get("robodepth") if isinstance(doc.get("robodepth"), str) else ""
    if doc.get("schema") != schema or "schema_version" not in doc:
        raise FormatError(f"{where}: not a {schema} file of a format version (made by "
                          f"{'robodepth ' + made if made else 'another program'}, before files "
                          f"carried one?); {redo} with robodepth {RELEASE}")
    raise FormatError(f"{where}: made by robodepth {made or '(unnamed)'} ({schema} version "
                      f"{doc.get('schema_version')}, this one reads {VERSIONS[schema]}); {redo} or "
                      f"use robodepth {made or 'that made it'}")
