"""The Koord front end (issue 47, docs/koord.md): Koord programs read into
the same AST the PCCL parser builds (compared with hand-written PCCL twins),
the shipped Koord programs' verdicts under run and explore, errors with
carets, and robustness on truncated and mutated Koord files."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from click.testing import CliRunner

from pccl.api import explore, load_program, run
from pccl.cli import main
from pccl.lang import ast
from pccl.lang.checker import check_program
from pccl.lang.errors import PcclError
from pccl.lang.files import is_koord_path
from pccl.lang.koord import parse_koord
from pccl.lang.parser import parse_program
from pccl.model.layout import AGS, LOC, POS

ROOT = Path(__file__).resolve().parents[2]
KOORD = ROOT / "programs" / "koord"
SHIPPED = sorted(KOORD.glob("*.koord"))
LANES = str(KOORD / "allstop.toml")
LINEFORM_WORLD = str(KOORD / "lineform.toml")
ALL_EXIT = "eventually (forall i: exited[i])"


def k(name: str) -> str:
    return str(KOORD / name)


# --------------------------------------------------------------------------
# The same AST as PCCL: every construct next to its PCCL twin
# --------------------------------------------------------------------------

KOORD_ALL = """\
# every construct with a PCCL equivalent
using Motion:
  sensors:
    pos position
    boolean reached
  actuators:
    pos target
using Log:
  actuators:
    stream stdout

allwrite:
  int total = 0
  float speed = 1
  list<int> seen = []

allread:
  pos x[]
  int[] votes
  boolean flags[][3]

local:
  boolean done = false; int step = 0
  pos[] points = [pos(1, 2), (3, 4, 5), pos3d(0, 0, 1)]
  int grid[4] = 0

init:
  x[pid] = Motion.position
  votes[pid] = pid

move:
  pre: not done and (step < 3 or speed > 0.5)
  eff:
    if step == 0 and x[pid] != midpoint(x[0], x[numAgents - 1]):
      x[pid] = midpoint(x[0], x[numAgents - 1])
      Motion.target = x[pid]
    elif Motion.reached:
      step = step + 1
    else:
      skip
    stdout << "step " << step
    Log.stdout << "at " << Motion.position
    atomic:
      total = total + votes[(pid + 1) % numBots]
      seen.add(pid)
    flags[pid][1] = points.size() > 0 && !points.contains(pos(1, 2))
    grid[2] = -step * 2 / 1

halt:
  pre: done || numAgents == 1
  eff: stop

invariant:
  bounded: forall i: step[i] <= 3
  total >= 0 -> exists j: votes[j] == j
"""

def _pccl_twin_of_koord_all() -> str:
    """KOORD_ALL, written in PCCL by hand (midpoint spelt out)."""
    mid = ("ItemPosition((x[0].x + x[getNumAgents() - 1].x) / 2.0, "
           "(x[0].y + x[getNumAgents() - 1].y) / 2.0, "
           "(x[0].z + x[getNumAgents() - 1].z) / 2.0)")
    return f"""\
allwrite:
  int total = 0;
  float speed = 1;
  List<int> seen = [];

allread:
  ItemPosition x;
  int votes;
  bool flags[3];

loc:
  bool done = false; int step = 0;
  List<ItemPosition> points = [ItemPosition(1, 2), ItemPosition(3, 4, 5), ItemPosition(0, 0, 1)];
  int grid[4] = 0;

Init:
  x = getPosition();
  votes = getAgentIndex();

move():
  pre(!done && (step < 3 || speed > 0.5));
  eff:
    if step == 0 && x[getAgentIndex()] != {mid}:
      x = {mid};
      doReach(x[getAgentIndex()], []);
    else if doReach_done:
      step = step + 1;
    else:
      skip;
    skip;
    skip;
    atomic:
      total = total + votes[(getAgentIndex() + 1) % getNumAgents()];
      add(seen, getAgentIndex());
    flags[1] = size(points) > 0 && !contains(points, ItemPosition(1, 2));
    grid[2] = -step * 2 / 1;

halt():
  pre(done || getNumAgents() == 1);
  eff: exit();

invariant:
  bounded: forall i: step[i] <= 3;
  total >= 0 -> exists j: votes[j] == j;
"""


def test_every_construct_is_the_pccl_ast():
    """Koord and its hand-written PCCL twin parse to equal ASTs (spans,
    file names and sources aside), statement ids included."""
    kp = parse_koord(KOORD_ALL, "all.koord")
    pp = parse_program(_pccl_twin_of_koord_all(), "all.pccl")
    assert kp.decls == pp.decls
    assert kp.init == pp.init
    assert kp.events == pp.events
    assert kp.invariants == pp.invariants
    assert kp == pp
    assert kp.n_statements == pp.n_statements
    assert [s.sid for s in ast.walk_stmts(kp.events[0].body)] == \
        [s.sid for s in ast.walk_stmts(pp.events[0].body)]


FOR_KOORD = """\
allread:
  int best[]
local:
  int i = 0
  int m = -1
init:
  best[pid] = pid * 3 % 4
scan:
  pre: m == -1
  eff:
    for i in range(numAgents):
      if best[i] > m:
        m = best[i]
    for i in range(1, 3):
      skip
    stop
invariant:
  forall j: exited[j] -> m[j] == 3
"""

FOR_PCCL = """\
allread:
  int best;
loc:
  int i = 0;
  int m = -1;
Init:
  best = getAgentIndex() * 3 % 4;
scan():
  pre(m == -1);
  eff:
    i = 0;
    while i < getNumAgents():
      if best[i] > m:
        m = best[i];
      i = i + 1;
    i = 1;
    while i < 3:
      skip;
      i = i + 1;
    exit();
invariant:
  forall j: exited[j] -> m[j] == 3;
"""


def test_bounded_for_is_a_while_loop():
    assert parse_koord(FOR_KOORD) == parse_program(FOR_PCCL)


def test_bounded_for_explores_as_its_twin(tmp_path):
    p = tmp_path / "scan.koord"
    p.write_text(FOR_KOORD)
    a = explore(str(p), agents=3, semantics="pccl")
    b = explore(FOR_PCCL, source=True, agents=3)
    assert a.status == b.status == "exhaustive"
    assert (a.stats.states, a.stats.transitions) == (b.stats.states, b.stats.transitions)


def test_allread_arrays_drop_the_robot_dimension():
    p = parse_koord(KOORD_ALL, "all.koord")
    decls = {d.name: d for d in p.decls}
    assert decls["x"].section == "allread" and decls["x"].type == ast.TypeRef("ItemPosition")
    # int[] votes: the one dimension is the robot's; boolean flags[][3]: then an array of 3
    assert decls["votes"].type == ast.TypeRef("int")
    assert decls["flags"].type == ast.TypeRef("bool") and decls["flags"].size == ast.IntLit(3)
    assert decls["points"].type == ast.TypeRef("List", ast.TypeRef("ItemPosition"))


def test_every_node_has_a_span_in_the_koord_file():
    p = parse_koord(KOORD_ALL, "all.koord")
    lines = KOORD_ALL.split("\n")
    nodes = [n for top in (*p.decls, *p.init, *p.events, *p.invariants) for n in ast.walk(top)]
    assert len(nodes) > 150
    for n in nodes:
        assert 1 <= n.span.line <= len(lines), n
        assert n.span.column >= 1, n
    # Motion.target = x[pid] is the doReach statement, at its own line
    reach = next(s for s in ast.walk_stmts(p.events[0].body)
                 if isinstance(s, ast.CallStmt) and s.name == "doReach")
    line = lines[reach.span.line - 1]
    assert line[reach.span.column - 1:].startswith("Motion.target = x[pid]")
    # pid is getAgentIndex() where pid is written
    pid = reach.args[0].index
    assert isinstance(pid, ast.Call) and pid.name == "getAgentIndex"
    assert line[pid.span.column - 1:pid.span.end_column - 1] == "pid"


def test_the_checker_accepts_the_koord_program():
    info = check_program(parse_koord(KOORD_ALL, "all.koord"))
    assert info is not None


ADD_PCCL = """\
allwrite:
  int sum = 0;
  int numAdded = 0;

loc:
  bool added = false;
  int finalSum = -1;

add():
  pre(!added);
  eff:
    atomic:
      sum = sum + getAgentIndex();
      numAdded = numAdded + 1;
    added = true;

total():
  pre(added && numAdded == getNumAgents());
  eff:
    finalSum = sum;
    skip;
    exit();

invariant:
  agree: forall i: forall j: exited[i] && exited[j] -> finalSum[i] == finalSum[j];
  full: forall i: exited[i] -> finalSum[i] == N * (N - 1) / 2;
"""


def test_add_numbers_is_its_pccl_twin():
    assert load_program(k("add_numbers.koord")) == parse_program(ADD_PCCL)


@pytest.mark.parametrize("agents", [2, 3])
def test_add_numbers_explores_as_its_pccl_twin(agents):
    """The same search, figure by figure: Koord file and PCCL text."""
    a = explore(k("add_numbers.koord"), agents=agents, semantics="pccl")
    b = explore(ADD_PCCL, source=True, agents=agents)
    assert a.status == b.status == "exhaustive" and a.exit_status == 0
    assert (a.stats.states, a.stats.transitions, a.stats.initial_states, a.stats.max_depth) == \
        (b.stats.states, b.stats.transitions, b.stats.initial_states, b.stats.max_depth)


# --------------------------------------------------------------------------
# The shipped programs: verdicts
# --------------------------------------------------------------------------

def test_the_suffixes():
    assert is_koord_path("a.koord") and is_koord_path(Path("b/c.KRD"))
    assert not is_koord_path("a.pccl") and not is_koord_path("koord")


@pytest.mark.parametrize("path", SHIPPED, ids=[p.name for p in SHIPPED])
def test_shipped_programs_check(path):
    # a program that calls its world's functions is checked with its world
    # (a .toml of its name, or of its name without its last '_' parts)
    parts = path.stem.split("_")
    worlds = [path.with_name("_".join(parts[:n]) + ".toml") for n in range(len(parts), 0, -1)]
    uses_world = "()" in path.read_text() and any(w.exists() for w in worlds)
    world = next((["--world", str(w)] for w in worlds if w.exists()), []) if uses_world else []
    res = CliRunner().invoke(main, ["check", str(path), *world])
    assert res.exit_code == 0, res.output
    assert res.output.startswith(f"{path}: ok (")


@pytest.mark.parametrize("agents", [2, 3, 4])
def test_add_numbers_sums_agree(agents):
    r = explore(k("add_numbers.koord"), agents=agents)
    assert r.status == "exhaustive" and r.exit_status == 0
    out = run(k("add_numbers.koord"), agents=agents)
    assert out.status == "final"


@pytest.mark.parametrize("agents", [2, 3])
def test_add_numbers_racy_is_caught(agents):
    r = explore(k("add_numbers_racy.koord"), agents=agents, semantics="pccl")
    assert r.status == "violation" and r.exit_status == 1
    assert r.violation.name == "full"
    # the lost update: both robots read the sum before either writes it
    reads = [s for s in r.trace if s.source == "seenSum = sum"]
    writes = [s for s in r.trace if s.source == "sum = seenSum + pid"]
    assert {s.agent for s in reads} == {0, 1} or agents > 2
    assert reads[1].step < writes[0].step


def test_leader_elects_the_largest_id():
    for agents in (2, 3):
        r = explore(k("leader.koord"), agents=agents)
        assert r.status == "exhaustive" and r.exit_status == 0
    out = run(k("leader.koord"), agents=3, seed=4)
    assert out.status == "final"


def test_leader_without_atomic_is_caught(tmp_path):
    src = (KOORD / "leader.koord").read_text()
    racy = src.replace("    atomic:\n      if candidate < pid:\n        candidate = pid\n"
                       "      numVoted = numVoted + 1\n",
                       "    seen = numVoted\n    if candidate < pid:\n      candidate = pid\n"
                       "    numVoted = seen + 1\n").replace("  int leader = -1\n",
                                                         "  int leader = -1\n  int seen = 0\n")
    assert racy != src
    p = tmp_path / "leader_racy.koord"
    p.write_text(racy)
    r = explore(str(p), agents=2)
    assert r.exit_status == 1


def test_fischer_is_safe_and_fast():
    for agents in (2, 3):
        r = explore(k("fischer.koord"), agents=agents)
        assert r.status == "exhaustive" and r.exit_status == 0
        assert r.stats.seconds < 5


def test_fischer_unsafe_counterexample_is_shortest():
    r = explore(k("fischer.koord"), overrides={"k": "2"}, semantics="pccl")
    assert r.status == "violation" and r.violation.name == "mutex"
    plain = explore(k("fischer.koord"), overrides={"k": "2"}, reduce="none", semantics="pccl")
    assert plain.status == "violation"
    # the unreduced search is plain BFS: its counterexample is the shortest path
    assert len(plain.trace) <= len(r.trace)


def test_lineform_converges():
    r = explore(k("lineform.koord"), world=LINEFORM_WORLD, properties=[ALL_EXIT])
    assert r.exit_status == 0 and r.status in ("exhaustive", "bounded")
    s = explore(k("lineform.koord"), world=LINEFORM_WORLD, blackbox="straight",
                properties=[ALL_EXIT])
    assert s.status == "exhaustive" and s.exit_status == 0
    # within a bound: under straight every robot has stopped by time 5, not by time 3
    ok = explore(k("lineform.koord"), world=LINEFORM_WORLD, blackbox="straight", max_time=6,
                 invariants=["time >= 5 -> (forall i: exited[i])"])
    assert ok.exit_status == 0
    late = explore(k("lineform.koord"), world=LINEFORM_WORLD, blackbox="straight", max_time=6,
                   invariants=["time >= 3 -> (forall i: exited[i])"])
    assert late.status == "violation"
    out = run(k("lineform.koord"), world=LINEFORM_WORLD)
    assert out.status == "final"
    (x1, y1, _z) = out.final[AGS][1][POS]       # agent 1's position
    assert abs(x1 - 2.0) < 0.05 and abs(y1) < 0.05


def test_lineform_without_the_stop_is_a_stall(tmp_path):
    src = (KOORD / "lineform.koord").read_text()
    p = tmp_path / "lineform_nostop.koord"
    p.write_text(src.replace("  eff:\n    stop\n", "  eff:\n    skip\n"))
    r = explore(str(p), world=LINEFORM_WORLD, blackbox="straight")
    assert r.exit_status == 1


@pytest.mark.parametrize("name", ["allstop.koord", "follow.koord", "follow_points.koord"])
def test_moving_programs_finish(name):
    r = explore(k(name), world=LANES, agents=2, properties=[ALL_EXIT])
    assert r.exit_status == 0 and not r.violations
    out = run(k(name), world=LANES, agents=2)
    assert out.status == "final"


def test_follow_points_visits_every_point():
    out = run(k("follow_points.koord"), world=LANES, agents=2, record_trace=True,
              semantics="pccl")
    assert out.status == "final"
    updates = [s for s in out.trace.steps if s.label[0] == "DOREACH UPDATE"]
    assert sorted(s.label[1] for s in updates) == [0, 0, 0, 1, 1, 1]   # 3 points each
    for i, agent in enumerate(out.final[AGS]):
        points, nxt, moving = agent[LOC]
        assert nxt == 3 and not moving
        x, y, _z = agent[POS]
        assert abs(x - 3.0) < 0.05 and abs(y - 2.0 * i) < 0.05


def test_allstop_waits_for_the_flag(tmp_path):
    """A robot that stops without the flag breaks the invariant."""
    src = (KOORD / "allstop.koord").read_text()
    p = tmp_path / "allstop_early.koord"
    p.write_text(src.replace("  pre: halt\n", "  pre: halt or legs == 3\n"))
    r = explore(str(p), world=LANES, agents=2)
    assert r.status == "violation" and r.violation.name == "stopsOnlyAfterHalt"


def test_koord_counterexample_replays_and_views(tmp_path):
    """Traces of a Koord program name the Koord file: replay re-reads it
    (through the same dispatch), the viewer shows its lines."""
    trace, page = tmp_path / "f.json", tmp_path / "f.html"
    res = CliRunner().invoke(main, ["explore", k("fischer.koord"), "--set", "k=3",
                                    "--trace-out", str(trace)])
    assert res.exit_code == 1 and "invariant 'mutex' violated" in res.output
    rep = CliRunner().invoke(main, ["replay", str(trace)])
    assert rep.exit_code == 1 and "reproduced: invariant 'mutex' violated" in rep.output
    view = CliRunner().invoke(main, ["view", str(trace), "-o", str(page)])
    assert view.exit_code == 0
    assert "turn = pid" in page.read_text()


def test_fmt_formats_koord_files():
    """``pccl fmt`` reads a Koord file through the Koord front end (the
    layout's own tests: tests/tools/test_fmt_koord.py)."""
    res = CliRunner().invoke(main, ["fmt", "--check", k("leader.koord")])
    assert res.exit_code == 0, res.output


# --------------------------------------------------------------------------
# Bad input: one message, file:line:column and a caret, exit 2
# --------------------------------------------------------------------------

BAD = [
    ("local:\n  int x = 0\n\nev():\n  pre: true\n  eff:\n    x = 1\n",
     4, 3, "a Koord event is written 'name:' without '()'"),
    ("local:\n  int x = 0\n\nev:\n  eff:\n    x = 1\n", 5, 3, "expected 'pre'"),
    ("allread:\n  int x[]\n\nev:\n  pre: true\n  eff:\n    x[0] = 1\n", 7, 7,
     "'x' is allread: a robot writes only its own entry, 'x[pid] = ...'"),
    ("allread:\n  int x\n", 2, 7, "an allread variable is an array indexed by robot"),
    ("ev:\n  pre: true\n  eff:\n    Motion.target = pos(1, 2)\n", 4, 5,
     "module 'Motion' is not declared"),
    ("using Motion:\n  actuators:\n    pos target\n\nev:\n  pre: Motion.position == pos(1,2)\n"
     "  eff:\n    stop\n", 6, 8, "'Motion.position' is not declared in 'using Motion:'"),
    ("using Motion:\n  sensors:\n    pos target\n", 3, 9, "Motion.target is one of the actuators"),
    ("using Motion:\n  sensors:\n    pos position\n\nev:\n  pre: true\n  eff:\n"
     "    Motion.position = pos(1, 1)\n", 8, 5, "Motion.position is one of the sensors"),
    ("using Motion:\n  actuators:\n    pos target\n\nev:\n  pre: Motion.target == pos(1, 1)\n"
     "  eff:\n    stop\n", 6, 8, "Motion.target is one of the actuators: it is assigned, not read"),
    ("using Camera:\n  sensors:\n    pos x\n", 1, 7, "unknown module 'Camera'"),
    ("def Task:\n  int id\n\nlocal:\n  Task t = 3\n", 5, 12,
     "a Task variable's initial value is a record literal 'Task(...)'"),
    ("def fun f(int a):\n  return a\n\ndef fun f(int b):\n  return b\n", 4, 9,
     "function 'f' is defined twice (first at line 1)"),
    ("def fun f(int a, int a):\n  return a\n", 1, 22, "parameter 'a' of 'f' is named twice"),
    ("def fun f(int a):\n  return a\n  x = 1\n", 2, 3,
     "'return' ends a function: it is its last statement"),
    ("def fun f(int a):\n  return g(a)\n\ndef fun g(int b):\n  return f(b)\n\n"
     "local:\n  int x = 0\nev:\n  pre: f(x) > 0\n  eff:\n    stop\n", 5, 10,
     "function 'f' calls itself (through f -> g -> f)"),
    ("def fun f(int a):\n  return a\n\nlocal:\n  int x = 0\nev:\n  pre: f(x, 1) > 0\n"
     "  eff:\n    stop\n", 7, 8, "'f' takes 1 argument, not 2"),
    ("def fun f(int a):\n  a = 1\n\nlocal:\n  int x = 0\nev:\n  pre: true\n  eff:\n"
     "    f(x)\n", 1, 15, "'f' assigns its parameter 'a'"),
    ("def fun f(int a):\n  x = a\n  y = a\n\nlocal:\n  int x = 0\n  int y = 0\nev:\n"
     "  pre: true\n  eff:\n    f(x + 1)\n", 11, 7, "this argument reads 'x', which 'f' assigns"),
    ("def fun f(int a):\n  x = a\n\nlocal:\n  int x = 0\nev:\n  pre: true\n  eff:\n"
     "    f(rand(2))\n", 9, 7, "an argument that calls rand() is not supported"),
    ("def fun f(int a):\n  x = a\n\nlocal:\n  int x = 0\nev:\n  pre: f(1) > 0\n  eff:\n"
     "    stop\n", 7, 8, "'f' is used in an expression: its body must be a single 'return e'"),
    ("local:\n  int x = 0\nev:\n  pre: true\n  eff:\n    return x\n", 6, 5,
     "'return' outside a function"),
    ("def fun go(boolean r):\n  Motion.target = pos(1, 1)\n  ok = r\n\nusing Motion:\n"
     "  actuators:\n    pos target\n  sensors:\n    boolean reached\n\nlocal:\n"
     "  boolean ok = false\nev:\n  pre: true\n  eff:\n    go(Motion.reached)\n", 16, 8,
     "this argument reads 'Motion.reached', which 'go' changes (assigning Motion.target"),
    ("local:\n  int i = 0\nev:\n  pre: true\n  eff:\n    for i = 0, 3:\n      i = i + 1\n",
     6, 5, "'for i = a, b:' is not supported: its published grammar and documents do not say"),
    ("local:\n  int i = 0\nev:\n  pre: true\n  eff:\n    for k in [1, 2]:\n      skip\n",
     6, 9, "'k' is not declared: declare the loop variable in 'local:'"),
    ("allwrite:\n  int i = 0\nev:\n  pre: true\n  eff:\n    for i in [1, 2]:\n      skip\n",
     6, 9, "the variable of 'for x in xs:' is a local variable"),
    ("local:\n  int i = 0\nev:\n  pre: true\n  eff:\n    for i in range(1, 2, 3):\n      skip\n",
     6, 14, "range takes 1 or 2 bounds, not 3"),
    ("local:\n  int i = 0\n  int[] xs = []\nev:\n  pre: true\n  eff:\n    for i in xs:\n"
     "      for i in xs:\n        skip\n", 8, 11, "a loop over 'i' inside a loop over 'i'"),
    ("local:\n  int i = 0\n  int[] for_i = []\nev:\n  pre: true\n  eff:\n    for i in [1]:\n"
     "      skip\n", 3, 9, "'for_i' is the name pccl gives the list"),
    ("local:\n  int[] xs = []\nev:\n  pre: any(xs)\n  eff:\n    stop\n", 4, 12,
     "any takes a list of booleans (boolean[]), not int[]"),
    ("local:\n  boolean b = true\nev:\n  pre: all(b)\n  eff:\n    stop\n", 4, 12,
     "all takes a list of booleans (boolean[]), not boolean"),
    ("local:\n  boolean[] b = []\nev:\n  pre: all(b, b)\n  eff:\n    stop\n", 4, 8,
     "all takes one list of booleans, not 2 arguments"),
    ("local:\n  int x = 0\nev:\n  pre: true\n  eff:\n    for k in range(3):\n      x = k\n",
     6, 9, "undeclared variable 'k'"),
    ("local:\n  stream s\n", 2, 3, "type 'stream' is not supported yet"),
    ("local:\n  Task t\n", 2, 3, "unknown type 'Task'"),
    ("local:\n  int x = 0\nev:\n  pre: x = 1\n  eff:\n    stop\n", 4, 10, "did you mean '=='?"),
    ("local:\n  int x = 0\nev:\n  pre: true\n  eff:\n    x << 1\n", 6, 5,
     "'<<' writes a log line"),
    ("local:\n  int x = 0\nev:\n  pre: true\n  eff:\n    x = y\n", 6, 9,
     "undeclared variable 'y'"),
    ("init:\n  stop\nlocal:\n  int x\n", 3, 1, "sections come in the order"),
    ("local:\n  int x = 0\nev:\n  pre: 1 < x < 2\n  eff:\n    stop\n", 4, 14,
     "comparisons cannot be chained"),
    ("local:\n  int x = 0\n  int x = 1\n", 3, 7, "'x'"),
    ("local:\n  int x = 0\nlocal:\n  int y = 0\n", 3, 1, "a second 'local:' section"),
    ("local:\n  int x = 0\nev:\n  pre: true\n  eff:\n    x = x +\n", 6, 12,
     "unexpected end of line: expected an expression"),
    ("local:\n  int x = 0\nev:\n  pre: true\n  eff:\n    x = 1\n   x = 2\n", 7, 4,
     "inconsistent indentation"),
    ("local:\n  int x = 0\nev:\n  pre: forall i: true\n  eff:\n    stop\n", 4, 8,
     "unexpected 'forall': expected an expression (quantifiers are for the invariant: section)"),
    ("local:\n  int x = 0\nev:\n  pre: true\n  eff:\n    x = (forall i: true)\n", 6, 10,
     "'forall' is only allowed in properties and invariants"),
    ("local:\n  list xs = []\n", 2, 3, "'list' needs an element type"),
    ("local:\n  int x = 0\nev:\n  pre: true\n  eff:\n    x.push(1)\n", 6, 7,
     "'push' is not a statement method"),
    ("local:\n  pos p = pos(1)\n", 2, 11, "pos takes 2 or 3 coordinates"),
    ("local:\n  int x = 0 @\n", 2, 13, "unexpected character '@'"),
]


@pytest.mark.parametrize("source, line, column, message", BAD,
                         ids=[f"bad{i}" for i in range(len(BAD))])
def test_bad_input_one_message_with_caret(tmp_path, source, line, column, message):
    p = tmp_path / "bad.koord"
    p.write_text(source)
    with pytest.raises(PcclError) as e:
        load_program(str(p)) if "undeclared" not in message and "'x'" != message \
            else check_program(load_program(str(p)))
    err = e.value
    assert message in err.message
    assert (err.line, err.column) == (line, column), err.render()
    res = CliRunner().invoke(main, ["check", str(p)])
    assert res.exit_code == 2
    assert res.stdout == ""
    assert res.stderr.count(": error: ") == 1
    assert res.stderr.startswith(f"{p}:{line}:{column}: error: ")
    caret = res.stderr.rstrip("\n").split("\n")[-1]
    assert caret.strip().startswith("|") and "^" in caret
    assert "Traceback" not in res.output


def test_unreadable_and_non_utf8_files(tmp_path):
    p = tmp_path / "x.koord"
    p.write_bytes(b"local:\n  int x = 0 \xff\n")
    res = CliRunner().invoke(main, ["check", str(p)])
    assert res.exit_code == 2 and "not valid UTF-8" in res.stderr
    res = CliRunner().invoke(main, ["check", str(tmp_path / "missing.koord")])
    assert res.exit_code == 2 and "Traceback" not in res.output


# --------------------------------------------------------------------------
# Fuzz: truncations and mutations of the shipped Koord programs
# --------------------------------------------------------------------------

SEED = 20261207
JUNK = ["@", "((", ")", ":", ";", "=", "==", "[", "]", '"', "/*", "#", "\t", "atomic:",
        "eff:", "pre:", "pid", "numAgents", "stop", "Motion.", "Motion.target =", "<<", "0",
        "-1", "99999999999999999999", "1.5e308", "true", "pos(", "x[pid] =", "using Motion:",
        "allread:", "local:", "init:", "def", "for", "for i in range(2):", "and", "not", "é", "\\", "{", "}", "[]"]


def _mutate(text, rng):
    from sources import mutate
    return mutate(text, rng, JUNK)


def _fuzz_cases(n_mut=12):
    from sources import mutant_cases
    names = ("add_numbers.koord", "lineform.koord", "follow_points.koord", "fischer.koord")
    return mutant_cases({name: (KOORD / name).read_text() for name in names}, n_mut,
                        random.Random(SEED), JUNK, n_trunc=6)


def _invoke(args):
    from conftest import cli_robust
    return cli_robust(*args)


@pytest.mark.slow
@pytest.mark.parametrize("name, text", _fuzz_cases())
def test_mutated_koord_program(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    world = ["--world", LINEFORM_WORLD] if name.startswith("lineform") else \
        ["--world", LANES] if name.startswith("follow") else []
    c = _invoke(["check", p])
    r = _invoke(["run", p, *world, "--max-time", "3", "--max-steps", "2000", "--blackbox",
                 "instant"])
    e = _invoke(["explore", p, *world, "--depth", "25", "--max-states", "1000"])
    if c.exit_code == 2:
        assert r.exit_code == 2 and e.exit_code == 2
        assert r.stderr == c.stderr == e.stderr
    else:
        assert c.exit_code == 0


def test_fuzz_corpus_is_varied():
    """Mutants of a Koord program both load and fail to load, and every
    failure is a PcclError (never another exception)."""
    rng = random.Random(SEED)
    text = (KOORD / "add_numbers.koord").read_text()
    ok = 0
    for _ in range(60):
        _, t = _mutate(text, rng)
        try:
            check_program(parse_koord(t, "m.koord"))
            ok += 1
        except PcclError:
            pass
    assert 0 < ok < 60


def test_a_long_operator_chain_is_read_as_pccl_reads_it():
    """3,000 operators: PCCL reads them (iteratively); so does the Koord
    front end (its port rewriting does not recurse where there is no port)."""
    chain = " + ".join(["1"] * 3000)
    src = f"local:\n  int x = 0\nev:\n  pre: true\n  eff:\n    x = {chain}\n"
    p = parse_koord(src)
    twin = parse_program(f"loc:\n  int x = 0;\nev():\n  pre(true);\n  eff:\n    x = {chain};\n")
    # (== on 3,000 nested dataclasses would itself recurse too deeply: compare walks)
    def shape(stmt):
        return [(type(n).__name__, n.value if isinstance(n, ast.IntLit) else None,
                 getattr(n, "op", None)) for n in ast.walk(stmt)]
    nodes = shape(p.events[0].body[0])
    assert len(nodes) == 2 + 2999 + 3000
    assert nodes == shape(twin.events[0].body[0])


def test_engines_workers_and_reductions_agree_on_koord():
    """A Koord program is an ordinary program to the back end: the native
    and Python engines, one worker or two, give the same search; without
    reductions the verdict is the same."""
    base = explore(k("fischer.koord"), agents=3)
    py = explore(k("fischer.koord"), agents=3, engine="python")
    two = explore(k("fischer.koord"), agents=3, workers=2)
    for r in (py, two):
        assert r.status == base.status == "exhaustive"
        assert (r.stats.states, r.stats.transitions) == (base.stats.states, base.stats.transitions)
    plain = explore(k("fischer.koord"), agents=2, reduce="none")
    assert plain.status == "exhaustive"


def test_the_api_takes_a_parsed_koord_program():
    """Program text is read as PCCL by ``source=True``; Koord text goes
    through parse_koord (docs/koord.md)."""
    src = (KOORD / "leader.koord").read_text()
    r = explore(parse_koord(src, "leader.koord"), agents=3)
    assert r.status == "exhaustive"
    assert (r.stats.states, r.stats.transitions) == \
        (lambda f: (f.stats.states, f.stats.transitions))(explore(k("leader.koord"), agents=3))


def test_pccl_check_reads_koord_files_through_the_one_dispatch():
    # `pccl check` reads through the front end alone (start-up), by the same
    # dispatch as the other commands (pccl.lang.files.parse_program_file)
    from click.testing import CliRunner
    from pccl.cli import main
    res = CliRunner().invoke(main, ["check", "programs/koord/leader.koord"])
    assert res.exit_code == 0 and res.output.startswith("programs/koord/leader.koord: ok ("), res.output


# --------------------------------------------------------------------------
# Functions: `def fun`, inlined where called (pccl/lang/koordfun.py)
# --------------------------------------------------------------------------

FUN_KOORD = """\
def fun twice(int v):
  return v * 2

def fun moveBy(pos p, int k):
  Motion.target = pos(p.x + twice(k), p.y)
  legs = legs + 1
  return legs

using Motion:
  actuators:
    pos target
  sensors:
    pos position
    boolean reached

local:
  int legs = 0

go:
  pre: legs < twice(1) and (legs == 0 or Motion.reached)
  eff:
    if pid == 0:
      moveBy(Motion.position, pid + 1)
    else:
      moveBy(pos(1, 2), 3 - pid)
"""

FUN_INLINED = """\
using Motion:
  actuators:
    pos target
  sensors:
    pos position
    boolean reached

local:
  int legs = 0

go:
  pre: legs < 1 * 2 and (legs == 0 or Motion.reached)
  eff:
    if pid == 0:
      Motion.target = pos(Motion.position.x + (pid + 1) * 2, Motion.position.y)
      legs = legs + 1
    else:
      Motion.target = pos(pos(1, 2).x + (3 - pid) * 2, pos(1, 2).y)
      legs = legs + 1
"""


def test_functions_are_inlined():
    """Each call is the body with the arguments in place (their trees: `(pid
    + 1) * 2`), a call in an expression its `return e`, a statement call
    its statements without the last `return`."""
    assert parse_koord(FUN_KOORD) == parse_koord(FUN_INLINED)
    prog = parse_koord(FUN_KOORD, "fun.koord")
    # the inlined statements keep the function's lines: traces show them
    assert [s.span.line for s in prog.events[0].body[0].branches[0][1]] == [5, 6]


def test_a_function_explores_as_its_inlined_twin(tmp_path):
    a, b = tmp_path / "fun.koord", tmp_path / "inl.koord"
    a.write_text(FUN_KOORD)
    b.write_text(FUN_INLINED)
    ra = explore(str(a), agents=2, world=LANES)
    rb = explore(str(b), agents=2, world=LANES)
    assert (ra.status, ra.stats.states, ra.stats.transitions) == \
        (rb.status, rb.stats.states, rb.stats.transitions)
