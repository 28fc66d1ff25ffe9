"""The visited set and the frontier on disk (``pccl explore --spill DIR``).

Without ``--spill`` a search whose process passes ``--max-memory`` stops
there, as a bound.  With it the search moves what grows with the states to
files in a fresh directory under ``DIR`` (removed when the search ends) and
goes on, the way TLC's disk-based fingerprint set and disk queue do:

* **The visited set** (:class:`SpillTable`): the states admitted since the
  last spill stay in an in-memory :class:`~pccl.search.explorer.FingerprintTable`
  (the buffer); a spill sorts the buffer's fingerprints on their first
  64 bits and merges them, with their state numbers, into one sorted file
  on disk (:class:`DiskSet`: three column files, written afresh by a
  streaming merge, the old ones deleted).  A batch of candidates is looked
  up in the buffer first and the rest in the file: an in-memory index of
  every page's first key (:data:`DiskSet.PAGE` keys) narrows each candidate
  to one page, a vectorised binary search (``numpy`` indexing of the mapped
  file) finishes it, all candidates of the batch at once.  The mapped
  pages are dropped from the process after every batch (``madvise``), so
  they do not count towards its resident memory.
* **Parent links** of spilled states go to an append-only file (4 bytes a
  state), read back only to rebuild a counterexample.
* **The next BFS level** (:class:`LevelFile`): admitted states are written,
  in admission order, to the level's file (``pickle``) and read back a
  segment at a time when the level is expanded.

When to spill (:class:`Spiller`): after every admitted batch, when the
buffer holds :attr:`Spiller.table_limit` states (a quarter of
``--max-memory`` at 36 bytes a state), or when the process's resident
memory (psutil) passes three quarters of ``--max-memory`` (then the next
level's states go too).  If the memory still passes ``--max-memory`` the
bound stops the search as without ``--spill``.

The result is the in-memory search's: the same state numbers in the same
order, hence the same states, transitions, depth, verdict and
counterexample (``tests/test_spill.py`` compares them).
"""

from __future__ import annotations

import errno
import mmap
import os
import pickle
import shutil
import tempfile
from collections.abc import Iterator
from typing import Any, Optional

import numpy as np

from pccl.lang.errors import PcclError
from pccl.search.fingerprint import fingerprint

__all__ = ["SpillError", "SpillDir", "DiskSet", "SpillTable", "LevelFile", "Spiller"]

_NO_PARENT = 0xFFFF_FFFF
#: bytes of memory a buffered state costs (fingerprint, parent link, index)
STATE_BYTES = 36


class SpillError(PcclError):
    """The spill directory cannot be written (absent and not creatable, not
    writable, the disk full): one message naming ``--spill``, exit 2."""

    def __init__(self, message: str):
        super().__init__(message, filename="--spill")


def _why(e: OSError) -> str:
    if e.errno in (errno.ENOSPC, errno.EDQUOT):
        return "the disk is full"
    return e.strerror or str(e)


class SpillDir:
    """A fresh directory for one search's files under ``parent`` (created
    if absent), removed by :meth:`close`."""

    def __init__(self, parent: str):
        self.parent = os.fspath(parent)
        try:
            os.makedirs(self.parent, exist_ok=True)
            self.path = tempfile.mkdtemp(prefix="pccl-spill-", dir=self.parent)
            probe = os.path.join(self.path, "probe")
            with open(probe, "wb") as f:
                f.write(b"\0" * 4096)
            os.remove(probe)
        except OSError as e:
            raise SpillError(f"cannot write the search's files to {self.parent}: "
                             f"{_why(e)}") from None

    def file(self, name: str) -> str:
        return os.path.join(self.path, name)

    def fail(self, e: OSError) -> SpillError:
        """The error to raise for ``e``, met writing or reading a file."""
        return SpillError(f"the search could not go on spilling to {self.parent}: {_why(e)}")

    def close(self) -> None:
        shutil.rmtree(self.path, ignore_errors=True)


def _madvise_dontneed(m: Optional[mmap.mmap]) -> None:
    """Drop the mapped pages of ``m`` from the process (the page cache keeps
    them): mapped file pages count towards resident memory."""
    advice = getattr(mmap, "MADV_DONTNEED", None)
    if m is not None and advice is not None and len(m):
        try:
            m.madvise(advice)
        except OSError:     # pragma: no cover - a platform without it
            pass


class _Column:
    """One column of the sorted file: a read-only mapping as a numpy array."""

    def __init__(self, path: str, dtype, n: int):
        self.path = path
        self.map: Optional[mmap.mmap] = None
        self.a: np.ndarray = np.empty(0, dtype=dtype)
        if n:
            with open(path, "rb") as f:
                self.map = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
            self.a = np.frombuffer(self.map, dtype=dtype, count=n)

    def drop_pages(self) -> None:
        _madvise_dontneed(self.map)

    def close(self) -> None:
        self.a = np.empty(0, dtype=self.a.dtype)
        if self.map is not None:
            self.map.close()
            self.map = None
        try:
            os.remove(self.path)
        except OSError:
            pass


_COLUMNS = (("k0", np.uint64), ("k1", np.uint64), ("num", np.uint32))


class DiskSet:
    """A set of 128-bit fingerprints ``(k0, k1)`` with a ``uint32`` value
    each (the state number), sorted on ``k0`` in three column files in
    ``directory`` (a :class:`SpillDir`).  :meth:`merge` adds entries,
    :meth:`lookup` finds a batch."""

    #: keys per page of the in-memory index (4 KiB of ``k0``)
    PAGE = 512
    #: entries merged per step (bounded temporaries)
    CHUNK = 1 << 18

    def __init__(self, directory: SpillDir):
        self.dir = directory
        self.n = 0
        self.gen = 0
        self.cols = [_Column("", dt, 0) for _, dt in _COLUMNS]
        self.index = np.empty(0, dtype=np.uint64)
        #: merges done
        self.merges = 0

    def lookup(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """The values of the fingerprints ``(q0[i], q1[i])`` (``uint64``
        arrays); -1 where absent."""
        out = np.full(len(q0), -1, dtype=np.int64)
        n = self.n
        if not n or not len(q0):
            return out
        k0, k1, num = (c.a for c in self.cols)
        page = self.PAGE
        # the last page whose first key is below q: the first key >= q is in it
        # (or is the next page's first)
        j = np.searchsorted(self.index, q0, "left").astype(np.int64) - 1
        inside = j >= 0
        lo = np.where(inside, j * page, 0)
        hi = np.where(inside, np.minimum((j + 1) * page, n), 0)
        act = np.flatnonzero(lo < hi)
        while act.size:
            a, b = lo[act], hi[act]
            mid = (a + b) >> 1
            less = k0[mid] < q0[act]
            lo[act] = np.where(less, mid + 1, a)
            hi[act] = np.where(less, b, mid)
            act = act[lo[act] < hi[act]]
        pos = lo                # the first position whose k0 >= q0
        act = np.flatnonzero(pos < n)
        while act.size:         # the run of equal k0 (almost always 0 or 1 long)
            p = pos[act]
            eq = k0[p] == q0[act]
            act, p = act[eq], p[eq]
            hit = k1[p] == q1[act]
            out[act[hit]] = num[p[hit]]
            miss = ~hit
            act, p = act[miss], p[miss] + 1
            pos[act] = p
            act = act[p < n]
        for c in self.cols:
            c.drop_pages()
        return out

    def merge(self, k0: np.ndarray, k1: np.ndarray, num: np.ndarray) -> None:
        """Add the entries ``(k0, k1) -> num`` (fingerprints not in the set,
        distinct; any order): a sorted merge into new files."""
        order = np.argsort(k0, kind="stable")
        new = (k0[order], k1[order], num[order].astype(np.uint32))
        del order
        self.gen += 1
        paths = [self.dir.file(f"{name}.{self.gen}") for name, _ in _COLUMNS]
        old, n_old = self.cols, self.n
        try:
            outs = [open(p, "wb") for p in paths]
            try:
                for part in self._merged(old, n_old, new):
                    for f, arr in zip(outs, part):
                        f.write(arr.tobytes())
            finally:
                for f in outs:
                    f.close()
        except OSError as e:
            for p in paths:
                try:
                    os.remove(p)
                except OSError:
                    pass
            raise self.dir.fail(e) from None
        for c in old:
            c.close()
        self.n = n_old + len(new[0])
        self.cols = [_Column(p, dt, self.n) for p, (_, dt) in zip(paths, _COLUMNS)]
        self.index = np.array(self.cols[0].a[::self.PAGE])
        self.cols[0].drop_pages()
        self.merges += 1

    def _merged(self, old: list, n_old: int, new: tuple) -> Iterator[tuple]:
        """The old entries and ``new`` (sorted) merged, a chunk at a time."""
        b0 = new[0]
        taken = 0
        for s in range(0, n_old, self.CHUNK):
            e = min(s + self.CHUNK, n_old)
            a = tuple(np.array(c.a[s:e]) for c in old)
            for c in old:
                c.drop_pages()
            upto = len(b0) if e == n_old else int(np.searchsorted(b0, a[0][-1], "right"))
            b = tuple(x[taken:upto] for x in new)
            taken = upto
            yield _merge2(a, b)
        if not n_old:
            yield new

    def close(self) -> None:
        for c in self.cols:
            c.close()
        self.n = 0


def _merge2(a: tuple, b: tuple) -> tuple:
    """Two column tuples sorted on their first column, merged (``a``'s
    entries first among equal keys)."""
    if not len(b[0]):
        return a
    ib = np.searchsorted(a[0], b[0], "right") + np.arange(len(b[0]))
    total = len(a[0]) + len(b[0])
    keep = np.ones(total, dtype=bool)
    keep[ib] = False
    out = []
    for x, y in zip(a, b):
        o = np.empty(total, dtype=x.dtype)
        o[ib] = y
        o[keep] = x
        out.append(o)
    return tuple(out)


class SpillTable:
    """The visited set of a search with ``--spill``: what
    :class:`~pccl.search.explorer.FingerprintTable` offers the explorer
    (``n``, ``new_positions``/``add``, ``found``, ``index_of``,
    ``lookup_keys``, ``parent``), over an in-memory buffer of the states
    admitted since the last :meth:`spill` and a :class:`DiskSet` of the
    others.  State numbers are global: the buffer's state ``i`` is
    ``base + i``."""

    key_of = staticmethod(fingerprint)

    def __init__(self, directory: SpillDir):
        from pccl.search.explorer import FingerprintTable
        self._new_buffer = FingerprintTable
        self.dir = directory
        self.disk = DiskSet(directory)
        self.mem = FingerprintTable()
        self.base = 0           # states on disk (numbered 0 .. base - 1)
        self.n = 0
        self._batch: Any = None
        self.found: Any = None
        path = directory.file("parents")
        try:
            self._parents = open(path, "w+b")
        except OSError as e:    # pragma: no cover - SpillDir probed it
            raise directory.fail(e) from None

    @property
    def buffered(self) -> int:
        """States in the in-memory buffer."""
        return self.mem.n

    def lookup(self, q: np.ndarray) -> np.ndarray:
        """State numbers of the fingerprints ``q`` (shape (k, 2)); -1 where absent."""
        out = self.mem.lookup(q)
        hit = out >= 0
        out[hit] += self.base
        if self.disk.n:
            miss = np.flatnonzero(~hit)
            if miss.size:
                out[miss] = self.disk.lookup(q[miss, 0], q[miss, 1])
        return out

    def new_positions(self, keys: list, first: np.ndarray) -> np.ndarray:
        q = np.frombuffer(b"".join(keys), dtype=np.uint64).reshape(-1, 2)[first]
        self.found = found = self.lookup(q)
        new = found < 0
        self._batch = q[new]
        return first[new]

    def add(self, count: int, parents: np.ndarray) -> None:
        q = self._batch[:count]
        self._batch = None
        if self.n + len(q) > 0xFFFF_FFFE:
            raise MemoryError("more than 2**32 - 2 states")
        self.mem.insert(q, parents)
        self.n += len(q)

    def spill(self) -> None:
        """Move the buffer to disk: its parent links appended to the parents
        file, its fingerprints merged into the sorted file."""
        mem, m = self.mem, self.mem.n
        if not m:
            return
        mem.slots = None        # the buffer's index first: room for the sort
        try:
            self._parents.seek(0, os.SEEK_END)
            self._parents.write(mem.parents[:m].tobytes())
            self._parents.flush()
        except OSError as e:
            raise self.dir.fail(e) from None
        fps = mem.fps[:m]
        self.disk.merge(fps[:, 0], fps[:, 1], np.arange(self.base, self.base + m, dtype=np.uint32))
        del fps
        self.mem = mem = None   # type: ignore[assignment]
        self.mem = self._new_buffer()
        self.base += m

    def index_of(self, key: bytes) -> int:
        return int(self.lookup(np.frombuffer(key, dtype=np.uint64).reshape(1, 2))[0])

    def lookup_keys(self, keys: list) -> np.ndarray:
        return self.lookup(np.frombuffer(b"".join(keys), dtype=np.uint64).reshape(-1, 2))

    def parent(self, idx: int) -> int:
        if idx >= self.base:
            return self.mem.parent(idx - self.base)
        try:
            raw = os.pread(self._parents.fileno(), 4, 4 * idx)
        except OSError as e:
            raise self.dir.fail(e) from None
        p = int.from_bytes(raw, "little")
        return -1 if p == _NO_PARENT else p

    def close(self) -> None:
        self.disk.close()
        self._parents.close()


class LevelFile:
    """One BFS level's states on disk, in admission order: segments of
    ``(first state number, states)`` written by :meth:`write` and read
    back, a segment at a time, by :meth:`segments` (which deletes the file)."""

    def __init__(self, directory: SpillDir, name: str):
        self.dir = directory
        self.path = directory.file(name)
        self.f: Any = None
        self.count = 0
        self.last: Any = None

    def write(self, states: list, first: int) -> None:
        try:
            if self.f is None:
                self.f = open(self.path, "wb")
            pickle.dump((first, states), self.f, protocol=pickle.HIGHEST_PROTOCOL)
        except OSError as e:
            raise self.dir.fail(e) from None
        self.count += len(states)
        self.last = states[-1]

    def segments(self) -> Iterator[tuple[list, range]]:
        """The states and their numbers, a written segment at a time."""
        if self.f is None:
            return
        try:
            self.f.close()
            f = open(self.path, "rb")
        except OSError as e:
            raise self.dir.fail(e) from None
        try:
            with f:
                while True:
                    try:
                        first, states = pickle.load(f)
                    except EOFError:
                        break
                    yield states, range(first, first + len(states))
                    del states
        finally:
            self.discard()

    def discard(self) -> None:
        if self.f is not None and not self.f.closed:
            self.f.close()
        try:
            os.remove(self.path)
        except OSError:
            pass


class Spiller:
    """When and what a search with ``--spill`` moves to disk (see the
    module's docstring): :meth:`relieve` after every admitted batch.

    ``max_memory``: the search's bound in bytes (None: none); ``states``:
    spill whenever the buffer or the next level holds that many states (for
    tests: many spills on a small search; None: decided by the memory)."""

    #: spill everything that can go once the resident memory passes this
    #: fraction of ``max_memory``
    PRESSURE = 0.75

    def __init__(self, parent: str, max_memory: Optional[int], states: Optional[int] = None):
        import weakref
        self.dir = SpillDir(parent)
        self.table = SpillTable(self.dir)
        # the files go with the table (a counterexample's replay and the
        # graph analyses read it after the search), at the latest at exit
        weakref.finalize(self.table, self.dir.close)
        self.threshold = None if max_memory is None else int(max_memory * self.PRESSURE)
        self.table_limit: Optional[int] = None
        self.level_limit: Optional[int] = states
        if states is not None:
            self.table_limit = states
        elif max_memory is not None:
            self.table_limit = max(1 << 14, max_memory // 4 // STATE_BYTES)
        self.levels = 0         # level files written
        self.level_writes = 0   # segments written to them
        self._rss: Any = None

    def rss(self) -> int:
        if self._rss is None:
            import psutil
            self._rss = psutil.Process().memory_info
        return int(self._rss().rss)

    def relieve(self, adm: Any) -> None:
        """After a batch: spill the table's buffer when it is full, or both
        it and the next level's states when the memory is pressed."""
        table = self.table
        pressed = self.threshold is not None and self.rss() > self.threshold
        lim = self.table_limit
        if lim is not None and (table.buffered >= lim or (pressed and table.buffered >= lim // 8)):
            table.spill()
        if adm.nxt and (pressed or (self.level_limit is not None
                                    and len(adm.nxt) >= self.level_limit)):
            if adm.spilled is None:
                adm.spilled = LevelFile(self.dir, f"level.{self.levels}")
                self.levels += 1
            adm.spilled.write(adm.nxt, adm.nxt_idx[0])
            self.level_writes += 1
            adm.nxt, adm.nxt_idx = [], []

    def figures(self) -> dict:
        """What was spilled: merges of the visited set, states on disk,
        segments of levels written."""
        return {"merges": self.table.disk.merges, "states_on_disk": self.table.base,
                "level_segments": self.level_writes}
