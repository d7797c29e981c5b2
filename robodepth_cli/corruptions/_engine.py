"""The corruption engine: every corruption module loaded, the registry, and the checked
entry points :func:`corrupt` and :func:`corrupt_chain`. Reached through the package
(``robodepth_cli.corruptions.REGISTRY`` etc.), which loads it on first use."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..errors import InvalidValueError
from ..imageio import as_rgb
from .depth import DepthError, scene_depth
from .registry import Corruption, registry
from .chains import Chain, expand_chain, looks_like_chain, parse_chain
from .scaling import scale_factor
from .severity import parse_level

# Importing a module registers its corruption(s).
from . import (  # noqa: F401  (imported for registration)
    brightness, dark, fog, frost, snow, contrast,
    defocus_blur, glass_blur, motion_blur, zoom_blur, elastic_transform, color_quant,
    gaussian_noise, impulse_noise, shot_noise, iso_noise, pixelate, jpeg_compression,
    fog_3d, near_focus, far_focus, motion_3d, zoom_3d, rain_3d,
)

REGISTRY: dict[str, Corruption] = registry()
NAMES: tuple[str, ...] = tuple(n for n, c in REGISTRY.items() if not c.needs_depth)
"""The benchmarks' 18, which need only the image."""
DEPTH_NAMES: tuple[str, ...] = tuple(n for n, c in REGISTRY.items() if c.needs_depth)
"""The corruptions that also take the scene's depth."""

def get(name: str) -> Corruption:
    """The registry record of ``name``; :class:`InvalidValueError` listing the valid names otherwise."""
    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        raise InvalidValueError(f"unknown corruption {name!r}; valid: {', '.join(REGISTRY)}") from None


def check_level(corruption: Corruption, level) -> int | float:
    """``level`` checked for ``corruption``: a number in ``1..5``, decimals allowed; an
    ``int`` for a whole level. :class:`~.severity.LevelError` naming both otherwise."""
    return parse_level(level, top=corruption.n_levels, what=corruption.name)


def corrupt(image: np.ndarray, name: str, level, rng: np.random.Generator, depth=None, *,
            severity_size: tuple[int, int] | None = None) -> np.ndarray:
    """Apply corruption ``name`` at ``level`` (1..5, decimals allowed: see
    :mod:`.severity`) to ``image``.

    ``image`` is uint8 RGB H x W x 3 with H, W >= 32; grayscale and RGBA are converted.
    All randomness comes from ``rng`` (a ``numpy.random.Generator``). Returns a new uint8
    H x W x 3 array; the input is never modified.

    ``depth`` is the scene's depth in metres (H x W; NaN, 0 or inf where missing), which a
    depth-aware corruption needs (:class:`DepthError` without it) and the others ignore;
    it is prepared by :func:`~.depth.scene_depth` (filled, sized to the image).

    ``severity_size`` ``(H0, W0)``: the size at which the level's spatial parameters are
    defined, scaled to the image's by :func:`~.scaling.scale_factor`; None: as tabulated.
    """
    c = get(name)
    level = check_level(c, level)
    _check_rng(rng)
    image = as_rgb(image)
    return _apply(c, image, level, rng, _depth_for(image, depth, (c,)), severity_size)


def corrupt_chain(image: np.ndarray, chain: Chain | str, rngs: Sequence[np.random.Generator],
                  depth=None, *, severity_size: tuple[int, int] | None = None) -> np.ndarray:
    """Apply the steps of ``chain`` (a :class:`~.chains.Chain` or its text) in order, step
    ``k`` drawing from ``rngs[k]`` (one generator per step:
    :func:`robodepth_cli.seeding.chain_rngs` gives the reproducible ones).

    Each step is exactly :func:`corrupt` of the previous step's output, so a chain of
    deterministic steps equals applying them one after another. Every depth-aware step
    receives the same ``depth``: no step moves the scene's geometry; every step the same
    ``severity_size``."""
    if not isinstance(chain, Chain):
        chain = parse_chain(chain)
    rngs = list(rngs)
    if len(rngs) != len(chain.steps):
        raise ValueError(f"chain {chain.text}: {len(chain.steps)} steps but {len(rngs)} generators")
    for rng in rngs:
        _check_rng(rng)
    out = as_rgb(image)
    steps = [get(step.name) for step in chain.steps]
    d = _depth_for(out, depth, steps, chain.text)
    for step, c, rng in zip(chain.steps, steps, rngs):
        out = _apply(c, out, step.level, rng, d, severity_size)
    return out


def render(clean: np.ndarray, variant: str, level, *, seed: int, dataset: str, key: str,
           depth=None, anchor: str | None = None,
           severity_size: tuple[int, int] | None = None) -> np.ndarray:
    """The image of one job: corruption ``variant`` at ``level``, or, when ``variant`` is a
    chain (its text; ``level`` is then unused), that chain; every draw from the job's own
    generators (:func:`~robodepth_cli.seeding.job_rng`,
    :func:`~robodepth_cli.seeding.chain_rngs`). The one rule by which ``corrupt``,
    ``preview``, a build and the torch transforms turn a job into pixels. ``depth`` and
    ``severity_size`` as :func:`corrupt` takes them.

    ``anchor``: the key of the test frame whose neighbour ``key`` is; each corruption's
    scene draws are then seeded from ``anchor`` and its noise from ``key``
    (:func:`~.frames.draw_key`)."""
    from .. import seeding
    from .frames import draw_key

    if looks_like_chain(variant):
        chain = parse_chain(variant)
        # Each step is seeded from its own draw key (key or anchor): at most two chains of
        # generators, each made once.
        by_key = {k: seeding.chain_rngs(seed, dataset, chain, k)
                  for k in {draw_key(step.name, key, anchor) for step in chain.steps}}
        rngs = [by_key[draw_key(step.name, key, anchor)][i] for i, step in enumerate(chain.steps)]
        return corrupt_chain(clean, chain, rngs, depth, severity_size=severity_size)
    return corrupt(clean, variant, level,
                   seeding.job_rng(seed, dataset, variant, level, draw_key(variant, key, anchor)), depth,
                   severity_size=severity_size)


def _steps(variant: str) -> tuple[str, ...]:
    return expand_chain(variant, (1,))[0].names if looks_like_chain(variant) else (variant,)


def needs_depth(variant: str) -> bool:
    """Whether ``variant`` (a corruption's name, a chain's text or a chain template whose
    steps lack levels) has a depth-aware step."""
    return any(get(n).needs_depth for n in _steps(variant))


def is_scaled(variant: str) -> bool:
    """Whether ``variant`` (as :func:`needs_depth` takes it) has a step whose pixels the
    severity size changes."""
    return any(get(n).scaled for n in _steps(variant))


def depth_aware_variant(name: str) -> bool:
    """Whether the variant ``name`` (a corruption, a chain; clean or a style: no) is made
    from the scene's depth."""
    return _of_corruptions(needs_depth, name)


def scaled_variant(name: str) -> bool:
    """Whether the variant ``name`` (a corruption, a chain; clean or a style: no) has a
    step whose pixels a severity size changes."""
    return _of_corruptions(is_scaled, name)


def _of_corruptions(test, name: str) -> bool:
    """``test(name)`` for a corruption or chain; False for any other variant's name."""
    try:
        return test(name)
    except InvalidValueError:  # clean, a style
        return False


def _depth_for(image: np.ndarray, depth, steps, what: str = ""):
    """The prepared depth when one of ``steps`` needs it (None otherwise); a depth-aware
    step without a depth is refused."""
    aware = [c.name for c in steps if c.needs_depth]
    if not aware:
        return None
    if depth is None:
        where = f"chain {what}: " if what else ""
        raise DepthError(f"{where}{aware[0]} needs the scene's depth, and none was given")
    return scene_depth(depth, image.shape[:2])


def _check_rng(rng) -> None:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")


def _apply(c: Corruption, image: np.ndarray, level, rng: np.random.Generator, depth,
           severity_size=None) -> np.ndarray:
    x = image.view()
    x.flags.writeable = False  # corruption functions are pure: writing to the input fails loudly
    s = scale_factor(x.shape, severity_size) if c.scaled else None
    # At the severity size itself (s == 1) the tabulated parameters, by the very same code.
    kw = {"scale": s} if s is not None and s != 1.0 else {}
    out = c.fn(x, depth, level, rng, **kw) if c.needs_depth else c.fn(x, level, rng, **kw)
    if out.dtype != np.uint8 or out.shape != x.shape:
        raise AssertionError(f"{c.name} returned {out.dtype} {out.shape} for {x.shape}")
    return out
