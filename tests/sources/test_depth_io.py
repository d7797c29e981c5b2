"""robodepth_cli.sources.depth_io: each form written here byte by byte (or by another
library) from its documentation, read back, compared with values worked out by hand."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from tests.helpers.depth_files import png16

from robodepth_cli.sources.depth_io import (
    DepthError,
    depth_format,
    read_depth,
    read_mask,
)

NAN = np.nan


def _same(a, b):
    np.testing.assert_array_equal(np.isnan(a), np.isnan(np.asarray(b, dtype=float)))
    np.testing.assert_allclose(np.nan_to_num(a), np.nan_to_num(np.asarray(b, dtype=float)), rtol=1e-6)




def test_png16_kitti_scale_and_millimetres(tmp_path):
    raw = np.array([[0, 256, 512], [1000, 65535, 1]], np.uint16)
    png16(tmp_path / "d.png", raw)
    _same(read_depth(tmp_path / "d.png", scale=256),
          [[NAN, 1.0, 2.0], [1000 / 256, 65535 / 256, 1 / 256]])
    _same(read_depth(tmp_path / "d.png", scale=1000), [[NAN, 0.256, 0.512], [1.0, 65.535, 0.001]])


def test_png_needs_a_scale_and_16_bits(tmp_path):
    png16(tmp_path / "d.png", np.ones((2, 2), np.uint16))
    with pytest.raises(DepthError, match="need a scale"):
        read_depth(tmp_path / "d.png")
    import cv2

    cv2.imwrite(str(tmp_path / "e.png"), np.ones((2, 2), np.uint8))
    with pytest.raises(DepthError, match="16-bit"):
        read_depth(tmp_path / "e.png", scale=256)


def test_npy_diode_shape_and_mask(tmp_path):
    # DIODE: <name>_depth.npy is H x W x 1 float32 metres, <name>_depth_mask.npy H x W 0/1.
    d = np.array([[[1.5], [0.0]], [[np.inf], [350.0]]], np.float32)
    np.save(tmp_path / "x_depth.npy", d)
    np.save(tmp_path / "x_depth_mask.npy", np.array([[1, 1], [1, 0]], np.float32))
    _same(read_depth(tmp_path / "x_depth.npy"), [[1.5, NAN], [NAN, 350.0]])
    _same(read_depth(tmp_path / "x_depth.npy", mask=tmp_path / "x_depth_mask.npy"),
          [[1.5, NAN], [NAN, NAN]])
    np.save(tmp_path / "m.npy", np.ones((3, 2)))
    with pytest.raises(DepthError, match="mask of 3 x 2"):
        read_depth(tmp_path / "x_depth.npy", mask=tmp_path / "m.npy")


def test_npy_integers_and_negative(tmp_path):
    np.save(tmp_path / "i.npy", np.array([[1000, 0], [2500, 7]], np.uint16))
    _same(read_depth(tmp_path / "i.npy", scale=1000), [[1.0, NAN], [2.5, 0.007]])
    np.save(tmp_path / "f.npy", np.array([[-1.0, np.nan, 2.0]], np.float64))
    _same(read_depth(tmp_path / "f.npy"), [[NAN, NAN, 2.0]])
    np.save(tmp_path / "bad.npy", np.ones((2, 2, 3), np.float32))
    with pytest.raises(DepthError, match="shape"):
        read_depth(tmp_path / "bad.npy")


def test_npz_one_array_or_depth(tmp_path):
    np.savez(tmp_path / "a.npz", np.array([[3.0, 0.0]], np.float32))
    _same(read_depth(tmp_path / "a.npz"), [[3.0, NAN]])
    np.savez(tmp_path / "b.npz", depth=np.array([[4.0]]), conf=np.array([[1.0]]))
    _same(read_depth(tmp_path / "b.npz"), [[4.0]])
    np.savez(tmp_path / "c.npz", a=np.ones((1, 1)), b=np.ones((1, 1)))
    with pytest.raises(DepthError, match="named 'depth'"):
        read_depth(tmp_path / "c.npz")


@pytest.mark.parametrize("order", ["<", ">"])
def test_pfm_rows_bottom_up_both_byte_orders(tmp_path, order):
    # Rows are stored bottom row first; the scale's sign is the byte order.
    top_down = np.array([[1.0, 2.0, 3.0], [4.0, 0.0, np.inf]], np.float32)
    header = b"Pf\n3 2\n" + (b"-1.0\n" if order == "<" else b"1.0\n")
    body = top_down[::-1].astype(order + "f4").tobytes()
    (tmp_path / "d.pfm").write_bytes(header + body)
    _same(read_depth(tmp_path / "d.pfm"), [[1.0, 2.0, 3.0], [4.0, NAN, NAN]])


def test_pfm_colour_refused(tmp_path):
    (tmp_path / "c.pfm").write_bytes(b"PF\n1 1\n-1.0\n" + b"\0" * 12)
    with pytest.raises(DepthError, match="'PF'"):
        read_depth(tmp_path / "c.pfm")


def test_sintel_dpt(tmp_path):
    # TAG_FLOAT 202021.25, width, height (int32), then float32 rows from the top.
    values = [[0.5, 1.0, 0.0], [2.0, 3.0, 1e10]]
    data = struct.pack("<fii", 202021.25, 3, 2) + struct.pack("<6f", *values[0], *values[1])
    (tmp_path / "frame_0001.dpt").write_bytes(data)
    _same(read_depth(tmp_path / "frame_0001.dpt"), [[0.5, 1.0, NAN], [2.0, 3.0, 1e10]])
    (tmp_path / "short.dpt").write_bytes(data[:-4])
    with pytest.raises(DepthError, match="5 values for a 3 x 2"):
        read_depth(tmp_path / "short.dpt")
    (tmp_path / "tag.dpt").write_bytes(struct.pack(">fii", 202021.25, 3, 2) + data[12:])
    with pytest.raises(DepthError, match="tag"):
        read_depth(tmp_path / "tag.dpt")


def test_eth3d_raw(tmp_path):
    # ETH3D: float32 row-major, no header, infinity where there is no ground truth.
    values = np.array([[1.25, np.inf], [7.5, 0.0]], "<f4")
    (tmp_path / "DSC_0001.JPG").write_bytes(values.tobytes())
    _same(read_depth(tmp_path / "DSC_0001.JPG", fmt="raw", shape=(2, 2)), [[1.25, NAN], [7.5, NAN]])
    with pytest.raises(DepthError, match="4 float32 values, but its image is 3 x 2"):
        read_depth(tmp_path / "DSC_0001.JPG", fmt="raw", shape=(3, 2))


def _exr(path, values):
    """An uncompressed one-channel ("Z", FLOAT) scanline OpenEXR file, written from the
    file-layout document: magic, version 2, the required attributes, the offset table,
    then one block per scanline (y, byte count, pixels)."""
    h, w = values.shape

    def attr(name, kind, data):
        return name + b"\0" + kind + b"\0" + struct.pack("<i", len(data)) + data

    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = b"".join([
        struct.pack("<ii", 20000630, 2),
        attr(b"channels", b"chlist", b"Z\0" + struct.pack("<iB3xii", 2, 0, 1, 1) + b"\0"),
        attr(b"compression", b"compression", b"\0"),
        attr(b"dataWindow", b"box2i", box), attr(b"displayWindow", b"box2i", box),
        attr(b"lineOrder", b"lineOrder", b"\0"),
        attr(b"pixelAspectRatio", b"float", struct.pack("<f", 1.0)),
        attr(b"screenWindowCenter", b"v2f", struct.pack("<ff", 0, 0)),
        attr(b"screenWindowWidth", b"float", struct.pack("<f", 1.0)), b"\0"])
    first = len(header) + 8 * h
    blocks = [struct.pack("<ii", y, 4 * w) + values[y].astype("<f4").tobytes() for y in range(h)]
    offsets = [first + sum(len(b) for b in blocks[:y]) for y in range(h)]
    path.write_bytes(header + struct.pack(f"<{h}Q", *offsets) + b"".join(blocks))


def test_exr_one_channel(tmp_path):
    pytest.importorskip("OpenEXR", reason="the exr extra (pip install 'robodepth-cli[exr]')")
    _exr(tmp_path / "d.exr", np.array([[1.0, 0.0, 2.5], [np.inf, 4.0, 100.0]], np.float32))
    _same(read_depth(tmp_path / "d.exr"), [[1.0, NAN, 2.5], [NAN, 4.0, 100.0]])


def test_masks_and_errors(tmp_path):
    png16(tmp_path / "m.png", np.array([[0, 1], [255, 0]], np.uint16))
    np.testing.assert_array_equal(read_mask(tmp_path / "m.png"), [[False, True], [True, False]])
    with pytest.raises(DepthError, match="no such file|cannot read"):
        read_depth(tmp_path / "none.npy")
    (tmp_path / "junk.npy").write_bytes(b"not numpy")
    with pytest.raises(DepthError, match="not a depth array"):
        read_depth(tmp_path / "junk.npy")
    with pytest.raises(DepthError, match="unknown depth file extension"):
        depth_format(tmp_path / "d.tif")
    with pytest.raises(DepthError, match="scale"):
        read_depth(tmp_path / "m.png", scale=0)


def test_cityscapes_disparity_to_depth(tmp_path):
    # disparity = (p - 1) / 256 where p > 0; depth = baseline * fx / disparity
    png16(tmp_path / "f_disparity.png", np.array([[257, 513, 0], [1, 1025, 65535]], np.uint16))
    (tmp_path / "f_camera.json").write_text(
        '{"extrinsic": {"baseline": 0.2}, "intrinsic": {"fx": 2000.0}}')
    got = read_depth(tmp_path / "f_disparity.png", fmt="cityscapes", camera=tmp_path / "f_camera.json")
    _same(got, [[400.0, 200.0, NAN], [NAN, 100.0, 400.0 / (65534 / 256)]])
    with pytest.raises(DepthError, match="needs its camera file"):
        read_depth(tmp_path / "f_disparity.png", fmt="cityscapes")
    (tmp_path / "bad.json").write_text('{"extrinsic": {}}')
    with pytest.raises(DepthError, match="not a Cityscapes camera file"):
        read_depth(tmp_path / "f_disparity.png", fmt="cityscapes", camera=tmp_path / "bad.json")
