"""Memory figures of this process, portably.

``peak_rss_bytes()`` is the peak resident set size (what ``pccl explore``
reports as peak memory).  On Linux and macOS it comes from
``getrusage(RUSAGE_SELF).ru_maxrss`` (on Linux ``VmHWM`` from
``/proc/self/status`` first: ``ru_maxrss`` survives ``exec``, so a process
started by a large one would report its parent's peak), whose unit is
KiB on Linux (and the BSDs) but bytes on macOS; psutil has no peak on Linux.
Where the ``resource`` module does not exist (Windows) it comes from psutil:
``peak_wset`` (the peak working set) where psutil has it, else the current
RSS.  ``rss_bytes()`` is the current resident set size (psutil).
"""

from __future__ import annotations

import sys

try:
    import resource as _resource
except ImportError:  # pragma: no cover - Windows
    _resource = None  # type: ignore[assignment]

__all__ = ["format_size", "peak_rss_bytes", "rss_bytes"]


def _maxrss_bytes(resource_module, platform: str = sys.platform) -> int:
    unit = 1 if platform in ("darwin", "ios") else 1024
    return int(resource_module.getrusage(resource_module.RUSAGE_SELF).ru_maxrss) * unit


def _psutil_peak() -> int:
    try:
        import psutil
    except ImportError:  # pragma: no cover - psutil is a dependency
        return 0
    try:
        info = psutil.Process().memory_info()
    except Exception:  # pragma: no cover - a platform psutil cannot read
        return 0
    return int(getattr(info, "peak_wset", 0) or info.rss)


def _vmhwm_bytes() -> int:
    """Linux: the peak RSS of this process's current address space
    (``VmHWM``).  Unlike ``ru_maxrss`` it starts afresh at ``exec``: a
    process started by a large parent does not inherit the parent's peak."""
    try:
        with open("/proc/self/status", "rb") as f:
            for line in f:
                if line.startswith(b"VmHWM:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return 0


def peak_rss_bytes() -> int:
    """The peak resident set size of this process in bytes (0 if unknown)."""
    if sys.platform.startswith("linux"):
        hwm = _vmhwm_bytes()
        if hwm:
            return hwm
    if _resource is not None:
        try:
            return _maxrss_bytes(_resource)
        except (OSError, ValueError, AttributeError):  # pragma: no cover
            pass
    return _psutil_peak()


def rss_bytes() -> int:
    """The current resident set size of this process in bytes (0 if unknown)."""
    try:
        import psutil
        return int(psutil.Process().memory_info().rss)
    except Exception:  # pragma: no cover - psutil missing or unreadable
        return peak_rss_bytes()


def format_size(n: int) -> str:
    """Bytes as ``--max-memory`` accepts them back (``1.5G``, ``300M``)."""
    for unit, size in (("G", 2**30), ("M", 2**20), ("K", 2**10)):
        if n >= size:
            v = n / size
            return f"{v:.1f}{unit}".replace(".0" + unit, unit)
    return str(n)


def parse_size(text: str) -> int:
    """``--max-memory`` values: bytes, or a number with K, M, G, T (powers of
    1024; an optional trailing ``B``/``iB``)."""
    import re
    m = re.fullmatch(r"\s*([0-9]+(?:\.[0-9]*)?)\s*([KMGT]?)(?:i?B)?\s*", str(text), re.I)
    if not m:
        raise ValueError(f"expected a size such as 800M or 4G, got {text!r}")
    v = float(m.group(1)) * 1024 ** " KMGT".index((m.group(2) or " ").upper())
    if v < 1 or v != v or v > 2**62:
        raise ValueError(f"size out of range: {text!r}")
    return int(v)
