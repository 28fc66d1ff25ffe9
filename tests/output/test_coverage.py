"""explore --coverage: guards held, events fired, statements never executed."""

from __future__ import annotations

import json
from pathlib import Path


from pccl.api import explore
from conftest import cli

ROOT = Path(__file__).resolve().parents[2]
NEVER = ROOT / "docs" / "examples" / "never.pccl"




def test_an_event_whose_guard_never_holds_is_named_with_its_statements():
    res = cli("explore", NEVER, "--coverage")
    assert res.exit_code == 0
    out = res.output
    alarm = next(ln for ln in out.splitlines() if ln.strip().startswith("Alarm"))
    assert alarm.split()[2:5] == ["0", "0", "never"]
    assert f"{NEVER}:18: [Alarm] n = 0;" in out and f"{NEVER}:19: [Alarm] exit();" in out
    assert f"{NEVER}:13: [Count] n = 0;" in out     # the dead branch of an if
    assert "never fired" not in next(ln for ln in out.splitlines() if ln.strip().startswith("Count"))


def test_coverage_json_and_api():
    data = json.loads(cli("explore", NEVER, "--coverage", "--format", "json").output)
    cov = data["coverage"]
    assert cov["never_fired"] == ["Alarm"]
    assert [u["line"] for u in cov["unexecuted"]] == [13, 18, 19]
    r = explore(str(NEVER), coverage=True)
    assert r.coverage.never_fired == ["Alarm"] and r.coverage.expanded == r.stats.states
    assert explore(str(NEVER)).coverage is None


def test_guard_held_but_not_fired_under_events_first(tmp_path):
    p = tmp_path / "two.pccl"
    p.write_text("loc:\n  int n = 0;\n\nA():\n  pre(n < 2);\n  eff:\n    n = n + 1;\n\n"
                 "B():\n  pre(n < 2);\n  eff:\n    n = n + 1;\n\nC():\n  pre(n == 2);\n  eff:\n    exit();\n")
    r = explore(str(p), coverage=True, events="first")
    ev = {e["event"]: e for e in r.coverage.events}
    assert ev["B"]["guard_held"] > 0 and ev["B"]["fired"] == 0
    assert ev["A"]["guard_held"] == ev["A"]["fired"] > 0
    assert r.coverage.never_fired == ["B"]
    assert [u["line"] for u in r.coverage.unexecuted] == [12]


def test_coverage_does_not_count_the_counterexample_rebuild():
    lost = ROOT / "docs" / "examples" / "lost_update.pccl"
    r = explore(str(lost), coverage=True)
    assert r.status == "violation"
    assert r.coverage.expanded <= r.stats.states
