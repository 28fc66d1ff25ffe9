"""Words users know (issue 44.6): no internal cell names in user output,
the cost of the Python engine said where it is the fall-back, and a stall
says how a finished team ends."""

from __future__ import annotations

import math
from pathlib import Path

from click.testing import CliRunner

from pccl.api import explore
from pccl.cli import main
from pccl.cli.cmd_explore import PYTHON_COST

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "programs"
DOCS = ROOT / "docs" / "examples"


def test_states_use_the_words_of_the_language_reference():
    # Fischer's violating state has an agent between the end of its block and
    # COUNTER ADVANCE (endEventBlock); a program whose atomic body ended has one
    # about to release the lock (atomicEnd)
    r = explore(str(PROGRAMS / "fischer.pccl"), overrides={"k": "1"},
                invariants=["count(inCs) <= 1"])
    text = "\n".join(str(s) for s in r.trace) + str(r.final_state)
    assert "endEventBlock" not in text and "atomicEnd" not in text
    descs = {r.model.compiled.describe_k(pc) for pc in range(len(r.model.ctl.cells))}
    assert "finishing its event block" in descs
    src = ("allwrite:\n  int x = 0;\nE():\n  pre(x == 0);\n  eff:\n    atomic:\n      x = 1;\n"
           "    exit();\n")
    r = explore(src, source=True, agents=1)
    descs = {r.model.compiled.describe_k(pc) for pc in range(len(r.model.ctl.cells))}
    assert "releasing the lock" in descs
    assert not any("End" in d for d in descs)


def test_the_python_fallback_says_what_it_costs():
    # --coverage counts guards in Python: one of the fall-backs that remain
    # (the tutorial's dock, this test's first program, runs natively now)
    res = CliRunner().invoke(main, ["explore", str(ROOT / "programs" / "fischer.pccl"), "--set",
                                    "k=0", "--coverage", "--no-progress"])
    header = res.output.splitlines()[0]
    assert f"engine python ({PYTHON_COST}" in header
    assert "interned" not in header


def test_the_python_fallbacks_cost_is_the_measured_one():
    # the header's figure is the range of docs/benchmarks.md's measured ratios
    # (native against Python on the programs that fell back before issue 43)
    text = (ROOT / "docs" / "benchmarks.md").read_text()
    table = text.split("*The programs that fell back before issue 43*", 1)[1].split("\n\n*", 1)[0]
    rows = [line.split("|") for line in table.splitlines() if line.startswith("| ")]
    head_row, body = rows[0], rows[1:]
    col = [c.strip() for c in head_row].index("native / Python")
    ratios = [float(r[col].strip().rstrip("x")) for r in body]
    assert len(ratios) >= 4
    lo, hi = math.floor(min(ratios)), math.ceil(max(ratios))
    assert PYTHON_COST.startswith(f"{lo}-{hi}x slower than the native engine"), (PYTHON_COST, ratios)
    assert "docs/benchmarks.md" in PYTHON_COST and "about 50x" not in PYTHON_COST


def test_a_stall_says_how_a_finished_team_ends():
    res = CliRunner().invoke(main, ["explore", str(PROGRAMS / "race_safe.pccl"), "--world",
                                    str(PROGRAMS / "race.toml"), "--no-progress"])
    assert res.exit_code == 1 and "violation: stall" in res.output
    assert ("note: a stall is also how a team ends whose agents are simply done: end each "
            "finished agent with `exit()`, or turn the check off with --no-stall") in res.output


COUNTER = """allwrite:
  int ticks = 0;
loc:
  int n = 0;
Tick():
  pre(true);
  eff:
    n = n + 1;
    if (n % 3 == 0):
      ticks = ticks + 1;
"""


def test_a_search_that_grows_without_bound_names_the_variable():
    for engine in ("native", "python"):
        r = explore(COUNTER, source=True, max_states=2000, engine=engine)
        assert r.status == "bounded"
        assert any(n.startswith("the search grows without bound: `n` of agent 0 went from 0 to ")
                   for n in r.notes), (engine, r.notes)
    r = explore(COUNTER, source=True, depth=30)
    assert any("`n` of agent 0" in n for n in r.notes)


def test_a_counter_bounded_by_the_program_gets_no_hint():
    # Fischer's counters stay within k (the program names its bound)
    r = explore(str(PROGRAMS / "fischer.pccl"), max_states=2000)
    assert r.status == "bounded" and not any("grows without bound" in n for n in r.notes)
