"""What an evaluation of a dataset's build is judged by (``robodepth evaluate`` and
``robodepth run``): the :class:`~.protocols.Setup` from the dataset's own settings (its
protocol, crop and valid depth range), the model's record and the flags, and the benchmark
whose scores ``--score`` prints."""

from __future__ import annotations

from ..errors import RobodepthError
from .protocols import Setup, make_setup


def evaluation_setup(dataset: str, recorded: dict, protocol, kind, stereo, png_scale, align,
                     align_space, crop, min_depth, max_depth) -> tuple[Setup, list[str]]:
    """The evaluation's setup from the flags, with the ``kind``, ``align`` and
    ``align_space`` the model's record gives (``recorded``: its ``evaluate`` entry) for those
    not given, and the dataset's own protocol, crop and depth range for those not given;
    and which of the record's settings it took (``kind disp``), for a note."""
    from ..sources.datasets import get_dataset

    given = {"kind": kind, "align": align, "align_space": align_space}
    kind = kind or recorded.get("kind")
    if not stereo:  # stereo's fixed 5.4 replaces any recorded alignment
        align = align or recorded.get("align")
        align_space = align_space or recorded.get("align_space")
    taken = [f"{k} {v}" for k, v in (("kind", kind), ("align", align), ("align_space", align_space))
             if given[k] is None and v is not None and v == recorded.get(k)]
    # The dataset's own protocol, crop and depth range (custom builds: no crop) unless flags say.
    own = dict(get_dataset(dataset).evaluation)
    setup = make_setup(protocol or own.get("protocol", "kitti"),
                       kind, stereo, png_scale, align=align, align_space=align_space,
                       crop=crop or own.get("crop"),
                       min_depth=own.get("min_depth") if min_depth is None else min_depth,
                       max_depth=own.get("max_depth") if max_depth is None else max_depth)
    return setup, taken


def scored_benchmark(dataset: str, variants):
    """The benchmark whose scores ``--score`` prints for ``dataset`` (its ``variants``: what
    an unpublished one scores); refused for one without."""
    from .. import benchmark_facts
    from ..sources.datasets import unpublished

    if dataset in unpublished():  # DEE and RR; CE needs robodepth score --baseline
        built = [v for v in variants if v.level is not None and v.level == int(v.level)]
        return benchmark_facts.unpublished(dataset, tuple(v.name for v in built), 1,
                             levels=[int(v.level) for v in built if v.name in benchmark_facts.CORRUPTIONS])
    if dataset not in benchmark_facts.BENCHMARKS:
        raise RobodepthError(f"--score: {dataset} has no robustness scores (they exist "
                             f"for {', '.join((*benchmark_facts.BENCHMARKS, *unpublished()))})")
    return benchmark_facts.get_benchmark(dataset)
