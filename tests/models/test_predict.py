"""`robodepth predict`: model specs -> predictions in the layout `robodepth evaluate` reads.

monodepth2-format checkpoints are made here with random weights (ResNet-18 and -50) and
their predictions compared with a forward pass written here from the architecture's rules
with plain torch.nn.functional ops over the state dicts; transformers models are tiny ones
made here from small random configs (nothing is downloaded).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import torch.nn.functional as F
from PIL import Image

from tests.helpers.builds import copy_build
from tests.helpers.imports import imported_by_command
from tests.helpers.models import NET_H, NET_W, random_monodepth2

VARIANTS = ["clean", "brightness/1", "brightness/3", "contrast/1", "contrast/3"]


@pytest.fixture(scope="module")
def dataset(kitti_c_build, tmp_path_factory):
    out = copy_build(kitti_c_build, tmp_path_factory)
    # KITTI-like ground truth (monodepth2's gt_depths.npz): sparse, 2..70 m, at 375 x 1242
    rng = np.random.default_rng(5)
    gts = np.empty(2, object)
    for i in range(2):
        g = np.linspace(70, 2, 375, dtype=np.float32)[:, None] * rng.uniform(0.9, 1.1, (375, 1242))
        g[rng.random(g.shape) > 0.1] = 0
        gts[i] = g.astype(np.float32)
    np.savez_compressed(out / "gt_depths.npz", data=gts)
    return out


def images_of(dataset, variant):
    from robodepth_cli import open_dataset

    ds = open_dataset(dataset)
    v = [v for v in ds.variants() if v.relpath == variant][0]
    return [np.asarray(Image.open(p).convert("RGB")) for p in v.images()]


# --------------------------------------------------------------------------- monodepth2 checkpoints

def reference_disp(enc, dec, images, post_process=False):
    """monodepth2's saved disparity, step by step: Lanczos resize to the checkpoint's size,
    /255, (x - 0.45) / 0.225, the ResNet and the decoder in F ops, sigmoid of scale 0,
    0.01 + 9.99 s; with post_process the mirror's map is blended by the column ramp."""
    h, w = enc["height"], enc["width"]
    x = np.stack([np.asarray(Image.fromarray(im).resize((w, h), Image.LANCZOS)) for im in images])
    x = torch.from_numpy(x).permute(0, 3, 1, 2).float() / 255
    if post_process:
        x = torch.cat([x, x.flip(3)])
    x = (x - 0.45) / 0.225

    def bn(t, p):
        return F.batch_norm(t, enc[p + ".running_mean"], enc[p + ".running_var"],
                            enc[p + ".weight"], enc[p + ".bias"], False, 0.0, 1e-5)

    def block(t, p, stride):
        if f"{p}.conv3.weight" in enc:  # bottleneck: 1x1, 3x3 (strided), 1x1
            y = F.relu(bn(F.conv2d(t, enc[p + ".conv1.weight"]), p + ".bn1"))
            y = F.relu(bn(F.conv2d(y, enc[p + ".conv2.weight"], stride=stride, padding=1), p + ".bn2"))
            y = bn(F.conv2d(y, enc[p + ".conv3.weight"]), p + ".bn3")
        else:
            y = F.relu(bn(F.conv2d(t, enc[p + ".conv1.weight"], stride=stride, padding=1), p + ".bn1"))
            y = bn(F.conv2d(y, enc[p + ".conv2.weight"], padding=1), p + ".bn2")
        if f"{p}.downsample.0.weight" in enc:
            t = bn(F.conv2d(t, enc[p + ".downsample.0.weight"], stride=stride), p + ".downsample.1")
        return F.relu(y + t)

    with torch.no_grad():
        f = [F.relu(bn(F.conv2d(x, enc["encoder.conv1.weight"], stride=2, padding=3), "encoder.bn1"))]
        t = F.max_pool2d(f[0], 3, 2, 1)
        for s in range(1, 5):
            b = 0
            while f"encoder.layer{s}.{b}.conv1.weight" in enc:
                t = block(t, f"encoder.layer{s}.{b}", 2 if b == 0 and s > 1 else 1)
                b += 1
            f.append(t)

        def conv3(t, p):
            return F.conv2d(F.pad(t, (1, 1, 1, 1), mode="reflect"), dec[p + ".weight"], dec[p + ".bias"])

        t = f[4]
        for step, i in enumerate(range(4, -1, -1)):
            t = F.elu(conv3(t, f"decoder.{2 * step}.conv.conv"))
            t = t.repeat_interleave(2, 2).repeat_interleave(2, 3)  # nearest x2
            if i > 0:
                t = torch.cat([t, f[i - 1]], 1)
            t = F.elu(conv3(t, f"decoder.{2 * step + 1}.conv.conv"))
        s = torch.sigmoid(conv3(t, "decoder.10.conv"))
    disp = (0.01 + (10 - 0.01) * s)[:, 0].numpy()
    if not post_process:
        return disp
    n = len(images)
    d, m = disp[:n].astype(np.float64), disp[n:, :, ::-1].astype(np.float64)
    col = np.linspace(0, 1, w)
    lm = 1 - np.clip(20 * (col - 0.05), 0, 1)  # the mirror's weight, left columns
    rm = lm[::-1]  # the image's own weight, right columns
    return rm * d + lm * m + (1 - lm - rm) * (d + m) / 2


@pytest.mark.slow
@pytest.mark.parametrize("layers,post", [(18, False), (50, False), (18, True)])
def test_monodepth2_matches_an_independent_forward_pass(dataset, tmp_path, cli, layers, post):
    enc, dec = random_monodepth2(tmp_path / "model", layers, seed=layers)
    flags = ["--post-process"] if post else []
    res = cli("predict", dataset, "--model", f"monodepth2:{tmp_path / 'model'}", "--out",
              tmp_path / "PRED", "--batch-size", 3, *flags)
    assert res.exit_code == 0, res.output
    for variant in VARIANTS:
        got = np.load(tmp_path / "PRED" / f"{variant}.npy")
        want = reference_disp(enc, dec, images_of(dataset, variant), post)
        assert got.shape == (2, NET_H, NET_W)
        assert got.dtype == (np.float64 if post else np.float32)
        assert want.std() > 0.05  # the random network is not saturated: a real comparison
        np.testing.assert_allclose(got, want, rtol=2e-5, atol=2e-6)
    record = json.loads((tmp_path / "PRED" / "predictions.json").read_text())
    assert record["output"] == "disparity" and record["scale"] == "relative"
    assert record["input_size"] == [NET_H, NET_W]
    assert record["evaluate"] == {"kind": "disp", "align": "median", "align_space": "depth"}
    assert record["identity"]["resnet"] == layers
    assert record["options"] == {"post_process": post}


@pytest.mark.slow
def test_post_process_mirrors(dataset, tmp_path, cli):
    """Flip averaging is symmetric: a mirrored image gets the mirrored map."""
    from robodepth_cli.models import load_model

    random_monodepth2(tmp_path / "m", 18, seed=3)
    model = load_model(f"monodepth2:{tmp_path / 'm'}", device="cpu", post_process=True)
    img = np.stack(images_of(dataset, "clean"))
    a = model.predict(img)
    b = model.predict(np.ascontiguousarray(img[:, :, ::-1]))
    np.testing.assert_allclose(a, b[:, :, ::-1], rtol=1e-5, atol=1e-6)


# --------------------------------------------------------------------------- transformers

def tiny_dpt(folder: Path):
    from transformers import DPTConfig, DPTForDepthEstimation, DPTImageProcessor

    torch.manual_seed(0)
    cfg = DPTConfig(hidden_size=32, num_hidden_layers=4, num_attention_heads=2, intermediate_size=37,
                    image_size=64, patch_size=16, neck_hidden_sizes=[8, 16, 32, 32],
                    fusion_hidden_size=16, backbone_out_indices=[0, 1, 2, 3], head_in_index=-1,
                    initializer_range=0.1)
    model = DPTForDepthEstimation(cfg).eval()
    with torch.no_grad():  # an output above 0 everywhere (the head ends in a ReLU)
        model.head.head[-2].weight.abs_()
        model.head.head[-2].bias.fill_(0.1)
    model.save_pretrained(folder)
    DPTImageProcessor(size={"height": 64, "width": 64}).save_pretrained(folder)
    return model


def tiny_depth_anything(folder: Path, kind="metric"):
    from transformers import DepthAnythingConfig, DepthAnythingForDepthEstimation, Dinov2Config
    from transformers import DPTImageProcessor

    torch.manual_seed(1)
    backbone = Dinov2Config(hidden_size=32, num_hidden_layers=2, num_attention_heads=2,
                            intermediate_size=37, image_size=28, patch_size=14,
                            out_features=["stage1", "stage2"], reshape_hidden_states=False,
                            initializer_range=0.1)
    cfg = DepthAnythingConfig(backbone_config=backbone, reassemble_hidden_size=32,
                              neck_hidden_sizes=[8, 16], reassemble_factors=[2, 1],
                              fusion_hidden_size=16, head_hidden_size=8, patch_size=14,
                              depth_estimation_type=kind, max_depth=20, initializer_range=0.1)
    model = DepthAnythingForDepthEstimation(cfg).eval()
    with torch.no_grad():  # away from the sigmoid's flat middle
        model.head.conv3.weight.mul_(20)
    model.save_pretrained(folder)
    DPTImageProcessor(size={"height": 28, "width": 42}, keep_aspect_ratio=False,
                      do_pad=False).save_pretrained(folder)
    return model


def reference_hf(folder, images):
    """The transformers recipe, written out: the processor, the model, then each map
    resized to its image with bicubic interpolation (corners not aligned)."""
    from transformers import AutoImageProcessor, AutoModelForDepthEstimation

    proc = AutoImageProcessor.from_pretrained(folder)
    model = AutoModelForDepthEstimation.from_pretrained(folder).eval()
    with torch.no_grad():
        depth = model(**proc(images=list(images), return_tensors="pt")).predicted_depth
    h, w = images[0].shape[:2]
    return F.interpolate(depth[:, None], size=(h, w), mode="bicubic", align_corners=False)[:, 0].numpy()


@pytest.mark.slow
@pytest.mark.parametrize("which", ["dpt", "depth_anything"])
def test_transformers_models(dataset, tmp_path, cli, which):
    folder = tmp_path / which
    (tiny_dpt if which == "dpt" else tiny_depth_anything)(folder)
    res = cli("predict", dataset, "-m", f"hf:{folder}", "-o", tmp_path / "P",
              "--variants", "clean,contrast/3", "-b", 2)
    assert res.exit_code == 0, res.output
    assert sorted(p.relative_to(tmp_path / "P").as_posix() for p in (tmp_path / "P").rglob("*.npy")) == \
        ["clean.npy", "contrast/3.npy"]
    for variant in ("clean", "contrast/3"):
        got = np.load(tmp_path / "P" / f"{variant}.npy")
        want = reference_hf(folder, images_of(dataset, variant))
        assert got.shape == (2, 64, 96)  # the image's size, as the processor post-processes
        assert want.std() > 1e-4
        np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-5)
    record = json.loads((tmp_path / "P" / "predictions.json").read_text())
    if which == "dpt":  # relative inverse depth
        assert (record["output"], record["scale"]) == ("disparity", "relative")
        assert record["evaluate"] == {"kind": "disp", "align": "scale-shift", "align_space": "disparity"}
    else:  # the config says metric
        assert (record["output"], record["scale"]) == ("depth", "metric")
        assert record["evaluate"] == {"kind": "depth", "align": "none", "align_space": "depth"}


def test_unknown_hf_name_offline(dataset, tmp_path, cli, monkeypatch):
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "empty-cache"))
    res = cli("predict", dataset, "-m", "hf:nobody/no-such-depth-model", "-o", tmp_path / "P")
    assert res.exit_code == 2
    line = res.output.strip()
    assert "\n" not in line
    assert "nobody/no-such-depth-model is not in the local Hugging Face cache" in line
    assert "hf download nobody/no-such-depth-model" in line
    assert not (tmp_path / "P").exists()


def test_hf_folder_of_another_model(dataset, tmp_path, cli):
    from transformers import BertConfig, BertModel

    BertModel(BertConfig(hidden_size=8, num_hidden_layers=1, num_attention_heads=2,
                         intermediate_size=8, vocab_size=20)).save_pretrained(tmp_path / "bert")
    res = cli("predict", dataset, "-m", f"hf:{tmp_path / 'bert'}", "-o", tmp_path / "P")
    assert res.exit_code == 2
    assert "a bert model, not a depth-estimation model" in res.output
    assert not (tmp_path / "P").exists()


# --------------------------------------------------------------------------- python callables

MODULE = '''
import os
import numpy as np

calls = []

def brightness(images):
    """brighter is nearer: a disparity from the mean intensity"""
    calls.append(len(images))
    fail_at = int(os.environ.get("FAIL_AT_CALL", "0"))
    if fail_at and len(calls) == fail_at:
        return np.full((len(images), 8, 8), np.nan, np.float32)
    return (0.02 + images.mean(axis=3) / 2550).astype(np.float32)

def wrong_shape(images):
    return np.zeros((len(images) + 1, 4, 4), np.float32)

def wrong_dtype(images):
    return np.zeros((len(images), 4, 4), np.int64)

def with_nan(images):
    out = np.ones((len(images), 4, 4), np.float32)
    out[0, 1, 1] = np.nan
    return out

def as_tensor(images):
    import torch
    return torch.from_numpy(images.mean(axis=3, keepdims=True).astype(np.float32)).permute(0, 3, 1, 2) + 1
'''


@pytest.fixture
def user_module(tmp_path):
    path = tmp_path / "usermodel.py"
    path.write_text(MODULE)
    return path


def test_python_callable(dataset, tmp_path, cli, user_module):
    res = cli("predict", dataset, "-m", f"python:{user_module}:brightness", "--kind", "disp",
              "-o", tmp_path / "P", "-b", 4)
    assert res.exit_code == 0, res.output
    for variant in VARIANTS:
        imgs = np.stack(images_of(dataset, variant))
        np.testing.assert_array_equal(np.load(tmp_path / "P" / f"{variant}.npy"),
                                      (0.02 + imgs.mean(axis=3) / 2550).astype(np.float32))
    record = json.loads((tmp_path / "P" / "predictions.json").read_text())
    assert record["evaluate"] == {"kind": "disp", "align": "scale-shift", "align_space": "disparity"}
    # N x 1 x h x w tensors are maps too
    res = cli("predict", dataset, "-m", f"python:{user_module}:as_tensor", "--kind", "depth",
              "--metric", "-o", tmp_path / "T", "--variants", "clean")
    assert res.exit_code == 0, res.output
    assert np.load(tmp_path / "T" / "clean.npy").shape == (2, 64, 96)
    assert json.loads((tmp_path / "T" / "predictions.json").read_text())["evaluate"]["align"] == "none"


def test_python_module_by_name(dataset, tmp_path, cli, user_module, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delitem(sys.modules, "usermodel", raising=False)
    res = cli("predict", dataset, "-m", "python:usermodel:brightness", "--kind", "disp",
              "-o", "P", "--variants", "clean")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "P" / "clean.npy").is_file()


def test_python_file_imports_a_module_beside_it(dataset, tmp_path, cli, monkeypatch):
    # Run from elsewhere: the file's own folder is searched, as for a script.
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "helper_beside_35.py").write_text("OFFSET = 3.0\n")
    (tmp_path / "m" / "net.py").write_text("import numpy as np\nfrom helper_beside_35 import OFFSET\n\n"
                                           "def predict(images):\n"
                                           "    return np.full((len(images), 4, 4), OFFSET, np.float32)\n")
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    monkeypatch.delitem(sys.modules, "helper_beside_35", raising=False)
    monkeypatch.setattr(sys, "path", list(sys.path))  # what the import adds goes with the test
    res = cli("predict", dataset, "-m", f"python:{tmp_path / 'm' / 'net.py'}:predict", "--kind", "depth",
              "--metric", "-o", tmp_path / "P", "--variants", "clean")
    assert res.exit_code == 0, res.output
    assert (np.load(tmp_path / "P" / "clean.npy") == 3.0).all()


@pytest.mark.parametrize("spec_tail,flags,message", [
    ("wrong_shape", ["--kind", "disp"], "returned shape (3, 4, 4) for a batch of 2 images; expected 2 x h x w"),
    ("wrong_dtype", ["--kind", "disp"], "returned dtype int64; expected floating-point maps"),
    ("with_nan", ["--kind", "disp"], "its output holds NaN"),
    ("brightness", [], "say what the function returns with --kind"),
    ("nothing_here", ["--kind", "disp"], "has no nothing_here"),
])
def test_bad_callables(dataset, tmp_path, cli, user_module, spec_tail, flags, message):
    res = cli("predict", dataset, "-m", f"python:{user_module}:{spec_tail}", "-o",
              tmp_path / "P", *flags)
    assert res.exit_code == 2
    assert message in res.output
    assert len(res.output.strip().splitlines()) == 1, res.output
    assert not (tmp_path / "P").exists()  # nothing half-written, not even the folder


def test_bad_specs_and_checkpoints(dataset, tmp_path, cli):
    def run(spec, *flags):
        res = cli("predict", dataset, "-m", spec, "-o", tmp_path / "P", *flags)
        assert res.exit_code == 2, res.output
        assert len(res.output.strip().splitlines()) == 1, res.output
        assert not (tmp_path / "P").exists()
        return res.output

    assert "unknown model adapter" in run("onnx:model.onnx")
    (tmp_path / "empty").mkdir()
    assert f"{tmp_path / 'empty'}: no encoder.pth" in run(f"monodepth2:{tmp_path / 'empty'}")
    # a ResNet-18 encoder with a ResNet-50 model's decoder
    random_monodepth2(tmp_path / "r18", 18)
    random_monodepth2(tmp_path / "r50", 50)
    (tmp_path / "mixed").mkdir()
    (tmp_path / "mixed" / "encoder.pth").write_bytes((tmp_path / "r18" / "encoder.pth").read_bytes())
    (tmp_path / "mixed" / "depth.pth").write_bytes((tmp_path / "r50" / "depth.pth").read_bytes())
    out = run(f"monodepth2:{tmp_path / 'mixed'}")
    assert "depth.pth: does not fit the depth decoder of a ResNet-18 encoder" in out
    assert "decoder.0.conv.conv.weight has shape (256, 2048, 3, 3), expected (256, 512, 3, 3)" in out
    # an encoder that is no ResNet (a block missing), and a pose encoder (two images in)
    enc = torch.load(tmp_path / "r18" / "encoder.pth")
    del enc["encoder.layer2.1.conv1.weight"]
    torch.save(enc, tmp_path / "mixed" / "encoder.pth")
    assert "not a monodepth2 ResNet encoder" in run(f"monodepth2:{tmp_path / 'mixed'}")
    enc = torch.load(tmp_path / "r18" / "encoder.pth")
    enc["encoder.conv1.weight"] = torch.cat([enc["encoder.conv1.weight"]] * 2, 1)
    torch.save(enc, tmp_path / "mixed" / "encoder.pth")
    assert "takes 6 channels; a depth encoder takes one RGB image" in run(f"monodepth2:{tmp_path / 'mixed'}")
    enc = torch.load(tmp_path / "r18" / "encoder.pth")
    del enc["height"]
    torch.save(enc, tmp_path / "mixed" / "encoder.pth")
    assert "no 'height' and 'width' entries" in run(f"monodepth2:{tmp_path / 'mixed'}")
    (tmp_path / "mixed" / "encoder.pth").write_text("not a checkpoint")
    assert "encoder.pth: not a PyTorch checkpoint" in run(f"monodepth2:{tmp_path / 'mixed'}")
    assert "--device cuda: CUDA is not available" in run(f"monodepth2:{tmp_path / 'r18'}", "--device", "cuda")
    assert "--post-process applies to monodepth2 models only" in run("python:x:y", "--post-process")
    assert "--variants 'fog': not a variant of" in run(f"monodepth2:{tmp_path / 'r18'}", "--variants", "fog")


# --------------------------------------------------------------------------- resume and PRED

def test_resume_skips_finished_variants_and_loses_only_the_one_in_flight(
        dataset, tmp_path, cli, user_module, monkeypatch):
    spec = f"python:{user_module}:brightness"
    pred = tmp_path / "P"
    # batch size 2 = one call per variant: the third call (brightness/3) returns NaN
    monkeypatch.setenv("FAIL_AT_CALL", "3")
    res = cli("predict", dataset, "-m", spec, "--kind", "disp", "-o", pred, "-b", 2)
    assert res.exit_code == 2 and "holds NaN" in res.output
    assert sorted(p.name for p in pred.rglob("*") if p.is_file()) == ["1.npy", "clean.npy", "predictions.json"]
    assert not (pred / "brightness" / "3.npy").exists()
    before = {p: p.stat().st_mtime_ns for p in pred.rglob("*.npy")}
    (pred / "contrast").mkdir()
    (pred / "contrast" / ".1.npy.abc.part").write_bytes(b"left by a killed run")

    monkeypatch.delenv("FAIL_AT_CALL")
    monkeypatch.delitem(sys.modules, "usermodel", raising=False)
    res = cli("predict", dataset, "-m", spec, "--kind", "disp", "-o", pred, "-b", 2)
    assert res.exit_code == 0, res.output
    assert "(2 already done, skipped)" in res.output
    assert all(p.stat().st_mtime_ns == t for p, t in before.items())
    assert sorted(p.relative_to(pred).as_posix() for p in pred.rglob("*") if p.is_file()) == \
        ["brightness/1.npy", "brightness/3.npy", "clean.npy", "contrast/1.npy", "contrast/3.npy",
         "predictions.json"]


def test_pred_of_another_model_or_foreign_files_refused(dataset, tmp_path, cli, user_module):
    pred = tmp_path / "P"
    res = cli("predict", dataset, "-m", f"python:{user_module}:brightness", "--kind", "disp",
              "-o", pred, "--variants", "clean")
    assert res.exit_code == 0
    res = cli("predict", dataset, "-m", f"python:{user_module}:brightness", "--kind", "depth",
              "-o", pred)
    assert res.exit_code == 2
    assert "holds predictions of another model or setting" in res.output
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("x")
    res = cli("predict", dataset, "-m", f"python:{user_module}:brightness", "--kind", "disp",
              "-o", tmp_path / "mine")
    assert res.exit_code == 2 and "not empty and holds no predictions.json" in res.output
    (tmp_path / "file").write_text("x")
    res = cli("predict", dataset, "-m", f"python:{user_module}:brightness", "--kind", "disp",
              "-o", tmp_path / "file")
    assert res.exit_code == 2 and "exists and is not a folder" in res.output


def test_predict_modules_import_no_heavy_library():
    preload = ["robodepth_cli.models", "robodepth_cli.commands.predict"]
    heavy = ["torch", "transformers", "cv2", "numba"]
    assert imported_by_command(["predict", "--help"], heavy, preload=preload) == []


# --------------------------------------------------------------------------- the loop

@pytest.mark.slow
def test_build_predict_evaluate_score(dataset, tmp_path, cli, user_module):
    """evaluate takes its defaults from PRED/predictions.json: the same numbers as with the
    flags given by hand; then score reads the CSV."""
    random_monodepth2(tmp_path / "m", 18)
    res = cli("predict", dataset, "-m", f"monodepth2:{tmp_path / 'm'}", "-o", tmp_path / "P")
    assert res.exit_code == 0, res.output
    assert f"next: robodepth evaluate {dataset} --pred {tmp_path / 'P'}" in res.output
    res = cli("evaluate", dataset, "--pred", tmp_path / "P", "-o", tmp_path / "r.csv", "--score")
    assert res.exit_code == 0, res.output
    assert "mCE" in res.stdout
    score = cli("score", tmp_path / "r.csv", "--benchmark", "kitti-c", "--allow-partial")
    assert score.exit_code == 0 and res.stdout.endswith(score.stdout)

    # a metric depth from a python function: evaluate reads --kind depth from the record
    res = cli("predict", dataset, "-m", f"python:{user_module}:as_tensor", "--kind", "depth",
              "--metric", "-o", tmp_path / "D")
    assert res.exit_code == 0, res.output
    recorded = cli("evaluate", dataset, "--pred", tmp_path / "D", "-o", tmp_path / "a.csv", "--json")
    given = cli("evaluate", dataset, "--pred", tmp_path / "D", "-o", tmp_path / "b.csv",
                "--kind", "depth", "--json")
    disp = cli("evaluate", dataset, "--pred", tmp_path / "D", "-o", tmp_path / "c.csv",
               "--kind", "disp", "--json")
    assert recorded.exit_code == given.exit_code == disp.exit_code == 0
    assert json.loads(recorded.stdout)["kind"] == "depth"
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
    assert (tmp_path / "a.csv").read_text() != (tmp_path / "c.csv").read_text()


@pytest.mark.slow
def test_relative_model_evaluated_after_scale_shift_in_disparity(dataset, tmp_path, cli):
    """A relative hf model's record makes scale-shift in disparity space evaluate's default."""
    tiny_dpt(tmp_path / "dpt")
    res = cli("predict", dataset, "-m", f"hf:{tmp_path / 'dpt'}", "-o", tmp_path / "P")
    assert res.exit_code == 0, res.output
    default = cli("evaluate", dataset, "--pred", tmp_path / "P", "-o", tmp_path / "a.csv", "--json")
    given = cli("evaluate", dataset, "--pred", tmp_path / "P", "-o", tmp_path / "b.csv", "--kind",
                "disp", "--align", "scale-shift", "--align-space", "disparity")
    median = cli("evaluate", dataset, "--pred", tmp_path / "P", "-o", tmp_path / "c.csv", "--align",
                 "median", "--align-space", "depth")
    assert default.exit_code == given.exit_code == median.exit_code == 0, default.output
    doc = json.loads(default.stdout)
    assert (doc["kind"], doc["align"], doc["align_space"]) == ("disp", "scale-shift", "disparity")
    assert (f"from {tmp_path / 'P' / 'predictions.json'}: kind disp, align scale-shift, "
            "align_space disparity") in default.stderr
    assert "predictions.json" not in given.stderr
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
    assert (tmp_path / "a.csv").read_text() != (tmp_path / "c.csv").read_text()
    # --stereo's fixed factor replaces the recorded alignment
    stereo = cli("evaluate", dataset, "--pred", tmp_path / "P", "-o", tmp_path / "s.csv", "--stereo",
                 "--json")
    assert stereo.exit_code == 0, stereo.output
    assert json.loads(stereo.stdout)["align"] == "none"


def test_unreadable_record_is_a_one_line_error(dataset, tmp_path, cli, user_module):
    res = cli("predict", dataset, "-m", f"python:{user_module}:brightness", "--kind", "disp",
              "-o", tmp_path / "P")
    assert res.exit_code == 0, res.output
    for content, message in ((b"{not json", "not valid JSON"), (b"\xff\xfe", "not UTF-8 text"),
                             (b"[]", "not a robodepth predictions record")):
        (tmp_path / "P" / "predictions.json").write_bytes(content)
        for args in (("evaluate", dataset, "--pred", tmp_path / "P", "-o", tmp_path / "r.csv"),
                     ("predict", dataset, "-m", f"python:{user_module}:brightness", "--kind",
                      "disp", "-o", tmp_path / "P")):
            res = cli(*args)
            assert res.exit_code == 2, res.output
            assert f"{tmp_path / 'P' / 'predictions.json'}: " in res.output and message in res.output
            assert len(res.output.strip().splitlines()) == 1, res.output


def test_custom_build_of_mixed_sizes_gets_one_file_per_image(tmp_path, cli, user_module):
    """Images that keep their own sizes: one .npy per image (the form evaluate reads), each
    at its image's size, written whole per variant and resumed like the arrays."""
    from tests.helpers.trees import random_image, save

    root = tmp_path / "city"
    sizes = {"a/x.png": (40, 64), "a/y.png": (48, 36), "b/z.png": (33, 90)}
    for i, (key, (h, w)) in enumerate(sizes.items()):
        save(root / key, random_image(h, w, seed=i))
    out = tmp_path / "C"
    res = cli("build", "custom", "--root", root, "--out", out, "--corruptions", "contrast",
              "--levels", "2")
    assert res.exit_code == 0, res.output
    pred = tmp_path / "P"
    res = cli("predict", out, "-m", f"python:{user_module}:brightness", "--kind", "disp", "-o", pred,
              "-b", 2, "--variants", "clean")
    assert res.exit_code == 0, res.output
    for key, (h, w) in sizes.items():
        img = np.asarray(Image.open(out / "clean" / key).convert("RGB"))
        got = np.load(pred / "clean" / key.replace(".png", ".npy"))
        assert got.shape == (h, w)  # each image at its own size
        np.testing.assert_array_equal(got, (0.02 + img.mean(axis=2) / 2550).astype(np.float32))
    (pred / "contrast").mkdir()
    (pred / "contrast" / ".2.abc.part").mkdir()  # a killed run's temporary folder
    res = cli("predict", out, "-m", f"python:{user_module}:brightness", "--kind", "disp", "-o", pred)
    assert res.exit_code == 0, res.output
    assert "(1 already done, skipped)" in res.output
    assert sorted(p.relative_to(pred).as_posix() for p in pred.rglob("*") if p.is_file()) == \
        ["clean/a/x.npy", "clean/a/y.npy", "clean/b/z.npy", "contrast/2/a/x.npy",
         "contrast/2/a/y.npy", "contrast/2/b/z.npy", "predictions.json"]
