"""``robodepth predict PUBLIC``: a model's predictions for a challenge's public folder,
written straight as a valid submission (a zip holding ``disp.npz``, one map per image id,
the keyed form) in the order of ``list.txt``.

Track kitti takes disparities: a model's disparity as it is, a sigmoid output through
monodepth2's ``disp_to_depth``, a depth map inverted (median scaling makes the scale
irrelevant). Track nyu takes depth in metres: only a metric depth model qualifies.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import RobodepthError
from . import layout


def is_public_folder(path: Path) -> bool:
    """Whether ``path`` is a challenge's public folder (challenge.json, list.txt, images/)."""
    return (Path(path) / layout.META).is_file() and (Path(path) / layout.LIST).is_file() \
        and (Path(path) / layout.IMAGES).is_dir()


def as_submission_map(m: np.ndarray, kind: str, metric: bool, track: str, spec: str) -> np.ndarray:
    """One model map as the track's submission takes it (see the module docstring)."""
    from ..evaluation.protocols import disp_to_depth

    if track == "nyu":
        if kind != "depth" or not metric:
            raise RobodepthError(f"{spec}: track nyu takes metric depth in metres; this model gives "
                                 f"{'relative ' if not metric else ''}{kind} maps (--kind depth --metric "
                                 "for a python: model that gives metres)")
        return m.astype(np.float32)
    if kind == "sigmoid":
        m = disp_to_depth(m)
    elif kind == "depth":
        with np.errstate(divide="ignore"):
            m = 1 / m
    return m.astype(np.float32)


def predict_submission(public: Path, model, out: Path, batch_size: int = 8,
                       progress: Callable[[int], None] | None = None) -> int:
    """Run ``model`` over the public folder's images in list order and write ``out`` (a
    zip holding ``disp.npz``); returns the number of maps. Each map is checked as the server
    checks it; ``out`` appears whole or not at all."""
    from ..files import atomic_output
    from ..imageio import read_rgb
    from .npzfile import write_npz
    from .submission import check_map

    meta = layout.read_meta(str(public))
    ids = layout.read_list(str(public))

    def maps():
        for start in range(0, len(ids), batch_size):
            chunk = ids[start:start + batch_size]
            images = [np.asarray(read_rgb(Path(public) / layout.IMAGES / f"{i}.png")) for i in chunk]
            done = 0
            while done < len(images):  # one forward pass per run of one image size
                end = done + 1
                while end < len(images) and images[end].shape == images[done].shape:
                    end += 1
                for k, m in enumerate(model.predict(np.stack(images[done:end]))):
                    image_id = chunk[done + k]
                    m = as_submission_map(m, model.kind, model.metric, meta["track"], model.spec)
                    check_map(m, f"{model.spec}: image {image_id}")
                    yield image_id, m
                if progress:
                    progress(end - done)
                done = end

    out = Path(out)
    npz = out.with_name(f".{out.name}.disp.npz.tmp")
    try:
        with open(npz, "wb") as fh:
            write_npz(fh, maps())
        with atomic_output(out) as fh, zipfile.ZipFile(fh, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            info = zipfile.ZipInfo("disp.npz", date_time=(1980, 1, 1, 0, 0, 0))
            info.external_attr = 0o644 << 16
            with open(npz, "rb") as src, zf.open(info, "w", force_zip64=True) as dst:
                for block in iter(lambda: src.read(1 << 20), b""):
                    dst.write(block)
    finally:
        if npz.exists():
            os.unlink(npz)
    return len(ids)
