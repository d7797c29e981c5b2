"""Writing one shard: parquet (the Hugging Face layout) or tar (WebDataset); docs/export.md
gives the columns and members. Every file's bytes are read from the build once, hashed, and
refused unless the hash is the manifest's. Memory holds one row group (:data:`ROW_GROUP`
images) of a parquet shard, one file of a tar shard; tar members have a fixed owner, mode
and time, so the same build gives the same bytes."""

from __future__ import annotations

import io
import json
import posixpath
from pathlib import Path
from typing import BinaryIO, Iterator

from ..files import sha256_bytes
from .plan import ExportError, Item, Shard

ROW_GROUP = 64  # images per parquet row group: the unit a reader fetches
GT_ROW_GROUP = 8  # depth maps per row group (a KITTI map is 1.9 MB of float32)
DEPTH_NPY = ".depth.npy"  # a ground-truth map's member suffix in a tar shard

_VALUE = {"_type": "Value"}
FEATURES = {"key": {**_VALUE, "dtype": "string"}, "variant": {**_VALUE, "dtype": "string"},
            "level": {**_VALUE, "dtype": "float64"}, "seed": {**_VALUE, "dtype": "int64"},
            "sha256": {**_VALUE, "dtype": "string"}}
IMAGE_FEATURES = {**FEATURES, "image": {"_type": "Image"}}
GT_FEATURES = {**FEATURES, "path": {**_VALUE, "dtype": "string"},
               "depth": {"_type": "Sequence", "feature": {"_type": "Sequence",
                                                          "feature": {**_VALUE, "dtype": "float32"}}}}


def _schema(gt: bool):
    import pyarrow as pa

    base = [("key", pa.string()), ("variant", pa.string()), ("level", pa.float64()),
            ("seed", pa.int64()), ("sha256", pa.string())]
    if gt:
        cols = [*base, ("path", pa.string()), ("depth", pa.list_(pa.list_(pa.float32())))]
        features = GT_FEATURES
    else:
        image = pa.struct([("bytes", pa.binary()), ("path", pa.string())])
        cols, features = [*base, ("image", image)], IMAGE_FEATURES
    meta = {"huggingface": json.dumps({"info": {"features": features}})}
    return pa.schema(cols, metadata=meta)


def read_checked(out: Path, item: Item) -> bytes:
    """The bytes of one file of the build, refused unless they are the manifest's."""
    try:
        data = (out / item.output).read_bytes()
    except OSError as exc:
        raise ExportError(f"{out / item.output}: cannot be read ({exc.strerror}); run robodepth "
                          f"verify {out}") from None
    if sha256_bytes(data) != item.sha256:
        raise ExportError(f"{out / item.output}: changed since the build (its sha256 is not the "
                          f"manifest's); run robodepth verify {out}")
    return data


def _payloads(out: Path, shard: Shard, gt: bool) -> Iterator[tuple[Item, object]]:
    """Each item with its bytes, or for the ground truth its map (each file read once)."""
    if not gt:
        for item in shard.items:
            yield item, read_checked(out, item)
        return
    from itertools import groupby

    from ..files import sha256_file
    from .groundtruth import read_maps

    for path, group in groupby(shard.items, key=lambda i: i.output):
        items = list(group)
        try:
            same = sha256_file(out / path) == items[0].sha256
        except OSError as exc:
            raise ExportError(f"{out / path}: cannot be read ({exc.strerror}); run robodepth "
                              f"verify {out}") from None
        if not same:
            raise ExportError(f"{out / path}: changed since the build (its sha256 is not the "
                              f"manifest's); run robodepth verify {out}")
        maps = read_maps(out / path, path, [i.part for i in items])
        for item in items:
            yield item, maps.pop(item.part)


def write_parquet(fh: BinaryIO, out: Path, shard: Shard, gt: bool, progress=None) -> list | None:
    """Write the shard; for the ground truth, return ``[path, key, sha256]`` of each map."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema = _schema(gt)
    # PNG bytes do not compress further, and no two are alike: stored as they are, without
    # dictionaries or min/max statistics of the blobs (time spent for nothing). Depth maps
    # (mostly NaN in KITTI's) are compressed.
    compression = {n: "none" for n in schema.names}
    compression["depth.list.element.list.element"] = "zstd"
    size = GT_ROW_GROUP if gt else ROW_GROUP
    maps: list = []
    with pq.ParquetWriter(fh, schema, compression=compression if gt else "none", use_dictionary=False,
                          write_statistics=["key", "variant", "level", "seed"]) as writer:
        batch: list[tuple[Item, object]] = []
        for pair in _payloads(out, shard, gt):
            batch.append(pair)
            if len(batch) == size:
                writer.write_table(_table(pa, schema, batch, gt, maps), row_group_size=size)
                _tick(progress, batch)
                batch = []
        if batch or not shard.items:
            writer.write_table(_table(pa, schema, batch, gt, maps), row_group_size=size)
            _tick(progress, batch)
    return maps if gt else None


def _tick(progress, batch) -> None:
    if progress:
        progress(sum(i.size for i, _ in batch))


def _table(pa, schema, batch, gt: bool, maps: list):
    items = [i for i, _ in batch]
    cols = {"key": [i.key for i in items], "variant": [i.variant for i in items],
            "level": [None if i.level is None else float(i.level) for i in items],
            "seed": [i.seed for i in items], "sha256": [i.sha256 for i in items]}
    if gt:
        from .groundtruth import map_sha256

        shas = [map_sha256(m) for _, m in batch]
        maps += [[i.output, i.key, sha] for i, sha in zip(items, shas)]
        cols["sha256"], cols["path"] = shas, [i.output for i in items]
        cols["depth"] = _depth_column(pa, [m for _, m in batch])
    else:
        cols["image"] = [{"bytes": d, "path": i.output} for i, d in batch]
    return pa.Table.from_pydict(cols, schema=schema)


def _depth_column(pa, maps):
    """The maps as one arrow list<list<float32>> column, built from their buffers (a list of
    Python floats per row would take seconds per KITTI map)."""
    import numpy as np

    rows = np.array([m.shape[0] for m in maps], dtype=np.int64)
    widths = np.concatenate([np.full(m.shape[0], m.shape[1], np.int64) for m in maps] or [rows[:0]])
    flat = np.concatenate([m.ravel() for m in maps] or [np.empty(0, np.float32)]).astype(np.float32)
    inner = pa.ListArray.from_arrays(pa.array(np.concatenate([[0], np.cumsum(widths)]), pa.int32()),
                                     pa.array(flat, pa.float32()))
    return pa.ListArray.from_arrays(pa.array(np.concatenate([[0], np.cumsum(rows)]), pa.int32()), inner)


def member_name(item: Item, gt: bool) -> str:
    """A file's member in its tar shard: the image key, or for a ground-truth map
    ``<key stem>.depth.npy`` (a file of no image of the split: its path's stem)."""
    return stem(item.key or item.output) + DEPTH_NPY if gt else item.key


def stem(name: str) -> str:
    """The WebDataset sample key of a member: its path up to the first dot of the file name."""
    folder, base = posixpath.split(name)
    return posixpath.join(folder, base.split(".", 1)[0])


def write_tar(fh: BinaryIO, out: Path, shard: Shard, gt: bool, progress=None) -> list | None:
    """Write the shard; for the ground truth, return ``[path, key, sha256]`` of each map."""
    import tarfile

    from ..files import sha256_bytes
    from .groundtruth import npy_bytes

    maps = []
    with tarfile.open(fileobj=fh, mode="w", format=tarfile.PAX_FORMAT) as tar:
        for item, data in _payloads(out, shard, gt):
            name = member_name(item, gt)
            sha = item.sha256
            if gt:
                data = npy_bytes(data)
                sha = sha256_bytes(data)
                maps.append([item.output, item.key, sha])
            meta = {"key": item.key, "variant": item.variant, "level": item.level,
                    "seed": item.seed, "sha256": sha, "path": item.output}
            _add(tar, name, data)
            _add(tar, stem(name) + ".json", json.dumps(meta, sort_keys=True).encode())
            if progress:
                progress(item.size)
    return maps if gt else None


def _add(tar, name: str, data: bytes) -> None:
    import tarfile

    info = tarfile.TarInfo(name)
    info.size, info.mode, info.mtime = len(data), 0o644, 0
    tar.addfile(info, io.BytesIO(data))


WRITERS = {"parquet": write_parquet, "webdataset": write_tar}
