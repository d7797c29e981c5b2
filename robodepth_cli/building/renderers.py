"""The renderers of a build (:func:`make_renderer`): the corruptions' (numpy engine), the
torch engine's and KITTI-S's styles (:mod:`robodepth_cli.styles.inputs`).

Which engine renders a corruption build, and where: the ``engine`` and ``device`` options
of the corruption datasets (kitti-c, kitti-c-hr, nyudepth2-c, custom).

``engine: numpy`` (the default) is the numpy engine, image by image on the CPU: the
published builds' bytes. ``engine: torch`` renders with
:mod:`robodepth_cli.corruptions.torch_engine` on ``device`` (``auto``: a CUDA GPU when torch
sees one, else the CPU), with the same per-image random streams; its outputs' manifest
rows carry the fingerprint ``engine=torch``, so a build never mixes the two engines'
files: switching engine in one OUT makes the outputs again. torch is imported only when
the torch engine is asked for.
"""

from __future__ import annotations

import threading
from dataclasses import replace
from typing import Iterator, Protocol, Sequence

import numpy as np

from ..benchmark_facts import TEMPORAL
from ..errors import InvalidValueError, reraise_interrupt
from ..output.layout import SEVERITY_SIZE, TORCH_FINGERPRINT
from ..sources.datasets import Dataset, Job, Options, StyleDataset


class Renderer(Protocol):
    """Renders the non-clean jobs of one source image. Must pickle small (it is sent to the
    workers) and load anything heavy lazily, once per process."""

    def render(self, clean: np.ndarray, key: str,
               jobs: Sequence[Job]) -> Iterator[tuple[Job, np.ndarray | Exception]]:
        """Yield ``(job, image)`` for every job, or ``(job, exception)`` for a job that failed
        on its own; ``clean`` is read-only."""

    def fingerprint(self, variant: str) -> str:
        """What, besides the seed and the size, decides ``variant``'s pixels ("" if nothing).
        A manifest row made with another fingerprint is redone."""


def make_renderer(ds: Dataset, config, depth=None) -> Renderer:
    """The renderer of a build of ``ds``; ``depth`` the depth source when the build has
    depth-aware variants."""
    if isinstance(ds, StyleDataset):
        from ..styles.inputs import make_renderer as style_renderer

        return style_renderer(config)
    from ..corruptions.scaling import parse_severity_size

    numpy_engine = CorruptionRenderer(ds.name, config.seed, depth,
                                      parse_severity_size(config.options.severity_size))
    if config.options.engine == "torch":
        return TorchCorruptionRenderer(ds.name, config.seed, config.options.device, config.jobs,
                                       numpy_engine)
    return numpy_engine


def settle(options: Options, where: dict[str, str],
           preset: set[str] = frozenset()) -> tuple[Options, list[str]]:
    """``options`` with ``engine`` (default numpy) and ``device`` decided: ``cpu`` for the
    numpy engine (``cuda`` is refused: it has no GPU path), the device
    ``auto`` picks for torch (``cuda`` refused when torch sees no GPU). ``where`` names the
    flag or file that set each key, for the messages; ``preset``: the keys the preset set.
    Returned with the notes the build prints (one line each).

    ``severity_size`` is recorded either way (``none`` when unset); the torch engine does not
    scale the levels to a severity size: a preset's gives way to ``none`` (with a note), one
    asked for is refused."""
    options = replace(options, severity_size=options.severity_size or "none")
    engine = options.engine or "numpy"
    device = options.device
    if engine == "numpy":
        if device == "cuda":
            raise InvalidValueError(f"{where.get('device', '--device')}: {device} needs --engine torch "
                                    f"(the numpy engine runs on the CPU)")
        return replace(options, engine=engine, device="cpu"), []
    size = options.severity_size
    notes = []
    if size != "none" and "severity_size" in preset:
        options = replace(options, severity_size="none")
        notes.append(f"{where.get('engine', '--engine')} torch: the levels are not scaled to the "
                     f"preset's severity size {size} (severity size none: each level as tabulated, "
                     f"at any image size; --engine numpy scales them)")
    elif size != "none":
        raise InvalidValueError(f"{where.get('engine', '--engine')}: the torch engine does not scale the "
                                f"levels to a severity size ({size}, from {where['severity_size']}); use "
                                f"--engine numpy, or --severity-size none")
    from ..corruptions.torch_engine import resolve_device

    try:
        chosen = resolve_device(device or "auto")
    except InvalidValueError as exc:
        raise exc.at(where.get("device", "--device")) from None
    return replace(options, engine=engine, device=chosen.type), notes


class TorchCorruptionRenderer:
    """The torch engine's renderer: one source image's jobs, each with the generators of
    :func:`robodepth_cli.corruptions.render`, on ``device``."""

    def __init__(self, dataset: str, seed: int, device: str, jobs: int = 1, numpy_engine=None):
        self.dataset = dataset
        # The depth-aware corruptions have no torch port: their jobs go to the numpy engine.
        self.numpy_engine = numpy_engine
        self.seed = seed
        self.device = device
        # Several local workers share the cores: one torch thread each, as OpenCV gets.
        self.threads = 1 if jobs > 1 and device == "cpu" else None

    def render(self, clean, key, jobs):
        from ..corruptions import needs_depth, torch_engine

        jobs = list(jobs)
        on_cpu = [job for job in jobs if needs_depth(job.variant)]
        jobs = [job for job in jobs if not needs_depth(job.variant)]
        if on_cpu:
            yield from self.numpy_engine.render(clean, key, on_cpu)

        if self.threads:
            import torch

            torch.set_num_threads(self.threads)
        batch = torch_engine.to_batch([clean], torch_engine.resolve_device(self.device))
        for job in jobs:
            try:
                out = torch_engine.render_batch(batch, job.variant, job.level, seed=self.seed,
                                                dataset=self.dataset, keys=[key])
                yield job, torch_engine.from_batch(out)[0]
            except Exception as exc:  # one broken variant must not sink the other outputs
                reraise_interrupt(exc)
                yield job, exc

    def fingerprint(self, variant: str) -> str:
        from ..corruptions import needs_depth

        return self.numpy_engine.fingerprint(variant) if needs_depth(variant) else TORCH_FINGERPRINT

    def depth_stamp(self, key: str) -> str:
        return self.numpy_engine.depth_stamp(key) if self.numpy_engine is not None else ""


# The corrupted sequences of the last test frame rendered in this process (see
# CorruptionRenderer._over_time): test frame key -> {key: frames}.
_SEQUENCES: dict[str, dict] = {}
_SEQUENCES_LOCK = threading.Lock()


class CorruptionRenderer:
    """Applies the corruptions, each job with its own generator (see :mod:`robodepth_cli.seeding`);
    the depth-aware ones get the source's depth from ``depth`` (a
    :class:`~.scenedepth.DepthSource`), read once per source and only when a job needs it."""

    def __init__(self, dataset: str, seed: int, depth=None, severity_size: tuple[int, int] | None = None):
        self.dataset = dataset
        self.seed = seed
        self.depth = depth
        self.severity_size = severity_size  # (H0, W0): see corruptions.scaling; None: as tabulated

    def render(self, clean, key, jobs, anchor=None, sequence=None):
        """``anchor``: the key of the test frame whose sequence ``key`` is in (``--frames``);
        ``sequence``: (its clean frames, this frame's index, the test frame's index), for
        the corruptions over time."""
        from ..corruptions import needs_depth, render

        depth: object = None
        for job in jobs:
            try:
                if sequence is not None and job.variant in TEMPORAL:
                    yield job, self._over_time(job, anchor, *sequence)
                    continue
                if depth is None and self.depth is not None and needs_depth(job.variant):
                    depth = self.depth.depth(key, clean.shape[:2])
                yield job, render(clean, job.variant, job.level, seed=self.seed, dataset=self.dataset,
                                  key=key, depth=depth, anchor=None if anchor == key else anchor,
                                  severity_size=self.severity_size)
            except Exception as exc:  # one broken variant must not sink the other outputs
                reraise_interrupt(exc)
                yield job, exc

    def _over_time(self, job, anchor, frames, position, center):
        """Frame ``position`` of the sequence ``frames`` under a corruption over time. The
        other frames of a sequence usually come next to the same worker, so the corrupted
        sequences of the last test frame are kept (keyed by everything they depend on)."""
        import hashlib

        from ..corruptions.temporal import corrupt_sequence
        from ..seeding import job_rng

        digest = hashlib.sha256()
        for f in frames:
            digest.update(b"-" if f is None else f.tobytes() + str(f.shape).encode())
        key = (self.seed, self.dataset, job.variant, job.level, anchor, center, digest.hexdigest())
        with _SEQUENCES_LOCK:  # a Dask worker runs tasks in threads
            for other in [a for a in _SEQUENCES if a != anchor]:
                del _SEQUENCES[other]  # another test frame's sequence: the last one is done with
            done = _SEQUENCES.setdefault(anchor, {}).get(key)
        if done is None:
            rng = job_rng(self.seed, self.dataset, job.variant, job.level, anchor)
            done = corrupt_sequence(job.variant, frames, center, job.level, rng)
            with _SEQUENCES_LOCK:
                _SEQUENCES.setdefault(anchor, {})[key] = done
        return done[position]

    def fingerprint(self, variant: str) -> str:
        # A corruption's output depends only on the seed, the size and the source, a
        # depth-aware one's on the depth source too, a spatial one's on the severity size.
        from ..corruptions import is_scaled, needs_depth
        from ..corruptions.scaling import size_text

        parts = [self.depth.fingerprint] if self.depth is not None and needs_depth(variant) else []
        if self.severity_size is not None and is_scaled(variant):
            parts.append(SEVERITY_SIZE + size_text(self.severity_size))
        return ";".join(parts)

    def depth_stamp(self, key: str) -> str:
        """What identifies source ``key``'s depth (:meth:`.scenedepth.DepthSource.stamp`)."""
        return self.depth.stamp(key) if self.depth is not None else ""
