"""Depth files written by the tests from the formats' own specifications, not by the
library that robodepth reads them with."""

from __future__ import annotations

import struct
import zlib


def png16(path, values):
    """A 16-bit greyscale PNG written from the PNG specification (IHDR bit depth 16,
    colour type 0, big-endian samples, filter type 0 on every row)."""
    h, w = values.shape

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    rows = b"".join(b"\0" + values[r].astype(">u2").tobytes() for r in range(h))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def depth_stamp(*files) -> str:
    """The stamp a depth-aware output's manifest row ends with (``;map=<stamp>``): the sha256
    of the hex sha256s of the files its depth is made from, joined by spaces."""
    import hashlib

    return hashlib.sha256(" ".join(hashlib.sha256(f.read_bytes()).hexdigest()
                                   for f in files).encode()).hexdigest()
