"""Decoded file data (a JSON trace file, a TOML world file): what kind of
value a key holds, and its name in the words of the file's format.

The checkers of those files (:mod:`pccl.output.tracecheck`,
:mod:`pccl.lang.world`) name what they got in their messages (``expected a
list, got an integer 5``; ``'radius' must be a number, got boolean``) with
the one classification here."""

from __future__ import annotations

import math
from typing import Any

#: The kinds of :func:`kind`, in JSON's words (as :mod:`pccl.output.tracecheck` writes them).
JSON_NAMES = {"null": "null", "boolean": "a boolean", "integer": "an integer",
              "float": "a number", "string": "a string", "list": "a list", "table": "an object"}
#: The kinds of :func:`kind`, in TOML's words (as :mod:`pccl.lang.world` writes them);
#: TOML has no null, and its dates and times are the other kind.
TOML_NAMES = {"boolean": "boolean", "integer": "integer", "float": "float", "string": "string",
              "list": "array", "table": "table", "other": "date/time"}


def kind(v: Any) -> str:
    """The kind of a decoded value: null, boolean, integer (never a
    bool), float, string, list, table (a dict), or other."""
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "boolean"
    if isinstance(v, int):
        return "integer"
    if isinstance(v, float):
        return "float"
    if isinstance(v, str):
        return "string"
    if isinstance(v, list):
        return "list"
    if isinstance(v, dict):
        return "table"
    return "other"


def is_integer(v: Any) -> bool:
    """An integer, not a boolean."""
    return isinstance(v, int) and not isinstance(v, bool)


def is_number(v: Any) -> bool:
    """An integer or a float, not a boolean (finite or not)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def is_finite_number(v: Any) -> bool:
    """An integer or a finite float, not a boolean."""
    return is_number(v) and math.isfinite(v)
