"""What each dataset is: its split format, where its source images live, how its outputs are
named, which variants and levels it has (their renderers are :mod:`robodepth_cli.building.renderers`).

A split entry becomes an :class:`Entry` with a *key*: the dataset-relative path of the
image with the extension ``.png`` (``kitti_data/<date>/<drive>/image_02/data/<frame>.png``
for KITTI, ``<scene>/rgb_<n>.png`` for NYU). The key names every output of that source,
``<variant>/<level>/<key>`` (``<variant>/<key>`` for datasets without levels,
``clean/<key>`` for the resized clean image), and is the relative path that seeds the
job's generator, so a PNG and a JPEG copy of a frame get the same noise.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Sequence


from ..benchmarks import BENCHMARKS, CLEAN, CORRUPTIONS, DEPTH_AWARE, N_LEVELS
from ..errors import InvalidValueError, os_reason
from ..imageio import ImageError
# SOURCE_EXTS: tried in this order when a split names no extension.
from ..keys import KITTI_PREFIX, PRESET_EXTS as SOURCE_EXTS, relative_parts
from .splits import SplitError

KITTI_SIDES = {"l": "image_02", "r": "image_03"}
# The corruption datasets' engine options (config keys and flags --engine, --device): which
# engine renders a build, and where (building/renderers.py).
ENGINE_OPTIONS = ("engine", "device")
ENGINES = ("numpy", "torch")
DEVICES = ("auto", "cpu", "cuda")


@dataclass(frozen=True)
class Entry:
    """One source image of a split."""

    line: int  # 1-based line number in the split file
    key: str  # dataset-relative path, posix, extension .png
    candidates: tuple[str, ...]  # source paths relative to the root, tried in order
    fields: tuple[str, ...] = ()  # the split line's fields as read (a byte-order mark dropped)


@dataclass(frozen=True)
class Job:
    """One output file: the source's ``key`` rendered as ``variant`` at ``level``."""

    variant: str  # a corruption, a chain's canonical text, a style or ``clean``
    level: int | float | None  # None: the clean image, a chain, or a dataset without levels

    def path(self, key: str) -> str:
        """The output path relative to OUT: ``<variant>/<level>/<key>``, with the level
        in its shortest form (``fog/2.5/...``); ``<chain directory name>/<key>`` for a
        chain (``fog-3+gaussian_noise-2.5/...``); ``<variant>/<key>`` otherwise."""
        from ..output.layout import output_path

        return output_path(self.variant, self.level, key)


def _with_exts(stem: str, first: str | None = None) -> tuple[str, ...]:
    exts = ((first,) if first else ()) + tuple(e for e in SOURCE_EXTS if e != first)
    return tuple(stem + e for e in exts)


def parse_eigen(fields: list[str]) -> tuple[str, tuple[str, ...]]:
    """``DATE/DRIVE FRAME SIDE`` -> (key, candidates). The frame number is zero-padded to 10
    digits, as the benchmark's KITTI loader formats it."""
    if len(fields) != 3:
        raise InvalidValueError(f"expected 3 fields 'DATE/DRIVE FRAME SIDE', got {len(fields)}")
    folder, frame, side = fields
    parts = relative_parts(folder, "folder")
    if not frame.isdigit():
        raise InvalidValueError(f"frame {frame!r} is not a number")
    if side not in KITTI_SIDES:
        raise InvalidValueError(f"side {side!r} is not one of {', '.join(KITTI_SIDES)}")
    rel = "/".join([*parts, KITTI_SIDES[side], "data", f"{int(frame):010d}"])
    return f"{KITTI_PREFIX}/{rel}.png", _with_exts(rel)


def parse_nyu(fields: list[str]) -> tuple[str, tuple[str, ...]]:
    """``RGB DEPTH FOCAL`` -> (key, candidates); the RGB path as listed is tried first."""
    if len(fields) != 3:
        raise InvalidValueError(f"expected 3 fields 'RGB DEPTH FOCAL', got {len(fields)}")
    rgb, depth, focal = fields
    relative_parts(rgb, "RGB path")
    relative_parts(depth, "depth path")
    try:
        float(focal)
    except ValueError:
        raise InvalidValueError(f"focal length {focal!r} is not a number") from None
    p = PurePosixPath(rgb)
    if p.suffix.lower() in SOURCE_EXTS:
        stem = str(p.with_suffix(""))
        return f"{stem}.png", _with_exts(stem, p.suffix)
    return f"{rgb}.png", (rgb, *_with_exts(rgb))


PARSERS = {"eigen": parse_eigen, "nyu": parse_nyu}
# What a line of each format looks like, for the message when a split of the other one is given.
SPLIT_KINDS = {"eigen": "a KITTI (Eigen) split (lines 'DATE/DRIVE FRAME SIDE')",
               "nyu": "an NYU Depth V2 split (lines 'RGB DEPTH FOCAL')"}


def read_split(path: Path, split_format: str, data: bytes | None = None) -> list[Entry]:
    """Parse a split file (``data``: its bytes, already read). Blank lines and lines starting
    with ``#`` are ignored. Raises :class:`SplitError` naming the file and line for a
    malformed or duplicate entry, and for a split without entries."""
    parse = PARSERS[split_format]
    try:
        # utf-8-sig: a byte-order mark (Windows editors write one) is not part of the first path.
        text = (Path(path).read_bytes() if data is None else data).decode("utf-8-sig")
    except UnicodeDecodeError:
        raise SplitError(f"{path}: not a text file") from None
    except OSError as exc:
        raise SplitError(f"{path}: cannot read the split ({os_reason(exc)})") from None
    entries: list[Entry] = []
    seen: dict[str, int] = {}
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        fields = tuple(line.split())
        try:
            key, cands = parse(list(fields))
        except InvalidValueError as exc:
            other = _other_format(line, split_format)
            if other:
                raise SplitError(f"{path}:{n}: this looks like {SPLIT_KINDS[other]}; this dataset "
                                 f"needs {SPLIT_KINDS[split_format]}") from None
            raise SplitError(f"{path}:{n}: {exc}") from None
        if key in seen:
            raise SplitError(f"{path}:{n}: duplicate of line {seen[key]} ({key})")
        seen[key] = n
        entries.append(Entry(n, key, cands, fields))
    if not entries:
        raise SplitError(f"{path}: the split lists no images")
    return entries


def _other_format(line: str, split_format: str) -> str:
    """The other split format that ``line`` parses as, or ""."""
    for fmt, parse in PARSERS.items():
        if fmt == split_format:
            continue
        try:
            parse(line.split())
        except InvalidValueError:
            continue
        return fmt
    return ""


def locate(root: Path, entry: Entry) -> tuple[str, Path]:
    """The first existing candidate of ``entry`` under ``root``, as (path relative to the
    root, path under the root). Raises :class:`ImageError` if none exists.

    Symlinks under the root are followed wherever they lead: a KITTI root is often a
    directory of links to date folders on other disks, and every link in it is the user's
    own. A split entry itself can never leave the root (no absolute paths, no ``..``).
    """
    for rel in entry.candidates:
        path = root / rel
        if path.is_file():
            return rel, path
    for rel in entry.candidates:
        if (root / rel).is_dir():
            raise ImageError(f"{root / rel}: is a directory, not an image file")
    tried = ", ".join(PurePosixPath(c).suffix for c in entry.candidates)
    raise ImageError(f"{root / entry.candidates[0]}: no such file (tried {tried})")


@dataclass(frozen=True)
class Dataset:
    """A dataset with corruptions as variants and numbered levels (KITTI-C, NYUDepth2-C).
    Datasets rendered differently (KITTI-S) subclass it and override the methods."""

    name: str
    split_format: str  # a key of PARSERS
    variant_key: str = "corruptions"  # the config key and flag that select the variants
    leveled: bool = True
    variant_noun: str = "corruption"  # in messages: "unknown corruption 'x'"
    corruptions: tuple[str, ...] = CORRUPTIONS  # this dataset's own, in benchmark order
    n_levels: int = N_LEVELS  # levels 1..n_levels
    discovers_sources: bool = False  # True: images found under the root, no split (custom)
    depth_in_root: bool = False  # True: a zero-shot preset, its depth maps under the root
    # (key, value) defaults of `robodepth evaluate`: protocol (kitti unless given), crop,
    # min_depth, max_depth (the protocol's unless given)
    evaluation: tuple = ()

    def variant_names(self) -> tuple[str, ...]:
        """The variants this dataset has; ``all`` in a configuration means these."""
        return self.corruptions

    def known_variant_names(self) -> tuple[str, ...]:
        """Every variant name of this kind, including those this dataset does not have (a
        message then says the dataset lacks it rather than that the name is unknown)."""
        return CORRUPTIONS + tuple(DEPTH_AWARE)

    def depth_variant_names(self) -> tuple[str, ...]:
        """The depth-aware corruptions this dataset can make given a depth source (its own
        ground truth, a custom build's ``depth``, or ``scene_depth``); never part of ``all``."""
        return tuple(DEPTH_AWARE) if self.leveled else ()

    def has_depth(self, extra: dict) -> bool:
        """Whether a build with options ``extra`` has a depth for the depth-aware corruptions."""
        return bool(not self.discovers_sources or self.depth_in_root or extra.get("depth")
                    or extra.get("scene_depth"))

    def levels(self) -> tuple[int, ...]:
        """The levels this dataset has (none for a dataset without levels)."""
        return tuple(range(1, self.n_levels + 1)) if self.leveled else ()

    def jobs(self, variants: Sequence[str], levels: Sequence) -> list[Job]:
        """Every output of one source: clean first, then variants x levels in the given
        order; a chain (a variant with ``:`` or ``+``) is one job, its levels in its name."""
        from ..corruptions.chains import looks_like_chain

        out = [Job(CLEAN, None)]
        for v in variants:
            chained = looks_like_chain(v)
            out += [Job(v, lv) for lv in levels] if self.leveled and not chained else [Job(v, None)]
        return out

    def options(self) -> tuple[str, ...]:
        """Config keys of this dataset beyond the common ones: the engine and its device,
        the depth of the depth-aware corruptions, the severity size."""
        return ENGINE_OPTIONS + ("scene_depth", "severity_size")

    def check_option(self, key: str, value, base: Path):
        """The checked value of option ``key``; :class:`InvalidValueError` saying what is wrong.
        ``base`` is the directory relative paths are resolved against."""
        if key == "scene_depth":
            from .predicted import check_option

            return check_option(value, base)
        if key == "severity_size":  # kept as its text (build.json, the manifest, the card)
            from ..corruptions.scaling import parse_severity_size, size_text

            return size_text(parse_severity_size(value))
        if key in ENGINE_OPTIONS:
            choices = ENGINES if key == "engine" else DEVICES
            if value is not None and value not in choices:
                raise InvalidValueError(f"expected one of {', '.join(choices)}, got {value!r}")
            return value
        raise InvalidValueError(f"{self.name} has no option {key!r}")

    def libraries(self) -> tuple[str, ...]:
        """Distributions whose versions the build record keeps (``verify`` compares those
        that decide a pixel with the lock's)."""
        return ("numpy", "Pillow", "opencv-python-headless", "scipy", "scikit-image", "numba",
                "llvmlite", "imagecorruptions-imaug", "av", "joblib", "tqdm", "PyYAML", "click",
                "fpng")


@dataclass(frozen=True)
class StyleDataset(Dataset):
    """KITTI-S: one AdaIN-stylised output per style, no levels. The style logic lives in
    :mod:`robodepth_cli.styles.inputs`; torch is loaded only by its renderer."""

    variant_key: str = "only_styles"
    leveled: bool = False
    variant_noun: str = "style"

    def variant_names(self) -> tuple[str, ...]:
        from ..styles.inputs import STYLES

        return STYLES

    def known_variant_names(self) -> tuple[str, ...]:
        return self.variant_names()

    def options(self) -> tuple[str, ...]:
        from ..styles.inputs import OPTIONS

        return OPTIONS

    def check_option(self, key: str, value, base: Path):
        from ..styles.inputs import check_option

        return check_option(key, value, base)

    def libraries(self) -> tuple[str, ...]:
        return super().libraries() + ("torch",)


def _benchmark_dataset(name: str, split_format: str, evaluation: tuple = ()) -> Dataset:
    """The dataset of corruption benchmark ``name``: its corruptions and levels."""
    b = BENCHMARKS[name]
    return Dataset(name, split_format, corruptions=b.corruptions, n_levels=b.n_levels,
                   evaluation=evaluation)


@dataclass(frozen=True)
class CustomDataset(Dataset):
    """Any folder of images (``build custom``): the sources are found under the root by
    pattern or listed in a file, each at its own size unless a size is given; see
    :mod:`robodepth_cli.sources.custom`."""

    discovers_sources: bool = True
    # Named subsets (name, comma-separated patterns), chosen by the `split` key (preset sets)
    splits: tuple = ()
    # Defaults of `robodepth evaluate` on a build of it: crop, min_depth, max_depth
    evaluation: tuple = (("crop", "none"),)

    def options(self) -> tuple[str, ...]:
        from .custom import OPTIONS

        return OPTIONS + super().options()

    def check_option(self, key: str, value, base: Path):
        from .custom import OPTIONS, check_option

        return check_option(key, value, base) if key in OPTIONS else super().check_option(key, value, base)


_WEATHERS = ("sunny", "cloudy", "foggy", "rainy")  # DrivingStereo's weather sets
_WEATHER_SPLITS = tuple((w, f"{w}/left-image-full-size/*.jpg,{w}/left-image-full-size/*.png")
                        for w in _WEATHERS) + (
    ("all", ",".join(f"{w}/left-image-full-size/*.{e}" for w in _WEATHERS for e in ("jpg", "png"))),)

DATASETS: dict[str, Dataset] = {
    "kitti-c": _benchmark_dataset("kitti-c", "eigen"),
    "nyudepth2-c": _benchmark_dataset("nyudepth2-c", "nyu", (("protocol", "nyu"),)),
    "kitti-s": StyleDataset("kitti-s", "eigen"),
    "custom": CustomDataset("custom", ""),
    # The zero-shot sets: custom builds whose pairing rule and reader are the preset's
    # (configs/<name>.yaml) and whose depth maps are under the root. Evaluation defaults
    # (crop, valid depth range) and where each comes from: docs/datasets-with-depth.md.
    "diode-c": CustomDataset("diode-c", "", depth_in_root=True, evaluation=(
        ("crop", "none"), ("min_depth", 0.6), ("max_depth", 350.0))),
    "sintel-c": CustomDataset("sintel-c", "", depth_in_root=True, evaluation=(
        ("crop", "none"), ("min_depth", 1e-3), ("max_depth", 70.0))),
    "eth3d-c": CustomDataset("eth3d-c", "", depth_in_root=True, evaluation=(
        ("crop", "none"), ("min_depth", 1e-5), ("max_depth", 1000.0))),
    "scannet-c": CustomDataset("scannet-c", "", depth_in_root=True, evaluation=(
        ("crop", "none"), ("min_depth", 1e-3), ("max_depth", 10.0))),
    "vkitti2-c": CustomDataset("vkitti2-c", "", depth_in_root=True, evaluation=(
        ("crop", "eigen"), ("min_depth", 1e-5), ("max_depth", 80.0))),
    "cityscapes-c": CustomDataset("cityscapes-c", "", depth_in_root=True, evaluation=(
        ("crop", "cityscapes"), ("min_depth", 1e-3), ("max_depth", 80.0))),
    "drivingstereo-c": CustomDataset("drivingstereo-c", "", depth_in_root=True, evaluation=(
        ("crop", "none"), ("min_depth", 1e-3), ("max_depth", 80.0)), splits=_WEATHER_SPLITS),
}


def get_dataset(name: str) -> Dataset:
    """The dataset called ``name``; :class:`InvalidValueError` listing the valid names otherwise."""
    try:
        return DATASETS[name]
    except KeyError:
        raise InvalidValueError(f"unknown dataset {name!r}; valid: {', '.join(DATASETS)}") from None
