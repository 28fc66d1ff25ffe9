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
import os
import re
import shutil

import pytest

from conftest import PROGRAMS, cli

from browser import Browser, chromium, file_url, trace_states

#: CI (.ci/run) sets PCCL_REQUIRE_CHROMIUM=1: there these tests must run, and
#: fail (rather than skip) without Chromium.
REQUIRED = os.environ.get("PCCL_REQUIRE_CHROMIUM") == "1"

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(chromium()[0] is None and not REQUIRED, reason=chromium()[1])]

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
    if chromium()[0] is None:
        pytest.fail(f"PCCL_REQUIRE_CHROMIUM=1 (CI) but {chromium()[1]}")
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


# ---------------------------------------------------------------------------
# readable (issue 44.5): each fails on the page before the fix
# ---------------------------------------------------------------------------

LIST3 = """
allwrite:
  List<int> xs = [];
  int n = 0;
  ItemPosition p = ItemPosition(1.0, 2.0);
Step():
  pre(n < 3);
  eff:
    add(xs, n);
    n = n + 1;
Done():
  pre(n >= 3);
  eff:
    exit();
"""


def test_a_list_of_three_ints_is_a_list_and_a_position_a_position(browser, tmp_path):
    prog, html = tmp_path / "l3.pccl", tmp_path / "l3.html"
    prog.write_text(LIST3)
    r = cli("run", prog, "--agents", "1", "--html", html)
    assert r.exit_code == 0, r.output
    b = browser
    b.open(file_url(html))
    b.eval("pcclViewer.goto(+document.body.dataset.steps)")
    val = b.eval("(() => { const v = c => document.querySelector(`#inspector tr[data-cell=\"${c}\"]`).dataset.value;"
                 " return [v('xs'), v('p')]; })()")
    assert val == ["[0, 1, 2]", "(1.0, 2.0, 0.0)"]
    lanes = b.eval("[...document.querySelectorAll('#swimlane .vrow[data-step]')].map(r => r.textContent).join(' ')")
    assert "xs=[0, 1, 2]" in lanes and "(0, 1, 2)" not in lanes


def test_inspector_keeps_the_pending_computation_apart_from_a_variable_k(browser, tmp_path):
    """Fischer's shared variable is named k: the agent's pending computation
    is not a row labelled k beside it."""
    html = tmp_path / "f.html"
    cli("explore", P / "fischer.pccl", "--set", "k=1", "--invariant", "count(inCs) <= 1", "--html", html)
    b = browser
    b.open(file_url(html))
    rows = b.eval("[...document.querySelectorAll('#inspector tr[data-cell]')].map(r => "
                  "[r.dataset.cell, r.firstChild.textContent, r.classList.contains('builtin')])")
    labelled_k = [r for r in rows if r[1] == "k"]
    assert labelled_k == [["k", "k", False]]             # the program's k only
    pending = [r for r in rows if r[0].startswith("at[")]
    assert len(pending) == 2 and all(r[2] and " " in r[1] for r in pending)   # words, not a name


def test_timeline_and_arena_have_legends_and_axes(browser, tmp_path):
    html = tmp_path / "f.html"
    cli("explore", P / "fischer.pccl", "--set", "k=1", "--invariant", "count(inCs) <= 1", "--html", html)
    b = browser
    b.open(file_url(html))
    events = b.eval("[...new Set([...document.querySelectorAll('.tl-bar')].map(e => e.dataset.event).filter(e => e))]")
    legend = b.eval("[...document.querySelectorAll('#legend .item')].map(e => e.dataset.legend)")
    assert events and all(f"event {e}" in legend for e in events)
    html2 = tmp_path / "r.html"
    cli("run", P / "race.pccl", "--world", P / "race.toml", "--html", html2)
    b.open(file_url(html2))
    ticks = b.eval("['x', 'y'].map(a => [...document.querySelectorAll(`#axis-${a} .tick`)].map(t => +t.dataset.value))")
    # the race world's arena is [-6, 7] x [-2, 7]: both axes span it
    assert min(ticks[0]) <= -6 and max(ticks[0]) >= 6 and min(ticks[1]) <= -2 and max(ticks[1]) >= 6
    assert "agent 0" in b.eval("[...document.querySelectorAll('#legend .item')].map(e => e.dataset.legend)")


def test_robots_at_one_spot_are_drawn_apart(browser, tmp_path):
    html = tmp_path / "r.html"
    cli("run", P / "race.pccl", "--world", P / "race.toml", "--html", html)
    b = browser
    b.open(file_url(html))
    drawn = b.eval("""(() => { const d = JSON.parse(JSON.stringify(pcclViewer.data));
      d.trace.initial.agents[1].position = d.trace.initial.agents[0].position.slice();
      pcclViewer.load(d);
      return [...document.querySelectorAll('.robot')].map(r => {
        const m = /translate\\(([^,]+),([^)]+)\\)/.exec(r.getAttribute('transform'));
        return [+m[1], +m[2], +r.dataset.x, +r.dataset.y]; }); })()""")
    r = b.eval("pcclViewer.data.world.radius")
    (x0, y0, px0, py0), (x1, y1, px1, py1) = drawn
    assert (px0, py0) == (px1, py1)                      # one spot in the state...
    assert ((x0 - x1) ** 2 + (y0 - y1) ** 2) ** 0.5 >= r  # ...two robots on the page


def test_swimlane_cells_are_not_cut_off(browser, tmp_path):
    html = tmp_path / "r.html"
    cli("run", P / "race.pccl", "--world", P / "race.toml", "--agents", "3", "--html", html)
    b = browser
    b.open(file_url(html))
    cut = b.eval("""(() => { const out = [];
      for (const k of [0, 1, 2, 3, 14, 30]) { pcclViewer.goto(k);
        for (const c of document.querySelectorAll('#swimlane .vrow span, #summary-list .vrow span')) {
          const row = c.parentElement.getBoundingClientRect(), r = c.getBoundingClientRect();
          if (c.scrollWidth > c.clientWidth + 1 || c.scrollHeight > c.clientHeight + 1 ||
              r.bottom > row.bottom + 1) out.push(c.textContent); } }
      return out; })()""")
    assert cut == []
    # and no two rows overlap
    overlap = b.eval("""(() => { const rs = [...document.querySelectorAll('#swimlane .vrow[data-index]')]
        .map(r => r.getBoundingClientRect()).sort((a, b) => a.top - b.top);
      return rs.some((r, i) => i > 0 && r.top < rs[i - 1].bottom - 1); })()""")
    assert overlap is False


def test_plot_of_chosen_variables(browser, tmp_path):
    html, trace = tmp_path / "f.html", tmp_path / "f.json"
    cli("explore", P / "fischer.pccl", "--set", "k=1", "--invariant", "count(inCs) <= 1",
        "--html", html, "--trace-out", trace)
    doc = json.loads(trace.read_text())
    b = browser
    b.open(file_url(html))
    got = b.eval("""(() => { const s = document.getElementById('plot-vars');
      [...s.options].forEach(o => o.selected = ['reqid', 'inCs[1]'].includes(o.textContent)); s.onchange();
      return [...document.querySelectorAll('#plot-area .plot-line')]
        .map(l => [l.dataset.name, JSON.parse(l.dataset.values)]); })()""")
    states = trace_states(doc)
    assert got == [["reqid", [s["shared"]["reqid"] for s in states]],
                   ["inCs[1]", [int(s["agents"][1]["variables"]["inCs"]) for s in states]]]
    b.eval("pcclViewer.goto(40)")
    assert b.eval("document.querySelector('#plot-area .tl-cursor').dataset.step") == "40"


# ---------------------------------------------------------------------------
# watched expressions: pccl's values, never the browser's evaluation
# ---------------------------------------------------------------------------

def test_watched_expressions_show_pccls_values_at_every_step(browser, tmp_path):
    html, trace = tmp_path / "f.html", tmp_path / "f.json"
    r = cli("explore", P / "fischer.pccl", "--set", "k=1", "--invariant", "count(inCs) <= 1",
            "--html", html, "--trace-out", trace,
            "--watch", "count(inCs)", "--watch", "count(inCs) <= 1", "--watch", "reqid + d / 3")
    assert r.exit_code == 1, r.output
    doc = json.loads(trace.read_text())
    b = browser
    b.open(file_url(html))
    got = b.eval("""(() => { const out = [], n = +document.body.dataset.steps;
      for (let k = 0; k <= n; k++) { pcclViewer.goto(k);
        out.push([...document.querySelectorAll('#watch-table tr[data-expr]')].map(r => r.dataset.value)); }
      return out; })()""")
    want = []
    for s in trace_states(doc):
        c = sum(1 for ag in s["agents"] if ag["variables"]["inCs"])
        want.append([str(c), "true" if c <= 1 else "false",
                     str(s["shared"]["reqid"] + s["shared"]["d"] // 3)])
    assert got == want
    # the invariant the search found violated is false exactly at the violating state
    assert [row[1] for row in got].index("false") == len(got) - 1
    # a watched number is offered to the plot
    assert "count(inCs)" in b.eval("[...document.getElementById('plot-vars').options].map(o => o.textContent)")


def test_the_static_page_does_not_evaluate_typed_text(browser, tmp_path):
    html = tmp_path / "f.html"
    cli("explore", P / "fischer.pccl", "--set", "k=1", "--invariant", "count(inCs) <= 1",
        "--html", html, "--watch", "reqid")
    b = browser
    b.open(file_url(html))
    b.eval("document.getElementById('expr-input').value = 'alert(1) || reqid'; "
           "document.getElementById('expr-go').click()")
    assert b.eval("document.querySelectorAll('#watch-table tr[data-expr]').length") == 1
    assert "--watch" in b.eval("document.getElementById('expr-msg').textContent")
    assert b.exceptions() == []


def test_serve_expression_box_evaluates_with_pccl(browser, tmp_path):
    import threading
    from pccl.api import make_model
    from pccl.tools import serve as S
    from pccl.output import traces as T
    m = make_model(str(P / "fischer.pccl"), overrides={"k": "1"}, reduce="none")
    session = S.Session(m, T.config("explore", m, program=str(P / "fischer.pccl")))
    srv = S.make_server(session, 0)
    th = threading.Thread(target=srv.serve_forever, daemon=True)
    th.start()
    try:
        b = browser
        b.open(S.url(srv))
        b.wait("document.body.dataset.depth === '0'")
        for _ in range(6):
            n = b.eval("+document.body.dataset.depth")
            b.eval("document.querySelector('#successors button').click()")
            b.wait(f"document.body.dataset.depth === '{n + 1}'")
        b.eval("document.getElementById('expr-input').value = 'count(start) + reqid'; "
               "document.getElementById('expr-go').click()")
        b.wait("document.querySelectorAll('#watch-table tr[data-expr]').length === 1")
        got = b.eval("""(() => { const out = [];
          for (let k = 0; k <= 6; k++) { pcclViewer.goto(k);
            out.push(document.querySelector('#watch-table tr[data-expr]').dataset.value); }
          return out; })()""")
        from pccl.output import display as D

        def value(st):      # count(start) + reqid, read off the state by name
            starts = sum(1 for i in range(m.N) if {n: v for n, _, v in D.agent_vars(m, st, i)}["start"])
            return str(starts + {n: v for n, _, v in D.shared_vars(m, st)}["reqid"])
        want = [value(st) for st in session.states]
        assert got == want
        # a wrong expression: its caret, and nothing watched
        b.eval("document.getElementById('expr-input').value = 'count(start'; "
               "document.getElementById('expr-go').click()")
        b.wait("document.getElementById('expr-msg').textContent.includes('^')")
        assert b.eval("document.querySelectorAll('#watch-table tr[data-expr]').length") == 1
        b.eval("document.querySelector('#watch-table .unwatch').click()")
        b.wait("document.querySelectorAll('#watch-table tr[data-expr]').length === 0")
    finally:
        srv.shutdown()
        srv.server_close()


def test_a_bad_watch_is_bad_input(tmp_path):
    r = cli("explore", P / "fischer.pccl", "--html", tmp_path / "f.html", "--watch", "count(nope)")
    assert r.exit_code == 2
    assert "--watch #1:1:7" in r.output and "^" in r.output and "Traceback" not in r.output
    r = cli("run", P / "fischer.pccl", "--watch", "reqid")
    assert r.exit_code == 2 and "--watch needs --html" in r.output
    r = cli("run", P / "fischer.pccl", "--html", tmp_path / "f.html", "--watch", "eventually reqid == 0")
    assert r.exit_code == 2 and "not a temporal property" in r.output
