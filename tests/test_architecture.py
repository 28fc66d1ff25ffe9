"""The import rules of docs/architecture.md, checked on the source: no
import cycles (counting imports inside functions too), a generic explorer,
a front end that knows nothing of the back end, rules and blackboxes that
see only what they are given."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: package name -> source directory (pyproject.toml's package-dir mapping)
PACKAGES = {"pccl": ROOT / "pccl", "pccl.semantics": ROOT / "semantics",
            "pccl.blackboxes": ROOT / "blackboxes"}


def _modules() -> dict[str, Path]:
    mods = {}
    for pkg, d in PACKAGES.items():
        for f in sorted(d.glob("*.py")):
            mods[pkg if f.stem == "__init__" else f"{pkg}.{f.stem}"] = f
    return mods


MODULES = _modules()


def _imports(name: str, path: Path) -> set[str]:
    """The pccl modules ``name`` imports, anywhere in the file."""
    is_pkg = path.stem == "__init__"
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = name.split(".")
                base = parts[:len(parts) - node.level + (1 if is_pkg else 0)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in MODULES else mod
                       for a in node.names]
        for t in targets:
            while t and t not in MODULES:
                t = t.rpartition(".")[0]            # pccl.x.y -> pccl.x
            if t and t != name and t.startswith("pccl") and t != "pccl":
                out.add(t)
    return out


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _reach(start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for m in GRAPH[todo.pop()]:
            if m not in seen:
                seen.add(m)
                todo.append(m)
    return seen


def test_the_graph_is_read():
    assert len(MODULES) > 30
    assert "pccl.semantics.rules" in GRAPH["pccl.engine"]
    assert "pccl.explorer" in GRAPH["pccl.api"]
    assert "pccl.blackboxes.base" in GRAPH["pccl.blackboxes.straight"]


def test_no_import_cycles():
    cycles = sorted(m for m in GRAPH if m in _reach(m) and m != "pccl.blackboxes")
    # a package's __init__ may import its submodules, which may import a sibling
    assert cycles == []


#: modules that know nothing of PCCL: the search and its bookkeeping
GENERIC = {"pccl.explorer", "pccl.parallel", "pccl.fingerprint", "pccl.memory"}
#: the front end: source text to a checked AST
FRONT = {"pccl.ast", "pccl.parser", "pccl.checker", "pccl.types", "pccl.errors",
         "pccl.values", "pccl.builtins"}
#: what the front end must not know
BACK = {"pccl.compile", "pccl.compiled", "pccl.engine", "pccl.explorer", "pccl.parallel", "pccl.reduce",
        "pccl.semantics.rules", "pccl.blackboxes", "pccl.api", "pccl.cli", "pccl.display"}


@pytest.mark.parametrize("mod", sorted(GENERIC))
def test_the_explorer_is_generic(mod):
    assert GRAPH[mod] <= GENERIC, GRAPH[mod] - GENERIC


@pytest.mark.parametrize("mod", sorted(FRONT))
def test_the_front_end_does_not_know_the_back_end(mod):
    assert not (_reach(mod) & BACK), _reach(mod) & BACK


def test_rules_see_only_what_they_are_given():
    """The rules read the model through their arguments: they import no
    engine, compiler, explorer or user interface."""
    assert not (_reach("pccl.semantics.rules")
                & {"pccl.engine", "pccl.compile", "pccl.compiled", "pccl.explorer", "pccl.parallel",
                   "pccl.reduce", "pccl.api", "pccl.cli", "pccl.checker", "pccl.parser"})


def test_blackboxes_import_only_blackboxes_and_errors():
    for mod in MODULES:
        if mod.startswith("pccl.blackboxes"):
            assert GRAPH[mod] <= {m for m in MODULES if m.startswith("pccl.blackboxes")} \
                | {"pccl.errors", "pccl.ast"}, (mod, GRAPH[mod])


def test_the_compiled_program_knows_nothing_of_the_search():
    """compiled.py is the program after compiling: it reaches neither the
    model nor the world, the blackboxes, the explorer or the reductions."""
    assert not (_reach("pccl.compiled")
                & {"pccl.engine", "pccl.world", "pccl.blackboxes", "pccl.explorer",
                   "pccl.parallel", "pccl.reduce", "pccl.api", "pccl.cli"})
    assert "pccl.compiled" in GRAPH["pccl.engine"]


def test_the_engine_gets_its_properties_parsed():
    """The engine imports no parser: properties come parsed and checked
    from pccl.properties (issue 22), the initial states from pccl.initstates."""
    assert "pccl.parser" not in GRAPH["pccl.engine"]
    assert {"pccl.properties", "pccl.initstates", "pccl.environment"} <= GRAPH["pccl.engine"]
    for mod in ("pccl.initstates", "pccl.environment"):
        assert not (_reach(mod) & {"pccl.parser", "pccl.engine", "pccl.explorer", "pccl.api"}), mod


def test_the_model_class_stays_small():
    """engine.Model under 300 lines (issue 22): properties, the Init-block
    search, the environment and the reductions live in their own modules."""
    tree = ast.parse(MODULES["pccl.engine"].read_text())
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Model")
    assert cls.end_lineno - cls.lineno + 1 < 300


def test_nothing_imports_the_command_line():
    assert [m for m in GRAPH if "pccl.cli" in GRAPH[m]] == []


def test_the_source_tree_has_the_installed_layout():
    """pccl/semantics and pccl/blackboxes link to the directories that
    pyproject.toml's package-dir maps them from: mypy, which does not read
    that mapping, and a plain checkout then see pccl.semantics.rules."""
    import tomllib
    mapping = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    for pkg, d in mapping.items():
        if pkg != "pccl":
            link = ROOT / pkg.replace(".", "/")
            assert link.is_symlink() and link.resolve() == (ROOT / d).resolve(), pkg
