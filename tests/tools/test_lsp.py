"""``pccl lsp`` (pccl/tools/lsp.py): a real client (pygls's LanguageClient) starts
``python -m pccl.cli lsp`` and speaks JSON-RPC to it over stdio; the
analysis behind the handlers is also tested on its own."""

from __future__ import annotations

import asyncio
import random
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pygls")
from lsprotocol import types as T  # noqa: E402
from pygls.lsp.client import LanguageClient  # noqa: E402
from pygls.uris import from_fs_path  # noqa: E402

from pccl.lang import ast as A  # noqa: E402
from pccl.tools import lsp as L  # noqa: E402
from pccl.lang.builtins import BUILTINS, READONLY_FLAGS  # noqa: E402
from pccl.lang.checker import check_program  # noqa: E402
from pccl.lang.errors import PcclError  # noqa: E402
from pccl.tools.fmt import format_source  # noqa: E402
from pccl.lang.parser import parse_program  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
PROPERTY_NAMES = {"time", "N", "pos", "exited", "stuck", "running"}
FISCHER = ROOT / "programs" / "fischer.pccl"
FISCHER_TEXT = FISCHER.read_text()


class Session:
    """A client connected to a server process, with the diagnostics it
    received per URI."""

    def __init__(self) -> None:
        self.client = LanguageClient("pccl-test", "1")
        self.diagnostics: dict[str, list[T.Diagnostic]] = {}
        self.events: dict[str, asyncio.Event] = {}

        self.expected: dict[str, int] = {}      # uri -> the version whose diagnostics we await

        @self.client.feature(T.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS)
        def on_diagnostics(params: T.PublishDiagnosticsParams) -> None:
            self.diagnostics[params.uri] = list(params.diagnostics)
            if params.version is None or params.version == self.expected.get(params.uri):
                self.event(params.uri).set()

    def event(self, uri: str) -> asyncio.Event:
        return self.events.setdefault(uri, asyncio.Event())

    async def start(self) -> None:
        await self.client.start_io(sys.executable, "-m", "pccl.cli", "lsp", cwd=str(ROOT))
        await self.client.initialize_async(T.InitializeParams(
            capabilities=T.ClientCapabilities(), root_uri=from_fs_path(str(ROOT))))
        self.client.initialized(T.InitializedParams())

    async def open(self, path: Path, text: str) -> str:
        uri = from_fs_path(str(path))
        self.event(uri).clear()
        self.expected[uri] = 1
        self.client.text_document_did_open(T.DidOpenTextDocumentParams(
            T.TextDocumentItem(uri=uri, language_id="pccl", version=1, text=text)))
        await asyncio.wait_for(self.event(uri).wait(), 20)
        return uri

    async def change(self, uri: str, version: int, text: str, wait: bool = True) -> None:
        self.event(uri).clear()
        self.expected[uri] = version
        self.client.text_document_did_change(T.DidChangeTextDocumentParams(
            T.VersionedTextDocumentIdentifier(uri=uri, version=version),
            [T.TextDocumentContentChangeWholeDocument(text=text)]))
        if wait:
            await asyncio.wait_for(self.event(uri).wait(), 20)

    async def stop(self) -> None:
        await self.client.shutdown_async(None)
        self.client.exit(None)
        await self.client.stop()


def run(coro_fn):
    async def main():
        s = Session()
        await s.start()
        try:
            return await coro_fn(s)
        finally:
            await s.stop()
    return asyncio.run(main())


def pos(text: str, needle: str, nth: int = 0, offset: int = 0) -> T.Position:
    """The position of the nth occurrence of needle in text (plus offset)."""
    k = -1
    for _ in range(nth + 1):
        k = text.index(needle, k + 1)
    k += offset
    line = text.count("\n", 0, k)
    return T.Position(line=line, character=k - (text.rfind("\n", 0, k) + 1))


def misspelt() -> str:
    """Fischer with `waitTime` misspelt as `waitTme` in the Wait event."""
    return FISCHER_TEXT.replace("if (c1 < waitTime):", "if (c1 < waitTme):")


# --------------------------------------------------------------------------
# Over stdio
# --------------------------------------------------------------------------

def test_misspelt_variable_one_diagnostic_at_its_range_with_a_quick_fix(tmp_path):
    text = misspelt()
    path = tmp_path / "fischer.pccl"
    # the CLI reports the same error, at the same place
    path.write_text(text)
    cli = subprocess.run([sys.executable, "-m", "pccl.cli", "check", str(path)],
                         capture_output=True, text=True)
    m = re.match(r".*:(\d+):(\d+): error: (.*)", cli.stderr)
    assert cli.returncode == 2 and m

    async def body(s: Session):
        uri = await s.open(path, text)
        diags = s.diagnostics[uri]
        assert len(diags) == 1
        d = diags[0]
        p = pos(text, "waitTme")
        assert d.range == T.Range(start=p, end=T.Position(line=p.line, character=p.character + 7))
        assert (d.range.start.line + 1, d.range.start.character + 1) == (int(m[1]), int(m[2]))
        assert d.message == m[3] == "undeclared variable 'waitTme' (did you mean 'waitTime'?)"
        assert d.severity == T.DiagnosticSeverity.Error
        actions = await s.client.text_document_code_action_async(T.CodeActionParams(
            text_document=T.TextDocumentIdentifier(uri=uri), range=d.range,
            context=T.CodeActionContext(diagnostics=[d])))
        assert len(actions) == 1 and actions[0].kind == T.CodeActionKind.QuickFix
        (edit,) = actions[0].edit.changes[uri]
        assert edit.range == d.range and edit.new_text == "waitTime"
        # applying the fix gives a program with no diagnostic
        await s.change(uri, 2, text.replace("waitTme", "waitTime"))
        assert s.diagnostics[uri] == []
        # a syntax error: one diagnostic where the parser says
        bad = text.replace("  pre(wait);", "  pre(wait;")
        await s.change(uri, 3, bad)
        (d,) = s.diagnostics[uri]
        with pytest.raises(PcclError) as e:
            parse_program(bad)
        assert (d.range.start.line + 1, d.range.start.character + 1) == (e.value.line, e.value.column)
        assert d.message == e.value.message
    run(body)


def test_hover_definition_references_symbols_completion_formatting_on_fischer():
    text = FISCHER_TEXT

    async def body(s: Session):
        uri = await s.open(FISCHER, text)
        assert s.diagnostics[uri] == []
        doc = T.TextDocumentIdentifier(uri=uri)

        async def hover(p):
            h = await s.client.text_document_hover_async(T.HoverParams(doc, p))
            return None if h is None else h.contents.value

        use = pos(text, "reqid", 2)                       # `if (reqid != -1):` in Start
        h = await hover(use)
        assert "int reqid = -1;" in h and "shared (allwrite)" in h and "line 8" in h
        h = await hover(pos(text, "waitTime", 1))         # a local with a rand initialiser
        assert "int waitTime = rand(k);" in h and "local" in h
        h = await hover(pos(text, "rand(", 0))
        assert "rand(int) -> int" in h and "0..n inclusive" in h
        h = await hover(pos(text, "Delay():", 0))
        assert "pre(delay);" in h and "event" in h
        assert await hover(pos(text, "// Fischer", 0, 3)) is None      # a comment word: nothing known

        loc = await s.client.text_document_definition_async(T.DefinitionParams(doc, use))
        decl = pos(text, "reqid", 0)
        assert loc.uri == uri and loc.range.start == decl
        assert loc.range.end == T.Position(line=decl.line, character=decl.character + 5)
        refs = await s.client.text_document_references_async(T.ReferenceParams(
            context=T.ReferenceContext(include_declaration=True), text_document=doc, position=use))
        # every `reqid` token outside comments, found by a plain scan
        expected = {(ln, m.start()) for ln, line in enumerate(text.split("\n"))
                    if not line.lstrip().startswith("//")
                    for m in re.finditer(r"\breqid\b", line)}
        assert {(r.range.start.line, r.range.start.character) for r in refs} == expected
        assert len(expected) == 5

        syms = await s.client.text_document_document_symbol_async(T.DocumentSymbolParams(doc))
        names = [x.name for x in syms]
        assert names == ["Agent::Fischer", "allwrite:", "allread:", "loc:", "Init:",
                         "Start()", "Wait()", "Assign()", "Delay()", "InCs()"]
        assert [c.name for c in syms[1].children] == ["reqid", "k", "d"]
        assert len(syms[3].children) == 11

        comp = await s.client.text_document_completion_async(T.CompletionParams(doc, use))
        labels = {i.label for i in comp.items}
        prog = check_program(parse_program(text))
        assert set(prog.variables) <= labels
        assert {"doReach", "rand", "getAgentIndex", "if", "while", "atomic", "int", "bool"} <= labels
        assert "Start" not in labels                    # events are not values

        edits = await s.client.text_document_formatting_async(T.DocumentFormattingParams(
            doc, T.FormattingOptions(tab_size=2, insert_spaces=True)))
        assert not edits                                # fischer is canonical
        messy = text.replace("  int k = 10;", "  int   k=10 ;")
        await s.change(uri, 2, messy)
        (edit,) = await s.client.text_document_formatting_async(T.DocumentFormattingParams(
            doc, T.FormattingOptions(tab_size=2, insert_spaces=True)))
        assert edit.new_text == text == format_source(messy)
    run(body)


def test_world_file_beside_the_program(tmp_path):
    prog = tmp_path / "race.pccl"
    world = tmp_path / "race.toml"
    text = (ROOT / "programs" / "race.pccl").read_text()
    prog.write_text(text)
    world.write_text("agents = 2\n[functions]\ngetInput = [[1.0, 2.0]]\ngetObs = []\nbogus = \n")

    async def body(s: Session):
        uri = await s.open(prog, text)
        wuri = from_fs_path(str(world))
        for _ in range(20):
            if wuri in s.diagnostics:
                break
            await asyncio.sleep(0.1)
        (wd,) = s.diagnostics[wuri]
        assert wd.message.startswith("invalid TOML") and wd.range.start.line == 4
        (pd,) = s.diagnostics[uri]
        assert pd.severity == T.DiagnosticSeverity.Warning and "race.toml" in pd.message
        # a world function the program uses only when the world defines it
        world.write_text("[functions]\ngetInput = [[1.0, 2.0]]\ngetObs = []\n")
        await s.change(uri, 2, text.replace("getObs()", "detour()", 1))
        (pd,) = s.diagnostics[uri]
        assert "unknown function 'detour'" in pd.message and s.diagnostics[wuri] == []
        world.write_text("[functions]\ngetInput = [[1.0, 2.0]]\ngetObs = []\ndetour = []\n")
        await s.change(uri, 3, text.replace("getObs()", "detour()", 1))
        assert s.diagnostics[uri] == [] and s.diagnostics[wuri] == []
    run(body)


@pytest.mark.slow
def test_a_thousand_random_edits_never_kill_the_server():
    rng = random.Random(26)
    pieces = ["(", ")", ":", ";", "\n", "  ", "if ", "x", "[", "]", "{", "}", "/*", "*/", "//",
              "=", "-", "pre(", "eff:", "\t", "enum ", "List<", ">", "1.5e", "\u00e9", "\\", "'"]

    async def body(s: Session):
        uri = await s.open(FISCHER, FISCHER_TEXT)
        text = FISCHER_TEXT
        doc = T.TextDocumentIdentifier(uri=uri)
        for version in range(2, 1002):
            k = rng.randrange(len(text) + 1)
            r = rng.random()
            if r < 0.4:
                text = text[:k] + rng.choice(pieces) + text[k:]
            elif r < 0.8:
                text = text[:k] + text[k + rng.randint(1, 12):]
            elif r < 0.95:
                j = rng.randrange(len(text) + 1)
                text = text[:k] + text[j:j + 40] + text[k:]
            else:
                text = FISCHER_TEXT                      # back to a good program now and then
            await s.change(uri, version, text, wait=version % 50 == 0)
            if version % 100 == 0:
                lines = text.split("\n")
                line = rng.randrange(len(lines))
                p = T.Position(line=line, character=rng.randint(0, len(lines[line])))
                await s.client.text_document_hover_async(T.HoverParams(doc, p))
                await s.client.text_document_definition_async(T.DefinitionParams(doc, p))
                await s.client.text_document_completion_async(T.CompletionParams(doc, p))
                await s.client.text_document_document_symbol_async(T.DocumentSymbolParams(doc))
                await s.client.text_document_formatting_async(T.DocumentFormattingParams(
                    doc, T.FormattingOptions(tab_size=2, insert_spaces=True)))
        # still alive, and still right: back to Fischer, no diagnostic, hover works
        await s.change(uri, 1003, FISCHER_TEXT)
        assert s.diagnostics[uri] == []
        h = await s.client.text_document_hover_async(T.HoverParams(doc, pos(FISCHER_TEXT, "reqid", 2)))
        assert "int reqid = -1;" in h.contents.value
        assert s.client.stopped is False
    run(body)


# --------------------------------------------------------------------------
# The analysis on its own
# --------------------------------------------------------------------------

def test_every_shipped_program_analyses_clean_with_its_world():
    for p in sorted((ROOT / "programs").glob("*.pccl")):
        an = L.analyse(p.read_text(), str(p))
        assert an.diagnostics == [], p
        base = p.with_suffix(".toml") if p.with_suffix(".toml").exists() else \
            p.with_name(p.stem.rpartition("_")[0] + ".toml")
        assert an.world_path == (str(base) if base.exists() else None), p
        # every occurrence's range holds the name, and every name used is declared
        lines = p.read_text().split("\n")
        bound = {q.var for q in A.walk(an.program) if isinstance(q, A.Quant)}
        for name, r in an.occurrences:
            assert lines[r.line][r.col:r.end_col] == name
            assert name in an.symbols or name in BUILTINS or name in an.info.functions \
                or name in READONLY_FLAGS or name in bound or name in PROPERTY_NAMES, name


def test_a_half_typed_program_keeps_its_last_symbols():
    good = L.analyse(FISCHER_TEXT, "f.pccl")
    half = L.analyse(FISCHER_TEXT + "\nNew():\n  pre(", "f.pccl", previous=good)
    assert half.diagnostics and half.program is good.program
    assert L.hover_text(half, "reqid") == L.hover_text(good, "reqid")


def test_enum_members_and_types_are_references():
    text = (ROOT / "programs" / "leader.pccl").read_text()
    an = L.analyse(text, "leader.pccl")
    assert an.symbols["Stage"].kind == "enum" and an.symbols["DONE"].kind == "member"
    n_done = len(re.findall(r"\bDONE\b", "\n".join(ln.split("//")[0] for ln in text.split("\n"))))
    assert len(L.references(an, "DONE")) == n_done >= 2
    assert "member 1 of enum `Stage`" in L.hover_text(an, "DONE")


def test_lsp_without_pygls_says_how_to_install(tmp_path):
    # a pygls that cannot be imported, first on the path
    (tmp_path / "pygls").mkdir()
    (tmp_path / "pygls" / "__init__.py").write_text("raise ImportError('no', name='pygls')\n")
    r = subprocess.run([sys.executable, "-c", "import sys; sys.path.insert(0, sys.argv[1]); "
                        "from pccl.cli import main; main(['lsp'])", str(tmp_path)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2
    assert "pip install -e '" in r.stderr and "[lsp]'" in r.stderr and "Traceback" not in r.stderr
