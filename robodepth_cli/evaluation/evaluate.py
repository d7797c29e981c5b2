"""``robodepth evaluate``: a model's predictions on a built dataset, scored under the
protocol of its benchmark (:mod:`.protocols`) against its ground truth
(:mod:`robodepth_cli.groundtruth.read`), into the results CSV that ``robodepth score`` reads.

With ``jobs`` > 1 the variants are shared out among this process and ``jobs - 1`` worker
processes, each evaluating whole variants with the same code as one job, so the numbers
are the same to the last bit; this process evaluates the first ones while the workers
start. The ground truth is read once, by this process, and handed to the workers as one
read-only mapped file (the page cache holds it once); a worker holds one variant's predictions at a
time (a block of maps for a ``.npy`` (:mod:`.batch`), one for per-image files, the whole
array for a ``.npz``).
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..api import BuiltDataset, Variant
from ..benchmark_facts import CLEAN
from ..errors import counted
from ..groundtruth.depthmaps import NoValidPixel
from ..groundtruth.read import GroundTruth, load_ground_truth
from ..predictions import Predictions, find_predictions
from .aspect import aspect_warnings
from .csvrows import DATASET_COLUMNS, SEVERITY_COLUMN, ResultsTable
from .batch import BLOCK, plan
from .image import image_errors
from .kernels import median
from .protocols import EvaluationError, Setup

# A worker takes about a second to start (a fresh interpreter importing numpy and OpenCV),
# the time of some 500 maps: a smaller evaluation gets fewer workers, down to none.
MAPS_PER_WORKER = 500

@dataclass
class VariantResult:
    variant: Variant
    metrics: dict[str, float]  # mean over the images
    ratios: np.ndarray | None = None  # median-scaling ratio per image (mono kitti only)
    flicker: dict[str, float] | None = None  # with --flicker: flicker.COLUMNS
    # Images left out: their ground truth has no valid pixel (position -> why).
    left_out: dict[int, str] = field(default_factory=dict)

    @property
    def csv_key(self) -> tuple[str, int]:
        """(corruption, level) as the results CSV names it: clean and styles have level 0."""
        return self.variant.name, self.variant.level or 0

    def ratio_summary(self) -> tuple[float, float] | None:
        """(median of the ratios, std of ratio / median), as monodepth2 prints them."""
        if self.ratios is None or not len(self.ratios):
            return None
        med = np.median(self.ratios)
        return float(med), float(np.std(self.ratios / med))


@dataclass
class Evaluation:
    dataset: str
    setup: Setup
    predictions: str
    ground_truth: str
    images: int  # per variant
    results: list[VariantResult] = field(default_factory=list)
    missing: list[Variant] = field(default_factory=list)  # no predictions (--allow-partial)
    pairs: int = 0  # consecutive frame pairs the flicker is measured on (0: not measured)
    # Images left out of every variant: no ground truth, their depth map being unusable
    # (key -> the build's reason); the metrics are the means over the others.
    left_out: dict[str, str] = field(default_factory=dict)
    split: str = ""  # the build's named subset (drivingstereo-c's weather), else ""
    warnings: list[str] = field(default_factory=list)  # e.g. aspect ratios far apart (.aspect)

    @property
    def columns(self) -> tuple[str, ...]:
        """The metrics, then (``--flicker``) the flicker measures."""
        from .flicker import COLUMNS

        return self.setup.metrics + (COLUMNS if self.pairs else ())

    def table(self, severity_size: str | None = None, comments=()) -> ResultsTable:
        """The results CSV: ``corruption,level`` then the metrics (and the flicker
        measures), full float precision (``repr``), then the ``dataset`` and ``split`` the
        results are on, and with a ``severity_size`` (a build's, not none) a last column of
        it; one row per variant, under the ``comments`` lines."""
        rows = []
        for r in self.results:
            name, level = r.csv_key
            values = {**r.metrics, **(r.flicker or {})}
            rows.append([name, level] + [repr(values[m]) for m in self.columns] + [self.dataset, self.split])
        table = ResultsTable.of(("corruption", "level") + self.columns + DATASET_COLUMNS, rows, comments,
                                source=self.dataset)
        return table if severity_size in (None, "none") else table.with_column(SEVERITY_COLUMN, severity_size)

    def to_json(self) -> dict:
        rows = []
        for r in self.results:
            name, level = r.csv_key
            row = {"corruption": name, "level": level, **r.metrics, **(r.flicker or {})}
            summary = r.ratio_summary()
            if summary:
                row["scaling_ratio"] = {"median": summary[0], "std": summary[1]}
            rows.append(row)
        return {"dataset": self.dataset, "split": self.split, "protocol": self.setup.protocol,
                "kind": self.setup.kind, "stereo": self.setup.stereo,
                "median_scaling": self.setup.median_scaling, "align": self.setup.alignment,
                "align_space": self.setup.align_space, "crop": self.setup.crop_name,
                "min_depth": self.setup.min_depth, "max_depth": self.setup.depth_cap,
                "predictions": self.predictions,
                "ground_truth": self.ground_truth, "images": self.images, "results": rows,
                "partial": bool(self.missing),
                **({"flicker_pairs": self.pairs} if self.pairs else {}),
                "missing": [{"corruption": v.name, "level": v.level or 0} for v in self.missing]}

    def summary(self) -> str:
        """A table of the metrics per variant (3 decimals) and, with median scaling, the
        ratios' median and spread per variant as monodepth2 prints them."""
        metrics = self.columns
        width = max([len("variant")] + [len(r.variant.label) for r in self.results]) + 2
        widths = [max(10, len(m) + 2) for m in metrics]  # flicker_abs_rel is longer than a number
        head = f"{'variant':<{width}}" + "".join(f"{m:>{w}}" for m, w in zip(metrics, widths))
        if self.setup.median_scaling:
            head += f"{'ratio med':>11}{'std':>7}"
        lines = [f"{self.dataset}: {counted(len(self.results), 'variant')} x {counted(self.images, 'image')}, "
                 f"{self.setup.describe()}", head]
        for r in self.results:
            values = {**r.metrics, **(r.flicker or {})}
            line = f"{r.variant.label:<{width}}" + "".join(f"{values[m]:>{w}.3f}"
                                                           for m, w in zip(metrics, widths))
            summary = r.ratio_summary()
            if summary:
                line += f"{summary[0]:>11.3f}{summary[1]:>7.3f}"
            lines.append(line)
        if self.pairs:
            lines.append(f"flicker over {self.pairs} pairs of consecutive frames")
        if self.missing:
            lines.append(f"partial: no predictions for {counted(len(self.missing), 'variant')}: "
                         f"{_list(self.missing)}")
        return "\n".join(lines) + "\n"


def split_name(dataset: BuiltDataset) -> str:
    """The named subset a build of a preset with several was made of (drivingstereo-c's
    ``foggy``), "" for every other build: what ``report --on DATASET:SPLIT`` calls a split."""
    from ..sources.datasets import DATASETS

    named = dict(getattr(DATASETS.get(dataset.name), "splits", ()))
    split = dataset.record.config.get("split")
    return split if isinstance(split, str) and split in named else ""


def _list(variants: Sequence[Variant], most: int = 12) -> str:
    """``"brightness 3, contrast 1,3"``: the notation of ``robodepth score``'s messages."""
    from .results import describe_variants

    return describe_variants(((v.name, v.level) for v in variants), most=most)


def evaluate(dataset: BuiltDataset, pred: Path, setup: Setup, *, gt: Path | None = None,
             allow_partial: bool = False, require_clean: bool = False,
             progress: Callable[[int], None] | None = None,
             on_total: Callable[[int], None] | None = None, jobs: int = 1,
             flicker: bool = False) -> Evaluation:
    """Evaluate the predictions under ``pred`` for every variant of ``dataset``.

    Everything that can be checked without reading the data is checked first: the
    predictions of every variant (presence, count, shape) and the ground truth (present,
    one map per split image). Missing variants are an error unless ``allow_partial``.
    ``progress(n)`` is called as images are done; ``on_total(n)`` once with their number.
    ``jobs``: processes, this one included (1: all in this process; see the module docstring), never
    more than the variants nor one per :data:`MAPS_PER_WORKER` maps. ``flicker``: also
    the flicker measures over the consecutive frames of the split (:mod:`.flicker`).
    Raises :class:`EvaluationError` for any bad input (with several jobs, the one of the
    first variant in order that has one, as with one job); nothing is written here.
    """
    pred = Path(pred)
    if not pred.is_dir():
        raise EvaluationError(f"{pred}: no such predictions directory")
    found, missing = _find_all(dataset, pred, setup, allow_partial, require_clean)
    setup = _kind_read(setup, found)
    pairs = None
    if flicker:
        from .flicker import check_pairs

        pairs = check_pairs(dataset.keys, setup.protocol, dataset.record.split.get("frames"))
    gt_path = _ground_truth_path(dataset, gt)
    names = dataset.depth_names() if gt_path.is_dir() else dataset.keys
    absent = {i for i, k in enumerate(dataset.keys) if k in dataset.no_depth} if gt is None else set()
    # Handed over in a list that the callee empties: with workers, it drops the maps once
    # shared, and nothing here keeps a second copy.
    truth = [load_ground_truth(gt_path, names, setup.protocol, setup.valid, absent=absent,
                               rule=setup.valid_rule)]
    aspect = aspect_warnings(found, truth[0].shapes, dataset.size)
    n = len(dataset.keys)
    if on_total:
        on_total(n * len(found))
    result = Evaluation(dataset.name, setup, str(pred), str(gt_path), n, missing=missing,
                        pairs=len(pairs or ()), split=split_name(dataset),
                        left_out={dataset.keys[i]: dataset.no_depth[dataset.keys[i]] for i in sorted(absent)},
                        warnings=aspect)
    jobs = min(jobs, len(found), -(-n * len(found) // MAPS_PER_WORKER))
    result.results = _evaluate_all(found, truth, setup, dataset.size, progress, pairs, jobs)
    return _with_left_out(result, dataset)


def _evaluate_all(found: list[tuple[Variant, Predictions]], held: list[GroundTruth], setup: Setup,
                  image_size, progress, pairs, jobs: int) -> list[VariantResult]:
    """Every variant's result, in ``jobs`` processes, this one among them; the ground truth is
    taken out of ``held``."""
    truth = held.pop()
    if jobs > 1:
        import tempfile

        with tempfile.TemporaryDirectory(prefix="robodepth-evaluate-") as tmp:
            shared = _shared(truth, Path(tmp) / "ground_truth.bin")
            # This process evaluates too: from a mapped file (the cache's, or the workers'),
            # not from maps read into memory, which would hold them twice.
            if truth.mapped is None:
                truth = shared.open()
            return _evaluate_in_workers(found, shared, truth, setup, image_size, progress, pairs, jobs)
    results, cache = [], {}
    for v, p in found:
        try:
            results.append(_evaluate_variant(v, p, truth, setup, image_size, progress, pairs, cache))
        finally:
            p.close()
    return results


def _shared(truth: GroundTruth, path: Path):
    """``truth`` in a file at ``path`` for the workers to map: a link to the cache's file
    when it is mapped from one (the cache may drop its entry meanwhile), else written."""
    mapped = truth.mapped
    if mapped is not None:
        try:
            os.link(mapped.path, path)
            return mapped.moved(str(path))
        except OSError:
            pass  # another file system: written
    return truth.share(path)


def _with_left_out(result: Evaluation, dataset: BuiltDataset) -> Evaluation:
    """``result`` with the images its variants left out (no valid ground-truth pixel)."""
    for r in result.results:
        for i, why in r.left_out.items():
            result.left_out.setdefault(dataset.keys[i], why)
    return result


def _find_all(dataset: BuiltDataset, pred: Path, setup: Setup, allow_partial: bool,
              require_clean: bool) -> tuple[list[tuple[Variant, Predictions]], list[Variant]]:
    """``(found, missing)``: each variant's predictions under ``pred`` (checked for count
    and shape), and the variants without; refused when none are there, when some are
    missing without ``allow_partial``, or the clean ones with ``require_clean``."""
    variants = dataset.variants()
    found: list[tuple[Variant, Predictions]] = []
    missing: list[Variant] = []
    for v in variants:
        p = find_predictions(pred, v, setup.png_scale)
        if p is None:
            missing.append(v)
        else:
            found.append((v, p))
    if not found:
        raise EvaluationError(f"{pred}: no predictions for any of the {len(variants)} variants of "
                              f"{dataset.path} (expected e.g. {variants[0].prediction_file(pred)})")
    if missing and not allow_partial:
        raise EvaluationError(f"{pred}: no predictions for {len(missing)} of {len(variants)} "
                              f"variants: {_list(missing)} (--allow-partial evaluates the rest)")
    if require_clean and variants[0].name == CLEAN and variants[0] in missing:
        raise EvaluationError(f"{pred}: no predictions for the clean images; the scores need "
                              "them (resilience rates divide by the clean DEE)")
    return found, missing


def _ground_truth_path(dataset: BuiltDataset, gt: Path | None) -> Path:
    """``--gt``, or the build's own ground truth; refused when there is none."""
    gt_path = gt if gt is not None else dataset.ground_truth()
    if gt_path is None:
        raise EvaluationError(f"{dataset.path}: no ground truth (gt_depths.npz for KITTI, gt/ for "
                              "NYU and builds with --depth); build it with ground truth, run "
                              "robodepth gt, or pass --gt")
    return Path(gt_path)


def _kind_read(setup: Setup, found: Sequence[tuple[Variant, Predictions]]) -> Setup:
    """The setup with the kind the predictions are actually read as: 16-bit PNGs hold
    depths, so predictions that are all PNGs are depths (another --kind, or --stereo, is
    refused), and PNGs beside arrays are refused unless the arrays are depths too."""
    pngs = [(v, p) for v, p in found if p.is_png]
    if not pngs:
        return setup
    v, p = pngs[0]
    if len(pngs) < len(found) and setup.kind != "depth":
        other = next(q for _, q in found if not q.is_png)
        raise EvaluationError(f"{p.source}: PNG predictions (depth) beside .npy predictions read "
                              f"as {setup.kind} ({other.source}); give every variant in one "
                              "form, or --kind depth if the arrays hold depths too")
    if setup.kind_given and setup.kind != "depth":
        raise EvaluationError(f"{p.source}: PNG predictions are depths (value / --png-scale), "
                              f"not --kind {setup.kind}")
    return replace(setup, kind="depth")


def _evaluate_in_workers(found: list[tuple[Variant, Predictions]], shared, truth: GroundTruth,
                         setup: Setup, image_size, progress, pairs, jobs: int) -> list[VariantResult]:
    """:func:`_evaluate_variant` of every variant in this process and ``jobs - 1`` worker
    processes, which map the ground truth ``shared`` (:meth:`GroundTruth.share`; ``truth``:
    this process's map of it); results in variant order."""
    from ..workers import in_order

    cache: dict = {}

    def here(variant, preds, setup, image_size, pairs):
        try:
            return _evaluate_variant(variant, preds, truth, setup, image_size, None, pairs, cache)
        finally:
            preds.close()

    results = []
    tasks = [(v, p, setup, image_size, pairs) for v, p in found]
    for (v, _), r in zip(found, in_order(_worker_variant, tasks, jobs, _start_worker, (shared,), here=here)):
        results.append(r)
        if progress:
            progress(len(v))
    return results


_WORKER_TRUTH: GroundTruth | None = None
_WORKER_CACHE: dict = {}  # _evaluate_variant's cache


def _start_worker(shared) -> None:
    global _WORKER_TRUTH
    _WORKER_CACHE.clear()  # that of another evaluation's ground truth
    # One OpenCV thread (one process per core already), told by its variable rather than
    # by importing cv2 now (0.08 s of a worker's start): the block calls never use it.
    os.environ["OPENCV_FOR_THREADS_NUM"] = "1"
    if "cv2" in sys.modules:  # imported already: its thread count is fixed, set it
        sys.modules["cv2"].setNumThreads(1)
    _WORKER_TRUTH = shared.open()


def _worker_variant(variant: Variant, preds: Predictions, setup: Setup, image_size,
                    pairs=None) -> VariantResult:
    try:
        return _evaluate_variant(variant, preds, _WORKER_TRUTH, setup, image_size, None, pairs,
                                 _WORKER_CACHE)
    finally:
        preds.close()


def _evaluate_variant(variant: Variant, preds: Predictions, truth: GroundTruth, setup: Setup,
                      image_size, progress, pairs=None, cache: dict | None = None) -> VariantResult:
    """The metrics of one variant; with ``pairs`` (consecutive frames), its flicker too.
    ``cache``: what depends on the ground truth only (each image's median, the block
    calls' plan), kept across the variants of one evaluation."""
    cache = {} if cache is None else cache
    errors = []
    ratios = []
    scales = []
    left_out = {}
    blocks = None if pairs else plan(preds, truth, setup, cache)
    for first in range(0, len(variant), BLOCK):
        last = min(first + BLOCK, len(variant))
        if blocks is not None:
            ok, out, block_ratios = blocks.judge(preds.block(first, last), first, last)
        for i in range(first, last):
            if blocks is not None and ok[i - first]:
                errors.append(out[i - first, :len(setup.metrics)])
                if setup.median_scaling:
                    ratios.append(block_ratios[i - first])
                continue
            _one_image(i, preds, truth, setup, image_size, pairs, cache, errors, ratios, scales, left_out)
        if progress:
            progress(last - first)
    flicker = None
    if pairs:
        from .flicker import measure

        try:
            flicker = measure(scales, [e[0] for e in errors], pairs)
        except EvaluationError as exc:
            raise EvaluationError(f"{preds.source}: {exc}") from None
    if not errors:
        raise EvaluationError(f"{preds.source}: no image of {variant.label} has usable ground truth"
                              + (f" ({next(iter(left_out.values()))})" if left_out else ""))
    result = variant_result(variant, errors, ratios, setup, flicker)
    result.left_out = left_out
    return result


def _one_image(i: int, preds: Predictions, truth: GroundTruth, setup: Setup, image_size, pairs,
               cache: dict, errors: list, ratios: list, scales: list, left_out: dict) -> None:
    """Image ``i`` judged alone (:func:`image_errors`), its results added to the lists."""
    # A map kept whole is judged in one pass over it (image_errors); flicker's scale
    # needs the valid pixels themselves.
    whole = None if pairs else truth.dense(i)
    try:
        gt = truth.get(i) if whole is None else None  # once: flicker reads it too
    except NoValidPixel as exc:
        if pairs:
            raise
        gt, left_out[i] = None, str(exc)
    if gt is None and whole is None:  # an image without ground truth (Evaluation.left_out)
        return
    m, where, is_png = preds.read(i)
    if gt is not None and setup.median_scaling and setup.align_space == "depth":
        if ("median", i) not in cache:
            cache["median", i] = median(gt[2])
        errs, ratio = image_errors(m, where, gt, setup, image_size, is_png, gt_median=cache["median", i])
    else:
        errs, ratio = image_errors(m, where, gt, setup, image_size, is_png, whole=whole)
    if ratio is not None:
        ratios.append(ratio)
    errors.append(errs)
    if pairs:
        from .flicker import frame_scale

        m = m if m.dtype in (np.float32, np.float64) else m.astype(np.float32)
        scales.append(frame_scale(m, setup.kind, *gt))


def variant_result(variant: Variant, errors: Sequence, ratios: Sequence, setup: Setup,
                   flicker=None) -> VariantResult:
    """A variant's row from its images' metrics (:func:`image_errors`), in split order."""
    means = np.array(errors, dtype=np.float64).mean(0)
    return VariantResult(variant, {k: float(v) for k, v in zip(setup.metrics, means)},
                         np.array(ratios, dtype=np.float64) if setup.median_scaling else None,
                         flicker)


