"""The native engine (pccl/model/native.py) against the Python engine: for every
program it serves, equal states, transitions, depth, time, verdicts,
violations and counterexample traces (labels and configurations), on the
shipped and test programs and on generated ones (tests/symattack.py's
seeded generator); programs and searches it does not serve fall back to
Python and say why.  Skipped where there is no C compiler or no Python.h."""

import glob
import os

import numpy as np
import pytest

from pccl.model import native as NV
from pccl.model import native_expr as NE
from pccl.api import explore, make_model
from pccl.model.layout import AGS, PC
from pccl.lang.errors import ArgumentError

from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as hs

from cases import programs

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
_probe = make_model(os.path.join(ROOT, "programs/fischer.pccl"), reduce="none")
MISSING = NV.unsupported(_probe)
pytestmark = pytest.mark.skipif(MISSING is not None, reason=f"native engine unavailable: {MISSING}")

UNREDUCED = dict(reduce="none", timelock=False, stall=False)


def canonical(model, st) -> tuple:
    """A configuration with each pc replaced by its k cell (pcs are interned
    in the order met: the native engine interns them all up front)."""
    ags = tuple((tuple(model.ctl.ks[a[PC]]),) + a[PC + 1:] for a in st[AGS])
    return st[:4] + (ags,) + st[5:]


def summary(r) -> dict:
    s = r.stats
    return {"status": r.status, "exit": r.exit_status, "initial": s.initial_states,
            "states": s.states, "transitions": s.transitions, "depth": s.max_depth,
            "max_time": s.max_time, "verdict": r.verdict,
            "violations": [(v.violation.identity, v.violation.message) for v in r.counterexamples],
            "traces": [(cx.trace.labels, tuple(canonical(r.model, st) for st in cx.trace.states))
                       for cx in r.counterexamples]}


def both(program, **kw):
    py = explore(program, engine="python", **kw)
    nat = explore(program, engine="native", **kw)
    # native, or Python after the native search met a runtime error
    assert nat.model.engine_used == "native" or "division by zero" in nat.model.engine_reason
    return summary(py), summary(nat)


def served(paths, reduce="none"):
    """The programs the native engine serves with these reductions."""
    out = []
    for p in paths:
        try:
            m = make_model(p, reduce=reduce)
        except Exception:
            continue
        if NV.unsupported(m) is None:
            out.append(os.path.relpath(p, ROOT))
    return out


ALL_PROGRAMS = sorted(glob.glob(os.path.join(ROOT, "programs", "*.pccl"))
                      + glob.glob(os.path.join(ROOT, "tests", "programs", "*.pccl")))
PROGRAMS = served(ALL_PROGRAMS)
# (under the default reductions a few fall back: rand() in a statement that
# statement merging runs through, tests/programs/eng_lock.pccl, ref_rand.pccl)
DEFAULT_PROGRAMS = served(ALL_PROGRAMS, reduce="auto")


def test_the_shipped_and_test_programs_served():
    assert {"programs/fischer.pccl", "programs/leader.pccl", "tests/programs/ref_atomic.pccl",
            "tests/programs/ref_mutex_bad.pccl", "tests/programs/eng_assert.pccl"} <= set(PROGRAMS)


#: program -> (the unreduced search's state budget, the default search's):
#: smaller budgets for the programs whose states cost most: eng_loop and
#: runaway spin for ever inside one event (an infinite space, so the search
#: always stops at its budget), each of their states a chain of up to 1,000
#: merged steps under the defaults; their bounded searches still compare the
#: engines state by state, at a tenth of the cost
BUDGET = {"tests/programs/eng_loop.pccl": (6_000, 300),
          "tests/programs/runaway.pccl": (60_000, 300)}


@pytest.mark.parametrize("program", PROGRAMS)
def test_equal_results_on_served_programs(program):
    budget = BUDGET.get(program, (60_000, None))[0]
    py, nat = both(os.path.join(ROOT, program), max_states=budget, find_all=True, **UNREDUCED)
    assert nat == py


@pytest.mark.parametrize("k, d, inv", [(1, 1, "count(inCs) <= 1"), (1, 2, None),
                                       (2, 1, "forall i: inCs[i] -> reqid == i")])
def test_fischer_equal_with_counterexample(k, d, inv):
    kw = dict(overrides={"k": str(k), "d": str(d)}, **UNREDUCED)
    if inv:
        kw["invariants"] = (inv,)
    py, nat = both(os.path.join(ROOT, "programs/fischer.pccl"), **kw)
    assert nat == py
    assert py["states"] > 10_000
    if inv == "count(inCs) <= 1":
        assert py["status"] == "violation" and len(py["traces"][0][0]) > 50


def test_three_agents_and_time_bound():
    kw = dict(overrides={"k": "0", "d": "1"}, agents=3, max_time=1, abstract_time=False,
              **UNREDUCED)
    py, nat = both(os.path.join(ROOT, "programs/fischer.pccl"), **kw)
    assert nat == py and py["status"] == "bounded" and py["max_time"] == 1


@settings(max_examples=20, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                 HealthCheck.filter_too_much])
@given(prog=programs(), agents=hs.integers(1, 3), blackbox=hs.sampled_from(["instant", "straight"]))
def test_equal_results_on_generated_programs(prog, agents, blackbox):
    """tests/search/test_fingerprints.py's generator, the programs the engine serves
    (int and bool variables; no floats, lists or rand in statements)."""
    text, invariants = prog
    kw = dict(source=True, agents=agents, blackbox=blackbox, invariants=invariants)
    assume(NV.unsupported(make_model(text, reduce="none", **kw)) is None)
    py, nat = both(text, find_all=True, max_states=2_000, **kw, **UNREDUCED)
    assert nat == py


def test_auto_falls_back_with_the_reason():
    # (a temporal property runs natively, issue 46: its P and Q in C, or
    # beyond C's subset as property memo sites, issue 43; both engines agree)
    kw = dict(overrides={"k": "1"}, properties=("eventually count(doReach_done) == 2",),
              max_states=100)
    r = explore(os.path.join(ROOT, "programs/fischer.pccl"), **kw)
    rp = explore(os.path.join(ROOT, "programs/fischer.pccl"), engine="python", **kw)
    assert r.model.engine_used == "native" and rp.model.engine_used == "python"
    assert (r.status, r.stats.states, r.stats.transitions) == \
        (rp.status, rp.stats.states, rp.stats.transitions)
    r = explore(os.path.join(ROOT, "programs/race.pccl"), reduce="none", timelock=False,
                world=os.path.join(ROOT, "programs/race.toml"), stall=False, max_states=100,
                delta=0.5, blackbox="straight")
    assert r.model.engine_used == "python" and r.model.engine_reason == "a non-integer δ"
    r = explore(os.path.join(ROOT, "programs/fischer.pccl"), overrides={"k": "1", "d": "1"},
                **UNREDUCED)
    assert r.model.engine_used == "native" and r.model.engine_reason is None


def test_native_asked_for_an_unsupported_search_is_an_error():
    with pytest.raises(ArgumentError, match="native engine cannot run this search: .*coverage"):
        explore(os.path.join(ROOT, "programs/fischer.pccl"), coverage=True, engine="native")


def test_overflow_falls_back_to_python():
    text = ("Agent::Grow\n\nallwrite:\n  int x = 1;\n\nallread:\n\nloc:\n\nInit:\n\n"
            "Double():\n  pre(x > 0);\n  eff:\n    x = x * 1000000;\n")
    r = explore(text, source=True, engine="auto", max_states=200, **UNREDUCED)
    py = explore(text, source=True, engine="python", max_states=200, **UNREDUCED)
    assert r.model.engine_used == "python" and "64 bits" in r.model.engine_reason
    assert summary(r) == summary(py)


def head(out: str) -> str:
    return next(ln for ln in out.splitlines() if ln.startswith("pccl explore"))


def test_header_names_the_engine(tmp_path):
    from click.testing import CliRunner
    from pccl.cli import main
    from pccl.cli.cmd_explore import PYTHON_COST
    args = ["explore", os.path.join(ROOT, "programs/fischer.pccl"), "--set", "k=0", "--set",
            "d=0", "--no-progress", "--reduce", "none", "--no-timelock", "--no-stall"]
    out = CliRunner().invoke(main, args).output
    assert head(out).endswith("reductions none, engine native")
    out = CliRunner().invoke(main, args[:-2] + ["--engine", "python"]).output
    assert head(out).endswith("reductions none, engine python")
    out = CliRunner().invoke(main, args[:-2]).output     # auto, time-lock check on
    assert head(out).endswith("reductions none, engine native")
    out = CliRunner().invoke(main, args[:7]).output     # the defaults
    assert head(out).endswith("reductions merge+symmetry+por+dead, engine native")
    # auto where the native engine cannot: the header says why
    out = CliRunner().invoke(main, ["explore", os.path.join(ROOT, "programs/race.pccl"),
                                    "--world", os.path.join(ROOT, "programs/race.toml"),
                                    "--delta", "0.5", "-b", "straight",
                                    "--no-progress", "--max-states", "50"]).output
    assert head(out).endswith(f"engine python ({PYTHON_COST}a non-integer δ)")
    # formation's invariant over positions (dist()) runs native (issue 43.1)
    out = CliRunner().invoke(main, ["explore", os.path.join(ROOT, "programs/formation.pccl"),
                                    "--world", os.path.join(ROOT, "programs/formation.toml"),
                                    "--no-progress", "--max-states", "50"]).output
    assert head(out).endswith(", engine native")
    # a program that moves runs native
    out = CliRunner().invoke(main, ["explore", os.path.join(ROOT, "programs/race.pccl"),
                                    "--no-progress", "--max-states", "50"]).output
    assert head(out).endswith("reductions merge+symmetry+por+dead, engine native")


# -- the batch hooks: one C call per chunk of a level, fingerprints in C -------

def reachable(nm, limit=20_000) -> list:
    """Native states of a breadth-first search (per-state successors()), with
    repeats: every successor met, admitted or not."""
    seen, level, out = set(), list(nm.init_states()), []
    out += level
    while level and len(out) < limit:
        nxt = []
        for s in level:
            for _, s2 in nm.successors(s):
                out.append(s2)
                if nm.key(s2) not in seen:
                    seen.add(nm.key(s2))
                    nxt.append(s2)
        level = nxt
    return out


CASES = [("programs/fischer.pccl", dict(overrides={"k": "1", "d": "1"})),
         ("programs/fischer.pccl", dict(overrides={"k": "1", "d": "1"}, reduce="auto")),
         ("programs/fischer.pccl", dict(overrides={"k": "0", "d": "1"}, agents=3,
                                        abstract_time=False, max_time=2)),
         ("programs/leader.pccl", {}),
         ("tests/programs/ref_mutex_bad.pccl", {})]


@pytest.mark.parametrize("program, kw", CASES)
def test_c_fingerprints_are_pccl_fingerprints(program, kw):
    """fingerprint_batch's keys are pccl.fingerprint's (xxh3-128 of marshal v2
    of the key, with and without the clock), and its first occurrences those
    of the explorer's own dict."""
    from pccl.search.fingerprint import fingerprint
    nm = NV.NativeModel(make_model(os.path.join(ROOT, program), **{"reduce": "none", **kw}))
    states = reachable(nm)
    assert len(states) > 100
    dropped = 0
    for lo in range(0, len(states), 5000):
        batch = states[lo:lo + 5000]
        ck, first, occ = nm.fingerprint_batch(batch)
        want = [fingerprint(nm.key(s)) for s in batch]
        assert ck == [b"".join(want)]
        first_of = dict(zip(reversed(want), range(len(want) - 1, -1, -1)))
        assert first.tolist() == sorted(first_of.values())
        assert occ.tolist() == [first_of[k] for k in want]
        dropped += len(batch) - len(first)
    assert dropped > 0      # repeats were met and dropped (not in every batch)


@pytest.mark.parametrize("program, kw, kinds", [
    (CASES[0][0], CASES[0][1], 1), (CASES[3][0], CASES[3][1], 2),
    ("programs/race_robust.pccl", dict(world=os.path.join(ROOT, "programs", "race.toml"),
                                       blackbox="nondet", agents=3, reduce="auto"), 10)])
def test_fingerprints_with_signatures_are_the_two_calls(program, kw, kinds):
    """fingerprint_sig_batch (one pass over the states) gives fingerprint_batch's
    three items and, fourth, stall_signatures' and the per-state signature's
    values; and equal signatures stay equal, unequal ones apart (the stall
    check only compares them), against pccl/model/stall.py's fields."""
    from pccl.model.stall import signature_fn
    py = make_model(os.path.join(ROOT, program), **{"reduce": "none", **kw})
    nm = NV.NativeModel(py)
    states = reachable(nm, 6_000)
    sig, want_sig = nm.stall_signature(), signature_fn(py)
    by_native: dict = {}
    by_python: dict = {}
    for lo in range(0, len(states), 2000):
        batch = states[lo:lo + 2000]
        ck, first, occ, sigs = nm.fingerprint_sig_batch(batch)
        ck2, first2, occ2 = nm.fingerprint_batch(batch)
        assert ck == ck2 and first.tolist() == first2.tolist() and occ.tolist() == occ2.tolist()
        assert sigs.tolist() == nm.stall_signatures(batch).tolist() == [sig(s) for s in batch]
        for s, h in zip(batch, sigs.tolist()):
            w = want_sig(nm.decode(s))
            by_native.setdefault(h, set()).add(w)
            by_python.setdefault(w, set()).add(h)
    assert all(len(v) == 1 for v in by_native.values())
    assert all(len(v) == 1 for v in by_python.values())
    assert len(by_native) >= kinds      # (Fischer's team looks the same throughout)


@pytest.mark.parametrize("seed", range(3))
def test_table_kernels_are_the_numpy_table(seed):
    """FingerprintTable with the native engine's probes (table_kernels) and
    without them, fed the same batches (repeats, fingerprints sharing their
    index word so that probes run long, index rebuilds as it grows): the same
    state numbers found and the same arrays; a slot past the index is refused."""
    import numpy as np
    from pccl.search.explorer import FingerprintTable
    nm = NV.NativeModel(make_model(os.path.join(ROOT, "programs", "fischer.pccl"),
                                   overrides={"k": "1", "d": "1"}))
    rng = np.random.default_rng(seed)
    c, py = FingerprintTable(capacity=64, kernels=nm.table_kernels), FingerprintTable(capacity=64)
    # (12 batches of 1,500 drawn from 10,000: about 8,300 admitted, the
    # arrays grown from 64 rows, the index of 8,192 slots rebuilt twice)
    pool = rng.integers(0, 2**63, size=(10_000, 2), dtype=np.uint64)
    pool[::3, 1] = pool[::3, 1] & np.uint64(0xFFFF_0000_0000_0000)   # equal low bits: long probes
    for _ in range(12):
        keys = pool[rng.integers(0, len(pool), 1500)]
        blob = [keys.tobytes()]
        _, first = np.unique(keys, axis=0, return_index=True)
        first.sort()
        a, b = c.new_positions(blob, first), py.new_positions(blob, first)
        assert a.tolist() == b.tolist() and c.found.tolist() == py.found.tolist()
        par = rng.integers(0, 1000, len(a)).astype(np.uint32)
        c.add(len(a), par)
        py.add(len(b), par)
        assert c.n == py.n
    assert np.array_equal(c.fps[:c.n], py.fps[:py.n])
    found = c.lookup(pool)
    assert np.array_equal(found, py.lookup(pool))
    assert int((found >= 0).sum()) == c.n > 4_000        # each admitted one found, once
    with pytest.raises(ValueError):
        nm.table_kernels[0](c.slots, c.fps, pool[:2], np.zeros(2, np.int64), len(c.slots))


def assert_batches_are_successors(nm, states) -> None:
    """successor_batch over ``states`` in chunks of 1,000: the counts and
    successors of nm.successors, state by state, and the labels met (a merged
    transition's rule label, the events fired), each once."""
    for lo in range(0, len(states), 1000):
        chunk = states[lo:lo + 1000]
        ns, flat, labs = nm.successor_batch(chunk)
        one = [nm.successors(s) for s in chunk]
        assert ns == [len(x) for x in one]
        assert flat == [b for x in one for _, b in x]
        assert sorted(labs, key=repr) == sorted({lab[:3] for x in one for lab, _ in x}, key=repr)


@pytest.mark.parametrize("program, kw", CASES)
def test_successor_batch_equals_successors(program, kw):
    nm = NV.NativeModel(make_model(os.path.join(ROOT, program), **{"reduce": "none", **kw}))
    assert_batches_are_successors(nm, reachable(nm, 5_000))


@pytest.mark.parametrize("program, kw", [
    ("tests/programs/ref_mutex_bad.pccl", dict(invariants=("count(inCs) <= 1",))),
    ("tests/programs/eng_assert.pccl", {})])
def test_c_violations_are_the_python_models(program, kw):
    """violations(state) in C: [] exactly where the Python model finds none,
    otherwise the Python model's own."""
    py = make_model(os.path.join(ROOT, program), reduce="none", **kw)
    nm = NV.NativeModel(py)
    states = reachable(nm, 5_000)
    bad = 0
    for s in states:
        got = [v.identity for v in nm.violations(s)]
        assert got == [v.identity for v in py.violations(nm.decode(s))]
        bad += bool(got)
    assert bad > 0
    # the batch check (one C call): every state with violations among the suspects
    suspects = nm.suspects(states)
    assert suspects == sorted(suspects)
    assert {j for j, s in enumerate(states) if nm.violations(s)} <= set(suspects)
    assert all(not nm.violations(s) for j, s in enumerate(states) if j not in set(suspects))


@pytest.mark.slow
def test_hooks_off_gives_the_same_search():
    """The explorer with the batch hooks and without them (per-state
    successors, Python's marshal and xxh3): the same search, at several
    batch sizes and a state budget that stops it mid-level."""
    from pccl.search.explorer import Explorer
    path = os.path.join(ROOT, "programs/fischer.pccl")

    class Plain:
        """nm without its batch hooks."""
        def __init__(self, nm):
            self.nm = nm

        def __getattr__(self, name):
            if name in ("successor_batch", "fingerprint_batch"):
                raise AttributeError(name)
            return getattr(self.nm, name)

    def run(model, batch, **kw):
        r = Explorer(model, batch=batch, labels=set(), **kw).run()
        return (r.status, r.stats.states, r.stats.transitions, r.stats.max_depth,
                [(f.violation.identity, f.trace.labels, f.trace.states) for f in r.found])

    for inv, kw in ((None, {}), (None, {"max_states": 7_777}), ("count(inCs) <= 1", {})):
        nm = NV.NativeModel(make_model(path, reduce="none", overrides={"k": "0", "d": "1"},
                                       invariants=(inv,) if inv else ()))
        want = run(Plain(nm), 4096, **kw)
        assert want[0] == ("violation" if inv else "bounded" if kw else "exhaustive")
        assert want[1] == 7_777 if kw else want[1] > 7_777
        for batch in (1000, NV.NativeModel.BATCH):
            assert run(nm, batch, **kw) == want


def test_without_xxhash_symbol_the_explorer_hashes_in_python(monkeypatch):
    """Where xxhash's module does not export XXH3_128bits the fingerprint hook
    is off, and the search is the same."""
    path = os.path.join(ROOT, "programs/fischer.pccl")
    kw = dict(overrides={"k": "0", "d": "0"}, **UNREDUCED)
    want = summary(explore(path, engine="native", **kw))
    monkeypatch.setattr(NV, "_xxh3_128_address", lambda: None)
    assert NV.NativeModel(make_model(path, reduce="none")).fingerprint_batch is None
    got = explore(path, engine="native", **kw)
    assert got.model.engine_used == "native" and summary(got) == want


def test_models_with_and_without_the_clock_in_the_key_side_by_side():
    """Two models of one program, the clock in the key and not: each one's C
    fingerprints are of its own key, whichever was built last (the key's
    form is a constant of the generated source, not a module global)."""
    from pccl.search.fingerprint import fingerprint
    path = os.path.join(ROOT, "programs/fischer.pccl")
    kw = dict(reduce="none", overrides={"k": "0", "d": "0"})
    a = NV.NativeModel(make_model(path, abstract_time=True, **kw))
    b = NV.NativeModel(make_model(path, abstract_time=False, **kw))
    for nm in (a, b, a):
        states = reachable(nm, 3_000)
        assert nm.fingerprint_batch(states)[0] == [b"".join(fingerprint(nm.key(s))
                                                            for s in states)]


# -- the default search: reductions, the time-lock and stall checks (issue 23) --

#: agents that name one another (a shared owner, a local peer copied from it):
#: symmetry's canonical key tries tied agents in every order
PEERS = """Agent::Peers

allwrite:
  int owner = -1;
  int turns = 0;

allread:

loc:
  int id = getAgentIndex();
  int peer = -1;
  int c = rand(1);
  bool want = true;

Init:

Claim():
  pre(want && owner == -1);
  eff:
    atomic:
      owner = id;
    c = c + 1;
    want = false;

Watch():
  pre(!want && peer == -1);
  eff:
    peer = owner;
    if (peer == id):
      c = 0;

Give():
  pre(owner == id && peer != -1);
  eff:
    atomic:
      owner = -1;
      turns = turns + 1;
    peer = -1;
    if (turns < 3):
      want = true;
"""


def test_the_default_search_runs_native():
    r = explore(os.path.join(ROOT, "programs/fischer.pccl"), overrides={"k": "1"})
    assert r.model.engine_used == "native" and r.model.engine_reason is None
    assert set(r.model.reduction.on) == {"merge", "symmetry", "por", "dead"} and r.timelock and r.stall


@pytest.mark.parametrize("program", DEFAULT_PROGRAMS)
def test_equal_default_results_on_served_programs(program):
    """Reductions, time-lock and stall checks on (the defaults): the same
    search, verdicts and counterexamples (merged labels included)."""
    # (a merged chain runs up to 1,000 steps: eng_loop's spin costs both
    # engines that much per state)
    budget = BUDGET.get(program, (None, 3_000))[1]
    py, nat = both(os.path.join(ROOT, program), max_states=budget, find_all=True)
    assert nat == py


@pytest.mark.slow
@pytest.mark.parametrize("k, d, inv, n", [(1, 1, "count(inCs) <= 1", 2), (2, 1, None, 2),
                                          (0, 1, None, 3),
                                          (1, 2, "forall i: inCs[i] -> reqid == i", 2)])
def test_fischer_default_equal(k, d, inv, n):
    kw = dict(overrides={"k": str(k), "d": str(d)}, agents=n)
    if inv:
        kw["invariants"] = (inv,)
    py, nat = both(os.path.join(ROOT, "programs/fischer.pccl"), **kw)
    assert nat == py
    assert py["states"] > 150          # (dead: Fischer's unread cstime leaves the key)
    if inv == "count(inCs) <= 1":
        assert py["status"] == "violation"


@pytest.mark.parametrize("reduce", ["merge", "por", "symmetry", "merge,por", "symmetry,por"])
def test_each_reduction_alone_equal(reduce):
    kw = dict(overrides={"k": "1", "d": "1"}, reduce=reduce,
              invariants=("count(inCs) <= 1",), find_all=True)
    py, nat = both(os.path.join(ROOT, "programs/fischer.pccl"), **kw)
    assert nat == py and py["status"] == "violation"


@pytest.mark.parametrize("agents", [2, 3])
def test_agents_naming_each_other_equal(agents):
    """Symmetry where agents hold other agents' ids (the permuting key), with
    a time-lock-free, stall-checked search."""
    m = make_model(PEERS, source=True, agents=agents)
    assert "symmetry" in m.reduction.on and NV.unsupported(m) is None
    py, nat = both(PEERS, source=True, agents=agents, find_all=True)
    assert nat == py and py["states"] > 50


def test_time_lock_and_stall_counterexamples_equal():
    for name in ("tl_spin.pccl", "tl_spin_leave.pccl", "token_keep.pccl"):
        path = os.path.join(ROOT, "tests", "programs", name)
        if NV.unsupported(make_model(path)) is not None:
            continue
        for stall in (True, False):
            py, nat = both(path, find_all=True, stall=stall)
            assert nat == py


def orbit_pairs(nm, py, states):
    """Whether the native key and the Python key identify the same states."""
    by_nat: dict = {}
    by_py: dict = {}
    for s in states:
        a, b = nm.key(s), py.key(nm.decode(s))
        by_nat.setdefault(a, b)
        by_py.setdefault(b, a)
        assert by_nat[a] == b and by_py[b] == a


@pytest.mark.parametrize("text, kw", [
    (os.path.join(ROOT, "programs/fischer.pccl"), dict(overrides={"k": "1", "d": "1"})),
    (os.path.join(ROOT, "programs/fischer.pccl"), dict(overrides={"k": "0", "d": "1"}, agents=3)),
    (PEERS, dict(source=True, agents=3))])
def test_canonical_keys_identify_the_same_states(text, kw):
    """The C canonical key and reduce.py's identify exactly the same states
    (both are canonical forms of an orbit): a bijection between the two sets
    of keys, over every successor met; and permuting the agents of a state
    leaves the C key as it is."""
    import itertools
    from array import array
    py = make_model(text, reduce="symmetry", **kw)
    nm = NV.NativeModel(py)
    states = reachable(nm, 8_000)
    orbit_pairs(nm, py, states)
    g = nm.gen
    bid, shid = g.reductions()[2]
    moved = 0
    for s in states[::37]:
        v = nm.unpack(s)
        for perm in itertools.permutations(range(g.N)):
            r = [0] * g.N
            for new, old in enumerate(perm):
                r[old] = new
            w = array("q", v)
            ren = r
            for new, old in enumerate(perm):
                blk = v[g.AG0 + old * g.A:g.AG0 + (old + 1) * g.A]
                for q in bid:
                    blk[q] = ren[blk[q]] if 0 <= blk[q] < g.N else blk[q]
                w[g.AG0 + new * g.A:g.AG0 + (new + 1) * g.A] = blk
            for q in list(shid) + list(range(g.LQ0, g.LQ0 + g.N)):
                w[q] = ren[v[q]] if 0 <= v[q] < g.N else v[q]
            t = nm.pack(w)
            moved += t != s
            assert nm.key(t) == nm.key(s)
            assert py.key(nm.decode(t)) == py.key(nm.decode(s))
    assert moved > 0


@pytest.mark.parametrize("program, kw", CASES + [("programs/fischer.pccl", dict(overrides={"k": "1"}, reduce="auto"))])
def test_reduced_successor_batch_equals_successors(program, kw):
    kw = {"reduce": "auto", **kw}
    nm = NV.NativeModel(make_model(os.path.join(ROOT, program), **kw))
    assert_batches_are_successors(nm, reachable(nm, 5_000))


def test_reduced_successors_are_the_python_ones():
    """State by state: the native reduced successors (labels and decoded
    configurations) are the Reduced wrapper's."""
    for kw in (dict(overrides={"k": "1", "d": "1"}), dict(overrides={"k": "0", "d": "1"}, agents=3)):
        py = make_model(os.path.join(ROOT, "programs/fischer.pccl"), **kw)
        nm = NV.NativeModel(py)
        states = reachable(nm, 4_000)
        merged = 0
        for s in states[::7]:
            want = py.successors(nm.decode(s))
            got = nm.successors(s)
            assert [lab for lab, _ in got] == [lab for lab, _ in want]
            assert [canonical(py, nm.decode(b)) for _, b in got] == [canonical(py, t) for _, t in want]
            merged += sum(len(lab) == 5 for lab, _ in got)
        assert merged > 0


@pytest.mark.slow
@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                 HealthCheck.filter_too_much])
@given(prog=programs(), agents=hs.integers(1, 3), blackbox=hs.sampled_from(["instant", "straight"]))
def test_equal_default_results_on_generated_programs(prog, agents, blackbox):
    """The generated programs under the default search (every sound
    reduction, the time-lock and stall checks)."""
    text, invariants = prog
    kw = dict(source=True, agents=agents, blackbox=blackbox, invariants=invariants)
    assume(NV.unsupported(make_model(text, **kw)) is None)
    py, nat = both(text, find_all=True, max_states=2_000, **kw)
    assert nat == py


def test_a_replaced_successor_function_runs_in_python():
    """A caller's own successors (a wrapper that counts or interrupts) is what
    the search runs: the native engine declines, saying why."""
    from pccl.api import explore_model
    m = make_model(os.path.join(ROOT, "programs/fischer.pccl"), overrides={"k": "0", "d": "0"})
    real, calls = m.successors, [0]

    def successors(s):
        calls[0] += 1
        return real(s)

    m.successors = successors
    r = explore_model(m, stall=False)      # (the stall check on: the frozen-team check explores again)
    assert r.model.engine_used == "python" and calls[0] == r.stats.states
    assert r.model.engine_reason == ("the model's successors function was replaced "
                                     "(the Python engine runs it)")


#: Partial-order reduction beyond agent-local steps, decided per state
#: (reduce.Por.eligible over independence.py's tables): local guards (an
#: agent at the top of its block counts only the events enabled now), a
#: shared variable only some agents write (``w``, those with k = 0), a read of one
#: nobody writes in some states, a lock-protected variable, LOCK REQUEST /
#: RELEASE / ATOMIC EXECUTION, and a write a property reads.
PORMIX = """Agent::PorMix

allwrite:
  int s = 0;
  int w = 0;
  int prot = 0;
  int seen = 0;

allread:

loc:
  int k = rand(1);
  int r = 0;
  int n = 0;

Init:

Write():
  pre(n == 0 && k == 0);
  eff:
    w = w + 1;
    n = 1;

Read():
  pre(n < 2);
  eff:
    r = w;
    r = r + s;
    n = n + 2;

Lock():
  pre(n >= 2 && n < 4);
  eff:
    atomic:
      prot = prot + 1;
      r = prot;
    n = 4;
    if (r > 1):
      seen = seen + 1;
"""


@pytest.mark.parametrize("agents, n0, events", [(2, 1, "any"), (3, 1, "any"), (2, 2, "any"),
                                                 (3, 2, "first")])
def test_per_state_por_equal(agents, n0, events):
    """The native engine's ample sets are reduce.Por's, state by state: the
    same search under the default options, with an invariant over ``seen``
    (its write is never ample) and one that fails, all violations."""
    kw = dict(source=True, agents=agents, n0=n0, events=events, find_all=True,
              invariants=("seen <= 1", "prot <= 2"))
    m = make_model(PORMIX, **{k: v for k, v in kw.items() if k != "find_all"})
    assert "por" in m.reduction.on and NV.unsupported(m) is None
    py, nat = both(PORMIX, **kw)
    assert nat == py
    # the per-state rule matters here: without por the search is larger
    nopor = summary(explore(PORMIX, engine="native", reduce="merge", **kw))
    assert py["states"] < nopor["states"]


def test_more_por_bits_than_a_mask_holds_runs_in_python():
    """64 shared variables and the lock bit do not fit the C masks of the
    per-state POR test: the native engine declines, naming why; without
    por it serves the program."""
    decls = "".join(f"  int v{k} = 0;\n" for k in range(64))
    text = PORMIX.replace("  int seen = 0;\n", "  int seen = 0;\n" + decls)
    m = make_model(text, source=True, agents=2)
    assert "por" in m.reduction.on
    assert "more than 63 shared and allread variables" in NV.unsupported(m)
    assert NV.unsupported(make_model(text, source=True, agents=2, reduce="merge")) is None
    assert NV.unsupported(make_model(PORMIX, source=True, agents=2)) is None


# -- --workers N on the native engine: forked workers over native vectors ------

FISCHER = os.path.join(ROOT, "programs/fischer.pccl")
MUTEX = "count(inCs) <= 1"
NATIVE_WORKER_CASES = {
    "fischer-exhaustive": (FISCHER, dict(overrides={"k": "1", "d": "1"}, **UNREDUCED)),
    "fischer-violation": (FISCHER, dict(overrides={"k": "1"}, invariants=(MUTEX,), **UNREDUCED)),
    "fischer-all": (FISCHER, dict(overrides={"k": "0"}, invariants=(MUTEX,), find_all=True,
                                  **UNREDUCED)),
    "fischer-max-states": (FISCHER, dict(overrides={"k": "1", "d": "1"}, max_states=3000,
                                         **UNREDUCED)),
    "fischer-depth": (FISCHER, dict(overrides={"k": "1", "d": "1"}, depth=15, **UNREDUCED)),
    # the defaults: merge+symmetry+por (the canonical key), time-lock and stall
    # recorder (slow: 40 s, the Python engine's 377,321 states)
    "fischer-3-agents-reduced": (FISCHER, dict(agents=3, overrides={"k": "0", "d": "1"})),
    "fischer-reduced-violation": (FISCHER, dict(overrides={"k": "1"}, invariants=(MUTEX,))),
    "fischer-recorder-depth": (FISCHER, dict(overrides={"k": "1", "d": "1"}, depth=40)),
    "fischer-recorder-max-states": (FISCHER, dict(overrides={"k": "1", "d": "1"},
                                                  max_states=2000)),
    "tl_spin-stall": (os.path.join(ROOT, "tests/programs/tl_spin.pccl"),
                      dict(find_all=True, stall=True)),
    "tl_spin-no-stall": (os.path.join(ROOT, "tests/programs/tl_spin.pccl"),
                         dict(find_all=True, stall=False)),
    "tl_spin-3-agents": (os.path.join(ROOT, "tests/programs/tl_spin.pccl"),
                         dict(agents=3, find_all=True)),
    "token_keep-stall": (os.path.join(ROOT, "tests/programs/token_keep.pccl"),
                         dict(find_all=True, stall=True)),
    "token_keep-no-timelock": (os.path.join(ROOT, "tests/programs/token_keep.pccl"),
                               dict(find_all=True, stall=True, timelock=False)),
    "peers-symmetry": (PEERS, dict(source=True, agents=3, find_all=True)),
}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if "3-agents-reduced" in n
                                  else n for n in sorted(NATIVE_WORKER_CASES)])
def test_native_workers_give_the_one_worker_results(name):
    """``--workers 2`` and ``3`` run the native engine (not the Python one,
    as before) and give one native worker's and the Python engine's
    figures, verdict, violations and counterexamples (decoded), with the
    time-lock/stall recorder on and off, violations and bounds."""
    program, kw = NATIVE_WORKER_CASES[name]
    py = explore(program, engine="python", **kw)
    one = explore(program, engine="auto", **kw)
    assert one.model.engine_used == "native", one.model.engine_reason
    assert summary(one) == summary(py)
    # the largest model time too (gathered from the workers; it was None)
    want = summary(one)
    assert want["max_time"] is not None
    for w in (2, 3):
        many = explore(program, engine="auto", workers=w, **kw)
        assert many.model.engine_used == "native", (w, many.model.engine_reason)
        assert summary(many) == want, f"workers={w}"


class _SlowBatch:
    """A native model whose batch of successors takes ``delay`` seconds longer
    in the forked workers: a worker slowed down, as by another job on its core."""

    def __init__(self, native, delay: float):
        self.native, self.pid, self.delay = native, os.getpid(), delay

    def __getattr__(self, name):
        return getattr(self.native, name)

    def successor_batch(self, states):
        import time
        if os.getpid() != self.pid:
            time.sleep(self.delay)
        return self.native.successor_batch(states)


@pytest.mark.parametrize("workers", [2, 3])
def test_native_workers_balance_large_levels(workers, monkeypatch):
    """Balanced levels engage with native workers when asked for
    (``PCCL_BALANCE=1``): states (native vectors) move between the
    processes, and the figures and the counterexample stay one native
    process's (small chunks and threshold: the forked workers inherit
    them); by default the native levels keep the static split."""
    from pccl.search import parallel as P
    from pccl.search import parallel_pipes as PP
    from pccl.search.explorer import Explorer
    monkeypatch.setattr(PP, "_CHUNK", 4)
    monkeypatch.setattr(PP, "_NATIVE_CHUNK", 1)
    monkeypatch.setattr(PP, "_BALANCE_NATIVE", True)       # PCCL_BALANCE=1
    monkeypatch.setattr(PP, "_MIN_GIVE", 2)
    monkeypatch.setattr(PP, "_BALANCE_LEVEL", 0)
    m = make_model(FISCHER, overrides={"k": "1"}, invariants=(MUTEX,),     # reduced: symmetry
                   reduce="merge,symmetry,por")       # (dead leaves too few states to move)
    m.lock_deadlocks = True
    nm = NV.NativeModel(m)
    one = Explorer(nm, max_states=20_000).run()
    e = P.ParallelExplorer(_SlowBatch(nm, 0.002), workers=workers,
                           max_states=20_000)
    many = e.run()
    assert e.moved > 10, e.moved
    # by default (no PCCL_BALANCE=1) native levels keep the static split
    monkeypatch.setattr(PP, "_BALANCE_NATIVE", False)
    static = P.ParallelExplorer(_SlowBatch(nm, 0.002), workers=workers, max_states=20_000)
    assert static.run().stats.states == many.stats.states and static.moved == 0
    sig = [(r.status, r.stats.states, r.stats.transitions, r.stats.max_depth,
            [(f.violation.kind, f.index, f.depth, f.trace and tuple(f.trace.labels),
              f.trace and f.trace.states) for f in r.found]) for r in (one, many)]
    assert sig[0] == sig[1] and one.found


def test_native_workers_overflow_fall_back_to_python_workers():
    """An int beyond 64 bits met by a native worker: the search runs again
    on the Python engine, with the workers, and gives its result."""
    text = ("Agent::Grow\n\nallwrite:\n  int x = 1;\n\nallread:\n\nloc:\n\nInit:\n\n"
            "Double():\n  pre(x > 0);\n  eff:\n    x = x * 1000000;\n")
    py = explore(text, source=True, engine="python", max_states=200, **UNREDUCED)
    for w in (2, 3):
        r = explore(text, source=True, engine="auto", workers=w, max_states=200, **UNREDUCED)
        assert r.model.engine_used == "python" and "64 bits" in r.model.engine_reason
        assert summary(r) == summary(py)        # max_time too (it was None)


def test_header_names_the_native_engine_with_workers():
    from click.testing import CliRunner
    from pccl.cli import main
    args = ["explore", FISCHER, "--set", "k=0", "--set", "d=0", "--no-progress", "--workers"]
    out = CliRunner().invoke(main, args + ["2"]).output
    # (levels of at most 11 states: the threads do not share them, and the header says so)
    assert head(out).endswith("reductions merge+symmetry+por+dead, engine native on 1 thread of 2 "
                              "(levels too narrow to share: the widest had 11 states, threads "
                              "share levels of 256 or more)"), out
    assert "states" in out and "Traceback" not in out
    out = CliRunner().invoke(main, args + ["2", "--engine", "native"],
                             env={"PCCL_THREADS": "0"}).output     # worker processes
    assert head(out).endswith("reductions merge+symmetry+por+dead, engine native"), out


def test_ray_declines_the_native_engine_with_the_reason():
    """``--ray`` keeps the Python engine (the actors would have to build the
    module again) and says so; ``--engine native`` with it is an error."""
    from pccl import api
    from pccl.model.options import ExploreOptions
    m = make_model(FISCHER, overrides={"k": "0"})
    assert api._choose_engine(m, ExploreOptions(ray="local"), True, False) is None
    assert m.engine_used == "python" and m.engine_reason.startswith("ray: the actors run the Python")
    with pytest.raises(ArgumentError, match="native engine cannot run this search: .*actors"):
        api._choose_engine(m, ExploreOptions(ray="local", engine="native"), True, False)
    assert isinstance(api._choose_engine(m, ExploreOptions(workers=2), True, False), NV.NativeModel)
    assert m.engine_used == "native"


def test_native_workers_stall_changes_in_a_batch_equal_state_by_state():
    """A native worker decides the stall check's per-state change for a chunk
    at once (:meth:`_Worker._changes`); the same as asking each state
    (``StateColumns.changed``) on the reachable states of a stalling program."""
    from pccl.search import liveness as L
    from pccl.search import parallel as P
    path = os.path.join(ROOT, "tests/programs/token_keep.pccl")
    m = make_model(path)
    nm = NV.NativeModel(m)
    cols = L.make_recorder(nm, True, True).columns
    assert cols.sig_of is not None
    states = [s for s in reachable(nm, 3000) if nm.successors(s)]
    w = P._Worker(nm, 0, 1, True, False, cols)
    ns, flat, _ = nm.successor_batch(states)
    w._changes(list(range(len(states))), states, ns, flat)
    want = [cols.changed(s, [t for _, t in nm.successors(s)]) for s in states]
    assert np.concatenate(w.g_chg).tolist() == want
    assert np.concatenate(w.g_chg_idx).tolist() == list(range(len(states)))
    assert any(want) and not all(want)


@pytest.mark.parametrize("chunked", [False, True])
@pytest.mark.parametrize("handed", [False, True])
def test_native_workers_stall_changes_from_the_fingerprints_pass(monkeypatch, chunked, handed):
    """With the stall check a native worker hashes each candidate's
    signature in the fingerprints' pass (:attr:`_Worker.sig_batch`) and
    decides its parents' changes from them when the level is finished: the
    same changes as asking each state, with the level fingerprinted whole or
    a chunk at a time, and with parents handed over by another worker (the
    candidates then put back in key order); the admitted states' signature
    column is their own signature."""
    from pccl.search import liveness as L
    from pccl.search import parallel_worker as P
    if chunked:
        monkeypatch.setattr(P, "_FP_LEVEL_BYTES", 0)
        monkeypatch.setattr(P, "_FP_CHUNK", 64)
    m = make_model(os.path.join(ROOT, "tests/programs/token_keep.pccl"))
    nm = NV.NativeModel(m)
    cols = L.make_recorder(nm, True, True).columns
    states = [s for s in reachable(nm, 3000) if nm.successors(s)]
    want = [cols.changed(s, [t for _, t in nm.successors(s)]) for s in states]
    w = P._Worker(nm, 0, 1, True, False, cols)
    assert w.sig_batch is not None
    half = len(states) // 2 if handed else 0
    w.level, w.level_idx = states[half:], list(range(half, len(states)))
    w.begin(False)
    if handed:          # expanded after my own: out of key order
        w.take(list(range(half)), states[:half])
    w.expand_some(None)
    w.finish()
    got = dict(zip(np.concatenate(w.g_chg_idx).tolist(), np.concatenate(w.g_chg).tolist()))
    assert got == dict(enumerate(want))
    assert any(want) and not all(want)
    assert w.cand_sigs.tolist() == cols.signatures(w.cand).tolist()


# -- packed states: int32 slots where they fit --------------------------------------

#: a shared int that passes 2**31 - 1 half-way, and a local left undefined
#: (INT64_MIN) until the first event: states of both forms in one search
BIG = """Agent::Big

allwrite:
  int big = 2147483000;

loc:
  int x;
  int steps = 0;

Init:

Grow():
  pre(steps < 12);
  eff:
    atomic:
      big = big + 97;
    steps = steps + 1;
    x = big - 2147483000;
"""


def test_pack_and_unpack_keep_every_value(monkeypatch):
    """pack's two forms: int32 where every slot fits (undefined, INT64_MIN,
    as INT32_MIN), else int64 (INT32_MIN itself, 2**31 and beyond); unpack
    gives the vector back, and the C calls read both forms as one state."""
    from array import array
    monkeypatch.setattr(NE, "_SMALL_OBJECT", 0)         # pack every model's states
    nm = NV.NativeModel(make_model(BIG, source=True, agents=2, reduce="none"))
    assert nm.gen.packs
    s0 = next(iter(nm.init_states()))
    v = nm.unpack(s0)
    assert len(s0) == 4 * len(v) and -(1 << 63) in v       # undefined x, packed
    for edge, size in ((-(1 << 63), 4), ((1 << 31) - 1, 4), (-(1 << 31) + 1, 4),
                       (-(1 << 31), 8), (1 << 31, 8), (-(1 << 40), 8)):
        w = array("q", v)
        w[len(w) - 1] = edge
        b = nm.pack(w)
        assert len(b) == size * len(w) and nm.unpack(b) == w, edge
        assert nm.key(b) == nm.key(w.tobytes())             # C: either form, one state
    # below the small-object limit nothing is packed
    monkeypatch.undo()
    plain = NV.NativeModel(make_model(BIG, source=True, agents=2, reduce="none"))
    assert not plain.gen.packs and len(next(iter(plain.init_states()))) == 8 * plain.gen.NS


@pytest.mark.parametrize("program, kw", [
    (BIG, dict(source=True, agents=2, **UNREDUCED)),
    (BIG, dict(source=True, agents=2, invariants=("big <= 2147483900",), **UNREDUCED)),
    (BIG, dict(source=True, agents=2, reduce="auto", timelock=False, stall=False)),
    (os.path.join(ROOT, "programs/fischer.pccl"), dict(overrides={"k": "1", "d": "1"}, **UNREDUCED)),
    (os.path.join(ROOT, "programs/fischer.pccl"),
     dict(overrides={"k": "2", "d": "1"}, invariants=("count(inCs) <= 1",), **UNREDUCED)),
    (os.path.join(ROOT, "programs/race_robust.pccl"),
     dict(world=os.path.join(ROOT, "programs/race.toml"), agents=3)),
    (os.path.join(ROOT, "programs/race_safe.pccl"),
     dict(world=os.path.join(ROOT, "programs/race.toml"), agents=2, reduce="none")),
])
def test_packed_states_give_equal_results(program, kw, monkeypatch):
    """With every model's states packed (as for teams whose int64 vectors
    pass the small-object limit): results, verdicts and counterexamples
    equal the Python engine's and the unpacked native search's; BIG meets
    both forms."""
    py, plain = both(program, **kw)
    monkeypatch.setattr(NE, "_SMALL_OBJECT", 0)
    packed = summary(explore(program, engine="native", **kw))
    assert packed == plain == py
    if program is BIG:
        nm = NV.NativeModel(make_model(BIG, source=True, agents=2, reduce="none"))
        sizes = {len(s) for s in reachable(nm, 20_000)}
        assert sizes == {4 * nm.gen.NS, 8 * nm.gen.NS}


def test_workers_over_packed_states_give_the_one_process_results(monkeypatch):
    """Fischer with 5 agents has 85 slots, so its states are packed: two
    native workers (states pickled between processes in either form) give
    one process's figures; two threads too."""
    kw = dict(agents=5, overrides={"k": "0", "d": "1"}, max_states=30_000,
              invariants=("count(inCs) <= 1",), engine="native")
    one = explore(os.path.join(ROOT, "programs/fischer.pccl"), **kw)
    threads = explore(os.path.join(ROOT, "programs/fischer.pccl"), workers=2, **kw)
    monkeypatch.setenv("PCCL_THREADS", "0")
    two = explore(os.path.join(ROOT, "programs/fischer.pccl"), workers=2, **kw)
    m = make_model(os.path.join(ROOT, "programs/fischer.pccl"), agents=5, overrides={"k": "0", "d": "1"})
    assert NV.NativeModel(m).gen.packs
    assert two.model.engine_used == "native" and two.model.engine_threads == 1
    assert threads.model.engine_threads == 2
    assert summary(two) == summary(one) == summary(threads)


# -- --workers N of a program that moves: stable interned ids ---------------------

RACE = os.path.join(ROOT, "programs/race.toml")
MOVING_WORKER_CASES = {
    # a robot stuck on remove(): a stall, with its counterexample
    "race-nonatomic-stuck": (os.path.join(ROOT, "programs/race_nonatomic.pccl"),
                             dict(world=RACE, agents=3)),
    # exhaustive, three robots (symmetry over positions), no recorder
    "race-robust": (os.path.join(ROOT, "programs/race_robust.pccl"),
                    dict(world=RACE, agents=3, timelock=False, stall=False)),
    # an invariant that fails once a robot has found no destination left
    "race-robust-violation": (os.path.join(ROOT, "programs/race_robust.pccl"),
                              dict(world=RACE, agents=3, invariants=("count(finished) == 0",))),
}


@pytest.mark.parametrize("name", sorted(MOVING_WORKER_CASES))
def test_native_workers_of_a_program_that_moves(name, monkeypatch):
    """A program that moves runs native with ``--workers`` (it ran the
    Python engine: its interned ids were numbered per process): ids are a
    hash of the value's encoding there, the same in every process, and the
    figures, verdict, violations and counterexamples equal one native
    process's (small ids) and the Python engine's.  (Worker processes,
    ``PCCL_THREADS=0``: threads share one process's ids,
    tests/search/test_level_kernel.py.)"""
    monkeypatch.setenv("PCCL_THREADS", "0")
    program, kw = MOVING_WORKER_CASES[name]
    py = explore(program, engine="python", **kw)
    one = explore(program, engine="auto", **kw)
    assert one.model.engine_used == "native", one.model.engine_reason
    assert summary(one) == summary(py)
    for w in (2, 3):
        many = explore(program, engine="auto", workers=w, **kw)
        assert many.model.engine_used == "native", (w, many.model.engine_reason)
        assert summary(many) == summary(one), f"workers={w}"


def test_stable_ids_are_a_hash_and_travel_between_processes():
    """Stable ids name a value alike in two models built apart (as in two
    processes): a state made in one reads back in the other once it has
    learnt the first's ids; small ids follow discovery order instead.
    (One model at a time searches: the models of one program share its C
    module, whose callbacks are the last model's.)"""
    m = make_model(os.path.join(ROOT, "programs/race_robust.pccl"), world=RACE, agents=2)
    a = NV.NativeModel(m, stable_ids=True)
    far = next(iter(a.init_states()))
    for _ in range(8):          # a few steps in: targets, lists, positions interned by a
        nxt = [s for _, s in a.successors(far)]
        far = nxt[-1] if nxt else far
    table = a.id_table()
    assert len(table) >= 3 and all(0 <= i < 1 << 62 for i in table)
    c = NV.NativeModel(m, stable_ids=True)
    with pytest.raises(KeyError):           # ids it has not seen
        c.decode(far)
    c.learn_ids(table)
    assert c.decode(far) == a.decode(far) and c.key(far) == a.key(far)
    for x in table.values():                # the same id for the same value, anywhere
        assert c.intern(x) == a.intern(x)
    small = NV.NativeModel(m)
    assert small.id_table() is None
    assert [small.intern(x) for x in table.values()] == list(range(len(table)))


def test_stable_ids_that_clash_fall_back_to_the_python_workers(monkeypatch):
    """Stable ids are 31 bits of a hash: an id that names two values (in one
    process, or in two, found by the coordinator's check of what each step
    interned) stops the native search, and the workers run the Python
    engine, saying so; with two bits of hash every search clashes."""
    program, kw = MOVING_WORKER_CASES["race-robust"]
    py = explore(program, engine="python", **kw)
    monkeypatch.setenv("PCCL_THREADS", "0")        # worker processes (threads: no stable ids)
    monkeypatch.setattr(NV, "_STABLE_MASK", 3)
    r = explore(program, engine="auto", workers=2, **kw)
    assert r.model.engine_used == "python" and "31-bit id" in r.model.engine_reason
    assert summary(r) == summary(py)
    reg: dict = {}
    NV.check_ids(reg, [(5, b"a" * 16), (6, b"b" * 16)])
    NV.check_ids(reg, [(5, b"a" * 16)])         # the same value again: fine
    with pytest.raises(NV.NativeOverflow, match="31-bit id"):
        NV.check_ids(reg, [(6, b"c" * 16)])


@pytest.mark.parametrize("workers", [2, 3])
def test_native_workers_rebalance_and_fingerprint_in_chunks(workers, monkeypatch):
    """A search from one initial state: the levels are rebalanced (states
    move from the worker that holds them all), and every level is
    fingerprinted a chunk at a time (thresholds lowered; the forked workers
    inherit them), with terminal states, the depth bound and an invariant
    met on the way: the figures and the counterexample stay one native
    process's.  Without rebalancing nothing moves."""
    from pccl.search import parallel as P
    from pccl.search import parallel_worker as PW
    from pccl.search.explorer import Explorer
    monkeypatch.setattr(PW, "_FP_LEVEL_BYTES", 0)
    monkeypatch.setattr(PW, "_FP_CHUNK", 7)
    monkeypatch.setattr(P, "_REBALANCE_LEVEL", 16)
    calls = []
    real = P._Worker._fp_more

    def counted(self):
        calls.append(1)
        return real(self)
    monkeypatch.setattr(P._Worker, "_fp_more", counted)
    program = os.path.join(ROOT, "programs/race_robust.pccl")
    for kw, bound in ((dict(invariants=("count(finished) == 0",)), {}),
                      (dict(), dict(max_depth=30)), (dict(), {})):
        m = make_model(program, world=RACE, agents=3, **kw)
        m.lock_deadlocks = True
        one = Explorer(NV.NativeModel(m), **bound).run()
        e = P.ParallelExplorer(NV.NativeModel(m, stable_ids=True), workers=workers, **bound)
        many = e.run()
        assert e.moved > 0, e.moved
        sig = [(r.status, r.stats.states, r.stats.transitions, r.stats.max_depth,
                sorted(b.value for b in r.bounds_hit),
                [(f.violation.kind, f.index, f.depth, f.trace and tuple(f.trace.labels))
                 for f in r.found]) for r in (one, many)]
        assert sig[0] == sig[1]
    assert calls            # worker 0's chunks, in this process
    monkeypatch.setattr(P, "_REBALANCE_LEVEL", 1 << 60)
    e = P.ParallelExplorer(NV.NativeModel(m, stable_ids=True), workers=workers)
    assert e.run().stats.states == one.stats.states and e.moved == 0
