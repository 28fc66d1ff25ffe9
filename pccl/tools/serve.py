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
``POST /api/follow``  take the path the last search found
==================  ======================================================

The model is the one ``explore`` would build from the same options, without
reductions (every transition is a real step).  A bad request is answered
with status 400 and ``{"error": message}``; nothing a client sends stops the
server.
"""

from __future__ import annotations

import json
import threading
from collections import deque
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any, Optional

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
    def __init__(self, model, cfg: dict):
        self.model = model
        self.cfg = cfg
        self.lock = threading.RLock()
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
        for name, v, lo in (("depth", depth, 0), ("max_states", max_states, 1)):
            if not isinstance(v, int) or isinstance(v, bool) or v < lo:
                raise BadRequest(f"{name}: expected an integer >= {lo}, got {v!r}")
        m = self.model
        root = self.states[-1]
        parent: dict = {m.key(root): None}
        queue = deque([(root, 0)])
        seen, found, bounded = 1, None, False
        while queue:
            st, d = queue.popleft()
            vs = list(m.violations(st))
            succ = m.successors(st)
            if not vs and not succ and m.terminal_kind(st) == "deadlock":
                vs = [m.deadlock_violation(st)]
            if vs:
                found = (st, vs[0], d)
                break
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
        if found is None:
            self.found = None
            how = "bounded: not every state within the bounds was explored" if bounded else "exhaustive"
            return {"status": "bounded" if bounded else "exhaustive", "states": seen, "path_length": 0,
                    "text": f"no violation within depth {depth} of the current state "
                            f"({seen:,} states, {how})"}
        st, v, d = found
        path_states, path_labels = [st], []
        while parent[m.key(path_states[-1])] is not None:
            prev, lab = parent[m.key(path_states[-1])]
            path_states.append(prev)
            path_labels.append(lab)
        path_states.reverse()
        path_labels.reverse()
        self.found = (self.states[:-1] + path_states, self.labels + path_labels)
        return {"status": "violation", "states": seen, "path_length": d,
                "violation": T.violation_record(m, v),
                "text": f"violation {d} steps from the current state: {v.message} ({seen:,} states searched)"}

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
        view = viewer.data(doc, model=m, states=self.states)
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


class Handler(BaseHTTPRequestHandler):
    server_version = "pccl-serve"
    session: Session
    page: bytes

    def log_message(self, format, *args):       # quiet: the terminal shows the URL only
        pass

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

    def do_POST(self):
        path = self.path.split("?", 1)[0]
        try:
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
            s = self.session
            with s.lock:
                if path == "/api/step":
                    s.step(_int_field(body, "index"))
                elif path == "/api/back":
                    s.back()
                elif path == "/api/truncate":
                    s.truncate(_int_field(body, "depth"))
                elif path == "/api/init":
                    s.start(_int_field(body, "index"))
                elif path == "/api/visit":
                    s.visit(_int_field(body, "id"))
                elif path == "/api/load":
                    s.load(body.get("text"))
                elif path == "/api/search":
                    self._json(200, s.search(body.get("depth", 20), body.get("max_states", 100_000)))
                    return
                elif path == "/api/follow":
                    s.follow()
                else:
                    self._json(404, {"error": f"no such action: {path}"})
                    return
                self._json(200, s.payload())
        except BadRequest as e:
            self._json(400, {"error": str(e)})
        except PcclError as e:                  # found while evaluating (a blackbox, a world value)
            self._json(400, {"error": e.render()})
        except Exception as e:                  # never stop the server
            self._json(500, {"error": f"internal error: {type(e).__name__}: {e}"})


def make_server(session: Session, port: int = 0, host: str = "127.0.0.1") -> ThreadingHTTPServer:
    """The server (not started: call ``serve_forever``); ``port`` 0 picks a free one."""
    from pccl.output import viewer
    title = f"pccl serve {session.cfg['program']['path']}"
    handler = type("BoundHandler", (Handler,), {
        "session": session, "page": viewer.page(None, mode="serve", title=title).encode("utf-8")})
    srv = ThreadingHTTPServer((host, port), handler)
    srv.daemon_threads = True
    return srv
