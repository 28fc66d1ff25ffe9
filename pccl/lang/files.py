"""A program file to its AST, whichever front end reads it: PCCL, or Koord
for ``.koord``/``.krd`` files (docs/koord.md).  The one dispatch every
command uses (``pccl check`` reads through it without the engines)."""

from __future__ import annotations

import os

from pccl.lang import ast as A

#: File name endings read as Koord.
KOORD_SUFFIXES = (".koord", ".krd")


def is_koord_path(path) -> bool:
    """Whether the file ``path`` is a Koord program (by its suffix; here,
    not in :mod:`pccl.lang.koord`, so that reading a PCCL file imports no
    Koord front end)."""
    name = os.fspath(path)
    if isinstance(name, bytes):
        name = os.fsdecode(name)
    return name.lower().endswith(KOORD_SUFFIXES)


def parse_program_file(path) -> A.Program:
    """The program in file ``path``: a Koord program (``.koord``, ``.krd``)
    read by the Koord front end, any other by the PCCL parser."""
    if is_koord_path(path):
        from pccl.lang.koord import parse_koord_file
        return parse_koord_file(os.fspath(path))
    from pccl.lang.parser import parse_file
    return parse_file(os.fspath(path))
