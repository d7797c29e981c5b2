"""KITTI-S inputs: the 12 style names, the user's style directory, and the build renderer.

Nothing here imports torch at import time: the dataset definition and the configuration
checks run in every build, and only a KITTI-S build that has images to render loads torch
(through :mod:`robodepth_cli.styles.adain`).
"""

from __future__ import annotations

import hashlib
import os
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from PIL import Image

from ..imageio import MIN_SIDE, read_rgb
from ..files import sha256_file
from ..errors import InvalidValueError, RobodepthError, reraise_interrupt
from ..integers import int_from_text

# The 12 KITTI-S styles in the benchmark's order; also the output directory names.
STYLES: tuple[str, ...] = (
    "cartoon", "digital_art", "ink_painting", "kids_drawing", "murals", "oil_painting",
    "penciling", "shadow_play", "sketch", "stained_glass", "relief", "water_color",
)
STYLE_EXTS = (".jpg", ".jpeg", ".png")
DEFAULT_STYLE_SIZE = 512


class StyleError(RobodepthError):
    """A style directory, style name or style image that cannot be used."""


def check_names(names: Sequence[str]) -> tuple[str, ...]:
    """``names`` without duplicates, in the given order; ``StyleError`` for an unknown one."""
    for n in names:
        if n not in STYLES:
            raise StyleError(f"unknown style {n!r}; valid: {', '.join(STYLES)}")
    return tuple(dict.fromkeys(names))


def find_style_images(directory: str | os.PathLike,
                      names: Sequence[str] = STYLES) -> dict[str, Path]:
    """``{style: image path}`` for every style of ``names``: the file ``<style>.jpg``,
    ``.jpeg`` or ``.png`` (extension case ignored) directly in ``directory``.

    ``StyleError`` if the directory is missing, if any style has no image (the message lists
    the missing styles and the expected file names) or has more than one.
    """
    names = check_names(names)
    directory = Path(directory)
    if not directory.is_dir():
        what = "is not a directory" if directory.exists() else "does not exist"
        raise StyleError(f"{directory}: the style directory {what}; it should hold one image "
                         f"per style, named <style>.jpg/.jpeg/.png ({', '.join(STYLES)})")
    by_stem: dict[str, list[Path]] = {}
    for p in sorted(directory.iterdir()):
        if p.suffix.lower() in STYLE_EXTS and p.is_file():
            by_stem.setdefault(p.stem, []).append(p)
    found, missing = {}, []
    for name in names:
        files = by_stem.get(name, [])
        if not files:
            missing.append(name)
        elif len(files) > 1:
            raise StyleError(f"{directory}: several images for style {name!r} "
                             f"({', '.join(f.name for f in files)}); keep one")
        else:
            found[name] = files[0]
    if missing:
        raise StyleError(f"{directory}: no image for style(s) {', '.join(missing)}; expected one "
                         f"file per style named <style>.jpg, .jpeg or .png, for: {', '.join(names)}")
    return found


def check_alpha(alpha) -> float:
    """``alpha`` as a float in [0, 1]; :class:`InvalidValueError` otherwise."""
    try:
        value = float(alpha)
    except (TypeError, ValueError):
        raise InvalidValueError(f"alpha must be a number between 0 and 1, got {alpha!r}") from None
    if isinstance(alpha, bool) or not 0.0 <= value <= 1.0:
        raise InvalidValueError(f"alpha must be between 0 and 1, got {alpha!r}")
    return value


def check_style_size(style_size) -> int | None:
    """``style_size`` as an int >= 32, or None for 0/None (keep the style image's size)."""
    if style_size is None or (not isinstance(style_size, bool) and style_size == 0):
        return None
    if isinstance(style_size, bool) or not isinstance(style_size, (int, np.integer)) \
            or style_size < MIN_SIDE:
        raise InvalidValueError(f"style size must be 0 (keep the image's size) or an integer >= "
                         f"{MIN_SIDE}, got {style_size!r}")
    return int(style_size)


def style_resize_size(width: int, height: int, style_size: int | None) -> tuple[int, int]:
    """``(W, H)`` with the shorter side equal to ``style_size`` and the longer side scaled
    and truncated (torchvision ``Resize(int)`` semantics); unchanged if ``style_size`` is
    None or 0."""
    if not style_size:
        return width, height
    if width <= height:
        return style_size, int(style_size * height / width)
    return int(style_size * width / height), style_size


def load_style(path: str | os.PathLike, style_size: int | None = DEFAULT_STYLE_SIZE) -> np.ndarray:
    """A style image as uint8 RGB, resized so its shorter side is ``style_size`` with
    Pillow's bilinear filter (antialiased when shrinking); 0/None keeps its size.
    ``ImageError`` naming the file if it cannot be read."""
    style_size = check_style_size(style_size)
    im = read_rgb(path)
    size = style_resize_size(*im.size, style_size)
    if size != im.size:
        im = im.resize(size, Image.BILINEAR)
    return np.asarray(im, dtype=np.uint8).copy()


# KITTI-S's build options are listed in sources/datasets.py (STYLE_OPTIONS), checked here.
DEVICES = ("auto", "cpu", "cuda")  # as adain.DEVICES, without importing torch


def check_option(key: str, value, base: Path):
    """The checked value of KITTI-S option ``key``; :class:`InvalidValueError` saying what is wrong.
    Paths are resolved against ``base``; None (unset) is allowed here, and refused by
    :func:`make_renderer` for the required ones."""
    if key in ("styles", "vgg", "decoder"):
        if value is None:
            return None
        if not isinstance(value, str) or not value:
            raise InvalidValueError(f"expected a path, got {value!r}")
        path = Path(base) / Path(value).expanduser()  # as typed, for messages
        if key == "styles":
            if not path.is_dir():
                raise InvalidValueError(f"{path}: the style directory "
                                 f"{'is not a directory' if path.exists() else 'does not exist'}")
        elif not path.is_file():
            raise InvalidValueError(f"{path}: {'not a file' if path.exists() else 'no such file'}")
        return str(path)
    if key == "device":
        if value not in DEVICES:
            raise InvalidValueError(f"expected one of {', '.join(DEVICES)}, got {value!r}")
        return value
    if key == "alpha":
        return check_alpha(value)
    if key == "style_size":
        return check_style_size(int_from_text(value, negative=False)) or 0
    raise InvalidValueError(f"unknown option {key!r}")


def make_renderer(config) -> "StyleRenderer":
    """The renderer of a resolved KITTI-S build configuration: checks that the style
    directory, the checkpoints and a style image for every selected style are there, loads
    and validates the checkpoints and the style images. :class:`StyleError`,
    :class:`~robodepth_cli.styles.adain.CheckpointError` or
    :class:`~robodepth_cli.imageio.ImageError` (naming the file) for anything missing or
    unusable."""
    opts = config.options
    for key, flag, what in (("styles", "--styles", "STYLE_DIR (one image per style)"),
                            ("vgg", "--vgg", "vgg_normalised.pth"),
                            ("decoder", "--decoder", "decoder.pth")):
        if getattr(opts, key) is None:
            raise StyleError(f"{config.dataset} needs {flag} {what}")
    images = find_style_images(opts.styles, config.variants)
    cores = os.cpu_count() or 1
    # On a cluster each worker thread renders one image at a time on its own core; locally
    # the cores are shared among the pool's processes.
    on_cluster = config.scheduler or config.scheduler_file
    choice = opts.device or "auto"
    from . import adain

    device = adain.choose_device(choice)  # --device cuda without one: refused here
    if on_cluster:
        # The workers' machines decide what "auto" means there, not this client's.
        print(f"robodepth: {config.dataset}: AdaIN on each worker's "
              f"{'GPU if it has one, else its CPU' if choice == 'auto' else choice} "
              f"(--device {choice})", file=sys.stderr)
        where = choice
    else:
        note = " (no CUDA device)" if choice == "auto" and device.type == "cpu" else ""
        print(f"robodepth: {config.dataset}: AdaIN on {adain.describe_device(device)}{note} "
              f"(--device {choice})", file=sys.stderr)
        where = device.type
    return StyleRenderer.prepare(opts.vgg, opts.decoder, images,
                                 alpha=1.0 if opts.alpha is None else opts.alpha,
                                 style_size=DEFAULT_STYLE_SIZE if opts.style_size is None else opts.style_size,
                                 threads=1 if on_cluster else max(1, cores // max(1, config.jobs)),
                                 device=where)


@dataclass
class StyleRenderer:
    """Renders the style jobs of one clean image with one batched AdaIN call.

    Made in the main process by :meth:`prepare`, which loads the checkpoints and the style
    images (refusing bad ones) and fingerprints them. The style statistics are computed by
    :meth:`warm_up`, once, in the main process when the build has work to do (a rerun with
    nothing to do never pays for them); a worker receives them (a few kB) and loads the
    encoder/decoder once per process. A worker that meets work the plan did not foresee
    (an output deleted since) computes them itself.
    """

    vgg: str
    decoder: str
    alpha: float
    threads: int
    features: dict[str, Any] = field(default_factory=dict)  # style -> adain.StyleFeatures
    fingerprints: dict[str, str] = field(default_factory=dict)  # style -> digest of its inputs
    style_images: dict[str, str] = field(default_factory=dict)  # style -> image path
    style_size: int | None = DEFAULT_STYLE_SIZE
    device: str = "cpu"  # "cpu", "cuda", or on a cluster "auto" (each worker decides)

    @classmethod
    def prepare(cls, vgg, decoder, style_images: dict[str, Path], *, alpha: float = 1.0,
                style_size: int | None = DEFAULT_STYLE_SIZE, threads: int = 0,
                device: str = "cpu") -> "StyleRenderer":
        """Load and check the checkpoints and style images. ``alpha`` and ``style_size`` are
        values :func:`check_option` accepted. ``threads``: torch threads of each rendering
        process (0: every core); :meth:`warm_up` computes the style statistics with every
        core. ``device``: where the rendering processes run AdaIN (``cpu``, ``cuda``, or
        ``auto``: each decides)."""
        cores = os.cpu_count() or 1
        _stylizer(str(vgg), str(decoder), cores, device)  # loads and checks both checkpoints
        for path in style_images.values():
            load_style(path, style_size)  # an unreadable style image is refused now
        weights = f"{sha256_file(vgg)}:{sha256_file(decoder)}:{alpha!r}:{style_size!r}"
        fingerprints = {name: hashlib.sha256(f"{weights}:{sha256_file(path)}".encode()).hexdigest()[:16]
                        for name, path in style_images.items()}
        # Absolute: the workers that load them need not share this process's directory.
        return cls(os.path.abspath(vgg), os.path.abspath(decoder), alpha, threads or cores,
                   fingerprints=fingerprints,
                   style_images={n: os.path.abspath(p) for n, p in style_images.items()},
                   style_size=style_size, device=device)

    def warm_up(self) -> None:
        """Compute the statistics of every style not done yet (with every core)."""
        todo = [n for n in self.style_images if n not in self.features]
        if todo:
            stylizer = _stylizer(self.vgg, self.decoder, os.cpu_count() or 1, self.device)
            for name in todo:
                self.features[name] = stylizer.style_features(load_style(self.style_images[name],
                                                                         self.style_size))

    def fingerprint(self, variant: str) -> str:
        """Digest of the checkpoints, the style image, alpha and the style size: a rebuild
        after any of them changed redoes that style."""
        return self.fingerprints[variant]

    def render(self, clean, key, jobs):
        try:
            stylizer = _stylizer(self.vgg, self.decoder, self.threads, self.device)
            if any(j.variant not in self.features for j in jobs):
                self.warm_up()
            images = stylizer.stylize(clean, [self.features[j.variant] for j in jobs], self.alpha)
        except Exception as exc:  # reported per job by the builder; the other images go on
            reraise_interrupt(exc)
            for job in jobs:
                yield job, exc
            return
        yield from zip(jobs, images)


_STYLIZERS: dict[tuple, Any] = {}
_STYLIZERS_LOCK = threading.Lock()  # a Dask worker runs tasks in several threads


def _stylizer(vgg: str, decoder: str, threads: int, device: str = "cpu"):
    """One :class:`adain.Stylizer` per process, checkpoint pair and device."""
    # the same files, typed or absolute
    k = (os.path.abspath(vgg), os.path.abspath(decoder), device)
    with _STYLIZERS_LOCK:
        if k not in _STYLIZERS:
            from . import adain

            _STYLIZERS.clear()
            _STYLIZERS[k] = adain.Stylizer.from_files(vgg, decoder, threads=threads,
                                                      device=adain.choose_device(device))
        return _STYLIZERS[k]
