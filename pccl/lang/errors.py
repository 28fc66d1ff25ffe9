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

from typing import Optional

from pccl.lang.ast import Span


class PcclError(Exception):
    """An error in the user's input, with an optional source location."""

    exit_status = 2

    def __init__(self, message: str, *, filename: Optional[str] = None,
                 source: Optional[str] = None, span: Optional[Span] = None,
                 line: Optional[int] = None, column: Optional[int] = None,
                 end_column: Optional[int] = None):
        super().__init__(message)
        if span is not None and getattr(span, "origin", None) is not None:
            filename, source = span.origin   # type: ignore[misc] # an option's text, not the program's
        self.message = message
        self.filename = filename
        self.source = source
        if span is not None and span.line > 0:
            line = span.line if line is None else line
            column = span.column if column is None else column
            if end_column is None and span.end_line == span.line:
                end_column = span.end_column
        self.line = line
        self.column = column
        self.end_column = end_column

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


#: Options whose flag is not ``--`` + the name with ``-`` for ``_`` (the
#: options are :mod:`pccl.model.options`; the spelling lives here, with the error
#: that renders it, so that this module imports nothing above it).
FLAGS = {"agents": "--agents", "rates": "--rate", "overrides": "--set",
         "invariants": "--invariant", "deadlock": "--no-deadlock", "find_all": "--all",
         "properties": "--property", "timelock": "--no-timelock",
         "stall": "--no-stall"}


def flag(name: str) -> str:
    """The command-line flag of the option ``name``."""
    return FLAGS.get(name, "--" + name.replace("_", "-"))


class OptionError(PcclError):
    """A bad value of an option, found where its meaning is known (the model:
    an agent's rate above n0, a δ the clock cannot add).  ``option`` is the
    option's name as the API spells it (``rates``); the message names no
    flag.  Rendered as the CLI spells the option (``--rate: error: ...``);
    the API re-raises it as an :class:`ArgumentError` of the function that
    was called (``pccl.api.explore: error: rates: ...``)."""

    def __init__(self, option: str, message: str):
        super().__init__(message, filename=flag(option))
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
    """How to install an optional extra of pccl: pccl is installed from its
    checkout (it is not on the package index), so the command names the
    checkout when there is one: ``pip install -e '/path/to/pccl[physics]'``."""
    from pathlib import Path
    root = Path(__file__).resolve().parent.parent.parent
    if (root / "pyproject.toml").is_file():
        return f"pip install -e '{root}[{extra}]'"
    return f"pip install -e '.[{extra}]' in the pccl checkout"

