"""Every ``:mod:``, ``:func:`` and ``:class:`` reference in the package's docstrings names
something that exists: a module of the package, or a name it defines (read from the source,
so that nothing is imported). A reference is relative (``.csvrows``: from the module's
package), absolute (``robodepth_cli.api.open_dataset``) or bare (``data_rows``: a name of the
module itself, or of the module named by the part before it); ``~`` is only how it is shown.
Inside a class, a bare name may be one of its methods. References to other projects
(``scipy.ndimage.zoom``) are left to them."""

from __future__ import annotations

import ast
import builtins
import importlib.util
import re

import pytest

from tests.helpers.paths import REPO

PKG = REPO / "robodepth_cli"
ROLE = re.compile(r":(mod|func|class|meth):`~?([A-Za-z0-9_.]+)(?:\(\))?`")


def _modules() -> dict[str, ast.Module]:
    out = {}
    for path in sorted(PKG.rglob("*.py")):
        parts = path.relative_to(PKG).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = ast.parse(path.read_text(encoding="utf-8"))
    return out


MODULES = _modules()
PACKAGES = {name for name in MODULES
            if (PKG.joinpath(*name.split(".")) / "__init__.py").is_file() or name == ""}


def _names(body) -> dict[str, ast.AST | None]:
    """The names a module or class body binds: defs, classes, assignments, imports."""
    out: dict[str, ast.AST | None] = {}
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out[node.name] = node
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            for t in node.targets if isinstance(node, ast.Assign) else [node.target]:
                for n in ast.walk(t):
                    if isinstance(n, ast.Name):
                        out[n.id] = None
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            for a in node.names:
                out[(a.asname or a.name).split(".")[0]] = None
        elif isinstance(node, (ast.If, ast.Try)):
            out.update(_names(node.body))
    return out


def _lazy(tree: ast.Module) -> set[str]:
    """Names a module hands out through ``__getattr__``: the strings it lists."""
    if "__getattr__" not in _names(tree.body):
        return set()
    return {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)}


def _defined(module: str, attrs: list[str]) -> bool:
    tree = MODULES[module]
    names = _names(tree.body)
    if not attrs:
        return True
    if attrs[0] not in names:
        return attrs[0] in _lazy(tree) and len(attrs) == 1
    node = names[attrs[0]]
    if len(attrs) == 1:
        return True
    if isinstance(node, ast.ClassDef) and len(attrs) == 2:
        return attrs[1] in _names(node.body)
    return node is None  # an imported or assigned name: its members are its own module's


def resolves(target: str, module: str, within: str = "") -> bool:
    """Whether ``target``, written in a docstring of ``module`` (inside class ``within``,
    if any), names what exists."""
    if within and "." not in target and _defined(module, [within, target]):
        return True  # a method of the class the docstring is in
    package = module if module in PACKAGES else module.rpartition(".")[0]
    if target.startswith("."):
        dots = len(target) - len(target.lstrip("."))
        base = package.split(".") if package else []
        base = base[:len(base) - (dots - 1)] if dots > 1 else base
        candidates = [".".join([*base, target.lstrip(".")]).strip(".")]
    elif target == "robodepth_cli" or target.startswith("robodepth_cli."):
        candidates = [target[len("robodepth_cli") + 1:]]
    else:
        top = target.split(".")[0]
        if target in dir(builtins):
            return True  # OSError
        if top not in _names(MODULES[module].body) and importlib.util.find_spec(top) is not None:
            return True  # another project's name
        candidates = [f"{module}.{target}".strip("."), f"{package}.{target}".strip("."), target]
    for full in candidates:
        parts = full.split(".") if full else []
        for cut in range(len(parts), -1, -1):
            mod = ".".join(parts[:cut])
            if mod in MODULES:
                if _defined(mod, parts[cut:]):
                    return True
                break
    return False


def _docstrings(node, within: str = ""):
    """(docstring, enclosing class name) of ``node`` and everything in it."""
    if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
        if isinstance(node, ast.ClassDef):
            within = node.name
        yield ast.get_docstring(node, clean=False) or "", within
    for child in ast.iter_child_nodes(node):
        yield from _docstrings(child, within)


def _references():
    for module, tree in MODULES.items():
        for doc, within in _docstrings(tree):
            for role, target in ROLE.findall(doc):
                yield module or "robodepth_cli", within, role, target


REFERENCES = sorted(set(_references()))


def test_the_docstrings_hold_references():
    assert len(REFERENCES) > 100


@pytest.mark.parametrize("module,within,role,target", REFERENCES)
def test_a_docstring_reference_names_what_exists(module, within, role, target):
    assert resolves(target, "" if module == "robodepth_cli" else module, within), \
        f"{module}: :{role}:`{target}` names nothing"


def test_the_resolver_refuses_what_does_not_exist():
    assert resolves(".csvrows", "evaluation.results")
    assert resolves("ResultsTable.data_rows", "evaluation.csvrows")
    assert resolves("robodepth_cli.api.open_dataset", "report.inputs")
    assert not resolves("._depth", "corruptions._engine")
    assert not resolves("robodepth_cli.api.no_such_name", "report.inputs")
    assert not resolves("ResultsTable.no_such_method", "evaluation.csvrows")
    assert resolves("data_rows", "evaluation.csvrows", within="ResultsTable")
    assert not resolves("data_rows", "evaluation.csvrows")
