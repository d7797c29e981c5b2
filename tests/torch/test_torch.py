"""robodepth_cli.torch: transforms that reproduce a build's pixels, and a dataset wrapper."""

from __future__ import annotations


import numpy as np
import pytest
import torch
from PIL import Image

from robodepth_cli import corruptions
from robodepth_cli.torch import Corrupt, KittiC, RandomCorrupt, TorchAPIError

from tests.helpers.manifest import manifest_rows
from tests.helpers.trees import kitti_tree, random_image

FRAMES = [(5, "l", ".png"), (7, "r", ".jpg"), (9, "l", ".png")]
VARIANTS = ("fog", "gaussian_noise", "glass_blur")


def load(path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB")).copy()


@pytest.fixture(scope="module")
def kitti_build(tmp_path_factory, cli):
    tmp = tmp_path_factory.mktemp("kitti")
    root = tmp / "kitti_raw"
    split = kitti_tree(root, FRAMES, size=(48, 96))
    out = tmp / "out"
    r = cli("build", "kitti-c", "--root", root, "--split", split, "--out", out, "--size", "40x80",
            "--seed", "5", "--corruptions", ",".join(VARIANTS), "--levels", "2,4")
    assert r.exit_code == 0, r.output
    return out, manifest_rows(out)


def test_key_reproduces_built_pixels(kitti_build):
    out, rows = kitti_build
    clean_of = {r["source"]: load(out / r["output"]) for r in rows if r["variant"] == "clean"}
    checked = 0
    for r in rows:
        if r["variant"] == "clean":
            continue
        t = Corrupt(r["variant"], int(r["level"]), seed=5, dataset="kitti-c")
        ours = t(clean_of[r["source"]], key=r["source"])
        np.testing.assert_array_equal(ours, load(out / r["output"]), err_msg=r["output"])
        checked += 1
    assert checked == len(FRAMES) * len(VARIANTS) * 2
    # Another seed or dataset draws something else.
    r = next(r for r in rows if r["variant"] == "gaussian_noise")
    other = Corrupt("gaussian_noise", int(r["level"]), seed=6, dataset="kitti-c")(clean_of[r["source"]], key=r["source"])
    assert not np.array_equal(other, load(out / r["output"]))


@pytest.mark.parametrize("on_the_fly", [False, True])
def test_kittic_dataset_same_pixels_either_way_in_split_order(kitti_build, on_the_fly):
    out, rows = kitti_build
    ds = KittiC(out, "glass_blur", 4, on_the_fly=on_the_fly)
    assert len(ds) == len(FRAMES)
    # split order, not the manifest's sorted order
    assert [ds[i]["key"].rsplit("/", 1)[1] for i in range(len(ds))] == [f"{f:010d}.png" for f, _, _ in FRAMES]
    for i in range(len(ds)):
        item = ds[i]
        built = load(out / "glass_blur" / "4" / item["key"])
        assert item["image"].dtype == torch.uint8 and tuple(item["image"].shape) == (3, 40, 80)
        np.testing.assert_array_equal(item["image"].permute(1, 2, 0).numpy(), built)
        assert "depth" not in item


def test_kittic_ground_truth_when_present(kitti_build, tmp_path):
    import shutil

    out, _ = kitti_build
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    maps = np.empty(len(FRAMES), dtype=object)
    for i in range(len(FRAMES)):
        maps[i] = np.full((6, 7), float(i + 1), dtype=np.float32)
    np.savez_compressed(copy / "gt_depths.npz", data=maps)
    ds = KittiC(copy, "fog", 2)
    assert [float(ds[i]["depth"][0, 0]) for i in range(len(FRAMES))] == [1.0, 2.0, 3.0]


def test_dataloader_workers(kitti_build):
    out, _ = kitti_build
    ds = KittiC(out, "gaussian_noise", 2, on_the_fly=True)
    loader = torch.utils.data.DataLoader(ds, batch_size=1, num_workers=2)
    got = {b["key"][0]: b["image"][0] for b in loader}
    assert len(got) == len(FRAMES)
    for key, img in got.items():
        np.testing.assert_array_equal(img.permute(1, 2, 0).numpy(), load(out / "gaussian_noise" / "2" / key))


class _Images(torch.utils.data.Dataset):
    def __init__(self, n, transform):
        self.img = random_image(40, 48, seed=1)
        self.n, self.transform = n, transform

    def __len__(self):
        return self.n

    def __getitem__(self, i):
        return torch.from_numpy(self.transform(self.img))


def test_unkeyed_draws_differ_between_workers_and_repeat_with_the_seed():
    def draws(seed):
        loader = torch.utils.data.DataLoader(_Images(4, Corrupt("gaussian_noise", 3, seed=seed)),
                                             batch_size=1, num_workers=2)
        return [b[0].numpy() for b in loader]

    torch.manual_seed(0)
    a = draws(1)
    torch.manual_seed(0)
    b = draws(1)
    # item 0 goes to worker 0 and item 1 to worker 1: their first draws must differ
    assert not np.array_equal(a[0], a[1])
    assert all(np.array_equal(x, y) for x, y in zip(a, b))


def test_types_round_trip():
    img = random_image(40, 56, seed=3).copy()
    t = Corrupt("pixelate", 5)  # deterministic: every type must give the same pixels
    ref = corruptions.corrupt(img, "pixelate", 5, np.random.default_rng(0))
    np.testing.assert_array_equal(t(img), ref)
    pil = t(Image.fromarray(img))
    assert isinstance(pil, Image.Image) and pil.mode == "RGB"
    np.testing.assert_array_equal(np.asarray(pil), ref)
    u8 = t(torch.from_numpy(img).permute(2, 0, 1))
    assert u8.dtype == torch.uint8 and tuple(u8.shape) == (3, 40, 56)
    np.testing.assert_array_equal(u8.permute(1, 2, 0).numpy(), ref)
    f = t(torch.from_numpy(img).permute(2, 0, 1).float() / 255)
    assert f.dtype == torch.float32 and float(f.max()) <= 1.0
    np.testing.assert_array_equal((f * 255).round().to(torch.uint8).permute(1, 2, 0).numpy(), ref)


def test_custom_key_uses_the_png_key():
    img = random_image(40, 56, seed=4)
    a = Corrupt("shot_noise", 2, seed=0)(img, key="city/a.JPG")
    b = Corrupt("shot_noise", 2, seed=0)(img, key="city/a.png")
    c = Corrupt("shot_noise", 2, seed=0)(img, key="city/b.png")
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_random_corrupt():
    img = random_image(40, 56, seed=5)
    assert RandomCorrupt(p=0.0, seed=0)(img) is img
    t = RandomCorrupt(names=["color_quant"], levels=[1], p=1.0, seed=0)
    np.testing.assert_array_equal(t(img), corruptions.corrupt(img, "color_quant", 1, np.random.default_rng(0)))
    mixed = RandomCorrupt(p=0.5, seed=1)
    changed = sum(not np.array_equal(mixed(img), img) for _ in range(40))
    assert 8 <= changed <= 32


@pytest.mark.parametrize("make", [
    lambda: Corrupt("rain", 1),
    lambda: Corrupt("fog", 6),
    lambda: RandomCorrupt(levels=[0]),
    lambda: RandomCorrupt(p=2),
    lambda: Corrupt("fog", 1)(np.zeros((40, 40), np.uint8)),
    lambda: Corrupt("fog", 1)(np.zeros((20, 40, 3), np.uint8)),
])
def test_bad_arguments(make):
    with pytest.raises(TorchAPIError):
        make()


def test_not_a_build(tmp_path):
    from robodepth_cli.api import DatasetError

    with pytest.raises(DatasetError, match="no build.json"):
        KittiC(tmp_path, "fog", 1)


def test_key_reproduces_a_custom_build(tmp_path, cli):
    from tests.helpers.trees import save

    root = tmp_path / "frames"
    save(root / "cam" / "a.JPG", random_image(40, 70, seed=7))
    save(root / "b.png", random_image(52, 44, seed=8))
    out = tmp_path / "out"
    r = cli("build", "custom", "--root", root, "--out", out, "--corruptions", "fog,shot_noise",
            "--levels", "3")
    assert r.exit_code == 0, r.output
    for rel, key in (("cam/a.JPG", "cam/a.png"), ("b.png", "b.png")):
        with Image.open(root / rel) as im:
            img = im.convert("RGB")  # the source itself: a custom build keeps its size
        for name in ("fog", "shot_noise"):
            # build custom defines the levels at 192 x 640 (its severity size)
            got = Corrupt(name, 3, seed=0, severity_size="192x640")(img, key=rel)
            np.testing.assert_array_equal(np.asarray(got), load(out / name / "3" / key))


def test_collate_batches_ground_truth_of_different_sizes(kitti_build, tmp_path):
    import shutil

    from robodepth_cli.torch import collate

    out, _ = kitti_build
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    # Two drives' frame sizes, as KITTI's ground truth has them (HxW 375x1242 and 370x1224,
    # scaled down): the default collate cannot stack these.
    sizes = [(6, 7), (5, 9), (6, 7)]
    maps = np.empty(len(FRAMES), dtype=object)
    for i, (h, w) in enumerate(sizes):
        maps[i] = np.arange(1, h * w + 1, dtype=np.float32).reshape(h, w) + 100 * i
    np.savez_compressed(copy / "gt_depths.npz", data=maps)
    ds = KittiC(copy, "fog", 2)
    with pytest.raises(RuntimeError):
        next(iter(torch.utils.data.DataLoader(ds, batch_size=3)))
    (batch,) = list(torch.utils.data.DataLoader(ds, batch_size=3, collate_fn=collate))
    assert batch["key"] == [ds[i]["key"] for i in range(3)]
    assert batch["image"].shape == (3, 3, 40, 80) and batch["image"].dtype == torch.uint8
    for i in range(3):
        np.testing.assert_array_equal(batch["image"][i].numpy(), ds[i]["image"].numpy())
    # Padded with zeros (no measurement) to the largest height and width; the sizes kept.
    assert batch["depth"].shape == (3, 6, 9)
    assert batch["depth_size"].tolist() == [list(s) for s in sizes]
    for i, (h, w) in enumerate(sizes):
        np.testing.assert_array_equal(batch["depth"][i, :h, :w].numpy(), maps[i])
        assert float(batch["depth"][i].sum()) == float(maps[i].sum())  # the rest is 0
