"""Scoring: track kitti gives the official evaluator's numbers, the resize is scikit-image's,
and the breakdowns follow the key."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from skimage.transform import resize

from robodepth_cli.challenge.resize import resize_at
from tests.helpers.challenge import official_evaluate, write_reference
from tests.helpers.evaluation import fake_disp, lidar_gt

METRICS = ("abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3")


@pytest.mark.parametrize("src, dst, dtype", [
    ((192, 640), (375, 1242), np.float32),  # Track 1: network size up to the KITTI frame
    ((7, 5), (3, 13), np.float32),  # one side shrinks (Gaussian blur first), one grows
    ((400, 1300), (375, 1242), np.float32),  # both shrink
    ((1, 9), (4, 4), np.float32),  # a single row
    ((48, 64), (480, 640), np.float16),  # float16 is made float32 first
    ((20, 30), (9, 31), np.float64),
])
def test_resize_at_is_scikit_image_resize(src, dst, dtype):
    a = (np.random.default_rng(1).random(src) * 0.3 + 0.01).astype(dtype)
    want = resize(a, dst).reshape(-1)
    index = np.random.default_rng(2).permutation(want.size)[: want.size // 3]
    got = resize_at(a, dst, index)
    assert got.dtype == want.dtype
    if dtype == np.float64:
        np.testing.assert_allclose(got, want[index], rtol=1e-15, atol=0)
    else:
        np.testing.assert_array_equal(got, want[index])


def _kitti_case(tmp_path, n=6, shape=(192, 640), dtype=np.float32):
    ids = [f"{i:02d}id" for i in range(n)]
    gts = [lidar_gt((375, 1242) if i % 2 else (370, 1226), i) for i in range(n)]
    disps = np.stack([fake_disp(shape, i, 0.1 + 0.05 * i) for i in range(n)]).astype(dtype)
    ref = write_reference(tmp_path / "ref", ids, gts, corruptions=["fog", "fog", "dark", "snow", "snow", "snow"][:n],
                          levels=[1, 2, 1, 3, 3, 1][:n])
    return ids, gts, disps, ref


def _zip(path, name, array):
    np.save(path.parent / name, array)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.write(path.parent / name, name)
    return path


# (750, 2484): twice the ground truth, where scikit-image blurs before sampling (sigma 0.5)
@pytest.mark.parametrize("shape", [(192, 640), (96, 320), (750, 2484)])
def test_track_kitti_equals_the_official_evaluator(cli, tmp_path, shape):
    ids, gts, disps, ref = _kitti_case(tmp_path, shape=shape)
    want = official_evaluate(disps, gts)
    sub = _zip(tmp_path / "disp.zip", "disp.npy", disps)
    res = cli("challenge", "score", sub, "--reference", ref, "--out", tmp_path / "out", "--json")
    assert res.exit_code == 0, res.output
    got = json.loads((tmp_path / "out" / "scores.json").read_text())
    np.testing.assert_allclose([got[m] for m in METRICS], want, rtol=1e-6, atol=0)
    assert json.loads(res.output)["abs_rel"] == got["abs_rel"]


def test_the_three_forms_give_the_same_scores(cli, tmp_path):
    ids, gts, disps, ref = _kitti_case(tmp_path)
    dense = _zip(tmp_path / "disp.zip", "disp.npy", disps)
    np.savez_compressed(tmp_path / "data.npz", data=disps)
    np.savez_compressed(tmp_path / "keyed.npz", **{i: d for i, d in zip(ids, disps)})
    # the keyed form in any member order: the ids decide
    np.savez_compressed(tmp_path / "reversed.npz", **{i: d for i, d in reversed(list(zip(ids, disps)))})
    scores = []
    for sub in (dense, tmp_path / "data.npz", tmp_path / "keyed.npz", tmp_path / "reversed.npz"):
        res = cli("challenge", "score", sub, "--reference", ref, "--json")
        assert res.exit_code == 0, res.output
        scores.append(json.loads(res.output))
    assert all(s == scores[0] for s in scores)


def test_float16_is_scored_as_its_float32_values(cli, tmp_path):
    ids, gts, disps, ref = _kitti_case(tmp_path)
    half = disps.astype(np.float16)
    want = official_evaluate(half.astype(np.float32), gts)
    res = cli("challenge", "score", _zip(tmp_path / "d.zip", "disp.npy", half), "--reference", ref, "--json")
    got = json.loads(res.output)
    np.testing.assert_allclose([got[m] for m in METRICS], want, rtol=1e-6)


def test_breakdowns_follow_the_key(cli, tmp_path):
    ids, gts, disps, ref = _kitti_case(tmp_path)
    res = cli("challenge", "score", _zip(tmp_path / "d.zip", "disp.npy", disps), "--reference", ref, "--json")
    got = json.loads(res.output)
    fog = official_evaluate(disps[:2], gts[:2])
    snow = official_evaluate(disps[3:], gts[3:])
    assert got["abs_rel_fog"] == pytest.approx(fog[0], rel=1e-6)
    assert got["dee_snow"] == pytest.approx((snow[0] - snow[4] + 1) / 2, rel=1e-6)
    level1 = official_evaluate(disps[[0, 2, 5]], [gts[0], gts[2], gts[5]])
    assert got["dee_level1"] == pytest.approx((level1[0] - level1[4] + 1) / 2, rel=1e-6)
    # weather & lighting holds fog, dark and snow here: the mean of their DEEs
    dees = [got[f"dee_{c}"] for c in ("fog", "dark", "snow")]
    assert got["dee_weather_lighting"] == pytest.approx(np.mean(dees))
    assert got["mdee"] == pytest.approx(np.mean(dees))
    assert got["images"] == 6


def test_only_the_key_rows_are_scored_but_every_map_is_checked(cli, tmp_path):
    ids, gts, disps, _ = _kitti_case(tmp_path)
    ref = write_reference(tmp_path / "dev", ids, gts)
    key = (ref / "key.csv").read_text().splitlines()
    (ref / "key.csv").write_text("\n".join(key[:3]) + "\n")  # the first two images only
    res = cli("challenge", "score", _zip(tmp_path / "d.zip", "disp.npy", disps), "--reference", ref, "--json")
    got = json.loads(res.output)
    np.testing.assert_allclose(got["abs_rel"], official_evaluate(disps[:2], gts[:2])[0], rtol=1e-6)
    bad = disps.copy()
    bad[5, 0, 0] = np.nan  # an unscored image's map is still refused, as the final phase would
    res = cli("challenge", "score", _zip(tmp_path / "b.zip", "disp.npy", bad), "--reference", ref)
    assert res.exit_code == 2 and "map 5" in res.output and "NaN" in res.output


def test_track_nyu_is_the_nyu_protocol(cli, tmp_path):
    from robodepth_cli.evaluation.protocols import NYU_METRICS

    rng = np.random.default_rng(3)
    ids = ["a", "b"]
    gts = [rng.uniform(0.5, 9, (480, 640)).astype(np.float32) for _ in ids]
    preds = np.stack([g * rng.uniform(0.9, 1.1, g.shape).astype(np.float32) for g in gts])
    ref = write_reference(tmp_path / "ref", ids, gts, track="nyu")
    np.savez_compressed(tmp_path / "disp.npz", data=preds)
    got = json.loads(cli("challenge", "score", tmp_path / "disp.npz", "--reference", ref, "--json").output)
    # the NYU protocol at full size: Eigen crop rows 45..470, columns 41..600, 1e-3 < gt < 10
    want = []
    for g, p in zip(gts, preds):
        gg, pp = g[45:471, 41:601], np.clip(p[45:471, 41:601], 1e-3, 10)
        m = (gg > 1e-3) & (gg < 10)
        gg, pp = gg[m], pp[m]
        t = np.maximum(gg / pp, pp / gg)
        e = np.log(pp) - np.log(gg)
        want.append([np.mean(np.abs(gg - pp) / gg), (t < 1.25).mean(),
                     np.mean(np.abs(np.log10(pp) - np.log10(gg))), np.sqrt(np.mean(e ** 2) - np.mean(e) ** 2) * 100])
    want = np.mean(want, 0)
    np.testing.assert_allclose([got["abs_rel"], got["a1"], got["log10"], got["silog"]], want, rtol=1e-5)
    assert set(NYU_METRICS) <= set(got)


def test_detailed_results_page(cli, tmp_path):
    ids, gts, disps, ref = _kitti_case(tmp_path)
    out = tmp_path / "out"
    res = cli("challenge", "score", _zip(tmp_path / "d.zip", "disp.npy", disps), "--reference", ref, "--out", out)
    assert res.exit_code == 0, res.output
    page = (out / "detailed_results.html").read_text()
    scores = json.loads((out / "scores.json").read_text())
    assert page.count("<svg") == 1 and "Per corruption" in page and "Per level" in page
    for c in ("fog", "dark", "snow"):
        assert f"{scores['dee_' + c]:.4f}" in page


def test_page_colours_are_the_reports():
    from robodepth_cli.challenge.page import CATEGORY_COLOURS
    from robodepth_cli.report.plot import COLOURS

    assert {k: tuple(int(v[i:i + 2], 16) for i in (1, 3, 5)) for k, v in CATEGORY_COLOURS.items()} == COLOURS
