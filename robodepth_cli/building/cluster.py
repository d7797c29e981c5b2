"""Builds on a Dask cluster: :class:`DaskExecutor`, the executor behind ``--scheduler``,
``--scheduler-file`` and the config key ``scheduler``.

The client (the ``robodepth build`` process) submits one Dask task per source image to an
existing ``distributed`` scheduler and receives each task's manifest rows; it alone writes
the manifest and the build record, exactly as with the local pool. Workers write the
images themselves, atomically, so OUT (and the root, and KITTI-S's checkpoints) must be
paths every worker sees, with the same contents, on a shared filesystem.

Before any work every connected worker runs a probe (:func:`probe`); a worker that fails
it refuses the build with one line naming the worker and the problem. A probe checks:

- the root is a readable directory listing the same top-level names as on the client (an
  empty or different directory at the same path is a host without the shared mount);
- every file a worker reads besides the images (KITTI-S's checkpoints) has the same
  sha256 as on the client;
- OUT is the client's OUT: the worker reads a token file the client wrote there, writes
  and deletes a file of its own;
- the same robodepth version and source code, and the same versions of the libraries that
  decide pixels (numpy, OpenCV, scikit-image, SciPy, Pillow, numba; torch for KITTI-S).

Workers that join later (a restarted worker, an adaptive cluster) run the same probe
before their first task; a refusal then stops the build like a write error (finished
images kept, a rerun resumes).

Failures: a worker that dies mid-task loses nothing: the scheduler gives its tasks to
another worker (their PNGs are rewritten whole, with the same bytes), and temporary files
it left in OUT are deleted at the end. A task that killed several workers in a row (the
scheduler's ``allowed-failures``, e.g. out of memory) stops the build with a message
naming its source image. Ctrl-C cancels every task that has not finished.

Only this module imports ``dask``/``distributed``, and only when a cluster is asked for.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import secrets
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

from .. import __version__
from ..errors import cannot_write, os_reason
from ..files import sha256_file
from ..output.folder import OutputFolder
from .executors import ExecutorError

CONNECT_TIMEOUT_S = 30  # to reach the scheduler
WORKERS_TIMEOUT_S = 120  # for the first worker to connect (batch systems start them late)
PROBE_TIMEOUT_S = 300  # for every worker's probe answer (hashing checkpoints on a slow disk)
PROBE_PREFIX = ".robodepth-probe-"
PROBE_SUFFIX = ".part"  # a probe file left by a killed worker is removed as a temporary

# Distributions whose versions decide pixels; opencv has several wheels providing cv2.
PIXEL_LIBRARIES = ("numpy", "opencv", "scikit-image", "scipy", "Pillow", "numba", "torch")
_OPENCV_WHEELS = ("opencv-python-headless", "opencv-python", "opencv-contrib-python-headless",
                  "opencv-contrib-python")


class ClusterError(ExecutorError):
    """The cluster cannot run (or stopped running) this build; one line naming the
    scheduler or worker and the problem."""


# --- what a worker must share with the client ---------------------------------------------

@dataclass(frozen=True)
class Requirements:
    """What the client found, for every worker to find the same.

    ``root_listing``: how many top-level names the root holds and the sha256 of them,
    sorted and joined by newlines (:func:`listing`); ``files``: ``(path, sha256)`` of
    other files workers read; ``token``: the name and content of the file the client wrote
    in OUT; ``versions``: :func:`pixel_versions` on the client.
    """

    root: str
    root_listing: tuple[int, str]
    out: str
    token: str
    files: tuple[tuple[str, str], ...] = ()
    versions: dict[str, str] = field(default_factory=dict)


def library_version(name: str) -> str:
    """The installed version of distribution ``name`` ("opencv": whichever OpenCV wheel
    provides cv2), or ``"not installed"``. Read from package metadata: nothing is imported."""
    from importlib import metadata

    for dist in (_OPENCV_WHEELS if name == "opencv" else (name,)):
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            continue
    return "not installed"


def source_digest() -> str:
    """sha256 (16 hex digits) of robodepth's own source files: two checkouts of the same
    version with different code would not make the same bytes."""
    here = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for p in sorted(here.rglob("*.py")):
        h.update(p.relative_to(here).as_posix().encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def pixel_versions(libraries: Sequence[str]) -> dict[str, str]:
    """robodepth's version and source digest, and the version of each of ``libraries``
    that is one of :data:`PIXEL_LIBRARIES` (``opencv-python-headless`` counts as opencv)."""
    wanted = {"opencv" if n.startswith("opencv") else n for n in libraries}
    versions = {"robodepth": f"{__version__} (source {source_digest()})"}
    versions.update({n: library_version(n) for n in PIXEL_LIBRARIES if n in wanted})
    return versions


def listing(directory: str) -> tuple[int, str]:
    """(number of entries, sha256 of their sorted names) of ``directory``: compared, not
    sent, so a root with a million files at its top costs every worker 64 bytes."""
    names = sorted(os.listdir(directory))
    return len(names), hashlib.sha256("\n".join(names).encode("utf-8", "surrogateescape")).hexdigest()


def probe(req: Requirements) -> str:
    """Check, in the process that will run tasks, that it sees what the client sees
    (the module docstring lists the checks). Returns "" if it does, else the first
    problem in one line."""
    root = req.root
    if not os.path.isdir(root):
        return f"cannot see the root {root} ({'not a directory' if os.path.exists(root) else 'no such directory'})"
    try:
        seen = listing(root)
    except OSError as exc:
        return f"cannot read the root {root} ({os_reason(exc)})"
    if seen != req.root_listing:
        return (f"sees other contents in the root {root} ({seen[0]} entries, the client "
                f"{req.root_listing[0]}): not the same shared directory")
    for path, sha in req.files:
        try:
            if sha256_file(path) != sha:
                return f"{path}: differs from the client's copy (sha256)"
        except OSError as exc:
            return f"cannot read {path} ({os_reason(exc)})"
    token = os.path.join(req.out, req.token)
    try:
        with open(token, encoding="utf-8") as fh:
            seen = fh.read()
    except OSError as exc:
        return f"does not see the output directory {req.out} (cannot read the client's {token}: {os_reason(exc)})"
    if seen != req.token:
        return f"sees another output directory at {req.out} (its {token} differs)"
    try:
        fd, mine = tempfile.mkstemp(prefix=PROBE_PREFIX, suffix=PROBE_SUFFIX, dir=req.out)
        os.close(fd)
        os.unlink(mine)
    except OSError as exc:
        return f"cannot write and delete a file in the output directory {req.out} ({os_reason(exc)})"
    have = pixel_versions(list(req.versions))
    diff = [f"{n} {have.get(n)} (client: {v})" for n, v in req.versions.items() if have.get(n) != v]
    if diff:
        return "other versions than the client: " + "; ".join(diff)
    return ""


def requirements(root: Path, out: Path, files: Sequence[str], libraries: Sequence[str]) -> Requirements:
    """The client's side of the probe for a build from ``root`` into ``out`` (which must
    exist): writes the token file in ``out`` (delete it with :func:`remove_token`)."""
    root = os.path.realpath(root)
    out = os.path.realpath(out)
    token = f"{PROBE_PREFIX}{secrets.token_hex(8)}{PROBE_SUFFIX}"
    try:
        with open(os.path.join(out, token), "w", encoding="utf-8") as fh:
            fh.write(token)
    except OSError as exc:
        raise ClusterError(cannot_write(out, exc, what="the output directory")) from None
    return Requirements(root=root, root_listing=listing(root), out=out, token=token,
                        files=tuple((os.path.realpath(f), sha256_file(f)) for f in files),
                        versions=pixel_versions(libraries))


def remove_token(req: Requirements) -> None:
    try:
        os.unlink(os.path.join(req.out, req.token))
    except FileNotFoundError:
        pass


# --- worker side ---------------------------------------------------------------------------

_PROBED: dict[str, str] = {}  # token -> probe result, per worker process


def _probe_once(req: Requirements) -> str:
    if req.token not in _PROBED:
        _PROBED.clear()  # one build at a time per worker matters; drop older builds' results
        _PROBED[req.token] = probe(req)
    return _PROBED[req.token]


@dataclass(frozen=True)
class _Refused:
    worker: str
    problem: str


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except Exception:  # not in a worker (never in a build); still say something
        return f"pid {os.getpid()}"


def _run_probe(req: Requirements) -> str:
    return _probe_once(req)


def _run_task(task: Any, fn: Callable[[Any], Any], req: Requirements) -> Any:
    """``fn(task)`` on a worker that passed the probe; a :class:`_Refused` otherwise."""
    problem = _probe_once(req)
    if problem:
        return _Refused(_worker_address(), problem)
    return fn(task)


# --- client side ---------------------------------------------------------------------------

def read_scheduler_file(path: str | os.PathLike) -> str:
    """The scheduler address in a scheduler file (the JSON ``dask scheduler
    --scheduler-file``, dask-jobqueue and dask-mpi write); :class:`ClusterError` otherwise."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise ClusterError(f"{path}: cannot read the scheduler file ({os_reason(exc)})") from None
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise ClusterError(f"{path}: not a scheduler file (not JSON)") from None
    address = data.get("address") if isinstance(data, dict) else None
    if not isinstance(address, str) or not address:
        raise ClusterError(f"{path}: not a scheduler file (no 'address')")
    return address


def _say(message: str) -> None:
    print(f"robodepth: {message}", file=sys.stderr, flush=True)


class DaskExecutor:
    """Runs a build's tasks on the workers of a running Dask scheduler.

    Use as a context manager (the connection is closed at the end). ``workers`` is the
    number of worker threads when connected: how many tasks run at once.
    """

    def __init__(self, address: str | None = None, scheduler_file: str | None = None, *,
                 connect_timeout: float | None = None, workers_timeout: float | None = None):
        if bool(address) == bool(scheduler_file):
            raise ValueError("give exactly one of address and scheduler_file")
        self.scheduler_file = str(scheduler_file) if scheduler_file else None
        self.address = address or read_scheduler_file(scheduler_file)
        self.connect_timeout = CONNECT_TIMEOUT_S if connect_timeout is None else connect_timeout
        self.workers_timeout = WORKERS_TIMEOUT_S if workers_timeout is None else workers_timeout
        self.client = None
        self.workers = 0
        self.requirements: Requirements | None = None
        self.folder: OutputFolder | None = None  # the build's, once checked
        self._connect()

    # -- connection

    def _connect(self) -> None:
        import logging

        from distributed import Client

        where = f"{self.address}" + (f" (from {self.scheduler_file})" if self.scheduler_file else "")
        # distributed logs every failed attempt; the one-line refusal below says it all.
        logging.getLogger("distributed").setLevel(logging.ERROR)
        # Connecting (and waiting for workers) can take long; without a word first it looks hung.
        _say(f"connecting to the Dask scheduler at {where} (giving up after "
             f"{self.connect_timeout:g} s)")
        try:
            self.client = Client(self.address, timeout=self.connect_timeout, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise ClusterError(f"{where}: cannot connect to the Dask scheduler ({exc})") from None
        except ValueError as exc:  # a malformed address
            raise ClusterError(f"{where}: not a Dask scheduler address ({exc})") from None
        if not self.client.nthreads():
            _say(f"connected; waiting for a worker to join (giving up after "
                 f"{self.workers_timeout:g} s)")
        try:
            self.client.wait_for_workers(1, timeout=self.workers_timeout)
        except TimeoutError:
            self.close()
            raise ClusterError(f"{where}: no worker connected to the scheduler within "
                               f"{self.workers_timeout:g} s") from None
        self.workers = sum(self.client.nthreads().values())

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None

    def __enter__(self) -> "DaskExecutor":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- the executor seam

    def check(self, root: Path, folder: OutputFolder, files: Sequence[str],
              libraries: Sequence[str]) -> None:
        """Probe every connected worker (see the module docstring) before any work;
        :class:`ClusterError` naming the first worker that fails and why."""
        req = requirements(root, folder.path, files, libraries)
        try:
            answers = self.client.run(_run_probe, req, on_error="return")
        except Exception as exc:  # the scheduler went away
            remove_token(req)
            raise ClusterError(f"{self.address}: the workers could not be probed ({type(exc).__name__}: {exc})") from None
        problems = [(w, a if isinstance(a, str) else f"the probe failed ({type(a).__name__}: {a})")
                    for w, a in sorted(answers.items()) if not isinstance(a, str) or a]
        if problems:
            remove_token(req)
            worker, problem = problems[0]
            more = f" (and {len(problems) - 1} more workers)" if len(problems) > 1 else ""
            raise ClusterError(f"worker {worker}: {problem}{more}; refused before any work")
        if not answers:
            remove_token(req)
            raise ClusterError(f"{self.address}: no worker answered the probe")
        self.requirements, self.folder = req, folder
        self.workers = sum(self.client.nthreads().values())

    def map_unordered(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Iterator[Any]:
        from distributed import as_completed

        if self.requirements is None:
            raise RuntimeError("check() the workers before running tasks")
        client, req = self.client, self.requirements
        before = set(client.nthreads())
        # fn and the requirements travel inside every task rather than scattered once: data
        # scattered to the workers is gone for good when they all leave (walltime), tasks
        # can always be rerun elsewhere.
        futures = client.map(functools.partial(_run_task, fn=fn, req=req), tasks, pure=False)
        by_key = {f.key: t for f, t in zip(futures, tasks)}
        done = 0
        try:
            for fut in as_completed(futures, loop=client.loop):
                if fut.status != "finished":
                    raise self._task_error(fut, by_key[fut.key]) from None
                result = fut.result()
                fut.release()  # the client keeps no result it has handed on
                if isinstance(result, _Refused):
                    raise ClusterError(f"worker {result.worker} (joined during the build): {result.problem}")
                done += 1
                yield result
        finally:
            client.cancel([f for f in futures if not f.done()])
            remove_token(req)
            if done < len(futures) or set(client.nthreads()) != before:
                # A worker that died or a task cancelled mid-write may leave a temporary file.
                self.folder.remove_temporaries()

    def _task_error(self, fut, task) -> Exception:
        name = getattr(task, "key", None) or getattr(getattr(task, "source", None), "key", "a task")
        if fut.status != "error":  # cancelled: the scheduler restarted or we lost it
            return ClusterError(f"{self.address}: the scheduler dropped the build's tasks ({fut.status})")
        exc = fut.exception()
        if type(exc).__name__ == "KilledWorker":
            return ClusterError(f"{name}: its task killed {self.address}'s workers repeatedly "
                                f"(out of memory?)")
        return exc  # a bug in a task: keep its traceback

    def describe(self) -> dict:
        nthreads = self.client.nthreads() if self.client is not None else {}
        return {"backend": "dask", "scheduler": self.address, "workers": len(nthreads),
                "threads": sum(nthreads.values())}
