"""The dead-variable reduction (pccl/model/dead.py, docs/reductions.md "Dead
variables"): which values it masks, that the masked key is what both
engines identify states by, and that verdicts stay (every shipped and test
program and generated programs are in tests/model/test_reduce.py's combinations,
``dead`` alone and with every other reduction)."""

from __future__ import annotations

import os
import textwrap

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hs

from pccl.api import explore, make_model
from pccl.model.dead import DEAD, DeadVars
from pccl.model.layout import AGS, DONE, FAIL, LOC, OBSTACLES, PC, REACH, RUNNING, STATUS

from conftest import ROOT, reachable
from cases import programs

RACE = os.path.join(ROOT, "programs/race_robust.pccl")
WORLD = os.path.join(ROOT, "programs/race.toml")


def src(text: str) -> str:
    return textwrap.dedent(text).lstrip("\n")


# x is written before it is read in every event; y is read by Use only,
# which needs flag; z only by the invariant
SCRATCH = src("""
    allwrite:
      int total = 0;

    loc:
      int x = 0;
      int y = 0;
      int z = 0;
      bool flag = false;

    Set():
      pre(!flag);
      eff:
        x = total + 1;
        y = x;
        z = x;
        flag = true;

    Use():
      pre(flag);
      eff:
        x = y + 1;
        atomic:
          total = x;
        flag = false;
    """)


def dead_names(m, st, i=0) -> set:
    d = DeadVars(m.model)
    mask = d.dead_mask(st, i)
    return {name for name, b in d.bit.items() if mask & b}


def states(m, limit=500) -> list:
    """Reachable states of the unreduced model behind ``m`` (its rules' identity)."""
    return reachable(m.model, limit)


def test_dead_values_at_the_top_depend_on_the_next_events():
    m = make_model(SCRATCH, source=True, agents=2, blackbox="instant", reduce="auto",
                   invariants=("total >= 0",))
    assert "dead" in m.reduction.on
    seen = {}
    for st in states(m):
        ag = st[AGS][0]
        if ag[PC] == m.model.ctl.empty_pc and ag[STATUS] == RUNNING:
            flag = ag[LOC][3]
            seen.setdefault(flag, set()).add(frozenset(dead_names(m, st)))
    # flag false: Set comes next and writes x, y and z before reading them;
    # flag true: Use reads y, writes x first; z is read by nobody
    assert seen[False] == {frozenset({"x", "y", "z"})}
    assert seen[True] == {frozenset({"x", "z"})}


def test_a_variable_a_property_reads_is_never_dead():
    m = make_model(SCRATCH, source=True, agents=2, blackbox="instant", reduce="auto",
                   invariants=("z[0] >= 0",))
    for st in states(m):
        assert "z" not in dead_names(m, st)


def test_states_differing_only_in_dead_values_share_a_key():
    m = make_model(SCRATCH, source=True, agents=2, blackbox="instant", reduce="auto")
    st = next(s for s in states(m) if s[AGS][0][LOC][3] is False
              and s[AGS][0][PC] == m.model.ctl.empty_pc)
    ag = st[AGS][0]
    other = ag[:LOC] + ((ag[LOC][0] + 7,) + ag[LOC][1:],) + ag[LOC + 1:]
    st2 = st[:AGS] + ((other,) + st[AGS][1:],) + st[AGS + 1:]
    assert m.key(st) == m.key(st2)
    assert m.model.plain_key(st) != m.model.plain_key(st2)
    # a live value (flag) is not masked
    flip = ag[:LOC] + (ag[LOC][:3] + (True,),) + ag[LOC + 1:]
    st3 = st[:AGS] + ((flip,) + st[AGS][1:],) + st[AGS + 1:]
    assert m.key(st) != m.key(st3)


def test_the_race_masks_the_destination_and_the_flags_of_a_robot_about_to_pick():
    m = make_model(RACE, world=WORLD, agents=2, blackbox="nondet", reduce="auto")
    d = DeadVars(m.model)
    # path-sensitive: PickDest writes currentDest before its doReach reads it,
    # on the path where finished stays false
    assert d.cond == ["finished"]
    hit = 0
    for st in states(m, 3000):
        for i, ag in enumerate(st[AGS]):
            pick = ag[LOC][1]
            if ag[PC] == m.model.ctl.empty_pc and ag[STATUS] == RUNNING and pick is True:
                names = dead_names(m, st, i)
                assert "currentDest" in names and "finished" not in names
                masked = d.mask(st)[AGS][i]
                assert masked[LOC][3] is DEAD
                r = ag[REACH]
                if r[DONE] or r[FAIL]:
                    hit += 1
                    assert masked[REACH][DONE] is DEAD and masked[REACH][OBSTACLES] == r[OBSTACLES]
                else:
                    assert masked[REACH] == r
    assert hit


@pytest.mark.parametrize("agents", [2, 3])
def test_engines_agree_under_dead_on_the_race(agents):
    kw = dict(world=WORLD, agents=agents)
    py = explore(RACE, engine="python", **kw)
    nat = explore(RACE, engine="native", **kw)
    without = explore(RACE, engine="native", reduce="merge,symmetry,por", **kw)
    assert "dead" in nat.model.reduction.on and nat.model.engine_used == "native"
    for r in (py, nat):
        assert (r.status, r.stats.states, r.stats.transitions, r.stats.max_depth) == \
            (nat.status, nat.stats.states, nat.stats.transitions, nat.stats.max_depth)
    assert without.status == nat.status == "bounded"     # not exhaustive for pymunk
    assert nat.stats.states < without.stats.states


def test_fischer_engines_agree_and_keep_the_violation():
    kw = dict(overrides={"k": "1", "d": "1"}, invariants=("count(inCs) <= 1",), agents=2)
    path = os.path.join(ROOT, "programs/fischer.pccl")
    runs = [explore(path, engine=e, reduce=r, **kw)
            for e in ("python", "native") for r in ("auto", "merge,symmetry,por")]
    assert len({r.status for r in runs}) == 1
    assert {len(r.violations) for r in runs} == {1}
    assert runs[0].stats.states == runs[2].stats.states
    assert runs[1].stats.states == runs[3].stats.states
    assert runs[0].stats.states < runs[1].stats.states
    assert len(runs[0].counterexamples[0].trace) == len(runs[1].counterexamples[0].trace)


def test_a_liveness_property_keeps_dead_on():
    """Issue 46: a lasso of the masked graph is rebuilt over real states
    (docs/reductions.md, "Temporal properties under the reductions"); the
    verdict is the unreduced one."""
    prop = "eventually forall i: !flag[i]"
    kw = dict(source=True, agents=2, blackbox="instant", properties=(prop,), find_all=True)
    m = make_model(SCRATCH, reduce="auto", **{k: v for k, v in kw.items() if k != "find_all"})
    assert "dead" in m.reduction.on and "dead" not in m.reduction.off
    # SCRATCH's total grows for ever: the same program counting modulo 3
    text = SCRATCH.replace("x = total + 1;", "x = (total + 1) % 3;")
    a = explore(text, reduce="dead", **kw)
    b = explore(text, reduce="none", engine="python", **kw)
    assert a.stats.states < b.stats.states
    assert (a.status, sorted(a.holds), [v["name"] for v in a.violations]) == \
        (b.status, sorted(b.holds), [v["name"] for v in b.violations])


def test_nothing_to_mask_leaves_it_off_under_auto():
    text = src("""
        allwrite:
          int n = 0;

        Go():
          pre(n < 3);
          eff:
            n = n + 1;
        """)
    m = make_model(text, source=True, agents=2, blackbox="instant")
    assert "dead" not in m.reduction.on and "dead" not in m.reduction.off
    assert DeadVars(m.model).all & ~DeadVars(m.model).keep == 0


# ---------------------------------------------------------------------------
# the soundness condition itself: equal masked keys are a bisimulation
# ---------------------------------------------------------------------------

def masked_bisimulation(m, limit: int) -> int:
    """Over the first ``limit`` reachable states of the *unreduced* model:
    states with equal masked keys have the same violations and the same
    labelled successors up to masked keys.  Returns how many states shared
    a masked key with another (the cases that exercised it)."""
    base = m.model
    d = DeadVars(base)

    def mk(st):
        return base.plain_key(d.mask(st))
    seen, level, groups = set(), list(base.init_states()), {}
    while level and len(seen) < limit:
        nxt = []
        for st in level:
            k = base.plain_key(st)
            if k in seen:
                continue
            seen.add(k)
            succ = base.plain_successors(st)
            sig = (frozenset((lab, mk(s)) for lab, s in succ),
                   frozenset((v.kind, v.name) for v in base.violations(st)))
            groups.setdefault(mk(st), set()).add(sig)
            nxt += [s for _, s in succ]
        level = nxt
    bad = [g for g in groups.values() if len(g) > 1]
    assert not bad, f"{len(bad)} masked keys with different futures"
    return len(seen) - len(groups)


@pytest.mark.parametrize("path,kw,limit,merges", [
    # (10,000: deep enough to reach Wait's test of waitTime; ignoring the reads of
    # conditions in the analysis is caught here, and not by the verdicts)
    ("programs/fischer.pccl", dict(overrides={"k": "1", "d": "1"}, invariants=("count(inCs) <= 1",)),
     10000, True),
    ("programs/race_robust.pccl", dict(world="programs/race.toml", agents=2, blackbox="nondet"),
     10000, True),
    ("programs/race_safe.pccl", dict(world="programs/race.toml", agents=2, blackbox="nondet"),
     3000, False),
    ("programs/leader.pccl", dict(agents=3), 3000, False),
])
def test_equal_masked_keys_have_equal_futures(path, kw, limit, merges):
    m = make_model(os.path.join(ROOT, path), **kw)
    assert "dead" in m.reduction.on
    assert (masked_bisimulation(m, limit) > 0) == merges


def test_equal_masked_keys_have_equal_futures_on_scratch():
    m = make_model(SCRATCH, source=True, agents=2, blackbox="instant")
    assert masked_bisimulation(m, 3000) > 0


@settings(max_examples=20, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(prog=programs(), agents=hs.integers(1, 3), blackbox=hs.sampled_from(["instant", "nondet"]))
def test_equal_masked_keys_have_equal_futures_on_generated_programs(prog, agents, blackbox):
    text, invariants = prog
    m = make_model(text, source=True, agents=agents, blackbox=blackbox,
                   invariants=tuple(invariants), reduce="dead")
    masked_bisimulation(m, 1000)


# ---------------------------------------------------------------------------
# issue 41: the soundness conditions as predicates, and the holes they close
# ---------------------------------------------------------------------------

def truth_and(text, reduce_engine, workers=1, **kw):
    """(verdict of the truth configuration, verdict of each (reduce, engine)
    in ``reduce_engine`` with ``workers``): the status, the exit status, the
    first violation's kind and message; the truth is ``reduce="none"``,
    exact, the Python engine, one worker."""
    def verdict(r):
        v = r.violation
        return (r.status, r.exit_status, v and v.kind, v and v.message)
    truth = verdict(explore(text, source=True, reduce="none", exact=True, engine="python", **kw))
    return truth, [verdict(explore(text, source=True, reduce=r, engine=e, workers=workers, **kw))
                   for r, e in reduce_engine]


# hole 1: x is never read, so the initial-state search merged its outcomes,
# also the one for which the initialiser itself fails
FAILING_INITIALISERS = {
    "division": "int x = 10 / (rand(2) - 2);",
    "index": "List<int> xs = [7, 8];\n  int x = xs[rand(2)];",
    "modulo": "int x = 7 % (rand(3) - 1);",
    "short-circuit": "bool b = rand(1) == 0 || 1 / 0 == 1;",
    "array": "int a[2] = 10 / (1 - rand(1));",
    "rand-bound": "int x = rand(0 - rand(1));",
}


@pytest.mark.parametrize("name", sorted(FAILING_INITIALISERS))
def test_an_unread_initialiser_keeps_its_failing_outcomes(name):
    text = src("""
        loc:
          %s

        Done():
          pre(true);
          eff:
            exit();
        """) % FAILING_INITIALISERS[name]
    truth, got = truth_and(text, [("auto", "native"), ("auto", "python"), ("dead", "native"),
                                  ("dead", "python")], agents=2)
    assert truth[0] == "violation" and truth[2] == "stuck", truth
    assert got == [truth] * 4


def test_the_reproducers_of_hole_1_on_both_engines_with_workers():
    for init in (FAILING_INITIALISERS["division"], FAILING_INITIALISERS["index"]):
        text = src("""
            loc:
              %s

            Done():
              pre(true);
              eff:
                exit();
            """) % init
        truth, got = truth_and(text, [("auto", "native"), ("auto", "python")], workers=2)
        assert truth[:3] == ("violation", 1, "stuck")
        assert got == [truth, truth]


def test_which_initialisers_take_one_outcome():
    """:func:`rand_outcomes_fail_alike` through :func:`can_collapse_initial_rand`:
    one outcome only where none can fail unlike another; the others are
    unread too (:func:`initial_rand_unread`) and take every failing outcome."""
    from pccl.model.dead import can_collapse_initial_rand, initial_rand_unread
    decls = {
        "big": ("int big = rand(100000000);", True),
        "shifted": ("int shifted = 3 - rand(5) + 1;", True),
        "neg": ("int neg = -rand(5);", True),
        "cmp": ("bool cmp = rand(5) < n;", True),
        "notb": ("bool notb = !(rand(1) == 0);", True),
        "bound_fails": ("int bound_fails = rand(n / 0);", True),      # fails alike: before any outcome
        "elems": ("int elems[3] = rand(4);", True),
        "div": ("int div = 10 / (rand(2) - 2);", False),
        "idx": ("int idx = xs[rand(1)];", False),
        "prod": ("int prod = rand(3) * 2;", False),                   # an int slot checks a product
        "sum2": ("int sum2 = rand(3) + rand(2);", False),
        "nested": ("int nested = rand(rand(1));", False),
        "flt": ("float flt = rand(3);", False),                      # a float conversion may overflow
        "orr": ("bool orr = rand(1) == 0 || n > 0;", False),          # short-circuits on an outcome
    }
    body = "\n".join("  " + d for d, _ in decls.values())
    text = f"loc:\n  int n = 3;\n  List<int> xs = [1, 2];\n{body}\n\nDone():\n  pre(true);\n  eff:\n    exit();\n"
    m = make_model(text, source=True, agents=1)
    for name, (_, one) in decls.items():
        assert initial_rand_unread(m, name), name
        assert can_collapse_initial_rand(m, name) == one, name
    assert not initial_rand_unread(m, "n") and not can_collapse_initial_rand(m, "n")
    # the big range stays one initial state
    assert len(list(m.init_states())) == 1


def test_a_read_rand_initialiser_is_not_collapsed():
    from pccl.model.dead import can_collapse_initial_rand, initial_rand_unread
    text = src("""
        loc:
          int x = rand(3);

        Done():
          pre(x >= 0);
          eff:
            exit();
        """)
    m = make_model(text, source=True, agents=1)
    assert not initial_rand_unread(m, "x") and not can_collapse_initial_rand(m, "x")
    assert len(list(m.init_states())) == 4


# hole 2: a user blackbox that subclasses a shipped one inherits its name,
# not its capabilities
REACH_PROGRAM = src("""
    loc:
      int st = 0;

    Go():
      pre(st == 0);
      eff:
        doReach(ItemPosition(rand(1) * 10.0, 0.0), []);
        st = 1;

    Tick():
      pre(st >= 1 && st < 4);
      eff:
        st = st + 1;

    Done():
      pre(st == 4);
      eff:
        exit();
    """)
REACH_WORLD = 'agents = 1\nstart = [[0, 0]]\n\n[[obstacles]]\npolygon = [[4, -1], [6, -1], [6, 1], [4, 1]]\n'


def test_a_subclassed_blackbox_does_not_inherit_the_reach_masking(tmp_path):
    from dead_retry_bb import Retry
    world = tmp_path / "w.toml"
    world.write_text(REACH_WORLD)
    kw = dict(world=str(world), blackbox=Retry(), invariants=("forall i: pos[i].x < 5",))
    truth, got = truth_and(REACH_PROGRAM, [("auto", "auto"), ("auto", "python"), ("dead", "python")], **kw)
    assert truth[:3] == ("violation", 1, "invariant")
    assert got == [truth] * 3
    m = make_model(REACH_PROGRAM, source=True, **kw)
    assert "dead" in m.reduction.on and not m.dead_vars.reach_masked
    # the shipped straight, the same program: the reach is masked, the verdict the truth's
    kw["blackbox"] = "straight"
    m = make_model(REACH_PROGRAM, source=True, **kw)
    assert m.dead_vars.reach_masked
    truth, got = truth_and(REACH_PROGRAM, [("auto", "auto"), ("auto", "python")], **kw)
    assert truth[0] == "exhaustive" and got == [truth, truth]


def test_capabilities_count_only_where_the_class_declares_them():
    from dead_retry_bb import Retry
    from pccl.blackboxes import BLACKBOXES, Nondet, Straight
    from pccl.blackboxes.base import NO_CAPABILITIES, Capabilities, declared_capabilities
    from pccl.model.dead import blackbox_settled_hold_still
    from pccl.model.reduce import blackbox_treats_robots_alike
    for name in ("instant", "straight", "nondet", "nondet-fail"):
        bb = BLACKBOXES[name]
        assert blackbox_settled_hold_still(bb) and blackbox_treats_robots_alike(bb), name
    assert declared_capabilities(BLACKBOXES["pymunk"]) == NO_CAPABILITIES
    assert not blackbox_settled_hold_still(Retry()) and not blackbox_treats_robots_alike(Retry())

    class Declared(Straight):           # a subclass that declares what it promises
        capabilities = Capabilities(settled_robots_hold_still=True)
    assert blackbox_settled_hold_still(Declared()) and not blackbox_treats_robots_alike(Declared())
    # a fresh instance of a shipped class is the shipped class's behaviour
    assert blackbox_settled_hold_still(Nondet("mine")) and blackbox_treats_robots_alike(Straight())
    patched = Straight()
    patched.step = Retry().step         # an instance whose step is replaced promises nothing
    assert declared_capabilities(patched) == NO_CAPABILITIES
    claims = Straight()
    claims.capabilities = Capabilities(True, True)   # nor one that claims on its own
    assert declared_capabilities(claims) == NO_CAPABILITIES
    assert not blackbox_settled_hold_still(None)

    class Named:                        # a shipped name, no declaration
        name = "nondet"
        uses_time = False

        def init_env(self, world, n_agents):
            return None

        def step(self, world, motions, env, time, delta):
            return BLACKBOXES["nondet"].step(world, motions, env, time, delta)
    assert declared_capabilities(Named()) == NO_CAPABILITIES


def test_symmetry_reads_the_same_capability():
    from dead_retry_bb import Retry
    from pccl.blackboxes import Straight
    text = src("""
        loc:
          int st = 0;

        Go():
          pre(st == 0);
          eff:
            doReach(ItemPosition(1.0, 0.0), []);
            st = 1;
        """)
    m = make_model(text, source=True, agents=2, blackbox=Retry())
    assert "symmetry" not in m.reduction.on
    assert "blackbox straight may treat agents differently" in m.reduction.off["symmetry"]
    assert "symmetry" in make_model(text, source=True, agents=2, blackbox=Straight()).reduction.on


@pytest.mark.slow
def test_the_collapse_keeps_the_documented_counts():
    """Programs whose unread initialisers cannot fail keep the figures of
    docs/reductions.md ("Dead variables"): Fischer's ``cstime = rand(5)``
    is one outcome, race_robust is unchanged."""
    from pccl.model.dead import can_collapse_initial_rand
    path = os.path.join(ROOT, "programs/fischer.pccl")
    kw = dict(overrides={"k": "2", "d": "2"})
    assert can_collapse_initial_rand(make_model(path, **kw), "cstime")
    for engine in ("python", "native"):
        r = explore(path, engine=engine, **kw)
        assert (r.status, r.stats.initial_states, r.stats.states) == ("exhaustive", 6, 1834), engine
    r = explore(RACE, world=WORLD, agents=3, engine="native")
    # complete for nondet, "not exhaustive for pymunk" (a second leg: issue 41 holes 3-4)
    assert (r.status, r.stats.states, r.stats.transitions) == ("bounded", 88168, 138720)
    assert r.search.status == "exhaustive" and not r.bounds
