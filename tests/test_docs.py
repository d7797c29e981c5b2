"""The documentation holds together: README.md and docs/*.md link only to files and headings
that exist, every docs page is in both indexes, and every command of `robodepth` with all its
options is documented on one page."""

import re

import click
import pytest
from tests.helpers.paths import PENDING_PACKAGES, REPO

from robodepth_cli.cli import main

PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]

# Pages other engineers are writing now, linked from both indexes ahead of them; a link to
# one of these may dangle until it lands. Remove a name once its page is on main.
PENDING: set[str] = set()

FENCE = re.compile(r"^(```|~~~).*?^\1", re.S | re.M)
INLINE_CODE = re.compile(r"`[^`\n]*`")
LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)")


def _prose(text: str) -> str:
    return INLINE_CODE.sub("", FENCE.sub("", text))


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading: markup dropped, lower case, punctuation removed,
    spaces to hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).replace("`", "")
    text = re.sub(r"[^\w\- ]", "", text.strip().lower())
    return text.replace(" ", "-")


def _anchors(path) -> set[str]:
    seen: dict[str, int] = {}
    for line in FENCE.sub("", path.read_text()).splitlines():
        m = re.match(r"#{1,6} (.*)", line)
        if m:
            slug = _slug(m.group(1))
            n = seen.get(slug, 0)
            seen[slug] = n + 1
            yield slug if n == 0 else f"{slug}-{n}"


def _links(page):
    for target in LINK.findall(_prose(page.read_text())):
        if re.match(r"[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
            continue
        yield target


def test_pages_exist():
    names = {p.name for p in PAGES}
    assert {"README.md", "corruptions.md", "datasets-and-layout.md", "ground-truth.md",
            "evaluation.md", "score.md", "custom-and-torch.md", "cluster.md", "performance.md",
            "development.md"} <= names


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(REPO).as_posix())
def test_relative_links_lead_somewhere(page):
    broken = []
    for target in _links(page):
        file, _, anchor = target.partition("#")
        dest = (page.parent / file).resolve() if file else page
        rel = dest.relative_to(REPO).as_posix() if dest.is_relative_to(REPO) else str(dest)
        if not dest.exists():
            if rel not in PENDING:
                broken.append(f"{target}: no file {rel}")
            continue
        if anchor and dest.suffix == ".md" and anchor not in set(_anchors(dest)):
            broken.append(f"{target}: no heading #{anchor} in {rel}")
    assert not broken, f"{page.name}: " + "; ".join(broken)


def test_link_check_sees_a_broken_link(tmp_path):
    page = tmp_path / "p.md"
    page.write_text("# Top\n\nSee [a](missing.md), [b](#top), [c](#nowhere), `[d](x.md)`.\n")
    assert list(_links(page)) == ["missing.md", "#top", "#nowhere"]
    assert set(_anchors(page)) == {"top"}
    assert _slug("One image: `robodepth corrupt` and `robodepth preview`") == \
        "one-image-robodepth-corrupt-and-robodepth-preview"


def test_every_docs_page_is_in_both_indexes():
    pages = {p.relative_to(REPO).as_posix() for p in (REPO / "docs").glob("*.md")} | PENDING
    pages.discard("docs/README.md")
    readme = {(REPO / t.partition("#")[0]).resolve() for t in _links(REPO / "README.md")}
    index = {(REPO / "docs" / t.partition("#")[0]).resolve() for t in _links(REPO / "docs" / "README.md")}
    for rel in sorted(pages):
        assert (REPO / rel).resolve() in readme, f"README.md's 'Read more' does not link {rel}"
        assert (REPO / rel).resolve() in index, f"docs/README.md does not link {rel}"


def _commands(cmd=main, path=()):
    yield path, cmd
    if isinstance(cmd, click.Group):
        for name, sub in sorted(cmd.commands.items()):
            yield from _commands(sub, (*path, name))


def _mentions(text: str, word: str) -> bool:
    return re.search(r"(?<![\w-])" + re.escape(word) + r"(?![\w-])", text) is not None


def test_every_command_and_option_is_documented():
    """For each command, one page names `robodepth CMD` and every option it takes (long and
    short forms, both sides of an on/off flag), so that page is its reference."""
    texts = {p.relative_to(REPO).as_posix(): p.read_text() for p in PAGES}
    problems = []
    for path, cmd in _commands():
        name = " ".join(("robodepth", *path))
        opts = sorted({o for p in cmd.params if isinstance(p, click.Option)
                       for o in (*p.opts, *p.secondary_opts)} - {"--help"})
        best = None
        for page, text in texts.items():
            if not _mentions(text, name):
                continue
            missing = [o for o in opts if not _mentions(text, o)]
            if best is None or len(missing) < len(best[1]):
                best = (page, missing)
        if best is None:
            problems.append(f"{name}: on no page")
        elif best[1]:
            problems.append(f"{name}: {best[0]} lacks {', '.join(best[1])}")
    assert not problems, "undocumented: " + "; ".join(problems)


PENDING_FOLDERS = {f"robodepth_cli/{name}/" for name in PENDING_PACKAGES}


def _tree_folders(text: str) -> set[str]:
    """The folders of the first fenced block after "## The code": one per line, two spaces of
    indent per level, a name ending with "/" (what follows it is its description)."""
    tour = text[text.index("## The code"):]
    fence = FENCE.search(tour)
    assert fence, 'no fenced tree after "## The code"'
    block = fence.group(0).splitlines()[1:-1]
    folders, path = set(), []
    for line in block:
        m = re.match(r"( *)(\w+)/(?:\s|$)", line)
        assert m, f"not a folder line: {line!r}"
        depth = len(m.group(1)) // 2
        path[depth:] = [m.group(2)]
        folders.add("/".join(path) + "/")
    return folders


def test_tree_parser_reads_nesting():
    text = "## The code\n\n```\nroot/  the top\n  a/   one\n    b/ two\n  c/\n```\n"
    assert _tree_folders(text) == {"root/", "root/a/", "root/a/b/", "root/c/"}


def test_development_tree_is_the_package_folders():
    """The layout tree in docs/development.md names every package folder, and only those: a
    folder added, moved or removed fails here until the tree follows."""
    tree = _tree_folders((REPO / "docs" / "development.md").read_text())
    real = {p.parent.relative_to(REPO).as_posix() + "/" for p in (REPO / "robodepth_cli").rglob("__init__.py")}
    assert "robodepth_cli/" in tree
    assert sorted(real - tree) == [], "folders missing from the tree"
    assert sorted(tree - real - PENDING_FOLDERS) == [], "the tree names folders that do not exist"
    assert sorted(PENDING_FOLDERS & real) == [], "these folders exist now: remove them from PENDING_FOLDERS"


def test_pages_name_every_depth_aware_corruption_and_what_video_covers():
    from robodepth_cli.corruptions import DEPTH_NAMES

    torch_page = (REPO / "docs" / "torch-engine.md").read_text(encoding="utf-8")
    row = next(ln for ln in torch_page.splitlines() if "[depth-aware]" in ln and ln.startswith("|"))
    assert [n for n in DEPTH_NAMES if n not in row] == []
    index = (REPO / "docs" / "README.md").read_text(encoding="utf-8")
    video = next(ln for ln in index.splitlines() if ln.startswith("| [video.md]"))
    assert "over time" in video and "flicker" in video


def test_the_performance_page_stays_under_8_kb():
    """A reference page of figures, read at a glance: under 8 KB (history belongs in the log)."""
    size = (REPO / "docs" / "performance.md").stat().st_size
    assert size < 8 * 1024, f"docs/performance.md is {size} bytes; trim its prose"


def test_the_readme_counts_what_robodepth_list_lists():
    from click.testing import CliRunner

    from robodepth_cli.benchmark_facts import CORRUPTIONS, DEPTH_AWARE
    from robodepth_cli.corruptions import REGISTRY

    import json

    listed = CliRunner().invoke(main, ["list", "--format", "json"])
    assert listed.exit_code == 0
    assert len(json.loads(listed.output)) == len(REGISTRY)
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    (line,) = [ln for ln in readme.splitlines() if ln.startswith("robodepth list ")]
    counts = [int(n) for n in re.findall(r"\b(\d+)\b", line.partition("#")[2])]
    assert counts == [len(REGISTRY), len(CORRUPTIONS), len(DEPTH_AWARE)], line
