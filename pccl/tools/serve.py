"""``pccl serve PROGRAM``: an interactive explorer in the browser.

A :class:`Session` holds one path through the model (a list of states and
the labels between them): start from an initial state, list the enabled
transitions, take one, go back, jump to any visited state, load a trace file
and continue from any of its states, run a bounded breadth-first search from
the current state.  :func:`make_server` serves it on 127.0.0.1 (the standard
library's ``ThreadingHTTPServer``) with the viewer page of
:mod:`pccl.output.viewer` and a JSON API:

==================  ======================================================
``GET /``           the page (the viewer's template and script, ``serve`` mode)
``GET /api/state``  ``{"view": viewer data of the path, "explorer": {...}}``
``GET /api/successors``  the enabled transitions of the current state
``POST /api/step``  ``{"index": i}``: take enabled transition ``i``
``POST /api/back``  drop the last step
``POST /api/truncate``  ``{"depth": k}``: keep the first ``k`` steps
``POST /api/init``  ``{"index": i}``: restart from initial state ``i``
``POST /api/visit`` ``{"id": i}``: jump to visited state ``i``
``POST /api/load``  ``{"text": trace file text}``: follow a trace in this model
``POST /api/search``  ``{"depth", "max_states"}``: bounded search from here
``POST /api/search/stop``  stop the search under way
``POST /api/follow``  take the path the last search found
``POST /api/watch``  ``{"expr": text}``: evaluate this expression in every state
                    of the path from now on (the page's expression box)
``POST /api/unwatch``  ``{"index": i}``: stop watching expression ``i``
==================  ======================================================

The model is the one ``explore`` would build from the same options, without
reductions (every transition is a real step).  A bad request is answered
with status 400 and ``{"error": message}``; nothing a client sends stops the
server.

Only the user's own browser tab drives it (a local developer server, as
Jupyter's and Vite's): every request must carry the per-run token printed
in the URL (``?token=`` on the page's address, then the ``X-PCCL-Token``
header the page sends; 403 without it), name the server in ``Host``
(``127.0.0.1:PORT`` or ``localhost:PORT``: a DNS-rebinding page's host is
refused, 403), come from no other ``Origin`` (403), and a ``POST`` must be
``Content-Type: application/json`` (415: a form or ``text/plain`` request,
which a page may send anywhere without asking, is refused).  A search runs
under ``--max-memory`` and ``--search-seconds``, can be stopped, and does
not hold the session's lock: the state endpoints answer while it runs.
"""

from __future__ import annotations

import hmac
import json
import secrets
import threading
import time as _time
from collections import deque
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any, Optional, cast

from pccl.output import codec as C
from pccl.output import display as D
from pccl.output import traces as T
from pccl.lang.errors import PcclError
from pccl.search.explorer import Trace
from pccl.model.layout import TIME

MAX_BODY = 64 * 2**20          # a loaded trace file, at most
MAX_INITIAL = 100_000


class BadRequest(Exception):
    pass


class Session:
    """The explorer's path and its searches.  ``max_memory`` (bytes, None: no
    bound) and ``search_seconds`` (None: no bound) bound every search."""

    def __init__(self, model, cfg: dict, *, max_memory: Optional[int] = None,
                 search_seconds: Optional[float] = 60.0):
        self.model = model
        self.cfg = cfg
        self.lock = threading.RLock()
        self.max_memory = max_memory
        self.search_seconds = search_seconds
        #: held by the one search under way (not :attr:`lock`: the path stays readable)
        self.search_lock = threading.Lock()
        self.cancel = threading.Event()
        # every lazily interned table built now: a search (in its own thread)
        # and the page's requests then only read them
        prepare = getattr(model, "prepare", None)
        if prepare is not None:
            prepare()
        self.initials: list = []
        for s in model.init_states():
            self.initials.append(s)
            if len(self.initials) >= MAX_INITIAL:
                break
        if not self.initials:
            raise PcclError("the model has no initial state", filename=cfg["program"]["path"])
        self.visited: list = []          # [(states, labels)]
        self.visit_ids: dict = {}        # model.key(state) -> id
        self.found: Optional[tuple] = None
        #: the expressions the page watches (viewer.watch_values: pccl's semantics)
        self.watch: list = []
        self.initial_index = 0
        self.start(0)

    # -- the path ---------------------------------------------------------
    def start(self, index: int) -> None:
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(self.initials):
            raise BadRequest(f"index: expected an initial state 0..{len(self.initials) - 1}, got {index!r}")
        self.initial_index = index
        self.states = [self.initials[index]]
        self.labels: list = []
        self._visit()

    def _visit(self) -> None:
        k = self.model.key(self.states[-1])
        if k not in self.visit_ids:
            self.visit_ids[k] = len(self.visited)
            self.visited.append((list(self.states), list(self.labels)))
        self.current_visit = self.visit_ids[k]

    def successors(self) -> list:
        return list(self.model.successors(self.states[-1]))

    def step(self, index) -> None:
        succ = self.successors()
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(succ):
            raise BadRequest(f"index: expected an enabled transition 0..{len(succ) - 1}, got {index!r}"
                             if succ else "index: no transition is enabled in this state")
        lab, nxt = succ[index]
        self.states.append(nxt)
        self.labels.append(lab)
        self._visit()

    def back(self) -> None:
        if not self.labels:
            raise BadRequest("back: already at the initial state")
        self.truncate(len(self.labels) - 1)

    def truncate(self, depth) -> None:
        if not isinstance(depth, int) or isinstance(depth, bool) or not 0 <= depth <= len(self.labels):
            raise BadRequest(f"depth: expected 0..{len(self.labels)}, got {depth!r}")
        del self.states[depth + 1:]
        del self.labels[depth:]
        self._visit()

    def visit(self, vid) -> None:
        if not isinstance(vid, int) or isinstance(vid, bool) or not 0 <= vid < len(self.visited):
            raise BadRequest(f"id: expected a visited state 0..{len(self.visited) - 1}, got {vid!r}")
        states, labels = self.visited[vid]
        self.states, self.labels = list(states), list(labels)
        self.current_visit = vid

    def load(self, text) -> None:
        """Follow a trace document's steps in this model."""
        from pccl.output import tracecheck as TC
        if not isinstance(text, str):
            raise BadRequest("text: expected the trace file's text")
        try:
            doc = TC.check(TC.parse_bytes(text.encode("utf-8"), "trace"), "trace")
        except PcclError as e:
            raise BadRequest(e.message) from None
        if doc["initial"] is None:
            raise BadRequest("the trace holds no path")
        # the trace's states decoded (pccl/output/codec.py) and compared with the
        # model's own, as replay does
        m = self.model
        version = doc["version"]
        try:
            init = C.decode_state(m, doc["initial"], "initial")
            why = None
        except C.DecodeError as e:
            init, why = None, e.message
        i = None if init is None else next(
            (j for j, s in enumerate(self.initials) if C.matches(init, s)), None)
        if i is None:
            raise BadRequest("the trace's initial state is not an initial state of this model "
                             "(another program, world or --set?)" + (f": {why}" if why else ""))
        states, labels = [self.initials[i]], []
        keys = ("rule", "agent", "event", "line", "column", "outcome")
        for k, rec in enumerate(doc["steps"]):
            st = states[-1]
            try:
                want = C.apply_changes(m, st, rec["changes"], f"steps[{k}].changes", version)
            except C.DecodeError:
                want = None
            for lab, nxt in m.successors(st):
                r = C.encode_step_head(m, rec["index"], lab, st, nxt)
                if want is not None and all(r.get(x) == rec.get(x) for x in keys) \
                        and C.matches(want, nxt):
                    states.append(nxt)
                    labels.append(lab)
                    break
            else:
                raise BadRequest(f"steps[{rec['index'] - 1}]: step {rec['index']} "
                                 f"({rec['rule']}, line {rec.get('line')}) is not enabled in this model")
        self.initial_index = i
        self.states, self.labels = states, labels
        for k in range(len(labels) + 1):           # every state of the trace is visited
            self.states, self.labels = states[:k + 1], labels[:k]
            self._visit()

    # -- checks and search -----------------------------------------------
    def checks(self, st) -> list:
        m = self.model
        out = []
        for p in m.properties:
            try:
                ok = bool(p.fn(st))
                msg = ""
            except Exception as e:           # a property that cannot be evaluated here
                ok, msg = False, f"could not be evaluated: {e}"
            out.append({"name": p.name, "holds": ok, "message": msg})
        names = {p.name for p in m.properties}
        for v in m.violations(st):
            if v.kind != "invariant" or v.name not in names:
                out.append({"name": v.name, "holds": False, "message": v.message})
        return out

    def search(self, depth, max_states) -> dict:
        """A bounded breadth-first search from the current state, run without
        :attr:`lock` (the page's other requests are answered meanwhile), one
        at a time, stopped by :meth:`stop`, ``--search-seconds`` or
        ``--max-memory``."""
        for name, v, lo in (("depth", depth, 0), ("max_states", max_states, 1)):
            if not isinstance(v, int) or isinstance(v, bool) or v < lo:
                raise BadRequest(f"{name}: expected an integer >= {lo}, got {v!r}")
        if not self.search_lock.acquire(blocking=False):
            raise BadRequest("a search is under way: stop it first (POST /api/search/stop)")
        try:
            self.cancel.clear()
            with self.lock:
                states, labels = list(self.states), list(self.labels)
            found, seen, why = self._bfs(states[-1], depth, max_states)
            with self.lock:
                if found is None:
                    self.found = None
                else:
                    self.found = self._path(states, labels, found[0], found[3])
        finally:
            self.search_lock.release()
        m = self.model
        if found is None:
            if why == "exhaustive":
                text = "exhaustive"
            elif why == "bounded":
                text = "bounded: not every state within the bounds was explored"
            else:
                text = f"{why}: not every state within the bounds was explored"
            return {"status": why if why in ("exhaustive", "bounded") else "stopped",
                    "stopped_by": None if why in ("exhaustive", "bounded") else why,
                    "states": seen, "path_length": 0,
                    "text": f"no violation within depth {depth} of the current state "
                            f"({seen:,} states, {text})"}
        st, v, d, _ = found
        return {"status": "violation", "states": seen, "path_length": d,
                "violation": T.violation_record(m, v),
                "text": f"violation {d} steps from the current state: {v.message} ({seen:,} states searched)"}

    def stop(self) -> bool:
        """Stop the search under way (True if one was)."""
        running = self.search_lock.locked()
        self.cancel.set()
        return running

    def _limit(self, t0: float) -> Optional[str]:
        """Why the search must stop now (None: it goes on)."""
        if self.cancel.is_set():
            return "stopped"
        if self.search_seconds is not None and _time.monotonic() - t0 > self.search_seconds:
            return f"time limit ({self.search_seconds:g} s, --search-seconds)"
        if self.max_memory is not None:
            from pccl.search.memory import format_size, rss_bytes
            if rss_bytes() > self.max_memory:
                return f"memory limit ({format_size(self.max_memory)}, --max-memory)"
        return None

    def _bfs(self, root, depth: int, max_states: int) -> tuple:
        """``(found, states seen, why it ended)``: ``found`` is ``(state,
        violation, depth, parents)`` or None; why: exhaustive, bounded or
        a limit."""
        m = self.model
        parent: dict = {m.key(root): None}
        queue = deque([(root, 0)])
        seen, bounded = 1, False
        t0 = _time.monotonic()
        tick = 0
        while queue:
            tick += 1
            if tick % 64 == 0:
                why = self._limit(t0)
                if why is not None:
                    return None, seen, why
            st, d = queue.popleft()
            vs = list(m.violations(st))
            succ = m.successors(st)
            if not vs and not succ and m.terminal_kind(st) == "deadlock":
                vs = [m.deadlock_violation(st)]
            if vs:
                return (st, vs[0], d, parent), seen, "violation"
            if d >= depth:
                bounded = bounded or bool(succ)
                continue
            for lab, nxt in succ:
                k = m.key(nxt)
                if k in parent:
                    continue
                if seen >= max_states:
                    bounded = True
                    break
                parent[k] = (st, lab)
                seen += 1
                queue.append((nxt, d + 1))
        return None, seen, "bounded" if bounded else "exhaustive"

    def _path(self, states: list, labels: list, st, parent: dict) -> tuple:
        """The path from the initial state to ``st`` through the search's tree."""
        m = self.model
        path_states, path_labels = [st], []
        while parent[m.key(path_states[-1])] is not None:
            prev, lab = parent[m.key(path_states[-1])]
            path_states.append(prev)
            path_labels.append(lab)
        path_states.reverse()
        path_labels.reverse()
        return (states[:-1] + path_states, labels + path_labels)

    def add_watch(self, text) -> None:
        """Watch ``text`` (checked first: a bad expression is a BadRequest
        with its caret)."""
        if not isinstance(text, str) or len(text) > 2000:
            raise BadRequest("expr: an expression (text, at most 2,000 characters) expected")
        if len(self.watch) >= 20:
            raise BadRequest("at most 20 watched expressions")
        try:
            from pccl.output import viewer
            viewer.watch_function(self.model, text, len(self.watch))
        except PcclError as e:
            raise BadRequest(e.render()) from None
        self.watch.append(text)

    def remove_watch(self, index) -> None:
        if not 0 <= index < len(self.watch):
            raise BadRequest(f"index: no watched expression {index}")
        del self.watch[index]

    def follow(self) -> None:
        if self.found is None:
            raise BadRequest("follow: the last search found no violation")
        self.states, self.labels = list(self.found[0]), list(self.found[1])
        self._visit()

    # -- what the page reads ------------------------------------------------
    def successor_records(self) -> list:
        m, st = self.model, self.states[-1]
        out = []
        for n, (lab, nxt) in enumerate(self.successors()):
            info = D.label_info(m, lab, st)
            rec = T.step_record(m, len(self.labels) + 1, lab, st, nxt)
            who = "" if info["agent"] is None else f"agent {info['agent']}  "
            text = who + info["rule"] + (f" [{info['event']}]" if info["event"] else "")
            if info["line"] is not None:
                text += f"  line {info['line']}: {info['source'] or ''}"
            if lab[0] == "DOREACH INVOKE":
                text += f"  outcome {lab[2]}"
            if lab[0] == "TIME ADVANCE":
                text += f"  → t={D.fmt_time(nxt[TIME])}"
            br = T.branch_text(rec["branch"])
            if br:
                text += "  " + br
            out.append({"index": n, "rule": info["rule"], "agent": info["agent"], "event": info["event"],
                        "line": info["line"], "source": info["source"], "text": text,
                        "changes": T.normal(rec["changes"])})
        return out

    def payload(self) -> dict:
        from pccl.output import viewer
        m, st = self.model, self.states[-1]
        checks = self.checks(st)
        vs = list(m.violations(st))
        succ = self.successor_records()
        terminal = ""
        if not succ:
            terminal = m.terminal_kind(st)
            if terminal == "deadlock" and not vs:
                vs = [m.deadlock_violation(st)]
                checks.append({"name": "deadlock", "holds": False, "message": vs[0].message})
        doc = T.document(m, self.cfg, Trace(tuple(self.states), tuple(self.labels)),
                         status="violation" if vs else "exploring",
                         violation=vs[0] if vs else None,
                         message=vs[0].message if vs else f"exploring: depth {len(self.labels)}")
        view = viewer.data(doc, model=m, states=self.states, labels=self.labels,
                           watch=self.watch)
        visited = []
        for vid, (sts, labs) in enumerate(self.visited):
            last = sts[-1]
            visited.append({"id": vid, "depth": len(labs),
                            "text": f"t={D.fmt_time(last[TIME])}" +
                                    (f" after {D.label_info(m, labs[-1], sts[-2])['rule']}" if labs else
                                     " initial")})
        return {"view": view,
                "explorer": {"depth": len(self.labels), "initial_index": self.initial_index,
                             "n_initial": len(self.initials), "successors": succ, "checks": checks,
                             "terminal": terminal, "visited": visited, "current_visit": self.current_visit}}


def _int_field(body: dict, name: str) -> Any:
    if name not in body:
        raise BadRequest(f"{name}: missing")
    return body[name]


class Refused(Exception):
    """A request not from the user's page: ``(status, message)``."""


class Handler(BaseHTTPRequestHandler):
    server_version = "pccl-serve"
    session: Session
    page: bytes
    token: str

    def log_message(self, format, *args):       # quiet: the terminal shows the URL only
        pass

    def _origins(self) -> tuple:
        port = cast(tuple, self.server.server_address)[1]
        return (f"127.0.0.1:{port}", f"localhost:{port}")

    def _check(self, post: bool) -> None:
        """Refused unless the request is the page's: the token, the Host,
        no foreign Origin, a JSON body for a POST."""
        hosts = self._origins()
        host = (self.headers.get("Host") or "").strip().lower()
        if host not in hosts:
            raise Refused(403, f"Host {host or '(none)'!r} refused: this server answers "
                               f"{' or '.join(hosts)} only")
        origin = self.headers.get("Origin")
        if origin is not None and origin.strip().lower() not in {f"http://{h}" for h in hosts}:
            raise Refused(403, f"Origin {origin!r} refused")
        given = self.headers.get("X-PCCL-Token") or _query(self.path).get("token") or ""
        if not hmac.compare_digest(given.encode(), self.token.encode()):
            raise Refused(403, "missing or wrong token: open the URL pccl serve printed "
                               "(it ends with ?token=...)")
        if post:
            ctype = (self.headers.get("Content-Type") or "").split(";")[0].strip().lower()
            if ctype != "application/json":
                raise Refused(415, f"Content-Type {ctype or '(none)'!r} refused: "
                                   f"a request's body is application/json")

    def _send(self, code: int, body: bytes, ctype: str) -> None:
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def _json(self, code: int, obj) -> None:
        self._send(code, json.dumps(obj, default=str).encode("utf-8"), "application/json")

    def do_GET(self):
        path = self.path.split("?", 1)[0]
        try:
            self._check(post=False)
        except Refused as e:
            self._json(e.args[0], {"error": e.args[1]})
            return
        try:
            if path in ("/", "/index.html"):
                self._send(200, self.page, "text/html; charset=utf-8")
            elif path == "/api/state":
                with self.session.lock:
                    self._json(200, self.session.payload())
            elif path == "/api/successors":
                with self.session.lock:
                    self._json(200, {"successors": self.session.successor_records()})
            else:
                self._json(404, {"error": f"no such page: {path}"})
        except Exception as e:                  # never stop the server
            self._json(500, {"error": f"internal error: {type(e).__name__}: {e}"})

    def _body(self) -> dict:
        """The request's JSON object (BadRequest otherwise)."""
        n = int(self.headers.get("Content-Length") or 0)
        if n < 0 or n > MAX_BODY:
            raise BadRequest(f"the request body must be at most {MAX_BODY} bytes")
        raw = self.rfile.read(n) if n else b"{}"
        try:
            body = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as e:
            raise BadRequest(f"the request body is not JSON: {e}") from None
        if not isinstance(body, dict):
            raise BadRequest("the request body must be a JSON object")
        return body

    def do_POST(self):
        path = self.path.split("?", 1)[0]
        try:
            self._check(post=True)
        except Refused as e:
            self._json(e.args[0], {"error": e.args[1]})
            self.close_connection = True
            return
        try:
            body = self._body()
            s = self.session
            if path == "/api/search":        # not under the lock: the page stays answered
                self._json(200, s.search(body.get("depth", 20), body.get("max_states", 100_000)))
                return
            if path == "/api/search/stop":
                self._json(200, {"stopped": s.stop()})
                return
            action = _ACTIONS.get(path)
            if action is None:
                self._json(404, {"error": f"no such action: {path}"})
                return
            with s.lock:
                action(s, body)
                self._json(200, s.payload())
        except BadRequest as e:
            self._json(400, {"error": str(e)})
        except PcclError as e:                  # found while evaluating (a blackbox, a world value)
            self._json(400, {"error": e.render()})
        except Exception as e:                  # never stop the server
            self._json(500, {"error": f"internal error: {type(e).__name__}: {e}"})


#: The actions on the path (POST, under the session's lock): path -> fn(session, body).
_ACTIONS = {
    "/api/step": lambda s, b: s.step(_int_field(b, "index")),
    "/api/back": lambda s, b: s.back(),
    "/api/truncate": lambda s, b: s.truncate(_int_field(b, "depth")),
    "/api/init": lambda s, b: s.start(_int_field(b, "index")),
    "/api/visit": lambda s, b: s.visit(_int_field(b, "id")),
    "/api/load": lambda s, b: s.load(b.get("text")),
    "/api/follow": lambda s, b: s.follow(),
    "/api/watch": lambda s, b: s.add_watch(b.get("expr")),
    "/api/unwatch": lambda s, b: s.remove_watch(_int_field(b, "index")),
}


def _query(path: str) -> dict:
    from urllib.parse import parse_qs
    q = parse_qs(path.partition("?")[2])
    return {k: v[0] for k, v in q.items() if v}


def make_server(session: Session, port: int = 0, host: str = "127.0.0.1",
                token: Optional[str] = None) -> ThreadingHTTPServer:
    """The server (not started: call ``serve_forever``); ``port`` 0 picks a
    free one; ``token`` (default: a new random one, ``srv.token``) is what
    every request must carry; :func:`url` is the address to open."""
    import os
    from pccl.output import viewer
    token = token or secrets.token_urlsafe(24)
    title = f"pccl serve {os.path.basename(str(session.cfg['program']['path']))}"
    handler = type("BoundHandler", (Handler,), {
        "session": session, "token": token,
        "page": viewer.page(None, mode="serve", title=title,
                            boot={"token": token}).encode("utf-8")})
    srv = ThreadingHTTPServer((host, port), handler)
    srv.daemon_threads = True
    srv.token = token           # type: ignore[attr-defined]
    return srv


def url(srv: ThreadingHTTPServer) -> str:
    """The address to open: the page with the run's token."""
    host, port = srv.server_address[:2]
    if isinstance(host, bytes):         # typeshed: an AF_UNIX address; never for this server
        host = host.decode()
    return f"http://{host}:{port}/?token={srv.token}"   # type: ignore[attr-defined]
