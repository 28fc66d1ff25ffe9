"""``pccl lsp``: a Language Server Protocol server for PCCL, over stdio
(pygls, lsprotocol: the ``lsp`` extra).

What it offers (docs/editors.md): diagnostics on open and on change (the
parse or check error the CLI reports, with its exact range and its
did-you-mean hint; the errors of a world file ``NAME.toml`` beside
``NAME.pccl``), hover, go to definition, find references, document
symbols, completion, formatting (:mod:`pccl.tools.fmt`) and a quick fix for a
did-you-mean.  Koord files (``.koord``, ``.krd``: docs/koord.md) are read by
the Koord front end: diagnostics (with a world file beside them), hover on
their names and on Koord's own words, definitions, references, the outline
and completion with Koord's words, and formatting (``pccl fmt``'s Koord layout).

The analysis (:class:`Analysis`, :func:`analyse`) knows nothing of the
protocol and is tested on its own; the handlers only translate.  The names
of a PCCL program are global (one name, one meaning), so hover and the
definitions work by the name under the cursor, against the last text that
parsed: a half-typed program keeps its last good symbols.  No handler lets
an exception out: a request that fails answers nothing.
"""

from __future__ import annotations

import logging
import os
import re
from dataclasses import dataclass, field
from typing import Any, Optional
from urllib.parse import unquote, urlparse

from pccl.lang import ast as A
from pccl.lang.builtins import BUILTINS, READONLY_FLAGS, Builtin
from pccl.lang.checker import CheckedProgram, check_program
from pccl.lang.errors import PcclError
from pccl.tools.fmt import HDR, tokenize

log = logging.getLogger("pccl.tools.lsp")

#: Reserved words and section headers offered by completion.
KEYWORDS = ("if", "else", "while", "atomic", "skip", "enum", "pre", "eff", "true", "false",
            "forall", "exists", "eventually", "reachable", "within")
HEADERS = ("allwrite:", "allread:", "loc:", "Init:", "invariant:")
TYPES = ("int", "bool", "float", "ItemPosition", "ObstacleList", "List")
_SECTION_WORD = {"allwrite": "shared (allwrite)", "allread": "allread (each agent's own, read by all)",
                 "loc": "local"}
#: Koord's words (completion, hover: docs/koord.md)
KOORD_KEYWORDS = ("if", "elif", "else", "atomic", "for", "in", "range", "skip", "stop", "pre",
                  "eff", "true", "false", "and", "or", "not", "pid", "numAgents", "def", "fun",
                  "return", "using", "forall", "exists")
KOORD_HEADERS = ("using Motion:", "sensors:", "actuators:", "allwrite:", "allread:", "local:",
                 "init:", "invariant:")
KOORD_TYPES = ("int", "float", "boolean", "pos", "list")
KOORD_WORDS = {
    "pid": "`pid`: this robot's id, 0 .. numAgents - 1 (PCCL's `getAgentIndex()`)",
    "numAgents": "`numAgents`: the number of robots (PCCL's `getNumAgents()`)",
    "numBots": "`numBots`: the number of robots (PCCL's `getNumAgents()`)",
    "stop": "`stop`: the robot stops for good (PCCL's `exit()`)",
    "Motion": ("module `Motion`: sensors `position`/`psn` (pos), `reached`/`done` (boolean); "
               "actuators `target` (pos: a `doReach`), `path` (pos[]: waypoint-following)"),
    "position": "`Motion.position`: this robot's position (PCCL's `getPosition()`)",
    "psn": "`Motion.psn`: this robot's position (PCCL's `getPosition()`)",
    "reached": "`Motion.reached`: the last target (or a path's last waypoint) is reached",
    "target": "`Motion.target = p`: start a motion to `p` (PCCL's `doReach(p, [])`)",
    "path": "`Motion.path = [p1, ..., pk]`: follow the waypoints in order (docs/koord.md)",
    "stdout": "`stdout << ...`: a log line (changes nothing pccl models)",
    "midpoint": "`midpoint(p, q)`: the position halfway between `p` and `q`",
    "atomic": ("`atomic:`: under Koord's round semantics a per-round mutex (one robot per round "
               "runs an atomic block)"),
}
_KOORD_HIDDEN = ("Motion_path", "Motion_follow")
_DID_YOU_MEAN = re.compile(r"\(did you mean '([A-Za-z_]\w*)'\?\)")
_WORD = re.compile(r"[A-Za-z_]\w*")


# --------------------------------------------------------------------------
# The analysis (no protocol here)
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class Range:
    """0-based, end exclusive (LSP's convention)."""
    line: int
    col: int
    end_line: int
    end_col: int

    @staticmethod
    def of(span: A.Span) -> "Range":
        return Range(span.line - 1, span.column - 1, span.end_line - 1, span.end_column - 1)


@dataclass(frozen=True)
class Diag:
    path: str               # the file it is about (the program or its world file)
    range: Range
    message: str
    severity: str = "error"     # error | warning
    suggestion: Optional[str] = None   # the did-you-mean name, if any


@dataclass
class Symbol:
    name: str
    kind: str               # variable | enum | member | event | invariant | flag
    decl: Any               # the AST node that declares it (None for flags)
    range: Range            # where the name is declared


@dataclass
class Analysis:
    path: str
    source: str
    diagnostics: list[Diag] = field(default_factory=list)
    program: Optional[A.Program] = None
    info: Optional[CheckedProgram] = None
    symbols: dict[str, Symbol] = field(default_factory=dict)
    #: every written occurrence of a name: (name, range), declarations included
    occurrences: list[tuple[str, Range]] = field(default_factory=list)
    world_path: Optional[str] = None


def world_beside(path: str) -> Optional[str]:
    """The world file of a program: ``NAME.toml`` in the program's folder,
    else that of a variant's base name (``race_safe.pccl`` -> ``race.toml``)."""
    stem, ext = os.path.splitext(path)
    if ext.lower() not in (".pccl", ".koord", ".krd"):
        return None
    folder, name = os.path.split(stem)
    while name:
        cand = os.path.join(folder, name + ".toml")
        if os.path.isfile(cand):
            return cand
        name = name.rpartition("_")[0]
    return None


def _error_diag(e: PcclError, path: str, source: str) -> Diag:
    lines = source.split("\n")
    line = max(1, e.line or 1)
    col = max(1, e.column or 1)
    text = lines[line - 1] if line <= len(lines) else ""
    if e.end_column and e.end_column > col:
        end = e.end_column
    else:                          # a word, or one character
        m = _WORD.match(text, col - 1)
        end = m.end() + 1 if m else col + 1
    m = _DID_YOU_MEAN.search(e.message)
    return Diag(e.filename if e.filename not in (None, "<input>") else path,
                Range(line - 1, col - 1, line - 1, end - 1), e.message,
                suggestion=m.group(1) if m else None)


def analyse(source: str, path: str, *, world_source: Optional[str] = None,
            previous: Optional[Analysis] = None) -> Analysis:
    """Parse and check ``source`` (the text of ``path``); load the world file
    beside it (``world_source``: its editor text, if open).  A program that
    does not parse keeps ``previous``'s symbols.  Runs with the garbage
    collector paused (:func:`pccl.lang.parser.without_gc`: its full
    collections walked every analysis the server holds)."""
    from pccl.lang.parser import without_gc
    with without_gc():
        return _analyse(source, path, world_source=world_source, previous=previous)


def _analyse(source: str, path: str, *, world_source: Optional[str] = None,
             previous: Optional[Analysis] = None) -> Analysis:
    from pccl.lang.files import is_koord_path
    from pccl.lang.koord import parse_koord
    from pccl.lang.parser import parse_program
    from pccl.lang.world import load_world, parse_world
    an = Analysis(path, source)
    parse = parse_koord if is_koord_path(path) else parse_program
    functions: frozenset[str] = frozenset()
    wpath = world_beside(path)
    if wpath is not None or world_source is not None:
        an.world_path = wpath or os.path.splitext(path)[0] + ".toml"
        try:
            w = (parse_world(world_source, an.world_path) if world_source is not None
                 else load_world(an.world_path))
            functions = frozenset(dict(w.functions).keys())
        except PcclError as e:
            d = _error_diag(e, an.world_path, world_source or _read(an.world_path))
            an.diagnostics.append(Diag(an.world_path, d.range, d.message))
            an.diagnostics.append(Diag(path, Range(0, 0, 0, 0), f"the world file beside this program, "
                                       f"{os.path.basename(an.world_path)}, has an error: {e.message}",
                                       severity="warning"))
        except Exception as e:      # noqa: BLE001 - an editor must not die of a world file
            log.exception("world file")
            an.diagnostics.append(Diag(path, Range(0, 0, 0, 0), f"cannot read the world file: {e}",
                                       severity="warning"))
    try:
        an.program = parse(source, path)
    except PcclError as e:
        an.diagnostics.append(_error_diag(e, path, source))
    except RecursionError:
        an.diagnostics.append(Diag(path, Range(0, 0, 0, 1), "program is nested too deeply"))
    if an.program is not None:
        try:
            an.info = check_program(an.program, functions=functions)
        except PcclError as e:
            an.diagnostics.append(_error_diag(e, path, source))
        except RecursionError:
            an.diagnostics.append(Diag(path, Range(0, 0, 0, 1), "program is nested too deeply"))
        _index(an)
    elif previous is not None:
        an.program, an.info = previous.program, previous.info
        an.symbols, an.occurrences = previous.symbols, previous.occurrences
    return an


def _read(path: str) -> str:
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return fh.read()
    except OSError:
        return ""


def _name_range(span: A.Span, name: str) -> Range:
    """The range of a name written at the start of ``span`` (a call)."""
    return Range(span.line - 1, span.column - 1, span.line - 1, span.column - 1 + len(name))


def _index(an: Analysis) -> None:
    """The declarations and every occurrence of each name."""
    prog = an.program
    assert prog is not None
    sym, occ = an.symbols, an.occurrences
    enums = {d.name for d in prog.decls if isinstance(d, A.EnumDecl)}

    hidden = _KOORD_HIDDEN if prog.language == "koord" else ()

    def declare(name: str, kind: str, decl: Any, span: A.Span) -> None:
        if span.line > 0 and name not in hidden:
            r = Range.of(span)
            sym.setdefault(name, Symbol(name, kind, decl, r))
            occ.append((name, r))

    for d in prog.decls:
        if isinstance(d, A.EnumDecl):
            declare(d.name, "enum", d, d.name_span)
            for m, ms in zip(d.members, d.member_spans):
                declare(m, "member", d, ms)
        else:
            declare(d.name, "variable", d, d.name_span)
            t: Optional[A.TypeRef] = d.type
            while t is not None:
                if t.name in enums and t.span.line > 0:
                    occ.append((t.name, _name_range(t.span, t.name) if t.elem is None
                                else Range.of(t.span)))
                t = t.elem
    for ev in prog.events:
        declare(ev.name, "event", ev, ev.name_span)
    for inv in prog.invariants:
        if inv.name:
            declare(inv.name, "invariant", inv, inv.name_span)
    for node in A.walk(prog):
        if isinstance(node, A.Name) and node.span.line > 0:
            occ.append((node.name, Range.of(node.span)))
        elif isinstance(node, (A.Call, A.CallStmt)) and node.span.line > 0:
            occ.append((node.name, _name_range(node.span, node.name)))


def word_at(source: str, line: int, col: int) -> Optional[tuple[str, Range]]:
    """The identifier at (0-based) ``line``/``col``, and its range."""
    lines = source.split("\n")
    if not 0 <= line < len(lines):
        return None
    text = lines[line]
    for m in _WORD.finditer(text):
        if m.start() <= col <= m.end():
            return m.group(), Range(line, m.start(), line, m.end())
    return None


def _slice(source: str, span: Optional[A.Span]) -> Optional[str]:
    """The source text of a span (lines joined), if it has one."""
    if span is None or span.line < 1:
        return None
    lines = source.split("\n")
    if span.end_line > len(lines):
        return None
    if span.line == span.end_line:
        return lines[span.line - 1][span.column - 1:span.end_column - 1]
    parts = [lines[span.line - 1][span.column - 1:]]
    parts += lines[span.line:span.end_line - 1]
    parts.append(lines[span.end_line - 1][:span.end_column - 1])
    return " ".join(p.strip() for p in parts)


def signature(b: Builtin) -> str:
    params = ", ".join(b.params[:max(b.arities)]) if b.arities else ""
    if len(b.arities) > 1:
        params += f"  ({b.arity_text()} arguments)"
    res = f" -> {b.result}" if b.result else ""
    return f"{b.name}({params}){res}"


def hover_text(an: Analysis, name: str) -> Optional[str]:
    """Markdown for the name: a variable's declaration and type, an event's
    guard, an enum, a built-in's signature and doc."""
    s = an.symbols.get(name)
    src = an.program.source if an.program is not None else an.source
    if is_koord(an):
        text = _koord_hover(an, name, s, src)
        if text is not None:
            return text
    if s is not None and s.kind == "variable":
        d: A.VarDecl = s.decl
        ty = str(an.info.variables[name].type) if an.info and name in an.info.variables else str(d.type)
        written = f"{d.type} {d.name}"
        if d.size is not None:
            written += f"[{_slice(src, d.size.span) or '…'}]"
        if d.init is not None:
            written += f" = {_slice(src, d.init.span) or '…'}"
        return (f"```pccl\n{written};\n```\n{_SECTION_WORD.get(d.section, d.section)} variable "
                f"of type `{ty}`, declared at line {s.range.line + 1}")
    if s is not None and s.kind == "event":
        ev: A.Event = s.decl
        guard = _slice(src, ev.guard.span) or "…"
        return (f"```pccl\n{ev.name}():\n  pre({guard});\n```\nevent, {len(ev.body)} "
                f"statement{'s' if len(ev.body) != 1 else ''} in its effect, line {s.range.line + 1}")
    if s is not None and s.kind in ("enum", "member"):
        e: A.EnumDecl = s.decl
        text = f"```pccl\nenum {e.name} {{ {', '.join(e.members)} }};\n```\n"
        if s.kind == "member":
            return text + f"member {e.members.index(name)} of enum `{e.name}`"
        return text + f"enum type, declared at line {s.range.line + 1}"
    if s is not None and s.kind == "invariant":
        inv: A.Invariant = s.decl
        return f"```pccl\n{name}: {_slice(src, inv.expr.span) or '…'}\n```\ninvariant"
    if name in BUILTINS:
        b = BUILTINS[name]
        where = {"statement": "statement", "expression": "function",
                 "uninterpreted": "uninterpreted function (value from the world file)",
                 "property": "property function"}[b.kind]
        return f"```pccl\n{signature(b)}\n```\nbuilt-in {where}: {b.doc}"
    if name in READONLY_FLAGS:
        return (f"```pccl\n{READONLY_FLAGS[name]} {name}\n```\nread-only flag set by the controller "
                f"after doReach")
    if an.info is not None and name in an.info.functions:
        return f"```pccl\n{name}() -> any\n```\nuninterpreted function given by the world file"
    return None


def is_koord(an: Analysis) -> bool:
    """Whether the analysis is of a Koord file."""
    from pccl.lang.files import is_koord_path
    return is_koord_path(an.path)


def _koord_hover(an: Analysis, name: str, s: Optional[Symbol], src: str) -> Optional[str]:
    """Hover in a Koord file: a declaration or an event as written in
    Koord, with its PCCL meaning; Koord's own words."""
    if s is not None and s.kind == "variable":
        d: A.VarDecl = s.decl
        ty = str(an.info.variables[name].type) if an.info and name in an.info.variables else str(d.type)
        written = _slice(src, d.span) or name
        section = {"loc": "local"}.get(d.section, d.section)
        extra = " (an array indexed by robot: `x[pid]` is this robot's entry)" if d.section == "allread" else ""
        return (f"```koord\n{written}\n```\n{section} variable of type `{ty}`{extra}, declared at "
                f"line {s.range.line + 1}")
    if s is not None and s.kind == "event":
        ev: A.Event = s.decl
        guard = _slice(src, ev.guard.span) or "…"
        return (f"```koord\n{ev.name}:\n  pre: {guard}\n```\nevent, {len(ev.body)} "
                f"statement{'s' if len(ev.body) != 1 else ''} in its effect, line {s.range.line + 1}")
    if s is None and name in KOORD_WORDS:
        return KOORD_WORDS[name]
    return None


def definition(an: Analysis, name: str) -> Optional[Range]:
    s = an.symbols.get(name)
    return s.range if s is not None else None


def references(an: Analysis, name: str, include_declaration: bool = True) -> list[Range]:
    decl = definition(an, name)
    return sorted({r for n, r in an.occurrences
                   if n == name and (include_declaration or r != decl)},
                  key=lambda r: (r.line, r.col))


@dataclass
class Outline:
    name: str
    kind: str               # section | variable | enum | event | invariant
    range: Range
    selection: Range
    children: list["Outline"] = field(default_factory=list)


def outline(an: Analysis) -> list[Outline]:
    """Sections with their declarations, the events, the invariants."""
    if an.program is None:
        return []
    if is_koord(an):
        return _koord_outline(an)
    src = an.program.source
    lines = src.split("\n")
    heads = [(t.line - 1, t) for t in tokenize(src) if t.kind == HDR and t.col == 0]
    out: list[Outline] = []
    event_lines = [ev.span.line - 1 for ev in an.program.events]
    bounds = sorted({h for h, _ in heads} | set(event_lines) | {len(lines)})
    for line, t in heads:
        end = next(b for b in bounds if b > line) - 1
        word = re.match(r"[A-Za-z]+", t.text)
        name = (word.group() if word else t.text) + (":" if not t.text.endswith("::") else "")
        if t.text.endswith("::"):
            m = _WORD.match(lines[line], len(t.text))
            name = t.text.replace(" ", "") + (m.group() if m else "")
        r = Range(line, 0, end, len(lines[end]) if end < len(lines) else 0)
        sel = Range(line, 0, line, len(t.text))
        node = Outline(name, "section", r, sel)
        for d in an.program.decls:
            if line <= d.span.line - 1 <= end:
                node.children.append(Outline(d.name, "enum" if isinstance(d, A.EnumDecl) else "variable",
                                             Range.of(d.span), Range.of(d.name_span)))
        for inv in an.program.invariants:
            if line <= inv.span.line - 1 <= end:
                node.children.append(Outline(inv.name or (_slice(src, inv.expr.span) or "invariant"),
                                             "invariant", Range.of(inv.span),
                                             Range.of(inv.name_span if inv.name else inv.expr.span)))
        out.append(node)
    for ev in an.program.events:
        out.append(Outline(f"{ev.name}()", "event", Range.of(ev.span), Range.of(ev.name_span)))
    out.sort(key=lambda o: (o.range.line, o.range.col))
    return out


def _koord_outline(an: Analysis) -> list[Outline]:
    """A Koord file's outline: its variables, events and named invariants
    (the symbols), in source order."""
    out = []
    for name, sym in an.symbols.items():
        if sym.kind in ("variable", "event", "invariant"):
            span = sym.decl.span
            out.append(Outline(name, sym.kind, Range.of(span) if span.line > 0 else sym.range,
                               sym.range))
    out.sort(key=lambda o: (o.range.line, o.range.col))
    return out


def completions(an: Analysis) -> list[tuple[str, str, str]]:
    """(label, kind, detail): the program's names, built-ins, keywords, types."""
    out: list[tuple[str, str, str]] = []
    for name, s in an.symbols.items():
        if s.kind == "event":
            continue
        detail = s.kind
        if s.kind == "variable" and an.info is not None and name in an.info.variables:
            v = an.info.variables[name]
            detail = f"{v.type} ({_SECTION_WORD.get(v.section, v.section)})"
        out.append((name, s.kind, detail))
    for name, b in BUILTINS.items():
        out.append((name, "function", signature(b)))
    for name in (an.info.functions if an.info is not None else ()):
        out.append((name, "function", f"{name}() -> any (world file)"))
    if is_koord(an):
        out += [(k, "keyword", "keyword") for k in KOORD_KEYWORDS]
        out += [(h, "keyword", "section") for h in KOORD_HEADERS]
        out += [(t, "type", "type") for t in KOORD_TYPES]
        out += [(f"Motion.{p}", "flag", KOORD_WORDS[p]) for p in ("position", "reached", "target", "path")]
        return out
    for name, ty in READONLY_FLAGS.items():
        out.append((name, "flag", f"{ty} (read-only)"))
    out += [(k, "keyword", "keyword") for k in KEYWORDS]
    out += [(h, "keyword", "section") for h in HEADERS]
    out += [(t, "type", "type") for t in TYPES]
    return out


def format_text(source: str, path: str) -> Optional[str]:
    """The formatted text, or None when the program does not parse."""
    from pccl.tools.fmt import FormatterBug, format_source
    try:
        return format_source(source, path)
    except (PcclError, FormatterBug, RecursionError):
        return None


# --------------------------------------------------------------------------
# The server (pygls)
# --------------------------------------------------------------------------

def uri_to_path(uri: str) -> str:
    p = urlparse(uri)
    return unquote(p.path) if p.scheme == "file" else uri


def _rng(r: Range) -> Any:
    from lsprotocol import types as T
    return T.Range(start=T.Position(line=r.line, character=r.col),
                   end=T.Position(line=r.end_line, character=r.end_col))


def _guarded(default: Any = None):
    """A handler ``f(params)`` as pygls calls it, ``handler(ls, params)``,
    that answers ``default`` when ``f`` raises."""
    def wrap(f):
        def handler(ls, params):
            try:
                return f(params)
            except Exception:       # noqa: BLE001 - a failed request answers nothing
                log.exception("handler %s", f.__name__)
                return default
        handler.__name__ = f.__name__
        return handler
    return wrap


#: a document of more lines than this is checked in the background thread
#: only (a request meanwhile answers from its last analysis)
SYNC_LINES = 2000
#: seconds a change waits for the next before its check starts (typing)
DEBOUNCE = 0.15


class _Checker:
    """The background checks (issue 42): a change to a document queues its
    check in one thread; a newer change of the same document cancels the
    check under way (:func:`pccl.lang.parser.cancellable`) and replaces the
    queued one, so the server keeps answering while a long document is
    checked and never spends time on a text that is gone.  The diagnostics
    are published from the server's event loop."""

    def __init__(self, session: "_Session") -> None:
        import threading
        self.session = session
        self.cv = threading.Condition()
        self.queued: dict[str, float] = {}      # uri -> when it was asked for
        self.running: Optional[tuple] = None    # (uri, its cancel event)
        self.loop: Any = None
        self.thread = threading.Thread(target=self._run, name="pccl-check", daemon=True)
        self.thread.start()

    def request(self, uri: str, changed: bool = True) -> None:
        """Queue a check of ``uri``; ``changed``: its text changed (the check
        under way is superseded), else (a request found its analysis
        stale) nothing is done when one is queued or under way."""
        import asyncio
        import time
        try:
            self.loop = asyncio.get_running_loop()
        except RuntimeError:
            pass
        with self.cv:
            running = self.running
            busy = running is not None and running[0] == uri
            if not changed and (busy or uri in self.queued):
                return
            self.queued[uri] = time.monotonic()
            if running is not None and busy and changed:
                running[1].set()                # superseded: give up the check under way
            self.cv.notify()

    def _run(self) -> None:
        import threading
        import time
        while True:
            with self.cv:
                while not self.queued:
                    self.cv.wait()
                uri, at = min(self.queued.items(), key=lambda kv: kv[1])
                wait = at + DEBOUNCE - time.monotonic()
                if wait > 0:
                    self.cv.wait(wait)
                    continue
                del self.queued[uri]
                cancel = threading.Event()
                self.running = (uri, cancel)
            try:
                self.session.check(uri, cancel, publish=self._publish)
            except Exception:       # noqa: BLE001 - the thread must go on
                log.exception("background check")
            finally:
                with self.cv:
                    self.running = None

    def _publish(self, fn) -> None:
        if self.loop is not None:
            self.loop.call_soon_threadsafe(fn)
        else:                       # no event loop (tests of the session): at once
            fn()


class _Session:
    """What the handlers share: the pygls server (its workspace holds the
    open documents) and the last analysis of each program."""

    def __init__(self, server) -> None:
        self.server = server
        self.analyses: dict[str, Analysis] = {}
        self.checker = _Checker(self)

    def doc_text(self, uri: str) -> Optional[str]:
        try:
            return self.server.workspace.get_text_document(uri).source
        except Exception:       # noqa: BLE001
            return None

    def open_text(self, path: str) -> Optional[str]:
        """The text of ``path`` if the client has it open, else None."""
        from pygls.uris import from_fs_path
        uri = from_fs_path(path) or path
        docs = self.server.workspace.text_documents
        return docs[uri].source if uri in docs else None

    def open_world_text(self, path: str) -> Optional[str]:
        return self.open_text(world_beside(path) or os.path.splitext(path)[0] + ".toml")

    def publish(self, uri: str, diagnostics: list, version: Optional[int] = None) -> None:
        from lsprotocol import types as T
        self.server.text_document_publish_diagnostics(
            T.PublishDiagnosticsParams(uri=uri, diagnostics=diagnostics, version=version))

    def refresh(self, uri: str, changed: bool = True) -> None:
        """Analyse a program and publish its diagnostics (and its world
        file's): at once for a short document, in the background thread for
        a long one (:class:`_Checker`; ``changed``: the text changed)."""
        path = uri_to_path(uri)
        if path.endswith(".toml"):
            self.refresh_world(uri, path)
            return
        source = self.doc_text(uri)
        if source is not None and source.count("\n") > SYNC_LINES:
            self.checker.request(uri, changed)
        else:
            self.refresh_program(uri, path)

    def check(self, uri: str, cancel, publish) -> None:
        """The background thread's check of ``uri`` (given up when
        ``cancel`` is set); ``publish(fn)`` runs ``fn`` on the event loop."""
        from pccl.lang.parser import ParseCancelled, cancellable
        path = uri_to_path(uri)
        source = self.doc_text(uri)
        if source is None:
            return
        version = self.server.workspace.get_text_document(uri).version
        try:
            with cancellable(cancel):
                an = analyse(source, path, world_source=self.open_world_text(path),
                             previous=self.analyses.get(uri))
        except ParseCancelled:
            return                  # a newer text is queued
        except Exception as e:          # noqa: BLE001 - the server must survive any text
            log.exception("analyse")
            an = Analysis(path, source, [Diag(path, Range(0, 0, 0, 1), f"pccl: internal error: {e}")])
        if cancel.is_set():
            return

        def done() -> None:
            if self.doc_text(uri) == source:        # still the document's text
                self.analyses[uri] = an
                self._publish_analysis(uri, path, an, version)
        publish(done)

    def refresh_world(self, uri: str, path: str) -> None:
        """A world file changed: its program's diagnostics cover it; alone,
        its own parse error."""
        from lsprotocol import types as T
        from pygls.uris import from_fs_path
        docs = self.server.workspace.text_documents
        for ext in (".pccl", ".koord", ".krd"):
            sibling = os.path.splitext(path)[0] + ext
            suri = from_fs_path(sibling) or sibling
            if suri in docs:
                self.refresh(suri)
                return
        if uri not in docs:
            return
        from pccl.lang.world import parse_world
        diags = []
        try:
            parse_world(docs[uri].source, path)
        except PcclError as e:
            d = _error_diag(e, path, docs[uri].source)
            diags.append(T.Diagnostic(range=_rng(d.range), message=d.message, source="pccl",
                                      severity=T.DiagnosticSeverity.Error))
        except Exception:       # noqa: BLE001
            log.exception("world file")
        self.publish(uri, diags)

    def refresh_program(self, uri: str, path: str) -> None:
        source = self.doc_text(uri)
        if source is None:
            return
        version = self.server.workspace.get_text_document(uri).version
        try:
            an = analyse(source, path, world_source=self.open_world_text(path),
                         previous=self.analyses.get(uri))
        except Exception as e:          # noqa: BLE001 - the server must survive any text
            log.exception("analyse")
            an = Analysis(path, source, [Diag(path, Range(0, 0, 0, 1), f"pccl: internal error: {e}")])
        self.analyses[uri] = an
        self._publish_analysis(uri, path, an, version)

    def _publish_analysis(self, uri: str, path: str, an: Analysis, version) -> None:
        from lsprotocol import types as T
        from pygls.uris import from_fs_path
        by_file: dict[str, list] = {path: []}
        if an.world_path:
            by_file.setdefault(an.world_path, [])
        for d in an.diagnostics:
            data = {"replace": d.suggestion} if d.suggestion else None
            by_file.setdefault(d.path, []).append(T.Diagnostic(
                range=_rng(d.range), message=d.message, source="pccl", data=data,
                severity=T.DiagnosticSeverity.Error if d.severity == "error"
                else T.DiagnosticSeverity.Warning))
        # the world file's first: a client that saw the program's has both
        for p, diags in sorted(by_file.items(), key=lambda kv: kv[0] == path):
            self.publish(uri if p == path else (from_fs_path(p) or p), diags,
                         version if p == path else None)

    def current(self, uri: str) -> Optional[Analysis]:
        """The analysis of the document's text; for a long document being
        checked in the background, its last one (names are global: hover
        and definitions stay right away from the edit)."""
        an = self.analyses.get(uri)
        if an is None or an.source != self.doc_text(uri):
            self.refresh(uri, changed=False)
            an = self.analyses.get(uri)
        return an

    def at(self, params: Any) -> Optional[tuple[Analysis, str, Range]]:
        """The analysis and the name (and its range) under the cursor."""
        uri = params.text_document.uri
        an = self.current(uri)
        source = self.doc_text(uri)
        if an is None or source is None:
            return None
        w = word_at(source, params.position.line, params.position.character)
        return None if w is None else (an, w[0], w[1])


def make_server():
    """A pygls server with every handler registered (pygls is imported here:
    the rest of the module works without it)."""
    from importlib.metadata import PackageNotFoundError, version

    from pygls.lsp.server import LanguageServer
    try:
        ver = version("pccl")
    except PackageNotFoundError:      # pragma: no cover - a source checkout
        ver = "0"
    server = LanguageServer("pccl", ver)
    session = _Session(server)
    _register_documents(server, session)
    _register_navigation(server, session)
    _register_edits(server, session)
    return server


def _register_documents(server, s: _Session) -> None:
    """Open, change, save, close: analyse and publish diagnostics."""
    from lsprotocol import types as T

    @server.feature(T.TEXT_DOCUMENT_DID_OPEN)
    @_guarded()
    def did_open(params: T.DidOpenTextDocumentParams) -> None:
        s.refresh(params.text_document.uri)

    @server.feature(T.TEXT_DOCUMENT_DID_CHANGE)
    @_guarded()
    def did_change(params: T.DidChangeTextDocumentParams) -> None:
        s.refresh(params.text_document.uri)

    @server.feature(T.TEXT_DOCUMENT_DID_SAVE)
    @_guarded()
    def did_save(params: T.DidSaveTextDocumentParams) -> None:
        s.refresh(params.text_document.uri)

    @server.feature(T.TEXT_DOCUMENT_DID_CLOSE)
    @_guarded()
    def did_close(params: T.DidCloseTextDocumentParams) -> None:
        s.analyses.pop(params.text_document.uri, None)


def _register_navigation(server, s: _Session) -> None:
    """Hover, go to definition, find references, document symbols."""
    from lsprotocol import types as T

    @server.feature(T.TEXT_DOCUMENT_HOVER)
    @_guarded()
    def hover(params: T.HoverParams) -> Optional[T.Hover]:
        found = s.at(params)
        if found is None:
            return None
        an, name, r = found
        text = hover_text(an, name)
        if text is None:
            return None
        return T.Hover(contents=T.MarkupContent(kind=T.MarkupKind.Markdown, value=text), range=_rng(r))

    @server.feature(T.TEXT_DOCUMENT_DEFINITION)
    @_guarded()
    def goto_definition(params: T.DefinitionParams) -> Optional[T.Location]:
        found = s.at(params)
        if found is None:
            return None
        r = definition(found[0], found[1])
        return None if r is None else T.Location(uri=params.text_document.uri, range=_rng(r))

    @server.feature(T.TEXT_DOCUMENT_REFERENCES)
    @_guarded(default=[])
    def find_references(params: T.ReferenceParams) -> list[T.Location]:
        found = s.at(params)
        if found is None:
            return []
        return [T.Location(uri=params.text_document.uri, range=_rng(r))
                for r in references(found[0], found[1], params.context.include_declaration)]

    kinds = {"section": T.SymbolKind.Namespace, "variable": T.SymbolKind.Variable,
             "enum": T.SymbolKind.Enum, "event": T.SymbolKind.Event,
             "invariant": T.SymbolKind.Boolean}

    def to_symbol(o: Outline) -> T.DocumentSymbol:
        return T.DocumentSymbol(name=o.name, kind=kinds[o.kind], range=_rng(o.range),
                                selection_range=_rng(o.selection),
                                children=[to_symbol(c) for c in o.children])

    @server.feature(T.TEXT_DOCUMENT_DOCUMENT_SYMBOL)
    @_guarded(default=[])
    def document_symbols(params: T.DocumentSymbolParams) -> list[T.DocumentSymbol]:
        an = s.current(params.text_document.uri)
        return [] if an is None else [to_symbol(o) for o in outline(an)]


def _register_edits(server, s: _Session) -> None:
    """Completion, formatting and the did-you-mean quick fix."""
    from lsprotocol import types as T

    ckinds = {"variable": T.CompletionItemKind.Variable, "enum": T.CompletionItemKind.Enum,
              "member": T.CompletionItemKind.EnumMember, "invariant": T.CompletionItemKind.Property,
              "function": T.CompletionItemKind.Function, "flag": T.CompletionItemKind.Variable,
              "keyword": T.CompletionItemKind.Keyword, "type": T.CompletionItemKind.Class}

    @server.feature(T.TEXT_DOCUMENT_COMPLETION)
    @_guarded()
    def complete(params: T.CompletionParams) -> Optional[T.CompletionList]:
        an = s.current(params.text_document.uri)
        if an is None:
            return None
        items = [T.CompletionItem(label=label, kind=ckinds.get(kind, T.CompletionItemKind.Text),
                                  detail=detail) for label, kind, detail in completions(an)]
        return T.CompletionList(is_incomplete=False, items=items)

    @server.feature(T.TEXT_DOCUMENT_FORMATTING)
    @_guarded(default=[])
    def formatting(params: T.DocumentFormattingParams) -> list[T.TextEdit]:
        uri = params.text_document.uri
        source = s.doc_text(uri)
        if source is None:
            return []
        out = format_text(source, uri_to_path(uri))
        if out is None or out == source:
            return []
        n = source.count("\n")
        last = len(source) - (source.rfind("\n") + 1)
        return [T.TextEdit(range=T.Range(start=T.Position(line=0, character=0),
                                         end=T.Position(line=n, character=last)), new_text=out)]

    @server.feature(T.TEXT_DOCUMENT_CODE_ACTION,
                    T.CodeActionOptions(code_action_kinds=[T.CodeActionKind.QuickFix]))
    @_guarded(default=[])
    def code_actions(params: T.CodeActionParams) -> list[T.CodeAction]:
        return [a for d in params.context.diagnostics
                if (a := _quick_fix(params.text_document.uri, d)) is not None]


def _quick_fix(uri: str, d: Any) -> Any:
    """The did-you-mean fix of diagnostic ``d`` (a CodeAction), or None."""
    from lsprotocol import types as T
    data = d.data if isinstance(d.data, dict) else {}
    new = data.get("replace")
    if not new:
        m = _DID_YOU_MEAN.search(d.message)
        new = m.group(1) if m else None
    if not new:
        return None
    edit = T.WorkspaceEdit(changes={uri: [T.TextEdit(range=d.range, new_text=new)]})
    return T.CodeAction(title=f"Change to '{new}'", kind=T.CodeActionKind.QuickFix,
                        diagnostics=[d], edit=edit, is_preferred=True)


_CONTENT_LENGTH = re.compile(rb"Content-Length:[ \t]*([^\r\n]*)", re.I)


async def read_frames(stop_event, reader, protocol, error) -> None:
    """pygls's stdio loop (``pygls.io_.run_async``), resynchronising after a
    malformed frame (issue 42): a ``Content-Length`` that is not a number is
    answered with a JSON-RPC parse error (``id`` null) and its body skipped
    up to the next header, which is found even when the skipped body ran
    into it without a newline (pygls lost every later frame: it only
    accepts a header line that is exactly ``Content-Length: N``); a body
    that is not JSON, or not a message, is answered likewise.  ``error(text)``
    writes such an answer."""
    import json
    length: Optional[int] = None
    bad = False
    while not stop_event.is_set():
        line = await reader.readline()
        if not line:
            break
        m = _CONTENT_LENGTH.search(line)
        if m:
            value = m.group(1).strip()
            if value.isdigit() and len(value) < 12:
                length, bad = int(value), False
            else:
                length, bad = None, True
                error(f"Content-Length: expected a number of bytes, got "
                      f"{value.decode('latin-1')[:40]!r}; frame skipped")
            continue
        if line.strip():
            continue                # another header (Content-Type), or a skipped body's line
        if length is None:
            if bad:
                bad = False         # the bad frame's body follows: skipped line by line
            continue
        body = await reader.readexactly(length) if length else b""
        length = None
        try:
            message = json.loads(body, object_hook=protocol.structure_message)
        except Exception as e:      # noqa: BLE001 - not JSON: answered, and the next frame read
            error(f"the frame's body is not a JSON-RPC message ({type(e).__name__})")
            continue
        try:
            protocol.handle_message(message)
        except Exception:           # noqa: BLE001
            log.exception("message")


def _error_writer(protocol):
    """``error(text)``: a JSON-RPC parse error (-32700, ``id`` null) on the
    protocol's writer."""
    import json

    def error(text: str) -> None:
        body = json.dumps({"jsonrpc": "2.0", "id": None,
                           "error": {"code": -32700, "message": f"pccl lsp: {text}"}}).encode()
        try:
            protocol.writer.write(b"Content-Length: %d\r\n\r\n" % len(body) + body)
        except Exception:           # noqa: BLE001 - a closed pipe: the loop ends on its own
            log.exception("write")
    return error


def serve() -> None:
    """Run the server on stdin/stdout until the client exits (pygls's
    ``start_io``, with :func:`read_frames` as the reading loop)."""
    import asyncio
    import sys
    import threading
    from pygls.io_ import StdinAsyncReader, StdoutWriter
    server = make_server()
    server._stop_event = threading.Event()
    reader = StdinAsyncReader(sys.stdin.buffer, server.thread_pool)
    server.protocol.set_writer(StdoutWriter(sys.stdout.buffer))
    try:
        asyncio.run(read_frames(server._stop_event, reader, server.protocol,
                                _error_writer(server.protocol)))
    except BrokenPipeError:
        log.error("the connection to the client is lost")
    except (KeyboardInterrupt, SystemExit):
        pass
    finally:
        server.shutdown()


__all__ = ["analyse", "Analysis", "Diag", "Range", "hover_text", "definition", "references",
           "outline", "completions", "format_text", "word_at", "make_server", "serve",
           "read_frames"]
