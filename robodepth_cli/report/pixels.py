"""What each corruption does to the pixels of a build (``robodepth stats``): per variant, the
histogram, mean and spread of each channel against the clean images', and PSNR (the MSE
pooled over every image) and SSIM (scikit-image's defaults, :func:`ssim`) against the clean
image, as docs/report.md defines them. The build is streamed: one clean and one variant
image are held at a time and a variant keeps only its sums; an image the build did not make
is left out of its variant."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ..errors import RobodepthError

CHANNELS = ("R", "G", "B")
SCHEMA, SCHEMA_VERSION = "robodepth-stats", 1
PEAK = 255.0


@dataclass
class Sums:
    """What a variant accumulates: its histogram and its clean images' over the same
    images, the squared differences, the SSIMs."""

    histogram: np.ndarray = field(default_factory=lambda: np.zeros((3, 256), np.int64))
    clean: np.ndarray = field(default_factory=lambda: np.zeros((3, 256), np.int64))
    sse: float = 0.0
    values: int = 0
    ssim: float = 0.0
    images: int = 0

    def add(self, image: np.ndarray, clean: np.ndarray | None) -> None:
        """Add one image (``H x W x 3`` uint8) and, for a corrupted one, its clean image."""
        self.histogram += histogram(image)
        self.images += 1
        if clean is None:
            return
        self.clean += histogram(clean)
        diff = image.astype(np.float64) - clean.astype(np.float64)
        self.sse += float(np.sum(diff * diff))
        self.values += diff.size
        self.ssim += ssim(clean, image)


def histogram(image: np.ndarray) -> np.ndarray:
    """``3 x 256`` counts of each value per channel of an ``H x W x 3`` uint8 image."""
    return np.stack([np.bincount(image[..., c].ravel(), minlength=256) for c in range(3)])


def moments(hist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per channel, the mean and population standard deviation of the values a ``3 x 256``
    histogram counts."""
    v = np.arange(256, dtype=np.float64)
    n = hist.sum(axis=1).astype(np.float64)
    mean = (hist * v).sum(axis=1) / n
    var = (hist * (v - mean[:, None]) ** 2).sum(axis=1) / n
    return mean, np.sqrt(var)


WINDOW = 7  # SSIM's window, scikit-image's default
C1, C2 = (0.01 * PEAK) ** 2, (0.03 * PEAK) ** 2  # K1 = 0.01, K2 = 0.03


def ssim(clean: np.ndarray, image: np.ndarray) -> float:
    """The SSIM of two ``H x W x 3`` uint8 images as scikit-image's
    ``structural_similarity(..., channel_axis=2, data_range=255)`` computes it by default:
    per pixel, means over the 7 x 7 window around it and sample (co)variances (times
    49/48), ``(2 mx my + C1)(2 cxy + C2) / ((mx^2 + my^2 + C1)(vx + vy + C2))``, averaged
    over the pixels whose window lies inside the image and over the channels. OpenCV's box
    filter takes the window means (about 3x faster than scikit-image's filters, the same
    value to 1e-15); at least 7 x 7 pixels."""
    import cv2

    if min(clean.shape[:2]) < WINDOW:
        raise RobodepthError(f"an image of {clean.shape[1]}x{clean.shape[0]} is smaller than SSIM's "
                             f"{WINDOW}x{WINDOW} window")
    x, y = clean.astype(np.float64), image.astype(np.float64)

    def mean(a):
        return cv2.boxFilter(a, cv2.CV_64F, (WINDOW, WINDOW), normalize=True,
                             borderType=cv2.BORDER_REFLECT)

    mx, my = mean(x), mean(y)
    k = WINDOW * WINDOW / (WINDOW * WINDOW - 1)
    vx, vy, cxy = k * (mean(x * x) - mx * mx), k * (mean(y * y) - my * my), k * (mean(x * y) - mx * my)
    s = (2 * mx * my + C1) * (2 * cxy + C2) / ((mx * mx + my * my + C1) * (vx + vy + C2))
    r = WINDOW // 2  # the pixels whose window lies inside the image
    return float(s[r:-r, r:-r].mean())


def psnr(sse: float, values: int) -> float | None:
    """10 log10(255^2 / MSE) of ``sse`` over ``values`` squared differences; None for 0."""
    return None if sse == 0 else float(10 * np.log10(PEAK * PEAK * values / sse))


def chosen(n: int, most: int | None) -> list[int]:
    """The images used: all ``n``, or ``most`` of them evenly spaced over the split (the
    first and the last among them)."""
    if most is None or most >= n:
        return list(range(n))
    return sorted({int(round(x)) for x in np.linspace(0, n - 1, most)})


def collect(dataset, most: int | None = None,
            progress: Callable[[int], None] | None = None) -> tuple[Sums, list[tuple[object, Sums]]]:
    """The clean images' sums and each other variant's, over :func:`chosen` images, reading
    each image once (image by image, every variant of it in turn)."""
    from ..benchmark_facts import CLEAN

    try:
        clean_v = dataset.variant(CLEAN)
    except KeyError:
        raise RobodepthError(f"{dataset.path}: the build has no clean images to compare with") from None
    others = [v for v in dataset.variants() if v != clean_v]
    if not others:
        raise RobodepthError(f"{dataset.path}: the build has no corrupted variant")
    clean_sums, sums = Sums(), [(v, Sums()) for v in others]
    for i in chosen(len(dataset.keys), most):
        key = dataset.keys[i]
        if key in clean_v.missing:
            continue
        clean = clean_v.read(i)
        clean_sums.add(clean, None)
        for v, s in sums:
            if key in v.missing:
                continue
            image = v.read(i)
            if image.shape != clean.shape:
                raise RobodepthError(f"{dataset.path / v.relpath / key}: {image.shape[1]}x{image.shape[0]}, "
                                     f"its clean image {clean.shape[1]}x{clean.shape[0]}")
            s.add(image, clean)
        if progress:
            progress(1)
    return clean_sums, sums


def _numbers(a) -> list:
    return [None if not np.isfinite(x) else float(x) for x in a]


def to_json(dataset, clean: Sums, sums: Sequence[tuple[object, Sums]], most: int | None) -> dict:
    """The statistics as the versioned JSON ``robodepth stats`` writes (docs/report.md)."""
    mean, std = moments(clean.histogram)
    out = {"schema": SCHEMA, "schema_version": SCHEMA_VERSION, "dataset": dataset.name,
           "build": str(dataset.path), "images": clean.images, "of": len(dataset.keys),
           "sample": most, "channels": list(CHANNELS),
           "clean": {"histogram": clean.histogram.tolist(), "mean": _numbers(mean), "std": _numbers(std)},
           "variants": []}
    for v, s in sums:
        entry = {"corruption": v.name, "level": v.level, "images": s.images}
        if s.images:
            m, d = moments(s.histogram)
            cm, cd = moments(s.clean)
            entry.update({"histogram": s.histogram.tolist(), "mean": _numbers(m), "std": _numbers(d),
                          "mean_shift": _numbers(m - cm),
                          "std_ratio": [None if c == 0 else float(x / c) for x, c in zip(d, cd)],
                          "psnr": psnr(s.sse, s.values), "ssim": s.ssim / s.images})
        out["variants"].append(entry)
    return out


def check_level(levels, level) -> None:
    """Refuse a ``--level`` that no variant has, in a build whose variants have levels (a
    build of styles alone has none: the figure shows every style)."""
    present = {lv for lv in levels if lv is not None}
    if present and level not in present:
        raise RobodepthError(f"--level {level}: the build has no variant at that level (it has "
                             + ", ".join(str(lv) for lv in sorted(present)) + ")")


def figure(doc: dict, level):
    """The appendix figure: one panel per variant at ``level`` (every corrupted variant
    when none has levels: styles), each channel's histogram of the variant as a line
    (R vermillion, G bluish green, B blue: Okabe-Ito) over the clean images' (grey, all
    channels), in percent of the pixels; PSNR and SSIM under each title."""
    from matplotlib.ticker import MaxNLocator

    from . import plot

    check_level([v["level"] for v in doc["variants"]], level)
    shown = [v for v in doc["variants"] if v["images"] and v["level"] == level]
    if not shown:
        shown = [v for v in doc["variants"] if v["images"] and v["level"] is None]
    ncols = min(6, len(shown))
    # Each panel its own y scale: a quantised or noisy histogram is spikes that would
    # flatten every other panel.
    fig, axes = plot.panel_grid(len(shown), ncols, (2.05, 1.85), (0.5, 1.3), sharex=True)
    colours = (plot.OKABE_ITO[1], plot.OKABE_ITO[2], plot.OKABE_ITO[0])
    clean = np.asarray(doc["clean"]["histogram"], np.float64)
    clean = 100 * clean.sum(axis=0) / clean.sum()  # percent of the pixels
    x = np.arange(256)
    for k, v in enumerate(shown):
        ax = axes[k // ncols][k % ncols]
        ax.fill_between(x, clean, step="mid", color=plot.CONTEXT, alpha=0.45, linewidth=0,
                        label="clean (all channels)" if k == 0 else None)
        hist = np.asarray(v["histogram"], np.float64)
        top = float(clean.max())
        for c, colour in enumerate(colours):
            frac = 100 * hist[c] / hist[c].sum()
            top = max(top, float(np.percentile(frac, 95)))
            ax.plot(x, frac, color=colour, linewidth=0.9, label=CHANNELS[c] if k == 0 else None)
        quality = f"PSNR {v['psnr']:.1f} dB" if v["psnr"] is not None else "identical"
        ax.set_title(f"{plot.pretty(v['corruption'])}\n{quality}, SSIM {v['ssim']:.2f}", fontsize=8.5, pad=3)
        ax.set_ylim(0, top * 1.3)
        ax.yaxis.set_major_locator(MaxNLocator(4))
        ax.tick_params(labelsize=7)
        ax.grid(color="#ececec", linewidth=0.6)
        ax.set_axisbelow(True)
    axes[0][0].set_xlim(0, 255)
    axes[0][0].set_xticks([0, 128, 255])
    for row in axes:
        row[0].set_ylabel("% of pixels", fontsize=8)
    for k in range(len(shown) - ncols, len(shown)):
        if k >= 0:
            axes[k // ncols][k % ncols].set_xlabel("pixel value", fontsize=8)
            axes[k // ncols][k % ncols].xaxis.set_tick_params(labelbottom=True)
    what = f"level {level}" if shown[0]["level"] is not None else "each style"
    plot.figure_title(fig, f"Pixel values under each corruption: {plot.bench_title(doc['dataset'])}, {what}",
                      f"{doc['images']} of {doc['of']} images; lines: R, G, B of the corrupted "
                      "images; grey: the clean images; peaks above the axis are cut")
    plot.figure_legend(fig)
    return fig
