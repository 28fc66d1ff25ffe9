"""What the native engine needs from the machine: a C compiler, Python's
headers; found without importing the engine."""

from __future__ import annotations

import os
import shutil
import sysconfig
from typing import Optional


def compiler() -> Optional[str]:
    """The C compiler the native engine calls (``$CC``, else ``cc``, else
    ``gcc`` on the PATH); None when there is none."""
    return shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")


def python_headers() -> Optional[str]:
    """The directory holding ``Python.h`` (the development headers the
    native modules compile against); None when it is not there."""
    inc = sysconfig.get_paths().get("include")
    if inc is None or not os.path.exists(os.path.join(inc, "Python.h")):
        return None
    return inc


def native_unavailable() -> Optional[str]:
    """Why no program can run on the native engine on this machine (None:
    programs in its subset can)."""
    if compiler() is None:
        return "no C compiler (cc) found"
    if python_headers() is None:
        return "Python.h (the Python development headers) not found"
    return None
