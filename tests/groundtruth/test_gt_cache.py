"""The ground truth kept between evaluations (groundtruth/cache.py): the second evaluation of
the same file under the same rule maps the arrays the first one kept instead of reading the
file; a changed file, another rule, a damaged entry, a cache turned off or not writable all
give the arrays a plain read gives."""

from __future__ import annotations

import json
import os

import cv2
import numpy as np
import pytest

from robodepth_cli.evaluation.protocols import make_setup
from robodepth_cli.groundtruth import cache
from robodepth_cli.groundtruth import read as gt_read
from robodepth_cli.groundtruth.kitti import GroundTruthError
from robodepth_cli.groundtruth.read import load_ground_truth

from tests.helpers.evaluation import lidar_gt

SHAPES = [(375, 1242), (370, 1226), (376, 1241)]
NAMES = [f"kitti_data/d/image_02/data/{i:010d}.png" for i in range(len(SHAPES))]
KITTI = make_setup("kitti")


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("ROBODEPTH_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("ROBODEPTH_GT_CACHE", raising=False)
    return tmp_path / "cache" / "ground-truth"


def _npz(path, seed=0):
    gts = np.empty(len(SHAPES), object)
    for i, shape in enumerate(SHAPES):
        gts[i] = lidar_gt(shape, seed + i)
    np.savez_compressed(path, data=gts)
    return path


def _load(path, names=NAMES, setup=KITTI, cached=True):
    return load_ground_truth(path, names, setup.protocol, setup.valid,
                             rule=setup.valid_rule if cached else None)


def _same(a, b):
    assert len(a) == len(b) and a.shapes == b.shapes and a.keys == b.keys
    for i in range(len(a)):
        (sa, ia, va), (sb, ib, vb) = a.get(i), b.get(i)
        assert tuple(sa) == tuple(sb)
        assert ia.dtype == ib.dtype and va.dtype == vb.dtype
        np.testing.assert_array_equal(ia, ib)
        np.testing.assert_array_equal(va, vb)


def _no_reading(monkeypatch):
    def refuse(*args):
        raise AssertionError("the ground-truth file was read")

    monkeypatch.setattr(gt_read, "read_gt_file", refuse)
    monkeypatch.setattr(gt_read, "read_depth_png", refuse)


def test_the_second_load_maps_what_the_first_kept(cache_dir, tmp_path, monkeypatch):
    path = _npz(tmp_path / "gt_depths.npz")
    plain = _load(path, cached=False)
    assert not cache_dir.exists()  # no rule: nothing kept
    first = _load(path)
    assert first.mapped is None and len(list(cache_dir.glob("*.json"))) == 1
    _no_reading(monkeypatch)
    second = _load(path)
    assert second.mapped is not None
    _same(second, plain)
    # the kept pixels are those the rule gives the map (written from the rule, not the cache)
    for i, shape in enumerate(SHAPES):
        g = lidar_gt(shape, i)
        _, index, values = second.get(i)
        np.testing.assert_array_equal(index, KITTI.valid(g))
        np.testing.assert_array_equal(values, g.reshape(-1)[KITTI.valid(g)])


def test_a_changed_file_is_read_again(cache_dir, tmp_path):
    path = _npz(tmp_path / "gt_depths.npz")
    _load(path)
    _npz(path, seed=10)  # the same shapes and names, other depths
    _same(_load(path), _load(path, cached=False))
    np.testing.assert_array_equal(_load(path).get(0)[2], lidar_gt(SHAPES[0], 10).reshape(-1)[
        KITTI.valid(lidar_gt(SHAPES[0], 10))])


def test_another_rule_is_another_entry(cache_dir, tmp_path):
    path = _npz(tmp_path / "gt_depths.npz")
    eigen = make_setup("kitti", crop="eigen")
    _load(path)
    got = _load(path, setup=eigen)
    _same(got, _load(path, setup=eigen, cached=False))
    assert len(list(cache_dir.glob("*.json"))) == 2
    assert got.get(0)[1].size != _load(path).get(0)[1].size  # the crops keep other pixels


@pytest.mark.parametrize("damage", ["truncated", "garbage", "other version", "offset outside"])
def test_a_damaged_entry_is_read_around_and_written_again(cache_dir, tmp_path, damage):
    path = _npz(tmp_path / "gt_depths.npz")
    _load(path)
    (meta,) = cache_dir.glob("*.json")
    data = meta.with_suffix(".bin")
    if damage == "truncated":
        data.write_bytes(data.read_bytes()[:100])
    elif damage == "garbage":
        meta.write_text("{not json")
    else:
        m = json.loads(meta.read_text())
        if damage == "other version":
            m["schema_version"] += 1
        else:
            m["entries"][0][1][0][0] = data.stat().st_size
        meta.write_text(json.dumps(m))
    got = _load(path)
    assert got.mapped is None  # read from the file
    _same(got, _load(path, cached=False))
    assert _load(path).mapped is not None  # and kept again


def test_a_count_or_order_that_does_not_match_is_refused_from_the_cache_too(cache_dir, tmp_path):
    path = _npz(tmp_path / "gt_depths.npz")
    _load(path)
    with pytest.raises(GroundTruthError, match="3 ground-truth maps, but the dataset's split has 2"):
        _load(path, names=NAMES[:2])


def test_a_folder_of_pngs_is_kept_and_a_changed_png_read_again(cache_dir, tmp_path, monkeypatch):
    nyu = make_setup("nyu")
    names = [f"scene/sync_depth_{i:05d}.png" for i in range(3)]
    rng = np.random.default_rng(0)
    for n in names:
        (tmp_path / "gt" / n).parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(tmp_path / "gt" / n), rng.integers(0, 12000, (480, 640)).astype(np.uint16))
    plain = _load(tmp_path / "gt", names, nyu, cached=False)
    _load(tmp_path / "gt", names, nyu)
    with monkeypatch.context() as m:
        _no_reading(m)
        kept = _load(tmp_path / "gt", names, nyu)
    assert kept.mapped is not None
    _same(kept, plain)
    for i in range(3):  # NYU's dense maps are kept whole, as read
        (raw, divisor), (want, d) = kept.dense(i), plain.dense(i)
        assert divisor == d == 1000.0 and raw.dtype == np.uint16
        np.testing.assert_array_equal(raw, want)
    cv2.imwrite(str(tmp_path / "gt" / names[1]), np.full((480, 640), 2000, np.uint16))
    again = _load(tmp_path / "gt", names, nyu)
    assert again.mapped is None
    assert (again.dense(1)[0] == 2000).all()


def test_off_or_not_writable_the_cache_is_not_used(cache_dir, tmp_path, monkeypatch):
    path = _npz(tmp_path / "gt_depths.npz")
    plain = _load(path, cached=False)
    monkeypatch.setenv("ROBODEPTH_GT_CACHE", "off")
    _same(_load(path), plain)
    _same(_load(path), plain)
    assert not cache_dir.parent.exists()
    monkeypatch.delenv("ROBODEPTH_GT_CACHE")
    cache_dir.parent.write_text("a file where the cache folder would be")
    _same(_load(path), plain)
    assert _load(path).mapped is None


def test_the_oldest_entries_go_first(cache_dir, tmp_path, monkeypatch):
    monkeypatch.setattr(cache, "MOST", 2)
    paths = [_npz(tmp_path / f"gt{i}.npz", seed=i) for i in range(3)]
    _load(paths[0])
    _load(paths[1])
    (oldest,) = [p for p in cache_dir.glob("*.json") if json.loads(p.read_text())["source"] == str(paths[0])]
    os.utime(oldest, ns=(1, 1))
    _load(paths[2])
    kept = {json.loads(p.read_text())["source"] for p in cache_dir.glob("*.json")}
    assert kept == {str(paths[1]), str(paths[2])}
    assert len(list(cache_dir.glob("*.bin"))) == 2
    assert _load(paths[1]).mapped is not None and _load(paths[0]).mapped is None


def test_evaluate_with_two_jobs_maps_the_cached_file(kitti_c, kitti_pred, cli, tmp_path, monkeypatch,
                                                     cache_dir):
    from robodepth_cli.evaluation import evaluate as E

    monkeypatch.setattr(E, "MAPS_PER_WORKER", 1)
    out, _ = kitti_c
    csv = [tmp_path / f"r{k}.csv" for k in range(3)]
    monkeypatch.setenv("ROBODEPTH_GT_CACHE", "off")
    assert cli("evaluate", out, "--pred", kitti_pred, "--out", csv[0], "--jobs", 1).exit_code == 0
    monkeypatch.delenv("ROBODEPTH_GT_CACHE")
    assert cli("evaluate", out, "--pred", kitti_pred, "--out", csv[1], "--jobs", 1).exit_code == 0
    assert len(list(cache_dir.glob("*.bin"))) == 1
    _no_reading(monkeypatch)
    res = cli("evaluate", out, "--pred", kitti_pred, "--out", csv[2], "--jobs", 2)
    assert res.exit_code == 0, res.output
    assert csv[0].read_bytes() == csv[1].read_bytes() == csv[2].read_bytes()
