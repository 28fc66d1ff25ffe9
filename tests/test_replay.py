"""pccl replay: reproduces violations and clean runs; names the first divergence."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from conftest import cli

ROOT = Path(__file__).resolve().parent.parent
PROGRAMS = ROOT / "programs"
LOST = ROOT / "docs" / "examples" / "lost_update.pccl"


def record(tmp_path, *args, name="t.json"):
    out = tmp_path / name
    cli(*args, "--trace-out", out)
    return out


def test_replay_reproduces_a_counterexample(tmp_path):
    t = record(tmp_path, "explore", PROGRAMS / "fischer.pccl", "--invariant", "count(inCs) <= 1",
               "--set", "k=1")
    n = len(json.loads(t.read_text())["steps"])
    assert n >= 130             # the globally shortest (--reduce none) has 130
    res = cli("replay", t)
    assert res.exit_code == 1, res.output
    assert f"replayed {n} of {n} steps" in res.output
    assert "reproduced: invariant 'count(inCs) <= 1' violated" in res.output
    assert "warning" not in res.output


def test_a_property_option_violation_is_recorded_and_reproduced(tmp_path):
    # --property texts travel in the trace (property_options) so that replay
    # checks them again; the reductions the search ran with are recorded too
    t = record(tmp_path, "explore", PROGRAMS / "fischer.pccl", "--property", "count(inCs) <= 1",
               "--set", "k=1")
    doc = json.loads(t.read_text())
    assert doc["config"]["property_options"] == ["count(inCs) <= 1"]
    assert doc["config"]["invariants"] == []
    assert doc["config"]["reductions"] == ["merge", "symmetry", "por"]
    n = len(doc["steps"])
    res = cli("replay", t)
    assert res.exit_code == 1, res.output
    assert f"replayed {n} of {n} steps" in res.output
    assert "reproduced: invariant 'count(inCs) <= 1' violated" in res.output
    t = record(tmp_path, "explore", PROGRAMS / "fischer.pccl", "--property", "count(inCs) <= 1",
               "--set", "k=1", "--reduce", "none", name="none.json")
    assert json.loads(t.read_text())["config"]["reductions"] == []
    # a file written before these fields existed still replays (they are optional)
    old = json.loads(t.read_text())
    del old["config"]["property_options"], old["config"]["reductions"]
    old["config"]["invariants"] = ["count(inCs) <= 1"]
    (tmp_path / "old.json").write_text(json.dumps(old))
    res = cli("replay", tmp_path / "old.json")
    assert res.exit_code == 1 and "reproduced:" in res.output, res.output


def test_a_reduced_counterexample_replays_step_by_step(tmp_path):
    # under the default reductions the trace file holds the expanded,
    # unreduced steps: replay re-executes each of them
    t = record(tmp_path, "explore", LOST, "--reduce", "auto", name="auto.json")
    n = len(json.loads(t.read_text())["steps"])
    full = record(tmp_path, "explore", LOST, "--reduce", "none", name="none.json")
    assert n >= len(json.loads(full.read_text())["steps"])
    res = cli("replay", t)
    assert res.exit_code == 1, res.output
    assert f"replayed {n} of {n} steps" in res.output
    assert "reproduced: invariant 'noLostUpdate' violated" in res.output


def test_replay_reproduces_a_clean_run(tmp_path):
    t = record(tmp_path, "run", PROGRAMS / "race.pccl", "--world", PROGRAMS / "race.toml",
               "-b", "instant", "--seed", "3")
    res = cli("replay", t)
    assert res.exit_code == 0, res.output
    assert "reproduced: final" in res.output


def test_replay_reproduces_a_stuck_run_with_rand_and_nondet(tmp_path):
    t = record(tmp_path, "run", PROGRAMS / "race_nonatomic.pccl", "--world", PROGRAMS / "race.toml",
               "-b", "nondet", "--agents", "3", "--seed", "5")
    res = cli("replay", t)
    assert res.exit_code == 1, res.output
    assert "stuck" in res.output


def test_edited_program_warns_and_names_the_diverging_step(tmp_path):
    prog = tmp_path / "lost.pccl"
    shutil.copy(LOST, prog)
    t = record(tmp_path, "explore", prog, "--reduce", "none")
    prog.write_text(prog.read_text().replace("total = mine + 1;", "total = mine + 2;"))
    res = cli("replay", t)
    assert res.exit_code == 2, res.output
    assert "has changed since the trace was recorded" in res.output
    assert "diverged at step 3 of 20 (agent 0 STATEMENT [Add] line 16" in res.output
    assert "the program differs here: line 16 now reads 'total = mine + 2;'" in res.output


def test_tampered_changes_are_named(tmp_path):
    t = record(tmp_path, "explore", LOST, "--reduce", "none")
    d = json.loads(t.read_text())
    d["steps"][2]["changes"][0]["new"] = 5
    t.write_text(json.dumps(d))
    res = cli("replay", t)
    assert res.exit_code == 2 and "diverged at step 3 of 20" in res.output
    assert "recorded total 0 -> 5; replayed total 0 -> 1" in res.output


def test_shifted_program_reports_a_transition_not_enabled(tmp_path):
    prog = tmp_path / "lost.pccl"
    shutil.copy(LOST, prog)
    t = record(tmp_path, "explore", prog, "--reduce", "none")
    prog.write_text(prog.read_text().replace("    mine = total;", "    skip;\n    mine = total;"))
    res = cli("replay", t)
    assert res.exit_code == 2
    assert "diverged at step 2 of 20" in res.output
    assert "line 15 now reads 'skip;'" in res.output


def test_tampered_initial_state_diverges_at_the_start(tmp_path):
    t = record(tmp_path, "explore", LOST, "--reduce", "none")
    d = json.loads(t.read_text())
    d["initial"]["shared"]["total"] = 7
    t.write_text(json.dumps(d))
    res = cli("replay", t)
    assert res.exit_code == 2
    assert "diverged at the initial state" in res.output and "shared.total" in res.output


def test_replay_accepts_json_output_and_refuses_other_files(tmp_path):
    out = cli("explore", LOST, "--format", "json").output
    (tmp_path / "o.json").write_text(out)
    assert cli("replay", tmp_path / "o.json").exit_code == 1
    (tmp_path / "bad.json").write_text("{}")
    res = cli("replay", tmp_path / "bad.json")
    assert res.exit_code == 2 and "not a pccl trace file" in res.output
    res = cli("replay", tmp_path / "missing.json")
    assert res.exit_code == 2


def test_replay_plot(tmp_path):
    t = record(tmp_path, "explore", LOST, "--reduce", "none")
    res = cli("replay", t, "--plot", tmp_path / "p.png")
    assert res.exit_code == 1 and (tmp_path / "p.png").stat().st_size > 0


def test_a_step_that_is_not_enabled_lists_the_enabled_ones(tmp_path):
    t = record(tmp_path, "explore", LOST, "--reduce", "none")
    d = json.loads(t.read_text())
    d["steps"][0]["rule"] = "IDLE"
    t.write_text(json.dumps(d))
    res = cli("replay", t)
    assert res.exit_code == 2
    assert "diverged at step 1 of 20 (agent 0 IDLE [Add] line 13" in res.output
    assert "that transition is not enabled; enabled here: agent 0 EVENT SELECT [Add]" in res.output
