"""Bad input gets one clear message and exit status 2, never a traceback;
exit statuses are honest (0 holds, 1 violation, 2 bad input)."""

from __future__ import annotations

import json

import pytest

from pccl.lang.errors import PcclError

from conftest import FISCHER, RACE, RACE_WORLD, interrupted
from conftest import cli

SMALL = ["--set", "k=1", "--set", "cstime=0"]




def user_error(res, *phrases, where=None):
    """Exit 2, one ': error: ' message on stderr containing every phrase."""
    assert res.exit_code == 2, (res.exit_code, res.output)
    err = res.stderr
    assert "Traceback" not in err
    assert err.count(": error: ") == 1, err
    if where is not None:
        assert err.startswith(where + ": error: "), err
    for p in phrases:
        assert p in err, (p, err)
    return err


# ---------------------------------------------------------------------------
# 2. a rate above n0 freezes an agent
# ---------------------------------------------------------------------------

def test_rate_above_n0_is_rejected():
    res = cli("explore", FISCHER, "--rate", "1=2", "--invariant", "count(inCs) <= 1")
    user_error(res, "rate 2 of agent 1 is above n0 = 1", "never run an event", "--n0 2")
    assert res.stdout == ""


def test_rate_above_n0_rejected_by_api():
    from pccl.api import make_model
    with pytest.raises(PcclError, match="above n0"):
        make_model(FISCHER, rates={1: 2})


def test_rates_in_header_and_json():
    res = cli("explore", FISCHER, *SMALL, "--n0", "2", "--rate", "1=2", "--max-states", "200")
    assert res.exit_code in (0, 1)
    header = res.stdout.splitlines()[0]
    assert "n0=2, rates 1=2," in header, header
    res = cli("explore", FISCHER, *SMALL, "--n0", "2", "--rate", "1=2", "--max-states", "200",
              "--format", "json")
    data = json.loads(res.stdout)
    assert data["n0"] == 2 and data["rates"] == [1, 2]
    res = cli("run", FISCHER, *SMALL, "--n0", "2", "--rate", "1=2", "--max-time", "3")
    assert "n0=2, rates 1=2," in res.stdout.splitlines()[0]
    res = cli("run", FISCHER, *SMALL, "--n0", "2", "--rate", "1=2", "--max-time", "3",
              "--format", "json")
    assert json.loads(res.stdout)["rates"] == [1, 2]


def test_help_rate_example_is_valid():
    res = cli("explore", "--help")
    assert "--n0 2 --rate 1=2" in res.stdout


# ---------------------------------------------------------------------------
# 6. errors found while exploring or running are one message, exit 2
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("cmd", ["explore", "run"])
def test_uninterpreted_function_without_world_value(cmd):
    res = cli(cmd, FISCHER, "--set", "k=getInput()", "--max-time", "3")
    user_error(res, "value of getInput() does not fit int", "needs --world")


@pytest.mark.parametrize("cmd", ["explore", "run"])
def test_arena_too_small_for_the_agents(cmd, tmp_path):
    w = tmp_path / "small.toml"
    w.write_text("arena = [[0, 0], [1, 1]]\n")
    res = cli(cmd, FISCHER, "--world", w, "--max-time", "3")
    user_error(res, "cannot place 2 agents", where=str(w))


def test_check_says_a_world_function_needs_world(tmp_path):
    p = tmp_path / "g.pccl"
    p.write_text("loc:\n  int c = getCount();\n")
    res = cli("check", p)
    err = user_error(res, "unknown function 'getCount'", "needs --world", where=f"{p}:2:11")
    assert "getCount under [functions]" in err


BLACKBOXES = '''
from pccl.blackboxes.base import Outcome

class Base:
    name = "mine"
    uses_time = False
    def init_env(self, world, n):
        return None

class Empty(Base):
    def step(self, world, motions, env, time, delta):
        return []

class Nothing(Base):
    def step(self, world, motions, env, time, delta):
        return None

class Raises(Base):
    def step(self, world, motions, env, time, delta):
        raise ZeroDivisionError("boom")

class Short(Base):
    def step(self, world, motions, env, time, delta):
        return [Outcome(((0.0, 0.0, 0.0),), (True,), (False,), None)]

class NotOutcome(Base):
    def step(self, world, motions, env, time, delta):
        return [(1, 2)]

class BadPos(Base):
    def step(self, world, motions, env, time, delta):
        return [Outcome(tuple("xy" for m in motions), (True,) * len(motions),
                        (False,) * len(motions), None)]

class BoolPos(Base):
    # (True, 0) equals (1, 0) and hashes alike: the engine's memo of checked
    # positions must still reject it
    def step(self, world, motions, env, time, delta):
        return [Outcome(tuple((1, 0) for m in motions), (True,) * len(motions),
                        (False,) * len(motions), None),
                Outcome(tuple((True, 0) for m in motions), (True,) * len(motions),
                        (False,) * len(motions), None)]

class Unhashable(Base):
    def step(self, world, motions, env, time, delta):
        return [Outcome(tuple(m.position for m in motions), (True,) * len(motions),
                        (False,) * len(motions), [1])]

class BadInit(Base):
    def init_env(self, world, n):
        raise KeyError("no env")
    def step(self, world, motions, env, time, delta):
        return []

EMPTY, NOTHING, RAISES, SHORT = Empty(), Nothing(), Raises(), Short()
NOT_OUTCOME, BAD_POS, UNHASHABLE, BAD_INIT = NotOutcome(), BadPos(), Unhashable(), BadInit()
BOOL_POS = BoolPos()
NOT_A_BLACKBOX = 42
'''

@pytest.fixture
def user_bb(tmp_path):
    path = tmp_path / "hard_bb.py"
    path.write_text(BLACKBOXES)
    prog = tmp_path / "mover.pccl"
    prog.write_text("""\
loc:
  bool sent = false;
  ObstacleList obs = getObs();

Go():
  pre(!sent);
  eff:
    doReach(ItemPosition(3, 3), obs);
    sent = true;
""")
    return path, prog


@pytest.mark.parametrize("cmd", ["explore", "run"])
def test_blackbox_returning_nothing(cmd, user_bb):
    path, prog = user_bb
    res = cli(cmd, prog, "--blackbox", f"{path}:EMPTY")
    user_error(res, "blackbox 'mine'", "no outcome")


# ---------------------------------------------------------------------------
# 8. user blackboxes: failures name the blackbox and the time
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("attr, phrase", [
    ("NOTHING", "step() must return a list of Outcome, got None"),
    ("RAISES", "step() raised ZeroDivisionError: boom"),
    ("SHORT", "'positions' must have one entry per agent (2), got 1 entries"),
    ("NOT_OUTCOME", "outcome 1 is tuple, not an Outcome"),
    ("BAD_POS", "position of agent 0 must be (x, y, z) finite numbers"),
    ("BOOL_POS", "outcome 2: position of agent 0 must be (x, y, z) finite numbers, got (True, 0)"),
    ("UNHASHABLE", "env holds a list"),
    ("BAD_INIT", "init_env() raised KeyError"),
])
@pytest.mark.parametrize("cmd", ["explore", "run"])
def test_failing_user_blackbox(cmd, attr, phrase, user_bb):
    path, prog = user_bb
    res = cli(cmd, prog, "--blackbox", f"{path}:{attr}")
    when = "0" if attr == "BAD_INIT" else "1"     # the time step() is given
    user_error(res, f"blackbox 'mine' failed at time {when}: ", phrase)


def test_not_a_blackbox(user_bb):
    path, prog = user_bb
    res = cli("explore", prog, "--blackbox", f"{path}:NOT_A_BLACKBOX")
    user_error(res, "NOT_A_BLACKBOX is not a blackbox")


def test_blackbox_object_checked_by_api():
    from pccl.api import make_model
    with pytest.raises(PcclError, match="is not a blackbox"):
        make_model(FISCHER, blackbox=object())


def test_empty_blackbox_name_is_an_error():
    res = cli("explore", FISCHER, *SMALL, "--blackbox", "")
    user_error(res, "empty blackbox name")


def test_world_function_shadowing_a_builtin(tmp_path):
    w = tmp_path / "w.toml"
    w.write_text("[functions]\ncount = 3\n")
    res = cli("explore", RACE, "--world", w)
    user_error(res, "function 'count' shadows the built-in count()", where=f"{w}:2:1")


# ---------------------------------------------------------------------------
# 7. infinite floats, over-long integers, coordinates near the float limit
# ---------------------------------------------------------------------------

BIG = "9" * 5000


def test_infinite_float_literal_in_program(tmp_path):
    p = tmp_path / "inf.pccl"
    p.write_text("loc:\n  float x = 1e999;\n")
    user_error(cli("check", p), "float literal 1e999 is out of range", where=f"{p}:2:13")


def test_infinite_float_literal_in_invariant():
    res = cli("explore", FISCHER, *SMALL, "--invariant", "1e999 > 0.0")
    user_error(res, "float literal 1e999 is out of range", where="--invariant #1:1:1")


def test_long_integer_literal_in_program(tmp_path):
    p = tmp_path / "big.pccl"
    p.write_text(f"loc:\n  int x = {BIG};\n")
    user_error(cli("check", p), "integer literal too long (5000 digits; at most 4300)",
               where=f"{p}:2:11")


@pytest.mark.parametrize("opt", [["--set", f"k={BIG}"],
                                 ["--invariant", f"count(inCs) <= {BIG}"]])
def test_long_integer_literal_in_options(opt):
    res = cli("explore", FISCHER, *opt, "--max-states", "10")
    user_error(res, "integer literal too long")


def test_long_integer_in_world(tmp_path):
    w = tmp_path / "w.toml"
    w.write_text(f"agents = {BIG}\n")
    user_error(cli("run", RACE, "--world", w), "integer too long", where=f"{w}:1:10")


def test_non_finite_world_function_value(tmp_path):
    w = tmp_path / "w.toml"
    w.write_text("[functions]\ngetInput = nan\n")
    user_error(cli("run", RACE, "--world", w), "values must be finite", where=f"{w}:2:12")


def test_start_position_near_the_float_limit(tmp_path):
    w = tmp_path / "w.toml"
    w.write_text("start = [[1e308, 0]]\n")
    for cmd in ("run", "explore"):
        user_error(cli(cmd, RACE, "--world", w), "coordinates must be within",
                   where=f"{w}:1:10")


def test_huge_values_are_displayed_and_overflow_is_stuck(tmp_path):
    # ints stored in a state stay within 10**4300 (docs/decisions.md, Number
    # limits): a value that keeps growing gets the agent stuck
    p = tmp_path / "grow.pccl"
    p.write_text("loc:\n  int x = 10;\n\n"
                 "Go():\n  pre(true);\n  eff:\n    x = x * x;\n")
    res = cli("run", p, "--max-time", "16")
    assert res.exit_code == 1, res.output
    assert "integer overflow: the result has more than 4,300 digits" in res.stdout
    assert "line 7" in res.stdout
    res = cli("run", p, "--max-time", "16", "--format", "json")
    assert res.exit_code == 1, res.output
    variables = json.loads(res.stdout)["final"]["agents"][0]["variables"]
    assert len(str(variables["x"])) == 4097          # 10**4096, the last value stored
    # a float that overflows is never stored: the agent is stuck at the line
    q = tmp_path / "overflow.pccl"
    q.write_text("loc:\n  float y = 1e300;\n\n"
                 "Go():\n  pre(true);\n  eff:\n    y = y * 1e300;\n")
    res = cli("run", q, "--max-time", "16")
    assert res.exit_code == 1 and "Traceback" not in res.output
    assert "float overflow" in res.stdout and "line 7" in res.stdout


@pytest.mark.parametrize("cmd", ["explore", "run"])
def test_target_near_the_float_limit(cmd, tmp_path):
    p = tmp_path / "far.pccl"
    p.write_text("loc:\n  bool sent = false;\n\nGo():\n  pre(!sent);\n  eff:\n"
                 "    doReach(ItemPosition(1e308, 0), []);\n    sent = true;\n")
    res = cli(cmd, p, "--blackbox", "instant")
    user_error(res, "cannot be rounded to the resolution")


# ---------------------------------------------------------------------------
# 9. the Python API checks its arguments
# ---------------------------------------------------------------------------

from pccl import api  # noqa: E402
from pccl.lang.errors import ArgumentError  # noqa: E402


@pytest.mark.parametrize("func, kw, phrase", [
    ("explore", dict(max_states=0), "max_states must be an integer >= 1, got 0"),
    ("explore", dict(max_states="10"), "max_states must be an integer or None, got '10'"),
    ("explore", dict(depth=-1), "depth must be an integer >= 0, got -1"),
    ("explore", dict(max_time=float("nan")), "max_time must be a finite number, got nan"),
    ("explore", dict(max_time=-1), "max_time must be >= 0, got -1"),
    ("explore", dict(invariants="count(inCs) <= 1"), "invariants must be a list of strings"),
    ("explore", dict(invariants=[3]), "invariants must contain strings, got 3"),
    ("explore", dict(delta=float("inf")), "delta must be a finite number"),
    ("explore", dict(delta="1"), "delta must be a number"),
    ("explore", dict(n0=1.5), "n0 must be an integer"),
    ("explore", dict(rates=[(1, 2)]), "rates must map agent indexes to rates"),
    ("explore", dict(rates={"1": 2}), "rates: an agent index must be an integer"),
    ("explore", dict(agents=True), "agents must be an integer or None, got True"),
    ("explore", dict(agents=0), "agents must be an integer >= 1, got 0"),
    ("explore", dict(overrides={"k": 2.5j}), "the value of k must be a PCCL expression"),
    ("explore", dict(overrides="k=2"), "overrides must map variable names"),
    ("explore", dict(progress=3), "progress must be callable or None"),
    ("explore", dict(deadlock="no"), "deadlock must be True or False"),
    ("explore", dict(max_sates=3), "unknown option max_sates"),
    ("explore", dict(world=3), "world must be a path, a World or None, got 3"),
    ("explore", dict(blackbox=3), "blackbox must be a name"),
    ("run", dict(seed="x"), "seed must be an integer, got 'x'"),
    ("run", dict(max_steps=0), "max_steps must be an integer >= 1, got 0"),
    ("run", dict(max_time=float("nan")), "max_time must be a finite number, got nan"),
    ("run", dict(abstract_time=True), "abstract_time is not an option of run"),
    ("make_model", dict(agents="2"), "agents must be an integer or None, got '2'"),
    ("make_model", dict(events="all"), "events must be 'any' or 'first', got 'all'"),
    ("make_model", dict(rng=3), "rng must be a random.Random or None"),
    ("make_model", dict(collisions="yes"), "collisions must be True or False"),
])
def test_api_arguments_are_checked(func, kw, phrase):
    with pytest.raises(ArgumentError) as info:
        getattr(api, func)(FISCHER, **kw)
    err = info.value
    assert isinstance(err, PcclError) and isinstance(err, ValueError)
    assert phrase in err.message, err.message
    assert err.render().startswith(f"pccl.api.{func}: error: ")


def test_api_program_argument_checked():
    with pytest.raises(ArgumentError, match="program must be a path"):
        api.explore(42)
    with pytest.raises(ArgumentError, match="program must be a path"):
        api.check(None)


def test_api_explore_model_checks_its_arguments():
    with pytest.raises(ArgumentError, match="model must be a Model"):
        api.explore_model(FISCHER)
    m = api.make_model(FISCHER, overrides={"k": "1", "cstime": "0"})
    with pytest.raises(ArgumentError, match="max_states must be an integer >= 1, got 0"):
        api.explore_model(m, max_states=0)


def test_api_check():
    info = api.check(RACE, world=RACE_WORLD)
    assert "getInput" in info.functions or info.variables
    with pytest.raises(PcclError, match="unknown function 'getCount'"):
        api.check("loc:\n  int c = getCount();\n", source=True)


# ---------------------------------------------------------------------------
# 13. exit statuses are documented and honest
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("cmd", [[], ["run"], ["explore"]])
def test_exit_statuses_in_help(cmd):
    out = " ".join(cli(*cmd, "--help").stdout.split())
    for phrase in ("0 the properties hold", "1 a violation", "2 bad input",
                   "130 interrupted (Ctrl-C)", "143 terminated (SIGTERM)"):
        assert phrase in out, (phrase, out)


def test_exit_statuses_in_readme():
    from conftest import ROOT
    text = (ROOT / "README.md").read_text()
    assert "## Exit codes" in text
    section = text.split("## Exit codes", 1)[1].split("\n## ", 1)[0]
    for code in ("| 0 |", "| 1 |", "| 2 |", "| 130 |", "| 143 |"):
        assert code in section, code


@pytest.mark.parametrize("cmd", ["run", "explore"])
@pytest.mark.parametrize("where", ["missing-dir", "parent-is-a-file"])
def test_unwritable_plot_path_is_rejected_before_the_search(cmd, where, tmp_path, monkeypatch):
    import pccl.api
    calls = []
    monkeypatch.setattr(pccl.api, "explore_model", lambda *a, **k: calls.append(1))
    monkeypatch.setattr(pccl.api, "run", lambda *a, **k: calls.append(1))
    (tmp_path / "file").write_text("")
    path = tmp_path / ("no" if where == "missing-dir" else "file") / "x.png"
    res = cli(cmd, FISCHER, *SMALL, "--plot", path)
    user_error(res, f"cannot write {path}: ", where="--plot")
    assert calls == [], "the search must not start"


def test_plot_failure_keeps_the_violation_status(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    import pccl.output.plot

    def fail(*a, **k):
        raise PcclError("cannot write plot: disk full", filename=str(tmp_path / "x.png"))
    monkeypatch.setattr(pccl.output.plot, "plot_trace", fail)
    monkeypatch.setattr(pccl.output.plot, "plot_run", fail)
    res = cli("explore", FISCHER, *SMALL, "--invariant", "count(inCs) <= 1",
              "--plot", tmp_path / "x.png")
    assert res.exit_code == 1, res.output
    assert "violation:" in res.stdout and "disk full" in res.stderr
    res = cli("run", FISCHER, *SMALL, "--max-time", "3",
              "--plot", tmp_path / "x.png")
    assert res.exit_code == 0 and "disk full" in res.stderr


def test_ctrl_c_during_run_exits_130(monkeypatch):
    import pccl.tools.runner

    def interrupted(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(pccl.tools.runner, "run", interrupted)
    res = cli("run", FISCHER)
    assert res.exit_code == 130 and "interrupted" in res.stderr
    assert "Aborted" not in res.output


@pytest.mark.parametrize("sig, code", [("SIGTERM", 143), ("SIGINT", 130)])
def test_signals_stop_explore_with_their_status(sig, code):
    # the Python engine: the native one may end the search before the signal
    rc, out, err = interrupted(["explore", FISCHER, "--no-progress", "--engine", "python",
                                "--reduce", "merge,symmetry,por"], sig)
    assert rc == code, (out, err)
    assert "interrupted" in out and "statistics:" in out
    assert "Traceback" not in out + err


@pytest.mark.parametrize("sig, code", [("SIGTERM", 143), ("SIGINT", 130)])
def test_signals_stop_a_native_search_with_their_status(sig, code):
    """A signal in the middle of the native engine's search (a progress
    line seen) prints the header, the statistics and the interrupted verdict."""
    rc, out, err = interrupted(["explore", FISCHER, "--agents", "3", "--set", "k=2", "--set", "d=2",
                                "--reduce", "merge,symmetry,por",
                                "--progress", "--progress-interval", "0.2"], sig,
                               ready="frontier", after=0.5)
    assert rc == code, (out, err)
    assert "engine native" in out
    assert "interrupted" in out and "statistics:" in out
    assert "Traceback" not in out + err


# ---------------------------------------------------------------------------
# 14. errors in option values point into the option
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("value, phrase, col, width", [
    ("1.5", "cannot initialise 'k' of type int with float", 1, 3),
    ("  true", "cannot initialise 'k' of type int with bool", 1, 4),
    ("1 + nosuch", "undeclared variable 'nosuch'", 5, 6),
    ("getInput()", "value of getInput() does not fit int", 1, 10),
    ("foo()", "unknown function 'foo'", 1, 3),
])
def test_set_errors_point_into_the_option(value, phrase, col, width):
    res = cli("explore", FISCHER, "--set", f"k={value}", "--max-states", "10")
    err = user_error(res, phrase, where=f"--set k:1:{col}")
    lines = err.splitlines()
    assert lines[1].endswith("| " + value.strip()), lines
    assert lines[2].endswith("| " + " " * (col - 1) + "^" * width), lines
    assert "fischer.pccl" not in err


@pytest.mark.parametrize("args, where, phrase", [
    (["--rate", "7=2"], "--rate", "agent 7 does not exist (agents are 0..1)"),
    (["--set", "nosuch=1"], "--set", "no variable named nosuch"),
    (["--blackbox", "nosuch"], "--blackbox", "unknown blackbox 'nosuch'"),
    (["--invariant", "time < 3", "--abstract-time"], "--abstract-time",
     "time abstraction is unsound"),
    (["--max-time", "3", "--abstract-time"], "--abstract-time", "cannot be combined"),
])
def test_option_errors_are_named_by_the_option(args, where, phrase):
    res = cli("explore", FISCHER, *args)
    err = user_error(res, phrase, where=where)
    assert "<input>" not in err


@pytest.mark.parametrize("cmd, opt, value", [
    ("explore", "--max-time", "nan"), ("run", "--max-time", "nan"),
    ("explore", "--delta", "inf"), ("run", "--delta", "nan"),
])
def test_non_finite_numbers_in_options(cmd, opt, value):
    res = cli(cmd, FISCHER, opt, value)
    assert res.exit_code == 2, res.output
    assert f"Invalid value for '{opt}': '{value}' is not a finite number" in res.stderr


# ---------------------------------------------------------------------------
# limits found on the way: deep expressions, absurd agent counts
# ---------------------------------------------------------------------------

def test_deeply_nested_expression_in_program(tmp_path):
    p = tmp_path / "deep.pccl"
    p.write_text("loc:\n  int x = " + "-" * 300 + "1;\n")
    user_error(cli("run", p), "expression nested too deeply (more than 100 levels)",
               where=f"{p}:2:111")


def test_deeply_nested_expression_in_options():
    res = cli("explore", FISCHER, "--set", "k=" + "-" * 300 + "1")
    user_error(res, "expression nested too deeply", where="--set k:1:101")
    res = cli("explore", FISCHER, "--invariant", "!" * 300 + "true")
    user_error(res, "expression nested too deeply", where="--invariant #1:1:101")


def test_absurd_agent_count():
    res = cli("explore", FISCHER, "--agents", "100000000000")
    user_error(res, "the number of agents must be at most 10,000", where="--agents")


@pytest.mark.parametrize("args, phrase", [
    (["--rate=-1=1"], "'-1=1': agents are numbered from 0"),
    (["--rate", "1=0"], "'1=0': a rate is a positive integer"),
    (["--set", "k=2", "--set", "k=3"], "variable k given more than once"),
    (["--rate", "1=1", "--rate", "1=1"], "agent 1 given more than once"),
])
def test_option_values_checked_by_the_option_parser(args, phrase):
    res = cli("explore", FISCHER, *args, "--max-states", "10")
    assert res.exit_code == 2, res.output
    assert phrase in res.stderr and "pccl.api" not in res.stderr
