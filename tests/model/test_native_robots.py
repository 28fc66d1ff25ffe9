"""The shipped blackboxes in C (pccl/model/native_c/robots.c, issue 43
item 2): DOREACH INVOKE's outcomes under instant, straight, nondet and
nondet-fail made in C at a memo miss, on the level kernel's threads.

Python is the reference: the native search with the outcomes made in C
equals the native search that asks Python (``PCCL_C_BLACKBOX=0``) and the
Python engine (states, transitions, depth, verdicts, counterexamples with
their positions), on the shipped programs, a distance exactly at nondet's
bound (left to Python), generated programs in open worlds, and with two
threads.  Each comparison also checks that C made outcomes (or, where it
must not, that it left them to Python), so none of them passes vacuously."""

from __future__ import annotations

import math
import os
import random

import pytest

from pccl.api import explore
from pccl.model import native as NV
from pccl.model import native_robots as NR
from pccl.model.environment import Environment
from pccl.lang.world import parse_world

from conftest import ROOT
from test_native import MISSING, summary

#: every test here compiles a native module and runs the Python engine: slow
pytestmark = [pytest.mark.skipif(MISSING is not None, reason=f"native engine unavailable: {MISSING}"),
              pytest.mark.slow]


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("PCCL_CACHE", str(tmp_path_factory.getbasetemp() / "native-cache"))


@pytest.fixture
def natives(monkeypatch):
    """The native models the searches of a test make (to read their
    robots_stats: outcomes made in C, misses C left to Python)."""
    made: list = []
    init = NV.NativeModel.__init__

    def spy(self, *a, **k):
        init(self, *a, **k)
        made.append(self)
    monkeypatch.setattr(NV.NativeModel, "__init__", spy)
    return made


def P(path: str) -> str:
    return os.path.join(ROOT, path)


def three(monkeypatch, natives, program, **kw):
    """(Python engine, native asking Python, native with C) summaries and
    the C side's (made in C, left to Python) counts."""
    py = summary(explore(program, engine="python", **kw))
    monkeypatch.setenv(NR.ENV_VAR, "0")
    natives.clear()
    off = summary(explore(program, engine="native", **kw))
    assert all(not n.robots_in_c for n in natives)
    monkeypatch.delenv(NR.ENV_VAR)
    natives.clear()
    on = summary(explore(program, engine="native", **kw))
    stats = [n.lib.robots_stats() for n in natives]
    made = sum(m for m, _ in stats)
    left = sum(n for _, n in stats)
    return py, off, on, made, left


#: (program, world, agents, states cap): worlds without obstacles, where C
#: makes the outcomes
OPEN = [
    ("programs/race_robust.pccl", "programs/race.toml", 3, 4_000),
    ("programs/race.pccl", "programs/race.toml", 2, None),
    ("programs/race_nonatomic.pccl", "programs/race.toml", 2, None),
    ("tests/programs/rdv_meet.pccl", "tests/programs/rdv_open.toml", 2, None),
    ("tests/programs/ref_doreach.pccl", None, 2, None),
    ("tests/programs/eng_move1.pccl", None, 2, None),
]


@pytest.mark.parametrize("blackbox", ["nondet", "nondet-fail", "instant", "straight"])
@pytest.mark.parametrize("program, world, agents, cap", OPEN)
def test_outcomes_made_in_c_equal_python(monkeypatch, natives, program, world, agents, cap,
                                         blackbox):
    kw = dict(agents=agents, blackbox=blackbox, find_all=True)
    if world is not None:
        kw["world"] = P(world)
    if cap is not None:
        kw["max_states"] = cap
    py, off, on, made, left = three(monkeypatch, natives, P(program), **kw)
    assert on == off == py
    assert made > 0 and left == 0


@pytest.mark.parametrize("program, world", [
    ("programs/race_robust.pccl", "programs/race_obstacles.toml"),
    ("programs/collide.pccl", "programs/collide.toml"),
    ("tests/programs/rdv_meet.pccl", "tests/programs/rdv_wall.toml"),
])
def test_obstacles_are_left_to_python(monkeypatch, natives, program, world):
    """Obstacles (shapely's geometry) stay in Python: C makes nothing."""
    py, off, on, made, left = three(monkeypatch, natives, P(program), world=P(world),
                                    blackbox="nondet", max_states=3_000)
    assert on == off == py
    assert made == 0 and all(not n.robots_in_c for n in natives)


BOUND_PROGRAM = """\
// Robot 1 drives along the x axis; robot 0 stands 0.6 off its path,
// exactly nondet's body bound 2 * (radius + tolerance) = 2 * (0.25 + 0.05).
loc:
  bool sent = false;

Go():
  pre(getAgentIndex() == 1 && !sent);
  eff:
    doReach(ItemPosition(4, 0), []);
    sent = true;
"""

BOUND_WORLD = """\
agents = 2
resolution = 0.01
radius = 0.25
tolerance = 0.05
speed = 1.0
start = [[2, 0.6], [0, 0]]
"""


def test_a_distance_at_the_bound_is_left_to_python(monkeypatch, natives, tmp_path):
    """Where the distance between two regions is within a few units in the
    last place of nondet's bound, math.hypot and C's hypot could decide
    the comparison differently: C leaves that miss to Python."""
    prog, world = tmp_path / "bound.pccl", tmp_path / "bound.toml"
    prog.write_text(BOUND_PROGRAM)
    world.write_text(BOUND_WORLD)
    assert math.hypot(0.0, 0.6) == 2 * (0.25 + 0.05)
    py, off, on, made, left = three(monkeypatch, natives, str(prog), world=str(world),
                                    blackbox="nondet", find_all=True)
    assert on == off == py
    assert left > 0 and made > 0


def test_two_threads_with_outcomes_made_in_c(monkeypatch, natives):
    """race_robust, 3 robots, under nondet on two threads of the level
    kernel (every level shared): the one-worker search's states,
    transitions and verdict, with the outcomes made in C."""
    from pccl.search import explorer as EX
    monkeypatch.setattr(EX, "SHARED_LEVEL", 1)
    kw = dict(world=P("programs/race.toml"), agents=3, blackbox="nondet")
    one = explore(P("programs/race_robust.pccl"), workers=1, **kw)
    natives.clear()
    two = explore(P("programs/race_robust.pccl"), workers=2, **kw)
    assert two.model.engine_threads == 2
    assert [n.robots_in_c for n in natives] == [True]
    assert natives[0].lib.robots_stats()[0] > 0
    assert two.status == one.status and not one.counterexamples and not two.counterexamples
    assert (two.stats.states, two.stats.transitions, two.stats.max_depth) == \
        (one.stats.states, one.stats.transitions, one.stats.max_depth) == (88_168, 138_720, 65)


def _open_cases(n: int) -> list:
    """Generated programs of the oracle's moving family whose world has no
    obstacle (tests/differential/gen.py) and that the native engine serves
    (no rand() in a statement, no indexed property)."""
    import tempfile
    from pccl.api import make_model
    from tests.differential import gen
    out = []
    seed = 930_000
    with tempfile.TemporaryDirectory() as d:
        while len(out) < n:
            c = gen.case(seed, families=("moving",))
            seed += 1
            if "[[obstacles]]" in c.world:
                continue
            prog, world = os.path.join(d, "gen.pccl"), os.path.join(d, "gen.toml")
            with open(prog, "w") as f:
                f.write(c.text)
            with open(world, "w") as f:
                f.write(c.world)
            m = make_model(prog, world=world, invariants=tuple(c.invariants))
            if NV.unsupported(m) is None:
                out.append(c)
    return out


@pytest.mark.parametrize("case", _open_cases(6), ids=lambda c: str(c.seed))
@pytest.mark.parametrize("blackbox", ["nondet", "straight"])
def test_generated_programs_in_open_worlds(monkeypatch, natives, tmp_path, case, blackbox):
    prog, world = tmp_path / "gen.pccl", tmp_path / "gen.toml"
    prog.write_text(case.text)
    world.write_text(case.world)
    py, off, on, made, left = three(monkeypatch, natives, str(prog), world=str(world),
                                    blackbox=blackbox, invariants=tuple(case.invariants),
                                    find_all=True, max_states=3_000)
    assert on == off == py
    assert made > 0


def test_rounding_is_round_pos(natives):
    """robots.c rounds a coordinate as Environment.round_pos does, bit for
    bit: random values at many scales, values half a resolution step off
    the grid (Python's round: half to even) and ties of round(x, 9)."""
    explore(P("tests/programs/eng_move1.pccl"), agents=2, max_states=10)
    lib = natives[0].lib
    rnd = random.Random(43)
    vals = [2.0 ** -10, -(2.0 ** -10), 0.5, 1.5, 2.5, -0.5, -0.0, 0.0, 1e-12, 123456.789]
    for _ in range(3000):
        e = rnd.choice([1e-3, 1e-1, 1.0, 10.0, 1e3, 1e6])
        vals.append(rnd.uniform(-e, e))
    for res in (0.01, 0.05, 0.25, 0.5, 0.001, 0.3, 1.0, 0.1):
        env = Environment(parse_world(f"resolution = {res}\n"), None, 1, 1)
        grid = [(k + 0.5) * res for k in range(-40, 40)]
        for c in vals + grid:
            want = env.round_pos((c, 0.0, 0.0))[0]
            got = lib.robots_round(c, res)
            assert got is not None and math.copysign(1, got) == math.copysign(1, want) \
                and got == want, (c, res, got, want)


def test_a_second_model_of_the_module_leaves_the_first_its_values():
    """Two native models of one source share the compiled module and its C
    table of values: the second's setup empties it, after the first has
    read the values C made for it (its states still decode to the Python
    model's configurations, and it numbers new values itself).  Under
    straight, C makes the positions along the way, which Python has not
    seen."""
    from pccl.api import make_model
    m = make_model(P("programs/race_robust.pccl"), world=P("programs/race.toml"), agents=2,
                   blackbox="straight", reduce="none")
    a = NV.NativeModel(m)
    assert a.robots_in_c
    level = list(zip(a.init_states(), m.init_states()))
    seen, pyseen, known = [], [], set()
    for _ in range(40):             # breadth first, native and Python side by side
        nxt = []
        for s, st in level:
            for (_l, t), (_pl, pt) in zip(a.successors(s), m.successors(st), strict=True):
                if t not in known:
                    known.add(t)
                    nxt.append((t, pt))
        level = nxt
        seen += [t for t, _ in level]
        pyseen += [pt for _, pt in level]
    assert a.lib.robots_stats()[0] > 0
    ids = {i for s in seen for i in a.unpack(s)[a.gen.AG0 + a.gen.MV::a.gen.A]}
    assert any(i not in a._vals for i in ids)          # made in C, not read yet
    b = NV.NativeModel(m)
    assert b.lib is a.lib and a.lib.vcount() == 0
    assert [a.decode(s) for s in seen] == pyseen
    n = len(a._vals)
    assert a.intern(("a new value",)) == n and b.intern(("a new value",)) == 0
