"""Evidence that the state-space reductions (pccl/model/reduce.py) are sound.

1. every shipped and test program, explored as tests/search/test_fingerprints.py
   explores it, under every combination of reductions: the verdict (status
   and the set of distinct violations) equals the verdict with
   ``reduce="none"``, and every counterexample, expanded, is a path of the
   unreduced model ending in a state with its violation;
2. the same over hypothesis-generated programs (test_fingerprints' generator);
3. hand-made programs for the corner cases: local loops, runtime errors
   inside a merged chain, rand inside a chain, id-valued variables, the
   reasons a reduction is off;
4. the plumbing: ``--reduce`` on the command line, the header and the JSON.
"""

from __future__ import annotations

import itertools
import json
import re
import subprocess
import sys
import textwrap

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hs

from pccl.model import reduce as RD
from pccl.api import explore, make_model
from pccl.model.engine import Model
from pccl.lang.errors import PcclError

from conftest import PROGRAMS, ROOT, verdict
from pccl.model.layout import AGS, AR, CNT, ENV, LCK, LOC, LQ, PC, PHASE, SH, STATUS, TIME
from cases import PINNED, SHIPPED, SLOW, TESTPROGS, programs

MUTEX = "count(inCs) <= 1"
#: every non-empty combination of merge, symmetry and por; dead alone and with all of them
COMBOS = [list(c) for n in range(1, 4) for c in itertools.combinations(RD.ALL[:3], n)] + \
    [["dead"], list(RD.ALL)]


def src(text: str) -> str:
    return textwrap.dedent(text).lstrip("\n")


def check_counterexamples(res):
    """Every (expanded) counterexample is a path of the unreduced model that
    ends in a state with the reported violation."""
    m = res.model
    for v, cx in zip(res.violations, res.counterexamples):
        tr = cx.trace
        if tr is None:              # reachable P found unreachable: no path
            assert v["kind"] == "unreachable"
            continue
        assert len(tr) == len(v.trace)
        for step in tr.steps:
            assert len(step.label) == 3, "an unexpanded merged label in a trace"
            succ = Model.successors(m, step.before)
            assert (step.label, step.after) in succ, f"step {step.number} is not a transition"
        last = tr.last
        if v["kind"] in ("stall", "frozen"):
            # the first state of the stall, or of a frozen team (pccl/model/frozen.py):
            # running agents, not terminal
            assert Model.successors(m, last)
            continue
        if v["kind"] in ("liveness", "timelock", "response"):
            # temporal (pccl/search/liveness.py): a lasso closes its cycle (up to the
            # reduced identity: a permutation of the agents under symmetry)
            if cx.cycle_start is not None:
                assert m.key(tr.states[cx.cycle_start]) == m.key(last)
            continue
        if v["kind"] == "deadlock" and v["name"] == "deadlock":
            # (a lock held by an exited agent is a deadlock of a state, below)
            assert not Model.successors(m, last) and m.terminal_kind(last) == "deadlock"
        else:
            ids = {(w.kind, w.name, w.span.line if w.span else None)
                   for w in Model.violations(m, last)}
            assert (v["kind"], v["name"], v["line"]) in ids


def auto_plan(program, **opts):
    """The reductions ``auto`` turns on for this case, and why the others are off."""
    opts = {k: v for k, v in opts.items()
            if k not in ("max_states", "depth", "find_all", "timelock", "fastest")}
    invariants = tuple(opts.pop("invariants", ()))
    return make_model(program, invariants=invariants, reduce="auto", **opts).reduction


def sound_set(program, **opts) -> tuple:
    """The reductions ``auto`` turns on for this case."""
    return auto_plan(program, **opts).on


def unsound(combo, plan) -> list:
    """The reductions of ``combo`` that asking for is an error: off under
    ``auto`` (merge is always sound; dead only under a liveness property,
    else it is merely left off under ``auto`` where nothing can be dead;
    counters only where off for a reason, else it is left off where no
    counter can pass its cap)."""
    return [r for r in combo if r not in plan.on and r != "merge"
            and (r != "dead" or "liveness" in plan.off.get("dead", ""))
            and (r != "counters" or "counters" in plan.off)]


def sym_sound(program, **opts) -> bool:
    return "symmetry" in sound_set(program, **opts)


def _bounded(options) -> bool:
    return "max_states" in options or "depth" in options


@pytest.mark.parametrize("name,program,options", [
    pytest.param(*c, id=c[0], marks=[pytest.mark.slow] if c[0] in SLOW else [])
    for c in SHIPPED + TESTPROGS])
def test_reductions_keep_the_verdict(name, program, options):
    base = explore(program, find_all=True, reduce="none", **options)
    got = (base.status, base.stats.states, base.stats.transitions, base.stats.max_depth)
    assert got == PINNED[name], "reduce='none' must keep the pinned counts"
    plan = auto_plan(program, **options)
    for combo in COMBOS:
        if combo == ["dead"]:
            continue     # dead alone: with all four here, and its own condition in test_dead.py
        bad = unsound(combo, plan)
        if bad:
            with pytest.raises(PcclError, match=f"{bad[0]} reduction is unsound"):
                explore(program, find_all=True, reduce=combo, **options)
            continue
        res = explore(program, find_all=True, reduce=combo, **options)
        assert res.stats.states <= base.stats.states
        check_counterexamples(res)
        if not _bounded(options):
            assert verdict(res) == verdict(base), f"{combo}: {res.verdict} != {base.verdict}"
        elif base.status == "exhaustive":
            assert res.status == "exhaustive"


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(prog=programs(), agents=hs.integers(1, 3), blackbox=hs.sampled_from(["instant", "nondet"]))
def test_random_programs_keep_the_verdict(prog, agents, blackbox):
    text, invariants = prog
    kw = dict(source=True, agents=agents, blackbox=blackbox, invariants=invariants,
              find_all=True)
    base = explore(text, reduce="none", max_states=4000, **kw)
    if base.bounds:          # not exhaustive: nothing to compare against
        return
    sym = "symmetry" in make_model(text, source=True, agents=agents, blackbox=blackbox,
                                   invariants=tuple(invariants), reduce="auto").reduction.on
    for combo in COMBOS:
        if "symmetry" in combo and not sym:
            continue
        if agents == 1 and combo not in (["merge"], ["dead"]):
            # symmetry and por asked for by name need two agents
            with pytest.raises(PcclError, match="needs two or more agents"):
                explore(text, reduce=combo, **kw)
            continue
        res = explore(text, reduce=combo, **kw)
        assert verdict(res) == verdict(base), f"{combo}: {res.verdict} != {base.verdict}"
        check_counterexamples(res)


# ---------------------------------------------------------------------------
# 3. corner cases
# ---------------------------------------------------------------------------

LOCAL_LOOP = src("""
    loc:
      int x = 0;

    Spin():
      pre(true);
      eff:
        while (true):
          x = 1 - x;
    """)


def test_zero_time_local_loop_is_explored_not_lost():
    base = explore(LOCAL_LOOP, source=True, blackbox="instant", reduce="none", timelock=False)
    res = explore(LOCAL_LOOP, source=True, blackbox="instant", reduce="auto", timelock=False)
    assert base.status == res.status == "exhaustive"
    assert "merge" in res.model.reduction.on
    # the loop never lets time advance: a time-lock, with and without merging
    base = explore(LOCAL_LOOP, source=True, blackbox="instant", reduce="none")
    res = explore(LOCAL_LOOP, source=True, blackbox="instant", reduce="auto")
    assert [v["kind"] for v in base.violations] == [v["kind"] for v in res.violations] \
        == ["timelock"]
    assert res.counterexamples[0].cycle_start is not None


STUCK_IN_CHAIN = src("""
    allwrite:
      int s = 0;

    loc:
      int x = 1;
      int y = 0;

    Go():
      pre(s == 0);
      eff:
        s = 1;
        x = x - 1;
        y = 3 / x;
        s = 2;
    """)


def test_runtime_error_inside_a_chain_is_the_stuck_state():
    base = explore(STUCK_IN_CHAIN, source=True, blackbox="instant", reduce="none", find_all=True)
    res = explore(STUCK_IN_CHAIN, source=True, blackbox="instant", reduce="merge", find_all=True)
    assert verdict(res) == verdict(base)
    assert res.violations[0]["kind"] == "stuck"
    assert res.violations[0]["line"] == 13
    assert res.trace[-1]["source"] == "y = 3 / x;"
    check_counterexamples(res)
    assert res.stats.states < base.stats.states


RAND_CHAIN = src("""
    allwrite:
      int s = 0;

    loc:
      int x = 0;
      int y = 0;

    Go():
      pre(s < 2);
      eff:
        x = rand(2);
        y = x + 1;
        s = s + y;
    """)


def test_rand_splits_a_chain_into_branches():
    base = explore(RAND_CHAIN, source=True, blackbox="instant", reduce="none",
                   invariants=["s < 4"], find_all=True)
    res = explore(RAND_CHAIN, source=True, blackbox="instant", reduce="merge",
                  invariants=["s < 4"], find_all=True)
    assert verdict(res) == verdict(base) and res.status == "violation"
    check_counterexamples(res)
    assert res.stats.states < base.stats.states


def test_a_property_read_stops_the_chain():
    # x is read by the invariant: its assignment is a visible step
    text = src("""
        loc:
          int x = 0;

        Go():
          pre(x == 0);
          eff:
            x = 1;
            x = 0;
        """)
    base = explore(text, source=True, blackbox="instant", reduce="none",
                   invariants=["forall i: x[i] == 0"])
    res = explore(text, source=True, blackbox="instant", reduce="merge",
                  invariants=["forall i: x[i] == 0"])
    assert base.status == res.status == "violation"


def test_fischer_figures():
    kw = dict(overrides={"k": "1", "d": "2"})
    none = explore(str(PROGRAMS / "fischer.pccl"), reduce="none", **kw)
    merge = explore(str(PROGRAMS / "fischer.pccl"), reduce="merge", **kw)
    auto = explore(str(PROGRAMS / "fischer.pccl"), reduce="auto", **kw)
    por = explore(str(PROGRAMS / "fischer.pccl"), reduce="por", **kw)
    assert auto.model.reduction.on == ("merge", "symmetry", "por", "dead")
    assert none.status == merge.status == auto.status == por.status == "exhaustive"
    assert none.stats.states > 2 * por.stats.states
    assert none.stats.states > 3 * merge.stats.states
    assert none.stats.states > 6 * auto.stats.states


def test_zero_time_local_loop_under_por_alone():
    # the loop's statements are never in an ample set: the search ends, and
    # the time-lock the loop is (time never advances) is found as without por
    base = explore(LOCAL_LOOP, source=True, blackbox="instant", reduce="none", find_all=True)
    res = explore(LOCAL_LOOP, source=True, blackbox="instant", reduce="por", find_all=True)
    assert verdict(res) == verdict(base)
    assert res.stats.states <= base.stats.states


GUARD_ERROR = src("""
    allwrite:
      int s = 0;

    loc:
      int x = getAgentIndex();
      int y = 0;

    Go():
      pre(10 / x > 1);
      eff:
        s = s + 1;

    Other():
      pre(y == 0);
      eff:
        y = 1;
    """)


def test_a_step_that_gets_the_agent_stuck_is_never_ample():
    # agent 0's EVENT SELECT divides by zero: visible, so not in an ample set
    base = explore(GUARD_ERROR, source=True, blackbox="instant", reduce="none", find_all=True)
    res = explore(GUARD_ERROR, source=True, blackbox="instant", reduce="por", find_all=True)
    assert base.status == "violation" and verdict(res) == verdict(base)
    assert res.violations[0]["kind"] == "stuck"
    check_counterexamples(res)


DEADLOCK = src("""
    allwrite:
      int turn = 0;

    loc:
      int id = getAgentIndex();
      int n = 0;

    Step():
      pre(n < 2);
      eff:
        n = n + 1;
        if (turn == id):
          turn = 1 - turn;

    Stop():
      pre(n >= 2);
      eff:
        exit();
    """)


@pytest.mark.parametrize("text,kinds", [(DEADLOCK, set()), (GUARD_ERROR, {"stuck", "deadlock"})])
def test_every_combination_keeps_deadlocks_and_exits(text, kinds):
    # GUARD_ERROR: agent 0 is stuck, so once agent 1 has spent its counter no
    # rule applies (a deadlock); DEADLOCK (despite its name) ends with both exited
    base = explore(text, source=True, blackbox="instant", reduce="none", find_all=True)
    assert {v["kind"] for v in base.violations} == kinds
    for combo in COMBOS:
        if "symmetry" in combo:
            continue             # ids in arithmetic: symmetry is unsound for both
        res = explore(text, source=True, blackbox="instant", reduce=combo, find_all=True)
        assert verdict(res) == verdict(base), combo
        check_counterexamples(res)


def test_por_ample_sets_are_one_agents_local_steps():
    # in every state the search expands, the POR successors are either all of
    # the rules' successors or every one of a single agent's (never a mix)
    m = make_model(str(PROGRAMS / "fischer.pccl"), overrides={"k": "1", "d": "1"}, reduce="por")
    full_model = make_model(str(PROGRAMS / "fischer.pccl"), overrides={"k": "1", "d": "1"},
                            reduce="none")
    seen, level, reduced = set(), list(m.init_states()), 0
    while level and len(seen) < 3000:
        nxt = []
        for st in level:
            got = m.successors(st)
            full = full_model.successors(st)
            assert got and set(map(repr, got)) <= set(map(repr, full))
            if len(got) < len(full):
                reduced += 1
                (agent,) = {lab[1] for lab, _ in got}
                assert agent is not None
                assert sorted(map(repr, got)) == sorted(repr(x) for x in full if x[0][1] == agent)
            for _, s2 in got:
                if m.key(s2) not in seen:
                    seen.add(m.key(s2))
                    nxt.append(s2)
        level = nxt
    assert reduced > 0


def test_fischer_counterexample_under_symmetry_replays():
    res = explore(str(PROGRAMS / "fischer.pccl"), invariants=[MUTEX], overrides={"k": "0"}, reduce="auto")
    assert res.status == "violation"
    check_counterexamples(res)
    # shown shortest against the unreduced semantics (issue 44.3) ...
    assert res.violations[0]["shortest"] == "yes"
    assert res.violations[0].shortening.status in ("shortened", "confirmed")
    # ... or, without that, shortest in the reduced graph only
    off = explore(str(PROGRAMS / "fischer.pccl"), invariants=[MUTEX], overrides={"k": "0"},
                  reduce="auto", shorten=False)
    check_counterexamples(off)
    assert off.violations[0]["shortest"] == "under the reductions"


def reasons(text, **kw):
    m = make_model(text, source=True, reduce="auto", **kw)
    return m.reduction


@pytest.mark.parametrize("text,props,why", [
    ("loc:\n  bool b = false;\n\nE():\n  pre(true);\n  eff:\n    b = true;\n",
     ["b[0] == false"], "b[0] names agent 0"),
    ("allwrite:\n  int t = 0;\n\nloc:\n  int id = getAgentIndex();\n\nE():\n  pre(true);\n"
     "  eff:\n    t = (id + 1) % getNumAgents();\n", [], "used other than"),
    ("allwrite:\n  int a[3] = 0;\n\nE():\n  pre(true);\n  eff:\n    a[getAgentIndex()] = 1;\n",
     [], "getAgentIndex()"),
    ("loc:\n  int x = 0;\n\nE():\n  pre(true);\n  eff:\n    doReach(ItemPosition(getAgentIndex(), 1), []);\n",
     [], "getAgentIndex()"),
])
def test_symmetry_off_with_a_reason(text, props, why):
    plan = reasons(text, invariants=tuple(props), blackbox="instant")
    assert "symmetry" not in plan.on and why in plan.off["symmetry"]
    assert "merge" in plan.on
    with pytest.raises(PcclError, match="symmetry reduction is unsound"):
        make_model(text, source=True, reduce="symmetry", invariants=tuple(props),
                   blackbox="instant")


def test_symmetric_properties_and_sentinels_keep_symmetry():
    text = src("""
        allwrite:
          int owner = -1;

        loc:
          int id = getAgentIndex();
          bool mine = false;

        Take():
          pre(owner == -1);
          eff:
            atomic:
              owner = id;
            mine = true;

        Give():
          pre(mine);
          eff:
            mine = false;
            atomic:
              owner = -1;
        """)
    props = ["forall i: forall j: (mine[i] && mine[j]) -> i == j", "count(mine) <= 1"]
    plan = reasons(text, invariants=tuple(props), blackbox="instant", agents=3)
    assert plan.on == ("merge", "symmetry", "por", "dead")
    base = explore(text, source=True, blackbox="instant", agents=3, invariants=props,
                   reduce="none", find_all=True)
    res = explore(text, source=True, blackbox="instant", agents=3, invariants=props,
                  find_all=True, reduce="auto")
    assert verdict(res) == verdict(base)
    check_counterexamples(res)
    assert res.stats.states < base.stats.states


OTHER_REF = src("""
    allwrite:
      int leader = -1;

    loc:
      int id = getAgentIndex();
      int seen = -1;
      bool done = false;

    Look():
      pre(!done);
      eff:
        seen = leader;
        atomic:
          leader = id;
        done = true;
    """)


def test_agents_holding_other_agents_ids_are_canonical():
    # ties broken by trying the tied group's orders: the same orbit, one key
    m = make_model(OTHER_REF, source=True, blackbox="instant", agents=3, reduce="symmetry")
    assert "symmetry" in m.reduction.on
    import itertools
    for st in list(explore(OTHER_REF, source=True, blackbox="instant", agents=3,
                           reduce="none").model.init_states()):
        ags = st[AGS]
        for perm in itertools.permutations(range(3)):
            r = {old: new for new, old in enumerate(perm)}

            def rn(v, r=r):
                return r[v] if type(v) is int and v >= 0 else v
            cells = []
            for old in perm:
                a = ags[old]
                loc = (rn(a[LOC][0]), rn(a[LOC][1]), a[LOC][2])
                cells.append((a[PC], a[CNT], a[LCK], a[STATUS], loc) + a[AR:])
            sh = (rn(st[SH][0]),)
            st2 = (st[TIME], st[PHASE], tuple(r[x] for x in st[LQ]), sh, tuple(cells), st[ENV])
            assert m.key(st2) == m.key(st)
    base = explore(OTHER_REF, source=True, blackbox="instant", agents=3, reduce="none",
                   find_all=True)
    res = explore(OTHER_REF, source=True, blackbox="instant", agents=3, find_all=True, reduce="auto")
    assert verdict(res) == verdict(base)
    assert res.stats.states < base.stats.states


def test_unknown_reduction_is_an_error():
    with pytest.raises(PcclError):
        make_model(LOCAL_LOOP, source=True, reduce="bogus")


# ---------------------------------------------------------------------------
# 4. command line
# ---------------------------------------------------------------------------

def pccl(*args):
    return subprocess.run([sys.executable, "-c", "from pccl.cli import main; main()", *args],
                          capture_output=True, text=True, cwd=ROOT)


def test_cli_header_and_json_name_the_reductions():
    r = pccl("explore", "programs/fischer.pccl", "--set", "k=0", "--invariant", MUTEX, "--reduce", "auto")
    assert r.returncode == 1
    assert "reductions merge+symmetry+por" in r.stdout.splitlines()[0]
    assert re.search(r"^counterexample \(\d+ steps, shortest[:;)]", r.stdout, re.M)
    r = pccl("explore", "programs/fischer.pccl", "--set", "k=0", "--invariant", MUTEX,
             "--no-shorten")
    assert "shortest under the reductions; not compared with the unreduced graph" in r.stdout
    r = pccl("explore", "programs/fischer.pccl", "--set", "k=0", "--reduce", "none",
             "--format", "json")
    data = json.loads(r.stdout)
    assert data["reductions"] == {"requested": "none", "on": [], "off": {}}
    r = pccl("explore", "programs/fischer.pccl", "--set", "k=0", "--invariant", "!inCs[0]",
             "--format", "json", "--reduce", "auto")
    data = json.loads(r.stdout)
    assert data["reductions"]["on"] == ["merge", "por", "dead"]
    assert "inCs[0] names agent 0" in data["reductions"]["off"]["symmetry"]
    r = pccl("explore", "programs/fischer.pccl", "--reduce", "symmetry", "--invariant", "!inCs[0]")
    assert r.returncode == 2 and "symmetry reduction is unsound" in r.stderr


def test_coverage_turns_the_reductions_off_with_a_reason():
    r = pccl("explore", "programs/fischer.pccl", "--set", "k=0", "--coverage")
    head = r.stdout.splitlines()[0]
    assert "reductions none; merge, symmetry, por, dead, counters off: --coverage counts the unreduced" in head
    none = pccl("explore", "programs/fischer.pccl", "--set", "k=0", "--coverage",
                "--reduce", "none")

    def body(out):           # all but the header and the timings
        return [ln for ln in out.splitlines()[1:]
                if not any(w in ln for w in ("seconds", "states/second", "peak memory"))]
    # the same verdict, counts and coverage as the unreduced search
    assert body(r.stdout) == body(none.stdout) and "coverage (" in r.stdout
    r = pccl("explore", "programs/fischer.pccl", "--set", "k=0", "--coverage", "--reduce", "merge")
    assert r.returncode == 2 and "merge reduction cannot be used here: --coverage" in r.stderr
    res = explore(str(PROGRAMS / "fischer.pccl"), overrides={"k": "0"}, coverage=True)
    assert res.model.reduction.on == () and res.coverage.expanded == res.stats.states


def test_reduced_counts_say_so():
    r = pccl("explore", "programs/fischer.pccl", "--set", "k=0")
    assert "states" in r.stdout and "(reduced: merge+symmetry+por+dead)" in r.stdout
    r = pccl("explore", "programs/fischer.pccl", "--set", "k=0", "--format", "json")
    assert json.loads(r.stdout)["statistics"]["reduced"] is True
    r = pccl("explore", "programs/fischer.pccl", "--set", "k=0", "--reduce", "none")
    assert "reduced" not in r.stdout


# ---------------------------------------------------------------------------
# 5. random programs whose guards are local, so that POR's ample sets apply
#    (checked when written: of 30 examples 19 were exhaustive within the
#    bound, and POR had fewer states than none in 16 of them)
# ---------------------------------------------------------------------------

LOCAL_GUARDS = ["a < 2", "b", "!b", "a == 0", "a >= 1 && !b", "10 / a > 1", "rand(1) == 0"]
BODY = ["a = a + 1;", "b = !b;", "s = s + a;", "s = a;", "if (s > a):\n      b = true;",
        "atomic:\n      s = s + 1;", "a = rand(1);", "while (a < 2):\n      a = a + 1;",
        "exit();", "assert(s < 4);", "t = t + 1;"]


@hs.composite
def local_guard_programs(draw):
    text = "allwrite:\n  int s = 0;\n  int t = 0;\n\nloc:\n"
    text += f"  int a = {draw(hs.sampled_from(['0', '1', 'rand(1)']))};\n  bool b = false;\n"
    for e in range(draw(hs.integers(1, 3))):
        guard = draw(hs.sampled_from(LOCAL_GUARDS))
        body = draw(hs.lists(hs.sampled_from(BODY), min_size=1, max_size=4))
        text += f"\nE{e}():\n  pre({guard});\n  eff:\n" + "".join(f"    {b}\n" for b in body)
    invariants = draw(hs.lists(hs.sampled_from(["s < 3", "t <= 2", "count(b) <= 1",
                                                "forall i: a[i] <= 2"]), max_size=2))
    return text, invariants


@settings(max_examples=80, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(prog=local_guard_programs(), agents=hs.integers(2, 3),
       events=hs.sampled_from(["any", "first"]))
def test_random_local_guard_programs_keep_the_verdict_under_por(prog, agents, events):
    text, invariants = prog
    kw = dict(source=True, agents=agents, blackbox="instant", invariants=invariants,
              find_all=True, events=events)
    base = explore(text, reduce="none", max_states=5000, **kw)
    if base.bounds:
        return
    for combo in (["por"], ["merge", "por"], "auto"):
        res = explore(text, reduce=combo, **kw)
        assert verdict(res) == verdict(base), f"{combo}: {res.verdict} != {base.verdict}"
        check_counterexamples(res)
