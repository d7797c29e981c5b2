"""The test suite's own shape: its folders mirror the package, each is a package (so two may
hold files of the same name), and no test module imports another (what tests share is in
tests/helpers/ and tests/conftest.py)."""

from __future__ import annotations

import ast

from tests.helpers.paths import PENDING_PACKAGES, REPO

TESTS = REPO / "tests"
# Folders of tests/ that are not a subpackage's tests: shared helpers, data, and the command
# line across commands.
NOT_MIRRORS = {"helpers", "data", "cli"}


def _modules():
    return [p for p in TESTS.rglob("*.py") if "data" not in p.relative_to(TESTS).parts[:1]]


def _imported(path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module)
            names |= {f"{node.module}.{a.name}" for a in node.names}
    return names


def _test_module_names(names) -> list[str]:
    return sorted(n for n in names if n.split(".")[-1].startswith("test_"))


def test_no_test_module_imports_another():
    found = {p.relative_to(REPO).as_posix(): _test_module_names(_imported(p)) for p in _modules()}
    assert {k: v for k, v in found.items() if v} == {}


def test_the_import_check_sees_a_test_module(tmp_path):
    path = tmp_path / "test_x.py"
    path.write_text("from test_evaluate import kitti_c\nimport tests.report.test_report\n"
                    "def f():\n    from tests.evaluation import test_evaluate\n")
    assert _test_module_names(_imported(path)) == [
        "test_evaluate", "tests.evaluation.test_evaluate", "tests.report.test_report"]


def test_every_test_folder_is_a_package_and_mirrors_a_part():
    folders = [p for p in TESTS.iterdir() if p.is_dir() and p.name not in {"data", "__pycache__"}]
    assert [p.name for p in folders if not (p / "__init__.py").is_file()] == []
    assert [p.name for p in TESTS.glob("_*.py") if p.name != "__init__.py"] == [], \
        "shared helpers go in tests/helpers/"
    parts = {p.name for p in (REPO / "robodepth_cli").iterdir() if (p / "__init__.py").is_file()}
    assert sorted(p.name for p in folders if p.name not in parts | NOT_MIRRORS | PENDING_PACKAGES) == []
    assert sorted(PENDING_PACKAGES & parts) == [], "these packages exist now: remove them from PENDING_PACKAGES"
