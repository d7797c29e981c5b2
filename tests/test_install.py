"""`make install`: which torch it installs, and the documented way to choose the CPU build."""

from __future__ import annotations

import re
import shutil
import subprocess

import pytest

from _paths import REPO


def make_n(*args: str) -> list[str]:
    """The commands ``make -n install ARGS`` would run, one per line."""
    if shutil.which("make") is None:
        pytest.skip("make is not installed on this machine")
    res = subprocess.run(["make", "-n", "-C", str(REPO), "install", *args], capture_output=True,
                         text=True, check=True)
    return res.stdout.splitlines()


def torch_lines(lines: list[str]) -> list[str]:
    return [ln for ln in lines if re.search(r"\btorch==", ln)]


def test_plain_install_pins_torch_from_the_default_index():
    (line,) = torch_lines(make_n())
    assert line.split()[-3:] == ["pip", "install", "torch==2.13.0"]
    assert "--index-url" not in line


def test_torch_index_installs_torch_alone_from_that_index():
    index = "file:///somewhere/cpu"
    lines = make_n(f"TORCH_INDEX={index}")
    (line,) = torch_lines(lines)
    words = line.split()
    assert words[words.index("--index-url") + 1] == index and words[-1] == "torch==2.13.0"
    # The package and its extras still come from the default index, torch already pinned.
    (editable,) = [ln for ln in lines if " -e " in ln]
    assert "--index-url" not in editable


def test_no_package_index_address_in_the_repository():
    # The CPU index's address is PyTorch's to give (its "Get started" page), not ours.
    for name in ("Makefile", "README.md", "docs/development.md"):
        text = (REPO / name).read_text()
        assert "download.pytorch.org" not in text and "/whl/" not in text, name
    assert "TORCH_INDEX" in (REPO / "README.md").read_text()
    assert "TORCH_INDEX" in (REPO / "docs/development.md").read_text()
