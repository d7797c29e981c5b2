"""The rules between the package's parts, written down where they are checked.

The imports of every module of ``robodepth_cli`` are read from its source (``ast``: imports
at the top, inside functions, ``importlib.import_module("...")`` with a literal name), so
a lazy import counts like any other: it is a dependency all the same, only paid later.
Then:

- no import circle between modules;
- the parts depend in one direction (below: who may not import whom);
- a subpackage's ``__init__.py`` imports no heavy library (``robodepth --help`` stays fast);
- no private name (leading underscore) is imported from outside the subpackage that owns it;
- the names the documentation promises (``open_dataset``, ``api``, ``torch``,
  ``corruptions``) exist with the documented parameters.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import re
from pathlib import Path

import pytest

from tests.helpers.paths import REPO

PKG = REPO / "robodepth_cli"
ROOT = "robodepth_cli"

HEAVY = {"numpy", "torch", "cv2", "PIL", "scipy", "skimage", "numba", "matplotlib", "transformers",
         "dask", "distributed", "h5py", "joblib", "pyarrow", "webdataset", "datasets"}

# The basics every part may use; they import nothing of the package but each other.
FOUNDATION = {"errors", "files", "sourcekeys", "integers", "progress", "benchmark_facts"}

# importer prefix -> the package prefixes it may not import. A prefix "x" means the module x
# or anything in the subpackage x/. From the ground up: the foundation; the corruptions;
# seeding; sources (where images and depth come from) with output (the names a build
# leaves); the ground truth (groundtruth/: made, written, read) and the predictions folder
# (predictions.py); the evaluation (numpy, numba); the build (building/); api, export, models,
# report, running; the torch package; commands; cli.
FORBIDDEN = {
    # The corruptions are the library's core, usable without the rest (torch transforms,
    # corrupt/preview): besides themselves only the foundation, seeding and imageio
    # (the engine's check of an input image) -- see test_corruptions_stand_alone.
    "seeding": {"corruptions", "imageio", "sources", "output", "building", "evaluation", "api",
                "torch", "cli", "commands"},
    # (sources/ may ask output/layout.py for the output-path rule: it owns every output name.)
    "sources": {"building", "evaluation", "commands", "output.manifest", "output.record",
                "output.verify", "api", "torch", "cli", "models", "running", "report", "export",
                "groundtruth"},
    # (verify is handed the build plan's outputs by its command: the datasets know them.)
    "output": {"building", "commands", "evaluation", "api", "torch", "cli", "running", "report",
               "models", "export", "styles", "groundtruth", "predictions", "sources"},
    # The ground truth is read with the evaluation's rule of valid pixels, handed to it.
    "groundtruth": {"building", "commands", "cli", "torch", "running", "models", "report", "api",
                    "export", "predictions", "styles", "evaluation"},
    "predictions": {"api", "building", "commands", "cli", "torch", "running", "models", "report",
                    "evaluation", "export", "sources", "output", "styles", "groundtruth"},
    "evaluation": {"building", "commands", "cli", "torch", "running", "report", "models",
                   "export", "styles", "output"},
    "styles": {"building", "commands", "evaluation", "output", "sources", "api", "torch", "cli",
               "running", "groundtruth", "predictions", "report", "models", "export"},
    "building": {"commands", "cli", "evaluation", "torch", "models", "running", "api", "report",
                 "export"},
    "models": {"building", "commands", "cli", "evaluation", "torch", "running", "report", "export",
               "groundtruth", "sources"},
    # api reads a build; the package's open_dataset hands it an export's store.
    "api": {"building", "commands", "cli", "torch", "running", "evaluation", "report", "models",
            "export"},
    # `robodepth run` joins the build's inputs, the models and the evaluation; only the
    # commands use it.
    "running": {"commands", "cli", "torch", "building.executors", "building.cluster", "report",
                "export"},
    # export/ reads a build through the api it is handed (commands/export.py), never importing it;
    # a build's ground-truth files it reads and writes back through groundtruth/'s own readers.
    "export": {"building", "commands", "cli", "torch", "evaluation", "models", "styles", "running",
               "api", "report", "predictions", "groundtruth.write", "groundtruth.depthmaps"},
    "report": {"building", "commands", "cli", "torch", "running", "models", "styles", "export",
               "sources", "groundtruth"},
    # The transforms may read a held-out protocol file as a build checks it (building/config.py);
    # they never run a build.
    "torch": {"building.pipeline", "building.checks", "building.executors", "building.cluster",
              "groundtruth.write", "commands", "cli", "running"},
}
CORRUPTIONS_MAY_IMPORT = {"corruptions", "errors", "sourcekeys", "seeding", "benchmark_facts", "imageio"}

# Imports that break the rules above today, each with the change that removes it. The list
# only shrinks: a new violation fails, and so does an entry that no longer happens.
KNOWN_VIOLATIONS: set[tuple[str, str]] = set()

def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PKG.rglob("*.py")):
        parts = path.relative_to(PKG).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path  # "" is the package itself
    return out


MODULES = _modules()


def _resolve(importer: str, is_package: bool, level: int, module: str | None) -> str | None:
    """The package-relative name of an import (None when it is outside the package)."""
    if level == 0:
        if module != ROOT and not (module or "").startswith(ROOT + "."):
            return None
        return (module or "")[len(ROOT) + 1:]
    base = importer.split(".") if importer else []
    if not is_package:
        base = base[:-1]
    if level > 1:
        base = base[:len(base) - (level - 1)]
    return ".".join(base + ([module] if module else []))


def _imports(name: str, path: Path) -> tuple[set[str], set[str]]:
    """(package modules, outside top-level packages) that ``name`` imports anywhere in it."""
    inside, outside = set(), set()
    is_package = path.name == "__init__.py"

    def add(target: str | None, top: str | None, names=()):
        if target is None:
            outside.add(top.split(".")[0])
            return
        # "from x import y" imports the module x.y when there is one; x itself otherwise
        # (as a parent package it is imported either way, like the parent of any module).
        subs = [f"{target}.{n}".lstrip(".") for n in names if f"{target}.{n}".lstrip(".") in MODULES]
        if subs and len(subs) == len(names):
            inside.update(subs)
        else:
            inside.add(target)
            inside.update(subs)

    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                add(_resolve(name, is_package, 0, alias.name), alias.name)
        elif isinstance(node, ast.ImportFrom):
            add(_resolve(name, is_package, node.level, node.module), node.module or "",
                [a.name for a in node.names])
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr == "import_module" and node.args
              and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)):
            text = node.args[0].value
            level = len(text) - len(text.lstrip("."))
            add(_resolve(name, is_package, level, text.lstrip(".") or None), text.lstrip("."))
    inside = {m for m in inside if m in MODULES and m != name}
    return inside, outside


GRAPH = {name: _imports(name, path)[0] for name, path in MODULES.items()}


def _under(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _label(module: str) -> str:
    return f"{ROOT}.{module}" if module else ROOT


def test_the_import_reader_sees_every_kind_of_import():
    """The rules below are only as good as this reader: a top-level, a relative, a lazy
    (in a function) and an importlib import are all seen."""
    assert "output.manifest" in GRAPH["api"]  # from .output.manifest import ... (top level)
    assert "styles.inputs" in GRAPH["sources.datasets"]  # inside a method
    assert "corruptions._engine" in GRAPH["corruptions"]  # importlib.import_module("._engine")
    assert "commands.common" in GRAPH["commands.corrupt"]  # from . import common
    assert "api" in GRAPH[""]  # the package's lazy open_dataset
    assert {"numpy"} <= _imports("imageio", MODULES["imageio"])[1]


def test_no_import_circle():
    assert _cycles(GRAPH) == [], "modules that import each other (a circle), via any import"


def _violations() -> set[tuple[str, str]]:
    found = set()
    for importer, targets in GRAPH.items():
        for target in targets:
            top = target.split(".")[0]
            if _under(importer, "corruptions") and top not in CORRUPTIONS_MAY_IMPORT:
                found.add((importer, target))
            if _under(target, "commands") and not (_under(importer, "commands") or importer == "cli"):
                found.add((importer, target))
            if target == "cli":
                found.add((importer, target))  # the entry point; nothing builds on it
            if (_under(importer, "commands") and importer != "commands" and _under(target, "commands")
                    and target not in ("commands", "commands.common")):
                found.add((importer, target))  # a command shares through common.py, not another command
            if importer in FOUNDATION and top not in FOUNDATION:
                found.add((importer, target))
            if importer == "" and target not in ("api", "export.reader", "formats"):
                found.add((importer, target))  # the package's face: open_dataset (build or export), lazily
            for prefix, banned in FORBIDDEN.items():
                if _under(importer, prefix) and any(_under(target, b) for b in banned):
                    found.add((importer, target))
    return found


def test_imports_go_one_way():
    found = _violations()
    new = sorted(found - KNOWN_VIOLATIONS)
    assert new == [], "imports against the direction of the parts: " + ", ".join(
        f"{_label(a)} -> {_label(b)}" for a, b in new)
    gone = sorted(KNOWN_VIOLATIONS - found)
    assert gone == [], f"fixed, so remove from KNOWN_VIOLATIONS: {gone}"


def _private_scope(owner: str) -> str:
    """Where a private name of ``owner`` may be imported: anywhere in a subpackage when
    ``owner`` is that subpackage or one of its modules; only in ``owner`` itself when it is
    a module of the package's top level."""
    path = MODULES.get(owner)
    if path is not None and path.name == "__init__.py":
        return owner
    package = owner.rpartition(".")[0]
    return package or owner


def _private_imports() -> set[tuple[str, str]]:
    """(importer, name): a private name (leading underscore, a module or a member) imported
    from outside the subpackage that owns it."""
    found = set()
    for name, path in MODULES.items():
        is_package = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                target = _resolve(name, is_package, node.level, node.module)
                fulls = [] if target is None else [f"{target}.{a.name}".lstrip(".") for a in node.names]
            elif isinstance(node, ast.Import):
                fulls = [t for t in (_resolve(name, is_package, 0, a.name) for a in node.names) if t]
            else:
                continue
            for full in fulls:
                parts = full.split(".")
                for i, part in enumerate(parts):
                    if part.startswith("_") and not part.startswith("__"):
                        if not _under(name, _private_scope(".".join(parts[:i]))):
                            found.add((name, full))
                        break
    return found


def test_no_private_name_crosses_a_subpackage():
    assert sorted(_private_imports()) == [], "import the public name, or make the name public"


def test_the_private_rule_catches_what_it_forbids():
    assert _private_scope("api") == "api"  # api's private names are its own
    assert _private_scope("report.plot") == "report"
    assert _private_scope("corruptions") == "corruptions"
    assert _under("corruptions.torch_engine._engine", _private_scope("corruptions"))
    assert not _under("sources.depth_io", _private_scope("corruptions"))


def test_the_rules_catch_what_they_forbid():
    """Each kind of rule flags a made-up import that breaks it (a rule that can never fire
    would pass forever)."""
    saved = {k: set(v) for k, v in GRAPH.items()}
    try:
        for importer, target in [("corruptions.fog", "sources.datasets"), ("sources.splits", "building.config"),
                                 ("output.manifest", "commands.common"), ("evaluation.scores", "building.pipeline"),
                                 ("api", "commands"), ("errors", "imageio"), ("torch", "cli"),
                                 ("seeding", "corruptions.severity"), ("export.driver", "api"),
                                 ("output.verify", "building.checks"), ("predictions", "api"),
                                 ("groundtruth.read", "evaluation.protocols"), ("sources.depth_io", "groundtruth.nyu"), ("evaluation.scores", "report.plot"),
                                 ("commands.run", "commands.evaluate")]:
            GRAPH[importer].add(target)
            assert (importer, target) in _violations(), (importer, target)
            GRAPH[importer].discard(target)
        GRAPH["errors"].add("files")
        GRAPH["files"].add("errors")
        assert _cycles(GRAPH) == [["errors", "files"]]
    finally:
        GRAPH.clear()
        GRAPH.update(saved)


def test_corruptions_stand_alone():
    """What the corruptions import of the package, beyond themselves: the error base, the
    seeding rule, the benchmark facts and the input-image check; nothing of how a build, an
    evaluation or the command line works."""
    used = {t.split(".")[0] for m, ts in GRAPH.items() if _under(m, "corruptions") for t in ts}
    assert used - {"corruptions"} <= CORRUPTIONS_MAY_IMPORT - {"corruptions"}


def test_the_evaluation_is_numpy():
    """evaluation/ computes with numpy, numba (its inner loops, evaluation/kernels.py) and
    OpenCV's resize (as the reference evaluators; the rank statistics are SciPy's); plotting
    is the report's, models are torch's."""
    used = set().union(*(_imports(n, p)[1] for n, p in MODULES.items() if _under(n, "evaluation")))
    assert used & HEAVY <= {"numpy", "numba", "cv2", "scipy"}, sorted(used & HEAVY)
    assert "scipy" not in set().union(*(_imports(n, p)[1] for n, p in MODULES.items()
                                        if _under(n, "evaluation") and n != "evaluation.ranking"))


@pytest.mark.parametrize("init", sorted(str(p.relative_to(PKG)) for p in PKG.rglob("__init__.py")))
def test_package_init_imports_no_heavy_library(init):
    path = PKG / init
    name = ".".join(Path(init).parent.parts)
    heavy = _imports(name, path)[1] & HEAVY
    assert not heavy, f"{init} imports {sorted(heavy)}: keep it light (robodepth --help loads it)"


# --- the public API, as the documentation uses it ------------------------------------------

# (module, name, documented parameters with their documented defaults; None: no default)
PUBLIC = [
    ("robodepth_cli", "open_dataset", {"path": None}),
    ("robodepth_cli.api", "open_dataset", {"path": None}),
    ("robodepth_cli.api", "DatasetError", None),
    ("robodepth_cli.torch", "Corrupt", {"name": None, "level": None, "seed": 0, "dataset": "custom"}),
    ("robodepth_cli.torch", "RandomCorrupt", {"names": None, "levels": None, "p": 0.5, "seed": None}),
    ("robodepth_cli.torch", "KittiC", {"root": None, "corruption": None, "level": None,
                                       "on_the_fly": False, "transform": None}),
    ("robodepth_cli.torch", "RandomChain", {"names": None, "steps": None, "severity": None,
                                            "distinct": None, "p": None, "seed": None}),
    ("robodepth_cli.torch", "TorchAPIError", None),
    ("robodepth_cli.corruptions", "corrupt", {"image": None, "name": None, "level": None, "rng": None}),
    ("robodepth_cli.corruptions", "corrupt_chain", {"image": None, "chain": None, "rngs": None}),
    ("robodepth_cli.corruptions", "render", {"variant": None, "level": None, "seed": None,
                                             "dataset": None, "key": None}),
    ("robodepth_cli.corruptions", "REGISTRY", None),
    ("robodepth_cli.corruptions", "NAMES", None),
    ("robodepth_cli.corruptions.severity", "parse_level", None),
    ("robodepth_cli.seeding", "chain_rngs", {"seed": None, "dataset": None, "chain": None}),  # + the key
]
_NO_DEFAULT = inspect.Parameter.empty


@pytest.mark.parametrize("module, name, params", PUBLIC, ids=[f"{m}.{n}" for m, n, _ in PUBLIC])
def test_public_api(module, name, params):
    obj = getattr(importlib.import_module(module), name)
    if params is None:
        return
    signature = inspect.signature(obj)
    for param, default in params.items():
        assert param in signature.parameters, f"{module}.{name} lost its parameter {param}"
        got = signature.parameters[param].default
        if default is not None:
            assert got == default, f"{module}.{name}: {param} defaults to {got!r}, documented {default!r}"


def test_built_dataset_methods_the_docs_use():
    from robodepth_cli.api import BuiltDataset, Variant

    for attr in ("variants", "variant", "size", "ground_truth", "depth_names"):
        assert hasattr(BuiltDataset, attr), attr
    for attr in ("images", "relpath", "label", "save_predictions", "prediction_file"):
        assert hasattr(Variant, attr), attr


def test_every_import_in_the_docs_works():
    """Each ``from robodepth_cli... import ...`` line in the README and docs/ runs."""
    lines = set()
    for page in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        lines.update(re.findall(r"^(from robodepth_cli[\w.]* import [\w, ]+)$",
                                page.read_text(encoding="utf-8"), re.M))
    assert len(lines) >= 3
    for line in sorted(lines):
        exec(line, {})  # noqa: S102 (our own documentation's import lines)


# Folder names that Python tooling takes for build output: ruff's and black's default
# excludes skip them and the common Python .gitignore hides them, so code there would go
# unlinted or even uncommitted.
TOOLING_OUTPUT_NAMES = {"build", "dist", "_build", "buck-out", "site-packages", "venv", ".venv",
                        "env", "node_modules", "__pypackages__"}


def test_no_folder_named_like_build_output():
    folders = {p.relative_to(REPO).as_posix() for p in PKG.rglob("*") if p.is_dir()
               and p.name != "__pycache__"}
    clashes = sorted(f for f in folders if Path(f).name in TOOLING_OUTPUT_NAMES)
    assert clashes == [], f"rename: {clashes} (tooling skips or ignores such folders)"


def _code_literals(path: Path) -> set[str]:
    """The string constants of a module's code (docstrings and f-string text included,
    since a path written into an f-string is still a path spelled out)."""
    import ast

    return {n.value for n in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
            if isinstance(n, ast.Constant) and isinstance(n.value, str)}


def test_the_predictions_record_name_is_spelled_by_its_owner_only():
    """``predictions.json`` is :data:`robodepth_cli.predictions.RECORD`: code elsewhere uses
    the constant (help text and docstrings may name the file)."""
    from robodepth_cli.predictions import RECORD

    owner = MODULES["predictions"]
    spelled = sorted(name for name, path in MODULES.items()
                     if path != owner and RECORD in _code_literals(path))
    assert spelled == [], f"use robodepth_cli.predictions.RECORD in {spelled}"


# ------------------------------------------------------------------ what a command loads

_NOT_FOR_JUDGING = ["robodepth_cli.building", "robodepth_cli.groundtruth", "robodepth_cli.corruptions",
                    "torch"]


def test_score_and_report_load_no_build_ground_truth_corruption_or_torch(tmp_path):
    """Judging results needs none of what makes a dataset: ``score`` and ``report`` run in a
    fresh interpreter load no module of building/, groundtruth/ or corruptions/, nor torch."""
    from tests.helpers.imports import imported_by_command
    from tests.helpers.report import evaluate_csv

    csv = evaluate_csv(tmp_path / "m.csv", "kitti-c", "MonoDepth2 R18")
    assert imported_by_command(["score", csv], _NOT_FOR_JUDGING, stdout_has="mCE") == []
    assert imported_by_command(["report", csv, "--out", tmp_path / "rep"], _NOT_FOR_JUDGING) == []
    assert (tmp_path / "rep" / "index.html").is_file()


def test_the_build_reader_does_not_know_the_export():
    """api.py reads a build; an export's store is handed to it by the package's open_dataset,
    so the evaluation (which reads builds through api) sits below the export."""
    assert not any(_under(t, "export") for t in GRAPH["api"])
    assert not any(_under(t, "export") for t in GRAPH["evaluation.evaluate"])
