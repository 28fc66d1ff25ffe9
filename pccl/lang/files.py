"""A program file to its AST, whichever front end reads it: PCCL, or Koord
for ``.koord``/``.krd`` files or when the language is given as ``koord``
(``--lang koord``, docs/koord.md).  The one dispatch every command uses
(``pccl check`` reads through it without the engines)."""

from __future__ import annotations

import os
from typing import Optional

from pccl.lang import ast as A

#: File name endings read as Koord.
KOORD_SUFFIXES = (".koord", ".krd")
#: The languages a program may be read as (``--lang``; None: the suffix decides).
LANGUAGES = ("pccl", "koord")


def is_koord_path(path) -> bool:
    """Whether the file ``path`` is a Koord program (by its suffix; here,
    not in :mod:`pccl.lang.koord`, so that reading a PCCL file imports no
    Koord front end)."""
    name = os.fspath(path)
    if isinstance(name, bytes):
        name = os.fsdecode(name)
    return name.lower().endswith(KOORD_SUFFIXES)


def is_koord(path, lang: Optional[str] = None) -> bool:
    """Whether ``path`` is read as Koord: ``lang`` when given (``"koord"``
    or ``"pccl"``), else the suffix decides (:func:`is_koord_path`)."""
    if lang is not None:
        return lang == "koord"
    return is_koord_path(path)


def parse_program_file(path, lang: Optional[str] = None) -> A.Program:
    """The program in file ``path``: a Koord program (``lang`` ``"koord"``,
    or no ``lang`` and the suffix ``.koord``/``.krd``) read by the Koord
    front end, any other by the PCCL parser."""
    if is_koord(path, lang):
        from pccl.lang.koord import parse_koord_file
        return parse_koord_file(os.fspath(path))
    from pccl.lang.parser import parse_file
    return parse_file(os.fspath(path))


def parse_program_text(source: str, filename: str = "<input>",
                       lang: Optional[str] = None) -> A.Program:
    """The program ``source`` (text, named ``filename`` in messages), read
    as :func:`parse_program_file` reads a file: ``lang``, else the name's
    suffix (so PCCL for ``<input>``)."""
    if is_koord(filename, lang):
        from pccl.lang.koord import parse_koord
        return parse_koord(source, filename)
    from pccl.lang.parser import parse_program
    return parse_program(source, filename)
