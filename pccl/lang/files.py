"""A program file to its AST, whichever front end reads it: PCCL, or Koord
for ``.koord``/``.krd`` files (docs/koord.md).  The one dispatch every
command uses (``pccl check`` reads through it without the engines)."""

from __future__ import annotations

import os

from pccl.lang import ast as A


def parse_program_file(path) -> A.Program:
    """The program in file ``path``: a Koord program (``.koord``, ``.krd``)
    read by the Koord front end, any other by the PCCL parser."""
    from pccl.lang.koord import is_koord_path, parse_koord_file
    if is_koord_path(path):
        return parse_koord_file(os.fspath(path))
    from pccl.lang.parser import parse_file
    return parse_file(os.fspath(path))
