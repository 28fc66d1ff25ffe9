"""The native engine's level kernel (``explore_levels``, pccl/model/native.py):
levels expanded, fingerprinted and admitted in C, on one thread or several.

The reference is the explorer's own batches (the same native model with the
kernel hidden): the kernel must admit the same states under the same
numbers with the same parents, whatever the threads, and stop where the
batches stop (violations, state budgets, depth bounds, states without
successors).  ``--workers N`` runs as N threads where the search records
no graph; the results are those of one worker."""

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as hs

from pccl.api import explore, make_model
from pccl.model import native as NV
from pccl.search import liveness as L
from pccl.search import explorer as EX
from pccl.search.explorer import Explorer

from cases import programs

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
FISCHER = os.path.join(ROOT, "programs/fischer.pccl")
_probe = make_model(FISCHER, reduce="none")
MISSING = NV.unsupported(_probe)
pytestmark = pytest.mark.skipif(MISSING is not None, reason=f"native engine unavailable: {MISSING}")

NOGRAPH = dict(timelock=False, stall=False)


@pytest.fixture(autouse=True)
def _shared(request, monkeypatch):
    """Every level shared between the threads (the search runs levels under
    SHARED_LEVEL states on one thread): the small programs here exercise the
    threads too.  A test marked ``real_shared_level`` keeps the real bound."""
    if "real_shared_level" not in request.keywords:
        monkeypatch.setattr(EX, "SHARED_LEVEL", 1)


class Batches:
    """A native model with its level kernel hidden: the explorer's batches."""

    def __init__(self, nm):
        self.nm = nm

    def __getattr__(self, name):
        if name == "explore_levels":
            return None
        return getattr(self.nm, name)


class Counted:
    """A native model whose kernel counts the states it admits, why it
    stopped and the levels it went on into (to show the kernel ran, not
    only the batches)."""

    def __init__(self, nm):
        self.nm, self.admitted, self.stops, self.crossed = nm, 0, set(), 0

    def explore_levels(self, *a):
        r = self.nm.explore_levels(*a)
        self.admitted += r[10]
        self.stops.add(r[2])
        self.crossed += r[0]
        return r

    def __getattr__(self, name):
        return getattr(self.nm, name)


def search(model, threads=1, **kw) -> tuple:
    """Everything a search says, and its table's arrays (numbers, parents)."""
    labels: set = set()
    ex = Explorer(model, batch=NV.NativeModel.BATCH, labels=labels, threads=threads, **kw)
    r = ex.run()
    s = r.stats
    n = ex.table.n
    return ((r.status, s.initial_states, s.states, s.transitions, s.max_depth, s.max_time,
             sorted(b.name for b in r.bounds_hit), sorted(map(repr, labels)),
             [(f.violation.identity, f.violation.message, f.trace.labels, f.trace.states)
              for f in r.found]),
            ex.table.fps[:n].copy(), ex.table.parents[:n].copy())


def assert_same(got, want) -> None:
    assert got[0] == want[0]
    assert np.array_equal(got[1], want[1])          # each state under the same number
    assert np.array_equal(got[2], want[2])          # ... with the same parent


def native(path, **kw):
    return NV.NativeModel(make_model(path, **kw))


CASES = [
    ("fischer 3 agents, reduced", FISCHER,
     dict(agents=3, overrides={"k": "0", "d": "1"})),
    ("fischer unreduced, violated", FISCHER,
     dict(reduce="none", overrides={"k": "1", "d": "1"}, invariants=("count(inCs) <= 1",))),
    ("leader", os.path.join(ROOT, "programs/leader.pccl"), dict(agents=3)),
    ("token ring", os.path.join(ROOT, "tests/programs/token_ring.pccl"), dict(agents=3)),
    ("exits", os.path.join(ROOT, "tests/programs/eng_flags.pccl"), dict(agents=3)),
    ("mutex violated", os.path.join(ROOT, "tests/programs/ref_mutex_bad.pccl"), dict(agents=3)),
    ("assertions", os.path.join(ROOT, "tests/programs/eng_assert.pccl"), dict(agents=2)),
]


@pytest.mark.parametrize("name, path, kw", CASES, ids=[c[0].replace(" ", "-").replace(",", "") for c in CASES])
@pytest.mark.parametrize("find_all", [False, True])
def test_kernel_admits_what_the_batches_admit(name, path, kw, find_all):
    nm = native(path, **kw)
    assert nm.explore_levels is not None
    want = search(Batches(nm), find_all=find_all)
    assert want[0][2] > 50 or want[0][0] == "violation"
    for threads in (1, 2, 3):
        c = Counted(nm)
        assert_same(search(c, threads, find_all=find_all), want)
        assert c.admitted > 0 or want[0][2] - want[0][1] < 200


def record(model, threads=1, stall=True, **kw) -> tuple:
    """A search with the graph recorder of the time-lock (and stall) checks:
    its figures and every array of the graph."""
    rec = L.make_recorder(model.nm, True, stall)
    ex = Explorer(model, batch=NV.NativeModel.BATCH, recorder=rec, threads=threads, **kw)
    r = ex.run()
    return ((r.status, r.stats.states, r.stats.transitions, rec.complete),
            {"src": rec.src.view().copy(), "dst": rec.dst.view().copy(),
             **{k: g.view().copy() for k, g in rec._columns().items()}})


@pytest.mark.parametrize("name, path, kw", CASES, ids=[c[0].replace(" ", "-").replace(",", "") for c in CASES])
@pytest.mark.parametrize("stall", [True, False])
def test_kernel_records_what_the_batches_record(name, path, kw, stall):
    """The graph the kernel records (each transition's source and target,
    each state's time cost, stall signature and change flag) is the
    batches' graph, array for array, for 1, 2 and 3 threads; under
    symmetry (fischer, leader) a change is decided on the successor as
    made, without it on the state its number stands for."""
    nm = native(path, **kw)
    want = record(Batches(nm), stall=stall)
    assert set(want[1]) == ({"src", "dst", "dyn", "sig", "chg"} if stall else {"src", "dst", "dyn"})
    assert len(want[1]["src"]) == want[0][2] or want[0][0] == "violation"
    for threads in (1, 2, 3):
        c = Counted(nm)
        got = record(c, threads, stall=stall)
        assert got[0] == want[0]
        for k, a in want[1].items():
            assert np.array_equal(got[1][k], a), k
        assert c.admitted > 0 or want[0][1] < 200


RACE = os.path.join(ROOT, "programs/race.toml")
MOVING = [("race_robust 3 robots", "programs/race_robust.pccl", 3),
          ("race_safe 3 robots", "programs/race_safe.pccl", 3),
          ("race violated", "programs/race.pccl", 2)]


@pytest.mark.parametrize("name, path, agents", MOVING, ids=[c[0].replace(" ", "-") for c in MOVING])
@pytest.mark.parametrize("graph", [False, True])
def test_kernel_on_programs_that_move(name, path, agents, graph, monkeypatch):
    """Memo sites (DOREACH INVOKE's outcomes under nondet) call Python on a
    miss: in the kernel the thread takes the GIL for it, the memo's lock
    held alone, while the other threads read the memo shared.  Each search
    starts from an empty memo (a fresh model), so the misses happen in the
    kernel's threads; the result is the batches': figures, labels, every
    state's parent, the violations with their traces (decoded: the values
    interned in the order the misses came), the recorded graph.  Only the
    calling thread fills a miss (the others give their chunk up).  Last, 2
    threads whose other thread is slow (1 ms a chunk): the calling thread
    makes the chunks it holds, misses included."""
    def fresh():
        return native(os.path.join(ROOT, path), agents=agents, world=RACE, blackbox="nondet")

    def run(model, nm, threads=1):
        rec = L.make_recorder(nm, True, True) if graph else None
        labels: set = set()
        ex = Explorer(model, batch=NV.NativeModel.BATCH, recorder=rec, labels=labels,
                      threads=threads)
        r = ex.run()
        s = r.stats
        arrays = {"parents": ex.table.parents[:ex.table.n].copy()}
        if rec is not None:
            arrays.update(src=rec.src.view().copy(), dst=rec.dst.view().copy(),
                          **{k: g.view().copy() for k, g in rec._columns().items() if k != "sig"})
        return ((r.status, s.initial_states, s.states, s.transitions, s.max_depth, s.max_time,
                 sorted(map(repr, labels)),
                 [(f.violation.message, f.trace.labels, nm.decode_trace(f.trace).states)
                  for f in r.found]), arrays)
    nm = fresh()
    want = run(Batches(nm), nm)
    assert nm.lib.memo_stats()[1] > 0          # (misses: the memo filled as it went)
    for threads, slow in ((1, None), (2, None), (3, None), (2, "1")):
        if slow:
            monkeypatch.setenv("PCCL_KERNEL_SLOW_HELPERS", slow)
        nm = fresh()
        c = Counted(nm)
        got = run(c, nm, threads)
        assert got[0] == want[0]
        for k, a in want[1].items():
            assert np.array_equal(got[1][k], a), k
        assert c.admitted > want[0][2] // 2
        assert nm.lib.memo_stats()[1] > 0
        assert 6 not in c.stops         # (a chunk given up at a miss is the kernel's own)
    # (whether another thread met a miss and left its chunk to the calling
    # thread depends on the scheduling: a search whose levels stay under
    # the shared-level size never wakes the others; the equalities above
    # hold either way, and remade chunks are counted in ex.kernel_dups)


@pytest.mark.parametrize("threads", [1, 2])
def test_interrupt_in_a_memo_miss_stops_the_kernel(threads, monkeypatch):
    """Ctrl-C (or SIGTERM, which pccl turns into the same KeyboardInterrupt)
    may be raised inside a memo miss's Python code, which the kernel calls:
    it stops the kernel, whose figures are taken, and is raised then; the
    search reports itself interrupted with consistent figures (it was
    swallowed, and the search ran on to the end).  (DOREACH INVOKE's
    misses in Python: the shipped blackbox's C off.)"""
    monkeypatch.setenv("PCCL_C_BLACKBOX", "0")
    class Interrupted(NV.NativeModel):
        calls = 0

        def _miss(self, k, b):
            Interrupted.calls += 1
            if Interrupted.calls == 400:
                raise KeyboardInterrupt
            return super()._miss(k, b)
    nm = Interrupted(make_model(os.path.join(ROOT, "programs/race_robust.pccl"), agents=3,
                                world=RACE, blackbox="nondet"))
    c = Counted(nm)
    ex = Explorer(c, batch=NV.NativeModel.BATCH, threads=threads)
    r = ex.run()
    assert Interrupted.calls >= 400 and c.admitted > 0
    assert r.status == "interrupted"
    assert r.stats.states == ex.table.n < 226_455


def test_kernel_records_across_a_grown_edge_array(monkeypatch):
    """Where the recorder's arrays cannot be reserved they grow by doubling:
    the kernel stops when the transitions fill them (why 5), they grow, it
    goes on, and the graph is the batches'."""
    from pccl.search import explorer
    monkeypatch.setattr(explorer, "_reserve", lambda shape, dtype: None)
    nm = native(FISCHER, agents=3, overrides={"k": "0", "d": "1"}, reduce="merge,symmetry,por")
    want = record(Batches(nm))
    c = Counted(nm)
    got = record(c, 2)
    assert 5 in c.stops
    assert got[0] == want[0]
    for k, a in want[1].items():
        assert np.array_equal(got[1][k], a), k


@pytest.mark.parametrize("bound", [dict(max_states=1), dict(max_states=5_000),
                                   dict(max_states=33_333), dict(max_depth=1),
                                   dict(max_depth=40)])
def test_kernel_stops_where_the_batches_stop(bound):
    """A state budget met mid-level, mid-chunk; a depth bound."""
    nm = native(FISCHER, reduce="none", overrides={"k": "1", "d": "1"})
    want = search(Batches(nm), **bound)
    assert want[0][0] == "bounded"
    for threads in (1, 2):
        c = Counted(nm)
        assert_same(search(c, threads, **bound), want)
        if "max_states" in bound and bound["max_states"] > 1:
            assert 3 in c.stops             # stopped for the budget: the batches cut it


def test_kernel_grows_the_table_as_it_admits():
    """A search of 100,000s of states: the index is rebuilt several times
    between the kernel's calls (it stops for room and is called again)."""
    nm = native(FISCHER, agents=3, overrides={"k": "1", "d": "1"}, reduce="merge,symmetry,por")
    want = search(Batches(nm))
    assert want[0][2] > 200_000
    c = Counted(nm)
    assert_same(search(c, 2), want)
    assert 3 in c.stops and c.admitted == want[0][2] - want[0][1]
    assert c.crossed > 10               # it went on from level to level


@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                 HealthCheck.filter_too_much])
@given(prog=programs(), agents=hs.integers(1, 3), blackbox=hs.sampled_from(["instant", "straight"]),
       threads=hs.integers(1, 4))
def test_kernel_equal_on_generated_programs(prog, agents, blackbox, threads):
    text, invariants = prog
    kw = dict(source=True, agents=agents, blackbox=blackbox, invariants=invariants)
    m = make_model(text, **kw)
    assume(NV.unsupported(m) is None)
    nm = NV.NativeModel(m)
    assume(nm.explore_levels is not None)
    try:
        want = search(Batches(nm), find_all=True, max_states=3_000)
    except NV.NativeOverflow:
        with pytest.raises(NV.NativeOverflow):
            search(nm, threads, find_all=True, max_states=3_000)
        return
    assert_same(search(nm, threads, find_all=True, max_states=3_000), want)


def summary(r) -> dict:
    s = r.stats
    return {"status": r.status, "states": s.states, "transitions": s.transitions,
            "depth": s.max_depth, "max_time": s.max_time, "verdict": r.verdict,
            "traces": [(cx.trace.labels, cx.trace.states) for cx in r.counterexamples]}


def test_workers_run_as_threads_without_a_graph():
    """``--workers 2`` with nothing recorded: one process, two threads of
    the kernel, one worker's results (and the events it saw: the threads
    see every transition)."""
    kw = dict(agents=3, overrides={"k": "0", "d": "1"}, **NOGRAPH)
    one = explore(FISCHER, workers=1, **kw)
    two = explore(FISCHER, workers=2, **kw)
    assert two.model.engine_used == "native" and two.model.engine_threads == 2
    assert one.model.engine_threads == 1
    assert summary(two) == summary(one)
    assert two.checked.never_fired == one.checked.never_fired == ()


def test_workers_with_the_default_checks_run_as_threads(monkeypatch):
    """The time-lock and stall checks' graph is recorded by the kernel: with
    them ``--workers 2`` is two threads too, and finds what one worker finds
    (a time-lock, a stall, nothing); ``PCCL_THREADS=0`` asks for processes."""
    for path, kw in ((FISCHER, dict(agents=2, overrides={"k": "0", "d": "1"})),
                     (os.path.join(ROOT, "tests/programs/tl_spin.pccl"), {}),
                     (os.path.join(ROOT, "tests/programs/token_keep.pccl"), {})):
        one = explore(path, workers=1, **kw)
        two = explore(path, workers=2, **kw)
        assert two.model.engine_used == "native" and two.model.engine_threads == 2
        assert summary(two) == summary(one)
        assert [(cx.violation.kind, cx.cycle_start) for cx in two.counterexamples] == \
            [(cx.violation.kind, cx.cycle_start) for cx in one.counterexamples]
    assert {cx.violation.kind for cx in one.counterexamples} == {"stall"}
    monkeypatch.setenv("PCCL_THREADS", "0")
    r = explore(FISCHER, workers=2, agents=2, overrides={"k": "0", "d": "1"})
    assert r.model.engine_threads == 1


@pytest.mark.parametrize("name", ["fischer", "tl_spin", "token_keep"])
def test_threads_decide_the_time_lock_beside_the_stall(name, monkeypatch):
    """With ``--workers 2`` the time-lock check's decision is made on a thread
    of its own while the search's thread makes the stall check's
    (pccl.search.liveness._Analysis.decide_beside); with one worker neither
    is made beside.  The violations, their order and their lassos are one
    worker's: nothing (Fischer k=0 d=1 with its invariant off), a
    time-lock (tl_spin), a stall (token_keep); with and without ``--all``."""
    import threading
    path, kw = {"fischer": (FISCHER, dict(agents=2, overrides={"k": "0", "d": "1"})),
                "tl_spin": (os.path.join(ROOT, "tests/programs/tl_spin.pccl"), {}),
                "token_keep": (os.path.join(ROOT, "tests/programs/token_keep.pccl"), {})}[name]
    where: list = []
    real = L._Analysis._locked

    def spy(self):
        where.append(threading.current_thread() is threading.main_thread())
        return real(self)

    monkeypatch.setattr(L._Analysis, "_locked", spy)
    for find_all in (False, True):
        one = explore(path, workers=1, find_all=find_all, **kw)
        assert where and all(where)         # (a counterexample's shortening analyses again)
        where.clear()
        two = explore(path, workers=2, find_all=find_all, **kw)
        assert where and not where[0]
        where.clear()
        assert summary(two) == summary(one)
        assert [(cx.violation.kind, cx.violation.message, cx.cycle_start) for cx in two.counterexamples] == \
            [(cx.violation.kind, cx.violation.message, cx.cycle_start) for cx in one.counterexamples]
        kinds = {cx.violation.kind for cx in one.counterexamples}
        assert kinds == {"fischer": set(), "tl_spin": {"timelock"}, "token_keep": {"stall"}}[name]


def test_workers_with_a_temporal_property_run_as_threads(monkeypatch):
    """A temporal property's columns are made on the kernel's threads (issue
    46): threads, one worker's results; forked processes (PCCL_THREADS=0)
    run it on the Python engine."""
    kw = dict(overrides={"k": "0", "d": "1"}, properties=("forall i: wait[i] ~> inCs[i]",))
    r = explore(FISCHER, workers=2, **kw)
    assert r.model.engine_used == "native" and r.model.engine_threads == 2
    assert summary(r) == summary(explore(FISCHER, workers=1, **kw))
    monkeypatch.setenv("PCCL_THREADS", "0")
    r = explore(FISCHER, workers=2, **kw)
    assert r.model.engine_used == "python" and r.model.engine_threads == 1


def test_programs_that_move_run_as_threads():
    """A program whose statements the generator leaves to Python (memo
    sites: a doReach under nondet, the environment's outcomes) runs the
    kernel too, its misses taking the GIL: threads, one worker's results."""
    path = os.path.join(ROOT, "programs/race_robust.pccl")
    kw = dict(agents=2, world=os.path.join(ROOT, "programs/race.toml"))
    for k in (NOGRAPH, {}):
        r = explore(path, workers=2, **kw, **k)
        assert r.model.engine_used == "native" and r.model.engine_threads == 2
        assert summary(r) == summary(explore(path, workers=1, **kw, **k))


def test_threads_fall_back_to_python_on_overflow():
    text = ("Agent::Grow\n\nallwrite:\n  int x = 1;\n\nallread:\n\nloc:\n\nInit:\n\n"
            "Double():\n  pre(x > 0);\n  eff:\n    x = x * 1000000;\n")
    r = explore(text, source=True, workers=2, max_states=200, reduce="none", **NOGRAPH)
    py = explore(text, source=True, engine="python", max_states=200, reduce="none", **NOGRAPH)
    assert r.model.engine_used == "python" and r.model.engine_threads == 1
    assert summary(r) == summary(py)


@pytest.mark.real_shared_level
def test_header_names_the_threads(tmp_path):
    """The header says the threads; where every level was too narrow to
    share (the default reductions leave Fischer k=0 d=1 levels of at most 9
    states), that the search ran as one thread, and why."""
    from click.testing import CliRunner
    from pccl.cli import main
    base = ["explore", FISCHER, "--set", "k=0", "--set", "d=1", "--no-timelock", "--no-stall",
            "--workers", "2"]
    res = CliRunner().invoke(main, base + ["--reduce", "none"])     # levels of up to 1,368
    assert res.exit_code == 0, res.output
    assert res.output.splitlines()[0].endswith("engine native on 2 threads")
    res = CliRunner().invoke(main, base)
    assert res.exit_code == 0, res.output
    assert res.output.splitlines()[0].endswith(
        "engine native on 1 thread of 2 (levels too narrow to share: the widest had 9 states, "
        "threads share levels of 256 or more)")


SLOW_CASES = [CASES[1], ("fischer unreduced", FISCHER,
                         dict(reduce="none", overrides={"k": "0", "d": "1"}))]


@pytest.mark.parametrize("name, path, kw", SLOW_CASES,
                         ids=[c[0].replace(" ", "-").replace(",", "") for c in SLOW_CASES])
def test_slow_threads_hold_no_one_up(name, path, kw, monkeypatch):
    """The search's own thread never waits for another: when the next chunk
    is in a slow thread's hands (here the others sleep 2 ms a chunk before
    handing it over, as a thread descheduled beside a busy loop would) it
    makes that chunk too; the first copy made is admitted, the other
    dropped (or, late, replaced).  The states, their numbers and parents
    and the recorded graph are the batches', for 2 and 3 threads."""
    nm = native(path, **kw)
    want = search(Batches(nm))
    want_graph = record(Batches(nm))
    monkeypatch.setenv("PCCL_KERNEL_SLOW_HELPERS", "2")
    dups = 0
    for threads in (2, 3):
        ex_states = search(Counted(nm), threads)
        assert_same(ex_states, want)
        got = record(Counted(nm), threads)
        assert got[0] == want_graph[0]
        for k, a in want_graph[1].items():
            assert np.array_equal(got[1][k], a), k
        ex = Explorer(nm, batch=NV.NativeModel.BATCH, threads=threads)
        ex.run()
        assert ex.kernel_chunks > 100
        dups += ex.kernel_dups
    assert dups > 0                 # the calling thread made chunks the others held


@pytest.mark.real_shared_level
def test_threads_note():
    """The header's note on threads: only with more than one thread, once the
    kernel ran, when its widest level was under SHARED_LEVEL states."""
    from pccl.search.explorer import SHARED_LEVEL
    assert SHARED_LEVEL == 256
    ex = Explorer(native(FISCHER, overrides={"k": "0", "d": "1"}), threads=2)
    assert ex.threads_note() is None                # nothing ran
    ex.kernel_chunks, ex.kernel_widest = 10, SHARED_LEVEL - 1
    assert ex.threads_note() == ("levels too narrow to share: the widest had 255 states, "
                                 "threads share levels of 256 or more")
    ex.kernel_widest = SHARED_LEVEL
    assert ex.threads_note() is None
    ex.threads, ex.kernel_widest = 1, 3
    assert ex.threads_note() is None
