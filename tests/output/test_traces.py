"""Trace files (--trace-out, "trace" in --format json): the schema, the
configuration recorded, typed values, branches."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest

from conftest import cli

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "programs"
FISCHER = PROGRAMS / "fischer.pccl"
RACE = PROGRAMS / "race.pccl"
RACE_NA = PROGRAMS / "race_nonatomic.pccl"
RACE_WORLD = PROGRAMS / "race.toml"
SCHEMA = json.loads((ROOT / "docs" / "trace-format.schema.json").read_text())
FISCHER_ARGS = ["explore", str(FISCHER), "--invariant", "count(inCs) <= 1", "--set", "k=1"]




def validate(doc):
    jsonschema.validate(doc, SCHEMA, cls=jsonschema.Draft202012Validator)


@pytest.fixture(scope="module")
def fischer_trace(tmp_path_factory):
    out = tmp_path_factory.mktemp("t") / "fischer.json"
    res = cli(*FISCHER_ARGS, "--trace-out", out)
    assert res.exit_code == 1
    assert f"trace written to {out}" in res.output
    return json.loads(out.read_text())


def test_schema_is_valid():
    jsonschema.Draft202012Validator.check_schema(SCHEMA)


def test_explore_trace_validates_and_records_configuration(fischer_trace):
    d = fischer_trace
    validate(d)
    c = d["config"]
    assert c["command"] == "explore" and c["program"]["path"].endswith("fischer.pccl")
    assert len(c["program"]["sha256"]) == 64
    assert c["overrides"] == {"k": "1"} and c["invariants"] == ["count(inCs) <= 1"]
    assert c["agents"] == 2 and c["delta"] == 1 and c["n0"] == 1 and c["rates"] == [1, 1]
    assert c["blackbox"] == "straight" and c["world"] is None and c["pccl_version"]
    assert d["result"]["status"] == "violation"
    assert d["result"]["violation"]["kind"] == "invariant"
    # reduced by default: at least the globally shortest 130 steps (--reduce
    # none), every one an unreduced step with its own index
    assert len(d["steps"]) >= 130
    assert [st["index"] for st in d["steps"]] == list(range(1, len(d["steps"]) + 1))


def test_typed_values_and_cell_paths(fischer_trace):
    d = fischer_trace
    a0 = d["initial"]["agents"][0]
    assert a0["variables"]["inCs"] is False and isinstance(a0["variables"]["waitTime"], int)
    assert a0["position"] == [0.0, 0.0, 0.0]
    assert d["initial"]["shared"] == {"reqid": -1, "k": 1, "d": 2}
    last = d["steps"][-1]
    # version 2 records the pending computation k as a change too (the
    # statement ids left to run): the last statement of the event block ran
    assert last["changes"] == [{"cell": {"agent": 0, "var": "inCs"}, "old": False, "new": True},
                               {"cell": {"agent": 0, "cell": "k"}, "old": [20, "end"],
                                "new": ["end"]}]
    assert (last["line"], last["column"], last["rule"]) == (68, 9, "STATEMENT")
    times = [ch for s in d["steps"] for ch in s["changes"] if ch["cell"] == {"cell": "time"}]
    assert times and all(isinstance(ch["new"], int) for ch in times)


def test_if_steps_name_the_branch(fischer_trace):
    ifs = [s for s in fischer_trace["steps"] if s["source"] and s["source"].startswith("if")]
    assert ifs and all(s["branch"]["kind"] == "if" for s in ifs)
    assert ifs[0]["branch"]["taken"] == "else" and ifs[0]["branch"]["line"] == 35
    others = [s for s in fischer_trace["steps"] if s["rule"] != "STATEMENT"]
    assert all(s["branch"] is None for s in others)


def test_explore_json_carries_the_trace():
    res = cli(*FISCHER_ARGS, "--format", "json")
    data = json.loads(res.output)
    validate(data["trace"])
    assert data["trace"]["steps"] == data["violations"][0]["trace"]["steps"]


def test_explore_without_violation_writes_an_empty_trace(tmp_path):
    out = tmp_path / "clean.json"
    res = cli("explore", PROGRAMS / "race_safe.pccl", "--world", RACE_WORLD, "-b", "instant",
              "--trace-out", out)
    assert res.exit_code == 0
    d = json.loads(out.read_text())
    validate(d)
    assert d["steps"] == [] and d["initial"] is None and d["result"]["status"] == "exhaustive"


def test_run_trace_records_seed_world_and_stuck_agent(tmp_path):
    out = tmp_path / "run.json"
    res = cli("run", RACE_NA, "--world", RACE_WORLD, "-b", "nondet", "--agents", "3",
              "--seed", "5", "--trace-out", out)
    d = json.loads(out.read_text())
    validate(d)
    c = d["config"]
    assert c["command"] == "run" and c["seed"] == 5 and c["world"]["sha256"]
    assert c["blackbox"] == "nondet" and c["agents"] == 3
    assert d["result"]["status"] in ("final", "violation", "deadlock")
    assert res.exit_code == (1 if d["result"]["violation"] else 0)
    pos = [s for s in d["steps"] for ch in s["changes"] if ch["cell"].get("cell") == "position"]
    assert pos and d["steps"][0]["index"] == 1
    dests = d["initial"]["shared"]["dests"]
    assert all(isinstance(p, list) and len(p) == 3 for p in dests)


def test_run_json_carries_the_trace():
    res = cli("run", RACE, "--world", RACE_WORLD, "--format", "json", "--seed", "4")
    data = json.loads(res.output)
    validate(data["trace"])
    assert data["trace"]["config"]["seed"] == 4


def test_enum_values_are_member_names(tmp_path):
    prog = tmp_path / "e.pccl"
    prog.write_text("loc:\n  enum Stage { PICK, GO };\n  Stage s = PICK;\n  int u;\n\n"
                    "Go():\n  pre(s == PICK);\n  eff:\n    s = GO;\n    exit();\n")
    out = tmp_path / "e.json"
    res = cli("run", prog, "--trace-out", out)
    assert res.exit_code == 0, res.output
    d = json.loads(out.read_text())
    validate(d)
    assert d["initial"]["agents"][0]["variables"] == {"s": "PICK", "u": None}
    ch = [c for s in d["steps"] for c in s["changes"] if c["cell"].get("var") == "s"]
    assert ch[0] == {"cell": {"agent": ch[0]["cell"]["agent"], "var": "s"}, "old": "PICK", "new": "GO"}


def test_trace_out_unwritable_is_refused_before_the_search(tmp_path):
    res = cli(*FISCHER_ARGS, "--trace-out", tmp_path / "nodir" / "x.json")
    assert res.exit_code == 2 and "--trace-out" in res.output


def test_a_reachable_witness_is_the_trace_of_an_explore_without_violation(tmp_path):
    # it used to be an empty trace: a 'reachable P' trace now carries its
    # verdict, the witness path and the property (result.witness)
    out = tmp_path / "w.json"
    res = cli("explore", FISCHER, "--set", "k=0", "--property", "reachable count(inCs) == 1",
              "--trace-out", out)
    assert res.exit_code == 0
    d = json.loads(out.read_text())
    validate(d)
    assert d["result"]["status"] == "exhaustive" and d["result"]["violation"] is None
    assert d["result"]["witness"]["text"] == "reachable count(inCs) == 1"
    assert d["steps"] and d["final"]["agents"][0]["variables"]["inCs"] != \
        d["final"]["agents"][1]["variables"]["inCs"]


def test_a_run_trace_records_stall_steps(tmp_path):
    out = tmp_path / "r.json"
    cli("run", RACE, "--world", RACE_WORLD, "--seed", "1", "--stall-steps", "7",
        "--trace-out", out)
    d = json.loads(out.read_text())
    validate(d)
    assert d["config"]["stall_steps"] == 7


def test_trace_format_doc_lists_every_violation_kind():
    """Issue 27: the documented kinds are the ones pccl/output/tracecheck.py accepts."""
    import re
    from pathlib import Path
    from pccl.output.tracecheck import VIOLATION_KINDS
    doc = (Path(__file__).resolve().parents[2] / "docs" / "trace-format.md").read_text()
    row = next(ln for ln in doc.splitlines() if ln.startswith("| `result` |"))
    part = row.split("its `kind` is", 1)[1]
    listed = set(re.findall(r"`([a-z]+)`", part))
    assert set(VIOLATION_KINDS) <= listed, set(VIOLATION_KINDS) - listed
