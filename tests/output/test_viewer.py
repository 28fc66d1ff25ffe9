"""The HTML viewer (pccl/output/viewer.py) and the explorer server (pccl/tools/serve.py)
without a browser: what the page embeds, the CLI options, the JSON API.
tests/output/test_viewer_browser.py drives both in headless Chromium."""

from __future__ import annotations

import json
import re
import shutil
import threading
import urllib.error
import urllib.request

import pytest

from conftest import FISCHER, RACE_NONATOMIC, RACE_WORLD, cli


def _without_paths(doc: dict) -> dict:
    from pccl.output.viewer import _without_paths as strip
    return strip(doc)


def boot(path) -> dict:
    """The data object a viewer file embeds."""
    text = open(path, encoding="utf-8").read()
    m = re.search(r"window\.PCCL_BOOT = (.*?);</script>", text, re.S)
    assert m, "no PCCL_BOOT in the page"
    return json.loads(m.group(1))


@pytest.fixture(scope="module")
def fischer_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("fischer")
    html, trace = d / "f.html", d / "f.json"
    r = cli("explore", FISCHER, "--set", "k=1", "--invariant", "count(inCs) <= 1",
            "--html", str(html), "--trace-out", str(trace))
    assert r.exit_code == 1, r.output
    assert f"viewer written to {html}" in r.output
    return html, trace


def test_page_embeds_the_trace_document_itself(fischer_files):
    html, trace = fischer_files
    b = boot(html)
    assert b["mode"] == "static"
    d = b["data"]
    # one encoder: the trace file's (without the absolute paths: viewer._without_paths)
    assert d["trace"] == _without_paths(json.loads(trace.read_text()))
    assert d["motion"] is False                              # Fischer draws a timeline
    assert d["source"]["text"] == open(FISCHER).read()
    # the pending computations: one per agent per state, the ends as the document says
    assert len(d["at"]) == len(d["trace"]["steps"]) + 1
    assert d["at"][0] == [a["at"] for a in d["trace"]["initial"]["agents"]]
    assert d["at"][-1] == [a["at"] for a in d["trace"]["final"]["agents"]]


def test_page_is_self_contained(fischer_files):
    html, _ = fischer_files
    text = html.read_text()
    assert "Content-Security-Policy" in text and "default-src 'none'" in text
    for attr in re.findall(r"""(?:src|href)\s*=\s*["']?([^"'\s>]+)""", text):
        assert not attr.startswith(("http:", "https:", "//")), attr
    assert "<link" not in text and "@import" not in text
    assert "/*{{" not in text         # every placeholder filled


def test_script_data_cannot_close_the_script_element(tmp_path):
    """A program whose text holds </script> is embedded escaped."""
    src = tmp_path / "p.pccl"
    src.write_text(open(FISCHER).read().replace("// Fischer", "// </script><script>alert(1)</script> Fischer", 1))
    html = tmp_path / "p.html"
    r = cli("explore", str(src), "--set", "k=1", "--invariant", "count(inCs) <= 1", "--html", str(html))
    assert r.exit_code == 1, r.output
    text = html.read_text()
    assert text.count("</script>") == 2          # the two script elements of the template
    assert "alert(1)" in boot(html)["data"]["source"]["text"]


def test_arena_data_for_a_moving_program(tmp_path):
    html, trace = tmp_path / "c.html", tmp_path / "c.json"
    r = cli("explore", RACE_NONATOMIC, "--world", RACE_WORLD, "--blackbox", "nondet", "--agents", "3",
            "--html", str(html), "--trace-out", str(trace))
    assert r.exit_code == 1
    d = boot(html)["data"]
    assert d["motion"] is True
    assert d["world"] == {"arena": [[-6.0, -2.0], [7.0, 7.0]], "obstacles": [],
                          "starts": [[0.0, 0.0], [-5.0, 1.0]], "radius": 0.25}
    assert d["trace"]["result"]["violation"]["kind"] == "stuck"


def test_html_output_checked_before_the_search(tmp_path):
    r = cli("explore", FISCHER, "--set", "k=1", "--html", str(tmp_path / "no" / "x.html"))
    assert r.exit_code == 2
    assert "--html" in r.output and "does not exist" in r.output
    assert "violation" not in r.output
    r = cli("run", FISCHER, "--html", str(tmp_path))
    assert r.exit_code == 2 and "is a directory" in r.output and "--html" in r.output


def test_explore_without_counterexample_writes_no_viewer(tmp_path):
    html = tmp_path / "x.html"
    r = cli("explore", FISCHER, "--set", "k=1", "--depth", "3", "--html", str(html))
    assert r.exit_code == 0, r.output
    assert "no counterexample, so no viewer written" in r.output
    assert not html.exists()


def test_run_and_replay_write_viewers(tmp_path):
    html, trace, html2 = tmp_path / "r.html", tmp_path / "r.json", tmp_path / "r2.html"
    r = cli("run", RACE_NONATOMIC, "--world", RACE_WORLD, "--html", str(html), "--trace-out", str(trace))
    assert r.exit_code == 0, r.output
    d = boot(html)["data"]
    assert d["trace"] == _without_paths(json.loads(trace.read_text()))
    assert d["trace"]["config"]["command"] == "run" and d["motion"] is True
    r = cli("replay", str(trace), "--html", str(html2))
    assert r.exit_code == 0, r.output
    d2 = boot(html2)["data"]
    assert d2["trace"] == d["trace"] and d2["at"] == d["at"]   # replayed states, same pending computations


def test_view_a_trace_file(fischer_files, tmp_path):
    html, trace = fischer_files
    out = tmp_path / "v.html"
    r = cli("view", str(trace), "-o", str(out))
    assert r.exit_code == 0, r.output
    assert boot(out)["data"] == boot(html)["data"]      # the same page as explore's --html


def test_view_a_trace_whose_program_is_gone(fischer_files, tmp_path):
    _, trace = fischer_files
    doc = json.loads(trace.read_text())
    prog = tmp_path / "gone.pccl"
    shutil.copy(FISCHER, prog)
    doc["config"]["program"].update(path=str(prog), absolute=str(prog), relative="gone.pccl")
    moved = tmp_path / "moved.json"
    moved.write_text(json.dumps(doc))
    prog.unlink()
    out = tmp_path / "v.html"
    r = cli("view", str(moved), "-o", str(out))
    assert r.exit_code == 0, r.output
    d = boot(out)["data"]
    assert d["at"] is None and d["source"] is None
    assert any("not replayed" in n for n in d["notes"])
    assert d["trace"] == _without_paths(doc)
    assert d["trace"]["config"]["program"]["path"] == "gone.pccl"


def test_view_bad_input(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "pccl-trace", "version": 1, "steps": 5}')
    r = cli("view", str(bad), "-o", str(tmp_path / "o.html"))
    assert r.exit_code == 2
    assert "Traceback" not in r.output and "bad.json" in r.output
    r = cli("view", str(tmp_path / "missing.json"), "-o", str(tmp_path / "o.html"))
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert not (tmp_path / "o.html").exists()


# ---------------------------------------------------------------------------
# pccl serve: the session and the HTTP API
# ---------------------------------------------------------------------------

def fischer_session():
    from pccl.api import make_model
    from pccl.tools import serve as S
    from pccl.output import traces as T
    m = make_model(FISCHER, overrides={"k": "1"}, invariants=("count(inCs) <= 1",), reduce="none")
    return S.Session(m, T.config("explore", m, program=FISCHER))     # the model's options


def test_session_steps_back_and_visits():
    from pccl.tools.serve import BadRequest
    s = fischer_session()
    p = s.payload()
    assert p["explorer"]["depth"] == 0 and p["view"]["trace"]["steps"] == []
    assert p["explorer"]["n_initial"] == len(list(s.model.init_states()))
    succ = p["explorer"]["successors"]
    assert [x["rule"] for x in succ] == ["EVENT SELECT", "EVENT SELECT"]
    assert succ[0]["line"] == 30 and "pre(start)" in succ[0]["text"]
    s.step(1)
    s.step(0)
    p = s.payload()
    steps = p["view"]["trace"]["steps"]
    assert len(steps) == 2 and steps[0]["agent"] == 1 and steps[0]["rule"] == "EVENT SELECT"
    assert p["explorer"]["depth"] == 2
    s.back()
    assert len(s.labels) == 1
    with pytest.raises(BadRequest, match="index"):
        s.step(99)
    with pytest.raises(BadRequest, match="index"):
        s.step(True)
    with pytest.raises(BadRequest, match="depth"):
        s.truncate(5)
    s.truncate(0)
    with pytest.raises(BadRequest, match="initial state"):
        s.back()
    vid = [v["id"] for v in s.payload()["explorer"]["visited"] if v["depth"] == 2][0]
    s.visit(vid)
    assert len(s.labels) == 2
    with pytest.raises(BadRequest, match="id"):
        s.visit(10_000)


def test_session_search_agrees_with_explore(fischer_files):
    """The bounded search from the initial state finds the violation at the
    depth of explore's shortest (unreduced) counterexample or less."""
    _, trace = fischer_files
    s = fischer_session()
    s.load(trace.read_text())
    n = len(json.loads(trace.read_text())["steps"])
    assert len(s.labels) == n
    ex = s.payload()["explorer"]
    assert {c["name"]: c["holds"] for c in ex["checks"]}["count(inCs) <= 1"] is False
    s.truncate(0)
    res = s.search(n, 1_000_000)
    assert res["status"] == "violation" and res["path_length"] <= n
    s.follow()
    assert len(s.labels) == res["path_length"]
    assert any(not c["holds"] for c in s.payload()["explorer"]["checks"])
    s.truncate(0)
    res = s.search(3, 1_000_000)
    assert res["status"] in ("bounded", "exhaustive") and res["path_length"] == 0


def test_session_load_refuses_a_trace_of_another_model(tmp_path):
    from pccl.tools.serve import BadRequest
    trace = tmp_path / "k2.json"
    r = cli("run", RACE_NONATOMIC, "--world", RACE_WORLD, "--trace-out", str(trace))
    assert r.exit_code == 0, r.output
    s = fischer_session()
    with pytest.raises(BadRequest, match="not an initial state of this model"):
        s.load(trace.read_text())
    with pytest.raises(BadRequest, match="config: missing"):
        s.load('{"format": "pccl-trace", "version": 1, "steps": 5}')
    with pytest.raises(BadRequest, match="text"):
        s.load(None)


def test_http_api_bad_requests_never_stop_the_server():
    from pccl.tools import serve as S
    srv = S.make_server(fischer_session(), 0)
    assert srv.server_address[0] == "127.0.0.1"
    th = threading.Thread(target=srv.serve_forever, daemon=True)
    th.start()
    base = f"http://127.0.0.1:{srv.server_address[1]}"
    tok = {"X-PCCL-Token": srv.token}

    def post(path, body: bytes):
        req = urllib.request.Request(base + path, data=body, method="POST",
                                     headers={"Content-Type": "application/json", **tok})
        try:
            with urllib.request.urlopen(req, timeout=30) as r:
                return r.status, json.load(r)
        except urllib.error.HTTPError as e:
            return e.code, json.load(e)
    try:
        with urllib.request.urlopen(S.url(srv), timeout=30) as r:
            page = r.read().decode()
        assert '"mode":"serve"' in page
        assert post("/api/step", b"not json") == (400, {"error": post("/api/step", b"not json")[1]["error"]})
        assert "not JSON" in post("/api/step", b"not json")[1]["error"]
        assert post("/api/step", b"[1]")[0] == 400
        code, body = post("/api/step", b'{"index": "x"}')
        assert code == 400 and "index" in body["error"]
        assert post("/api/step", b"{}")[1]["error"] == "index: missing"
        assert post("/api/nothing", b"{}")[0] == 404
        assert post("/api/search", b'{"depth": -1}')[0] == 400
        code, body = post("/api/step", b'{"index": 0}')
        assert code == 200 and body["explorer"]["depth"] == 1
        with urllib.request.urlopen(urllib.request.Request(base + "/api/successors", headers=tok),
                                    timeout=30) as r:
            assert len(json.load(r)["successors"]) >= 1
    finally:
        srv.shutdown()
        srv.server_close()


def test_serve_cli_bad_input(tmp_path):
    r = cli("serve", str(tmp_path / "none.pccl"))
    assert r.exit_code == 2 and "Traceback" not in r.output
    r = cli("serve", FISCHER, "--port", "70000")
    assert r.exit_code == 2 and "--port" in r.output


def test_wheel_carries_the_viewer_assets():
    """Every file of pccl/output/viewer_assets is package data, and the page is
    built from the installed resources."""
    import fnmatch
    import tomllib
    from pathlib import Path
    from pccl.output import viewer
    root = Path(__file__).resolve().parents[2]
    pkg = root / "pccl" / "output"
    globs = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["pccl.output"]
    assets = sorted(p.relative_to(pkg).as_posix() for p in (pkg / "viewer_assets").iterdir())
    assert {"viewer_assets/viewer.html", "viewer_assets/viewer.js", "viewer_assets/viewer.css"} <= set(assets)
    for a in assets:
        assert any(fnmatch.fnmatch(a, g) for g in globs), a
    page = viewer.page(None, mode="serve")
    assert viewer._asset("viewer.js").strip() in page and viewer._asset("viewer.css").strip() in page
