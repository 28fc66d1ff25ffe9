"""The dead-variable reduction (pccl/model/dead.py, docs/reductions.md "Dead
variables"): which values it masks, that the masked key is what both
engines identify states by, and that verdicts stay (every shipped and test
program and generated programs are in tests/test_reduce.py's combinations,
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
from test_fingerprints import programs

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


def test_a_liveness_property_turns_dead_off_and_asking_is_an_error():
    from pccl.lang.errors import PcclError
    prop = "eventually forall i: !flag[i]"
    m = make_model(SCRATCH, source=True, agents=2, blackbox="instant", properties=(prop,))
    assert "dead" not in m.reduction.on and "liveness" in m.reduction.off["dead"]
    with pytest.raises(PcclError, match="dead reduction is unsound"):
        make_model(SCRATCH, source=True, agents=2, blackbox="instant", properties=(prop,),
                   reduce="dead")


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
