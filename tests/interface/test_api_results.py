"""Issue 27, item 5: API results have short reprs and typed step changes."""

from __future__ import annotations

from pathlib import Path

from pccl.output import display as D
from pccl.output import traces as T
from pccl.api import explore, run

ROOT = Path(__file__).resolve().parents[2]
RACE = str(ROOT / "programs" / "race.pccl")
RACE_WORLD = str(ROOT / "programs" / "race.toml")
FISCHER = str(ROOT / "programs" / "fischer.pccl")


def test_reprs_are_one_short_line():
    r = explore(RACE, world=RACE_WORLD, blackbox="instant")
    s = run(RACE, world=RACE_WORLD, seed=3, record_trace=True)
    for x in (r, s):
        text = repr(x)
        assert "\n" not in text and len(text) < 300, len(text)   # was 80 KB for r
    assert repr(r).startswith("<ExploreResult violation (exit 1): ")
    # 92 states of the reduced graph; the trace shortened against the unreduced
    # semantics (issue 44.3: 71 steps under the reductions)
    assert "92 states" in repr(r) and "trace of 68 steps" in repr(r)
    assert repr(s).startswith("<RunResult final (exit 0): 'every agent exited'; t=18")


def test_step_changes_are_data_and_agree_with_the_text_and_the_trace_file():
    r = explore(FISCHER, invariants=["count(inCs) <= 1"], overrides={"k": "0"})
    last = r.trace[-1].changes[0]
    assert last.cell == f"inCs[{last.agent}]" and last.old is False and last.new is True
    assert dict(last.path) == {"agent": last.agent, "var": "inCs"}
    cx = r.counterexamples[0].trace
    m = r.model
    for n, step in enumerate(r.trace):
        before, after = cx.states[n], cx.states[n + 1]
        # the printed text: what pccl explore prints for the step
        printed = [(c, o, nw) for c, o, nw in D.diff(m, before, after)]
        assert [(c.cell, c.old_text, c.new_text) for c in step.changes] == printed
        # the data: the trace file's typed changes (without counter, env
        # and, since version 2, k, t0 and obstacles: cells the text does not
        # print)
        typed = [c for c in T.changes(m, before, after)
                 if c["cell"].get("cell") not in ("counter", "env", "k", "t0", "obstacles")]
        assert [(dict(c.path), c.old, c.new) for c in step.changes] == \
               [(c["cell"], c["old"], c["new"]) for c in typed]
        # the CLI's JSON is the trace format's step (vocabulary version 2; it
        # was the printed form): every changed cell, typed
        assert step.to_json()["changes"] == T.changes(m, before, after)
        assert step.to_json() == T.step_record(m, n + 1, cx.labels[n], before, after)
