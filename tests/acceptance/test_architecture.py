"""The import rules of docs/architecture.md, checked on the source: no
import cycles (counting imports inside functions too), a generic explorer,
a front end that knows nothing of the back end, rules and blackboxes that
see only what they are given."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from pccl.tools import archdoc

ROOT = Path(__file__).resolve().parents[2]
_SETUP = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
#: package name -> source directory: pyproject.toml's package list and its package-dir mapping
#: (pccl.semantics and pccl.blackboxes come from the top-level semantics/ and blackboxes/)
PACKAGES = archdoc.packages(ROOT)
MODULES = archdoc.modules(ROOT)
#: every import of every module, function-local ones too: the reader that also writes
#: docs/architecture.md's import tables (one reader, pccl/tools/archdoc.py)
GRAPH = archdoc.graph(MODULES)


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
GENERIC = {"pccl.search.explorer", "pccl.search.parallel", "pccl.search.parallel_worker",
           "pccl.search.parallel_pipes", "pccl.search.parallel_ray", "pccl.search.fingerprint",
           "pccl.search.visited", "pccl.search.scc", "pccl.search.memory", "pccl.search.spill", "pccl.search.safedata"}
#: the front end: source text to a checked AST
FRONT = {"pccl.lang.ast", "pccl.lang.parser", "pccl.lang.lalrfast", "pccl.lang.koord",
         "pccl.lang.files", "pccl.lang.checker", "pccl.lang.types", "pccl.lang.errors",
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


def test_the_engine_gets_its_properties_parsed():
    """The engine imports no parser: properties come parsed and checked
    from pccl.model.properties (issue 22), the initial states from
    pccl.model.initstates, the world, blackbox and clock from
    pccl.model.environment."""
    assert "pccl.lang.parser" not in GRAPH["pccl.model.engine"]
    assert {"pccl.model.properties", "pccl.model.initstates",
            "pccl.model.environment"} <= GRAPH["pccl.model.engine"]
    for mod in ("pccl.model.initstates", "pccl.model.environment"):
        assert not (_reach(mod) & {"pccl.lang.parser", "pccl.model.engine", "pccl.search.explorer",
                                   "pccl.api"}), mod


def test_the_model_class_stays_small():
    """engine.Model under 300 lines (issue 22): properties, the Init-block
    search, the environment and the reductions live in their own modules."""
    tree = ast.parse(MODULES["pccl.model.engine"].read_text())
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Model")
    assert cls.end_lineno - cls.lineno + 1 < 300


def test_nothing_imports_the_command_line():
    """Nothing outside pccl/cli/ imports it (inside, ``python -m pccl.cli`` does)."""
    assert [m for m in GRAPH if _layer(m) != "cli" and any(_layer(d) == "cli" for d in GRAPH[m])] == []


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


_layer = archdoc.layer


#: which layer may import which (besides itself): docs/architecture.md, "Who may import whom"
MAY_IMPORT = {
    "lang": set(),
    "blackboxes": {"lang"},
    "semantics": {"lang", "model"},             # the rules read the configuration's layout only (below)
    "search": set(),
    "model": {"lang", "semantics", "blackboxes", "search"},
    "output": {"lang", "semantics", "blackboxes", "search", "model"},
    "tools": {"lang", "semantics", "blackboxes", "search", "model", "output"},
    "api": {"lang", "semantics", "blackboxes", "search", "model", "output", "tools"},
    "cli": {"lang", "semantics", "blackboxes", "search", "model", "output", "tools", "api"},
}
#: imports against the layers that the code still has (issue 22: the helpers who own these
#: modules are removing them; delete an entry when its import goes, the test then keeps it out).
KNOWN_EXCEPTIONS: set[tuple[str, str]] = set()     # none left (issue 45)


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


#: the search family: the explorer and its frontiers, the graph analyses,
#: checkpoints and the bookkeeping (by module name, wherever the package puts them)
SEARCH = {"explorer", "fastest", "parallel", "parallel_worker", "parallel_pipes", "parallel_ray", "liveness",
          "checkpoint", "fingerprint", "visited", "memory"}
#: PCCL's display and configuration layout: what the search reads only
#: through the model (a step's time cost, a label's text, a stall's note)
DISPLAY_LAYOUT = {"display", "layout", "traces", "views", "values", "stall", "reduce", "plot",
                  "viewer", "graph", "results"}


def _by_stem(stems: set) -> set:
    return {m for m in MODULES if m.rpartition(".")[2] in stems}


@pytest.mark.parametrize("mod", sorted(_by_stem(SEARCH)))
def test_the_search_family_imports_no_display_or_layout(mod):
    """Not even through another module: what the search needs of a state
    or a label comes through the model's methods."""
    reached = {m for m in _reach(mod) | {mod} if m.rpartition(".")[2] in DISPLAY_LAYOUT}
    assert not reached, reached


def test_the_search_family_is_found():
    assert {m.rpartition(".")[2] for m in _by_stem(SEARCH)} == SEARCH


def test_the_search_family_has_no_long_or_complex_function():
    """No function of the search family (and stall.py) above 80 lines or
    above complexity 15 (ruff's C901, as .ci/run's check)."""
    import shutil
    import subprocess
    import sys
    files = sorted(str(MODULES[m]) for m in _by_stem(SEARCH | {"stall"}))
    long = []
    for f in files:
        for node in ast.walk(ast.parse(Path(f).read_text(), f)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > 80:
                    long.append(f"{Path(f).name}:{node.lineno} {node.name} ({n} lines)")
    assert long == []
    if shutil.which("ruff") is None and not _has_module("ruff"):
        pytest.skip("ruff is not installed")
    out = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "--select", "C901",
                          "--config", "lint.mccabe.max-complexity=15", *files],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stdout + out.stderr


def _has_module(name: str) -> bool:
    import importlib.util
    return importlib.util.find_spec(name) is not None

# ---------------------------------------------------------------------------
# docs/architecture.md, generated and checked (pccl/tools/archdoc.py)
# ---------------------------------------------------------------------------

DOC = ROOT / "docs" / "architecture.md"


@pytest.mark.slow       # reads and parses every module (1-4 s under load)
def test_the_doc_has_the_import_diagram_of_the_code():
    """The generated part of docs/architecture.md is what the imports give:
    after changing an import or a module's docstring, run
    `python -m pccl.tools.archdoc`."""
    assert archdoc.main(["--check"]) == 0


def test_the_generated_tables_agree_with_the_graph():
    """Each module row lists exactly the other layers' modules it imports,
    and each layer's count is the number of its modules whose imports reach
    that layer (read back from the doc, recomputed here from GRAPH)."""
    text = DOC.read_text()
    part = text[text.index(archdoc.BEGIN):text.index(archdoc.END)]
    table = [[c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
             for line in part.splitlines() if line.startswith("| `")]
    rows = {"pccl." + re.findall(r"`([\w.]+)`", c[0])[0]: set(re.findall(r"`([\w.]+)`", c[2]))
            for c in table if len(c) == 3}
    listed = {m for m in MODULES if m != "pccl" and not (MODULES[m].stem == "__init__"
                                                         and not archdoc._has_code(MODULES[m]))}
    assert set(rows) == listed
    for mod, shown in rows.items():
        assert shown == {d.partition(".")[2] for d in GRAPH[mod] if _layer(d) != _layer(mod)}, mod
    layers = [c for c in table if len(c) == 5]
    assert [c[0].strip("`") for c in layers] == [x for x in archdoc.ORDER if x in MAY_IMPORT]
    for c in layers:
        lay = c[0].strip("`")
        mods = [x for x in rows if _layer(x) == lay]
        assert int(c[2]) == len(mods), lay
        want: dict = {}
        for x in mods:
            for d in {_layer(y) for y in GRAPH[x]} - {lay}:
                want[d] = str(int(want.get(d, "0")) + 1)
        assert dict(re.findall(r"`(\w+)` \((\d+)\)", c[3])) == want, lay
        users = {_layer(m) for m in GRAPH if m != "pccl" and _layer(m) != lay
                 and any(_layer(d) == lay for d in GRAPH[m])}
        assert set(re.findall(r"`(\w+)`", c[4])) == users, lay


def test_the_import_reader_sees_function_local_and_relative_imports(tmp_path):
    (tmp_path / "pccl" / "a").mkdir(parents=True)
    (tmp_path / "pccl" / "b").mkdir()
    for f in ("pccl/__init__.py", "pccl/a/__init__.py", "pccl/b/__init__.py", "pccl/b/y.py", "pccl/b/z.py"):
        (tmp_path / f).write_text('"""A module."""\n')
    (tmp_path / "pccl" / "a" / "x.py").write_text(
        '"""X."""\nimport os\n\n\ndef f():\n    from pccl.b import y\n    return y\n\n\n'
        'def g():\n    from ..b.z import thing\n    return thing\n')
    (tmp_path / "pyproject.toml").write_text(
        '[tool.setuptools]\npackages = ["pccl", "pccl.a", "pccl.b"]\n')
    mods = archdoc.modules(tmp_path)
    assert archdoc.graph(mods)["pccl.a.x"] == {"pccl.b.y", "pccl.b.z"}


def _run(*args):
    return subprocess.run([sys.executable, "-m", "pccl.tools.archdoc", *args],
                          capture_output=True, text=True, cwd=ROOT)


@pytest.mark.slow       # reads and parses every module (1-4 s under load)
def test_check_fails_on_a_drifted_doc_and_regenerating_fixes_it(tmp_path):
    doc = tmp_path / "architecture.md"
    text = DOC.read_text()
    drifted = text.replace("| `output.codec` |", "| `output.codec_old` |", 1)
    assert drifted != text
    doc.write_text(drifted)
    r = _run("--check", "--doc", str(doc))
    assert r.returncode == 1 and "differs from the code" in r.stderr and "codec_old" in r.stdout
    assert doc.read_text() == drifted                      # --check writes nothing
    r = _run("--doc", str(doc))
    assert r.returncode == 0 and doc.read_text() == text
    assert _run("--check", "--doc", str(doc)).returncode == 0


@pytest.mark.slow       # reads and parses every module (1-4 s under load)
def test_a_doc_without_markers_is_one_message_and_exit_2(tmp_path):
    doc = tmp_path / "architecture.md"
    doc.write_text("# Architecture\n\nno generated part\n")
    r = _run("--check", "--doc", str(doc))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert f"{doc}: expected one line '{archdoc.BEGIN}'" in r.stderr
    r = _run("--doc", str(tmp_path / "missing.md"))
    assert r.returncode == 2 and "--doc" in r.stderr and "Traceback" not in r.stderr


#: `module.name` in backticks: a module of pccl by its last name (`codec`) or its
#: path under pccl (`output.codec`), then attributes
_DOTTED = re.compile(r"`([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)+)(?:\(\))?`")


def _resolve(dotted: str):
    """The object ``dotted`` names, or None when it does not start with a module of pccl."""
    import importlib
    parts = dotted.split(".")
    if parts[0] == "pccl":
        parts = parts[1:]
    short = {}
    for m in MODULES:
        short.setdefault(m.rpartition(".")[2], []).append(m)
    for i in range(len(parts), 0, -1):
        full = "pccl." + ".".join(parts[:i])
        if full in MODULES:
            mod = full
            break
        if i == 1 and len(short.get(parts[0], [])) == 1:
            mod = short[parts[0]][0]
            break
    else:
        return None
    obj = importlib.import_module(mod)
    for a in parts[i:]:
        obj = getattr(obj, a)
    return obj


@pytest.mark.slow       # reads and parses every module (1-4 s under load)
def test_every_module_name_in_the_doc_exists():
    """Every `module.name` in backticks on docs/architecture.md (the trace's
    data flow names its functions so) is a module of pccl and an attribute
    of it, checked by import; `model.x` and `world.x` that are no module's
    are read on a model of Fischer's protocol (`model.compiled.layout`)."""
    from pccl.api import make_model
    m = make_model(str(ROOT / "programs" / "fischer.pccl"), agents=2)
    instances = {"model": m, "world": m.world}
    text = DOC.read_text()
    names = sorted(set(_DOTTED.findall(text)))
    assert "codec.encode_path" in names and "reduce.expand_trace" in names
    missing = []
    for n in names:
        if n.rpartition(".")[2] in ("py", "md", "toml", "json", "lark", "pccl", "txt", "c", "h"):
            continue                                        # a file name
        try:
            _resolve(n)
        except AttributeError as e:
            first, *rest = n.split(".")
            obj = instances.get(first)
            try:
                for a in rest:
                    obj = getattr(obj, a)
            except AttributeError:
                obj = None
            if obj is None:
                missing.append(f"{n}: {e}")
    assert missing == []


def test_the_trace_section_names_only_real_functions():
    """The section "A trace from search to file to replay": every dotted
    name in its diagram (module.function) resolves by import."""
    text = DOC.read_text()
    sec = text[text.index("## A trace from search to file to replay"):]
    sec = sec[:sec.index("\n## ", 1)]
    names = set(re.findall(r"\b((?:explorer|liveness|runner|reduce|native|api|traces|codec|tracecheck|replay)"
                           r"(?:\.\w+)+)", sec))
    assert len(names) > 20
    bad = []
    for n in sorted(names):
        try:
            if _resolve(n) is None:
                bad.append(n)
        except AttributeError as e:
            bad.append(f"{n}: {e}")
    assert bad == []


def _bytecode_imports(name: str, path: Path) -> set[str]:
    """The pccl modules ``name`` imports, read a second way: from the
    compiled bytecode's IMPORT_NAME instructions (every code object, nested
    functions included), not from the syntax tree."""
    import dis
    is_pkg = path.stem == "__init__"
    out: set[str] = set()
    todo = [compile(path.read_text(), str(path), "exec")]
    while todo:
        code = todo.pop()
        todo += [c for c in code.co_consts if hasattr(c, "co_code")]
        ins = list(dis.get_instructions(code))
        for k, i in enumerate(ins):
            if i.opname != "IMPORT_NAME":
                continue
            level, fromlist = ins[k - 2].argval, ins[k - 1].argval
            mod = i.argval
            if level:
                base = name.split(".")[:len(name.split(".")) - level + (1 if is_pkg else 0)]
                mod = ".".join(base + ([mod] if mod else []))
            for t in [f"{mod}.{f}" for f in fromlist or ()] or [mod]:
                t = t if t in MODULES else mod
                while t and t not in MODULES:
                    t = t.rpartition(".")[0]
                if t and t != name and t != "pccl":
                    out.add(t)
    return out


def test_the_import_reader_agrees_with_the_bytecode():
    """archdoc's reader (the syntax tree) and the compiled code give the same graph."""
    assert {m: _bytecode_imports(m, p) for m, p in MODULES.items()} == GRAPH


TEST_FOLDERS = {"lang", "semantics", "blackboxes", "model", "search", "output", "tools",
                "interface", "acceptance", "oracle"}


def test_tests_mirror_the_layers():
    """Every test file lives in a folder named after a layer (docs/architecture.md,
    "The folders"), is named after what it tests (no issue numbers, no "more"/"2"),
    and imports no test module of another folder (shared helpers are modules at
    the top of tests/)."""
    tests = ROOT / "tests"
    assert not list(tests.glob("test_*.py")), "a test file at the top of tests/"
    bad_names, cross = [], []
    for f in sorted(tests.glob("*/test_*.py")):
        assert f.parent.name in TEST_FOLDERS, f
        if re.search(r"(\d|_more|_issue\w*|_hardening\w*|_split|_whole)\.py$", f.name):
            bad_names.append(f.name)
        for m in re.finditer(r"^\s*from (test_\w+) import|^\s*import (test_\w+)", f.read_text(), re.M):
            name = m.group(1) or m.group(2)
            if not (f.parent / f"{name}.py").exists():
                cross.append(f"{f.relative_to(ROOT)} imports {name}")
    assert not bad_names and not cross, (bad_names, cross)
