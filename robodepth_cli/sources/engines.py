"""Which engine renders a corruption build, and where: the ``engine`` and ``device`` options
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

from ..errors import InvalidValueError

OPTIONS = ("engine", "device")  # config keys (and flags --engine, --device)
ENGINES = ("numpy", "torch")
DEVICES = ("auto", "cpu", "cuda")
TORCH_FINGERPRINT = "engine=torch"


def check_option(key: str, value):
    """The checked text of ``engine`` or ``device``; :class:`InvalidValueError` otherwise."""
    choices = ENGINES if key == "engine" else DEVICES
    if value is None:
        return None
    if value not in choices:
        raise InvalidValueError(f"expected one of {', '.join(choices)}, got {value!r}")
    return value


def settle(extra: dict, where: dict[str, str], preset: set[str] = frozenset()) -> dict:
    """``extra`` with ``engine`` (default numpy) and ``device`` decided: ``cpu`` for the
    numpy engine (``cuda`` is refused: it has no GPU path), the device
    ``auto`` picks for torch (``cuda`` refused when torch sees no GPU). ``where`` names the
    flag or file that set each key, for the messages; ``preset``: the keys the preset set.

    ``severity_size`` is recorded either way (``none`` when unset); the torch engine does not
    scale the levels to a severity size: a preset's gives way to ``none``, one asked for is
    refused."""
    extra = {**extra, "severity_size": extra.get("severity_size") or "none"}
    engine = extra.get("engine") or "numpy"
    device = extra.get("device")
    if engine == "numpy":
        if device == "cuda":
            raise InvalidValueError(f"{where.get('device', '--device')}: {device} needs --engine torch "
                                    f"(the numpy engine runs on the CPU)")
        return {**extra, "engine": engine, "device": "cpu"}
    size = extra["severity_size"]
    if size != "none" and "severity_size" in preset:
        extra = {**extra, "severity_size": "none"}
    elif size != "none":
        raise InvalidValueError(f"{where.get('engine', '--engine')}: the torch engine does not scale the "
                                f"levels to a severity size ({size}, from {where['severity_size']}); use "
                                f"--engine numpy, or --severity-size none")
    from ..corruptions.torch_engine import resolve_device

    try:
        chosen = resolve_device(device or "auto")
    except InvalidValueError as exc:
        raise InvalidValueError(f"{where.get('device', '--device')}: {exc}") from None
    return {**extra, "engine": engine, "device": chosen.type}


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
                yield job, exc

    def fingerprint(self, variant: str) -> str:
        from ..corruptions import needs_depth

        return self.numpy_engine.fingerprint(variant) if needs_depth(variant) else TORCH_FINGERPRINT
