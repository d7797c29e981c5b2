"""challenge build: the public folder reveals nothing, the private one holds the key and the
ground truth, the images are the build's own, and the same seed gives the same bytes."""

from __future__ import annotations

import csv
import json
import re
import struct
from collections import Counter

import numpy as np
import pytest

from robodepth_cli.benchmark_facts import ALL_CORRUPTIONS
from tests.helpers.manifest import manifest_by_output
from tests.helpers.messages import one_line_error
from tests.helpers.paths import FIXTURES

SPLIT = FIXTURES / "kitti_split.txt"
FLAGS = ("--split", SPLIT, "--size", "64x96", "--corruptions", "brightness,contrast,dark",
         "--levels", "1,2", "-n", "12", "--jobs", "1", "--no-progress")


@pytest.fixture(scope="module")
def challenge(cli, kitti_scans_root, tmp_path_factory):
    out = tmp_path_factory.mktemp("challenge") / "C"
    res = cli("challenge", "build", "kitti-c", "--root", kitti_scans_root, "--seed", "5", "--out", out, *FLAGS)
    assert res.exit_code == 0, res.output
    return out


def _key(out):
    with open(out / "private" / "key.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _chunks(data: bytes) -> dict[bytes, bytes]:
    """Chunk type -> contents of the chunks other than the pixels' (IDAT)."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks = 8, {}
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        if kind != b"IDAT":
            chunks[kind] = data[pos + 8:pos + 8 + length]
        pos += 12 + length
    return chunks


def test_public_folder_reveals_nothing(challenge):
    public = challenge / "public"
    files = sorted(p.relative_to(public).as_posix() for p in public.rglob("*") if p.is_file())
    ids = (public / "list.txt").read_text().split()
    assert files == sorted(["README.md", "challenge.json", "list.txt"] + [f"images/{i}.png" for i in ids])
    assert all(re.fullmatch(r"[0-9a-f]{10}", i) for i in ids)
    # No text, time or other metadata chunks: besides the header and the end, only fpng's
    # marker of its own encoder (fdEC), the same bytes in every image.
    chunks = [_chunks((public / "images" / f"{i}.png").read_bytes()) for i in ids]
    assert all(set(c) == {b"IHDR", b"fdEC", b"IEND"} for c in chunks)
    assert len({c[b"fdEC"] for c in chunks}) == 1
    key = _key(challenge)
    secrets = set(ALL_CORRUPTIONS) | {r["source"] for r in key} | {"kitti_data", "2011_09_26", "drive",
                                                                   "image_02", "0000000069", "0000000054"}
    for name in ("README.md", "challenge.json", "list.txt"):
        text = (public / name).read_text()
        found = [s for s in secrets if re.search(rf"(?<![a-z_]){re.escape(s)}(?![a-z_])", text)]
        assert found == [], (name, found)
    meta = json.loads((public / "challenge.json").read_text())
    assert meta == {"format": 1, "track": "kitti", "images": 12, "size": [64, 96]}


def test_key_balance_and_order(challenge):
    key = _key(challenge)
    ids = (challenge / "public" / "list.txt").read_text().split()
    assert [r["id"] for r in key] == ids and [int(r["position"]) for r in key] == list(range(12))
    assert Counter(r["corruption"] for r in key) == {"brightness": 4, "contrast": 4, "dark": 4}
    assert Counter((r["corruption"], r["level"]) for r in key) == {
        (c, lv): 2 for c in ("brightness", "contrast", "dark") for lv in ("1", "2")}
    assert len({(r["source"], r["corruption"], r["level"]) for r in key}) == 12
    assert {r["seed"] for r in key} == {"5"}


def test_images_and_ground_truth_are_the_builds(cli, challenge, kitti_scans_root, tmp_path):
    """Each image is byte for byte what robodepth build makes for its frame, corruption and
    level with the same seed; each ground-truth map is that frame's from gt_depths.npz."""
    ref = tmp_path / "KITTI_C"
    res = cli("build", "kitti-c", "--root", kitti_scans_root, "--split", SPLIT, "--out", ref, "--size", "64x96",
              "--corruptions", "brightness,contrast,dark", "--levels", "1,2", "--seed", "5", "--jobs", "1")
    assert res.exit_code == 0, res.output
    rows = manifest_by_output(ref)
    gts = np.load(ref / "gt_depths.npz", allow_pickle=True)["data"]  # our own build: trusted
    keys = [f"kitti_data/{line.split()[0]}/image_02/data/{line.split()[1]}.png"
            for line in SPLIT.read_text().splitlines()]
    with np.load(challenge / "private" / "gt.npz", allow_pickle=False) as gt:
        for r in _key(challenge):
            out = f"{r['corruption']}/{r['level']}/{r['source']}"
            assert rows[out]["sha256"] == r["sha256"]
            png = (challenge / "public" / "images" / f"{r['id']}.png").read_bytes()
            assert png == (ref / out).read_bytes()
            want = gts[keys.index(r["source"])]
            # lidar maps are mostly empty: stored as their valid pixels (docs/challenge.md)
            shape, index, depth = (gt[f"{r['id']}.{k}"] for k in ("shape", "index", "depth"))
            m = np.zeros(tuple(shape), np.float32)
            m.reshape(-1)[index] = depth
            assert depth.dtype == np.float32 and index.dtype == np.int32
            np.testing.assert_array_equal(m, want)


def test_same_seed_same_bytes_other_seed_other_draw(cli, challenge, kitti_scans_root, tmp_path):
    again, other = tmp_path / "again", tmp_path / "other"
    for out, seed in ((again, "5"), (other, "6")):
        res = cli("challenge", "build", "kitti-c", "--root", kitti_scans_root, "--seed", seed, "--out", out, *FLAGS)
        assert res.exit_code == 0, res.output

    def tree(out):
        return {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*"))
                if p.is_file() and "build" not in p.relative_to(out).parts[1:2]}

    assert tree(again) == tree(challenge)
    assert [(r["source"], r["corruption"], r["level"]) for r in _key(other)] != \
        [(r["source"], r["corruption"], r["level"]) for r in _key(challenge)]


def test_refusals(cli, challenge, kitti_scans_root, tmp_path):
    res = cli("challenge", "build", "kitti-c", "--root", kitti_scans_root, "--seed", "5", "--out", challenge, *FLAGS)
    one_line_error(res, "public: exists")
    res = cli("challenge", "build", "kitti-c", "--root", kitti_scans_root, "--seed", "5", "--out",
              tmp_path / "x", "-n", "0")
    one_line_error(res, "--images 0")
    res = cli("challenge", "build", "kitti-c", "--root", kitti_scans_root, "--seed", "5", "--out",
              tmp_path / "y", "--corruptions", "snowfall")
    one_line_error(res, "snowfall")


def test_nyu_track(cli, tmp_path):
    out = tmp_path / "N"
    res = cli("challenge", "build", "nyudepth2-c", "--root", FIXTURES / "nyu", "--split", FIXTURES / "nyu_split.txt",
              "--seed", "1", "-n", "4", "--out", out, "--jobs", "1", "--corruptions", "brightness,pixelate",
              "--no-progress")
    assert res.exit_code == 0, res.output
    assert json.loads((out / "public" / "challenge.json").read_text())["track"] == "nyu"
    assert "depth map in metres" in (out / "public" / "README.md").read_text()
    key = _key(out)
    assert {int(r["level"]) for r in key} <= {1, 2, 3, 4}
    from PIL import Image

    with np.load(out / "private" / "gt.npz", allow_pickle=False) as gt:
        for r in key:
            png = FIXTURES / "nyu" / r["source"].replace("rgb_", "sync_depth_").replace(".png", ".png")
            mm = np.asarray(Image.open(png), dtype=np.float32)
            np.testing.assert_allclose(gt[r["id"]], mm / 1000.0, rtol=1e-6)


def test_predict_writes_a_valid_submission(cli, challenge, tmp_path):
    """robodepth predict on the public folder: a zip holding disp.npz, each image's map under
    its id (a python: model's disparity from the image's own pixels), accepted by check and
    scored."""
    (tmp_path / "net.py").write_text("import numpy as np\n\ndef predict(images):\n"
                                     "    return images.mean(-1).astype(np.float32) / 255 + 0.01\n")
    sub = tmp_path / "submission.zip"
    res = cli("predict", challenge / "public", "-m", f"python:{tmp_path / 'net.py'}:predict", "--kind", "disp",
              "-o", sub, "--no-progress")
    assert res.exit_code == 0, res.output
    assert cli("challenge", "check", sub, "--public", challenge / "public").exit_code == 0
    from PIL import Image
    import io
    import zipfile

    with zipfile.ZipFile(sub) as zf:
        assert zf.namelist() == ["disp.npz"]
        with np.load(io.BytesIO(zf.read("disp.npz")), allow_pickle=False) as npz:
            ids = (challenge / "public" / "list.txt").read_text().split()
            assert list(npz.keys()) == ids
            for i in ids:
                rgb = np.asarray(Image.open(challenge / "public" / "images" / f"{i}.png").convert("RGB"))
                np.testing.assert_allclose(npz[i], rgb.mean(-1) / 255 + 0.01, rtol=1e-6)
    res = cli("challenge", "score", sub, "--reference", challenge / "private", "--json")
    assert res.exit_code == 0 and json.loads(res.output)["images"] == 12


def test_predict_on_track_nyu_needs_metric_depth(cli, tmp_path):
    out = tmp_path / "N"
    res = cli("challenge", "build", "nyudepth2-c", "--root", FIXTURES / "nyu", "--split", FIXTURES / "nyu_split.txt",
              "--seed", "2", "-n", "2", "--out", out, "--jobs", "1", "--corruptions", "pixelate", "--no-progress")
    assert res.exit_code == 0, res.output
    (tmp_path / "net.py").write_text("import numpy as np\n\ndef predict(images):\n"
                                     "    return np.full(images.shape[:3], 3.0, np.float32)\n")
    net = f"python:{tmp_path / 'net.py'}:predict"
    one_line_error(cli("predict", out / "public", "-m", net, "--kind", "disp", "-o", tmp_path / "s.zip",
                       "--no-progress"), "track nyu takes metric depth")
    assert not (tmp_path / "s.zip").exists()
    res = cli("predict", out / "public", "-m", net, "--kind", "depth", "--metric", "-o", tmp_path / "s.zip",
              "--no-progress")
    assert res.exit_code == 0, res.output
    got = json.loads(cli("challenge", "score", tmp_path / "s.zip", "--reference", out / "private", "--json").output)
    assert got["images"] == 2 and "silog" in got


def test_custom_with_depth(cli, tmp_path):
    """A custom build with --depth (given in --config): each image's ground truth is its own
    depth map."""
    from PIL import Image

    rng = np.random.default_rng(0)
    (tmp_path / "rgb").mkdir()
    (tmp_path / "depth").mkdir()
    for i in range(3):
        Image.fromarray(rng.integers(0, 255, (40, 60, 3), dtype=np.uint8)).save(tmp_path / "rgb" / f"im{i}.png")
        np.save(tmp_path / "depth" / f"im{i}.npy", rng.uniform(1, 20, (40, 60)).astype(np.float32))
    (tmp_path / "cfg.yaml").write_text(f"depth: {tmp_path / 'depth'}\n")
    res = cli("challenge", "build", "custom", "--root", tmp_path / "rgb", "--config", tmp_path / "cfg.yaml",
              "--seed", "1", "-n", "5", "--corruptions", "fog,brightness", "--out", tmp_path / "C", "--no-progress")
    assert res.exit_code == 0, res.output
    key = _key(tmp_path / "C")
    assert max(Counter(r["source"] for r in key).values()) == 2  # 5 images of 3 frames: at most twice
    with np.load(tmp_path / "C" / "private" / "gt.npz", allow_pickle=False) as gt:
        for r in key:
            np.testing.assert_array_equal(gt[r["id"]], np.load(tmp_path / "depth" / r["source"].replace(".png", ".npy")))
