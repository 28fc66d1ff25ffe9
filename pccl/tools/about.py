"""What ran: pccl's version, the native engine's availability, the extras
installed, Python and the platform (``pccl --version``, for bug reports).

Nothing here imports an engine module or an extra: the extras are looked up
with :func:`importlib.util.find_spec` (which finds, without running, a
module), so that ``pccl --version`` stays a fast command."""

from __future__ import annotations

import importlib.util
import platform
import sys

from pccl import __version__
from pccl.model.toolchain import compiler, native_unavailable

#: The optional extras (pyproject.toml's optional dependencies) and the
#: module each one provides.
EXTRAS = (("plot", "matplotlib"), ("physics", "pymunk"), ("ray", "ray"), ("lsp", "pygls"))


def installed(module: str) -> bool:
    """Whether ``module`` can be imported here (found, not imported)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def version_lines() -> list[str]:
    """The lines ``pccl --version`` prints."""
    why = native_unavailable()
    native = (f"native engine available (C compiler {compiler()})" if why is None
              else f"native engine unavailable ({why}): searches run the Python engine")
    extras = ", ".join(f"{mod} ({extra}) {'installed' if installed(mod) else 'not installed'}"
                       for extra, mod in EXTRAS)
    impl = platform.python_implementation()
    return [f"pccl {__version__}",
            native,
            f"extras: {extras}",
            f"Python {platform.python_version()} ({impl}, {sys.executable})",
            f"platform: {platform.system()} {platform.release()} {platform.machine()}"]
