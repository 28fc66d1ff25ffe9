"""The split of the engine (docs/architecture.md): a CompiledProgram holds
what compiling produced, the Model the transition system the explorer sees;
the rules read the model only as a RuleContext, whose compiled members are
the compiled program's own."""

from __future__ import annotations

import pytest

from pccl.model.compiled import CompiledProgram
from pccl.model.engine import Model
from pccl.lang.errors import OptionError
from pccl.search.explorer import Explorer
from pccl.model.layout import AGS, EXITED, RUNNING, SH, STATUS
from pccl.model.options import check_model_values
from pccl.semantics import rules as R
from pccl.lang.types import indexes_agent

from conftest import FISCHER, model_of, set_agent
from pccl.api import make_model

#: what compiling the program produces: it lives in model.compiled only
COMPILE_TIME = {"comp", "info", "layout", "stmts", "stmt_event", "code", "guards",
                "functions", "stuck_reasons", "_decl_fns"}
#: what the explorer calls: the Model's, never the compiled program's
SEARCH = {"init_states", "successors", "key", "violations", "terminal_kind",
          "deadlock_violation", "next_time", "environment_step", "properties", "temporal",
          "world", "blackbox", "delta", "max_time"}

GUARDS = """
    Agent::Guards

    allwrite:
      int turn = 0;

    allread:
      int x = 0;
      int a[2] = 0;

    loc:
      int c = 0;

    Init:

    Bump():
      pre(c < 2 && x[getAgentIndex()] == c);
      eff:
        x = x + 1;
        c = c + 1;

    Take():
      pre(turn == getAgentIndex() && a[1] == 0);
      eff:
        a[1] = 1;
        turn = 1 - turn;

    Peek():
      pre(a[0][1] == 0 && c == 2);
      eff:
        exit();
"""


def test_the_model_holds_no_compile_time_attributes():
    m = make_model(FISCHER, agents=2, reduce="none")
    assert not (COMPILE_TIME & set(vars(m))), COMPILE_TIME & set(vars(m))
    for name in ("describe_k", "span_of", "stmt_span", "stuck_code", "_compile_stmt",
                 "_compile_enabled_events", "enabled_events"):
        assert not hasattr(Model, name), name          # methods of CompiledProgram now
    assert COMPILE_TIME - {"_decl_fns"} <= set(vars(m.compiled))


def test_the_compiled_program_has_no_search_methods():
    m = make_model(FISCHER, agents=2, reduce="none")
    for name in SEARCH:
        assert not hasattr(CompiledProgram, name), name
        assert not hasattr(m.compiled, name), name
        assert hasattr(m, name), name


def test_the_rule_context_binds_the_compiled_programs_members():
    """A rule reads ``m.ctl``, ``m.oracle``, … with one lookup: the very
    objects of the compiled program, not copies."""
    m = make_model(FISCHER, agents=2, reduce="none")
    c = m.compiled
    assert m.ctl is c.ctl and m.oracle is c.oracle and m.guards_rand is c.guards_rand
    assert m.enabled_events is c.enabled_events
    assert m.stuck_code.__self__ is c
    code = m.stuck_code("error", "a reason", None)
    assert c.stuck_reasons[code] == ("error", "a reason", None)


@pytest.mark.parametrize("events", ["any", "first"])
def test_compiled_enabled_events_agree_with_one_guard_at_a_time(events):
    """The generated enabled-events function and the guard-by-guard one give
    the same events for every agent of every reachable state."""
    m = model_of(GUARDS, agents=2, events=events)
    states = []
    res = Explorer(m, max_states=400, recorder=_Collect(states)).run()
    assert res.stats.states == len(states) > 10
    fired, several = set(), 0
    for st in states:
        for i, ag in enumerate(st[AGS]):
            if ag[STATUS] != RUNNING:
                continue
            got = m.compiled.enabled_events(i, ag, st[SH], st[AGS])
            assert got == m.compiled.enabled_events_slow(i, ag, st[SH], st[AGS]), (st, i)
            fired.update(got)
            several += len(got) > 1
    assert fired == {0, 1, 2}
    assert (several > 0) == (events == "any")      # "first" keeps one event only


class _Collect:
    def __init__(self, out):
        self.out = out

    def states(self, sts):
        self.out.extend(sts)

    def edges(self, src, dst):
        pass


def test_the_configuration_kernel_is_public():
    """The engine reaches the rules' kernel through public names only."""
    import re
    from pathlib import Path
    src = Path(__file__).resolve().parents[2] / "pccl"
    for f in sorted(src.rglob("*.py")):
        assert not re.search(r"\bR\._", f.read_text()), f.name
    err = R.Err.of(ZeroDivisionError("x"))
    assert err.reason == "division by zero" == R.describe_error(ZeroDivisionError())
    assert ZeroDivisionError in R.RUNTIME_ERRORS


def test_a_runtime_error_gets_the_agent_stuck_through_the_public_kernel():
    m = model_of("""
        Agent::Div

        loc:
          int z = 0;

        Init:

        E():
          pre(true);
          eff:
            z = 1 / z;
    """, agents=1)
    st = next(m.init_states())
    ag = st[AGS][0]
    bad = R.stuck_successor(m, st, 0, ag, "division by zero", None)
    assert bad[AGS][0][STATUS] >= 2 and bad[AGS][0][STATUS] != EXITED
    assert m.compiled.stuck_reasons[bad[AGS][0][STATUS]] == ("error", "division by zero", None)


# -- the per-agent indexing rule: one home (types.indexes_agent) ------------------------

@pytest.mark.parametrize("section, is_array, n, prop, picks", [
    ("allwrite", False, 1, False, False), ("allwrite", True, 2, True, False),
    ("allread", False, 1, False, True),      # x[j]: agent j's x
    ("allread", True, 1, False, False),      # a[k]: this agent's element k
    ("allread", True, 2, False, True),       # a[j][k]: agent j's element k
    ("loc", False, 1, False, False),         # a local is this agent's only
    ("loc", False, 1, True, True),           # in a property: v[i]
    ("loc", True, 1, True, True), ("allread", True, 1, True, True),
])
def test_indexes_agent(section, is_array, n, prop, picks):
    assert indexes_agent(section, is_array, n, in_property=prop) is picks


def test_checker_and_compiler_read_the_same_indexing_rule():
    """``a[1]`` is this agent's element 1 and ``a[0][1]`` agent 0's: the
    checker accepts both as ints and the compiled guards read them so."""
    m = model_of(GUARDS, agents=2)
    st = next(m.init_states())

    def enabled(s, i):
        return m.compiled.enabled_events(i, s[AGS][i], s[SH], s[AGS])
    # Take reads a[1], the asking agent's own element 1
    st1 = set_agent(m, st, 1, a=(0, 1))
    assert 1 in enabled(st1, 0) and 1 not in enabled(st1, 1)
    # Peek reads a[0][1], agent 0's element 1, whoever asks
    st2 = set_agent(m, set_agent(m, st, 1, c=2), 0, c=2)
    assert 2 in enabled(st2, 0) and 2 in enabled(st2, 1)
    st3 = set_agent(m, st2, 0, a=(0, 1))
    assert 2 not in enabled(st3, 0) and 2 not in enabled(st3, 1)
    st4 = set_agent(m, st2, 1, a=(0, 1))
    assert 2 in enabled(st4, 0) and 2 in enabled(st4, 1)


# -- option checks: one function, the model's messages --------------------------------

def test_check_model_values_gives_the_rate_map_the_model_uses():
    assert check_model_values(3, delta=1, max_time=None, n0=2, rates={1: 2}, events="any") \
        == [1, 2, 1] == make_model(FISCHER, agents=3, n0=2, rates={1: 2}, reduce="none").rho


@pytest.mark.parametrize("kw, option, text", [
    (dict(n0=0), "n0", "n0 must be a positive integer, got 0"),
    (dict(rates={5: 1}), "rates", "agent 5 does not exist (agents are 0..1)"),
    (dict(delta=0), "delta", "δ must be a positive finite number, got 0"),
    (dict(events="all"), "events", "must be 'any' or 'first', got 'all'"),
])
def test_check_model_values_names_the_option(kw, option, text):
    args = dict(delta=1, max_time=None, n0=1, rates={}, events="any")
    args.update(kw)
    with pytest.raises(OptionError) as e:
        check_model_values(2, **args)
    assert e.value.option == option and e.value.message == text
