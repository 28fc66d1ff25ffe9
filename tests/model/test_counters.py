"""Counter saturation (pccl/model/counters.py, docs/reductions.md "Counter
saturation"): which counters the condition accepts and refuses, that the
clamp is what both engines identify states by, that verdicts equal the
unreduced search's, and that counterexamples are runs of the unreduced
program."""

from __future__ import annotations

import os
import textwrap

import pytest

from pccl.api import explore, make_model
from pccl.lang.errors import PcclError
from pccl.model import counters as C
from pccl.model.engine import Model
from pccl.model.layout import AGS, LOC

from conftest import ROOT, cli

FISCHER = os.path.join(ROOT, "programs/fischer.pccl")


def src(text: str) -> str:
    return textwrap.dedent(text).lstrip("\n")


# t ticks for ever (the unreduced state space is infinite); it is compared
# with 3 and with the shared constant K; hits counts the agents past K
TICK = src("""
    allwrite:
      int K = 4;
      int hits = 0;

    loc:
      int t = 0;
      bool seen = false;

    Tick():
      pre(true);
      eff:
        t = t + 1;
        if (t >= K && !seen):
          seen = true;
          atomic:
            hits = hits + 1;
        if (t == 3):
          skip;
    """)

# bounded by c: the unreduced search is finite; t and v exceed their caps
# by different paths (Step and Jump add different amounts)
BOUNDED = src("""
    allwrite:
      int s = 0;

    loc:
      int c = 0;
      int t = 0;
      int v = rand(1);

    Step():
      pre(c < 3);
      eff:
        c = c + 1;
        t = t + 2;
        if (t > 1 && v <= 2):
          atomic:
            s = s + 1;

    Jump():
      pre(c < 3 && t != 1);
      eff:
        c = c + 1;
        t = t + 3;
        v = v + 1;
        if (t == 4):
          t = 0;

    Done():
      pre(c >= 3);
      eff:
        exit();
    """)


def problem(text: str, name: str, **kw):
    return C.counter_problem(make_model(text, source=True, reduce="none", **kw), name)


def test_counters_compared_with_bounded_constants_are_saturable():
    assert problem(TICK, "t") == (None, 5)                 # t >= K (K = 4), t == 3
    m = make_model(BOUNDED, source=True, reduce="none")
    assert C.counter_problem(m, "t") == (None, 5)          # t == 4
    assert C.counter_problem(m, "v") == (None, 3)          # v <= 2
    assert C.counter_problem(m, "c") == (None, 4)          # c < 3, c >= 3
    # a constant given by --set moves the cap
    assert problem(TICK, "t", overrides={"K": "9"}) == (None, 10)


#: TICK's last statement, which the tests below replace
LAST = "    if (t == 3):\n      skip;\n"


@pytest.mark.parametrize("change,why", [
    (True, "read other than compared"),
    (False, "a property reads t"),
])
def test_refused_counters_say_why(change, why):
    if change:      # t read in arithmetic
        assert LAST in TICK
        got = problem(TICK.replace(LAST, "    hits = t % 2;\n"), "t")
    else:
        got = problem(TICK, "t", invariants=("forall i: t[i] < 9",))
    assert got[0] is not None and why in got[0] and got[1] is None


@pytest.mark.parametrize("line,why", [
    ("t = t - 1;", "assigned a value that reads it"),
    ("t = t + K;", "assigned a value that reads it"),     # an increment by a literal only
    ("K = 5;", "read other than compared"),               # K is written: not a constant
])
def test_refused_writes(line, why):
    text = TICK.replace(LAST, f"    {line}\n")
    got = problem(text, "t")
    assert got[0] is not None and why in got[0], got


def test_counters_that_cannot_exceed_their_cap_leave_auto_unchanged():
    """Fischer's c1 < waitTime, c2 < d and c3 < 3 each guard their own
    increment: no key would change, so auto does not list the reduction."""
    m = make_model(FISCHER, invariants=("count(inCs) <= 1",))
    caps = C.saturable_counters(m.model)
    assert len(caps) >= 3
    assert not C.can_saturate(m.model)
    assert "counters" not in m.reduction.on and "counters" not in m.reduction.off
    assert C.can_saturate(make_model(TICK, source=True, reduce="none"))


def test_the_clamp_identifies_states_beyond_the_cap():
    m = make_model(TICK, source=True, agents=2, reduce="counters")
    assert "counters" in m.reduction.on
    st = next(iter(m.init_states()))
    slot = m.compiled.layout.vars["t"].slot

    def with_t(st, vals):
        ags = tuple(ag[:LOC] + (ag[LOC][:slot] + (v,) + ag[LOC][slot + 1:],) + ag[LOC + 1:]
                    for ag, v in zip(st[AGS], vals))
        return st[:AGS] + (ags,) + st[AGS + 1:]
    assert m.key(with_t(st, (5, 0))) == m.key(with_t(st, (700, 0)))
    assert m.key(with_t(st, (4, 0))) != m.key(with_t(st, (5, 0)))
    assert m.key(with_t(st, (6, 9))) == m.key(with_t(st, (5, 5)))


def check_counterexamples(res) -> int:
    """Every counterexample is a path of the unreduced model from an initial
    state; returns how many were checked."""
    m = res.model
    inits = set(m.model.init_states())
    n = 0
    for cx in res.counterexamples:
        tr = cx.trace
        if tr is None:
            continue
        assert tr.states[0] in inits
        for step in tr.steps:
            assert (step.label, step.after) in Model.successors(m.model, step.before)
        n += 1
    return n


def verdict(res) -> tuple:
    return res.status, {(v["kind"], v["name"], v["line"]) for v in res.violations}


@pytest.mark.parametrize("engine", ["python", "native"])
@pytest.mark.parametrize("agents", [1, 2])
def test_verdicts_equal_the_unreduced_search(engine, agents):
    for inv in ("s < 3", "s < 9"):
        kw = dict(source=True, agents=agents, invariants=(inv,), find_all=True, engine=engine)
        none = explore(BOUNDED, reduce="none", **kw)
        for red in ("counters", "auto"):
            got = explore(BOUNDED, reduce=red, **kw)
            assert "counters" in got.model.reduction.on
            assert verdict(got) == verdict(none), (red, inv)
            assert got.stats.states < none.stats.states
            check_counterexamples(got)


def test_an_infinite_space_becomes_finite_and_its_violation_is_a_real_run():
    """Unreduced, TICK never ends (t grows); saturated it is exhaustive and
    finds that both agents pass K, by a run of the unreduced program."""
    none = explore(TICK, source=True, agents=2, reduce="none", invariants=("hits < 2",), max_states=3000)
    assert none.status == "violation" or not none.complete
    got = explore(TICK, source=True, agents=2, invariants=("hits < 2",), find_all=True)
    assert "counters" in got.model.reduction.on and got.complete
    assert ("invariant", "hits < 2") in {(v["kind"], v["name"]) for v in got.violations}
    assert check_counterexamples(got) >= 1
    # the same with the constant raised: the cap follows it, the search still ends
    far = explore(TICK, source=True, agents=2, invariants=("hits < 2",), find_all=True, overrides={"K": "60"})
    assert far.complete and far.stats.states < 10 * got.stats.states


def test_python_and_native_search_the_same_graph():
    for text, n, kw in ((TICK, 3, dict(invariants=("hits < 3",))), (BOUNDED, 2, dict(invariants=("s < 9",)))):
        py = explore(text, source=True, agents=n, engine="python", find_all=True, **kw)
        nat = explore(text, source=True, agents=n, engine="native", find_all=True, **kw)
        assert nat.model.engine_used == "native"
        assert "counters" in py.model.reduction.on
        assert (py.stats.initial_states, py.stats.states, py.stats.transitions, py.stats.max_depth) == \
            (nat.stats.initial_states, nat.stats.states, nat.stats.transitions, nat.stats.max_depth)
        assert verdict(py) == verdict(nat)


def test_temporal_properties_turn_it_off():
    m = make_model(TICK, source=True, agents=2, properties=("eventually hits > 0",))
    assert "counters" not in m.reduction.on
    assert "temporal property" in m.reduction.off["counters"]
    with pytest.raises(PcclError, match="counters reduction is unsound here"):
        make_model(TICK, source=True, agents=2, properties=("eventually hits > 0",), reduce="counters")


def test_the_cli_lists_it(tmp_path):
    p = tmp_path / "tick.pccl"
    p.write_text(TICK)
    r = cli("explore", str(p), "--agents", "2", "--invariant", "hits < 2")
    assert r.exit_code == 1
    assert "reductions merge+symmetry+por+dead+counters" in r.output.splitlines()[0]
    r = cli("explore", str(p), "--reduce", "counters", "--property", "eventually hits > 0")
    assert r.exit_code == 2 and "counters reduction is unsound here" in r.output
