"""The import rules of docs/architecture.md, checked on the source: no
import cycles (counting imports inside functions too), a generic explorer,
a front end that knows nothing of the back end, rules and blackboxes that
see only what they are given."""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
_SETUP = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
#: package name -> source directory: pyproject.toml's package list and its package-dir mapping
#: (pccl.semantics and pccl.blackboxes come from the top-level semantics/ and blackboxes/)
PACKAGES = {pkg: ROOT / _SETUP["package-dir"].get(pkg, pkg.replace(".", "/")) for pkg in _SETUP["packages"]}


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
    assert "pccl.semantics.rules" in GRAPH["pccl.model.engine"]
    assert "pccl.search.explorer" in GRAPH["pccl.api"]
    assert "pccl.blackboxes.base" in GRAPH["pccl.blackboxes.straight"]


def test_no_import_cycles():
    cycles = sorted(m for m in GRAPH if m in _reach(m) and m != "pccl.blackboxes")
    # a package's __init__ may import its submodules, which may import a sibling
    assert cycles == []


#: modules that know nothing of PCCL: the search and its bookkeeping
GENERIC = {"pccl.search.explorer", "pccl.search.parallel", "pccl.search.fingerprint", "pccl.search.memory"}
#: the front end: source text to a checked AST
FRONT = {"pccl.lang.ast", "pccl.lang.parser", "pccl.lang.checker", "pccl.lang.types", "pccl.lang.errors",
         "pccl.lang.values", "pccl.lang.builtins"}
#: what the front end must not know
BACK = {"pccl.model.compile", "pccl.model.compiled", "pccl.model.engine", "pccl.search.explorer",
        "pccl.search.parallel", "pccl.model.reduce", "pccl.semantics.rules", "pccl.blackboxes", "pccl.api",
        "pccl.cli", "pccl.output.display"}


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
                & {"pccl.model.engine", "pccl.model.compile", "pccl.model.compiled", "pccl.search.explorer",
                   "pccl.search.parallel", "pccl.model.reduce", "pccl.api", "pccl.cli", "pccl.lang.checker",
                   "pccl.lang.parser"})


def test_blackboxes_import_only_blackboxes_and_errors():
    for mod in MODULES:
        if mod.startswith("pccl.blackboxes"):
            assert GRAPH[mod] <= {m for m in MODULES if m.startswith("pccl.blackboxes")} \
                | {"pccl.lang.errors", "pccl.lang.ast"}, (mod, GRAPH[mod])


def test_the_compiled_program_knows_nothing_of_the_search():
    """compiled.py is the program after compiling: it reaches neither the
    model nor the world, the blackboxes, the explorer or the reductions."""
    assert not (_reach("pccl.model.compiled")
                & {"pccl.model.engine", "pccl.lang.world", "pccl.blackboxes", "pccl.search.explorer",
                   "pccl.search.parallel", "pccl.model.reduce", "pccl.api", "pccl.cli"})
    assert "pccl.model.compiled" in GRAPH["pccl.model.engine"]


def test_nothing_imports_the_command_line():
    assert [m for m in GRAPH if "pccl.cli" in GRAPH[m]] == []


def test_the_source_tree_has_no_links_and_the_mapped_packages_import_from_the_top():
    """No symbolic link in the package's source (issue 22: semantics/ and blackboxes/
    stay at the top, mapped by pyproject.toml's package-dir, not linked into pccl/), so
    a tool that reads paths sees them once, where they are; the installed
    pccl.semantics and pccl.blackboxes are those folders' files."""
    import importlib
    links = [p.relative_to(ROOT).as_posix() for top in ("pccl", "semantics", "blackboxes")
             for p in (ROOT / top).rglob("*") if p.is_symlink()]
    assert links == []
    assert not (ROOT / "pccl" / "semantics").exists() and not (ROOT / "pccl" / "blackboxes").exists()
    mapping = _SETUP["package-dir"]
    assert {pkg for pkg in mapping if pkg != "pccl"} == {"pccl.semantics", "pccl.blackboxes"}
    for pkg, d in mapping.items():
        mod = importlib.import_module(pkg)
        assert mod.__file__ is not None
        assert Path(mod.__file__).resolve() == (ROOT / d / "__init__.py").resolve(), pkg


def _layer(mod: str) -> str:
    """The subpackage (layer) of a module: pccl.model.engine -> model; pccl.api -> api."""
    return mod.split(".")[1] if "." in mod else mod


#: which layer may import which (besides itself): docs/architecture.md, "Who may import whom"
MAY_IMPORT = {
    "lang": set(),
    "blackboxes": {"lang"},
    "semantics": {"lang", "model"},             # the rules read the configuration's layout only (below)
    "search": set(),
    "model": {"lang", "semantics", "blackboxes", "search"},
    "output": {"lang", "semantics", "blackboxes", "search", "model"},
    "tools": {"lang", "semantics", "blackboxes", "search", "model", "output", "api"},
    "api": {"lang", "semantics", "blackboxes", "search", "model", "output", "tools"},
    "cli": {"lang", "semantics", "blackboxes", "search", "model", "output", "tools", "api"},
}
#: imports against the layers that the code still has (issue 22: the helpers who own these
#: modules are removing them; delete an entry when its import goes, the test then keeps it out).
KNOWN_EXCEPTIONS = {
    ("pccl.search.fastest", "pccl.model.layout"),       # a step's time cost: to come through the model
    ("pccl.search.liveness", "pccl.model.layout"),      # reach/phase cells: to come through the model
    ("pccl.search.liveness", "pccl.model.reduce"),      # expand_trace: to move to the one trace type
    ("pccl.search.liveness", "pccl.model.stall"),       # the stall check of a lasso
    ("pccl.search.liveness", "pccl.output.display"),    # label_info: a label's text from the model
    ("pccl.search.checkpoint", "pccl.lang.errors"),     # PcclError for a bad checkpoint file
    ("pccl.model.stall", "pccl.output.display"),        # fmt_pos, fmt_time, source_line in stall reasons
    ("pccl.output.viewer", "pccl.api"),                 # program_moves for the viewer's page
}


def _against_the_layers() -> set[tuple[str, str]]:
    return {(m, d) for m, deps in GRAPH.items() for d in deps
            if _layer(d) != _layer(m) and _layer(d) not in MAY_IMPORT[_layer(m)]}


def test_every_module_is_in_a_layer():
    """Every package of pccl is a layer of MAY_IMPORT, and every directory of
    modules under pccl/ is a package listed in pyproject.toml (so that wheels ship it)."""
    assert {_layer(m) for m in MODULES if m != "pccl"} == set(MAY_IMPORT)
    dirs = {p.parent for p in (ROOT / "pccl").rglob("*.py") if "__pycache__" not in p.parts}
    assert dirs <= set(PACKAGES.values()), dirs - set(PACKAGES.values())


def test_layers_import_only_the_layers_below():
    assert _against_the_layers() <= KNOWN_EXCEPTIONS, sorted(_against_the_layers() - KNOWN_EXCEPTIONS)


def test_the_known_exceptions_are_still_there():
    """An exception whose import is gone is deleted from the list (so it cannot come back)."""
    assert KNOWN_EXCEPTIONS <= _against_the_layers(), sorted(KNOWN_EXCEPTIONS - _against_the_layers())


def test_semantics_reads_only_the_layout_of_the_model():
    assert {d for m in MODULES if _layer(m) == "semantics" for d in GRAPH[m] if _layer(d) == "model"} \
        <= {"pccl.model.layout"}
