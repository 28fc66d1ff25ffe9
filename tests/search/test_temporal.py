"""Temporal properties (spec section 9, docs/temporal.md): the property
forms, liveness with lassos, bounded response, reachability, time-locks and
--fastest, on small programs of tests/programs/.

Where a verdict can be computed two ways it is: the liveness and
bounded-response verdicts are compared with a plain reference search
written here over the model's own successor relation (a dict graph and a
fixpoint, no numpy, no SCCs)."""

from __future__ import annotations

import json
import pytest

from pccl.api import explore, make_model
from pccl.model.layout import AGS, DISCRETE, EXITED, FAIL, LOC, PHASE, REACH, STATUS, TIME

from conftest import FISCHER, TEST_PROGRAMS
from conftest import cli, verdict

RDV = str(TEST_PROGRAMS / "rdv_meet.pccl")
RDV_OPEN = str(TEST_PROGRAMS / "rdv_open.toml")
RDV_WALL = str(TEST_PROGRAMS / "rdv_wall.toml")
RING = str(TEST_PROGRAMS / "token_ring.pccl")
KEEP = str(TEST_PROGRAMS / "token_keep.pccl")
SPIN = str(TEST_PROGRAMS / "tl_spin.pccl")
SPIN_LEAVE = str(TEST_PROGRAMS / "tl_spin_leave.pccl")
FAST = str(TEST_PROGRAMS / "fast_slow.pccl")
ALL_EXIT = "eventually forall i: exited[i]"




# ---------------------------------------------------------------------------
# reference: the graph by plain dicts, verdicts by fixpoints
# ---------------------------------------------------------------------------

def ref_graph(model):
    """(initial keys, {key: state}, {key: [successor keys]})."""
    key = model.key
    init = []
    states, succ = {}, {}
    todo = []
    for s in model.init_states():
        k = key(s)
        if k not in states:
            states[k] = s
            init.append(k)
            todo.append(k)
    while todo:
        k = todo.pop()
        out = []
        for _, s2 in model.successors(states[k]):
            k2 = key(s2)
            out.append(k2)
            if k2 not in states:
                states[k2] = s2
                todo.append(k2)
        succ[k] = out
    return init, states, succ


def ref_leadsto_fails(model, start, q) -> bool:
    """Is there a start state (an initial one when ``start`` is None) where Q
    fails, from which some run keeps Q false: a finite run ending in a
    terminal state, or an infinite one through dynamic states (TIME ADVANCE)
    infinitely often?  No fairness among agents' arrivals.  Fair EG by the
    textbook fixpoint: Z = nu Z. notQ & EX E[notQ U (Z & dyn)]."""
    init, states, succ = ref_graph(model)
    notq = {k for k, s in states.items() if not q(s)}
    dyn = {k for k, s in states.items() if s[PHASE] != DISCRETE}
    terminal = {k for k in states if not succ[k]}

    def eu(target):          # E[notQ U target], target inside notQ
        res = set(target)
        changed = True
        while changed:
            changed = False
            for k in notq - res:
                if any(k2 in res for k2 in succ[k]):
                    res.add(k)
                    changed = True
        return res
    z = set(notq)
    while True:
        t = eu(z & dyn)
        znew = {k for k in notq if any(k2 in t for k2 in succ[k])}
        if znew == z:
            break
        z = znew
    bad = eu(z | (terminal & notq))
    starts = init if start is None else [k for k, s in states.items() if start(s)]
    return any(k in bad for k in starts)


def ref_within_fails(model, p, q, ticks) -> bool:
    """A path on which more than ``ticks`` time steps pass after P without Q:
    search over (state, clock of the oldest unanswered P) without pruning."""
    init, states, succ = ref_graph(model)
    seen = set()
    todo = []
    for k in init:
        s = states[k]
        c = 0 if (p(s) and not q(s)) else -1
        todo.append((k, c))
    while todo:
        node = todo.pop()
        if node in seen:
            continue
        seen.add(node)
        k, c = node
        for k2 in succ[k]:
            s2 = states[k2]
            c2 = c + 1 if (c >= 0 and s2[PHASE] != DISCRETE) else c
            if c2 > ticks:
                return True
            if q(s2):
                c2 = -1
            elif c2 == -1 and p(s2):
                c2 = 0
            todo.append((k2, c2))
    return False


def lasso_ok(model, res, stays_false):
    """The counterexample is a real lasso: the cycle returns to its start
    state, advances time, and ``stays_false`` holds on every state from the
    start of the check on."""
    cx = res.counterexamples[0]
    tr = cx.trace
    loop = cx.cycle_start
    assert loop is not None and 0 <= loop < len(tr)
    assert model.key(tr.states[loop]) == model.key(tr.last)
    assert any(s[PHASE] != DISCRETE for s in tr.states[loop + 1:])
    return all(stays_false(s) for s in tr.states[loop:])


# ---------------------------------------------------------------------------
# parsing and checking
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("form, kind", [
    ("eventually forall i: exited[i]", "eventually"),
    ("want[0] ~> has[0]", "leadsto"),
    ("want[0] ~> has[0] within 3", "within"),
    ("reachable count(has) == 1", "reachable"),
])
def test_property_forms_parse(form, kind):
    m = make_model(RING, properties=[form], agents=2)
    assert [p.kind for p in m.temporal] == [kind]
    assert m.properties == []


def test_forall_makes_one_instance_per_agent():
    m = make_model(RING, properties=["forall i: want[i] ~> has[i]"], agents=3)
    assert [p.name for p in m.temporal] == [f"forall i: want[i] ~> has[i] [i={k}]"
                                            for k in range(3)]


def test_plain_property_is_an_invariant():
    m = make_model(RING, properties=["count(has) <= 1"], agents=2)
    assert len(m.properties) == 1 and m.temporal == []
    r = explore(RING, agents=3, properties=["count(has) <= 1"])
    assert r.exit_status == 0 and r.status == "exhaustive"


def test_invariant_section_takes_temporal_forms(tmp_path):
    src = open(RING).read() + ("\ninvariant:\n  one: count(has) <= 1;\n"
                               "  live: forall i: want[i] ~> has[i];\n"
                               "  goal: reachable has[1];\n")
    f = tmp_path / "ring.pccl"
    f.write_text(src)
    r = explore(str(f), agents=3)
    assert r.exit_status == 0
    assert "live [i=2]" in r.holds and "goal" in r.holds
    assert [w["name"] for w in r.witnesses] == ["goal"]


@pytest.mark.parametrize("form, message", [
    ("eventually exitd[0]", "undeclared variable 'exitd' (did you mean 'exited'?)"),
    ("exists i: eventually exited[i]", "only 'forall' may quantify a temporal property"),
    ("(eventually want[0]) && has[0]", "must stand at the top of a property"),
    ("want[0] ~> has[0] within want[1]", "bound of 'within' must be a constant"),
    ("want[0] ~> ", "unexpected end of input"),
    ("count(exited) > 0 ~> stuck", "'stuck' is per-agent: write stuck[i]"),
])
def test_property_errors_exit_2_with_caret(form, message):
    res = cli("explore", RING, "--property", form)
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith("--property #1:1:"), res.stderr
    assert message in res.stderr
    assert "^" in res.stderr and res.stdout == ""


def test_invariant_option_refuses_temporal_forms():
    res = cli("explore", RING, "--invariant", "eventually has[0]")
    assert res.exit_code == 2
    assert "goes with --property" in res.stderr and "^" in res.stderr


def test_temporal_forms_are_not_program_expressions(tmp_path):
    f = tmp_path / "bad.pccl"
    f.write_text("loc:\n  bool b = false;\nE():\n  pre(eventually b);\n  eff: b = true;\n")
    res = cli("check", f)
    assert res.exit_code == 2
    assert "'eventually' is only allowed in properties" in res.stderr
    assert f"{f}:4:7" in res.stderr


def test_api_properties_argument_is_validated():
    from pccl.lang.errors import ArgumentError
    with pytest.raises(ArgumentError, match="properties"):
        explore(RING, properties="eventually has[0]")
    with pytest.raises(ArgumentError, match="timelock"):
        explore(RING, timelock="yes")


def test_status_predicates():
    m = make_model(SPIN_LEAVE, properties=["reachable count(exited) == 2 && !running[0]"])
    r = explore(SPIN_LEAVE, properties=["reachable count(exited) == 2 && !running[0]",
                                        "reachable exited[1] && running[0]",
                                        "count(stuck) == 0"])
    assert r.exit_status == 0, r.verdict
    assert len(r.witnesses) == 2
    last = r.witnesses[0]["_trace"].last
    assert all(ag[STATUS] == EXITED for ag in last[AGS])
    assert m.temporal[0].p(last)


# ---------------------------------------------------------------------------
# reachable
# ---------------------------------------------------------------------------

def test_reachable_on_fischer_gives_a_witness_and_unreachable_fails():
    r = explore(FISCHER, overrides={"k": "0"}, properties=["reachable count(inCs) == 1"],
                reduce="none")     # shortest in the rules (reduce: shortest under them)
    assert r.exit_status == 0 and r.status == "exhaustive"
    (w,) = r.witnesses
    tr = w["_trace"]
    assert sum(v is True for v in (tr.last[AGS][i][LOC][r.model.compiled.layout.vars["inCs"].slot]
                                   for i in range(2))) == 1
    # shortest: no state on the path before the last satisfies it
    p = r.model.temporal[0].p
    assert not any(p(s) for s in tr.states[:-1])
    r3 = explore(FISCHER, overrides={"k": "0"}, properties=["reachable count(inCs) == 3"])
    assert r3.exit_status == 1
    assert r3.violations[0]["kind"] == "unreachable"
    assert "unreachable" in r3.verdict


def test_reachable_cli():
    res = cli("explore", FISCHER, "--set", "k=0", "--property", "reachable count(inCs) == 1")
    assert res.exit_code == 0
    assert "reachable: `reachable count(inCs) == 1` is reached; witness (" in res.output
    res = cli("explore", FISCHER, "--set", "k=0", "--property", "reachable count(inCs) == 3")
    assert res.exit_code == 1
    assert "unreachable: no reachable state satisfies" in res.output


# ---------------------------------------------------------------------------
# eventually
# ---------------------------------------------------------------------------

def test_walled_rendezvous_fails_eventually_all_exit_with_a_lasso():
    r = explore(RDV, world=RDV_WALL, blackbox="straight", properties=[ALL_EXIT])
    assert r.exit_status == 1
    v = r.violations[0]
    assert v["kind"] == "liveness" and v.cycle_start is not None
    m = r.model
    assert lasso_ok(m, r, lambda s: not all(ag[STATUS] == EXITED for ag in s[AGS]))
    # robot 0's doReach failed on the wall
    assert r.counterexamples[0].trace.last[AGS][0][REACH][FAIL] is True
    assert ref_leadsto_fails(make_model(RDV, world=RDV_WALL, blackbox="straight",
                                        properties=[ALL_EXIT]),
                             None, m.temporal[0].p)


def test_open_rendezvous_holds():
    for bb in ("straight", "nondet"):
        r = explore(RDV, world=RDV_OPEN, blackbox=bb, properties=[ALL_EXIT])
        assert r.exit_status == 0, r.verdict
        assert r.holds == [ALL_EXIT]
    m = make_model(RDV, world=RDV_OPEN, blackbox="straight", properties=[ALL_EXIT])
    assert not ref_leadsto_fails(m, None, m.temporal[0].p)


def test_nondet_fair_arrival():
    """Under nondet robot 0 may 'stay' forever; fair arrival rules that out."""
    r = explore(RDV, world=RDV_OPEN, blackbox="nondet", properties=[ALL_EXIT])
    assert r.exit_status == 0
    # without the fairness assumption (the reference has none) it would fail
    m = make_model(RDV, world=RDV_OPEN, blackbox="nondet", properties=[ALL_EXIT])
    assert ref_leadsto_fails(m, None, m.temporal[0].p)


def test_terminal_counterexample(tmp_path):
    f = tmp_path / "stop.pccl"
    f.write_text("loc:\n  bool done = false;\nStop():\n  pre(!done);\n  eff:\n    exit();\n")
    r = explore(str(f), properties=["eventually done[0]"])
    assert r.exit_status == 1
    cx = r.counterexamples[0]
    assert cx.cycle_start is None
    assert "ends (terminal state)" in r.violations[0]["message"]
    assert r.model.successors(cx.trace.last) == []


# ---------------------------------------------------------------------------
# leads-to and within
# ---------------------------------------------------------------------------

def test_token_ring_leads_to_holds():
    r = explore(RING, agents=3, properties=["forall i: want[i] ~> has[i]"])
    assert r.exit_status == 0
    assert len(r.holds) == 3
    m = make_model(RING, agents=3, properties=["forall i: want[i] ~> has[i]"])
    for p in m.temporal:
        assert not ref_leadsto_fails(m, p.p, p.q)


def test_token_keeper_violates_leads_to_with_a_lasso():
    r = explore(KEEP, agents=3, properties=["forall i: want[i] ~> has[i]"])
    assert r.exit_status == 1
    v = r.violations[0]
    assert v["kind"] == "liveness" and v.cycle_start is not None
    i = int(v["name"].rsplit("=", 1)[1].rstrip("]"))
    assert i != 0
    m = r.model
    inst = m.temporal[i]
    assert lasso_ok(m, r, lambda s: not inst.q(s))
    assert any(inst.p(s) for s in r.counterexamples[0].trace.states)
    ref = make_model(KEEP, agents=3, properties=["forall i: want[i] ~> has[i]"])
    assert ref_leadsto_fails(ref, inst.p, inst.q)
    assert not ref_leadsto_fails(ref, ref.temporal[0].p, ref.temporal[0].q)


@pytest.mark.parametrize("bound", [0, 1, 2, 3, 4, 5, 6, 7, 8, 9])
def test_within_agrees_with_reference(bound):
    prop = f"want[1] ~> has[1] within {bound}"
    r = explore(RING, agents=3, properties=[prop])
    m = make_model(RING, agents=3, properties=[prop])
    p = m.temporal[0]
    assert p.ticks == bound
    assert (r.exit_status == 1) == ref_within_fails(m, p.p, p.q, p.ticks), r.verdict
    if r.exit_status == 1:
        tr = r.counterexamples[0].trace
        assert tr.last[TIME] - tr.states[r.counterexamples[0].p_at][TIME] > bound


def test_within_has_a_threshold():
    fails = [explore(RING, agents=3, properties=[f"want[1] ~> has[1] within {t}"]).exit_status
             for t in range(0, 12)]
    assert fails[0] == 1 and fails[-1] == 0
    first_ok = fails.index(0)
    assert all(x == 0 for x in fails[first_ok:])


def test_within_fractional_bound_and_time_abstraction():
    r = explore(RING, agents=3, properties=["want[1] ~> has[1] within 2.5"])
    assert r.model.abstract_time          # the monitor clock keeps abstraction sound
    assert r.model.temporal[0].ticks == 2


# ---------------------------------------------------------------------------
# time-locks
# ---------------------------------------------------------------------------

def test_zero_time_spin_is_a_time_lock():
    r = explore(SPIN)
    assert r.exit_status == 1
    v = r.violations[0]
    assert v["kind"] == "timelock"
    assert "agent 0 (lines 12, 13)" in v["message"]
    cx = r.counterexamples[0]
    tr = cx.trace
    assert r.model.key(tr.states[cx.cycle_start]) == r.model.key(tr.last)
    assert all(s[PHASE] == DISCRETE and s[TIME] == 0 for s in tr.states)


def test_spin_that_can_be_left_is_no_time_lock():
    r = explore(SPIN_LEAVE)
    assert r.exit_status == 0, r.verdict
    # it does have zero-time cycles: agent 0's loop before agent 1 moves
    init, states, succ = ref_graph(r.model)
    assert any(k in succ[k2] for k in states for k2 in succ[k])


def test_no_timelock_option():
    assert explore(SPIN, timelock=False).exit_status == 0
    res = cli("explore", SPIN, "--no-timelock")
    assert res.exit_code == 0
    res = cli("explore", SPIN, "--reduce", "none")
    assert res.exit_code == 1
    assert "-- cycle: the steps below repeat forever --" in res.output
    assert "counterexample (a lasso: 1 step, then a cycle of 2 steps repeated forever)" \
        in res.output


# ---------------------------------------------------------------------------
# --fastest
# ---------------------------------------------------------------------------

def test_fastest_finds_the_earlier_violation():
    bfs = explore(FAST, agents=1, reduce="none")
    fast = explore(FAST, agents=1, fastest=True, reduce="none")
    assert bfs.exit_status == fast.exit_status == 1
    tb, tf = bfs.counterexamples[0].trace, fast.counterexamples[0].trace
    assert tb.last[TIME] == 2 and tf.last[TIME] == 0
    assert len(tb) < len(tf)
    res = cli("explore", FAST, "-n", "1", "--fastest")
    assert "fastest: violation at t=0" in res.output


def test_fastest_agrees_on_small_programs():
    for prog, kw in ((RING, dict(agents=3)), (SPIN_LEAVE, {}), (RDV, dict(world=RDV_OPEN))):
        a = explore(prog, **kw)
        b = explore(prog, fastest=True, **kw)
        assert (a.status, a.stats.states, a.stats.transitions) == \
            (b.status, b.stats.states, b.stats.transitions)
    # the time-lock check works on the graph the fastest search records
    assert explore(SPIN, fastest=True).violations[0]["kind"] == "timelock"


@pytest.mark.slow
def test_fastest_agrees_on_verdicts_and_counts():
    for args in (dict(overrides={"k": "0"}), dict(overrides={"k": "0"},
                                                  invariants=["count(inCs) <= 1"])):
        a = explore(FISCHER, **args)
        b = explore(FISCHER, fastest=True, **args)
        assert a.status == b.status and a.exit_status == b.exit_status
        if a.status == "exhaustive":
            assert a.stats.states == b.stats.states
            assert a.stats.transitions == b.stats.transitions
        else:
            assert b.counterexamples[0].trace.last[TIME] <= a.counterexamples[0].trace.last[TIME]


@pytest.mark.slow
def test_fastest_among_equal_times_is_shortest():
    r = explore(FISCHER, overrides={"k": "0"}, invariants=["count(inCs) <= 1"], fastest=True)
    tr = r.counterexamples[0].trace
    assert tr.last[TIME] == 10
    # BFS finds its path at time 10 too: fastest cannot be longer at the same time
    # (the reduced search's own path: the default shortens it against the
    # unreduced semantics, issue 44.3; --fastest is not shortened)
    b = explore(FISCHER, overrides={"k": "0"}, invariants=["count(inCs) <= 1"], shorten=False)
    assert b.counterexamples[0].trace.last[TIME] == 10
    assert len(tr) == len(b.counterexamples[0].trace)


def test_workers_check_temporal_properties_and_run_fastest():
    """With workers the temporal verdict is the one-process verdict
    (tests/search/test_parallel.py compares them in full); --fastest with workers
    gives the one-process result too (before: refused)."""
    one = cli("explore", RING, "--agents", "3", "--property", "forall i: want[i] ~> has[i]",
              "--no-progress", "--format", "json")
    two = cli("explore", RING, "--agents", "3", "--property", "forall i: want[i] ~> has[i]",
              "--no-progress", "--format", "json", "--workers", "2")
    assert one.exit_code == two.exit_code == 0, two.stderr
    a, b = json.loads(one.stdout), json.loads(two.stdout)
    assert a["holds"] == b["holds"] and len(a["holds"]) == 3
    assert a["statistics"]["states"] == b["statistics"]["states"]
    one = cli("explore", RING, "--agents", "3", "--fastest", "--no-progress", "--format", "json")
    two = cli("explore", RING, "--agents", "3", "--fastest", "--no-progress", "--format", "json",
              "--workers", "2")
    assert one.exit_code == two.exit_code, two.stderr
    assert json.loads(one.stdout)["statistics"]["states"] == \
        json.loads(two.stdout)["statistics"]["states"]
    assert "Traceback" not in two.stderr


@pytest.mark.parametrize("seed", range(5))
def test_graph_reachability_agrees_with_a_plain_search(seed):
    """Graph.can_reach (relaxation rounds, then the reversed graph) and
    Graph.reach agree with a dict-based backward search on random graphs."""
    import numpy as np
    from pccl.search.liveness import Graph
    rng = np.random.default_rng(seed)
    n, e = 200, 400
    src = np.sort(rng.integers(0, n, e)).astype(np.uint32)
    dst = rng.integers(0, n, e).astype(np.uint32)
    fptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(src, minlength=n), out=fptr[1:])
    g = Graph(n, fptr, dst, src, np.zeros(n, bool), None, None)
    goal = rng.random(n) < 0.05
    want = _plain_can_reach(src, dst, goal)
    for rounds in (1, 3, 1000):
        assert set(np.flatnonzero(g.can_reach(goal, rounds=rounds)).tolist()) == want
    assert set(np.flatnonzero(g.reach(np.flatnonzero(goal), backward=True)).tolist()) == want



@pytest.fixture(scope="module")
def reach_back():
    """The native engine's backward reachability (a compiled module's
    ``reach_back``), or a skip where no compiler is there."""
    import os
    from pccl.api import make_model
    from pccl.model import native as NV
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    py = make_model(os.path.join(root, "programs", "fischer.pccl"), overrides={"k": "1", "d": "1"})
    why = NV.unsupported(py)
    if why:
        pytest.skip(f"no native engine here: {why}")
    return NV.NativeModel(py).reach_back


@pytest.mark.parametrize("seed", range(6))
def test_native_backward_reachability_agrees_with_a_plain_search(seed, reach_back):
    """Graph.can_reach with the native kernel (sweeps over the transitions,
    last to first) gives the plain search's set on random graphs (transitions
    back to earlier states included), on a ladder whose every transition
    leads forward (one sweep) and on the reversed ladder (each sweep settles
    one more state: not settled in the rounds given, numpy goes on from the
    kernel's part)."""
    import numpy as np
    from pccl.search.liveness import Graph
    rng = np.random.default_rng(seed)
    n, e = 300, 900
    src = np.sort(rng.integers(0, n, e)).astype(np.uint32)
    dst = rng.integers(0, n, e).astype(np.uint32)
    graphs = [(src, dst)]
    g, lsrc, ldst = _ladder(200, 2)
    graphs.append((lsrc, ldst))
    order = np.argsort(ldst, kind="stable")           # i+1.. -> i: backward edges
    graphs.append((ldst[order], lsrc[order]))
    for s, d in graphs:
        m = max(int(s.max()), int(d.max())) + 1
        for goal in (rng.random(m) < 0.03, np.arange(m) == m - 1, np.arange(m) == 0):
            want = _plain_can_reach(s, d, goal)
            for rounds in (1, 3, 1000):
                g = Graph(m, None, d, s, np.zeros(m, bool), None, None)
                g.kernel = reach_back
                assert set(np.flatnonzero(g.can_reach(goal, rounds=rounds)).tolist()) == want
    with pytest.raises(ValueError):     # a state number past the mask: refused, not written
        reach_back(np.array([0, 5], np.uint32), np.array([1, 2], np.uint32), np.zeros(3, np.uint8), 4)


def _plain_can_reach(src, dst, goal) -> set:
    """The states that can reach ``goal``: a dict-based backward search."""
    import numpy as np
    preds: dict = {}
    for a, b in zip(src.tolist(), dst.tolist()):
        preds.setdefault(b, []).append(a)
    want = set(np.flatnonzero(goal).tolist())
    todo = list(want)
    while todo:
        v = todo.pop()
        for u in preds.get(v, ()):
            if u not in want:
                want.add(u)
                todo.append(u)
    return want


def _ladder(n: int, fan: int):
    """A graph by source (as the search records it): state i -> i+1 .. i+fan
    (as far as n), the goal the last state: every state reaches it, but only
    along the chain, so no few relaxation rounds settle it."""
    import numpy as np
    from pccl.search.liveness import Graph
    src = np.repeat(np.arange(n, dtype=np.uint32), fan)
    dst = src + np.tile(np.arange(1, fan + 1, dtype=np.uint32), n)
    keep = dst < n
    src, dst = src[keep], dst[keep]
    return Graph(n, None, dst, src, np.zeros(n, bool), None, None), src, dst


def _peak(fn):
    """``fn()`` and the peak of the memory it allocated (numpy arrays
    included: numpy reports them to tracemalloc) beyond what it started with."""
    import tracemalloc
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        out = fn()
        return out, tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()


@pytest.fixture
def small_chunks(monkeypatch):
    """The analysis's chunks small, so that a small graph has many of them
    and a memory bound per transition is not drowned by one chunk."""
    from pccl.search import liveness
    monkeypatch.setattr(liveness, "_EDGE_CHUNK", 1 << 12, raising=False)
    monkeypatch.setattr(liveness, "_STATE_CHUNK", 1 << 10, raising=False)
    # once untraced, on a small graph: the first calls of some numpy
    # functions import modules, which tracemalloc would count
    import numpy as np
    g, _, _ = _ladder(400, 3)
    g.fptr, g.rev(), g.reach(np.arange(3), backward=True)
    goal = np.zeros(400, bool)
    goal[-1] = True
    g.can_reach(goal, rounds=1)
    goal[:-10] = True
    g.can_reach(goal, rounds=0)


@pytest.mark.parametrize("seed", range(4))
def test_chunked_reversed_graph_equals_a_stable_argsort(seed, small_chunks):
    """The reversed CSR arrays built a chunk at a time (a counting sort) are
    those of a stable argsort of the targets, and the chunked reachability
    agrees with a plain search, across many chunks."""
    import numpy as np
    from pccl.search.liveness import Graph
    rng = np.random.default_rng(seed)
    n, e = 3000, 20000
    src = np.sort(rng.integers(0, n, e)).astype(np.uint32)
    dst = rng.integers(0, n, e).astype(np.uint32)
    g = Graph(n, None, dst, src, np.zeros(n, bool), None, None)
    rptr, rsrc = g.rev()
    order = np.argsort(dst, kind="stable")
    want_ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(dst, minlength=n), out=want_ptr[1:])
    assert np.array_equal(rptr, want_ptr) and np.array_equal(rsrc, src[order])
    want_fptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(src, minlength=n), out=want_fptr[1:])
    assert np.array_equal(g.fptr, want_fptr)
    goal = rng.random(n) < 0.002
    want = _plain_can_reach(src, dst, goal)
    for rounds in (0, 2, 1000):
        assert set(np.flatnonzero(g.can_reach(goal, rounds=rounds)).tolist()) == want
    assert set(np.flatnonzero(g.reach(np.flatnonzero(goal), backward=True)).tolist()) == want


def test_graph_analysis_arrays_are_compact(small_chunks):
    """The CSR offsets are 4 bytes per state (the transitions fit in 32
    bits), and the reversed graph keeps 4 bytes per transition: no array
    of 8 bytes per transition, kept or while it is built (the stall check
    used to double a large search's peak memory with them)."""
    n, fan = 20000, 8
    g, src, dst = _ladder(n, fan)
    e = len(src)
    assert g.fptr.dtype.itemsize == 4
    (rptr, rsrc), peak = _peak(g.rev)
    assert rptr.dtype.itemsize == 4 and rsrc.dtype.itemsize == 4
    # kept: 4 per transition, 4 per state; while built: counts and a cursor per state
    assert peak <= 4 * e + 8 * n + 256 * 1024, (peak, e, n)


def test_can_reach_memory_is_bounded(small_chunks):
    """can_reach when relaxation rounds do not settle it (the stall check's
    second search): every state unsettled (the reversed graph of all the
    transitions) costs at most about 4 bytes per transition; few unsettled
    (a long chain into a well-connected goal) costs nothing per transition
    and a few bytes per state.
    Both agree with a plain search."""
    import numpy as np
    from pccl.search.liveness import Graph
    n, fan = 20000, 8
    g, src, dst = _ladder(n, fan)
    e = len(src)
    goal = np.zeros(n, bool)
    goal[-1] = True
    can, peak = _peak(lambda: g.can_reach(goal))
    assert can.all()
    assert peak <= 4 * e + 10 * n + 256 * 1024, (peak, e, n)
    # every state one step from the goal, but for a chain of 300 at the end
    rng = np.random.default_rng(0)
    chain = 300
    src2 = np.repeat(np.arange(n, dtype=np.uint32), fan)
    dst2 = rng.integers(0, n, len(src2)).astype(np.uint32)
    tail = src2 >= n - chain
    dst2[tail] = np.minimum(src2[tail] + 1, n - 1)
    goal = np.zeros(n, bool)
    goal[: n - chain] = rng.random(n - chain) < 0.5
    g2 = Graph(n, None, dst2, src2, np.zeros(n, bool), None, None)
    can, peak = _peak(lambda: g2.can_reach(goal, rounds=4))
    assert set(np.flatnonzero(can).tolist()) == _plain_can_reach(src2, dst2, goal)
    assert peak <= 4 * n + 128 * 1024, (peak, len(src2), n)


def test_backward_reach_from_many_states_is_bounded(small_chunks):
    """A breadth-first step over a frontier of every state gathers a chunk
    at a time: no temporary arrays of 8 bytes per transition."""
    import numpy as np
    n, fan = 20000, 8
    g, src, dst = _ladder(n, fan)
    e = len(src)
    g.rev()
    seeds = np.arange(0, n, 2)
    seen, peak = _peak(lambda: g.reach(seeds, backward=True))
    assert set(np.flatnonzero(seen).tolist()) == _plain_can_reach(src, dst, np.isin(np.arange(n), seeds))
    assert peak <= 12 * n + 256 * 1024, (peak, e, n)


# ---------------------------------------------------------------------------
# pccl run: stalled teams
# ---------------------------------------------------------------------------

def test_run_stops_a_stalled_team():
    from pccl.api import run
    r = run(RDV, world=RDV_WALL, blackbox="straight")
    assert r.status == "stalled" and r.exit_status == 1
    assert r.stalled_since == 1
    assert r.final[TIME] == 1 + 20            # 20 unchanged time steps after t = 1
    assert [i for i, _ in r.waiting] == [0, 1]
    # the cause first: agent 0's Arrive is blocked by its failed doReach
    assert r.message.startswith("agent 0 waits for Go (line 12: ")
    assert ("Arrive (line 18: `doReach_done` is false — doReach_fail[0] is true: its doReach "
            "to (2.0, 0.0, 0.0) failed" in r.waiting[0][1])
    # only guards that can hold for the agent: agent 1 (id 1) never runs Go
    # or Arrive (`id == 0`), so it waits for Wait alone
    assert r.waiting[1][1] == "waits for Wait (line 24: `met` is false — met = false)"
    assert r.message.endswith("nothing changed since t = 1 (no variable, position or flag for "
                              "20 time steps) while agents still run")
    # explore's stall check names the same causes (pccl/model/stall.py, one code)
    from pccl.model.stall import waiting
    assert r.waiting == waiting(r.model, r.final)
    # nothing changed in the state between t = 1 and the end, but the clock
    from pccl.tools.runner import _signature
    sigs = {_signature(s) for t, s in r.summary if t >= 1}
    assert len(sigs) == 1


def test_run_stall_steps_option():
    from pccl.api import run
    from pccl.lang.errors import ArgumentError
    r = run(RDV, world=RDV_WALL, blackbox="straight", stall_steps=5)
    assert r.status == "stalled" and r.final[TIME] == 6
    r = run(RDV, world=RDV_WALL, blackbox="straight", stall_steps=0, max_time=30)
    assert r.status == "bounded" and r.exit_status == 0
    with pytest.raises(ArgumentError, match="stall_steps"):
        run(RDV, stall_steps=-1)
    res = cli("run", RDV, "--world", RDV_WALL, "--stall-steps", "3")
    assert res.exit_code == 1
    assert "result: stalled — agent 0 waits for Go" in res.output
    assert "nothing changed since t = 1 (no variable, position or flag for 3 time steps)" \
        in res.output
    # the per-step summary collapses the identical time steps into one line
    assert "  t=2–4: a0 (0.0, 0.0, 0.0)  a1 (3.0, 0.0, 0.0) (3 identical time steps)" \
        in res.output
    assert len([ln for ln in res.output.splitlines() if ln.startswith("  t=")]) == 3


def test_run_of_a_moving_or_finishing_team_is_not_stalled():
    from pccl.api import run
    assert run(RDV, world=RDV_OPEN, blackbox="straight").status == "final"
    # the token keeps going round: variables change every time step
    r = run(RING, agents=3, max_time=60)
    assert r.status == "bounded" and r.exit_status == 0


# ---------------------------------------------------------------------------
# reductions
# ---------------------------------------------------------------------------

def test_liveness_keeps_the_reductions_a_symmetric_property_allows():
    """Issue 46: symmetry, dead and por stay on with a liveness property
    (tests/search/test_liveness_reduced.py checks the verdicts and lassos); a
    property that names an agent keeps symmetry off, and says why."""
    m = make_model(SPIN, reduce="auto", properties=["eventually !b"])
    assert {"symmetry", "por"} <= set(m.reduction.on), m.reduction.describe()
    m = make_model(SPIN, reduce="auto", properties=["eventually exited[0]"])
    assert "symmetry" not in m.reduction.on
    assert "exited[0] names agent 0 in property `eventually exited[0]`" in m.reduction.describe()
    res = cli("explore", SPIN, "--reduce", "auto", "--property", "eventually !b",
              "--no-timelock")
    # every run of tl_spin stays in time 0: no run counts, so it holds (vacuously);
    # the time-lock check is what reports such a program
    assert res.exit_code == 0
    assert "needs real cycles" not in res.output and "proven for invariants only" not in res.output
    assert "  property 'eventually !b': held" in res.output


def test_verdicts_agree_with_and_without_reductions():
    cases = [(SPIN, {}, []), (SPIN_LEAVE, {}, []),
             (RING, dict(agents=3), ["forall i: want[i] ~> has[i]", "want[1] ~> has[1] within 3"]),
             (KEEP, dict(agents=3), ["forall i: want[i] ~> has[i]"]),
             (RDV, dict(world=RDV_WALL, blackbox="straight"), [ALL_EXIT])]
    for prog, kw, props in cases:
        a = explore(prog, reduce="none", properties=props, find_all=True, **kw)
        b = explore(prog, reduce="auto", properties=props, find_all=True, **kw)
        assert verdict(a, lines=False, holds=True) == verdict(b, lines=False, holds=True)


def test_lasso_trace_file_validates_and_replays(tmp_path):
    import json
    import jsonschema
    from conftest import ROOT
    out = tmp_path / "lasso.json"
    res = cli("explore", RDV, "--world", RDV_WALL, "-b", "straight", "--property", ALL_EXIT,
              "--trace-out", out)
    assert res.exit_code == 1
    doc = json.loads(out.read_text())
    jsonschema.validate(doc, json.loads((ROOT / "docs" / "trace-format.schema.json").read_text()))
    assert doc["result"]["cycle_start"] == 8 and len(doc["steps"]) == 14
    assert doc["result"]["violation"]["kind"] == "liveness"
    rep = cli("replay", out)
    assert rep.exit_code == 1
    assert "(after 14 steps; a lasso: the cycle from step 8 closes)" in rep.output
