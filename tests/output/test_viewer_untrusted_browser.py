"""Issue 42, holes 1 and 4, in headless Chromium (tests/browser.py): the page
of a tampered trace renders without the file the trace names, and a program
holding the template's markers renders its own page."""

from __future__ import annotations

import json
import shutil

import pytest

from conftest import FISCHER, ROOT, cli

from browser import Browser, chromium, file_url
from test_viewer_untrusted import SECRET, secrets, tampered

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(chromium()[0] is None, reason=chromium()[1])]


@pytest.fixture(scope="module")
def browser():
    b = Browser()
    yield b
    b.close()


def rendered(b) -> dict:
    return b.eval("""(() => ({
        html: document.documentElement.outerHTML,
        text: document.body.innerText,
        title: document.getElementById('title').textContent,
        steps: +document.getElementById('slider').max,
        source: document.getElementById('source').innerText,
        data: JSON.stringify(window.PCCL_BOOT || null)}))()""")


def test_tampered_trace_page_in_chromium_holds_no_byte_of_the_named_file(browser, tmp_path):
    trace = tmp_path / "f.json"
    r = cli("explore", FISCHER, "--set", "k=1", "--invariant", "count(inCs) <= 1",
            "--trace-out", str(trace))
    assert r.exit_code == 1, r.output
    doc = json.loads(trace.read_text())
    for which, target in secrets(tmp_path).items():
        sent = tampered(doc, target, tmp_path / f"sent-{which}.json")
        out = tmp_path / f"{which}.html"
        assert cli("view", sent, "-o", str(out)).exit_code == 0
        b = browser
        b.open(file_url(out))
        assert b.exceptions() == []
        st = rendered(b)
        assert st["steps"] == len(doc["steps"])          # the trace is shown
        for field in ("html", "text", "source", "data"):
            assert SECRET not in st[field] and SECRET[::-1] not in st[field], field
        assert "source not shown" in st["text"]
        assert str(target.parent) not in st["html"]
        assert b.requests == [file_url(out)]


def test_a_program_holding_the_template_markers_renders(browser, tmp_path):
    prog = tmp_path / "viewer_marker.pccl"
    shutil.copy(ROOT / "tests" / "programs" / "viewer_marker.pccl", prog)
    out = tmp_path / "m.html"
    r = cli("explore", str(prog), "--html", str(out))
    assert "viewer written to" in r.output, r.output
    b = browser
    b.open(file_url(out))
    assert b.exceptions() == []
    st = rendered(b)
    assert st["title"] and st["steps"] > 0
    assert "/*{{JS}}*/" in st["source"] and "/*{{BOOT}}*/" in st["source"]
    assert json.loads(st["data"])["data"]["source"]["text"] == prog.read_text()
