"""Depth maps as datasets ship them, read into one form: float32 metres, NaN where invalid.

:func:`read_depth` is the one public reader (custom builds with ``--depth``, the zero-shot
presets, and anything else that needs "the depth of this image"). Forms, by extension
unless ``fmt`` names one:

``png``
    a 16-bit single-channel PNG holding ``depth x scale`` (``scale`` 256: KITTI's depth
    benchmark; 1000: millimetres, NYU and ScanNet; 100: centimetres, Virtual KITTI 2).
    ``scale`` is required: an integer file has no unit of its own.
``npy``
    a 2-D array, or H x W x 1 (DIODE); floats are metres, integers need ``scale`` as PNGs do.
``npz``
    an ``.npz`` holding one array, or several of which one is named ``depth``; then as npy.
``pfm``
    Portable Float Map: ``Pf`` (one channel), ``W H``, a scale whose sign is the byte order
    (negative: little-endian), then float32 rows from the bottom row up.
``exr``
    OpenEXR, one channel (or three equal ones), read with the ``OpenEXR`` package (the
    ``exr`` extra; imported only here).
``dpt``
    MPI Sintel: the float32 tag 202021.25, width and height as int32, then width x height
    float32 row by row from the top, all little-endian.
``raw``
    ETH3D: float32 little-endian values, row by row, no header; the size must be given
    (``shape``: the image's).
``cityscapes``
    Cityscapes' disparity: a 16-bit PNG whose pixel ``p > 0`` is the disparity
    ``(p - 1) / 256`` (``p = 0``: none), turned into depth ``baseline x fx / disparity``
    with ``extrinsic.baseline`` and ``intrinsic.fx`` of the frame's ``camera`` JSON file.

The scale rule, the same in every command: a scale is for integer maps (16-bit PNG, integer
``.npy``/``.npz``) and they need one; a float map holds metres, and a scale given with it is
refused rather than applied.

Invalid everywhere: 0, negative values, NaN and infinity (ETH3D marks its holes with
infinity, KITTI and the PNG forms with 0), and where ``mask`` (a second map of the same size:
``.npy``, ``.npz`` or ``.png``) is 0 or False (DIODE's ``*_depth_mask.npy``).
"""

from __future__ import annotations

import errno
import struct
import zipfile
from pathlib import Path

import numpy as np

# One DepthError for reading a map and for handing it to a corruption: catching the
# exported robodepth_cli.corruptions.DepthError catches both.
from ..corruptions.depth import DepthError
from ..errors import os_reason

FORMATS = ("png", "npy", "npz", "pfm", "exr", "dpt", "raw", "cityscapes")
EXTENSIONS = {".png": "png", ".npy": "npy", ".npz": "npz", ".pfm": "pfm", ".exr": "exr",
              ".dpt": "dpt"}
DPT_TAG = 202021.25
_MAX_SIDE = 1 << 16  # no depth map is wider or taller; a larger header is a damaged file




def depth_format(path: str | Path, fmt: str | None = None) -> str:
    """The form ``path`` is read as: ``fmt`` when given, else its extension's."""
    if fmt is not None:
        if fmt not in FORMATS:
            raise DepthError(f"{path}: unknown depth format {fmt!r}; valid: {', '.join(FORMATS)}")
        return fmt
    form = EXTENSIONS.get(Path(path).suffix.lower())
    if form is None:
        raise DepthError(f"{path}: unknown depth file extension; valid: "
                         f"{', '.join(EXTENSIONS)} (or name the format)")
    return form


def read_depth(path: str | Path, *, fmt: str | None = None, scale: float | None = None,
               mask: str | Path | None = None, shape: tuple[int, int] | None = None,
               camera: str | Path | None = None) -> np.ndarray:
    """The depth map at ``path`` in metres (float32, H x W), NaN where it is invalid (see the
    module docstring). ``scale``: the file holds ``depth x scale``; ``mask``: a file whose 0
    pixels are invalid; ``shape``: (H, W) of a ``raw`` file; ``camera``: the JSON file of a
    ``cityscapes`` disparity. Raises :class:`DepthError`."""
    path = Path(path)
    form = depth_format(path, fmt)
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise DepthError(f"{path}: depth scale {scale!r} must be a positive number")
    if form == "cityscapes":
        if camera is None:
            raise DepthError(f"{path}: a Cityscapes disparity needs its camera file")
        scale = _disparity_scale(Path(camera), path)
    try:
        values = _READERS[form](path, shape)
    except DepthError:
        raise
    except OSError as exc:
        raise DepthError(f"{path}: cannot read the depth map ({os_reason(exc)})") from None
    except (ValueError, EOFError, zipfile.BadZipFile, struct.error) as exc:
        raise DepthError(f"{path}: not a {form} depth map ({exc})") from None
    values = _two_d(values, path)
    if form != "cityscapes":
        check_scale(path, _kind(values.dtype, path), scale)
    depth = values.astype(np.float32)
    if form == "cityscapes":
        with np.errstate(divide="ignore"):  # p <= 1: no disparity, made NaN below
            depth = np.float32(scale) / ((depth - 1) / 256)
    elif scale is not None:
        depth /= np.float32(scale)
    with np.errstate(invalid="ignore"):
        depth[~(np.isfinite(depth) & (depth > 0))] = np.nan
    if mask is not None:
        keep = read_mask(mask)
        if keep.shape != depth.shape:
            raise DepthError(f"{mask}: mask of {keep.shape[0]} x {keep.shape[1]}, but its depth "
                             f"map {path} is {depth.shape[0]} x {depth.shape[1]}")
        depth[~keep] = np.nan
    return depth


INTEGER_NEEDS_SCALE = ("integer depth values need a scale, --depth-scale (the file holds depth x "
                      "scale: 256 for KITTI, 1000 for millimetres)")
FLOAT_HAS_NO_SCALE = ("float depth values are metres; a scale (--depth-scale) is for integer maps "
                      "(16-bit PNG, integer .npy), so it is refused rather than applied")


def check_scale(path: str | Path, kind: str, scale: float | None) -> None:
    """The scale rule (module docstring) for a map of ``kind`` (``integer`` or ``float``)."""
    if kind == "integer" and scale is None:
        raise DepthError(f"{path}: {INTEGER_NEEDS_SCALE}")
    if kind == "float" and scale is not None:
        raise DepthError(f"{path}: {FLOAT_HAS_NO_SCALE}")


def _kind(dtype: np.dtype, path: Path) -> str:
    if dtype.kind in "iub":
        return "integer"
    if dtype.kind == "f":
        return "float"
    raise DepthError(f"{path}: depth values of dtype {dtype}; expected numbers")


def value_kind(path: str | Path, fmt: str | None = None) -> str | None:
    """Whether the map at ``path`` holds ``integer`` or ``float`` values, read from its
    header where it has one (the check before a build's work); None when that cannot be
    told cheaply or the file is unreadable (its own reading then says why)."""
    path = Path(path)
    try:
        form = depth_format(path, fmt)
        if form in ("pfm", "exr", "dpt", "raw"):
            return "float"
        if form == "png":
            from PIL import Image

            with Image.open(path) as im:
                return "integer" if im.mode.startswith("I") else None
        if form == "npy":
            with open(path, "rb") as fh:
                version = np.lib.format.read_magic(fh)
                read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                        else np.lib.format.read_array_header_2_0)
                return _kind(read(fh)[2], path)
        if form == "npz":
            return _kind(_npz(path, None).dtype, path)
    except (DepthError, OSError, ValueError, EOFError, zipfile.BadZipFile):
        return None
    return None


def read_mask(path: str | Path) -> np.ndarray:
    """A validity mask (``.npy``, ``.npz`` or ``.png``) as booleans: True where nonzero."""
    path = Path(path)
    form = depth_format(path)
    if form not in ("npy", "npz", "png"):
        raise DepthError(f"{path}: a mask must be .npy, .npz or .png")
    try:
        values = _READERS[form](path, None)
    except OSError as exc:
        raise DepthError(f"{path}: cannot read the mask ({os_reason(exc)})") from None
    except (ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise DepthError(f"{path}: not a {form} mask ({exc})") from None
    values = _two_d(values, path)
    with np.errstate(invalid="ignore"):
        return np.nan_to_num(values.astype(np.float64), nan=0.0) != 0


def _two_d(values: np.ndarray, path: Path) -> np.ndarray:
    if values.ndim == 3 and values.shape[2] == 1:
        values = values[:, :, 0]
    if values.ndim != 2 or 0 in values.shape:
        raise DepthError(f"{path}: an array of shape {values.shape}; expected one H x W map")
    return values


def _png(path: Path, shape) -> np.ndarray:
    """A 16-bit depth PNG (:func:`robodepth_cli.imageio.read_depth_png`); a missing one
    raises FileNotFoundError, which the caller turns into a missing depth map."""
    from ..imageio import read_depth_png

    if not Path(path).exists():
        raise FileNotFoundError(errno.ENOENT, "No such file or directory", str(path))
    return read_depth_png(path, "depth map", DepthError).astype(np.int64)


NPY_MAGIC = b"\x93NUMPY"


def _npy(path: Path, shape) -> np.ndarray:
    with open(path, "rb") as fh:
        if fh.read(len(NPY_MAGIC)) != NPY_MAGIC:
            raise DepthError(f"{path}: not a depth array (not a .npy file: it does not start as "
                             "one)")
    try:
        return np.load(path, allow_pickle=False)
    except ValueError as exc:
        if "pickle" in str(exc):  # an array of Python objects: numpy would unpickle them
            raise DepthError(f"{path}: not a depth array (it holds Python objects)") from None
        raise


def _npz(path: Path, shape) -> np.ndarray:
    with np.load(path, allow_pickle=False) as z:
        names = list(z.files)
        name = names[0] if len(names) == 1 else "depth" if "depth" in names else None
        if name is None:
            raise DepthError(f"{path}: holds {', '.join(names) or 'nothing'}; expected one array, "
                             "or one named 'depth'")
        return z[name]


def _pfm(path: Path, shape) -> np.ndarray:
    with open(path, "rb") as fh:
        kind = fh.readline().strip()
        if kind != b"Pf":
            raise DepthError(f"{path}: PFM type {kind.decode('latin-1')!r}; a depth map is 'Pf' "
                             "(one channel)")
        dims = fh.readline().split()
        scale = float(fh.readline().strip())
        if len(dims) != 2:
            raise DepthError(f"{path}: PFM size line is not 'WIDTH HEIGHT'")
        w, h = int(dims[0]), int(dims[1])
        _check_side(path, w, h)
        data = np.frombuffer(fh.read(), dtype="<f4" if scale < 0 else ">f4")
    if data.size != w * h:
        raise DepthError(f"{path}: {data.size} values for a {w} x {h} PFM (truncated?)")
    return data.reshape(h, w)[::-1]


def _exr(path: Path, shape) -> np.ndarray:
    try:
        import OpenEXR
    except ImportError:
        raise DepthError(f"{path}: reading EXR needs the OpenEXR package (pip install "
                         "'robodepth-cli[exr]')") from None
    if not path.is_file():
        raise FileNotFoundError(2, "No such file or directory")
    try:
        with OpenEXR.File(str(path)) as f:
            channels = {n: np.asarray(c.pixels) for n, c in f.channels().items()}
    except DepthError:
        raise
    except Exception as exc:  # the binding raises its own types for a damaged file
        raise DepthError(f"{path}: not a readable EXR ({exc})") from None
    arrays = []
    for a in channels.values():  # an "RGB" entry is one H x W x 3 array
        arrays += [a[:, :, i] for i in range(a.shape[2])] if a.ndim == 3 else [a]
    if not arrays or any(not np.array_equal(arrays[0], a, equal_nan=True) for a in arrays[1:]):
        raise DepthError(f"{path}: EXR channels {', '.join(channels)}; a depth map has one "
                         "channel (or equal ones)")
    return arrays[0]


def _dpt(path: Path, shape) -> np.ndarray:
    with open(path, "rb") as fh:
        head = fh.read(12)
        if len(head) < 12:
            raise DepthError(f"{path}: shorter than a .dpt header")
        tag, w, h = struct.unpack("<fii", head)
        if tag != np.float32(DPT_TAG):
            raise DepthError(f"{path}: tag {tag!r} is not Sintel's {DPT_TAG} (wrong byte order "
                             "or not a .dpt file)")
        _check_side(path, w, h)
        data = np.frombuffer(fh.read(), dtype="<f4")
    if data.size != w * h:
        raise DepthError(f"{path}: {data.size} values for a {w} x {h} .dpt map")
    return data.reshape(h, w)


def _raw(path: Path, shape) -> np.ndarray:
    if shape is None:
        raise DepthError(f"{path}: a raw float32 map has no header; its size must be given")
    h, w = shape
    data = np.fromfile(path, dtype="<f4")
    if data.size != h * w:
        raise DepthError(f"{path}: {data.size} float32 values, but its image is {h} x {w} "
                         f"({h * w} values)")
    return data.reshape(h, w)


def _disparity_scale(camera: Path, path: Path) -> float:
    """``baseline x fx`` of a Cityscapes camera file (metres x pixels)."""
    import json

    try:
        data = json.loads(camera.read_text(encoding="utf-8"))
        value = float(data["extrinsic"]["baseline"]) * float(data["intrinsic"]["fx"])
    except OSError as exc:
        raise DepthError(f"{camera}: cannot read the camera file ({os_reason(exc)})") from None
    except (ValueError, KeyError, TypeError):
        raise DepthError(f"{camera}: not a Cityscapes camera file (extrinsic.baseline, "
                         f"intrinsic.fx) for {path}") from None
    if not (np.isfinite(value) and value > 0):
        raise DepthError(f"{camera}: baseline x fx is {value!r}; must be positive")
    return value


def _check_side(path: Path, w: int, h: int) -> None:
    if not (0 < w < _MAX_SIDE and 0 < h < _MAX_SIDE):
        raise DepthError(f"{path}: header says {w} x {h}; not a depth map's size")


_READERS = {"png": _png, "npy": _npy, "npz": _npz, "pfm": _pfm, "exr": _exr, "dpt": _dpt,
            "raw": _raw, "cityscapes": _png}
