"""``robodepth challenge build``: a challenge set drawn from a build of the source frames
(``private/build/``, a ``robodepth build`` with no corruption, so its checks, resuming and
manifest serve here); each image is rendered with the job seed a build of the same seed
gives it, so its pixels are that build's. The public folder is written under a temporary
name and renamed when complete."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..errors import RobodepthError, failure_reason
from . import layout
from .draw import Pick, draw

DEFAULT_IMAGES = {"kitti": 500, "nyu": 200}  # the ICRA 2023 challenge's tracks


def build_challenge(cfg, root: Path, out: Path, *, images: int | None, track: str | None,
                    progress: bool = False, command: list[str] | None = None) -> dict:
    """Build the challenge ``out/public`` and ``out/private`` (see the module docstring)
    from build configuration ``cfg`` (its variants and levels are the ones drawn from);
    returns the public ``challenge.json``."""
    from ..api import open_dataset
    from ..building.pipeline import build
    from ..sources.datasets import get_dataset

    ds = get_dataset(cfg.dataset)
    if not ds.leveled:
        raise RobodepthError(f"{cfg.dataset}: a challenge draws corruptions and levels; "
                             "this dataset has none")
    if not cfg.variants:
        raise RobodepthError("--corruptions: at least one corruption to draw from")
    # By default the track of the dataset's protocol: nyu, else kitti (the official evaluator).
    track = track or dict(ds.evaluation).get("protocol", "kitti")
    n = images or DEFAULT_IMAGES[track]
    public, private = Path(out) / "public", Path(out) / "private"
    if public.exists() and any(public.iterdir()):
        raise RobodepthError(f"{public}: exists; a challenge is drawn once (remove "
                             f"{out} to draw another)")
    stage = private / layout.BUILD
    summary = build(dataclasses.replace(cfg, variants=()), root, stage, progress=progress,
                    command=command, gt=True)
    if summary.interrupted:
        raise KeyboardInterrupt  # the command line says what was kept, exit status 130
    if not summary.complete:
        raise RobodepthError(f"{stage}: the build of the source frames did not finish "
                             f"({summary.text()}); fix it and rerun")
    built = open_dataset(stage)
    maps = ground_truth_maps(built)
    sources = [k for k in built.keys if k in maps]
    picks = draw(n, sources, cfg.variants, cfg.levels, cfg.seed, cfg.dataset)
    # The private files are written before the public folder takes its name: a challenge
    # whose key could not be written never looks built.
    _write_public(cfg, ds, root, stage, public, picks, track, progress,
                  then=lambda shas: _write_private(cfg, private, picks, shas, maps, track, n))
    return layout.read_meta(str(public))


def ground_truth_maps(built) -> dict:
    """Per source key of a build with ground truth, a function giving its full depth map
    (float32 metres, 0 or NaN where invalid): KITTI's ``gt_depths.npz`` (split order), NYU's
    16-bit PNGs in millimetres, a build with depth's ``gt/<key>.npy``."""
    from ..groundtruth.read import GroundTruthError, read_depth_maps
    from ..imageio import read_depth_png

    gt = built.ground_truth()
    if gt is None:
        raise RobodepthError(f"{built.path}: no ground truth (the scans or depth maps of "
                             "the source frames are missing); a challenge needs it")
    if gt.is_file():
        depth = read_depth_maps(gt)
        return {k: (lambda m=m: np.asarray(m, np.float32)) for k, m in zip(built.keys, depth)}
    names = built.depth_names()
    out = {}
    for key, name in zip(built.keys, names):
        path = gt / name
        if key in built.no_depth or not path.is_file():
            continue
        if name.endswith(".npy"):
            out[key] = lambda p=path: np.load(p, allow_pickle=False).astype(np.float32)
        else:
            out[key] = lambda p=path: read_depth_png(p, "ground truth", GroundTruthError).astype(np.float32) / 1000.0
    return out


def _write_public(cfg, ds, root: Path, stage: Path, public: Path, picks: list[Pick],
                  track: str, progress: bool, then) -> None:
    """Render and write every image, then the list, README and metadata, then call
    ``then`` with the sha256 of each id's PNG; the folder appears whole after that."""
    from ..building.gather import gather_sources
    from ..building.pipeline import make_renderer
    from ..building.jobs import load_source
    from ..files import atomic_directory, sha256_bytes, write_atomic
    from ..imageio import encode_png
    from ..progress import bar as progress_bar
    from ..sources.datasets import Job

    from ..building.gather import check_root

    checked = check_root(root, labeled_ok=ds.split_format == "nyu")
    sources, split = gather_sources(ds, cfg, checked, stage, root)
    by_key = {s.key: s for s in sources}
    renderer = make_renderer(ds, cfg, checked, split.get("path"), sources)
    shas, sizes = {}, set()
    order = sorted(picks, key=lambda p: (p.source, p.corruption, p.level))  # each frame decoded once
    with atomic_directory(public) as tmp, progress_bar("img", len(picks), progress=progress) as bar:
        (tmp / layout.IMAGES).mkdir()
        clean_key, clean = None, None
        for p in order:
            if p.source != clean_key:
                clean, why = load_source(by_key[p.source], cfg.size)
                if clean is None:
                    raise RobodepthError(why)
                clean_key = p.source
            [(_, img)] = list(renderer.render(clean, p.source, [Job(p.corruption, p.level)]))
            if isinstance(img, BaseException):
                raise RobodepthError(f"{by_key[p.source].path}: {p.corruption} level "
                                     f"{p.level}: {failure_reason(img)}")
            data = encode_png(img, method="fast")
            write_atomic(tmp / layout.IMAGES / f"{p.id}.png", data)
            shas[p.id] = sha256_bytes(data)
            sizes.add(img.shape[:2])
            bar.update(1)
        size = next(iter(sizes)) if len(sizes) == 1 else None
        ids = [p.id for p in picks]
        (tmp / layout.LIST).write_text("".join(i + "\n" for i in ids), encoding="utf-8")
        meta = {"format": layout.FORMAT, "track": track, "images": len(ids),
                "size": list(size) if size else None}
        (tmp / layout.META).write_text(layout.meta_text(meta), encoding="utf-8")
        (tmp / layout.README).write_text(readme(meta), encoding="utf-8")
        then(shas)


def _write_private(cfg, private: Path, picks: list[Pick], shas: dict, maps: dict, track: str,
                   n: int) -> None:
    from ..files import atomic_output, write_atomic
    from .npzfile import write_npz

    rows = [{"id": p.id, "position": p.position, "source": p.source, "corruption": p.corruption,
             "level": p.level, "seed": cfg.seed, "sha256": shas[p.id]} for p in picks]
    with atomic_output(private / layout.GT) as fh:
        write_npz(fh, (m for p in picks for m in layout.gt_members(p.id, maps[p.source]())))
    write_atomic(private / layout.KEY, layout.key_text(rows).encode())
    write_atomic(private / layout.LIST, "".join(p.id + "\n" for p in picks).encode())
    meta = {"format": layout.FORMAT, "track": track, "images": n, "dataset": cfg.dataset,
            "seed": cfg.seed, "corruptions": list(cfg.variants), "levels": list(cfg.levels)}
    write_atomic(private / layout.META, layout.meta_text(meta).encode())


def readme(meta: dict) -> str:
    """The public README: what to predict, in which order, and how to submit. It says
    nothing about any image beyond the set's size."""
    n, track = meta["images"], meta["track"]
    what = ("a disparity map (any scale: each map is median-scaled to the ground truth, as "
            "in the official evaluator)" if track == "kitti" else
            "a depth map in metres (no scaling is applied)")
    size = f"{meta['size'][0]} x {meta['size'][1]}" if meta.get("size") else "various sizes"
    return f"""# Challenge test set

{n} images in `images/` ({size}), named by anonymous ids. For every image predict {what}.
Maps may have any height and width; each is resized to its ground truth.

## The order

`list.txt` gives the ids, one a line. Predictions in an array follow **this order**, which
is not the order of the file names sorted (sorting them as strings gives another order).

## What to submit

Recommended: a keyed npz, immune to order mistakes; each map stored under its id:

```python
import numpy as np
np.savez_compressed("disp.npz", **{{image_id: prediction for image_id, prediction in maps.items()}})
```

then zip it: `zip submission.zip disp.npz`. Also accepted, as the official toolkit wrote them:

- `disp.npy` holding one float array of shape ({n}, H, W), maps in the order of `list.txt`,
  zipped alone: `zip submission.zip disp.npy`;
- `disp.npz` written with `np.savez_compressed("disp.npz", data=array)`, same array.

float16, float32 or float64; every value finite and above zero. A list of per-batch arrays
(saved with pickle) is refused: stack them into one array first. float16 halves the upload.

`robodepth challenge check submission.zip --public THIS_FOLDER` gives the server's verdict
on a submission offline, and `robodepth predict THIS_FOLDER --model ... --out submission.zip`
writes one.
"""
