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


LOCK = "robodepth_cli/constraints.txt"
# Every distribution whose version decides a pixel of a build.
PIXEL_DISTRIBUTIONS = {"numpy", "opencv-python-headless", "scipy", "scikit-image", "pillow", "numba",
                       "llvmlite", "fpng", "imagecorruptions-imaug", "av", "torch"}


def pip_lines(lines: list[str]) -> list[list[str]]:
    return [ln.split() for ln in lines if " pip install " in ln]


def lock_pins() -> dict[str, str]:
    pins = {}
    for line in (REPO / LOCK).read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, version = line.split("==")
            pins[name.lower()] = version
    return pins


def test_every_install_step_takes_the_lock():
    lines = pip_lines(make_n())
    assert len(lines) == 3
    for words in lines:
        assert words[words.index("-c") + 1] == LOCK, words
        assert not [w for w in words if "==" in w]  # versions come from the lock alone
    torch, editable, frost = lines
    assert torch[-1] == "torch" and "--index-url" not in torch
    assert "-e" in editable
    assert frost[-1] == "imagecorruptions-imaug" and "--no-deps" in frost


def test_install_compiles_the_kernels_once_the_package_and_textures_are_in():
    # The warm-up (tests/test_warmup.py) fills the numba cache the installed package reads;
    # frost's kernels need the textures installed just before.
    lines = make_n()
    commands = [ln for ln in lines if not ln.startswith("#")]
    warm = [i for i, ln in enumerate(commands) if ln.split()[1:] == ["-m", "robodepth_cli.warmup"]]
    assert len(warm) == 1, lines
    last_pip = max(i for i, ln in enumerate(commands) if " pip install " in ln)
    assert warm[0] == last_pip + 1


def test_torch_index_installs_torch_alone_from_that_index():
    index = "file:///somewhere/cpu"
    torch, editable, frost = pip_lines(make_n(f"TORCH_INDEX={index}"))
    assert torch[torch.index("--index-url") + 1] == index and torch[-1] == "torch"
    assert torch[torch.index("-c") + 1] == LOCK
    # The package and its extras still come from the default index, torch already pinned.
    assert "--index-url" not in editable and "--index-url" not in frost


def test_the_lock_pins_every_pixel_distribution_exactly():
    from packaging.requirements import Requirement

    pins = lock_pins()
    assert set(pins) == PIXEL_DISTRIBUTIONS
    text = (REPO / "pyproject.toml").read_text()
    # pyproject.toml keeps ranges, and the locked versions are inside them.
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10: pip's own copy of the same parser
        from pip._vendor import tomli as tomllib

    project = tomllib.loads(text)["project"]
    specs = project["dependencies"] + [s for extra in project["optional-dependencies"].values() for s in extra]
    checked = set()
    for spec in specs:
        req = Requirement(spec)
        if req.name.lower() in pins:
            assert req.specifier.contains(pins[req.name.lower()]), spec
            checked.add(req.name.lower())
    assert {"numpy", "opencv-python-headless", "scipy", "scikit-image", "pillow", "numba", "fpng"} <= checked
    assert re.search(r'^style = \["torch==([^"]+)"\]', text, re.M).group(1) == pins["torch"]


def test_the_installed_versions_are_the_locked_ones():
    # make install installed this environment: the locked install.
    from importlib import metadata

    for name, version in lock_pins().items():
        assert metadata.version(name).split("+")[0] == version, name


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
