"""Reading, resizing and writing images.

A source becomes its clean image by converting it to RGB and resizing it with Pillow's
Lanczos filter, once; every variant starts from that uint8 image. Outputs are PNG files
written atomically."""

from __future__ import annotations

import os
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO

import numpy as np
from PIL import Image, UnidentifiedImageError
from .errors import InvalidValueError, RobodepthError, os_reason
from .files import write_atomic

MIN_SIDE = 32
MAX_SIDE = 8192  # an output side; larger ones need tens of GB per worker (fog's map alone is side^2)


class ImageError(RobodepthError):
    """An image that cannot be used; the message names the file and the problem."""


def as_rgb(img: np.ndarray, *, what: str = "image") -> np.ndarray:
    """Return ``img`` as a uint8 H x W x 3 RGB array.

    Grayscale (H x W or H x W x 1) is repeated over three channels, RGBA drops its alpha,
    16-bit integers are scaled to 8 bits. Anything else raises :class:`ImageError`.
    """
    if not isinstance(img, np.ndarray):
        raise ImageError(f"{what}: expected a numpy array, got {type(img).__name__}")
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    elif img.dtype == np.bool_:
        img = img.astype(np.uint8) * 255
    if img.dtype != np.uint8:
        raise ImageError(f"{what}: expected uint8 pixels, got {img.dtype}")
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    elif img.ndim == 3 and img.shape[2] == 4:
        img = img[..., :3]
    if img.ndim != 3 or img.shape[2] != 3:
        raise ImageError(f"{what}: expected H x W, H x W x 3 or H x W x 4 pixels, got shape {img.shape}")
    h, w = img.shape[:2]
    if h < MIN_SIDE or w < MIN_SIDE:
        raise ImageError(f"{what}: {h}x{w} pixels (HxW) is too small (at least {MIN_SIDE}x{MIN_SIDE})")
    return np.ascontiguousarray(img)


def _float_to_gray(im: Image.Image) -> Image.Image:
    """A float (mode F) image with values in [0, 1] as 8-bit gray: ``round(v * 255)``, the
    inverse of the usual ``uint8 / 255`` (so a uint8 image saved as floats comes back
    exactly). Any other range has no agreed meaning and is refused (:class:`ImageError`
    without the file name, which the caller adds)."""
    arr = np.asarray(im, dtype=np.float64)
    if not np.isfinite(arr).all():
        raise ImageError("float pixels include NaN or infinity; only floats in 0..1 are read")
    lo, hi = float(arr.min()), float(arr.max())
    if lo < 0.0 or hi > 1.0:
        raise ImageError(f"float pixels range over [{lo:g}, {hi:g}]; only floats in 0..1 are "
                         f"read (scaled to 0..255); convert the image to 8 bits")
    return Image.fromarray(np.rint(arr * 255.0).astype(np.uint8), "L")


def _pil_to_rgb(im: Image.Image) -> Image.Image:
    if im.mode in ("I;16", "I;16B", "I;16L", "I"):
        # 16-bit grayscale: keep the top 8 bits.
        arr = np.asarray(im, dtype=np.uint32) >> 8
        return Image.fromarray(np.clip(arr, 0, 255).astype(np.uint8), "L").convert("RGB")
    if im.mode == "F":
        # Pillow would clip the floats to 0..255 as they are: a 0..1 image comes out black.
        return _float_to_gray(im).convert("RGB")
    return im.convert("RGB")


def read_rgb(path: str | os.PathLike | BinaryIO, *, orient: bool = False) -> Image.Image:
    """Open an image file (or a binary file object: an export's image) fully decoded as an
    RGB Pillow image, or raise ``ImageError``.

    Grayscale, palette, RGBA and CMYK images are converted to RGB; 16-bit integer pixels
    keep their top 8 bits; float (mode F) pixels must lie in 0..1 and become
    ``round(v * 255)`` (other ranges are refused). With ``orient``, the EXIF orientation tag
    is applied first, so a phone photo comes out the way viewers show it (used for single
    images and custom builds; the benchmark sources carry no such tag and are read as stored).
    """
    path = path if hasattr(path, "read") else Path(path)
    try:
        with Image.open(path) as im:
            im.load()
            if orient:
                from PIL import ImageOps

                im = ImageOps.exif_transpose(im)
            rgb = _pil_to_rgb(im)
    except ImageError as exc:
        raise ImageError(f"{path}: {exc}") from None
    except FileNotFoundError:
        raise ImageError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise ImageError(f"{path}: is a directory, not an image") from None
    except UnidentifiedImageError:
        raise ImageError(f"{path}: not an image file Pillow can read") from None
    except (OSError, SyntaxError, ValueError, Image.DecompressionBombError) as exc:
        # A bomb is a header claiming an absurd size: corrupt or hostile, either way unusable.
        raise ImageError(f"{path}: unreadable image ({exc})") from None
    w, h = rgb.size
    if h < MIN_SIDE or w < MIN_SIDE:
        raise ImageError(f"{path}: {h}x{w} pixels (HxW) is too small (at least {MIN_SIDE}x{MIN_SIDE})")
    return rgb


EXIF_ORIENTATION = 0x0112  # the EXIF tag: 1 as stored; 2-8 mirrored and/or turned to display
TRANSPOSED = (5, 6, 7, 8)  # orientations that swap height and width


def exif_orientation(path: str | os.PathLike) -> int:
    """The EXIF orientation of the image at ``path`` from its header (1: display as stored,
    also when there is no tag, or the file cannot be read: reading it fails later, with the
    reason)."""
    try:
        with Image.open(path) as im:
            value = im.getexif().get(EXIF_ORIENTATION, 1)
    except Exception:  # noqa: BLE001 (any unreadable header: the image's own failure, later)
        return 1
    return value if isinstance(value, int) and 1 <= value <= 8 else 1


def stored_size(path: str | os.PathLike, orientation: int = 1) -> tuple[int, int] | None:
    """The (H, W) of an image from its header, as stored, or as shown when its EXIF
    ``orientation`` turns it (:data:`TRANSPOSED`); None if it cannot be read (the caller's
    reader says why)."""
    try:
        with Image.open(path) as im:
            return (im.width, im.height) if orientation in TRANSPOSED else (im.height, im.width)
    except Exception:  # anything unreadable fails where it is read, with the reason
        return None


def resize_lanczos(im: Image.Image, size_hw: tuple[int, int] | None) -> np.ndarray:
    """The clean image: RGB, resized to ``(H, W)`` with Pillow's Lanczos filter (unless it is
    already that size or ``size_hw`` is None), as a uint8 H x W x 3 array."""
    if size_hw is not None:
        h, w = size_hw
        if im.size != (w, h):
            im = im.resize((w, h), Image.LANCZOS)
    return np.asarray(im, dtype=np.uint8).copy()


def load_clean(path: str | os.PathLike, size_hw: tuple[int, int] | None, *,
               orient: bool = False) -> np.ndarray:
    """The clean image of ``path``: :func:`read_rgb` (``orient`` as there), then
    :func:`resize_lanczos` to ``size_hw``."""
    return resize_lanczos(read_rgb(path, orient=orient), size_hw)


# The two ways a build can write its PNGs (``--png``). Both give exactly the same pixels;
# only the bytes, and so the manifest's sha256 and the file sizes, differ.
PNG_METHODS = ("fast", "compact")
DEFAULT_PNG = "fast"
# What each writes, for the build record.
PNG_ENCODERS = {
    "fast": "fpng (one pass; gray: opencv-libpng filters=none,sub,up strategy=rle level 1)",
    "compact": "opencv-libpng filters=none,sub,up strategy=rle",
}


def check_png(method: str) -> None:
    """Refuse (:class:`RobodepthError`) before any work if ``method`` cannot run here."""
    if method == "fast":
        try:
            import fpng  # noqa: F401
        except ImportError as exc:
            raise RobodepthError(f"--png fast needs the fpng package ({exc}); install it with "
                                 f"'pip install fpng', or pass --png compact") from None


def encode_png(img: np.ndarray, compress_level: int = 1, *, method: str = "compact") -> bytes:
    """``img`` (uint8 H x W gray, H x W x 3 RGB or H x W x 4 RGBA) as PNG bytes that decode
    to exactly these pixels; the same pixels always give the same bytes.

    ``method="compact"``: OpenCV's libpng writer with zlib level ``compress_level`` (0-9),
    zlib's RLE strategy and libpng's fast row filters (None, Sub or Up, chosen per row): on
    the images a build writes (mostly noise and blur) this costs much less CPU than Pillow,
    which tries all five filters on every row, for slightly larger files.

    ``method="fast"``: fpng, a PNG writer made for speed (one pass, a simple LZ matcher): about 8x less CPU than the compact writer on a 192 x 640 build image, for
    files about 25% larger (bench/png.py measures both). fpng writes 24- and 32-bit images
    only, so a gray image is written by the compact writer (``compress_level`` is then
    used; fpng ignores it).
    """
    if img.dtype != np.uint8:
        raise ValueError(f"cannot encode {img.dtype} pixels as PNG (uint8 only)")
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (3, 4)):
        raise ValueError(f"cannot encode an image of shape {img.shape} as PNG")
    if method == "fast" and img.ndim == 3:
        import fpng

        return fpng.fpng_ext.encode_ndarray(np.ascontiguousarray(img))
    if method not in PNG_METHODS:
        raise ValueError(f"unknown PNG method {method!r}; valid: {', '.join(PNG_METHODS)}")
    return _encode_libpng(img, compress_level)


def _encode_libpng(img: np.ndarray, compress_level: int) -> bytes:
    import cv2

    if img.ndim == 3 and img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
    elif img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_RGBA2BGRA)
    ok, buf = cv2.imencode(".png", img, [cv2.IMWRITE_PNG_COMPRESSION, compress_level,
                                         cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_RLE,
                                         cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FAST_FILTERS])
    if not ok:
        raise ValueError(f"OpenCV could not encode an image of shape {img.shape} as PNG")
    return buf.tobytes()


def write_png(path: str | os.PathLike, img: np.ndarray, compress_level: int = 1, *,
              method: str = "compact") -> bytes:
    """Encode ``img`` as PNG (:func:`encode_png`) and write it atomically; return the bytes
    written."""
    data = encode_png(img, compress_level, method=method)
    write_atomic(path, data)
    return data


def parse_size(text: str) -> tuple[int, int]:
    """``"192x640"`` -> ``(192, 640)``; ``InvalidValueError`` with a readable message otherwise."""
    parts = text.lower().replace(" ", "").split("x")
    if len(parts) != 2 or not all(p.isdigit() for p in parts):
        raise InvalidValueError(f"size {text!r} is not of the form HxW, e.g. 192x640")
    h, w = int(parts[0]), int(parts[1])
    if h < MIN_SIDE or w < MIN_SIDE:
        raise InvalidValueError(f"size {text!r}: both sides must be at least {MIN_SIDE}")
    if h > MAX_SIDE or w > MAX_SIDE:
        raise InvalidValueError(f"size {text!r}: both sides must be at most {MAX_SIDE}")
    return h, w


# --- 16-bit single-channel PNGs: depth maps ----------------------------------------------
# The one reader of them (BTS's NYU sync_depth files, PNG predictions, a custom build's
# --depth PNGs): OpenCV's decoder, whatever reads them.

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@contextmanager
def _native_stderr_silenced():
    """File descriptor 2 sent to /dev/null: libpng prints ``libpng error: Read Error`` there
    for a truncated file before OpenCV returns None; the one-line error says it instead."""
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def read_depth_png(file: Path, what: str, error: type[RobodepthError], data: bytes | None = None) -> np.ndarray:
    """The ``H x W`` uint16 map of a 16-bit single-channel PNG ``file`` (or of its bytes
    ``data``, already read); every refusal is an ``error`` naming the file, ``what`` saying
    whose file it is (``ground truth of image 3``)."""
    import cv2

    file = Path(file)
    if data is None and not file.is_file():
        raise error(f"{file}: no such file ({what})")
    try:
        data = file.read_bytes() if data is None else data
    except OSError as exc:
        raise error(f"{file}: cannot read ({os_reason(exc)}) ({what})") from None
    raw = None
    if data[:8] == PNG_SIGNATURE:
        with _native_stderr_silenced():
            raw = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if raw is None:
        raise error(f"{file}: not a readable PNG, truncated or damaged ({what})")
    if raw.ndim != 2 or raw.dtype != np.uint16:
        got = f"{raw.dtype.itemsize * 8}-bit" + (f", {raw.shape[2]} channels" if raw.ndim == 3 else "")
        raise error(f"{file}: {got}; expected a 16-bit single-channel PNG ({what})")
    return raw
