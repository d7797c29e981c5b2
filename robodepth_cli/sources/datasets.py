"""What each dataset is, one declarative spec each (:data:`DATASETS`): its split format,
where its source images and depth live, how its outputs are named, which variants and levels
it has, its preset (what ``robodepth build NAME`` builds unless a config file or a flag says
otherwise; ``configs/NAME.yaml`` repeats it for the user to read, and a test holds the two
equal), the options it takes with their checks, its evaluation protocol and its published
baseline. The renderers are :mod:`robodepth_cli.building.renderers`.

A split entry becomes an :class:`Entry` with a *key*: the dataset-relative path of the
image with the extension ``.png`` (``kitti_data/<date>/<drive>/image_02/data/<frame>.png``
for KITTI, ``<scene>/rgb_<n>.png`` for NYU). The key names every output of that source,
``<variant>/<level>/<key>`` (``<variant>/<key>`` for datasets without levels,
``clean/<key>`` for the resized clean image), and is the relative path that seeds the
job's generator, so a PNG and a JPEG copy of a frame get the same noise.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path, PurePosixPath
from typing import Any, Callable, Sequence

from ..benchmark_facts import BENCHMARKS, CLEAN, CORRUPTIONS, DEPTH_AWARE, N_LEVELS, Baseline
from ..errors import InvalidValueError, os_reason
# SOURCE_EXTS: tried in this order when a split names no extension.
from ..sourcekeys import KITTI_PREFIX, PRESET_EXTS as SOURCE_EXTS, relative_parts
from .splits import SplitError

KITTI_SIDES = {"l": "image_02", "r": "image_03"}
# The corruption datasets' engines (--engine) and where they run (--device): building/renderers.py.
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
    root, path under the root). Raises :class:`~robodepth_cli.imageio.ImageError` if none exists.

    Symlinks under the root are followed wherever they lead: a KITTI root is often a
    directory of links to date folders on other disks, and every link in it is the user's
    own. A split entry itself can never leave the root (no absolute paths, no ``..``).
    """
    from ..imageio import ImageError  # PIL: not loaded by the commands that only name datasets

    for rel in entry.candidates:
        path = root / rel
        if path.is_file():
            return rel, path
    for rel in entry.candidates:
        if (root / rel).is_dir():
            raise ImageError(f"{root / rel}: is a directory, not an image file")
    tried = ", ".join(PurePosixPath(c).suffix for c in entry.candidates)
    raise ImageError(f"{root / entry.candidates[0]}: no such file (tried {tried})")


# --- the options a dataset takes ---------------------------------------------------------
# Each check is (value, base directory for relative paths) -> the checked value, or
# InvalidValueError saying what is wrong. The checks that need numpy or the depth readers
# import their module when a value is checked, so naming the datasets stays light.

@dataclass(frozen=True)
class Option:
    """A config key (and flag ``--key-name``) a dataset takes beyond the common ones."""

    key: str
    check: Callable[[Any, Path], Any]


def _one_of(choices: tuple[str, ...]):
    def check(value, base: Path):
        if value is not None and value not in choices:
            raise InvalidValueError(f"expected one of {', '.join(choices)}, got {value!r}")
        return value
    return check


def _scene_depth(value, base: Path):
    from .predicted import check_option

    return check_option(value, base)


def _severity_size(value, base: Path):  # kept as its text (build.json, the manifest, the card)
    from ..corruptions.scaling import parse_severity_size, size_text

    return size_text(parse_severity_size(value))


def _custom(key: str):
    def check(value, base: Path):
        from . import custom, depth_pairs

        if key == "pattern":
            return custom.parse_patterns(value)
        return custom.check_list(value, base) if key == "list" else depth_pairs.check_option(key, value, base)
    return check


def _style(key: str):
    def check(value, base: Path):
        from ..styles.inputs import check_option

        return check_option(key, value, base)
    return check


# The corruption datasets: the engine, its device, the depth of the depth-aware corruptions
# (a model's predictions) and the size the levels are defined at.
CORRUPTION_OPTIONS = (Option("engine", _one_of(ENGINES)), Option("device", _one_of(DEVICES)),
                      Option("scene_depth", _scene_depth), Option("severity_size", _severity_size))
# A folder of images: which images (sources/custom.py) and their depth (sources/depth_pairs.py).
CUSTOM_OPTIONS = tuple(Option(k, _custom(k)) for k in (
    "pattern", "list", "depth", "depth_pattern", "depth_mask", "depth_camera", "depth_scale",
    "depth_format", "depth_size")) + CORRUPTION_OPTIONS
# KITTI-S: the style images, AdaIN's checkpoints, its strength, the style size, its device.
STYLE_OPTIONS = tuple(Option(k, _style(k)) for k in ("styles", "vgg", "decoder", "alpha",
                                                     "style_size", "device"))


@dataclass(frozen=True)
class Options:
    """A build's values of the options above, typed; None: not set. ``build.json`` keeps
    those that are set as its ``extra`` mapping."""

    engine: str | None = None  # numpy or torch
    device: str | None = None  # the torch engine's or AdaIN's: auto, cpu, cuda
    scene_depth: str | None = None  # a predictions folder, absolute
    severity_size: str | None = None  # HxW or none
    pattern: tuple[str, ...] | None = None  # globs under the root
    list: str | None = None  # a file of relative image paths, absolute
    depth: str | None = None  # the depth maps' directory, absolute
    depth_pattern: str | None = None  # templates (sources/depth_pairs.py)
    depth_mask: str | None = None
    depth_camera: str | None = None
    depth_scale: float | None = None
    depth_format: str | None = None
    depth_size: str | None = None  # match or any
    styles: str | None = None  # paths as typed, joined to their config file's directory
    vgg: str | None = None
    decoder: str | None = None
    alpha: float | None = None
    style_size: int | None = None

    def as_dict(self) -> dict[str, Any]:
        """The options that are set."""
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}


# --- the spec ----------------------------------------------------------------------------

@dataclass(frozen=True)
class Dataset:
    """A dataset with corruptions as variants and numbered levels (KITTI-C, NYUDepth2-C).
    Datasets rendered differently (KITTI-S) subclass it and override the methods."""

    name: str
    split_format: str = ""  # a key of PARSERS; "" for one that finds its sources (custom)
    # Its preset: the split, the output size (HxW; None: each image at its own), the size its
    # levels are defined at (None: the benchmark's pixels), worker processes, and its options'
    # values ((key, value) pairs: where a zero-shot set's depth is, kitti-s's AdaIN settings).
    # Every preset builds all its variants at all its levels, seed 0, no limit.
    split: str | None = None
    size: str | None = None
    severity_size: str | None = None
    processes: int = 2
    settings: tuple = ()
    presets: tuple[str, ...] = ()  # other presets of it (configs/<name>.yaml: kitti-c-hr)
    # Its layout
    variant_key: str = "corruptions"  # the config key and flag that select the variants
    leveled: bool = True
    variant_noun: str = "corruption"  # in messages: "unknown corruption 'x'"
    corruptions: tuple[str, ...] = CORRUPTIONS  # this dataset's own, in benchmark order
    n_levels: int = N_LEVELS  # levels 1..n_levels
    discovers_sources: bool = False  # True: images found under the root, no split (custom)
    depth_in_root: bool = False  # True: a zero-shot set, its depth maps under the root
    # Named subsets (name, comma-separated patterns) chosen by the `split` key (weather sets)
    splits: tuple = ()
    options: tuple[Option, ...] = CORRUPTION_OPTIONS
    # Its evaluation: (key, value) defaults of `robodepth evaluate`: protocol (kitti unless
    # given), crop, min_depth, max_depth (the protocol's unless given)
    evaluation: tuple = ()
    # The published baseline its CE is measured against (benchmark_facts.py); None: scored
    # against the results CSV the user names (score --baseline), else as DEE and RR only.
    baseline: Baseline | None = None

    def preset(self) -> dict[str, Any]:
        """Its preset as the raw values of a configuration file."""
        raw: dict[str, Any] = {"dataset": self.name}
        if self.split:
            raw["split"] = self.split
        raw.update({"size": self.size, self.variant_key: "all"})
        if self.leveled:
            raw["levels"] = "all"
        if self.severity_size:
            raw["severity_size"] = self.severity_size
        return {**raw, "seed": 0, "jobs": self.processes, "limit": None, **dict(self.settings)}

    def option_keys(self) -> tuple[str, ...]:
        return tuple(o.key for o in self.options)

    def check_option(self, key: str, value, base: Path):
        """The checked value of option ``key``; :class:`InvalidValueError` saying what is wrong.
        ``base`` is the directory relative paths are resolved against."""
        for option in self.options:
            if option.key == key:
                return option.check(value, base)
        raise InvalidValueError(f"{self.name} has no option {key!r}")

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

    def has_depth(self, options: Options) -> bool:
        """Whether a build with ``options`` has a depth for the depth-aware corruptions."""
        return bool(not self.discovers_sources or self.depth_in_root or options.depth
                    or options.scene_depth)

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
    options: tuple[Option, ...] = STYLE_OPTIONS

    def variant_names(self) -> tuple[str, ...]:
        from ..styles.inputs import STYLES

        return STYLES

    def known_variant_names(self) -> tuple[str, ...]:
        return self.variant_names()

    def libraries(self) -> tuple[str, ...]:
        return super().libraries() + ("torch",)


@dataclass(frozen=True)
class CustomDataset(Dataset):
    """Any folder of images (``build custom``): the sources are found under the root by
    pattern or listed in a file, each at its own size unless a size is given; see
    :mod:`robodepth_cli.sources.custom`."""

    discovers_sources: bool = True
    severity_size: str | None = "192x640"  # the levels as KITTI-C's, scaled to each image by area
    options: tuple[Option, ...] = CUSTOM_OPTIONS
    evaluation: tuple = (("crop", "none"),)


def _published(name: str) -> dict[str, Any]:
    """The corruptions, levels and baseline of published benchmark ``name``."""
    b = BENCHMARKS[name]
    return {"corruptions": b.corruptions, "n_levels": b.n_levels, "baseline": b.baseline}


def _zero_shot(name: str, crop: str, min_depth: float, max_depth: float, **settings) -> CustomDataset:
    """A zero-shot set: a folder of images whose depth maps are under the same root, paired
    by its ``settings`` (pattern, depth_*). Where each default comes from:
    docs/datasets-with-depth.md."""
    given = {k: settings.pop(k) for k in ("split", "splits", "severity_size") if k in settings}
    return CustomDataset(name, depth_in_root=True, settings=tuple(settings.items()), **given,
                         evaluation=(("crop", crop), ("min_depth", min_depth), ("max_depth", max_depth)))


_WEATHERS = ("sunny", "cloudy", "foggy", "rainy")  # DrivingStereo's weather sets
_WEATHER_SPLITS = tuple((w, f"{w}/left-image-full-size/*.jpg,{w}/left-image-full-size/*.png")
                        for w in _WEATHERS) + (
    ("all", ",".join(f"{w}/left-image-full-size/*.{e}" for w in _WEATHERS for e in ("jpg", "png"))),)

DATASETS: dict[str, Dataset] = {
    "kitti-c": Dataset("kitti-c", "eigen", split="eigen_test", size="192x640", presets=("kitti-c-hr",),
                       **_published("kitti-c")),
    "nyudepth2-c": Dataset("nyudepth2-c", "nyu", split="nyu_test", size="480x640",
                           evaluation=(("protocol", "nyu"),), **_published("nyudepth2-c")),
    "kitti-s": StyleDataset("kitti-s", "eigen", split="eigen_test", size="192x640", processes=1,
                            settings=(("alpha", 1.0), ("style_size", 512), ("device", "auto"))),
    "custom": CustomDataset("custom"),
    "diode-c": _zero_shot("diode-c", "none", 0.6, 350.0,
                          pattern="indoors/scene_*/scan_*/*.png,outdoor/scene_*/scan_*/*.png",
                          depth_pattern="{path}_depth.npy", depth_mask="{path}_depth_mask.npy"),
    "sintel-c": _zero_shot("sintel-c", "none", 1e-3, 70.0, pattern="training/final/*/*.png",
                           depth_pattern="training/depth/{parts[2]}/{stem}.dpt"),
    "eth3d-c": _zero_shot("eth3d-c", "none", 1e-5, 1000.0, pattern="*/images/dslr_images/*.JPG",
                          depth_pattern="{parts[0]}/ground_truth_depth/dslr_images/{name}",
                          depth_format="raw"),
    "scannet-c": _zero_shot("scannet-c", "none", 1e-3, 10.0, severity_size="480x640",
                            pattern="*/color/*.jpg", depth_pattern="{parts[0]}/depth/{stem}.png",
                            depth_scale=1000, depth_size="any"),
    "vkitti2-c": _zero_shot("vkitti2-c", "eigen", 1e-5, 80.0, pattern="*/clone/frames/rgb/Camera_0/*.jpg",
                            depth_pattern="{parts[0]}/{parts[1]}/frames/depth/{parts[4]}/depth_{digits}.png",
                            depth_scale=100),
    "cityscapes-c": _zero_shot("cityscapes-c", "cityscapes", 1e-3, 80.0,
                               pattern="leftImg8bit/val/*/*_leftImg8bit.png",
                               depth_pattern="disparity/{parts[1]}/{parts[2]}/{prefix}_disparity.png",
                               depth_camera="camera/{parts[1]}/{parts[2]}/{prefix}_camera.json",
                               depth_format="cityscapes"),
    "drivingstereo-c": _zero_shot("drivingstereo-c", "none", 1e-3, 80.0, split="all",
                                  splits=_WEATHER_SPLITS,
                                  depth_pattern="{parts[0]}/depth-map-full-size/{stem}.png",
                                  depth_scale=256),
}


def unpublished() -> tuple[str, ...]:
    """The datasets with corruptions but no published baseline."""
    return tuple(n for n, d in DATASETS.items() if d.leveled and d.baseline is None)


def zero_shot() -> tuple[str, ...]:
    """The zero-shot sets: folders of images with their depth maps under the same root."""
    return tuple(n for n, d in DATASETS.items() if d.depth_in_root)


def preset_names(which: Callable[[Dataset], bool]) -> tuple[str, ...]:
    """The presets of the datasets ``which`` selects, each dataset's own first (for help texts)."""
    return tuple(p for n, d in DATASETS.items() if which(d) for p in (n, *d.presets))


def get_dataset(name: str) -> Dataset:
    """The dataset called ``name``; :class:`InvalidValueError` listing the valid names otherwise."""
    try:
        return DATASETS[name]
    except KeyError:
        raise InvalidValueError(f"unknown dataset {name!r}; valid: {', '.join(DATASETS)}") from None
