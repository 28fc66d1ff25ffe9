"""The viewer and the command line agree (issue 44.5): for every shipped
program's run and every shipped counterexample, the page's per-step panels,
read in headless Chromium, are the CLI's text of the same trace:

* the "time steps" panel of a run is ``pccl run``'s ``time steps:`` lines,
  each row current from the step after which its time step's state holds
  (the agents' positions the row names are the inspector's at that step);
* the step panel at step k is the CLI's step k (``run --trace``, a
  counterexample's listing), with its changes.

A page written without the model (``pccl view`` of a trace whose program is
not found) words the panels itself: its time-step rows still sit at the
same steps and name the same positions.
"""

from __future__ import annotations

import json
import re
import shutil

import pytest

from conftest import PROGRAMS, cli

from browser import Browser, chromium, file_url

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(chromium()[0] is None, reason=chromium()[1])]

P = PROGRAMS
RACE_W = ("--world", P / "race.toml")

#: every shipped program, run (seed 0)
RUNS = {
    "collide": (P / "collide.pccl", "--world", P / "collide.toml", "--collisions"),
    "collide_fixed": (P / "collide_fixed.pccl", "--world", P / "collide.toml", "--collisions"),
    "fischer": (P / "fischer.pccl", "--max-time", "20"),
    "formation": (P / "formation.pccl", "--world", P / "formation.toml"),
    "leader": (P / "leader.pccl",),
    "race": (P / "race.pccl", *RACE_W),
    "race_nonatomic": (P / "race_nonatomic.pccl", *RACE_W),
    "race_robust": (P / "race_robust.pccl", *RACE_W),
    "race_safe": (P / "race_safe.pccl", *RACE_W),
    "rendezvous": (P / "rendezvous.pccl", "--world", P / "rendezvous.toml"),
    "koord_add_numbers_racy": (P / "koord" / "add_numbers_racy.koord",),
}

#: every shipped program's counterexample (the commands of their headers, the README)
CEXES = {
    "collide": (P / "collide.pccl", "--world", P / "collide.toml", "--collisions"),
    "fischer": (P / "fischer.pccl", "--set", "k=1", "--invariant", "count(inCs) <= 1"),
    "race": (P / "race.pccl", *RACE_W),
    "race_nonatomic": (P / "race_nonatomic.pccl", *RACE_W, "--blackbox", "nondet", "--agents", "3"),
    "race_safe": (P / "race_safe.pccl", *RACE_W),
}

STEP = re.compile(r"^\s*\d+\. t=")


@pytest.fixture(scope="module")
def browser():
    b = Browser()
    yield b
    b.close()


def cli_steps(lines: list) -> list:
    """The steps of a CLI listing: each step's line with its changes' line."""
    out: list = []
    for ln in lines:
        if STEP.match(ln):
            out.append(ln)
        elif out and ln.startswith(" " * 8) and not ln.lstrip().startswith("--"):
            out[-1] += "\n" + ln
    return out


def between(text: str, start: str, stop) -> list:
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith(start))
    j = next(k for k in range(i + 1, len(lines)) if lines[k].startswith(stop))
    return lines[i + 1:j]


def page_steps(b) -> list:
    """The step panel's text at every step, 1..n."""
    return b.eval("""(() => { const out = [], n = +document.body.dataset.steps;
      for (let k = 1; k <= n; k++) { pcclViewer.goto(k);
        out.push(document.getElementById('steptext').textContent); }
      return out; })()""")


def page_summary(b) -> list:
    """The time-steps panel: per row, the step it starts at, the row current
    there (its text) and the inspector's agent positions at that step."""
    return b.eval("""(() => { const out = [];
      for (const k of pcclViewer.times) { pcclViewer.goto(k);
        const cur = document.querySelector('#summary-list .vrow.cur');
        const pos = [...document.querySelectorAll('#inspector tr[data-cell^="pos["]')]
          .map(r => r.dataset.value);
        out.push({k, text: cur ? cur.textContent : null, pos}); }
      return out; })()""")


def positions_of(line: str, n: int) -> list:
    """The agents' positions a time-step line names (``a0 (1.0, 0.0, 0.0)``),
    as numbers."""
    return [numbers(re.search(rf"\ba{i} (\([^)]*\))", line).group(1)) for i in range(n)]


def numbers(text: str) -> list:
    return [float(x) for x in text.strip("()").split(",")]


def check_summary(b, lines: list, doc: dict, *, exact: bool = True) -> None:
    rows = page_summary(b)
    n = len(doc["initial"]["agents"])
    invokes = [0] + [k + 1 for k, s in enumerate(doc["steps"]) if s["rule"] == "DOREACH INVOKE"]
    assert len(rows) == len(lines)
    for row, line in zip(rows, lines):
        if exact:
            assert row["text"] == line.strip()
        # the row is current from the step whose state it describes
        assert row["k"] in invokes
        assert [numbers(p) for p in row["pos"]] == positions_of(line, n), (row, line)
        if exact:
            assert row["pos"] == re.findall(r"\ba\d+ (\([^)]*\))", line)
        assert positions_of(row["text"], n) == positions_of(line, n)


@pytest.mark.parametrize("name", sorted(RUNS))
def test_run_page_agrees_with_the_cli(browser, tmp_path, name):
    html, trace = tmp_path / "run.html", tmp_path / "run.json"
    r = cli("run", *RUNS[name], "--trace", "--html", html, "--trace-out", trace)
    assert r.exit_code in (0, 1), r.output
    doc = json.loads(trace.read_text())
    b = browser
    b.open(file_url(html))
    assert b.exceptions() == []
    # the time steps
    lines = between(r.output, "time steps:", "result:")
    assert lines and not b.eval("document.getElementById('summary').hidden")
    check_summary(b, lines, doc)
    # every step, as --trace prints it
    want = cli_steps(between(r.output, "trace:", "time steps:"))
    assert len(want) == len(doc["steps"]) > 0
    assert page_steps(b) == want


@pytest.mark.parametrize("name", sorted(CEXES))
def test_counterexample_page_agrees_with_the_cli(browser, tmp_path, name):
    html, trace = tmp_path / "cex.html", tmp_path / "cex.json"
    r = cli("explore", *CEXES[name], "--html", html, "--trace-out", trace)
    assert r.exit_code == 1, r.output
    doc = json.loads(trace.read_text())
    b = browser
    b.open(file_url(html))
    assert b.exceptions() == []
    want = cli_steps(between(r.output, "counterexample (", ("violating state:", "state at the end")))
    assert len(want) == len(doc["steps"]) > 0
    assert page_steps(b) == want


def test_page_without_the_model_keeps_the_time_steps_in_place(browser, tmp_path):
    """`pccl view` of a trace whose program is not found: the page words the
    time steps itself; its rows start at the same steps and name the same
    positions as the CLI's lines."""
    src = tmp_path / "src"
    src.mkdir()
    prog = src / "race.pccl"
    shutil.copy(P / "race.pccl", prog)
    shutil.copy(P / "race.toml", src / "race.toml")
    trace, html = tmp_path / "run.json", tmp_path / "view.html"
    r = cli("run", prog, "--world", src / "race.toml", "--trace-out", trace)
    assert r.exit_code == 0, r.output
    lines = between(r.output, "time steps:", "result:")
    shutil.rmtree(src)
    v = cli("view", trace, "-o", html)
    assert v.exit_code == 0, v.output
    b = browser
    b.open(file_url(html))
    doc = json.loads(trace.read_text())
    check_summary(b, lines, doc, exact=False)
    assert b.eval("pcclViewer.data.text === null")      # the page's own wording
