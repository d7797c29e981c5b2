"""A built dataset from Python (docs/open-dataset.md): its variants, their images in split
order, and where a model's predictions go.

>>> from robodepth_cli import open_dataset
>>> ds = open_dataset("KITTI_C")                          # doctest: +SKIP
>>> for variant in ds.variants():                         # doctest: +SKIP
...     preds = [model(path) for path in variant.images()]
...     variant.save_predictions("PRED", preds)

:meth:`Variant.save_predictions` writes the form ``robodepth evaluate`` reads: one
N x h x w array per variant, image ``i`` being the ``i``-th image of the build's split."""

from __future__ import annotations

import io
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from .errors import InvalidValueError, RobodepthError
from .output.layout import (GT_DIR, GT_FILE, MANIFEST, RECORD, depth_gt_name, output_path,
                            variant_dir, variant_order)
from .output.record import BuildRecord



class DatasetError(RobodepthError):
    """A directory that is not a usable built dataset, or predictions that do not fit it."""


def read_output(root: Path, store, output: str) -> np.ndarray | None:
    """The image of the build's file ``output`` (its path in the build), from the build
    folder ``root`` or from an export's ``store``; None when the build has no such file."""
    from .imageio import read_rgb

    if store is not None:
        return np.asarray(read_rgb(io.BytesIO(store.read(output)))) if store.has(output) else None
    path = Path(root) / output
    return np.asarray(read_rgb(path)) if path.is_file() else None


def read_neighbours(root: Path, store, relpath: str, key: str, frames, like: np.ndarray) -> list:
    """The images of frame ``key``'s neighbours at the offsets ``frames`` in the variant
    directory ``relpath`` (named as ``build --frames`` writes them: :func:`robodepth_cli.sourcekeys.neighbour_key`),
    from a build or an export; a neighbour the build does not have is black (the shape of
    ``like``), as ManyDepth's loader makes a missing file."""
    from .sourcekeys import neighbour_key

    out = []
    for o in frames:
        near = neighbour_key(key, o)
        img = read_output(root, store, f"{relpath}/{near}") if near else None
        out.append(np.zeros_like(like) if img is None else img)
    return out


@dataclass(frozen=True)
class Variant:
    """One variant of a built dataset: the clean images, one corruption at one level
    (decimals included), a chain of corruptions (``fog:3+gaussian_noise:2.5``), or one
    style (KITTI-S). ``level`` is None for the clean images, chains and styles."""

    root: Path  # the dataset directory
    name: str
    level: int | float | None
    keys: tuple[str, ...]  # the split's image keys, in split order
    # The keys whose image of this variant the build did not make, each with the reason
    # (the manifest row's error, or "not built" when the build stopped before it).
    missing: dict[str, str] = field(default_factory=dict, compare=False)
    store: object = field(default=None, compare=False, repr=False)  # an export's; None: a build

    @property
    def relpath(self) -> str:
        """``clean``, ``<corruption>/<level>``, ``<chain directory name>`` or ``<style>``:
        the variant's directory in the dataset, and its prediction file's path in PRED
        without the extension."""
        return variant_dir(self.name, self.level)

    @property
    def label(self) -> str:
        """``clean``, ``<corruption> <level>`` or ``<style>``, for messages."""
        from .corruptions.severity import level_text

        return self.name if self.level is None else f"{self.name} {level_text(self.level)}"

    def __len__(self) -> int:
        return len(self.keys)

    def images(self, missing: str = "raise") -> list[Path]:
        """The variant's image files, in split order (image ``i`` is prediction ``i``).

        When the build failed to make some of them (see :attr:`missing`), ``missing="raise"``
        (the default) raises :class:`DatasetError` saying how many and which, before any of
        them is read; ``missing="skip"`` leaves them out and gives the ones that exist (their
        predictions then cover only part of the split: :meth:`save_predictions` wants
        every image). Rerunning the build command makes the missing ones. An export (no
        files) raises :class:`DatasetError`: use :meth:`read` or :meth:`open`.
        """
        if missing not in ("raise", "skip"):
            raise ValueError(f"missing={missing!r}: expected 'raise' or 'skip'")
        base = self.root / self.relpath
        if self.store is not None:
            raise DatasetError(f"{self.root}: an export's images are in shards; use variant.read(i)")
        if self.missing and missing == "raise":
            raise DatasetError(f"{base}: {failed_text(self.missing, len(self.keys))}; rerun the "
                               f"build command to make them, or use images(missing='skip') for "
                               f"the {len(self.keys) - len(self.missing)} that exist")
        return [base / key for key in self.keys if key not in self.missing]

    def open(self, i: int):
        """Image ``i``'s PNG as a binary file object, a build's file or an export's bytes
        (:class:`DatasetError` for an image the build did not make)."""
        if self.keys[i] in self.missing:
            raise DatasetError(f"{self.root / self.relpath / self.keys[i]}: {self.missing[self.keys[i]]}")
        if self.store is None:
            return open(self.root / self.relpath / self.keys[i], "rb")
        return io.BytesIO(self.store.read(f"{self.relpath}/{self.keys[i]}"))

    def read(self, i: int) -> np.ndarray:
        """Image ``i`` (H x W x 3 uint8) as :meth:`open` finds it: the same pixels either way."""
        from .imageio import read_rgb

        with self.open(i) as fh:  # a build's file by its path, so that errors name it
            return np.asarray(read_rgb(fh if self.store else self.root / self.relpath / self.keys[i]))

    def prediction_file(self, pred: str | os.PathLike) -> Path:
        """Where :meth:`save_predictions` writes: ``PRED/<relpath>.npy``."""
        from .predictions import prediction_file

        return prediction_file(pred, self.relpath)

    def save_predictions(self, pred: str | os.PathLike, predictions) -> Path:
        """Write a model's outputs for this variant as ``PRED/<relpath>.npy``; return the path.

        Parameters
        ----------
        pred : path
            The predictions directory (created if needed).
        predictions : array (N x h x w) or sequence of N arrays (h x w)
            One 2-D map per image, in the order of :meth:`images`: a disparity or a depth,
            whatever ``robodepth evaluate --kind`` will be told. Anything ``np.asarray``
            takes (CPU tensors too); a leading axis of length 1 per map (1 x h x w) is
            dropped. Floating dtypes are kept, others are stored as float32.

        The file is written through a temporary file and a rename, one map at a time (a
        list is never stacked into a second copy in memory). Raises :class:`DatasetError`
        for a wrong count, a map that is not 2-D, or maps of different sizes.
        """
        target = self.prediction_file(pred)
        n = len(predictions)
        if n != len(self.keys):
            raise DatasetError(f"{target}: {n} predictions for the {len(self.keys)} images of "
                               f"{self.label}")
        from .predictions import PredictionsError, PredictionWriter

        try:
            with PredictionWriter(target, n) as out:
                for i in range(n):
                    out.write(predictions[i])
        except PredictionsError as exc:
            raise DatasetError(str(exc)) from None
        return target


class BuiltDataset:
    """A dataset directory written by ``robodepth build`` (use :func:`open_dataset`)."""

    def __init__(self, path: Path, record: BuildRecord, keys: tuple[str, ...],
                 variants: Sequence[tuple[str, int | None]],
                 missing: dict[tuple, dict[str, str]] | None = None, store=None,
                 no_depth: dict[str, str] | None = None):
        self.path, self.store = path, store  # store: an export's files; None for a build
        # The images of a build with depth whose depth map the build could not use (missing,
        # unreadable, all invalid), each with the reason: they have no ground truth and no
        # depth-aware outputs, and rerunning the build cannot change that.
        self.no_depth: dict[str, str] = no_depth or {}
        self.record = record
        self.name: str = record.dataset
        self.keys = keys
        missing = missing or {}
        self._variants = tuple(Variant(path, v, lv, keys, missing.get((v, lv), {}), store)
                               for v, lv in variants)

    def __repr__(self) -> str:
        failed = self.failed
        return (f"<BuiltDataset {self.name} at {self.path}: {len(self._variants)} variants x "
                f"{len(self.keys)} images" + (f", {len(failed)} failed" if failed else "") + ">")

    @property
    def failed(self) -> dict[str, str]:
        """The source images (keys, in split order) with at least one output the build did
        not make, each with the first reason: {} after a build that exited 0."""
        reasons: dict[str, str] = {}
        for v in self._variants:
            for key, why in v.missing.items():
                if not self.lacks_depth(v, key):
                    reasons.setdefault(key, why)
        return {k: reasons[k] for k in self.keys if k in reasons}

    def lacks_depth(self, variant: Variant, key: str) -> bool:
        """Whether ``variant``'s image ``key`` is missing because its depth map is unusable
        (a depth-aware variant of an image in :attr:`no_depth`): not a failure to redo."""
        from .corruptions import depth_aware_variant

        return key in self.no_depth and depth_aware_variant(variant.name)

    def incomplete(self) -> str:
        """``"OUT: 2 of 697 images failed in the build (key: why; ...); rerunning the build
        command makes them"``, or "" when every image was made."""
        failed = self.failed
        if not failed:
            return ""
        return (f"{self.path}: {failed_text(failed, len(self.keys))}; rerunning the build "
                f"command makes them")

    @property
    def size(self) -> tuple[int, int] | None:
        """(H, W) of the built images, as the build record states it."""
        size = self.record.size
        return (int(size[0]), int(size[1])) if size else None

    def variants(self) -> list[Variant]:
        """Every variant the build has: clean first, then the corruptions (or styles) in the
        benchmark's order, levels ascending."""
        return list(self._variants)

    def variant(self, name: str, level: int | None = None) -> Variant:
        """The variant ``name`` at ``level`` (None for clean and styles); KeyError if absent."""
        for v in self._variants:
            if (v.name, v.level) == (name, level):
                return v
        raise KeyError((name, level))

    def depth_names(self) -> list[str]:
        """Per image, in split order, the relative path of its ground-truth PNG in a
        directory of them (a build's ``gt/``, BTS's test folder): the split line's DEPTH
        field (``bathroom/sync_depth_00045.png``) when the build's split file is still there
        unchanged, else BTS's naming, ``<scene>/rgb_NNNNN`` -> ``<scene>/sync_depth_NNNNN.png``
        (other names keep theirs, as ``.png``)."""
        if self._with_depth:
            return [depth_gt_name(k) for k in self.keys]  # float maps, <key stem>.npy
        listed = _split_depths(self.record)
        return [listed.get(k) or bts_depth_name(k) for k in self.keys]

    @property
    def _with_depth(self) -> bool:
        """Whether this is a build that pairs depth maps (custom --depth, a zero-shot set)."""
        from .sources.datasets import get_dataset

        return get_dataset(self.name).discovers_sources

    def ground_truth(self) -> Path | None:
        """The build's own ground truth (``gt_depths.npz`` for KITTI datasets, ``gt/`` for
        NYU and builds with depth), or None when it has none; an export's, copied out of its
        shards."""
        if self.store:
            return self.store.ground_truth()
        in_dir = self.name == "nyudepth2-c" or self._with_depth
        path = self.path / (GT_DIR if in_dir else GT_FILE)
        return path if path.exists() else None


def open_dataset(path: str | os.PathLike, *, warn: bool = True, meta: Path | None = None,
                 store=None) -> BuiltDataset:
    """Open a dataset directory written by ``robodepth build``; with ``meta`` (the folder
    holding its record and manifest) and ``store`` (``store(keys, manifest)``: the files by
    their path in the build), the export of one, whose images are read with
    :meth:`Variant.read` (:func:`robodepth_cli.open_dataset` passes them for an export).

    Reads ``build.json`` (the dataset and the split's image keys in order) and
    ``manifest.csv`` (which variants and levels were built, and which images failed).
    Raises :class:`DatasetError` naming the file when the directory is not a build or its
    record is unusable. A build that did not make every image (it exited 1) opens with an
    :class:`IncompleteBuild` warning (unless ``warn`` is False) saying how many images
    failed and which; :attr:`BuiltDataset.failed` lists them and
    ``variant.images(missing="skip")`` iterates the ones that exist.
    """
    from .sources.datasets import get_dataset
    from .output.folder import OutputFolder
    from .output.manifest import ManifestError

    path = Path(path)
    if not path.is_dir():
        raise DatasetError(f"{path}: not a directory (expected a dataset made by robodepth build)")
    meta = path if meta is None else meta
    record_path = meta / RECORD
    folder = OutputFolder(meta)
    record = folder.record()
    if record is None:
        raise DatasetError(f"{path}: no {RECORD}; not a dataset made by robodepth build")
    if not isinstance(record.dataset, str):
        raise DatasetError(f"{record_path}: not a robodepth build record (no dataset)")
    try:
        ds = get_dataset(record.dataset)
    except InvalidValueError as exc:
        raise DatasetError(f"{record_path}: {exc}") from None
    keys = _split_keys(record, record_path)
    try:
        rows = folder.rows()
    except ManifestError as exc:
        raise DatasetError(str(exc)) from None
    if not rows:
        raise DatasetError(f"{path}: no {MANIFEST} (or an empty one); was the build run to the end?")
    variants = variant_order(ds, {(r.variant, r.level) for r in rows.values()})
    store = store(keys, rows) if store is not None else None
    dataset = BuiltDataset(path, record, keys, variants, _missing(rows, keys, variants), store,
                           _no_depth(rows, keys) if ds.discovers_sources else None)
    if dataset.failed and warn:
        import warnings

        warnings.warn(IncompleteBuild(dataset.incomplete() + "; variant.images() raises for a "
                                      "variant without all of its images, variant.images("
                                      "missing='skip') gives the ones that exist, dataset.failed "
                                      "lists them"), stacklevel=2)
    return dataset


class IncompleteBuild(UserWarning):
    """:func:`open_dataset` of a build that did not make every image (it exited 1, or
    stopped early)."""


def _missing(rows: dict, keys: tuple[str, ...], variants) -> dict[tuple, dict[str, str]]:
    """Per variant, the keys whose output has no manifest row without an error, each with
    the reason."""
    missing = {}
    for v, lv in variants:
        gone = {}
        folder = output_path(v, lv, "")  # "<variant dir>/": the keys' paths follow it
        for key in keys:
            row = rows.get(folder + key)
            if row is None or row.error:
                gone[key] = row.error if row is not None else "not built (the build stopped before it)"
        if gone:
            missing[(v, lv)] = gone
    return missing


def _no_depth(rows: dict, keys: tuple[str, ...]) -> dict[str, str]:
    """The keys whose ground truth (``gt/<key stem>.npy``) the build failed, with the reason."""
    found = {}
    for key in keys:
        row = rows.get(f"{GT_DIR}/{depth_gt_name(key)}")
        if row is not None and row.error:
            found[key] = row.error
    return found


def failed_text(failed: dict[str, str], total: int, shown: int = 3) -> str:
    """``"2 of 697 images failed in the build (a.png: why; b.png: why)"``."""
    listed = "; ".join(f"{k}: {why}" for k, why in list(failed.items())[:shown])
    more = f"; and {len(failed) - shown} more" if len(failed) > shown else ""
    return (f"{len(failed)} of {total} image{'s' if total != 1 else ''} failed in the build "
            f"({listed}{more})")


def _split_keys(record: BuildRecord, record_path: Path) -> tuple[str, ...]:
    """The split's image keys in order, as the record lists them."""
    if not record.keys:
        raise DatasetError(f"{record_path}: lists no split keys; not a finished robodepth build record")
    return tuple(record.keys)


def bts_depth_name(key: str) -> str:
    """``<scene>/rgb_NNNNN.png`` -> ``<scene>/sync_depth_NNNNN.png`` (BTS's test folder)."""
    from pathlib import PurePosixPath

    p = PurePosixPath(key)
    name = p.stem
    if name.startswith("rgb_"):
        name = "sync_depth_" + name[len("rgb_"):]
    return str(p.with_name(name + ".png"))


def _split_depths(record: BuildRecord) -> dict[str, str]:
    """{image key: DEPTH field} from the build's NYU-format split file, if it is still
    there and unchanged; {} otherwise (or for other formats)."""
    from .sources.datasets import read_split
    from .sources.splits import SplitError
    from .files import sha256_bytes

    split = record.split
    try:
        data = Path(split["path"]).read_bytes()
    except (KeyError, TypeError, OSError):
        return {}
    if sha256_bytes(data) != split.get("sha256"):
        return {}
    try:
        entries = read_split(Path(split["path"]), "nyu", data)
    except SplitError:
        return {}  # not an NYU-format split
    return {e.key: e.fields[1] for e in entries}
