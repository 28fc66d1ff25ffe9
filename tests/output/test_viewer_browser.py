"""The HTML viewer and ``pccl serve`` in a real browser (headless Chromium
over the DevTools Protocol, tests/browser.py).

Every test skips, saying why, when there is no Chromium (``.ci/run``
installs Debian's).  Screenshots are kept in build/viewer-screenshots/.
"""

from __future__ import annotations

import json
import os
import threading
import time

import pytest

from conftest import FISCHER, RACE_NONATOMIC, RACE_WORLD, ROOT, cli

from browser import Browser, chromium, file_url, trace_states

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(chromium()[0] is None, reason=chromium()[1])]

SHOTS = ROOT / "build" / "viewer-screenshots"


@pytest.fixture(scope="module")
def browser():
    b = Browser()
    yield b
    b.close()


def shot(browser, name):
    SHOTS.mkdir(parents=True, exist_ok=True)
    browser.screenshot(SHOTS / name)


def cell_names(step):
    """The cells the page shows as changed: every change but the agent
    cells it does not print (k, t0, obstacles: codec.INTERNAL_CELLS)."""
    from pccl.output.codec import INTERNAL_CELLS, cell_name
    return sorted(cell_name(ch["cell"]) for ch in step["changes"]
                  if not ("agent" in ch["cell"] and ch["cell"].get("cell") in INTERNAL_CELLS))


def page_state(b) -> dict:
    return b.eval("""(() => {
      const ins = document.getElementById('inspector'), src = document.getElementById('source');
      return {step: +document.body.dataset.step, steps: +document.body.dataset.steps,
              robots: [...document.querySelectorAll('.robot')].map(r => ({agent: +r.dataset.agent,
                 x: +r.dataset.x, y: +r.dataset.y, status: r.dataset.status})),
              changed: ins.dataset.changed, violating: ins.dataset.violating,
              banner: (document.getElementById('violating') || {}).textContent || null,
              line: src.dataset.line, agent: src.dataset.agent,
              curLine: (document.querySelector('#source .ln.cur') || {}).textContent || null,
              swimCur: (document.querySelector('#swimlane .vrow.cur') || {dataset: {}}).dataset.step};
    })()""")


def check_step(b, doc, states, k):
    st = page_state(b)
    assert st["step"] == k
    for r in st["robots"]:
        assert [r["x"], r["y"]] == states[k]["agents"][r["agent"]]["position"][:2]
        assert r["status"] == states[k]["agents"][r["agent"]]["status"]["status"]
    if k > 0:
        rec = doc["steps"][k - 1]
        assert st["line"] == ("" if rec["line"] is None else str(rec["line"]))
        if rec["line"] is not None:
            assert st["curLine"].strip() == rec["source"].strip() or rec["source"].strip() in st["curLine"]
        # the changed cells are the step's changes (and the agents' pending computations)
        shown = [c for c in st["changed"].split(",") if c and not c.startswith("at[")]
        assert sorted(shown) == cell_names(rec)
    assert st["swimCur"] == str(k)
    return st


def test_race_counterexample_steps_to_the_violation(browser, tmp_path):
    """The acceptance command: the page animates the stuck robot's race; stepping
    through it shows the robots where the trace has them, the step's source
    line and changed cells; the last step shows the violating state."""
    html, trace = tmp_path / "cex.html", tmp_path / "cex.json"
    r = cli("explore", RACE_NONATOMIC, "--world", RACE_WORLD, "--blackbox", "nondet", "--agents", "3",
            "--html", str(html), "--trace-out", str(trace))
    assert r.exit_code == 1, r.output
    doc = json.loads(trace.read_text())
    states = trace_states(doc)
    b = browser
    b.open(file_url(html))
    assert b.exceptions() == []
    n = len(doc["steps"])
    assert page_state(b)["steps"] == n
    # forward with the keyboard's arrow (the page's key handler), then by the API
    b.send("Input.dispatchKeyEvent", type="keyDown", key="ArrowRight", code="ArrowRight",
           windowsVirtualKeyCode=39)
    b.send("Input.dispatchKeyEvent", type="keyUp", key="ArrowRight", code="ArrowRight",
           windowsVirtualKeyCode=39)
    check_step(b, doc, states, 1)
    for k in range(2, n + 1):
        b.eval("pcclViewer.next()")
        check_step(b, doc, states, k)
    st = page_state(b)
    v = doc["result"]["violation"]
    assert v["kind"] == "stuck" and st["violating"] == "true"
    assert v["message"] in st["banner"]
    stuck = [r for r in st["robots"] if r["status"] == "stuck"]
    assert [r["agent"] for r in stuck] == [v["agent"]]
    # the JavaScript's states agree with the recorded final state (two encoders, one answer)
    final = b.eval("pcclViewer.state()")
    for ag in final["agents"] + doc["final"]["agents"]:
        ag.pop("at")
    want = json.loads(json.dumps(doc["final"]))
    assert final == want
    ring = b.eval("[...document.querySelectorAll('#rings circle')].map(c => +c.dataset.agent)")
    assert ring == [v["agent"]]
    shot(b, "race_nonatomic_cex.png")
    # back one step: no longer the violating state; clicking a swimlane row jumps
    b.eval("pcclViewer.prev()")
    assert page_state(b)["violating"] == "false"
    b.eval("document.querySelector('#swimlane .vrow[data-step]').click()")
    assert page_state(b)["step"] == int(b.eval("document.querySelector('#swimlane .vrow[data-step]')"
                                               ".dataset.step"))
    # the page asked for nothing but itself, and names no remote resource
    assert b.requests == [file_url(html)]
    text = html.read_text()
    for attr in ("src=", "href="):
        for piece in text.split(attr)[1:]:
            assert not piece.lstrip("\"'").startswith(("http:", "https:", "//")), piece[:60]


def test_hash_opens_a_step_and_playback_advances(browser, tmp_path):
    html, trace = tmp_path / "cex.html", tmp_path / "cex.json"
    cli("explore", RACE_NONATOMIC, "--world", RACE_WORLD, "--blackbox", "nondet", "--agents", "3",
        "--html", str(html), "--trace-out", str(trace))
    doc = json.loads(trace.read_text())
    b = browser
    b.open(file_url(html) + "#step=7")
    check_step(b, doc, trace_states(doc), 7)
    b.eval("document.getElementById('speed').value = '100'; pcclViewer.play()")
    b.wait("+document.body.dataset.step >= 20", timeout=30)
    b.eval("pcclViewer.pause()")


def test_fischer_timeline(browser, tmp_path):
    html, trace = tmp_path / "fischer.html", tmp_path / "fischer.json"
    r = cli("explore", FISCHER, "--set", "k=1", "--invariant", "count(inCs) <= 1",
            "--html", str(html), "--trace-out", str(trace))
    assert r.exit_code == 1
    doc = json.loads(trace.read_text())
    b = browser
    b.open(file_url(html))
    assert b.eval("!!document.getElementById('timeline') && !document.getElementById('arena')")
    n = len(doc["steps"])
    b.eval(f"pcclViewer.goto({n})")
    states = trace_states(doc)
    check_step(b, doc, states, n)
    assert b.eval("document.querySelector('.tl-cursor').dataset.step") == str(n)
    # both agents in the critical section at the violating state, as the inspector says
    assert b.eval("[0,1].map(i => document.querySelector(`#inspector tr[data-cell=\"inCs[${i}]\"]`)"
                  ".dataset.value)") == ["true", "true"]
    # the pending computation of each agent is the replayed one (explore knows the states)
    at = b.eval("[0,1].map(i => document.querySelector(`.lane[data-agent=\"${i}\"]`).dataset.at)")
    assert at == [a["at"] for a in doc["final"]["agents"]]
    b.eval("pcclViewer.goto(60)")
    shot(b, "fischer_timeline.png")


def test_long_trace_stays_responsive(browser, tmp_path):
    """A 10,000-step run: the page loads, and stepping and jumping are quick;
    the swimlane keeps only the visible rows in the DOM."""
    html, trace = tmp_path / "long.html", tmp_path / "long.json"
    r = cli("run", FISCHER, "--max-time", "850", "--html", str(html),
            "--trace-out", str(trace))
    assert r.exit_code in (0, 1), r.output
    n = len(json.loads(trace.read_text())["steps"])
    assert n >= 10_000
    b = browser
    t0 = time.monotonic()
    b.open(file_url(html))
    load = time.monotonic() - t0
    assert b.eval("+document.body.dataset.steps") == n
    assert load < 20, load
    t0 = time.monotonic()
    for k in (n, n // 2, 1, n - 1, 5000):
        b.eval(f"pcclViewer.goto({k})")
        assert b.eval("+document.body.dataset.step") == k
    for _ in range(50):
        b.eval("pcclViewer.next()")
    steps = time.monotonic() - t0
    assert steps < 20, steps
    assert b.eval("document.querySelectorAll('#swimlane .vrow').length") < 200


# ---------------------------------------------------------------------------
# pccl serve
# ---------------------------------------------------------------------------

@pytest.fixture
def fischer_server():
    from pccl.api import make_model
    from pccl.tools import serve as S
    from pccl.output import traces as T
    m = make_model(FISCHER, overrides={"k": "1"}, invariants=("count(inCs) <= 1",), reduce="none")
    cfg = T.config("explore", m, program=FISCHER)        # overrides, invariants: the model's options
    session = S.Session(m, cfg)
    srv = S.make_server(session, 0)
    th = threading.Thread(target=srv.serve_forever, daemon=True)
    th.start()
    yield srv, session
    srv.shutdown()
    srv.server_close()


def test_serve_reaches_two_agents_in_cs_by_clicking(browser, fischer_server):
    from pccl.api import make_model
    from pccl.tools import serve as S
    from pccl.output import traces as T
    srv, _ = fischer_server
    # the indices of the transitions to choose, from a second session's search
    m = make_model(FISCHER, overrides={"k": "1"}, invariants=("count(inCs) <= 1",), reduce="none")
    planner = S.Session(m, T.config("explore", m, program=FISCHER))
    res = planner.search(400, 1_000_000)
    assert res["status"] == "violation"
    states, labels = planner.found
    picks = []
    for a, lab in zip(states, labels):
        picks.append([lab2 for lab2, _ in m.successors(a)].index(lab))
    b = browser
    url = f"http://127.0.0.1:{srv.server_address[1]}/"
    b.open(S.url(srv))
    b.wait("document.body.dataset.depth === '0'")
    assert b.eval("document.querySelector('#checks li').dataset.holds") == "true"
    for d, i in enumerate(picks):
        b.eval(f"document.querySelector('#successors button[data-index=\"{i}\"]').click()")
        b.wait(f"document.body.dataset.depth === '{d + 1}'")
    li = b.eval("(() => { const l = document.querySelector('#checks li'); "
                "return [l.dataset.name, l.dataset.holds, l.textContent]; })()")
    assert li[0] == "count(inCs) <= 1" and li[1] == "false" and "violated" in li[2]
    assert b.eval("document.getElementById('inspector').dataset.violating") == "true"
    assert b.eval("[0,1].map(i => document.querySelector(`#inspector tr[data-cell=\"inCs[${i}]\"]`)"
                  ".dataset.value)") == ["true", "true"]
    shot(b, "serve_fischer.png")
    # back, then a bad request: an error on the page, and the server goes on
    b.eval("document.getElementById('back').click()")
    b.wait(f"document.body.dataset.depth === '{len(picks) - 1}'")
    b.eval("pcclViewer.act('/api/step', {index: 9999}).catch(() => 0)")
    b.wait("document.getElementById('error').textContent.includes('index')")
    b.eval("document.getElementById('search-depth').value = '10'; document.getElementById('search-go').click()")
    b.wait("document.getElementById('search-result').dataset.status")
    assert b.eval("document.getElementById('search-result').dataset.status") == "violation"
    b.eval("document.getElementById('search-follow').click()")
    b.wait(f"document.body.dataset.depth === '{len(picks)}'")
    assert all(u.startswith(url) for u in b.requests), b.requests


def test_serve_page_loads_a_trace_file(browser, fischer_server, tmp_path):
    srv, session = fischer_server
    trace = tmp_path / "f.json"
    r = cli("explore", FISCHER, "--set", "k=1", "--invariant", "count(inCs) <= 1", "--trace-out", str(trace))
    assert r.exit_code == 1
    n = len(json.loads(trace.read_text())["steps"])
    b = browser
    from pccl.tools import serve as S
    b.open(S.url(srv))
    b.wait("document.body.dataset.depth === '0'")
    node = b.send("DOM.querySelector", nodeId=b.send("DOM.getDocument")["root"]["nodeId"], selector="#load-file")
    b.send("DOM.setFileInputFiles", nodeId=node["nodeId"], files=[os.fspath(trace)])
    b.wait(f"document.body.dataset.depth === '{n}'")
    # continue from one of its states: view step 5, explore from there
    b.eval("pcclViewer.goto(5); document.getElementById('here').click()")
    b.wait("document.body.dataset.depth === '5'")
    assert len(session.labels) == 5
