"""The frozen-team check over the search's own graph against the
re-exploration it replaced (pccl/model/frozen.py: ``check_recorded`` and
``check``; docs/reductions.md, "Frozen teams").

``check`` (a second breadth-first search of the reduced model, in Python)
stays as the reference: each case is explored twice, once with the check
over the recorded graph (``check`` made to fail, so that a fall-back would
show) and once with ``PCCL_FROZEN_GRAPH=0`` and no state limit (the
re-exploration), and everything the user sees must agree: status, verdict,
violations, the frozen team's trace (states and labels), the notes and the
figures.  Over the shipped and test programs, on both engines, reduced and
unreduced, one thread and two, and over generated programs of the
differential oracle (tests/differential/gen.py).
"""

from __future__ import annotations

import pytest

from pccl.api import explore
from pccl.model import frozen as F

from cases import FROZEN_BUSY, FROZEN_ONE_SHOT
from conftest import PROGRAMS, TEST_PROGRAMS

pytestmark = pytest.mark.slow     # every case explores twice

PATROL = str(TEST_PROGRAMS / "patrol.pccl")

#: a one-shot event in a team that makes progress (not frozen), and a busy
#: wait on a token value nobody holds (frozen): tests/cases.py's
ONE_SHOT, BUSY = FROZEN_ONE_SHOT, FROZEN_BUSY


def _boom(*a, **k):
    raise AssertionError("the frozen-team check explored again")


def _seen(res) -> tuple:
    """What a result shows of the check: everything but the seconds."""
    cxs = []
    for cx in res.counterexamples:
        tr = cx.trace
        cxs.append((cx.violation.kind, cx.violation.message,
                    None if tr is None else (tuple(tr.labels), tuple(tr.states))))
    s = res.stats
    return (res.status, res.exit_status, res.verdict, tuple(cxs), tuple(res.notes),
            (s.states, s.transitions, s.max_depth))


def both(monkeypatch, program: str, *, strict: bool = True, **kw) -> tuple:
    """(over the graph, explored again) for one search; ``strict``: the
    first may not explore again (else it may: ``--workers 2`` runs as
    processes where threads cannot serve the program, and those record no
    labels)."""
    with monkeypatch.context() as mp:
        if strict:
            mp.setattr(F, "check", _boom)
        new = explore(program, **kw)
    with monkeypatch.context() as mp:
        mp.setenv("PCCL_FROZEN_GRAPH", "0")
        mp.setattr(F, "LIMIT", 10**7)
        old = explore(program, **kw)
    return new, old


def frozen(res) -> bool:
    return any(v.kind == "frozen" for v in res.violations)


# (program, options); the patrol cases are frozen, the others clean
CASES = [
    ("patrol-pillar", PATROL, dict(world=str(TEST_PROGRAMS / "patrol_pillar.toml"),
                                   blackbox="straight")),
    ("patrol-four", PATROL, dict(world=str(TEST_PROGRAMS / "patrol4.toml"), blackbox="straight")),
    ("patrol-open", PATROL, dict(world=str(TEST_PROGRAMS / "patrol.toml"), blackbox="straight")),
    ("busy-wait", BUSY, dict(source=True)),
    ("one-shot", ONE_SHOT, dict(source=True)),
    ("race-straight", str(PROGRAMS / "race.pccl"),
     dict(world=str(PROGRAMS / "race.toml"), blackbox="straight")),
    ("race_robust-straight", str(PROGRAMS / "race_robust.pccl"),
     dict(world=str(PROGRAMS / "race.toml"), blackbox="straight")),
    ("collide-straight", str(PROGRAMS / "collide.pccl"),
     dict(world=str(PROGRAMS / "collide.toml"), blackbox="straight")),
    ("leader", str(PROGRAMS / "leader.pccl"), dict()),
    ("fischer-k1", str(PROGRAMS / "fischer.pccl"), dict(overrides={"k": "1", "cstime": "0"})),
    ("token_ring", str(TEST_PROGRAMS / "token_ring.pccl"), dict()),
    ("eng_lock", str(TEST_PROGRAMS / "eng_lock.pccl"), dict()),
    ("peterson_swapped", str(TEST_PROGRAMS / "peterson_swapped.pccl"), dict()),
    ("alternate", str(TEST_PROGRAMS / "alternate.pccl"), dict()),
    ("list_seen-2", str(TEST_PROGRAMS / "list_seen.pccl"), dict(agents=2)),
]
FROZEN = {"patrol-pillar", "patrol-four", "busy-wait"}
#: where the symmetry reduction is sound (asked for elsewhere, it is an error)
SYMMETRIC = {"race-straight", "race_robust-straight", "fischer-k1", "alternate", "list_seen-2"}

#: the cases ``--workers 2`` runs as threads of the level kernel (the others
#: as processes: robots that move, statements that call Python)
THREADED = {"fischer-k1", "busy-wait", "one-shot"}

#: how each case is searched: the engine, the reductions, the threads
WAYS = [
    ("native", dict()),
    ("python", dict(engine="python")),
    ("unreduced", dict(reduce="none")),
    ("symmetry", dict(reduce="merge,symmetry,por,dead")),
    ("threads", dict(workers=2)),
    # the native engine's batches, not its level kernel (which spilling turns off)
    ("batches", dict(spill=True)),
]


@pytest.mark.parametrize("name,program,kw,opts", [
    pytest.param(name, program, kw, opts, id=f"{name}-{way}")
    for name, program, kw in CASES for way, opts in WAYS
    if way != "symmetry" or name in SYMMETRIC])
def test_the_graph_check_agrees_with_the_re_exploration(monkeypatch, tmp_path, name, program, kw,
                                                        opts):
    if opts.get("spill"):
        opts = {**opts, "spill": str(tmp_path)}
    new, old = both(monkeypatch, program, strict="workers" not in opts or name in THREADED,
                    **kw, **opts)
    assert _seen(new) == _seen(old)
    if name in FROZEN:
        assert frozen(new), new.verdict
    else:
        assert not frozen(new), new.verdict


def test_the_graph_check_has_no_state_limit(monkeypatch):
    """The re-exploration stops at its limit; over the graph the check runs
    (and finds the same frozen team the re-exploration finds within a
    larger limit)."""
    kw = dict(world=str(TEST_PROGRAMS / "patrol4.toml"), blackbox="straight")
    monkeypatch.setattr(F, "LIMIT", 100)
    with monkeypatch.context() as mp:
        mp.setenv("PCCL_FROZEN_GRAPH", "0")
        limited = explore(PATROL, **kw)
    assert limited.status == "exhaustive"
    assert any(n.startswith("frozen teams not checked") for n in limited.notes)
    new, old = both(monkeypatch, PATROL, **kw)
    assert frozen(new) and _seen(new) == _seen(old)


def test_processes_fall_back_to_the_re_exploration(monkeypatch):
    """``--workers 2`` as processes records no labels: the check explores
    again (and says the same)."""
    monkeypatch.setenv("PCCL_THREADS", "0")
    kw = dict(world=str(TEST_PROGRAMS / "patrol_pillar.toml"), blackbox="straight", workers=2)
    calls = []
    real = F.check

    def counting(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(F, "check", counting)
    res = explore(PATROL, **kw)
    assert calls and frozen(res)
    one = explore(PATROL, **{**kw, "workers": 1})
    assert len(calls) == 1              # one process: over the graph
    assert [v.message for v in res.violations] == [v.message for v in one.violations]


@pytest.mark.parametrize("seed", range(24))
def test_generated_programs_agree(monkeypatch, seed):
    """Programs of the differential oracle's generator."""
    from differential import gen, oracle
    case = gen.case(seed, families=("core", "sym", "por"))
    files = oracle.Files(case)
    try:
        kw = oracle.base_kw(case, files)        # the source given as text
        kw.update(find_all=False, max_states=20_000)
        try:
            new, old = both(monkeypatch, case.text, **kw)
        except Exception as e:          # a program the search rejects: both reject it
            with pytest.raises(type(e)):
                explore(case.text, **kw)
            return
        assert _seen(new) == _seen(old)
    finally:
        files.close()


#: a team that stops changing once each agent has started: a stall, which
#: the stall check reports (the frozen-team check then does not run)
STALLED = """\
allwrite:
  int x = 0;
loc:
  bool started = false;
Start():
  pre(!started);
  eff:
    started = true;
"""


@pytest.mark.parametrize("name,program,kw", [
    ("busy-wait", BUSY, dict(source=True)),
    ("one-shot", ONE_SHOT, dict(source=True)),
    ("fischer-k1", str(PROGRAMS / "fischer.pccl"), dict(overrides={"k": "1", "cstime": "0"})),
    ("stalled", STALLED, dict(source=True)),
])
def test_threads_decide_beside_the_other_checks(monkeypatch, name, program, kw):
    """With ``--workers 2`` on the level kernel the frozen-team decision runs
    on a thread of its own beside the time-lock and stall checks
    (pccl.api._frozen_beside); with one worker on the search's thread.
    Everything the user sees is one worker's: a frozen team found, a clean
    search, and a stall found by the other checks (the decision made on
    the side is dropped, the frozen-team check does not run)."""
    import threading
    where: list = []
    real = F.decide_recorded

    def spy(*a, **k):
        where.append(threading.current_thread() is threading.main_thread())
        return real(*a, **k)

    monkeypatch.setattr(F, "decide_recorded", spy)
    monkeypatch.setattr(F, "check", _boom)
    one = explore(program, **kw)
    assert where == ([] if name == "stalled" else [True])
    where.clear()
    two = explore(program, workers=2, **kw)
    assert where == [False]             # started before the other checks, on its thread
    assert _seen(two) == _seen(one)
    assert frozen(two) == (name == "busy-wait")
    assert (name == "stalled") == any(v.kind == "stall" for v in two.violations)
