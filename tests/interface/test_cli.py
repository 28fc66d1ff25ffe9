"""The ``pccl`` command line: help, check, run and explore, their output
formats and exit statuses (0 ok, 1 violation, 2 bad input)."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest


from conftest import FISCHER, RACE, RACE_NONATOMIC, RACE_WORLD, TEST_PROGRAMS
from conftest import cli

LOOP = str(TEST_PROGRAMS / "eng_loop.pccl")
SMALL = ["--set", "k=1", "--set", "cstime=0"]




def assert_user_error(res, where=None):
    assert res.exit_code == 2, res.output
    err = res.stderr
    assert ": error: " in err
    if where is not None:
        assert err.startswith(where + ": error: "), err
    assert res.stdout == ""


# ---------------------------------------------------------------------------
# help
# ---------------------------------------------------------------------------

def test_help():
    res = cli("--help")
    assert res.exit_code == 0
    for word in ("check", "run", "explore", "Exit status"):
        assert word in res.stdout


def test_run_help():
    res = cli("run", "--help")
    assert res.exit_code == 0
    for opt in ("--seed", "--max-steps", "--max-time", "--trace", "--format", "--blackbox",
                "--world", "--agents", "--rate", "--events", "--n0", "--delta"):
        assert opt in res.stdout, opt


def test_explore_help():
    res = cli("explore", "--help")
    assert res.exit_code == 0
    for opt in ("--depth", "--max-states", "--max-time", "--invariant", "--no-deadlock", "--all",
                "--format", "--abstract-time", "--blackbox", "--events", "--set"):
        assert opt in res.stdout, opt


def test_console_script_and_module_entry_point():
    out = subprocess.run([sys.executable, "-m", "pccl.cli", "check", RACE],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "ok" in out.stdout


# ---------------------------------------------------------------------------
# check
# ---------------------------------------------------------------------------

def test_check_ok():
    for prog in (FISCHER, RACE, RACE_NONATOMIC):
        res = cli("check", prog)
        assert res.exit_code == 0 and res.stdout.startswith(prog) and "ok" in res.stdout


def test_check_type_error_has_location_and_caret(tmp_path):
    p = tmp_path / "bad.pccl"
    p.write_text("E():\n  pre(true);\n  eff:\n    x = 1;\n")
    res = cli("check", p)
    assert_user_error(res, f"{p}:4:5")
    lines = res.stderr.splitlines()
    assert "x = 1;" in lines[1]
    caret = lines[2]
    assert caret.rstrip().endswith("^")
    # the caret sits under the x
    assert caret.index("^") == lines[1].index("x = 1")


def test_check_syntax_error(tmp_path):
    p = tmp_path / "syn.pccl"
    p.write_text("loc:\n  int x = 0;\nE():\n  pre(x > );\n  eff:\n    skip;\n")
    res = cli("check", p)
    assert_user_error(res)
    assert re.match(rf"{re.escape(str(p))}:4:\d+: error: ", res.stderr)
    assert "^" in res.stderr


def test_check_missing_file(tmp_path):
    res = cli("check", tmp_path / "nope.pccl")
    assert_user_error(res)


def test_check_bad_world(tmp_path):
    w = tmp_path / "w.toml"
    w.write_text("agents = 2\nresolution = -1\n")
    res = cli("check", RACE, "--world", w)
    assert_user_error(res)
    assert str(w) in res.stderr


# ---------------------------------------------------------------------------
# run
# ---------------------------------------------------------------------------

def test_run_text():
    res = cli("run", RACE, "--world", RACE_WORLD)
    assert res.exit_code == 0
    out = res.stdout
    assert "blackbox straight" in out and "seed 0" in out
    assert "result: final" in out
    assert "time steps:" in out and "final configuration:" in out
    assert "exited" in out


def test_run_json():
    res = cli("run", RACE, "--world", RACE_WORLD, "--format", "json", "--seed", "4")
    assert res.exit_code == 0
    data = json.loads(res.stdout)
    assert data["status"] == "final" and data["exit_status"] == 0 and data["seed"] == 4
    final = data["final"]               # a state as the trace format writes one
    assert final["shared"]["dests"] == []
    assert [a["status"]["status"] for a in final["agents"]] == ["exited", "exited"]
    assert data["summary"][0]["time"] == 0


def test_run_json_trace():
    res = cli("run", RACE, "--world", RACE_WORLD, "--format", "json", "--trace")
    data = json.loads(res.stdout)
    steps = data["trace"]["steps"]      # the trace document (docs/trace-format.md)
    assert steps and steps[0]["index"] == 1
    assert {"rule", "agent", "time", "changes"} <= set(steps[0])


def test_run_trace_prints_rule_names():
    res = cli("run", RACE, "--world", RACE_WORLD, "--trace")
    assert res.exit_code == 0
    for rule in ("EVENT SELECT", "STATEMENT", "DOREACH UPDATE", "COUNTER ADVANCE",
                 "LOCK REQUEST", "ATOMIC EXECUTION", "LOCK RELEASE", "TIME ADVANCE",
                 "DOREACH INVOKE", "EXIT"):
        assert rule in res.stdout, rule
    assert re.search(r"^\s+1\. t=0\s+agent \d", res.stdout, re.M)


def test_run_stuck_agent_exit_1_with_source_line():
    for seed in range(30):
        res = cli("run", RACE_NONATOMIC, "--world", RACE_WORLD, "--blackbox", "instant",
                  "--seed", seed)
        if res.exit_code == 1:
            break
    assert res.exit_code == 1
    assert "result: violation" in res.stdout and "remove" in res.stdout
    assert re.search(rf"at {re.escape(RACE_NONATOMIC)}:35:\d+: remove\(dests, currentDest\);",
                     res.stdout)


def test_run_max_steps():
    res = cli("run", LOOP, "--blackbox", "instant", "--max-steps", "200")
    assert res.exit_code == 1
    assert "max-steps" in res.stdout and "agent 1" in res.stdout


def test_run_same_seed_same_output():
    a = cli("run", FISCHER, "--seed", "5", "--max-time", "12", "--trace")
    b = cli("run", FISCHER, "--seed", "5", "--max-time", "12", "--trace")
    assert a.exit_code == b.exit_code == 0
    assert a.stdout == b.stdout


@pytest.mark.parametrize("args", [
    ["--blackbox", "nosuch"], ["--rate", "7=2"], ["--rate", "x"], ["--set", "nosuch=1"],
    ["--world", "/nonexistent/w.toml"], ["--agents", "0"], ["--events", "all"],
])
def test_run_bad_options_exit_2(args):
    res = cli("run", RACE, *args)
    assert res.exit_code == 2


# ---------------------------------------------------------------------------
# explore
# ---------------------------------------------------------------------------

def test_explore_exit_0():
    res = cli("explore", RACE, "--world", RACE_WORLD, "-b", "straight")
    assert res.exit_code == 0
    assert "no violation — exhaustive [blackbox straight]" in res.stdout
    for word in ("states", "transitions", "max depth", "seconds", "states/second"):
        assert word in res.stdout


def test_explore_exit_1_with_counterexample():
    res = cli("explore", FISCHER, *SMALL, "--invariant", "count(inCs) <= 1")
    assert res.exit_code == 1
    out = res.stdout
    assert "violation: invariant 'count(inCs) <= 1' violated" in out
    assert "counterexample (" in out and "violating state:" in out
    assert re.search(r"^\s+1\. t=0\s+agent \d\s+EVENT SELECT\s+\[Start\]", out, re.M)


def test_explore_bound_named():
    # unreduced: the depth is counted in the rules' steps (a reduced search counts merged
    # chains as one step and reaches race's stall within 12 of them: 14 steps expanded)
    res = cli("explore", RACE, "--world", RACE_WORLD, "--depth", "12", "--reduce", "none")
    assert res.exit_code == 0 and "--depth 12" in res.stdout
    res = cli("explore", RACE, "--world", RACE_WORLD, "--max-states", "50")
    assert res.exit_code == 0 and "--max-states 50" in res.stdout
    res = cli("explore", FISCHER, *SMALL, "--max-time", "4")
    assert res.exit_code == 0 and "--max-time 4" in res.stdout
    assert "time abstraction off" in res.stdout


@pytest.mark.parametrize("args", [
    [FISCHER, "--invariant", "count(inCS) <= 1"],
    [FISCHER, "--invariant", "count(inCs) <="],
    [RACE, "--blackbox", "nosuch"],
    [RACE, "--world", "/nonexistent/w.toml"],
    ["/nonexistent/p.pccl"],
    [RACE, "--set", "dests=[1,"],
])
def test_explore_exit_2(args):
    res = cli("explore", *args)
    assert res.exit_code == 2
    assert "Error" in res.stderr or ": error: " in res.stderr


def test_explore_property_typo_rendered_with_caret():
    res = cli("explore", FISCHER, "--invariant", "count(inCS) <= 1")
    assert_user_error(res)
    lines = res.stderr.splitlines()
    assert re.match(r".*:1:7: error: ", lines[0])
    assert "count(inCS) <= 1" in lines[1]
    assert lines[2].index("^") == lines[1].index("inCS")


def test_explore_json():
    res = cli("explore", FISCHER, *SMALL, "--invariant", "count(inCs) <= 1", "--format", "json")
    assert res.exit_code == 1
    data = json.loads(res.stdout)
    assert data["status"] == "violation" and data["exit_status"] == 1
    assert data["blackbox"] == "straight" and data["agents"] == 2
    (v,) = data["violations"]
    # its path as the trace format writes one (version 2): initial, steps, final
    assert v["kind"] == "invariant" and v["trace"]["steps"] and v["trace"]["initial"]
    assert all(a["variables"]["inCs"] for a in v["trace"]["final"]["agents"])
    assert {"states", "transitions", "max_depth"} <= set(data["statistics"])
    ok = json.loads(cli("explore", RACE, "--world", RACE_WORLD, "-b", "straight",
                        "--format", "json").stdout)
    assert ok["status"] == "exhaustive" and ok["violations"] == [] and ok["exit_status"] == 0


def test_explore_k_format():
    res = cli("explore", FISCHER, *SMALL, "--invariant", "count(inCs) <= 1", "--format", "k")
    assert res.exit_code == 1
    out = res.stdout
    for tok in ("<gMemory>", "</gMemory>", "<MMap>", "</MMap>", "|->", "<time>", "<agent>",
                "<memory>"):
        assert tok in out, tok
    assert re.search(r"<gMemory> reqid \|-> \d+ k \|-> \d+ d \|-> \d+ </gMemory>", out)
    assert re.search(r"<time> \d+ </time>", out)


def test_explore_all_and_no_deadlock():
    prog = str(TEST_PROGRAMS / "eng_assert.pccl")
    a = cli("explore", prog, "--blackbox", "instant", "--all")
    assert a.exit_code == 1 and "deadlock: " in a.stdout and "assertion failed" in a.stdout
    b = cli("explore", prog, "--blackbox", "instant", "--all", "--no-deadlock")
    # no deadlock reported; the checked section says the check was off
    assert b.exit_code == 1 and "deadlock: " not in b.stdout and "deadlock -" in b.stdout


TIMING = re.compile(r"^\s*(seconds|states/second|peak memory)\b")


def strip_timing(text):
    return [ln for ln in text.splitlines() if not TIMING.match(ln)]


@pytest.mark.parametrize("args", [
    [FISCHER, *SMALL, "--invariant", "count(inCs) <= 1"],
    [RACE_NONATOMIC, "--world", RACE_WORLD, "--blackbox", "nondet", "--all"],
    [RACE, "--world", RACE_WORLD, "--depth", "20"],
])
def test_explore_output_is_deterministic(args):
    a, b = cli("explore", *args), cli("explore", *args)
    assert a.exit_code == b.exit_code
    assert strip_timing(a.stdout) == strip_timing(b.stdout)
    assert len(strip_timing(a.stdout)) < len(a.stdout.splitlines())     # timing lines exist


def test_explore_stuck_agent_names_source_location():
    res = cli("explore", RACE_NONATOMIC, "--world", RACE_WORLD, "--blackbox", "nondet")
    assert res.exit_code == 1
    assert "[blackbox nondet]" in res.stdout
    assert re.search(rf"^  at {re.escape(RACE_NONATOMIC)}:35:\d+$", res.stdout, re.M)
    assert "stuck(remove of an element not in the list" in res.stdout


def test_explore_defaults_to_nondet_for_a_program_that_moves():
    """README promises every interleaving and timing: without --blackbox the
    paper's buggy race_nonatomic.pccl must not explore clean."""
    res = cli("explore", RACE_NONATOMIC, "--world", RACE_WORLD)
    assert res.exit_code == 1, res.output
    header = res.stdout.splitlines()[0]
    assert "blackbox nondet (default for programs that move)" in header
    assert "stuck" in res.stdout and "[blackbox nondet]" in res.stdout


def test_explore_explicit_deterministic_blackbox_notes_fixed_timing():
    res = cli("explore", RACE_NONATOMIC, "--world", RACE_WORLD, "-b", "straight")
    assert res.exit_code == 0, res.output
    assert "blackbox straight," in res.stdout.splitlines()[0]      # chosen, no reason given
    assert ("no violation — exhaustive [blackbox straight] (travel times fixed by straight; "
            "-b nondet explores every timing)") in res.stdout
    # a program that does not move: no note, and the run default stays
    res = cli("explore", FISCHER, *SMALL)
    assert "blackbox straight," in res.stdout and "travel times" not in res.stdout


def test_run_keeps_straight_default_for_a_program_that_moves():
    res = cli("run", RACE_NONATOMIC, "--world", RACE_WORLD)
    assert "blackbox straight," in res.stdout.splitlines()[0]


def test_did_you_mean_for_options_choices_and_blackboxes():
    res = cli("explore", RACE, "--events", "anny")
    assert res.exit_code == 2 and "(did you mean 'any'?)" in res.stderr
    res = cli("run", RACE, "--format", "jsn")
    assert res.exit_code == 2 and "(did you mean 'json'?)" in res.stderr
    res = cli("explore", RACE, "--blackbox", "nondett")
    assert res.exit_code == 2 and "did you mean 'nondet'?" in res.stderr
    res = cli("explore", RACE, "--event", "any")                 # click's own suggestion
    assert res.exit_code == 2 and "'--events'" in res.stderr
    res = cli("explore", FISCHER, "--invariant", "cnt(inCs) <= 1")
    assert res.exit_code == 2 and "unknown function 'cnt' (did you mean 'count'?)" in res.stderr


def test_check_names_the_world_for_a_world_function():
    from conftest import PROGRAMS
    res = cli("check", str(PROGRAMS / "collide_fixed.pccl"))
    assert res.exit_code == 2
    assert "unknown function 'detour'" in res.stderr and "needs --world FILE" in res.stderr


PLAIN_LINE = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d  (initial configurations generated [\d,]+  )?"
                        r"states [\d,]+  frontier [\d,]+  "
                        r"depth \d+  (t \d+  )?[\d,]+ states/s  mem [\d,]+ MiB$")


def test_explore_progress_not_a_terminal_plain_timestamped_lines():
    """stderr is not a terminal (CliRunner, like CI or nohup): timestamped
    lines, the header first, no carriage return and no escape code."""
    res = cli("explore", FISCHER, "--max-states", "600000", "--progress-interval", "0.05",
              "--reduce", "merge,symmetry,por")
    err = res.stderr
    assert "\r" not in err and "\x1b" not in err
    lines = err.splitlines()
    assert len(lines) >= 2, err
    assert re.match(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d  pccl explore ", lines[0])
    # the report's header: the progress header, and the engine once the search chose it
    assert res.stdout.splitlines()[0] in (lines[0].split("  ", 1)[1],
                                          lines[0].split("  ", 1)[1] + ", engine native")
    assert all(PLAIN_LINE.match(ln) for ln in lines[1:]), err


def test_explore_progress_defaults_off_a_terminal_until_the_search_is_long():
    res = cli("explore", FISCHER, *SMALL)                  # far shorter than 10 s
    assert res.stderr == ""
    res = cli("explore", FISCHER, *SMALL, "--progress")    # asked for: the header at once
    assert re.match(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d  pccl explore ", res.stderr)
    res = cli("explore", FISCHER, "--max-states", "60000", "--progress-interval", "0.05",
              "--no-progress")
    assert res.stderr == ""


def test_explore_progress_on_a_terminal_is_a_live_display():
    import io
    from pccl.cli import _progress_printer
    out = io.StringIO()
    show = _progress_printer("pccl explore x.pccl: 2 agents, blackbox nondet", None, 10.0,
                             stream=out, tty=True)
    show({"states": 1000, "frontier": 10, "depth": 3, "seconds": 0.5, "memory": 2**27})
    show({"states": 4000, "frontier": 20, "depth": 4, "seconds": 1.5, "memory": 2**27})
    show.close()
    text = out.getvalue()
    assert "\x1b[" in text                                   # redrawn in place
    head = text.index("pccl explore x.pccl: 2 agents, blackbox nondet")
    line = text.index("0:00:01  states 4,000  frontier 20  depth 4  3,000 states/s  mem 128 MiB")
    assert head < line
    assert text.endswith("\x1b[2K")                          # erased: the report follows


def test_explore_run_json_stuck_status():
    for seed in range(30):
        res = cli("run", RACE_NONATOMIC, "--world", RACE_WORLD, "--blackbox", "instant",
                  "--seed", seed, "--format", "json")
        if res.exit_code == 1:
            break
    data = json.loads(res.stdout)
    assert data["status"] == "violation" and data["exit_status"] == 1
    stuck = [a["status"] for a in data["final"]["agents"] if a["status"]["status"] == "stuck"]
    assert len(stuck) == 1 and stuck[0]["line"] == 35 and "remove" in stuck[0]["reason"]


@pytest.mark.parametrize("workers", ["1", "2"])
def test_ctrl_c_stops_cleanly_with_statistics_and_an_interrupted_verdict(workers):
    import select
    import signal
    import time

    # Progress lines on stderr are the ready signal: the first one with
    # figures means the search loop (and its SIGINT handler) is running.
    proc = subprocess.Popen(
        [sys.executable, "-m", "pccl.cli", "explore", str(FISCHER), "--agents", "3",
         "--set", "k=2", "--reduce", "merge,symmetry,por", "--progress", "--progress-interval", "0.2",
         "--workers", workers],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        # a runner that ignores SIGINT (a background job without job control)
        # passes that on, and Python keeps it ignored: Ctrl-C as a terminal sends it
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    seen = []
    deadline = time.monotonic() + 120
    while not any("frontier" in line for line in seen):
        assert proc.poll() is None, ("exited before the search started", seen)
        assert time.monotonic() < deadline, ("no progress line", seen)
        ready, _, _ = select.select([proc.stderr], [], [], 1.0)
        if ready:
            seen.append(proc.stderr.readline())
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    err = "".join(seen) + err
    assert proc.returncode == 130, (out, err)
    assert "interrupted" in out and "not exhaustive" in out
    assert "states/second" in out
    assert "Traceback" not in err


def test_ctrl_c_during_the_graph_analysis_reports_the_search(monkeypatch):
    """An interruption during the time-lock and stall analysis (after the
    search) still gives the search's report, interrupted (not every check
    ran), instead of no report at all."""
    from pccl import api
    from pccl.search import liveness

    def interrupted(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(liveness, "analyse", interrupted)
    r = api.explore(str(FISCHER), overrides={"k": "1"}, reduce="merge,symmetry,por")
    assert r.status == "interrupted" and r.stats.states > 1000
    assert "interrupted" in r.verdict


# ---------------------------------------------------------------------------
# issue 27, item 5: --exit-codes detailed, run --format k, run's JSON status
# ---------------------------------------------------------------------------

_P = "programs/"
_T = "tests/programs/"
DETAILED_CASES = [
    (("explore", _P + "fischer.pccl", "--set", "k=1", "--invariant", "count(inCs) <= 1"), 12),
    (("run", _P + "fischer.pccl", "--set", "k=1", "--invariant", "count(inCs) <= 1"), 12),
    (("explore", _P + "race.pccl", "--world", _P + "race.toml", "-b", "instant"), 14),
    (("explore", _T + "eng_assert.pccl"), 14),
    (("explore", _P + "race_safe.pccl", "--world", _P + "race.toml"), 11),       # stall
    (("run", _T + "rdv_meet.pccl", "--world", _T + "rdv_wall.toml"), 11),         # stalled
    (("explore", _T + "tl_spin.pccl"), 15),
    (("explore", "docs/examples/never.pccl", "--property", "eventually false"), 13),
    (("run", _T + "runaway.pccl", "--max-steps", "50"), 16),
    (("explore", "docs/examples/never.pccl"), 0),
]


@pytest.mark.parametrize("args, detailed", DETAILED_CASES)
def test_exit_codes_detailed_tells_the_violations_apart(args, detailed):
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    plain = cli(*args, cwd=root)
    res = cli(*args, "--exit-codes", "detailed", cwd=root)
    assert plain.exit_code == (1 if detailed else 0)          # the default is unchanged
    assert res.exit_code == detailed, res.output
    assert plain.output.splitlines()[:3] == res.output.splitlines()[:3]   # same verdict


def test_exit_codes_table_is_documented():
    """Every detailed status is in the exit-code table of the README and of
    docs/language.md."""
    from pathlib import Path
    from pccl.tools.exitcodes import DETAILED, TABLE
    root = Path(__file__).resolve().parents[2]
    assert {c for c, _ in TABLE} == set(DETAILED.values())
    for doc in ("README.md", "docs/language.md"):
        text = (root / doc).read_text()
        for code, _ in TABLE:
            assert f"| {code} |" in text, (doc, code)


def test_detailed_exit_status_in_json():
    res = cli("run", FISCHER, "--set", "k=1", "--invariant", "count(inCs) <= 1",
              "--exit-codes", "detailed", "--format", "json")
    data = json.loads(res.output)
    assert res.exit_code == data["exit_status"] == 12
    # one vocabulary (version 2): explore's word; run's older "result" is gone
    assert data["status"] == "violation" and "result" not in data
    assert (data["format"], data["version"], data["command"]) == ("pccl-output", 2, "run")


def test_run_format_k_prints_the_final_configuration_in_k():
    res = cli("run", FISCHER, "--set", "k=1", "--format", "k", "--max-time", "3")
    assert res.exit_code == 0
    tail = res.output.split("final configuration:\n", 1)[1]
    assert tail.startswith("<agent> ") and "<gMemory>" in tail and "<time> 3 </time>" in tail


# ---------------------------------------------------------------------------
# issue 27, item 6: --depth means what the counterexample shows
# ---------------------------------------------------------------------------

def test_depth_is_shown_in_the_counterexample_and_is_what_depth_bounds():
    args = ("explore", FISCHER, "--set", "k=1", "--invariant", "count(inCs) <= 1")
    out = cli(*args, "--no-shorten").output
    m = re.search(r"^counterexample \((\d+) steps, shortest under the reductions; not compared "
                  r"with the unreduced graph \(--no-shorten\); depth (\d+) "
                  r"in the reduced graph, as --depth counts\):$", out, re.M)
    assert m, out
    steps, depth = int(m[1]), int(m[2])
    assert steps > depth                     # the steps are expanded, the depth is not
    # shortened against the unreduced semantics (issue 44.3), the depth is still said
    short = cli(*args).output
    assert re.search(rf"^counterexample \(\d+ steps, shortest: the reduced search's had "
                     rf"{steps} steps; depth {depth} in the reduced graph, as --depth counts\):$",
                     short, re.M), short
    # the depth printed is the smallest --depth that finds the violation
    assert cli(*args, "--depth", str(depth)).exit_code == 1
    below = cli(*args, "--depth", str(depth - 1))
    assert below.exit_code == 0 and f"stopped by --depth {depth - 1}" in below.output
    # without reductions steps and depth are one number, and the note is not printed
    plain = cli(*args, "--reduce", "none").output
    assert re.search(r"^counterexample \(\d+ steps\):$", plain, re.M), plain
