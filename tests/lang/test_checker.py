"""Tests of the static checker (pccl.lang.checker) and the built-in table.

Every error message is pinned by a golden test of the full rendered text:
``file:line:col: error: message``, the source line and the caret; the cases
live as files in tests/golden/ (regenerate with PCCL_REGEN_GOLDEN=1).
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import replace
from pathlib import Path

import pytest

from pccl.lang import ast
from pccl.lang.ast import Span
from pccl.lang.builtins import BUILTINS, READONLY_FLAGS, STATEMENTS, EXPRESSIONS, UNINTERPRETED
from pccl.lang.checker import CheckedProgram, check_program, check_property
from pccl.lang.types import ANY, BOOL, FLOAT, INT, OBSTACLES, POS, Ty, array_of, enum_ty, list_of
from pccl.cli import cli_spelling
from pccl.lang.errors import PcclError
from pccl.lang.parser import parse_program, parse_property

PROGRAMS = Path(__file__).resolve().parents[2] / "programs"
SHIPPED = sorted(PROGRAMS.glob("*.pccl"))


def check(src: str, **kw) -> CheckedProgram:
    return check_program(parse_program(src, "t.pccl"), **kw)


def check_error(src: str, **kw) -> str:
    prog = parse_program(src, "t.pccl")
    with pytest.raises(PcclError) as ei:
        check_program(prog, **kw)
    return ei.value.respell(cli_spelling).render()      # as pccl prints it


def prop(text: str, info: CheckedProgram) -> None:
    check_property(parse_property(text, "--invariant"), info,
                   filename="--invariant", source=text)


def prop_error(text: str, info: CheckedProgram) -> str:
    with pytest.raises(PcclError) as ei:
        prop(text, info)
    return ei.value.respell(cli_spelling).render()      # as pccl prints it


# --------------------------------------------------------------------------
# The shipped programs
# --------------------------------------------------------------------------

def _world_functions() -> frozenset[str]:
    """Names of the uninterpreted functions the shipped world files define."""
    names = set()
    for w in PROGRAMS.glob("*.toml"):
        names |= set(tomllib.loads(w.read_text()).get("functions", {}))
    return frozenset(names)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_shipped_programs_check_clean(path):
    info = check_program(parse_program(path.read_text(), str(path)),
                         functions=_world_functions())
    assert info.variables


def test_shipped_programs_exist():
    assert {p.name for p in SHIPPED} >= {"fischer.pccl", "race.pccl", "race_nonatomic.pccl"}


def test_fischer_symbol_table():
    info = check_program(parse_program((PROGRAMS / "fischer.pccl").read_text(), "fischer.pccl"))
    assert info.name == "Fischer"
    table = {v.name: (v.section, str(v.type), v.is_array, v.size)
             for v in info.variables.values()}
    assert table == {
        "reqid": ("allwrite", "int", False, None),
        "k": ("allwrite", "int", False, None),
        "d": ("allwrite", "int", False, None),
        "id": ("loc", "int", False, None),
        "waitTime": ("loc", "int", False, None),
        "start": ("loc", "bool", False, None),
        "assign": ("loc", "bool", False, None),
        "delay": ("loc", "bool", False, None),
        "wait": ("loc", "bool", False, None),
        "inCs": ("loc", "bool", False, None),
        "c1": ("loc", "int", False, None),
        "c2": ("loc", "int", False, None),
        "cstime": ("loc", "int", False, None),
        "c3": ("loc", "int", False, None),
    }
    # declaration order is kept
    assert list(info.variables) == ["reqid", "k", "d", "id", "waitTime", "start",
                                    "assign", "delay", "wait", "inCs", "c1", "c2",
                                    "cstime", "c3"]
    assert [v.name for v in info.vars_in("allwrite")] == ["reqid", "k", "d"]
    assert info.vars_in("allread") == []
    assert info.type_of("reqid") == INT and info.type_of("inCs") == BOOL
    assert info.section_of("waitTime") == "loc"
    assert info.type_of("doReach_done") == BOOL
    assert info.events == ("Start", "Wait", "Assign", "Delay", "InCs")
    assert info.enums == {} and info.members == {}
    with pytest.raises(KeyError):
        info.type_of("nope")


def test_race_symbol_table():
    info = check_program(parse_program((PROGRAMS / "race.pccl").read_text(), "race.pccl"))
    assert info.type_of("dests") == list_of(POS)
    assert str(info.type_of("dests")) == "List<ItemPosition>"
    assert info.type_of("obs") == OBSTACLES
    assert info.type_of("Pick") == BOOL
    assert info.type_of("currentDest") == POS
    assert info.events == ("PickDest", "Remove")


def test_arrays_enums_and_allread_in_symbol_table():
    info = check("""\
allwrite:
  enum Stage { PICK, GO, DONE };
  int slots[2 * 3 - 1];
allread:
  bool votes[4] = false;
  Stage mine = PICK;
loc:
  enum Light { RED, GREEN };
  List<List<float>> grid = [];
""")
    slots = info.variables["slots"]
    assert (slots.section, slots.is_array, slots.size, slots.value_type) == ("allwrite", True, 5, INT)
    assert info.type_of("slots") == array_of(INT, 5)
    assert str(info.type_of("slots")) == "int[5]"
    votes = info.variables["votes"]
    assert (votes.section, votes.size, votes.value_type, votes.per_agent) == ("allread", 4, BOOL, True)
    assert info.type_of("mine") == enum_ty("Stage") and str(enum_ty("Stage")) == "Stage"
    assert info.type_of("grid") == list_of(list_of(FLOAT))
    assert info.enums == {"Stage": ("PICK", "GO", "DONE"), "Light": ("RED", "GREEN")}
    assert info.members == {"PICK": ("Stage", 0), "GO": ("Stage", 1), "DONE": ("Stage", 2),
                            "RED": ("Light", 0), "GREEN": ("Light", 1)}
    assert info.type_of("GREEN") == enum_ty("Light")
    assert info.variables["grid"].per_agent and not slots.per_agent


# --------------------------------------------------------------------------
# The built-in table
# --------------------------------------------------------------------------

def test_builtin_table():
    assert STATEMENTS == {"doReach", "exit", "assert", "add", "remove"}
    assert EXPRESSIONS == {"getAgentIndex", "getNumAgents", "rand", "getPosition",
                           "ItemPosition", "dist", "head", "isEmpty", "size", "contains"}
    assert UNINTERPRETED == {"getInput", "getObs"}
    assert BUILTINS["ItemPosition"].arities == (2, 3)
    assert BUILTINS["dist"].params == ("pos", "pos") and BUILTINS["dist"].result == "float"
    assert BUILTINS["head"].result == "elem"
    assert BUILTINS["doReach"].params == ("pos", "obstacles") and BUILTINS["doReach"].result is None
    assert BUILTINS["getInput"].arities == (0,) and BUILTINS["getInput"].result == "any"
    assert BUILTINS["rand"].in_properties is False
    assert BUILTINS["count"].kind == "property"
    assert READONLY_FLAGS == {"doReach_done": "bool", "doReach_fail": "bool"}
    for b in BUILTINS.values():
        assert max(b.arities) == len(b.params), b.name
        assert (b.result is None) == b.is_statement, b.name


# --------------------------------------------------------------------------
# What the type rules accept
# --------------------------------------------------------------------------

GOOD = """\
Agent::Good

allwrite:
  enum Stage { PICK, GO, DONE };
  int n = 3;
  float speed = 1;
  List<ItemPosition> dests = getInput();
  List<float> weights = [1, 2.5];
  List<List<int>> groups = [[], [1, 2]];
  Stage phase = PICK;
  int total = n * 2 + n % 2 - n / 2;
  float ratio = 7 / 2.0;
allread:
  int ticket = 0;
  bool ready = false;
  int votes[3] = -1;
  List<int> inbox = [];
loc:
  int id = getAgentIndex();
  int waitTime = rand(n);
  ItemPosition home = getPosition();
  ItemPosition target = ItemPosition(1, 2.5, 0);
  ObstacleList obs = getObs();
  ObstacleList none = [];
  float d = dist(home, target);
  float x = home.x + home.y * home.z;
  bool b = getInput();
  Stage stage = phase;
  int flags[2];
  bool done = doReach_done || doReach_fail;
  int m = getNumAgents();

Init:
  doReach(getPosition(), obs);
  doReach(target, []);
  flags[0] = 1;
  flags[1] = flags[0] + size(dests);

Vote():
  pre(ready && ticket >= 0 && !done);
  eff:
    ticket = ticket[0] + 1;
    votes[1] = votes[0][2];
    add(inbox, ticket);
    if (!isEmpty(inbox[1]) && inbox[1][0] > 0):
      remove(inbox, head(inbox));
    ready = size(inbox) > n;
    skip;

Move():
  pre(stage == GO && phase != DONE);
  eff:
    atomic:
      if (contains(dests, target)):
        remove(dests, target);
      else if (isEmpty(dests)):
        exit();
      else:
        target = head(dests);
        add(dests, ItemPosition(0, 0));
    while (d > 1.0 && speed < 2):
      d = d - speed;
      speed = speed * 2;
    add(weights, 3);
    add(groups[0], 4);
    groups[1] = [5];
    speed = -speed;
    x = 1;
    assert(d >= 0 || x != 1.0);
    stage = DONE;
    stage = getInput();

invariant:
  safe: count(ready) <= N;
  forall i: votes[i][0] >= -1;
"""


def test_good_program_checks_clean():
    info = check(GOOD)
    assert info.name == "Good"
    assert info.variables["votes"].size == 3


def test_expr_types():
    info = check(GOOD)
    t = lambda e, **kw: info.expr_type(parse_property(e, "e"), **kw)  # noqa: E731
    assert t("n + 1") == INT
    assert t("n / 2") == INT
    assert t("n / 2.0") == FLOAT
    assert t("speed * 2") == FLOAT
    assert t("-n") == INT
    assert t("head(dests)") == POS
    assert t("home.x") == FLOAT
    assert t("[1, 2.5]") == list_of(FLOAT)
    assert t("[]") == list_of(ANY)
    assert t("getInput()") == ANY
    assert t("ticket[1]") == INT
    assert t("votes[1]") == INT           # this agent's element 1
    assert t("votes[1][2]") == INT        # agent 1's element 2
    assert t("inbox[1]") == list_of(INT)  # agent 1's list
    assert t("groups[0]") == list_of(INT)
    assert t("PICK") == enum_ty("Stage")
    assert t("flags") == array_of(INT, 2)
    assert t("count(ready)", in_property=True) == INT
    assert t("time", in_property=True) == FLOAT
    assert t("pos[j]", in_property=True, bound=frozenset({"j"})) == POS
    assert t("votes[j][0]", in_property=True, bound=frozenset({"j"})) == INT


def test_ty_strings():
    assert [str(x) for x in (INT, BOOL, FLOAT, POS, OBSTACLES, ANY)] == \
        ["int", "bool", "float", "ItemPosition", "ObstacleList", "any"]
    assert str(list_of(list_of(INT))) == "List<List<int>>"
    assert str(array_of(list_of(BOOL), 2)) == "List<bool>[2]"
    assert Ty("int") == INT


def test_world_functions_are_uninterpreted_any():
    src = """\
allwrite:
  List<ItemPosition> targets = getTargets();
loc:
  int speed = getSpeed();
"""
    assert check_error(src).startswith("t.pccl:2:32: error: unknown function 'getTargets'")
    info = check(src, functions=frozenset({"getTargets", "getSpeed"}))
    assert info.functions == {"getTargets", "getSpeed"}
    assert info.type_of("targets") == list_of(POS)


def test_world_function_takes_no_arguments():
    src = """\
loc:
  int speed = getSpeed(1);
"""
    assert check_error(src, functions=frozenset({"getSpeed"})) == """\
t.pccl:2:15: error: 'getSpeed' takes no arguments, got 1
    2 |   int speed = getSpeed(1);
      |               ^^^^^^^^^^^"""


def test_first_error_in_source_order():
    src = """\
loc:
  int a = true;
  int b = 1.5;

Init:
  a = false;
"""
    assert check_error(src).startswith("t.pccl:2:11: error: cannot initialise 'a'")


def test_enum_usable_above_its_declaration():
    check("""\
allwrite:
  Stage phase = GO;
loc:
  enum Stage { PICK, GO };
""")


# --------------------------------------------------------------------------
# Errors the parser never lets through: checked on hand-built trees, since
# the checker is also an API for trees built by other tools.
# --------------------------------------------------------------------------

def _render(prog: ast.Program) -> str:
    with pytest.raises(PcclError) as ei:
        check_program(prog)
    return ei.value.respell(cli_spelling).render()      # as pccl prints it


def test_field_assignment_is_rejected():
    src = "loc:\n  ItemPosition p;\n\nInit:\n  p.x = 1.0;\n"
    stmt = ast.Assign(0, ast.Field(ast.Name("p", span=Span(5, 3, 5, 4)), "x", span=Span(5, 3, 5, 6)),
                      ast.FloatLit(1.0, span=Span(5, 9, 5, 12)), span=Span(5, 3, 5, 13))
    prog = replace(parse_program("loc:\n  ItemPosition p;\n", "t.pccl"),
                   init=(stmt,), source=src)
    assert _render(prog) == """\
t.pccl:5:3: error: cannot assign to field '.x': assign a whole ItemPosition instead
    5 |   p.x = 1.0;
      |   ^^^"""


def test_call_target_is_rejected():
    src = "loc:\n  int c;\n\nInit:\n  getInput() = 1;\n"
    stmt = ast.Assign(0, ast.Call("getInput", (), span=Span(5, 3, 5, 13)),
                      ast.IntLit(1, span=Span(5, 16, 5, 17)), span=Span(5, 3, 5, 18))
    prog = replace(parse_program("loc:\n  int c;\n", "t.pccl"), init=(stmt,), source=src)
    assert _render(prog) == """\
t.pccl:5:3: error: cannot assign to this expression: the target must be a variable or an element of one
    5 |   getInput() = 1;
      |   ^^^^^^^^^^"""


def test_implies_and_quantifier_outside_properties():
    src = "loc:\n  bool a;\n\nInit:\n  a = a -> a;\n"
    imp = ast.Binary("->", ast.Name("a", span=Span(5, 7, 5, 8)), ast.Name("a", span=Span(5, 12, 5, 13)),
                     span=Span(5, 7, 5, 13))
    prog = replace(parse_program("loc:\n  bool a;\n", "t.pccl"),
                   init=(ast.Assign(0, ast.Name("a", span=Span(5, 3, 5, 4)), imp,
                                    span=Span(5, 3, 5, 14)),), source=src)
    assert _render(prog) == """\
t.pccl:5:7: error: '->' is only allowed in properties
    5 |   a = a -> a;
      |       ^^^^^^"""
    src = "loc:\n  bool a;\n\nInit:\n  a = forall i: a;\n"
    q = ast.Quant("forall", "i", ast.Name("a", span=Span(5, 17, 5, 18)), span=Span(5, 7, 5, 18))
    prog = replace(prog, init=(ast.Assign(0, ast.Name("a", span=Span(5, 3, 5, 4)), q,
                                          span=Span(5, 3, 5, 19)),), source=src)
    assert _render(prog) == """\
t.pccl:5:7: error: 'forall' is only allowed in properties
    5 |   a = forall i: a;
      |       ^^^^^^^^^^^"""


def test_a_clash_points_at_the_name_on_a_continuation_line():
    # the member is written two lines below the enum keyword: the name's own
    # span (from the parser), not a search of the declaration's first line
    src = "loc:\n  int GO = 0\n  enum Stage {\n    PICK,\n    GO }\nInit:\n  skip\n"
    assert _render(parse_program(src, filename="t.pccl")) == """\
t.pccl:5:5: error: 'GO' is already declared as a variable at line 2
    5 |     GO }
      |     ^^"""


def test_duplicate_member_in_one_enum():
    src = "loc:\n  enum Stage { GO, GO };\n"
    # built by hand (the parser rejects it first); spans as the parser gives them
    decl = ast.EnumDecl("loc", "Stage", ("GO", "GO"), span=Span(2, 3, 2, 24),
                        name_span=Span(2, 8, 2, 13),
                        member_spans=(Span(2, 16, 2, 18), Span(2, 20, 2, 22)))
    prog = ast.Program(None, (decl,),
                       (), (), (), filename="t.pccl", source=src)
    assert _render(prog) == """\
t.pccl:2:20: error: duplicate member 'GO' in enum 'Stage'
    2 |   enum Stage { GO, GO };
      |                    ^^"""


def test_list_without_element_type():
    src = "loc:\n  List xs;\n"
    prog = ast.Program(None, (ast.VarDecl("loc", ast.TypeRef("List", span=Span(2, 3, 2, 7)), "xs",
                                          None, None, span=Span(2, 3, 2, 10)),),
                       (), (), (), filename="t.pccl", source=src)
    assert _render(prog) == """\
t.pccl:2:3: error: List needs an element type: List<T>
    2 |   List xs;
      |   ^^^^"""


def test_trees_without_spans_report_without_location():
    decls = (ast.VarDecl("loc", ast.TypeRef("int"), "c", None, None),
             ast.VarDecl("loc", ast.TypeRef("int"), "c", None, None))
    prog = ast.Program(None, decls, (), (), (), filename="built")
    assert _render(prog) == "built: error: duplicate variable 'c'"
    prog = ast.Program(None, decls[:1], (ast.CallStmt(0, "moveTo", ()),), (), (),
                       filename="built")
    assert _render(prog) == "built: error: unknown function 'moveTo'"


# --------------------------------------------------------------------------
# Properties
# --------------------------------------------------------------------------

PROPS_PROGRAM = """\
Agent::Props

allwrite:
  int reqid = -1;
  int slots[3];
  List<ItemPosition> dests = getInput();
  enum Stage { PICK, GO, DONE };
  Stage phase = PICK;
  int time_left = 5;
allread:
  int ticket = 0;
  bool ready = false;
  int votes[2];
loc:
  bool inCs = false;
  int c = 0;
  List<int> seen = [];
  ItemPosition target;
  Stage stage = PICK;
"""

GOOD_PROPERTIES = [
    'count(inCs) <= 1',
    'forall i: inCs[i] -> reqid == i',
    'exists i: ticket[i] > 0 && ready[i]',
    'forall i: forall j: i != j -> !(inCs[i] && inCs[j])',
    'time <= 10.5 || N > 2',
    'count(ready) + count(inCs) <= N',
    'forall i: dist(pos[i], target[i]) < 1.0',
    'forall i: pos[i].x >= 0',
    'phase != DONE -> size(dests) > 0',
    'forall i: stage[i] == GO -> contains(dests, target[i])',
    'slots[0] + votes[1][0] >= 0',
    'forall i: size(seen[i]) == 0 || seen[i][0] >= 0',
    'count(doReach_done) <= getNumAgents()',
    'forall i: doReach_fail[i] -> !inCs[i]',
    'isEmpty(dests) || head(dests) == ItemPosition(0, 0)',
    'time_left > 0',
]


@pytest.fixture(scope="module")
def props_info():
    return check_program(parse_program(PROPS_PROGRAM, "props.pccl"))


@pytest.mark.parametrize("text", GOOD_PROPERTIES)
def test_good_property(text, props_info):
    prop(text, props_info)


def test_fischer_mutex_property():
    info = check_program(parse_program((PROGRAMS / "fischer.pccl").read_text(), "fischer.pccl"))
    prop("count(inCs) <= 1", info)
    prop("forall i: forall j: inCs[i] && inCs[j] -> i == j", info)
    prop("exists i: reqid == id[i] || reqid == -1", info)
    assert prop_error("inCs", info) == """\
--invariant:1:1: error: 'inCs' is per-agent: write inCs[i]
    1 | inCs
      | ^^^^"""


def test_property_names_clash_with_program_variables():
    info = check("""\
allwrite:
  int time = 0;
  int N = 2;
loc:
  ItemPosition pos;
""")
    prop("forall N: N >= 0", info)          # a bound id shadows
    assert prop_error("time > 3", info) == """\
--invariant:1:1: error: 'time' is ambiguous in a property: the program declares a variable 'time'; rename it
    1 | time > 3
      | ^^^^"""
    assert prop_error("N > 3", info) == """\
--invariant:1:1: error: 'N' is ambiguous in a property: the program declares a variable 'N'; rename it
    1 | N > 3
      | ^"""
    assert prop_error("forall i: pos[i].x > 0", info) == """\
--invariant:1:11: error: 'pos' is ambiguous in a property: the program declares a variable 'pos'; rename it
    1 | forall i: pos[i].x > 0
      |           ^^^"""


def test_invariant_section_is_checked_as_properties():
    src = """\
loc:
  int c = 0;

invariant:
  small: c < 3;
"""
    assert check_error(src) == """\
t.pccl:5:10: error: 'c' is per-agent: write c[i]
    5 |   small: c < 3;
      |          ^"""
    check(src.replace("c < 3", "forall i: c[i] < 3"))


# --------------------------------------------------------------------------
# Golden messages: tests/golden/checker/NAME.pccl (a program, read as t.pccl)
# and tests/golden/properties/NAME.prop (an --invariant against PROPS_PROGRAM),
# each with NAME.err, the whole rendered message as pccl prints it (the
# options it names spelt as flags, pccl.cli.cli_spelling).  To add a case, add the
# source file and run with PCCL_REGEN_GOLDEN=1, which (re)writes every .err
# that differs from the checker's output; review the diff before committing.
# --------------------------------------------------------------------------

GOLDEN = Path(__file__).resolve().parents[1] / "golden"
REGEN_GOLDEN = os.environ.get("PCCL_REGEN_GOLDEN", "") not in ("", "0")


def _golden(kind: str, ext: str) -> list:
    return sorted((GOLDEN / kind).glob("*" + ext))


def _compare_golden(source: Path, message: str) -> None:
    expected = source.with_suffix(".err")
    if REGEN_GOLDEN:
        if not expected.exists() or expected.read_text() != message + "\n":
            expected.write_text(message + "\n")
        return
    assert expected.exists(), f"{expected.name} missing: run with PCCL_REGEN_GOLDEN=1"
    assert message == expected.read_text().rstrip("\n")


def test_golden_files_come_in_pairs():
    for kind, ext in (("checker", ".pccl"), ("properties", ".prop")):
        sources = {p.stem for p in _golden(kind, ext)}
        errs = {p.stem for p in _golden(kind, ".err")}
        assert len(sources) > 20
        assert errs == sources, (kind, errs ^ sources)


@pytest.mark.parametrize("path", _golden("checker", ".pccl"), ids=lambda p: p.stem)
def test_program_error(path):
    _compare_golden(path, check_error(path.read_text()))


@pytest.mark.parametrize("path", _golden("properties", ".prop"), ids=lambda p: p.stem)
def test_property_error(path, props_info):
    _compare_golden(path, prop_error(path.read_text(), props_info))
