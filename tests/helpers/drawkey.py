"""The draw key of ``corrupt`` and ``preview`` without ``--as``, written from the documented
rule: ``"pixels:"`` and the sha256 of the image array's shape, dtype and bytes."""

from __future__ import annotations

import hashlib

import numpy as np


def pixels_key(img: np.ndarray) -> str:
    head = f"{img.shape}|{img.dtype.str}|".encode("ascii")
    return "pixels:" + hashlib.sha256(head + np.ascontiguousarray(img).tobytes()).hexdigest()
