"""A directory nothing can be written into, even by root: a read-only tmpfs where this
machine allows a mount, else a directory without write permission (for a non-root user)."""

from __future__ import annotations

import os
import subprocess
from contextlib import contextmanager
from pathlib import Path

import pytest


@contextmanager
def read_only_directory(tmp_path: Path):
    """The directory ``tmp_path/ro``, read-only while the block runs (the fixture
    ``read_only_dir`` of tests/conftest.py)."""
    where = tmp_path / "ro"
    where.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(where)],
                             capture_output=True).returncode == 0
    if not mounted:
        if os.geteuid() == 0:
            pytest.skip("root without mount: no directory is read-only for this process")
        where.chmod(0o555)
    try:
        yield where
    finally:
        if mounted:
            subprocess.run(["umount", str(where)], capture_output=True)
        else:
            where.chmod(0o755)


def read_only_reason(where: Path) -> str:
    """The reason an OSError gives for a write into ``where``."""
    try:
        (where / ".probe").write_bytes(b"")
    except OSError as exc:
        return exc.strerror
    raise AssertionError(f"{where} is writable")


@contextmanager
def read_only_tree(tree: Path):
    """``tree`` read-only for every user while the block runs: remounted on itself as a
    read-only bind mount where this machine allows a mount, else (a non-root user) each of
    its folders without write permission."""
    if subprocess.run(["mount", "--bind", str(tree), str(tree)], capture_output=True).returncode == 0:
        try:
            if subprocess.run(["mount", "-o", "remount,ro,bind", str(tree)], capture_output=True).returncode == 0:
                yield tree
                return
        finally:
            subprocess.run(["umount", str(tree)], capture_output=True)
    if os.geteuid() == 0:
        pytest.skip("root without mount: no folder is read-only for this process")
    folders = [tree, *(p for p in tree.rglob("*") if p.is_dir())]
    for folder in folders:
        folder.chmod(0o555)
    try:
        yield tree
    finally:
        for folder in folders:
            folder.chmod(0o755)
