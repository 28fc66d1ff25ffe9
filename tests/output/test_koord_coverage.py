"""explore --coverage under Koord's round semantics (docs/koord.md,
"Semantics"; pccl/output/coverage.py): an event's statements run inside
its one transition (EVENT TRANS) and each counts once per such
transition; an ATOMIC WAIT runs none; the report names the same dead
statements as under PCCL's semantics for a program where the two agree."""

from __future__ import annotations

import json
from pathlib import Path

from pccl.api import explore, make_model
from pccl.lang import ast as A
from pccl.lang.koord import parse_koord
from pccl.output.coverage import CoverageModel
from conftest import cli

ROOT = Path(__file__).resolve().parents[2]
ADD = str(ROOT / "programs" / "koord" / "add_numbers.koord")

NEVER = """\
# A counter that never reaches its alarm: the guard of alarm never holds.
local:
  int n = 0

count:
  pre: n < 3
  eff:
    n = n + 1
    if n > 5:
      n = 0

alarm:
  pre: n > 5
  eff:
    n = 0
    stop

halt:
  pre: n == 3
  eff:
    stop
"""


def test_koord_coverage_names_the_dead_statements(tmp_path):
    p = tmp_path / "never.koord"
    p.write_text(NEVER)
    res = cli("explore", str(p), "--coverage", "--agents", "2")
    assert res.exit_code == 0, res.output
    assert f"{p}:10: [count] n = 0" in res.output
    assert f"{p}:15: [alarm] n = 0" in res.output and f"{p}:16: [alarm] stop" in res.output
    data = json.loads(cli("explore", str(p), "--coverage", "--agents", "2",
                          "--format", "json").output)
    cov = data["coverage"]
    assert cov["never_fired"] == ["alarm"]
    assert [u["line"] for u in cov["unexecuted"]] == [10, 15, 16]
    # computed two ways: PCCL's semantics runs the same statements here
    pccl = explore(parse_koord(NEVER, str(p)), coverage=True, semantics="pccl", agents=2)
    assert pccl.coverage.unexecuted == cov["unexecuted"]
    assert pccl.coverage.never_fired == cov["never_fired"]


def _sid_of(prog, text_start: str, line_of) -> int:
    for ev in prog.events:
        for s in A.walk_stmts(ev.body):
            if line_of(s.span.line).strip().startswith(text_start):
                return s.sid
    raise AssertionError(text_start)


def test_each_statement_counts_once_per_event_transition_and_not_on_atomic_wait():
    """add_numbers.koord: the statements of `add` inside `atomic:` run in
    exactly the EVENT TRANS transitions of `add` (its ATOMIC WAITs, which
    there are, run nothing)."""
    m = make_model(ADD, agents=3, reduce="none")
    cov = CoverageModel(m.with_uses(("coverage",)))
    lines = Path(ADD).read_text().split("\n")
    sid = _sid_of(m.program, "sum = sum + pid", lambda n: lines[n - 1])
    seen, todo = set(), list(cov.init_states())
    add = next(k for k, ev in enumerate(m.program.events) if ev.name == "add")
    trans = waits = 0
    while todo:
        st = todo.pop()
        if st in seen:
            continue
        seen.add(st)
        for lab, s2 in cov.successors(st):
            trans += lab[0] == "EVENT TRANS" and lab[2] == add
            waits += lab[0] == "ATOMIC WAIT"
            todo.append(s2)
    assert waits > 0
    assert cov.fired[add] == trans
    assert cov.executed[sid] == trans
    assert cov.report().unexecuted == []


def test_coverage_of_a_koord_program_counts_every_expanded_state():
    r = explore(ADD, coverage=True, agents=3)
    assert r.status == "exhaustive" and r.coverage.expanded == r.stats.states
    assert r.coverage.never_fired == [] and r.coverage.unexecuted == []
