"""Writing one shard: parquet (the Hugging Face layout) or tar (WebDataset).

Every file's bytes are read from the build once, hashed, and refused unless the hash is
the manifest's: what an export holds is provably what the build made. Memory holds one
row group (:data:`ROW_GROUP` images) of a parquet shard, one file of a tar shard.

Parquet rows: ``key``, ``variant``, ``level`` (null without levels), ``seed``, ``sha256``
and ``image`` (Hugging Face's Image feature: ``{bytes, path}``, the PNG as built and its
path in the build); the ground truth's rows have ``path`` and ``data`` (the file's bytes)
instead of ``image``. The features are in the schema's ``huggingface`` metadata, where the
``datasets`` library reads them.

Tar samples (one per image of the shard's variant): ``<key>.png`` (the key is the image's
path in the split, so members keep the benchmark's tree) and ``<key stem>.json`` with the
row's key, variant, level, seed, sha256 and path in the build. Members are written with
fixed owner, mode and time, so the same build gives the same bytes.
"""

from __future__ import annotations

import io
import json
import posixpath
from pathlib import Path
from typing import BinaryIO, Iterator

from ..files import sha256_bytes
from .plan import ExportError, Item, Shard

ROW_GROUP = 64  # images per parquet row group: the unit a reader fetches

_VALUE = {"_type": "Value"}
FEATURES = {"key": {**_VALUE, "dtype": "string"}, "variant": {**_VALUE, "dtype": "string"},
            "level": {**_VALUE, "dtype": "float64"}, "seed": {**_VALUE, "dtype": "int64"},
            "sha256": {**_VALUE, "dtype": "string"}}
IMAGE_FEATURES = {**FEATURES, "image": {"_type": "Image"}}
GT_FEATURES = {**FEATURES, "path": {**_VALUE, "dtype": "string"},
               "data": {**_VALUE, "dtype": "large_binary"}}


def _schema(gt: bool):
    import pyarrow as pa

    base = [("key", pa.string()), ("variant", pa.string()), ("level", pa.float64()),
            ("seed", pa.int64()), ("sha256", pa.string())]
    if gt:
        cols, features = [*base, ("path", pa.string()), ("data", pa.large_binary())], GT_FEATURES
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


def _payloads(out: Path, shard: Shard) -> Iterator[tuple[Item, bytes]]:
    for item in shard.items:
        yield item, read_checked(out, item)


def write_parquet(fh: BinaryIO, out: Path, shard: Shard, gt: bool, progress=None) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema = _schema(gt)
    # PNG and npz bytes do not compress further, and no two are alike: stored as they are,
    # without dictionaries or min/max statistics of the blobs (time spent for nothing).
    with pq.ParquetWriter(fh, schema, compression="none", use_dictionary=False,
                          write_statistics=["key", "variant", "level", "seed"]) as writer:
        batch: list[tuple[Item, bytes]] = []
        for pair in _payloads(out, shard):
            batch.append(pair)
            if len(batch) == ROW_GROUP:
                writer.write_table(_table(pa, schema, batch, gt), row_group_size=ROW_GROUP)
                _tick(progress, batch)
                batch = []
        if batch or not shard.items:
            writer.write_table(_table(pa, schema, batch, gt), row_group_size=ROW_GROUP)
            _tick(progress, batch)


def _tick(progress, batch) -> None:
    if progress:
        progress(sum(i.size for i, _ in batch))


def _table(pa, schema, batch, gt: bool):
    items = [i for i, _ in batch]
    cols = {"key": [i.key for i in items], "variant": [i.variant for i in items],
            "level": [None if i.level is None else float(i.level) for i in items],
            "seed": [i.seed for i in items], "sha256": [i.sha256 for i in items]}
    if gt:
        cols["path"] = [i.output for i in items]
        cols["data"] = [d for _, d in batch]
    else:
        cols["image"] = [{"bytes": d, "path": i.output} for i, d in batch]
    return pa.Table.from_pydict(cols, schema=schema)


def member_name(item: Item, gt: bool) -> str:
    """A file's member in its tar shard: the image key, or the ground truth's path in the
    build."""
    return item.output if gt else item.key


def stem(name: str) -> str:
    """The WebDataset sample key of a member: its path up to the first dot of the file name."""
    folder, base = posixpath.split(name)
    return posixpath.join(folder, base.split(".", 1)[0])


def write_tar(fh: BinaryIO, out: Path, shard: Shard, gt: bool, progress=None) -> None:
    import tarfile

    with tarfile.open(fileobj=fh, mode="w", format=tarfile.PAX_FORMAT) as tar:
        for item, data in _payloads(out, shard):
            name = member_name(item, gt)
            meta = {"key": item.key, "variant": item.variant, "level": item.level,
                    "seed": item.seed, "sha256": item.sha256, "path": item.output}
            _add(tar, name, data)
            _add(tar, stem(name) + ".json", json.dumps(meta, sort_keys=True).encode())
            if progress:
                progress(item.size)


def _add(tar, name: str, data: bytes) -> None:
    import tarfile

    info = tarfile.TarInfo(name)
    info.size, info.mode, info.mtime = len(data), 0o644, 0
    tar.addfile(info, io.BytesIO(data))


WRITERS = {"parquet": write_parquet, "webdataset": write_tar}
