"""`robodepth evaluate` refuses what cannot give a meaningful number, and says which kind of
prediction it read: dead maps, implausible kinds, mixed forms, a wrong --kind under --score,
outputs that cannot be written, ground truth in another order.

Every case here once produced NaN rows, numpy warnings, a misreported kind or a late
failure (issue 19).
"""

from __future__ import annotations

import json
import re
import warnings

import cv2
import numpy as np
import pytest

from tests.helpers.messages import one_line_error
from tests.helpers.readonly import read_only_reason
from tests.helpers.evaluation import KEY69, KITTI_VARIANTS, read_csv, write_form1

KEY54 = KEY69.replace("0000000069", "0000000054")


def copy_pred(kitti_pred, dst, change=None):
    arrays = {v: np.load(kitti_pred / f"{v}.npy") for v in KITTI_VARIANTS}
    if change:
        change(arrays)
    return write_form1(dst, arrays)


def png_pred(dst, value_of=lambda variant, i: 1000):
    """Every variant as one 16-bit PNG per image (depth x 256)."""
    for v in KITTI_VARIANTS:
        for i, key in enumerate((KEY69, KEY54)):
            p = dst / v / key
            p.parent.mkdir(parents=True, exist_ok=True)
            value = value_of(v, i)
            img = value if isinstance(value, np.ndarray) else np.full((64, 96), value, np.uint16)
            cv2.imwrite(str(p), img)
    return dst


def evaluate(cli, out, pred, csv, *flags):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = cli("evaluate", out, "--pred", pred, "--out", csv, *flags)
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)], \
        [str(w.message) for w in caught]
    assert "nan" not in res.stdout.lower() and "RuntimeWarning" not in res.output
    return res


# --------------------------------------------------------------------------- dead maps (item 2)

def _dead(rel, i, value):
    def change(arrays):
        arrays[rel][i] = value
    return change


@pytest.mark.parametrize("change, flags, pattern", [
    (_dead("clean", 1, 0.0), (), r"clean\.npy: prediction 1: no positive finite value"),
    (_dead("contrast/3", 0, 0.0), ("--stereo",), r"contrast/3\.npy: prediction 0: no positive finite value"),
    (_dead("brightness/1", 1, np.inf), (), r"brightness/1\.npy: prediction 1 contains inf \(6144 pixels\)"),
    (_dead("clean", 0, 0.0), ("--kind", "depth"), r"clean\.npy: prediction 0: no positive finite value"),
], ids=["disp-zero", "disp-zero-stereo", "disp-inf", "depth-zero"])
def test_dead_prediction_maps_are_refused(kitti_c, kitti_pred, tmp_path, change, flags, pattern, cli):
    out, _ = kitti_c
    pred = copy_pred(kitti_pred, tmp_path / "p", change)
    res = evaluate(cli, out, pred, tmp_path / "r.csv", *flags)
    one_line_error(res, stderr=True, pattern=pattern)
    assert not (tmp_path / "r.csv").exists()


def test_median_scaling_needs_a_finite_median(kitti_c, kitti_pred, tmp_path, cli):
    """Mostly-zero disparities leave a depth median of infinity: the ratio would be 0 and
    every metric NaN; the map is refused, naming the rule."""
    out, _ = kitti_c

    def mostly_dead(arrays):
        arrays["clean"][1, :, :80] = 0.0

    pred = copy_pred(kitti_pred, tmp_path / "p", mostly_dead)
    res = evaluate(cli, out, pred, tmp_path / "r.csv")
    one_line_error(res, stderr=True, pattern=r"clean\.npy: prediction 1: .*median")


def test_all_zero_png_is_refused(kitti_c, tmp_path, cli):
    out, _ = kitti_c
    pred = png_pred(tmp_path / "p", lambda v, i: 0 if (v, i) == ("brightness/3", 1) else 1000)
    res = evaluate(cli, out, pred, tmp_path / "r.csv")
    one_line_error(res, stderr=True, pattern=r"brightness/3/kitti_data/.*/0000000054\.png \(image 1\): no positive finite value")


def test_zero_at_some_pixels_is_clamped_and_inf_is_refused(kitti_c, kitti_pred, tmp_path, cli):
    """A few zero disparities (infinitely far) are clamped to 80 m, as monodepth2 clamps
    them: the metrics stay finite. inf would turn into NaN in the resize: refused."""
    out, _ = kitti_c

    def some(value):
        def change(arrays):
            arrays["clean"][0, 40:42, 10:20] = value
        return change

    pred = copy_pred(kitti_pred, tmp_path / "p", some(0.0))
    res = evaluate(cli, out, pred, tmp_path / "r.csv")
    assert res.exit_code == 0, res.output
    rows = read_csv(tmp_path / "r.csv")
    assert all(np.isfinite(float(v)) for r in rows for k, v in r.items() if k not in ("corruption", "level", "dataset", "split"))
    pred = copy_pred(kitti_pred, tmp_path / "q", some(np.inf))
    res = evaluate(cli, out, pred, tmp_path / "r2.csv")
    one_line_error(res, stderr=True, pattern=r"clean\.npy: prediction 0 contains inf \(20 pixels\)")


def test_help_states_the_rule_for_zero_and_inf(cli):
    text = " ".join(cli("evaluate", "--help").output.split())
    assert "0 and inf" in text and ".npz" in text


# --------------------------------------------------------------------------- the kind read (item 8)

def test_png_predictions_are_reported_as_depth(kitti_c, tmp_path, cli):
    out, _ = kitti_c
    pred = png_pred(tmp_path / "p", lambda v, i: 1000 + 200 * i)
    res = evaluate(cli, out, pred, tmp_path / "r.csv", "--json")
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["kind"] == "depth"
    res = evaluate(cli, out, pred, tmp_path / "r2.csv")
    assert "predictions: depth" in res.stdout and "predictions: disp" not in res.stdout


def test_a_folder_mixing_npy_and_png_is_refused(kitti_c, kitti_pred, tmp_path, cli):
    out, _ = kitti_c
    pred = copy_pred(kitti_pred, tmp_path / "p")
    (pred / "clean.npy").unlink()
    (pred / "clean" / KEY69).parent.mkdir(parents=True)
    np.save((pred / "clean" / KEY69).with_suffix(".npy"), np.load(kitti_pred / "clean.npy")[0])
    cv2.imwrite(str(pred / "clean" / KEY54), np.full((64, 96), 1000, np.uint16))
    res = evaluate(cli, out, pred, tmp_path / "r.csv")
    one_line_error(res, stderr=True, pattern=r"0000000054\.png: a PNG prediction \(a depth\) among \.npy predictions")


def test_png_variants_beside_array_variants_are_refused_unless_both_are_depth(kitti_c, kitti_pred,
                                                                            tmp_path, cli):
    out, _ = kitti_c
    pred = copy_pred(kitti_pred, tmp_path / "p")
    (pred / "contrast/1.npy").unlink()
    for key in (KEY69, KEY54):
        (pred / "contrast/1" / key).parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(pred / "contrast/1" / key), np.full((64, 96), 1000, np.uint16))
    res = evaluate(cli, out, pred, tmp_path / "r.csv")
    one_line_error(res, stderr=True, pattern=r"contrast/1: PNG predictions \(depth\) beside .npy predictions read as disp")
    res = evaluate(cli, out, pred, tmp_path / "r.csv", "--kind", "depth", "--json")
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["kind"] == "depth"


# --------------------------------------------------------------------------- implausible kinds (item 9)

def test_sigmoid_outside_0_1_is_refused(kitti_c, tmp_path, cli):
    out, _ = kitti_c
    depths = {v: np.random.default_rng(1).uniform(1, 80, (2, 64, 96)).astype(np.float32)
              for v in KITTI_VARIANTS}
    pred = write_form1(tmp_path / "p", depths)
    res = evaluate(cli, out, pred, tmp_path / "r.csv", "--kind", "sigmoid")
    one_line_error(res, stderr=True, pattern=r"clean\.npy: prediction 0: values up to 7\d\.\d+; --kind sigmoid .*\[0, 1\]")


def test_stereo_with_depth_is_explained(kitti_c, kitti_pred, tmp_path, cli):
    """Right for a stereo model's depths in monodepth2's units, wrong for metric ones: said."""
    out, _ = kitti_c
    warning = (r"robodepth: warning: --stereo multiplied every depth by 5\.4: right for a stereo "
               r"model's depths in monodepth2's units .* wrong for depths in metres")
    depths = write_form1(tmp_path / "d", {v: 1 / np.load(kitti_pred / f"{v}.npy") for v in KITTI_VARIANTS})
    res = evaluate(cli, out, depths, tmp_path / "r.csv", "--stereo", "--kind", "depth")
    assert res.exit_code == 0, res.output
    assert re.search(warning, res.stderr), res.stderr
    res = evaluate(cli, out, png_pred(tmp_path / "p"), tmp_path / "r.csv", "--stereo", "--json")
    assert res.exit_code == 0, res.output
    assert re.search(warning, res.stderr), res.stderr
    assert json.loads(res.stdout)["kind"] == "depth"
    res = evaluate(cli, out, kitti_pred, tmp_path / "r.csv", "--stereo")
    assert "warning" not in res.stderr


# --------------------------------------------------------------------------- --score and a wrong kind (item 4)

def test_score_with_an_implausible_clean_dee_prints_the_metrics_then_warns(kitti_c, kitti_pred,
                                                                          tmp_path, cli):
    """Mono disparities read as a stereo model's: every depth hits the 80 m cap, far
    beyond a street whose ground truth is 4 to 10 m away."""
    out, gts = kitti_c
    near = np.empty(2, object)
    for i, g in enumerate(gts):
        near[i] = np.where(g > 0, 4 + g / 14, 0).astype(np.float32)
    np.savez_compressed(tmp_path / "near.npz", data=near)
    res = evaluate(cli, out, kitti_pred, tmp_path / "r.csv", "--stereo", "--score",
                   "--gt", tmp_path / "near.npz")
    assert res.exit_code == 0, res.output  # the work is done: a warning, not a refusal
    assert res.stdout.splitlines()[2].startswith("clean ")  # the metrics table came first
    last = res.stderr.strip().splitlines()[-1]
    assert re.match(r"robodepth: warning: clean DEE \d\.\d+ is implausible .*check --kind", last), last
    assert "r.csv:" not in last  # not blamed on a line of the CSV just written
    assert (tmp_path / "r.csv").exists()


# --------------------------------------------------------------------------- outputs (items 3, 18)

def test_an_unwritable_out_fails_before_any_work(kitti_c, kitti_pred, tmp_path, read_only_dir,
                                                 monkeypatch, cli):
    out, _ = kitti_c
    from robodepth_cli.evaluation import evaluate as E

    def no_work(*a, **k):
        raise AssertionError("evaluation started")

    monkeypatch.setattr(E, "load_ground_truth", no_work)
    csv = read_only_dir / "r.csv"
    res = cli("evaluate", out, "--pred", kitti_pred, "--out", csv)
    one_line_error(res, stderr=True, pattern=rf"--out {re.escape(str(csv))}: cannot write \({read_only_reason(read_only_dir)}\)")
    (tmp_path / "file").write_text("")
    res = cli("evaluate", out, "--pred", kitti_pred, "--out", tmp_path / "file" / "r.csv")
    one_line_error(res, stderr=True, pattern=r"file/r\.csv: cannot write \(.*file is not a directory\)")


def test_the_default_results_file_is_not_replaced_without_force(kitti_c, kitti_pred, tmp_path,
                                                                monkeypatch, cli):
    out, _ = kitti_c
    monkeypatch.chdir(tmp_path)
    csv = tmp_path / "results.csv"
    csv.write_text("mine\n")
    res = cli("evaluate", out, "--pred", kitti_pred)
    one_line_error(res, stderr=True, pattern=r"results\.csv exists \(the default --out\); give --out FILE, or --force")
    assert csv.read_text() == "mine\n"
    res = cli("evaluate", out, "--pred", kitti_pred, "--force")
    assert res.exit_code == 0, res.output
    assert "wrote results.csv (replaced)" in res.stderr
    assert read_csv(csv)[0]["corruption"] == "clean"
    res = cli("evaluate", out, "--pred", kitti_pred, "--out", csv)  # named: the user chose it
    assert res.exit_code == 0 and f"wrote {csv} (replaced)" in res.stderr


def test_missing_variants_are_written_as_score_writes_them(kitti_c, kitti_pred, tmp_path, cli):
    out, _ = kitti_c
    pred = copy_pred(kitti_pred, tmp_path / "p")
    (pred / "brightness/3.npy").unlink()
    (pred / "contrast/1.npy").unlink()
    (pred / "contrast/3.npy").unlink()
    res = evaluate(cli, out, pred, tmp_path / "r.csv")
    one_line_error(res, stderr=True, pattern=r"no predictions for 3 of 5 variants: brightness 3, contrast 1,3 ")


def test_ground_truth_in_another_order_is_refused(kitti_c, kitti_pred, tmp_path, cli):
    """Ground truth that robodepth writes carries the split's keys; evaluate checks them."""
    from robodepth_cli.groundtruth import kitti as kitti_raw

    out, gts = kitti_c
    keys = ["2011_09_26/2011_09_26_drive_0002_sync 0000000054",
            "2011_09_26/2011_09_26_drive_0002_sync 0000000069"]
    kitti_raw.save_object_npz(tmp_path / "swapped.npz", gts[::-1], keys=keys)
    res = evaluate(cli, out, kitti_pred, tmp_path / "r.csv", "--gt", tmp_path / "swapped.npz")
    one_line_error(res, stderr=True, pattern=r"swapped\.npz: map 0 is the ground truth of 2011_09_26/2011_09_26_drive_0002_sync "
                        r"0000000054, but image 0 of the split is .*0000000069")
    kitti_raw.save_object_npz(tmp_path / "right.npz", gts, keys=keys[::-1])
    res = evaluate(cli, out, kitti_pred, tmp_path / "r.csv", "--gt", tmp_path / "right.npz")
    assert res.exit_code == 0, res.output


# --------------------------------------------------------------------------- damaged files (item 18)

def test_a_truncated_png_is_one_line_and_libpng_stays_quiet(kitti_c, tmp_path, capfd, cli):
    out, _ = kitti_c
    pred = png_pred(tmp_path / "p", lambda v, i: np.random.default_rng(i).integers(500, 9000, (64, 96), np.uint16))
    bad = pred / "brightness/1" / KEY54
    data = bad.read_bytes()
    bad.write_bytes(data[:len(data) - 20])
    res = evaluate(cli, out, pred, tmp_path / "r.csv")
    one_line_error(res, stderr=True, pattern=r"0000000054\.png: not a readable PNG, truncated or damaged \(prediction of image 1\)")
    assert "libpng" not in capfd.readouterr().err


def test_npz_errors_name_the_file_once(kitti_c, kitti_pred, tmp_path, cli):
    out, _ = kitti_c
    pred = copy_pred(kitti_pred, tmp_path / "p")
    (pred / "clean.npy").unlink()
    np.savez(pred / "clean.npz", np.zeros((2, 4, 4)), np.zeros(3))
    res = evaluate(cli, out, pred, tmp_path / "r.csv")
    one_line_error(res, stderr=True, pattern=r"clean\.npz: holds 2 arrays; expected exactly one")
    assert res.stderr.count("clean.npz") == 1, res.stderr

    # A damaged member (CRC error) is one line too, not a traceback.
    np.savez_compressed(pred / "clean.npz", np.random.default_rng(0).random((2, 64, 96)).astype(np.float32))
    data = bytearray((pred / "clean.npz").read_bytes())
    data[len(data) // 2:len(data) // 2 + 64] = bytes(64)
    (pred / "clean.npz").write_bytes(bytes(data))
    res = evaluate(cli, out, pred, tmp_path / "r.csv")
    one_line_error(res, stderr=True, pattern=r"clean\.npz: cannot read its array, damaged\?")
    assert res.stderr.count("clean.npz") == 1, res.stderr


def _resized_preds(kitti_pred, dst, shape):
    """``kitti_pred``'s maps resized to ``shape`` (height, width), every variant."""
    def resize(arrays):
        for v, a in arrays.items():
            arrays[v] = np.stack([cv2.resize(m, (shape[1], shape[0])) for m in a])

    return copy_pred(kitti_pred, dst, resize)


def test_a_prediction_of_another_aspect_ratio_is_warned_then_refused(kitti_c, kitti_pred, tmp_path, cli):
    """The build's images are 64 x 96, the ground truth of image 0 375 x 1242 (aspect
    ratios 1.5 and 3.312): maps of either aspect ratio pass without a word; 50 x 300 (6.0:
    1.8 times apart from the ground truth's, 4 from the images') is warned; 96 x 10 (31.8
    times apart) is refused before anything is written."""
    out, _ = kitti_c
    for shape in ((64, 96), (120, 400)):
        res = evaluate(cli, out, _resized_preds(kitti_pred, tmp_path / f"ok{shape[0]}", shape),
                       tmp_path / "ok.csv")
        assert res.exit_code == 0 and "aspect" not in res.output, res.output
    pred = _resized_preds(kitti_pred, tmp_path / "wide", (50, 300))
    res = evaluate(cli, out, pred, tmp_path / "wide.csv")
    assert res.exit_code == 0, res.output
    warned = [ln for ln in res.output.splitlines() if "aspect" in ln]
    assert len(warned) == len(KITTI_VARIANTS)
    assert warned[0] == (f"robodepth: warning: {pred / 'clean.npy'}: prediction 0 is 50 x 300, its "
                         f"ground truth 375 x 1242: aspect ratios 1.8 times apart (more than 1.5); "
                         f"resized to the ground truth's size anyway")
    pred = _resized_preds(kitti_pred, tmp_path / "thin", (96, 10))
    res = evaluate(cli, out, pred, tmp_path / "thin.csv")
    assert one_line_error(res) == (f"robodepth: error: {pred / 'clean.npy'}: prediction 0 is 96 x 10, its ground truth "
                                   f"375 x 1242: aspect ratios 31.8 times apart (more than 4: a "
                                   f"transposed array or another model output?); give maps of "
                                   f"the image's shape")
    assert not (tmp_path / "thin.csv").exists()
