"""`robodepth evaluate` and the `open_dataset` API: predictions -> metrics under the kitti and nyu protocols.

The expected metrics come from references written here, step by step from the protocols'
rules (monodepth2's evaluate_depth.py for kitti, BTS's eval_with_pngs.py / AdaBins's
evaluate.py for nyu), on whole maps with boolean masks as those scripts do; never from the
package's own output.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.helpers.evaluation import KEY69, KITTI_VARIANTS, fake_disp, kitti_preds, lidar_gt, read_csv, ref_errors, smooth_depth, write_form1
from tests.helpers.paths import REPO

KITTI_COLS = ["abs_rel", "sq_rel", "rmse", "rmse_log", "a1", "a2", "a3"]
NYU_COLS = KITTI_COLS + ["log10", "silog"]


# --------------------------------------------------------------------------- references

def ref_kitti(gts, preds, kind="disp", stereo=False):
    """monodepth2's loop: resize to the gt size, invert, Garg crop and 1e-3 < gt < 80,
    median scaling (mono) or x5.4 (stereo), clamp to [1e-3, 80], mean over images."""
    errors, ratios = [], []
    for gt, pred in zip(gts, preds):
        h, w = gt.shape
        if kind == "sigmoid":
            pred = 1 / 100 + (1 / 0.1 - 1 / 100) * pred
        pred = cv2.resize(pred, (w, h))
        depth = pred if kind == "depth" else 1 / pred
        mask = (gt > 1e-3) & (gt < 80)
        crop = np.zeros(gt.shape, bool)
        crop[int(0.40810811 * h):int(0.99189189 * h), int(0.03594771 * w):int(0.96405229 * w)] = True
        mask &= crop
        d, g = depth[mask], gt[mask]
        if stereo:
            d = d * 5.4
        else:
            ratios.append(np.median(g) / np.median(d))
            d = d * ratios[-1]
        d[d < 1e-3] = 1e-3
        d[d > 80] = 80
        errors.append(ref_errors(g, d))
    return np.array(errors, np.float64).mean(0), ratios


def ref_upsample(a, h, w):
    """Corner-aligned bilinear upsampling, sample positions in float32 as PyTorch computes
    them, interpolated by SciPy (an implementation independent of the package's)."""
    from scipy.ndimage import map_coordinates

    ys = np.float32(a.shape[0] - 1) / np.float32(h - 1) * np.arange(h, dtype=np.float32)
    xs = np.float32(a.shape[1] - 1) / np.float32(w - 1) * np.arange(w, dtype=np.float32)
    yy, xx = np.meshgrid(ys.astype(np.float64), xs.astype(np.float64), indexing="ij")
    return map_coordinates(a.astype(np.float64), [yy, xx], order=1, mode="nearest").astype(np.float32)


def ref_nyu(gts_mm, preds):
    """BTS/AdaBins: gt = png / 1000; upsample a smaller prediction; clamp to [1e-3, 10],
    inf to 10; valid 1e-3 < gt < 10 in rows 45..470, columns 41..600; no scaling."""
    errors = []
    for raw, pred in zip(gts_mm, preds):
        gt = raw.astype(np.float32) / 1000.0
        if pred.shape != gt.shape:
            pred = ref_upsample(pred, *gt.shape)
        pred = pred.copy()
        pred[pred < 1e-3] = 1e-3
        pred[pred > 10] = 10
        pred[np.isinf(pred)] = 10
        valid = (gt > 1e-3) & (gt < 10)
        crop = np.zeros(gt.shape, bool)
        crop[45:471, 41:601] = True
        valid &= crop
        errors.append(ref_errors(gt[valid], pred[valid], nyu=True))
    return np.array(errors, np.float64).mean(0)


# --------------------------------------------------------------------------- data

def check_rows(rows, expected_by_variant, cols):
    assert [f"{r['corruption']}/{r['level']}".replace("clean/0", "clean") for r in rows] == \
        list(expected_by_variant)
    for r, want in zip(rows, expected_by_variant.values()):
        got = [float(r[c]) for c in cols]
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-9)


# --------------------------------------------------------------------------- kitti protocol

@pytest.mark.parametrize("flags, kind, stereo", [
    ((), "disp", False),
    (("--stereo",), "disp", True),
    (("--kind", "sigmoid"), "sigmoid", False),
    (("--kind", "depth", "--stereo"), "depth", True),
])
def test_kitti_matches_monodepth2_rules(kitti_c, kitti_pred, tmp_path, flags, kind, stereo, cli):
    out, gts = kitti_c
    pred = kitti_pred
    if kind == "sigmoid":  # raw sigmoid outputs in [0, 1]
        pred = write_form1(tmp_path / "sig", {v: kitti_preds(k) * 20 for k, v in enumerate(KITTI_VARIANTS)})
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv", *flags)
    assert res.exit_code == 0, res.stderr
    expected = {}
    for v in KITTI_VARIANTS:
        arr = np.load(pred / f"{v}.npy")
        expected[v] = ref_kitti(gts, list(arr), kind, stereo)[0]
    rows = read_csv(tmp_path / "r.csv")
    assert list(rows[0]) == ["corruption", "level"] + KITTI_COLS + ["dataset", "split"]
    assert {(r["dataset"], r["split"]) for r in rows} == {("kitti-c", "")}
    check_rows(rows, expected, KITTI_COLS)
    # The summary prints monodepth2's scaling-ratio line figures, only with median scaling.
    clean_ratios = ref_kitti(gts, list(np.load(pred / "clean.npy")), kind, stereo)[1]
    if stereo:
        assert "ratio med" not in res.stdout
    else:
        med = np.median(clean_ratios)
        line = next(ln for ln in res.stdout.splitlines() if ln.startswith("clean "))
        assert line.split()[-2:] == [f"{med:.3f}", f"{np.std(np.array(clean_ratios) / med):.3f}"]


def test_csv_keeps_full_precision(kitti_c, kitti_pred, tmp_path, cli):
    out, gts = kitti_c
    assert cli("evaluate", out, "--pred", kitti_pred, "--out", tmp_path / "r.csv").exit_code == 0
    text = (tmp_path / "r.csv").read_text()
    clean = text.splitlines()[1].split(",")
    want = ref_kitti(gts, list(np.load(kitti_pred / "clean.npy")))[0]
    assert clean[:2] == ["clean", "0"]
    assert float(clean[2]) == pytest.approx(want[0], rel=1e-6)  # the sums are float64 here
    assert len(clean[2]) > 10  # not rounded to a few decimals


def test_identities_perfect_and_scaled(kitti_c, tmp_path, cli):
    """Perfect predictions: abs_rel 0 and a1 1. A constant factor: same mono result (the
    median ratio absorbs it), a different stereo result."""
    out, gts = kitti_c
    # The inverse ground truth at its own size: the resize is the identity, so every valid
    # pixel's depth is exact. Invalid pixels get an arbitrary disparity.
    perfect = [np.where(g > 0, 1 / np.maximum(g, 1e-6), 1.0).astype(np.float32) for g in gts]
    # Form 2 (a file per image): maps of different sizes are fine there.
    ds_keys = json.loads((out / "build.json").read_text())["split"]["keys"]

    def write_form2(pred, factor):
        for v in KITTI_VARIANTS:
            for key, m in zip(ds_keys, perfect):
                p = pred / v / key.replace(".png", ".npy")
                p.parent.mkdir(parents=True, exist_ok=True)
                np.save(p, m * factor)
        return pred

    good = write_form2(tmp_path / "perfect", 1.0)
    for flags in ((), ("--stereo",)):
        factor = 5.4 if flags else 1.0  # stereo: depth = 1 / disp, then x 5.4
        pred = write_form2(tmp_path / f"p{factor}", factor) if flags else good
        assert cli("evaluate", out, "--pred", pred, "--out", tmp_path / "p.csv", *flags).exit_code == 0
        for r in read_csv(tmp_path / "p.csv"):
            assert float(r["abs_rel"]) < 1e-6 and float(r["a1"]) == 1.0

    scaled = write_form2(tmp_path / "scaled", 3.7)
    results = {}
    for name, pred in (("good", good), ("scaled", scaled)):
        for flags in ((), ("--stereo",)):
            assert cli("evaluate", out, "--pred", pred, "--out", tmp_path / "s.csv", *flags).exit_code == 0
            results[name, bool(flags)] = [float(r["abs_rel"]) for r in read_csv(tmp_path / "s.csv")]
    np.testing.assert_allclose(results["good", False], results["scaled", False], atol=1e-6)
    assert all(abs(a - b) > 0.1 for a, b in zip(results["good", True], results["scaled", True]))


def test_prediction_forms_agree(kitti_c, kitti_pred, tmp_path, cli):
    """Form 1 as .npy and .npz and form 2 (one .npy or 16-bit .png per image) give the
    same rows; a PNG is a depth (value / --png-scale)."""
    out, gts = kitti_c
    keys = json.loads((out / "build.json").read_text())["split"]["keys"]
    arrays = {v: np.load(kitti_pred / f"{v}.npy") for v in KITTI_VARIANTS}
    npz = write_form1(tmp_path / "npz", arrays, ".npz")
    per_image = tmp_path / "files"
    for v, arr in arrays.items():
        for key, m in zip(keys, arr):
            p = per_image / v / key.replace(".png", ".npy")
            p.parent.mkdir(parents=True, exist_ok=True)
            np.save(p, m)
    csvs = []
    for pred in (kitti_pred, npz, per_image):
        assert cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv").exit_code == 0
        csvs.append((tmp_path / "r.csv").read_text())
    assert csvs[0] == csvs[1] == csvs[2]

    # 16-bit PNGs of depth x 100 at the image size, evaluated as depths.
    pngs = tmp_path / "pngs"
    depths = {}
    for v, arr in arrays.items():
        depths[v] = []
        for key, m in zip(keys, arr):
            raw = np.clip(np.round(100 * 0.03 / m * 40), 0, 65535).astype(np.uint16)
            p = pngs / v / key
            p.parent.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(p), raw)
            depths[v].append(raw.astype(np.float32) / np.float32(100))
    res = cli("evaluate", out, "--pred", pngs, "--out", tmp_path / "png.csv", "--png-scale", "100",
              "--stereo")
    assert res.exit_code == 0, res.stderr
    check_rows(read_csv(tmp_path / "png.csv"),
               {v: ref_kitti(gts, depths[v], "depth", True)[0] for v in KITTI_VARIANTS}, KITTI_COLS)


# --------------------------------------------------------------------------- nyu protocol

@pytest.fixture(scope="module")
def nyu_c(fixtures_dir, tmp_path_factory, cli):
    out = tmp_path_factory.mktemp("nyu") / "NYU_C"
    res = cli("build", "nyudepth2-c", "--root", fixtures_dir / "nyu", "--split",
              fixtures_dir / "nyu_split.txt", "--out", out, "--corruptions", "brightness",
              "--levels", "1", "--jobs", "1")
    assert res.exit_code == 0, res.output
    gts = []
    for i, n in enumerate(("00001", "00119")):
        rng = np.random.default_rng(i)
        mm = (smooth_depth(480, 640, i) / 8 * 1000).astype(np.uint16)
        mm[rng.random(mm.shape) < 0.2] = 0  # holes
        mm[:5] = 12000  # beyond 10 m: invalid
        path = out / "gt" / "bedroom" / f"sync_depth_{n}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(path), mm)
        gts.append(mm)
    return out, gts


def test_nyu_matches_bts_adabins_rules(nyu_c, tmp_path, cli):
    out, gts = nyu_c
    keys = ["bedroom/rgb_00001.png", "bedroom/rgb_00119.png"]
    rng = np.random.default_rng(5)
    # BTS style: one 16-bit PNG per image in millimetres, at the full size, with an image
    # whose depth goes past 10 m and below 1 mm.
    pngs, depths = tmp_path / "bts", {}
    for v in ("clean", "brightness/1"):
        depths[v] = []
        for key, gt in zip(keys, gts):
            mm = np.clip(gt.astype(np.float64) * rng.uniform(0.8, 1.3, gt.shape), 0, 15000)
            mm[0, :10] = 0
            mm = mm.astype(np.uint16)
            (pngs / v / key).parent.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(pngs / v / key), mm)
            depths[v].append(mm.astype(np.float32) / np.float32(1000))
    res = cli("evaluate", out, "--pred", pngs, "--out", tmp_path / "bts.csv")
    assert res.exit_code == 0, res.stderr
    rows = read_csv(tmp_path / "bts.csv")
    assert list(rows[0]) == ["corruption", "level"] + NYU_COLS + ["dataset", "split"]
    assert {(r["dataset"], r["split"]) for r in rows} == {("nyudepth2-c", "")}
    check_rows(rows, {v: ref_nyu(gts, d) for v, d in depths.items()}, NYU_COLS)

    # AdaBins style: arrays at half the size, upsampled with corners aligned.
    small = {v: np.stack([cv2.resize(d, (320, 240), interpolation=cv2.INTER_AREA) for d in ds])
             for v, ds in depths.items()}
    pred = write_form1(tmp_path / "ada", small)
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "ada.csv")
    assert res.exit_code == 0, res.stderr
    check_rows(read_csv(tmp_path / "ada.csv"), {v: ref_nyu(gts, list(a)) for v, a in small.items()},
               NYU_COLS)


def test_corner_aligned_upsampling_is_pytorchs():
    """AdaBins upsamples with torch's interpolate(bilinear, align_corners=True)."""
    import torch

    from robodepth_cli.evaluation.protocols import upsample_corners

    rng = np.random.default_rng(0)
    for (h, w), (H, W) in (((240, 320), (480, 640)), ((7, 5), (13, 11)), ((1, 4), (3, 9))):
        a = rng.uniform(0.5, 9, (h, w)).astype(np.float32)
        want = torch.nn.functional.interpolate(torch.from_numpy(a)[None, None], (H, W),
                                               mode="bilinear", align_corners=True)[0, 0].numpy()
        np.testing.assert_allclose(upsample_corners(a, H, W), want, rtol=0, atol=4e-6)


# --------------------------------------------------------------------------- the whole loop

def test_build_predict_evaluate_score(kitti_c, kitti_pred, tmp_path, cli):
    """--score prints what `robodepth score` prints for the CSV; --json carries both. The
    subset build is complete for evaluate (its own variants); the scores are partial."""
    out, _ = kitti_c
    res = cli("evaluate", out, "--pred", kitti_pred, "--out", tmp_path / "r.csv", "--score")
    assert res.exit_code == 0, res.stderr
    score = cli("score", tmp_path / "r.csv", "--benchmark", "kitti-c", "--allow-partial")
    assert score.exit_code == 0
    assert res.stdout.endswith(score.stdout)
    assert "partial: 86 variants missing" in res.stdout
    assert "missing 86 of 90 variants" in res.stderr

    res = cli("evaluate", out, "--pred", kitti_pred, "--out", tmp_path / "j.csv", "--score", "--json")
    doc = json.loads(res.stdout)
    score_json = json.loads(cli("score", tmp_path / "j.csv", "-b", "kitti-c", "--allow-partial",
                                "--json").stdout)
    assert doc["scores"] == score_json
    assert [(r["corruption"], r["level"]) for r in doc["results"]] == \
        [("clean", 0), ("brightness", 1), ("brightness", 3), ("contrast", 1), ("contrast", 3)]
    assert set(doc["results"][0]["scaling_ratio"]) == {"median", "std"}
    assert doc["partial"] is False and doc["csv"] == str(tmp_path / "j.csv")


def test_missing_variants_and_allow_partial(kitti_c, kitti_pred, tmp_path, cli):
    out, _ = kitti_c
    pred = write_form1(tmp_path / "p", {v: np.load(kitti_pred / f"{v}.npy")
                                        for v in ("clean", "brightness/1", "contrast/3")})
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv")
    assert res.exit_code == 2
    assert "no predictions for 2 of 5 variants: brightness 3, contrast 1" in res.stderr
    assert not (tmp_path / "r.csv").exists()
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv", "--allow-partial", "--json")
    assert res.exit_code == 0, res.stderr
    doc = json.loads(res.stdout)
    assert doc["partial"] is True
    assert doc["missing"] == [{"corruption": "brightness", "level": 3},
                              {"corruption": "contrast", "level": 1}]
    assert [r["corruption"] + r["level"] for r in read_csv(tmp_path / "r.csv")] == \
        ["clean0", "brightness1", "contrast3"]


# --------------------------------------------------------------------------- bad input

def _bad_pred(kitti_pred, tmp_path, change):
    pred = write_form1(tmp_path / "bad", {v: np.load(kitti_pred / f"{v}.npy") for v in KITTI_VARIANTS})
    change(pred)
    return pred


def _set(rel, fn):
    def change(pred):
        a = np.load(pred / f"{rel}.npy")
        np.save(pred / f"{rel}.npy", fn(a))
    return change


def _nan(a):
    a[1, 10, 20] = np.nan
    return a


def _negative(a):
    a[1, 3, 3] = -0.5
    return a


def _png(rel_key, img):
    """Every variant as PNGs (PNGs beside arrays are refused), contrast/1's first one bad."""
    def change(pred):
        for v in KITTI_VARIANTS:
            (pred / f"{v}.npy").unlink()
            for key in (rel_key, rel_key.replace("0000000069", "0000000054")):
                p = pred / v / key
                p.parent.mkdir(parents=True, exist_ok=True)
                cv2.imwrite(str(p), np.full((64, 96), 1000, np.uint16))
        cv2.imwrite(str(pred / "contrast/1" / rel_key), img)
    return change


@pytest.mark.parametrize("change, message", [
    (_set("brightness/3", lambda a: a[:1]), r"brightness/3\.npy: 1 predictions for the 2 images of brightness 3"),
    (_set("clean", lambda a: a[:, None]), r"clean\.npy: shape \(2, 1, 64, 96\); expected N x h x w"),
    (_set("contrast/3", _nan), r"contrast/3\.npy: prediction 1 contains NaN"),
    (_set("clean", _negative), r"clean\.npy: prediction 1 has negative values"),
    (_png(KEY69, np.full((50, 50), 1000, np.uint16)),
     r"contrast/1/kitti_data/.*/0000000069\.png \(image 0\) is 50 x 50; a PNG prediction must have"),
    (_png(KEY69, np.full((64, 96), 100, np.uint8)),
     r"0000000069\.png: 8-bit; expected a 16-bit single-channel PNG \(prediction of image 0\)"),
    (_png(KEY69, np.full((64, 96, 3), 100, np.uint16)),
     r"0000000069\.png: 16-bit, 3 channels; expected a 16-bit single-channel PNG"),
])
def test_bad_predictions_are_one_line_errors(kitti_c, kitti_pred, tmp_path, change, message, cli):
    out, _ = kitti_c
    pred = _bad_pred(kitti_pred, tmp_path, change)
    before = sorted(p for p in tmp_path.rglob("*"))
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv")
    assert res.exit_code == 2, res.stdout
    assert res.stderr.startswith("robodepth: error: ") and res.stderr.count("\n") == 1
    assert re.search(message, res.stderr), res.stderr
    assert sorted(p for p in tmp_path.rglob("*")) == before  # nothing written, no CSV


def test_bad_ground_truth(kitti_c, kitti_pred, tmp_path, cli):
    out, gts = kitti_c
    one = np.empty(1, object)
    one[0] = gts[0]
    np.savez_compressed(tmp_path / "one.npz", data=one)
    res = cli("evaluate", out, "--pred", kitti_pred, "--gt", tmp_path / "one.npz", "--out", tmp_path / "r.csv")
    assert res.exit_code == 2
    assert "one.npz: 1 ground-truth maps, but the dataset's split has 2 images" in res.stderr
    assert not (tmp_path / "r.csv").exists()

    bare = tmp_path / "bare"  # the same build without its ground truth
    bare.mkdir()
    for name in ("build.json", "manifest.csv"):
        (bare / name).write_bytes((out / name).read_bytes())
    res = cli("evaluate", bare, "--pred", kitti_pred, "--out", tmp_path / "r.csv")
    assert res.exit_code == 2
    assert f"{bare}: no ground truth" in res.stderr and "--gt" in res.stderr

    res = cli("evaluate", tmp_path, "--pred", kitti_pred)
    assert res.exit_code == 2 and "no build.json; not a dataset made by robodepth build" in res.stderr


def test_flag_combinations_refused(kitti_c, kitti_pred, tmp_path, cli):
    out, _ = kitti_c
    for flags, message in ((("--protocol", "nyu", "--stereo"), "--stereo applies to --protocol kitti only"),
                           (("--protocol", "nyu", "--kind", "disp"), "--protocol nyu evaluates depths"),
                           (("--png-scale", "0"), "--png-scale 0: must be a positive number")):
        res = cli("evaluate", out, "--pred", kitti_pred, "--out", tmp_path / "r.csv", *flags)
        assert res.exit_code == 2 and message in res.stderr, res.stderr
    assert not (tmp_path / "r.csv").exists()


# --------------------------------------------------------------------------- alignment

def ref_align(p, g, align):
    """The alignments from their definitions, by generic least squares (numpy's lstsq and
    polyfit), not the package's closed forms: returns the aligned values."""
    if align == "median":  # in the inputs' dtype, as monodepth2's median scaling
        return p * (np.median(g) / np.median(p))
    p, g = p.astype(np.float64), g.astype(np.float64)
    if align == "scale":
        s = np.linalg.lstsq(p[:, None], g, rcond=None)[0][0]
        return s * p
    s, t = np.polyfit(p, g, 1)
    return s * p + t


def ref_kitti_aligned(gts, preds, align, space, kind="disp", crop="garg", lo=1e-3, hi=80.0):
    """monodepth2's loop with the alignment in place of median scaling: resize, the crop
    and lo < gt < hi, align p (a depth or a disparity) to g (gt or 1/gt), back to a depth
    (a disparity <= 0: hi), clamp to [lo, hi]."""
    errors = []
    for gt, pred in zip(gts, preds):
        h, w = gt.shape
        pred = cv2.resize(pred, (w, h))
        disp = pred if kind == "disp" else 1 / pred
        box = {"garg": (0.40810811, 0.99189189, 0.03594771, 0.96405229),
               "eigen": (0.3324324, 0.91351351, 0.0359477, 0.96405229),
               "none": (0, 1, 0, 1)}[crop]
        inside = np.zeros(gt.shape, bool)
        inside[int(box[0] * h):int(box[1] * h), int(box[2] * w):int(box[3] * w)] = True
        mask = (gt > lo) & (gt < hi) & inside
        g = gt[mask]
        if space == "depth":
            d = ref_align(1 / disp[mask], g, align)
        else:
            a = ref_align(disp[mask], 1 / g, align)
            d = np.where(a > 0, 1 / np.where(a > 0, a, 1), hi)
        d = np.clip(d, lo, hi)
        errors.append(ref_errors(g, d))
    return np.array(errors, np.float64).mean(0)


def _form2(out, pred, maps_by_variant):
    keys = json.loads((out / "build.json").read_text())["split"]["keys"]
    for v, maps in maps_by_variant.items():
        for key, m in zip(keys, maps):
            p = pred / v / key.replace(".png", ".npy")
            p.parent.mkdir(parents=True, exist_ok=True)
            np.save(p, m)
    return pred


@pytest.mark.parametrize("align,space", [("median", "disparity"), ("scale", "depth"),
                                         ("scale", "disparity"), ("scale-shift", "depth"),
                                         ("scale-shift", "disparity")])
def test_alignments_match_their_definitions(kitti_c, kitti_pred, tmp_path, cli, align, space):
    out, gts = kitti_c
    res = cli("evaluate", out, "--pred", kitti_pred, "--out", tmp_path / "r.csv", "--align", align,
              "--align-space", space, "--json")
    assert res.exit_code == 0, res.stderr
    doc = json.loads(res.stdout)
    assert (doc["align"], doc["align_space"], doc["median_scaling"]) == (align, space, align == "median")
    expected = {v: ref_kitti_aligned(gts, list(np.load(kitti_pred / f"{v}.npy")), align, space)
                for v in KITTI_VARIANTS}
    check_rows(read_csv(tmp_path / "r.csv"), expected, KITTI_COLS)


def test_crop_and_depth_range(kitti_c, kitti_pred, tmp_path, cli):
    out, gts = kitti_c
    for crop in ("eigen", "none"):
        res = cli("evaluate", out, "--pred", kitti_pred, "--out", tmp_path / "r.csv", "--crop", crop,
                  "--min-depth", "5", "--max-depth", "50", "--align", "scale-shift",
                  "--align-space", "disparity")
        assert res.exit_code == 0, res.stderr
        expected = {v: ref_kitti_aligned(gts, list(np.load(kitti_pred / f"{v}.npy")), "scale-shift",
                                         "disparity", crop=crop, lo=5.0, hi=50.0)
                    for v in KITTI_VARIANTS}
        check_rows(read_csv(tmp_path / "r.csv"), expected, KITTI_COLS)


def test_median_default_unchanged(kitti_c, kitti_pred, tmp_path, cli):
    """Spelling out today's kitti default (median, depth, garg, 1e-3..80) changes no byte."""
    out, _ = kitti_c
    assert cli("evaluate", out, "--pred", kitti_pred, "--out", tmp_path / "a.csv").exit_code == 0
    res = cli("evaluate", out, "--pred", kitti_pred, "--out", tmp_path / "b.csv", "--align", "median",
              "--align-space", "depth", "--crop", "garg", "--min-depth", "0.001", "--max-depth", "80")
    assert res.exit_code == 0, res.stderr
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


def test_affine_distorted_predictions_are_perfect_after_scale_shift(kitti_c, tmp_path, cli):
    """A disparity s/gt + t (a relative model's ambiguity) and a depth s*gt + t give abs_rel 0
    and a1 1 after scale-shift in their own space; median scaling cannot undo the shift."""
    out, gts = kitti_c
    filled = [np.where(g > 0, g, 1.0).astype(np.float64) for g in gts]
    disp = {v: [(0.37 / f + 0.021 * (1 + k)).astype(np.float32) for f in filled]
            for k, v in enumerate(KITTI_VARIANTS)}
    depth = {v: [(2.5 * f - 1.5).astype(np.float32) for f in filled] for v in KITTI_VARIANTS}
    for maps, kind, space in ((disp, "disp", "disparity"), (depth, "depth", "depth")):
        pred = _form2(out, tmp_path / kind, maps)
        res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv", "--kind", kind,
                  "--align", "scale-shift", "--align-space", space)
        assert res.exit_code == 0, res.stderr
        for r in read_csv(tmp_path / "r.csv"):
            assert float(r["abs_rel"]) < 1e-5 and float(r["a1"]) == 1.0, r
        res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "m.csv", "--kind", kind)
        assert res.exit_code == 0, res.stderr
        assert all(float(r["abs_rel"]) > 1e-3 for r in read_csv(tmp_path / "m.csv"))


def test_relative_depth_on_nyu(nyu_c, tmp_path, cli):
    """A relative disparity on NYU: scale-shift in disparity space recovers it exactly;
    without --align it is refused (nyu evaluates metric depths)."""
    out, gts = nyu_c
    maps = {v: [(3.0 / np.where(g > 0, g / 1000, 1.0) + 0.2).astype(np.float32) for g in gts]
            for v in ("clean", "brightness/1")}
    pred = write_form1(tmp_path / "P", {v: np.stack(m) for v, m in maps.items()})
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv", "--kind", "disp",
              "--align", "scale-shift", "--align-space", "disparity")
    assert res.exit_code == 0, res.stderr
    for r in read_csv(tmp_path / "r.csv"):
        assert float(r["abs_rel"]) < 1e-5 and float(r["a1"]) == 1.0
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv", "--kind", "disp")
    assert res.exit_code == 2 and "--protocol nyu evaluates depths in metres" in res.stderr


def test_alignment_refusals(kitti_c, kitti_pred, tmp_path, cli):
    out, gts = kitti_c
    for flags, message in (
            (("--stereo", "--align", "scale"), "--stereo scales by 5.4 and aligns nothing"),
            (("--min-depth", "10", "--max-depth", "5"), "need 0 < min-depth < max-depth"),
            (("--align", "fit"), "robodepth: error: --align: 'fit' is not one of")):
        res = cli("evaluate", out, "--pred", kitti_pred, "--out", tmp_path / "r.csv", *flags)
        assert res.exit_code == 2 and message in res.stderr, res.stderr
    # a zero disparity has no depth: least squares in depth space has no number to give
    zero = {v: np.load(kitti_pred / f"{v}.npy") for v in KITTI_VARIANTS}
    zero["clean"] = zero["clean"].copy()
    zero["clean"][1, :, :48] = 0  # the left half infinitely far
    pred = write_form1(tmp_path / "zero", zero)
    res = cli("evaluate", out, "--pred", pred, "--out", tmp_path / "r.csv", "--align", "scale")
    assert res.exit_code == 2
    assert f"{pred / 'clean.npy'}: prediction 1: not a number after --align scale in depth space" \
        in res.stderr
    # negative values: refused, except under scale-shift where an affine output may have them
    neg = write_form1(tmp_path / "neg", {v: np.load(kitti_pred / f"{v}.npy") - 0.005
                                         for v in KITTI_VARIANTS})
    res = cli("evaluate", out, "--pred", neg, "--out", tmp_path / "r.csv")
    assert res.exit_code == 2 and "has negative values" in res.stderr
    res = cli("evaluate", out, "--pred", neg, "--out", tmp_path / "r.csv", "--align", "scale-shift",
              "--align-space", "disparity")
    assert res.exit_code == 0, res.stderr
    assert len(read_csv(tmp_path / "r.csv")) == len(KITTI_VARIANTS)


# --------------------------------------------------------------------------- Python API

def test_open_dataset_variants_and_images(kitti_c):
    from robodepth_cli import open_dataset

    out, _ = kitti_c
    ds = open_dataset(out)
    assert ds.name == "kitti-c" and ds.size == (64, 96)
    assert [v.relpath for v in ds.variants()] == KITTI_VARIANTS
    split = [ln.split() for ln in Path(ds.record.split["path"]).read_text().splitlines() if ln.strip()]
    for v in ds.variants():
        images = v.images()
        assert [p.relative_to(out / v.relpath).as_posix() for p in images] == \
            [f"kitti_data/{d}/image_02/data/{f}.png" for d, f, _ in split]
        assert all(p.is_file() for p in images)


def test_save_predictions_writes_form_1(kitti_c, tmp_path):
    from robodepth_cli import open_dataset
    from robodepth_cli.errors import RobodepthError

    out, _ = kitti_c
    v = open_dataset(out).variant("contrast", 3)
    maps = [np.full((4, 5), i + 1, np.float64) for i in range(2)]
    path = v.save_predictions(tmp_path / "P", maps)
    assert path == tmp_path / "P" / "contrast" / "3.npy"
    saved = np.load(path)
    assert saved.dtype == np.float64 and saved.shape == (2, 4, 5) and saved[1, 0, 0] == 2
    assert not [p for p in path.parent.iterdir() if p.name.startswith(".")]  # no temporary left
    with pytest.raises(RobodepthError, match=r"3\.npy: 1 predictions for the 2 images of contrast 3"):
        v.save_predictions(tmp_path / "P", maps[:1])
    with pytest.raises(RobodepthError, match=r"prediction 1 is 5 x 4, prediction 0 is 4 x 5"):
        v.save_predictions(tmp_path / "P", [maps[0], maps[1].T])
    assert np.load(path)[1, 0, 0] == 2  # the earlier file is intact


def test_prediction_writer_writes_in_large_pieces(tmp_path):
    """Maps are gathered into writes of many megabytes, not written one by one: on Linux
    the page cache then keeps the file in large folios, which evaluate's mapping takes in
    a fraction of the time. Counted in write system calls (/proc/self/io)."""
    from robodepth_cli.predictions import PredictionWriter

    io = Path("/proc/self/io")
    if not io.is_file():
        pytest.skip("no /proc/self/io")

    def writes() -> int:
        return int(next(ln for ln in io.read_text().splitlines() if ln.startswith("syscw:")).split()[1])

    maps = [np.full((192, 640), i, np.float32) for i in range(40)]  # 480 KiB each, 19.7 MB
    before = writes()
    with PredictionWriter(tmp_path / "clean.npy", len(maps)) as out:
        for m in maps:
            out.write(m)
    assert writes() - before < 10  # one a map would be 40
    assert np.array_equal(np.load(tmp_path / "clean.npy"), np.stack(maps))

def _blocks(path, heading):
    text = path.read_text()
    section = text[text.index(heading):]
    section = section[:section.index("\n#", 3)] if "\n#" in section[3:] else section
    return (re.findall(r"```python\n(.*?)```", section, re.S),
            re.findall(r"```sh\n(.*?)```", section, re.S))


@pytest.mark.slow
def test_readme_loop_runs(kitti_c, tmp_path, monkeypatch, cli):
    """The README's loop, its predict and evaluate commands exactly as printed, with a
    random-weight monodepth2 checkpoint where the README's model folder is."""
    from tests.helpers.models import random_monodepth2

    out, _ = kitti_c
    _, shell = _blocks(REPO / "README.md", "## The loop: build, predict, evaluate, score")
    lines = [ln.split("#")[0].split() for block in shell for ln in block.splitlines()]
    predict = [ln for ln in lines if ln[:2] == ["robodepth", "predict"]]
    evaluate = [ln for ln in lines if ln[:2] == ["robodepth", "evaluate"]]
    assert len(predict) == 1 and len(evaluate) == 1
    (tmp_path / "KITTI_C").symlink_to(out)
    monkeypatch.chdir(tmp_path)
    model = predict[0][predict[0].index("--model") + 1]
    random_monodepth2(tmp_path / model.partition(":")[2], 18)
    res = cli(*predict[0][1:])
    assert res.exit_code == 0, res.output
    res = cli(*evaluate[0][1:])
    assert res.exit_code == 0, res.stderr
    assert "mCE" in res.stdout
    assert [r["corruption"] for r in read_csv(tmp_path / "results.csv")] == \
        ["clean", "brightness", "brightness", "contrast", "contrast"]


def test_python_loop_in_the_docs_runs(kitti_c, tmp_path, monkeypatch, cli):
    """docs/predict.md's hand-written loop, exactly as printed, with a stand-in model."""
    out, _ = kitti_c
    python, _ = _blocks(REPO / "docs" / "predict.md", "### In Python")
    assert len(python) == 1 and 5 <= len(python[0].strip().splitlines()) <= 14
    (tmp_path / "KITTI_C").symlink_to(out)
    monkeypatch.chdir(tmp_path)

    def model(image):  # stand-in: brighter pixels are nearer
        assert image.dtype == np.uint8 and image.shape == (64, 96, 3)
        return (0.02 + image.mean(axis=2) / 2550).astype(np.float32)

    exec(compile(python[0], "predict.md", "exec"), {"model": model})
    res = cli("evaluate", "KITTI_C", "--pred", "PRED", "--score")
    assert res.exit_code == 0, res.stderr
    assert "mCE" in res.stdout
    assert [r["corruption"] for r in read_csv(tmp_path / "results.csv")] == \
        ["clean", "brightness", "brightness", "contrast", "contrast"]


def test_import_stays_light():
    code = ("import sys, robodepth_cli; assert 'numpy' not in sys.modules; "
            "assert callable(robodepth_cli.open_dataset)")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO)


@pytest.mark.parametrize("bom", [b"", b"\xef\xbb\xbf"], ids=["plain", "byte-order-mark"])
def test_nyu_ground_truth_follows_the_split_depth_paths(nyu_c, tmp_path, cli, bom):
    """A directory of ground truth is read at each split line's DEPTH path (a split with a
    byte-order mark too: the mark is not part of the first image's key); without the split
    file, at BTS's names (rgb_NNNNN -> sync_depth_NNNNN)."""
    import hashlib

    out, gts = nyu_c
    split = tmp_path / "split.txt"
    split.write_bytes(bom + b"bedroom/rgb_00001.jpg depth/first.png 518.8579\n"
                            b"bedroom/rgb_00119.jpg depth/second.png 518.8579\n")
    record = json.loads((out / "build.json").read_text())
    record["split"].update(path=str(split), sha256=hashlib.sha256(split.read_bytes()).hexdigest())
    ds = tmp_path / "NYU"
    ds.mkdir()
    (ds / "build.json").write_text(json.dumps(record))
    (ds / "manifest.csv").write_bytes((out / "manifest.csv").read_bytes())
    gt_dir = tmp_path / "gt"
    (gt_dir / "depth").mkdir(parents=True)
    cv2.imwrite(str(gt_dir / "depth/first.png"), gts[0])
    cv2.imwrite(str(gt_dir / "depth/second.png"), gts[1])
    preds = np.stack([g.astype(np.float32) / 1000 * 1.1 for g in gts])
    pred = write_form1(tmp_path / "P", {"clean": preds, "brightness/1": preds})
    res = cli("evaluate", ds, "--pred", pred, "--gt", gt_dir, "--out", tmp_path / "r.csv")
    assert res.exit_code == 0, res.output
    check_rows(read_csv(tmp_path / "r.csv"), {v: ref_nyu(gts, list(preds)) for v in ("clean", "brightness/1")},
               NYU_COLS)

    split.write_text("changed since the build\n")
    res = cli("evaluate", ds, "--pred", pred, "--gt", gt_dir, "--out", tmp_path / "r.csv")
    assert res.exit_code == 2 and "bedroom/sync_depth_00001.png: no such file" in res.output


def _object_npz(path, maps, protocol):
    """np.savez_compressed(path, data=<object array>) with the given pickle protocol."""
    import pickle
    import zipfile

    obj = np.empty(len(maps), object)
    for i, m in enumerate(maps):
        obj[i] = m
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        with zf.open("data.npy", "w", force_zip64=True) as member:
            np.lib.format.write_array_header_1_0(member, np.lib.format.header_data_from_array_1_0(obj))
            pickle.Pickler(member, protocol=protocol).dump(obj)
    return path


@pytest.mark.parametrize("protocol", [2, 4, 5])
def test_ground_truth_file_read_map_by_map(tmp_path, protocol):
    """The pickled object array is read one map at a time (each reduced to its valid
    pixels as it arrives); the result is what numpy's own loader gives, for the pickle
    protocols numpy and the ground-truth writers use."""
    from robodepth_cli.groundtruth.read import load_ground_truth
    from robodepth_cli.evaluation.protocols import kitti_valid

    maps = [lidar_gt((40 + i, 90 + 3 * i), i) for i in range(20)]
    path = _object_npz(tmp_path / "gt.npz", maps, protocol)
    loaded = np.load(path, allow_pickle=True)["data"]  # numpy's loader, for comparison
    gt = load_ground_truth(path, [str(i) for i in range(20)], "kitti", kitti_valid)
    assert len(gt) == 20
    for i, m in enumerate(loaded):
        shape, index, values = gt.get(i)
        assert shape == m.shape
        assert np.array_equal(index, kitti_valid(m)) and np.array_equal(values, m.reshape(-1)[index])


def test_ground_truth_pickle_runs_no_code(kitti_c, kitti_pred, tmp_path, cli):
    out, gts = kitti_c
    marker = tmp_path / "ran"

    class Payload:
        def __reduce__(self):
            return (Path.touch, (marker,))

    path = _object_npz(tmp_path / "evil.npz", [gts[0], Payload()], 4)
    res = cli("evaluate", out, "--pred", kitti_pred, "--gt", path, "--out", tmp_path / "r.csv")
    assert res.exit_code == 2
    assert "evil.npz: holds a pickled pathlib" in res.output and "may hold only numpy arrays" in res.output
    assert not marker.exists() and not (tmp_path / "r.csv").exists()


def test_builds_carry_ground_truth_that_evaluate_reads(fixtures_dir, tmp_path, cli):
    """No ground truth written by the test: `robodepth build` makes it (KITTI from velodyne
    scans, NYU from the test folder's sync_depth files) and evaluate finds it. The ground
    truth itself as the prediction is perfect: abs_rel 0, a1 1 (and silog 0 for NYU)."""
    import shutil

    raw = tmp_path / "kitti_raw"
    shutil.copytree(fixtures_dir / "kitti_raw", raw)
    rng = np.random.default_rng(0)
    for frame in ("0000000069", "0000000054"):
        pts = np.column_stack([rng.uniform(5, 70, 30000), rng.uniform(-15, 15, 30000),
                               rng.uniform(-2, 1, 30000), np.ones(30000)]).astype(np.float32)
        velo = raw / "2011_09_26/2011_09_26_drive_0002_sync/velodyne_points/data" / f"{frame}.bin"
        velo.parent.mkdir(parents=True, exist_ok=True)
        pts.tofile(velo)
    kitti = tmp_path / "KITTI_C"
    res = cli("build", "kitti-c", "--root", raw, "--split", fixtures_dir / "kitti_split.txt", "--out", kitti,
              "--size", "64x96", "--corruptions", "brightness", "--levels", "2", "--jobs", "1")
    assert res.exit_code == 0, res.output
    assert (kitti / "gt_depths.npz").is_file()
    maps = np.load(kitti / "gt_depths.npz", allow_pickle=True)["data"]
    keys = json.loads((kitti / "build.json").read_text())["split"]["keys"]
    pred = tmp_path / "PK"
    for v in ("clean", "brightness/2"):
        for key, m in zip(keys, maps):
            p = pred / v / key.replace(".png", ".npy")
            p.parent.mkdir(parents=True, exist_ok=True)
            np.save(p, np.where(m > 0, m, 1).astype(np.float32))
    res = cli("evaluate", kitti, "--pred", pred, "--kind", "depth", "--out", tmp_path / "k.csv")
    assert res.exit_code == 0, res.output
    for r in read_csv(tmp_path / "k.csv"):
        assert float(r["abs_rel"]) < 1e-6 and float(r["a1"]) == 1.0

    nyu = tmp_path / "NYU_C"
    res = cli("build", "nyudepth2-c", "--root", fixtures_dir / "nyu", "--split", fixtures_dir / "nyu_split.txt",
              "--out", nyu, "--corruptions", "brightness", "--levels", "1", "--jobs", "1")
    assert res.exit_code == 0, res.output
    pred = tmp_path / "PN"
    for v in ("clean", "brightness/1"):
        for n in ("00001", "00119"):
            p = pred / v / "bedroom" / f"rgb_{n}.png"
            p.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(fixtures_dir / "nyu" / "bedroom" / f"sync_depth_{n}.png", p)
    res = cli("evaluate", nyu, "--pred", pred, "--out", tmp_path / "n.csv")
    assert res.exit_code == 0, res.output
    for r in read_csv(tmp_path / "n.csv"):
        assert float(r["abs_rel"]) < 1e-6 and float(r["a1"]) == 1.0 and abs(float(r["silog"])) < 1e-3


@pytest.mark.slow
def test_kitti_s_styles(fixtures_dir, kitti_c, tmp_path, cli):
    """KITTI-S: one row per style (level 0, like the clean row), the kitti protocol; no
    robustness scores exist for it, so --score is refused before any work."""
    from tests.helpers.adain import save_checkpoints

    from robodepth_cli import open_dataset

    _, gts = kitti_c
    vgg, dec, _, _ = save_checkpoints(tmp_path)
    out = tmp_path / "KITTI_S"
    res = cli("build", "kitti-s", "--root", fixtures_dir / "kitti_raw", "--split", fixtures_dir / "kitti_split.txt",
              "--styles", fixtures_dir / "styles", "--vgg", vgg, "--decoder", dec, "--size", "32x96",
              "--style-size", "32", "--only-styles", "sketch,cartoon", "--jobs", "1", "--out", out)
    assert res.exit_code == 0, res.output
    _object_npz(tmp_path / "gt.npz", gts, 4)
    ds = open_dataset(out)
    assert [v.relpath for v in ds.variants()] == ["clean", "cartoon", "sketch"]  # the styles' order
    preds = {}
    for k, v in enumerate(ds.variants()):
        preds[v.relpath] = [fake_disp((32, 96), i, 0.1 * k) for i in range(len(v.images()))]
        v.save_predictions(tmp_path / "P", preds[v.relpath])
    assert (tmp_path / "P" / "sketch.npy").is_file()
    res = cli("evaluate", out, "--pred", tmp_path / "P", "--gt", tmp_path / "gt.npz", "--score",
              "--out", tmp_path / "s.csv")
    assert res.exit_code == 2 and "--score: kitti-s has no robustness scores" in res.output
    assert not (tmp_path / "s.csv").exists()
    res = cli("evaluate", out, "--pred", tmp_path / "P", "--gt", tmp_path / "gt.npz", "--out", tmp_path / "s.csv")
    assert res.exit_code == 0, res.output
    rows = read_csv(tmp_path / "s.csv")
    assert [(r["corruption"], r["level"]) for r in rows] == [("clean", "0"), ("cartoon", "0"), ("sketch", "0")]
    check_rows(rows, {(v if v == "clean" else f"{v}/0"): ref_kitti(gts, p)[0] for v, p in preds.items()},
               KITTI_COLS)
