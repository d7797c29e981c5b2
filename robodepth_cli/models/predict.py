"""``robodepth predict``: run a model over the variants of a built dataset and write its
predictions where ``robodepth evaluate`` reads them (docs/predict.md).

Each variant's file (or, for a build without one image size, folder of per-image ``.npy``)
is streamed into a temporary name renamed into place when complete, so a killed run loses
at most the variant in flight and a rerun skips the finished ones. ``predictions.json`` is
written once the model has produced its first valid batch; a later run into the same PRED
must be of the same model on the same dataset's split. A batch holds at most
:data:`BATCH_PIXELS` pixels (:func:`batch_limit`)."""

from __future__ import annotations

import functools
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from .. import __version__
from ..api import BuiltDataset, Variant
from ..benchmark_facts import CLEAN
from ..errors import RobodepthError, cannot_write
from ..predictions import (RECORD, ImageFilesWriter, PredictionWriter, finished, read_record, write_record,
                           remove_leftovers, split_digest)
from .size import measured

# The most pixels one forward pass holds: the memory of a batch (its images, the model's
# float copies and activations) grows with its pixels. 2**22: 34 images of 192 x 640, 9 of
# 375 x 1242, 13 of 480 x 640, so the default 8 is never lowered on the benchmarks; a
# ResNet-18 monodepth2 on the CPU peaks at about 1.75 GB there (0.7 GB at 8 images, 3.1 GB
# at 68: about 41 MB per 192 x 640 image).
BATCH_PIXELS = 1 << 22
# What must agree for a run to add to an earlier one's predictions.
_SAME = ("adapter", "identity", "options", "evaluate")


@dataclass
class PredictRun:
    written: list[Variant] = field(default_factory=list)
    skipped: list[Variant] = field(default_factory=list)  # finished by an earlier run
    # Images without a usable depth map (key -> reason): their depth-aware images do not
    # exist, and their predictions there are NaN (evaluate leaves these images out).
    no_depth: dict[str, str] = field(default_factory=dict)


def select_variants(dataset: BuiltDataset, value: str | None) -> list[Variant]:
    """The variants ``value`` names (comma-separated ``clean``, ``<corruption>`` for all its
    built levels, ``<corruption>/<level>``, ``<style>``), in the build's order; all of them
    when ``value`` is None or ``all``."""
    variants = dataset.variants()
    if value is None or value.strip() == "all":
        return variants
    chosen = set()
    for item in (s.strip() for s in value.split(",")):
        if not item:
            continue
        hits = [v for v in variants if item in (v.relpath, v.name)]
        if not hits:
            names = sorted({v.name for v in variants}, key=[v.name for v in variants].index)
            raise RobodepthError(f"--variants {item!r}: not a variant of {dataset.path} (it has: "
                                 f"{', '.join(names)}; a corruption's level as NAME/LEVEL)")
        chosen.update(hits)
    if not chosen:
        raise RobodepthError(f"--variants {value!r}: names no variant")
    return [v for v in variants if v in chosen]


def make_record(dataset: BuiltDataset, model) -> dict:
    return {"robodepth_version": __version__, "dataset": dataset.name,
            "dataset_path": str(dataset.path), "split_sha256": split_digest(dataset.keys),
            "images": len(dataset.keys), **model.record()}


def _pixels(size) -> int | None:
    """``height x width`` of a size given as ``(h, w)`` or as a processor's
    ``{"height": h, "width": w}``; None for anything else (``{"shortest_edge": 384}``)."""
    if isinstance(size, dict):
        size = (size.get("height"), size.get("width"))
    if (isinstance(size, (list, tuple)) and len(size) == 2
            and all(isinstance(v, int) and v > 0 for v in size)):
        return size[0] * size[1]
    return None


def batch_limit(requested: int, image_size, input_size=None) -> int:
    """The images per batch for ``requested`` (``--batch-size``) under :data:`BATCH_PIXELS`,
    each image counted at the larger of its own size and the network's input size; at
    least 1. An unknown image size leaves ``requested`` as it is (the per-image form
    limits each batch as it reads it)."""
    pixels = max(_pixels(image_size) or 0, _pixels(input_size) or 0)
    if pixels == 0:
        return requested
    return max(1, min(requested, BATCH_PIXELS // pixels))


def _chunks(variant: Variant, batch_size: int, image_size, input_size, per_item: int = 1,
            opens=None) -> list[range]:
    """The positions of ``variant``'s images in batches of at most ``batch_size`` items and
    :data:`BATCH_PIXELS` pixels, an item holding ``per_item`` images (a multi-frame model's
    frame and neighbours); a build without one size reads each image's size from its
    header (a build's file or an export's bytes: :meth:`Variant.open`, or ``opens(i)``)."""
    n = len(variant)
    if image_size is not None:
        step = max(1, batch_limit(batch_size, image_size, input_size) // per_item)
        return [range(i, min(i + step, n)) for i in range(0, n, step)]
    from PIL import Image

    per_input = _pixels(input_size) or 0
    chunks, start, held = [], 0, 0
    for i in range(n):
        with (opens or variant.open)(i) as fh, Image.open(fh) as im:
            pixels = max(im.width * im.height, per_input) * per_item
        if i > start and (i - start == batch_size or held + pixels > BATCH_PIXELS):
            chunks.append(range(start, i))
            start, held = i, 0
        held += pixels
    return chunks + ([range(start, n)] if n > start else [])


def check_outside(dataset: BuiltDataset, pred: Path) -> None:
    """Refuse a PRED that is the dataset's folder or lies inside it (symlinks resolved):
    the build's manifest lists every file there, so ``verify`` would fail on the
    predictions, and a rebuild could delete them."""
    d, p = Path(os.path.realpath(dataset.path)), Path(os.path.realpath(pred))
    if p == d or p.is_relative_to(d):
        raise RobodepthError(f"--out {pred}: inside the dataset {dataset.path}, whose files its "
                             "manifest lists (verify would report the predictions as extra files); "
                             "give a folder outside it")


def prepare_output(pred: Path, record: dict) -> bool:
    """Check that PRED can hold these predictions before any work: it is writable, and it
    is new, empty, or an earlier run's of the same model on the same split. Returns
    whether PRED was created here (so that a run failing before its first file removes it)."""
    pred = Path(pred)
    if pred.exists() and not pred.is_dir():
        raise RobodepthError(f"--out {pred}: exists and is not a folder")
    earlier = read_record(pred) if pred.is_dir() else None
    if earlier is not None:
        if earlier.get("split_sha256") != record["split_sha256"]:
            raise RobodepthError(f"--out {pred}: holds predictions for another dataset or split "
                                 f"({earlier.get('dataset_path')}); use another --out")
        for key in _SAME:
            if earlier.get(key) != record.get(key):
                why = (" (its weights, or a python: module's file, changed since)"
                       if key == "identity" else "")
                raise RobodepthError(f"--out {pred}: holds predictions of another model or setting "
                                     f"({earlier.get('model')}, {key} differs{why}); use another "
                                     "--out or delete it")
    elif pred.is_dir() and any(pred.iterdir()):
        raise RobodepthError(f"--out {pred}: not empty and holds no {RECORD} (not written by "
                             "robodepth predict); use a new or empty folder")
    created = not pred.exists()
    try:
        pred.mkdir(parents=True, exist_ok=True)
        probe = pred / f".{RECORD}.probe"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise RobodepthError(cannot_write(pred, exc, "--out")) from None
    return created


def _read_images(variant: Variant, indices: range) -> list[np.ndarray]:
    return [variant.read(i) for i in indices]


def _read_sequences(variant: Variant, indices: range, frames: tuple[int, ...]) -> list[np.ndarray]:
    """For a multi-frame model: per image, an ``F x H x W x 3`` stack of it and its
    neighbours at ``frames`` (the same variant's files of frame ``n + offset``, from the
    build's folder or an export's shards; a neighbour the build does not have is black)."""
    from ..api import read_neighbours

    out = []
    for i in indices:
        frame = variant.read(i)
        near = read_neighbours(variant.root, variant.store, variant.relpath, variant.keys[i],
                               frames, frame)
        out.append(np.stack([frame, *near]))
    return out


def check_frames(dataset: BuiltDataset, model) -> None:
    """A multi-frame model needs a build with those neighbours (``build --frames``)."""
    lacking = sorted(set(model.frames) - dataset.record.frames)
    if lacking:
        raise RobodepthError(f"{model.spec} takes the neighbour frames {', '.join(map(str, model.frames))}; "
                             f"{dataset.path} has no neighbours at {', '.join(map(str, lacking))} "
                             f"(build it with --frames {','.join(map(str, model.frames))})")


def same_size_runs(images: list[np.ndarray]):
    """Consecutive images of one size, as ``N x H x W x 3`` batches."""
    start = 0
    for i in range(1, len(images) + 1):
        if i == len(images) or images[i].shape != images[start].shape:
            yield np.stack(images[start:i])
            start = i


def predict(dataset: BuiltDataset, model, pred: Path, variants: Sequence[Variant], *,
            batch_size: int = 8, progress: Callable[[int], None] | None = None,
            on_total: Callable[[int], None] | None = None) -> PredictRun:
    """Write ``model``'s predictions for ``variants`` of ``dataset`` under ``pred``.

    Variants whose files an earlier run finished are skipped. Raises
    :class:`~robodepth_cli.errors.RobodepthError` for bad input or output; the variant in flight is then not written.
    """
    if batch_size < 1:
        raise RobodepthError(f"--batch-size {batch_size}: must be at least 1")
    frames = tuple(getattr(model, "frames", ()))  # a multi-frame model's neighbours
    if frames:
        check_frames(dataset, model)
    read = functools.partial(_read_sequences, frames=frames) if frames else _read_images
    pred = Path(pred)
    check_outside(dataset, pred)
    record = make_record(dataset, model)
    created = prepare_output(pred, record)
    recorded = read_record(pred) is not None
    run = PredictRun()
    todo = []
    for v in variants:
        (run.skipped if finished(pred, v) else todo).append(v)
    remove_leftovers(pred, todo)
    if on_total:
        on_total(sum(len(v) for v in todo))
    try:
        with ThreadPoolExecutor(1) as reader:
            for v in todo:
                lacking = _lacking(dataset, v, run)
                read_v = _stand_in(read, dataset, lacking)
                n = len(v)
                chunks = _chunks(v, batch_size, dataset.size, model.input_size, 1 + len(frames),
                                 _opens(dataset, v, lacking))
                out_writer = (ImageFilesWriter(pred, v) if dataset.size is None
                              else PredictionWriter(v.prediction_file(pred), n))
                with out_writer as out:
                    pending = reader.submit(read_v, v, chunks[0]) if chunks else None
                    for k in range(len(chunks)):
                        images = pending.result()
                        pending = (reader.submit(read_v, v, chunks[k + 1])
                                   if k + 1 < len(chunks) else None)
                        at = chunks[k].start
                        for batch in same_size_runs(images):
                            maps = model.predict(batch) if recorded else first_batch(model, batch, pred, record)
                            recorded = True
                            for m in maps:
                                out.write(_no_prediction(m) if at in lacking else m)
                                at += 1
                            if progress:
                                progress(len(batch))
                run.written.append(v)
    except BaseException:
        if created and recorded is False:
            _remove_empty(pred)
        raise
    return run


def first_batch(model, batch: np.ndarray, pred: Path, record: dict) -> np.ndarray:
    """The maps of the run's first batch, its model's size measured on it (torch models) and
    the record written with it."""
    maps, size = measured(model, batch)
    if size is not None:
        record["size"] = size
    write_record(pred, record)
    return maps


def _lacking(dataset: BuiltDataset, v: Variant, run: PredictRun) -> set[int]:
    """The positions of ``v``'s images that are missing because their depth map is unusable
    (noted in ``run.no_depth``); :class:`RobodepthError` for an image the build failed otherwise
    (a rerun makes it)."""
    if not v.missing:
        return set()
    from ..api import failed_text

    other = {k: why for k, why in v.missing.items() if not dataset.lacks_depth(v, k)}
    if other:
        raise RobodepthError(f"{dataset.path / v.relpath}: {failed_text(other, len(v))}; rerun the "
                             "build command to make them, or leave this variant out with --variants")
    run.no_depth.update({k: dataset.no_depth[k] for k in v.missing})
    return {i for i, k in enumerate(v.keys) if k in v.missing}


def _stand_in(read, dataset: BuiltDataset, lacking: set[int]):
    """``read`` with the clean image standing in for each image at ``lacking`` (so that its
    prediction has the shape of the others; :func:`_no_prediction` then replaces it)."""
    if not lacking:
        return read
    clean = dataset.variant(CLEAN)

    def read_some(v: Variant, indices: range) -> list[np.ndarray]:
        return [clean.read(i) if i in lacking else v.read(i) for i in indices]

    return read_some


def _opens(dataset: BuiltDataset, v: Variant, lacking: set[int]):
    """``v.open``, with the clean image standing in at ``lacking`` (its size is the same)."""
    if not lacking:
        return None
    clean = dataset.variant(CLEAN)
    return lambda i: clean.open(i) if i in lacking else v.open(i)


def _no_prediction(m: np.ndarray) -> np.ndarray:
    """The prediction written for an image that does not exist: NaN (0 for integer maps)."""
    return np.full_like(m, np.nan) if m.dtype.kind == "f" else np.zeros_like(m)


def _remove_empty(pred: Path) -> None:
    for root, _, files in os.walk(pred, topdown=False):
        if files:
            return
        try:
            os.rmdir(root)
        except OSError:
            return
