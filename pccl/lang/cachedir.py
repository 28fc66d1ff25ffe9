"""pccl's cache directory (``$PCCL_CACHE``, else ``~/.cache/pccl``): the
parser's LALR tables and the native engine's compiled modules, used only
while nobody but this user can write there.

Both are code: lark's cache is a pickle, which runs what it says when it is
read, and a native module is a shared object, which runs when it is loaded.
A file in a directory that another user can write could be theirs.  So the
directory is made ``0700``, and a cache is read or written only when the
directory (and the file, if it exists) belongs to this user and is not
writable by group or others (docs/decisions.md, "The caches are private")."""

from __future__ import annotations

import os
import stat
from typing import Optional


def cache_dir() -> str:
    """Where the cache is asked to be: ``$PCCL_CACHE``, else ``~/.cache/pccl``."""
    return os.environ.get("PCCL_CACHE") or os.path.join(
        os.path.expanduser("~"), ".cache", "pccl")


def is_private(path: str) -> bool:
    """Whether ``path`` (a file or directory) belongs to this user and no one
    else can write it.  True where there are no POSIX owners (Windows: a
    user's profile directory is private by its ACL)."""
    getuid = getattr(os, "getuid", None)
    if getuid is None:                  # pragma: no cover - not POSIX
        return True
    try:
        st = os.stat(path)
    except OSError:
        return False
    return st.st_uid == getuid() and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def private_cache_dir() -> Optional[str]:
    """The cache directory, made (mode 0700) if need be; None when it cannot
    be made or written, or is not private (:func:`is_private`): then
    nothing is cached there."""
    d = cache_dir()
    try:
        os.makedirs(d, mode=0o700, exist_ok=True)
    except OSError:
        return None
    if not os.access(d, os.W_OK) or not is_private(d):
        return None
    return d


def private_file(path: str) -> bool:
    """Whether the cache file ``path`` may be read: absent (it will be
    written), or this user's and writable by no one else."""
    return not os.path.lexists(path) or (not os.path.islink(path) and is_private(path))
