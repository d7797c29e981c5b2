"""`make install`: which torch it installs, and the documented way to choose the CPU build."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys

import pytest

from tests.helpers.paths import REPO


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


def browser_step(tmp_path, *, have_browser: bool, apt_get: bool, uid: int, apt_fails=False):
    """Run the browser step of ``make -n install`` in a shell whose PATH holds only stand-ins
    (a browser, apt-get, id) that log their calls: ``(stderr, calls)``."""
    lines = make_n("CHROMIUM=robodepth-test-browser")
    start = next(i for i, ln in enumerate(lines) if ln.startswith("if command -v robodepth-test-browser"))
    end = next(i for i in range(start, len(lines)) if lines[i].strip() == "fi")
    script = "\n".join(lines[start:end + 1])
    fake = tmp_path / f"bin-{have_browser}-{apt_get}-{uid}-{apt_fails}"
    fake.mkdir()
    log = fake / "calls.log"

    def tool(name, body):
        (fake / name).write_text(f"#!/bin/sh\n{body}\n")
        (fake / name).chmod(0o755)

    tool("id", f'echo {uid}')
    if have_browser:
        tool("robodepth-test-browser", "exit 0")
    if apt_get:
        tool("apt-get", f'echo "apt-get $*" >> {log}\nexit {1 if apt_fails else 0}')
    res = subprocess.run(["/bin/sh", "-c", script], capture_output=True, text=True,
                         env={"PATH": str(fake)})
    assert res.returncode == 0, res.stderr
    calls = log.read_text().splitlines() if log.exists() else []
    return res.stderr, calls


def test_install_gets_the_browser_where_the_system_allows(tmp_path):
    # already there: nothing done, nothing said
    assert browser_step(tmp_path, have_browser=True, apt_get=True, uid=0) == ("", [])
    # missing, apt-get, root: installed
    err, calls = browser_step(tmp_path, have_browser=False, apt_get=True, uid=0)
    assert calls == ["apt-get update", "apt-get install -y chromium"] and err == ""
    # apt-get fails (no network): one line saying so, and the rest of make install goes on
    err, calls = browser_step(tmp_path, have_browser=False, apt_get=True, uid=0, apt_fails=True)
    assert calls == ["apt-get update"]
    assert err.strip() == ("make install: apt-get could not install chromium; the browser test "
                           "will fail until it is installed")
    # not root, or no apt-get: how to get it, and nothing attempted
    for apt_get, uid in ((True, 1000), (False, 0)):
        err, calls = browser_step(tmp_path, have_browser=False, apt_get=apt_get, uid=uid)
        assert calls == []
        assert len(err.strip().splitlines()) == 1
        assert "the browser test needs Chromium" in err and "apt-get install -y chromium" in err


def test_ci_runs_exactly_the_readme_set_up():
    ci = [ln.strip() for ln in (REPO / ".ci" / "run").read_text().splitlines()
          if ln.strip() and not ln.startswith("#")]
    assert [ln for ln in ci if ln.startswith("make")] == ["make install", "make test"]
    assert not [ln for ln in ci if "apt-get" in ln or "chromium" in ln]
    readme = (REPO / "README.md").read_text()
    block = readme[readme.index("## Set-up"):].split("```sh\n")[1].split("```")[0]
    assert [ln.split("#")[0].strip() for ln in block.splitlines()] == ["make install", "make test"]


def test_make_test_lints_first_with_the_installed_ruff():
    """`make test` runs the linter before the suite, with the rule set pyproject.toml states,
    and `make install` brings the linter (the test extra)."""
    if shutil.which("make") is None:
        pytest.skip("make is not installed on this machine")
    lines = subprocess.run(["make", "-n", "-C", str(REPO), "test"], capture_output=True, text=True,
                           check=True).stdout.splitlines()
    lines = [ln for ln in lines if not ln.startswith("make")]  # make's "Entering directory"
    assert [ln.split()[1:4] for ln in lines] == [["-m", "ruff", "check"], ["-m", "pytest", "-q"]]
    text = (REPO / "pyproject.toml").read_text()
    lint = text[text.index("[tool.ruff.lint]"):]
    assert re.search(r'^select = \["E9", "F"', lint, re.M)  # a stated rule set, not ruff's default
    assert re.search(r'^test = \[[^\]]*"ruff', text, re.M)
    (editable,) = [ln for ln in make_n() if " -e " in ln]
    assert "test" in re.search(r"\[([\w,]+)\]", editable).group(1).split(",")
    # The tree as committed passes it.
    res = subprocess.run([sys.executable, "-m", "ruff", "check", str(REPO)], capture_output=True,
                         text=True, cwd=REPO)
    assert res.returncode == 0, res.stdout + res.stderr
