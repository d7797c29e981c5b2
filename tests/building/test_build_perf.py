"""The builder's work layout that its speed depends on (timings are in bench/build.py):
one decode and resize per source image, small messages to the workers."""

from __future__ import annotations

import pickle

from robodepth_cli.building import gather, pipeline as builder, renderers, jobs

from robodepth_cli.building import config
from robodepth_cli.sources.datasets import get_dataset

from tests.helpers.trees import kitti_tree

FRAMES = [(5, "l", ".png"), (7, "r", ".jpg")]


def test_each_source_is_decoded_and_resized_once(tmp_path, monkeypatch, cli):
    split = kitti_tree(tmp_path / "kitti_raw", FRAMES)
    calls = []
    real = jobs.load_clean

    def counting(path, size, **kw):
        calls.append((str(path), size))
        return real(path, size, **kw)

    monkeypatch.setattr(jobs, "load_clean", counting)
    res = cli("build", "kitti-c", "--root", tmp_path / "kitti_raw", "--split", split,
              "--out", tmp_path / "out", "--size", "48x96", "--corruptions", "contrast,color_quant",
              "--levels", "1,2", "--jobs", "1")
    assert res.exit_code == 0, res.output
    assert len(calls) == len(FRAMES)  # not once per output (5 outputs per source here)
    assert len({path for path, _ in calls}) == len(FRAMES)
    assert {size for _, size in calls} == {(48, 96)}


def test_what_a_worker_receives_per_source_is_small(tmp_path):
    """A task names its source by path; the image is read in the worker, never pickled."""
    split = kitti_tree(tmp_path / "kitti_raw", FRAMES)
    cfg = config.resolve("kitti-c", flags={"split": str(split)})
    ds = get_dataset(cfg.dataset)
    sources = gather.find_sources((tmp_path / "kitti_raw").resolve(), split, ds)
    renderer = renderers.make_renderer(ds, cfg)
    planned = builder.plan(ds, cfg, sources, {}, renderer)
    assert len(planned[0].jobs) == 18 * 5 + 1
    assert len(pickle.dumps(renderer)) < 1024
    for task in planned:
        # An image of even 48 x 96 would take 13.8 kB; 91 job descriptions take far less.
        assert len(pickle.dumps(task)) < 8 * 1024
