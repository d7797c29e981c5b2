"""Which split a build reads: a standard split (from its record and a checked local cache)
or the user's own file. Reading a split's lines is the dataset's business
(:func:`robodepth_cli.sources.datasets.read_split`); choosing and obtaining the file happens here.

The project does not ship the split files. ``splits/splits.json`` (at the top of the
repository) records, for each standard split, its public address, sha256 and number of
entries. :func:`standard_split` returns a cached copy, downloading it on first use with a
timeout and refusing any file whose sha256 differs from the record. When the download is
impossible the error asks for ``--split FILE``.

Overrides, for mirrors and tests: the ``url=`` argument, or the environment variable
``ROBODEPTH_SPLIT_URL_<NAME>`` (name upper-cased, e.g. ``ROBODEPTH_SPLIT_URL_EIGEN_TEST``)
for the address; ``ROBODEPTH_CACHE_DIR`` for the cache directory (default
``$XDG_CACHE_HOME/robodepth`` or ``~/.cache/robodepth``).
"""

from __future__ import annotations

import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path

from ..files import cache_dir, data_dir, sha256_bytes, write_atomic
from ..errors import InvalidValueError, RobodepthError, os_reason

RECORDS_FILE = data_dir("splits") / "splits.json"
TIMEOUT_S = 30.0
MAX_BYTES = 8 << 20  # the real files are ~50 KB; anything far larger is not a split


class SplitError(RobodepthError):
    """A split that cannot be obtained or read; the message says what to do instead."""


@dataclass(frozen=True)
class SplitRecord:
    name: str
    format: str  # the dataset line format: "eigen" or "nyu"
    file: str
    url: str
    sha256: str
    lines: int  # number of entries (non-blank lines)
    description: str = ""


def records() -> dict[str, SplitRecord]:
    """All standard splits of ``splits/splits.json``, by name."""
    try:
        raw = json.loads(RECORDS_FILE.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise SplitError(f"{RECORDS_FILE}: cannot read the split records ({exc})") from None
    return {name: SplitRecord(name=name, **fields) for name, fields in raw.items()}


def record(name: str) -> SplitRecord:
    recs = records()
    if name not in recs:
        raise SplitError(f"unknown standard split {name!r}; valid: {', '.join(recs)} (or a split file)")
    return recs[name]


def check_choice(value, split_format: str, base: Path, owner: str = "this dataset") -> str:
    """The split a configuration names: a standard split name whose format is
    ``split_format`` (e.g. "eigen"), kept as the name, or a split file, returned as typed
    (joined to ``base``, e.g. a config file's directory), so messages show what the user
    wrote. :class:`InvalidValueError` for anything else, including a bare word that is neither a
    standard name nor a file (the message lists the standard names); the file itself is
    read later."""
    from .sequences import FORMAT, SPLITS

    if not isinstance(value, str) or not value:
        raise InvalidValueError(f"expected a standard split name or a file, got {value!r}")
    formats = {**{r.name: r.format for r in records().values()}, **dict.fromkeys(SPLITS, FORMAT)}
    fits = [n for n, f in formats.items() if f == split_format]
    if value in formats:
        if formats[value] != split_format:
            raise InvalidValueError(f"{value!r} is not a split of {owner}; valid: "
                             f"{', '.join(fits)} or a split file")
        return value
    path = Path(base) / Path(value).expanduser()
    if not path.exists() and "/" not in value and os.sep not in value and not Path(value).suffix:
        # A bare word such as 'eigen' was meant as a standard split name.
        raise InvalidValueError(f"no standard split named {value!r} (and no such file); standard splits "
                         f"of {owner}: {', '.join(fits)}; or give a split file")
    return str(path)


def split_path(choice: str, root: Path | None = None) -> Path:
    """The file of a split :func:`check_choice` accepted: the checked, cached copy of a
    standard split (downloaded on first use), a split of consecutive frames made from the
    tree under ``root`` (:mod:`.sequences`), or the user's file."""
    from .sequences import SPLITS, generate

    if choice in records():
        return standard_split(choice)
    if choice in SPLITS:
        if root is None:  # a caller without a tree: a bug, not a user's mistake
            raise TypeError(f"the {choice} split is made from a raw tree: give its root")
        return generate(choice, Path(root), cache_dir())
    return Path(choice)


def url_for(rec: SplitRecord) -> str:
    return os.environ.get(f"ROBODEPTH_SPLIT_URL_{rec.name.upper()}") or rec.url


def count_entries(data: bytes) -> int:
    return sum(1 for line in data.splitlines() if line.strip())


def _download(url: str, timeout: float) -> bytes:
    import urllib.request  # here: naming a dataset (robodepth --help) never loads http

    with urllib.request.urlopen(url, timeout=timeout) as resp:  # noqa: S310 (http(s) from our records or the user)
        data = resp.read(MAX_BYTES + 1)
    if len(data) > MAX_BYTES:
        raise SplitError(f"{url}: more than {MAX_BYTES} bytes; this is not a split file")
    return data


def clone_copy(rec: SplitRecord) -> Path | None:
    """The copy of ``rec``'s file that a clone of robodepth keeps for its tests
    (``tests/data/splits``), if this package runs from a clone and the copy has the
    recorded sha256; None otherwise."""
    path = Path(__file__).resolve().parents[2] / "tests" / "data" / "splits" / rec.file
    try:
        return path if sha256_bytes(path.read_bytes()) == rec.sha256 else None
    except OSError:
        return None


def standard_split(name: str, *, url: str | None = None, cache: Path | None = None,
                   timeout: float = TIMEOUT_S) -> Path:
    """The local path of standard split ``name``, checked against its sha256.

    A cached copy with the right checksum is used as it is. Otherwise the file is fetched
    from ``url`` (default: the environment override, then the recorded address), checked
    (sha256 and entry count) and written atomically into the cache. Raises
    :class:`SplitError` when offline or on a mismatch; nothing is cached then.
    """
    rec = record(name)
    target = (cache or cache_dir()) / "splits" / rec.file
    stale = ""
    try:
        cached = sha256_bytes(target.read_bytes())
    except OSError:
        cached = None  # not cached yet (or unreadable): fetch it
    if cached == rec.sha256:
        return target
    if cached is not None:
        # Say so before fetching: an edited copy would otherwise vanish without a word.
        stale = f"the cached copy {target} has sha256 {cached[:12]}..., expected {rec.sha256[:12]}..."
        print(f"robodepth: warning: {stale} (changed or damaged); downloading the {name} split again",
              file=sys.stderr)
        stale = f" ({stale}, so it was not used)"
    src = url or url_for(rec)
    hint = "download it yourself and pass it with --split FILE"
    copy = clone_copy(rec)
    if copy is not None:
        hint += f" (this clone holds a checked copy: --split {copy})"
    import urllib.error

    try:
        data = _download(src, timeout)
    except urllib.error.HTTPError as exc:  # the server answered: not an offline problem
        raise SplitError(f"cannot download the {name} split from {src} (HTTP {exc.code} {exc.reason}); "
                         f"{hint}{stale}") from None
    except (urllib.error.URLError, OSError, ValueError) as exc:
        reason = getattr(exc, "reason", None) or exc
        raise SplitError(f"cannot download the {name} split from {src} ({reason}); "
                         f"offline? {hint}{stale}") from None
    got = sha256_bytes(data)
    if got != rec.sha256:
        raise SplitError(f"the {name} split downloaded from {src} has sha256 {got}, expected "
                         f"{rec.sha256}; refusing it: {hint}")
    n = count_entries(data)
    if n != rec.lines:  # unreachable with a matching sha256 unless the record itself is wrong
        raise SplitError(f"the {name} split from {src} has {n} entries, expected {rec.lines}")
    try:
        write_atomic(target, data)
    except OSError as exc:
        raise SplitError(f"cannot write the split cache {target} ({os_reason(exc)}); "
                         f"set ROBODEPTH_CACHE_DIR or pass --split FILE") from None
    return target
