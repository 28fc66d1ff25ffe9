"""Partial-order reduction beyond agent-local steps (issue 23 item 2):
shared reads and writes no other agent can still touch in this time step,
lock steps the queue makes independent, doReach; merging running the
steps POR finds movable (docs/reductions.md, "Partial-order reduction").

1. the attack (tests/porattack.py): generated programs with shared
   variables, locks and doReach whose ample sets use the new rules,
   including ones where the independence almost holds; verdicts equal to
   ``reduce="none"``, counterexamples replay, and the ample sets are
   diamonds state by state;
2. teeth: each condition weakened by a monkeypatch, and the attack (or a
   hand-made program) catches it;
3. hand-made cases for each new kind of ample step.
"""

from __future__ import annotations

import textwrap

import pytest

import porattack
from pccl.api import explore, make_model
from pccl.model import independence as I
from pccl.model import reduce as RD
from pccl.model.engine import Model
from pccl.model.layout import DISCRETE, PHASE

from conftest import PROGRAMS, verdict
from test_reduce import check_counterexamples


def src(text: str) -> str:
    return textwrap.dedent(text).lstrip("\n")


# ---------------------------------------------------------------------------
# 1. the attack
# ---------------------------------------------------------------------------

@pytest.mark.slow
def test_the_attack_keeps_the_verdict():
    compared = reduced = 0
    bad = []
    kinds: set = set()
    for seed in range(60):
        r = porattack.check(seed)
        if "invalid" in r or "bounded" in r:
            continue
        compared += 1
        for name, v in r.items():
            if name in ("states", "results", "base"):
                continue
            if not v[1]:
                bad.append((seed, name))
        for res in r["results"]:
            check_counterexamples(res)
        kinds |= {k for k, _, _ in r["base"][1]}
        if r["states"]["por"] < r["states"]["none"]:
            reduced += 1
    assert bad == [], f"python tests/porattack.py SEED shows the program: {bad}"
    assert compared >= 25 and reduced >= compared // 2
    # the attack reaches every kind of violation the reductions must keep
    assert {"invariant", "assert", "deadlock", "stall"} <= kinds, kinds


@pytest.mark.slow
def test_the_ample_sets_are_diamonds():
    bad = {seed: porattack.diamonds(seed) for seed in range(16)}
    assert {s: b for s, b in bad.items() if b} == {}


# ---------------------------------------------------------------------------
# 2. teeth: each condition weakened, and caught
# ---------------------------------------------------------------------------

def _ignore_others(self, st, j, b):
    return 0, 0


def _always(*a, **k):
    return False


WEAKENINGS = {
    # C1: the others' remaining accesses ignored
    "footprint": [(RD.Por, "footprint", _ignore_others)],
    # C1 for LOCK RELEASE: a waiter's ATOMIC WAIT ignored
    "may_wait": [(RD, "may_wait", _always)],
    # C1: every variable taken as lock-protected
    "protected": [(I.Independence, "_protected", lambda self, outside: self._all_bits())],
}


@pytest.mark.slow
@pytest.mark.parametrize("weak", sorted(WEAKENINGS))
def test_the_attack_catches_a_weakened_condition(monkeypatch, weak):
    for obj, attr, fn in WEAKENINGS[weak]:
        monkeypatch.setattr(obj, attr, fn)
    caught = []
    for seed in range(40):
        if porattack.diamonds(seed, limit=150, inner=150):
            caught.append(seed)
            break
        r = porattack.check(seed, combos=(("por",),), limit=3000)
        if "por" in r and not r["por"][1]:
            caught.append(seed)
            break
    assert caught, f"weakening {weak} went unnoticed"


TWO_FLAGS = src("""
    Agent::Flags

    allwrite:
      int u = 0;
      int v = 0;

    loc:
      bool done = false;

    Init:

    UpU():
      pre(getAgentIndex() == 0 && !done);
      eff:
        u = 1;
        u = 0;
        done = true;

    UpV():
      pre(getAgentIndex() == 1 && !done);
      eff:
        v = 1;
        v = 0;
        done = true;
""")


def test_c2_a_write_a_property_reads_is_never_ample(monkeypatch):
    # u and v are each written by one agent only, so the writes are
    # independent; but the invariant reads them: only the interleaving
    # u = 1, v = 1 violates it, and taking agent 0's writes as ample (they
    # are visible) would run u = 1; u = 0 before agent 1 ever moves
    kw = dict(source=True, agents=2, blackbox="instant", find_all=True,
              invariants=["u + v < 2"])
    base = explore(TWO_FLAGS, reduce="none", **kw)
    assert base.violations
    for combo in (["por"], ["merge", "por"], "auto"):
        res = explore(TWO_FLAGS, reduce=combo, **kw)
        assert verdict(res) == verdict(base)
        check_counterexamples(res)
    monkeypatch.setattr(I.Independence, "_writes_visible", _always)
    weak = explore(TWO_FLAGS, reduce="por", **kw)
    assert "invariant" in {v["kind"] for v in base.violations}
    assert "invariant" not in {v["kind"] for v in weak.violations}


LOOP_AND_ASSERT = src("""
    Agent::Spin

    allwrite:
      int s = 0;

    loc:
      bool b = false;

    Init:

    Loop():
      pre(getAgentIndex() == 0);
      eff:
        while (s == 0):
          b = !b;

    Fail():
      pre(getAgentIndex() == 1);
      eff:
        assert(s == 1);
""")


def test_c3_a_loop_step_is_never_ample(monkeypatch):
    # agent 0 spins in zero time reading s (nobody writes it); agent 1's
    # assertion fails.  Were loop steps ample, agent 0's spin would be
    # expanded alone forever and agent 1's violation never reached.
    kw = dict(source=True, agents=2, blackbox="instant", find_all=True)
    base = explore(LOOP_AND_ASSERT, reduce="none", **kw)
    assert "assert" in {v["kind"] for v in base.violations}
    res = explore(LOOP_AND_ASSERT, reduce="por", **kw)
    assert verdict(res) == verdict(base)
    monkeypatch.setattr(I.Independence, "in_loop", _always)
    weak = explore(LOOP_AND_ASSERT, reduce="por", **kw)
    assert "assert" not in {v["kind"] for v in weak.violations}


# ---------------------------------------------------------------------------
# 3. hand-made: each new kind of ample step
# ---------------------------------------------------------------------------

def ample_agents(text, agents=2, limit=3000, **kw):
    """The (rule, agent) of the first step of every reduced state whose
    ample set is one agent's steps, over the reduced reachable states."""
    m = make_model(text, source=True, agents=agents, reduce="por", **kw)
    seen, todo, out = set(), list(m.init_states()), set()
    while todo and len(seen) < limit:
        st = todo.pop()
        red = m.successors(st)
        full = Model.successors(m.model, st)
        if st[PHASE] == DISCRETE and len(red) < len(full):
            assert len({lab[1] for lab, _ in red}) == 1
            out |= {(lab[0], lab[1]) for lab, _ in red}
        for _, s2 in red:
            if s2 not in seen:
                seen.add(s2)
                todo.append(s2)
    return out


SHARED_READ = src("""
    Agent::Reader

    allwrite:
      int s = 5;
      int w = 0;

    loc:
      int x = 0;
      bool done = false;

    Init:

    Read():
      pre(!done);
      eff:
        x = s;
        done = true;
""")


def test_a_read_nobody_can_write_is_ample():
    rules = {r for r, _ in ample_agents(SHARED_READ, blackbox="instant")}
    assert "STATEMENT" in rules
    # the same read, now that agent 1 writes s in the same time step: never ample
    racy = SHARED_READ.replace("x = s;", "x = s;\n    s = getAgentIndex();")
    kw = dict(source=True, agents=2, blackbox="instant", find_all=True)
    for text in (SHARED_READ, racy):
        assert verdict(explore(text, reduce="por", **kw)) == verdict(explore(text, reduce="none", **kw))


def test_the_almost_independent_write_keeps_its_violation():
    # agent 0 reads s; agent 1 (only it) may write s in the same time step;
    # the interleaving where the write comes first violates the invariant
    text = src("""
        Agent::Almost

        allwrite:
          int s = 0;

        loc:
          int x = 0;
          bool done = false;

        Init:

        Read():
          pre(!done && getAgentIndex() == 0);
          eff:
            x = s;
            done = true;

        Write():
          pre(!done && getAgentIndex() == 1);
          eff:
            s = 1;
            done = true;
    """)
    kw = dict(source=True, agents=2, blackbox="instant", find_all=True,
              invariants=["forall i: x[i] == 0"])
    base = explore(text, reduce="none", **kw)
    assert base.violations
    for combo in (["por"], ["merge", "por"], "auto"):
        res = explore(text, reduce=combo, **kw)
        assert verdict(res) == verdict(base)
        check_counterexamples(res)


LOCKS = src("""
    Agent::Locks

    allwrite:
      List<int> q = [];
      int n = 0;

    loc:
      bool done = false;

    Init:

    Put():
      pre(!done);
      eff:
        atomic:
          add(q, getAgentIndex());
          n = size(q);
        done = true;
""")


def test_lock_steps_and_protected_variables_are_ample():
    got = ample_agents(LOCKS, agents=3, blackbox="instant")
    rules = {r for r, _ in got}
    assert {"ATOMIC EXECUTION", "STATEMENT", "LOCK RELEASE"} <= rules, rules
    kw = dict(source=True, agents=3, blackbox="instant", find_all=True,
              invariants=["n <= 2"])
    base = explore(LOCKS, reduce="none", **kw)
    assert base.violations
    for combo in (["por"], ["merge", "por"], "auto"):
        res = explore(LOCKS, reduce=combo, **kw)
        assert verdict(res) == verdict(base)
        assert res.stats.states < base.stats.states
        check_counterexamples(res)


def test_doreach_is_ample_unless_a_property_reads_the_flags(tmp_path):
    text = src("""
        Agent::Mover

        loc:
          bool sent = false;

        Init:

        Go():
          pre(!sent);
          eff:
            doReach(ItemPosition(getAgentIndex(), 1), getObs());
            sent = true;
    """)
    rules = {r for r, _ in ample_agents(text, blackbox="nondet")}
    assert "DOREACH UPDATE" in rules
    rules = {r for r, _ in ample_agents(text, blackbox="nondet",
                                       invariants=["forall i: !doReach_done[i]"])}
    assert "DOREACH UPDATE" not in rules


@pytest.mark.slow
def test_fischer_reduces_further_and_keeps_the_violation():
    # the shipped program: POR now takes Fischer's reads of reqid and its
    # lock steps; the verdict (a mutual-exclusion violation at k = 0) stays
    kw = dict(agents=2, overrides={"k": "0", "d": "1"}, invariants=["count(inCs) <= 1"],
              find_all=True)
    base = explore(str(PROGRAMS / "fischer.pccl"), reduce="merge", **kw)
    res = explore(str(PROGRAMS / "fischer.pccl"), reduce="merge,por", **kw)
    assert verdict(res) == verdict(base)
    check_counterexamples(res)
    assert res.stats.states < base.stats.states


def test_ample_states_differ_from_the_old_local_only_rule():
    # some reduced state of Fischer takes an ample step the old rule (local
    # steps only) would not: a read of the shared reqid or a lock step
    got = ample_agents(open(PROGRAMS / "fischer.pccl").read(), agents=2,
                       overrides={"k": "1", "d": "1"})
    assert {"LOCK REQUEST", "ATOMIC EXECUTION", "LOCK RELEASE"} & {r for r, _ in got}


# ---------------------------------------------------------------------------
# spent agents: a plain statement of an agent whose counter is spent (it
# waited for the lock) is ample while TIME ADVANCE is enabled
# ---------------------------------------------------------------------------

SPENT = src("""
    Agent::T

    allwrite:
      int x = 0;

    loc:
      boolean go = true;
      ObstacleList obs = getObs();

    Go():
      pre(go);
      eff:
        doReach(ItemPosition(1, 0), obs);
        atomic:
          x = x + 1;
        assert(!doReach_done);
        go = false;
""")


@pytest.mark.parametrize("engine", ["python", "native"])
def test_a_spent_agents_read_of_its_flag_keeps_the_violation(engine, tmp_path):
    # agent 1 waits for the lock (its counter is spent), then runs
    # assert(!doReach_done): if TIME ADVANCE and an arrival come first, the
    # assertion fails.  The read of the flag keeps the state fully expanded
    if engine == "native":
        from test_native import MISSING
        if MISSING:
            pytest.skip(MISSING)
    p = tmp_path / "spent.pccl"
    p.write_text(SPENT)
    base = explore(str(p), reduce="none", engine="python")
    assert base.status == "violation" and {k for k, _, _ in verdict(base)[1]} == {"assert"}
    res = explore(str(p), engine=engine)
    assert res.model.engine_used == engine
    assert verdict(res) == verdict(base)
    check_counterexamples(res)


def test_spent_agents_reduce_the_race(monkeypatch):
    kw = dict(world=str(PROGRAMS / "race.toml"), agents=2, blackbox="nondet", engine="python")
    new = explore(str(PROGRAMS / "race_robust.pccl"), **kw)
    monkeypatch.setattr(I.Independence, "_spent_local", lambda self, pc: False)
    old = explore(str(PROGRAMS / "race_robust.pccl"), **kw)
    assert verdict(new) == verdict(old) == ("bounded", set())     # not exhaustive for pymunk
    assert new.stats.states < 0.85 * old.stats.states


SPENT_KINDS = src("""
    Agent::T

    allwrite:
      int x = 0;

    loc:
      int y = 0;
      int seen = 0;
      ItemPosition p;

    Go():
      pre(y == 0);
      eff:
        y = 1;
        if (doReach_done):
          y = 2;
        p = getPosition();
        y = x;
        doReach(ItemPosition(1, 0), getObs());
        seen = 1;

    Loop():
      pre(y == 5);
      eff:
        while (y < 9):
          y = y + 1;
        exit();
""")


def test_which_steps_of_a_spent_agent_are_ample(tmp_path):
    # Independence.spent_local, statement by statement: only a plain
    # statement touching nothing but the agent's own variables (not the
    # doReach flags, its position, shared data, a property's variable)
    p = tmp_path / "kinds.pccl"
    p.write_text(SPENT_KINDS)
    m = make_model(str(p), agents=2, blackbox="nondet", reduce="none",
                   invariants=["forall i: seen[i] <= 1"]).model
    m.prepare()                 # every k cell interned
    ind = I.Independence(m)
    got = {}
    for pc in range(len(m.ctl.cells)):
        info = m.ctl.info(pc)
        if info.sid is not None and info.sid in m.compiled.stmts:
            line = m.compiled.stmts[info.sid].span.line
            got.setdefault(line, set()).add(ind.spent_local(pc))
    assert got[14] == {True}           # y = 1
    assert got[15] == {False}          # if (doReach_done)
    assert got[16] == {True}           # y = 2
    assert got[17] == {False}          # p = getPosition()
    assert got[18] == {False}          # y = x (shared)
    assert got[19] == {False}          # doReach
    assert got[20] == {False}          # seen = 1 (a property reads it)
    assert got[25] == {False} and got[26] == {False} and got[27] == {False}  # loop, exit
