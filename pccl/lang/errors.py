"""User-facing errors: one message, file:line:column, the source line and a caret.

Every problem with the user's input (syntax, types, world files, options)
is raised as a :class:`PcclError`; the CLI prints ``err.render()`` to stderr
and exits with status 2.  Nothing else should reach the user as a traceback.

Format (pylox style)::

    programs/bad.pccl:12:5: error: undeclared variable 'foo'
       12 |     foo = 3;
          |     ^^^
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Optional

if TYPE_CHECKING:      # a name for annotations only: pccl.lang.ast costs ~15 ms to import,
    from pccl.lang.ast import Span      # and the CLI's start-up imports this module


class PcclError(Exception):
    """An error in the user's input, with an optional source location."""

    exit_status = 2

    def __init__(self, message: str, *, filename: Optional[str] = None,
                 source: Optional[str] = None, span: Optional[Span] = None,
                 line: Optional[int] = None, column: Optional[int] = None,
                 end_column: Optional[int] = None, template: bool = False,
                 where: Optional[str] = None):
        super().__init__(message)
        if span is not None and getattr(span, "origin", None) is not None:
            filename, source = span.origin   # type: ignore[misc] # an option's text, not the program's
        #: the message and the location as written, with option placeholders
        #: (:func:`spell`): the message only when ``template``; the location
        #: given as ``where`` (``pccl {ray}``), or a filename that starts with
        #: one (``{invariants} #1``: an option's text)
        self.template = message if template else None
        if where is None and filename is not None and filename.startswith("{"):
            where = filename
        self.where = where
        self.message = message
        self.filename = filename if where is None else where
        self.source = source
        if span is not None and span.line > 0:
            line = span.line if line is None else line
            column = span.column if column is None else column
            if end_column is None and span.end_line == span.line:
                end_column = span.end_column
        self.line = line
        self.column = column
        self.end_column = end_column
        self.respell(keyword_spelling)

    def respell(self, spelling: "Spelling") -> "PcclError":
        """Write the options this error names as ``spelling`` does (its
        message's placeholders and its location): as the API's keywords
        when made (:func:`keyword_spelling`); the CLI respells it as flags
        before rendering it.  Returns the error."""
        if self.template is not None:
            self.message = spell(self.template, spelling)
            self.args = (self.message,)
        if self.where is not None:
            self.filename = spell(self.where, location_spelling(spelling))
        return self

    def render(self) -> str:
        return render_message(self.message, filename=self.filename,
                              source=self.source, line=self.line,
                              column=self.column, end_column=self.end_column)

    def __str__(self) -> str:
        return self.render()


class ToolLimitError(PcclError):
    """A limit of the tool, not an error of the program nor a violation of
    its properties (``rand(n)`` with more outcomes in one transition than
    explore enumerates): reported like bad input, with the location, exit
    status 2."""


class ArgumentError(PcclError, ValueError):
    """A bad argument to a function of the Python API (:mod:`pccl.api`):
    its ``filename`` is the function, e.g. ``pccl.api.explore``."""


#: How a front end writes an option named in a text: ``spelling(name, value)``
#: with ``value`` None for the option itself, else its value as text; None
#: for a name it does not know (the placeholder is left as written).  The API
#: writes keywords (:func:`keyword_spelling`), the CLI its flags
#: (``pccl.cli.cli_spelling``): no module below the CLI writes a flag.
Spelling = Callable[[str, Optional[str]], Optional[str]]

#: An option in a text: ``{fastest}``, ``{workers=1}``, ``{rates=1=2}``
#: (lowercase names only: ``{ x = 1; }`` of a program's block is not one); or
#: a span quoted in backticks (a property's text), which is left alone.
_PLACEHOLDER = re.compile(r"`[^`]*`|\{([a-z][a-z0-9_]*)(?:=([^{}]*))?\}")


def spell(text: str, spelling: Spelling) -> str:
    """``text`` with its option placeholders written by ``spelling``
    (``{workers=1}``: ``workers=1`` for the API, ``--workers 1`` for the
    CLI); placeholders ``spelling`` does not know, and anything quoted in
    backticks (program text), stay as they are."""
    def one(m: re.Match) -> str:
        if m.group(1) is None:
            return m.group(0)
        out = spelling(m.group(1), m.group(2))
        return m.group(0) if out is None else out
    return _PLACEHOLDER.sub(one, text)


def keyword_spelling(name: str, value: Optional[str]) -> str:
    """An option as the API's keyword: ``fastest``, ``workers=1``; a pair of
    ``rates`` or ``overrides`` as the dict the keyword takes
    (``rates={1: 2}``, ``overrides={'k': '2'}``)."""
    if value is None:
        return name
    key, eq, v = value.partition("=")
    if eq and name == "rates":
        return f"rates={{{key}: {v}}}"
    if eq and name == "overrides":
        return f"overrides={{{key!r}: {v!r}}}"
    return f"{name}={value}"


def location_spelling(spelling: Spelling) -> Spelling:
    """``spelling`` for an error's location (an option's text): the option
    alone, its value being the text's place (``{invariants=#1}`` is
    ``--invariant #1`` on the command line, ``invariants #1`` in the API)."""
    def spell_at(name: str, value: Optional[str]) -> Optional[str]:
        out = spelling(name, None)
        return out if out is None or value is None else f"{out} {value}"
    return spell_at


class CheckpointFileError(PcclError):
    """A checkpoint that cannot be written or resumed (the search's
    :class:`pccl.search.checkpoint.CheckpointError`, as the API raises it):
    one message naming ``--checkpoint`` or ``--resume``, exit 2."""


class OptionError(PcclError):
    """A bad value of an option, found where its meaning is known (the model:
    an agent's rate above n0, a δ the clock cannot add).  ``option`` is the
    option's name as the API spells it (``rates``); the message names other
    options as placeholders (``{n0=2}``).  Rendered by the CLI with its flags
    (``--rate: error: ...``); the API re-raises it as an :class:`ArgumentError`
    of the function that was called (``pccl.api.explore: error: rates: ...``)."""

    def __init__(self, option: str, message: str):
        super().__init__(message, filename="{" + option + "}", template=True)
        self.option = option

    def for_api(self, func: str) -> "ArgumentError":
        return ArgumentError(f"{self.option}: {self.message}", filename=f"pccl.api.{func}")


def render_message(message: str, *, filename: Optional[str], source: Optional[str],
                   line: Optional[int], column: Optional[int],
                   end_column: Optional[int] = None, kind: str = "error") -> str:
    where = filename or "<input>"
    if line:
        where += f":{line}"
        if column:
            where += f":{column}"
    out = [f"{where}: {kind}: {message}"]
    if source is not None and line:
        lines = source.splitlines()
        if 1 <= line <= len(lines):
            text = lines[line - 1].expandtabs(1).rstrip("\n")
            gutter = f"{line:>5} | "
            out.append(gutter + text)
            if column:
                col = max(1, column)
                width = 1
                if end_column and end_column > col:
                    width = end_column - col
                width = max(1, min(width, max(1, len(text) - col + 1)))
                out.append(" " * (len(gutter) - 2) + "| " + " " * (col - 1) + "^" * width)
    return "\n".join(out)


class PcclRuntimeError(Exception):
    """A runtime error inside a PCCL program (division by zero, undefined
    read, remove of an absent element, ...).  The engine turns it into a
    *stuck agent* (a result), never into a crash of the tool."""

    #: where the engine caught it, e.g. ("guard", event), when not at a statement
    where: Optional[tuple] = None

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


def install_hint(extra: str) -> str:
    """How to install an optional extra of pccl.  Run from a checkout (the
    README's editable install), the command names the checkout: ``pip install
    -e '/path/to/pccl[physics]'``; installed from a wheel, the packages the
    extra adds, read from pccl's installed metadata: ``pip install
    'pymunk>=6.6'`` (pccl is not on the package index, so ``pccl[physics]``
    would not resolve)."""
    from pathlib import Path
    root = Path(__file__).resolve().parent.parent.parent
    if (root / "pyproject.toml").is_file():
        return f"pip install -e '{root}[{extra}]'"
    import importlib.metadata
    try:
        reqs = importlib.metadata.requires("pccl") or []
    except importlib.metadata.PackageNotFoundError:
        reqs = []
    marker = f'extra == "{extra}"'
    wanted = [r.split(";", 1)[0].strip() for r in reqs if marker in r.replace("'", '"')]
    if wanted:
        return "pip install " + " ".join(f"'{r}'" for r in wanted)
    return f"pip install -e '.[{extra}]' in the pccl checkout"

