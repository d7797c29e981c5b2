"""NYU Depth V2 test frames and ground truth straight from the official labeled file, a
MATLAB v7.3 (HDF5) file read with h5py one frame at a time; its datasets are stored
transposed (``images[i].T`` is the 480 x 640 x 3 RGB image, ``rawDepths[i].T`` the depth in
metres). Frame ``i`` is the split's ``rgb_{i:05d}``: its clean source is exactly the JPEG
BTS's extraction script writes (:func:`bts_jpeg`, :func:`decode_jpeg`), its ground truth
BTS's ``sync_depth_{i:05d}.png`` (:func:`sync_depth`)."""

from __future__ import annotations

import io
import re
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Callable, Sequence

import numpy as np

from ..errors import RobodepthError, cannot_write, os_reason
from ..files import write_atomic

HEIGHT, WIDTH = 480, 640
# BTS keeps rows 7..473 and columns 7..631 and blacks out the rest (the Kinect
# registration's invalid border).
ROWS, COLS = slice(7, 474), slice(7, 632)
DEPTH_SCALE = np.float32(1000.0)  # sync_depth PNGs hold millimetres
KEYS = ("images", "rawDepths", "sceneTypes")
_RGB_NAME = re.compile(r"rgb_(\d+)(?:\.[A-Za-z]+)?")


class NyuError(RobodepthError):
    """A labeled file, split line or depth file that cannot be used; the message names it."""


@dataclass(frozen=True)
class NyuFrame:
    """One line of a NYU-format split (``RGB DEPTH FOCAL``)."""

    line: int  # 1-based line number in the split file
    rgb: str  # as listed, e.g. bathroom/rgb_00045.jpg
    depth: str  # as listed, e.g. bathroom/sync_depth_00045.png

    @property
    def scene(self) -> str:
        """The scene folder of the RGB path ("" if it has none)."""
        return PurePosixPath(self.rgb).parent.name

    @property
    def index(self) -> int | None:
        """The frame index in the labeled file: the number of ``rgb_NNNNN.<ext>``."""
        m = _RGB_NAME.fullmatch(PurePosixPath(self.rgb).name)
        return int(m.group(1)) if m else None

    @property
    def jpeg(self) -> str:
        """Where BTS's layout keeps this frame's JPEG: the listed RGB path, ``.jpg`` unless it
        already ends in ``.jpg`` or ``.jpeg``."""
        p = PurePosixPath(self.rgb)
        return self.rgb if p.suffix.lower() in (".jpg", ".jpeg") else str(p.with_suffix(".jpg"))


def read_frames(split: Path) -> list[NyuFrame]:
    """The frames of a NYU-format split file, with the checks every split gets
    (:func:`robodepth_cli.sources.datasets.read_split`)."""
    from ..sources.datasets import read_split

    return [NyuFrame(e.line, e.fields[0], e.fields[1]) for e in read_split(split, "nyu")]


def is_labeled_file(root: Path) -> bool:
    """Whether ``root`` names a file (the labeled ``.mat``) rather than a BTS test folder."""
    return Path(root).is_file()


class LabeledFile:
    """``nyu_depth_v2_labeled.mat`` opened for reading one frame at a time.

    Raises :class:`NyuError` for a file that is not HDF5, lacks one of ``images``,
    ``rawDepths`` and ``sceneTypes``, or whose datasets do not have the layout above.
    """

    def __init__(self, path: Path):
        import h5py

        self.path = Path(path)
        try:
            hdf5 = h5py.is_hdf5(self.path)
        except OSError as exc:
            raise NyuError(f"{self.path}: cannot read ({os_reason(exc)})") from None
        if not hdf5:
            if not self.path.exists():
                raise NyuError(f"{self.path}: no such file")
            raise NyuError(f"{self.path}: not an HDF5 file (the official nyu_depth_v2_labeled.mat is "
                           f"MATLAB v7.3, which is HDF5)")
        try:
            self._file = h5py.File(self.path, "r")
        except OSError as exc:
            raise NyuError(f"{self.path}: cannot open as HDF5 ({exc})") from None
        try:
            self._check(h5py)
        except BaseException:
            self._file.close()
            raise

    def _check(self, h5py) -> None:
        f = self._file
        for key in KEYS:
            if key not in f or not isinstance(f[key], h5py.Dataset):
                raise NyuError(f"{self.path}: no {key!r} dataset; is this nyu_depth_v2_labeled.mat?")
        images, depths, scenes = (f[k] for k in KEYS)
        n = images.shape[0] if images.ndim else 0
        expect = {"images": ((n, 3, WIDTH, HEIGHT), np.uint8, images),
                  "rawDepths": ((n, WIDTH, HEIGHT), np.float32, depths)}
        for key, (shape, dtype, ds) in expect.items():
            if ds.shape != shape or ds.dtype != dtype:
                raise NyuError(f"{self.path}: {key!r} is {' x '.join(map(str, ds.shape))} {ds.dtype}, expected "
                               f"{' x '.join(map(str, shape))} {np.dtype(dtype)}")
        if h5py.check_dtype(ref=scenes.dtype) is None or scenes.ndim != 2 or scenes.shape[0] != 1 \
                or scenes.shape[1] != n:
            raise NyuError(f"{self.path}: 'sceneTypes' is {' x '.join(map(str, scenes.shape))} {scenes.dtype}, "
                           f"expected 1 x {n} object references")
        self.n = n
        self._images, self._depths = images, depths
        self._scene_refs = scenes[0]

    def close(self) -> None:
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def scene(self, i: int) -> str:
        """The scene name of frame ``i`` (``sceneTypes[0][i]`` decoded)."""
        try:
            codes = self._file[self._scene_refs[i]][()]
        except (ValueError, KeyError, TypeError) as exc:
            raise NyuError(f"{self.path}: 'sceneTypes' entry {i} is not a valid reference ({exc})") from None
        return "".join(chr(int(c)) for c in np.ravel(codes))

    def rgb(self, i: int) -> np.ndarray:
        """Frame ``i``'s image, 480 x 640 x 3 RGB uint8."""
        return np.ascontiguousarray(self._read("images", self._images, i).T)

    def depth(self, i: int) -> np.ndarray:
        """Frame ``i``'s raw depth in metres, 480 x 640 float32."""
        return np.ascontiguousarray(self._read("rawDepths", self._depths, i).T)

    def _read(self, key: str, dataset, i: int) -> np.ndarray:
        try:
            return dataset[i]
        except (OSError, ValueError, KeyError) as exc:  # a damaged or truncated file
            raise NyuError(f"{self.path}: cannot read {key}[{i}] ({exc})") from None


def bts_jpeg(rgb: np.ndarray) -> bytes:
    """The bytes BTS writes as ``rgb_NNNNN.jpg`` for the RGB image ``rgb`` (480 x 640 x 3):
    everything outside rows 7..473 and columns 7..631 set to 0, then encoded by OpenCV at
    its default JPEG quality (95, 4:2:0), as ``cv2.imwrite`` does."""
    import cv2

    boxed = np.zeros((HEIGHT, WIDTH, 3), dtype=np.uint8)
    boxed[ROWS, COLS] = rgb[ROWS, COLS, ::-1]  # OpenCV takes BGR
    ok, buf = cv2.imencode(".jpg", boxed)
    if not ok:  # pragma: no cover - a 480 x 640 uint8 image always encodes
        raise NyuError("OpenCV could not encode a JPEG")
    return buf.tobytes()


def decode_jpeg(data: bytes) -> np.ndarray:
    """JPEG bytes decoded to RGB uint8 the way every source image is read (Pillow)."""
    from PIL import Image

    with Image.open(io.BytesIO(data)) as im:
        return np.asarray(im.convert("RGB"), dtype=np.uint8).copy()


def sync_depth(depth: np.ndarray) -> np.ndarray:
    """BTS's ``sync_depth`` pixels: ``depth * 1000`` computed in float32 (as the float32
    ``rawDepths`` times 1000.0 is in numpy), then truncated to uint16."""
    return (np.asarray(depth, dtype=np.float32) * DEPTH_SCALE).astype(np.uint16)


def encode_depth_png(depth_mm: np.ndarray) -> bytes:
    """A uint16 H x W depth map as a 16-bit grayscale PNG."""
    import cv2

    ok, buf = cv2.imencode(".png", depth_mm)
    if not ok:  # pragma: no cover
        raise NyuError("OpenCV could not encode a 16-bit PNG")
    return buf.tobytes()


def sync_depth_file(path: Path) -> tuple[bytes, tuple[int, int]]:
    """The bytes of a BTS ``sync_depth`` file, checked to be a single-channel 16-bit PNG
    (:func:`robodepth_cli.imageio.read_depth_png`), and its size (H, W)."""
    from ..imageio import read_depth_png

    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise NyuError(f"{path}: no such file (depth)") from None
    except OSError as exc:
        raise NyuError(f"{path}: cannot read ({os_reason(exc)}) (depth)") from None
    return data, read_depth_png(path, "depth", NyuError, data).shape


def frame_index(labeled: LabeledFile, rgb: str) -> int:
    """The index in ``labeled`` of the split's RGB path ``rgb`` (``SCENE/rgb_NNNNN.<ext>``):
    ``NNNNN``, checked to be within the file and a frame of scene ``SCENE``. Raises
    :class:`NyuError` (the message starts with ``rgb``) otherwise."""
    frame = NyuFrame(0, rgb, "")
    i = frame.index
    if i is None:
        raise NyuError(f"{rgb}: not named rgb_NNNNN.<ext>, so no frame of {labeled.path.name} can be "
                       f"found for it")
    if i >= labeled.n:
        raise NyuError(f"{rgb}: frame {i} is beyond {labeled.path}, which has {labeled.n} frames")
    if not frame.scene:
        raise NyuError(f"{rgb}: no scene folder (expected SCENE/rgb_NNNNN.jpg)")
    scene = labeled.scene(i)
    if scene != frame.scene:
        raise NyuError(f"{rgb}: frame {i} of {labeled.path} is a {scene!r} scene, not {frame.scene!r}")
    return i


def check_frames(labeled: LabeledFile, frames: Sequence[NyuFrame], split_name: str) -> None:
    """Every frame names a frame of ``labeled`` (:func:`frame_index`); :class:`NyuError`
    naming the first split line that does not."""
    for f in frames:
        try:
            frame_index(labeled, f.rgb)
        except NyuError as exc:
            raise NyuError(f"{split_name}:{f.line}: {exc}") from None


def source_name(path: Path, index: int) -> str:
    """How a build's manifest names frame ``index`` of the labeled file at ``path``."""
    return f"{Path(path).name}#{index}"


_opened: dict[str, LabeledFile] = {}


def opened(path: str | Path) -> LabeledFile:
    """The labeled file at ``path``, opened once per process (build workers read many frames)."""
    key = str(path)
    if key not in _opened:
        _opened[key] = LabeledFile(path)
    return _opened[key]


def source_image(path: str | Path, index: int):
    """The clean source of frame ``index`` of the labeled file at ``path`` as a Pillow RGB
    image: BTS's JPEG of it (:func:`bts_jpeg`), decoded as a JPEG file is."""
    from PIL import Image

    data = bts_jpeg(opened(path).rgb(index))
    with Image.open(io.BytesIO(data)) as im:
        return im.convert("RGB")


def export(root: Path, frames: Sequence[NyuFrame], out: Path, *, split_name: str = "split",
           rgb: bool = True, progress: Callable[[int], object] | None = None) -> list[tuple[str, str]]:
    """Write BTS's test layout for ``frames`` under ``out``: ``<depth path>`` as listed in
    the split (e.g. ``bathroom/sync_depth_00045.png``) and, from a labeled file with
    ``rgb=True``, the JPEG at :attr:`NyuFrame.jpeg`.

    ``root`` is the labeled ``.mat`` file (frames read from it) or a BTS test folder (its
    ``sync_depth`` files are copied after a check). Every frame is checked before the first
    file is written; the files go into a temporary folder that becomes ``out`` at the end
    (``out`` must not exist, or be empty), so an interrupted export leaves nothing. Returns ``(relative path, sha256)``
    of every depth file written, in split order.
    """
    from ..files import atomic_directory

    try:
        with atomic_directory(out) as tmp:  # OUT appears whole, or not at all
            return _export(root, frames, tmp, split_name, rgb, progress)
    except OSError as exc:  # reads raise NyuError: this is a write into OUT (a full disk, ...)
        raise NyuError(cannot_write(out, exc)) from None


def _export(root, frames, out, split_name, rgb, progress):
    from ..files import sha256_bytes

    written = []
    if is_labeled_file(root):
        with LabeledFile(root) as labeled:
            check_frames(labeled, frames, split_name)
            for f in frames:
                i = f.index
                if rgb:
                    write_atomic(out / f.jpeg, bts_jpeg(labeled.rgb(i)))
                data = encode_depth_png(sync_depth(labeled.depth(i)))
                write_atomic(out / f.depth, data)
                written.append((f.depth, sha256_bytes(data)))
                if progress:
                    progress(1)
        return written
    root = Path(root)
    for f in frames:  # all of them checked (and decoded) before anything is written
        try:
            sync_depth_file(root / f.depth)
        except NyuError as exc:
            raise NyuError(f"{split_name}:{f.line}: {exc}") from None
    for f in frames:
        data, _ = sync_depth_file(root / f.depth)
        write_atomic(out / f.depth, data)
        written.append((f.depth, sha256_bytes(data)))
        if progress:
            progress(1)
    return written
