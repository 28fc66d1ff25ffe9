"""The explorer's contract, independent of PCCL: the Model protocol, the
visited table, bounds, traces, replay failures, batching."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from pccl.api import explore, explore_model, make_model, parse_size, format_size
from pccl.search.explorer import Bound, ExactTable, Explorer, FingerprintTable, Model, ReplayError, Trace
from pccl.search.fingerprint import fingerprint


@dataclass(frozen=True)
class V:
    name: str

    @property
    def identity(self):
        return self.name


class Grid:
    """A toy model: (x, y) on a w×h grid, steps right or up; ``bad`` cells
    violate the invariant.  Not PCCL: the explorer must not care."""

    def __init__(self, w=6, h=5, bad=()):
        self.w, self.h, self.bad = w, h, set(bad)

    def init_states(self):
        return [(0, 0), (0, 0)]                 # duplicates are merged

    def successors(self, s):
        x, y = s
        out = []
        if x + 1 < self.w:
            out.append((("right",), (x + 1, y)))
        if y + 1 < self.h:
            out.append((("up",), (x, y + 1)))
        return out

    def key(self, s):
        return s

    def violations(self, s):
        return [V(f"bad {s}")] if s in self.bad else []

    def terminal_kind(self, s):
        return "final"

    def deadlock_violation(self, s):
        return None


def test_a_toy_model_satisfies_the_protocol_and_is_explored():
    g = Grid()
    assert isinstance(g, Model)
    r = Explorer(g).run()
    assert r.status == "exhaustive"
    assert r.stats.states == 30 and r.stats.initial_states == 1
    assert r.stats.transitions == 2 * 30 - 6 - 5
    assert r.stats.max_depth == 9


def test_shortest_counterexample_and_trace_type():
    r = Explorer(Grid(bad={(2, 3)})).run()
    assert r.status == "violation"
    cx = r.found[0]
    tr = cx.trace
    assert isinstance(tr, Trace) and len(tr) == cx.depth == 5
    assert tr.initial == (0, 0) and tr.last == (2, 3)
    pairs = list(tr)
    assert pairs[0] == (None, (0, 0)) and len(pairs) == 6
    steps = tr.steps
    assert [s.number for s in steps] == [1, 2, 3, 4, 5]
    assert all(s.after == pairs[n + 1][1] for n, s in enumerate(steps))
    assert tr.to_json(lambda s: {"n": s.number, "to": list(s.after)})[-1] == {"n": 5, "to": [2, 3]}


def test_find_all_reports_each_distinct_violation_once():
    r = Explorer(Grid(bad={(1, 1), (3, 0), (5, 4)}), find_all=True).run()
    assert sorted(f.violation.name for f in r.found) == ["bad (1, 1)", "bad (3, 0)", "bad (5, 4)"]
    assert [f.depth for f in r.found] == sorted(f.depth for f in r.found)
    assert r.stats.states == 30


def test_bounds_are_an_enum():
    r = Explorer(Grid(), max_depth=3).run()
    assert r.status == "bounded" and r.bounds_hit == [Bound.DEPTH]
    r = Explorer(Grid(), max_states=7).run()
    assert r.status == "bounded" and r.bounds_hit == [Bound.MAX_STATES]
    assert r.stats.states == 7                 # admitted exactly, not "about"
    r = Explorer(Grid(), max_states=30).run()
    assert r.status == "exhaustive"            # the budget was enough


class Flaky(Grid):
    """Breaks the determinism contract: after ``limit`` calls, states have no
    successors any more."""

    def __init__(self, limit):
        super().__init__(bad={(3, 3)})
        self.calls, self.limit = 0, limit

    def successors(self, s):
        self.calls += 1
        return super().successors(s) if self.calls <= self.limit else []


def test_replay_failure_explains_itself():
    honest = Flaky(10**9)
    Explorer(honest).run()          # how many calls the search itself makes
    search_calls = honest.calls - 6  # the replay of the 6-step trace made the rest
    with pytest.raises(ReplayError, match=r"diverged at step 1 of 6.*deterministic"):
        Explorer(Flaky(search_calls)).run()


@pytest.mark.parametrize("batch", [1, 7, 1000])
def test_batch_size_does_not_change_anything(batch):
    prog = "programs/race_nonatomic.pccl"
    m = make_model(prog, world="programs/race.toml", blackbox="nondet", agents=2)
    a = Explorer(m, batch=batch, find_all=True).run()
    b = Explorer(m, find_all=True).run()
    assert (a.status, a.stats.states, a.stats.transitions, a.stats.max_depth) == \
        (b.status, b.stats.states, b.stats.transitions, b.stats.max_depth)
    assert [f.index for f in a.found] == [f.index for f in b.found]
    assert [f.trace.labels for f in a.found] == [f.trace.labels for f in b.found]


def test_first_violation_statistics_do_not_depend_on_batching():
    m = make_model("programs/fischer.pccl", overrides={"k": "1"},
                   invariants=("count(inCs) <= 1",))
    a = Explorer(m, batch=50).run()
    b = Explorer(m).run()
    assert a.status == b.status == "violation"
    assert (a.stats.states, a.stats.transitions) == (b.stats.states, b.stats.transitions)
    assert a.found[0].trace.labels == b.found[0].trace.labels


@settings(max_examples=30, deadline=None)
@given(st.lists(st.binary(min_size=1, max_size=6), min_size=1, max_size=400),
       st.integers(min_value=1, max_value=50))
def test_fingerprint_table_agrees_with_a_python_dict(keys, chunk):
    """Admission in chunks (with duplicates inside and across chunks, and
    index rebuilds as the table grows) numbers states like a dict would."""
    table, ref = FingerprintTable(capacity=4), {}
    exact = ExactTable()
    for a in range(0, len(keys), chunk):
        part = [fingerprint(k) for k in keys[a:a + chunk]]
        first = np.fromiter(dict(zip(reversed(part), range(len(part) - 1, -1, -1))).values(),
                            dtype=np.int64)
        first.sort()
        new = table.new_positions(part, first)
        new_x = exact.new_positions(part, first)
        assert new.tolist() == new_x.tolist()
        table.add(len(new), np.zeros(len(new), dtype=np.int64))
        exact.add(len(new), np.zeros(len(new), dtype=np.int64))
        for p in new.tolist():
            ref[part[p]] = len(ref)
    assert table.n == len(ref) == exact.n
    for k, idx in ref.items():
        assert table.index_of(k) == idx == exact.index_of(k)
    assert table.index_of(fingerprint(b"never seen" * 3)) == -1


def test_the_table_costs_about_24_bytes_per_state():
    t = FingerprintTable()
    assert t.fps.base is not None     # reserved mapping: no growth copies on Linux
    n = 200_000
    keys = [fingerprint(i) for i in range(n)]
    first = np.arange(n, dtype=np.int64)
    t.new_positions(keys, first)
    t.add(n, np.zeros(n, dtype=np.int64))
    # 16 B fingerprint + 4 B parent per state, 4 B per index slot at most half full
    assert t.slots.nbytes <= 4 * 4 * n and t.slots.dtype == np.uint32
    assert t.fps.itemsize * 2 + t.parents.itemsize == 20


def test_max_memory_is_an_honest_bound():
    r = explore("programs/fischer.pccl", overrides={"k": "2"}, max_memory=1)
    assert r.status == "bounded" and r.exit_status == 0
    assert r.search.bounds_hit == [Bound.MAX_MEMORY]
    assert r.bound_labels == ["max_memory=1"]
    assert "stopped by max_memory=1" in r.verdict and r.stats.states > 0


def test_sizes_round_trip():
    assert parse_size("800M") == 800 * 2**20 and parse_size("4G") == 4 * 2**30
    assert parse_size("1.5GiB") == int(1.5 * 2**30) and parse_size("123") == 123
    assert parse_size(format_size(parse_size("3G"))) == 3 * 2**30
    for bad in ("", "x", "-1G", "4Q"):
        with pytest.raises(ValueError):
            parse_size(bad)


def test_interrupted_after_violations_reports_them_and_exits_1():
    # (k = 1, cstime = 0: the first violation at 3,475 states, the whole
    # search --all 13,696; with cstime free they were ~125k and more)
    m = make_model("programs/fischer.pccl", overrides={"k": "1", "cstime": "0"},
                   invariants=("count(inCs) <= 1",), reduce="none")
    real, calls = m.successors, [0]

    def successors(s):       # one Ctrl-C, after the first violation, before the end
        calls[0] += 1
        if calls[0] == 5_000:
            raise KeyboardInterrupt
        return real(s)

    m.successors = successors
    r = explore_model(m, find_all=True)
    assert r.status == "interrupted" and r.exit_status == 1
    assert r.violations and "interrupted" in r.verdict and "not exhaustive" in r.verdict


def test_interrupted_without_violations_exits_130():
    m = make_model("programs/fischer.pccl", overrides={"k": "2"}, reduce="merge,symmetry,por")
    real, calls = m.successors, [0]

    def successors(s):
        calls[0] += 1
        if calls[0] > 5_000:
            raise KeyboardInterrupt
        return real(s)

    m.successors = successors
    r = explore_model(m)
    assert r.status == "interrupted" and r.exit_status == 130 and not r.violations


class _Bad:
    identity = "bad"


class _Clocked:
    """A toy model: 0 -> 1 (violates), 0 -> 2; the clock of state s is 10 s.
    The batch {1, 2} is cut after 1, so 2 is never admitted."""

    def init_states(self):
        return [0]

    def successors(self, s):
        return [("a", 1), ("b", 2)] if s == 0 else []

    def key(self, s):
        return s

    def violations(self, s):
        return [_Bad()] if s == 1 else []

    def terminal_kind(self, s):
        return "final"

    def deadlock_violation(self, s):
        return None

    def clock(self, s):
        return 10 * s


def test_max_time_counts_only_admitted_states():
    from pccl.search.explorer import Explorer
    r = Explorer(_Clocked()).run()
    assert r.status == "violation" and r.stats.states == 2
    assert r.stats.max_time == 10          # state 2 (time 20) was never admitted


class ManyStarts(Grid):
    """Initial configurations without end that are all one state (as 50
    symmetric agents' ``rand`` initialisers are under symmetry): only a bound
    on the initial phase itself can stop the search."""

    def init_states(self):
        while True:
            yield (0, 0)


def test_max_states_bounds_the_initial_configurations_generated():
    seen: list = []
    ex = Explorer(ManyStarts(), max_states=500, batch=64, progress=seen.append,
                  progress_interval=1e-9)
    r = ex.run()
    assert r.status == "bounded" and r.bounds_hit == [Bound.MAX_STATES]
    cap = 500 + 64              # explorer.initial_candidate_cap
    assert r.stats.initial_states == 1 and ex.initial_candidates == cap
    # progress lines during the initial phase, with the candidates generated
    assert seen and 0 < seen[-1]["initial_candidates"] < cap and seen[-1]["states"] == 1


def test_max_memory_bounds_the_initial_configurations():
    r = Explorer(ManyStarts(), max_memory=1, batch=64).run()
    assert r.status == "bounded" and r.bounds_hit == [Bound.MAX_MEMORY]


def test_the_initial_phase_bound_is_not_reported_when_nothing_was_left():
    # exactly as many candidates as the cap (one state, no successors): none left out
    class Exactly(Grid):
        def init_states(self):
            return [(0, 0)] * (2 + 64)
    r = Explorer(Exactly(w=1, h=1), max_states=2, batch=64).run()
    assert r.status == "exhaustive" and r.stats.initial_states == 1


@pytest.mark.slow
@pytest.mark.parametrize("how", [{}, {"workers": 2}, {"fastest": True}])
def test_a_big_team_with_a_state_budget_ends_in_its_initial_phase(how):
    # Fischer with 12 agents: 11^12 (3 * 10^12) initial candidates (waitTime =
    # rand(10) each) that symmetry folds into fewer states, still far more than
    # the budget, which stops the enumeration (30 agents and 3,000 states cost
    # 9 CPU-s, most of it compiling the 30-agent module and enumerating)
    r = explore("programs/fischer.pccl", agents=12, max_states=300, **how)
    assert r.status == "bounded" and r.search.bounds_hit == [Bound.MAX_STATES]
    assert 0 < r.stats.initial_states <= 300


INIT_STUCK_IN_ATOMIC = "allwrite:\n  int s = 1;\nInit:\n  atomic:\n    assert(s < 0);\n"


@pytest.mark.parametrize("engine", ["python", "native"])
def test_an_agent_stuck_holding_the_lock_in_init_is_a_violation(engine):
    # found by the differential oracle (seed 400162): agent 0's Init fails
    # inside `atomic:` and keeps the lock, so agent 1's Init can never go on;
    # the initial-state search had no state at all: "no violation — exhaustive"
    # with 0 states (and StopIteration natively, a traceback in `pccl run`)
    r = explore(INIT_STUCK_IN_ATOMIC, source=True, engine=engine)
    assert r.status == "violation" and r.violation.kind == "assert", r.verdict
    assert r.stats.initial_states >= 1
    from pccl.api import run
    out = run(INIT_STUCK_IN_ATOMIC, source=True)
    assert out.status == "violation"
