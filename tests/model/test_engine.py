"""Engine and runner acceptance cases (issue 3): ``pccl.api.run`` on the
paper's programs, the paper's Fischer run driven by a hand-made schedule,
determinism, and ``--max-steps``; plus model-interface properties (key,
terminal kinds, initial states)."""

from __future__ import annotations

from pathlib import Path

import pytest

from pccl.output import display as D
from pccl.api import explore_model, make_model, run
from pccl.model.engine import Model

from conftest import (AGS, DISCRETE, EXITED, FISCHER, RACE, RACE_NONATOMIC, RACE_WORLD, STATUS,
                      TEST_PROGRAMS, model_of, shared, var)
from pccl.model.layout import PHASE, POS, TIME, with_agents, with_counter, with_pc, with_status

LOOP = str(TEST_PROGRAMS / "eng_loop.pccl")
ASSERT_PROG = str(TEST_PROGRAMS / "eng_assert.pccl")


def line_of(path, text) -> int:
    lines = Path(path).read_text().splitlines()
    (n,) = [k + 1 for k, ln in enumerate(lines) if ln.strip() == text]
    return n


# ---------------------------------------------------------------------------
# (a) race.pccl runs to a clean final state
# ---------------------------------------------------------------------------

def test_run_race_ends_final_with_dests_empty():
    res = run(RACE, world=RACE_WORLD)
    assert res.status == "final" and res.exit_status == 0
    m = res.model
    assert all(ag[STATUS] == EXITED for ag in res.final[AGS])
    assert shared(m, res.final, "dests") == ()
    assert res.violations == []
    # the destinations were visited: agent 0 ends on the last one it raced for
    assert res.final[TIME] > 0


def test_run_race_three_agents_lays_out_missing_start():
    res = run(RACE, world=RACE_WORLD, agents=3)
    assert res.status == "final" and res.exit_status == 0
    m = res.model
    assert m.N == 3 and len(res.final[AGS]) == 3
    assert all(ag[STATUS] == EXITED for ag in res.final[AGS])
    assert shared(m, res.final, "dests") == ()
    starts = [ag[POS] for ag in res.summary[0][1][AGS]]
    assert starts[0] == (0.0, 0.0, 0.0) and starts[1] == (-5.0, 1.0, 0.0)
    assert starts[2] not in starts[:2]          # laid out automatically, apart


# ---------------------------------------------------------------------------
# (b) race_nonatomic under instant: some seed gets an agent stuck on remove
# ---------------------------------------------------------------------------

def test_run_race_nonatomic_instant_some_seed_stuck_on_remove():
    remove_line = line_of(RACE_NONATOMIC, "remove(dests, currentDest);")
    found = None
    for seed in range(60):
        res = run(RACE_NONATOMIC, world=RACE_WORLD, blackbox="instant", seed=seed)
        stuck = [v for v in res.violations if v.kind == "stuck"]
        if stuck and "remove" in stuck[0].message:
            found = (seed, res, stuck[0])
            break
    assert found is not None, "no seed in 0..59 gets an agent stuck on remove"
    seed, res, v = found
    assert res.status == "violation" and res.exit_status == 1
    assert v.span is not None and v.span.line == remove_line
    ag = res.final[AGS][v.agent]
    assert ag[STATUS] >= 2
    text = D.status_text(res.model, ag[STATUS])
    assert "remove" in text and f"line {remove_line}" in text


def test_run_race_nonatomic_straight_is_clean():
    res = run(RACE_NONATOMIC, world=RACE_WORLD, blackbox="straight")
    assert res.status == "final" and res.exit_status == 0


# ---------------------------------------------------------------------------
# (c) the paper's Fischer run (Section 5.1)
# ---------------------------------------------------------------------------

def paper_rand(n, agent, span):
    """waitTime = rand(10): 6 for agent 0, 3 for agent 1 (the paper's MMap);
    cstime = rand(5): 3 and 5 (also the paper's; the program ignores it)."""
    if n == 10:
        return 6 if agent == 0 else 3
    return 3 if agent == 0 else 5


@pytest.fixture(scope="module")
def fischer_paper_model():
    return make_model(FISCHER, rand_policy=paper_rand, abstract_time=False)


def both_in_cs(m, st):
    return var(m, st, 0, "inCs") is True and var(m, st, 1, "inCs") is True


def drive(m, st, choose, until, limit=2000):
    """Follow a schedule: ``choose(labels) -> index``; stop when ``until(st)``."""
    hist = [st]
    for _ in range(limit):
        if until(st):
            return hist
        out = m.successors(st)
        assert out, "schedule ran into a terminal state"
        labs = [l for l, _ in out]
        # every successor has its own label: choosing by label is well defined
        assert len(set(labs)) == len(labs)
        st = out[choose(labs)][1]
        hist.append(st)
    raise AssertionError("schedule did not reach the goal")


def last_discrete_at(hist, t):
    """The last state of time step t (after every agent's event ran)."""
    return [s for s in hist if s[TIME] == t and s[PHASE] == DISCRETE][-1]


def test_fischer_paper_initial_state(fischer_paper_model):
    m = fischer_paper_model
    (st,) = m.init_states()
    assert [var(m, st, i, "waitTime") for i in (0, 1)] == [6, 3]
    assert [var(m, st, i, "cstime") for i in (0, 1)] == [3, 5]
    assert shared(m, st, "reqid") == -1 and shared(m, st, "k") == 10 and shared(m, st, "d") == 2


def test_fischer_paper_schedule_both_in_cs_at_time_11(fischer_paper_model):
    """Schedule: agent 1 moves first whenever it can, then agent 0, then the
    system rules.  This is the paper's run: agent 1 checks reqid at time 8
    before agent 0 overwrites it, and agent 0 enters at time 11."""
    m = fischer_paper_model
    (st,) = m.init_states()
    prio = {1: 0, 0: 1, None: 2}
    hist = drive(m, st, lambda labs: min(range(len(labs)), key=lambda k: prio[labs[k][1]]),
                 lambda s: s[TIME] == 11 and both_in_cs(m, s))
    end = hist[-1]
    assert end[0] == 11 and both_in_cs(m, end)
    # the paper's MMap at time 11: reqid 0, agent 1 at c3 = 3, agent 0 just entered
    assert shared(m, end, "reqid") == 0
    assert var(m, end, 1, "c3") == 3 and var(m, end, 0, "c3") == 0
    assert not any(var(m, end, i, n) for i in (0, 1) for n in ("start", "wait", "assign", "delay"))
    # time 0: both executed Start
    t0 = last_discrete_at(hist, 0)
    assert var(m, t0, 0, "start") is False and var(m, t0, 1, "start") is False
    assert var(m, t0, 0, "wait") is True and var(m, t0, 1, "wait") is True
    # time 4: agent 1 is in Assign (assign true), agent 0 waits with c1 = 4 < 6
    t4 = last_discrete_at(hist, 4)
    assert var(m, t4, 1, "assign") is True
    assert var(m, t4, 0, "c1") == 4 and var(m, t4, 0, "wait") is True
    assert var(m, t4, 0, "assign") is False
    # no state before time 11 has both agents in the critical section
    assert not any(both_in_cs(m, s) for s in hist[:-1])
    # the whole run: one event per agent per time step (n0 = 1)
    assert [s[TIME] for s in hist].count(11) >= 1 and hist[-1][TIME] == 11


def test_fischer_paper_shortest_schedule_by_search():
    """BFS over the fixed initial state, time bounded by 11, for a state at
    time 11 with both agents in the critical section; then replay its labels."""
    m = make_model(FISCHER, rand_policy=paper_rand, max_time=11,
                   invariants=["!(time == 11 && inCs[0] && inCs[1])"])
    assert m.abstract_time is False
    res = explore_model(m)
    assert res.status == "violation" and res.exit_status == 1
    raw = list(res.counterexamples[0].trace)
    end = raw[-1][1]
    assert end[0] == 11 and both_in_cs(m, end) and shared(m, end, "reqid") == 0
    hist = [s for _, s in raw]
    t0, t4 = last_discrete_at(hist, 0), last_discrete_at(hist, 4)
    assert not var(m, t0, 0, "start") and not var(m, t0, 1, "start")
    assert var(m, t4, 1, "assign") is True and var(m, t4, 0, "c1") == 4
    # replay the schedule by labels on a fresh model: same end state
    m2 = make_model(FISCHER, rand_policy=paper_rand, max_time=11)
    (st,) = m2.init_states()
    for label, _ in raw[1:]:
        (st,) = [s for l, s in m2.successors(st) if l == label]
    assert st == end


# ---------------------------------------------------------------------------
# (d) determinism
# ---------------------------------------------------------------------------

def trace_of(res):
    return [(st.label, st.before, st.after) for st in res.trace.steps]


@pytest.mark.parametrize("program, kw", [
    (RACE, dict(world=RACE_WORLD)),
    (RACE_NONATOMIC, dict(world=RACE_WORLD, blackbox="instant")),
    (FISCHER, dict(max_time=30)),
])
def test_same_seed_same_run(program, kw):
    a = run(program, seed=11, record_trace=True, **kw)
    b = run(program, seed=11, record_trace=True, **kw)
    assert a.status == b.status and a.steps == b.steps and a.message == b.message
    assert a.final == b.final
    assert trace_of(a) == trace_of(b)
    assert a.summary == b.summary


def test_different_seeds_can_differ():
    traces = set()
    for seed in range(8):
        res = run(RACE, world=RACE_WORLD, seed=seed, record_trace=True)
        assert res.status == "final"
        traces.add(res.trace.labels)
    assert len(traces) > 1


def test_seed_drives_rand_in_run():
    vals = set()
    for seed in range(12):
        res = run(FISCHER, seed=seed, max_time=1)
        m = res.model
        vals.add((var(m, res.final, 0, "waitTime"), var(m, res.final, 1, "waitTime")))
    assert len(vals) > 1
    assert all(0 <= a <= 10 and 0 <= b <= 10 for a, b in vals)


# ---------------------------------------------------------------------------
# (e) --max-steps
# ---------------------------------------------------------------------------

def test_max_steps_stops_looping_agent():
    res = run(LOOP, blackbox="instant", max_steps=300)
    assert res.status == "max-steps" and res.exit_status == 1
    assert res.looping_agent == 1
    assert "agent 1" in res.message
    assert "line 14" in res.message            # the loop's body, `n = n + 1;`
    assert res.final[TIME] == 0                     # time never advanced
    assert var(res.model, res.final, 1, "n") > 100


def test_max_steps_message_reads_well():
    res = run(LOOP, blackbox="instant", max_steps=300)
    assert "at at" not in res.message


def test_max_steps_not_hit_by_ordinary_runs():
    res = run(RACE, world=RACE_WORLD, max_steps=60)
    assert res.status == "final"


# ---------------------------------------------------------------------------
# other runner outcomes
# ---------------------------------------------------------------------------

def test_run_bounded_by_max_time():
    res = run(FISCHER, seed=3, max_time=7)
    assert res.status == "bounded" and res.exit_status == 0
    assert res.final[TIME] == 7


def test_run_failed_assertion_is_a_violation():
    res = run(ASSERT_PROG, blackbox="instant")
    assert res.status == "violation" and res.exit_status == 1
    (v,) = res.violations
    assert v.kind == "assert" and v.agent == 1
    assert v.span.line == line_of(ASSERT_PROG, "assert(getAgentIndex() == 0 || steps < 2);")


def test_run_with_rates_runs_event_block_per_rate():
    prog = """
        loc:
          int n = 0;
        Tick():
          pre(true);
          eff:
            n = n + 1;
        """
    from pccl.tools.runner import run as run_model
    import random
    m = model_of(prog, n0=2, rates={1: 2}, max_time=5, abstract_time=False,
                 rand_policy=lambda n, a, s: 0)
    res = run_model(m, seed=1, record_trace=True, rng=random.Random(1))
    assert res.status == "bounded"
    per = {}
    for st in res.trace.steps:
        l, before = st.label, st.before
        if l[0] == "EVENT SELECT":
            per.setdefault((before[TIME], l[1]), 0)
            per[(before[TIME], l[1])] += 1
    # time steps 0..5 (the last one runs its events, then --max-time stops time)
    assert sorted(per) == [(t, i) for t in range(6) for i in (0, 1)]
    for t in range(6):
        assert per[(t, 0)] == 2 and per[(t, 1)] == 1
    assert var(m, res.final, 0, "n") == 12 and var(m, res.final, 1, "n") == 6


def test_run_summary_one_entry_per_time_step():
    res = run(RACE, world=RACE_WORLD)
    times = [t for t, _ in res.summary]
    assert times == list(range(len(times)))
    assert times[-1] == res.final[TIME]


# ---------------------------------------------------------------------------
# the model interface
# ---------------------------------------------------------------------------

def test_init_states_deterministic_and_distinct():
    m = make_model(FISCHER, overrides={"k": "2"}, reduce="none")
    a, b = list(m.init_states()), list(m.init_states())
    assert a == b
    assert len(a) == len(set(a)) == 3 * 3 * 6 * 6
    # under dead, the cstime nobody reads takes one value: 3 * 3 waitTimes
    m = make_model(FISCHER, overrides={"k": "2"})
    assert "dead" in m.reduction.on and len(set(m.init_states())) == 3 * 3


def test_key_hashable_and_stable_and_abstracts_time():
    m = make_model(RACE, world=RACE_WORLD)
    assert m.abstract_time is True
    (st,) = m.init_states()
    later = (5,) + st[1:]
    assert hash(m.key(st)) == hash(m.key(st)) and m.key(st) == m.key(later)
    m2 = make_model(RACE, world=RACE_WORLD, abstract_time=False)
    (st2,) = m2.init_states()
    assert m2.key(st2) != m2.key((5,) + st2[1:])


def test_time_abstraction_refused_when_property_reads_time():
    from pccl.lang.errors import PcclError
    with pytest.raises(PcclError):
        make_model(RACE, world=RACE_WORLD, abstract_time=True, invariants=["time < 100"])
    m = make_model(RACE, world=RACE_WORLD, invariants=["time < 100"])
    assert m.abstract_time is False
    m = make_model(RACE, world=RACE_WORLD, max_time=10)
    assert m.abstract_time is False


def test_exact_and_fingerprint_exploration_agree():
    a = explore_model(make_model(RACE, world=RACE_WORLD, agents=3), exact=True)
    b = explore_model(make_model(RACE, world=RACE_WORLD, agents=3), exact=False)
    assert a.status == b.status == "exhaustive"
    assert (a.stats.states, a.stats.transitions, a.stats.max_depth) == \
        (b.stats.states, b.stats.transitions, b.stats.max_depth)


def test_every_reachable_terminal_state_of_race_is_final():
    m = make_model(RACE, world=RACE_WORLD)
    (st,) = m.init_states()
    seen, todo, terminals = {m.key(st)}, [st], 0
    while todo:
        s = todo.pop()
        out = m.successors(s)
        if not out:
            terminals += 1
            assert m.terminal_kind(s) == "final"
            assert shared(m, s, "dests") == ()
        for _, s2 in out:
            k = m.key(s2)
            if k not in seen:
                seen.add(k)
                todo.append(s2)
    assert terminals >= 1


def test_deadlock_violation_names_waiting_agents():
    m = make_model(ASSERT_PROG, blackbox="instant")
    (st,) = m.init_states()
    # agent 1 stuck with budget left blocks time; agent 0 has done its step
    stuck = m.stuck_code("assert", "assertion failed", None)
    ags = list(st[AGS])
    ags[0] = with_counter(with_pc(ags[0], m.ctl.empty_pc), 1)
    ags[1] = with_status(ags[1], stuck)
    st = with_agents(st, tuple(ags))
    assert m.successors(st) == []
    assert m.terminal_kind(st) == "deadlock"
    v = m.deadlock_violation(st)
    assert v.kind == "deadlock" and "agent 0" in v.message and "agent 1" not in v.message


def test_model_rejects_bad_parameters():
    from pccl.lang.errors import PcclError
    for kw in (dict(agents=0), dict(delta=0), dict(n0=0), dict(events="some")):
        with pytest.raises(PcclError):
            make_model(RACE, world=RACE_WORLD, **kw)


def test_model_is_a_model():
    assert isinstance(make_model(RACE), Model)


def test_fractional_delta_reaches_max_time():
    res = run(RACE, world=RACE_WORLD, delta=0.1, max_time=0.3)
    assert res.status == "bounded"
    assert len(res.summary) == 4                 # t = 0, 0.1, 0.2, 0.3
    assert res.final[TIME] == pytest.approx(0.3)


def test_fractional_delta_advances_time():
    res = run(RACE, world=RACE_WORLD, delta=0.5, max_time=2)
    assert [t for t, _ in res.summary] == [0, 0.5, 1.0, 1.5, 2.0]
    assert res.status == "bounded" and res.final[TIME] == 2.0


OFF_GRID_WORLD = """
agents = 2
resolution = 0.01
start = [[0.003, 0], [2, 1.0049]]
"""


def test_stationary_agent_keeps_its_position(tmp_path):
    w = tmp_path / "w.toml"
    w.write_text(OFF_GRID_WORLD)
    m = make_model(str(TEST_PROGRAMS / "eng_move1.pccl"), world=str(w), blackbox="instant")
    (st,) = m.init_states()
    start = st[AGS][0][POS]
    for _ in range(40):
        out = m.successors(st)
        if not out:
            break
        _, st = out[-1]
        assert st[AGS][0][POS] == start, "agent 0 never moves"
    assert st[AGS][1][POS] == (3.0, 3.0, 0.0)


def test_positions_after_environment_step_are_rounded(tmp_path):
    w = tmp_path / "w.toml"
    w.write_text(OFF_GRID_WORLD)
    m = make_model(str(TEST_PROGRAMS / "eng_move1.pccl"), world=str(w), blackbox="straight")
    (st,) = m.init_states()
    for _ in range(60):
        out = m.successors(st)
        if not out:
            break
        label, st = out[-1]
        if label[0] == "DOREACH INVOKE":
            for ag in st[AGS]:
                assert ag[POS] == m.round_pos(ag[POS])
