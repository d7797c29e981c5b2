"""Corruptions over time: they act on a test frame's sequence (its neighbours from
``build --frames`` and itself, in time order), not on one image; docs/video.md gives each
one and its levels.

Each is a pure function ``(frames, center, level, rng) -> frames``: ``frames`` the clean
uint8 images in time order (None where the drive has no frame, and None stays None),
``center`` the test frame's index. All draws are the sequence's (seeded from the test
frame's key), so every frame of a sequence is cut from the same corrupted video. A decimal
level interpolates the level table linearly (a CRF rounded to an integer)."""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from ..benchmark_facts import TEMPORAL

P_LEVELS = (0.2, 0.4, 0.6, 0.8, 1.0)
LEVELS: dict[str, tuple[float, ...]] = {
    "frame_lost": P_LEVELS,
    "frame_freeze": P_LEVELS,
    "h264_crf": (18, 26, 34, 42, 51),
    "h265_crf": (18, 26, 34, 42, 51),
    "bit_error": (1e-6, 3e-6, 1e-5, 3e-5, 1e-4),
}
assert tuple(LEVELS) == TEMPORAL
BIT_ERROR_CRF = 23  # libx264's default quality

Frames = Sequence[np.ndarray | None]


def parameter(name: str, level) -> float:
    """The parameter of ``name`` at ``level`` (1..5, decimals interpolated)."""
    table = LEVELS[name]
    lo = min(int(np.floor(level)), len(table)) - 1
    hi = min(lo + 1, len(table) - 1)
    return table[lo] + (table[hi] - table[lo]) * (float(level) - (lo + 1))


def _neighbour_draws(frames: Frames, rng: np.random.Generator) -> np.ndarray:
    # One uniform per position in time order, present or not, so a frame's draw does not
    # depend on which other frames the drive has.
    return rng.random(len(frames))


def frame_lost(frames: Frames, center: int, level, rng: np.random.Generator) -> list:
    p = parameter("frame_lost", level)
    u = _neighbour_draws(frames, rng)
    return [f if f is None or i == center or u[i] >= p else np.zeros_like(f)
            for i, f in enumerate(frames)]


def frame_freeze(frames: Frames, center: int, level, rng: np.random.Generator) -> list:
    p = parameter("frame_freeze", level)
    u = _neighbour_draws(frames, rng)
    out = list(frames)
    for step in (-1, 1):  # outward from the test frame, so a freeze can last several frames
        i = center + step
        while 0 <= i < len(out):
            inner = out[i - step]
            if out[i] is not None and inner is not None and u[i] < p:
                out[i] = inner
            i += step
    return out


def _present(frames: Frames) -> list[int]:
    return [i for i, f in enumerate(frames) if f is not None]


def _through_codec(frames: Frames, codec_name: str, crf: int, rate: float = 0.0,
                   rng: np.random.Generator | None = None) -> list:
    from . import codec

    idx = _present(frames)
    clip = [frames[i] for i in idx]
    data = codec.encode(clip, codec_name, crf)
    if rate:
        data = codec.flip_bits(data, codec_name, rate, rng)
    shown = codec.decode(data, codec_name, len(clip), clip[0].shape[:2])
    out = list(frames)
    for i, img in zip(idx, shown):
        out[i] = img
    return out


def h264_crf(frames: Frames, center: int, level, rng: np.random.Generator) -> list:
    return _through_codec(frames, "h264", round(parameter("h264_crf", level)))


def h265_crf(frames: Frames, center: int, level, rng: np.random.Generator) -> list:
    return _through_codec(frames, "h265", round(parameter("h265_crf", level)))


def bit_error(frames: Frames, center: int, level, rng: np.random.Generator) -> list:
    return _through_codec(frames, "h264", BIT_ERROR_CRF, parameter("bit_error", level), rng)


FUNCTIONS: dict[str, Callable] = {
    "frame_lost": frame_lost, "frame_freeze": frame_freeze, "h264_crf": h264_crf,
    "h265_crf": h265_crf, "bit_error": bit_error,
}


def corrupt_sequence(name: str, frames: Frames, center: int, level,
                     rng: np.random.Generator) -> list:
    """The sequence ``frames`` (test frame at ``center``) under ``name`` at ``level``."""
    if frames[center] is None:
        raise ValueError("the test frame of a sequence cannot be missing")
    return FUNCTIONS[name](frames, center, level, rng)
