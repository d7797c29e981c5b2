"""What `robodepth predict` says before its work (issue 26): the device `--device auto`
chose for a monodepth2 or hf model comes first, before any image (a long CPU run where a
GPU was expected is seen at once), and a bad --batch-size is the one-line error of every
bad option value."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def dataset(kitti_c_build):
    return kitti_c_build


@pytest.fixture
def stopped_before_the_images(monkeypatch):
    """predict's driver stopped before its first image: what is said is said before."""
    from robodepth_cli.errors import RobodepthError
    from robodepth_cli.models import predict as P

    def stop(*args, **kwargs):
        raise RobodepthError("stopped before the first image")

    monkeypatch.setattr(P, "predict", stop)


def test_the_device_auto_chose_is_said_first(dataset, tmp_path, cli, stopped_before_the_images):
    import torch
    from tests.helpers.models import random_monodepth2

    random_monodepth2(tmp_path / "m", 18)
    res = cli("predict", dataset, "-m", f"monodepth2:{tmp_path / 'm'}", "--out", tmp_path / "PRED",
              "--no-progress")
    device = "cuda" if torch.cuda.is_available() else "cpu"
    assert res.stderr.splitlines() == [
        f"robodepth: monodepth2:{tmp_path / 'm'} runs on {device} (--device auto)",
        "robodepth: error: stopped before the first image"], res.stderr


def test_a_python_model_chooses_its_own_device(dataset, tmp_path, cli, stopped_before_the_images):
    module = tmp_path / "m.py"
    module.write_text("def predict(images):\n    return images.mean(axis=3)\n")
    res = cli("predict", dataset, "-m", f"python:{module}:predict", "--kind", "disp", "--out",
              tmp_path / "PRED", "--no-progress")
    assert res.stderr == "robodepth: error: stopped before the first image\n"


def test_batch_size_zero_is_one_line(dataset, tmp_path, cli):
    res = cli("predict", dataset, "-m", "python:x.py:f", "--out", tmp_path / "PRED", "-b", "0")
    assert res.exit_code == 2
    assert res.output == "robodepth: error: --batch-size: must be at least 1\n"
