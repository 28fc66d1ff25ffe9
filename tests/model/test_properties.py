"""Property-based tests (hypothesis): random schedules through the engine.

A schedule is a sequence of drawn successor indices from a drawn initial
state.  Along every schedule, over Fischer (k = 2), Race, Race non-atomic and
a lock-heavy test program, under several blackboxes:

* the lock invariants hold: at most one agent holds the lock, the holder heads
  the lockQueue, no id is queued twice, and an agent is queued iff its
  lockState is request or lock;
* counters stay within 0..n0, time only moves by TIME ADVANCE (+δ);
* an agent rule changes only that agent's cell (and shared memory / the
  lock queue), a global rule no agent's program state;
* the engine never raises; states are hashable, equal to their pickled
  copy, and ``model.key`` is stable;
* successors are a function of the state (same list when asked twice).
"""

from __future__ import annotations

import functools
import pickle

import pytest

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hs

from pccl.api import make_model as _make_model, run

from conftest import (AGS, CNT, DISCRETE, DYNAMIC, EXITED, FISCHER, LCK, LOCK, PC, RACE,
                      RACE_NONATOMIC, RACE_WORLD, REQUEST, STATUS, TEST_PROGRAMS)
from pccl.model.layout import LQ, PHASE, TIME

LOCK_PROG = str(TEST_PROGRAMS / "eng_lock.pccl")


def make_model(*args, **kw):
    """The unreduced model: these properties are of the rules' single steps."""
    return _make_model(*args, reduce="none", **kw)

MODELS = {
    "fischer": lambda: make_model(FISCHER, overrides={"k": "2"}),
    "fischer-first": lambda: make_model(FISCHER, overrides={"k": "2"}, events="first",
                                        abstract_time=False),
    "race-straight": lambda: make_model(RACE, world=RACE_WORLD),
    "race-nondet-3": lambda: make_model(RACE, world=RACE_WORLD, blackbox="nondet", agents=3),
    "race_nonatomic-instant": lambda: make_model(RACE_NONATOMIC, world=RACE_WORLD,
                                                 blackbox="instant"),
    "race_nonatomic-nondet-3": lambda: make_model(RACE_NONATOMIC, world=RACE_WORLD,
                                                  blackbox="nondet", agents=3),
    "lock-instant": lambda: make_model(LOCK_PROG, blackbox="instant"),
    "lock-3-n0-2-rates": lambda: make_model(LOCK_PROG, blackbox="instant", agents=3, n0=2,
                                            rates={1: 2}),
    "lock-nondet-n0-3": lambda: make_model(LOCK_PROG, blackbox="nondet", n0=3, rates={0: 2}),
}


@functools.cache
def model(name):
    return MODELS[name]()


@functools.cache
def inits(name):
    return tuple(model(name).init_states())


def check_lock_invariants(m, st):
    lq = st[LQ]
    ags = st[AGS]
    assert len(set(lq)) == len(lq), f"id queued twice: {lq}"
    holders = [i for i, ag in enumerate(ags) if ag[LCK] == LOCK]
    assert len(holders) <= 1, f"several lock holders: {holders}"
    if holders:
        assert lq and lq[0] == holders[0], f"holder {holders[0]} is not the head of {lq}"
    for i, ag in enumerate(ags):
        assert (i in lq) == (ag[LCK] in (REQUEST, LOCK)), \
            f"agent {i} lockState {ag[LCK]} vs lockQueue {lq}"
    assert all(0 <= i < len(ags) for i in lq)


def check_state(m, st):
    hash(st)
    k1 = m.key(st)
    assert hash(k1) == hash(m.key(st)) and k1 == m.key(st)
    cp = pickle.loads(pickle.dumps(st))
    assert cp == st and hash(cp) == hash(st) and m.key(cp) == k1
    assert st[PHASE] in (DISCRETE, DYNAMIC)
    for i, ag in enumerate(st[AGS]):
        assert 0 <= ag[CNT] <= m.n0, f"agent {i} counter {ag[CNT]} outside 0..{m.n0}"
        assert ag[STATUS] in (0, 1) or ag[STATUS] in m.compiled.stuck_reasons
        assert 0 <= ag[PC] < len(m.ctl.ks)
    check_lock_invariants(m, st)


def check_step(m, label, before, after):
    rule, agent, _ = label
    if rule == "TIME ADVANCE":
        assert after[TIME] == before[TIME] + m.delta and before[PHASE] == DISCRETE and after[PHASE] == DYNAMIC
        assert after[2:] == before[2:]
    elif rule == "DOREACH INVOKE":
        assert before[PHASE] == DYNAMIC and after[PHASE] == DISCRETE and after[TIME] == before[TIME]
        assert after[2:4] == before[2:4]
        for a, b in zip(before[AGS], after[AGS]):
            assert a[:CNT] == b[:CNT] and a[LCK:6] == b[LCK:6] and b[CNT] == 0
    else:
        assert agent is not None and after[TIME] == before[TIME] and after[PHASE] == before[PHASE] == DISCRETE
        for j, (a, b) in enumerate(zip(before[AGS], after[AGS])):
            if j != agent:
                assert a == b, f"{rule} of agent {agent} changed agent {j}"
        assert before[AGS][agent][STATUS] == 0      # only running agents move
        if rule not in ("LOCK REQUEST", "LOCK RELEASE"):
            assert after[LQ] == before[LQ]
        if rule in ("COUNTER ADVANCE", "ATOMIC WAIT"):
            assert after[AGS][agent][CNT] == before[AGS][agent][CNT] + m.rho[agent]
        else:
            assert after[AGS][agent][CNT] == before[AGS][agent][CNT]
        if rule == "EXIT":
            assert after[AGS][agent][STATUS] == EXITED


def walk(name, data, steps):
    m = model(name)
    starts = inits(name)
    st = starts[data.draw(hs.integers(0, len(starts) - 1), label="init")]
    check_state(m, st)
    for _ in range(steps):
        out = m.successors(st)
        assert out == m.successors(st)
        if not out:
            assert m.terminal_kind(st) in ("final", "bounded", "deadlock")
            if m.terminal_kind(st) == "final":
                assert all(ag[STATUS] == EXITED for ag in st[AGS])
            break
        label, nxt = out[data.draw(hs.integers(0, len(out) - 1))]
        check_step(m, label, st, nxt)
        check_state(m, nxt)
        m.violations(nxt)             # never raises
        st = nxt
    return st


SETTINGS = settings(max_examples=40, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@SETTINGS
@given(name=hs.sampled_from(sorted(MODELS)), data=hs.data())
def test_random_schedules_keep_lock_invariants(name, data):
    walk(name, data, steps=250)


@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(data=hs.data())
def test_lock_program_long_schedules(data):
    walk("lock-3-n0-2-rates", data, steps=600)


@pytest.mark.parametrize("name", ["lock-instant", "race_nonatomic-instant"])
def test_whole_state_space_keeps_lock_invariants(name):
    """Not random: every reachable state (the search goes on past stuck agents)."""
    m = model(name)
    todo = list(inits(name))
    seen = {m.key(s) for s in todo}
    while todo:
        s = todo.pop()
        check_lock_invariants(m, s)
        for _label, s2 in m.successors(s):
            k = m.key(s2)
            if k not in seen:
                seen.add(k)
                todo.append(s2)
    assert len(seen) > 200


@settings(max_examples=15, deadline=None, derandomize=True)
@given(seed=hs.integers(0, 2 ** 32 - 1),
       prog=hs.sampled_from(["race", "race_nonatomic", "fischer", "lock"]),
       blackbox=hs.sampled_from(["instant", "straight", "nondet"]))
def test_runs_never_raise_and_are_reproducible(seed, prog, blackbox):
    path = {"race": RACE, "race_nonatomic": RACE_NONATOMIC, "fischer": FISCHER,
            "lock": LOCK_PROG}[prog]
    world = RACE_WORLD if prog.startswith("race") else None
    a = run(path, world=world, blackbox=blackbox, seed=seed, max_time=20)
    b = run(path, world=world, blackbox=blackbox, seed=seed, max_time=20)
    assert a.status in ("final", "bounded", "violation", "deadlock", "max-steps")
    assert a.exit_status == (0 if a.status in ("final", "bounded") else 1)
    assert (a.status, a.final, a.steps) == (b.status, b.final, b.steps)
    check_lock_invariants(a.model, a.final)
