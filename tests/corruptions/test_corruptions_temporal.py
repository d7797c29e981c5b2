"""The corruptions over time on synthetic sequences: lost and frozen frames, codec round
trips at increasing CRF, bit errors in the coded stream."""

from __future__ import annotations

import concurrent.futures
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest
from PIL import Image

from robodepth_cli.corruptions import codec, temporal

from tests.helpers.paths import FIXTURES, REPO


@pytest.fixture(scope="module")
def sequence():
    """Three 96 x 320 frames of a real photograph, the camera panning 8 px per frame."""
    path = next(FIXTURES.glob("kitti_raw/**/image_02/data/*.png"))
    im = np.asarray(Image.open(path).convert("RGB").resize((336, 96), Image.LANCZOS))
    return [np.ascontiguousarray(im[:, 8 * i: 8 * i + 320]) for i in range(3)]


def psnr(out, ref) -> float:
    mse = np.mean([np.mean((o.astype(float) - r) ** 2) for o, r in zip(out, ref)])
    return 10 * np.log10(255 ** 2 / mse)


@pytest.mark.parametrize("name", ["h264_crf", "h265_crf"])
def test_codec_round_trip_close_at_lowest_crf_and_worse_as_it_grows(sequence, name):
    quality = [psnr(temporal.corrupt_sequence(name, sequence, 1, lv, np.random.default_rng(0)), sequence)
               for lv in range(1, 6)]
    assert quality[0] > 30  # CRF 18: close to the input
    assert all(a > b for a, b in zip(quality, quality[1:])), quality
    assert quality[-1] < 27


def test_codec_keeps_missing_frames_and_odd_sizes(sequence):
    frames = [None, sequence[0][:95, :317], sequence[1][:95, :317]]
    out = temporal.corrupt_sequence("h264_crf", frames, 1, 1, np.random.default_rng(0))
    assert out[0] is None and [o.shape for o in out[1:]] == [(95, 317, 3)] * 2
    assert psnr(out[1:], frames[1:]) > 30


def test_bit_flips_land_in_the_picture_data_only(sequence):
    data = codec.encode(sequence, "h264", 23)
    spans = codec.slice_spans(data, "h264")
    inside = np.zeros(len(data), bool)
    for s, e in spans:
        inside[s:e] = True
    assert 0.5 < inside.mean() < 1  # parameter sets, SEI and NAL headers are outside
    flipped = codec.flip_bits(data, "h264", 1e-3, np.random.default_rng(5))
    diff = np.frombuffer(flipped, np.uint8) ^ np.frombuffer(data, np.uint8)
    n_bits = int(np.unpackbits(diff).sum())
    expected = inside.sum() * 8 * 1e-3
    assert abs(n_bits - expected) < 5 * np.sqrt(expected)
    assert not diff[~inside].any()
    assert codec.flip_bits(data, "h264", 0.0, np.random.default_rng(5)) == data


def test_bit_errors_damage_more_at_higher_levels(sequence):
    clean_trip = codec.decode(codec.encode(sequence, "h264", temporal.BIT_ERROR_CRF), "h264", 3,
                              sequence[0].shape[:2])

    def damage(level) -> float:
        """Mean squared difference from the error-free round trip, over several streams (a
        single flip may or may not hit something that shows)."""
        return float(np.mean([
            np.mean([(a.astype(float) - b) ** 2 for a, b in zip(clean_trip, temporal.corrupt_sequence(
                "bit_error", sequence, 1, level, np.random.default_rng(s)))])
            for s in range(6)]))

    assert damage(1) < damage(3) < damage(5)
    assert damage(5) > 100  # a mean squared error of 100: visibly broken


def test_frame_lost_blacks_out_neighbours_only(sequence):
    frames = [None, *sequence]  # a drive start: no frame before
    out = temporal.corrupt_sequence("frame_lost", frames, 2, 5, np.random.default_rng(0))
    assert out[0] is None and out[2] is sequence[1]
    assert not out[1].any() and not out[3].any()
    # p = 0.4 at level 2: the share of lost neighbours over many sequences
    lost = [not temporal.corrupt_sequence("frame_lost", sequence, 1, 2, np.random.default_rng(s))[i].any()
            for s in range(1000) for i in (0, 2)]
    assert abs(np.mean(lost) - 0.4) < 0.05  # 4.5 standard deviations of 2000 draws


def test_frame_freeze_repeats_the_frame_towards_the_test_frame(sequence):
    five = [sequence[0], sequence[1], sequence[2], sequence[1], sequence[0]]
    five = [f.copy() for f in five]
    out = temporal.corrupt_sequence("frame_freeze", five, 2, 5, np.random.default_rng(0))
    assert all(o is five[2] for o in out)  # p = 1: the whole sequence frozen on the test frame
    frozen = [temporal.corrupt_sequence("frame_freeze", sequence, 1, 3, np.random.default_rng(s))[i]
              is sequence[1] for s in range(1000) for i in (0, 2)]
    assert abs(np.mean(frozen) - 0.6) < 0.05  # p = 0.6 at level 3


def test_levels_between_integers_interpolate():
    assert temporal.parameter("h264_crf", 1) == 18 and temporal.parameter("h264_crf", 5) == 51
    assert temporal.parameter("h264_crf", 2.5) == 30
    assert temporal.parameter("frame_lost", 4.5) == pytest.approx(0.9)


@pytest.mark.parametrize("instructions", ["asm=0", "asm=SSE2", "asm=AVX"])
def test_h264_stream_is_the_same_whichever_instructions_libx264_may_use(monkeypatch, instructions):
    """Restricting libx264 to C, SSE2 or AVX code stands in for an older CPU: the stream
    must not change. (Without its cpu-independent mode, AVX2 and SSE2 gave other streams.)"""
    rng = np.random.default_rng(5)
    base = cv2.GaussianBlur(rng.integers(0, 256, (96, 336, 3), dtype=np.uint8), (9, 9), 3)
    frames = [np.ascontiguousarray(base[:, 4 * i:4 * i + 320]) for i in range(3)]
    ours = codec.encode(frames, "h264", 30)
    monkeypatch.setattr(codec, "X264_PARAMS", f"{codec.X264_PARAMS}:{instructions}")
    assert codec.encode(frames, "h264", 30) == ours


# A child process: encodes and decodes one tiny sequence, prints the digests. Some children
# switch FFmpeg's SIMD off (as a CPU without it runs) or run on one CPU only.
_CHILD = """
import ctypes, glob, hashlib, os, sys
import cv2
import numpy as np
import av
if sys.argv[1] == "no-simd":
    libs = os.path.join(os.path.dirname(av.__file__), os.pardir, "av.libs")
    ctypes.CDLL(glob.glob(os.path.join(libs, "libavutil-*.so*"))[0]).av_force_cpu_flags(0)
if sys.argv[1] == "one-cpu":
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
from robodepth_cli.corruptions import codec
rng = np.random.default_rng(3)
base = np.kron(rng.integers(0, 256, (5, 9, 3)), np.ones((8, 8, 1))).astype(np.uint8)
frames = [np.ascontiguousarray(base[:, 2 * i:2 * i + 64]) for i in range(3)]
data = codec.encode(frames, "h264", 30)
shown = codec.decode(data, "h264", 3, (40, 64))
print(hashlib.sha256(data).hexdigest(), hashlib.sha256(b"".join(f.tobytes() for f in shown)).hexdigest())
"""


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="needs Linux's sched_setaffinity")
def test_h264_gives_the_same_bytes_in_any_process():
    """20 processes, some with FFmpeg's SIMD switched off and some on one CPU: one stream
    and one decoded sequence. (With FFmpeg's colour conversion, switching its SIMD off
    changed the stream.)"""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    modes = ["plain", "no-simd", "one-cpu", "plain"] * 5
    with concurrent.futures.ThreadPoolExecutor(4) as pool:
        runs = list(pool.map(lambda mode: subprocess.run([sys.executable, "-c", _CHILD, mode], env=env,
                                                         capture_output=True, text=True, timeout=120), modes))
    assert all(r.returncode == 0 for r in runs), [r.stderr[-500:] for r in runs if r.returncode]
    results = {mode: set() for mode in modes}
    for mode, r in zip(modes, runs):
        results[mode].add(r.stdout.strip())
    assert len(set().union(*results.values())) == 1, results


def test_colour_conversion_by_hand():
    """BT.601 limited range: grey v has Y = 16 + 219 v / 255 (200: 187.8) and chroma 128,
    and comes back within a level; pure red has Y = 16 + 65.481 = 81.5, U = 128 - 37.797
    = 90.2, V = 128 + 112 = 240."""
    grey = np.full((2, 4, 3), 200, np.uint8)
    yuv = codec.rgb_to_yuv420p(grey)
    assert yuv.shape == (3, 4)
    assert (yuv[:2] == 188).all() and (yuv[2:] == 128).all()
    assert np.abs(codec.yuv420p_to_rgb(yuv).astype(int) - 200).max() <= 1
    red = np.zeros((2, 2, 3), np.uint8)
    red[..., 0] = 255
    y, u, v = codec.rgb_to_yuv420p(red).reshape(-1)[[0, 4, 5]]
    assert abs(int(y) - 81.5) <= 1 and (u, v) == (90, 240)
    back = codec.yuv420p_to_rgb(codec.rgb_to_yuv420p(red))
    assert np.abs(back.astype(int) - red).max() <= 2


# A child process (a crash inside the encoder kills it, not pytest): every codec corruption
# at every level on small frames, each run twice in the process; prints one digest per size
# and corruption. (Unpadded, libx265 corrupted its heap on frames 48 or fewer pixels wide,
# and libx264 read uninitialised memory there. FFmpeg's parser read past the end of an
# unpadded stream. With libx265 in the process, libx264's stream at 9 x 31 and 32 x 56
# changed in one run of 50 under load until both encoders ran their CPU-independent code.)
_SMALL_CHILD = """
import hashlib, sys
import cv2
import numpy as np
from robodepth_cli.corruptions import temporal
rng = np.random.default_rng(7)
for size in sys.argv[1:]:
    h, w = map(int, size.split("x"))
    base = np.kron(rng.integers(0, 256, (h // 8 + 1, w // 8 + 2, 3)), np.ones((8, 8, 1))).astype(np.uint8)
    frames = [np.ascontiguousarray(base[:h, 4 * i:4 * i + w]) for i in range(3)]
    for name in ("h264_crf", "h265_crf", "bit_error"):
        digest = hashlib.sha256()
        for level in (1, 2, 3, 4, 5, 2.5):
            a, b = (temporal.corrupt_sequence(name, frames, 1, level, np.random.default_rng(1)) for _ in range(2))
            assert all(o.shape == (h, w, 3) and o.dtype == np.uint8 for o in a), (size, name)
            assert all(np.array_equal(x, y) for x, y in zip(a, b)), (size, name, level)
            digest.update(b"".join(o.tobytes() for o in a))
        print(size, name, digest.hexdigest(), flush=True)
"""

# libx265 wrote past its lookahead's buffers on frames 48 pixels wide or narrower (a glibc
# abort or a segfault, in the build's worker: the whole build), read memory it never wrote
# at 64 x 64, refused under 16 rows and changed its stream now and then on 16 rows.
SMALL_SIZES = ["32x48", "32x40", "48x48", "64x48", "32x16", "8x8", "9x31", "32x56", "32x64", "64x64"]


def test_codec_corruptions_on_small_frames_run_and_repeat():
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    runs = [subprocess.run([sys.executable, "-c", _SMALL_CHILD, *SMALL_SIZES], env=env,
                           capture_output=True, text=True, timeout=300) for _ in range(2)]
    for r in runs:
        assert r.returncode == 0, (r.returncode, r.stdout[-300:], r.stderr[-500:])
        assert len(r.stdout.split("\n")) == 3 * len(SMALL_SIZES) + 1
    assert runs[0].stdout == runs[1].stdout  # the same bytes in another process
