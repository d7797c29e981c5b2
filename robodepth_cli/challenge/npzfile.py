"""Writing ``.npz`` files whose bytes depend only on their arrays.

``np.savez`` stamps every member with the current time, so two runs give different bytes;
:func:`write_npz` gives each member a fixed time (1980-01-01, the zip format's first day),
and never pickles. Read back with ``np.load(path, allow_pickle=False)``.
"""

from __future__ import annotations

import zipfile
from typing import Iterable

import numpy as np

_EPOCH = (1980, 1, 1, 0, 0, 0)


def write_npz(fh, members: Iterable[tuple[str, np.ndarray]], compress: bool = True) -> None:
    """Write ``(name, array)`` pairs into the binary file ``fh`` as an npz: member
    ``<name>.npy`` per array, deflated (``compress``) or stored, in the order given."""
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(fh, "w", compression=method, allowZip64=True) as zf:
        for name, array in members:
            info = zipfile.ZipInfo(f"{name}.npy", date_time=_EPOCH)
            info.compress_type = method
            info.external_attr = 0o644 << 16
            with zf.open(info, "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.ascontiguousarray(array), allow_pickle=False)
