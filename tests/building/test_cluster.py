"""Builds on a real Dask cluster: a `dask scheduler` and single-threaded `dask worker`
processes on 127.0.0.1, started here and torn down even when a test fails."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.helpers.imports import imported_by_command
from tests.helpers.manifest import manifest_rows
from tests.helpers.trees import kitti_tree, random_image, save, tree

# Every test here is a long end-to-end run (make test-fast leaves them out).
pytestmark = pytest.mark.slow

CHEAP = ["--corruptions", "brightness,gaussian_noise,zoom_blur", "--levels", "1,3", "--size", "48x160"]
SLOWER = ["--corruptions", "contrast,gaussian_noise,zoom_blur,motion_blur", "--levels", "2,4",
          "--size", "96x320"]
START_TIMEOUT_S = 60


def _unshare_works() -> bool:
    try:
        return subprocess.run(["unshare", "-Urm", "true"], capture_output=True, timeout=10).returncode == 0
    except (OSError, subprocess.SubprocessError):
        return False


class LocalCluster:
    """A scheduler and workers as separate process groups, on loopback, no dashboards."""

    def __init__(self, base: Path):
        self.base = base
        self.file = base / "scheduler.json"
        self.procs: list[subprocess.Popen] = []
        self.client = None
        self.scheduler = self._start(
            [sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
             "--no-dashboard", "--scheduler-file", str(self.file)], "scheduler")
        deadline = time.monotonic() + START_TIMEOUT_S
        while not (self.file.exists() and self.file.stat().st_size):
            assert self.scheduler.poll() is None, self._log("scheduler")
            assert time.monotonic() < deadline, "the scheduler did not start"
            time.sleep(0.1)
        time.sleep(0.1)  # the file is written in one go, but let the writer close it
        self.address = json.loads(self.file.read_text())["address"]
        from distributed import Client

        self.client = Client(self.address, timeout=START_TIMEOUT_S, set_as_default=False)

    def _start(self, args, name, cwd=None, env=None) -> subprocess.Popen:
        log = open(self.base / f"{name}.log", "wb")
        proc = subprocess.Popen(args, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True)
        log.close()
        self.procs.append(proc)
        return proc

    def _log(self, name) -> str:
        return (self.base / f"{name}.log").read_text(errors="replace")[-3000:]

    def add_worker(self, name: str, *, cwd=None, env=None, prefix=()) -> tuple[subprocess.Popen, str]:
        """Start one single-threaded worker; returns it and its address once connected."""
        before = set(self.client.nthreads())
        proc = self._start([*prefix, sys.executable, "-m", "dask", "worker", "--scheduler-file",
                            str(self.file), "--nworkers", "1", "--nthreads", "1", "--no-dashboard",
                            "--host", "127.0.0.1", "--local-directory", str(self.base / name),
                            "--name", name], name, cwd=cwd, env=env)
        deadline = time.monotonic() + START_TIMEOUT_S
        while True:
            new = set(self.client.nthreads()) - before
            if new:
                return proc, new.pop()
            assert proc.poll() is None, self._log(name)
            assert time.monotonic() < deadline, f"worker {name} did not connect"
            time.sleep(0.1)

    def stop(self, proc: subprocess.Popen, address: str | None = None) -> None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait(timeout=30)
        if address:  # until the scheduler has noticed, it would count the worker
            deadline = time.monotonic() + START_TIMEOUT_S
            while address in self.client.nthreads() and time.monotonic() < deadline:
                time.sleep(0.1)

    @contextlib.contextmanager
    def extra_worker(self, name: str, **start):
        """One more worker (``add_worker``'s options) for the block, stopped after it, pass or
        fail; yields its address."""
        proc, address = self.add_worker(name, **start)
        try:
            yield address
        finally:
            self.stop(proc, address)

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
        for proc in self.procs:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=30)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    c = None
    try:
        c = LocalCluster(tmp_path_factory.mktemp("cluster"))
        c.add_worker("w1")
        c.add_worker("w2")
        yield c
    finally:
        if c is not None:
            c.close()


@pytest.fixture(scope="module")
def kitti(tmp_path_factory):
    base = tmp_path_factory.mktemp("data")
    root = base / "kitti_raw"
    split = kitti_tree(root, [(i, "l", ".png") for i in range(8)], size=(120, 400))
    return root, split


@pytest.fixture(scope="module")
def build(build_kitti, kitti):
    """``build(out, *flags)``: ``robodepth build kitti-c`` of the module's tree."""
    return lambda out, *flags: build_kitti(*kitti, out, *flags)


@pytest.fixture(scope="module")
def local(build, tmp_path_factory):
    """Local builds to compare with, keyed by their flags."""
    made = {}

    def get(flags):
        key = tuple(flags)
        if key not in made:
            out = tmp_path_factory.mktemp("local") / "out"
            res = build(out, *flags, "--jobs", "1")
            assert res.exit_code == 0, res.output
            made[key] = out
        return made[key]

    return get


def same_as_local(build, local, flags, out, *how):
    """Build ``flags`` into ``out`` the way ``how`` says; it must equal the local build.
    Returns the local build's directory."""
    res = build(out, *flags, *how)
    assert res.exit_code == 0, res.output
    want = local(flags)
    assert tree(out) == tree(want)
    assert manifest_rows(out) == manifest_rows(want)
    return want


def test_cluster_build_is_the_local_build(cli, build, cluster, local, tmp_path):
    out = tmp_path / "out"
    want = same_as_local(build, local, CHEAP, out, "--scheduler", cluster.address)
    record = json.loads((out / "build.json").read_text())
    assert record["status"] == "finished"
    assert record["executor"] == {"backend": "dask", "scheduler": cluster.address, "workers": 2,
                                  "threads": 2}
    assert not list(out.glob(".robodepth-probe-*"))
    # Resume and verify work as with a local build; the scheduler file gives the address too.
    (out / manifest_rows(out)[3]["output"]).unlink()
    res = build(out, *CHEAP, "--scheduler-file", cluster.file)
    assert res.exit_code == 0, res.output
    assert f"1 written, {len(manifest_rows(want)) - 1} skipped" in res.output
    assert tree(out) == tree(want)
    assert cli("verify", out).exit_code == 0


def test_chains_and_decimal_levels_on_the_cluster_are_the_local_build(cli, build, cluster, local, tmp_path):
    flags = ["--corruptions", "gaussian_noise", "--levels", "2.5", "--size", "48x160",
             "--compose", "fog:1+gaussian_noise:2.5,contrast:2+pixelate:1.5"]
    out = tmp_path / "out"
    same_as_local(build, local, flags, out, "--scheduler", cluster.address)
    assert {r["variant"] for r in manifest_rows(out)} == {"clean", "gaussian_noise", "fog:1+gaussian_noise:2.5",
                                                  "contrast:2+pixelate:1.5"}
    assert cli("verify", out).exit_code == 0


def test_scheduler_in_a_config_file(build, cluster, local, tmp_path):
    cfg = tmp_path / "cluster.yaml"
    cfg.write_text(f"scheduler: {cluster.address}\n")
    out = tmp_path / "out"
    res = build(out, *CHEAP, "--config", cfg, "--limit", "2")
    assert res.exit_code == 0, res.output
    assert json.loads((out / "build.json").read_text())["executor"]["backend"] == "dask"
    want = tree(local(CHEAP))
    got = tree(out)
    assert got and all(got[p] == want[p] for p in got)


def test_kitti_s_on_the_cluster_loads_the_checkpoints_once_per_worker(cli, cluster, kitti, tmp_path):
    from tests.helpers.adain import save_checkpoints

    vgg, dec, _, _ = save_checkpoints(tmp_path, seed=3)
    styles = tmp_path / "styles"
    save(styles / "sketch.png", random_image(40, 48, seed=1))
    save(styles / "murals.jpg", random_image(48, 40, seed=2))
    root, split = kitti
    args = ["build", "kitti-s", "--root", root, "--split", split, "--styles", styles, "--vgg", vgg,
            "--decoder", dec, "--size", "32x96", "--style-size", "32", "--only-styles", "sketch,murals",
            "--limit", "2"]
    res = cli(*args, "--out", tmp_path / "local", "--jobs", "1")
    assert res.exit_code == 0, res.output
    res = cli(*args, "--out", tmp_path / "cluster", "--scheduler", cluster.address)
    assert res.exit_code == 0, res.output
    assert tree(tmp_path / "cluster") == tree(tmp_path / "local")
    assert manifest_rows(tmp_path / "cluster") == manifest_rows(tmp_path / "local")
    # Each worker process keeps one loaded model for these checkpoints, reused by every task;
    # on a cluster each worker decides what --device auto means.
    held = cluster.client.run(lambda: list(__import__("robodepth_cli.styles.inputs").styles.inputs._STYLIZERS))
    assert any(held.values()) and all(v in ([], [(str(vgg), str(dec), "auto")]) for v in held.values()), held


def test_a_killed_worker_loses_nothing(cluster, kitti, local, tmp_path):
    victim, address = cluster.add_worker("w3")
    out = tmp_path / "out"
    root, split = kitti
    proc = subprocess.Popen(
        [sys.executable, "-m", "robodepth_cli.cli", "build", "kitti-c", "--root", str(root), "--split",
         str(split), "--out", str(out), *SLOWER, "--scheduler", cluster.address, "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        # SIGINT as a terminal has it, also when the suite runs from a background shell.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while not cluster.client.processing().get(address):  # the victim holds build tasks
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the build never reached the third worker"
            time.sleep(0.02)
        cluster.stop(victim)
        _, err = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        cluster.stop(victim, address)
    assert proc.returncode == 0, err
    want = local(SLOWER)
    assert tree(out) == tree(want)  # also: no temporary file the dead worker left
    assert manifest_rows(out) == manifest_rows(want)


def test_ctrl_c_cancels_the_cluster_tasks_and_the_rerun_completes(build, cluster, kitti, local, tmp_path):
    out = tmp_path / "out"
    root, split = kitti
    args = [sys.executable, "-m", "robodepth_cli.cli", "build", "kitti-c", "--root", str(root), "--split",
            str(split), "--out", str(out), *SLOWER, "--scheduler", cluster.address, "--no-progress"]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not any(cluster.client.processing().values()):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the build never started"
            time.sleep(0.02)
        os.kill(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert json.loads((out / "build.json").read_text())["status"] == "interrupted"
    deadline = time.monotonic() + 30
    while any(cluster.client.processing().values()):  # nothing of that build is left to run
        assert time.monotonic() < deadline, cluster.client.processing()
        time.sleep(0.1)
    res = build(out, *SLOWER, "--scheduler", cluster.address)
    assert res.exit_code == 0, res.output
    assert tree(out) == tree(local(SLOWER))


def test_worker_with_other_robodepth_is_refused_before_any_work(build, cluster, tmp_path):
    shadow = tmp_path / "shadow"
    pkg = Path(__import__("robodepth_cli").__file__).parent
    shutil.copytree(pkg, shadow / "robodepth_cli", ignore=shutil.ignore_patterns("__pycache__"))
    release = shadow / "robodepth_cli" / "formats.py"  # robodepth_cli.__version__ is its RELEASE
    release.write_text(release.read_text().replace('RELEASE = "', 'RELEASE = "0.0.0+other'))
    env = {**os.environ, "PYTHONPATH": str(shadow)}
    out = tmp_path / "out"
    with cluster.extra_worker("other", env=env, cwd=shadow) as address:  # python -m puts the cwd first
        res = build(out, *CHEAP, "--scheduler", cluster.address)
    assert res.exit_code == 2, res.output
    connecting, msg = res.output.strip().splitlines()  # the error is the one line after
    assert connecting.startswith(f"robodepth: connecting to the Dask scheduler at {cluster.address}")
    assert msg.startswith(f"robodepth: error: worker {address}: other versions than the client: robodepth 0.0.0+other")
    assert "refused before any work" in msg
    assert not tree(out) and not (out / "build.json").exists() and not (out / "manifest.csv").exists()
    assert not list(out.glob(".robodepth-probe-*"))


@pytest.mark.skipif(not _unshare_works(), reason="needs unprivileged mount namespaces (unshare -Urm)")
def test_worker_that_cannot_see_the_root_is_refused_before_any_work(build, cluster, kitti, tmp_path):
    """A host without the shared mount: the worker runs in its own mount namespace where the
    data's directory is an empty tmpfs."""
    root, _ = kitti
    hide = root.parent
    prefix = ["unshare", "-Urm", "sh", "-c", 'mount -t tmpfs tmpfs "$0" && exec "$@"', str(hide)]
    out = tmp_path / "out"
    with cluster.extra_worker("blind", prefix=prefix) as address:
        res = build(out, *CHEAP, "--scheduler", cluster.address)
    assert res.exit_code == 2, res.output
    assert res.output.strip().splitlines()[1:] == [
        f"robodepth: error: worker {address}: cannot see the root {root} (no such directory); "
        f"refused before any work"]
    assert not tree(out) and not (out / "build.json").exists()


def test_probe_names_each_problem(tmp_path):
    """The probe itself, in this process: what a worker on a host without the shared
    paths, or with other files or versions, reports."""
    from robodepth_cli.building import cluster

    root, out = tmp_path / "root", tmp_path / "out"
    (root / "2011_09_26").mkdir(parents=True)
    out.mkdir()
    ckpt = tmp_path / "decoder.pth"
    ckpt.write_bytes(b"weights")
    req = cluster.requirements(root, out, [str(ckpt)], ["numpy", "opencv-python-headless", "torch", "tqdm"])
    assert set(req.versions) == {"robodepth", "numpy", "opencv", "torch"}  # tqdm decides no pixel
    token = out / req.token
    assert token.read_text() == req.token and token.name.startswith(".robodepth-probe-")
    assert cluster.probe(req) == ""
    assert [p.name for p in out.iterdir()] == [token.name]  # the probe's own file is gone

    from dataclasses import replace

    assert cluster.probe(replace(req, root=str(tmp_path / "nope"))) == \
        f"cannot see the root {tmp_path / 'nope'} (no such directory)"
    (root / "2011_09_28").mkdir()
    assert cluster.probe(req) == (f"sees other contents in the root {root} (2 entries, the client 1): "
                                  f"not the same shared directory")
    (root / "2011_09_28").rmdir()
    ckpt.write_bytes(b"other weights")
    assert cluster.probe(req) == f"{ckpt}: differs from the client's copy (sha256)"
    ckpt.write_bytes(b"weights")
    token.write_text("another build")
    assert cluster.probe(req) == f"sees another output directory at {out} (its {token} differs)"
    token.unlink()
    assert cluster.probe(req).startswith(f"does not see the output directory {out} (cannot read the client's {token}: ")
    token.write_text(req.token)
    older = replace(req, versions={**req.versions, "numpy": "1.0.0"})
    assert cluster.probe(older) == f"other versions than the client: numpy {req.versions['numpy']} (client: 1.0.0)"
    cluster.remove_token(req)
    assert not token.exists()


def test_scheduler_config_keys(tmp_path):
    from robodepth_cli.building.config import ConfigError, resolve

    f = tmp_path / "c.yaml"
    f.write_text("scheduler_file: run/scheduler.json\n")
    cfg = resolve("kitti-c", f)
    assert (cfg.scheduler, cfg.scheduler_file) == (None, str(tmp_path / "run" / "scheduler.json"))
    # A flag chooses anew: it replaces the file's choice of the other key.
    cfg = resolve("kitti-c", f, {"scheduler": "tcp://head:8786"})
    assert (cfg.scheduler, cfg.scheduler_file) == ("tcp://head:8786", None)
    assert resolve("kitti-c").scheduler is None and resolve("kitti-c").scheduler_file is None
    f.write_text("scheduler: tcp://head:8786\nscheduler_file: s.json\n")
    with pytest.raises(ConfigError, match=f"^{f}: give either {f}: scheduler or {f}: scheduler_file, not both$"):
        resolve("kitti-c", f)
    f.write_text("scheduler: 8786\n")
    with pytest.raises(ConfigError, match="scheduler: expected a Dask scheduler address such as tcp://head:8786, got 8786"):
        resolve("kitti-c", f)


def test_unreachable_scheduler_and_bad_scheduler_file(build, tmp_path, monkeypatch):
    import socket

    from robodepth_cli.building import cluster

    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 2)

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    res = build(tmp_path / "out", *CHEAP, "--scheduler", f"tcp://127.0.0.1:{port}")
    assert res.exit_code == 2
    # Said before the wait, so a slow refusal does not look like a hang.
    first, error = res.output.splitlines()
    assert first == (f"robodepth: connecting to the Dask scheduler at tcp://127.0.0.1:{port} "
                     f"(giving up after 2 s)")
    assert error.startswith(f"robodepth: error: tcp://127.0.0.1:{port}: cannot connect to the Dask scheduler")
    assert not (tmp_path / "out").exists()
    bad = tmp_path / "s.json"
    bad.write_text("{}")
    res = build(tmp_path / "out", *CHEAP, "--scheduler-file", bad)
    assert res.output.strip() == f"robodepth: error: {bad}: not a scheduler file (no 'address')"
    res = build(tmp_path / "out", *CHEAP, "--scheduler-file", bad, "--scheduler", "tcp://x:1")
    assert res.output.strip() == "robodepth: error: --scheduler and --scheduler-file: give one of them, not both"


def test_a_local_build_never_imports_dask(kitti, tmp_path):
    root, split = kitti
    argv = ["build", "kitti-c", "--root", root, "--split", split, "--out", tmp_path / "out", "--corruptions",
            "contrast", "--levels", "1", "--size", "32x96", "--limit", "2", "--jobs", "2", "--no-progress"]
    assert imported_by_command(argv, ["dask", "distributed"]) == []
    assert len(tree(tmp_path / "out")) == 4
