"""pccl simulate: outcome counts, and the pccl run command printed for each
outcome reproduces it."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path


from pccl.model.layout import TIME
import conftest

ROOT = Path(__file__).resolve().parents[2]
ARGS = ["simulate", "programs/race_nonatomic.pccl", "--world", "programs/race.toml", "-b", "nondet",
        "--agents", "3", "--runs", "200"]


def cli(*args):
    return conftest.cli(*args, cwd=ROOT)


def test_simulate_reports_stuck_with_a_seed_whose_run_reproduces_it():
    res = cli(*ARGS)
    assert res.exit_code == 1
    out = res.output
    assert "200 runs (seeds 0–199), 3 agents, blackbox nondet" in out
    blocks = re.findall(r"^  (.+?): (\d+) runs? \(.*\n(?:    e\.g\. (.*)\n)?    first seed (\d+): (.*)$",
                        out, re.M)
    assert sum(int(b[1]) for b in blocks) == 200
    stuck = [b for b in blocks if b[0].startswith("stuck")]
    assert stuck
    for label, _count, example, seed, command in blocks:
        argv = shlex.split(command)
        assert argv[:2] == ["pccl", "run"] and argv[-2:] == ["--seed", seed]
        run = cli(*argv[1:])
        if label.startswith("stuck"):
            assert run.exit_code == 1
            assert f"result: violation — {example}" in run.output
        else:
            # a stalled run (nondet may fail a robot whose lane meets
            # another's, and the race programs then wait forever) exits 1
            assert run.exit_code == (1 if label == "stalled" else 0)
            assert f"result: {label} —" in run.output
    assert ("completion time (" in out) == any(b[0] == "final" for b in blocks)


def test_simulate_json_and_first_seed():
    res = cli(*ARGS[:-1], "20", "--seed", "100", "--format", "json")
    data = json.loads(res.output)
    assert sum(o["count"] for o in data["outcomes"]) == 20
    assert all(100 <= o["first_seed"] < 120 for o in data["outcomes"])
    assert all(o["command"].endswith(f"--seed {o['first_seed']}") for o in data["outcomes"])
    assert data["exit_status"] == res.exit_code


def test_simulate_clean_program_exits_0():
    res = cli("simulate", "programs/race_safe.pccl", "--world", "programs/race.toml", "--runs", "5")
    assert res.exit_code == 0 and "final: 5 runs (100.0%, 95% CI" in res.output
    assert "violations: none in 5 runs" in res.output


def test_each_simulated_run_is_the_run_of_its_seed():
    import random
    from pccl.api import make_model, run
    from pccl.tools.simulate import simulate
    prog, world = str(ROOT / "programs/race_nonatomic.pccl"), str(ROOT / "programs/race.toml")
    rng = random.Random(0)
    model = make_model(prog, world=world, blackbox="nondet", agents=3, rng=rng, max_time=100,
                       abstract_time=False)
    got = {}
    simulate(model, rng, runs=60, seed=0,
             on_run=lambda k, r: got.__setitem__(k, (r.status, r.message, r.final[TIME], r.steps)))
    for k in range(60):
        r = run(prog, world=world, blackbox="nondet", agents=3, seed=k)
        assert got[k] == (r.status, r.message, r.final[TIME], r.steps), k


def test_a_bad_option_names_the_flag():
    """simulate builds its model from the options of pccl run: a rate above
    n0 is reported against --rate, as pccl run reports it."""
    res = cli("simulate", "programs/fischer.pccl", "--runs", "2", "--rate", "1=2")
    run = cli("run", "programs/fischer.pccl", "--rate", "1=2")
    assert res.exit_code == run.exit_code == 2
    assert res.output.strip().startswith("--rate: error: rate 2 of agent 1 is above n0 = 1")
    assert res.output.strip() == run.output.strip()


# ---------------------------------------------------------------------------
# issue 27, item 1: simulate checks properties, and its commands reproduce
# ---------------------------------------------------------------------------

FISCHER = ["simulate", "programs/fischer.pccl", "--set", "k=1", "--runs", "30",
           "--invariant", "count(inCs) <= 1"]
_OUTCOME = re.compile(r"^  (.+?): (\d+) runs? \(.*\n(?:    e\.g\. (.*)\n)?"
                      r"    first seed (\d+): (.*)$", re.M)


def test_simulate_checks_an_invariant_and_every_printed_command_reproduces():
    """Fischer's mutual exclusion fails on some runs: simulate must say so
    (it used to report 30 bounded runs and exit 0), and each printed
    ``pccl run`` command (no ``-b ''`` without -b) must give that outcome."""
    res = cli(*FISCHER)
    assert res.exit_code == 1, res.output
    out = res.output
    assert "checked on every run: 'count(inCs) <= 1'" in out
    blocks = _OUTCOME.findall(out)
    assert sum(int(b[1]) for b in blocks) == 30
    assert any(b[0].startswith("invariant") for b in blocks)
    for label, _count, example, seed, command in blocks:
        argv = shlex.split(command)
        assert "-b" not in argv and "''" not in command
        assert argv[:2] == ["pccl", "run"] and argv[-2:] == ["--seed", seed]
        run = cli(*argv[1:])
        if label.startswith("invariant"):
            assert run.exit_code == 1, command
            assert f"result: violation — {example}" in run.output
        else:
            assert run.exit_code == 0 and f"result: {label} —" in run.output, command


def test_simulate_program_invariant_section_and_first_trace():
    """The program's own invariant: section is checked on every run, and the
    first violating run's trace is printed; it is the trace of pccl run."""
    args = ["simulate", "tests/programs/fast_slow.pccl", "--agents", "2", "--runs", "5"]
    res = cli(*args)
    assert res.exit_code == 1
    assert "checked on every run: safe '!bad[0]'" in res.output
    m = re.search(r"^first violating run \(seed (\d+)\): violation — invariant 'safe' violated\n"
                  r"trace \((\d+) steps", res.output, re.M)
    assert m, res.output
    run = cli("run", "tests/programs/fast_slow.pccl", "--agents", "2", "--seed", m[1], "--trace")
    run_steps = re.findall(r"^ +\d+\. t=.*$", run.output, re.M)
    sim_steps = re.findall(r"^ +\d+\. t=.*$", res.output, re.M)
    assert int(m[2]) == len(run_steps) > 10
    assert sim_steps == run_steps[-10:]                # the last 10 steps
    full = cli(*args, "--trace")
    assert re.findall(r"^ +\d+\. t=.*$", full.output, re.M) == run_steps


def test_simulate_trace_out_replays(tmp_path):
    out = tmp_path / "first.json"
    res = cli(*FISCHER, "--trace-out", out)
    assert res.exit_code == 1 and out.exists()
    rep = cli("replay", out)
    assert rep.exit_code == 1, rep.output       # reproduces the violation
    assert "count(inCs) <= 1" in rep.output


def test_simulate_property_is_checked():
    res = cli("simulate", "programs/fischer.pccl", "--set", "k=1", "--runs", "10",
              "--property", "count(inCs) <= 1")
    assert res.exit_code == 1
    assert "count(inCs) <= 1" in res.output.split("outcomes:")[1].split("first seed")[0]
    # the printed command carries the property
    assert "--property 'count(inCs) <= 1'" in res.output


def test_simulate_runs_flag_and_deprecated_n():
    new = cli("simulate", "programs/race_safe.pccl", "--world", "programs/race.toml", "--runs", "3")
    old = cli("simulate", "programs/race_safe.pccl", "--world", "programs/race.toml", "-n", "3")
    assert new.exit_code == old.exit_code == 0
    assert "3 runs (seeds 0–2)" in new.output and "deprecated" not in new.output
    assert "-n is deprecated" in old.output and "use --runs" in old.output
    both = cli("simulate", "programs/race_safe.pccl", "--runs", "3", "-n", "3")
    assert both.exit_code == 2 and "Traceback" not in both.output


def test_wilson_interval():
    from pccl.tools.simulate import wilson
    lo, hi = wilson(0, 10)
    assert lo == 0 and abs(hi - 0.2775) < 1e-3          # the textbook value
    lo, hi = wilson(5, 10)
    assert abs(lo - 0.2366) < 1e-3 and abs(hi - 0.7634) < 1e-3
    # symmetric: k successes is n - k failures
    assert all(abs(a + b - 1) < 1e-12
               for a, b in zip(wilson(3, 17), reversed(wilson(14, 17))))


def test_simulate_json_statistics():
    data = json.loads(cli(*FISCHER, "--format", "json").output)
    v = data["violations"]
    bad = [o for o in data["outcomes"] if o["violation"]]
    assert v["count"] == sum(o["count"] for o in bad) > 0
    assert v["ci95"][0] <= v["frequency"] <= v["ci95"][1]
    times = v["time_to_violation"]
    assert times["min"] <= times["median"] <= times["max"]
    assert data["invariants"] == ["count(inCs) <= 1"]
