"""Build configurations: presets, the user's ``--config FILE`` and flags.

A configuration is resolved in three layers, each overriding the one before: the preset
named on the command line (``configs/<preset>.yaml``, else a dataset's own preset from its
spec in :mod:`robodepth_cli.sources.datasets`), the user's file, then the flags.
Every layer is checked strictly as it is applied (unknown keys, wrong types, unknown
variant names, impossible levels), so a bad value is reported with the file or flag that
set it, the key, and the valid choices, before any work starts.

Keys: ``dataset`` (the dataset definition, e.g. ``kitti-c``), ``split`` (a standard split
name of ``splits/splits.json``, or a split file; relative paths in a YAML file are relative
to that file), ``size`` (``HxW`` or ``[H, W]``), ``corruptions`` (list of names, or
``all``: the dataset's own corruptions; ``none``: only chains), ``levels`` (list, or
``all``: the dataset's own levels; decimals such as 2.5 within the dataset's range),
``compose`` (chains such as ``fog:3+gaussian_noise:2.5``, a list or comma-separated text;
each is one more variant, built under its directory name), ``seed`` (integer >= 0), ``jobs`` (worker processes, >= 1), ``limit`` (first N
source images, or null for all), ``scheduler`` (a Dask scheduler address such as
``tcp://head:8786``: run the build on that cluster, ``jobs`` is then unused) or
``scheduler_file`` (the JSON file a Dask scheduler writes; at most one of the two: a later
layer's choice replaces an earlier layer's), ``png`` (``fast`` or ``compact``: how the PNGs
are written; same pixels either way; unset: the encoder OUT was built with, else ``fast``),
``frames`` (KITTI-C: neighbour offsets such as ``-1,1``, written beside every test frame), and
the dataset's own options (:class:`~robodepth_cli.sources.datasets.Option`: ``severity_size``,
``engine``, a custom build's ``depth``...). A corruption or level the dataset does not
have (fog or level 5 for NYUDepth2-C) is refused, naming the dataset's valid set.
"""

from __future__ import annotations

import importlib.util
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ..benchmark_facts import TEMPORAL
from ..files import data_dir
from ..sources import splits
from ..sources.datasets import DATASETS, Options, get_dataset
from .scenedepth import missing_depth
from ..errors import InvalidValueError
from .choices import (_CHECKS, _VARIANTS, ALL, NONE, ConfigError, check_train,  # noqa: F401
                      choose_chains, choose_levels, choose_names, takes_frames)

CONFIG_DIR = data_dir("configs")


@dataclass(frozen=True)
class BuildConfig:
    preset: str
    dataset: str
    split: str  # a standard split name, or a split file's path as typed (joined to its config file's directory)
    size: tuple[int, int] | None  # (H, W); None: every image at its own size (custom)
    variants: tuple[str, ...]
    levels: tuple[int, ...]
    seed: int
    jobs: int
    limit: int | None
    options: Options = field(default_factory=Options)  # the dataset's own options
    scheduler: str | None = None  # a Dask scheduler's address: build on that cluster
    scheduler_file: str | None = None  # or the scheduler file that holds it
    png: str | None = None  # "fast" or "compact"; None: the build's own, else fast
    frames: tuple[int, ...] = ()  # neighbour offsets (--frames -1,1); () a single-frame build
    # What the build says before it starts about how the settings were settled (one line
    # each); not part of the record.
    notes: tuple[str, ...] = field(default=(), compare=False)

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        del d["notes"], d["options"]
        d["extra"] = self.options.as_dict()  # the record's name for the options that are set
        if not self.frames:
            del d["frames"]  # a single-frame build's record has no frames key
        else:
            d["frames"] = list(self.frames)
        d["size"] = None if self.size is None else list(self.size)
        d["variants"] = list(self.variants)
        d["levels"] = list(self.levels)
        return d


def presets() -> tuple[str, ...]:
    """The preset names: the ``configs/*.yaml`` files and the datasets."""
    return tuple(sorted({p.stem for p in CONFIG_DIR.glob("*.yaml")} | set(DATASETS)))


def load_yaml(path: Path) -> dict[str, Any]:
    """A YAML mapping from ``path`` (safe loader); :class:`ConfigError` otherwise."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the config ({getattr(exc, 'strerror', None) or exc})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        tag = re.search(r"constructor for the tag '([^']*)'", problem)
        if isinstance(exc, yaml.constructor.ConstructorError) and tag:
            # e.g. !!python/object/apply:os.system: the safe loader refuses to build it.
            name = tag.group(1).replace("tag:yaml.org,2002:", "!!")
            raise ConfigError(f"{path}: {at}YAML tag {name!r} is not allowed (configs are read with a "
                              f"safe loader: plain values, lists and mappings only)") from None
        raise ConfigError(f"{path}: not valid YAML ({at}{problem})") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of keys to values, got {type(data).__name__}")
    return data


def _loc(where: str, key: str) -> str:
    """Where a value came from, for messages: a flag names itself, a file needs the key."""
    return where if where.startswith("--") else f"{where}: {key}"


class _Resolver:
    """Applies layers of raw values onto the current configuration, checking each one."""

    KEYS = ("dataset", "split", "size", "levels", "seed", "jobs", "limit", "png")
    ONE_OF = ("scheduler", "scheduler_file")  # where a cluster build runs: one or the other

    def __init__(self, preset: str):
        self.preset = preset
        self.values: dict[str, Any] = {}
        self.origin: dict[str, str] = {}
        self.preset_origin = ""  # the first layer applied: the preset

    @property
    def dataset(self):
        return get_dataset(self.values["dataset"])

    @classmethod
    def keys_of(cls, ds) -> tuple[str, ...]:
        """The config keys dataset ``ds`` takes (no ``levels`` for one without levels)."""
        return (tuple(k for k in cls.KEYS if k != "levels" or ds.leveled)
                + (ds.variant_key,) + (("compose", "train") if ds.leveled else ())
                + (("frames",) if takes_frames(ds) else ())
                + ds.option_keys() + cls.ONE_OF)

    def valid_keys(self) -> tuple[str, ...]:
        return self.keys_of(self.dataset)  # set by the preset, which is applied first

    def _elsewhere(self, where: str, key: str) -> str:
        """For a key another dataset takes: the message saying it does not apply here."""
        ds = self.dataset
        others = [d.name for d in DATASETS.values() if d.name != ds.name and key in self.keys_of(d)]
        if not others:
            return ""
        flag = where.startswith("--")
        what = where if flag else f"{where}: key {key!r}"
        hint = ""
        if key == "levels":
            hint = f"; {ds.name} has no levels (one output per {ds.variant_noun})"
        elif any(key == d.variant_key for d in DATASETS.values()):
            pick = f"--{ds.variant_key.replace('_', '-')}" if flag else repr(ds.variant_key)
            hint = f"; {ds.name} picks its {ds.variant_noun}s with {pick}"
        return f"{what} does not apply to {ds.name} (it is a setting of {', '.join(others)}){hint}"

    def apply(self, where: str, raw: dict[str, Any], base: Path) -> None:
        self.preset_origin = self.preset_origin or where
        if "dataset" in raw:
            self._set_dataset(where, raw["dataset"])
        for key, value in raw.items():
            if key == "dataset":
                continue
            if key not in self.valid_keys():
                elsewhere = self._elsewhere(where, key)
                if elsewhere:
                    raise ConfigError(elsewhere)
                raise ConfigError(f"{where}: unknown key {key!r}; valid keys: {', '.join(self.valid_keys())}")
            self.values[key] = self._check(_loc(where, key), key, value, base)
            self.origin[key] = where
        both = [k for k in self.ONE_OF if k in raw]
        if len(both) > 1:
            raise ConfigError(f"{where}: give either {' or '.join(_loc(where, k) for k in both)}, not both")
        for key in both:
            for other in self.ONE_OF:
                if other != key:
                    self.values.pop(other, None)

    def _set_dataset(self, where: str, name) -> None:
        try:
            ds = get_dataset(name)
        except InvalidValueError as exc:
            raise ConfigError(f"{where}: dataset: {exc}") from None
        if "dataset" in self.values and ds.name != self.values["dataset"]:
            raise ConfigError(f"{where}: dataset: {name!r} does not match {self.values['dataset']!r} "
                              f"of {self.origin['dataset']}; use the preset {name!r} instead")
        self.values["dataset"] = ds.name
        self.origin["dataset"] = where

    def _check(self, loc: str, key: str, v, base: Path):
        """The checked value of ``key`` by its rule in :data:`_CHECKS` (a dataset's own
        option by the dataset's); a value the rule refuses is a :class:`ConfigError` at ``loc``."""
        ds = self.dataset
        rule = _CHECKS.get(_VARIANTS if key == ds.variant_key else key)
        try:
            return rule(loc, v, base, ds) if rule else ds.check_option(key, v, base)
        except (InvalidValueError, splits.SplitError) as exc:  # SplitError: the records file
            raise ConfigError(f"{loc}: {exc}") from None

    def result(self) -> BuildConfig:
        required = ("dataset", "split", "size", self.dataset.variant_key, "seed", "jobs")
        missing = [k for k in required if k not in self.values
                   and not (k == "split" and self.dataset.discovers_sources)]
        if missing:
            raise ConfigError(f"preset {self.preset!r}: missing keys {', '.join(missing)}")
        ds = self.dataset
        variants = tuple(self.values[ds.variant_key]) + tuple(self.values.get("compose", ()))
        if not variants and not ds.discovers_sources:  # a folder's clean images alone are a set
            where = self.origin.get("compose") or self.origin[ds.variant_key]
            raise ConfigError(f"{where}: nothing to build: {ds.variant_key} none and no compose chains")
        seen = set(self.values.get("train", {}).get("corruptions", ())) & set(self.values[ds.variant_key])
        if seen:
            raise ConfigError(f"{self.origin['train']}: train: {', '.join(sorted(seen))} also built for "
                              f"testing; a held-out protocol trains on other corruptions")
        over_time = [v for v in variants if v in TEMPORAL]
        if over_time and not self.values.get("frames"):
            raise ConfigError(f"{self.origin[ds.variant_key]}: {over_time[0]} is a corruption over "
                              f"time: it needs the neighbour frames (--frames, e.g. -1,1)")
        coded = [v for v in over_time if v not in ("frame_lost", "frame_freeze")]
        if coded and importlib.util.find_spec("av") is None:  # found, not imported
            raise ConfigError(f"{self.origin[ds.variant_key]}: {coded[0]} needs PyAV: "
                              f"pip install 'robodepth-cli[video]'")
        levels = self.values.get("levels", ds.levels()) if ds.leveled else ()
        notes: list[str] = []
        options = Options(**{k: v for k, v in self.values.items() if k in ds.option_keys()})
        lacking = missing_depth(ds, self.values, options)  # (key, why): a depth-aware variant without depth
        if lacking:
            raise ConfigError(f"{_loc(self.origin[lacking[0]], lacking[0])}: {lacking[1]}")
        if "engine" in ds.option_keys():  # the corruption datasets: which engine, on which device
            from .renderers import settle

            try:
                options, notes = settle(options, {k: _loc(w, k) for k, w in self.origin.items()},
                                        {k for k, w in self.origin.items() if w == self.preset_origin})
            except InvalidValueError as exc:
                raise ConfigError(str(exc)) from None
            if options.engine == "torch" and self.values.get("frames"):
                raise ConfigError(f"{_loc(self.origin['engine'], 'engine')}: the torch engine does not "
                                  f"render neighbour frames (--frames); use --engine numpy")
        return BuildConfig(preset=self.preset, dataset=ds.name, split=self.values.get("split", ""),
                           size=self.values["size"], variants=tuple(variants), levels=tuple(levels),
                           seed=self.values["seed"], jobs=self.values["jobs"],
                           limit=self.values.get("limit"), options=options,
                           scheduler=self.values.get("scheduler"),
                           scheduler_file=self.values.get("scheduler_file"),
                           png=self.values.get("png"), frames=self.values.get("frames", ()),
                           notes=tuple(notes))


def resolve(preset: str, config_file: Path | None = None,
            flags: dict[str, Any] | None = None) -> BuildConfig:
    """The configuration of preset ``preset``, overridden by ``config_file`` and then by
    ``flags`` (a mapping of config key to flag text; None values are ignored)."""
    if preset not in presets():
        raise ConfigError(f"unknown dataset {preset!r}; valid: {', '.join(presets())}")
    r = _Resolver(preset)
    preset_file = CONFIG_DIR / f"{preset}.yaml"
    if preset_file.is_file():
        raw = load_yaml(preset_file)
        if "dataset" not in raw:
            raise ConfigError(f"{preset_file}: dataset: missing")
        r.apply(str(preset_file), raw, preset_file.parent)
    else:  # a dataset without a preset file: its spec's
        r.apply(f"the preset of {preset}", get_dataset(preset).preset(), Path())
    if config_file is not None:
        r.apply(str(config_file), load_yaml(config_file), Path(config_file).parent)
    for key, value in (flags or {}).items():
        if value is not None:
            r.apply(f"--{key.replace('_', '-')}", {key: value}, Path())
    return r.result()
