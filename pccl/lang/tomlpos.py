"""Positions in TOML text: where a key, a table header or an array element
is written.

``tomllib`` decodes TOML but gives no positions, and a message about a world
file must put a caret under the offending key or value.  :class:`TomlSource`
re-reads the text just enough for that: it finds the line of ``key`` in
``[table]`` (or in the ``index``-th ``[[table]]``), the column where its value
starts and ends, and the element at a path of array indexes inside the value,
across lines, strings and comments.  It decodes nothing: the values come from
``tomllib``; this module only says where they are written.

Used by :mod:`pccl.lang.world` (the world checker).  All lines and columns are
1-based, end columns exclusive (as :class:`pccl.lang.ast.Span`).
"""

from __future__ import annotations

import bisect
import re
from typing import NamedTuple, Optional

__all__ = ["TomlSource", "Where", "decode_error_location", "long_integer_location"]


class Where(NamedTuple):
    """A place in the text: one line, columns [column, end_column)."""
    line: int
    column: int
    end_column: int


class TomlSource:
    """The text of one TOML document, for locating what ``tomllib`` read."""

    def __init__(self, source: str):
        self.source = source
        self.lines = source.splitlines()

    def locate(self, table: Optional[str], key: str, index: int = 0, *,
               at_value: bool = True, path: tuple = ()) -> Optional[Where]:
        """Where ``key`` of ``[table]`` (None: the top level; the ``index``-th
        ``[[table]]``) is written: its value when ``at_value`` (the element
        at ``path``, a tuple of array indexes, inside the value), else the
        key itself.  A key that is not written (a table given as a header)
        locates its header; None when nothing is found."""
        found = self.find(table, key, index)
        if not found:
            return None
        line, kcol, kend, vcol = found
        if not at_value or vcol is None:
            return Where(line, kcol, kend)
        if path:
            elem = self.element(line, vcol, path)
            if elem:
                return Where(*elem)
        return Where(line, vcol, self.value_end(line, vcol))

    def find(self, table: Optional[str], key: str, index: int = 0):
        """(line, key column, key end column, value column) of ``key`` in
        ``[table]`` (or the ``index``-th ``[[table]]``; None = top level)."""
        current: Optional[str] = None
        count = -1
        key_re = re.compile(r"^(\s*)([\"']?)" + re.escape(key) + r"\2\s*=\s*")
        for no, text in self.logical_lines():
            hdr = re.match(r"^\s*\[\[\s*([^\]]+?)\s*\]\]", text)
            if hdr:
                current = hdr.group(1).strip("\"'")
                count = count + 1 if current == table else count
                continue
            hdr = re.match(r"^\s*\[\s*([^\]]+?)\s*\]", text)
            if hdr:
                current = hdr.group(1).strip("\"'")
                continue
            if current != table or (table == "obstacles" and count != index):
                continue
            m = key_re.match(text)
            if m:
                col = len(m.group(1)) + 1
                end = col + len(key) + 2 * len(m.group(2))
                return no, col, end, m.end() + 1
        # a table header: [[obstacles]] without polygon, [foo] unknown, ...
        names = [key] if table is None else [f"{table}.{key}", table]
        for name in names:
            count = -1
            for no, text in self.logical_lines():
                hdr = re.match(r"^(\s*)(\[\[?)\s*([^\]]+?)\s*\]", text)
                if hdr and hdr.group(3).replace(" ", "").strip("\"'") == name:
                    count += 1
                    if name != table or hdr.group(2) == "[" or count == index:
                        col = len(hdr.group(1)) + 1
                        end = len(text.split("#")[0].rstrip()) + 1
                        return no, col, end, None
        return None

    def logical_lines(self):
        """(line number, text) of the lines that start a key or a header,
        skipping the continuation lines of multi-line arrays and strings."""
        depth = 0
        in_ml = None  # open multi-line string delimiter
        for no, text in enumerate(self.lines, start=1):
            starts_here = depth == 0 and in_ml is None
            i = 0
            quote = None
            while i < len(text):
                if in_ml:
                    j = text.find(in_ml, i)
                    if j < 0:
                        break
                    in_ml, i = None, j + 3
                    continue
                ch = text[i]
                if quote:
                    if ch == "\\" and quote == '"':
                        i += 2
                        continue
                    if ch == quote:
                        quote = None
                elif text.startswith('"""', i) or text.startswith("'''", i):
                    in_ml, i = text[i:i + 3], i + 3
                    continue
                elif ch in "\"'":
                    quote = ch
                elif ch == "#":
                    break
                elif ch in "[{" and not (starts_here and depth == 0
                                          and text[:i].strip() == ""):
                    depth += 1
                elif ch in "]}" and depth > 0:
                    depth -= 1
                i += 1
            if starts_here:
                yield no, text

    def element(self, line: int, col: int, path: tuple):
        """(line, column, end column) of the array element at ``path`` inside
        the value starting at ``line``:``col``, or None."""
        starts = [0]
        for t in self.lines:
            starts.append(starts[-1] + len(t) + 1)
        # work on the lines as rendered (splitlines() drops \r)
        text = "\n".join(self.lines) + "\n"
        at = _nth_element(text, starts[line - 1] + col - 1, path)
        if at is None:
            return None
        pos = at
        end = _skip_value(text, pos)
        ln = bisect.bisect_right(starts, pos)
        c = pos - starts[ln - 1] + 1
        eln = bisect.bisect_right(starts, max(pos, end - 1))
        ec = end - starts[ln - 1] + 1 if eln == ln else len(self.lines[ln - 1]) + 1
        return ln, c, ec

    def value_end(self, line: int, col: int) -> int:
        text = self.lines[line - 1]
        rest = text[col - 1:]
        # cut a trailing comment outside strings
        quote = None
        for i, ch in enumerate(rest):
            if quote:
                if ch == quote:
                    quote = None
            elif ch in "\"'":
                quote = ch
            elif ch == "#":
                rest = rest[:i]
                break
        return col + len(rest.rstrip())


def _skip_blank(text: str, i: int) -> int:
    """The first offset from ``i`` not blank nor in a comment."""
    n = len(text)
    while i < n:
        if text[i] in " \t\r\n":
            i += 1
        elif text[i] == "#":
            while i < n and text[i] != "\n":
                i += 1
        else:
            break
    return i


def _skip_value(text: str, i: int) -> int:
    """The offset just after the TOML value starting at ``i``."""
    n = len(text)
    if i >= n:
        return i
    if text[i] in "\"'":
        q = text[i]
        i += 1
        while i < n and text[i] != q and text[i] != "\n":
            i += 2 if (text[i] == "\\" and q == '"') else 1
        return i + 1
    if text[i] in "[{":
        return _skip_brackets(text, i)
    while i < n and text[i] not in ",]}\n#":
        i += 1
    while i > 0 and text[i - 1] in " \t":
        i -= 1
    return i


def _skip_brackets(text: str, i: int) -> int:
    """The offset just after the array or inline table starting at ``i``."""
    n = len(text)
    depth = 0
    while i < n:
        ch = text[i]
        if ch in "\"'":
            i = _skip_value(text, i)
            continue
        if ch == "#":
            i = _skip_blank(text, i)
            continue
        if ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
            if depth == 0:
                return i + 1
        i += 1
    return i


def _nth_element(text: str, pos: int, path: tuple) -> Optional[int]:
    """The offset of the element at ``path`` (indices into nested arrays)
    inside the value at offset ``pos``, or None."""
    n = len(text)
    for idx in path:
        if pos >= n or text[pos] != "[":
            return None
        pos += 1
        count = 0
        while True:
            pos = _skip_blank(text, pos)
            if pos >= n or text[pos] == "]":
                return None
            if count == idx:
                break
            pos = _skip_blank(text, _skip_value(text, pos))
            if pos < n and text[pos] == ",":
                pos += 1
                count += 1
            else:
                return None
    return pos


_LOC = re.compile(r"\s*\(at line (\d+), column (\d+)\)\s*$")
_END = re.compile(r"\s*\(at end of document\)\s*$")


def decode_error_location(e: Exception, source: str) -> tuple:
    """(message, line, column) of a ``tomllib.TOMLDecodeError``, its position
    taken out of the message ('at end of document' -> the last line)."""
    msg = str(e)
    line = getattr(e, "lineno", None)
    col = getattr(e, "colno", None)
    m = _LOC.search(msg)
    if m:
        line, col = int(m.group(1)), int(m.group(2))
        msg = msg[:m.start()]
    else:
        m = _END.search(msg)
        if m:
            msg = msg[:m.start()] + " at end of file"
            lines = source.splitlines()
            line = max(1, len(lines))
            col = len(lines[-1]) + 1 if lines else 1
    msg = getattr(e, "msg", None) or msg
    return msg, line, col


def long_integer_location(source: str, max_digits: int) -> Optional[Where]:
    """Where the first integer of more than ``max_digits`` digits is written
    (``tomllib`` raises a bare ValueError for it)."""
    m = re.search(rf"\d{{{max_digits + 1},}}", source)
    if not m:
        return None
    line = source.count("\n", 0, m.start()) + 1
    col = m.start() - (source.rfind("\n", 0, m.start()) + 1) + 1
    return Where(line, col, col + len(m.group()))
