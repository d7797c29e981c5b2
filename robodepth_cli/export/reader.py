"""Reading an export back: the files of a build, found in its shards by their path in the
build, each checked against the build's manifest as it is read.

:class:`ExportStore` is what :func:`robodepth_cli.open_dataset` gives a dataset opened from
an export (``dataset.store``); :func:`shard_rows` reads a whole shard for ``verify`` and the
ground truth. A parquet read fetches one row group (64 images) and keeps the last one, so
reading a variant in split order reads each shard once; a tar read seeks to the member.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Iterator

from ..files import sha256_bytes
from ..output.layout import GT_DIR, GT_FILE
from ..formats import FormatError, check
from .layout import GT_CONFIG, META, NEIGHBOURS, RECORD, SCHEMA
from .plan import ExportError, neighbour_outputs


def read_export_record(to: Path) -> dict | None:
    """The export record of ``to``, or None when there is none; ExportError naming the file
    when it cannot be read or is of another format version."""
    path = Path(to) / META / RECORD
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:
        raise ExportError(f"{path}: cannot be read as an export record ({exc})") from None
    try:
        check(record if isinstance(record, dict) else {}, SCHEMA, str(path), "export the build again")
    except FormatError as exc:
        raise ExportError(str(exc)) from None
    return record


def is_export(path: Path) -> bool:
    return (Path(path) / META / RECORD).is_file()


def opening(path: Path) -> dict:
    """How :func:`robodepth_cli.api.open_dataset` opens ``path`` when it is an export: the
    folder holding the build's record and manifest (``meta``) and the maker of the store
    its images are read from (``store``); {} for anything else (a build)."""
    if not is_export(path):
        return {}
    return {"meta": Path(path) / META, "store": lambda keys, manifest: ExportStore(path, keys, manifest)}


def shard_rows(path: Path, fmt: str, prefix: str) -> Iterator[tuple[str, bytes]]:
    """(path in the build, bytes) of every image in one shard, in order. Raises whatever
    the shard's reader raises for a damaged file (the caller names the shard)."""
    if fmt == "parquet":
        import pyarrow.parquet as pq

        for batch in pq.ParquetFile(path).iter_batches(batch_size=64, columns=["image"]):
            for cell in batch.column("image").to_pylist():
                yield cell["path"], cell["bytes"]
        return
    import tarfile

    with tarfile.open(path, mode="r:") as tar:
        for member in tar:
            if not member.isfile() or member.name.endswith(".json"):
                continue
            data = tar.extractfile(member).read()
            yield (f"{prefix}/{member.name}" if prefix else member.name), data


def export_files(to: Path, paths) -> Iterator[tuple[str, bytes]]:
    """(path in the build, bytes) of those of ``paths`` that the images in ``to``'s shards
    hold, shard by shard (each shard that may hold one is read once); a shard that cannot
    be read yields nothing."""
    record = read_export_record(to) or {}
    wanted = set(paths)
    for e in record.get("shards") or []:
        if e["config"] == GT_CONFIG or not any(p.startswith(e["prefix"] + "/") for p in wanted):
            continue
        try:
            for name, data in shard_rows(Path(to) / e["file"], record.get("format"), e["prefix"]):
                if name in wanted:
                    yield name, data
        except Exception:  # noqa: BLE001 -- any reader error means a damaged shard (verify names it)
            continue


def gt_rows(path: Path, fmt: str) -> Iterator[tuple[str, str, bytes]]:
    """(path of its file in the build, image key, the map's ``.npy`` bytes) of every
    ground-truth map in one shard, in order (see :mod:`.groundtruth`)."""
    from .groundtruth import npy_bytes

    if fmt == "parquet":
        import pyarrow.parquet as pq

        for batch in pq.ParquetFile(path).iter_batches(batch_size=8, columns=["path", "key", "depth"]):
            depth = batch.column("depth")
            for i, (p, k) in enumerate(zip(batch.column("path").to_pylist(), batch.column("key").to_pylist())):
                rows = depth[i].values
                flat = rows.flatten().to_numpy(zero_copy_only=False)
                yield p, k, npy_bytes(flat.reshape(len(rows), -1) if len(rows) else flat.reshape(0, 0))
        return
    import tarfile

    with tarfile.open(path, mode="r:") as tar:
        data = None
        for member in tar:
            if member.isfile() and member.name.endswith(".json") and data is not None:
                meta = json.loads(tar.extractfile(member).read())
                yield meta["path"], meta["key"], data
                data = None
            elif member.isfile():
                data = tar.extractfile(member).read()


class ExportStore:
    """The files of the build exported into ``path``, by their path in the build."""

    def __init__(self, path: Path, keys, manifest: dict):
        record = read_export_record(path)
        self.path = Path(path)
        if record.get("status") != "finished":
            raise ExportError(f"{self.path}: the export did not finish; rerun the robodepth export "
                              "command that made it")
        self.format = record.get("format")
        self.shards = record.get("shards") or []
        self._sha = {p: r.sha256 for p, r in manifest.items() if not r.error}
        self._where: dict[str, tuple[int, int]] = {}
        around = neighbour_outputs(manifest)
        for n, e in enumerate(self.shards):
            if e["config"] == GT_CONFIG:
                continue
            if e["split"].endswith(NEIGHBOURS):
                paths = around.get(e["prefix"], [])[e["start"]:e["start"] + e["rows"]]
            else:  # the split's images this variant has (see plan), in split order
                made = [p for p in (f"{e['prefix']}/{k}" for k in keys)
                        if p in manifest and not manifest[p].error]
                paths = made[e["start"]:e["start"] + e["rows"]]
            self._where.update((p, (n, j)) for j, p in enumerate(paths))
        self._cache: dict = {}
        self._gt_dir = None

    def __getstate__(self):  # open files and cached row groups stay in their process
        return {**self.__dict__, "_cache": {}, "_gt_dir": None}

    def has(self, output: str) -> bool:
        return output in self._where

    def read(self, output: str) -> bytes:
        """The bytes of the build's file ``output``; :class:`ExportError` if the export
        lacks it or holds other bytes than the manifest says."""
        if output not in self._where:
            raise ExportError(f"{self.path}: holds no {output}")
        n, j = self._where[output]
        file = self.path / self.shards[n]["file"]
        try:
            data = self._parquet(file, n, j) if self.format == "parquet" else self._tar(file, n, output)
        except (OSError, ValueError, KeyError) as exc:  # pyarrow's errors derive from these
            raise ExportError(f"{file}: cannot be read ({exc}); run robodepth verify "
                              f"{self.path}") from None
        if sha256_bytes(data) != self._sha.get(output):
            raise ExportError(f"{file}: {output} is not the build's (its sha256 is not the "
                              f"manifest's); run robodepth verify {self.path}")
        return data

    def _parquet(self, file: Path, n: int, j: int) -> bytes:
        import pyarrow.parquet as pq

        pf = self._cache.get(("file", n))
        if pf is None:
            self._cache = {("file", n): pq.ParquetFile(file)}
            pf = self._cache[("file", n)]
        start = 0
        for g in range(pf.num_row_groups):
            rows = pf.metadata.row_group(g).num_rows
            if j < start + rows:
                break
            start += rows
        group = self._cache.get(("group", n, g))
        if group is None:
            group = pf.read_row_group(g, columns=["image"]).column("image").to_pylist()
            self._cache = {("file", n): pf, ("group", n, g): group}
        return group[j - start]["bytes"]

    def _tar(self, file: Path, n: int, output: str) -> bytes:
        members = self._cache.get(("members", n))
        if members is None:
            import tarfile

            with tarfile.open(file, mode="r:") as tar:
                members = {m.name: (m.offset_data, m.size) for m in tar if m.isfile()}
            self._cache[("members", n)] = members
        prefix = self.shards[n]["prefix"]
        offset, size = members[output[len(prefix) + 1:]]
        with open(file, "rb") as fh:
            fh.seek(offset)
            return fh.read(size)

    def ground_truth(self) -> Path | None:
        """The build's ground truth (``gt_depths.npz`` or ``gt/``), written back from the
        export's maps into a temporary folder that lives as long as this store: the same
        values as the build's files; None when the export has none."""
        entries = [e for e in self.shards if e["config"] == GT_CONFIG]
        if not entries:
            return None
        if self._gt_dir is None:
            import tempfile

            from .groundtruth import from_npy, write_back

            maps: dict[str, list] = {}
            keys: dict[str, list] = {}
            for e in entries:
                file = self.path / e["file"]
                for (path, key, data), want in zip(gt_rows(file, self.format), e.get("maps") or []):
                    if [path, key, sha256_bytes(data)] != want:
                        raise ExportError(f"{file}: the ground truth of {key or path} is not the one "
                                          f"exported; run robodepth verify {self.path}")
                    maps.setdefault(path, []).append(from_npy(data, str(file)))
                    keys.setdefault(path, []).append(key)
            tmp = tempfile.TemporaryDirectory(prefix="robodepth-gt-")
            write_back(Path(tmp.name), maps, keys)
            self._gt_dir = tmp
        root = Path(self._gt_dir.name)
        return root / GT_FILE if (root / GT_FILE).is_file() else root / GT_DIR
