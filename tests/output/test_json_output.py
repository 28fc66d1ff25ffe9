"""One JSON vocabulary for run, explore, simulate and replay --format json.

Every output is validated against ``$defs/output`` of the one schema
(docs/trace-format.schema.json); they share the top level (format, version,
command, status, message, exit_status, trace) and write states, steps and
paths one way: the trace format's (pccl/output/codec.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest
from referencing import Registry, Resource

from conftest import cli

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "programs"
TESTS = ROOT / "tests" / "programs"
LOST = ROOT / "docs" / "examples" / "lost_update.pccl"
SCHEMA = json.loads((ROOT / "docs" / "trace-format.schema.json").read_text())
_REGISTRY = Registry().with_resource(SCHEMA["$id"], Resource.from_contents(SCHEMA))
OUTPUT = jsonschema.Draft202012Validator({"$ref": SCHEMA["$id"] + "#/$defs/output"},
                                         registry=_REGISTRY)
TOP = ("format", "version", "command", "status", "message", "exit_status")


def run_json(*args) -> dict:
    res = cli(*args, "--format", "json")
    data = json.loads(res.stdout)
    OUTPUT.validate(data)
    assert res.exit_code == data["exit_status"], res.output
    assert list(data)[:len(TOP)] == list(TOP) and list(data)[-1] == "trace"
    assert data["command"] == args[0]
    return data


CASES = {
    "run clean": ("run", PROGRAMS / "race.pccl", "--world", PROGRAMS / "race.toml", "-b",
                  "instant", "--seed", "3"),
    "run stuck": ("run", PROGRAMS / "race_nonatomic.pccl", "--world", PROGRAMS / "race.toml",
                  "-b", "nondet", "--agents", "3", "--seed", "5"),
    "explore violation": ("explore", LOST, "--reduce", "none"),
    "explore clean": ("explore", PROGRAMS / "race_safe.pccl", "--world", PROGRAMS / "race.toml",
                      "-b", "instant"),
    "explore witness": ("explore", PROGRAMS / "fischer.pccl", "--set", "k=0", "--property",
                        "reachable count(inCs) == 1"),
    "explore lasso": ("explore", TESTS / "rdv_meet.pccl", "--world", TESTS / "rdv_wall.toml",
                      "-b", "straight", "--property", "eventually forall i: exited[i]"),
    "simulate violation": ("simulate", PROGRAMS / "fischer.pccl", "--set", "k=1", "--invariant",
                           "count(inCs) <= 1", "--runs", "4"),
    "simulate clean": ("simulate", PROGRAMS / "race.pccl", "--world", PROGRAMS / "race.toml",
                       "-b", "instant", "--runs", "3"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_every_output_is_valid_and_its_trace_replays(case, tmp_path):
    data = run_json(*CASES[case])
    if data["trace"] is None:
        assert case == "simulate clean"
        return
    assert data["trace"]["version"] == data["version"] == 2
    out = tmp_path / "out.json"
    out.write_text(json.dumps(data))
    replayed = run_json("replay", out)
    if data["trace"]["initial"] is None:        # explore found nothing: no path to replay
        assert replayed["status"] == "empty" and replayed["trace"] is None
        return
    assert replayed["status"] in ("violation", "clean", "witness"), replayed["message"]
    assert replayed["exit_status"] == (1 if data["exit_status"] == 1 else 0)
    # the replay writes the same trace again: the codec encodes the decoded states
    assert replayed["trace"]["steps"] == data["trace"]["steps"]
    assert replayed["trace"]["initial"] == data["trace"]["initial"]
    assert replayed["trace"]["final"] == data["trace"]["final"]


def test_explore_writes_a_counterexample_one_way():
    # the finding's path and the trace document: two routes (the API's views,
    # the trace document) to one encoding of the same counterexample
    data = run_json(*CASES["explore violation"])
    path, doc = data["violations"][0]["trace"], data["trace"]
    assert path == {"initial": doc["initial"], "steps": doc["steps"], "final": doc["final"]}
    w = run_json(*CASES["explore witness"])
    assert w["witnesses"][0]["trace"]["steps"] == w["trace"]["steps"]


def test_run_final_is_the_trace_documents_final():
    data = run_json(*CASES["run stuck"])
    assert data["final"] == data["trace"]["final"]
    assert data["status"] == data["trace"]["result"]["status"] == "violation"


def test_replay_json_of_a_divergence_and_of_an_old_file(tmp_path):
    d = json.loads(cli("explore", LOST, "--reduce", "none", "--format", "json").stdout)["trace"]
    d["steps"][2]["changes"][0]["new"] = 5
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    data = run_json("replay", bad)
    assert (data["status"], data["exit_status"], data["diverged_at"]) == ("diverged", 2, 3)
    assert data["trace"] is None and data["steps_replayed"] == 2
    old = run_json("replay", ROOT / "tests" / "fixtures" / "traces_v1" / "race_run_clean.json")
    assert old["recorded_version"] == 1 and old["trace"]["version"] == 2
    assert old["status"] == "clean" and old["steps_replayed"] == old["steps_total"] == 108


@pytest.mark.parametrize("extra, complete", [((), True), (("--max-states", "100"), False)])
def test_all_says_whether_the_search_explored_everything(extra, complete):
    # --all: violations found, and the verdict (text and JSON) says whether the
    # search went on to the end or a bound stopped it
    args = ("explore", PROGRAMS / "fischer.pccl", "--set", "k=1", "--invariant",
            "count(inCs) <= 1", "--all", *extra)
    data = run_json(*args)
    assert data["status"] in ("violation", "bounded")
    assert data["exhaustive"] is complete
    text = cli(*args, "--no-progress").stdout.splitlines()[1]
    if complete:
        assert data["status"] == "violation"
        assert "search complete: every reachable state explored" in text
    else:
        assert "not exhaustive" in text or "stopped by --max-states 100" in text
        assert "search complete" not in text
