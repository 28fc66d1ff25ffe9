"""pccl graph: DOT that Graphviz parses (checked with pydot), JSON with the same graph."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pydot
import pytest

from conftest import cli

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

ROOT = Path(__file__).resolve().parents[2]
LOST = ROOT / "docs" / "examples" / "lost_update.pccl"
NEVER = ROOT / "docs" / "examples" / "never.pccl"




def state_nodes(g) -> list:
    out = [n for n in g.get_nodes() if re.fullmatch(r"s\d+", n.get_name())]
    for sub in g.get_subgraphs():
        out += state_nodes(sub)
    return out


def test_dot_parses_and_marks_violating_states(tmp_path):
    out = tmp_path / "g.dot"
    res = cli("graph", LOST, "-o", out)
    assert res.exit_code == 1            # some states violate noLostUpdate
    m = re.search(r"(\d+) states, (\d+) transitions, (\d+) violating \(complete\)", res.output)
    states, transitions, bad = map(int, m.groups())
    (g,) = pydot.graph_from_dot_data(out.read_text())
    nodes = state_nodes(g)
    assert len(nodes) == states
    assert len(g.get_edges()) == transitions
    red = [n for n in nodes if n.get("color") == '"red"']
    assert len(red) == bad > 0
    assert all("noLostUpdate" in n.get("label") for n in red)
    assert any(n.get("peripheries") == "2" for n in nodes)
    assert any(s.get_name().startswith("cluster_t") for s in g.get_subgraphs())
    if shutil.which("dot"):
        subprocess.run(["dot", "-Tsvg", str(out), "-o", str(tmp_path / "g.svg")], check=True)


def test_json_graph_and_max_states(tmp_path):
    out = tmp_path / "g.json"
    res = cli("graph", NEVER, "-o", out, "--max-states", "20")
    assert res.exit_code == 0 and "truncated at --max-states 20" in res.output
    d = json.loads(out.read_text())
    assert d["format"] == "pccl-graph" and d["truncated"] and d["states"] == len(d["nodes"]) == 20
    assert all(0 <= e["from"] < 20 and 0 <= e["to"] < 20 for e in d["edges"])
    assert d["nodes"][0]["initial"] and d["nodes"][0]["state"]["agents"][0]["variables"] == {"n": 0}
    assert {"rule", "agent", "changes"} <= set(d["edges"][0])
    full = tmp_path / "full.json"
    cli("graph", NEVER, "-o", full)
    d = json.loads(full.read_text())
    assert not d["truncated"] and d["states"] == 87     # as many as explore finds
    assert any(n["terminal"] == "final" for n in d["nodes"])


def test_unknown_extension_is_refused(tmp_path):
    res = cli("graph", LOST, "-o", tmp_path / "g.png")
    assert res.exit_code == 2 and "use a .dot, .gv or .json file" in res.output


def test_a_bad_option_names_the_flag(tmp_path):
    """graph builds its model from the command's options object: a value
    only the model can judge is reported against the flag (exit 2)."""
    res = cli("graph", LOST, "-o", tmp_path / "g.dot", "--rate", "7=2")
    assert res.exit_code == 2
    assert res.output.strip().startswith("--rate: error: agent 7 does not exist"), res.output
    assert not (tmp_path / "g.dot").exists()
