"""Frozen teams (issue 44, point 2; pccl/model/frozen.py, docs/temporal.md#frozen-teams).

The acceptance cases are the two patrol programs of the issue: three robots
on four corners with a pillar on one edge (under ``straight`` the robot that
drives it retries its doReach for ever, the others wait on the corners it
holds), and four robots on four corners (nobody can reserve the next one).
Both explored clean before: a retry toggles ``doReach_fail`` and a busy
wait takes and releases the lock at every step, so the stall check sees
changes.  The verdicts are checked against an independent brute force over
the unreduced rules (:func:`really_frozen`).
"""

from __future__ import annotations

import json

import pytest

from pccl.api import explore, make_model
from pccl.model.engine import Model
from pccl.model.layout import AGS, AR, POS, REACH, SH, STATUS, TARGET

from cases import FROZEN_BUSY, FROZEN_ONE_SHOT
from conftest import ROOT, TEST_PROGRAMS, cli, closure

pytestmark = pytest.mark.slow     # every test here explores (0.5-15 s each on a loaded machine)

PATROL = str(TEST_PROGRAMS / "patrol.pccl")
OPEN = str(TEST_PROGRAMS / "patrol.toml")
PILLAR = str(TEST_PROGRAMS / "patrol_pillar.toml")
FOUR = str(TEST_PROGRAMS / "patrol4.toml")


def progress(st) -> tuple:
    """What the team has achieved (the patrol programs read no local in a
    property): shared and allread variables, statuses, positions, targets."""
    return (st[SH], tuple((ag[STATUS], ag[AR], ag[POS], ag[REACH][TARGET]) for ag in st[AGS]))


def really_frozen(m, st) -> tuple:
    """Independently, over the unreduced rules of ``m`` (the model of a result,
    whose interned pending code the state's is): ``(frozen, events that
    still fire)`` from ``st``: no
    terminal state reachable, time advances, nothing changes the progress
    tuple, and some event never fires."""
    steps = closure(m, st, 50_000, key=lambda s: Model.key(m, s))
    fires = {lab[2] for lab, _, _ in steps if lab is not None and lab[0] == "EVENT SELECT"
             and lab[2] is not None}
    frozen = (not any(lab is None for lab, _, _ in steps)
              and any(lab[0] == "TIME ADVANCE" for lab, _, _ in steps)
              and all(progress(a) == progress(b) for _, a, b in steps)
              and len(fires) < len(m.program.events))
    return frozen, fires


def names(m, evs) -> set:
    return {m.program.events[e].name for e in evs}


def frozen_of(res):
    return [v for v in res.violations if v.kind == "frozen"]


# ---------------------------------------------------------------------------
# the acceptance cases
# ---------------------------------------------------------------------------

def test_patrol_with_a_pillar_is_frozen():
    res = explore(PATROL, world=PILLAR, blackbox="straight")
    assert res.status == "violation" and res.exit_status == 1, res.verdict
    (v,) = frozen_of(res)
    assert v.message.startswith("frozen: the team runs for ever, but nothing it does can change "
                                "a variable, a position or a doReach target again: event Arrive "
                                "(line 37: `moving && doReach_done`) can never fire again "
                                "(fired before); still firing: Reserve (line 26), Retry (line 44)")
    tr = res.counterexamples[0].trace
    m = res.model
    frozen, fires = really_frozen(m, tr.last)
    assert frozen and names(m, fires) == {"Reserve", "Retry"}
    # Arrive fired on the way (robots 2 and 1 moved on), then never again
    assert any(lab[0] == "EVENT SELECT" and lab[2] == 1 for lab in tr.labels)
    # unreduced, the path is a shortest one: the state before the last is not frozen yet
    res = explore(PATROL, world=PILLAR, blackbox="straight", reduce="none")
    tr = res.counterexamples[0].trace
    assert really_frozen(res.model, tr.last)[0]
    assert not really_frozen(res.model, tr.states[-2])[0]


def test_four_robots_on_four_corners_are_frozen_from_the_start():
    res = explore(PATROL, world=FOUR, blackbox="straight")
    assert res.status == "violation" and res.exit_status == 1, res.verdict
    (v,) = frozen_of(res)
    assert ("events Arrive (line 37: `moving && doReach_done`) and Retry (line 44: "
            "`moving && doReach_fail`) never fire; still firing: Reserve (line 26)") in v.message
    tr = res.counterexamples[0].trace
    assert len(tr) == 0                 # frozen in the initial state
    m = res.model
    frozen, fires = really_frozen(m, tr.last)
    assert frozen and names(m, fires) == {"Reserve"}


def test_the_patrol_programs_explored_clean_without_the_check():
    """What main said before (the stall check alone): clean."""
    for world in (PILLAR, FOUR):
        res = explore(PATROL, world=world, blackbox="straight", stall=False)
        assert res.status == "exhaustive" and res.exit_status == 0, res.verdict


@pytest.mark.parametrize("world", [PILLAR, FOUR])
@pytest.mark.parametrize("reduce", ["merge", "por", "dead", "auto"])
def test_the_same_verdict_under_every_reduction(world, reduce):
    res = explore(PATROL, world=world, blackbox="straight", reduce=reduce)
    (v,) = frozen_of(res)
    base = explore(PATROL, world=world, blackbox="straight", reduce="none")
    assert v.message == frozen_of(base)[0].message
    assert really_frozen(res.model, res.counterexamples[0].trace.last)[0]


def test_a_patrol_that_goes_round_is_not_frozen():
    """Three robots in the open: Retry never fires (nothing fails a doReach),
    but the robots keep moving: no false alarm."""
    for bb in ("straight", "nondet"):
        res = explore(PATROL, world=OPEN, blackbox=bb)
        assert res.exit_status == 0 and not res.violations, (bb, res.verdict)
        assert res.checked["events"]["never_fired"] == [{"event": "Retry", "line": 43}]
        assert not any("frozen" in n for n in res.notes)


def test_a_pillar_that_may_be_passed_is_not_frozen():
    """Under nondet-fail a failed doReach may succeed on the next try: the
    team is never frozen (and under nondet it never fails)."""
    for bb in ("nondet", "nondet-fail"):
        res = explore(PATROL, world=PILLAR, blackbox=bb)
        assert not frozen_of(res), (bb, res.verdict)


# ---------------------------------------------------------------------------
# one-shot events, small programs
# ---------------------------------------------------------------------------

#: (the programs: tests/cases.py)
ONE_SHOT = dict(program=FROZEN_ONE_SHOT, source=True)
BUSY = dict(program=FROZEN_BUSY, source=True)


def test_a_one_shot_event_in_a_team_that_makes_progress_is_not_frozen():
    res = explore(**ONE_SHOT)
    assert res.status == "exhaustive" and res.exit_status == 0, res.verdict


def test_a_busy_wait_on_a_value_nobody_sets_is_frozen():
    """Pass waits on a token value no agent ever holds; Poll takes and releases the lock."""
    res = explore(**BUSY)
    (v,) = frozen_of(res)
    assert "event Pass (line 11: `started && tok == id + 5`) never fires" in v.message
    # Start (one-shot: private) can still fire in the initial state, frozen already
    assert v.message.endswith("still firing: Start (line 7), Poll (line 15)")
    # the stall check alone saw the lock queue change
    assert explore(**BUSY, stall=False).status == "exhaustive"


# ---------------------------------------------------------------------------
# the command line, replay, the limit
# ---------------------------------------------------------------------------

def test_cli_exit_codes_json_and_replay(tmp_path):
    out = tmp_path / "t.json"
    r = cli("explore", PATROL, "--world", PILLAR, "-b", "straight", "--trace-out", str(out))
    assert r.exit_code == 1, r.output
    assert "violation: frozen: the team runs for ever" in r.output
    r = cli("explore", PATROL, "--world", FOUR, "-b", "straight", "--exit-codes", "detailed")
    assert r.exit_code == 11, r.output
    r = cli("explore", PATROL, "--world", FOUR, "-b", "straight", "--format", "json")
    doc = json.loads(r.output)
    assert doc["violations"][0]["kind"] == "frozen"
    r = cli("replay", str(out))
    assert r.exit_code == 1, r.output
    assert "reproduced: frozen: the team runs for ever" in r.output
    # a frozen-team file whose message names the wrong events diverges
    doc = json.loads(out.read_text())
    doc["result"]["violation"]["message"] = doc["result"]["violation"]["message"].replace(
        "Arrive", "Reserve", 1)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    r = cli("replay", str(bad))
    assert r.exit_code == 2 and "does not name the events" in r.output, r.output


def test_no_stall_turns_the_check_off():
    r = cli("explore", PATROL, "--world", FOUR, "-b", "straight", "--no-stall")
    assert r.exit_code == 0, r.output


def test_a_search_larger_than_the_limit_says_the_check_did_not_run(monkeypatch):
    from pccl.model import frozen as F
    monkeypatch.setattr(F, "LIMIT", 1000)
    # over the search's own graph the limit does not apply
    res = explore(PATROL, world=FOUR, blackbox="straight")
    assert res.status == "violation" and res.counterexamples[0].violation.kind == "frozen"
    # where the check explores again (PCCL_FROZEN_GRAPH=0: as for --workers N
    # processes), it stops at its limit
    monkeypatch.setenv("PCCL_FROZEN_GRAPH", "0")
    res = explore(PATROL, world=FOUR, blackbox="straight")
    assert res.status == "exhaustive" and res.exit_status == 0
    # (the native engine's search: the check explores its native model again)
    assert res.model.engine_used == "native"
    assert "frozen teams not checked: 3,160 states, more than the 1,000 the check explores again" \
        in res.notes
    res = explore(PATROL, world=FOUR, blackbox="straight", engine="python")
    assert ("frozen teams not checked: 3,160 states, more than the 1,000 the check explores "
            "again (in Python)") in res.notes
    # and a bounded or violating search says nothing of it
    res = explore(PATROL, world=FOUR, blackbox="straight", max_states=100)
    assert res.status == "bounded" and not any("frozen" in n for n in res.notes)


@pytest.mark.slow
@pytest.mark.parametrize("world", [PILLAR, FOUR])
def test_the_native_and_python_engines_find_the_same_frozen_team(world):
    """The check on the native engine's search explores the native model
    (successors, keys, the progress signature's slots in C): the same
    verdict, message, counts and path as on the Python engine's."""
    out = {}
    for engine in ("python", "native"):
        r = explore(PATROL, world=world, blackbox="straight", engine=engine, find_all=True)
        assert r.model.engine_used == engine
        out[engine] = (r.status, r.stats.states, r.stats.transitions,
                       [(cx.violation.kind, cx.violation.message, cx.trace.labels,
                         [tuple(a[1:] for a in st[AGS]) for st in cx.trace.states])
                        for cx in r.counterexamples])
    assert out["native"] == out["python"]
    assert any(v[0] == "frozen" for v in out["python"][3])


def test_check_stops_at_its_limit():
    from pccl.model.frozen import check
    m = make_model(PATROL, world=FOUR, blackbox="straight")
    r = check(m, limit=100)
    assert not r.ran and "more than 100 states" in r.reason
    r = check(m)
    assert r.ran and r.states == 3160 and r.violation is not None


# ---------------------------------------------------------------------------
# no false alarm on the shipped programs
# ---------------------------------------------------------------------------

SHIPPED = [     # clean and exhaustive: the check runs on each
    ("programs/race.pccl", "programs/race.toml", {"blackbox": "straight"}),
    ("programs/race_safe.pccl", "programs/race.toml", {"blackbox": "straight"}),
    ("programs/race_robust.pccl", "programs/race.toml", {"blackbox": "straight"}),
    ("programs/formation.pccl", "programs/formation.toml", {"blackbox": "straight"}),
    ("programs/leader.pccl", None, {}),
    ("programs/collide.pccl", "programs/collide.toml", {"blackbox": "straight"}),
    ("programs/fischer.pccl", None, {"overrides": {"k": "2"}}),
    ("tests/programs/token_ring.pccl", None, {}),
    ("tests/programs/eng_lock.pccl", None, {}),
    ("tests/programs/peterson_swapped.pccl", None, {}),
]


@pytest.mark.parametrize("program,world,kw", SHIPPED, ids=[p for p, _, _ in SHIPPED])
def test_no_false_alarm_on_shipped_programs(program, world, kw):
    args = dict(kw)
    if world:
        args["world"] = str(ROOT / world)
    res = explore(str(ROOT / program), **args)
    assert res.status == "exhaustive" and res.exit_status == 0, res.verdict
    assert not any("frozen" in n for n in res.notes)      # the check ran
