"""Flag spelling in the CLI only (issue 22): below the command line a text
names an option as a placeholder (``{depth=10}``, :func:`pccl.lang.errors.spell`);
``pccl.api`` writes it as its keyword (``depth=10``), ``pccl`` as its flag
(``--depth 10``).  Each case moved: the API's text names no flag, the CLI's
is what it always was.  And no flag literal below the CLI, so none comes back."""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import pytest

import pccl.api as api
from pccl.cli import FLAGS, cli_spelling, flag, main
from pccl.lang.errors import ArgumentError, PcclError, keyword_spelling, location_spelling, spell
from pccl.model.options import OPTION_NAMES, api_spelling

from conftest import FISCHER, RACE, RACE_WORLD, TEST_PROGRAMS, cli

LOOP = str(TEST_PROGRAMS / "eng_loop.pccl")

ROOT = Path(__file__).resolve().parents[2]

#: Modules that are command-line front ends: they write the flags of the
#: command line they serve.  pccl/cli/ is ``pccl``; simulate.py prints the
#: ``pccl run ...`` command that reproduces an outcome; exitcodes.py is the
#: table of ``--exit-codes detailed`` in the CLI's help; archdoc.py has its
#: own command line (``python -m pccl.tools.archdoc --check``); replay.py is
#: ``pccl replay`` (its errors name its own --program/--world/--blackbox; the
#: API offers no replay); serve.py is the viewer's server, answering the page
#: in the terms of the ``pccl view`` command that started it.
FRONT_ENDS = {*(p.relative_to(ROOT).as_posix() for p in (ROOT / "pccl" / "cli").glob("*.py")),
              "pccl/tools/simulate.py", "pccl/tools/exitcodes.py",
              "pccl/tools/archdoc.py", "pccl/tools/replay.py", "pccl/tools/serve.py"}
#: Modules that still write flags, and why (docs/architecture.md, "Flag
#: spelling").  An entry is deleted when its flags go; the test below then
#: keeps them out.
PENDING: dict = {}


#: Other programs' flags that are spelt like one of pccl's: the C compiler's
#: command line, and the ``ray start`` command a message suggests.
OTHER_PROGRAMS = {("pccl/model/native_build.py", "-w"), ("pccl/model/native_build.py", "-o"),
                  ("pccl/search/parallel_ray.py", "--port"),
                  # --watch is the page's, no option of the API (no placeholder spells it)
                  ("pccl/output/viewer.py", "--watch")}


def _cli_flags() -> set[str]:
    """Every flag of every ``pccl`` command (``--max-states``, ``-b``...)."""
    out = set()
    for cmd in main.commands.values():
        for p in cmd.params:
            out.update(o for o in [*p.opts, *getattr(p, "secondary_opts", [])] if o.startswith("-"))
    return out


def _strings(path: Path):
    """(line, text) of the string constants of ``path`` but docstrings (the
    parts of f-strings included)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    docs = set()
    for n in ast.walk(tree):
        if isinstance(n, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and n.body:
            b = n.body[0]
            if isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant):
                docs.add(id(b.value))
    for n in ast.walk(tree):
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs:
            yield n.lineno, n.value


def flag_literals(root: Path, flags: set[str]) -> dict[str, list]:
    """``{path: [(line, flag), ...]}`` of the flags written in string
    constants of the package under ``root`` (outside the docstrings)."""
    pattern = re.compile(r"(?<![\w-])(" + "|".join(sorted(map(re.escape, flags), key=len, reverse=True))
                         + r")(?![\w-])")
    out: dict[str, list] = {}
    for path in sorted((root / "pccl").rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        for line, text in _strings(path):
            for m in pattern.finditer(text):
                out.setdefault(rel, []).append((line, m.group(1)))
    return out


def test_no_flag_is_written_below_the_cli():
    found = flag_literals(ROOT, _cli_flags())
    below = {p: [(line, f) for line, f in hits if (p, f) not in OTHER_PROGRAMS]
             for p, hits in found.items() if p not in FRONT_ENDS and p not in PENDING}
    below = {p: hits for p, hits in below.items() if hits}
    assert below == {}, f"flags written below the CLI (name the option as a placeholder, {{depth=10}}): {below}"
    # a pending module whose flags are gone leaves the list (so they cannot come back)
    assert set(PENDING) <= set(found), sorted(set(PENDING) - set(found))


def test_the_scan_finds_a_flag(tmp_path):
    """The scan itself: a flag in a message and in an f-string is found, one
    in a docstring or a comment is not, nor a word that only contains one."""
    (tmp_path / "pccl").mkdir()
    (tmp_path / "pccl" / "m.py").write_text(
        '"""Module doc: --depth here is documentation."""\n'
        'def f(n):\n    """--max-states in a docstring."""\n'
        '    # --depth in a comment\n'
        '    a = "stopped by --depth"\n'
        '    b = f"use -b {n} or --max-states {n}"\n'
        '    c = "x--depth and --depthy and ulimit -v"\n'
        '    return a, b, c\n')
    assert flag_literals(tmp_path, {"--depth", "--max-states", "-b"}) == {
        "pccl/m.py": [(5, "--depth"), (6, "-b"), (6, "--max-states")]}


# ---------------------------------------------------------------------------
# the spellings
# ---------------------------------------------------------------------------

def test_the_two_spellings_of_a_placeholder():
    text = "use {workers=1} without {ray}; {timelock=False}, {rates=1=2}, {overrides=k=2}, {blackbox=nondet}"
    assert spell(text, api_spelling) == ("use workers=1 without ray; timelock=False, rates={1: 2}, "
                                         "overrides={'k': '2'}, blackbox=nondet")
    assert spell(text, cli_spelling) == ("use --workers 1 without --ray; --no-timelock, --rate 1=2, "
                                         "--set k=2, -b nondet")
    # a name that is no option, and a program's block, are left as written
    assert spell("{x} and { y = 1; } and {1, 2}", api_spelling) == "{x} and { y = 1; } and {1, 2}"
    assert spell("{x} and { y = 1; }", cli_spelling) == "{x} and { y = 1; }"
    # program text quoted in backticks is left alone, even a placeholder's look-alike
    assert spell("property `{depth}` needs {depth}", cli_spelling) == "property `{depth}` needs --depth"
    assert spell("property `{depth}` needs {depth}", keyword_spelling) == "property `{depth}` needs depth"
    # an error's location: the option, then its place
    assert spell("{invariants} #1", location_spelling(cli_spelling)) == "--invariant #1"
    assert spell("{invariants} #1", location_spelling(api_spelling)) == "invariants #1"
    assert keyword_spelling("depth", "10") == "depth=10"


def test_every_option_has_a_flag_of_its_command():
    """The CLI spells every option's name as a flag some command has (the
    table FLAGS is the only place that knows the exceptions)."""
    flags = _cli_flags()
    assert {n for n in OPTION_NAMES if flag(n) not in flags} <= {"functions", "rand_policy", "source",
                                                                "progress_interval", "record_trace"}
    assert set(FLAGS) <= OPTION_NAMES


def test_the_engine_and_the_api_have_no_flag_table():
    import pccl.lang.errors as E
    import pccl.model.options as O
    assert not hasattr(E, "FLAGS") and not hasattr(E, "flag")
    assert not hasattr(O, "FLAGS") and not hasattr(O, "flag")


# ---------------------------------------------------------------------------
# each case: the API's keywords, the CLI's flags
# ---------------------------------------------------------------------------

def test_bound_labels_and_verdict():
    r = api.explore(FISCHER, depth=3)
    assert r.bound_labels == ["depth=3"]
    assert "stopped by depth=3 [" in r.verdict and "--" not in r.verdict
    assert [b["bound"] for b in r.checked["bounds"]] == ["depth=3", "max_memory=80% of RAM"]
    out = cli("explore", FISCHER, "--depth", "3")
    assert "stopped by --depth 3 [" in out.output
    assert "  bounds: --depth 3 (stopped the search), --max-memory 80% of RAM (not reached)" in out.output
    r = api.explore(FISCHER, max_time=2, max_states=10**6)
    assert r.bound_labels == ["max_time=2"]
    assert cli("explore", FISCHER, "--max-time", "2", "--format", "json").output.count('"--max-time 2"') == 2


def test_builtin_checks_turned_off():
    r = api.explore(FISCHER, depth=2, timelock=False, deadlock=False, stall=False)
    details = {b["check"]: b["detail"] for b in r.checked["builtin"]}
    assert details == {"assertions": None, "stuck agents": None, "deadlock": "deadlock=False",
                       "stall": "stall=False", "time-lock": "timelock=False",
                       "collisions": "collisions not given"}
    out = cli("explore", FISCHER, "--depth", "2", "--no-timelock", "--no-deadlock", "--no-stall",
              "--format", "json")
    details = {b["check"]: b["detail"] for b in json.loads(out.output)["checked"]["builtin"]}
    assert details["deadlock"] == "--no-deadlock" and details["time-lock"] == "--no-timelock"
    assert details["stall"] == "--no-stall" and details["collisions"] == "--collisions not given"


def test_engine_reason():
    r = api.explore(FISCHER, depth=2, fastest=True)
    why = r.model.engine_reason
    assert r.model.engine_used == "python" and why == "fastest orders the search in Python"
    out = cli("explore", FISCHER, "--depth", "2", "--fastest")
    assert out.exit_code == 0 and "because --fastest orders the search in Python)" in out.output, out.output
    with pytest.raises(ArgumentError) as e:
        api.explore(FISCHER, depth=2, engine="native", coverage=True)
    assert e.value.filename == "engine" and "--" not in e.value.message
    out = cli("explore", FISCHER, "--depth", "2", "--engine", "native", "--coverage")
    assert out.exit_code == 2 and out.stderr.startswith("--engine: error: the native engine cannot run")


def test_reduction_errors_and_reasons():
    with pytest.raises(PcclError) as e:
        api.explore(FISCHER, agents=1, reduce=["symmetry"])
    assert e.value.filename == "reduce" and e.value.message.endswith("drop it from reduce")
    out = cli("explore", FISCHER, "--agents", "1", "--reduce", "symmetry")
    assert out.exit_code == 2 and out.stderr.startswith("--reduce: error: symmetry reduction needs two")
    assert "drop it from --reduce" in out.stderr
    r = api.explore(FISCHER, depth=2, coverage=True)
    assert r.model.reduction.off_reasons()["merge"] == "coverage counts the unreduced transitions"
    out = cli("explore", FISCHER, "--depth", "2", "--coverage", "--format", "json")
    assert json.loads(out.output)["reductions"]["off"]["merge"] == "--coverage counts the unreduced transitions"


def test_option_text_locations():
    with pytest.raises(PcclError) as e:
        api.explore(FISCHER, invariants=["1e999 > 0"])
    assert str(e.value).startswith("invariants #1:1:1: error: float literal")
    with pytest.raises(PcclError) as e:
        api.explore(FISCHER, overrides={"k": "1 +"})
    assert e.value.filename == "overrides k"
    out = cli("explore", FISCHER, "--set", "k=1 +")
    assert out.exit_code == 2 and out.stderr.startswith("--set k:")
    with pytest.raises(PcclError) as e:
        api.explore(FISCHER, invariants=["eventually inCs[0]"])
    assert e.value.message.startswith("invariants takes a state property") and "--" not in str(e.value)
    out = cli("explore", FISCHER, "--invariant", "eventually inCs[0]")
    assert out.stderr.startswith("--invariant #1:1:1: error: --invariant takes a state property")
    assert "goes with --property" in out.stderr


def test_notes_on_the_blackbox_and_the_world():
    r = api.explore(RACE, world=RACE_WORLD, blackbox="straight", max_states=200)
    assert "(travel times fixed by straight; blackbox=nondet explores every timing)" in r.verdict
    out = cli("explore", RACE, "--world", RACE_WORLD, "-b", "straight", "--max-states", "200")
    assert "(travel times fixed by straight; -b nondet explores every timing)" in out.output
    r = api.explore(RACE, max_states=50)
    assert any(n.startswith("no world given, so the defaults") for n in r.checked["notes"])
    out = cli("explore", RACE, "--max-states", "50")
    assert "  note: no --world given, so the defaults are used" in out.output


def test_checkpoint_mismatch_names_the_option(tmp_path):
    d = str(tmp_path / "ck")
    calls = []

    def interrupt(progress) -> None:         # Ctrl-C at the 5th progress call
        calls.append(progress)
        if len(calls) == 5:
            raise KeyboardInterrupt

    r = api.explore(FISCHER, checkpoint=d, progress=interrupt, progress_interval=1e-9,
                    overrides={"k": "1"})
    assert r.status == "interrupted"
    with pytest.raises(PcclError) as e:
        api.explore(FISCHER, overrides={"k": "2"}, resume=d)
    assert e.value.filename == "resume"
    assert "written with overrides={'k': '1'}, this run has overrides={'k': '2'}" in e.value.message
    out = cli("explore", FISCHER, "--set", "k=2", "--resume", d)
    assert out.exit_code == 2 and out.stderr.startswith("--resume: error: ")
    assert "written with --set k=1, this run has --set k=2" in out.stderr


def test_the_checkers_world_hint():
    src = "loc:\n  int c = getCount();\n"
    with pytest.raises(PcclError) as e:
        api.check(src, source=True)
    assert "a function the world provides needs world=FILE defining getCount" in e.value.message
    e.value.respell(cli_spelling)
    assert "needs --world FILE defining getCount" in e.value.message


def test_a_liveness_note_under_a_depth_bound():
    r = api.explore(FISCHER, properties=["eventually inCs[0]"], depth=3)
    assert "liveness properties not checked: the search was bounded by depth" in r.notes
    out = cli("explore", FISCHER, "--property", "eventually inCs[0]", "--depth", "3")
    assert "note: liveness properties not checked: the search was bounded by --depth" in out.output


# ---------------------------------------------------------------------------
# a run's messages (tools/runner.py): keywords from the API, flags from pccl run,
# and pccl replay accepts a file written either way
# ---------------------------------------------------------------------------

def test_a_run_bounded_by_max_time_names_the_option_in_each_spelling(tmp_path):
    from pccl.api import run
    from pccl.output import traces as T
    res = run(FISCHER, max_time=3, seed=1, record_trace=True)
    assert res.status == "bounded"
    assert res.message == "stopped at max_time=3", res.message
    out = cli("run", FISCHER, "--max-time", "3", "--seed", "1", "--trace-out", str(tmp_path / "cli.json"))
    assert "stopped at --max-time 3" in out.output, out.output
    # the API's file and the CLI's file both replay: the message is compared in either spelling
    T.write(T.run_document(res, T.config("run", res.model, program=FISCHER, seed=1)),
            tmp_path / "api.json")
    for name in ("api.json", "cli.json"):
        rep = cli("replay", str(tmp_path / name))
        assert rep.exit_code == 0, (name, rep.output)
        assert "reproduced" in rep.output, rep.output
    # a file whose message names another bound does not
    doc = json.loads((tmp_path / "cli.json").read_text())
    doc["result"]["message"] = "stopped at --max-time 4"
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    rep = cli("replay", str(tmp_path / "bad.json"))
    assert rep.exit_code == 2 and "does not match" in rep.output, rep.output


def test_a_run_past_max_steps_names_the_option_in_each_spelling():
    from pccl.api import run
    res = run(LOOP, blackbox="instant", max_steps=300)
    assert res.status == "max-steps", res.status
    assert res.message.endswith("raise max_steps if this is intended"), res.message
    assert "--" not in res.message
    out = cli("run", LOOP, "-b", "instant", "--max-steps", "300")
    assert "raise --max-steps if this is intended" in out.output, out.output
