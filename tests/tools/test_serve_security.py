"""``pccl serve`` answers only the user's own page (issue 42, hole 2): a
per-run token, a Host check against DNS rebinding, no foreign Origin, JSON
bodies only; a search runs bounded (time, memory), can be stopped, and
leaves ``/api/state`` answering (pccl/tools/serve.py)."""

from __future__ import annotations

import http.client
import json
import threading
import time

import pytest

from conftest import FISCHER, ROOT

RUNAWAY = str(ROOT / "tests" / "programs" / "runaway.pccl")     # x grows for ever


def _session(program, **kw):
    from pccl.api import make_model
    from pccl.output import traces as T
    from pccl.tools import serve as S
    m = make_model(program, reduce="none", **({"overrides": {"k": "1"}} if program == FISCHER else {}))
    return S.Session(m, T.config("explore", m, program=program), **kw)


@pytest.fixture
def server(request):
    from pccl.tools import serve as S
    program, kw = getattr(request, "param", (FISCHER, {}))
    session = _session(program, **kw)
    srv = S.make_server(session, 0)
    th = threading.Thread(target=srv.serve_forever, kwargs={"poll_interval": 0.02}, daemon=True)
    th.start()
    yield srv, session
    session.stop()
    srv.shutdown()
    srv.server_close()


def request(srv, method, path, body=None, *, headers=None, token=True, host=None):
    """``(status, JSON body)`` of one request, with the page's headers unless
    overridden (``headers`` wins; a value None leaves the header out)."""
    port = srv.server_address[1]
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    h = {"Host": host or f"127.0.0.1:{port}"}
    if token:
        h["X-PCCL-Token"] = srv.token
    if body is not None:
        h["Content-Type"] = "application/json"
    h.update(headers or {})
    c.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
    for k, v in h.items():
        if v is not None:
            c.putheader(k, v)
    data = None if body is None else (body if isinstance(body, bytes) else json.dumps(body).encode())
    if data is not None:
        c.putheader("Content-Length", str(len(data)))
    c.endheaders(data)
    r = c.getresponse()
    raw = r.read()
    c.close()
    try:
        return r.status, json.loads(raw)
    except ValueError:
        return r.status, raw.decode("utf-8", "replace")


def test_the_page_and_api_answer_the_token_holder(server):
    srv, session = server
    from pccl.tools import serve as S
    assert S.url(srv).endswith(f"/?token={srv.token}") and len(srv.token) >= 24
    code, page = request(srv, "GET", f"/?token={srv.token}", token=False)
    assert code == 200 and f'"token":"{srv.token}"' in page
    assert request(srv, "GET", "/api/state")[0] == 200
    code, body = request(srv, "POST", "/api/step", {"index": 0})
    assert code == 200 and body["explorer"]["depth"] == 1
    port = srv.server_address[1]
    assert request(srv, "GET", "/api/state", host=f"localhost:{port}",
                   headers={"Origin": f"http://localhost:{port}"})[0] == 200


def test_a_second_server_has_another_token():
    from pccl.tools import serve as S
    a, b = (S.make_server(_session(FISCHER), 0) for _ in range(2))
    try:
        assert a.token != b.token
    finally:
        a.server_close()
        b.server_close()


@pytest.mark.parametrize("path", ["/", "/api/state", "/api/successors"])
def test_missing_or_wrong_token_is_refused(server, path):
    srv, _ = server
    code, body = request(srv, "GET", path, token=False)
    assert code == 403 and "token" in body["error"]
    code, _ = request(srv, "GET", path, token=False, headers={"X-PCCL-Token": srv.token[:-1] + "x"})
    assert code == 403
    code, _ = request(srv, "POST", "/api/step", {"index": 0}, token=False)
    assert code == 403


@pytest.mark.parametrize("host", ["evil.example:{port}", "127.0.0.1", "127.0.0.1:1", "localhost",
                                  "attacker.test"])
def test_a_foreign_host_is_refused(server, host):
    """A DNS-rebinding page reaches 127.0.0.1 under its own name."""
    srv, session = server
    port = srv.server_address[1]
    code, body = request(srv, "GET", "/api/state", host=host.format(port=port))
    assert code == 403 and "Host" in body["error"]
    code, _ = request(srv, "POST", "/api/step", {"index": 0}, host=host.format(port=port))
    assert code == 403 and session.labels == []


@pytest.mark.parametrize("origin", ["http://evil.example", "null", "http://127.0.0.1:1",
                                    "https://127.0.0.1:{port}"])
def test_a_foreign_origin_is_refused(server, origin):
    srv, session = server
    port = srv.server_address[1]
    code, body = request(srv, "POST", "/api/step", {"index": 0},
                         headers={"Origin": origin.format(port=port)})
    assert code == 403 and "Origin" in body["error"] and session.labels == []
    assert request(srv, "GET", "/api/state", headers={"Origin": origin.format(port=port)})[0] == 403


@pytest.mark.parametrize("ctype", ["text/plain", "application/x-www-form-urlencoded",
                                   "multipart/form-data; boundary=x", None])
def test_a_post_that_is_not_json_is_refused(server, ctype):
    """A page may send these anywhere without a CORS preflight."""
    srv, session = server
    code, body = request(srv, "POST", "/api/step", b'{"index": 0}', headers={"Content-Type": ctype})
    assert code == 415 and "Content-Type" in body["error"] and session.labels == []


def _search_while_polling(srv, body) -> tuple:
    """Run ``/api/search`` in a thread and poll ``/api/state`` while it runs;
    ``(search's answer, [seconds each poll took], polls made while running)``."""
    out: dict = {}

    def run():
        out["search"] = request(srv, "POST", "/api/search", body)
    th = threading.Thread(target=run)
    th.start()
    waits, during = [], 0
    time.sleep(0.3)
    while th.is_alive():
        t0 = time.perf_counter()
        code, st = request(srv, "GET", "/api/state")
        waits.append(time.perf_counter() - t0)
        assert code == 200 and "explorer" in st
        if th.is_alive():
            during += 1
        time.sleep(0.1)
    th.join()
    return out["search"], waits, during


@pytest.mark.slow
@pytest.mark.parametrize("server", [(RUNAWAY, {"search_seconds": 3.0})], indirect=True)
def test_state_answers_during_a_search_stopped_by_its_time_bound(server):
    srv, _ = server
    (code, res), waits, during = _search_while_polling(
        srv, {"depth": 10 ** 9, "max_states": 10 ** 9})
    assert code == 200, res
    assert res["status"] == "stopped" and "time limit" in res["stopped_by"]
    assert "exhaustive" not in res["text"] and res["states"] > 1
    assert during >= 3 and max(waits) < 2.0, waits


@pytest.mark.slow
def test_state_answers_during_a_search_stopped_by_its_memory_bound():
    from pccl.search.memory import rss_bytes
    from pccl.tools import serve as S
    session = _session(RUNAWAY, search_seconds=60.0, max_memory=rss_bytes() + 40 * 2 ** 20)
    srv = S.make_server(session, 0)
    threading.Thread(target=srv.serve_forever, kwargs={"poll_interval": 0.02}, daemon=True).start()
    try:
        (code, res), waits, during = _search_while_polling(
            srv, {"depth": 10 ** 9, "max_states": 10 ** 9})
        assert code == 200, res
        assert res["status"] == "stopped" and "memory limit" in res["stopped_by"], res
        assert during >= 1 and max(waits) < 2.0, waits
    finally:
        session.stop()
        srv.shutdown()
        srv.server_close()


@pytest.mark.slow
@pytest.mark.parametrize("server", [(RUNAWAY, {"search_seconds": 60.0})], indirect=True)
def test_a_search_can_be_stopped_and_only_one_runs(server):
    srv, _ = server
    out: dict = {}

    def run():
        out["search"] = request(srv, "POST", "/api/search", {"depth": 10 ** 9, "max_states": 10 ** 9})
    th = threading.Thread(target=run)
    th.start()
    time.sleep(0.5)
    code, body = request(srv, "POST", "/api/search", {"depth": 3})
    assert code == 400 and "under way" in body["error"]
    t0 = time.perf_counter()
    code, body = request(srv, "POST", "/api/search/stop", {})
    assert code == 200 and body == {"stopped": True}
    th.join(20)
    assert not th.is_alive() and time.perf_counter() - t0 < 10
    code, res = out["search"]
    assert code == 200 and res["status"] == "stopped" and res["stopped_by"] == "stopped"
    # and the next search runs
    code, res = request(srv, "POST", "/api/search", {"depth": 2})
    assert code == 200 and res["status"] == "bounded"


@pytest.mark.slow
def test_serve_prints_a_url_with_a_token_on_a_free_port():
    """The default port is a free one (0), not a fixed one."""
    import subprocess
    import sys
    p = subprocess.Popen([sys.executable, "-m", "pccl.cli", "serve", FISCHER, "--set", "k=1"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        line = p.stdout.readline()
    finally:
        p.terminate()
        p.wait(30)
    import re
    m = re.search(r"open http://127\.0\.0\.1:(\d+)/\?token=([\w-]{24,}) ", line)
    assert m, line
    assert int(m.group(1)) != 8024
