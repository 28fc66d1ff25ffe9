"""``pccl lsp`` on Koord files (issue 47; docs/koord.md, docs/editors.md):
diagnostics at file:line:column from the Koord front end (a world file
beside the program included), hover on Koord declarations, events and
words, definitions and references, the outline, completion with Koord's
words; and once over stdio with a real client."""

from __future__ import annotations

import asyncio
import shutil
import sys
from pathlib import Path

import pytest

pytest.importorskip("pygls")
from lsprotocol import types as T  # noqa: E402
from pygls.lsp.client import LanguageClient  # noqa: E402
from pygls.uris import from_fs_path  # noqa: E402

from pccl.tools import lsp as L  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
KOORD = ROOT / "programs" / "koord"
LEADER = (KOORD / "leader.koord").read_text()


def _line_col(text: str, needle: str) -> tuple[int, int]:
    k = text.index(needle)
    return text.count("\n", 0, k), k - (text.rfind("\n", 0, k) + 1)


def test_every_shipped_koord_program_analyses_clean_with_its_world():
    for p in sorted(KOORD.glob("*.koord")):
        an = L.analyse(p.read_text(), str(p))
        assert an.diagnostics == [], (p.name, an.diagnostics)
        assert an.program is not None and an.program.language == "koord"


def test_a_koord_error_is_one_diagnostic_at_its_place():
    bad = LEADER.replace("pre:", "pre ", 1)
    an = L.analyse(bad, "/x/leader.koord")
    assert len(an.diagnostics) == 1
    d = an.diagnostics[0]
    line, col = _line_col(bad, "pre ")
    # the word after 'pre' where ':' was expected, as `pccl check` says it
    assert (d.range.line, d.range.col, d.range.end_col) == (line, col + 5, col + 8), d
    assert d.message == "unexpected 'not': expected ':'"
    # the same text read as PCCL (a .pccl name) is another error: the suffix decides
    assert L.analyse(LEADER, "/x/leader.pccl").diagnostics


def test_a_misspelt_koord_name_is_one_diagnostic_on_the_name(tmp_path):
    text = (KOORD / "add_numbers.koord").read_text().replace("sum = sum + pid", "sum = sun + pid")
    an = L.analyse(text, str(tmp_path / "a.koord"))
    assert len(an.diagnostics) == 1
    d = an.diagnostics[0]
    line, col = _line_col(text, "sun + pid")
    assert (d.range.line, d.range.col, d.range.end_col) == (line, col, col + 3), d
    assert d.message == "undeclared variable 'sun'"


def test_the_world_beside_a_koord_program(tmp_path):
    src = (KOORD / "task_alloc.koord").read_text()
    p = tmp_path / "task_alloc.koord"
    assert L.analyse(src, str(p)).diagnostics[0].message.startswith("unknown function 'taskSites'")
    shutil.copy(KOORD / "task_alloc.toml", tmp_path / "task_alloc.toml")
    assert L.world_beside(str(tmp_path / "task_alloc_racy.koord")) == str(tmp_path / "task_alloc.toml")
    assert L.analyse(src, str(p)).diagnostics == []
    (tmp_path / "task_alloc.toml").write_text("agents = 2\n[functions]\ntaskSites = [1, 2\n")
    ds = L.analyse(src, str(p)).diagnostics
    assert any(d.path.endswith("task_alloc.toml") for d in ds), ds


def test_hover_definition_references_outline_completion():
    src = (KOORD / "add_numbers.koord").read_text()
    an = L.analyse(src, "/x/add_numbers.koord")
    h = L.hover_text(an, "sum")
    assert h.startswith("```koord\nint sum = 0\n```") and "allwrite variable of type `int`" in h
    h = L.hover_text(an, "add")
    assert "add:\n  pre: not added" in h and "event" in h
    assert "getAgentIndex" in L.hover_text(an, "pid")
    assert "per-round mutex" in L.hover_text(an, "atomic")
    line, col = _line_col(src, "int sum")
    assert L.definition(an, "sum").line == line
    refs = L.references(an, "sum")
    assert len(refs) >= 4 and all(src.split("\n")[r.line][r.col:r.end_col] == "sum" for r in refs)
    names = [o.name for o in L.outline(an)]
    assert names[:4] == ["sum", "numAdded", "added", "finalSum"] and "add" in names and "total" in names
    labels = {c[0] for c in L.completions(an)}
    assert {"sum", "pid", "numAgents", "stop", "local:", "init:", "boolean", "Motion.target"} <= labels
    assert "loc:" not in labels and "Init:" not in labels


def test_motion_path_hidden_names_are_not_symbols():
    src = (KOORD / "follow_path.koord").read_text()
    an = L.analyse(src, "/x/follow_path.koord")
    assert an.diagnostics == []
    assert "Motion_path" not in an.symbols and "Motion_follow" not in an.symbols
    assert {o.name for o in L.outline(an)} == {"started", "go", "finish", "atEnd"}
    assert "waypoints" in L.hover_text(an, "path")


def test_over_stdio_a_koord_file_gets_its_diagnostic_and_hover(tmp_path):
    path = tmp_path / "leader.koord"
    bad = LEADER.replace("votes[pid] = pid", "votes[0] = pid", 1) if "votes[pid] = pid" in LEADER \
        else LEADER + "\nbroken:\n  pre: true\n  eff:\n    x[0 = 1\n"

    async def main():
        client = LanguageClient("pccl-test", "1")
        got: dict = {}
        ev = asyncio.Event()

        @client.feature(T.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS)
        def on_diagnostics(params: T.PublishDiagnosticsParams) -> None:
            got[params.uri] = list(params.diagnostics)
            ev.set()
        await client.start_io(sys.executable, "-m", "pccl.cli", "lsp", cwd=str(ROOT))
        await client.initialize_async(T.InitializeParams(capabilities=T.ClientCapabilities(),
                                                         root_uri=from_fs_path(str(tmp_path))))
        client.initialized(T.InitializedParams())
        uri = from_fs_path(str(path))
        try:
            client.text_document_did_open(T.DidOpenTextDocumentParams(
                T.TextDocumentItem(uri=uri, language_id="koord", version=1, text=bad)))
            await asyncio.wait_for(ev.wait(), 30)
            line, col = _line_col(LEADER, "pid")
            hover = await client.text_document_hover_async(T.HoverParams(
                T.TextDocumentIdentifier(uri=uri), T.Position(line=line, character=col)))
            return got[uri], hover
        finally:
            await client.shutdown_async(None)
            client.exit(None)
            await client.stop()
    diags, hover = asyncio.run(main())
    assert len(diags) == 1 and diags[0].severity == T.DiagnosticSeverity.Error, diags
    assert hover is not None and "getAgentIndex" in hover.contents.value
