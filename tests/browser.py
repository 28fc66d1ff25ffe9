"""A headless Chromium driven over the Chrome DevTools Protocol, for the
viewer's tests (tests/output/test_viewer_browser.py).

``Browser()`` starts ``chromium --headless`` with a fresh profile and a
DevTools port chosen by Chromium, connects to its page over a websocket
(the ``websocket-client`` package) and offers ``open(url)``,
``eval(js)`` (awaits promises, returns the value), ``screenshot(path)`` and
``requests`` (every URL the page asked for, from ``Network.requestWillBeSent``).
:func:`chromium` finds the browser or says why there is none; tests skip
with that reason.
"""

from __future__ import annotations

import base64
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
import urllib.request
from typing import Any, Optional


def chromium() -> tuple[Optional[str], str]:
    """(path of the browser or None, why not)."""
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        path = shutil.which(name)
        if path:
            try:
                import websocket  # noqa: F401
            except ImportError:
                return None, "the browser tests need websocket-client: pip install -e '.[test]'"
            return path, ""
    return None, ("no Chromium on this machine: install Debian's chromium "
                  "(apt-get install -y chromium; .ci/run does) to run the browser tests")


class BrowserError(RuntimeError):
    pass


class Browser:
    def __init__(self, width: int = 1400, height: int = 1000, timeout: float = 60.0):
        import websocket
        path, why = chromium()
        if path is None:
            raise BrowserError(why)
        self.timeout = timeout
        self.profile = tempfile.mkdtemp(prefix="pccl-chromium-")
        self.proc = subprocess.Popen(
            [path, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
             "--no-first-run", "--no-default-browser-check", "--disable-extensions",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--remote-debugging-port=0", "--remote-allow-origins=*",
             f"--user-data-dir={self.profile}", f"--window-size={width},{height}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        port = self._port()
        deadline = time.monotonic() + timeout
        ws_url = None
        while ws_url is None:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as r:
                pages = [t for t in json.load(r) if t.get("type") == "page"]
            if pages:
                ws_url = pages[0]["webSocketDebuggerUrl"]
            elif time.monotonic() > deadline:
                raise BrowserError("Chromium opened no page")
            else:
                time.sleep(0.1)
        self.ws = websocket.create_connection(ws_url, timeout=timeout, suppress_origin=True)
        self._id = 0
        self.events: list = []
        self.send("Page.enable")
        self.send("Runtime.enable")
        self.send("Network.enable")
        self.console: list = []

    def _port(self) -> int:
        deadline = time.monotonic() + self.timeout
        assert self.proc.stderr is not None
        lines = []
        while time.monotonic() < deadline:
            line = self.proc.stderr.readline()
            if not line:
                if self.proc.poll() is not None:
                    raise BrowserError("Chromium exited: " + "".join(lines)[-2000:])
                continue
            lines.append(line)
            m = re.search(r"DevTools listening on ws://[^:]+:(\d+)/", line)
            if m:
                return int(m.group(1))
        raise BrowserError("Chromium did not open its DevTools port")

    def send(self, method: str, **params) -> Any:
        self._id += 1
        mid = self._id
        self.ws.send(json.dumps({"id": mid, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == mid:
                if "error" in msg:
                    raise BrowserError(f"{method}: {msg['error']}")
                return msg.get("result")
            if "method" in msg:
                self.events.append(msg)

    @property
    def requests(self) -> list:
        """The URLs of every request the page made."""
        return [e["params"]["request"]["url"] for e in self.events
                if e["method"] == "Network.requestWillBeSent"]

    def exceptions(self) -> list:
        return [e["params"]["exceptionDetails"] for e in self.events
                if e["method"] == "Runtime.exceptionThrown"]

    def open(self, url: str) -> None:
        self.events.clear()
        self.send("Page.navigate", url=url)
        self.wait("document.readyState === 'complete'")

    def eval(self, expr: str) -> Any:
        r = self.send("Runtime.evaluate", expression=expr, returnByValue=True, awaitPromise=True)
        if r.get("exceptionDetails"):
            d = r["exceptionDetails"]
            raise BrowserError(f"{expr[:80]}: {d.get('exception', {}).get('description') or d.get('text')}")
        return r["result"].get("value")

    def wait(self, cond: str, timeout: Optional[float] = None) -> Any:
        deadline = time.monotonic() + (timeout or self.timeout)
        while True:
            v = self.eval(f"!!({cond})")
            if v:
                return v
            if time.monotonic() > deadline:
                raise BrowserError(f"timed out waiting for {cond}")
            time.sleep(0.05)

    def screenshot(self, path) -> None:
        r = self.send("Page.captureScreenshot", format="png")
        with open(path, "wb") as f:
            f.write(base64.b64decode(r["data"]))

    def close(self) -> None:
        try:
            self.ws.close()
        except Exception:
            pass
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        shutil.rmtree(self.profile, ignore_errors=True)


def file_url(path) -> str:
    return "file://" + os.path.abspath(os.fspath(path))


def trace_states(doc: dict) -> list:
    """Every state of a trace document (``--trace-out``), rebuilt in Python
    from its initial state and each step's changes: what a page showing the
    trace must show (tests/output/test_viewer_browser.py,
    test_viewer_agreement.py)."""
    import copy
    out = [doc["initial"]]
    for rec in doc["steps"]:
        s = copy.deepcopy(out[-1])
        for ch in rec["changes"]:
            c = ch["cell"]
            if "agent" in c:
                ag = s["agents"][c["agent"]]
                if "var" in c:
                    ag["variables"][c["var"]] = ch["new"]
                else:
                    ag[c["cell"]] = ch["new"]
            elif "var" in c:
                s["shared"][c["var"]] = ch["new"]
            else:
                s[c["cell"]] = ch["new"]
        out.append(s)
    return out
