"""A trace is data (issue 42, hole 1): ``pccl view`` of a trace someone sent
embeds only a file whose bytes have the recorded sha256 (found as replay
finds it), never the file a tampered ``config.program.path`` names; a page
holds no absolute path unless ``--embed-paths``.  The browser half is in
tests/output/test_viewer_untrusted_browser.py."""

from __future__ import annotations

import json
import os
import re

import pytest

from conftest import FISCHER, ROOT, cli

SECRET = "SECRET-7f3a9c-do-not-share"


def boot(path) -> dict:
    text = open(path, encoding="utf-8").read()
    m = re.search(r"window\.PCCL_BOOT = (.*?);</script>", text, re.S)
    assert m, "no PCCL_BOOT in the page"
    return json.loads(m.group(1))


@pytest.fixture(scope="module")
def fischer_trace(tmp_path_factory):
    d = tmp_path_factory.mktemp("untrusted")
    trace = d / "f.json"
    r = cli("explore", FISCHER, "--set", "k=1", "--invariant", "count(inCs) <= 1",
            "--trace-out", str(trace))
    assert r.exit_code == 1, r.output
    return json.loads(trace.read_text())


def secrets(tmp_path) -> dict:
    """Files a hostile trace may name: a private note, and a PCCL program of
    the reader's (it parses: the replay would run on it)."""
    note = tmp_path / "private" / "notes.txt"
    note.parent.mkdir()
    note.write_text(f"user:{SECRET}:1000\nsecond line {SECRET[::-1]}\n")
    prog = tmp_path / "private" / "mine.pccl"
    prog.write_text(f"// {SECRET}\n" + open(FISCHER).read())
    return {"note": note, "program": prog}


def tampered(doc: dict, target, where) -> str:
    """The trace with its program record pointing at ``target`` (its
    sha256 left as recorded: Fischer's), written to ``where``."""
    doc = json.loads(json.dumps(doc))
    doc["config"]["program"].update(path=str(target), absolute=str(target))
    doc["config"]["program"].pop("relative", None)
    where.write_text(json.dumps(doc))
    return str(where)


def assert_no_byte_of(page_bytes: bytes, secret_file) -> None:
    data = open(secret_file, "rb").read()
    assert SECRET.encode() not in page_bytes
    for line in data.splitlines():
        if len(line) > 8:
            assert line not in page_bytes, line


@pytest.mark.slow
@pytest.mark.parametrize("which", ["note", "program"])
def test_a_tampered_trace_does_not_embed_the_file_it_names(fischer_trace, tmp_path, which):
    target = secrets(tmp_path)[which]
    tr = tampered(fischer_trace, target, tmp_path / "sent.json")
    out = tmp_path / "v.html"
    r = cli("view", tr, "-o", str(out))
    assert r.exit_code == 0, r.output
    page = out.read_bytes()
    assert_no_byte_of(page, target)
    d = boot(out)["data"]
    assert d["source"] is None and d["at"] is None
    why = [n for n in d["notes"] if "source not shown" in n]
    assert why and "no file with the recorded sha256" in why[0]
    assert "source not shown" in r.stderr and "recorded sha256" in r.stderr
    # the page names no directory of the reader's
    assert str(target.parent).encode() not in page


@pytest.mark.slow
def test_replay_html_of_a_tampered_trace_shows_no_source(fischer_trace, tmp_path):
    """``pccl replay --html`` replays against the named program with a
    warning (it changed), but the page it writes does not carry it."""
    target = secrets(tmp_path)["program"]
    tr = tampered(fischer_trace, target, tmp_path / "sent.json")
    out = tmp_path / "r.html"
    r = cli("replay", tr, "--html", str(out))
    assert "has changed since the trace was recorded" in r.output
    assert_no_byte_of(out.read_bytes(), target)
    assert boot(out)["data"]["source"] is None


@pytest.mark.slow
def test_the_recorded_program_is_found_by_its_hash(fischer_trace, tmp_path):
    """A trace whose recorded path is gone but which sits next to a copy of
    its program (the same bytes) shows that copy, replayed."""
    doc = json.loads(json.dumps(fischer_trace))
    copy = tmp_path / "fischer.pccl"
    copy.write_bytes(open(FISCHER, "rb").read())
    doc["config"]["program"].update(path="elsewhere/fischer.pccl", absolute="/nowhere/fischer.pccl",
                                    relative="fischer.pccl")
    tr = tmp_path / "t.json"
    tr.write_text(json.dumps(doc))
    out = tmp_path / "v.html"
    r = cli("view", str(tr), "-o", str(out))
    assert r.exit_code == 0, r.output
    d = boot(out)["data"]
    assert d["source"]["text"] == open(FISCHER).read() and d["at"] is not None
    assert d["source"]["path"] == "fischer.pccl"        # its file name: no directory


@pytest.mark.slow
def test_pages_hold_no_absolute_path_unless_asked(fischer_trace, tmp_path):
    doc = json.loads(json.dumps(fischer_trace))
    assert os.path.isabs(doc["config"]["program"]["absolute"])
    tr = tmp_path / "t.json"
    tr.write_text(json.dumps(doc))
    out = tmp_path / "v.html"
    r = cli("view", str(tr), "-o", str(out))
    assert r.exit_code == 0, r.output
    assert str(ROOT).encode() not in out.read_bytes()
    assert boot(out)["data"]["source"]["text"] == open(FISCHER).read()
    r = cli("view", str(tr), "-o", str(out), "--embed-paths")
    assert r.exit_code == 0, r.output
    d = boot(out)["data"]
    assert d["trace"]["config"]["program"] == doc["config"]["program"]
    assert os.path.isabs(d["source"]["path"])


# ---------------------------------------------------------------------------
# hole 4: no user text reaches a template position
# ---------------------------------------------------------------------------

MARKER_PROGRAM = ROOT / "tests" / "programs" / "viewer_marker.pccl"


@pytest.mark.slow
def test_a_program_holding_the_markers_round_trips_through_its_page(tmp_path):
    out = tmp_path / "m.html"
    r = cli("explore", str(MARKER_PROGRAM), "--html", str(out))
    assert "viewer written to" in r.output, r.output
    text = out.read_text()
    d = boot(out)["data"]
    assert d["source"]["text"] == MARKER_PROGRAM.read_text()
    # the template's pieces are each there once: the script and style are not in the data
    from pccl.output import viewer
    for piece in viewer._template_parts():
        assert text.count(piece) == 1
    assert text.count("window.PCCL_BOOT = ") == 1


@pytest.mark.parametrize("nasty", ["</script><script>alert(1)</script>", "<!--", "</SCRIPT",
                                   "\u2028\u2029", "/*{{JS}}*/", "{{TITLE}}", "]]>"])
def test_data_is_escaped_for_a_script_element(nasty):
    from pccl.output import viewer
    data = {"source": {"path": "p.pccl", "text": f"x {nasty} y"}, "notes": [nasty]}
    html = viewer.page(data, title=nasty)
    m = re.search(r"window\.PCCL_BOOT = (.*?);</script>", html, re.S)
    blob = m.group(1)
    for bad in ("</", "<!--", "\u2028", "\u2029", "/*{{", "{{TITLE}}"):
        assert bad not in blob or bad in ("/*{{", "{{TITLE}}")
    assert json.loads(blob)["data"] == data
    assert html.count("<script>") == 2 and "window.PCCL_BOOT = " not in html.split("<script>")[2]
