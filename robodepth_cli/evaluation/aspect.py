"""A prediction's aspect ratio against its ground truth's, checked before any map is judged.

A map is resized to its ground truth's size whatever its own, so a transposed array or the
wrong model output (96 x 10 against 375 x 1242) would be judged without a word. The factor
between the two aspect ratios (width / height, the larger over the smaller) decides: above
:data:`WARN_FACTOR` a warning, above :data:`REFUSE_FACTOR` a refusal. A map with the aspect
ratio of the build's images (``build --size``) is never warned: the build chose it. A model's usual
outputs stay well inside the first: 192 x 640 against 375 x 1242 is 1.006, NYU's 416 x 544
crop against 480 x 640 1.02; a square 384 x 384 output against KITTI's 375 x 1242 (3.3) is
warned, a transposed 640 x 192 (11) refused.
"""

from __future__ import annotations

from typing import Sequence

from .protocols import EvaluationError

WARN_FACTOR = 1.5
REFUSE_FACTOR = 4.0


def aspect_factor(a: Sequence[int], b: Sequence[int]) -> float:
    """How far apart the aspect ratios of the (height, width) shapes ``a`` and ``b`` are:
    the larger ratio over the smaller, 1 when they are alike."""
    ra, rb = a[1] / a[0], b[1] / b[0]
    return max(ra, rb) / min(ra, rb)


def check_aspect(shape: Sequence[int], gt_shape: Sequence[int], where: str,
                 image_size: Sequence[int] | None = None) -> str:
    """"" when the map of ``shape`` (read from ``where``) has an aspect ratio within
    :data:`WARN_FACTOR` of its ground truth's ``gt_shape`` or of the build's images'
    ``image_size`` (None: their own sizes); else the warning's text up to
    :data:`REFUSE_FACTOR`, and :class:`EvaluationError` past it."""
    f = aspect_factor(shape, gt_shape)
    if f <= WARN_FACTOR or (image_size and aspect_factor(shape, image_size) <= WARN_FACTOR):
        return ""
    text = (f"{where} is {shape[0]} x {shape[1]}, its ground truth {gt_shape[0]} x "
            f"{gt_shape[1]}: aspect ratios {f:.1f} times apart")
    if f > REFUSE_FACTOR:
        raise EvaluationError(f"{text} (more than {REFUSE_FACTOR:g}: a transposed array or "
                              "another model output?); give maps of the image's shape")
    return f"{text} (more than {WARN_FACTOR:g}); resized to the ground truth's size anyway"


def aspect_warnings(found, gt_shapes: Sequence[Sequence[int]], image_size=None) -> list[str]:
    """:func:`check_aspect` of each variant's first map (``found``: (variant, predictions)
    pairs) against the first image's ground truth: the warnings, one per variant that
    calls for one; raises for the first past the refusal factor."""
    if not gt_shapes:
        return []
    notes = []
    for _, p in found:
        try:
            m, where, _ = p.read(0)
        finally:
            p.close()  # the variant is read again, maybe by a worker (an open file does not pickle)
        note = check_aspect(m.shape, gt_shapes[0], where, image_size)
        if note:
            notes.append(note)
    return notes
