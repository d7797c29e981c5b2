"""Large kernels by FFT: the blurs a severity size stretches over a large image (a 561-tap
motion streak, a glass blur sigma of 20) would take time in proportion to their taps when
applied directly; through the FFT of the border-padded image they take the same time at
any size of kernel."""

from __future__ import annotations

import cv2
import numpy as np
import scipy.fft


def correlate(img: np.ndarray, kernel: np.ndarray, anchor: tuple[int, int], border: int,
              dtype=np.float32) -> np.ndarray:
    """``out[y, x] = sum_ij kernel[i, j] * img[y + i - ay, x + j - ax]`` on every channel of
    ``img`` (H x W or H x W x C), samples outside the image taken by OpenCV ``border``
    (e.g. ``cv2.BORDER_REPLICATE``); ``anchor = (ay, ax)``. Computed by ``dtype`` FFT of the
    padded image; returns ``dtype`` of ``img``'s shape."""
    kh, kw = kernel.shape
    ay, ax = anchor
    h, w = img.shape[:2]
    src = np.ascontiguousarray(img, dtype=dtype)
    padded = cv2.copyMakeBorder(src, ay, kh - 1 - ay, ax, kw - 1 - ax, border)
    if padded.ndim == 2:
        padded = padded[:, :, None]
    shape = (scipy.fft.next_fast_len(padded.shape[0], real=True),
             scipy.fft.next_fast_len(padded.shape[1], real=True))
    spec = scipy.fft.rfft2(padded, s=shape, axes=(0, 1), workers=1)
    # Correlation is convolution with the flipped kernel; the wrap-around of the circular
    # convolution only reaches the first kh - 1 rows and kw - 1 columns, which are dropped.
    spec *= scipy.fft.rfft2(kernel[::-1, ::-1].astype(dtype), s=shape)[:, :, None]
    out = scipy.fft.irfft2(spec, s=shape, axes=(0, 1), workers=1)[kh - 1:kh - 1 + h, kw - 1:kw - 1 + w]
    return np.ascontiguousarray(out.reshape(img.shape) if img.ndim == 2 else out)


def taps_kernel(dys: np.ndarray, dxs: np.ndarray, weights: np.ndarray):
    """The kernel and anchor for :func:`correlate` of a sum of shifted copies,
    ``sum_t weights[t] * img[y - dys[t], x - dxs[t]]``."""
    ay, ax = int(dys.max()), int(dxs.max())
    kernel = np.zeros((ay - int(dys.min()) + 1, ax - int(dxs.min()) + 1), np.float64)
    np.add.at(kernel, (ay - dys, ax - dxs), weights)
    return kernel, (ay, ax)
