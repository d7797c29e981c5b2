"""`robodepth predict` measures a torch model's parameters and FLOPs per image, records them
in predictions.json, and `evaluate` carries them into the results as `params` and `flops`.

The expected counts are computed here by hand from the layers' shapes: a convolution of
``c_in`` to ``c_out`` channels with a ``k x k`` kernel has ``c_out * c_in * k * k`` weights
plus ``c_out`` biases, and over an ``h x w`` output costs ``c_out * c_in * k * k * h * w``
multiply-adds, 2 FLOPs each (bias additions and activations are not counted).
"""

from __future__ import annotations

import csv
import json

import pytest

from tests.helpers.builds import copy_build
from tests.helpers.models import NET_H, NET_W, random_monodepth2

H, W = 64, 96  # the session build's image size

CONV_STACK = '''
import numpy as np
import torch
from torch import nn


class Net(nn.Module):
    """3 -> 8 (3x3, padding 1) -> 4 (3x3, stride 2, padding 1) -> 1 (1x1)."""

    def __init__(self):
        super().__init__()
        torch.manual_seed(0)
        self.a = nn.Conv2d(3, 8, 3, padding=1)
        self.b = nn.Conv2d(8, 4, 3, stride=2, padding=1)
        self.c = nn.Conv2d(4, 1, 1)

    def forward(self, images):
        x = torch.from_numpy(np.ascontiguousarray(images)).permute(0, 3, 1, 2).float() / 255
        with torch.no_grad():
            return torch.sigmoid(self.c(torch.relu(self.b(torch.relu(self.a(x)))))) + 0.01


net = Net()


def declared(images):
    return net(images)


declared.robodepth_module = net


def plain(images):
    return np.ones((len(images), 4, 4), np.float32)


def not_a_module(images):
    return plain(images)


not_a_module.robodepth_module = "net"
'''


def conv(cin, cout, k, h, w):
    """(parameters, FLOPs) of one convolution with bias over an h x w output."""
    return cout * cin * k * k + cout, 2 * cout * cin * k * k * h * w


PARAMS = conv(3, 8, 3, H, W)[0] + conv(8, 4, 3, H // 2, W // 2)[0] + conv(4, 1, 1, H // 2, W // 2)[0]
FLOPS = conv(3, 8, 3, H, W)[1] + conv(8, 4, 3, H // 2, W // 2)[1] + conv(4, 1, 1, H // 2, W // 2)[1]


@pytest.fixture(scope="module")
def dataset(kitti_c, tmp_path_factory):
    return copy_build(kitti_c[0], tmp_path_factory)


@pytest.fixture
def stack(tmp_path):
    path = tmp_path / "stack.py"
    path.write_text(CONV_STACK)
    return path


def _record(pred):
    return json.loads((pred / "predictions.json").read_text())


def _rows(path):
    return list(csv.DictReader(path.open()))


@pytest.mark.parametrize("name", ["net", "declared"])
def test_conv_stack_counted_and_carried_into_the_results(dataset, tmp_path, cli, stack, name):
    assert (PARAMS, FLOPS) == (521, 3_551_232)  # the arithmetic above, written out
    pred = tmp_path / "P"
    res = cli("predict", dataset, "-m", f"python:{stack}:{name}", "--kind", "disp", "-o", pred,
              "-b", 3)
    assert res.exit_code == 0, res.output
    size = _record(pred)["size"]
    assert size["params"] == PARAMS
    assert size["flops"] == FLOPS  # per image: the batch of 2 images counted once, halved
    assert size["image_size"] == [H, W]
    res = cli("evaluate", dataset, "--pred", pred, "-o", tmp_path / "r.csv")
    assert res.exit_code == 0, res.output
    rows = _rows(tmp_path / "r.csv")
    assert len(rows) == 5 and all(r["params"] == str(PARAMS) and r["flops"] == str(FLOPS) for r in rows)
    score = cli("score", tmp_path / "r.csv", "--benchmark", "kitti-c", "--allow-partial")
    assert score.exit_code == 0, score.output


def test_a_function_without_a_module_has_no_size(dataset, tmp_path, cli, stack):
    pred = tmp_path / "P"
    res = cli("predict", dataset, "-m", f"python:{stack}:plain", "--kind", "depth", "-o", pred)
    assert res.exit_code == 0, res.output
    assert "size" not in _record(pred)
    res = cli("evaluate", dataset, "--pred", pred, "-o", tmp_path / "r.csv")
    assert res.exit_code == 0, res.output
    header = (tmp_path / "r.csv").read_text().splitlines()[0].split(",")
    assert "params" not in header and "flops" not in header


def test_robodepth_module_that_is_no_module_refused(dataset, tmp_path, cli, stack):
    res = cli("predict", dataset, "-m", f"python:{stack}:not_a_module", "--kind", "depth",
              "-o", tmp_path / "P")
    assert res.exit_code == 2
    assert "robodepth_module must be a torch.nn.Module" in res.output
    assert "Traceback" not in res.output


@pytest.mark.slow
def test_monodepth2_parameters_are_its_checkpoints_weights(dataset, tmp_path, cli):
    """A monodepth2 model's parameters: every weight and bias of encoder.pth and depth.pth
    (not the batch norms' running statistics, which are buffers); its FLOPs at the network's
    input size, twice that with --post-process (the mirror image's pass)."""
    enc, dec = random_monodepth2(tmp_path / "m", 18)
    want = sum(v.numel() for d in (enc, dec) for k, v in d.items() if hasattr(v, "numel")
               and k.endswith((".weight", ".bias")) and not k.startswith("encoder.fc."))
    sizes = {}
    for post in (False, True):
        pred = tmp_path / f"P{post}"
        flags = ["--post-process"] if post else []
        res = cli("predict", dataset, "-m", f"monodepth2:{tmp_path / 'm'}", "-o", pred,
                  "--variants", "clean", *flags)
        assert res.exit_code == 0, res.output
        sizes[post] = _record(pred)["size"]
    assert sizes[False]["params"] == sizes[True]["params"] == want
    # The stem alone, 7x7 from 3 to 64 channels at half the input size, is a lower bound.
    assert sizes[False]["flops"] > 2 * 64 * 3 * 49 * (NET_H // 2) * (NET_W // 2)
    assert sizes[True]["flops"] == 2 * sizes[False]["flops"]


@pytest.mark.slow
def test_hf_model_parameters_are_its_saved_weights(dataset, tmp_path, cli):
    """An hf: model's parameters: the elements of the tensors save_pretrained wrote (tied
    tensors once); its FLOPs at least its patch embedding's at the processor's 32 x 32."""
    import torch
    from safetensors.torch import load_file
    from transformers import DPTConfig, DPTForDepthEstimation, DPTImageProcessor

    torch.manual_seed(3)
    cfg = DPTConfig(hidden_size=16, num_hidden_layers=4, num_attention_heads=2, intermediate_size=24,
                    image_size=32, patch_size=8, neck_hidden_sizes=[8, 8, 16, 16],
                    fusion_hidden_size=8, backbone_out_indices=[0, 1, 2, 3], head_in_index=-1)
    DPTForDepthEstimation(cfg).save_pretrained(tmp_path / "dpt")
    DPTImageProcessor(size={"height": 32, "width": 32}).save_pretrained(tmp_path / "dpt")
    saved = load_file(tmp_path / "dpt" / "model.safetensors")
    pred = tmp_path / "P"
    res = cli("predict", dataset, "-m", f"hf:{tmp_path / 'dpt'}", "-o", pred, "--variants", "clean")
    assert res.exit_code == 0, res.output
    size = _record(pred)["size"]
    assert size["params"] == sum(t.numel() for t in saved.values())
    assert size["flops"] > conv(3, 16, 8, 4, 4)[1]


def test_run_writes_the_size_as_evaluate_does(tmp_path, cli, stack):
    """robodepth run: the same params and flops columns, and the kept predictions.json's
    size, as predict and evaluate give (the images at 64 x 96, as the hand count's)."""
    from tests.helpers.paths import FIXTURES

    res = cli("run", "nyudepth2-c", "--root", FIXTURES / "nyu", "--split", FIXTURES / "nyu_split.txt",
              "-m", f"python:{stack}:net", "--kind", "depth", "--out", tmp_path / "r.csv",
              "--size", f"{H}x{W}", "--corruptions", "brightness", "--levels", "1",
              "--keep-predictions", tmp_path / "K", "--no-progress")
    assert res.exit_code == 0, res.output
    rows = _rows(tmp_path / "r.csv")
    assert len(rows) == 2 and all(r["params"] == str(PARAMS) and r["flops"] == str(FLOPS) for r in rows)
    size = _record(tmp_path / "K")["size"]
    assert (size["params"], size["flops"]) == (PARAMS, FLOPS)
