"""Tensor building blocks shared by the torch corruptions, each the exact counterpart of a
numpy-engine helper: the same float32/float64 operations in the same order, one operation
per torch call (so no fused multiply-add changes a rounding)."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch

TorchFn = Callable[[torch.Tensor, object, Sequence[np.random.Generator]], torch.Tensor]

_TORCH: dict[str, TorchFn] = {}


def register(fn: TorchFn) -> TorchFn:
    """Decorator: the torch version of the corruption of the same name."""
    if fn.__name__ in _TORCH:
        raise ValueError(f"{fn.__name__!r} registered twice in the torch engine")
    _TORCH[fn.__name__] = fn
    return fn


def implemented() -> dict[str, TorchFn]:
    return dict(_TORCH)


def tensor(arr: np.ndarray, device) -> torch.Tensor:
    """A copy of numpy ``arr`` (a table; often read-only) on ``device``."""
    return torch.from_numpy(np.array(arr)).to(device)


def f32(v) -> float:
    """``v`` rounded to float32, as a Python float: a scalar a float32 tensor uses as is."""
    return float(np.float32(v))


def fma(a: torch.Tensor, b, c: torch.Tensor) -> torch.Tensor:
    """float32 ``a * b + c`` rounded once, as a fused multiply-add (OpenCV's SIMD code uses
    them): the float32 product is exact in float64, so only the sum is rounded (twice, to
    float64 then float32, which differs from one rounding only on rare exact ties)."""
    b = b.to(torch.float64) if isinstance(b, torch.Tensor) else b
    return (a.to(torch.float64) * b + c.to(torch.float64)).to(torch.float32)


def truncate(v: torch.Tensor, scale: float = 255.0) -> torch.Tensor:
    """``uint8(floor(clip(v * scale, 0, 255)))`` (numpy engine: ``truncate_to_uint8``);
    ``scale`` is rounded to ``v``'s precision, as numpy does with a Python float."""
    out = v * scale
    return out.clamp_(0.0, 255.0).to(torch.uint8)


def drawn(rngs: Sequence[np.random.Generator], draw, device) -> torch.Tensor:
    """``draw(rng)`` for every image's generator, in batch order, stacked on ``device``."""
    return torch.from_numpy(np.stack([draw(rng) for rng in rngs])).to(device)


def hwc_order(u: torch.Tensor) -> torch.Tensor:
    """Per-element draws made in C order of an H x W x 3 image (N x H x W x 3) as N x 3 x H x W."""
    return u.permute(0, 3, 1, 2)


def sample_law(x: torch.Tensor, table, u: torch.Tensor) -> torch.Tensor:
    """:meth:`~.._sampling.ValueTable.sample` on tensors: element ``i`` of uint8 ``x`` is
    the first ``j`` with ``u[i] < cdf[x[i], j]`` (float64 comparisons, so the very same
    ``j``), ``u`` float64 shaped like ``x``.

    The numpy engine walks up from its guide entry, one step at a time; a whole tensor
    would wait for its slowest element (a tail value can be a hundred steps away), so here
    a binary search runs between the guide entries of the uniform's bucket and of the next
    one, which bracket the answer, in a fixed number of steps."""
    dev = x.device
    cdf = tensor(table.cdf, dev).reshape(-1)
    n_guide = table.guide.shape[1]
    # guide[k, b + 1] (255 past the last bucket) is the first j with cdf > (b + 1) / n >= u.
    upper = np.concatenate([table.guide[:, 1:], np.full((len(table.guide), 1), 255, np.uint8)], axis=1)
    guide = tensor(table.guide.astype(np.int64), dev).reshape(-1)
    upper = tensor(upper.astype(np.int64), dev).reshape(-1)
    k = x.to(torch.int64)
    bucket = k * n_guide + (u * n_guide).to(torch.int64)
    lo, hi = guide[bucket], upper[bucket]
    row = k * 256  # cdf rows are 256 wide
    for _ in range(9):  # 2**8 > 255: the bracket is a single j after 8 halvings
        mid = (lo + hi) >> 1
        above = u >= torch.take(cdf, row + mid)
        lo = torch.where(above, mid + 1, lo)
        hi = torch.where(above, hi, mid)
    return lo.to(torch.uint8)


def shift_blur(img: torch.Tensor, radius: int, sigma: float, angle: float) -> torch.Tensor:
    """The numpy engine's ``motion_blur.shift_blur`` of one image (``... x H x W``, any
    real dtype): float32 ``sum_t k_t * img[clamp(row - dy_t), clamp(col - dx_t)]``
    accumulated tap by tap. The clamped reads are slices of the image padded once by
    repeating its edges."""
    from ..motion_blur import motion_taps

    h, w = img.shape[-2:]
    dys, dxs, ks = motion_taps(radius, sigma, angle, (h, w))
    py, px = int(np.abs(dys).max(initial=0)), int(np.abs(dxs).max(initial=0))
    src = img.to(torch.float32)
    lead = src.shape[:-2]
    padded = torch.nn.functional.pad(src.reshape(1, -1, h, w), (px, px, py, py), mode="replicate")
    padded = padded.reshape(*lead, h + 2 * py, w + 2 * px)
    acc = torch.zeros_like(src)
    for dy, dx, k in zip(dys.tolist(), dxs.tolist(), ks.tolist()):
        acc += padded[..., py - dy:py - dy + h, px - dx:px - dx + w] * f32(k)
    return acc


def zoom_layer(img: torch.Tensor, r0, r1, wy, c0, wx) -> torch.Tensor:
    """One bilinear layer of the numpy engine's ``zoom_blur._accumulate``: rows blended
    ``a + wy * (b - a)``, then columns ``v + wx * (v' - v)`` with ``v'`` the column after
    ``v`` in the blended full-width row, zero past its end. ``img`` float32 ``... x H x W``."""
    dev = img.device
    r0, r1 = torch.from_numpy(r0).to(dev), torch.from_numpy(r1).to(dev)
    a = img.index_select(-2, r0)
    rows = a + torch.from_numpy(wy).to(dev)[:, None] * (img.index_select(-2, r1) - a)
    rows = torch.nn.functional.pad(rows, (0, 1))
    c0 = torch.from_numpy(c0).to(dev)
    v = rows.index_select(-1, c0)
    return v + torch.from_numpy(wx).to(dev) * (rows.index_select(-1, c0 + 1) - v)


def zoomed(img: torch.Tensor, z: float, *, crop: bool) -> torch.Tensor:
    """The numpy engine's ``clipped_zoom`` (``crop=True``: the centre crop zoomed, the whole
    layer) or ``linear_zoom`` (``crop=False``) of float32 ``... x H x W``."""
    from ..zoom_blur import linear_taps, zoom_axis

    h, w = img.shape[-2:]
    if crop:
        (top, ch, oh), (left, cw, ow) = zoom_axis(h, z), zoom_axis(w, z)
    else:
        (top, ch, oh), (left, cw, ow) = (0, h, round(h * z)), (0, w, round(w * z))
    r0, r1, wy = linear_taps(ch, oh, top, oh)
    c0, _, wx = linear_taps(cw, ow, left, ow)
    return zoom_layer(img, r0, r1, wy, c0, wx)
