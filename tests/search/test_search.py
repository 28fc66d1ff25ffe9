"""The search skeleton (docs/architecture.md, "Search"): the three frontiers
(breadth-first levels, the fastest priority, partitioned workers) share
initial-state admission, bounds, recording, statistics and progress, and
search any model: nothing of PCCL's configuration is read, what they need
(a step's time cost) comes through the model."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from pccl.search.explorer import Bound, Explorer, Progress, terminal
from pccl.search.fastest import FastestExplorer
from pccl.search.parallel import ParallelExplorer


@dataclass(frozen=True)
class Bad:
    name: str

    @property
    def identity(self):
        return self.name


class Grid:
    """A model that is no PCCL model: states are ``(x, t)`` pairs of ints;
    a step either moves ``x`` on by one (no time) or waits (``t`` + 1, one
    time step).  ``x == goal`` violates ``"goal"``; ``x == wall`` is a
    deadlock, ``t == horizon`` the model's own bound."""

    def __init__(self, inits=((0, 0),), goal=None, wall=None, horizon=3, width=6):
        self.inits, self.goal, self.wall = list(inits), goal, wall
        self.horizon, self.width = horizon, width

    def init_states(self):
        return list(self.inits)

    def successors(self, s):
        x, t = s
        if x == self.wall:
            return []
        out = []
        if x + 1 < self.width:
            out.append(("move", (x + 1, t)))
        if t < self.horizon:
            out.append(("wait", (x, t + 1)))
        return out

    def key(self, s):
        return s

    def violations(self, xt):
        return [Bad("goal")] if xt[0] == self.goal else []

    def terminal_kind(self, xt):
        if xt[0] == self.wall:
            return "deadlock"
        return "bounded" if xt[0] + 1 >= self.width else "final"

    def deadlock_violation(self, s):
        return Bad("deadlock")


class TimedGrid(Grid):
    """A grid whose states remember the step into them: ``(x, t, waited)``,
    the model's time cost of that step (a function of the state, as PCCL's
    phase: the fastest search relies on it)."""

    def init_states(self):
        return [(x, t, 0) for x, t in self.inits]

    def successors(self, s):
        return [(lab, (x, t, int(lab == "wait"))) for lab, (x, t) in Grid.successors(self, s[:2])]

    def violations(self, s):
        return Grid.violations(self, s[:2])

    def terminal_kind(self, s):
        return Grid.terminal_kind(self, s[:2])

    @staticmethod
    def time_costs(states):
        return [xt[2] for xt in states]


def _run(cls, model, **kw):
    if cls is ParallelExplorer:
        kw.setdefault("workers", 2)
    return cls(model, **kw).run()


FRONTIERS = [Explorer, FastestExplorer, ParallelExplorer]


def _figures(r):
    return (r.status, r.stats.states, r.stats.transitions, r.stats.initial_states,
            [b.value for b in r.bounds_hit], [f.violation.identity for f in r.found])


@pytest.mark.parametrize("cls", FRONTIERS)
def test_every_frontier_searches_a_model_that_is_not_pccl(cls):
    """No configuration layout: a model of int pairs is searched whole; the
    grid's right edge is the model's own bound."""
    m = TimedGrid(width=4, horizon=2)
    seen, todo = set(), m.init_states()
    while todo:                     # the reachable states, by a plain set
        st = todo.pop()
        if st not in seen:
            seen.add(st)
            todo.extend(t for _, t in m.successors(st))
    r = _run(cls, m)
    assert r.status == "bounded" and r.bounds_hit == [Bound.MODEL]
    assert r.stats.states == len(seen) > 4 * 3
    assert r.stats.transitions == sum(len(m.successors(st)) for st in seen)


def test_the_frontiers_agree_on_figures_and_verdicts():
    cases = [dict(width=4, horizon=2), dict(width=6, horizon=3, wall=3),
             dict(width=6, horizon=3, goal=4, wall=5)]
    for case in cases:
        rs = [_run(cls, TimedGrid(**case), find_all=True) for cls in FRONTIERS]
        assert len({_figures(r)[:4] for r in rs}) == 1, [_figures(r) for r in rs]
        assert all(sorted(_figures(r)[5]) == sorted(_figures(rs[0])[5]) for r in rs)


class Shortcut(TimedGrid):
    """From x = 0 a "jump" reaches the goal x = 3 in one step that costs a
    time step; three "move"s reach it in no time."""

    def successors(self, xt):
        out = TimedGrid.successors(self, xt)
        return out + [("jump", (3, xt[1], 1))] if xt[0] == 0 else out


def test_fastest_orders_on_the_models_time_cost():
    m = Shortcut(goal=3, width=6, horizon=0)
    bfs = Explorer(m).run()
    fast = FastestExplorer(m).run()
    assert bfs.found[0].trace.labels == ("jump",)
    assert fast.found[0].trace.labels == ("move", "move", "move")
    assert sum(m.time_costs(list(fast.found[0].trace.states[1:]))) == 0


@pytest.mark.parametrize("cls", FRONTIERS)
def test_initial_states_are_admitted_in_chunks_within_the_budget(cls):
    """Ten initial states (three repeated) in chunks of four, a budget of
    five: the first five distinct ones, the budget bound, and no more of
    the model's initial states built than one beyond the budget per chunk."""
    inits = [(x, 0) for x in (0, 1, 1, 2, 3, 3, 4, 5, 5, 0)]
    m = TimedGrid(inits=inits, width=6, horizon=0)
    r = _run(cls, m, max_states=5, batch=4)
    assert r.stats.states == 5 and r.stats.initial_states == 5
    assert Bound.MAX_STATES in r.bounds_hit
    full = _run(cls, m, batch=4)
    assert full.stats.initial_states == 6


@pytest.mark.parametrize("cls", FRONTIERS)
def test_the_depth_bound_and_deadlocks_are_shared(cls):
    m = TimedGrid(width=6, horizon=3, wall=2)
    r = _run(cls, m, max_depth=1)
    assert r.status == "bounded" and Bound.DEPTH in r.bounds_hit
    r = _run(cls, m)
    assert r.status == "violation" and r.found[0].violation.identity == "deadlock"
    assert [lab for lab, _ in list(r.found[0].trace)[1:]] == ["move", "move"]
    assert _run(cls, m, deadlock=False).status == "exhaustive"


def test_terminal_reads_the_model():
    m = TimedGrid(width=3, wall=1)
    assert terminal(m, (1, 0, 0), True) == (None, Bad("deadlock"))
    assert terminal(m, (1, 0, 0), False) == (None, None)
    assert terminal(m, (2, 0, 0), True) == (Bound.MODEL, None)


def test_every_frontier_reports_progress():
    """The fastest search reports progress too (it used to report none)."""
    for cls in FRONTIERS:
        seen: list = []
        _run(cls, TimedGrid(width=6, horizon=3), progress=seen.append, progress_interval=1e-9)
        assert seen, cls.__name__
        assert {"states", "frontier", "depth", "seconds", "memory"} <= set(seen[-1])
        assert all(0 < p["states"] <= 2 * 6 * 4 for p in seen)


def test_progress_is_rate_limited():
    calls: list = []
    p = Progress(calls.append, 3600.0, 0.0)
    for _ in range(5):
        p(lambda secs: {"seconds": secs})
    assert calls == []
    p = Progress(calls.append, 0.0, 0.0)
    p(lambda secs: {"seconds": secs})
    assert len(calls) == 1 and calls[0]["seconds"] > 0


def test_the_pccl_model_gives_the_search_its_time_costs():
    """Model.time_costs (what fastest.py and liveness.py read) agrees with
    the configuration's phase, read here through the layout."""
    from pccl.api import make_model
    from pccl.model.layout import DISCRETE, PHASE, AGS, REACH, TARGET, DONE, FAIL, POS
    m = make_model("programs/race_nonatomic.pccl", world="programs/race.toml",
                   blackbox="nondet", agents=2)
    states, todo, seen = [], list(m.init_states()), set()
    while todo and len(states) < 400:
        s = todo.pop()
        if s in seen:
            continue
        seen.add(s)
        states.append(s)
        todo.extend(t for _, t in m.successors(s))
    costs = m.time_costs(states)
    assert [int(c) for c in costs] == [int(s[PHASE] != DISCRETE) for s in states]
    assert 0 < sum(costs) < len(states)

    def pending(st):
        return sum(1 << i for i, ag in enumerate(st[AGS])
                   if ag[REACH][TARGET] is not None and not ag[REACH][DONE]
                   and not ag[REACH][FAIL] and tuple(ag[POS][:2]) != tuple(ag[REACH][TARGET][:2]))
    assert [m.arrival_pending(s) for s in states] == [pending(s) for s in states]
    assert any(m.arrival_pending(s) for s in states)


def test_the_model_names_a_labels_agent_and_line_as_the_display_does():
    """Model.label_line (what liveness.py reads for a time-lock's loops)
    agrees with the display's label_info on every transition of reachable
    states of two programs (events, statements, locks, doReach)."""
    from pccl.api import make_model
    from pccl.output.display import label_info
    for prog, kw in (("programs/fischer.pccl", dict(agents=2, overrides={"k": "0"})),
                     ("programs/race_nonatomic.pccl", dict(world="programs/race.toml",
                                                           blackbox="nondet", agents=2))):
        m = make_model(prog, reduce="none", **kw)
        todo, seen, rules = list(m.init_states()), set(), set()
        while todo and len(seen) < 600:
            s = todo.pop()
            if s in seen:
                continue
            seen.add(s)
            for lab, t in m.successors(s):
                info = label_info(m, lab, s)
                assert m.label_line(lab) == (info["agent"], info["line"]), lab
                rules.add(lab[0])
                todo.append(t)
        assert {"EVENT SELECT", "STATEMENT"} <= rules, rules
