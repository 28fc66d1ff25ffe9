"""The engine's explorer against an independent reference implementation.

``tests/reference.py`` implements the rewrite rules of docs/language.md §11-§12
directly from that text (a tree-walking interpreter sharing only the
parser with the engine).  Here both explore the same programs and must agree
exactly on

* the number of distinct states (initial states included, at depth 0),
* the number of transitions (successor counts of every expanded state,
  including successors that lead to already-seen states),
* the depth reached,
* the length of the shortest counterexample (invariant or stuck agent).

The oracle's own numbers are pinned as well (``expected``), so that a change
on either side shows up; they were obtained from the oracle alone.

The engine runs with ``deadlock=False`` and ``find_all=True`` when counting:
otherwise the first violation (a stuck agent, a deadlock) would stop the
search and the counts would not be those of the whole reachable graph.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from pccl.lang import ast as A
from pccl.api import explore as _explore, make_model
from pccl.search.explorer import Explorer
from pccl.lang.parser import parse_file
from pccl.lang.world import World

from reference import ReferenceModel, bfs, shortest_violation


def explore(*args, **kw):
    """The unreduced search (reduce='none'): this file pins its counts and
    shortest counterexamples; tests/model/test_reduce.py covers the reductions."""
    kw.setdefault("reduce", "none")
    return _explore(*args, **kw)


HERE = Path(__file__).resolve().parents[1]
REF_PROGRAMS = HERE / "programs"
PROGRAMS = HERE.parent / "programs"


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------

def load(name: str) -> A.Program:
    if name.startswith("ref_"):
        return parse_file(str(REF_PROGRAMS / f"{name}.pccl"))
    return parse_file(str(PROGRAMS / f"{name}.pccl"))


def set_inits(prog: A.Program, values: dict) -> A.Program:
    """The oracle's own constant overrides: replace initialisers by integers."""
    decls = []
    for d in prog.decls:
        if isinstance(d, A.VarDecl) and d.name in values:
            d = dataclasses.replace(d, init=A.IntLit(values[d.name]))
        decls.append(d)
    return dataclasses.replace(prog, decls=tuple(decls))


def engine_counts(prog, agents, *, depth=None, **opts):
    model = make_model(prog, agents=agents, reduce="none", **opts)
    st = Explorer(model, exact=True, max_depth=depth, deadlock=False,
                  find_all=True).run().stats
    return st.states, st.transitions, st.max_depth


def oracle_counts(prog, agents, *, depth=None, **opts):
    return bfs(ReferenceModel(prog, agents, **opts), max_depth=depth)


def engine_violation(prog, agents, *, invariants=(), **opts):
    """(kind, length of the shortest counterexample) or None."""
    # the reference interpreter decides safety: stuck agents, assertions,
    # invariants (deadlocks and stalls are checked elsewhere)
    r = explore(prog, agents=agents, invariants=list(invariants), exact=True,
                deadlock=False, stall=False, **opts)
    if not r.violations:
        # complete for the blackbox searched ("bounded" only when the covering
        # nondet says it is not exhaustive for straight/pymunk or for pymunk)
        assert r.status == "exhaustive" or (r.not_covered and not r.bounds), r.verdict
        return None
    v = r.violations[0]
    return v["kind"], len(v.trace)


# Race worlds: two robots, starts as in programs/race.toml, no obstacles.
RACE_STARTS = ((0.0, 0.0, 0.0), (-5.0, 1.0, 0.0))
RACE_DESTS_2 = ((4, 0), (4, 6))
RACE_DESTS_3 = ((4, 0), (4, 6), (5.5, 6))


def race_world(dests) -> World:
    return World(n_agents=2, starts=RACE_STARTS,
                 functions=(("getInput", dests), ("getObs", ())))


RACE_TOML_3 = """
agents = 2
resolution = 0.01
radius = 0.25
start = [[0, 0], [-5, 1]]

[functions]
getInput = [[4, 0], [4, 6], [5.5, 6]]
"""


# --------------------------------------------------------------------------
# (a) small hand-made programs: state and transition counts
# --------------------------------------------------------------------------

# (program, agents, options common to both sides, expected (states, transitions, depth))
SMALL = [
    ("ref_ifchain", 2, {}, (443, 737, 42)),
    ("ref_ifchain", 3, {}, (15148, 37792, 57)),
    ("ref_while", 2, {}, (783, 1386, 26)),
    ("ref_atomic", 2, {}, (867, 1428, 53)),
    ("ref_atomic", 3, {}, (20156, 45784, 68)),
    ("ref_atomic", 2, {"n0": 2}, (2946, 5186, 53)),
    ("ref_nested", 2, {}, (471, 768, 45)),
    ("ref_rand", 2, {}, (3150, 5580, 12)),
    ("ref_list", 2, {}, (326, 528, 50)),
    ("ref_allread", 2, {}, (115, 180, 22)),
    ("ref_allread", 3, {}, (895, 2032, 32)),
    ("ref_events", 2, {}, (676, 1316, 34)),
    ("ref_events", 2, {"events": "first"}, (63, 98, 28)),
    ("ref_events", 2, {"n0": 2, "rates": {1: 2}}, (1228, 2530, 40)),
    ("ref_events", 2, {"max_time": 3, "abstract_time": False}, (1212, 2294, 30)),
    ("ref_doreach", 2, {"blackbox": "instant"}, (119, 190, 48)),
    ("ref_doreach", 2, {"blackbox": "nondet"}, (447, 742, 48)),
    ("ref_doreach", 2, {"blackbox": "nondet", "max_time": 3, "abstract_time": False},
     (273, 428, 34)),
    ("ref_mutex_bad", 2, {}, (111, 176, 16)),
    ("ref_assert", 2, {}, (101, 147, 22)),
    ("ref_init", 3, {}, (5888, 9984, 28)),
    ("ref_init", 3, {"n0": 2, "rates": {1: 2}}, (7744, 13504, 34)),
    ("ref_undef", 2, {}, (35, 58, 10)),
    ("ref_values", 2, {}, (79, 132, 26)),
    ("ref_guard_error", 2, {}, (6, 7, 3)),
]


def _id(case):
    name, agents, opts, _ = case
    extra = ",".join(f"{k}={v}" for k, v in sorted(opts.items()))
    return f"{name}-{agents}" + (f"-{extra}" if extra else "")


@pytest.mark.parametrize("case", SMALL, ids=[_id(c) for c in SMALL])
def test_small_program_counts(case):
    name, agents, opts, expected = case
    prog = load(name)
    opts = dict(opts)
    opts.setdefault("blackbox", "instant")
    opts.setdefault("abstract_time", True)
    ref = oracle_counts(prog, agents, **opts)
    assert ref == expected, "the oracle's own count changed"
    assert engine_counts(prog, agents, **opts) == ref


def test_events_policies_differ():
    """Sanity of the case table: `first` explores a strict subset."""
    prog = load("ref_events")
    anyc = oracle_counts(prog, 2)
    first = oracle_counts(prog, 2, events="first")
    assert first[0] < anyc[0]


def test_depth_bound_counts():
    """--depth: states at the bound are counted, not expanded."""
    prog = load("ref_values")
    opts = dict(blackbox="instant", abstract_time=False)
    ref = oracle_counts(prog, 2, depth=12, **opts)
    assert ref == (38, 62, 12)
    assert engine_counts(prog, 2, depth=12, **opts) == ref


def test_rand_duplicate_outcomes_delta_two():
    """rand outcomes that give equal states still are separate transitions
    (the oracle counts one transition per outcome); delta = 2, --max-time 5."""
    src = """
allwrite:
  int x = 0;
loc:
  int y = rand(2) / 2;
Go():
  pre(x < 2);
  eff:
    x = x + 1 + rand(2) / 3;
"""
    from pccl.lang.parser import parse_program
    prog = parse_program(src, "<dup>")
    opts = dict(blackbox="instant", delta=2, max_time=5, abstract_time=False)
    ref = oracle_counts(prog, 2, **opts)
    assert ref == (144, 272, 18)
    assert engine_counts(prog, 2, **opts) == ref
    opts = dict(blackbox="instant", abstract_time=True)
    ref = oracle_counts(prog, 2, **opts)
    assert ref == (88, 200, 10)
    assert engine_counts(prog, 2, **opts) == ref


# --------------------------------------------------------------------------
# (b) Fischer with small constants
# --------------------------------------------------------------------------

# (oracle constants, depth bound, expected)
FISCHER = [
    ({"k": 1, "d": 1, "cstime": 0}, None, (16402, 27870, 556)),
    ({"k": 1, "d": 1}, 30, (14652, 23904, 30)),
    ({"k": 2, "d": 1, "cstime": 0}, None, (39130, 66374, 614)),
]


def fischer_engine_program(consts: dict):
    """Shared constants go through the engine's `overrides` (TLC-style
    constants); the local `cstime` (never read) is replaced in the AST."""
    prog = load("fischer")
    local = {k: v for k, v in consts.items() if k == "cstime"}
    shared = {k: str(v) for k, v in consts.items() if k != "cstime"}
    return set_inits(prog, local), shared


@pytest.mark.parametrize("consts,depth,expected", FISCHER,
                         ids=["k1-d1-cs0", "k1-d1-depth30", "k2-d1-cs0"])
def test_fischer_counts(consts, depth, expected):
    ref = oracle_counts(set_inits(load("fischer"), consts), 2, depth=depth)
    assert ref == expected
    eprog, overrides = fischer_engine_program(consts)
    assert engine_counts(eprog, 2, depth=depth, blackbox="instant",
                         abstract_time=True, overrides=overrides) == ref


@pytest.mark.parametrize("consts,expected", [
    ({"k": 1, "d": 1, "cstime": 0}, 110),
    ({"k": 2, "d": 1, "cstime": 0}, 83),
], ids=["k1-d1", "k2-d1"])
def test_fischer_shortest_mutex_violation(consts, expected):
    model = ReferenceModel(set_inits(load("fischer"), consts), 2)
    # plain BFS over full states (time included): the real transition system
    # (the depth bound only keeps a changed program from running forever)
    ref = shortest_violation(model, lambda s: model.count(s, "inCs") > 1, max_depth=150)
    assert ref == expected
    eprog, overrides = fischer_engine_program(consts)
    assert engine_violation(eprog, 2, invariants=["count(inCs) <= 1"],
                            blackbox="instant", abstract_time=True,
                            overrides=overrides) == ("invariant", ref)


# --------------------------------------------------------------------------
# (c) Race, with and without the check inside atomic
# --------------------------------------------------------------------------

# Under nondet the robots' paths meet (both race for the same destination),
# so a moving robot may also fail (pymunk's discs block one another): the
# counts grew when nondet began to cover that (docs/blackboxes.md).
RACE = [
    ("race", "instant", RACE_DESTS_2, (722, 1206, 72)),
    ("race", "nondet", RACE_DESTS_2, (2234, 3783, 72)),      # was 1562: fail outcomes
    ("race_nonatomic", "instant", RACE_DESTS_2, (450, 738, 66)),
    ("race_nonatomic", "nondet", RACE_DESTS_2, (2020, 3391, 67)),   # was 1372
    ("race", "nondet", RACE_DESTS_3, (5280, 8991, 94)),      # was 3729
    ("race_nonatomic", "nondet", RACE_DESTS_3, (4647, 7869, 92)),   # was 3144
]


def race_oracle(name, bb, dests):
    return ReferenceModel(load(name), 2, blackbox=bb, starts=RACE_STARTS,
                          functions={"getInput": dests, "getObs": ()})


@pytest.mark.parametrize("name,bb,dests,expected", RACE,
                         ids=[f"{c[0]}-{c[1]}-{len(c[2])}dests" for c in RACE])
def test_race_counts(name, bb, dests, expected):
    ref = bfs(race_oracle(name, bb, dests))
    assert ref == expected
    assert engine_counts(load(name), 2, blackbox=bb, world=race_world(dests),
                         abstract_time=True) == ref


def test_race_counts_toml_world(tmp_path):
    """The same world, read from a TOML file by the engine."""
    path = tmp_path / "race3.toml"
    path.write_text(RACE_TOML_3)
    ref = bfs(race_oracle("race_nonatomic", "instant", RACE_DESTS_3))
    assert engine_counts(load("race_nonatomic"), 2, blackbox="instant",
                         world=str(path), abstract_time=True) == ref


# Shortest "some agent stuck".  Note: race.pccl gets stuck too, under instant
# and nondet: PickDest tests isEmpty(dests) and reads head(dests) in two
# separate transitions, so the other robot can remove the last destination
# in between ("head of an empty list").  Engine and oracle agree on this.
@pytest.mark.parametrize("name,bb,dests,expected", [
    ("race", "instant", RACE_DESTS_2, 51),
    ("race", "nondet", RACE_DESTS_2, 51),
    ("race_nonatomic", "instant", RACE_DESTS_2, 27),
    ("race_nonatomic", "nondet", RACE_DESTS_2, 27),
    ("race_nonatomic", "nondet", RACE_DESTS_3, 27),
])
def test_race_shortest_stuck(name, bb, dests, expected):
    model = race_oracle(name, bb, dests)
    # full states; the bound only keeps a changed program from running forever
    ref = shortest_violation(model, model.any_stuck, max_depth=80)
    assert ref == expected
    assert engine_violation(load(name), 2, blackbox=bb, world=race_world(dests),
                            abstract_time=True) == ("stuck", ref)


@pytest.mark.parametrize("bb,dests,expected", [
    ("nondet", RACE_DESTS_2, (4585, 7991, 99)),     # was 3595: fail outcomes
    ("instant", RACE_DESTS_3, (4610, 7814, 124)),
], ids=["nondet-2dests", "instant-3dests"])
def test_race_safe_never_stuck(bb, dests, expected):
    """programs/race_safe.pccl closes both races: same counts, no stuck agent."""
    model = race_oracle("race_safe", bb, dests)
    assert bfs(model) == expected
    # a robot may wait forever (nondet: never arrives), so time is unbounded:
    # search the time-abstracted graph
    assert shortest_violation(model, model.any_stuck, use_key=True) is None
    prog = load("race_safe")
    assert engine_counts(prog, 2, blackbox=bb, world=race_world(dests),
                         abstract_time=True) == expected
    assert engine_violation(prog, 2, blackbox=bb, world=race_world(dests),
                            abstract_time=True) is None


# --------------------------------------------------------------------------
# shortest counterexamples on the small programs
# --------------------------------------------------------------------------

def test_mutex_bad_shortest():
    prog = load("ref_mutex_bad")
    model = ReferenceModel(prog, 2)
    ref = shortest_violation(model, lambda s: model.count(s, "inCs") > 1, max_depth=50)
    # select, select, owner = id, inCs = true, owner = id, inCs = true
    assert ref == 6
    assert engine_violation(prog, 2, invariants=["count(inCs) <= 1"],
                            blackbox="instant", abstract_time=True) == ("invariant", 6)


@pytest.mark.parametrize("agents", [2])  # 3 agents: ~5 s more, same verdict
def test_atomic_mutex_holds(agents):
    prog = load("ref_atomic")
    model = ReferenceModel(prog, agents)
    # time grows without bound: search the time-abstracted graph
    assert shortest_violation(model, lambda s: model.count(s, "inCs") > 1,
                              use_key=True) is None
    assert engine_violation(prog, agents, invariants=["count(inCs) <= 1"],
                            blackbox="instant", abstract_time=True) is None


@pytest.mark.parametrize("name,agents,kind,expected", [
    ("ref_list", 2, "stuck", 8),          # remove of an absent element
    ("ref_list", 3, "stuck", 8),
    ("ref_assert", 2, "stuck", 12),       # division by zero comes first
    ("ref_assert", 1, "assert", 15),      # assert(x != 3) fails
    ("ref_undef", 2, "stuck", 4),         # read of an undefined array element
    ("ref_guard_error", 2, "stuck", 1),
])
def test_shortest_stuck(name, agents, kind, expected):
    prog = load(name)
    model = ReferenceModel(prog, agents)
    ref = shortest_violation(model, model.any_stuck, max_depth=200)
    assert ref == expected
    assert engine_violation(prog, agents, blackbox="instant",
                            abstract_time=True) == (kind, ref)
