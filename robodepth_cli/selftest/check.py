"""``robodepth selftest``: build the fixtures shipped in this package (:data:`BUILDS`, one of
each kind of variant, through the ordinary builder) and compare every output with the
reference recorded on the locked install (docs/reproducibility.md). KITTI-S outputs pass
within :data:`STYLE_TOLERANCE` grey levels (torch's CPU kernels are not bit-exact across
CPUs), every other output must be the reference's bytes; an output whose optional
dependency is missing (PyAV, torch) is skipped and said so. The reference holds each
output's sha256 and its pixels, so a difference says by how much; only :func:`record`
(``make selftest-record``) writes it, on the lock's install alone."""

from __future__ import annotations

import hashlib
import importlib.util
import json
import lzma
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..benchmark_facts import ALL_CORRUPTIONS, TEMPORAL
from ..errors import RobodepthError

DATA = Path(__file__).resolve().parent / "data"
REFERENCE = "reference.json"
PIXELS = "reference.xz"
STYLE_TOLERANCE = 1  # grey levels, KITTI-S only
CODEC = ("h264_crf", "h265_crf", "bit_error")  # need PyAV
# The optional distributions some outputs need: without one, those are skipped and a line
# says so. {distribution: what it is needed for}
OPTIONAL = {"av": "h264_crf, h265_crf, bit_error: PyAV (av)", "torch": "KITTI-S: torch"}
LEVELS = "1,2,3,4,5,2.5"
ADAIN_SEED = 20240601

_SEQUENCE = {"root": "kitti_raw", "split": "sequence_split.txt", "size": "32x64", "frames": "-1,1"}

# (name, dataset, flags as on the command line: paths relative to DATA)
BUILDS: tuple[tuple[str, str, dict[str, str]], ...] = (
    ("custom", "custom", {"root": "images", "depth": "depth", "depth_scale": "256",
                          "corruptions": ",".join(ALL_CORRUPTIONS), "levels": LEVELS,
                          "compose": "fog:3+gaussian_noise:2.5"}),
    ("sequence", "kitti-c", {**_SEQUENCE, "levels": LEVELS,
                             "corruptions": ",".join(TEMPORAL)}),
    ("neighbours", "kitti-c", {**_SEQUENCE, "levels": "3",
                               "corruptions": "fog,frost,glass_blur,motion_blur,gaussian_noise"}),
    ("kitti-s", "kitti-s", {"root": "kitti_raw", "split": "sequence_split.txt", "size": "32x64",
                            "styles": "styles", "only_styles": "sketch", "style_size": "32",
                            "device": "cpu", "vgg": "{vgg}", "decoder": "{decoder}"}),
)
_PATH_FLAGS = ("root", "depth", "split", "styles")


class SelftestError(RobodepthError):
    """The selftest cannot run or cannot read its reference."""


# ----------------------------------------------------------------------- the builds


def absent() -> tuple[str, ...]:
    """The distributions of :data:`OPTIONAL` this install lacks."""
    return tuple(name for name in OPTIONAL if importlib.util.find_spec(name) is None)


def needs(entry: dict) -> str | None:
    """The optional distribution a reference output needs, if any."""
    if entry["corruption"] in CODEC:
        return "av"
    return "torch" if entry["variant"].startswith("kitti-s:") else None


def write_random_adain(folder: Path) -> tuple[Path, Path]:
    """AdaIN checkpoints in the published layout with normal weights drawn from numpy's
    generator seeded with :data:`ADAIN_SEED` (scaled by 1.4/sqrt(fan-in), so activations
    stay of order one and the decoded image is neither flat black nor white)."""
    import torch

    from ..styles.adain import DECODER_LAYOUT, ENCODER_LAYOUT, expected_tensors

    rng = np.random.default_rng(ADAIN_SEED)
    paths = []
    for name, layout in (("vgg", ENCODER_LAYOUT), ("decoder", DECODER_LAYOUT)):
        state = {}
        for key, (shape, _) in expected_tensors(layout).items():
            scale = 1.4 / np.sqrt(np.prod(shape[1:])) if key.endswith("weight") else 0.05
            state[key] = torch.from_numpy(rng.standard_normal(shape, dtype=np.float32) * np.float32(scale))
        paths.append(folder / f"{name}.pth")
        torch.save(state, paths[-1])
    return paths[0], paths[1]


def build_flags(flags: dict[str, str], checkpoints: dict[str, str]) -> dict[str, str]:
    """A build's flags with the fixture paths made absolute and the corruptions this
    install cannot build left out."""
    out = {k: str(DATA / v) if k in _PATH_FLAGS else v.format(**checkpoints) for k, v in flags.items()}
    if "corruptions" in out:
        skip = CODEC if "av" in absent() else ()
        out["corruptions"] = ",".join(c for c in out["corruptions"].split(",") if c not in skip)
    return out


def build_all(work: Path) -> None:
    """Run every build of :data:`BUILDS` into ``work/<name>`` through the ordinary builder."""
    from ..building.config import resolve
    from ..building.pipeline import build

    missing = absent()
    vgg, decoder = ("", "") if "torch" in missing else write_random_adain(work)
    checkpoints = {"vgg": str(vgg), "decoder": str(decoder)}
    for name, dataset, flags in BUILDS:
        if dataset == "kitti-s" and "torch" in missing:
            continue
        flags = build_flags(flags, checkpoints)
        root = Path(flags.pop("root"))
        summary = build(resolve(dataset, None, flags), root, work / name, command=["selftest"], gt=False)
        if summary.fatal or summary.interrupted:
            raise SelftestError(f"the {name} build stopped: {summary.fatal or 'interrupted'}")


@dataclass(frozen=True)
class Built:
    sha256: str
    error: str
    variant: str  # "<build>:<variant directory>", e.g. "custom:fog/3"
    corruption: str  # the row's variant name (a corruption, a chain, a style or clean)


def built_outputs(work: Path) -> dict[str, Built]:
    """``{"<build>/<output>": Built}`` of every build's manifest."""
    from ..output.layout import variant_dir
    from ..output.folder import OutputFolder

    found = {}
    for name, _, _ in BUILDS:
        for path, row in OutputFolder(work / name).rows().items():
            found[f"{name}/{path}"] = Built(row.sha256, row.error,
                                            f"{name}:{variant_dir(row.variant, row.level)}", row.variant)
    return found


def plan_digest() -> str:
    """What the reference was made from: the builds and every fixture file's bytes. A
    reference recorded for another plan cannot be compared with."""
    h = hashlib.sha256(json.dumps([BUILDS, ADAIN_SEED], sort_keys=True).encode())
    for p in sorted(q for q in DATA.rglob("*") if q.suffix in (".png", ".txt")):  # the inputs
        h.update(p.relative_to(DATA).as_posix().encode() + b"\0" + p.read_bytes())
    return h.hexdigest()[:16]


# ----------------------------------------------------------------------- the reference


@dataclass
class Reference:
    # "<build>/<output>" -> {"sha256", "shape", "offset" (into pixels), "variant", "corruption"}
    outputs: dict[str, dict]
    pixels: bytes
    plan: str
    versions: dict[str, str] = field(default_factory=dict)  # the install it was recorded on

    def image(self, key: str) -> np.ndarray:
        entry = self.outputs[key]
        size = int(np.prod(entry["shape"]))
        return np.frombuffer(self.pixels, np.uint8, size, entry["offset"]).reshape(entry["shape"])


def read_reference(folder: Path = DATA) -> Reference:
    try:
        meta = json.loads((folder / REFERENCE).read_text(encoding="utf-8"))
        pixels = lzma.decompress((folder / PIXELS).read_bytes())
        return Reference(meta["outputs"], pixels, meta["plan"], meta.get("versions", {}))
    except (OSError, ValueError, KeyError, TypeError, lzma.LZMAError) as exc:
        raise SelftestError(f"{folder}: cannot read the selftest's reference ({exc!r}); reinstall "
                            f"robodepth") from None


def record(work: Path, folder: Path = DATA) -> int:
    """Write the reference of the builds in ``work`` into ``folder``; the number of outputs."""
    from PIL import Image

    from ..files import write_atomic
    from ..versionlock import installed, locked

    outputs, chunks, offset = {}, [], 0
    for key, out in sorted(built_outputs(work).items()):
        if out.error:
            raise SelftestError(f"{key}: the build failed ({out.error}); nothing recorded")
        with Image.open(work / key) as im:
            img = np.ascontiguousarray(np.asarray(im), dtype=np.uint8)
        outputs[key] = {"sha256": out.sha256, "shape": list(img.shape), "offset": offset,
                        "variant": out.variant, "corruption": out.corruption}
        chunks.append(img.tobytes())
        offset += img.size
    meta = {"plan": plan_digest(), "versions": installed(locked()), "outputs": outputs}
    write_atomic(folder / PIXELS, lzma.compress(b"".join(chunks), preset=9 | lzma.PRESET_EXTREME))
    write_atomic(folder / REFERENCE, (json.dumps(meta, sort_keys=True) + "\n").encode())
    return len(outputs)


# ----------------------------------------------------------------------- the comparison


@dataclass
class VariantResult:
    outputs: int = 0
    differ: int = 0  # beyond the tolerance
    largest: int = 0  # grey levels, over the differing outputs
    not_built: list[str] = field(default_factory=list)  # why an output is missing

    def text(self) -> str:
        if self.not_built:
            return f"{len(self.not_built)} of {self.outputs} outputs not built ({self.not_built[0]})"
        return (f"{self.differ} of {self.outputs} outputs differ from the reference, largest "
                f"difference {self.largest} grey level{'s' if self.largest != 1 else ''}")


@dataclass
class Outcome:
    checked: int  # outputs compared
    failed: dict[str, VariantResult]  # variants that do not match, in reference order
    skipped: tuple[str, ...]  # the optional distributions missing, their outputs skipped
    versions: list[str]  # installed versions other than the lock's

    @property
    def ok(self) -> bool:
        """Whether every output has the reference's bytes; the versions do not decide it
        (an install at other versions that makes every reference byte passes, warned)."""
        return not self.failed


def compare(work: Path, ref: Reference) -> dict[str, VariantResult]:
    """Every output of the reference against the build's: the variants that do not match."""
    from ..output.compare import largest_difference, pixels

    built, skip = built_outputs(work), absent()
    results: dict[str, VariantResult] = {}
    for key, entry in ref.outputs.items():
        if needs(entry) in skip:
            continue
        v = results.setdefault(entry["variant"], VariantResult())
        v.outputs += 1
        out = built.get(key)
        if out is None or out.error:
            v.not_built.append(out.error if out else "no manifest row")
        elif out.sha256 != entry["sha256"]:
            try:
                d = largest_difference(pixels((work / key).read_bytes()), ref.image(key))
            except (OSError, ValueError):  # the build's file is gone or damaged
                d = None
            d = 255 if d is None else d  # another size: as different as it gets
            if d > tolerance(entry):
                v.differ += 1
                v.largest = max(v.largest, d)
    return {k: v for k, v in results.items() if v.differ or v.not_built}


def tolerance(entry: dict) -> int:
    """KITTI-S's stylised outputs may differ by :data:`STYLE_TOLERANCE`; nothing else may."""
    styled = entry["variant"].startswith("kitti-s:") and entry["corruption"] != "clean"
    return STYLE_TOLERANCE if styled else 0


def checked_count(ref: Reference) -> int:
    skip = absent()
    return sum(1 for e in ref.outputs.values() if needs(e) not in skip)


def version_differences() -> list[str]:
    """The pixel-deciding distributions installed at other versions than the lock's (PyAV
    and torch only when installed: without one, its outputs are skipped and the run says so)."""
    from ..versionlock import differences, installed, locked

    lock = {k: v for k, v in locked().items() if k not in absent()}
    return differences(installed(lock), lock, missing=True)


def run(work: Path, ref: Reference | None = None) -> Outcome:
    """Build into ``work`` (which must be empty) and compare with the reference."""
    ref = read_reference() if ref is None else ref
    if ref.plan != plan_digest():
        raise SelftestError("the reference was recorded for other fixtures or builds than these; "
                            "rerun 'make selftest-record' on the locked install")
    build_all(work)
    return Outcome(checked_count(ref), compare(work, ref), absent(), version_differences())
