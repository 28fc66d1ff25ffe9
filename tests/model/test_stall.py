"""The stall check of ``pccl explore`` (pccl/model/stall.py, pccl/search/liveness.py) and
the zero-time runaway note (pccl/search/explorer.py's ``on_runaway``).

The verdicts are checked against an independent brute-force search over the
unreduced rules: from the counterexample's last state, every reachable
transition keeps ``pccl run``'s signature (pccl/tools/runner.py) and time still
advances; from the state before it, some transition changes it.
"""

from __future__ import annotations

import json
import textwrap

import pytest

from pccl.api import explore, make_model
from pccl.model.engine import Model
from pccl.tools.runner import _signature

from conftest import TEST_PROGRAMS, cli, closure
from pccl.model.layout import AGS, REACH, FAIL, RUNNING, STATUS, TIME

RDV = str(TEST_PROGRAMS / "rdv_meet.pccl")
WALL = str(TEST_PROGRAMS / "rdv_wall.toml")
OPEN = str(TEST_PROGRAMS / "rdv_open.toml")


def src(text: str) -> str:
    return textwrap.dedent(text).lstrip("\n")


def really_stalled(m, st) -> bool:
    """Independently: from ``st`` no reachable transition changes run's
    signature (private locals aside: none of these programs change one
    after stalling), no state is terminal, time advances, an agent runs."""
    steps = closure(m, st)
    if any(lab is None for lab, _, _ in steps):
        return False
    if not any(lab[0] == "TIME ADVANCE" for lab, _, _ in steps):
        return False
    if not any(ag[STATUS] == RUNNING for ag in st[AGS]):
        return False
    return all(_signature(a) == _signature(b) for _, a, b in steps)


def stall_of(res):
    return [v for v in res.violations if v.kind == "stall"]


# ---------------------------------------------------------------------------
# the walled rendezvous
# ---------------------------------------------------------------------------

def test_walled_rendezvous_stalls_under_straight():
    res = explore(RDV, world=WALL, blackbox="straight")
    assert res.exit_status == 1 and res.status == "violation"
    v = res.violation
    assert v.kind == "stall"
    # the counterexample ends with the environment step that fails the doReach
    last = res.counterexamples[0].trace.steps[-1]
    assert last.label[0] == "DOREACH INVOKE"
    assert last.after[AGS][0][REACH][FAIL] and not last.before[AGS][0][REACH][FAIL]
    # what each agent waits on: the blocked robot's flag, the waiting robot's guard
    assert "agent 0 waits for" in v.message and "doReach_fail[0] is true" in v.message
    assert "doReach_done[0] never becomes true" in v.message
    assert "agent 1 waits for Wait (line 24: `met` is false" in v.message
    # independently: the last state is stalled, the one before is not
    m = make_model(RDV, world=WALL, blackbox="straight", reduce="none")
    tr = res.counterexamples[0].trace
    assert really_stalled(m, tr.last)
    assert not really_stalled(m, tr.states[-2])


def test_rendezvous_without_the_wall_passes():
    for bb in ("straight", "nondet"):
        res = explore(RDV, world=OPEN, blackbox=bb)
        assert res.exit_status == 0 and res.status == "exhaustive", (bb, res.verdict)
        assert res.stall


def test_walled_rendezvous_stalls_under_the_default_blackbox():
    r = cli("explore", RDV, "--world", WALL)
    assert r.exit_code == 1, r.output
    assert "stall:" in r.output and "doReach_fail[0] is true" in r.output


def test_cli_stall_and_no_stall():
    r = cli("explore", RDV, "--world", WALL, "-b", "straight")
    assert r.exit_code == 1
    out = r.output
    assert "violation: stall: the team can never change again" in out
    assert "doReach_fail[0] false -> true" in out.split("violating state:")[0].splitlines()[-1]
    r = cli("explore", RDV, "--world", WALL, "-b", "straight", "--no-stall")
    assert r.exit_code == 0, r.output
    r = cli("explore", RDV, "--world", OPEN, "-b", "straight")
    assert r.exit_code == 0, r.output
    r = cli("explore", RDV, "--world", WALL, "-b", "straight", "--format", "json")
    doc = json.loads(r.output)
    assert doc["stall_check"] is True
    assert doc["violations"][0]["kind"] == "stall"
    assert doc["trace"]["result"]["violation"]["kind"] == "stall"


def test_api_stall_false_and_bad_value():
    res = explore(RDV, world=WALL, blackbox="straight", stall=False)
    assert res.exit_status == 0 and not res.stall
    from pccl.lang.errors import ArgumentError
    with pytest.raises(ArgumentError, match="stall"):
        explore(RDV, world=WALL, blackbox="straight", stall="yes")


def test_stall_trace_replays(tmp_path):
    out = tmp_path / "t.json"
    r = cli("explore", RDV, "--world", WALL, "-b", "straight", "--trace-out", out)
    assert r.exit_code == 1
    r = cli("replay", out)
    assert r.exit_code == 1, r.output
    assert "reproduced" in r.output


@pytest.mark.parametrize("workers", [2, 3])
@pytest.mark.parametrize("case", ["rdv-wall", "rdv-open", "race-safe-sym", "take-turns-sym"])
def test_workers_find_the_same_stalls(case, workers):
    """The workers decide each expanded state's change on its actual
    successors (pccl/search/parallel.py), so the stall verdict, its counterexample
    and the figures are those of one process (issue 20: one verdict on every
    backend), under symmetry too."""
    program, kw = {
        "rdv-wall": (RDV, dict(world=WALL, blackbox="straight")),
        "rdv-open": (RDV, dict(world=OPEN, blackbox="nondet")),
        "race-safe-sym": ("programs/race_safe.pccl", dict(world="programs/race.toml")),
        "take-turns-sym": (TAKE_TURNS, dict(source=True, agents=3, blackbox="instant")),
    }[case]
    one = explore(program, **kw)
    many = explore(program, workers=workers, **kw)
    assert (many.status, many.verdict, many.stats.states, many.stats.transitions) == \
        (one.status, one.verdict, one.stats.states, one.stats.transitions)
    assert [(v.kind, v.message) for v in many.violations] == \
        [(v.kind, v.message) for v in one.violations]
    assert [s.rule for s in many.trace] == [s.rule for s in one.trace]
    assert many.stall and not any("stall check not run" in n for n in many.notes)
    # the workers, kept for the analysis' replay, are gone once the result is made
    import multiprocessing
    assert not multiprocessing.active_children()


# ---------------------------------------------------------------------------
# the definition, program by program, against brute force and under reductions
# ---------------------------------------------------------------------------

#: agents take the turn from each other for ever: `turn` changes every
#: step, so no stall, though under symmetry turn = 0 and turn = 1 are one
#: state (the change is decided on the actual successor, not the renamed one)
TAKE_TURNS = src("""
    allwrite:
      int turn = -1;
    loc:
      int id = getAgentIndex();

    Take():
      pre(turn != id);
      eff:
        turn = id;
    """)

#: each agent sets its flag once, then idles for ever (symmetric): a stall
SET_ONCE = src("""
    allread:
      bool done = false;

    Go():
      pre(!done);
      eff:
        done = true;
    """)

#: agent waits for a flag nobody sets while it counts privately: a stall
#: (a private loc: no other agent, guard or property reads it)
PRIVATE_SPIN = src("""
    allwrite:
      bool go = false;
    loc:
      int c = 0;

    Spin():
      pre(!go);
      eff:
        c = (c + 1) % 3;

    Leave():
      pre(go);
      eff:
        exit();
    """)

#: a shared variable keeps changing: no stall
TOGGLE = src("""
    allwrite:
      int x = 0;

    Flip():
      pre(true);
      eff:
        x = 1 - x;
    """)

#: everyone exits: final, no stall
EXITS = src("""
    loc:
      int n = 0;

    Go():
      pre(n < 2);
      eff:
        n = n + 1;

    Done():
      pre(n == 2);
      eff:
        exit();
    """)


@pytest.mark.parametrize("text,stalls", [(TAKE_TURNS, False), (SET_ONCE, True),
                                         (PRIVATE_SPIN, True), (TOGGLE, False),
                                         (EXITS, False)])
@pytest.mark.parametrize("reduce", ["none", "auto", "merge", "por", "symmetry"])
def test_verdict_by_definition_under_every_reduction(text, stalls, reduce):
    m = make_model(text, source=True, blackbox="instant", agents=2, reduce="auto")
    if reduce not in ("none", "auto") and reduce not in m.reduction.on:
        pytest.skip(f"{reduce} is not sound here")
    res = explore(text, source=True, blackbox="instant", agents=2, reduce=reduce)
    assert bool(stall_of(res)) == stalls, res.verdict
    if stalls:
        tr = res.counterexamples[0].trace
        base = make_model(text, source=True, blackbox="instant", agents=2, reduce="none")
        if text is not PRIVATE_SPIN:    # run's signature counts private locals
            assert really_stalled(base, tr.last)
        for step in tr.steps:           # a real path of the rules
            assert (step.label, step.after) in Model.successors(base, step.before)


def test_take_turns_keeps_symmetry_on():
    m = make_model(TAKE_TURNS, source=True, blackbox="instant", agents=2, reduce="auto")
    assert "symmetry" in m.reduction.on
    res = explore(TAKE_TURNS, source=True, blackbox="instant", agents=2)
    base = explore(TAKE_TURNS, source=True, blackbox="instant", agents=2, reduce="none")
    assert res.stats.states < base.stats.states       # the orbits were merged
    assert res.status == base.status == "exhaustive"


def test_a_change_into_a_renamed_representative_is_a_change():
    """Under symmetry a state number stands for an orbit: the recorder
    decides a transition's change on the actual successor.  turn 0 -> 1
    reaches the representative of its own orbit (agents swapped), which has
    the source's signature; the actual successor does not."""
    from pccl.search.liveness import GraphRecorder
    import numpy as np
    m = make_model(TAKE_TURNS, source=True, blackbox="instant", agents=2, reduce="symmetry")
    s = next(s2 for s2 in (t for _, t in m.successors(next(iter(m.init_states())))))
    from pccl.model.layout import SH, with_shared
    a = with_shared(s, (0,) + tuple(s[SH][1:]))
    b = with_shared(s, (1,) + tuple(s[SH][1:]))
    rec = GraphRecorder(m, stall=True)
    assert rec.wants_candidates
    rec.states([a])
    rec.edges(np.array([0]), np.array([0]), [b])
    assert rec.chg.view()[0] == 1
    rec.edges(np.array([0]), np.array([0]), [a])
    rec2 = GraphRecorder(m, stall=True)
    rec2.states([a])
    rec2.edges(np.array([0]), np.array([0]), [a])
    assert rec2.chg.view()[0] == 0


def test_a_time_lock_is_not_a_stall():
    res = explore(str(TEST_PROGRAMS / "tl_spin.pccl"), find_all=True)
    kinds = {v.kind for v in res.violations}
    assert "timelock" in kinds and "stall" not in kinds


# ---------------------------------------------------------------------------
# zero-time runaways, and the largest model time
# ---------------------------------------------------------------------------

RUNAWAY = str(TEST_PROGRAMS / "runaway.pccl")     # x grows for ever in zero time


def test_zero_time_runaway_note():
    r = cli("explore", RUNAWAY, "--agents", "1", "--reduce", "none", "--max-states", "1200")
    assert r.exit_code == 0
    note = [ln for ln in r.stderr.splitlines() if "zero-time runaway" in ln]
    assert note, r.stderr
    assert "agent 0 keeps time from advancing (at line 9: x = x + 1;)" in note[0]
    assert "max time         0" in r.stdout
    assert "note: zero-time runaway" in r.stdout
    res = explore(RUNAWAY, agents=1, reduce="none", max_states=1200)
    assert res.stats.max_time == 0
    assert any("zero-time runaway" in n for n in res.notes)


def test_no_runaway_note_when_time_advances():
    res = explore(RDV, world=OPEN, blackbox="straight")
    assert not any("runaway" in n for n in res.notes)


def test_max_time_is_the_largest_reachable_time():
    # with the clock in the state every reachable time is a state: compare
    # with a brute-force walk of the rules
    res = explore(RDV, world=OPEN, blackbox="straight", abstract_time=False, reduce="none")
    m = make_model(RDV, world=OPEN, blackbox="straight", abstract_time=False, reduce="none")
    seen, todo, best = set(), list(m.init_states()), None
    while todo:
        s = todo.pop()
        if m.key(s) in seen:
            continue
        seen.add(m.key(s))
        best = s[TIME] if best is None else max(best, s[TIME])
        todo.extend(s2 for _, s2 in m.successors(s))
    assert res.stats.max_time == best and best > 0
    assert res.stats.as_dict()["max_time"] == best
