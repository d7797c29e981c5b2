"""A sequence of frames through a real video codec (PyAV's bundled FFmpeg: libx264 for
H.264, libx265 for H.265/HEVC), and bit errors in the encoded stream, decoded as a player
would. PyAV (the ``video`` extra) is imported here only, when a sequence is encoded.

The settings and paddings are docs/video.md's (:func:`coded_size`). The bytes are the same
in any process and on any CPU with the same library versions: the colour conversions both
ways are exact integer arithmetic here (:func:`rgb_to_yuv420p`, :func:`yuv420p_to_rgb`), not
FFmpeg's swscale, whose SIMD code differs with the CPU; the encoder and decoder run one
thread each and the encoders' CPU-independent code (:data:`X264_PARAMS`, :data:`X265_PARAMS`)."""

from __future__ import annotations

import io

import numpy as np

from ..errors import RobodepthError

CODECS = {"h264": ("libx264", "h264"), "h265": ("libx265", "hevc")}
FPS = 10
# Narrow pictures the encoders mishandle are widened (valgrind, one encode of 3 frames):
# - libx265's lookahead (its cuTree, on the half-size picture in 8 x 8 blocks) writes past
#   its buffers when a row has fewer than 4 blocks, i.e. 48 pixels wide or narrower (a
#   glibc abort or a segfault in a later encode), and its motion search reads memory it
#   never wrote on pictures exactly one 64-pixel block wide and 64 or more high (none at
#   56, 62, 72 or 128 wide);
# - libx264 reads uninitialised memory 48 pixels wide or narrower (none at 56, 64, 640).
# Either way the stream could change with what ran before in the process.
NARROW = {"h264": (48, 64), "h265": (64, 72)}  # codec -> (widest padded, padded width)
# libx265 refuses pictures under 16 rows, and on 16 rows its stream changed between two
# encodes in one process now and then (3 processes in 80 under load; none at 64 rows).
H265_MIN_HEIGHT = 64
# FFmpeg's parser reads up to AV_INPUT_BUFFER_PADDING_SIZE bytes past the end of its input,
# which must be zeros.
PARSER_PADDING = 64
# One thread each, and the encoders' canonical code instead of the SIMD code they pick from
# the CPU: libx264's assembly takes other decisions on AVX than on SSE2 (another stream at
# 192 x 640), and libx265's gives another stream at every instruction set it dispatches
# (SSE2, SSE4.2, AVX, AVX2, AVX-512) and reads memory it never wrote (valgrind; none with
# asm=none), so its stream could change with what ran before in the process. x264's
# cpu-independent mode keeps its assembly where that is exact; asm=none costs x265 no time
# here (3 frames of 192 x 640 to 376 x 1242, measured side by side).
X264_PARAMS = "threads=1:lookahead-threads=1:sliced-threads=0:cpu-independent=1"
X265_PARAMS = "log-level=none:pools=1:frame-threads=1:asm=none"


def _av():
    try:
        import av
    except ImportError:
        raise RobodepthError("the video corruptions need PyAV: pip install 'robodepth-cli[video]'") from None
    return av


# BT.601 limited range in 1/256 (Y) and 1/1024 (chroma of a 2 x 2 sum) fixed point.
_Y = np.array([66, 129, 25], np.int32)
_U = np.array([-38, -74, 112], np.int32)
_V = np.array([112, -94, -18], np.int32)


def rgb_to_yuv420p(img: np.ndarray) -> np.ndarray:
    """uint8 RGB (even H x W) as a yuv420p picture in PyAV's layout (3H/2 rows of W: the Y,
    U and V planes one after the other, flat): ``Y = ((66 R + 129 G + 25 B + 128) >> 8)
    + 16``; U and V the same with (-38, -74, 112) and (112, -94, -18) on the sum of each
    2 x 2 block, ``(... + 512) >> 10``, + 128. Exact integers."""
    h, w = img.shape[:2]
    rgb = img.astype(np.int32)
    y = ((rgb @ _Y + 128) >> 8) + 16
    block = rgb.reshape(h // 2, 2, w // 2, 2, 3).sum(axis=(1, 3))
    u = ((block @ _U + 512) >> 10) + 128
    v = ((block @ _V + 512) >> 10) + 128
    flat = np.concatenate([y.reshape(-1), u.reshape(-1), v.reshape(-1)])
    return np.clip(flat, 0, 255).astype(np.uint8).reshape(h * 3 // 2, w)


def yuv420p_to_rgb(yuv: np.ndarray) -> np.ndarray:
    """The inverse conversion of a PyAV yuv420p array (3H/2 x W) to uint8 RGB H x W, each
    chroma sample covering its 2 x 2 block: with ``C = 298 (Y - 16)``, ``D = U - 128``,
    ``E = V - 128``: ``R = (C + 409 E + 128) >> 8``, ``G = (C - 100 D - 208 E + 128) >> 8``,
    ``B = (C + 516 D + 128) >> 8``, clipped to 0..255. Exact integers."""
    h, w = yuv.shape[0] * 2 // 3, yuv.shape[1]
    flat = yuv.reshape(-1).astype(np.int32)
    c = 298 * (flat[:h * w].reshape(h, w) - 16)
    n = h * w // 4
    d, e = (flat[h * w + i * n:h * w + (i + 1) * n].reshape(h // 2, w // 2) - 128 for i in range(2))
    d, e = (np.repeat(np.repeat(p, 2, axis=0), 2, axis=1) for p in (d, e))
    rgb = np.stack([c + 409 * e, c - 100 * d - 208 * e, c + 516 * d], axis=-1)
    return np.clip((rgb + 128) >> 8, 0, 255).astype(np.uint8)


def coded_size(h: int, w: int, codec: str) -> tuple[int, int]:
    """The picture size (H, W) the encoder gets for frames of ``h`` x ``w``: even; for
    H.264 64 wide when the frame is 48 or narrower, for H.265 72 wide when it is 64 or
    narrower and at least 64 high (on smaller pictures the encoders read memory they never
    wrote, write past their buffers or give another stream now and then). Sizes the
    encoders handle are left alone, so their streams do not change."""
    h, w = h + h % 2, w + w % 2
    widest, padded = NARROW[codec]
    w = padded if w <= widest else w
    if codec == "h265":
        h = max(h, H265_MIN_HEIGHT)
    return h, w


def encode(frames: list[np.ndarray], codec: str, crf: int) -> bytes:
    """``frames`` (uint8 H x W x 3, same size) as an Annex B elementary stream of
    :func:`coded_size` pictures, padded by repeating the last row and column."""
    av = _av()
    encoder, fmt = CODECS[codec]
    h, w = frames[0].shape[:2]
    ch, cw = coded_size(h, w, codec)
    buf = io.BytesIO()
    with av.open(buf, "w", format=fmt) as container:
        stream = container.add_stream(encoder, rate=FPS)
        stream.width, stream.height = cw, ch
        stream.pix_fmt = "yuv420p"
        params = {"h264": {"x264-params": X264_PARAMS}, "h265": {"x265-params": X265_PARAMS}}[codec]
        stream.options = {"crf": str(int(crf)), "preset": "medium", "threads": "1", **params}
        for img in frames:
            img = np.pad(img, ((0, ch - h), (0, cw - w), (0, 0)), mode="edge")
            frame = av.VideoFrame.from_ndarray(rgb_to_yuv420p(img), format="yuv420p")
            for packet in stream.encode(frame):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)
    return buf.getvalue()


def decode(data: bytes, codec: str, n: int, size: tuple[int, int]) -> list[np.ndarray]:
    """``n`` frames of ``size`` (H, W) from the stream ``data``, as a player shows them: a
    picture the decoder cannot make is replaced by the last one shown (black before the
    first); FFmpeg's own error concealment repairs what it can inside a damaged picture."""
    av = _av()
    ctx = av.CodecContext.create(CODECS[codec][1], "r")
    ctx.thread_count = 1
    pictures: list[np.ndarray] = []

    def take(packet):
        try:
            pictures.extend(yuv420p_to_rgb(f.to_ndarray(format="yuv420p")) for f in ctx.decode(packet))
        except (av.error.FFmpegError, ValueError):
            pass  # a packet the decoder refuses: its picture is not shown

    # PyAV hands the parser the bytes object as it is (valgrind: reads past its end in
    # av_parser_parse2); a view of a zero-padded copy gives it the padding it expects.
    padded = bytearray(data)
    padded.extend(bytes(PARSER_PADDING))
    try:
        packets = ctx.parse(memoryview(padded)[:len(data)]) + ctx.parse(None)  # None: flush
    except av.error.FFmpegError:
        packets = []
    for packet in packets:
        take(packet)
    take(None)
    h, w = size
    shown, last = [], np.zeros((h, w, 3), np.uint8)
    for i in range(n):
        if i < len(pictures) and pictures[i].shape[0] >= h and pictures[i].shape[1] >= w:
            last = np.ascontiguousarray(pictures[i][:h, :w])
        shown.append(last)
    return shown


def slice_spans(data: bytes, codec: str) -> list[tuple[int, int]]:
    """The byte spans of the coded picture data in an Annex B stream: each coded slice's
    NAL unit without its NAL header (the parameter sets and SEI are left out: a link that
    loses those loses the whole stream, which is not a bit error)."""
    starts = []
    i = data.find(b"\x00\x00\x01")
    while i >= 0:
        starts.append(i + 3)
        i = data.find(b"\x00\x00\x01", i + 3)
    spans = []
    for k, s in enumerate(starts):
        end = (starts[k + 1] - 3) if k + 1 < len(starts) else len(data)
        if s >= len(data):
            continue
        if codec == "h264":
            slice_nal, header = (data[s] & 0x1F) in (1, 5), 1
        else:
            slice_nal, header = ((data[s] >> 1) & 0x3F) <= 21, 2
        if slice_nal and end > s + header:
            spans.append((s + header, end))
    return spans


def flip_bits(data: bytes, codec: str, rate: float, rng: np.random.Generator) -> bytes:
    """``data`` with each bit of the coded picture data flipped with probability ``rate``:
    the number of flips drawn binomially, then their positions without repeats."""
    spans = slice_spans(data, codec)
    sizes = np.array([e - s for s, e in spans], dtype=np.int64)
    total = int(sizes.sum()) * 8
    if total == 0:
        return data
    k = int(rng.binomial(total, rate))
    bits = rng.choice(total, size=k, replace=False) if k else np.empty(0, np.int64)
    offsets = np.concatenate([[0], np.cumsum(sizes)]) * 8
    buf = bytearray(data)
    for b in np.sort(bits):
        span = int(np.searchsorted(offsets, b, side="right")) - 1
        byte = spans[span][0] + int(b - offsets[span]) // 8
        buf[byte] ^= 0x80 >> int((b - offsets[span]) % 8)
    return bytes(buf)
