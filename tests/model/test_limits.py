"""Hardening, second part: Init limits, lazy initial states, locks held by
exited agents, exact time, size limits, signals, nesting (the items of the
hardening issue not covered by test_hardening.py)."""

from __future__ import annotations

import re
import json

import pytest

from pccl.lang.errors import PcclError

from conftest import FISCHER, interrupted, model_of
from pccl.model.layout import AGS, LOC
from conftest import cli




def write(tmp_path, text, name="p.pccl"):
    p = tmp_path / name
    p.write_text(text)
    return p


# ---------------------------------------------------------------------------
# 1. the Init step limit is per path, and equal branches merge
# ---------------------------------------------------------------------------

RAND_LOOP_INIT = """\
loc:
  int c = 0;
  int x = 0;

Init:
  while (c < 17):
    x = rand(1);
    c = c + 1;

Go():
  pre(true);
  eff:
    exit();
"""


def test_init_rand_loop_is_not_stuck():
    m = model_of(RAND_LOOP_INIT)
    inits = list(m.init_states())
    assert not any(m.violations(s) for s in inits)
    assert len(inits) == 4          # x in {0, 1} per agent, c = 17
    from pccl.api import explore_model
    r = explore_model(m)
    assert r.status == "exhaustive", r.verdict


def test_init_that_loops_forever_is_stuck_quickly():
    m = model_of("loc:\n  int c = 0;\n\nInit:\n  while (true):\n    c = 1;\n")
    (st,) = m.init_states()
    (v, *_) = m.violations(st)
    assert v.kind == "stuck" and "Init does not finish" in v.message


# ---------------------------------------------------------------------------
# 10. initial states are generated lazily: --max-states bounds memory
# ---------------------------------------------------------------------------

HUGE_RAND = "loc:\n  int x = rand(100000000);\n\nGo():\n  pre(true);\n  eff:\n    exit();\n"


def test_initial_states_are_generated_lazily():
    import itertools
    import time
    m = model_of(HUGE_RAND)
    t = time.perf_counter()
    first = list(itertools.islice(m.init_states(), 5))
    assert time.perf_counter() - t < 5
    assert [s[AGS][1][LOC][0] for s in first] == [0, 1, 2, 3, 4]     # agent 0 has x = 0


def test_max_states_bounds_a_huge_rand_declaration(tmp_path):
    # (without dead: x is never read, so under auto its values are one state, below)
    res = cli("explore", write(tmp_path, HUGE_RAND), "--max-states", "10", "--reduce", "merge,por")
    assert res.exit_code == 0, res.output
    assert "stopped by --max-states 10" in res.stdout


def test_a_huge_rand_nobody_reads_is_one_initial_state(tmp_path):
    res = cli("explore", write(tmp_path, HUGE_RAND), "--max-states", "10")
    assert res.exit_code == 0, res.output
    assert "no violation — exhaustive" in res.stdout and "reductions merge+symmetry+por+dead" in res.stdout
    assert re.search(r"initial states +1 ", res.stdout), res.stdout


def test_fischer_with_50_agents_is_bounded_by_max_states():
    """In a fresh process: the peak memory of a test process is the peak of
    every test it ran before."""
    import subprocess
    import sys
    code = ("from pccl.api import explore; "
            f"r = explore({str(FISCHER)!r}, agents=50, max_states=2000); "
            "print(r.status, r.stats.states, r.stats.peak_memory)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    status, states, peak = out.stdout.split()
    # bounded by the state budget: exactly 2,000 states admitted, or fewer when
    # the initial phase's candidate cap stopped it (explorer.initial_candidate_cap)
    assert status == "bounded" and 0 < int(states) <= 2000
    assert int(peak) < 2**30


# ---------------------------------------------------------------------------
# 3. waiting for a lock held by an exited agent is a deadlock
# ---------------------------------------------------------------------------

EXIT_IN_ATOMIC = """\
allwrite:
  int x = 0;

loc:
  bool done = false;

Go():
  pre(!done);
  eff:
    if (getAgentIndex() == 0):
      atomic:
        x = 1;
        exit();
    else:
      atomic:
        x = 2;
      done = true;
"""


def test_waiting_for_a_lock_held_by_an_exited_agent_is_a_deadlock(tmp_path):
    p = write(tmp_path, EXIT_IN_ATOMIC)
    res = cli("explore", p, "--format", "json")
    assert res.exit_code == 1, res.output
    data = json.loads(res.stdout)
    (v,) = data["violations"]
    assert v["kind"] == "deadlock" and v["line"] == 15
    assert "agent 1 waits forever for the lock" in v["message"]
    assert "agent 0 holds it and has exited" in v["message"]
    # --no-deadlock turns it off like the other deadlocks
    assert cli("explore", p, "--no-deadlock", "--no-stall").exit_code == 0


def test_run_stops_at_a_lock_held_by_an_exited_agent(tmp_path):
    res = cli("run", write(tmp_path, EXIT_IN_ATOMIC), "--seed", "1")
    assert res.exit_code == 1, res.output
    assert "waits forever for the lock" in res.stdout


def test_exit_in_atomic_without_waiters_is_no_violation():
    m = model_of(EXIT_IN_ATOMIC.replace("      atomic:\n        x = 2;\n", "      x = 2;\n"))
    from pccl.api import explore_model
    assert explore_model(m, stall=False).status == "exhaustive"   # the survivor idles for ever


# ---------------------------------------------------------------------------
# 5. the clock holds exact multiples of δ: no δ freezes it
# ---------------------------------------------------------------------------

TICK = "loc:\n  int c = 0;\n\nGo():\n  pre(true);\n  eff:\n    c = 1;\n"


def test_tiny_delta_advances_the_clock(tmp_path):
    p = write(tmp_path, TICK)
    res = cli("explore", p, "--delta", "1e-12", "--max-time", "5e-12",
              "--invariant", "time < 3e-12")
    assert res.exit_code == 1, res.output
    assert "invariant 'time < 3e-12' violated" in res.stdout
    res = cli("explore", p, "--delta", "1e-12", "--max-time", "5e-12",
              "--invariant", "time <= 5e-12")
    assert res.exit_code == 0 and "stopped by --max-time" in res.stdout, res.stdout


def test_tiny_delta_run_ends(tmp_path):
    import subprocess
    import sys
    p = write(tmp_path, TICK)
    out = subprocess.run([sys.executable, "-m", "pccl.cli", "run", str(p), "--delta", "1e-12",
                          "--max-time", "5e-12", "--format", "json"],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["final"]["time"] == 5e-12


def test_decimal_delta_is_exact():
    m = model_of(TICK, delta=0.1, max_time=0.3, abstract_time=False)
    t, seen = 0, []
    while t is not None:
        seen.append(t)
        t = m.next_time(t)
    assert seen == [0, 0.1, 0.2, 0.3]


@pytest.mark.parametrize("args", [["explore", "--max-time", "nan"], ["explore", "--delta", "inf"],
                                  ["run", "--max-time", "inf"], ["run", "--delta", "nan"]])
def test_non_finite_time_options(args, tmp_path):
    res = cli(args[0], write(tmp_path, TICK), *args[1:])
    assert res.exit_code == 2 and "Traceback" not in res.output


@pytest.mark.parametrize("kw", [{"delta": float("inf")}, {"delta": float("nan")},
                                {"max_time": float("nan")}, {"max_time": float("inf")}])
def test_model_refuses_non_finite_time(kw):
    from pccl.model.engine import Model
    from pccl.model.options import ModelOptions
    from pccl.lang.parser import parse_program
    with pytest.raises(PcclError):
        Model(parse_program(TICK), ModelOptions(**kw))


def test_clock_beyond_float_range_is_an_error(tmp_path):
    p = write(tmp_path, TICK)
    res = cli("run", p, "--delta", "1e308", "--max-time", "1.7e308")
    assert res.exit_code == 0 and "stopped at --max-time" in res.stdout, res.output
    res = cli("explore", p, "--delta", "1e308", "--no-abstract-time")
    assert res.exit_code == 2, res.output
    assert "--delta: error: the clock cannot advance from 1e+308" in res.stderr


# ---------------------------------------------------------------------------
# 15. a flat chain of operators is not nesting; deep nesting is located
# ---------------------------------------------------------------------------

def chain_program(expr, ty="int"):
    return (f"loc:\n  {ty} x = {expr};\n  {ty} y = {expr};\n\nGo():\n  pre({'x' if ty == 'bool' else 'true'});\n"
            f"  eff:\n    y = {expr};\n    exit();\n")


@pytest.mark.parametrize("expr, ty, value", [
    (" + ".join(["1"] * 3000), "int", 3000),
    (" - ".join(["1"] * 3000), "int", 2 - 3000),
    (" + ".join(["2 * 3 - 4 / 2 % 3"] * 2000), "int", 2000 * 4),
    (" && ".join(["true"] * 3000), "bool", True),
    ("false && 1 / 0 == 0 && " + " && ".join(["true"] * 20), "bool", False),
    (" + ".join(["0.1"] * 3000), "float", None),
])
def test_long_flat_chains_work(tmp_path, expr, ty, value):
    from pccl.api import make_model
    p = write(tmp_path, chain_program(expr, ty))
    m = make_model(str(p))
    (st,) = m.init_states()
    x = st[AGS][0][LOC][0]
    if value is None:                       # left to right, as Python would
        value = 0.1
        for _ in range(2999):
            value = value + 0.1
    assert x == value
    res = cli("explore", p, "--no-stall")       # the program idles once its chain is done
    assert res.exit_code == 0, res.output


def test_long_chain_in_an_invariant():
    res = cli("explore", FISCHER, "--set", "k=1", "--set", "cstime=0", "--max-states", "100",
              "--invariant", " + ".join(["0"] * 3000) + " == 0")
    assert res.exit_code == 0, res.output


def test_deep_nesting_is_located(tmp_path):
    p = write(tmp_path, "loc:\n  int x = " + "1 + (" * 150 + "1" + ")" * 150 + ";\n")
    res = cli("check", p)
    assert res.exit_code == 2
    assert res.stderr.startswith(f"{p}:2:506: error: expression nested too deeply"), res.stderr
    assert "^" in res.stderr


def test_deep_blocks_are_located(tmp_path):
    body = "".join("  " * (k + 2) + "if (true):\n" for k in range(150))
    src = "loc:\n  int x = 0;\n\nGo():\n  pre(true);\n  eff:\n" + body + "  " * 152 + "x = 1;\n"
    p = write(tmp_path, src)
    res = cli("check", p)
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith(f"{p}:107:205: error: blocks nested too deeply"), res.stderr


# ---------------------------------------------------------------------------
# 11. size limits: arrays, agents, long effects, growing integers
# ---------------------------------------------------------------------------

def test_huge_array_is_a_located_error(tmp_path):
    p = write(tmp_path, "loc:\n  int a[100000000] = 0;\n")
    res = cli("check", p)
    assert res.exit_code == 2
    assert res.stderr.startswith(f"{p}:2:9: error: array size must be at most 1,000,000"), \
        res.stderr


def test_world_with_too_many_agents_is_located(tmp_path):
    w = write(tmp_path, "agents = 100000000\n", "w.toml")
    res = cli("explore", FISCHER, "--world", w)
    assert res.exit_code == 2
    assert res.stderr.startswith(f"{w}:1:10: error: 'agents' must be at most 10,000"), res.stderr


def test_growing_integer_gets_the_agent_stuck(tmp_path):
    p = write(tmp_path, "loc:\n  int x = 2;\n\nGrow():\n  pre(true);\n  eff:\n    x = x * x;\n")
    res = cli("run", p, "--max-time", "20")
    assert res.exit_code == 1, res.stdout
    assert "stuck: integer overflow: the result has more than 4,300 digits" in res.stdout
    res = cli("explore", p, "--format", "json")
    assert res.exit_code == 1
    (v,) = json.loads(res.stdout)["violations"]
    assert v["kind"] == "stuck" and v["line"] == 7


def test_long_effect_costs_linear_memory():
    import tracemalloc
    from pccl.api import explore_model
    n = 4000
    src = ("loc:\n  int x = 0;\n\nGo():\n  pre(x == 0);\n  eff:\n" + "    x = x + 1;\n" * n
           + "    exit();\n")
    tracemalloc.start()
    try:
        m = model_of(src, agents=1)
        r = explore_model(m)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert r.status == "exhaustive" and r.stats.states == n + 3
    assert peak < 40 * 2**20, peak          # the k cells of every suffix were 64 MB


# ---------------------------------------------------------------------------
# 12. signals at any moment: run and initial-state generation too
# ---------------------------------------------------------------------------

def _signalled(args, sig):
    rc, out, err = interrupted(args, sig)
    assert "Traceback" not in out + err
    return rc, out, err


@pytest.mark.parametrize("sig, code", [("SIGTERM", 143), ("SIGINT", 130)])
def test_signals_stop_run_with_the_run_so_far(sig, code, tmp_path):
    rc, out, err = _signalled(["run", write(tmp_path, TICK), "--max-time", "100000000",
                               "--stall-steps", "0"], sig)
    assert rc == code, (out, err)
    assert "result: interrupted — interrupted after" in out and "final configuration:" in out


def test_signal_during_initial_states(tmp_path):
    rc, out, err = _signalled(["explore", write(tmp_path, HUGE_RAND), "--no-progress",
                               "--reduce", "merge,por"], "SIGTERM")
    assert rc == 143, (out, err)
    assert "interrupted" in out and "statistics:" in out


def test_rand_with_too_many_outcomes_in_a_statement_is_a_limit_of_the_tool(tmp_path):
    """rand(10**8) in an effect would build 10^8 successors of one state
    before any bound is checked: it stops the search as a limit of the tool
    (a ToolLimitError with the line), not as a stuck agent (a violation of
    the program) -- docs/decisions.md."""
    from pccl.api import explore
    from pccl.lang.errors import ToolLimitError
    p = tmp_path / "big.pccl"
    p.write_text("loc:\n  int x = 0;\n\nGo():\n  pre(x == 0);\n  eff:\n    x = rand(100000000) + 1;\n")
    with pytest.raises(ToolLimitError) as e:
        explore(str(p), max_states=10)
    assert e.value.line == 7 and e.value.column == 9
    assert "at most 1,000,000" in e.value.message and "a limit of the tool" in e.value.message
    small = tmp_path / "small.pccl"
    small.write_text("loc:\n  int x = 0;\n\nGo():\n  pre(x == 0);\n  eff:\n    x = rand(3) + 1;\n")
    r = explore(str(small), agents=1, stall=False)
    assert r.status == "exhaustive" and not r.violations


def test_long_run_summary_is_bounded(monkeypatch, tmp_path):
    """A run of many time steps keeps an evenly thinned summary, not one
    state per time step."""
    from pccl.tools import runner
    from pccl.api import run
    monkeypatch.setattr(runner, "SUMMARY_LIMIT", 50)
    p = tmp_path / "tick.pccl"
    p.write_text("loc:\n  int x = 0;\n\nTick():\n  pre(true);\n  eff:\n    x = 1 - x;\n")
    r = run(str(p), agents=1, max_time=1000)
    assert r.status == "bounded"
    assert 25 <= len(r.summary) <= 51
    times = [t for t, _ in r.summary]
    assert times == sorted(times) and times[0] == 0
