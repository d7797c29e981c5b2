"""Ctrl-C or SIGTERM landing while a compiled (numba) kernel runs stops the build; it is
never recorded as the image's failure (issue 42).

A KeyboardInterrupt raised by the signal handler as such a kernel returns reaches its
caller as ``SystemError: CPUDispatcher(...) returned a result with an exception set``: an
Exception, which the renderer's per-job handler used to yield as a failed output (and the
build went on).

Each compiled kernel that each corruption calls from Python is wrapped so that an interval
timer, armed just before the real kernel starts, delivers a signal whose handler raises
KeyboardInterrupt, as Ctrl-C's does (the OS delivers it at the set time; a thread sending
it would first have to get the GIL). It landed inside the kernel when the failure carries
that SystemError; landed elsewhere (before the kernel, or after it when the timer is
stopped), the try is made again with another delay.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import signal
import sys
import time

import numpy as np
import pytest
from numba.core.registry import CPUDispatcher


SIZE = (192, 640)  # KITTI-C's
TRIES = 40


def _kernels() -> dict[tuple[str, str], CPUDispatcher]:
    """(module, name) -> every compiled kernel defined at the top of a corruption module."""
    import robodepth_cli.corruptions as package

    found = {}
    for info in pkgutil.iter_modules(package.__path__):
        module = importlib.import_module(f"{package.__name__}.{info.name}")
        for name, value in vars(module).items():
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == module.__name__:
                found[(module.__name__, name)] = value
    return found


class _Depth:
    """A depth source (the renderer's interface): a ramp from 1 to 80 m."""

    fingerprint = "depth=test"

    def depth(self, key, shape):
        h, w = shape
        return np.linspace(80.0, 1.0, h * w).reshape(h, w)

    def stamp(self, key):
        return "test"


def _render(name: str, image) -> list:
    from robodepth_cli.building.renderers import CorruptionRenderer
    from robodepth_cli.sources.datasets import Job

    return list(CorruptionRenderer("custom", 0, _Depth()).render(image, "a", [Job(name, 3)]))


def _image(size=SIZE):
    return np.random.default_rng(1).integers(0, 256, (*size, 3), dtype=np.uint8)


class _Patched:
    """Module attributes replaced for the ``with`` block: {(module, name): value}."""

    def __init__(self, patches):
        self.patches = patches
        self.saved = {}

    def __enter__(self):
        for (module, name), value in self.patches.items():
            self.saved[(module, name)] = getattr(sys.modules[module], name)
            setattr(sys.modules[module], name, value)

    def __exit__(self, *exc):
        for (module, name), value in self.saved.items():
            setattr(sys.modules[module], name, value)


@pytest.fixture(scope="module")
def longest_calls():
    """kernel (module, name) -> (corruption, call number, seconds) of its longest call from
    Python in a render of every corruption; kernels called only by other kernels are
    absent (they run inside those)."""
    from robodepth_cli.corruptions import REGISTRY

    for corruption in REGISTRY:  # compiled (or loaded) with their real globals first
        _render(corruption, _image())
    longest: dict[tuple, tuple] = {}
    counts: dict[tuple, int] = {}
    current: list[str] = []
    patches = {}
    for where, real in _kernels().items():
        def timed(*args, _where=where, _real=real, **kwargs):
            counts[_where] = counts.get(_where, 0) + 1
            start = time.perf_counter()
            try:
                return _real(*args, **kwargs)
            finally:
                took = time.perf_counter() - start
                if took > longest.get(_where, ("", 0, -1.0))[2]:
                    longest[_where] = (current[0], counts[_where], took)
        patches[where] = timed
    with _Patched(patches):
        for corruption in REGISTRY:
            current[:] = [corruption]
            counts.clear()
            ((_, out),) = _render(corruption, _image())
            assert isinstance(out, np.ndarray), (corruption, out)
    return longest


def _armed(real, nth: int, delay: float, state: dict):
    """``real`` wrapped: its ``nth`` call starts the timer (``delay`` seconds) just before
    it starts the kernel, and stops it once the kernel has returned; ``state["inside"]``
    says whether the timer had gone off by then (the signal came during the call)."""
    calls = [0]

    def wrapped(*args, **kwargs):
        calls[0] += 1
        if calls[0] != nth:
            return real(*args, **kwargs)
        signal.setitimer(signal.ITIMER_REAL, delay)
        try:
            return real(*args, **kwargs)
        finally:
            state["inside"] = signal.getitimer(signal.ITIMER_REAL)[0] == 0.0
            signal.setitimer(signal.ITIMER_REAL, 0)

    return wrapped


@pytest.fixture
def alarm_interrupts():
    previous = signal.signal(signal.SIGALRM, signal.default_int_handler)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _delays(took: float) -> list[float]:
    """Delays to try in turn: a third of the kernel's time, then less (a busy machine can
    stretch the moments before the kernel starts)."""
    return [max(took * f, 1e-6) for f in (0.33, 0.2, 0.1, 0.05)] * (TRIES // 4)


@pytest.mark.parametrize("kernel", [f"{m.rsplit('.', 1)[1]}.{n}" for m, n in _kernels()])
def test_a_signal_inside_each_kernel_stops_the_render(longest_calls, alarm_interrupts, kernel):
    where = (f"robodepth_cli.corruptions.{kernel.split('.')[0]}", kernel.split(".")[1])
    if where not in longest_calls:
        pytest.skip(f"{kernel} is not called from Python during a render (kernels call it, or it runs once)")
    corruption, nth, took = longest_calls[where]
    image = _image()
    for delay in _delays(took):
        state = {"inside": False}
        with _Patched({where: _armed(getattr(sys.modules[where[0]], where[1]), nth, delay, state)}):
            try:
                results = _render(corruption, image)
            except KeyboardInterrupt:
                results = None
        if state["inside"]:
            break  # else the kernel had returned before the timer went off: again
    else:
        pytest.fail(f"{corruption}: {kernel} ({took * 1e6:.0f} us): no signal landed inside it "
                    f"in {TRIES} tries")
    assert results is None, f"{corruption}: {kernel}: the interrupt did not stop it: {results}"


def test_most_kernels_are_reached_from_python(longest_calls):
    # Those not called from Python during a render are few: the loop above covers the rest.
    assert len(longest_calls) >= len(_kernels()) * 2 // 3, sorted(longest_calls)


def test_is_interrupt_follows_the_chain_and_the_pending_note():
    from robodepth_cli.errors import is_interrupt, note_interrupt

    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as inner:
            raise SystemError("returned a result with an exception set") from inner
    except SystemError as exc:
        assert is_interrupt(exc)
    assert not is_interrupt(ValueError("a broken image"))
    note_interrupt()
    try:
        assert is_interrupt(ValueError("whatever became of the KeyboardInterrupt"))
    finally:
        note_interrupt(False)
    assert not is_interrupt(ValueError("a broken image"))


IN_KERNEL = """
import os, signal, sys, threading
sys.argv = ["robodepth", *sys.argv[1:]]
# A shell that starts the suite in the background leaves SIGINT ignored in its children.
signal.signal(signal.SIGINT, signal.default_int_handler)
from robodepth_cli.corruptions import brightness
from robodepth_cli.cli import main
real = brightness._brighten
calls = []

def sigint_inside(*args):
    # The second image's: the first one's outputs are recorded before the signal. The
    # thread gets the GIL once the nogil kernel has released it.
    calls.append(1)
    if len(calls) == 2:
        sys.stderr.write("SIGNAL\\n")
        threading.Timer(0.002, os.kill, (os.getpid(), signal.SIGINT)).start()
    return real(*args)

brightness._brighten = sigint_inside
main()
"""


def _three_images(tmp_path, shape) -> tuple:
    """(root holding a.png, b.png, c.png of random pixels, the OUT to build, the
    environment with the checkout first on the path)."""
    import cv2

    from tests.helpers.paths import REPO

    root = tmp_path / "images"
    root.mkdir()
    rng = np.random.default_rng(0)
    for name in ("a", "b", "c"):
        cv2.imwrite(str(root / f"{name}.png"), rng.integers(0, 256, (*shape, 3), np.uint8))
    return root, tmp_path / "OUT", {**os.environ, "PYTHONPATH": str(REPO)}


def _build_args(root, out) -> list:
    return ["build", "custom", "--root", root, "--out", out, "--corruptions", "brightness",
            "--levels", "3", "-j", "1", "--no-progress"]


@pytest.mark.slow
def test_a_build_interrupted_inside_a_kernel_stops_and_records_no_failure(tmp_path):
    import subprocess

    root, out, env = _three_images(tmp_path, (960, 3200))
    proc = subprocess.run([sys.executable, "-c", IN_KERNEL, *_build_args(root, out)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert "SIGNAL" in proc.stderr, proc.stderr
    assert proc.returncode == 130, proc.stderr
    assert "SystemError" not in proc.stderr and " 0 failed of " in proc.stderr, proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("robodepth: interrupted;"), proc.stderr
    manifest = (out / "manifest.csv").read_text() if (out / "manifest.csv").exists() else ""
    assert "SystemError" not in manifest and "exception set" not in manifest, manifest
    assert not (out / "brightness/3/c.png").exists()


LONG_KERNEL = """
import signal, sys
sys.argv = ["robodepth", *sys.argv[1:]]
signal.signal(signal.SIGINT, signal.default_int_handler)
import numba
from robodepth_cli.corruptions import brightness
from robodepth_cli.cli import main

@numba.njit(nogil=True)
def spin(n):  # a compiled kernel that runs for many seconds without the GIL
    x = 0.0
    for i in range(n):
        x = (x * 1.0000001 + i) % 1000.0
    return x

spin(10)
real = brightness._brighten
calls = []

def long_kernel(*args):
    calls.append(1)
    if len(calls) == 2:  # the second image's: the first one's outputs are recorded
        sys.stderr.write("READY\\n")
        sys.stderr.flush()
        spin(1_000_000_000)
    return real(*args)

brightness._brighten = long_kernel
main()
"""


@pytest.mark.slow
def test_a_one_worker_build_stops_at_once_while_a_long_kernel_runs(tmp_path):
    # On the main thread the signal's handler waited for the kernel's end (seconds, a
    # minute on a large image for the depth-aware ones); the task now runs in a thread.
    import subprocess

    root, out, env = _three_images(tmp_path, (48, 64))
    proc = subprocess.Popen([sys.executable, "-c", LONG_KERNEL, *_build_args(root, out)], env=env,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr.readline().strip() == "READY"
        time.sleep(0.5)  # well inside the kernel
        sent = time.monotonic()
        proc.send_signal(signal.SIGINT)
        err = proc.communicate(timeout=120)[1]
        took = time.monotonic() - sent
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == 130, err
    assert took < 3.0, f"stopped {took:.1f} s after the signal"
    assert err.strip().splitlines()[-1] == "robodepth: interrupted; rerun the same command to resume"
    assert " 0 failed of " in err, err
    assert not (out / "brightness/3/b.png").exists() and (out / "brightness/3/a.png").is_file()
    rerun = subprocess.run([sys.executable, "-m", "robodepth_cli.cli", *_build_args(root, out)],
                           env=env, capture_output=True, text=True, timeout=120)
    assert rerun.returncode == 0 and "0 failed" in rerun.stderr, rerun.stderr
