"""Acceptance cases of issue 4 (``explore``): the paper's experiments (spec
§8), bounds and their verdicts, determinism, time abstraction, ``--all``,
deadlocks and the property language (docs/language.md §10)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from pccl.search.explorer import Bound
from pccl.output.results import StepView

from pccl.api import explore as _explore, make_model
from pccl.lang.errors import PcclError

from conftest import (FISCHER, RACE, RACE_NONATOMIC, RACE_WORLD, TEST_PROGRAMS, var)


def explore(*args, **kw):
    """The unreduced search (reduce='none'): this file pins its counts and
    shortest counterexamples; tests/model/test_reduce.py covers the reductions."""
    kw.setdefault("reduce", "none")
    return _explore(*args, **kw)


ASSERT_PROG = str(TEST_PROGRAMS / "eng_assert.pccl")
MUTEX = "count(inCs) <= 1"
SMALL = {"k": "1", "cstime": "0"}          # Fischer with waitTime in 0..1, cstime fixed


def line_of(path, text) -> int:
    lines = Path(path).read_text().splitlines()
    (n,) = [k + 1 for k, ln in enumerate(lines) if ln.strip() == text]
    return n


def both_in_cs_at_end(res):
    agents = res.final_state["agents"]
    return len(agents) == 2 and all(a["variables"]["inCs"] is True for a in agents)


# ---------------------------------------------------------------------------
# Fischer (paper §5.1)
# ---------------------------------------------------------------------------

@pytest.fixture(scope="module")
def fischer_any():
    progress = []
    res = explore(FISCHER, invariants=[MUTEX], progress=progress.append)
    return res, progress


def check_fischer_violation(res):
    assert res.status == "violation" and res.exit_status == 1
    assert res.violation["kind"] == "invariant" and res.violation["name"] == MUTEX
    assert "count(inCs) <= 1" in res.verdict and "straight" in res.verdict
    assert both_in_cs_at_end(res)
    raw = list(res.counterexamples[0].trace)
    m = res.model
    end = raw[-1][1]
    assert var(m, end, 0, "inCs") is True and var(m, end, 1, "inCs") is True
    # no earlier state of the counterexample violates the property
    assert not any(var(m, s, 0, "inCs") and var(m, s, 1, "inCs") for _, s in raw[:-1])
    # the trace is the path: numbered steps, consecutive, replayable
    assert [s["index"] for s in res.trace] == list(range(1, len(raw)))
    assert len(res.trace) == res.violation["depth"]
    st = raw[0][1]
    assert st in m.init_states()
    for label, nxt in raw[1:]:
        assert (label, nxt) in m.successors(st)
        st = nxt
    rules = {s["rule"] for s in res.trace}
    assert {"EVENT SELECT", "STATEMENT", "COUNTER ADVANCE", "TIME ADVANCE", "DOREACH INVOKE",
            "LOCK REQUEST", "ATOMIC EXECUTION", "LOCK RELEASE"} <= rules
    last = res.trace[-1]
    assert last["rule"] == "STATEMENT" and last["source"] == "inCs = true;"
    assert {"cell": {"agent": last["agent"], "var": "inCs"}, "old": False, "new": True} \
        in last["changes"]


def test_fischer_mutex_violation_found(fischer_any):
    res, progress = fischer_any
    check_fischer_violation(res)
    assert res.stats.initial_states == 11 * 11 * 6 * 6
    assert res.model.abstract_time is True


def test_fischer_progress_reported(fischer_any):
    res, progress = fischer_any
    assert progress, "no progress report during a multi-second search"
    p = progress[-1]
    assert {"states", "frontier", "depth", "seconds", "memory"} <= set(p)
    assert 0 < p["states"] <= res.stats.states


def test_fischer_mutex_violation_found_events_first():
    # k = 2 (waitTime in 0..2) instead of 10 keeps this under 3 s; the search
    # with the shipped k = 10 takes as long as test_fischer_mutex_violation_found
    kw = dict(invariants=[MUTEX], overrides={"k": "2"})
    res = explore(FISCHER, events="first", **kw)
    check_fischer_violation(res)
    assert res.model.events_policy == "first"
    # Fischer's guards exclude each other: the two policies agree exactly
    base = explore(FISCHER, **kw)
    check_fischer_violation(base)
    assert res.violation["depth"] == base.violation["depth"]
    assert res.stats.states == base.stats.states


def test_fischer_mutex_violation_small_k():
    res = explore(FISCHER, invariants=[MUTEX], overrides=SMALL)
    check_fischer_violation(res)


def test_fischer_mutex_holds_with_large_d():
    # the paper: no violation when d > 2 ... for these small wait times
    res = explore(FISCHER, invariants=[MUTEX], overrides={"k": "1", "cstime": "0", "d": "3"})
    assert res.status in ("exhaustive", "violation")
    res2 = explore(FISCHER, invariants=[MUTEX], overrides={"k": "0", "cstime": "0", "d": "3"})
    assert res2.status == "exhaustive" and res2.exit_status == 0


# ---------------------------------------------------------------------------
# Race (paper §2.1, §5.2)
# ---------------------------------------------------------------------------

RACE_SAFE = str(Path(RACE).with_name("race_safe.pccl"))
RACE_ROBUST = str(Path(RACE).with_name("race_robust.pccl"))


@pytest.mark.parametrize("agents", [2, 3])
def test_race_no_violation_exhaustive_straight(agents):
    res = explore(RACE, world=RACE_WORLD, blackbox="straight", agents=agents)
    assert res.violations == [], res.verdict
    assert res.status == "exhaustive" and res.exit_status == 0
    assert res.verdict.startswith("no violation — exhaustive [blackbox straight] (travel times "
                                  "fixed by straight; blackbox=nondet explores every timing)")
    assert res.model.N == agents


def test_api_explore_defaults_to_nondet_for_a_program_that_moves():
    res = explore(RACE_NONATOMIC, world=RACE_WORLD)
    assert res.blackbox == "nondet" and res.status == "violation"
    assert res.model.blackbox_reason == "default for programs that move"
    res = explore(FISCHER, overrides=SMALL, depth=3)       # no doReach: the run default
    assert res.blackbox == "straight" and res.model.blackbox_reason is None
    assert "travel times" not in res.verdict


@pytest.mark.parametrize("agents", [2, 3])
@pytest.mark.parametrize("blackbox", ["instant", "nondet"])
def test_race_head_race_under_instant_and_nondet(blackbox, agents):
    """docs/decisions.md, "The Race program has a second race": PickDest
    tests isEmpty(dests) and takes head(dests) in two transitions."""
    res = explore(RACE, world=RACE_WORLD, blackbox=blackbox, agents=agents)
    assert res.status == "violation" and res.exit_status == 1
    v = res.violation
    assert v["kind"] == "stuck" and "head of an empty list" in v["message"]
    assert v["line"] == line_of(RACE, "currentDest = head(dests);")


@pytest.mark.parametrize("blackbox", ["instant", "nondet"])
def test_race_failure_is_only_the_head_race(blackbox):
    """With every violation collected, the only problem in race.pccl is
    `head` of an emptied list, never `remove`."""
    res = explore(RACE, world=RACE_WORLD, blackbox=blackbox, find_all=True, deadlock=False)
    head_line = line_of(RACE, "currentDest = head(dests);")
    assert res.violations
    for v in res.violations:
        assert v["kind"] == "stuck" and "head of an empty list" in v["message"]
        assert v["line"] == head_line


@pytest.mark.parametrize("blackbox, agents", [("instant", 2), ("straight", 2), ("straight", 3)])
def test_race_safe_no_violation_exhaustive(blackbox, agents):
    # under the covering nondet both robots may drive for one waypoint, block
    # each other and never handle doReach_fail: a stall (pinned in
    # test_fingerprints); the races it closes are the stuck agents
    res = explore(RACE_SAFE, world=RACE_WORLD, blackbox=blackbox, agents=agents,
                  stall=blackbox != "nondet")
    assert res.violations == [], res.verdict
    assert res.status == "exhaustive" and res.exit_status == 0
    assert f"[blackbox {blackbox}]" in res.verdict


def test_race_safe_stalls_under_nondet():
    """Under the covering nondet two robots heading for the same waypoint may
    both fail, and race_safe never handles doReach_fail: a stall whose
    message names the flag (docs/decisions.md, README)."""
    res = explore(RACE_SAFE, world=RACE_WORLD, blackbox="nondet")
    assert res.status == "violation" and res.exit_status == 1
    assert res.violation["kind"] == "stall", res.verdict
    assert "doReach_fail[0] is true" in res.verdict and "doReach_fail[1] is true" in res.verdict


@pytest.mark.parametrize("blackbox, agents", [("instant", 2), ("straight", 2), ("nondet", 2),
                                              ("straight", 3)])
def test_race_robust_no_violation_exhaustive(blackbox, agents):
    res = explore(RACE_ROBUST, world=RACE_WORLD, blackbox=blackbox, agents=agents)
    assert res.violations == [], res.verdict
    if blackbox == "nondet":
        # complete for nondet; its robots start second legs, which nondet
        # does not follow under pymunk (docs/blackboxes.md)
        assert res.status == "bounded" and "not exhaustive for pymunk" in res.verdict
        assert res.exit_status == 0
    else:
        assert res.status == "exhaustive" and res.exit_status == 0


@pytest.mark.parametrize("agents", [2, 3])
@pytest.mark.parametrize("blackbox", ["instant", "nondet"])
def test_race_nonatomic_stuck_on_remove(blackbox, agents):
    res = explore(RACE_NONATOMIC, world=RACE_WORLD, blackbox=blackbox, agents=agents)
    assert res.status == "violation" and res.exit_status == 1
    v = res.violation
    assert v["kind"] == "stuck" and "remove" in v["message"]
    assert v["line"] == line_of(RACE_NONATOMIC, "remove(dests, currentDest);")
    end = res.final_state["agents"][v["agent"]]        # the trace format's state (version 2)
    assert end["status"]["status"] == "stuck" and end["status"]["line"] == v["line"]
    assert f"[blackbox {blackbox}]" in res.verdict


@pytest.mark.parametrize("agents", [2, 3])
def test_race_nonatomic_straight_clean(agents):
    res = explore(RACE_NONATOMIC, world=RACE_WORLD, blackbox="straight", agents=agents)
    assert res.status == "exhaustive" and res.exit_status == 0 and res.violations == []


# ---------------------------------------------------------------------------
# determinism
# ---------------------------------------------------------------------------

def summary(res):
    s = res.stats
    return (res.status, res.verdict, res.exit_status, s.initial_states, s.states, s.transitions,
            s.max_depth, res.trace, res.final_state, res.bounds)


@pytest.mark.parametrize("program, kw", [
    (FISCHER, dict(invariants=[MUTEX], overrides=SMALL)),
    (RACE_NONATOMIC, dict(world=RACE_WORLD, blackbox="nondet", agents=3)),
    (RACE, dict(world=RACE_WORLD, agents=3, depth=25)),
])
def test_explore_is_deterministic(program, kw):
    assert summary(explore(program, **kw)) == summary(explore(program, **kw))


# ---------------------------------------------------------------------------
# time abstraction
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("program, kw", [
    (FISCHER, dict(invariants=[MUTEX], overrides=SMALL, depth=300)),
    (RACE_NONATOMIC, dict(world=RACE_WORLD, blackbox="nondet", depth=300)),
    (RACE, dict(world=RACE_WORLD, blackbox="straight", depth=300)),
    (RACE, dict(world=RACE_WORLD, blackbox="straight", depth=30)),
    (FISCHER, dict(overrides=SMALL, depth=40)),
])
def test_time_abstraction_preserves_verdicts(program, kw):
    on = explore(program, abstract_time=True, **kw)
    off = explore(program, abstract_time=False, **kw)
    assert on.model.abstract_time and not off.model.abstract_time
    assert on.status == off.status
    assert on.exit_status == off.exit_status
    assert on.bounds == off.bounds
    assert (on.violation is None) == (off.violation is None)
    if on.violation:
        for k in ("kind", "name", "line", "depth"):
            assert on.violation[k] == off.violation[k]
    assert on.stats.states <= off.stats.states


def test_time_abstraction_makes_fischer_finite():
    kw = dict(overrides={"k": "2", "cstime": "0"})
    on = explore(FISCHER, **kw)
    assert on.model.abstract_time
    assert on.status == "exhaustive" and on.exit_status == 0 and on.bounds == []
    off = explore(FISCHER, abstract_time=False, max_states=40_000, **kw)
    assert off.status == "bounded" and off.exit_status == 0
    assert off.bound_labels == ["max_states=40000"] and "max_states=40000" in off.verdict
    assert off.bounds == [Bound.MAX_STATES]
    assert off.stats.states > on.stats.states
    off2 = explore(FISCHER, abstract_time=False, depth=on.stats.max_depth + 50, **kw)
    assert off2.status == "bounded" and "depth=" in off2.verdict


def test_traces_show_real_time_under_abstraction():
    res = explore(FISCHER, invariants=[MUTEX], overrides=SMALL)
    times = [s["time"] for s in res.trace]
    assert times == sorted(times) and times[-1] > 0
    assert res.final_state["time"] >= times[-1]


# ---------------------------------------------------------------------------
# bounds name themselves
# ---------------------------------------------------------------------------

def test_depth_bound():
    res = explore(RACE, world=RACE_WORLD, depth=10)
    assert res.status == "bounded" and res.exit_status == 0
    assert res.bounds == [Bound.DEPTH]
    assert res.bound_labels == ["depth=10"] and "depth=10" in res.verdict
    assert res.stats.max_depth == 10
    assert "exhaustive" not in res.verdict


def test_depth_zero_explores_initial_states_only():
    res = explore(FISCHER, overrides=SMALL, depth=0)
    assert res.status == "bounded"
    assert res.stats.states == res.stats.initial_states == 4 and res.stats.transitions == 0


def test_max_states_bound():
    res = explore(RACE, world=RACE_WORLD, agents=3, max_states=100)
    assert res.status == "bounded" and res.exit_status == 0
    assert res.bound_labels == ["max_states=100"] and "max_states=100" in res.verdict
    assert 100 <= res.stats.states < 130


def test_max_time_bound():
    res = explore(FISCHER, overrides=SMALL, max_time=3, invariants=["time <= 3"])
    assert res.model.abstract_time is False
    assert res.status == "bounded" and res.exit_status == 0
    assert res.bounds == [Bound.MODEL]
    assert res.bound_labels == ["max_time=3"] and "max_time=3" in res.verdict
    res2 = explore(FISCHER, overrides=SMALL, max_time=3, invariants=["time <= 2"])
    assert res2.status == "violation" and res2.final_state["time"] == 3


def test_violation_within_bounds_still_reported():
    res = explore(RACE_NONATOMIC, world=RACE_WORLD, blackbox="instant", depth=1000, max_time=50)
    assert res.status == "violation"


# ---------------------------------------------------------------------------
# --all, deadlocks
# ---------------------------------------------------------------------------

def test_find_all_reports_each_distinct_violation_once():
    res = explore(RACE_NONATOMIC, world=RACE_WORLD, blackbox="nondet", find_all=True)
    assert res.status == "violation" and res.exit_status == 1
    ids = [(v.kind, v.name, v.line, v.column) for v in res.violations]
    assert len(ids) == len(set(ids))
    assert any(v.kind == "stuck" and "remove" in v.message for v in res.violations)
    one = explore(RACE_NONATOMIC, world=RACE_WORLD, blackbox="nondet")
    assert res.violations[0].message == one.violation.message
    assert res.violations[0].trace == one.trace
    # every violation comes with its own shortest trace to a violating state
    for v in res.violations:
        assert v.depth == len(v.trace)


def test_find_all_with_several_kinds_and_invariants():
    res = explore(ASSERT_PROG, blackbox="instant", find_all=True,
                  invariants=["forall i: steps[i] <= 5", "N == 2", "steps[0] <= 0"])
    kinds = Counter(v["kind"] for v in res.violations)
    assert kinds["assert"] == 1
    assert kinds["deadlock"] == 1
    names = [v["name"] for v in res.violations if v["kind"] == "invariant"]
    assert names == ["steps[0] <= 0"]      # the others hold
    assert res.violations[0]["name"] == "steps[0] <= 0"      # BFS order: depth 3 first
    depths = [v["depth"] for v in res.violations]
    assert depths == sorted(depths)
    assert "more distinct violation" in res.verdict


def test_deadlock_detected_and_can_be_turned_off():
    """Agent 1 fails its assertion with budget left: it is stuck and blocks
    the clock, agent 0 can do nothing more: a deadlock after the assert."""
    on = explore(ASSERT_PROG, blackbox="instant", find_all=True)
    assert [v["kind"] for v in on.violations] == ["assert", "deadlock"]
    dl = on.violations[1]
    assert "deadlock" in dl["message"] and "agent 0" in dl["message"]
    assert dl["depth"] == len(dl.trace) > on.violations[0]["depth"]
    off = explore(ASSERT_PROG, blackbox="instant", find_all=True, deadlock=False)
    assert [v["kind"] for v in off.violations] == ["assert"]
    assert off.status == "violation"


def test_assert_violation_is_first():
    res = explore(ASSERT_PROG, blackbox="instant")
    assert res.violation["kind"] == "assert" and res.violation["agent"] == 1
    assert res.violation["line"] == line_of(ASSERT_PROG, "assert(getAgentIndex() == 0 || steps < 2);")


# ---------------------------------------------------------------------------
# property language
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("prop, holds", [
    ("forall i: inCs[i] -> !wait[i]", True),
    ("forall i: c1[i] <= waitTime[i]", True),
    ("forall i: exists j: id[j] == i", True),
    ("N == 2", True),
    ("exists i: !inCs[i]", False),
    ("inCs[0] -> reqid == 0", False),
    ("N == 3", False),
    ("reqid == -1 || reqid == 0 || reqid == 1", True),
])
def test_property_language_on_fischer(prop, holds):
    res = explore(FISCHER, invariants=[prop], overrides=SMALL)
    assert res.status == ("exhaustive" if holds else "violation"), res.verdict
    assert res.exit_status == (0 if holds else 1)
    if not holds:
        assert res.violation["name"] == prop


@pytest.mark.parametrize("prop, holds", [
    ("pos[0].x == 0", False),
    ("forall i: pos[i].y <= 7", True),
    ("exists i: Pick[i]", False),
    ("count(Pick) >= 0", True),
    ("size(dests) <= 3", True),
    ("isEmpty(dests) -> forall i: !Pick[i] || size(dests) == 0", True),
])
def test_property_language_on_race(prop, holds):
    res = explore(RACE, world=RACE_WORLD, blackbox="straight", invariants=[prop])
    assert res.status == ("exhaustive" if holds else "violation"), res.verdict


def test_property_time_and_pos():
    res = explore(RACE, world=RACE_WORLD, blackbox="straight", invariants=["time <= 5"])
    assert res.model.abstract_time is False
    assert res.status == "violation" and res.final_state["time"] == 6
    res = explore(RACE, world=RACE_WORLD, blackbox="straight",
                  invariants=["time >= 4 -> pos[0].x > 0"])
    assert res.status == "exhaustive"


def test_property_typo_is_a_user_error():
    with pytest.raises(PcclError) as info:
        explore(FISCHER, invariants=["count(inCS) <= 1"])
    text = info.value.render()
    assert ": error: " in text and "^" in text and "inCS" in text
    assert info.value.exit_status == 2


@pytest.mark.parametrize("prop", ["count(inCs <= 1", "foo[0]", "inCs", "forall: inCs[0]",
                                  "count(reqid) <= 1"])
def test_bad_properties_are_user_errors(prop):
    with pytest.raises(PcclError) as info:
        explore(FISCHER, invariants=[prop], overrides=SMALL, depth=1)
    assert ": error: " in info.value.render()


def test_program_invariant_section_is_checked(tmp_path):
    src = Path(FISCHER).read_text() + "\ninvariant:\n  mutex: count(inCs) <= 1;\n"
    p = tmp_path / "fischer_inv.pccl"
    p.write_text(src)
    res = explore(str(p), overrides=SMALL)
    assert res.status == "violation" and res.violation["name"] == "mutex"
    assert res.violation["line"] == len(src.splitlines())


# ---------------------------------------------------------------------------
# the explorer against a plain breadth-first search over the model
# ---------------------------------------------------------------------------

def plain_bfs(m, max_depth=None):
    """(number of states, transitions, {depth of first violating state by kind})."""
    level = []
    seen = set()
    for s in m.init_states():
        if m.key(s) not in seen:
            seen.add(m.key(s))
            level.append(s)
    first, depth, transitions = {}, 0, 0
    while level:
        nxt = []
        for s in level:
            for v in m.violations(s):
                first.setdefault(v.kind, depth)
            if max_depth is not None and depth >= max_depth:
                continue
            out = m.successors(s)
            transitions += len(out)
            for _, s2 in out:
                k = m.key(s2)
                if k not in seen:
                    seen.add(k)
                    nxt.append(s2)
        level, depth = nxt, depth + 1
    return len(seen), transitions, first


@pytest.mark.parametrize("program, kw", [
    (RACE, dict(world=RACE_WORLD, blackbox="straight", agents=3)),
    (RACE_NONATOMIC, dict(world=RACE_WORLD, blackbox="straight")),
    (FISCHER, dict(overrides=SMALL)),
    (str(TEST_PROGRAMS / "eng_lock.pccl"), dict(blackbox="instant")),
])
@pytest.mark.parametrize("reduce", ["none", "auto"])
def test_explorer_counts_match_plain_bfs(program, kw, reduce):
    # the explorer and a plain BFS over the same (reduced or not) model agree
    res = explore(program, reduce=reduce, **kw)
    assert res.status == "exhaustive"
    n, t, first = plain_bfs(make_model(program, reduce=reduce, **kw))
    assert first == {}
    assert (res.stats.states, res.stats.transitions) == (n, t)


@pytest.mark.parametrize("program, kw", [
    (RACE_NONATOMIC, dict(world=RACE_WORLD, blackbox="nondet", agents=3)),
    (RACE_NONATOMIC, dict(world=RACE_WORLD, blackbox="instant")),
    (FISCHER, dict(overrides=SMALL, invariants=[MUTEX])),
])
def test_counterexample_is_shortest(program, kw):
    res = explore(program, **kw)
    assert res.status == "violation"
    _, _, first = plain_bfs(make_model(program, reduce="none", **kw),
                            max_depth=res.violation["depth"])
    assert first[res.violation["kind"]] == res.violation["depth"] == len(res.trace)


def test_collisions_checked_when_asked():
    res = explore(RACE, world=RACE_WORLD, blackbox="instant", collisions=True)
    assert res.status == "violation" and res.violation["kind"] == "collision"
    pos = [a["position"] for a in res.final_state["agents"]]
    assert pos[0][:2] == pos[1][:2] == [4.0, 0.0]
    off = explore(RACE, world=RACE_WORLD, blackbox="instant", find_all=True, deadlock=False)
    assert off.violations and all(v["kind"] != "collision" for v in off.violations)


def test_properties_over_allread_variables():
    prog = str(TEST_PROGRAMS / "eng_flags.pccl")
    ok = explore(prog, blackbox="instant",
                 invariants=["count(up) <= N", "forall i: up[i] -> n[i] > 0",
                             "exists i: !up[i] || n[i] >= 1"])
    assert ok.status == "exhaustive", ok.verdict
    bad = explore(prog, blackbox="instant", invariants=["count(up) <= 1"])
    assert bad.status == "violation" and len(bad.trace) == bad.violation["depth"]
    st = bad.final_state["agents"]
    assert [a["variables"]["up"] for a in st] == [True, True]


ABS_MAXTIME = str(TEST_PROGRAMS / "eng_abs_maxtime.pccl")


def test_max_time_violation_found_without_abstraction():
    res = explore(ABS_MAXTIME, agents=1, blackbox="instant", max_time=3)
    assert res.model.abstract_time is False
    assert res.status == "violation" and res.violation["kind"] == "assert"
    assert res.final_state["time"] == 3


def test_forced_time_abstraction_with_max_time_is_refused_or_sound():
    try:
        res = explore(ABS_MAXTIME, agents=1, blackbox="instant", max_time=3, abstract_time=True)
    except PcclError:
        return
    assert res.status == "violation", res.verdict


# ---------------------------------------------------------------------------
# counterexample steps (docs/language.md §10: numbered steps with time, agent, rule,
# event, source line and the variables changed)
# ---------------------------------------------------------------------------

def test_counterexample_steps_have_the_promised_fields():
    res = explore(RACE_NONATOMIC, world=RACE_WORLD, blackbox="nondet")
    for n, s in enumerate(res.trace, 1):
        assert s.step == n
        # the trace format's step (version 2: index for step, plus column and branch)
        assert {"index", "time", "agent", "rule", "event", "line", "column", "source", "branch",
                "changes"} == set(s.to_json()) - {"outcome"}
        assert isinstance(s, StepView)
        if s.rule in ("TIME ADVANCE", "DOREACH INVOKE"):
            assert s.agent is None
        else:
            assert s.agent in (0, 1)
        if s.rule in ("STATEMENT", "DOREACH UPDATE", "EXIT", "LOCK REQUEST"):
            assert s.line and s.source and s.event in ("PickDest", "Remove")
    stmt_lines = Path(RACE_NONATOMIC).read_text().splitlines()
    for s in res.trace:
        if s.rule == "STATEMENT":
            assert stmt_lines[s.line - 1].strip() == s.source


def test_counterexample_line_and_source_agree():
    res = explore(RACE_NONATOMIC, world=RACE_WORLD, blackbox="nondet")
    lines = Path(RACE_NONATOMIC).read_text().splitlines()
    for s in res.trace:
        if s["line"]:
            assert lines[s["line"] - 1].strip() == s["source"], s
