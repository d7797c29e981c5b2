"""The loop of ``robodepth run``: per variant, its images rendered in memory batch by batch,
predicted, and each map judged at once; only the metric rows are kept.

Variant by variant in the order of the results CSV, each in split order and in the batches
``robodepth predict`` makes (:func:`~robodepth_cli.models.predict.batch_limit`), so the
model sees the same batches and every number equals build -> predict -> evaluate's. A
model on a GPU gets the next batch rendered in a second thread while it runs on this one; a
model on the CPU gets them one after the other: its threads already use every core, and an
overlap would only add contention. A finished
variant's row goes into the state (:mod:`.state`) before the next one starts.
"""

from __future__ import annotations

import functools
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Callable, Sequence

import numpy as np

from ..api import Variant
from ..benchmark_facts import CLEAN
from ..errors import failure_reason
from ..evaluation.evaluate import Evaluation, VariantResult, variant_result
from ..evaluation.image import image_errors
from ..models import predict
from ..predictions import PredictionWriter, finished, remove_leftovers, split_digest
from ..building.renderers import Renderer
from ..sources.datasets import Job
from .inputs import RunError, RunInputs
from .state import RunState


def settings(inputs: RunInputs, model, setup, batch: int, engine: str) -> dict:
    """What decides the numbers of a variant besides the variant (see :mod:`.state`)."""
    from dataclasses import asdict

    record = model.record()
    cfg = inputs.cfg
    return {"dataset": inputs.ds.name, "root": str(inputs.root), "split": inputs.split["sha256"],
            "keys": split_digest(inputs.keys), "size": list(cfg.size) if cfg.size else None,
            "seed": cfg.seed, "engine": engine, "batch": batch,
            "model": {k: record[k] for k in ("model", "adapter", "identity", "options", "evaluate")},
            "setup": asdict(setup), "severity_size": cfg.options.severity_size or "none"}


def render_batch(renderer: Renderer, cleans: Sequence[np.ndarray], keys: Sequence[str],
                 paths: Sequence[str], job: Job) -> list[np.ndarray]:
    """The images of ``job`` for one batch of sources, as a build renders them."""
    if job.variant == CLEAN:
        return list(cleans)
    out = []
    for clean, key, path in zip(cleans, keys, paths):
        ((_, img),) = renderer.render(clean, key, [job])
        if isinstance(img, BaseException):
            level = "" if job.level is None else f" level {job.level}"
            raise RunError(f"{path}: {job.variant}{level}: {failure_reason(img)}")
        out.append(img)
    return out


@dataclass(frozen=True)
class RunContext:
    """What the loop judges with, made once by the session (:mod:`.session`): the inputs
    and their decoded clean images, the renderer, the model, the ground truth, the
    evaluation setup, the state, ``step`` images per batch (the batches of ``robodepth
    predict``) and ``keep``, where to also write the predictions (None: nowhere)."""

    inputs: RunInputs
    cleans: list[np.ndarray]
    renderer: Renderer
    model: Any
    truth: Any  # groundtruth.read.GroundTruth
    setup: Any  # evaluation.setup.EvaluationSetup
    state: RunState
    step: int
    keep: Path | None = None

    @property
    def bounds(self) -> list[tuple[int, int]]:
        """The batches, as (first, end) indices of the images."""
        n = len(self.cleans)
        return [(i, min(i + self.step, n)) for i in range(0, n, self.step)]


def run(ctx: RunContext, *, progress: Callable[[int], None] | None = None,
        on_total: Callable[[int], None] | None = None,
        on_clean: Callable[[dict], None] | None = None) -> tuple[Evaluation, int]:
    """Judge the model on every variant of the inputs; the evaluation (as ``robodepth
    evaluate`` makes it) and how many variants an earlier run had finished. With
    ``ctx.keep``, the predictions are also written there, in ``robodepth predict``'s
    layout; ``on_clean``: called with the clean variant's metrics when it is computed."""
    inputs, model, keep, state = ctx.inputs, ctx.model, ctx.keep, ctx.state
    n = len(ctx.cleans)
    result = Evaluation(inputs.ds.name, ctx.setup, str(keep) if keep else model.spec,
                        ctx.truth.source, n)
    record = None
    if keep is not None:
        record = predict.make_record(SimpleNamespace(name=inputs.ds.name, path=inputs.root, keys=inputs.keys),
                               model)
        predict.prepare_output(keep, record)
    todo, earlier = [], 0
    for variant, _ in inputs.variants:
        done = state.get(variant.relpath)
        if done is not None and (keep is None or finished(keep, variant)):
            earlier += 1
        else:
            todo.append(variant)
    if keep is not None:
        remove_leftovers(keep, todo)
    if on_total:
        on_total(n * len(todo))
    with (_Inline() if model.device == "cpu" else ThreadPoolExecutor(1)) as painter:
        for variant, job in inputs.variants:
            if variant not in todo:
                metrics, ratios = state.get(variant.relpath)
                result.results.append(VariantResult(variant, metrics, ratios))
                continue
            r = _judge(ctx, variant, job, painter, record, progress)
            record = None  # written with the first batch
            state.add(variant.relpath, r.metrics, r.ratios)
            result.results.append(r)
            if on_clean is not None and variant.name == CLEAN:
                on_clean(r.metrics)
    return result, earlier


class _Inline:
    """The executor interface of one worker thread, running each call at once, here."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def submit(self, fn, *args) -> Future:
        done = Future()
        done.set_result(fn(*args))
        return done


def _judge(ctx: RunContext, variant: Variant, job: Job, painter, record,
           progress: Callable[[int], None] | None) -> VariantResult:
    """One variant: its batches rendered by ``painter`` (the next while the model predicts
    this one), predicted and each map judged at once; ``record``: the predictions' record,
    written with the first batch (None: already written, or nothing kept)."""
    model, keep, keys = ctx.model, ctx.keep, ctx.inputs.keys
    paths = [s.path or s.rel for s in ctx.inputs.sources]
    bounds = ctx.bounds
    paint = [functools.partial(render_batch, ctx.renderer, ctx.cleans[a:b], keys[a:b], paths[a:b], job)
             for a, b in bounds]
    writer = PredictionWriter(variant.prediction_file(keep), len(ctx.cleans)) if keep is not None else None
    errors, ratios = [], []
    with writer if writer is not None else nullcontext() as out:
        pending = painter.submit(paint[0])
        for k, (a, _) in enumerate(bounds):
            images = pending.result()
            if k + 1 < len(bounds):
                pending = painter.submit(paint[k + 1])
            i = a
            for batch in predict.same_size_runs(images):
                if record is None:
                    maps = model.predict(batch)
                else:  # once the model has given a valid batch, as predict (its size too)
                    maps = predict.first_batch(model, batch, keep, record)
                    record = None
                for m in maps:
                    errs, ratio = image_errors(m, f"{model.spec}: {variant.label}: {variant.keys[i]}",
                                               ctx.truth.get(i), ctx.setup, ctx.inputs.cfg.size)
                    errors.append(errs)
                    if ratio is not None:
                        ratios.append(ratio)
                    if out is not None:
                        out.write(m)
                    i += 1
                if progress:
                    progress(len(batch))
    return variant_result(variant, errors, ratios, ctx.setup)
