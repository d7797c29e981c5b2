"""The report's one-frame figure: each --pred drawn by what it holds (its predictions.json,
or --kind per --pred), so depth and disparity models sit side by side under "bright is
near"; model names of any length readable above their rows (issue 26 items 2, 3)."""

from __future__ import annotations

from tests.helpers.report import tables as _tables


import numpy as np
import pytest

from tests.helpers.report import evaluate_csv, figure_texts, no_overlap

pytest.importorskip("matplotlib")

H, W = 64, 96


def _preds(build, where, kind, record=True):
    """Predictions of one scene on every variant: disparity rising towards the bottom of
    the image (near), stored as it is (disp) or as its inverse (depth)."""
    from robodepth_cli import open_dataset

    ds = open_dataset(build)
    disp = np.linspace(0.02, 0.3, H, dtype=np.float32)[:, None] * np.ones((1, W), np.float32)
    for v in ds.variants():
        v.save_predictions(where, [disp if kind == "disp" else 1 / disp] * len(ds.keys))
    if record:
        from robodepth_cli.predictions import write_record  # as robodepth predict writes it

        write_record(where, {"model": "test", "evaluate": {"kind": kind, "align": "none", "align_space": "depth"}})
    return where


def _rows(fig, n_rows, cols):
    return [[fig.axes[r * cols + k].images[0].get_array() for k in range(cols)] for r in range(1, n_rows + 1)]


def test_depth_and_disparity_models_drawn_alike(small_build, tmp_path, cli):  # noqa: F811
    from robodepth_cli.report import write as W
    from robodepth_cli.report.qualitative import qualitative

    disp = _preds(small_build, tmp_path / "DISP", "disp")
    depth = _preds(small_build, tmp_path / "DEPTH", "depth")
    a = evaluate_csv(tmp_path / "a.csv", "kitti-c", "MonoViT")
    b = evaluate_csv(tmp_path / "b.csv", "kitti-c", "DIFFNet")
    report = W.assemble(_tables([a, b]), ["disparity model", "metric depth model"], None, "none", small_build)
    (_, _, caption, fig), guessed = qualitative(report, small_build, [disp, depth], 0)
    assert guessed == []
    assert "metric depth model (depth, drawn inverted, as its predictions.json records)" in caption
    rows = _rows(fig, 2, 3)
    for row in rows:
        for m in row:  # near (the bottom rows of the image) is bright: large values
            assert m[-1].mean() > m[0].mean()
    np.testing.assert_allclose(np.asarray(rows[1]), np.asarray(rows[0]), rtol=1e-5)
    # --kind per --pred overrides the records: both drawn as depths, the disparity inverted.
    (_, _, caption, fig), _ = qualitative(report, small_build, [disp, depth], 0, ("depth", "depth"))
    top, bottom = _rows(fig, 2, 3)[0][0][0].mean(), _rows(fig, 2, 3)[0][0][-1].mean()
    assert top > bottom and "as --kind says" in caption


def test_kind_of_a_folder_without_record_is_said(small_build, tmp_path, cli):  # noqa: F811
    plain = _preds(small_build, tmp_path / "PLAIN", "disp", record=False)
    a = evaluate_csv(tmp_path / "a.csv", "kitti-c", "MonoViT")
    out = tmp_path / "out"
    res = cli("report", a, "--dataset", small_build, "--pred", plain, "--out", out)
    assert res.exit_code == 0, res.output
    assert (f"robodepth: warning: --pred {plain}: no predictions.json says what it holds; drawn "
            "as disp (the kitti-c default); give --kind if wrong") in res.output
    res = cli("report", a, "--dataset", small_build, "--pred", plain, "--kind", "disp",
              "--kind", "depth", "--out", out)
    assert res.exit_code == 2 and "--kind given 2 times for 1 --pred folder;" in res.output
    res = cli("report", a, "--kind", "disp", "--out", out)
    assert res.exit_code == 2 and "--kind needs --pred" in res.output


@pytest.mark.parametrize("cols", [4, 2])
def test_long_model_names_are_whole_and_apart(cols):
    """Names of 23 characters and more, with and without spaces, above rows as wide as two
    or four panels: no two texts overlap, none is cut off by the figure's edge, and each
    name is all there (line breaks aside)."""
    from robodepth_cli.report.figures import qualitative_figure

    names = ["monodepth2 resnet18 640x192",  # 27 characters: overlapped before
             "depth-anything/Depth-Anything-V2-Small-hf (disparity)",
             "an_extremely_long_checkpoint_name_without_any_space_" * 3, "b"]
    image = np.zeros((48, 160, 3), np.uint8)
    ramp = np.linspace(0.1, 1, 48)[:, None] * np.ones((1, 160))
    fig = qualitative_figure(["clean", "fog 3", "snow 3", "dark 3"][:cols], [image] * cols,
                             [(n, [ramp] * cols) for n in names], "kitti-c", "frame")
    no_overlap(fig)
    edge = fig.bbox
    texts = figure_texts(fig)
    for name in names:
        shown = [(t, box) for t, box in texts if t.replace("\n", "").replace(" ", "") == name.replace(" ", "")]
        assert len(shown) == 1, (name, [t for t, _ in texts])
        box = shown[0][1]
        assert edge.x0 <= box.x0 and box.x1 <= edge.x1 and edge.y0 <= box.y0 and box.y1 <= edge.y1, name
        for ax in fig.axes:  # nor drawn over an image or a colour bar
            inter = box.intersection(box, ax.get_window_extent())
            assert inter is None or inter.width < 1 or inter.height < 1, name
