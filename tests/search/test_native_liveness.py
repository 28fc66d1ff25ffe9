"""The native engine's temporal searches (issue 46) against the Python engine.

The native engine records the graph of a temporal search with its own state
vectors: the per-state columns of the properties (P/Q bits, the robots
under way) are made in C (``tcols``, on the level kernel's threads or one C
call per batch), Tarjan's components in C (``scc``), and the lassos of a
quotient graph made real through the Python model
(pccl/search/native_liveness.py).  Python stays the reference: both
engines must give the same verdicts, the same states and transitions, the
same recorded columns state by state, and lassos that are real runs.
Teeth: a dropped edge and a wrong column are caught.  (The cycle proviso
is the Python tables' that the native POR reads: test_liveness_reduced.py
bites there.)
"""

from __future__ import annotations

import numpy as np
import pytest

from pccl.api import explore, make_model
from pccl.model import native as NV
from pccl.search import liveness as L
from pccl.search.explorer import Explorer
from pccl.search.native_liveness import attach_scc

from conftest import FISCHER, PROGRAMS, TEST_PROGRAMS
from test_liveness_reduced import real_lasso, verdict

pytestmark = pytest.mark.skipif(NV.native_unavailable() is not None,
                                reason="no C compiler for the native engine")

ALT = str(TEST_PROGRAMS / "alternate.pccl")
DRIVE = str(TEST_PROGRAMS / "drive_exit.pccl")
DRIVE3 = str(TEST_PROGRAMS / "drive3.toml")
TOKEN = str(TEST_PROGRAMS / "token_ring.pccl")
TOKEN_KEEP = str(TEST_PROGRAMS / "token_keep.pccl")
RACE = str(PROGRAMS / "race_robust.pccl")
RACE_WORLD = str(PROGRAMS / "race.toml")
ALL_EXIT = "eventually forall i: exited[i]"

#: a per-agent int read by a property before it is set: C cannot decide the
#: bit (an undefined value), Python does (a runtime error: it does not hold)
UNDEF = """allwrite:
  int s = 0;
loc:
  int x;
Go():
  pre(s < 3);
  eff:
    x = s;
    s = s + 1;
"""

CASES = [
    (ALT, dict(agents=2), [ALL_EXIT, "eventually count(exited) == 0"]),
    (ALT, dict(agents=3), [ALL_EXIT]),
    (DRIVE, dict(world=DRIVE3, blackbox="nondet"), [ALL_EXIT]),
    (RACE, dict(world=RACE_WORLD, agents=2, blackbox="nondet"),
     [ALL_EXIT, "eventually count(exited) >= 1"]),
    (RACE, dict(world=RACE_WORLD, agents=2, blackbox="nondet-fail"),
     ["forall i: exited[i] ~> count(exited) == 2"]),
    (TOKEN, dict(agents=3), ["forall i: want[i] ~> has[i]", "want[1] ~> has[1] within 4"]),
    (TOKEN_KEEP, dict(agents=3), ["forall i: want[i] ~> has[i]"]),
    (FISCHER, dict(agents=2, overrides={"k": 1, "d": 1}),
     ["count(wait) >= 1 ~> count(inCs) >= 1", "forall i: inCs[i] ~> !inCs[i]",
      "reachable count(inCs) == 1"]),
    (UNDEF, dict(source=True, agents=2, blackbox="instant"),
     ["eventually forall i: x[i] >= 0", "s == 0 ~> x[0] == 0"]),
]
IDS = [f"{str(c[0]).rsplit('/', 1)[-1][:12].strip()}-{i}" for i, c in enumerate(CASES)]


def differences(prog, kw, props, reduce: str) -> list:
    """What differs between the Python and the native engine's temporal
    search (an empty list: they agree), and whether the native lassos are
    real runs."""
    kw = dict(kw, properties=props, reduce=reduce, find_all=True, shorten=False)
    py = explore(prog, engine="python", **kw)
    nat = explore(prog, engine="native", **kw)
    out = []
    if nat.model.engine_used != "native":
        out.append(("engine", nat.model.engine_used, nat.model.engine_reason))
    if verdict(nat) != verdict(py):
        out.append(("verdict", verdict(nat), verdict(py)))
    for f in ("states", "transitions", "max_depth"):
        if getattr(nat.stats, f) != getattr(py.stats, f):
            out.append((f, getattr(nat.stats, f), getattr(py.stats, f)))
    if not real_lasso(nat):
        out.append(("lasso", "not a real run"))
    for a, b in zip(nat.counterexamples, py.counterexamples):
        if (a.violation.kind, a.violation.name) != (b.violation.kind, b.violation.name):
            out.append(("counterexample", a.violation.name, b.violation.name))
        elif "symmetry" not in nat.model.reduction.on and (
                len(a.trace) != len(b.trace) or a.cycle_start != b.cycle_start):
            # (under symmetry the engines' representatives differ: the same
            # orbits, other real states, so another real cycle may be shown)
            out.append(("lasso length", a.violation.name, (len(a.trace), a.cycle_start),
                        (len(b.trace), b.cycle_start)))
    return out


#: each case reduced (auto) and not (none), but Fischer's unreduced graph,
#: which takes the Python engine a minute
RUNS = [(c, red) for c in CASES for red in ("auto", "none") if not (c[0] == FISCHER and red == "none")]


@pytest.mark.slow
@pytest.mark.parametrize("case, reduce", RUNS,
                         ids=[f"{red}-{IDS[CASES.index(c)]}" for c, red in RUNS])
def test_native_and_python_temporal_searches_agree(case, reduce):
    prog, kw, props = case
    assert differences(prog, kw, props, reduce) == []


@pytest.mark.slow
def test_generated_programs_native_against_python():
    """tests/liveattack.py's generated programs with liveness properties: the
    native engine, where it serves them, gives the Python engine's verdict,
    states and transitions, reduced or not (python tests/liveattack.py
    FIRST N engines runs more)."""
    import liveattack
    native = 0
    for seed in range(0, 16):
        r = liveattack.check_engines(seed, real_lasso)
        for red in ("auto", "none"):
            if red in r:
                assert r[red][1:] == (True, True), (seed, red, r)
                native += r[red][0]
    assert native >= 8, native


def columns(monkeypatch, prog, kw, props, engine: str, kernel: bool = True) -> dict:
    """The recorded graph of a search, as the analysis gets it."""
    got: dict = {}
    real = L.analyse

    def spy(model, explorer, sr, rec, **k):
        n = sr.stats.states
        got.update(dyn=rec.dyn.view()[:n].copy(), bits=rec.bits.view()[:n].copy(),
                   pend=None if rec.pend is None else rec.pend.view()[:n].copy(),
                   src=rec.src.view().copy(), dst=rec.dst.view().copy())
        return real(model, explorer, sr, rec, **k)
    monkeypatch.setattr(L, "analyse", spy)
    if not kernel:
        monkeypatch.setattr(Explorer, "_kernel", lambda self, adm, depth: None)
    explore(prog, engine=engine, properties=props, find_all=True, shorten=False, **kw)
    monkeypatch.undo()
    return got


@pytest.mark.slow
@pytest.mark.parametrize("prog, kw, props", [CASES[3], CASES[5], CASES[8]],
                         ids=["race_nondet", "token", "undefined"])
def test_recorded_columns_are_the_python_engines(monkeypatch, prog, kw, props):
    """State by state: the P/Q bits, the robots under way, the time costs
    and the transitions the native engine records (by the level kernel, and
    by the batches) are the Python engine's (reduce none: the same
    numbering)."""
    kw = dict(kw, reduce="none")
    ref = columns(monkeypatch, prog, kw, props, "python")
    for kernel in (True, False):
        got = columns(monkeypatch, prog, kw, props, "native", kernel)
        for name in ("dyn", "bits", "pend", "src", "dst"):
            if ref[name] is None:
                assert got[name] is None, name
                continue
            assert np.array_equal(got[name], ref[name]), (name, kernel)
    if "forall i: want[i] ~> has[i]" in props:
        assert ref["bits"].any() and (ref["bits"] != ref["bits"][0]).any()
    if kw.get("blackbox") == "nondet":
        assert ref["pend"] is not None and ref["pend"].any()


@pytest.mark.slow
def test_an_undefined_value_leaves_the_column_to_python(monkeypatch):
    """C says which states it cannot decide; Python decides them (and the
    level kernel hands their chunks to the batches)."""
    calls: list = []
    real = NV.NativeModel.decode

    def counted(self, b):
        calls.append(1)
        return real(self, b)
    monkeypatch.setattr(NV.NativeModel, "decode", counted)
    r = explore(UNDEF, source=True, agents=2, blackbox="instant", engine="native",
                properties=["eventually forall i: x[i] >= 0"], shorten=False)
    assert r.model.engine_used == "native"
    assert calls


def test_scc_in_c_numbers_components_as_python_tarjan():
    m = make_model(ALT, properties=[ALL_EXIT])
    native = NV.NativeModel(m).temporal_scc
    calls: list = []

    def kernel(*args):
        calls.append(1)
        return native(*args)
    rng = np.random.default_rng(46)
    for trial in range(30):
        n = int(rng.integers(1, 300))
        m_edges = int(rng.integers(0, 4 * n))
        src = np.sort(rng.integers(0, n, m_edges)).astype(np.uint32)
        dst = rng.integers(0, n, m_edges).astype(np.uint32)
        g = L.Graph(n, None, dst, src, np.zeros(n, dtype=bool), None, None)
        allowed = rng.random(n) < 0.8
        nodes = np.flatnonzero(allowed & (rng.random(n) < 0.7))
        want = g.sccs(nodes, allowed)
        attach_scc(g, kernel)
        got = g.sccs(nodes, allowed)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1]), trial
    assert len(calls) == 30


# ---------------------------------------------------------------------------
# teeth
# ---------------------------------------------------------------------------

@pytest.mark.slow
def test_teeth_a_dropped_edge_is_caught(monkeypatch):
    """Drop one recorded transition in twenty of the native search: the
    comparison with the Python engine sees it."""
    real = L.GraphRecorder.freeze

    def dropping(self, n):
        g = real(self, n)
        if getattr(self.model, "temporal_columns", None) is None:
            return g            # (the Python engine's graph stays whole)
        keep = np.ones(len(g.fdst), dtype=bool)
        keep[::20] = False
        return L.Graph(n, None, g.fdst[keep], g.esrc[keep], g.dyn, g.bits, g.pend)
    monkeypatch.setattr(L.GraphRecorder, "freeze", dropping)
    prog, kw, props = CASES[5]
    assert differences(prog, kw, props, "auto")


@pytest.mark.slow
def test_teeth_a_wrong_column_is_caught(monkeypatch):
    """A native P bit that is not the property's: caught state by state."""
    prog, kw, props = CASES[5]
    kw = dict(kw, reduce="none")
    ref = columns(monkeypatch, prog, kw, props, "python")
    real = NV.Generator.temporal_c
    monkeypatch.setattr(NV.Generator, "temporal_c",
                        lambda self: real(self).replace("TPBIT[] = {0", "TPBIT[] = {62"))
    got = columns(monkeypatch, prog, kw, props, "native", kernel=False)
    assert not np.array_equal(got["bits"], ref["bits"])


@pytest.mark.slow
def test_workers_as_threads_record_the_same_temporal_graph():
    """--workers 2 runs a native temporal search as two threads of the level
    kernel (each making chunks and their columns): the verdict, states and
    transitions of one."""
    prog, kw, props = CASES[3]
    one = explore(prog, properties=props, find_all=True, shorten=False, **kw)
    two = explore(prog, properties=props, find_all=True, shorten=False, workers=2, **kw)
    assert two.model.engine_used == "native" and two.model.engine_threads == 2
    assert verdict(two) == verdict(one)
    assert (two.stats.states, two.stats.transitions) == (one.stats.states, one.stats.transitions)
    assert real_lasso(two)


@pytest.mark.slow
def test_a_temporal_lasso_is_shortened_within_the_python_engines_budget(monkeypatch):
    """The search without the reductions that shortens a temporal verdict's
    lasso keeps the budget it had when temporal properties ran on Python
    alone (shorten.MAX_STATES), whichever engine runs it."""
    from pccl.model import shorten as S
    monkeypatch.setattr(S, "MAX_STATES", 5)
    prog, kw, props = CASES[3]
    r = explore(prog, properties=props, **kw)
    assert r.model.engine_used == "native" and r.exit_status == 1
    sh = r.counterexamples[0].shortening
    assert sh.status == "not-shown" and "budget of 5 states" in sh.reason, sh


@pytest.mark.slow
def test_fairness_is_decided_only_where_a_lasso_would_use_it(monkeypatch):
    """Under symmetry with fair arrival the components the representatives
    cannot decide are searched over real states only when the lasso would
    end in one (race_robust, 2 robots: none, where deciding every one first
    made 14 such searches); the verdict and the lasso stay those of the
    unreduced search (test_native_and_python_temporal_searches_agree)."""
    from pccl.search import lift
    calls: list = []
    real = lift.RealCycles.has_fair_cycle

    def counted(self, c, inside):
        calls.append(1)
        return real(self, c, inside)
    monkeypatch.setattr(lift.RealCycles, "has_fair_cycle", counted)
    r = explore(RACE, world=RACE_WORLD, agents=2, blackbox="nondet", properties=[ALL_EXIT],
                shorten=False)
    assert "symmetry" in r.model.reduction.on and r.exit_status == 1
    assert calls == [] and real_lasso(r)


@pytest.mark.slow
@pytest.mark.parametrize("prog, kw, props", [CASES[3], CASES[5]], ids=["race_nondet", "token"])
def test_native_temporal_search_interrupted_and_resumed(tmp_path, prog, kw, props):
    """A native temporal search checkpointed at random points and resumed
    (the recorded columns travel in the checkpoint): the uninterrupted
    result (tests/search/test_checkpoint.py's harness)."""
    import random
    from test_checkpoint import _calls, interrupted_run, summary
    opts = dict(kw, properties=props, shorten=False)
    full = explore(prog, engine="native", **opts)
    assert full.model.engine_used == "native"
    calls = _calls(prog, opts)
    rng = random.Random("temporal-" + prog)
    cuts = sorted(rng.sample(range(1, calls + 1), min(3, calls)))
    cuts = [c - (cuts[i - 1] if i else 0) for i, c in enumerate(cuts)]
    r, resumed = interrupted_run(prog, opts, str(tmp_path / "ck"), cuts)
    assert r.model.engine_used == "native"
    assert summary(r) == summary(full)
    assert resumed >= 1
