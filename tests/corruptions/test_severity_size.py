"""A severity that means the same at every resolution (``--severity-size``), measured on
images: a scene rendered at the severity size and at 3x it, each corrupted with the
severity size set, the 3x result shrunk 3x by area; an effect taken as a share of the
image must agree within 15 %.

* Blurs, warps and blocks (defocus, motion, glass, zoom, pixelate, elastic, the
  depth-aware lens and motion): a slanted step edge; its spread is the 10-90 % rise of
  its edge spread function (all rows' profiles, placed by their distance from the ideal
  edge line: a warp's jitter widens it as a blur does).
* Textures (frost, fog): on a flat image, the distance at which the horizontal
  autocorrelation falls to 1/2 (above a pixel of the severity size, both images blurred
  by one such pixel).
* Random ones by statistics: glass blur's mean displacement (of a coordinate image through
  its shuffle), snow's flakes (their mean area and their share of the image).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from robodepth_cli.corruptions import REGISTRY, corrupt
from robodepth_cli.corruptions.scaling import parse_severity_size, scale_factor
from robodepth_cli.errors import InvalidValueError

REF = (192, 640)
K = 3
LEVELS = (1, 3, 5)
EDGE_AT = 0.7  # the edge's place across the width (off-centre: zoom blur moves it there)
LO, HI = 60.0, 190.0


def edge_scene(h: int, w: int) -> np.ndarray:
    """A step from LO to HI along the line ``u = EDGE_AT + 0.08 (v - 1/2)`` (u, v the
    pixel centre's place as a share of the width and height), each pixel the share of it
    on the bright side: the same scene at every size."""
    e = edge_column(h, w)
    x = np.arange(w)[None, :] + 0.5
    cover = np.clip(x - e[:, None] + 0.5, 0.0, 1.0)
    img = LO + (HI - LO) * cover
    return np.repeat(np.rint(img)[:, :, None], 3, axis=2).astype(np.uint8)


def edge_column(h: int, w: int) -> np.ndarray:
    v = (np.arange(h) + 0.5) / h
    return (EDGE_AT + 0.08 * (v - 0.5)) * w


def shrink(img: np.ndarray, k: int = K) -> np.ndarray:
    h, w = img.shape[:2]
    return cv2.resize(img.astype(np.float32), (w // k, h // k), interpolation=cv2.INTER_AREA)


def edge_spread(img: np.ndarray) -> float:
    """The 10-90 % rise of the edge as a share of the width: the pixels of the middle 60 %
    of the rows within a quarter width of the edge, binned by their distance from the
    ideal edge line (quarter pixels; the slant samples every phase), averaged per bin (the
    edge spread function; a jitter of the edge from row to row widens it too)."""
    img = np.asarray(img, np.float64).mean(axis=2)
    h, w = img.shape
    rows = slice(int(0.2 * h), int(0.8 * h))
    dist = (np.arange(w)[None, :] + 0.5 - edge_column(h, w)[rows, None]).ravel()
    near = np.abs(dist) < w / 4
    bins = np.floor(dist[near] * 4).astype(np.int64)
    bins -= bins.min()
    esf = np.bincount(bins, img[rows].ravel()[near]) / np.maximum(np.bincount(bins), 1)
    esf = (esf - LO) / (HI - LO)
    x10, x90 = (_crossing(esf, q) for q in (0.1, 0.9))
    return (x90 - x10) / 4 / w


def _crossing(esf: np.ndarray, q: float) -> float:
    k = int(np.argmax(esf >= q))
    return k - 1 + (q - esf[k - 1]) / (esf[k] - esf[k - 1])


def flat_scene(h: int, w: int, value: int = 128) -> np.ndarray:
    return np.full((h, w, 3), value, np.uint8)


def above_a_pixel(img: np.ndarray) -> np.ndarray:
    """The channel-averaged image blurred by one pixel (Gaussian sigma 1): the structure
    above a pixel of the severity size, where the 3x image shrunk and the image made at
    that size can agree (pixel by pixel, a flake a few pixels wide is sampled differently)."""
    g = np.asarray(img, np.float64).mean(axis=2)
    return cv2.GaussianBlur(g, (0, 0), 1.0)


def correlation_length(img: np.ndarray) -> float:
    """Where the horizontal autocorrelation of the (centred) image :func:`above_a_pixel`
    falls to 1/2, as a share of the width."""
    g = above_a_pixel(img)
    g = g - g.mean(axis=1, keepdims=True)
    h, w = g.shape
    spec = np.fft.rfft(g, n=2 * w, axis=1)
    r = np.fft.irfft(np.abs(spec) ** 2, axis=1)[:, :w].sum(axis=0)
    r /= r[0]
    k = int(np.argmax(r < 0.5))
    assert k > 0, "no fall to 1/2 within the width"
    return (k - 1 + (r[k - 1] - 0.5) / (r[k - 1] - r[k])) / w


DEPTH_FAR, DEPTH_NEAR = 40.0, 4.0


def depth_of(h: int, w: int) -> np.ndarray:
    """Far everywhere but the bottom fifth (near): the lens focused near blurs the edge."""
    d = np.full((h, w), DEPTH_FAR, np.float32)
    d[int(0.8 * h):] = DEPTH_NEAR
    return d


def run(img, name, level, size=REF, seed=0):
    h, w = img.shape[:2]
    return corrupt(img, name, level, np.random.default_rng(seed), depth_of(h, w), severity_size=size)


def ratio(measure, scene, name, level, size=REF, seeds=(0,)):
    """The measure at 3x (shrunk) over the measure at the severity size, averaged over seeds."""
    small = scene(*REF)
    big = scene(REF[0] * K, REF[1] * K)
    a = np.mean([measure(run(small, name, level, size, s)) for s in seeds])
    b = np.mean([measure(shrink(run(big, name, level, size, s))) for s in seeds])
    return b / a


EDGES = ("defocus_blur", "motion_blur", "glass_blur", "zoom_blur", "pixelate", "elastic_transform",
         "near_focus", "far_focus", "motion_3d")


@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("name", EDGES)
def test_an_edge_spreads_over_the_same_share_of_the_image(name, level):
    # The warp's field is smooth over ~2 % of the image: a few dozen independent bumps.
    seeds = range(8) if name == "elastic_transform" else (0, 1, 2) if name == "glass_blur" else (0,)
    assert ratio(edge_spread, edge_scene, name, level, seeds=seeds) == pytest.approx(1.0, abs=0.15)


@pytest.mark.parametrize("name", ["defocus_blur", "motion_blur", "glass_blur", "pixelate", "elastic_transform"])
def test_without_a_severity_size_the_spread_stays_in_pixels(name):
    # What the option changes: as tabulated, 3x the image gets about a third of the spread.
    r = ratio(edge_spread, edge_scene, name, 5, size=None, seeds=(0, 1))
    assert r < 0.6


@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("name", ["frost", "fog"])
def test_a_texture_keeps_its_grain(name, level):
    seeds = (0, 1, 2)
    assert ratio(correlation_length, flat_scene, name, level, seeds=seeds) == pytest.approx(1.0, abs=0.15)


def _shuffle_displacement(shape, delta, iterations, scale, seed):
    """Glass blur's shuffle on a coordinate image: the mean distance each pixel's value
    comes from, as a share of the width (away from the unwritten margin)."""
    from robodepth_cli.corruptions.glass_blur import block_sources, shuffle_pixels, swap_offsets

    h, w = shape
    rng = np.random.default_rng(seed)
    if scale is None:
        img = np.zeros((h, w, 2), np.int32)
        img[..., 0] = np.arange(h)[:, None]
        img[..., 1] = np.arange(w)[None, :]
        moved = shuffle_pixels(img, swap_offsets(shape, delta, iterations, rng), delta)
        rows, cols = moved[..., 0], moved[..., 1]
    else:
        rows, cols = block_sources(shape, scale, delta, iterations, rng)
    dy = rows - np.arange(h)[:, None]
    dx = cols - np.arange(w)[None, :]
    m = int(4 * delta * (scale or 1)) + 2
    return np.hypot(dy[m:-m, m:-m], dx[m:-m, m:-m]).mean() / w


@pytest.mark.parametrize("level", [1, 2, 3, 4, 5])
def test_glass_blur_mean_displacement_is_a_share_of_the_image(level):
    from robodepth_cli.corruptions.glass_blur import LEVELS as GLASS

    _, delta, iterations = GLASS[level - 1]
    small = (96, 320)
    a = _shuffle_displacement(small, delta, iterations, None, 0)
    b = _shuffle_displacement((small[0] * K, small[1] * K), delta, iterations, float(K), 0)
    assert b / a == pytest.approx(1.0, abs=0.05)


def _flakes(img: np.ndarray):
    """(mean flake area, share of the image in flakes), areas as shares of the image: a
    flake is a connected region (8 neighbours) of the image :func:`above_a_pixel` brighter
    than the whitened background by 40 levels."""
    from scipy import ndimage

    g = above_a_pixel(img)
    bright = g > np.median(g) + 40
    labels, n = ndimage.label(bright, structure=np.ones((3, 3)))
    return bright.sum() / max(n, 1) / g.size, bright.mean()


@pytest.mark.parametrize("level", LEVELS)
def test_snow_flakes_keep_their_size_and_their_share(level):
    seeds = range(4)
    small = flat_scene(*REF, 20)
    big = flat_scene(REF[0] * K, REF[1] * K, 20)
    a = np.mean([_flakes(run(small, "snow", level, seed=s)) for s in seeds], axis=0)
    b = np.mean([_flakes(shrink(run(big, "snow", level, seed=s))) for s in seeds], axis=0)
    assert b[0] / a[0] == pytest.approx(1.0, abs=0.15)  # flake size
    assert b[1] / a[1] == pytest.approx(1.0, abs=0.15)  # area fraction


@pytest.mark.parametrize("name", [n for n, c in REGISTRY.items() if c.scaled])
@pytest.mark.parametrize("level", [1, 3, 5, 2.5])
def test_at_the_severity_size_itself_the_bytes_are_the_tabulated_ones(name, level):
    rng = np.random.default_rng(7)
    img = (rng.random((48, 160, 3)) * 255).astype(np.uint8)
    depth = np.linspace(1.0, 30.0, 48 * 160, dtype=np.float32).reshape(48, 160)
    plain = corrupt(img, name, level, np.random.default_rng(3), depth)
    assert (corrupt(img, name, level, np.random.default_rng(3), depth, severity_size=(48, 160)) == plain).all()
    # The function itself, handed a factor of exactly 1, takes the same path.
    c = REGISTRY[name]
    x = img.copy()
    x.flags.writeable = False
    args = (x, depth, level) if c.needs_depth else (x, level)
    if not c.needs_depth:
        assert (c.fn(*args, np.random.default_rng(3), scale=1.0) == plain).all()


def test_per_pixel_corruptions_do_not_scale():
    assert {n for n, c in REGISTRY.items() if not c.scaled} == {
        "brightness", "dark", "contrast", "color_quant", "gaussian_noise", "impulse_noise", "shot_noise",
        "iso_noise", "jpeg_compression", "zoom_blur", "fog_3d", "zoom_3d", "rain_3d"}
    img = edge_scene(64, 96)
    for name in ("gaussian_noise", "jpeg_compression", "contrast"):
        assert (run(img, name, 3, size=(8, 8)) == run(img, name, 3, size=None)).all()


def test_the_rule_is_the_square_root_of_the_area_ratio():
    assert scale_factor((576, 1920), (192, 640)) == 3.0
    assert scale_factor((1024, 2048), (192, 640)) == pytest.approx((1024 * 2048 / (192 * 640)) ** 0.5)
    assert scale_factor((1024, 2048), None) is None
    assert parse_severity_size("none") is None and parse_severity_size("480x640") == (480, 640)
    assert parse_severity_size([192, 640]) == (192, 640)
    with pytest.raises(InvalidValueError, match="HxW"):
        parse_severity_size("640")


def _manifest(out):
    import csv

    with open(out / "manifest.csv", newline="") as f:
        return {r["variant"]: r for r in csv.DictReader(f)}


def test_a_build_records_its_severity_size_and_redoes_the_scaled_files_for_another(cli, fixtures_dir, tmp_path):
    import json

    root = fixtures_dir / "kitti_raw"
    args = ("build", "custom", "--root", root, "--corruptions", "defocus_blur,gaussian_noise", "--levels", "3",
            "--limit", "1")
    out = tmp_path / "c"
    assert cli(*args, "--out", out).exit_code == 0
    config = json.loads((out / "build.json").read_text())["config"]
    assert config["extra"]["severity_size"] == "192x640"  # build custom's default
    rows = _manifest(out)
    assert rows["defocus_blur"]["params"] == "severity_size=192x640" and rows["gaussian_noise"]["params"] == ""
    again = cli(*args, "--out", out, "--severity-size", "none")
    assert again.exit_code == 0 and "1 written, 2 skipped" in again.output
    rows_none = _manifest(out)
    assert rows_none["defocus_blur"]["params"] == "" and rows_none["defocus_blur"]["sha256"] != rows["defocus_blur"]["sha256"]
    assert rows_none["gaussian_noise"]["sha256"] == rows["gaussian_noise"]["sha256"]
    assert json.loads((out / "build.json").read_text())["config"]["extra"]["severity_size"] == "none"


def test_kitti_c_keeps_no_severity_size(cli, fixtures_dir, tmp_path):
    import json

    out = tmp_path / "k"
    r = cli("build", "kitti-c", "--root", fixtures_dir / "kitti_raw", "--split", fixtures_dir / "kitti_split.txt",
            "--out", out, "--corruptions", "defocus_blur", "--levels", "3", "--limit", "1")
    assert r.exit_code == 0, r.output
    assert json.loads((out / "build.json").read_text())["config"]["extra"]["severity_size"] == "none"
    assert _manifest(out)["defocus_blur"]["params"] == ""


def test_a_bad_severity_size_is_refused_naming_the_flag(cli, fixtures_dir, tmp_path):
    r = cli("corrupt", fixtures_dir / "styles" / next(p.name for p in (fixtures_dir / "styles").iterdir()),
            "-c", "defocus_blur", "-l", "3", "--severity-size", "640", "--out", tmp_path / "x.png")
    assert r.exit_code == 2 and "--severity-size: size '640' is not of the form HxW" in r.output
    assert not (tmp_path / "x.png").exists()


def test_the_dataset_card_states_the_severity_size():
    """Each configuration's severity sizes come from the manifest rows of its files (two build
    requests into one build can differ), not from the last request's build.json."""
    from types import SimpleNamespace

    from robodepth_cli.export.card import card, holdings
    from robodepth_cli.output.manifest import Params

    record = SimpleNamespace(dataset="custom", keys=["a.png", "b.png"], seed=0, robodepth="x",
                             command=[], config={"levels": [3], "size": None, "extra": {}})

    def text(*params):
        items = [SimpleNamespace(level=3, seed=0, output=f"defocus_blur/3/{k}") for k in ("a.png", "b.png")]
        rows = {i.output: SimpleNamespace(params=p, parsed=Params.parse(p)) for i, p in zip(items, params)}
        held = holdings([SimpleNamespace(config="defocus_blur", items=items)], rows)
        return card(record, [{"config": "defocus_blur", "split": "level_3"}], "parquet", "x", held)

    assert "- `defocus_blur`: levels 3; seed 0; numpy engine; severity size 192x640\n" in text(
        "severity_size=192x640", "severity_size=192x640")
    assert "- `defocus_blur`: levels 3; seed 0; numpy engine; severity size none\n" in text("", "")
    assert "severity size 192x640, none" in text("severity_size=192x640", "")
    assert "square root of the area ratio" in text("", "")


def test_the_report_names_each_files_severity_size_and_a_mixed_table_says_so(tmp_path, cli):
    import json

    files = []
    for m, size in (("A", "192x640"), ("B", None)):
        p = tmp_path / f"ds_{m}.csv"
        col, val = (",severity_size", f",{size}") if size else ("", "")
        p.write_text(f"corruption,level,dee{col}\nclean,0,0.1{val}\nfog,1,0.2{val}\nfog,2,0.25{val}\n")
        files.append(p)
    res = cli("report", *files, "--name", "A", "--name", "B", "--on", "diode-c", "--out", tmp_path / "r")
    assert res.exit_code == 0, res.output
    page = (tmp_path / "r" / "index.html").read_text(encoding="utf-8")
    assert "severity size 192x640" in page and "severity size none" in page
    assert page.count("made at different severity sizes (192x640, none)") == 1
    doc = json.loads((tmp_path / "r" / "scores.json").read_text())
    assert [m["severity_size"] for m in doc["datasets"][0]["models"]] == ["192x640", "none"]
    files[1].write_text(files[0].read_text())
    res = cli("report", *files, "--name", "A", "--name", "B", "--on", "diode-c", "--out", tmp_path / "s")
    assert "different severity sizes" not in (tmp_path / "s" / "index.html").read_text(encoding="utf-8")


def test_evaluate_writes_the_builds_severity_size_into_the_results():
    import csv
    import io

    from robodepth_cli.evaluation.csvrows import ResultsTable

    text = "corruption,level,abs_rel,a1\nclean,0,0.1,0.9\nfog,1,0.2,0.8\n"
    plain = ResultsTable.parse(text, "r.csv")
    scaled = plain.with_column("severity_size", "192x640").text()
    rows = list(csv.DictReader(io.StringIO(scaled)))  # any CSV reader still reads it
    assert [r["severity_size"] for r in rows] == ["192x640", "192x640"] and rows[1]["a1"] == "0.8"
    assert ResultsTable.parse(scaled, "r.csv").severity_size() == "192x640"
    assert plain.severity_size() == "none" and plain.text() == text


def test_the_transforms_take_the_severity_size():
    import torch
    from robodepth_cli.torch import Corrupt, RandomCorrupt, TorchAPIError

    img = edge_scene(96, 320)
    scaled = Corrupt("defocus_blur", 3, seed=0, severity_size=(32, 96))(img, key="a.png")
    assert (scaled == run(img, "defocus_blur", 3, size=(32, 96), seed=0)).all()
    assert not (scaled == Corrupt("defocus_blur", 3, seed=0)(img, key="a.png")).all()
    one = RandomCorrupt(["motion_blur"], [4], p=1.0, seed=3, severity_size="96x320")
    assert (one(img) == RandomCorrupt(["motion_blur"], [4], p=1.0, seed=3)(img)).all()  # its own size
    with pytest.raises(TorchAPIError, match="severity_size"):
        Corrupt("fog", 3, severity_size="wide")
    with pytest.raises(TorchAPIError, match="torch engine"):
        Corrupt("fog", 3, severity_size="96x320")(torch.zeros((2, 3, 96, 320), dtype=torch.uint8))


def test_the_torch_engine_takes_none_from_a_preset_and_refuses_an_asked_size(cli, fixtures_dir, tmp_path):
    import json

    args = ("build", "custom", "--root", fixtures_dir / "kitti_raw", "--corruptions", "fog", "--levels", "1",
            "--limit", "1", "--engine", "torch", "--device", "cpu")
    r = cli(*args, "--out", tmp_path / "t")
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "t" / "build.json").read_text())["config"]["extra"]["severity_size"] == "none"
    r = cli(*args, "--out", tmp_path / "u", "--severity-size", "192x640")
    assert r.exit_code == 2 and "the torch engine does not scale the levels" in r.output
    assert not (tmp_path / "u").exists()


def test_corrupt_takes_the_severity_size(cli, fixtures_dir, tmp_path):
    from PIL import Image

    frame = next((fixtures_dir / "kitti_raw").rglob("*.png"))
    outs = {}
    for size in ("none", "375x1242", "96x320"):
        r = cli("corrupt", frame, "-c", "defocus_blur", "-l", "3", "--severity-size", size,
                "--out", tmp_path / f"{size}.png")
        assert r.exit_code == 0, r.output
        with Image.open(tmp_path / f"{size}.png") as im:
            outs[size] = np.asarray(im)
    assert (outs["none"] == outs["375x1242"]).all()  # the frame's own size: the tabulated bytes
    assert sharpness(outs["96x320"]) < sharpness(outs["none"])  # ~3.9x the radius: blurrier


def sharpness(img: np.ndarray) -> float:
    """Mean absolute horizontal gradient: falls as a blur widens."""
    g = np.asarray(img, np.float64).mean(axis=2)
    return float(np.abs(np.diff(g, axis=1)).mean())


def test_list_says_which_corruptions_scale(cli):
    import json

    listed = {c["name"]: c["scaled"] for c in json.loads(cli("list", "--format", "json").stdout)}
    assert listed == {n: c.scaled for n, c in REGISTRY.items()} and listed["motion_blur"] and not listed["gaussian_noise"]
