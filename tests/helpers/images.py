"""Small test images, the benchmark's float-to-uint8 rule and a replayable generator,
shared by the corruption tests."""

from __future__ import annotations

import cv2
import numpy as np


def smooth_image(h: int, w: int, seed: int = 0) -> np.ndarray:
    """A photo-like uint8 test image: smooth random structure plus some edges."""
    rng = np.random.default_rng(seed)
    base = rng.random((h // 4 + 2, w // 4 + 2, 3))
    img = cv2.resize(base, (w, h), interpolation=cv2.INTER_CUBIC)
    img[h // 3:h // 2, w // 5:w // 2] = 0.9  # a flat patch with sharp borders
    return np.clip(img * 255, 0, 255).astype(np.uint8)


def truncate(v: np.ndarray) -> np.ndarray:
    """The benchmark's float-to-uint8 rule: clip to [0, 1], scale by 255, truncate."""
    return (np.clip(v, 0, 1) * 255).astype(np.uint8)


def assert_close_uint8(ours: np.ndarray, expected: np.ndarray, min_exact: float = 0.999) -> None:
    """Same shape, uint8, no value off by more than one, at least ``min_exact`` equal."""
    assert ours.shape == expected.shape and ours.dtype == np.uint8
    diff = np.abs(ours.astype(int) - expected.astype(int))
    assert diff.max() <= 1, f"max diff {diff.max()}"
    assert (diff == 0).mean() >= min_exact, f"only {(diff == 0).mean():.4%} exact"


class ReplayRng:
    """Serves prescribed draws to code that asks a numpy Generator for them."""

    def __init__(self, **draws):
        self.draws = draws

    def standard_normal(self, shape, dtype=np.float64):
        out = self.draws["standard_normal"](shape)
        return out.astype(dtype)

    def uniform(self, low, high):
        return self.draws["uniform"]

    def random(self, shape, dtype=np.float64):
        return self.draws["random"].astype(dtype).reshape(shape)
