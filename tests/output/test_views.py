"""--view steps|swimlane in explore, run and replay."""

from __future__ import annotations

from pathlib import Path


import conftest

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "programs"
FISCHER = ["explore", str(PROGRAMS / "fischer.pccl"), "--reduce", "none",
           "--invariant", "count(inCs) <= 1",
           "--set", "k=1"]


def cli(*args, columns=100):
    return conftest.cli(*args, env={"COLUMNS": str(columns)})


def trace_block(text: str) -> list:
    lines = text.splitlines()
    a = next(k for k, ln in enumerate(lines) if ln.startswith("counterexample ("))
    b = next(k for k, ln in enumerate(lines) if ln.startswith("violating state:"))
    return lines[a + 1:b]


def test_swimlane_fits_100_columns_and_shows_both_agents_entering():
    res = cli(*FISCHER, "--view", "swimlane")
    assert res.exit_code == 1
    block = trace_block(res.output)
    assert max(len(ln) for ln in block) <= 100
    assert block[0].split("│")[0].strip() == "agent 0" and "agent 1" in block[0]
    assert "shared" in block[0]
    cols = [ln.split("│") for ln in block if ln.count("│") == 2]
    assert any("inCs=true" in c[0] for c in cols)      # agent 0 enters
    assert any("inCs=true" in c[1] for c in cols)      # agent 1 enters
    assert any("reqid=0" in c[2] for c in cols)        # shared variables beside
    assert any(ln.startswith("── t=10 ") for ln in block)
    assert any("waitTime=0" in ln for ln in block[:8])


def test_swimlane_follows_the_terminal_width():
    block = trace_block(cli(*FISCHER, "--view", "swimlane", columns=60).output)
    assert max(len(ln) for ln in block) <= 60
    wide = trace_block(cli(*FISCHER, "--view", "swimlane", columns=160).output)
    assert len(wide) < len(block)


def test_steps_view_starts_with_the_initial_state_and_names_branches():
    res = cli(*FISCHER, "--view", "steps")
    block = trace_block(res.output)
    assert block[0] == "initial state:"
    assert sum("waitTime = 0" in ln for ln in block[1:7]) == 2     # each agent's draw
    assert any("line 32: if (reqid != -1):  → else (line 35)" in ln for ln in block)
    assert any("no change: a0 COUNTER ADVANCE, a1 EVENT SELECT Start" in ln for ln in block)
    full = trace_block(cli(*FISCHER, "--view", "steps", "--full").output)
    assert not any("no change:" in ln for ln in full)
    assert sum(1 for ln in full if ln[:5].strip().rstrip(".").isdigit()) == 130
    assert len(block) < len(full)


def test_views_in_run_and_replay(tmp_path):
    t = tmp_path / "t.json"
    res = cli("run", PROGRAMS / "race.pccl", "--world", PROGRAMS / "race.toml", "-b", "instant",
              "--seed", "3", "--view", "swimlane", "--trace-out", t)
    assert res.exit_code == 0
    assert "PickDest()" in res.output and "moves: pos=" in res.output
    res = cli("replay", t, "--view", "steps")
    assert res.exit_code == 0 and "initial state:" in res.output
    assert "→ else" in res.output or "→ then" in res.output
