"""The AdaIN models, checkpoint loading and the batched engine against the per-pair reference."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import torch
from PIL import Image

from tests.helpers.adain import adain_decoder, full_vgg, reference_stylize, save_checkpoints, smooth_image
from robodepth_cli.styles import adain
from robodepth_cli.styles import inputs as styles
from robodepth_cli.imageio import ImageError


@pytest.fixture(scope="module")
def checkpoints(tmp_path_factory):
    return save_checkpoints(tmp_path_factory.mktemp("ckpt"), seed=3)


@pytest.fixture(scope="module")
def stylizer(checkpoints):
    vgg_path, dec_path, _, _ = checkpoints
    return adain.Stylizer.from_files(vgg_path, dec_path)


@pytest.fixture(scope="module")
def images():
    rng = np.random.default_rng(11)
    content = smooth_image(rng, 64, 96)
    styles = [smooth_image(rng, 64, 64), smooth_image(rng, 48, 80), smooth_image(rng, 64, 64)]
    return content, styles


# ------------------------------------------------------------------------- layout


def test_published_indices_of_convolutions():
    enc, dec = adain.encoder(), adain.decoder()
    assert len(enc) == 31 and isinstance(enc[30], torch.nn.ReLU)
    assert [i for i, m in enumerate(enc) if isinstance(m, torch.nn.Conv2d)] == \
        [0, 2, 5, 9, 12, 16, 19, 22, 25, 29]
    assert [i for i, m in enumerate(dec) if isinstance(m, torch.nn.Conv2d)] == \
        [1, 5, 8, 11, 14, 18, 21, 25, 28]
    # The published files' keys and shapes, taken from an independently written layout.
    vgg, d = full_vgg(), adain_decoder()
    published_enc = {k: v.shape for k, v in vgg.state_dict().items() if int(k.split(".")[0]) <= 30}
    assert {k: v.shape for k, v in enc.state_dict().items()} == published_enc
    assert {k: v.shape for k, v in dec.state_dict().items()} == \
        {k: v.shape for k, v in d.state_dict().items()}


def test_loaded_encoder_matches_published_model(checkpoints):
    vgg_path, _, vgg, _ = checkpoints
    enc = adain.load_model(vgg_path, "vgg")
    x = torch.rand(1, 3, 40, 56, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        torch.testing.assert_close(enc(x), vgg[:31](x))


# ---------------------------------------------------------------- engine vs SPEC


def _outputs_meaningful(img: np.ndarray) -> None:
    # Guards the premise of the comparisons: saturated outputs would agree trivially.
    assert ((img > 0) & (img < 255)).mean() > 0.9 and img.std() > 5


@pytest.mark.slow
def test_batched_engine_matches_per_pair_reference(checkpoints, stylizer, images):
    _, _, vgg, dec = checkpoints
    content, styles = images
    feats = [stylizer.style_features(s) for s in styles]
    got = stylizer.stylize(content, feats)
    assert len(got) == len(styles)
    for out, style in zip(got, styles):
        ref = reference_stylize(vgg, dec, content, style)
        _outputs_meaningful(ref)
        assert out.shape == content.shape and out.dtype == np.uint8
        diff = np.abs(out.astype(int) - ref.astype(int))
        assert diff.max() <= 1 and (diff > 0).mean() < 0.002
    # Different styles really give different images.
    assert np.abs(got[0].astype(int) - got[1].astype(int)).mean() > 1


@pytest.mark.slow
@pytest.mark.parametrize("chunk,channels_last", [(1, False), (3, True)])
def test_engine_options_do_not_change_the_result(checkpoints, stylizer, images, chunk, channels_last):
    vgg_path, dec_path, _, _ = checkpoints
    content, styles = images
    other = adain.Stylizer.from_files(vgg_path, dec_path, chunk=chunk, channels_last=channels_last)
    a = stylizer.stylize(content, [stylizer.style_features(s) for s in styles])
    b = other.stylize(content, [other.style_features(s) for s in styles])
    for x, y in zip(a, b):
        assert np.abs(x.astype(int) - y.astype(int)).max() <= 1


def test_same_bytes_for_any_thread_count_and_chunk(checkpoints, images):
    # A build's bytes must not depend on its number of workers, and a
    # worker of a pool of two runs torch with one thread.
    vgg_path, dec_path, _, _ = checkpoints
    styles = images[1]
    # Large enough for oneDNN to split work between threads (64 x 96 is not).
    content = smooth_image(np.random.default_rng(4), 96, 160)
    before = torch.get_num_threads()
    try:
        outs, feats = [], None
        for threads, chunk in ((2, 2), (1, 1), (1, 3)):
            st = adain.Stylizer.from_files(vgg_path, dec_path, threads=threads, chunk=chunk)
            if feats is None:  # the first stylizer's style features serve all three
                feats = [st.style_features(s) for s in styles]
            outs.append(np.stack(st.stylize(content, feats)))
    finally:
        torch.set_num_threads(before)
    assert np.array_equal(outs[0], outs[1]) and np.array_equal(outs[0], outs[2])


@pytest.mark.parametrize("alpha", [0.0, 0.4])
def test_alpha_blends_content_and_style_features(checkpoints, stylizer, images, alpha):
    _, _, vgg, dec = checkpoints
    content, styles = images
    out = stylizer.stylize(content, [stylizer.style_features(styles[0])], alpha=alpha)[0]
    ref = reference_stylize(vgg, dec, content, styles[0], alpha=alpha)
    assert np.abs(out.astype(int) - ref.astype(int)).max() <= 1
    full = stylizer.stylize(content, [stylizer.style_features(styles[0])], alpha=1.0)[0]
    assert np.abs(out.astype(int) - full.astype(int)).mean() > 1
    if alpha == 0.0:
        # No style at all: the decoder applied to the content's own features.
        with torch.no_grad():
            x = torch.tensor(content, dtype=torch.float32).permute(2, 0, 1)[None] / 255
            plain = (dec(vgg[:31](x))[0].clamp(0, 1) * 255 + 0.5).to(torch.uint8)
        assert np.abs(out.astype(int) - plain.permute(1, 2, 0).numpy().astype(int)).max() <= 1


def test_alpha_out_of_range_is_refused(stylizer, images):
    content, styles = images
    with pytest.raises(ValueError, match="alpha"):
        stylizer.stylize(content, [stylizer.style_features(styles[0])], alpha=1.5)


def test_size_not_divisible_by_8_is_cropped(checkpoints, stylizer, images):
    _, _, vgg, dec = checkpoints
    content = images[0][:61, :90]  # decoder gives 64 x 96
    style = images[1][0]
    out = stylizer.stylize(content, [stylizer.style_features(style)])[0]
    assert out.shape == (61, 90, 3)
    ref = reference_stylize(vgg, dec, content, style)
    assert np.abs(out.astype(int) - ref.astype(int)).max() <= 1


def test_no_styles_gives_no_images(stylizer, images):
    assert stylizer.stylize(images[0], []) == []


def test_adain_statistics_match_style():
    # After AdaIN, each channel has the style's mean and (unbiased) std.
    gen = torch.Generator().manual_seed(5)
    fc = torch.rand(1, 8, 6, 7, generator=gen) * 3
    ms, ss = torch.rand(2, 8, 1, 1, generator=gen), torch.rand(2, 8, 1, 1, generator=gen) + 0.5
    t = adain.adain(fc, ms, ss)
    assert t.shape == (2, 8, 6, 7)
    m, s = adain.mean_std(t, eps=0.0)
    torch.testing.assert_close(m, ms, rtol=1e-5, atol=1e-5)
    # std_c includes eps, so the result's std is ss * sqrt(var_c / (var_c + eps)).
    torch.testing.assert_close(s, ss, rtol=1e-4, atol=1e-4)


# ------------------------------------------------------------------ style images


def test_style_is_resized_to_shorter_side_bilinear(tmp_path):
    rng = np.random.default_rng(2)
    img = smooth_image(rng, 100, 150)
    path = tmp_path / "s.png"
    Image.fromarray(img).save(path)
    out = styles.load_style(path, 64)
    assert out.shape == (64, 96, 3)
    expected = np.asarray(Image.fromarray(img).resize((96, 64), Image.BILINEAR))
    np.testing.assert_array_equal(out, expected)
    tall = styles.load_style(path.rename(tmp_path / "t.png"), 0)
    assert tall.shape == (100, 150, 3)
    assert styles.style_resize_size(300, 700, 512) == (512, 1194)
    assert styles.style_resize_size(700, 300, 512) == (1194, 512)


def test_bad_style_size_and_unreadable_style(tmp_path):
    with pytest.raises(ValueError, match="style size"):
        styles.check_style_size(8)
    bad = tmp_path / "cartoon.png"
    bad.write_bytes(b"not an image")
    with pytest.raises(ImageError, match="cartoon.png"):
        styles.load_style(bad)


# ------------------------------------------------------------------- checkpoints


class _NotATensor:
    pass


def _state(model):
    # Copies: the models are shared by the module's fixtures.
    return {k: v.clone() for k, v in model.state_dict().items()}


def _save(state, path):
    torch.save(state, path)
    return path


def test_missing_tensor_is_refused(tmp_path, checkpoints):
    _, _, vgg, _ = checkpoints
    state = _state(vgg)
    del state["29.weight"]
    path = _save(state, tmp_path / "vgg.pth")
    with pytest.raises(adain.CheckpointError, match=r"vgg\.pth: missing tensor '29\.weight'"):
        adain.load_model(path, "vgg")


def test_misshapen_tensor_is_refused(tmp_path, checkpoints):
    _, _, _, dec = checkpoints
    state = _state(dec)
    state["1.weight"] = state["1.weight"].transpose(0, 1).contiguous()
    path = _save(state, tmp_path / "dec.pth")
    with pytest.raises(adain.CheckpointError,
                       match=r"dec\.pth: tensor '1\.weight' .*shape \(512, 256, 3, 3\), expected \(256, 512, 3, 3\)"):
        adain.load_model(path, "decoder")


def test_unexpected_tensors_are_refused_but_deeper_vgg_layers_ignored(tmp_path, checkpoints):
    _, _, vgg, dec = checkpoints
    state = _state(dec)
    state["29.weight"] = torch.zeros(3)
    with pytest.raises(adain.CheckpointError, match=r"unexpected tensor '29\.weight'"):
        adain.load_model(_save(state, tmp_path / "dec.pth"), "decoder")
    state = _state(vgg)
    state["1.weight"] = torch.zeros(3)  # a pad has no weights
    with pytest.raises(adain.CheckpointError, match=r"unexpected tensor '1\.weight'"):
        adain.load_model(_save(state, tmp_path / "vgg.pth"), "vgg")
    # Only up to relu4_1 is needed: a truncated VGG loads as well as the full one.
    short = {k: v for k, v in vgg.state_dict().items() if int(k.split(".")[0]) <= 30}
    assert len(short) < len(vgg.state_dict())
    adain.load_model(_save(short, tmp_path / "short.pth"), "vgg")


def test_non_state_dict_files_are_refused(tmp_path):
    p = tmp_path / "model.pth"
    with open(p, "wb") as fh:
        pickle.dump({"0.weight": _NotATensor()}, fh)
    with pytest.raises(adain.CheckpointError, match=r"model\.pth: not a PyTorch state_dict"):
        adain.load_model(p, "vgg")
    with pytest.raises(adain.CheckpointError, match=r"list\.pth: expected a state_dict"):
        adain.load_model(_save([torch.zeros(2)], tmp_path / "list.pth"), "vgg")
    with pytest.raises(adain.CheckpointError, match=r"nested\.pth: .*entry 'model' is a dict"):
        adain.load_model(_save({"model": {"0.weight": torch.zeros(1)}}, tmp_path / "nested.pth"), "vgg")
    (tmp_path / "text.pth").write_text("hello")
    with pytest.raises(adain.CheckpointError, match=r"text\.pth: not a PyTorch state_dict"):
        adain.load_model(tmp_path / "text.pth", "decoder")
    with pytest.raises(adain.CheckpointError, match=r"absent\.pth: no such file"):
        adain.load_model(tmp_path / "absent.pth", "decoder")


def test_swapped_checkpoints_are_named(checkpoints):
    vgg_path, dec_path, _, _ = checkpoints
    with pytest.raises(adain.CheckpointError, match=r"decoder\.pth: this is the AdaIN decoder checkpoint"):
        adain.load_model(dec_path, "vgg")
    with pytest.raises(adain.CheckpointError, match=r"vgg_normalised\.pth: this is the AdaIN vgg checkpoint"):
        adain.load_model(vgg_path, "decoder")


def test_non_finite_weights_are_refused(tmp_path, checkpoints):
    _, _, _, dec = checkpoints
    state = _state(dec)
    state["28.bias"][0] = float("nan")
    with pytest.raises(adain.CheckpointError, match=r"'28\.bias' contains NaN"):
        adain.load_model(_save(state, tmp_path / "dec.pth"), "decoder")


def test_engine_is_self_contained():
    """The torch engine loads none of the KITTI-S input handling (which imports it lazily):
    no import circle between adain and styles."""
    import subprocess
    import sys

    code = "import sys, robodepth_cli.styles.adain; print('robodepth_cli.styles.inputs' in sys.modules)"
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "False"
