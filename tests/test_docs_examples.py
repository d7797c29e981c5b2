"""The documentation's examples run and say what the tool does.

The shell examples of `robodepth corrupt` and `robodepth preview` in README.md,
docs/corruptions.md and docs/severity-and-chains.md need only an image: they are run on a
small copy of a test frame (`--size 192x640` becomes `--size 48x160`, and an output under
docs/ goes to the temporary folder), and the outputs their comments name must be there.
The chain errors that severity-and-chains.md quotes are compared with the real ones, and
its Python examples are executed. The other pages' examples need a built dataset, weights
or a cluster, and are not run here. The commands' own `--help` examples are checked to
parse."""

from __future__ import annotations

import re
import shlex

import click
import numpy as np
import pytest
from PIL import Image

from tests.helpers.paths import REFERENCE, REPO

PAGES = ["README.md", "docs/corruptions.md", "docs/severity-and-chains.md"]
SH_BLOCK = re.compile(r"^```sh\n(.*?)^```", re.S | re.M)
PY_BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
TEXT_BLOCK = re.compile(r"^```text\n(.*?)^```", re.S | re.M)


def shell_commands(text: str) -> list[tuple[str, str]]:
    """``(command, comment)`` for each command of the page's ``sh`` blocks, continuation
    lines joined."""
    out = []
    for block in SH_BLOCK.findall(text):
        for line in block.replace("\\\n", " ").splitlines():
            command, _, comment = line.partition("#")
            if command.strip():
                out.append((" ".join(command.split()), comment.strip()))
    return out


def image_examples():
    for page in PAGES:
        for command, comment in shell_commands((REPO / page).read_text()):
            if command.startswith(("robodepth corrupt ", "robodepth preview ")):
                yield pytest.param(command, comment, id=f"{page}: {command}")


@pytest.fixture
def frame(tmp_path, monkeypatch):
    """A small frame.png in the current folder, as the examples name it."""
    monkeypatch.chdir(tmp_path)
    small = Image.open(REFERENCE / "kitti" / "kitti_like_md2__input.png").convert("RGB")
    small.resize((160, 48), Image.LANCZOS).save(tmp_path / "frame.png")
    return tmp_path / "frame.png"


def test_the_pages_have_image_examples():
    assert len(list(image_examples())) >= 10


@pytest.mark.parametrize("command,comment", list(image_examples()))  # a list: pytest 10 refuses generators
def test_image_example_runs_and_writes_what_it_says(command, comment, frame, cli):
    args = shlex.split(command.replace("--size 192x640", "--size 48x160")
                       .replace("docs/images/", "images/"))[1:]
    res = cli(*args)
    assert res.exit_code == 0, res.output
    out = args[args.index("--out") + 1]
    if out.endswith(".png"):
        assert (frame.parent / out).is_file()
    named = [w for w in comment.split() if w.endswith(".png")]
    for name in named:  # NAME/LEVEL stand for every corruption and level
        pattern = name.replace("NAME", "*").replace("LEVEL", "*")
        assert list(frame.parent.glob(pattern)), f"{command}: no {name}"
    if "NAME/LEVEL" in comment:
        assert len(list(frame.parent.glob(pattern))) == 18 * 5


def test_quoted_chain_errors_are_the_real_ones(frame, cli):
    page = (REPO / "docs" / "severity-and-chains.md").read_text()
    block = [b for b in TEXT_BLOCK.findall(page) if "robodepth: error:" in b][0]
    lines = [line for line in block.splitlines() if line.strip()]
    assert len(lines) == 5
    for line in lines:
        chain = re.search(r"chain '([^']*)'", line).group(1)
        res = cli("corrupt", frame, "-c", chain, "-l", "2", "--out", "x.png")
        assert res.exit_code == 2
        want = ".*".join(re.escape(part) for part in line.split("..."))  # "..." elides a list
        assert re.fullmatch(want, res.output.strip()), (line, res.output)
    quoted = re.search(r"`(robodepth: error: --level: [^`]*)`", page.replace("\n", " ")).group(1)
    res = cli("corrupt", frame, "-c", "fog", "-l", "5.5", "--out", "x.png")
    assert res.output.strip() == quoted


def test_python_examples_of_severity_and_chains_run():
    """Executed in order in one namespace, given what the page says they take: ``image`` an
    H x W x 3 uint8 array, ``index`` a sample's key, ``epoch`` an epoch."""
    blocks = PY_BLOCK.findall((REPO / "docs" / "severity-and-chains.md").read_text())
    assert len(blocks) == 2
    image = np.asarray(Image.open(REFERENCE / "kitti" / "kitti_like_md2__input.png")
                       .convert("RGB").resize((64, 32)))
    for index in range(4):  # p = 0.8: some draws apply nothing
        namespace = {"image": image, "index": index, "epoch": 2}
        for block in blocks:
            exec(compile(block, "severity-and-chains.md", "exec"), namespace)
        assert namespace["applied"] == "" or "+" in namespace["applied"] or ":" in namespace["applied"]


def _help_examples():
    from robodepth_cli.cli import main

    def walk(cmd, path):
        if isinstance(cmd, click.Group):
            for name, sub in sorted(cmd.commands.items()):
                yield from walk(sub, (*path, name))
        else:
            yield path, cmd

    for path, cmd in walk(main, ()):
        with click.Context(cmd, info_name=" ".join(("robodepth", *path))) as ctx:
            text = cmd.get_help(ctx)
        examples = []
        for line in re.sub(r"\\\n\s*", " ", text).splitlines():
            code = line.split("#")[0].strip()
            if code.startswith(f"robodepth {' '.join(path)} ") or code == f"robodepth {' '.join(path)}":
                examples.append(code)
        yield path, cmd, examples


def test_help_examples_parse_and_keep_their_line_breaks():
    """An example of a command's --help is one command line (a lost backslash would run two
    lines into one, with the next line's indentation in the middle) whose options the
    command knows."""
    seen = 0
    for path, cmd, examples in _help_examples():
        for example in examples:
            seen += 1
            assert not re.search(r"\S {3,}-", example), f"a lost line continuation: {example}"
            args = shlex.split(example)[1 + len(path):]
            cmd.make_context(" ".join(path), args, resilient_parsing=True)  # unknown options raise
    assert seen >= 20
