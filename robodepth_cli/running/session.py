"""One ``robodepth run`` from its settings to its results CSV: the configuration, the
sources decoded once, the model, the evaluation setup, the resumable state and the loop
(:mod:`.loop`); the command only parses the flags and prints."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable


@dataclass(frozen=True)
class RunSettings:
    """One run's settings, as the command parsed them: the dataset made in memory from
    ``root`` (``config_file`` and ``flags``, the selection flags, as for build), the model
    ``spec`` with how it runs and what its maps hold, ``evaluation`` (the evaluate flags:
    stereo, align, align_space, crop, min_depth, max_depth), the results CSV ``out`` and
    ``keep``, the predictions' folder (None: not kept)."""

    dataset: str
    root: Path
    out: Path
    spec: str
    config_file: Path | None = None
    flags: dict = field(default_factory=dict)
    engine: str = "numpy"
    batch_size: int = 8
    device: str = "auto"
    post_process: bool = False
    kind: str | None = None
    metric: bool | None = None
    evaluation: dict = field(default_factory=dict)
    keep: Path | None = None
    progress: bool = True


def run(settings: RunSettings, *, note: Callable[[str], None], on_state: Callable[[Path], None]):
    """Judge the model on the dataset as ``settings`` say; write the results CSV and return
    ``(result, its results table, the benchmark scored, whether the CSV was replaced)``.
    ``note`` prints a line for the user; ``on_state`` is told the state file once the
    decoding is done (the run then resumes from it)."""
    from ..building.config import resolve
    from ..evaluation.configure import evaluation_setup, scored_benchmark
    from ..evaluation.modelsize import with_size
    from ..files import check_writable
    from ..models import load_model
    from ..models.predict import BATCH_PIXELS, batch_limit
    from ..predictions import RECORD
    from ..progress import bar as progress_bar
    from . import inputs as inputs_mod, loop
    from .state import RunState

    s, out = settings, settings.out
    check_writable(out, "--out")
    if s.keep is not None:
        check_writable(s.keep / RECORD, "--keep-predictions")
    cfg = resolve(s.dataset, s.config_file, {**s.flags, **inputs_mod.engine_flags(s.engine, s.device)})
    inputs = inputs_mod.gather(cfg, s.root, out)
    bench = scored_benchmark(cfg.dataset, [v for v, _ in inputs.variants])
    model = load_model(s.spec, device=s.device, kind=s.kind, metric=s.metric,
                       post_process=s.post_process)
    setup, _ = evaluation_setup(cfg.dataset, model.record()["evaluate"], None, s.kind, png_scale=None,
                                **s.evaluation)
    renderer = inputs_mod.renderer(inputs)
    step = batch_limit(s.batch_size, cfg.size, model.input_size)
    if step < s.batch_size:
        note(f"robodepth: --batch-size {s.batch_size}: {step} images per batch (a batch "
             f"holds at most {BATCH_PIXELS:,} pixels)")
    state = RunState.open(out, loop.settings(inputs, model, setup, step, s.engine))
    state.check_writable()
    if state.note:
        note(f"robodepth: {state.note}")
    with progress_bar("img", len(inputs.sources), progress=s.progress, desc="decoding") as bar:
        cleans = inputs_mod.decode(inputs, bar.update)
    truth = inputs_mod.ground_truth(inputs, setup)
    on_state(state.path)
    context = loop.RunContext(inputs, cleans, renderer, model, truth, setup, state, step, s.keep)
    with progress_bar("img", progress=s.progress, desc="run") as bar:
        def set_total(n):
            bar.reset(total=n)

        result, earlier = loop.run(context, progress=bar.update, on_total=set_total,
                                   on_clean=_early_warning(bench, setup, note))
    if earlier:
        note(f"robodepth: {earlier} of {len(inputs.variants)} variants taken from "
             f"{state.path} (finished by an earlier run)")
    replacing = out.exists()
    table = replace(with_size(result.table(cfg.options.severity_size), {"size": _size(model, cleans)}),
                    source=str(out))
    table.write(out)
    state.remove()
    return result, table, bench, replacing


def _size(model, cleans) -> dict | None:
    """The model's size (models/size.py) measured on the first clean image, as predict
    measures it on its first batch (the FLOPs per image do not depend on the batch)."""
    import numpy as np

    from ..models.size import measured

    first = cleans[0]
    frames = tuple(getattr(model, "frames", ()))
    batch = np.stack([first] * (1 + len(frames)))[None] if frames else first[None]
    return measured(model, batch)[1]


def _early_warning(bench, setup, note: Callable[[str], None]):
    """What to do with the clean variant's metrics as soon as they are known: with scores
    to come, warn at once when its DEE is implausible, so that a mixed-up --kind or
    --stereo can be stopped (Ctrl-C) before the other variants are computed."""
    from ..evaluation.results import implausible_dee

    def check(metrics: dict) -> None:
        text = implausible_dee(metrics, setup) if bench is not None else ""
        if text:
            note(f"robodepth: warning: {text}; if one of them is wrong, Ctrl-C now and rerun "
                 "with it right (the finished variants are kept)")
    return check
