"""Atomic writes and the rule that recognises their leftovers."""

from __future__ import annotations

import hashlib
import os

import pytest

from tests.helpers.readonly import read_only_reason
from robodepth_cli import files
from robodepth_cli.errors import RobodepthError


def test_a_killed_writes_leftover_is_recognised_and_nothing_else(tmp_path, monkeypatch):
    seen = []

    def killed(src, dst):  # the process dies between writing the temporary file and the rename
        seen.append(os.path.basename(src))
        raise KeyboardInterrupt

    monkeypatch.setattr(files.os, "replace", killed)
    with pytest.raises(KeyboardInterrupt):
        files.write_atomic(tmp_path / "frame.png", b"data")
    monkeypatch.undo()
    assert len(seen) == 1 and files.is_temporary(seen[0])
    assert not (tmp_path / seen[0]).exists()  # removed on the way out
    for name in ("frame.png", ".part", "frame.png.part", ".hidden", "manifest.csv"):
        assert not files.is_temporary(name), name


def test_write_atomic_and_hashes(tmp_path):
    target = tmp_path / "a" / "b.bin"
    files.write_atomic(target, b"x" * 3_000_000)
    assert target.read_bytes() == b"x" * 3_000_000
    assert os.listdir(target.parent) == ["b.bin"]
    want = hashlib.sha256(b"x" * 3_000_000).hexdigest()
    assert files.sha256_file(target) == files.sha256_bytes(target.read_bytes()) == want


def test_a_read_only_file_system_is_named_as_such(read_only_dir, fixtures_dir, cli):
    reason = read_only_reason(read_only_dir)  # "Read-only file system" where the mount works
    for target, ending in ((read_only_dir / "out.png", f"cannot write ({reason})"),
                           (read_only_dir / "new" / "deeper" / "out.png",
                            f"cannot write ({read_only_dir}: {reason})")):
        with pytest.raises(RobodepthError) as info:
            files.check_writable(target, "--out")
        assert str(info.value) == f"--out {target}: {ending}"
    frame = next((fixtures_dir / "kitti_raw").rglob("*.png"))
    res = cli("corrupt", frame, "-c", "fog", "-l", "1", "--out", read_only_dir / "sub" / "fog.png")
    assert res.exit_code == 2  # refused before any work, in check_writable's words
    assert res.output.strip().endswith(f"({read_only_dir}: {reason})"), res.output
