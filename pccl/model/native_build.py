"""Compiling and caching the native engine's modules: the generated source
of :mod:`pccl.model.native` with the fixed C of ``native_c/`` it includes
(package data), compiled with the system C compiler into a CPython
extension module, cached by the hash of both and the Python ABI, loaded."""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from typing import Any, Optional

from pccl.lang.cachedir import cache_dir, private_cache_dir, private_file
from pccl.model.toolchain import compiler

# The module cache ($PCCL_CACHE or ~/.cache/pccl): one file per generated
# source, written atomically (compiled in a temporary directory of the cache,
# then renamed: a half-written module is never under a module's name), kept
# under a size bound ($PCCL_CACHE_SIZE) by removing the least recently used
# modules after a new one is written.  A module is touched when it is
# loaded (its mtime is its last use).  The cache's lock file orders loading
# and pruning between processes: a process holds it shared from the look
# for its module to the end of loading it, the pruner exclusively, so no
# module is removed while another process loads it (a module another
# process has loaded may go: on Linux its mapping stays).  A process never
# removes a module it has loaded itself.

#: the cache's bound when $PCCL_CACHE_SIZE is not set (a module is 25-60 KB:
#: about 2,500 modules)
CACHE_SIZE_DEFAULT = 100 * 2**20
CACHE_SIZE_ENV = "PCCL_CACHE_SIZE"
#: a compile's temporary directory left by a killed process is removed by
#: the pruner once it is this old (seconds)
STALE_TMP = 3600.0
_PREFIX = "pccl_native_"
_LOCK = ".native.lock"
#: the modules this process has loaded (never pruned by it)
_LOADED: set = set()


def cache_bound() -> Optional[int]:
    """The cache's bound in bytes from $PCCL_CACHE_SIZE (a size: bytes, or a
    number with K, M, G; ``0``: no bound), :data:`CACHE_SIZE_DEFAULT` when
    unset; a :class:`~pccl.lang.errors.PcclError` naming the variable when
    it is not a size."""
    text = os.environ.get(CACHE_SIZE_ENV)
    if text is None or not text.strip():
        return CACHE_SIZE_DEFAULT
    if text.strip() == "0":
        return None
    from pccl.search.memory import parse_size
    from pccl.lang.errors import PcclError
    try:
        return parse_size(text)
    except ValueError:
        raise PcclError(f"expected a size such as 100M or 1G (0: no bound) for the native "
                        f"module cache, got {text!r}", filename=CACHE_SIZE_ENV) from None


def _module_ext() -> str:
    return sysconfig.get_config_var("EXT_SUFFIX") or ".so"


class _Lock:
    """The cache's lock file, held shared (loading) or exclusive (pruning)
    while the ``with`` block runs; a no-op where there is no ``fcntl``."""

    def __init__(self, d: str, exclusive: bool):
        self.path, self.exclusive = os.path.join(d, _LOCK), exclusive
        self.f: Any = None

    def __enter__(self):
        try:
            import fcntl
        except ImportError:         # pragma: no cover - not POSIX
            return self
        try:
            self.f = open(self.path, "a")
        except OSError:             # a cache that cannot be written: nothing is pruned
            return self
        fcntl.flock(self.f, fcntl.LOCK_EX if self.exclusive else fcntl.LOCK_SH)
        return self

    def __exit__(self, *exc) -> None:
        if self.f is not None:
            self.f.close()          # releases the lock
            self.f = None


def cache_modules(d: Optional[str] = None) -> list:
    """The native modules in the cache: ``(last use, size, path)``, least
    recently used first."""
    d = cache_dir() if d is None else d
    ext = _module_ext()
    out = []
    try:
        names = os.listdir(d)
    except OSError:
        return []
    for n in names:
        if n.startswith(_PREFIX) and n.endswith(ext):
            p = os.path.join(d, n)
            try:
                st = os.stat(p)
            except OSError:         # removed meanwhile
                continue
            out.append((st.st_mtime, st.st_size, p))
    out.sort()
    return out


def prune_cache(d: Optional[str] = None, bound: Optional[int] = None, *,
                keep=()) -> list:
    """Remove the least recently used modules until the cache holds at most
    ``bound`` bytes of them (never one in ``keep`` or loaded by this
    process), and compile directories older than :data:`STALE_TMP`; the
    paths removed.  ``bound`` None: only the stale directories."""
    import time
    d = cache_dir() if d is None else d
    removed: list = []
    spare = {os.path.abspath(p) for p in (*keep, *_LOADED)}
    with _Lock(d, exclusive=True):
        now = time.time()
        for n in os.listdir(d):
            p = os.path.join(d, n)
            if n.startswith("tmp") and os.path.isdir(p):
                try:
                    if now - os.stat(p).st_mtime > STALE_TMP:
                        shutil.rmtree(p, ignore_errors=True)
                except OSError:
                    pass
        if bound is None:
            return removed
        mods = cache_modules(d)
        total = sum(m[1] for m in mods)
        for _, size, p in mods:
            if total <= bound:
                break
            if os.path.abspath(p) in spare:
                continue
            try:
                os.unlink(p)
            except FileNotFoundError:       # another pruner was first
                pass
            except OSError:
                continue
            total -= size
            removed.append(p)
    return removed


def clear_cache(d: Optional[str] = None) -> tuple:
    """Remove every native module of the cache (and stale compile
    directories); ``(modules removed, bytes)``."""
    d = cache_dir() if d is None else d
    mods = cache_modules(d)
    if not mods:
        return 0, 0
    gone = prune_cache(d, 0)
    sizes = {p: size for _, size, p in mods}
    return len(gone), sum(sizes[p] for p in gone)


#: the fixed C of every module (package data, pyproject.toml): the generated
#: source includes its files (Generator.source; native_c/native.h says how)
C_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "native_c")
_FIXED: list = []


def fixed_sources() -> bytes:
    """The fixed C files' names and contents (:data:`C_DIR`, in name order,
    read once per process): a module's cache key and a checkpoint's
    identity hash them with the generated source."""
    if not _FIXED:
        parts = []
        for n in sorted(os.listdir(C_DIR)):
            if n.endswith((".c", ".h")):
                with open(os.path.join(C_DIR, n), "rb") as f:
                    parts.append(n.encode() + b"\0" + f.read() + b"\0")
        _FIXED.append(b"".join(parts))
    return _FIXED[0]


def source_digest(src: str, tag: str = "") -> str:
    """The sha256 (hex) of generated source ``src`` with the fixed C it
    includes (and ``tag``, the Python ABI for the module cache)."""
    return hashlib.sha256(src.encode() + fixed_sources() + tag.encode()).hexdigest()


#: the C compiler's optimisation levels $PCCL_NATIVE_OPT may choose
OPT_LEVELS = ("0", "1", "2", "3")


def opt_level() -> str:
    """The optimisation level native modules are compiled at: ``2`` (``-O2``),
    or ``$PCCL_NATIVE_OPT`` when it is one of :data:`OPT_LEVELS`.  The test
    suite sets ``0``: it compiles a thousand small modules whose searches
    are short, and ``-O0`` compiles them about three times faster; the
    search's results do not depend on it (tests/model/test_native_opt.py
    holds ``-O0`` and ``-O2`` equal).  Any other value is a
    :class:`~pccl.lang.errors.PcclError` naming the variable."""
    v = os.environ.get("PCCL_NATIVE_OPT", "2").strip() or "2"
    if v not in OPT_LEVELS:
        from pccl.lang.errors import PcclError
        raise PcclError(f"expected an optimisation level {', '.join(OPT_LEVELS)} for the native "
                        f"engine's C compiler, got {v!r}", filename="PCCL_NATIVE_OPT")
    return v


def _compile(d: str, name: str, src: str, path: str) -> None:
    """Compile the module ``name`` of source ``src`` to ``path`` (atomically:
    in a temporary directory of the cache, then renamed)."""
    cc = compiler()
    assert cc is not None
    full = f"#define MODNAME \"{name}\"\n#define INITFN PyInit_{name}\n" + src
    with tempfile.TemporaryDirectory(dir=d) as tmp:
        c_path = os.path.join(tmp, name + ".c")
        with open(c_path, "w") as f:
            f.write(full)
        out = os.path.join(tmp, name + _module_ext())
        inc = sysconfig.get_paths()["include"]
        # -ffp-contract=off: no fused multiply-add, so that float arithmetic
        # (native_c/robots.c) rounds as Python's does
        p = subprocess.run([cc, "-O" + opt_level(), "-ffp-contract=off", "-shared", "-fPIC", "-pthread", "-w",
                            f"-I{inc}", f"-I{C_DIR}", "-o", out, c_path],
                           capture_output=True, text=True)
        if p.returncode != 0:
            raise RuntimeError(f"the C compiler failed on the native module:\n{p.stderr[-2000:]}")
        os.chmod(out, 0o755)        # whatever the umask: no one else may write it
        os.replace(out, path)


#: the directory of this process's modules when the cache directory is not
#: private (:func:`module_dir`)
_PROCESS_DIR: list = []


def module_dir() -> str:
    """Where native modules are compiled to and loaded from: the cache
    directory when it is private to this user (a shared object runs when
    it is loaded: :mod:`pccl.lang.cachedir`), else a directory of this
    process's own (mode 0700, removed at exit): nothing is reused then."""
    d = private_cache_dir()
    if d is not None:
        return d
    if not _PROCESS_DIR:
        import atexit
        _PROCESS_DIR.append(tempfile.mkdtemp(prefix="pccl-native-"))
        atexit.register(shutil.rmtree, _PROCESS_DIR[0], True)
    return _PROCESS_DIR[0]


def module_name(src: str) -> str:
    """The cache's name of the module of ``src``: the hash of the source, the
    fixed C it includes, the Python ABI and the optimisation level."""
    tag = (sysconfig.get_config_var("SOABI") or sys.implementation.cache_tag) + "-O" + opt_level()
    return f"{_PREFIX}{source_digest(src, tag)[:20]}"


def build(src: str):
    """Compile ``src`` into an extension module (cached by the hash of the
    source, the fixed C it includes and the Python ABI); the module.  After compiling a new one, the
    cache is pruned to its bound (:func:`prune_cache`)."""
    bound = cache_bound()           # a bad $PCCL_CACHE_SIZE: before any work
    opt_level()                     # a bad $PCCL_NATIVE_OPT likewise
    name = module_name(src)
    d = module_dir()
    path = os.path.join(d, name + _module_ext())
    built = False
    mod = None
    for _ in range(3):      # a module pruned by another process between the two looks
        if not os.path.exists(path) or not private_file(path):
            _compile(d, name, src, path)
            built = True
        with _Lock(d, exclusive=False):
            if not os.path.exists(path):
                continue
            try:
                os.utime(path)      # its last use: the pruner removes the least recent
            except OSError:         # a cache that cannot be written
                pass
            spec = importlib.util.spec_from_file_location(name, path)
            assert spec is not None and spec.loader is not None
            mod = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(mod)
            _LOADED.add(os.path.abspath(path))
            break
    if mod is None:
        raise RuntimeError(f"the native module {path} was removed three times while loading")
    if built:
        prune_cache(d, bound, keep=(path,))
    return mod
