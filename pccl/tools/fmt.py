"""``pccl fmt``: print a PCCL (or Koord) program in one canonical layout.

The formatter works on tokens and lines, not on the AST, so that it keeps
every comment and the program's line structure (docs and traces cite line
numbers).  It changes only white space:

* indentation: two spaces per block level (levels are those the parser's
  indenter sees: a tab counts 8 columns); a line inside brackets (a
  continuation) moves with its statement;
* spacing inside a line: one space around binary operators and ``=``, after
  ``,``, ``;`` and a statement's ``:``, before a trailing ``{``; none inside
  ``()`` and ``[]``, before ``, ; : ) ]``, after a unary ``-``/``!``, between
  a function and its ``(``, around ``.`` and in ``List<T>``; section headers
  written ``allwrite:`` (no space before the colon) and ``Agent::Name``;
* comments: kept verbatim; a trailing ``//`` comment keeps its column when
  the code ends before it (aligned comments stay aligned), else it goes two
  spaces after the code; a comment-only line is indented like the code it
  sits in;
* blank lines: no trailing white space, at most one blank line in a row,
  one blank line before each section header and each event, none at the
  start or the end of the file, which ends with one newline.

:func:`format_source` checks its own work: the formatted text must parse to
the same AST as the original (spans aside) and format to itself; otherwise
it raises :class:`FormatterBug` instead of returning a changed program.

A Koord file (``.koord``, ``.krd``) gets the same treatment with Koord's
tokens and words (:func:`_koord_layout`; docs/koord.md, "Formatting"): the
check reads it through the Koord front end.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Optional

from pccl.lang.errors import PcclError
from pccl.lang.files import is_koord
from pccl.lang.koord import parse_koord
from pccl.lang.parser import parse_program

__all__ = ["format_source", "FormatterBug", "tokenize", "Tok"]

INDENT = "  "
_TAB = 8

# Token kinds
WS, NL, COMMENT, BCOMMENT, HDR, WORD, NUM, OP, BAD = (
    "ws", "nl", "comment", "bcomment", "hdr", "word", "num", "op", "bad")

# Mirrors the terminals of grammar.lark, in lark's order (priority first).
_TOKEN_RE = re.compile(r"""
  (?P<nl>\n)
| (?P<ws>[\t \f\r]+)
| (?P<comment>//[^\n]*)
| (?P<bcomment>/\*(?:[^*]|\*(?!/))*\*/)
| (?P<hdr>(?i:agent)[\t ]*::|(?i:allwrite|mw|allread|sw|local|loc|init|invariants?)[\t ]*:)
| (?P<num>(?:[0-9]+\.[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[0-9]+[eE][+-]?[0-9]+|[0-9]+)
| (?P<word>[A-Za-z_][A-Za-z0-9_]*)
| (?P<op>->|~>|\|\||&&|==|!=|<=|>=|[<>+\-*/%!=()\[\]{},:;.])
| (?P<bad>.)
""", re.VERBOSE)

#: Words that are not operands (a ``-`` after them is unary).
KEYWORDS = frozenset({"if", "else", "while", "atomic", "Atomic", "skip", "enum", "pre", "Pre",
                      "eff", "Eff", "forall", "exists", "eventually", "reachable", "within"})
_BINARY = frozenset({"->", "~>", "||", "&&", "==", "!=", "<=", ">=", "<", ">", "+", "-",
                     "*", "/", "%", "="})
_NO_SPACE_BEFORE = frozenset({",", ";", ":", ")", "]", "."})
_HDR_WORD = re.compile(r"[A-Za-z]+")


@dataclass(frozen=True)
class Tok:
    kind: str
    text: str
    line: int        # 1-based
    col: int         # 0-based offset in the line


class FormatterBug(Exception):
    """The formatted text would not mean the same program: a bug, never the
    user's fault.  The file is left as it is."""


def tokenize(text: str, pattern: Optional[re.Pattern] = None) -> list[Tok]:
    """Every token of ``text``, white space and comments included (the
    concatenation of the texts is ``text``); ``pattern``: the token regex
    (PCCL's unless given: Koord's is ``_KOORD_TOKEN_RE``)."""
    out = []
    line, line_start = 1, 0
    for m in (pattern or _TOKEN_RE).finditer(text):
        kind = m.lastgroup or BAD
        out.append(Tok(kind, m.group(), line, m.start() - line_start))
        nls = m.group().count("\n")
        if nls:
            line += nls
            line_start = m.start() + m.group().rfind("\n") + 1
    return out


def _width(ws: str) -> int:
    return ws.count(" ") + ws.count("\t") * _TAB


def _is_operand_end(t: Optional[Tok]) -> bool:
    """Whether a token ends an operand (then a following ``-`` is binary and
    a following ``(``/``[`` is a call or an index)."""
    if t is None:
        return False
    if t.kind == NUM:
        return True
    if t.kind == WORD:
        return t.text not in KEYWORDS
    return t.text in (")", "]")


def _join(toks: list[Tok], in_decls: bool) -> str:
    """The code tokens of one line, spaced canonically.  Every decision
    depends on the tokens alone, never on the white space written, so
    formatting is idempotent."""
    out: list[str] = []
    prev: Optional[Tok] = None
    prev_text = prev_prev_text = ""
    unary_pending = False       # the previous token was a unary operator
    in_decl = 0                 # tokens since the start of a declaration
    generic = 0                 # depth inside ``List<...>`` of a declaration
    for t in toks:
        text = t.text
        if t.kind == HDR:
            word = _HDR_WORD.match(text)
            text = (word.group() if word else text) + ("::" if text.endswith("::") else ":")
        generic_open = (in_decls and text == "<" and prev is not None and prev.kind == WORD
                        and (in_decl == 1 or (generic > 0 and prev_prev_text == "<")))
        generic_close = generic > 0 and text == ">"
        unary = text == "!" or (text == "-" and not _is_operand_end(prev))
        if prev is None:
            sep = ""
        elif generic_open or generic_close or (generic > 0 and prev_text == "<"):
            sep = ""
        elif unary_pending or prev_text in ("(", "[", ".") or text in _NO_SPACE_BEFORE:
            sep = ""
        elif prev.kind == HDR:
            sep = "" if prev_text.endswith("::") else " "
        elif text == "(":
            sep = "" if prev.kind == WORD and (prev.text not in KEYWORDS
                                               or prev.text in ("pre", "Pre")) else " "
        elif text == "[":
            sep = "" if _is_operand_end(prev) else " "
        else:
            sep = " "
        # never join two tokens into one (``<`` ``=``, ``a`` ``b``), nor write ``--``
        if sep == "" and prev is not None and (len(tokenize(prev_text + text)) != 2
                                               or prev_text == text == "-"):
            sep = " "
        out.append(sep)
        out.append(text)
        generic += 1 if generic_open else -1 if generic_close else 0
        unary_pending = unary
        in_decl = 0 if (text == ";" or t.kind == HDR) else in_decl + 1
        prev, prev_text, prev_prev_text = t, text, prev_text
    return "".join(out)


def format_source(source: str, filename: str = "<input>", lang: Optional[str] = None) -> str:
    """The canonical layout of ``source`` (a program that parses; a syntax
    error is raised as :class:`pccl.lang.errors.PcclError`), read as
    ``lang`` (``"pccl"``, ``"koord"``; None: ``filename``'s suffix decides)."""
    parse, layout = parse_program, _layout
    if is_koord(filename, lang):
        parse, layout = parse_koord, _koord_layout
    original = parse(source, filename)
    out = layout(source)
    try:
        again = parse(out, filename)
    except PcclError as e:
        raise FormatterBug(f"{filename}: the formatted program does not parse: {e.message}") from None
    if again != original:
        raise FormatterBug(f"{filename}: the formatted program differs from the original")
    if layout(out) != out:
        raise FormatterBug(f"{filename}: formatting is not idempotent")
    return out


def _layout(source: str) -> str:
    text = source.replace("\r\n", "\n").replace("\r", "\n")
    if text.startswith("\ufeff"):
        text = text[1:]
    lines = _physical_lines(text)
    infos = _line_infos(lines)
    levels, stacks = _block_levels(infos)
    rows = _rows(lines, infos, levels, stacks, _next_code(len(lines), levels))
    return _blank_lines(_place_comments(rows), levels)


def _physical_lines(text: str) -> list[list[Tok]]:
    """Physical lines of tokens; a multi-line block comment belongs to the
    line where it starts, and the lines it covers are not lines of their own."""
    lines: list[list[Tok]] = [[]]
    for t in tokenize(text):
        if t.kind == NL:
            lines.append([])
        else:
            lines[-1].append(t)
    return lines


def _line_infos(lines: list[list[Tok]]) -> list[tuple[int, bool, int]]:
    """Pass 1: per line, its indent width, whether it holds code, and the
    bracket depth at its start (a line inside brackets is a continuation)."""
    infos: list[tuple[int, bool, int]] = []
    depth = 0
    for lt in lines:
        indent = _width(lt[0].text) if lt and lt[0].kind == WS else 0
        code = [t for t in lt if t.kind not in (WS, COMMENT, BCOMMENT)]
        infos.append((indent, bool(code), depth))
        for t in code:
            if t.text in ("(", "[", "{"):
                depth += 1
            elif t.text in (")", "]", "}"):
                depth = max(0, depth - 1)
    return infos


def _block_levels(infos: list[tuple[int, bool, int]]) -> tuple[dict[int, int], dict[int, list[int]]]:
    """Pass 2: block levels of the lines that start a logical line, as the
    parser's indenter computes them; the open widths after each line."""
    levels: dict[int, int] = {}
    stacks: dict[int, list[int]] = {}
    stack = [0]
    for k, (indent, is_code, depth) in enumerate(infos):
        if is_code and depth == 0:
            if indent > stack[-1]:
                stack.append(indent)
            else:
                while len(stack) > 1 and indent < stack[-1]:
                    stack.pop()
            levels[k] = len(stack) - 1
        stacks[k] = list(stack)
    return levels, stacks


def _next_code(n: int, levels: dict[int, int]) -> dict[int, int]:
    """Per line, the next line that starts a logical line (-1: none)."""
    next_code: dict[int, int] = {}
    nxt = -1
    for k in range(n - 1, -1, -1):
        next_code[k] = nxt
        if k in levels:
            nxt = k
    return next_code


def _rows(lines: list[list[Tok]], infos: list[tuple[int, bool, int]], levels: dict[int, int],
          stacks: dict[int, list[int]], next_code: dict[int, int]
          ) -> list[tuple[int, str, Optional[int], Optional[str]]]:
    """Each line re-indented and formatted: (line index, text, trailing
    comment's offset from the indentation, the comment)."""
    rows: list[tuple[int, str, Optional[int], Optional[str]]] = []
    in_decls = False
    open_cols: list[int] = []   # per open bracket: the column its continuation lines start at
    for k, lt in enumerate(lines):
        indent, is_code, depth = infos[k]
        body = lt[1:] if lt and lt[0].kind == WS else lt
        if not body:
            rows.append((k, "", None, None))
            continue
        if k in levels:
            new_indent = INDENT * levels[k]
        elif is_code or depth > 0:          # a continuation inside brackets
            new_indent = " " * (open_cols[-1] if open_cols else len(INDENT) * 2)
        else:                               # a comment-only line
            new_indent = INDENT * _comment_level(indent, stacks[k], infos, next_code[k])
        first = body[0]
        if first.kind == HDR:
            in_decls = re.match(r"(?i:allwrite|mw|allread|sw|local|loc)\b", first.text) is not None
        elif k in levels and levels[k] == 0:
            in_decls = False                # an event ends the declarations
        text, comment = _format_line(body, in_decls)
        offset = None
        if comment is not None:
            c = body[-1]
            # the comment's column, from the indentation (or, after a
            # multi-line block comment, from the start of its last line)
            lead = len(lt[0].text) if lt[0].kind == WS else 0
            offset = c.col - lead if c.line == lt[0].line else c.col
        rows.append((k, new_indent + text, offset, comment))
        _track_brackets(new_indent + text, open_cols)
    return rows


def _comment_level(indent: int, stack: list[int], infos: list[tuple[int, bool, int]], j: int) -> int:
    """The block level of a comment-only line of width ``indent``, with the
    open widths ``stack`` and the next line of code ``j`` (-1: none)."""
    open_widths = list(stack)
    if j >= 0 and infos[j][0] > open_widths[-1]:
        open_widths.append(infos[j][0])
    return _level_of(indent, open_widths)


def _track_brackets(line: str, open_cols: list[int]) -> None:
    """Update the open brackets after a formatted line: a continuation line
    starts just after its bracket, or, when the bracket ends its line, four
    columns right of that line's indentation."""
    toks = [t for t in tokenize(line) if t.kind not in (WS, NL, COMMENT, BCOMMENT)]
    indent = len(line) - len(line.lstrip(" "))
    for n, t in enumerate(toks):
        if t.text in ("(", "[", "{"):
            if n + 1 < len(toks) and t.line == toks[n + 1].line:
                open_cols.append(t.col + 1)
            else:
                open_cols.append(indent + 2 * len(INDENT))
        elif t.text in (")", "]", "}") and open_cols:
            open_cols.pop()


def _level_of(indent: int, widths: list[int]) -> int:
    """The deepest open level whose width is at most ``indent``."""
    level = 0
    for k, w in enumerate(widths):
        if w <= indent:
            level = k
    return level


def _format_line(body: list[Tok], in_decls: bool) -> tuple[str, Optional[str]]:
    """One physical line without its indentation: code tokens spaced, block
    comments kept in place; a trailing ``//`` comment is returned apart."""
    parts: list[str] = []
    code: list[Tok] = []

    def flush() -> None:
        if code:
            parts.append(_join(code, in_decls))
            code.clear()

    trailing = None
    for t in body:
        if t.kind == WS:
            continue
        if t.kind == COMMENT:
            flush()
            trailing = t.text
        elif t.kind == BCOMMENT:
            flush()
            parts.append(t.text)
        else:
            code.append(t)
    flush()
    text = " ".join(parts)
    if trailing is not None and not text:
        return trailing, None
    return text, trailing


def _place_comments(rows: list[tuple[int, str, Optional[int], Optional[str]]]) -> list[tuple[int, str]]:
    """Join each trailing comment to its line: at the same distance from the
    line's indentation as it was written (so aligned comments stay aligned),
    or one space after the code when the code reaches that column."""
    out: list[tuple[int, str]] = []
    for line, text, offset, comment in rows:
        if comment is not None and offset is not None:
            indent = len(text) - len(text.lstrip(" "))
            last = text.rsplit("\n", 1)[-1]
            col = indent + offset if "\n" not in text else offset
            text = text + " " * max(1, col - len(last)) + comment
        out.extend((line, piece.rstrip()) for piece in text.split("\n"))
    return out


_EVENT_HDR = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\s*\(\s*\)\s*:")
_SECTION_HDR = re.compile(r"(?i:agent[\t ]*::|(?:allwrite|mw|allread|sw|local|loc|init|invariants?)[\t ]*:)")


def _blank_lines(out_lines: list[tuple[int, str]], levels: dict[int, int]) -> str:
    """At most one blank line in a row; one before each top-level section
    header or event (after the first code line); none at either end."""
    result: list[str] = []
    seen_code = False
    last = -1
    for k, s in out_lines:
        first_piece, last = k != last, k
        if s == "":
            if result and result[-1] != "":
                result.append("")
            continue
        top = first_piece and levels.get(k) == 0 and (_EVENT_HDR.match(s) or _SECTION_HDR.match(s))
        if top and seen_code and result and result[-1] != "":
            # a comment block directly above the header stays attached to it
            j = len(result)
            while j > 0 and result[j - 1].lstrip().startswith(("//", "/*")) \
                    and not result[j - 1].startswith(" "):
                j -= 1
            if j > 0 and result[j - 1] != "":
                result.insert(j, "")
        if levels.get(k) is not None:
            seen_code = True
        result.append(s)
    while result and result[-1] == "":
        result.pop()
    while result and result[0] == "":
        result.pop(0)
    return "\n".join(result) + "\n" if result else ""


# --------------------------------------------------------------------------
# Koord files (docs/koord.md, "Formatting")
# --------------------------------------------------------------------------

# Mirrors the terminals of koord.lark: `#` and `//` line comments, strings
# (log lines), `<<`.
_KOORD_TOKEN_RE = re.compile(r"""
  (?P<nl>\n)
| (?P<ws>[\t \f\r]+)
| (?P<comment>(?://|\#)[^\n]*)
| (?P<bcomment>/\*(?:[^*]|\*(?!/))*\*/)
| (?P<num>(?:[0-9]+\.[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[0-9]+[eE][+-]?[0-9]+|[0-9]+)
| (?P<word>[A-Za-z_][A-Za-z0-9_]*)
| (?P<op>"[^"\n]*"|<<|->|\|\||&&|==|!=|<=|>=|[<>+\-*/%!=()\[\]{},:;.])
| (?P<bad>.)
""", re.VERBOSE)

#: Koord's words that are not operands (a ``-`` or ``(`` after them starts
#: an operand of their own).
KOORD_KEYWORDS = frozenset({
    "if", "elif", "else", "for", "in", "and", "or", "not", "return", "pre", "eff", "atomic",
    "stop", "skip", "forall", "exists", "using", "def", "fun", "sensors", "actuators",
    "allwrite", "allread", "local", "init", "invariant"})
_KOORD_BINARY = frozenset({"<<", "->", "||", "&&", "==", "!=", "<=", ">=", "<", ">", "+", "-",
                           "*", "/", "%", "="})


def _koord_tokenize(text: str) -> list[Tok]:
    return tokenize(text, _KOORD_TOKEN_RE)


def _koord_operand_end(t: Optional[Tok]) -> bool:
    if t is None:
        return False
    if t.kind == NUM:
        return True
    if t.kind == WORD:
        return t.text not in KOORD_KEYWORDS
    return t.text in (")", "]") or t.text.startswith('"')


def _koord_join(toks: list[Tok]) -> str:
    """The code tokens of one Koord line, spaced canonically (from the
    tokens alone, so that formatting is idempotent): one space around binary
    operators, ``=`` and ``<<``, after ``,`` ``;`` ``:``; none inside ``()``
    and ``[]``, before ``, ; : ) ] .``, after a unary ``-``/``!``, after
    ``.``, between a name and its ``(`` or ``[``, in ``list<T>``."""
    out: list[str] = []
    prev: Optional[Tok] = None
    prev_text = ""
    unary_pending = False
    generic = 0                 # depth inside ``list<...>``
    for t in toks:
        text = t.text
        generic_open = (text == "<" and prev is not None and prev.kind == WORD
                        and prev_text in ("list", "List"))
        generic_close = generic > 0 and text == ">"
        unary = text == "!" or (text == "-" and not _koord_operand_end(prev))
        if prev is None:
            sep = ""
        elif generic_open or generic_close or (generic > 0 and prev_text == "<"):
            sep = ""
        elif unary_pending or prev_text in ("(", "[", ".") or text in _NO_SPACE_BEFORE:
            sep = ""
        elif text in ("(", "["):
            sep = "" if _koord_operand_end(prev) else " "
        else:
            sep = " "
        if sep == "" and prev is not None and (len(_koord_tokenize(prev_text + text)) != 2
                                               or prev_text == text == "-"):
            sep = " "
        out.append(sep)
        out.append(text)
        generic += 1 if generic_open else -1 if generic_close else 0
        unary_pending = unary
        prev, prev_text = t, text
    return "".join(out)


def _koord_layout(source: str) -> str:
    """A Koord program laid out: two spaces per block level (the levels
    Koord's indenter sees), a continuation line (inside brackets) four
    spaces deeper than its statement, canonical spacing inside each line,
    comments verbatim (a trailing one two spaces after the code, a
    comment-only line indented like the next line of code), no trailing
    white space, at most one blank line in a row, none at the start or the
    end, one newline at the end."""
    text = source.replace("\r\n", "\n").replace("\r", "\n")
    if text.startswith("\ufeff"):
        text = text[1:]
    lines: list[list[Tok]] = [[]]
    for t in _koord_tokenize(text):
        if t.kind == NL:
            lines.append([])
        else:
            lines[-1].append(t)
    infos = _line_infos(lines)
    levels, _ = _block_levels(infos)
    next_code = _next_code(len(lines), levels)
    rows: list[str] = []
    level = 0
    for k, lt in enumerate(lines):
        body = lt[1:] if lt and lt[0].kind == WS else lt
        body = [t for t in body if t.kind != WS or t is not body[-1]]
        if not body:
            rows.append("")
            continue
        code = [t for t in body if t.kind not in (WS, COMMENT, BCOMMENT)]
        if k in levels:
            level = levels[k]
            pad = INDENT * level
        elif code:
            pad = INDENT * level + INDENT * 2        # a continuation line
        else:
            nxt = next_code[k]
            pad = INDENT * (levels[nxt] if nxt >= 0 else 0)
        if not code:
            rows.append(pad + " ".join(t.text for t in body if t.kind != WS))
            continue
        rows.append(pad + _koord_code_line(body))
    return _koord_blank_lines(rows)


def _koord_code_line(body: list[Tok]) -> str:
    """A line of code: its tokens joined, a block comment inside it where
    it is (one space apart), a trailing comment two spaces after it."""
    trailing = ""
    if body[-1].kind == COMMENT:
        trailing = "  " + body[-1].text
        body = body[:-1]
    pieces: list[str] = []
    run: list[Tok] = []
    for t in body:
        if t.kind == BCOMMENT:
            if run:
                pieces.append(_koord_join(run))
                run = []
            pieces.append(t.text)
        elif t.kind != WS:
            run.append(t)
    if run:
        pieces.append(_koord_join(run))
    return " ".join(pieces) + trailing


def _koord_blank_lines(rows: list[str]) -> str:
    out: list[str] = []
    for r in rows:
        r = r.rstrip()
        if r == "" and (not out or out[-1] == ""):
            continue
        out.append(r)
    while out and out[-1] == "":
        out.pop()
    return "\n".join(out) + "\n" if out else ""
