"""Tests of the static checker (pccl.checker) and the built-in table.

Every error message is pinned by a golden test of the full rendered text:
``file:line:col: error: message``, the source line and the caret.
"""

from __future__ import annotations

import tomllib
from dataclasses import replace
from pathlib import Path

import pytest

from pccl import ast
from pccl.ast import Span
from pccl.builtins import BUILTINS, READONLY_FLAGS, STATEMENTS, EXPRESSIONS, UNINTERPRETED
from pccl.checker import CheckedProgram, check_program, check_property
from pccl.types import ANY, BOOL, FLOAT, INT, OBSTACLES, POS, Ty, array_of, enum_ty, list_of
from pccl.errors import PcclError
from pccl.parser import parse_program, parse_property

PROGRAMS = Path(__file__).resolve().parent.parent / "programs"
SHIPPED = sorted(PROGRAMS.glob("*.pccl"))


def check(src: str, **kw) -> CheckedProgram:
    return check_program(parse_program(src, "t.pccl"), **kw)


def check_error(src: str, **kw) -> str:
    prog = parse_program(src, "t.pccl")
    with pytest.raises(PcclError) as ei:
        check_program(prog, **kw)
    return ei.value.render()


def prop(text: str, info: CheckedProgram) -> None:
    check_property(parse_property(text, "--invariant"), info,
                   filename="--invariant", source=text)


def prop_error(text: str, info: CheckedProgram) -> str:
    with pytest.raises(PcclError) as ei:
        prop(text, info)
    return ei.value.render()


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
    return ei.value.render()


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


def test_duplicate_member_in_one_enum():
    src = "loc:\n  enum Stage { GO, GO };\n"
    prog = ast.Program(None, (ast.EnumDecl("loc", "Stage", ("GO", "GO"), span=Span(2, 3, 2, 24)),),
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


PROGRAM_ERRORS = [
    pytest.param(
        """\
loc:
  int c = 0;

Tick():
  pre(true);
  eff:
    c = cc + 1;
""",
        """\
t.pccl:7:9: error: undeclared variable 'cc'
    7 |     c = cc + 1;
      |         ^^
""",
        id='undeclared_variable'),
    pytest.param(
        """\
allwrite:
  List<int> dests = [1];
loc:
  int currentDest;

Pick():
  pre(!isempty(dests));
  eff:
    currentDest = head(dests);
""",
        """\
t.pccl:7:8: error: unknown function 'isempty' (did you mean 'isEmpty'?)
    7 |   pre(!isempty(dests));
      |        ^^^^^^^
""",
        id='unknown_function_did_you_mean'),
    pytest.param(
        """\
loc:
  int currentDest;

Pick():
  pre(true);
  eff:
    currentDest = currentDst + 1;
""",
        """\
t.pccl:7:19: error: undeclared variable 'currentDst' (did you mean 'currentDest'?)
    7 |     currentDest = currentDst + 1;
      |                   ^^^^^^^^^^
""",
        id='undeclared_variable_did_you_mean'),
    pytest.param(
        """\
allwrite:
  List<int> dests = [1];

Pick():
  pre(true);
  eff:
    remov(dests, 1);
""",
        """\
t.pccl:7:5: error: unknown function 'remov' (did you mean 'remove'?)
    7 |     remov(dests, 1);
      |     ^^^^^
""",
        id='unknown_statement_did_you_mean'),
    pytest.param(
        """\
loc:
  int count;

Pick():
  pre(true);
  eff:
    cont = 1;
""",
        """\
t.pccl:7:5: error: undeclared variable 'cont' (did you mean 'count'?)
    7 |     cont = 1;
      |     ^^^^
""",
        id='assign_undeclared_did_you_mean'),
    pytest.param(
        """\
loc:
  int c = 0;

Tick():
  pre(time > 3);
  eff:
    c = 1;
""",
        """\
t.pccl:5:7: error: undeclared variable 'time' (a program cannot read the clock)
    5 |   pre(time > 3);
      |       ^^^^
""",
        id='undeclared_time'),
    pytest.param(
        """\
allwrite:
  int x = 0;
loc:
  bool x = true;
""",
        """\
t.pccl:4:8: error: duplicate variable 'x' (first declared at line 2)
    4 |   bool x = true;
      |        ^
""",
        id='duplicate_variable_across_sections'),
    pytest.param(
        """\
allwrite:
  enum Stage { PICK, GO };
loc:
  enum Stage { WAIT };
""",
        """\
t.pccl:4:8: error: duplicate enum 'Stage' (first declared at line 2)
    4 |   enum Stage { WAIT };
      |        ^^^^^
""",
        id='duplicate_enum'),
    pytest.param(
        """\
allwrite:
  enum Stage { PICK, GO };
  enum Phase { WAIT, GO };
""",
        """\
t.pccl:3:22: error: duplicate enum member 'GO' (first declared at line 2)
    3 |   enum Phase { WAIT, GO };
      |                      ^^
""",
        id='enum_member_clashes_with_member'),
    pytest.param(
        """\
allwrite:
  int GO = 1;
  enum Stage { PICK, GO };
""",
        """\
t.pccl:3:22: error: 'GO' is already declared as a variable at line 2
    3 |   enum Stage { PICK, GO };
      |                      ^^
""",
        id='enum_member_clashes_with_variable'),
    pytest.param(
        """\
loc:
  enum Stage { PICK, GO };
  int Stage = 0;
""",
        """\
t.pccl:3:7: error: 'Stage' is already declared as an enum at line 2
    3 |   int Stage = 0;
      |       ^^^^^
""",
        id='variable_clashes_with_enum'),
    pytest.param(
        """\
loc:
  enum ItemPosition { A, B };
""",
        """\
t.pccl:2:8: error: 'ItemPosition' is a built-in type; it cannot name an enum
    2 |   enum ItemPosition { A, B };
      |        ^^^^^^^^^^^^
""",
        id='enum_named_like_builtin_type'),
    pytest.param(
        """\
loc:
  bool doReach_done = false;
""",
        """\
t.pccl:2:8: error: 'doReach_done' is a read-only flag of the controller; it cannot be declared
    2 |   bool doReach_done = false;
      |        ^^^^^^^^^^^^
""",
        id='declare_readonly_flag'),
    pytest.param(
        """\
loc:
  int c = 0;

Tick():
  pre(true);
  eff:
    c = c + 1;

Tick():
  pre(c > 3);
  eff:
    c = 0;
""",
        """\
t.pccl:9:1: error: duplicate event 'Tick' (first declared at line 4)
    9 | Tick():
      | ^^^^
""",
        id='duplicate_event'),
    pytest.param(
        """\
loc:
  bool inCs = false;

invariant:
  mutex: count(inCs) <= 1;
  mutex: count(inCs) < 2;
""",
        """\
t.pccl:6:3: error: duplicate invariant 'mutex' (first declared at line 5)
    6 |   mutex: count(inCs) < 2;
      |   ^^^^^
""",
        id='duplicate_invariant'),
    pytest.param(
        """\
loc:
  Position p;
""",
        """\
t.pccl:2:3: error: unknown type 'Position'
    2 |   Position p;
      |   ^^^^^^^^
""",
        id='unknown_type'),
    pytest.param(
        """\
allwrite:
  List<Point> ps = [];
""",
        """\
t.pccl:2:8: error: unknown type 'Point'
    2 |   List<Point> ps = [];
      |        ^^^^^
""",
        id='unknown_list_element_type'),
    pytest.param(
        """\
allwrite:
  int n = 3;
loc:
  int a[n];
""",
        """\
t.pccl:4:9: error: array size must be a constant int expression
    4 |   int a[n];
      |         ^
""",
        id='array_size_not_constant'),
    pytest.param(
        """\
loc:
  bool flags[getNumAgents()];
""",
        """\
t.pccl:2:14: error: array size must be a constant int expression
    2 |   bool flags[getNumAgents()];
      |              ^^^^^^^^^^^^^^
""",
        id='array_size_call'),
    pytest.param(
        """\
loc:
  int a[2 - 2];
""",
        """\
t.pccl:2:9: error: array size must be at least 1, got 0
    2 |   int a[2 - 2];
      |         ^^^^^
""",
        id='array_size_not_positive'),
    pytest.param(
        """\
loc:
  int a[4 / (1 - 1)];
""",
        """\
t.pccl:2:9: error: division by zero in array size
    2 |   int a[4 / (1 - 1)];
      |         ^^^^^^^^^^^
""",
        id='array_size_division_by_zero'),
    pytest.param(
        """\
loc:
  int c = 1.5;
""",
        """\
t.pccl:2:11: error: cannot initialise 'c' of type int with float
    2 |   int c = 1.5;
      |           ^^^
""",
        id='init_type_mismatch'),
    pytest.param(
        """\
allwrite:
  List<int> xs = [true, false];
""",
        """\
t.pccl:2:18: error: cannot initialise 'xs' of type List<int> with List<bool>
    2 |   List<int> xs = [true, false];
      |                  ^^^^^^^^^^^^^
""",
        id='init_list_type_mismatch'),
    pytest.param(
        """\
loc:
  bool flags[3] = 0;
""",
        """\
t.pccl:2:19: error: cannot initialise 'flags' of type bool with int
    2 |   bool flags[3] = 0;
      |                   ^
""",
        id='init_array_fill_type'),
    pytest.param(
        """\
loc:
  enum Stage { PICK, GO };
  enum Light { RED, GREEN };
  Stage s = RED;
""",
        """\
t.pccl:4:13: error: cannot initialise 's' of type Stage with Light
    4 |   Stage s = RED;
      |             ^^^
""",
        id='init_enum_mismatch'),
    pytest.param(
        """\
loc:
  int waitTime = rand(k);
  int k = 10;
""",
        """\
t.pccl:2:23: error: 'k' is not declared yet: an initialiser can use only variables declared above it
    2 |   int waitTime = rand(k);
      |                       ^
""",
        id='init_use_before_declaration'),
    pytest.param(
        """\
loc:
  int k = k + 1;
""",
        """\
t.pccl:2:11: error: 'k' is not declared yet: an initialiser can use only variables declared above it
    2 |   int k = k + 1;
      |           ^
""",
        id='init_self_reference'),
    pytest.param(
        """\
allwrite:
  int first = id;
loc:
  int id = getAgentIndex();
""",
        """\
t.pccl:2:15: error: shared (allwrite) variable 'first' cannot be initialised from per-agent (loc) variable 'id'
    2 |   int first = id;
      |               ^^
""",
        id='shared_init_from_local'),
    pytest.param(
        """\
allwrite:
  int leader = ticket;
allread:
  int ticket = 0;
""",
        """\
t.pccl:2:16: error: shared (allwrite) variable 'leader' cannot be initialised from per-agent (allread) variable 'ticket'
    2 |   int leader = ticket;
      |                ^^^^^^
""",
        id='shared_init_from_allread'),
    pytest.param(
        """\
allwrite:
  int owner = getAgentIndex();
""",
        """\
t.pccl:2:15: error: 'getAgentIndex' needs an agent: a shared (allwrite) initialiser cannot call it
    2 |   int owner = getAgentIndex();
      |               ^^^^^^^^^^^^^
""",
        id='shared_init_agent_function'),
    pytest.param(
        """\
allwrite:
  ItemPosition home = getPosition();
""",
        """\
t.pccl:2:23: error: 'getPosition' needs an agent: a shared (allwrite) initialiser cannot call it
    2 |   ItemPosition home = getPosition();
      |                       ^^^^^^^^^^^
""",
        id='shared_init_position'),
    pytest.param(
        """\
allwrite:
  bool ready = doReach_done;
""",
        """\
t.pccl:2:16: error: 'doReach_done' is per-agent: a shared (allwrite) initialiser cannot use it
    2 |   bool ready = doReach_done;
      |                ^^^^^^^^^^^^
""",
        id='shared_init_flag'),
    pytest.param(
        """\
Init:
  moveTo(1, 2);
""",
        """\
t.pccl:2:3: error: unknown function 'moveTo'
    2 |   moveTo(1, 2);
      |   ^^^^^^
""",
        id='unknown_function_statement'),
    pytest.param(
        """\
loc:
  int c = getCount();
""",
        """\
t.pccl:2:11: error: unknown function 'getCount': not a built-in; a function the world provides needs --world FILE defining getCount under [functions]
    2 |   int c = getCount();
      |           ^^^^^^^^
""",
        id='unknown_function_expression'),
    pytest.param(
        """\
loc:
  float d = dist(getPosition());
""",
        """\
t.pccl:2:13: error: 'dist' takes 2 arguments, got 1
    2 |   float d = dist(getPosition());
      |             ^^^^^^^^^^^^^^^^^^^
""",
        id='arity_dist'),
    pytest.param(
        """\
loc:
  ItemPosition p = ItemPosition(1);
""",
        """\
t.pccl:2:20: error: 'ItemPosition' takes 2 or 3 arguments, got 1
    2 |   ItemPosition p = ItemPosition(1);
      |                    ^^^^^^^^^^^^^^^
""",
        id='arity_item_position'),
    pytest.param(
        """\
Init:
  exit(0);
""",
        """\
t.pccl:2:3: error: 'exit' takes no arguments, got 1
    2 |   exit(0);
      |   ^^^^^^^
""",
        id='arity_exit'),
    pytest.param(
        """\
loc:
  int r = rand(1, 5);
""",
        """\
t.pccl:2:11: error: 'rand' takes 1 argument, got 2
    2 |   int r = rand(1, 5);
      |           ^^^^^^^^^^
""",
        id='arity_rand'),
    pytest.param(
        """\
Init:
  doReach(getPosition());
""",
        """\
t.pccl:2:3: error: 'doReach' takes 2 arguments, got 1
    2 |   doReach(getPosition());
      |   ^^^^^^^^^^^^^^^^^^^^^^
""",
        id='arity_doreach'),
    pytest.param(
        """\
allwrite:
  List<int> xs = getInput(3);
""",
        """\
t.pccl:2:18: error: 'getInput' takes no arguments, got 1
    2 |   List<int> xs = getInput(3);
      |                  ^^^^^^^^^^^
""",
        id='arity_uninterpreted'),
    pytest.param(
        """\
loc:
  bool b = exit();
""",
        """\
t.pccl:2:12: error: 'exit' is a statement, not a value
    2 |   bool b = exit();
      |            ^^^^
""",
        id='statement_as_value'),
    pytest.param(
        """\
loc:
  int c = 0;

Tick():
  pre(true);
  eff:
    if (assert(c > 0)):
      c = 0;
""",
        """\
t.pccl:7:9: error: 'assert' is a statement, not a value
    7 |     if (assert(c > 0)):
      |         ^^^^^^
""",
        id='statement_as_value_nested'),
    pytest.param(
        """\
allwrite:
  List<int> xs = [1, 2];

Init:
  head(xs);
""",
        """\
t.pccl:5:3: error: 'head' returns a value; it is not a statement
    5 |   head(xs);
      |   ^^^^
""",
        id='value_as_statement'),
    pytest.param(
        """\
Init:
  getInput();
""",
        """\
t.pccl:2:3: error: 'getInput' returns a value; it is not a statement
    2 |   getInput();
      |   ^^^^^^^^
""",
        id='uninterpreted_as_statement'),
    pytest.param(
        """\
loc:
  bool inCs = false;
  int n = count(inCs);
""",
        """\
t.pccl:3:11: error: 'count' is only available in properties
    3 |   int n = count(inCs);
      |           ^^^^^
""",
        id='count_in_program'),
    pytest.param(
        """\
allwrite:
  List<int> xs = getInput;
""",
        """\
t.pccl:2:18: error: 'getInput' is a function: call it, getInput()
    2 |   List<int> xs = getInput;
      |                  ^^^^^^^^
""",
        id='function_as_value'),
    pytest.param(
        """\
allwrite:
  List<ItemPosition> targets = getTargets();
""",
        """\
t.pccl:2:32: error: unknown function 'getTargets': not a built-in; a function the world provides needs --world FILE defining getTargets under [functions]
    2 |   List<ItemPosition> targets = getTargets();
      |                                ^^^^^^^^^^
""",
        id='world_function_unknown_without_world'),
    pytest.param(
        """\
loc:
  int c = 0;
  float f = 0.5;

Tick():
  pre(true);
  eff:
    c = c + f;
""",
        """\
t.pccl:8:9: error: cannot assign float to 'c' of type int
    8 |     c = c + f;
      |         ^^^^^
""",
        id='assign_float_to_int'),
    pytest.param(
        """\
loc:
  int c = 0;

Init:
  c = c > 1;
""",
        """\
t.pccl:5:7: error: cannot assign bool to 'c' of type int
    5 |   c = c > 1;
      |       ^^^^^
""",
        id='assign_bool_to_int'),
    pytest.param(
        """\
allwrite:
  List<ItemPosition> dests = getInput();
loc:
  ItemPosition target;

Init:
  target = dests;
""",
        """\
t.pccl:7:12: error: cannot assign List<ItemPosition> to 'target' of type ItemPosition
    7 |   target = dests;
      |            ^^^^^
""",
        id='assign_list_to_position'),
    pytest.param(
        """\
loc:
  int c = 0;

Tick():
  pre(true);
  eff:
    if (c):
      c = 0;
""",
        """\
t.pccl:7:9: error: condition of 'if' must be bool, got int
    7 |     if (c):
      |         ^
""",
        id='if_condition_not_bool'),
    pytest.param(
        """\
loc:
  int c = 0;

Tick():
  pre(true);
  eff:
    if (c > 3):
      c = 0;
    else if (c + 1):
      c = 1;
""",
        """\
t.pccl:9:14: error: condition of 'if' must be bool, got int
    9 |     else if (c + 1):
      |              ^^^^^
""",
        id='else_if_condition_not_bool'),
    pytest.param(
        """\
loc:
  int c = 3;

Init:
  while (c):
    c = c - 1;
""",
        """\
t.pccl:5:10: error: condition of 'while' must be bool, got int
    5 |   while (c):
      |          ^
""",
        id='while_condition_not_bool'),
    pytest.param(
        """\
loc:
  int c = 0;

Tick():
  pre(c + 1);
  eff:
    c = 0;
""",
        """\
t.pccl:5:7: error: condition of 'pre' must be bool, got int
    5 |   pre(c + 1);
      |       ^^^^^
""",
        id='pre_condition_not_bool'),
    pytest.param(
        """\
loc:
  int c = 0;

Init:
  assert(c);
""",
        """\
t.pccl:5:10: error: condition of 'assert' must be bool, got int
    5 |   assert(c);
      |          ^
""",
        id='assert_condition_not_bool'),
    pytest.param(
        """\
loc:
  int c = 0;
  bool b = c == true;
""",
        """\
t.pccl:3:12: error: cannot compare int with bool using '=='
    3 |   bool b = c == true;
      |            ^^^^^^^^^
""",
        id='equality_incompatible'),
    pytest.param(
        """\
loc:
  enum Stage { PICK, GO };
  Stage s = PICK;
  bool b = s != 0;
""",
        """\
t.pccl:4:12: error: cannot compare Stage with int using '!='
    4 |   bool b = s != 0;
      |            ^^^^^^
""",
        id='equality_enum_vs_int'),
    pytest.param(
        """\
loc:
  bool b = true;
  bool c = b < false;
""",
        """\
t.pccl:3:12: error: operands of '<' must be numbers, got bool
    3 |   bool c = b < false;
      |            ^
""",
        id='ordering_bool'),
    pytest.param(
        """\
loc:
  enum Stage { PICK, GO };
  bool b = PICK < GO;
""",
        """\
t.pccl:3:12: error: operands of '<' must be numbers, got Stage
    3 |   bool b = PICK < GO;
      |            ^^^^
""",
        id='ordering_enum'),
    pytest.param(
        """\
loc:
  int c = 0;
  bool b = c && true;
""",
        """\
t.pccl:3:12: error: operands of '&&' must be bool, got int
    3 |   bool b = c && true;
      |            ^
""",
        id='and_on_int'),
    pytest.param(
        """\
loc:
  bool b = false || 1.5;
""",
        """\
t.pccl:2:21: error: operands of '||' must be bool, got float
    2 |   bool b = false || 1.5;
      |                     ^^^
""",
        id='or_on_float'),
    pytest.param(
        """\
loc:
  int c = 0;
  bool b = !c;
""",
        """\
t.pccl:3:13: error: operand of '!' must be bool, got int
    3 |   bool b = !c;
      |             ^
""",
        id='not_on_int'),
    pytest.param(
        """\
loc:
  bool b = true;
  int c = -b;
""",
        """\
t.pccl:3:12: error: operand of '-' must be a number, got bool
    3 |   int c = -b;
      |            ^
""",
        id='negate_bool'),
    pytest.param(
        """\
loc:
  int c = 1 + true;
""",
        """\
t.pccl:2:15: error: operands of '+' must be numbers, got bool
    2 |   int c = 1 + true;
      |               ^^^^
""",
        id='arith_on_bool'),
    pytest.param(
        """\
loc:
  ItemPosition p = getPosition();
  float f = p * 2;
""",
        """\
t.pccl:3:13: error: operands of '*' must be numbers, got ItemPosition
    3 |   float f = p * 2;
      |             ^
""",
        id='arith_on_position'),
    pytest.param(
        """\
loc:
  float f = 7.5 % 2;
""",
        """\
t.pccl:2:13: error: operands of '%' must be int, got float
    2 |   float f = 7.5 % 2;
      |             ^^^
""",
        id='mod_on_float'),
    pytest.param(
        """\
loc:
  int c = 7 / 2.0;
""",
        """\
t.pccl:2:11: error: cannot initialise 'c' of type int with float
    2 |   int c = 7 / 2.0;
      |           ^^^^^^^
""",
        id='division_is_float'),
    pytest.param(
        """\
loc:
  int c = getInput() + 1;
""",
        """\
t.pccl:2:11: error: operand of '+' has no static type (a value from the world file): store it in a typed variable first
    2 |   int c = getInput() + 1;
      |           ^^^^^^^^^^
""",
        id='arith_on_any'),
    pytest.param(
        """\
allwrite:
  List<int> xs = [1, 2, true];
""",
        """\
t.pccl:2:25: error: list elements disagree: bool after int
    2 |   List<int> xs = [1, 2, true];
      |                         ^^^^
""",
        id='list_literal_disagree'),
    pytest.param(
        """\
allwrite:
  List<int> xs = [];

Init:
  add([1, 2], 3);
""",
        """\
t.pccl:5:7: error: argument 1 of 'add' must be a List variable (it is rewritten in place), not an expression
    5 |   add([1, 2], 3);
      |       ^^^^^^
""",
        id='add_to_expression'),
    pytest.param(
        """\
loc:
  int c = 0;

Init:
  add(c, 3);
""",
        """\
t.pccl:5:7: error: argument 1 of 'add' must be a List variable, got int
    5 |   add(c, 3);
      |       ^
""",
        id='add_to_non_list'),
    pytest.param(
        """\
allwrite:
  List<int> xs = [];

Init:
  add(xs, 2.5);
""",
        """\
t.pccl:5:11: error: argument 2 of 'add' must be int (the list's element type), got float
    5 |   add(xs, 2.5);
      |           ^^^
""",
        id='add_element_type'),
    pytest.param(
        """\
allwrite:
  List<ItemPosition> dests = getInput();

Init:
  remove(dests, 1);
""",
        """\
t.pccl:5:17: error: argument 2 of 'remove' must be ItemPosition (the list's element type), got int
    5 |   remove(dests, 1);
      |                 ^
""",
        id='remove_element_type'),
    pytest.param(
        """\
Init:
  remove(doReach_done, 1);
""",
        """\
t.pccl:2:10: error: 'doReach_done' is read-only: set by the controller
    2 |   remove(doReach_done, 1);
      |          ^^^^^^^^^^^^
""",
        id='remove_from_flag'),
    pytest.param(
        """\
allread:
  List<int> mine = [];

Init:
  add(mine[0], 1);
""",
        """\
t.pccl:5:7: error: cannot write agent 0's component of allread variable 'mine': an agent writes only its own component, `mine = …`
    5 |   add(mine[0], 1);
      |       ^^^^^^^
""",
        id='add_to_other_agents_list'),
    pytest.param(
        """\
loc:
  int c = 0;
  int h = head(c);
""",
        """\
t.pccl:3:16: error: argument 1 of 'head' must be a List, got int
    3 |   int h = head(c);
      |                ^
""",
        id='head_of_non_list'),
    pytest.param(
        """\
allwrite:
  List<ItemPosition> dests = getInput();
loc:
  int h = head(dests);
""",
        """\
t.pccl:4:11: error: cannot initialise 'h' of type int with ItemPosition
    4 |   int h = head(dests);
      |           ^^^^^^^^^^^
""",
        id='head_result_type'),
    pytest.param(
        """\
allwrite:
  List<ItemPosition> dests = getInput();
loc:
  bool b = contains(dests, true);
""",
        """\
t.pccl:4:28: error: argument 2 of 'contains' must be ItemPosition (the list's element type), got bool
    4 |   bool b = contains(dests, true);
      |                            ^^^^
""",
        id='contains_element_type'),
    pytest.param(
        """\
loc:
  int n = size(getPosition());
""",
        """\
t.pccl:2:16: error: argument 1 of 'size' must be a List, got ItemPosition
    2 |   int n = size(getPosition());
      |                ^^^^^^^^^^^^^
""",
        id='size_of_position'),
    pytest.param(
        """\
loc:
  int r = rand(2.5);
""",
        """\
t.pccl:2:16: error: argument 1 of 'rand' must be int, got float
    2 |   int r = rand(2.5);
      |                ^^^
""",
        id='rand_of_float'),
    pytest.param(
        """\
loc:
  ItemPosition p = ItemPosition(1, true);
""",
        """\
t.pccl:2:36: error: argument 2 of 'ItemPosition' must be a number, got bool
    2 |   ItemPosition p = ItemPosition(1, true);
      |                                    ^^^^
""",
        id='item_position_of_bool'),
    pytest.param(
        """\
loc:
  float d = dist(getPosition(), 3);
""",
        """\
t.pccl:2:33: error: argument 2 of 'dist' must be ItemPosition, got int
    2 |   float d = dist(getPosition(), 3);
      |                                 ^
""",
        id='dist_of_int'),
    pytest.param(
        """\
loc:
  ObstacleList obs = getObs();

Init:
  doReach(3, obs);
""",
        """\
t.pccl:5:11: error: argument 1 of 'doReach' must be ItemPosition, got int
    5 |   doReach(3, obs);
      |           ^
""",
        id='doreach_target_type'),
    pytest.param(
        """\
Init:
  doReach(getPosition(), getPosition());
""",
        """\
t.pccl:2:26: error: argument 2 of 'doReach' must be ObstacleList, got ItemPosition
    2 |   doReach(getPosition(), getPosition());
      |                          ^^^^^^^^^^^^^
""",
        id='doreach_obstacles_type'),
    pytest.param(
        """\
Init:
  doReach(getPosition(), [1, 2]);
""",
        """\
t.pccl:2:26: error: argument 2 of 'doReach' must be ObstacleList, got List<int>
    2 |   doReach(getPosition(), [1, 2]);
      |                          ^^^^^^
""",
        id='doreach_obstacles_int_list'),
    pytest.param(
        """\
loc:
  int c = 0;
  float f = c.x;
""",
        """\
t.pccl:3:13: error: field '.x' needs an ItemPosition, got int
    3 |   float f = c.x;
      |             ^^^
""",
        id='field_on_non_position'),
    pytest.param(
        """\
loc:
  float f = getPosition().w;
""",
        """\
t.pccl:2:13: error: ItemPosition has no field '.w' (only .x, .y, .z)
    2 |   float f = getPosition().w;
      |             ^^^^^^^^^^^^^^^
""",
        id='unknown_field'),
    pytest.param(
        """\
loc:
  int c = 0;
  int d = c[0];
""",
        """\
t.pccl:3:11: error: cannot index a value of type int
    3 |   int d = c[0];
      |           ^^^^
""",
        id='index_non_indexable'),
    pytest.param(
        """\
loc:
  int a[3];
  int d = a[true];
""",
        """\
t.pccl:3:13: error: index must be int, got bool
    3 |   int d = a[true];
      |             ^^^^
""",
        id='index_not_int'),
    pytest.param(
        """\
allread:
  int ticket = 0;
loc:
  int t = ticket[1.0];
""",
        """\
t.pccl:4:18: error: agent index must be int, got float
    4 |   int t = ticket[1.0];
      |                  ^^^
""",
        id='agent_index_not_int'),
    pytest.param(
        """\
loc:
  int a[3];
  int b[3];

Init:
  assert(a == b);
""",
        """\
t.pccl:6:10: error: array 'a' must be indexed: write a[i]
    6 |   assert(a == b);
      |          ^
""",
        id='array_not_indexed'),
    pytest.param(
        """\
loc:
  int a[3];

Init:
  a = 0;
""",
        """\
t.pccl:5:3: error: cannot assign to array 'a' as a whole: assign its elements, a[i] = …
    5 |   a = 0;
      |   ^
""",
        id='array_assigned_whole'),
    pytest.param(
        """\
Init:
  doReach_done = true;
""",
        """\
t.pccl:2:3: error: 'doReach_done' is read-only: set by the controller
    2 |   doReach_done = true;
      |   ^^^^^^^^^^^^
""",
        id='assign_doreach_done'),
    pytest.param(
        """\
Init:
  doReach_fail[0] = false;
""",
        """\
t.pccl:2:3: error: 'doReach_fail' is read-only: set by the controller
    2 |   doReach_fail[0] = false;
      |   ^^^^^^^^^^^^
""",
        id='assign_doreach_fail_indexed'),
    pytest.param(
        """\
allread:
  int ticket = 0;

Init:
  ticket[1] = 5;
""",
        """\
t.pccl:5:3: error: cannot write agent 1's component of allread variable 'ticket': an agent writes only its own component, `ticket = …`
    5 |   ticket[1] = 5;
      |   ^^^^^^^^^
""",
        id='write_other_agent_allread'),
    pytest.param(
        """\
allread:
  int ticket = 0;
loc:
  int id = getAgentIndex();

Init:
  ticket[id] = 5;
""",
        """\
t.pccl:7:3: error: cannot write agent id's component of allread variable 'ticket': an agent writes only its own component, `ticket = …`
    7 |   ticket[id] = 5;
      |   ^^^^^^^^^^
""",
        id='write_other_agent_allread_own_id'),
    pytest.param(
        """\
allread:
  int votes[3];

Init:
  votes[0][2] = 1;
""",
        """\
t.pccl:5:3: error: cannot write agent 0's component of allread variable 'votes': an agent writes only its own component, `votes[k] = …`
    5 |   votes[0][2] = 1;
      |   ^^^^^^^^^^^
""",
        id='write_other_agent_allread_array'),
    pytest.param(
        """\
loc:
  enum Stage { PICK, GO };

Init:
  GO = PICK;
""",
        """\
t.pccl:5:3: error: cannot assign to enum member 'GO'
    5 |   GO = PICK;
      |   ^^
""",
        id='assign_enum_member'),
    pytest.param(
        """\
Init:
  getInput = 3;
""",
        """\
t.pccl:2:3: error: cannot assign to function 'getInput'
    2 |   getInput = 3;
      |   ^^^^^^^^
""",
        id='assign_function'),
    pytest.param(
        """\
Init:
  rand = 3;
""",
        """\
t.pccl:2:3: error: cannot assign to function 'rand'
    2 |   rand = 3;
      |   ^^^^
""",
        id='assign_builtin_function'),
    pytest.param(
        """\
loc:
  bool inCs = false;

Init:
  count(inCs);
""",
        """\
t.pccl:5:3: error: 'count' is only available in properties
    5 |   count(inCs);
      |   ^^^^^
""",
        id='count_as_statement'),
    pytest.param(
        """\
Init:
  total = 1;
""",
        """\
t.pccl:2:3: error: undeclared variable 'total'
    2 |   total = 1;
      |   ^^^^^
""",
        id='assign_undeclared'),
    pytest.param(
        """\
loc:
  int a[-(-2) + 7 / 2 * -1 + 7 % 4 - 3];
""",
        """\
t.pccl:2:9: error: array size must be at least 1, got -1
    2 |   int a[-(-2) + 7 / 2 * -1 + 7 % 4 - 3];
      |         ^^^^^^^^^^^^^^^^^^^^^^^^^^^^^^
""",
        id='array_size_expression_not_positive'),
]

PROPERTY_ERRORS = [
    pytest.param(
        'inCs',
        """\
--invariant:1:1: error: 'inCs' is per-agent: write inCs[i]
    1 | inCs
      | ^^^^
""",
        id='property_bare_local'),
    pytest.param(
        'c > 0',
        """\
--invariant:1:1: error: 'c' is per-agent: write c[i]
    1 | c > 0
      | ^
""",
        id='property_bare_local_in_count_expr'),
    pytest.param(
        'ticket == 1',
        """\
--invariant:1:1: error: 'ticket' is per-agent: write ticket[i]
    1 | ticket == 1
      | ^^^^^^
""",
        id='property_bare_allread'),
    pytest.param(
        'pos == pos',
        """\
--invariant:1:1: error: 'pos' is per-agent: write pos[i]
    1 | pos == pos
      | ^^^
""",
        id='property_bare_pos'),
    pytest.param(
        'doReach_done',
        """\
--invariant:1:1: error: 'doReach_done' is per-agent: write doReach_done[i]
    1 | doReach_done
      | ^^^^^^^^^^^^
""",
        id='property_bare_flag'),
    pytest.param(
        'count(inCs)',
        """\
--invariant:1:1: error: a property must be bool, got int
    1 | count(inCs)
      | ^^^^^^^^^^^
""",
        id='property_not_bool'),
    pytest.param(
        'forall i: c[i] + 1',
        """\
--invariant:1:11: error: the body of 'forall' must be bool, got int
    1 | forall i: c[i] + 1
      |           ^^^^^^^^
""",
        id='property_quant_body_not_bool'),
    pytest.param(
        'count(c) == 0',
        """\
--invariant:1:7: error: 'count' takes the name of a bool local or allread variable, count(v)
    1 | count(c) == 0
      |       ^
""",
        id='property_count_int'),
    pytest.param(
        'count(inCS) <= 1',
        """\
--invariant:1:7: error: undeclared variable 'inCS' (did you mean 'inCs'?)
    1 | count(inCS) <= 1
      |       ^^^^
""",
        id='property_count_typo'),
    pytest.param(
        'count(reqid) == 0',
        """\
--invariant:1:7: error: 'count' takes the name of a bool local or allread variable, count(v)
    1 | count(reqid) == 0
      |       ^^^^^
""",
        id='property_count_shared'),
    pytest.param(
        'count(inCs[0]) == 0',
        """\
--invariant:1:7: error: 'count' takes the name of a bool local or allread variable, count(v)
    1 | count(inCs[0]) == 0
      |       ^^^^^^^
""",
        id='property_count_expression'),
    pytest.param(
        'count(inCs, ready) == 0',
        """\
--invariant:1:1: error: 'count' takes 1 argument, got 2
    1 | count(inCs, ready) == 0
      | ^^^^^^^^^^^^^^^^^^
""",
        id='property_count_arity'),
    pytest.param(
        'inCs[getAgentIndex()]',
        """\
--invariant:1:6: error: 'getAgentIndex' cannot be used in a property: quantify over agent ids instead, forall i: …
    1 | inCs[getAgentIndex()]
      |      ^^^^^^^^^^^^^
""",
        id='property_get_agent_index'),
    pytest.param(
        'rand(3) == reqid',
        """\
--invariant:1:1: error: 'rand' cannot be used in a property: a property is evaluated on a state, not sampled
    1 | rand(3) == reqid
      | ^^^^
""",
        id='property_rand'),
    pytest.param(
        'dist(getPosition(), pos[0]) < 1',
        """\
--invariant:1:6: error: 'getPosition' cannot be used in a property: write pos[i] for agent i's position
    1 | dist(getPosition(), pos[0]) < 1
      |      ^^^^^^^^^^^
""",
        id='property_get_position'),
    pytest.param(
        'size(getInput()) >= 0',
        """\
--invariant:1:6: error: 'getInput' cannot be used in a property: its value belongs to the world, not to the state
    1 | size(getInput()) >= 0
      |      ^^^^^^^^
""",
        id='property_get_input'),
    pytest.param(
        'forall i: exit()',
        """\
--invariant:1:11: error: 'exit' is a statement, not a value
    1 | forall i: exit()
      |           ^^^^
""",
        id='property_statement'),
    pytest.param(
        'foo(1) == 2',
        """\
--invariant:1:1: error: unknown function 'foo'
    1 | foo(1) == 2
      | ^^^
""",
        id='property_unknown_function'),
    pytest.param(
        'forall i: done[i]',
        """\
--invariant:1:11: error: undeclared variable 'done' (did you mean 'DONE'?)
    1 | forall i: done[i]
      |           ^^^^
""",
        id='property_undeclared'),
    pytest.param(
        'inCs[true]',
        """\
--invariant:1:6: error: agent index must be int, got bool
    1 | inCs[true]
      |      ^^^^
""",
        id='property_agent_index_not_int'),
    pytest.param(
        '(forall i: inCs[i]) && c[i] > 0',
        """\
--invariant:1:26: error: undeclared variable 'i'
    1 | (forall i: inCs[i]) && c[i] > 0
      |                          ^
""",
        id='property_quant_var_outside'),
    pytest.param(
        'reqid == true',
        """\
--invariant:1:1: error: cannot compare int with bool using '=='
    1 | reqid == true
      | ^^^^^^^^^^^^^
""",
        id='property_type_mismatch'),
    pytest.param(
        'reqid -> inCs[0]',
        """\
--invariant:1:1: error: operands of '->' must be bool, got int
    1 | reqid -> inCs[0]
      | ^^^^^
""",
        id='property_implies_int'),
]


@pytest.mark.parametrize("src, expected", PROGRAM_ERRORS)
def test_program_error(src, expected):
    assert check_error(src) == expected.rstrip("\n")


@pytest.mark.parametrize("text, expected", PROPERTY_ERRORS)
def test_property_error(text, expected, props_info):
    assert prop_error(text, props_info) == expected.rstrip("\n")
