"""Split files: the records, download + checksum + cache, parsing."""

from __future__ import annotations

import functools
import hashlib
import re
import shutil
import socket
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer

import pytest

from robodepth_cli.sources import splits
from robodepth_cli.sources.datasets import locate, read_split
from robodepth_cli.imageio import ImageError
from robodepth_cli.sources.splits import SplitError

from tests.helpers.paths import SPLITS


class _QuietHandler(SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


@pytest.fixture
def serve():
    """serve(directory) -> base URL of an HTTP server on 127.0.0.1 for that directory."""
    servers = []

    def start(directory):
        handler = functools.partial(_QuietHandler, directory=str(directory))
        httpd = ThreadingHTTPServer(("127.0.0.1", 0), handler)
        threading.Thread(target=httpd.serve_forever, daemon=True).start()
        servers.append(httpd)
        return f"http://127.0.0.1:{httpd.server_port}"

    yield start
    for s in servers:
        s.shutdown()
        s.server_close()


@pytest.fixture
def cache(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("ROBODEPTH_CACHE_DIR", str(d))
    return d


def closed_port_url(name: str) -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    return f"http://127.0.0.1:{port}/{name}"  # nothing listens there any more


def test_records_match_sources_md(splits_dir):
    """splits/splits.json carries exactly the address, sha256 and size SOURCES.md gives."""
    table = (splits_dir / "SOURCES.md").read_text()
    recs = splits.records()
    assert {r.file for r in recs.values()} == {"eigen_test_files.txt", "nyudepthv2_test_files_with_gt.txt"}
    for rec in recs.values():
        row = next(line for line in table.splitlines() if line.startswith(f"| `{rec.file}`"))
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[2] == rec.url and cells[3] == rec.sha256
        assert int(re.match(r"\d+", cells[1]).group()) == rec.lines
        data = (splits_dir / rec.file).read_bytes()
        assert hashlib.sha256(data).hexdigest() == rec.sha256
        assert splits.count_entries(data) == rec.lines


def test_download_check_and_cache(splits_dir, serve, cache):
    base = serve(splits_dir)
    path = splits.standard_split("eigen_test", url=f"{base}/eigen_test_files.txt")
    assert path == cache / "splits" / "eigen_test_files.txt"
    assert path.read_bytes() == (splits_dir / "eigen_test_files.txt").read_bytes()
    # Cached: no network needed any more.
    assert splits.standard_split("eigen_test", url=closed_port_url("x")) == path
    # A damaged cache is not trusted: it is fetched again.
    path.write_text("2011_09_26/2011_09_26_drive_0002_sync 0000000069 l\n")
    assert splits.standard_split("nyu_test", url=f"{base}/nyudepthv2_test_files_with_gt.txt").is_file()
    assert splits.standard_split("eigen_test", url=f"{base}/eigen_test_files.txt") == path
    assert hashlib.sha256(path.read_bytes()).hexdigest() == splits.record("eigen_test").sha256


def test_checksum_mismatch_is_refused(splits_dir, serve, cache, tmp_path):
    served = tmp_path / "served"
    served.mkdir()
    text = (splits_dir / "eigen_test_files.txt").read_text()
    (served / "eigen_test_files.txt").write_text(text.replace("0000000069 l", "0000000069 r", 1))
    with pytest.raises(SplitError) as err:
        splits.standard_split("eigen_test", url=f"{serve(served)}/eigen_test_files.txt")
    msg = str(err.value)
    assert "sha256" in msg and splits.record("eigen_test").sha256 in msg and "--split FILE" in msg
    assert not (cache / "splits" / "eigen_test_files.txt").exists()


def test_offline_asks_for_a_split_file(cache):
    url = closed_port_url("eigen_test_files.txt")
    with pytest.raises(SplitError) as err:
        splits.standard_split("eigen_test", url=url)
    assert f"cannot download the eigen_test split from {url}" in str(err.value)
    assert "offline?" in str(err.value) and "--split FILE" in str(err.value)
    # The clone's own checked copy is named, so the user need not download anything.
    copy = SPLITS / "eigen_test_files.txt"
    assert str(err.value).endswith(f"(this clone holds a checked copy: --split {copy})")


def test_missing_file_on_server_is_an_error(serve, cache, tmp_path):
    with pytest.raises(SplitError, match=r"\(HTTP 404 File not found\); download it yourself"):
        splits.standard_split("eigen_test", url=f"{serve(tmp_path)}/eigen_test_files.txt")


def test_cache_dir_defaults(monkeypatch, tmp_path):
    monkeypatch.delenv("ROBODEPTH_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert splits.cache_dir() == tmp_path / "xdg" / "robodepth"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert splits.cache_dir() == tmp_path / "home" / ".cache" / "robodepth"


def test_build_without_split_downloads_the_standard_one(splits_dir, fixtures_dir, serve, cache,
                                                        monkeypatch, tmp_path, cli):
    """The first two Eigen test frames are the two fixture frames."""
    monkeypatch.setenv("ROBODEPTH_SPLIT_URL_EIGEN_TEST", f"{serve(splits_dir)}/eigen_test_files.txt")
    out = tmp_path / "out"
    res = cli("build", "kitti-c", "--root", fixtures_dir / "kitti_raw", "--out", out, "--limit", "2",
              "--corruptions", "contrast", "--levels", "1", "--size", "64x96", "--jobs", "1")
    assert res.exit_code == 0, res.output
    assert (cache / "splits" / "eigen_test_files.txt").is_file()
    assert len(list(out.rglob("*.png"))) == 4

    monkeypatch.setenv("ROBODEPTH_SPLIT_URL_EIGEN_TEST", closed_port_url("eigen_test_files.txt"))
    shutil.rmtree(cache)
    res = cli("build", "kitti-c", "--root", fixtures_dir / "kitti_raw", "--out", tmp_path / "out2",
              "--corruptions", "contrast")
    assert res.exit_code == 2
    assert "offline?" in res.output and "--split FILE" in res.output
    assert len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "out2").exists()


# --- parsing -------------------------------------------------------------------------------

def write(tmp_path, text):
    p = tmp_path / "split.txt"
    p.write_text(text)
    return p


def test_eigen_lines(tmp_path):
    p = write(tmp_path, "# mine\n2011_09_26/2011_09_26_drive_0002_sync 0000000069 l\n\n"
                        "2011_10_03/2011_10_03_drive_0047_sync 12 r\n")
    a, b = read_split(p, "eigen")
    assert (a.line, b.line) == (2, 4)
    assert a.key == "kitti_data/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"
    assert b.key == "kitti_data/2011_10_03/2011_10_03_drive_0047_sync/image_03/data/0000000012.png"
    assert a.candidates[:2] == ("2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png",
                                "2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.jpg")


def test_nyu_lines(tmp_path):
    p = write(tmp_path, "bathroom/rgb_00045.jpg bathroom/sync_depth_00045.png 518.8579")
    (e,) = read_split(p, "nyu")
    assert e.key == "bathroom/rgb_00045.png"
    assert e.candidates[0] == "bathroom/rgb_00045.jpg" and "bathroom/rgb_00045.png" in e.candidates


@pytest.mark.parametrize("fmt, line, problem", [
    ("eigen", "2011_09_26/d 0000000001", "expected 3 fields"),
    ("eigen", "2011_09_26/d 0000000001 l extra", "expected 3 fields"),
    ("eigen", "2011_09_26/d 0000000001 x", "side 'x' is not one of l, r"),
    ("eigen", "2011_09_26/d frame l", "frame 'frame' is not a number"),
    ("eigen", "/etc/d 0000000001 l", "is not a relative path"),
    ("eigen", "2011_09_26/../../etc 0000000001 l", "'..' component"),
    ("nyu", "bathroom/rgb_1.jpg bathroom/d_1.png", "expected 3 fields"),
    ("nyu", "../rgb_1.jpg bathroom/d_1.png 518.8", "'..' component"),
    ("nyu", "bathroom/rgb_1.jpg bathroom/d_1.png f", "focal length 'f' is not a number"),
])
def test_bad_lines_name_file_and_line(tmp_path, fmt, line, problem):
    p = write(tmp_path, f"# header\n{line}\n")
    with pytest.raises(SplitError) as err:
        read_split(p, fmt)
    assert str(err.value).startswith(f"{p}:2: ") and problem in str(err.value)


def test_duplicates_and_empty(tmp_path):
    p = write(tmp_path, "d/x 1 l\nd/x 0000000001 l\n")
    with pytest.raises(SplitError, match=r"split.txt:2: duplicate of line 1"):
        read_split(p, "eigen")
    with pytest.raises(SplitError, match="the split lists no images"):
        read_split(write(tmp_path, "\n\n"), "eigen")


def test_locate_png_or_jpg_and_follow_symlinks(tmp_path):
    root = tmp_path / "root"
    data = root / "d/x/image_02/data"
    data.mkdir(parents=True)
    (data / "0000000001.jpg").write_bytes(b"j")
    e1, e2 = read_split(write(tmp_path, "d/x 1 l\nd/x 2 l\n"), "eigen")
    assert locate(root, e1) == ("d/x/image_02/data/0000000001.jpg", data / "0000000001.jpg")
    with pytest.raises(ImageError, match=r"0000000002.png: no such file \(tried .png, .jpg, .jpeg\)"):
        locate(root, e2)
    # A link in the user's own root is followed, wherever it leads.
    (tmp_path / "elsewhere.png").write_bytes(b"s")
    (data / "0000000002.png").symlink_to(tmp_path / "elsewhere.png")
    assert locate(root, e2) == ("d/x/image_02/data/0000000002.png", data / "0000000002.png")
