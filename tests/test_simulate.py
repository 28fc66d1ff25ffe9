"""pccl simulate: outcome counts, and the pccl run command printed for each
outcome reproduces it."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path


from pccl.layout import TIME
import conftest

ROOT = Path(__file__).resolve().parent.parent
ARGS = ["simulate", "programs/race_nonatomic.pccl", "--world", "programs/race.toml", "-b", "nondet",
        "--agents", "3", "-n", "200"]


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
    res = cli("simulate", "programs/race_safe.pccl", "--world", "programs/race.toml", "-n", "5")
    assert res.exit_code == 0 and "final: 5 runs (100.0%)" in res.output


def test_each_simulated_run_is_the_run_of_its_seed():
    import random
    from pccl.api import make_model, run
    from pccl.simulate import simulate
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
    res = cli("simulate", "programs/fischer.pccl", "-n", "2", "--rate", "1=2")
    run = cli("run", "programs/fischer.pccl", "--rate", "1=2")
    assert res.exit_code == run.exit_code == 2
    assert res.output.strip().startswith("--rate: error: rate 2 of agent 1 is above n0 = 1")
    assert res.output.strip() == run.output.strip()
