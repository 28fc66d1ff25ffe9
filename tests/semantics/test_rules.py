"""One test per rewrite rule (docs/language.md §11): enabled on a hand-built configuration
with exactly the expected successor, and disabled when its condition fails.

Configurations are built from a tiny program's initial state by editing the
tuples (pc via ``model.ctl.intern``, counters, lockState, lockQueue, phase);
see ``conftest.py`` for the helpers.
"""

from __future__ import annotations

import itertools

import pytest

from pccl.output import display as D
from pccl.output import codec as C
from pccl.model.layout import AEND, END, acq
from pccl.lang.errors import PcclError

from conftest import (AGS, CNT, DISCRETE, DYNAMIC, EXITED, IDLE, LCK, LOCK, PC, POS, REACH,
                      REQUEST, RUNNING, STATUS, agent_rules, k_of, k_pc, labels, model_of, only,
                      set_agent, set_state, sid, succ, var)
from pccl.model.layout import DONE, LQ, PHASE, T0, TARGET, TIME

# Every statement form, each on a line of its own with unique text, so that
# `sid(m, text)` finds it.
PROG = """
allwrite:
  int s = 0;
  List<int> xs = [1, 2];
allread:
  int a = 5;
loc:
  int x = 0;
  bool go = true;
  List<int> ys = [];
  ObstacleList obs = getObs();

A():
  pre(go);
  eff:
    x = x + 1;
    if (x == 1):
      x = 10;
    else if (x == 2):
      x = 20;
    else:
      x = 30;
    while (x < 3):
      x = x + 2;
    add(ys, 7);
    remove(xs, 1);
    assert(x > 0);
    skip;
    atomic:
      s = s + 1;
      atomic:
        s = s + 2;
    doReach(ItemPosition(1, 2), obs);
    exit();

B():
  pre(go && x >= 0);
  eff:
    skip;

C():
  pre(!go && x == 99);
  eff:
    x = 98;
"""


@pytest.fixture(scope="module")
def m():
    return model_of(PROG)


@pytest.fixture(scope="module")
def st0(m):
    (st,) = m.init_states()
    return st


def event_k(m, e):
    return tuple(s.sid for s in m.program.events[e].body) + (END,)


def test_initial_configuration(m, st0):
    # language.md §11, Initialisation: time 0, counters 0, discrete, empty queue, k empty
    assert st0[TIME] == 0 and st0[PHASE] == DISCRETE and st0[LQ] == ()
    for i, ag in enumerate(st0[AGS]):
        assert k_of(m, ag) == ()
        assert ag[CNT] == 0 and ag[LCK] == IDLE and ag[STATUS] == RUNNING
        assert var(m, st0, i, "x") == 0 and var(m, st0, i, "go") is True
        assert var(m, st0, i, "ys") == ()
        assert ag[REACH][TARGET] is None and ag[REACH][DONE:] == (False, False, ())
    assert var(m, st0, 0, "s") == 0 and var(m, st0, 0, "xs") == (1, 2)


# ---------------------------------------------------------------------------
# EVENT SELECT / IDLE
# ---------------------------------------------------------------------------

def test_event_select_any_offers_every_enabled_event(m, st0):
    out = succ(m, st0, agent=0)
    assert [l for l, _ in out] == [("EVENT SELECT", 0, 0), ("EVENT SELECT", 0, 1)]
    for (_l, s), e in zip(out, (0, 1)):
        assert s == set_agent(m, st0, 0, pc=k_pc(m, *event_k(m, e)))


def test_event_select_first_takes_first_enabled_in_source_order():
    mf = model_of(PROG, events="first")
    (st,) = mf.init_states()
    out = succ(mf, st, agent=0)
    assert [l for l, _ in out] == [("EVENT SELECT", 0, 0)]
    assert out[0][1] == set_agent(mf, st, 0, pc=k_pc(mf, *event_k(mf, 0)))
    # A disabled: B is the first enabled event
    mf2 = model_of(PROG.replace("pre(go);", "pre(go && x < 0);"), events="first")
    (st2,) = mf2.init_states()
    assert [l for l, _ in succ(mf2, st2, agent=0)] == [("EVENT SELECT", 0, 1)]
    # only C enabled: it is chosen although it is last
    st3 = set_agent(mf, st, 0, go=False, x=99)
    out3 = succ(mf, st3, agent=0)
    assert [l for l, _ in out3] == [("EVENT SELECT", 0, 2)]
    assert out3[0][1] == set_agent(mf, st3, 0, pc=k_pc(mf, *event_k(mf, 2)))


def test_event_select_disabled_when_budget_spent(m, st0):
    st = set_agent(m, st0, 0, counter=1)       # counter + 1 > n0 = 1
    assert labels(m, st, agent=0) == []
    m2 = model_of(PROG, n0=2)
    (s2,) = m2.init_states()
    s2 = set_agent(m2, s2, 0, counter=1)       # 1 + 1 <= 2: still enabled
    assert {l[0] for l in labels(m2, s2, agent=0)} == {"EVENT SELECT"}
    s2 = set_agent(m2, s2, 0, counter=2)
    assert labels(m2, s2, agent=0) == []


def test_event_select_disabled_unless_k_empty(m, st0):
    st = set_agent(m, st0, 0, pc=k_pc(m, sid(m, "skip"), END))
    assert agent_rules(m, st, 0) == ["STATEMENT"]


def test_idle_when_no_guard_holds(m, st0):
    st = set_agent(m, st0, 0, go=False)        # A, B disabled; C needs x == 99
    assert only(m, st, "IDLE", 0) == (("IDLE", 0, None), set_agent(m, st, 0, pc=k_pc(m, END)))
    assert agent_rules(m, st, 0) == ["IDLE"]


def test_idle_disabled_when_some_guard_holds_or_budget_spent(m, st0):
    assert "IDLE" not in agent_rules(m, st0, 0)
    st = set_agent(m, st0, 0, go=False, counter=1)
    assert agent_rules(m, st, 0) == []


def test_event_select_idle_then_counter_advance_spends_one_execution(m, st0):
    st = set_agent(m, st0, 0, go=False)
    _, s1 = only(m, st, "IDLE", 0)
    _, s2 = only(m, s1, "COUNTER ADVANCE", 0)
    assert s2 == set_agent(m, st, 0, counter=1)


# ---------------------------------------------------------------------------
# STATEMENT
# ---------------------------------------------------------------------------

def at(m, st, i, *k, **kw):
    return set_agent(m, st, i, pc=k_pc(m, *k), **kw)


def test_statement_assignment(m, st0):
    a = sid(m, "x = x + 1")
    st = at(m, st0, 0, a, END, x=4)
    assert only(m, st, "STATEMENT", 0) == (("STATEMENT", 0, a), at(m, st0, 0, END, x=5))
    assert agent_rules(m, st, 0) == ["STATEMENT"]


def test_statement_assignment_to_shared_is_global(m, st0):
    # sequential consistency: the write is seen by every agent at once
    s1 = sid(m, "s = s + 1")
    st = at(m, st0, 0, s1, END)
    _, after = only(m, st, "STATEMENT", 0)
    assert var(m, after, 0, "s") == 1
    assert after == set_state(m, at(m, st0, 0, END), s=1)


@pytest.mark.parametrize("x, branch, value", [(1, "x = 10", 10), (2, "x = 20", 20),
                                              (5, "x = 30", 30)])
def test_statement_if_else_if_else(m, st0, x, branch, value):
    i = sid(m, "if (x == 1)")
    w = sid(m, "while")
    st = at(m, st0, 0, i, w, END, x=x)
    # one transition evaluates the conditions and leaves exactly that branch
    assert only(m, st, "STATEMENT", 0) == (("STATEMENT", 0, i),
                                           at(m, st0, 0, sid(m, branch), w, END, x=x))


def test_statement_if_without_else_and_false_condition_leaves_rest():
    mm = model_of("""
        loc:
          int x = 0;
        E():
          pre(true);
          eff:
            if (x > 0):
              x = 1;
            skip;
        """)
    (st,) = mm.init_states()
    i, sk = sid(mm, "if"), sid(mm, "skip")
    st = at(mm, st, 0, i, sk, END)
    assert only(mm, st, "STATEMENT", 0)[1] == at(mm, st, 0, sk, END)


def test_statement_while_true_runs_body_then_tests_again(m, st0):
    w, body = sid(m, "while"), sid(m, "x = x + 2")
    st = at(m, st0, 0, w, END, x=0)
    assert only(m, st, "STATEMENT", 0) == (("STATEMENT", 0, w), at(m, st0, 0, body, w, END, x=0))


def test_statement_while_false_exits_loop(m, st0):
    w, nxt = sid(m, "while"), sid(m, "add(ys")
    st = at(m, st0, 0, w, nxt, END, x=3)
    assert only(m, st, "STATEMENT", 0) == (("STATEMENT", 0, w), at(m, st0, 0, nxt, END, x=3))


def test_statement_while_one_test_per_transition(m, st0):
    w, body = sid(m, "while"), sid(m, "x = x + 2")
    st = at(m, st0, 0, w, END, x=0)
    seq = []
    for _ in range(10):
        out = succ(m, st, agent=0)
        assert len(out) == 1
        (l, st) = out[0]
        seq.append(l)
        if k_of(m, st[AGS][0]) == (END,):
            break
    # test (x=0), body, test (x=2), body, test (x=4): exit
    assert seq == [("STATEMENT", 0, w), ("STATEMENT", 0, body)] * 2 + [("STATEMENT", 0, w)]
    assert var(m, st, 0, "x") == 4


def test_statement_add(m, st0):
    a = sid(m, "add(ys")
    st = at(m, st0, 0, a, END, ys=(3,))
    assert only(m, st, "STATEMENT", 0) == (("STATEMENT", 0, a), at(m, st0, 0, END, ys=(3, 7)))


def test_statement_remove_removes_one_occurrence(m, st0):
    r = sid(m, "remove(xs")
    st = set_state(m, at(m, st0, 0, r, END), xs=(2, 1, 3, 1))
    assert only(m, st, "STATEMENT", 0) == (
        ("STATEMENT", 0, r), set_state(m, at(m, st0, 0, END), xs=(2, 3, 1)))


def test_statement_assert_true(m, st0):
    a = sid(m, "assert")
    st = at(m, st0, 0, a, END, x=1)
    assert only(m, st, "STATEMENT", 0) == (("STATEMENT", 0, a), at(m, st0, 0, END, x=1))
    assert m.violations(only(m, st, "STATEMENT", 0)[1]) == []


def test_statement_assert_false_gets_agent_stuck(m, st0):
    a = sid(m, "assert")
    st = at(m, st0, 0, a, END, x=0)
    (l, after) = only(m, st, "STATEMENT", 0)
    ag = after[AGS][0]
    assert ag[STATUS] >= 2 and ag[PC] == st[AGS][0][PC]
    assert set_agent(m, after, 0, status=RUNNING) == st       # nothing else changed
    (v,) = m.violations(after)
    assert v.kind == "assert" and v.agent == 0
    assert v.span.line == m.compiled.stmts[a].span.line
    assert succ(m, after, agent=0) == []


def test_statement_skip(m, st0):
    k = sid(m, "skip")
    st = at(m, st0, 0, k, END)
    assert only(m, st, "STATEMENT", 0) == (("STATEMENT", 0, k), at(m, st0, 0, END))


def test_statement_nested_atomic_runs_body_under_held_lock(m, st0):
    inner = sid(m, "atomic", 1)
    body = sid(m, "s = s + 2")
    st = set_state(m, at(m, st0, 0, inner, AEND, END, lock=LOCK), lq=(0,))
    assert agent_rules(m, st, 0) == ["STATEMENT"]
    assert only(m, st, "STATEMENT", 0) == (
        ("STATEMENT", 0, inner), set_state(m, at(m, st0, 0, body, AEND, END, lock=LOCK), lq=(0,)))


def test_statement_disabled_for_stuck_and_exited_agents(m, st0):
    st = at(m, st0, 0, sid(m, "skip"), END)
    stuck = set_agent(m, st, 0, status=m.stuck_code("error", "test", None))
    assert labels(m, stuck, agent=0) == []
    exited = set_agent(m, st, 0, status=EXITED)
    assert labels(m, exited, agent=0) == []


def test_statement_order_within_event_is_sequential(m, st0):
    # the event A's effect runs one statement per transition, in order
    st = at(m, st0, 0, *event_k(m, 0))
    seen = []
    for _ in range(40):
        out = succ(m, st, agent=0)
        if not out:
            break
        assert len(out) == 1
        (l, st) = out[0]
        seen.append(l[0])
    assert seen[:1] == ["STATEMENT"]
    assert "LOCK REQUEST" in seen and "ATOMIC EXECUTION" in seen and "LOCK RELEASE" in seen
    assert seen[-2:] == ["DOREACH UPDATE", "EXIT"]
    assert st[AGS][0][STATUS] == EXITED
    assert var(m, st, 0, "s") == 3 and var(m, st, 0, "xs") == (2,) and var(m, st, 0, "ys") == (7,)
    assert st[LQ] == () and st[AGS][0][LCK] == IDLE


# ---------------------------------------------------------------------------
# EXIT
# ---------------------------------------------------------------------------

def test_exit(m, st0):
    e = sid(m, "exit")
    st = at(m, st0, 0, e, END)
    assert only(m, st, "EXIT", 0) == (("EXIT", 0, e), set_agent(m, st0, 0, pc=k_pc(m), status=EXITED))
    assert agent_rules(m, st, 0) == ["EXIT"]


def test_exit_disabled_for_stuck_agent(m, st0):
    st = at(m, st0, 0, sid(m, "exit"), END, status=m.stuck_code("error", "x", None))
    assert labels(m, st, agent=0) == []


# ---------------------------------------------------------------------------
# DOREACH UPDATE
# ---------------------------------------------------------------------------

def test_doreach_update_resets_flags_sets_target_and_t0():
    mm = model_of(PROG, abstract_time=False)
    (st0,) = mm.init_states()
    d, e = sid(mm, "doReach"), sid(mm, "exit")
    old = ((9.0, 9.0, 0.0), (), 1, True, True, ())
    st = set_state(mm, at(mm, st0, 0, d, e, END, reach=old), time=3)
    new = ((1.0, 2.0, 0.0), (), 3, False, False, ())
    assert only(mm, st, "DOREACH UPDATE", 0) == (
        ("DOREACH UPDATE", 0, d), set_state(mm, at(mm, st0, 0, e, END, reach=new), time=3))


def test_doreach_update_under_time_abstraction_keeps_no_t0(m, st0):
    d, e = sid(m, "doReach"), sid(m, "exit")
    assert m.abstract_time
    st = set_state(m, at(m, st0, 0, d, e, END), time=7)
    _, after = only(m, st, "DOREACH UPDATE", 0)
    assert after[AGS][0][REACH] == ((1.0, 2.0, 0.0), (), None, False, False, ())
    assert k_of(m, after[AGS][0]) == (e, END)


def test_doreach_update_disabled_unless_head(m, st0):
    st = at(m, st0, 0, sid(m, "exit"), sid(m, "doReach"), END)
    assert "DOREACH UPDATE" not in agent_rules(m, st, 0)


# ---------------------------------------------------------------------------
# COUNTER ADVANCE
# ---------------------------------------------------------------------------

def test_counter_advance(m, st0):
    st = at(m, st0, 0, END)
    assert only(m, st, "COUNTER ADVANCE", 0) == (("COUNTER ADVANCE", 0, None),
                                                 set_agent(m, st0, 0, counter=1))


def test_counter_advance_disabled_when_budget_exceeded(m, st0):
    st = at(m, st0, 0, END, counter=1)        # counter + 1 > n0 = 1
    assert labels(m, st, agent=0) == []


def test_counter_advance_with_rate():
    mm = model_of(PROG, n0=2, rates={1: 2})
    (st,) = mm.init_states()
    s1 = at(mm, st, 1, END)
    assert only(mm, s1, "COUNTER ADVANCE", 1)[1] == set_agent(mm, st, 1, counter=2)
    s0 = at(mm, st, 0, END, counter=1)         # rate 1: 1 + 1 <= 2
    assert only(mm, s0, "COUNTER ADVANCE", 0)[1] == set_agent(mm, st, 0, counter=2)
    s1b = at(mm, st, 1, END, counter=1)        # rate 2: 1 + 2 > 2
    assert labels(mm, s1b, agent=1) == []


def test_rate_larger_than_n0_is_rejected():
    # counter 0 + 2 > n0 = 1: agent 1 could never run an event, and a search
    # would "explore clean" without it
    with pytest.raises(PcclError, match="above n0"):
        model_of(PROG, n0=1, rates={1: 2})


def test_bad_rates_are_rejected():
    with pytest.raises(PcclError):
        model_of(PROG, rates={5: 2})
    with pytest.raises(PcclError):
        model_of(PROG, rates={0: 0})


# ---------------------------------------------------------------------------
# Locking
# ---------------------------------------------------------------------------

def test_lock_request(m, st0):
    o = sid(m, "atomic")
    d = sid(m, "doReach")
    # agent 1 already holds the lock: the request is queued behind it
    base = set_agent(m, st0, 1, pc=k_pc(m, sid(m, "s = s + 1"), AEND, END), lock=LOCK)
    st = set_state(m, at(m, base, 0, o, d, END), lq=(1,))
    assert only(m, st, "LOCK REQUEST", 0) == (
        ("LOCK REQUEST", 0, o),
        set_state(m, at(m, base, 0, acq(o), AEND, d, END, lock=REQUEST), lq=(1, 0)))


def test_lock_request_on_empty_queue(m, st0):
    o = sid(m, "atomic")
    st = at(m, st0, 0, o, END)
    _, after = only(m, st, "LOCK REQUEST", 0)
    assert after[LQ] == (0,) and after[AGS][0][LCK] == REQUEST
    assert k_of(m, after[AGS][0]) == (acq(o), AEND, END)
    assert after[AGS][0][CNT] == 0


def test_lock_request_disabled_when_lock_held(m, st0):
    o = sid(m, "atomic")
    st = set_state(m, at(m, st0, 0, o, AEND, END, lock=LOCK), lq=(0,))
    assert "LOCK REQUEST" not in agent_rules(m, st, 0)
    assert all(s[LQ] == (0,) for _, s in succ(m, st, agent=0))


def waiting(m, st0, i=0, other_lq=(1, 0), counter=0):
    """Agent i requested the lock (atomic at line of `atomic`), agent 1-i holds it."""
    o = sid(m, "atomic")
    j = 1 - i
    st = set_agent(m, st0, j, pc=k_pc(m, sid(m, "s = s + 1"), AEND, END), lock=LOCK)
    st = at(m, st, i, acq(o), AEND, END, lock=REQUEST, counter=counter)
    return set_state(m, st, lq=other_lq), o


def test_atomic_wait(m, st0):
    st, o = waiting(m, st0)
    assert agent_rules(m, st, 0) == ["ATOMIC WAIT"]
    assert only(m, st, "ATOMIC WAIT", 0) == (("ATOMIC WAIT", 0, o), set_agent(m, st, 0, counter=1))


def test_atomic_wait_uses_rate():
    mm = model_of(PROG, n0=4, rates={0: 3})
    (st0,) = mm.init_states()
    st, o = waiting(mm, st0)
    assert only(mm, st, "ATOMIC WAIT", 0)[1] == set_agent(mm, st, 0, counter=3)
    st2 = set_agent(mm, st, 0, counter=2)      # 2 + 3 > 4
    assert labels(mm, st2, agent=0) == []


def test_atomic_wait_disabled_at_head_of_queue(m, st0):
    o = sid(m, "atomic")
    st = set_state(m, at(m, st0, 0, acq(o), AEND, END, lock=REQUEST), lq=(0, 1))
    assert agent_rules(m, st, 0) == ["ATOMIC EXECUTION"]


def test_atomic_wait_disabled_when_budget_spent(m, st0):
    st, _ = waiting(m, st0, counter=1)
    assert labels(m, st, agent=0) == []
    # the holder is not affected by the waiter's budget
    assert agent_rules(m, st, 1) == ["STATEMENT"]


def test_atomic_execution(m, st0):
    o = sid(m, "atomic")
    body = sid(m, "s = s + 1")
    st = set_state(m, at(m, st0, 0, acq(o), AEND, END, lock=REQUEST), lq=(0,))
    assert only(m, st, "ATOMIC EXECUTION", 0) == (
        ("ATOMIC EXECUTION", 0, o),
        set_state(m, at(m, st0, 0, body, sid(m, "atomic", 1), AEND, END, lock=LOCK), lq=(0,)))


def test_atomic_execution_does_not_need_budget(m, st0):
    # the counter does not increase, and the grant is possible with counter = n0
    o = sid(m, "atomic")
    st = set_state(m, at(m, st0, 0, acq(o), AEND, END, lock=REQUEST, counter=1), lq=(0, 1))
    _, after = only(m, st, "ATOMIC EXECUTION", 0)
    assert after[AGS][0][CNT] == 1 and after[AGS][0][LCK] == LOCK


def test_atomic_execution_disabled_unless_head(m, st0):
    st, _ = waiting(m, st0)
    assert "ATOMIC EXECUTION" not in agent_rules(m, st, 0)


def test_lock_release(m, st0):
    d = sid(m, "doReach")
    st = set_state(m, at(m, st0, 0, AEND, d, END, lock=LOCK), lq=(0, 1))
    assert only(m, st, "LOCK RELEASE", 0) == (
        ("LOCK RELEASE", 0, None), set_state(m, at(m, st0, 0, d, END, lock=IDLE), lq=(1,)))


def test_lock_release_disabled_without_lock(m, st0):
    st = at(m, st0, 0, AEND, END, lock=IDLE)
    assert labels(m, st, agent=0) == []


def test_lock_handover_order_follows_queue(m, st0):
    """Two agents request; the first in the queue gets the lock first, the
    second only after LOCK RELEASE."""
    o = sid(m, "atomic")
    st = at(m, at(m, st0, 0, o, END), 1, o, END)
    _, st = only(m, st, "LOCK REQUEST", 1)
    _, st = only(m, st, "LOCK REQUEST", 0)
    assert st[LQ] == (1, 0)
    assert agent_rules(m, st, 0) == ["ATOMIC WAIT"]
    assert agent_rules(m, st, 1) == ["ATOMIC EXECUTION"]
    _, st = only(m, st, "ATOMIC EXECUTION", 1)
    # run agent 1 to its LOCK RELEASE
    while k_of(m, st[AGS][1])[0] != AEND:
        ((_, st),) = succ(m, st, agent=1)
    _, st = only(m, st, "LOCK RELEASE", 1)
    assert st[LQ] == (0,)
    assert agent_rules(m, st, 0) == ["ATOMIC EXECUTION"]


# ---------------------------------------------------------------------------
# TIME ADVANCE
# ---------------------------------------------------------------------------

def all_done(m, st, counters=(1, 1)):
    for i, c in enumerate(counters):
        st = set_agent(m, st, i, counter=c)
    return st


def test_time_advance(m, st0):
    st = all_done(m, st0)
    assert labels(m, st) == [("TIME ADVANCE", None, None)]
    assert only(m, st, "TIME ADVANCE")[1] == set_state(m, st, time=1, phase=DYNAMIC)


@pytest.mark.parametrize("delta", [2, 0.5])
def test_time_advance_by_delta(delta):
    mm = model_of(PROG, delta=delta)
    (st,) = mm.init_states()
    st = set_state(mm, all_done(mm, st), time=3)
    assert only(mm, st, "TIME ADVANCE")[1][0] == 3 + delta


def test_time_advance_disabled_while_an_agent_has_budget(m, st0):
    st = all_done(m, st0, (1, 0))
    assert "TIME ADVANCE" not in [l[0] for l in labels(m, st)]


def test_time_advance_disabled_when_all_exited(m, st0):
    st = set_agent(m, set_agent(m, st0, 0, status=EXITED), 1, status=EXITED)
    assert labels(m, st) == []
    assert m.terminal_kind(st) == "final"


def test_time_advance_disabled_beyond_max_time():
    mm = model_of(PROG, max_time=3)
    (st,) = mm.init_states()
    st = all_done(mm, st)
    assert labels(mm, set_state(mm, st, time=2)) == [("TIME ADVANCE", None, None)]
    at3 = set_state(mm, st, time=3)
    assert labels(mm, at3) == []
    assert mm.terminal_kind(at3) == "bounded"


def test_stuck_agent_blocks_time(m, st0):
    stuck = m.stuck_code("error", "test", None)
    st = set_agent(m, all_done(m, st0, (1, 0)), 1, status=stuck)
    assert labels(m, st) == []
    assert m.terminal_kind(st) == "deadlock"
    # a stuck agent whose budget is spent does not block it
    st2 = set_agent(m, all_done(m, st0, (1, 1)), 1, status=stuck)
    assert labels(m, st2) == [("TIME ADVANCE", None, None)]


def test_exited_agent_does_not_block_time(m, st0):
    st = set_agent(m, all_done(m, st0, (1, 0)), 1, status=EXITED)
    assert labels(m, st) == [("TIME ADVANCE", None, None)]


def test_time_advance_needs_a_running_agent(m, st0):
    stuck = m.stuck_code("error", "test", None)
    st = all_done(m, st0)
    st = set_agent(m, set_agent(m, st, 0, status=stuck), 1, status=EXITED)
    assert labels(m, st) == []
    assert m.terminal_kind(st) == "deadlock"


def test_time_advance_with_rates():
    mm = model_of(PROG, n0=2, rates={1: 2})
    (st,) = mm.init_states()
    # agent 0 (rate 1) must reach 2; agent 1 (rate 2) is done at 1 already (1 + 2 > 2)
    assert "TIME ADVANCE" not in [l[0] for l in labels(mm, all_done(mm, st, (1, 2)))]
    assert [l[0] for l in labels(mm, all_done(mm, st, (2, 1)))] == ["TIME ADVANCE"]


def test_time_advance_ignores_pending_k_of_agent_without_budget(m, st0):
    # an agent whose budget was burnt by ATOMIC WAIT (counter = n0) does not block time
    st, _ = waiting(m, st0, counter=1)
    st = set_agent(m, st, 1, counter=1)
    assert ("TIME ADVANCE", None, None) in labels(m, st)


# ---------------------------------------------------------------------------
# DOREACH INVOKE
# ---------------------------------------------------------------------------

def test_doreach_invoke_instant(m, st0):
    tgt = (1.0, 2.0, 0.0)
    st = set_agent(m, st0, 0, reach=(tgt, (), None, False, False, ()), counter=1)
    st = set_state(m, set_agent(m, st, 1, counter=1), time=1, phase=DYNAMIC)
    out = m.successors(st)
    assert [l for l, _ in out] == [("DOREACH INVOKE", None, 0)]
    exp = set_agent(m, st, 0, counter=0, pos=tgt, reach=(tgt, (), None, True, False, ()))
    exp = set_state(m, set_agent(m, exp, 1, counter=0), phase=DISCRETE)
    assert out[0][1] == exp        # time unchanged, agent 1 (no target) holds still


def test_doreach_invoke_no_target_holds_position_and_flags(m, st0):
    st = set_state(m, all_done(m, st0), time=1, phase=DYNAMIC)
    (_, after), = m.successors(st)
    for i in (0, 1):
        assert after[AGS][i][POS] == st0[AGS][i][POS]
        assert after[AGS][i][REACH][3:] == (False, False, ())
        assert after[AGS][i][CNT] == 0


def test_doreach_invoke_nondet_one_successor_per_outcome():
    mm = model_of(PROG, blackbox="nondet")
    (st0,) = mm.init_states()
    t0, t1 = (1.0, 2.0, 0.0), (3.0, 3.0, 0.0)
    st = set_agent(mm, st0, 0, reach=(t0, (), None, False, False, ()), counter=1)
    st = set_agent(mm, st, 1, reach=(t1, (), None, False, False, ()), counter=1)
    st = set_state(mm, st, time=1, phase=DYNAMIC)
    out = mm.successors(st)
    assert [l[0] for l, _ in out] == ["DOREACH INVOKE"] * 4
    got = {(s[AGS][0][POS], s[AGS][0][REACH][DONE], s[AGS][1][POS], s[AGS][1][REACH][DONE]) for _, s in out}
    p0, p1 = st0[AGS][0][POS], st0[AGS][1][POS]
    assert got == {(a, a == t0, b, b == t1) for a, b in itertools.product((p0, t0), (p1, t1))}
    for _, s in out:
        assert s[PHASE] == DISCRETE and s[TIME] == 1 and all(ag[CNT] == 0 for ag in s[AGS])


def test_doreach_invoke_disabled_in_discrete_phase_and_agents_wait_in_dynamic(m, st0):
    assert "DOREACH INVOKE" not in [l[0] for l in labels(m, st0)]
    st = set_state(m, st0, phase=DYNAMIC)        # agents have budget, but the world moves first
    assert [l[0] for l in labels(m, st)] == ["DOREACH INVOKE"]


def test_doreach_invoke_moves_exited_agents_too(m, st0):
    # an exited robot's controller still runs toward its last target (docs/blackboxes.md)
    tgt = (1.0, 2.0, 0.0)
    st = set_agent(m, st0, 0, reach=(tgt, (), None, False, False, ()), status=EXITED)
    st = set_state(m, set_agent(m, st, 1, counter=1), time=1, phase=DYNAMIC)
    (_, after), = m.successors(st)
    assert after[AGS][0][POS] == tgt and after[AGS][0][STATUS] == EXITED


# ---------------------------------------------------------------------------
# rand
# ---------------------------------------------------------------------------

RAND_PROG = """
loc:
  int w = rand(2);
  int r = 0;
E():
  pre(true);
  eff:
    r = rand(3);
"""


def test_rand_in_declarations_one_initial_state_per_combination():
    mm = model_of(RAND_PROG)
    inits = list(mm.init_states())
    assert len(inits) == 9
    assert {(var(mm, s, 0, "w"), var(mm, s, 1, "w")) for s in inits} == set(
        itertools.product(range(3), repeat=2))


def test_rand_in_declarations_three_agents():
    mm = model_of(RAND_PROG, agents=3)
    assert len(list(mm.init_states())) == 27


def test_rand_statement_branches_0_to_n_inclusive():
    mm = model_of(RAND_PROG)
    st = next(iter(mm.init_states()))
    r = sid(mm, "r = rand")
    st = at(mm, st, 0, r, END)
    out = succ(mm, st, "STATEMENT", 0)
    assert len(out) == 4
    assert sorted(var(mm, s, 0, "r") for _, s in out) == [0, 1, 2, 3]
    assert {s for _, s in out} == {at(mm, st, 0, END, r=v) for v in range(4)}


def test_rand_policy_gives_one_outcome():
    mm = model_of(RAND_PROG, rand_policy=lambda n, agent, span: n)
    (st,) = mm.init_states()
    assert var(mm, st, 0, "w") == 2 and var(mm, st, 1, "w") == 2
    st = at(mm, st, 0, sid(mm, "r = rand"), END)
    (_, after), = succ(mm, st, "STATEMENT", 0)
    assert var(mm, after, 0, "r") == 3


def test_rand_policy_is_told_the_agent_in_declarations():
    calls = []
    mm = model_of(RAND_PROG, rand_policy=lambda n, agent, span: calls.append((n, agent)) or 0)
    list(mm.init_states())
    assert calls == [(2, 0), (2, 1)]


def test_rand_policy_is_told_the_agent_in_effects():
    calls = []
    mm = model_of(RAND_PROG, rand_policy=lambda n, agent, span: calls.append((n, agent)) or 0)
    (st,) = mm.init_states()
    calls.clear()
    st = at(mm, st, 1, sid(mm, "r = rand"), END)
    succ(mm, st, "STATEMENT", 1)
    assert calls == [(3, 1)]


def test_rand_in_guard_branches_between_event_and_idle():
    mm = model_of("""
        E():
          pre(rand(1) == 1);
          eff:
            skip;
        """)
    (st,) = mm.init_states()
    assert sorted(l[0] for l in labels(mm, st, agent=0)) == ["EVENT SELECT", "IDLE"]


def test_rand_in_if_condition_branches():
    mm = model_of("""
        loc:
          int x = 0;
        E():
          pre(true);
          eff:
            if (rand(1) == 0):
              x = 1;
            else:
              x = 2;
        """)
    (st,) = mm.init_states()
    i = sid(mm, "if")
    st = at(mm, st, 0, i, END)
    out = succ(mm, st, "STATEMENT", 0)
    assert {k_of(mm, s[AGS][0]) for _, s in out} == {(sid(mm, "x = 1"), END), (sid(mm, "x = 2"), END)}


# ---------------------------------------------------------------------------
# Runtime errors: the agent is stuck(reason, location)
# ---------------------------------------------------------------------------

ERR_PROG = """
allwrite:
  List<int> xs = [1, 2];
  List<int> empty = [];
allread:
  int a = 5;
loc:
  int z = 0;
  int j = 7;
  int y;
  int arr[3];
  int x = 0;
  ObstacleList obs = getObs();
E():
  pre(GUARD);
  eff:
    BODY
"""


def err_model(body, guard="true"):
    return model_of(ERR_PROG.replace("BODY", body).replace("GUARD", guard))


def run_agent0(mm, steps=10):
    (st,) = mm.init_states()
    trail = []
    for _ in range(steps):
        out = succ(mm, st, agent=0)
        if not out:
            break
        assert len(out) == 1
        l, st = out[0]
        trail.append(l)
    return st, trail


@pytest.mark.parametrize("body, reason", [
    ("x = 1 / z;", "division by zero"),
    ("x = 1 % z;", "modulo by zero"),
    ("x = y + 1;", "read of undefined variable 'y'"),
    ("remove(xs, 9);", "remove of an element not in the list"),
    ("x = head(empty);", "head of an empty list"),
    ("x = arr[j];", "index 7 out of range"),
    ("arr[j] = 1;", "index 7 out of range"),
    ("x = arr[1];", "undefined"),
    ("x = a[j];", "agent index 7 out of range"),
    ("x = a[0 - 1];", "agent index -1 out of range"),
    ("if (1 / z > 0):\n      skip;", "division by zero"),
    ("while (y > 0):\n      skip;", "read of undefined variable 'y'"),
    ("assert(head(empty) > 0);", "head of an empty list"),
    ("doReach(ItemPosition(1 / z, 0), obs);", "division by zero"),
])
def test_runtime_error_gets_agent_stuck_with_reason_and_line(body, reason):
    mm = err_model(body)
    st, trail = run_agent0(mm)
    line = mm.program.source.splitlines().index("    " + body.split("\n")[0]) + 1
    ag = st[AGS][0]
    assert ag[STATUS] >= 2, trail
    assert trail[-1][0] in ("STATEMENT", "DOREACH UPDATE")
    (v,) = mm.violations(st)
    assert v.kind == "stuck" and v.agent == 0
    assert reason in v.message
    assert v.span is not None and v.span.line == line
    text = D.status_text(mm, ag[STATUS])
    assert text.startswith("stuck(") and reason in text and f"at line {line}" in text
    # the stuck agent takes no further step; the other agent is unaffected
    assert succ(mm, st, agent=0) == []
    assert st[AGS][1][STATUS] == RUNNING
    assert C.encode_status(mm, ag[STATUS])["line"] == line


def test_runtime_error_in_guard_gets_agent_stuck_at_guard():
    mm = err_model("skip;", guard="1 / z > 0")
    (st,) = mm.init_states()
    (l, after), = succ(mm, st, agent=0)
    assert l[0] == "EVENT SELECT"
    (v,) = mm.violations(after)
    assert v.kind == "stuck" and "division by zero" in v.message
    line = mm.program.source.splitlines().index("  pre(1 / z > 0);") + 1
    assert v.span.line == line
    assert succ(mm, after, agent=0) == []


def test_runtime_error_leaves_state_otherwise_unchanged():
    mm = err_model("x = 1 / z;")
    (st,) = mm.init_states()
    _, st1 = only(mm, st, "EVENT SELECT", 0)
    _, st2 = only(mm, st1, "STATEMENT", 0)
    assert set_agent(mm, st2, 0, status=RUNNING) == st1


def test_same_error_same_stuck_code():
    # the stuck reason is interned: the same error at the same place is one state
    mm = err_model("x = 1 / z;")
    (st,) = mm.init_states()
    a = at(mm, st, 0, sid(mm, "x = 1 / z"), END)
    b = at(mm, st, 1, sid(mm, "x = 1 / z"), END)
    s1 = only(mm, a, "STATEMENT", 0)[1][AGS][0][STATUS]
    s2 = only(mm, b, "STATEMENT", 1)[1][AGS][1][STATUS]
    assert s1 == s2 >= 2


# ---------------------------------------------------------------------------
# state identity of k (docs/language.md §11)
# ---------------------------------------------------------------------------

TWO_SKIPS = """
loc:
  bool f = true;
A():
  pre(f);
  eff:
    skip;
B():
  pre(f);
  eff:
    skip;
"""


def test_equal_statements_at_different_lines_are_different_items():
    mm = model_of(TWO_SKIPS)
    (st,) = mm.init_states()
    (la, sa), (lb, sb) = succ(mm, st, "EVENT SELECT", 0)
    assert la[2] == 0 and lb[2] == 1
    assert sa != sb and k_of(mm, sa[AGS][0]) != k_of(mm, sb[AGS][0])
    # after the skip, both wait at endEventBlock, which carries no event name
    ((_, ea),) = succ(mm, sa, agent=0)
    ((_, eb),) = succ(mm, sb, agent=0)
    assert k_of(mm, ea[AGS][0]) == (END,)
    assert ea == eb
    # ... and IDLE leads to the same configuration too
    idle = set_agent(mm, st, 0, f=False)
    (_, si), = succ(mm, idle, "IDLE", 0)
    assert si == set_agent(mm, ea, 0, f=False)


def test_init_block_runs_before_time_zero_uninterleaved():
    mm = model_of("""
        allwrite:
          int s = 0;
        loc:
          int w = rand(1);
          int mine = -1;
          ObstacleList obs = getObs();
        Init:
          doReach(getPosition(), obs);
          atomic:
            s = s + 1;
            mine = s;
        E():
          pre(true);
          eff:
            skip;
        """, abstract_time=False)
    inits = list(mm.init_states())
    assert len(inits) == 4                       # w: 2 x 2
    for st in inits:
        assert st[TIME] == 0 and st[PHASE] == DISCRETE and st[LQ] == ()
        assert var(mm, st, 0, "s") == 2          # shared initialiser once, then each Init
        # agents run their Init in id order
        assert (var(mm, st, 0, "mine"), var(mm, st, 1, "mine")) == (1, 2)
        for i in (0, 1):
            ag = st[AGS][i]
            assert k_of(mm, ag) == () and ag[LCK] == IDLE and ag[CNT] == 0
            assert ag[REACH][TARGET] == ag[POS] and ag[REACH][T0] == 0


def test_runtime_error_in_declaration_gets_agent_stuck_in_initial_state():
    mm = model_of("""
        loc:
          int z = 0;
          int q = 1 / z;
        E():
          pre(true);
          eff:
            skip;
        """)
    (st,) = mm.init_states()
    vs = mm.violations(st)
    assert [(v.kind, v.agent) for v in vs] == [("stuck", 0), ("stuck", 1)]
    assert all(v.span.line == 3 and "division by zero" in v.message for v in vs)
