"""The native engine (pccl/model/native.py) against the Python engine: for every
program it serves, equal states, transitions, depth, time, verdicts,
violations and counterexample traces (labels and configurations), on the
shipped and test programs and on generated ones (tests/symattack.py's
seeded generator); programs and searches it does not serve fall back to
Python and say why.  Skipped where there is no C compiler or no Python.h."""

import glob
import os

import pytest

from pccl.model import native as NV
from pccl.api import explore, make_model
from pccl.model.layout import AGS, PC
from pccl.lang.errors import ArgumentError

from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as hs

from test_fingerprints import programs

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_probe = make_model(os.path.join(ROOT, "programs/fischer.pccl"), reduce="none")
MISSING = NV.unsupported(_probe)
pytestmark = pytest.mark.skipif(MISSING is not None, reason=f"native engine unavailable: {MISSING}")

UNREDUCED = dict(reduce="none", timelock=False, stall=False)


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("PCCL_CACHE", str(tmp_path_factory.getbasetemp() / "native-cache"))


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


def served(paths):
    out = []
    for p in paths:
        try:
            m = make_model(p, reduce="none")
        except Exception:
            continue
        if NV.unsupported(m) is None:
            out.append(os.path.relpath(p, ROOT))
    return out


PROGRAMS = served(sorted(glob.glob(os.path.join(ROOT, "programs", "*.pccl"))
                         + glob.glob(os.path.join(ROOT, "tests", "programs", "*.pccl"))))


def test_the_shipped_and_test_programs_served():
    assert {"programs/fischer.pccl", "programs/leader.pccl", "tests/programs/ref_atomic.pccl",
            "tests/programs/ref_mutex_bad.pccl", "tests/programs/eng_assert.pccl"} <= set(PROGRAMS)


@pytest.mark.parametrize("program", PROGRAMS)
def test_equal_results_on_served_programs(program):
    py, nat = both(os.path.join(ROOT, program), max_states=60_000, find_all=True, **UNREDUCED)
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
    """tests/test_fingerprints.py's generator, the programs the engine serves
    (int and bool variables; no floats, lists or rand in statements)."""
    text, invariants = prog
    kw = dict(source=True, agents=agents, blackbox=blackbox, invariants=invariants)
    assume(NV.unsupported(make_model(text, reduce="none", **kw)) is None)
    py, nat = both(text, find_all=True, max_states=2_000, **kw, **UNREDUCED)
    assert nat == py


def test_auto_falls_back_with_the_reason():
    r = explore(os.path.join(ROOT, "programs/fischer.pccl"), overrides={"k": "1"})
    assert r.model.engine_used == "python"
    assert "reduction" in r.model.engine_reason
    r = explore(os.path.join(ROOT, "programs/race.pccl"), reduce="none", timelock=False,
                stall=False, max_states=100)
    assert r.model.engine_used == "python" and "List<ItemPosition>" in r.model.engine_reason
    r = explore(os.path.join(ROOT, "programs/fischer.pccl"), overrides={"k": "1", "d": "1"},
                **UNREDUCED)
    assert r.model.engine_used == "native" and r.model.engine_reason is None


def test_native_asked_for_an_unsupported_search_is_an_error():
    with pytest.raises(ArgumentError, match="native engine cannot run this search: .*time-lock"):
        explore(os.path.join(ROOT, "programs/fischer.pccl"), reduce="none", engine="native")


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
    args = ["explore", os.path.join(ROOT, "programs/fischer.pccl"), "--set", "k=0", "--set",
            "d=0", "--no-progress", "--reduce", "none", "--no-timelock", "--no-stall"]
    out = CliRunner().invoke(main, args).output
    assert head(out).endswith("reductions none, engine native")
    out = CliRunner().invoke(main, args[:-2] + ["--engine", "python"]).output
    assert head(out).endswith("reductions none, engine python")
    out = CliRunner().invoke(main, args[:-2]).output     # auto, time-lock check on
    assert head(out).endswith("reductions none")
