"""Hostile and broken submissions: one line, a non-zero exit, nothing written outside the
output folder, memory bounded by what is read, not by what the archive claims."""

from __future__ import annotations

import io
import os
import stat
import tracemalloc
import zipfile

import numpy as np
import pytest

from robodepth_cli.challenge.submission import open_submission
from robodepth_cli.errors import RobodepthError
from tests.helpers.challenge import public_folder
from tests.helpers.messages import one_line_error

IDS = ["aa01", "bb02", "cc03"]


def _maps(n=3, shape=(8, 12), dtype=np.float32):
    return (np.random.default_rng(0).random((n, *shape)) * 0.2 + 0.05).astype(dtype)


def _npy_bytes(a) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=True)
    return buf.getvalue()


def _zip(path, members, method=zipfile.ZIP_DEFLATED):
    with zipfile.ZipFile(path, "w", method) as zf:
        for name, data in members:
            if isinstance(name, zipfile.ZipInfo):
                zf.writestr(name, data)
            else:
                zf.writestr(name, data)
    return path


def _streamed(path, shape, block: bytes, count: int):
    """A zip whose member disp.npy has a float32 header of ``shape`` and then ``block``
    ``count`` times, written as a stream (never whole in memory)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        with zf.open("disp.npy", "w", force_zip64=True) as fh:
            header = io.BytesIO()
            np.lib.format.write_array_header_1_0(header, {"descr": "<f4", "fortran_order": False, "shape": shape})
            fh.write(header.getvalue())
            for _ in range(count):
                fh.write(block)
    return path


@pytest.fixture
def public(tmp_path):
    return public_folder(tmp_path / "public", IDS)


def _check(cli, sub, public, *parts):
    before = set(os.listdir(sub.parent))
    res = cli("challenge", "check", sub, "--public", public)
    line = one_line_error(res, *parts)
    assert set(os.listdir(sub.parent)) == before  # nothing written beside it
    return line


def test_a_valid_submission_passes(cli, tmp_path, public):
    sub = _zip(tmp_path / "s.zip", [("disp.npy", _npy_bytes(_maps()))])
    res = cli("challenge", "check", sub, "--public", public)
    assert res.exit_code == 0 and "valid (3 maps, in list order)" in res.output


def test_macos_extras_are_ignored(cli, tmp_path, public):
    sub = _zip(tmp_path / "s.zip", [("disp.npy", _npy_bytes(_maps())), ("__MACOSX/._disp.npy", b"junk"),
                                    (".DS_Store", b"junk")])
    assert cli("challenge", "check", sub, "--public", public).exit_code == 0


@pytest.mark.parametrize("name, part", [("../disp.npy", "'..'"), ("/tmp/disp.npy", "absolute path"),
                                        ("a/../../disp.npy", "'..'")])
def test_escaping_paths(cli, tmp_path, public, name, part):
    _check(cli, _zip(tmp_path / "s.zip", [(name, _npy_bytes(_maps()))]), public, part)


def test_symlink_member(cli, tmp_path, public):
    info = zipfile.ZipInfo("disp.npy")
    info.external_attr = (stat.S_IFLNK | 0o777) << 16
    _check(cli, _zip(tmp_path / "s.zip", [(info, "/etc/passwd")]), public, "symlink")


def test_nested_archive(cli, tmp_path, public):
    inner = io.BytesIO()
    with zipfile.ZipFile(inner, "w") as zf:
        zf.writestr("disp.npy", _npy_bytes(_maps()))
    _check(cli, _zip(tmp_path / "s.zip", [("inner.zip", inner.getvalue())]), public, "archive inside")


def test_several_and_no_arrays(cli, tmp_path, public):
    _check(cli, _zip(tmp_path / "a.zip", [("a.npy", _npy_bytes(_maps())), ("b.npz", b"PK")]), public, "2 arrays")
    _check(cli, _zip(tmp_path / "b.zip", [("readme.txt", b"hello")]), public, "no .npy or .npz")
    _check(cli, _zip(tmp_path / "c.zip", [("disp.npy", _npy_bytes(_maps())), ("notes.txt", b"x")]),
           public, "besides the array")


def test_zip_bomb_refused_from_the_index(cli, tmp_path, public):
    # 1.2 GB of zeros declared as one .npy member, deflated to about a MB: refused by the
    # declared size before anything is inflated, with memory to spare.
    path = _streamed(tmp_path / "bomb.zip", (3, 10000, 10000), bytes(1 << 22), 300)
    assert path.stat().st_size < 10e6
    tracemalloc.start()
    _check(cli, path, public, "over the limit", "--max-size")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 50e6


def test_declared_sizes_are_not_trusted(tmp_path):
    # A member whose local data is larger than its header says: never read past the header.
    a = _maps()
    data = _npy_bytes(a)
    path = _zip(tmp_path / "s.zip", [("disp.npy", data + bytes(10 ** 6))])
    with pytest.raises(RobodepthError, match="header announces"):
        open_submission(str(path), IDS, 10 ** 9)


def test_size_limit_of_the_upload(cli, tmp_path, public):
    sub = tmp_path / "disp.npy"
    np.save(sub, _maps(shape=(400, 500)))
    res = cli("challenge", "check", sub, "--public", public, "--max-size", "1")
    one_line_error(res, "over the limit of 1 MB")


def test_object_array_is_never_unpickled(cli, tmp_path, public):
    marker = tmp_path / "pwned"

    class Evil:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    arr = np.empty(3, object)
    arr[:] = [Evil(), Evil(), Evil()]
    sub = _zip(tmp_path / "s.zip", [("disp.npy", _npy_bytes(arr))])
    _check(cli, sub, public, "object array", "pickle")
    assert not marker.exists()


def test_header_claiming_a_huge_shape(cli, tmp_path, public):
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f4", "fortran_order": False,
                                                  "shape": (3, 10 ** 6, 10 ** 6)})
    sub = tmp_path / "disp.npy"
    sub.write_bytes(header.getvalue() + bytes(64))
    _check(cli, sub, public, "each side must be 1..8192")
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f4", "fortran_order": False, "shape": (3, 100, 100)})
    sub.write_bytes(header.getvalue() + bytes(64))  # 120,000 bytes announced, 64 there
    _check(cli, sub, public, "header announces")


@pytest.mark.parametrize("array, part", [
    (_maps(dtype=np.int32), "dtype int32"),
    (_maps(n=2), "2 maps; the challenge has 3"),
    (_maps()[:, None], "expected 3 dimensions"),
    (_maps()[0], "expected 3 dimensions"),
])
def test_wrong_arrays(cli, tmp_path, public, array, part):
    _check(cli, _zip(tmp_path / "s.zip", [("disp.npy", _npy_bytes(array))]), public, part)


@pytest.mark.parametrize("value, part", [(np.nan, "NaN"), (np.inf, "infinity"), (0.0, "<= 0"), (-1.0, "<= 0")])
def test_bad_values(cli, tmp_path, public, value, part):
    a = _maps()
    a[2, 3, 4] = value
    _check(cli, _zip(tmp_path / "s.zip", [("disp.npy", _npy_bytes(a))]), public, part, "map 2", "cc03")


def test_keyed_form_names_missing_and_extra_ids(cli, tmp_path, public):
    np.savez(tmp_path / "k.npz", aa01=_maps()[0], bb02=_maps()[1], zz99=_maps()[2])
    _check(cli, tmp_path / "k.npz", public, "no map for 1 image(s) (cc03)", "zz99")
    np.savez(tmp_path / "k2.npz", aa01=_maps()[0], bb02=_maps()[1], cc03=_maps())
    _check(cli, tmp_path / "k2.npz", public, "cc03.npy", "expected one H x W map")


def test_not_an_archive(cli, tmp_path, public):
    sub = tmp_path / "s.zip"
    sub.write_bytes(b"hello world")
    _check(cli, sub, public, "neither a zip")
    sub.write_bytes(b"PK\x03\x04garbage")
    _check(cli, sub, public, "not a readable zip")


def test_folder_as_codabench_extracts_it(tmp_path):
    res = tmp_path / "res"
    res.mkdir()
    np.save(res / "disp.npy", _maps())
    (res / "metadata").write_text("x")  # the worker may leave one
    with open_submission(str(res), IDS, 10 ** 9) as sub:
        assert [i for i, _ in sub.maps()] == IDS
    os.symlink("/etc/passwd", res / "link.npy")
    with pytest.raises(RobodepthError, match="symlink"):
        open_submission(str(res), IDS, 10 ** 9)


def test_npz_in_a_deflated_zip_leaves_no_temporary_file(tmp_path):
    buf = io.BytesIO()
    np.savez_compressed(buf, **{i: m for i, m in zip(IDS, _maps())})
    sub = _zip(tmp_path / "s.zip", [("disp.npz", buf.getvalue())])
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    with open_submission(str(sub), IDS, 10 ** 9, scratch=str(scratch)) as s:
        assert s.form == "keyed" and len(list(s.maps())) == 3
    assert list(scratch.iterdir()) == []


def test_maps_are_read_one_at_a_time(tmp_path):
    # 40 maps of 1000 x 1000 float32 (160 MB) in one zip member: peak memory a few maps.
    ids = [f"i{k}" for k in range(40)]
    path = _streamed(tmp_path / "big.zip", (40, 1000, 1000), np.full((1000, 1000), 0.5, np.float32).tobytes(), 40)
    tracemalloc.start()
    with open_submission(str(path), ids, 10 ** 9) as sub:
        n = sum(1 for _ in sub.maps())
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert n == 40 and peak < 20e6
