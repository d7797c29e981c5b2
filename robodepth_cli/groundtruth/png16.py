"""The one reader of 16-bit single-channel PNGs, the form of depth maps (BTS's NYU
``sync_depth`` files, PNG predictions, a custom build's ``--depth`` PNGs): OpenCV's decoder,
whatever reads them. Each caller words the refusal for its own file (ground truth, a
prediction, a depth map), from :attr:`Png16Error.got`."""

from __future__ import annotations

import os
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..errors import RobodepthError, os_reason

SIGNATURE = b"\x89PNG\r\n\x1a\n"


class Png16Error(RobodepthError):
    """Not a 16-bit single-channel PNG: ``got`` is ``""`` for bytes no PNG decoder reads
    (truncated, damaged, not a PNG) and else what it is (``8-bit``, ``16-bit, 3 channels``);
    ``raw`` the decoded array, when there is one."""

    def __init__(self, got: str, raw: np.ndarray | None = None):
        super().__init__(got or "not a readable PNG")
        self.got = got
        self.raw = raw


@contextmanager
def _native_stderr_silenced():
    """File descriptor 2 sent to /dev/null: libpng prints ``libpng error: Read Error`` there
    for a truncated file before OpenCV returns None; the one-line error says it instead."""
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def read_png16(source: Path | bytes) -> np.ndarray:
    """The ``H x W`` uint16 map of a PNG file (a path; :class:`OSError` as reading raises
    it) or of its bytes; :class:`Png16Error` for anything else."""
    import cv2

    data = source if isinstance(source, bytes) else Path(source).read_bytes()
    raw = None
    if data[:8] == SIGNATURE:
        with _native_stderr_silenced():
            raw = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if raw is None:
        raise Png16Error("")
    if raw.ndim != 2 or raw.dtype != np.uint16:
        raise Png16Error(f"{raw.dtype.itemsize * 8}-bit" + (f", {raw.shape[2]} channels" if raw.ndim == 3 else ""),
                         raw)
    return raw


def read_depth_png(file: Path, what: str, error: type[RobodepthError]) -> np.ndarray:
    """:func:`read_png16` of ``file`` with the refusals as ``error`` naming it; ``what``
    says whose file it is (``ground truth of image 3``)."""
    if not file.is_file():
        raise error(f"{file}: no such file ({what})")
    try:
        return read_png16(file)
    except OSError as exc:
        raise error(f"{file}: cannot read ({os_reason(exc)}) ({what})") from None
    except Png16Error as exc:
        if not exc.got:
            raise error(f"{file}: not a readable PNG, truncated or damaged ({what})") from None
        raise error(f"{file}: {exc.got}; expected a 16-bit single-channel PNG ({what})") from None
