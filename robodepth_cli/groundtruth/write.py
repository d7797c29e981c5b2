"""The ground truth a build writes beside its images, so the dataset can be evaluated as it is
(docs/ground-truth.md): ``OUT/gt_depths.npz`` for KITTI splits
(:mod:`robodepth_cli.groundtruth.kitti`), ``OUT/gt/<depth path>`` PNGs for NYU splits
(:mod:`robodepth_cli.groundtruth.nyu`), ``OUT/gt/<key stem>.npy`` float32 metres for a
build with depth (:func:`robodepth_cli.sources.depth_io.read_depth`, never resized).

Rows have the variant ``gt``, no level, seed 0 and the map's size (0 x 0 for the npz).
``params`` fingerprints the inputs, so a rebuild skips ground truth whose inputs have not
changed. A failure (a bad calibration, a truncated scan) is a failed row, like a broken
image; missing inputs are a note, and rerunning the same build adds the file."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import RobodepthError, cannot_write
from ..output.folder import OutputFolder
from ..output.layout import GT_DIR, GT_FILE, depth_gt_name
from ..output.manifest import Row

GT = "gt"  # the variant of ground-truth rows
_VERSION = "1"  # bump when the ground truth of the same inputs changes
# A scene's median depth beyond this is no plausible distance in metres (KITTI's is ~15 m,
# the farthest outdoor sets' ~100 m): the map is most likely in millimetres or another unit.
PLAUSIBLE_MEDIAN_M = 1000.0


@dataclass(frozen=True)
class GtJob:
    """One ground-truth output of a build."""

    output: str  # relative to OUT
    source: str  # what it is made from, for the manifest
    params: str  # fingerprint of the inputs
    frames: tuple = ()  # KITTI: the KittiFrames; NYU: (NyuFrame,)
    error: str = ""  # known before any work (a NYU frame not in the labeled file)


@dataclass
class GtPlan:
    kind: str  # "kitti", "nyu" or "depth"
    root: Path
    split_name: str
    jobs: list[GtJob]
    note: str = ""  # why there is no ground truth, when there is none
    # Depth maps written whose values look like another unit than metres: "path (median X m)".
    implausible: list[str] = field(default_factory=list)

    def unit_warning(self) -> str:
        """The build's warning about :attr:`implausible` maps."""
        shown = ", ".join(self.implausible[:2]) + (", ..." if len(self.implausible) > 2 else "")
        return (f"warning: {len(self.implausible)} depth map(s) have a median depth above "
                f"{PLAUSIBLE_MEDIAN_M:g} m, no plausible distance in metres ({shown}): are they in "
                "another unit? The evaluation leaves out images without a valid pixel in its "
                "depth range")


def _stat(path: Path) -> str:
    try:
        st = path.stat()
    except OSError:
        return "missing"
    return f"{st.st_size}:{st.st_mtime_ns}"


def _fingerprint(*parts: str) -> str:
    return hashlib.sha256("\n".join((_VERSION,) + parts).encode()).hexdigest()[:16]


def plan_gt(split_format: str, root: Path, split_path: Path, limit: int | None,
            rerun: str | None = None, lost=frozenset()) -> GtPlan:
    """The ground truth of a build of the first ``limit`` lines of ``split_path`` from
    ``root`` (a split format of ``eigen`` means KITTI, ``nyu`` NYU). ``rerun`` is the
    build's command as typed, which a note about missing inputs repeats; ``lost``: the
    image keys whose images are not in the root either (their own failures)."""
    root = Path(root)
    if split_format == "eigen":
        return _plan_kitti(root, split_path, limit, rerun, lost)
    return _plan_nyu(root, split_path, limit, rerun)


def plan_for(ds, cfg, root: Path, split_path: str | None, sources, frames: int,
             rerun: str | None) -> GtPlan | None:
    """The ground truth of a build: from the split for KITTI and NYU, from the paired depth
    maps for a build with depth; None for a custom build without depth."""
    if not ds.discovers_sources:
        lost = {s.key for s in sources if s.error}
        return plan_gt(ds.split_format, root, Path(split_path), frames, rerun, lost)
    from ..sources.depth_pairs import rule_of

    rule = rule_of(cfg.options, root, ds.depth_in_root)
    return None if rule is None else plan_depth(rule, root, sources)


def plan_depth(rule, root: Path, sources) -> GtPlan:
    """One job per source image: its depth map paired by ``rule`` (see the module docstring)."""
    from ..sources.depth_pairs import pair

    plan = GtPlan("depth", root, "", [])
    base = Path(rule.directory)
    for src in sources:
        output = f"{GT_DIR}/{depth_gt_name(src.key)}"
        if src.error:
            plan.jobs.append(GtJob(output, "", "", (rule, None, None), f"no image: {src.error}"))
            continue
        found = pair(rule, src.rel)
        inputs = [rule.fingerprint()] + [_stat(base / f) for f in (found.depth, found.mask,
                                                                    found.camera) if f]
        plan.jobs.append(GtJob(output, found.depth, _fingerprint(*inputs),
                               (rule, found, src), found.error))
    return plan


def _later(what: str, rerun: str | None) -> str:
    # Rerunning the build, not `robodepth gt` into OUT: only the build records the file in
    # its manifest, so `verify` keeps passing.
    command = f": {rerun}" if rerun else ""
    return (f"the images are built; put the {what} in place and rerun the same build, which adds "
            f"only the ground truth{command}")


def _plan_kitti(root: Path, split_path: Path, limit: int | None, rerun: str | None,
                lost=frozenset()) -> GtPlan:
    from . import kitti as gt_kitti

    frames = gt_kitti.read_frames(split_path)[:limit]
    plan = GtPlan("kitti", root, str(split_path), [])
    missing = gt_kitti.missing_velodyne(root, frames)
    lost_frames = {gt_kitti.frame_key(k) for k in lost}
    absent = [f for f in missing if f.key in lost_frames]
    if absent:
        lines = ", ".join(str(f.line) for f in absent[:3]) + (", ..." if len(absent) > 3 else "")
        many = len(absent) > 1
        plan.note = (f"no ground truth: split line{'s' if many else ''} {lines} name"
                     f"{'' if many else 's'} a frame not in the root: "
                     f"{'their images' if many else 'its image'} failed (above) and "
                     f"{'their scans' if many else 'its scan'} ({absent[0].velodyne(root)}"
                     f"{', ...' if many else ''}) {'are' if many else 'is'} missing too; "
                     f"{GT_FILE} holds one map per split line, so it is made only once every "
                     f"line's frame has its scan: correct or remove "
                     f"{'those lines' if many else 'that line'} and rerun the build")
        return plan
    if missing:
        others = len(missing) - 1
        more = f" and {others} other frame{'s' if others > 1 else ''}" if others else ""
        plan.note = (f"no ground truth: {missing[0].velodyne(root)} (split line {missing[0].line}){more} "
                     f"missing; " + _later("velodyne scans", rerun))
        return plan
    inputs = [f"{f.folder} {f.frame} {_stat(f.velodyne(root))}" for f in frames]
    for date in sorted({f.date for f in frames}):
        inputs += [f"{date}/{name} {_stat(root / date / name)}" for name in (gt_kitti.CAM_TO_CAM, gt_kitti.VELO_TO_CAM)]
    source = f"{len(frames)} velodyne scans"
    plan.jobs.append(GtJob(GT_FILE, source, _fingerprint(*inputs), tuple(frames)))
    return plan


def _plan_nyu(root: Path, split_path: Path, limit: int | None, rerun: str | None) -> GtPlan:
    from . import nyu as gt_nyu

    frames = gt_nyu.read_frames(split_path)[:limit]
    plan = GtPlan("nyu", root, str(split_path), [])
    if root.is_file():
        labeled = gt_nyu.opened(root)
        stat = _stat(root)
        for f in frames:
            try:
                i = gt_nyu.frame_index(labeled, f.rgb)
            except gt_nyu.NyuError as exc:
                plan.jobs.append(GtJob(f"{GT_DIR}/{f.depth}", "", "", (f,), f"{split_path}:{f.line}: {exc}"))
                continue
            plan.jobs.append(GtJob(f"{GT_DIR}/{f.depth}", gt_nyu.source_name(root, i),
                                   _fingerprint(stat, str(i)), (f,)))
        return plan
    missing = [f for f in frames if not (root / f.depth).is_file()]
    if missing:
        more = f" and {len(missing) - 1} other depth files" if len(missing) > 1 else ""
        plan.note = (f"no ground truth: {root / missing[0].depth} (split line {missing[0].line}){more} "
                     f"missing; " + _later("depth files", rerun))
        return plan
    for f in frames:
        plan.jobs.append(GtJob(f"{GT_DIR}/{f.depth}", f.depth, _fingerprint(_stat(root / f.depth)), (f,)))
    return plan


def _row(job: GtJob, sha: str = "", error: str = "", size: tuple[int, int] = (0, 0)) -> Row:
    return Row(job.output, job.source, GT, None, 0, size[0], size[1], sha, error, job.params)


def _is_done(job: GtJob, out: Path, done: dict[str, Row]) -> Row | None:
    from ..files import sha256_file

    r = done.get(job.output)
    if r is None or r.error or job.error or r.params != job.params or r.source != job.source:
        return None
    try:
        return r if sha256_file(out / job.output) == r.sha256 else None
    except OSError:
        return None


def run_gt(plan: GtPlan, folder: OutputFolder, progress: bool = False):
    """Make the jobs of ``plan`` that ``folder``'s manifest does not list as done. Yields
    ``(state, row)`` per job, state one of ``"skipped"``, ``"written"``, ``"failed"``,
    ``"fatal"`` (a write error)."""
    from ..progress import bar as progress_bar

    out, done = folder.path, folder.rows()
    todo = []
    for job in plan.jobs:
        r = _is_done(job, out, done)
        if r is not None:
            yield "skipped", r
        else:
            todo.append(job)
    if not todo:
        return
    if plan.kind == "kitti":
        yield from _run_kitti(plan, todo[0], out, progress)
        return
    run = _run_depth if plan.kind == "depth" else _run_nyu
    with progress_bar("depth", len(todo), progress=progress, desc="ground truth") as bar:
        for job in todo:
            yield run(plan, job, out)
            bar.update(1)


def _run_kitti(plan: GtPlan, job: GtJob, out: Path, progress: bool):
    from threadpoolctl import threadpool_limits
    from ..progress import bar as progress_bar

    from . import kitti as gt_kitti

    target = out / job.output
    with progress_bar("frame", len(job.frames), progress=progress, desc="ground truth") as bar:
        try:
            with threadpool_limits(1, user_api="blas"):
                maps = list(gt_kitti.depth_maps(plan.root, job.frames, plan.split_name, bar.update))
        except RobodepthError as exc:
            target.unlink(missing_ok=True)
            yield "failed", _row(job, error=str(exc))
            return
        # The maps are all made; compressing them takes a while with the bar at its end.
        bar.set_description_str(f"ground truth: compressing and writing {job.output}")
        bar.refresh()
        try:
            sha = gt_kitti.save_object_npz(target, maps, [f.key for f in job.frames])
        except OSError as exc:
            yield "fatal", _row(job, error=cannot_write(target, exc))
            return
    yield "written", _row(job, sha)


def _run_nyu(plan: GtPlan, job: GtJob, out: Path):
    from . import nyu as gt_nyu
    from ..files import write_atomic
    from ..files import sha256_bytes

    target = out / job.output
    (frame,) = job.frames
    try:
        if job.error:
            raise gt_nyu.NyuError(job.error)
        if plan.root.is_file():
            labeled = gt_nyu.opened(plan.root)
            depth = gt_nyu.sync_depth(labeled.depth(gt_nyu.frame_index(labeled, frame.rgb)))
            data, size = gt_nyu.encode_depth_png(depth), depth.shape
        else:
            data, size = gt_nyu.sync_depth_file(plan.root / frame.depth)
    except RobodepthError as exc:
        target.unlink(missing_ok=True)
        return "failed", _row(job, error=str(exc))
    try:
        write_atomic(target, data)
    except OSError as exc:
        return "fatal", _row(job, error=cannot_write(target, exc))
    return "written", _row(job, sha256_bytes(data), size=size)




def _run_depth(plan: GtPlan, job: GtJob, out: Path):
    import io

    import numpy as np

    from ..files import sha256_bytes, write_atomic
    from ..imageio import stored_size
    from ..sources.depth_pairs import read_pair

    target = out / job.output
    rule, found, src = job.frames
    try:
        if job.error:
            raise RobodepthError(job.error)
        base = Path(rule.directory)
        size = stored_size(src.path)  # the depth map is the stored image's
        if size is None and (rule.same_size or rule.fmt == "raw"):
            raise RobodepthError(f"{src.path}: cannot read the image's size")
        depth = read_pair(rule, found, size)
        if rule.same_size and depth.shape != size:
            raise RobodepthError(f"{base / found.depth}: depth map of {depth.shape[0]} x "
                                 f"{depth.shape[1]}, its image {src.rel} is {size[0]} x {size[1]} "
                                 "(--depth-size any allows it)")
        if not np.isfinite(depth).any():
            raise RobodepthError(f"{base / found.depth}: no valid depth (every pixel is 0, "
                                 "negative, NaN, infinite or masked)")
    except RobodepthError as exc:
        target.unlink(missing_ok=True)
        return "failed", _row(job, error=str(exc))
    median = float(np.nanmedian(depth))
    if median > PLAUSIBLE_MEDIAN_M:
        plan.implausible.append(f"{base / found.depth} (median {median:g} m)")
    buf = io.BytesIO()
    np.save(buf, depth, allow_pickle=False)
    data = buf.getvalue()
    try:
        write_atomic(target, data)
    except OSError as exc:
        return "fatal", _row(job, error=cannot_write(target, exc))
    return "written", _row(job, sha256_bytes(data), size=depth.shape)
