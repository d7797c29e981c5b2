"""Which depth map belongs to which image: the pairing rule of a build with depth.

A custom build reads depth when ``depth`` (``--depth DIR``) is given; a zero-shot preset
(``diode-c``, ``sintel-c``, ...) always does, from its root unless ``depth`` says otherwise.
Config keys (each also a flag ``--depth-...``):

``depth``
    the directory the depth paths are relative to.
``depth_pattern``
    where an image's depth map is, relative to ``depth``: a template with the image's
    ``{path}`` (its path relative to the root without the extension), ``{dir}`` (its
    directory, ``.`` at the top), ``{stem}`` (file name without extension), ``{name}``
    (file name), ``{ext}`` (extension with the dot), ``{digits}`` (the last run of digits
    in the stem: ``00042`` of ``rgb_00042``), ``{prefix}`` (the stem up to its last ``_``:
    ``bonn_000000_000019`` of ``bonn_000000_000019_leftImg8bit``) and ``{parts[i]}`` (its
    i-th directory), e.g. ``{dir}/{stem}_depth.npy``. Unset: the same relative path with a depth extension
    (``.png``, ``.npy``, ``.npz``, ``.pfm``, ``.exr``, ``.dpt``), the one that exists.
``depth_mask``
    a template like ``depth_pattern`` for a mask file whose 0 pixels are invalid (DIODE).
``depth_camera``
    a template like ``depth_pattern`` for the camera file a ``cityscapes`` disparity needs.
``depth_scale``
    the file holds ``depth x scale`` (256 KITTI-style PNGs, 1000 millimetres).
``depth_format``
    one of :data:`~.depth_io.FORMATS`, when the extension does not say (ETH3D's raw maps
    are named ``.JPG``).
``depth_size``
    ``match`` (default): a depth map must have its image's size (as stored, before any
    ``--size``); ``any``: any size (the evaluation resizes the prediction to it).
"""

from __future__ import annotations

import math
import posixpath
import re
import string
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from ..errors import InvalidValueError
from ..sourcekeys import relative_parts
from .depth_io import EXTENSIONS, FORMATS

FIELDS = ("path", "dir", "stem", "name", "ext", "digits", "prefix", "parts")
SIZES = ("match", "any")


@dataclass(frozen=True)
class DepthRule:
    """How a build finds and reads each image's depth map."""

    directory: str  # absolute
    pattern: str | None = None
    mask: str | None = None
    camera: str | None = None
    scale: float | None = None
    fmt: str | None = None
    same_size: bool = True

    def fingerprint(self) -> str:
        return f"{self.pattern}|{self.mask}|{self.camera}|{self.scale!r}|{self.fmt}|{self.same_size}"


@dataclass(frozen=True)
class DepthPair:
    """One image's depth (and mask) path, or why there is none."""

    depth: str = ""  # relative to the rule's directory
    mask: str = ""
    camera: str = ""
    error: str = ""


def check_template(value, key: str) -> str:
    """A pairing template with only the known fields; :class:`InvalidValueError` otherwise."""
    if not isinstance(value, str) or not value.strip():
        raise InvalidValueError(f"expected a path template such as '{{dir}}/{{stem}}_depth.npy', "
                                f"got {value!r}")
    try:
        fields = [f for _, f, _, _ in string.Formatter().parse(value) if f is not None]
    except ValueError as exc:
        raise InvalidValueError(f"{value!r}: {exc}") from None
    for f in fields:
        base = f.split("[")[0].split(".")[0]
        if base not in FIELDS or (base == "parts") != ("[" in f) or "." in f:
            raise InvalidValueError(f"{value!r}: unknown field {{{f}}}; valid: "
                                    f"{', '.join('{' + x + '}' for x in FIELDS[:-1])}, {{parts[i]}}")
    return value.strip()


def check_option(key: str, value, base: Path):
    """The checked value of one depth key (see the module docstring)."""
    if value is None:
        return None
    if key == "depth":
        if not isinstance(value, str) or not value.strip():
            raise InvalidValueError(f"expected the directory of the depth maps, got {value!r}")
        return str((base / Path(value).expanduser()).resolve())
    if key in ("depth_pattern", "depth_mask", "depth_camera"):
        return check_template(value, key)
    if key == "depth_scale":
        try:
            scale = float(value)
        except (TypeError, ValueError):
            scale = math.nan
        if isinstance(value, bool) or not (math.isfinite(scale) and scale > 0):
            raise InvalidValueError(f"expected a positive number (256 for KITTI-style PNGs, 1000 "
                                    f"for millimetres), got {value!r}")
        return scale
    if key == "depth_format":
        if value not in FORMATS:
            raise InvalidValueError(f"expected one of {', '.join(FORMATS)}, got {value!r}")
        return value
    if key == "depth_size":
        if value not in SIZES:
            raise InvalidValueError(f"expected one of {', '.join(SIZES)}, got {value!r}")
        return value
    raise InvalidValueError(f"no depth option {key!r}")


def rule_of(options, root: Path, in_root: bool) -> DepthRule | None:
    """The depth rule of a build's :class:`~.datasets.Options`; None when it reads no depth (a
    custom build without ``depth``). ``in_root``: the dataset's depth lives under its root."""
    directory = options.depth or (str(root) if in_root else None)
    if directory is None:
        return None
    return DepthRule(directory, options.depth_pattern, options.depth_mask, options.depth_camera,
                     options.depth_scale, options.depth_format, options.depth_size in (None, "match"))


def fill(template: str, rel: str) -> str:
    """``template`` for the image at ``rel`` (posix, relative to the root), normalised;
    :class:`InvalidValueError` when it names a path outside the depth directory."""
    p = PurePosixPath(rel)
    dirs = list(p.parent.parts)
    digits = re.findall(r"\d+", p.stem)
    if "{digits}" in template and not digits:
        raise InvalidValueError(f"{template!r}: the name {p.name} has no digits")
    try:
        text = template.format(path=str(p.with_suffix("")), dir=str(p.parent), stem=p.stem,
                               name=p.name, ext=p.suffix, digits=digits[-1] if digits else "",
                               prefix=p.stem.rpartition("_")[0] or p.stem, parts=dirs)
    except IndexError:
        raise InvalidValueError(f"{template!r}: {rel} has only {len(dirs)} directories") from None
    out = posixpath.normpath(text)
    relative_parts(out, "depth path")
    return out


def pair(rule: DepthRule, rel: str) -> DepthPair:
    """The depth (and mask) of the image at ``rel``, found under the rule's directory."""
    root = Path(rule.directory)
    try:
        if rule.pattern:
            depth = fill(rule.pattern, rel)
            if not (root / depth).is_file():
                return DepthPair(error=f"{root / depth}: no such depth file (for {rel})")
        else:
            stem = str(PurePosixPath(rel).with_suffix(""))
            found = [stem + e for e in EXTENSIONS if (root / (stem + e)).is_file()]
            if not found:
                return DepthPair(error=f"{root / stem}: no depth file (tried "
                                       f"{', '.join(EXTENSIONS)}) for {rel}")
            if len(found) > 1:
                return DepthPair(error=f"{root / stem}: several depth files ({', '.join(found)}) for "
                                       f"{rel}; say which with --depth-pattern")
            depth = found[0]
        mask = fill(rule.mask, rel) if rule.mask else ""
        camera = fill(rule.camera, rel) if rule.camera else ""
    except InvalidValueError as exc:
        return DepthPair(error=f"{rel}: {exc}")
    for what, extra in (("mask", mask), ("camera", camera)):
        if extra and not (root / extra).is_file():
            return DepthPair(error=f"{root / extra}: no such {what} file (for {rel})")
    return DepthPair(depth, mask, camera)


def read_pair(rule: DepthRule, found: DepthPair, shape: tuple[int, int] | None = None):
    """The depth map of a pair (:func:`pair`) in metres, NaN where invalid, read with the
    rule's form, scale, mask and camera (:func:`~.depth_io.read_depth`); ``shape``: the
    image's (H, W), which a ``raw`` map needs. Raises ``DepthError`` (a RobodepthError)."""
    from .depth_io import DepthError, read_depth

    if found.error:
        raise DepthError(found.error)
    base = Path(rule.directory)
    return read_depth(base / found.depth, fmt=rule.fmt, scale=rule.scale,
                      mask=base / found.mask if found.mask else None, shape=shape,
                      camera=base / found.camera if found.camera else None)


def depth_of(options, root: Path, in_root: bool, rel: str,
             shape: tuple[int, int] | None = None):
    """The depth map of the image at ``rel`` (relative to ``root``) in a build with
    ``options`` (:class:`~.datasets.Options`), or None when the build reads no depth: where
    the depth of a custom build's or zero-shot set's image comes from, in one call."""
    rule = rule_of(options, root, in_root)
    return None if rule is None else read_pair(rule, pair(rule, rel), shape)
