"""Counterexamples as short as the program's bug (issue 44.3): under the
reductions, the counterexample shown is shortened against the unreduced
semantics (pccl/model/shorten.py, api._shorten); the verdict never changes,
the path replays, and the output says when it is not shown to be shortest."""

from __future__ import annotations

import json
import textwrap

import pytest

from conftest import cli
from pccl import api
from pccl.model import shorten as S
from pccl.model.reduce import unreduced
from pccl.tools.replay import replay

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# every test here explores a program two or three times (0.3-2.5 s each,
# measured with --durations on 2 loaded cores): not in the quick subset
pytestmark = pytest.mark.slow
TP = ROOT / "tests" / "programs"
ASSERT = str(TP / "eng_assert.pccl")        # 17 steps under the reductions, 13 without
SPIN = str(TP / "tl_spin.pccl")             # a time-lock lasso: 4 steps, 3 without
KEEP = str(TP / "token_keep.pccl")          # a stall: 3 steps, 1 without
RACE = str(ROOT / "programs" / "race.pccl")
RACE_WORLD = str(ROOT / "programs" / "race.toml")

#: the two-statement loop of the issue: a time-lock lasso of 7 steps under
#: the reductions, 4 without
LOOP = textwrap.dedent("""\
    allwrite:
      int x = 0;
    Spin():
      pre(true);
      eff:
        while (true):
          x = 1;
          x = 0;
    """)


def lengths(res) -> tuple:
    cx = res.counterexamples[0]
    return len(cx.trace), cx.cycle_start


def both(program, **kw) -> tuple:
    """The default search, the same without shortening, and --reduce none."""
    return (api.explore(program, **kw), api.explore(program, shorten=False, **kw),
            api.explore(program, reduce="none", **kw))


@pytest.mark.parametrize("program, kw, kind", [
    (ASSERT, {}, "assert"),
    (SPIN, {}, "timelock"),
    (KEEP, {}, "stall"),
    (RACE, dict(world=RACE_WORLD), "stuck"),
    (KEEP, dict(agents=3, properties=["forall i: want[i] ~> has[i]"]), "liveness"),
])
def test_default_counterexample_as_short_as_unreduced(program, kw, kind):
    res, off, none = both(program, **kw)
    assert res.violation.kind == off.violation.kind == none.violation.kind == kind
    # the reduced search's path is longer (these programs show it) ...
    assert len(off.counterexamples[0].trace) > len(none.counterexamples[0].trace)
    # ... and the one shown is as short as the unreduced search's
    assert lengths(res) == lengths(none)
    sh = res.counterexamples[0].shortening
    assert sh.status == "shortened" and sh.reduced_steps == len(off.counterexamples[0].trace)
    assert res.violation.shortest == "yes" and off.violation.shortest == "under the reductions"
    # the verdict never changes (a stall's message ends with what the agents
    # of the path's last state wait on: that part is the path's)
    assert (res.status, res.exit_status) == (off.status, off.exit_status)
    cut = (lambda t: t.split(";")[0]) if kind == "stall" else (lambda t: t)
    assert cut(res.verdict) == cut(off.verdict)
    assert res.violation.message == res.counterexamples[0].violation.message
    assert res.stats.states == off.stats.states


def test_the_two_statement_loop(tmp_path):
    p = tmp_path / "loop.pccl"
    p.write_text(LOOP)
    res, off, none = both(str(p))
    assert res.violation.kind == "timelock"
    assert lengths(off) == (7, 4) and lengths(res) == lengths(none) == (4, 1)


def test_a_shortest_reduced_path_is_confirmed():
    res = api.explore(str(TP / "ref_undef.pccl"))
    none = api.explore(str(TP / "ref_undef.pccl"), reduce="none")
    assert res.counterexamples[0].shortening.status == "confirmed"
    assert len(res.trace) == len(none.trace)
    assert res.violation.shortest == "yes"


def test_no_shortening_without_reductions_or_when_fastest():
    none = api.explore(ASSERT, reduce="none")
    assert none.counterexamples[0].shortening is None and none.violation.shortest == "yes"
    assert "shortening" not in none.violation.to_json()
    fast = api.explore(ASSERT, fastest=True)
    assert fast.counterexamples[0].shortening is None


def test_the_budget_keeps_the_reduced_path_and_says_so(monkeypatch):
    off = api.explore(ASSERT, shorten=False)
    monkeypatch.setattr(S, "MAX_STATES", 5)
    monkeypatch.setattr(S, "MAX_STATES_NATIVE", 5)
    res = api.explore(ASSERT)
    sh = res.counterexamples[0].shortening
    assert sh.status == "not-shown" and "budget of 5 states" in sh.reason
    assert "reduce='none'" in sh.reason or "reduce=none" in sh.reason
    assert lengths(res) == lengths(off) and res.verdict == off.verdict
    assert res.violation.shortest == "under the reductions"


def test_cli_text_and_json():
    r = cli("explore", ASSERT)
    assert r.exit_code == 1
    assert ("counterexample (13 steps, shortest: the reduced search's had 17 steps; depth 6 in "
            "the reduced graph, as --depth counts):") in r.output
    r = cli("explore", ASSERT, "--no-shorten")
    assert r.exit_code == 1
    assert ("counterexample (17 steps, shortest under the reductions; not compared with the "
            "unreduced graph (--no-shorten)") in r.output
    r = cli("explore", ASSERT, "--format", "json")
    v = json.loads(r.output)["violations"][0]
    assert v["shortest"] == "yes"
    assert v["shortening"] == {"status": "shortened", "reduced_steps": 17, "reason": None}
    assert len(v["trace"]["steps"]) == 13
    r = cli("explore", SPIN)
    assert ("counterexample (a lasso: 1 step, then a cycle of 2 steps repeated forever, as short "
            "as without the reductions: the reduced search's had 4 steps):") in r.output


@pytest.mark.parametrize("program, args", [
    (ASSERT, ()), (SPIN, ()), (KEEP, ()), (RACE, ("--world", RACE_WORLD)),
    (KEEP, ("-n", "3", "--property", "forall i: want[i] ~> has[i]")),
])
def test_the_shortened_trace_replays(tmp_path, program, args):
    out = tmp_path / "t.json"
    r = cli("explore", program, *args, "--trace-out", out)
    assert r.exit_code == 1, r.output
    doc = json.loads(out.read_text())
    res = replay(str(out))
    assert res.status == "violation" and res.exit_status == 1, res.message
    assert res.diverged_at is None and len(res.labels) == len(doc["steps"]) == res.steps_total


def test_shortest_paths_agrees_with_the_unreduced_search():
    """The fallback search (a violation whose first instance is another
    agent's) finds the unreduced search's length, and reports its budget."""
    res = api.explore(ASSERT, shorten=False)
    cx = res.counterexamples[0]
    m = unreduced(res.model)
    paths, complete = S.shortest_paths(m, [(cx.violation, len(cx.trace))])
    assert complete and len(paths[0]) == 13
    assert m.violations(paths[0].last) and cx.violation in m.violations(paths[0].last)
    # no shorter path than 13 exists
    paths, complete = S.shortest_paths(m, [(cx.violation, 13)])
    assert complete and paths == [None]
    paths, complete = S.shortest_paths(m, [(cx.violation, len(cx.trace))], max_states=5)
    assert not complete and paths == [None]


def test_every_violation_of_all_is_shortened():
    lost = str(ROOT / "docs" / "examples" / "lost_update.pccl")
    res, off, none = both(lost, find_all=True, deadlock=False)
    assert [c.violation for c in res.counterexamples] == [c.violation for c in off.counterexamples]
    assert res.verdict == off.verdict and res.exit_status == off.exit_status == 1
    by = {c.violation.identity: len(c.trace) for c in none.counterexamples}
    for c, o in zip(res.counterexamples, off.counterexamples):
        assert len(c.trace) == by[c.violation.identity] <= len(o.trace)
        assert c.shortening.status in ("shortened", "confirmed")
    assert any(c.shortening.status == "shortened" for c in res.counterexamples)
