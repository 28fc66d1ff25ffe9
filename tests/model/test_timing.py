"""The timing a verdict covers (issue 44.1): lock-step rounds under n0 = 1
are said in the clean verdict and in ``checked``, with the option that
explores agents running ahead."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from pccl.api import explore
from pccl.cli import main

ROOT = Path(__file__).resolve().parents[2]
PETERSON = ROOT / "tests" / "programs" / "peterson_swapped.pccl"
MUTEX = "count(inCs) <= 1"


def test_the_textbook_peterson_bug_is_clean_under_lockstep_and_says_so():
    r = explore(str(PETERSON), invariants=[MUTEX])
    assert r.status == "exhaustive"
    assert "lock-step rounds, n0 = 1" in r.verdict and "n0=2 also explores" in r.verdict
    assert "event Enter (line 17)" in r.verdict
    assert r.checked["timing"].startswith("lock-step rounds (n0 = 1)")


def test_the_option_the_verdict_names_finds_the_bug():
    r = explore(str(PETERSON), invariants=[MUTEX], n0=2)
    assert r.status == "violation" and r.violation.kind == "invariant"
    assert "lock-step" not in r.verdict
    assert r.checked["timing"].startswith("n0 = 2: every agent runs up to 2 event blocks")


def test_the_cli_spells_the_option_and_prints_the_timing_line():
    res = CliRunner().invoke(main, ["explore", str(PETERSON), "--invariant", MUTEX,
                                    "--no-progress"])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert "--n0 2 also explores an agent running a second block" in lines[1]
    assert "  timing: lock-step rounds (n0 = 1): every agent runs one event block per time step" \
        in lines


@pytest.mark.parametrize("text, agents", [
    # one agent: nobody to run ahead of
    ("allwrite:\n  int s = 0;\nE():\n  pre(true);\n  eff:\n    s = s + 1;\n    exit();\n", 1),
    # no shared variable: the agents cannot observe each other
    ("loc:\n  int s = 0;\nE():\n  pre(true);\n  eff:\n    s = s + 1;\n    exit();\n", 2),
])
def test_no_note_where_the_rounds_cannot_matter(text, agents):
    r = explore(text, source=True, agents=agents)
    assert r.status == "exhaustive" and "lock-step" not in r.verdict


def test_rates_are_said_per_agent():
    r = explore(str(PETERSON), invariants=[MUTEX], n0=2, rates={1: 2})
    assert r.checked["timing"] == ("n0 = 2 with rates: event blocks per time step agent 0 2, "
                                   "agent 1 1, their statements interleaved")
