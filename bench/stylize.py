"""Benchmark: KITTI-S stylisation, our batched engine against the straightforward way.

Both run in the same process on the same inputs: one 192 x 640 content image and 12
512 x 512 style images, random-weight AdaIN models in the published layout (the speed of a
convolution does not depend on its weights).

- straightforward: one (content, style) pair at a time, as the public AdaIN test script
  does it: encode the content, encode the style, AdaIN, decode; default (NCHW) tensors,
  torch's default threads (every core).
- ours (robodepth_cli.styles.adain.Stylizer): the 12 style statistics computed once (reported
  apart; a build does it once for its 8,364 images), the content encoded once for its 12
  styles, decoding batched over styles in chunks, channels-last tensors, inference mode.
  Timed for several chunk sizes, without channels-last, and as 1 process x 2 threads
  against 2 processes x 1 thread (the joblib pool a build would use).

Goal: <= 0.8 s per stylised image on this 2-core machine, >= 4x the
straightforward way. With a CUDA device, ours is also timed there (``--device cuda``: all
styles of a frame in one batch); without one the GPU line says "not measured".

    python -m bench.stylize [--repeats N] [--pairs N] [--contents N] [--chunks 1,2,4]
                            [--style-hw 512x512] [--no-processes]
"""

from __future__ import annotations

import argparse
import copy
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


import torch  # noqa: E402
from joblib import Parallel, delayed  # noqa: E402

from robodepth_cli.styles import adain  # noqa: E402
from robodepth_cli.sources.datasets import Job  # noqa: E402
from robodepth_cli.styles.inputs import STYLES, StyleRenderer  # noqa: E402

BUDGET_S = 0.8
MIN_SPEEDUP = 4.0


def smooth_image(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    from PIL import Image

    small = rng.integers(0, 256, (max(h // 16, 2), max(w // 16, 2), 3), dtype=np.uint8)
    noise = rng.integers(0, 24, (h, w, 3))
    base = np.asarray(Image.fromarray(small).resize((w, h), Image.BILINEAR), dtype=np.int64)
    return np.clip(base + noise, 0, 255).astype(np.uint8)


def straightforward(enc, dec, content: np.ndarray, style: np.ndarray) -> np.ndarray:
    """One pair, nothing reused: the baseline."""
    with torch.no_grad():
        c = torch.from_numpy(content).permute(2, 0, 1)[None].float() / 255
        s = torch.from_numpy(style).permute(2, 0, 1)[None].float() / 255
        fc, fs = enc(c), enc(s)
        ms, ss = adain.mean_std(fs)
        out = dec(adain.adain(fc, ms, ss))[:, :, :content.shape[0], :content.shape[1]]
        return adain.round_to_uint8(out)[0]


CPU_USE: list[float] = []  # cores busy in this process during each in-process timing


def timed(fn, *args):
    """(wall seconds, result, CPU seconds of this process's threads)."""
    t, c = time.perf_counter(), time.process_time()
    result = fn(*args)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    CPU_USE.append(cpu / wall)
    return wall, result, cpu


def _render_all(renderer: StyleRenderer, content: np.ndarray) -> int:
    jobs = [Job(s, None) for s in renderer.features]
    return sum(1 for _ in renderer.render(content, "bench", jobs))


def gpu_line(enc, dec, contents, feats, cpu_s: float, n_contents: int) -> None:
    """The same stylisation on the CUDA device, all styles of a frame in one batch, when
    there is one (after a warm-up that absorbs CUDA start-up); else says it was not
    measured."""
    if not torch.cuda.is_available():
        print("ours on a GPU (--device cuda): not measured (torch finds no CUDA device here)")
        return
    dev = adain.choose_device("cuda")
    st = adain.Stylizer(copy.deepcopy(enc), copy.deepcopy(dec), device=dev)
    st.stylize(contents[0], feats)
    torch.cuda.synchronize()
    best = float("inf")
    for _ in range(3):
        t = time.perf_counter()
        for c in contents[:n_contents]:
            st.stylize(c, feats)
        best = min(best, (time.perf_counter() - t) / (n_contents * len(feats)))
    print(f"ours on {adain.describe_device(dev)}, all {len(feats)} styles in one batch: "
          f"{best * 1000:.1f} ms/image, {cpu_s / best:.1f}x the CPU; full KITTI-S "
          f"(8,364 images): {best * 8364:.0f} s of stylising")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=2, help="straightforward pairs per round (default 2)")
    ap.add_argument("--repeats", type=int, default=2, help="rounds; each variant reports its best (default 2)")
    ap.add_argument("--contents", type=int, default=1,
                    help="content images per timing of ours, each with all 12 styles (default 1)")
    ap.add_argument("--chunks", default="1,2,4", help="chunk sizes to time (default 1,2,4)")
    ap.add_argument("--style-hw", default="512x512", help="style image size after resizing")
    ap.add_argument("--no-processes", action="store_true", help="skip the 2-process timing")
    args = ap.parse_args()
    sh, sw = (int(v) for v in args.style_hw.split("x"))
    chunks = [int(c) for c in args.chunks.split(",")]
    cores = os.cpu_count() or 1

    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    contents = [smooth_image(rng, 192, 640) for _ in range(max(args.contents, 2))]
    styles = [smooth_image(rng, sh, sw) for _ in STYLES]
    enc, dec = adain.encoder(), adain.decoder()
    load = os.getloadavg()
    print(f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}")
    print(f"torch {torch.__version__}, {cores} cores, torch threads {torch.get_num_threads()}; "
          f"content 192x640, {len(styles)} styles {sh}x{sw}, random weights")

    configs = [(True, c) for c in chunks] + [(False, adain.DEFAULT_CHUNK)]
    # Own copies of the modules: a Stylizer converts its modules' memory format in place.
    stylizers = {cfg: adain.Stylizer(copy.deepcopy(enc), copy.deepcopy(dec), chunk=cfg[1],
                                     channels_last=cfg[0]) for cfg in configs}
    # Warm-up: first calls pay for oneDNN primitive creation.
    straightforward(enc, dec, contents[0], styles[0])
    first = stylizers[configs[0]]
    t_feat, feats, _ = timed(lambda: [first.style_features(s) for s in styles])
    print(f"ours: style statistics, once per build: {t_feat:.2f} s for {len(styles)} styles")
    for st in stylizers.values():
        st.stylize(contents[0], feats[:st.chunk])

    pool = None
    if not args.no_processes and cores >= 2:
        tmp = tempfile.TemporaryDirectory()
        vgg, dcp = Path(tmp.name) / "vgg.pth", Path(tmp.name) / "dec.pth"
        torch.save(enc.state_dict(), vgg)
        torch.save(dec.state_dict(), dcp)
        renderer = StyleRenderer(str(vgg), str(dcp), 1.0, 1, dict(zip(STYLES, feats)))
        warm = StyleRenderer(str(vgg), str(dcp), 1.0, 1, {STYLES[0]: feats[0]})
        pool = Parallel(n_jobs=2)
        pool.__enter__()
        pool(delayed(_render_all)(warm, contents[i % 2]) for i in range(4))

    # Rounds alternate between the variants, and each reports its best round: other
    # processes on the machine then slow every variant alike instead of whichever ran last.
    naive_t: list[tuple[float, float]] = []  # (wall, cpu) per image
    ours_t: dict = {cfg: [] for cfg in configs}
    procs_t: list[float] = []
    for r in range(args.repeats):
        for i in range(args.pairs):
            t, _, cpu = timed(straightforward, enc, dec, contents[0],
                              styles[(r * args.pairs + i) % len(styles)])
            naive_t.append((t, cpu))
        for cfg, st in stylizers.items():
            t, _, cpu = timed(lambda: [st.stylize(c, feats) for c in contents[:args.contents]])
            n_img = args.contents * len(styles)
            ours_t[cfg].append((t / n_img, cpu / n_img))
        if pool is not None:
            n = 2 * args.contents
            t0 = time.perf_counter()
            counts = pool(delayed(_render_all)(renderer, contents[i % 2]) for i in range(n))
            procs_t.append((time.perf_counter() - t0) / sum(counts))
    if pool is not None:
        pool.__exit__(None, None, None)
        tmp.cleanup()

    naive, naive_cpu = min(naive_t)
    print(f"straightforward (one pair at a time): {naive:.3f} s/image, CPU {naive_cpu:.3f} s/image "
          f"(best of {len(naive_t)} pairs)")
    results, cpus = {}, {}
    for cfg, ts in ours_t.items():
        results[cfg], cpus[cfg] = min(ts)
        print(f"ours, 1 process x {torch.get_num_threads()} threads, chunk {cfg[1]}, "
              f"{'channels-last' if cfg[0] else 'NCHW'}: {results[cfg]:.3f} s/image, "
              f"CPU {cpus[cfg]:.3f} s/image")
    procs = min(procs_t) if procs_t else None
    if procs is not None:
        print(f"ours, 2 processes x 1 thread, chunk {adain.DEFAULT_CHUNK}, channels-last: "
              f"{procs:.3f} s/image ({2 * args.contents} contents x {len(styles)} styles)")
    best_cl, best_chunk = min(results, key=results.get)
    best = results[(best_cl, best_chunk)]

    print()
    print(f"best in-process: chunk {best_chunk}, {'channels-last' if best_cl else 'NCHW'}: "
          f"{best:.3f} s/image, {naive / best:.1f}x the straightforward way "
          f"(CPU time: {naive_cpu / cpus[(best_cl, best_chunk)]:.1f}x)")
    if procs is not None:
        print(f"2 processes x 1 thread: {procs:.3f} s/image, {naive / procs:.1f}x; "
              f"{'processes' if procs < best else 'threads'} faster by {max(best, procs) / min(best, procs):.2f}x")
    gpu_line(enc, dec, contents, feats, results[(best_cl, best_chunk)], args.contents)
    use = min(CPU_USE)
    print(f"cores used by this process while timed: {use:.2f} to {max(CPU_USE):.2f} of {cores}"
          + (" -- other processes competed for the CPU; numbers are pessimistic" if use < 0.8 * cores else ""))
    overall = min(best, procs or best)
    ok = overall <= BUDGET_S and naive / overall >= MIN_SPEEDUP
    print(f"goal <= {BUDGET_S} s/image and >= {MIN_SPEEDUP:.0f}x: {'met' if ok else 'NOT met'} "
          f"({overall:.3f} s/image, {naive / overall:.1f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
