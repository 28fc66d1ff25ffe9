"""Koord's round semantics (``semantics="koord"``, pccl/model/koord.py;
docs/koord.md, "Semantics"): EventTrans, IDLE, SkipEvent, round-consistent
shared memory, ``atomic:`` as a per-round mutex; verdicts that differ from
PCCL's semantics as the rules predict; engines, workers and replay agree;
the option errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from pccl.api import explore, make_model, run
from pccl.cli import main
from pccl.lang.errors import PcclError
from pccl.model.koord import RND, KoordModel
from pccl.model.layout import AGS, CNT, LOC, LQ, PHASE, SH, DISCRETE

from conftest import reachable

ROOT = Path(__file__).resolve().parents[2]
KOORD = ROOT / "programs" / "koord"


def k(name: str) -> str:
    return str(KOORD / name)


LOST = k("add_numbers_lost.koord")
INV = "noLostUpdate"


def _succ(m, st):
    return [(lab, s2) for lab, s2 in m.successors(st)]


def _first(m, st, rule, agent):
    hits = [s2 for lab, s2 in m.successors(st) if lab[0] == rule and lab[1] == agent]
    assert hits, (rule, agent, [lab for lab, _ in m.successors(st)])
    return hits[0]


# --------------------------------------------------------------------------
# The rules, one configuration at a time
# --------------------------------------------------------------------------

def test_koord_files_default_to_the_round_semantics():
    m = make_model(LOST)
    assert m.semantics == "koord" and isinstance(m.model, KoordModel)
    assert make_model(LOST, semantics="pccl").semantics == "pccl"
    st = next(iter(m.init_states()))
    assert len(st) == RND + 1 and st[RND] is None


def test_an_event_is_one_transition_and_reads_the_round_start():
    """EventTrans: robot 0's whole event is one step; robot 1, acting
    later in the same round, reads the sum of the round's start (0), so its
    write (1 + 1) overwrites robot 0's: the lost update, step by step."""
    m = make_model(LOST)
    st0 = next(iter(m.init_states()))
    labels = sorted(lab for lab, _ in m.successors(st0))
    assert labels == [("EVENT TRANS", 0, 0), ("EVENT TRANS", 1, 0)]
    st1 = _first(m, st0, "EVENT TRANS", 0)
    assert st1[SH] == (1,) and st1[AGS][0][CNT] == 1
    assert st1[RND] == ((0,), ((), ()))                  # the round started with sum = 0
    # robot 0 has acted: it has no transition left in this round
    assert {lab[1] for lab, _ in m.successors(st1)} == {1}
    st2 = _first(m, st1, "EVENT TRANS", 1)
    assert st2[SH] == (2,)                               # 0 + 1 + 1, not 1 + 1 + 1
    # the round ends: TIME ADVANCE (copies refreshed), then the environment
    (lab, st3), = m.successors(st2)
    assert lab[0] == "TIME ADVANCE" and st3[RND] is None and st3[LQ] == ()
    (lab, st4), = m.successors(st3)
    assert lab[0] == "DOREACH INVOKE" and st4[PHASE] == DISCRETE
    assert all(ag[CNT] == 0 for ag in st4[AGS])


def test_the_same_steps_under_pccl_lose_nothing():
    m = make_model(LOST, semantics="pccl")
    st = next(iter(m.init_states()))
    assert len(st) == RND                               # no round cell
    assert {lab[0] for lab, _ in m.successors(st)} == {"EVENT SELECT"}


def test_atomic_is_a_per_round_mutex():
    """The first robot of a round that enters `atomic:` holds the round's
    mutex; a later robot's event that would enter one is not performed
    (ATOMIC WAIT: nothing changes but its turn) and runs next round."""
    m = make_model(k("add_numbers.koord"))
    st0 = next(iter(m.init_states()))
    st1 = _first(m, st0, "EVENT TRANS", 1)
    assert st1[LQ] == (1,) and st1[SH] == (1, 1)           # sum = 0 + 1, numAdded = 1
    (lab, st2), = m.successors(st1)
    assert lab[0] == "ATOMIC WAIT" and lab[1] == 0
    assert st2[SH] == st1[SH] and st2[AGS][0][CNT] == 1
    assert st2[AGS][0][:CNT] == st1[AGS][0][:CNT] and st2[AGS][0][CNT + 1:] == st1[AGS][0][CNT + 1:]
    st3 = m.successors(m.successors(st2)[0][1])[0][1]      # TIME ADVANCE, DOREACH INVOKE
    assert st3[LQ] == ()
    st4 = _first(m, st3, "EVENT TRANS", 0)                 # next round: robot 0 adds
    assert st4[SH] == (1, 2)


def test_skip_event_lets_a_round_pass():
    m = make_model(LOST, skip_events=True)
    st0 = next(iter(m.init_states()))
    labels = sorted(lab for lab, _ in m.successors(st0))
    assert ("SKIP EVENT", 0, None) in labels and ("SKIP EVENT", 1, None) in labels
    skipped = _first(m, st0, "SKIP EVENT", 0)
    assert skipped[SH] == st0[SH] and skipped[AGS][0][CNT] == 1 and skipped[RND] is None


def test_idle_when_no_event_is_enabled():
    src = ("allwrite:\n  int x = 0\n\nbump:\n  pre: x < 0\n  eff:\n    x = 1\n")
    m = make_model(_write(src, "idle.koord"))
    st = next(iter(m.init_states()))
    assert sorted(lab for lab, _ in m.successors(st)) == [("IDLE", 0, None), ("IDLE", 1, None)]


_TMP: list = []


def _write(src: str, name: str) -> str:
    import tempfile
    d = Path(tempfile.mkdtemp())
    _TMP.append(d)
    p = d / name
    p.write_text(src)
    return str(p)


def test_an_event_that_never_ends_gets_its_robot_stuck(monkeypatch):
    src = ("local:\n  int i = 0\n\nspin:\n  pre: true\n  eff:\n"
           "    for i in range(0, 2):\n      i = 0\n")
    monkeypatch.setattr(KoordModel, "EVENT_STEPS", 200)
    r = explore(_write(src, "spin.koord"), agents=1)
    assert r.status == "violation" and r.violation.kind == "stuck"
    assert "did not end within 200 steps" in r.violation.message


# --------------------------------------------------------------------------
# Verdicts: the two semantics disagree as the rules predict
# --------------------------------------------------------------------------

@pytest.mark.parametrize("agents", [2, 3])
def test_lost_update_under_koord_not_under_pccl(agents):
    kd = explore(LOST, agents=agents)
    assert kd.status == "violation" and kd.violation.name == INV and kd.exit_status == 1
    # the shortest counterexample: every robot adds in the first round
    assert [s.rule for s in kd.trace] == ["EVENT TRANS"] * agents
    assert {s.time for s in kd.trace} == {0}
    pc = explore(LOST, agents=agents, semantics="pccl")
    assert pc.status == "exhaustive" and pc.exit_status == 0


@pytest.mark.parametrize("agents", [2, 3])
def test_atomic_add_numbers_holds_under_both(agents):
    for sem in ("koord", "pccl"):
        r = explore(k("add_numbers.koord"), agents=agents, semantics=sem)
        assert r.status == "exhaustive" and r.exit_status == 0, sem


def test_skip_events_adds_the_runs_where_a_robot_waits():
    src = ("local:\n  boolean added = false\n\nadd:\n  pre: not added\n  eff:\n"
           "    added = true\n\nfinish:\n  pre: added\n  eff:\n    stop\n")
    p = _write(src, "once.koord")
    inv = ["time >= 1 -> (forall i: added[i])"]
    assert explore(p, invariants=inv).status == "exhaustive"
    r = explore(p, invariants=inv, skip_events=True)
    assert r.status == "violation"
    assert "SKIP EVENT" in [s.rule for s in r.trace]


def test_events_first_is_the_runtime_choice():
    src = ("allwrite:\n  int x = 0\n\na:\n  pre: x == 0\n  eff:\n    x = 1\n\n"
           "b:\n  pre: x == 0\n  eff:\n    x = 2\n\nc:\n  pre: x != 0\n  eff:\n    stop\n\n"
           "invariant:\n  never2: x != 2\n")
    p = _write(src, "first.koord")
    assert explore(p, agents=1).status == "violation"
    assert explore(p, agents=1, events="first").status == "exhaustive"


def test_fischer_under_the_round_semantics():
    assert explore(k("fischer.koord"), agents=2).status == "exhaustive"
    bad = explore(k("fischer.koord"), agents=2, overrides={"k": "3"})
    assert bad.status == "violation" and bad.violation.name == "mutex"


# --------------------------------------------------------------------------
# Engines, workers, reductions, replay agree
# --------------------------------------------------------------------------

def _figures(r):
    return r.status, r.stats.states, r.stats.transitions, r.stats.max_depth


@pytest.mark.parametrize("name,agents", [("add_numbers.koord", 3), ("fischer.koord", 2)])
def test_engines_workers_and_reduce_requests_agree(name, agents):
    base = explore(k(name), agents=agents, engine="python", reduce="none")
    assert _figures(explore(k(name), agents=agents, reduce="none")) == _figures(base)
    assert _figures(explore(k(name), agents=agents, workers=2, reduce="none")) == _figures(base)
    assert _figures(explore(k(name), agents=agents, exact=True, reduce="none")) == _figures(base)
    # symmetry (on by default where sound): the same figures with and without workers
    red = explore(k(name), agents=agents)
    assert red.status == base.status
    assert _figures(explore(k(name), agents=agents, workers=2)) == _figures(red)


def test_native_engine_and_reductions_say_why_not():
    res = CliRunner().invoke(main, ["explore", LOST])
    head = res.output.splitlines()[0]
    assert "merge, por, counters off: not argued for Koord's round" in head
    assert "engine python" in head and "not Koord's round semantics (--semantics koord)" in head
    res = CliRunner().invoke(main, ["explore", LOST, "--engine", "native"])
    assert res.exit_code == 2 and "native engine cannot run this search" in res.output
    res = CliRunner().invoke(main, ["explore", LOST, "--reduce", "por"])
    assert res.exit_code == 2 and "not argued for Koord's round semantics" in res.output


def test_counterexample_replays_with_the_round_cell(tmp_path):
    trace = tmp_path / "lost.json"
    res = CliRunner().invoke(main, ["explore", LOST, "--trace-out", str(trace)])
    assert res.exit_code == 1
    assert "round start (what robots still to act in this round read): sum = 0" in res.output
    doc = json.loads(trace.read_text())
    assert doc["config"]["options"]["semantics"] is None
    assert doc["final"]["round"] == {"shared": {"sum": 0}, "allread": [{}, {}]}
    assert any(ch["cell"] == {"cell": "round"} for st in doc["steps"] for ch in st["changes"])
    rep = CliRunner().invoke(main, ["replay", str(trace)])
    assert rep.exit_code == 1 and f"reproduced: invariant '{INV}' violated" in rep.output
    # the same file, its round cell edited: replay sees the difference
    doc["final"]["round"]["shared"]["sum"] = 5
    trace.write_text(json.dumps(doc))
    assert CliRunner().invoke(main, ["replay", str(trace)]).exit_code == 2


def test_runs_take_the_semantics():
    out = run(LOST, agents=3, seed=1, record_trace=True)
    assert out.status == "violation"
    ok = run(LOST, agents=3, seed=1, semantics="pccl")
    assert ok.status == "final"


# --------------------------------------------------------------------------
# Options: what fits, what does not (exit 2, one message)
# --------------------------------------------------------------------------

def test_pccl_programs_reject_the_koord_semantics():
    res = CliRunner().invoke(main, ["explore", str(ROOT / "programs" / "fischer.pccl"),
                                    "--semantics", "koord"])
    assert res.exit_code == 2
    assert "--semantics koord is Koord's execution model" in res.output
    assert "applies to Koord programs (.koord, .krd, or --lang koord) only" in res.output
    with pytest.raises(PcclError, match="semantics=koord is Koord's execution model"):
        make_model(str(ROOT / "programs" / "fischer.pccl"), semantics="koord")


@pytest.mark.parametrize("args,text", [
    (["--n0", "2"], "--n0 does not apply under Koord's round semantics"),
    (["--n0", "2", "--rate", "1=2"], "--n0 does not apply"),
    (["--semantics", "pccl", "--skip-events"], "--skip-events is Koord's SkipEvent rule"),
])
def test_options_that_do_not_fit(args, text):
    for cmd in ("explore", "run"):
        res = CliRunner().invoke(main, [cmd, LOST, *args])
        assert res.exit_code == 2 and text in res.output, (cmd, res.output)
        assert "Traceback" not in res.output


def test_coverage_is_counted_under_koord():
    """(It was refused; tests/output/test_koord_coverage.py checks the counts.)"""
    res = CliRunner().invoke(main, ["explore", LOST, "--coverage"])
    assert res.exit_code == 1 and "coverage (" in res.output, res.output


# --------------------------------------------------------------------------
# Cross-check with PCCL's semantics at the rounds' boundaries
# --------------------------------------------------------------------------

def _round_starts(m, cap: int = 200_000) -> set:
    """Every reachable configuration in which no running agent is inside an
    event (discrete, every counter 0, every running agent at the top of its
    event block), without the round cell: a plain search over
    ``m.successors`` (``m`` unreduced)."""
    from pccl.model.layout import PC, RUNNING, STATUS
    empty = m.ctl.empty_pc
    seen, todo, starts = set(), list(m.init_states()), set()
    while todo:
        st = todo.pop()
        if st in seen:
            continue
        seen.add(st)
        assert len(seen) < cap
        ags = st[AGS]
        if st[PHASE] == DISCRETE and all(ag[CNT] == 0 and (ag[STATUS] != RUNNING
                                                           or ag[PC] == empty) for ag in ags):
            starts.add(st[:RND])
        todo.extend(s2 for _, s2 in m.successors(st))
    return starts


def test_own_variables_only_same_rounds_under_both():
    """A program whose events touch only the robot's own variables (and its
    motion): PCCL's statements interleave inside a round, but every round
    ends where Koord's one-transition events end.  The round-start
    configurations of the two semantics are the same set."""
    opts = dict(world=str(KOORD / "allstop.toml"), agents=2, blackbox="straight",
                abstract_time=False, reduce="none")
    kd = _round_starts(make_model(k("follow.koord"), **opts))
    pc = _round_starts(make_model(k("follow.koord"), semantics="pccl", **opts))
    assert len(kd) > 5 and kd == pc


def test_reading_others_only_koord_rounds_are_pccl_rounds():
    """Robots that read the others' allread entries and write only their own
    (line formation): every round of Koord's semantics (reads of the round's
    start) is a round of PCCL's (in which every robot may read before any
    writes); PCCL may have more (a read after another robot's write; not
    here, where only the middle robot writes)."""
    opts = dict(world=str(KOORD / "lineform.toml"), blackbox="straight", abstract_time=False,
                reduce="none")
    kd = _round_starts(make_model(k("lineform.koord"), **opts))
    pc = _round_starts(make_model(k("lineform.koord"), semantics="pccl", **opts))
    assert len(kd) > 3 and kd <= pc


def test_writes_merge_per_variable_last_writer_wins():
    """Robot 0 writes `a`, robot 1 writes `b`, both `c` (different values),
    in one round: the global store gets both `a` and `b` (a robot's event
    writes back only what it assigned) and the last writer's `c`."""
    src = ("allwrite:\n  int a = 0\n  int b = 0\n  int c = 0\n\nlocal:\n  boolean done = false\n\n"
           "go:\n  pre: not done\n  eff:\n    if pid == 0:\n      a = 1\n    else:\n      b = 1\n"
           "    c = pid + 5\n    done = true\n")
    m = make_model(_write(src, "merge.koord"))
    st0 = next(iter(m.init_states()))
    first0 = _first(m, _first(m, st0, "EVENT TRANS", 0), "EVENT TRANS", 1)
    first1 = _first(m, _first(m, st0, "EVENT TRANS", 1), "EVENT TRANS", 0)
    assert first0[SH] == (1, 1, 6) and first1[SH] == (1, 1, 5)
    assert first0[RND] == ((0, 0, 0), ((), ()))


def test_runs_draw_rand_afresh_in_every_round():
    """Under `run` rand is sampled: a robot's turn is not remembered
    (KoordModel's turn table serves the search only), so from x = 0 a run
    sees both outcomes of the next draw."""
    src = "local:\n  int x = 0\n\nflip:\n  pre: true\n  eff:\n    x = rand(1)\n"
    out = run(_write(src, "flip.koord"), agents=1, seed=3, max_time=60, record_trace=True)
    draws = [after[AGS][0][LOC][0] for lab, after in zip(out.trace.labels, out.trace.states[1:])
             if lab[0] == "EVENT TRANS"]
    assert len(draws) >= 50
    assert {b for a, b in zip(draws, draws[1:]) if a == 0} == {0, 1}


# --------------------------------------------------------------------------
# Symmetry under the round semantics
# --------------------------------------------------------------------------

def _canonical(m, slots):
    """A brute-force canonical form of a round-semantics state under every
    permutation of the robots (written here, apart from pccl's symmetric
    key): the agents reordered, the agent ids in the id slots, the lock
    queue and the round cell renamed; positions left out (the programs
    below do not move)."""
    import itertools
    loc_s, ar_s, sh_s = slots[0], slots[1], slots[2]

    def ren(vals, idx, perm):
        v = list(vals)
        for k in idx:
            if type(v[k]) is int and v[k] >= 0:
                v[k] = perm[v[k]]
        return tuple(v)

    def form(st, perm):
        inv = sorted(range(len(perm)), key=lambda j: perm[j])     # new place -> old agent
        ags = tuple(st[AGS][j][:LOC] + (ren(st[AGS][j][LOC], loc_s, perm),
                                         ren(st[AGS][j][LOC + 1], ar_s, perm))
                    for j in inv)
        rnd = st[RND]
        if rnd is not None:
            rnd = (ren(rnd[0], sh_s, perm), tuple(ren(rnd[1][j], ar_s, perm) for j in inv))
        return (st[PHASE], tuple(perm[j] for j in st[LQ]), ren(st[SH], sh_s, perm), ags, rnd)

    def canon(st):
        return min((form(st, perm) for perm in itertools.permutations(range(m.N))), key=repr)
    return canon


CLAIM = """\
allwrite:
  int owner = -1
  int claims = 0

allread:
  boolean holds[]

local:
  boolean done = false

claim:
  pre: not done and owner == -1
  eff:
    atomic:
      owner = pid
      claims = claims + 1
    holds[pid] = true

release:
  pre: owner == pid
  eff:
    owner = -1
    holds[pid] = false
    done = true
"""


@pytest.mark.parametrize("name,agents,over", [
    ("fischer.koord", 3, {}), ("fischer.koord", 3, {"k": "3"}), ("claim", 3, {})])
def test_symmetry_covers_every_orbit(name, agents, over):
    """The symmetric search reaches a state of every orbit (under robot
    permutations) that the plain search reaches, and no other orbit: the
    canonical forms (computed by brute force here) of the states each
    search stores are the same set, and the symmetric search stores fewer."""
    from pccl.model.reduce import symmetry_problem
    path = _write(CLAIM, "claim.koord") if name == "claim" else k(name)
    red = make_model(path, agents=agents, overrides=over)
    assert "symmetry" in red.reduction.on, red.reduction.describe()
    plain = make_model(path, agents=agents, overrides=over, reduce="none")
    why, slots = symmetry_problem(plain.model)
    assert why is None
    canon = _canonical(plain.model, slots)
    reduced = reachable(red, limit=1 << 40)      # one state per key: what each search stores
    every = reachable(plain, limit=1 << 40)
    assert {canon(st) for st in reduced} == {canon(st) for st in every}
    assert len(reduced) < len(every)


@pytest.mark.parametrize("name,agents,over", [
    ("fischer.koord", 3, {"k": "3"}), ("add_numbers_lost.koord", 3, {}),
    ("fischer.koord", 3, {}), ("add_numbers.koord", 3, {})])
def test_symmetry_keeps_verdicts_and_shortest_counterexamples(name, agents, over):
    red = explore(k(name), agents=agents, overrides=over)
    plain = explore(k(name), agents=agents, overrides=over, reduce="none")
    assert red.status == plain.status
    if plain.violation is not None:
        assert red.violation.name == plain.violation.name
        assert len(red.trace) == len(plain.trace)
    else:
        assert red.stats.states <= plain.stats.states
        assert name != "fischer.koord" or red.stats.states < plain.stats.states
