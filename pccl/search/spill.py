"""The visited set and the frontier on disk (``pccl explore --spill DIR``).

Without ``--spill`` a search whose process passes ``--max-memory`` stops
there, as a bound.  With it the search moves what grows with the states to
files in a fresh directory under ``DIR`` (removed when the search ends) and
goes on, the way TLC's disk-based fingerprint set and disk queue do:

* **The visited set** (:class:`SpillTable`): the states admitted since the
  last spill stay in an in-memory :class:`~pccl.search.explorer.FingerprintTable`
  (the buffer); a spill sorts the buffer's fingerprints on their first
  64 bits and merges them, with their state numbers, into one sorted file
  on disk (:class:`DiskSet`: written afresh by a streaming merge, the old
  one deleted).  A batch of candidates is looked up in the buffer first;
  the rest go through a Bloom filter of the file's fingerprints (10 bits
  each, in memory: most new states stop there), and those it cannot rule
  out are found in the file: an in-memory index of every page's first key
  (a page: :data:`DiskSet.PAGE` entries) names each candidate's page, which
  is read with ``pread`` (once per page for the whole batch) and searched,
  all candidates at once with numpy.  The file is never mapped (mapped
  pages would count towards the process's resident memory).
* **Parent links** of spilled states go to an append-only file (4 bytes a
  state), read back only to rebuild a counterexample.
* **The next BFS level** (:class:`LevelFile`): admitted states are written,
  in admission order, to the level's file and read back a segment at a
  time when the level is expanded.  A segment is data, not a pickle (the
  spill directory is a path anyone with access to it could write to):
  records of at most 2,048 states, each a kind byte, its length (8 bytes)
  and MessagePack of its first state number (or numbers) and its states
  (:func:`pccl.search.safedata.pack_segment`; JSON for an integer past 64
  bits), checked when read back.

When to spill (:class:`Spiller`): after every admitted batch, when the
buffer holds :attr:`Spiller.table_limit` states (a quarter of
``--max-memory`` at 36 bytes a state); and once the process's resident
memory (psutil) passes three quarters of ``--max-memory``, the buffer when
it holds an eighth of that, and the next level's states.  (Measured: a
laxer rule under pressure, merging only once the buffer held a quarter of
the file, let fischer k=2 d=2 pass ``--max-memory 70M``.)
If the memory still passes ``--max-memory`` the bound stops the search as
without ``--spill``.

The result is the in-memory search's: the same state numbers in the same
order, hence the same states, transitions, depth, verdict and
counterexample (``tests/search/test_spill.py`` compares them).

With ``--workers N`` each worker spills its partition and its share of the
levels the same way (:class:`PartitionTable`, :class:`WorkerSpiller`: the
end of this module).
"""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from typing import Any, Optional

import numpy as np

from pccl.search import safedata
from pccl.search.fingerprint import fingerprint

__all__ = ["SpillError", "SpillDir", "DiskSet", "SpillTable", "LevelFile", "Spiller",
           "PartitionTable", "WorkerSpiller", "WorkerSpills", "worker_dirs"]

_NO_PARENT = 0xFFFF_FFFF
#: bytes of memory a buffered state costs (fingerprint, parent link, index)
STATE_BYTES = 36


class SpillError(Exception):
    """The spill directory cannot be written (absent and not creatable, not
    writable, the disk full).  The front ends report it as one message
    naming ``--spill`` (``pccl.api`` raises it as a ``PcclError``), exit 2."""

    #: the option a report names (a placeholder: ``--spill`` on the command
    #: line, ``spill`` in the API)
    option = "{spill}"


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


#: one entry of the sorted file: the fingerprint's two halves, the state number
RECORD = np.dtype([("k0", "<u8"), ("k1", "<u8"), ("num", "<u4")])


class DiskSet:
    """A set of 128-bit fingerprints ``(k0, k1)`` with a ``uint32`` value
    each (the state number), in one file of :data:`RECORD` entries sorted on
    ``k0``, in ``directory`` (a :class:`SpillDir`).  :meth:`merge` adds
    entries, :meth:`lookup` finds a batch.

    The file is never mapped: a lookup reads, with ``pread``, the one page
    (:data:`PAGE` entries, and the next page's first) that the in-memory
    index of every page's first key names for each candidate, once per page
    however many candidates fall in it.  (Mapped, a touched page of a
    large-folio page cache brings up to 256 KiB into the process's resident
    memory: measured on ext4, Linux 6.18.)"""

    #: entries per page of the in-memory index (5 KiB of the file)
    PAGE = 256
    #: entries merged per step (bounded temporaries: about 70 bytes each)
    CHUNK = 1 << 16
    #: queries looked up per step (bounded temporaries: a page each)
    QUERIES = 1024

    def __init__(self, directory: SpillDir):
        self.dir = directory
        self.n = 0
        self.gen = 0
        self.path: Optional[str] = None
        self._fd: Optional[int] = None
        self.index = np.empty(0, dtype=np.uint64)
        #: merges done, pages read
        self.merges = 0
        self.reads = 0
        #: a Bloom filter of the file's fingerprints (:meth:`maybe`): most
        #: new states are never looked up on disk
        self.bloom = np.zeros(0, dtype=np.uint8)

    # -- lookups ---------------------------------------------------------------
    def lookup(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """The values of the fingerprints ``(q0[i], q1[i])`` (``uint64``
        arrays); -1 where absent."""
        out = np.full(len(q0), -1, dtype=np.int64)
        if not self.n:
            return out
        cand = np.flatnonzero(self.maybe(q0, q1))
        q0, q1 = q0[cand], q1[cand]
        step = self.QUERIES
        try:
            for s in range(0, len(q0), step):
                out[cand[s:s + step]] = self._lookup(q0[s:s + step], q1[s:s + step])
        except OSError as e:
            raise self.dir.fail(e) from None
        return out

    # -- the Bloom filter ------------------------------------------------------
    #: bits of the filter per entry (at least), and probes: about 1 % false positives
    BLOOM_BITS = 10
    BLOOM_PROBES = 4

    def _probes(self, q0: np.ndarray, q1: np.ndarray) -> Iterator[np.ndarray]:
        """The filter's bit numbers of each fingerprint, a probe at a time
        (double hashing on the fingerprint's halves, already uniform)."""
        mask = np.uint64(len(self.bloom) * 8 - 1)
        for i in range(self.BLOOM_PROBES):
            yield (q1 + q0 * np.uint64(i)) & mask

    def maybe(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """False where the fingerprint is certainly not in the set."""
        bloom = self.bloom
        out = np.ones(len(q0), dtype=bool)
        for h in self._probes(q0, q1):
            out &= (bloom[h >> np.uint64(3)] >> (h & np.uint64(7)).astype(np.uint8)) & 1 == 1
        return out

    def _bloom_add(self, q0: np.ndarray, q1: np.ndarray) -> None:
        step = self.CHUNK      # bounded temporaries
        for s in range(0, len(q0), step):
            self._bloom_add_slice(q0[s:s + step], q1[s:s + step])

    def _bloom_add_slice(self, q0: np.ndarray, q1: np.ndarray) -> None:
        for h in self._probes(q0, q1):
            h.sort()            # the bits of one byte together: OR-ed by reduceat
            byte = h >> np.uint64(3)
            bits = np.left_shift(np.uint8(1), (h & np.uint64(7)).astype(np.uint8))
            starts = np.flatnonzero(np.r_[True, byte[1:] != byte[:-1]])
            self.bloom[byte[starts]] |= np.bitwise_or.reduceat(bits, starts)

    def _bloom_size(self, n: int) -> int:
        """Bytes of a filter for ``n`` entries (a power of two)."""
        size = 64
        while size * 8 < n * self.BLOOM_BITS:
            size *= 2
        return size

    def _read(self, start: int, count: int, into: np.ndarray) -> int:
        """Entries ``start ..`` (at most ``count``) into ``into``; how many."""
        count = min(count, self.n - start)
        if count <= 0:
            return 0
        assert self._fd is not None
        view = into.reshape(-1).view(np.uint8).data[:count * RECORD.itemsize]
        got = os.preadv(self._fd, [view], start * RECORD.itemsize)
        if got != count * RECORD.itemsize:
            raise OSError(errno.EIO, "short read of the spilled fingerprints")
        return count

    def _lookup(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        page, width = self.PAGE, self.PAGE + 1
        out = np.full(len(q0), -1, dtype=np.int64)
        # the last page whose first key is below q: the first key >= q is in
        # it or is the next page's first (both read), or is entry 0
        j = np.maximum(np.searchsorted(self.index, q0, "left").astype(np.int64) - 1, 0)
        pages, row = np.unique(j, return_inverse=True)
        buf = np.empty((len(pages), width), dtype=RECORD)
        size = RECORD.itemsize
        rb = width * size
        mv = buf.reshape(-1).view(np.uint8).data
        fd, preadv = self._fd, os.preadv
        assert fd is not None
        got = [preadv(fd, [mv[o:o + rb]], at)
               for o, at in zip(range(0, len(pages) * rb, rb), (pages * (page * size)).tolist())]
        del mv
        valid = np.asarray(got, dtype=np.int64) // size
        if (valid < np.minimum(width, self.n - pages * page)).any():
            raise OSError(errno.EIO, "short read of the spilled fingerprints")
        self.reads += len(pages)
        k0, k1, num = buf["k0"], buf["k1"], buf["num"]
        lo = np.zeros(len(q0), dtype=np.int64)
        hi = valid[row]
        act = np.flatnonzero(lo < hi)
        while act.size:         # binary search in each candidate's page
            a, b, rw = lo[act], hi[act], row[act]
            mid = (a + b) >> 1
            less = k0[rw, mid] < q0[act]
            lo[act] = np.where(less, mid + 1, a)
            hi[act] = np.where(less, b, mid)
            act = act[lo[act] < hi[act]]
        pos, end = lo, valid[row]
        act = np.flatnonzero(pos < end)
        while act.size:         # the run of equal k0 (almost always 0 or 1 long)
            p, rw = pos[act], row[act]
            eq = k0[rw, p] == q0[act]
            act, p, rw = act[eq], p[eq], rw[eq]
            hit = k1[rw, p] == q1[act]
            out[act[hit]] = num[rw[hit], p[hit]]
            miss = ~hit
            act, p = act[miss], p[miss] + 1
            pos[act] = p
            beyond = act[p == width]        # the run goes on past the window read
            for i in beyond.tolist():
                out[i] = self._scan(int(pages[row[i]]) * page + width, q0[i], q1[i])
            act = act[p < end[act]]
        return out

    def _scan(self, start: int, q0, q1) -> int:
        """The value of ``(q0, q1)`` in the run of equal ``k0`` from entry
        ``start`` on (-1 if absent): one entry at a time (a run of equal
        64-bit halves longer than a page: practically never)."""
        one = np.empty(1, dtype=RECORD)
        while self._read(start, 1, one) and one["k0"][0] == q0:
            if one["k1"][0] == q1:
                return int(one["num"][0])
            start += 1
        return -1

    # -- merges ----------------------------------------------------------------
    def merge(self, k0: np.ndarray, k1: np.ndarray, num: np.ndarray) -> None:
        """Add the entries ``(k0, k1) -> num`` (fingerprints not in the set,
        distinct; any order)."""
        self.merge_sorted(self.sort_entries(k0, k1, num))

    @staticmethod
    def sort_entries(k0: np.ndarray, k1: np.ndarray, num: np.ndarray) -> np.ndarray:
        """The entries as :data:`RECORD` entries sorted on ``k0``."""
        new = np.empty(len(k0), dtype=RECORD)
        order = np.argsort(k0, kind="stable")
        new["k0"], new["k1"], new["num"] = k0[order], k1[order], num[order]
        return new

    def merge_sorted(self, new: np.ndarray) -> None:
        """Add the entries ``new`` (from :meth:`sort_entries`): a sorted merge
        into a new file, the old one read a chunk at a time, the page index
        and the Bloom filter built on the way."""
        self.gen += 1
        path = self.dir.file(f"fingerprints.{self.gen}")
        firsts: list = []
        written = 0
        size = self._bloom_size(self.n + len(new))
        grow = size != len(self.bloom)
        if grow:                # a larger filter, of every entry (the old one is dropped)
            self.bloom = np.zeros(size, dtype=np.uint8)
        else:
            self._bloom_add(new["k0"], new["k1"])
        try:
            with open(path, "wb") as f:
                for part in self._merged(new):
                    firsts.append(part["k0"][(-written) % self.PAGE::self.PAGE].copy())
                    written += len(part)
                    if grow:
                        self._bloom_add(part["k0"], part["k1"])
                    _tofile(part, f)
                    del part
            fd = os.open(path, os.O_RDONLY)
        except OSError as e:
            try:
                os.remove(path)
            except OSError:
                pass
            raise self.dir.fail(e) from None
        self._drop()
        self.path, self._fd = path, fd
        self.n = written
        self.index = np.concatenate(firsts) if firsts else np.empty(0, dtype=np.uint64)
        self.merges += 1

    def _merged(self, new: np.ndarray) -> Iterator[np.ndarray]:
        """The file's entries and ``new`` (sorted) merged, a chunk at a time."""
        n_old, b0 = self.n, new["k0"]
        taken = 0
        chunk = np.empty(self.CHUNK, dtype=RECORD)
        for s in range(0, n_old, self.CHUNK):
            got = self._read(s, self.CHUNK, chunk)
            a = chunk[:got]
            upto = len(new) if s + got == n_old else int(np.searchsorted(b0, a["k0"][-1], "right"))
            yield _merge2(a, new[taken:upto])
            taken = upto
        if not n_old:
            for s in range(0, len(new), self.CHUNK):
                yield new[s:s + self.CHUNK]

    def _drop(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if self.path is not None:
            try:
                os.remove(self.path)
            except OSError:
                pass
            self.path = None

    def close(self) -> None:
        self._drop()
        self.n = 0


def _tofile(arr: np.ndarray, f) -> None:
    arr.tofile(f)


def _merge2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Two record arrays sorted on ``k0``, merged (``a``'s entries first
    among equal keys)."""
    if not len(b):
        return a
    ib = np.searchsorted(a["k0"], b["k0"], "right") + np.arange(len(b))
    out = np.empty(len(a) + len(b), dtype=RECORD)
    keep = np.ones(len(out), dtype=bool)
    keep[ib] = False
    out[ib] = b
    out[keep] = a
    return out


class SpillTable:
    """The visited set of a search with ``--spill``: what
    :class:`~pccl.search.explorer.FingerprintTable` offers the explorer
    (``n``, ``new_positions``/``add``, ``found``, ``index_of``,
    ``lookup_keys``, ``parent``), over an in-memory buffer of the states
    admitted since the last :meth:`spill` and a :class:`DiskSet` of the
    others.  State numbers are global: the buffer's state ``i`` is
    ``base + i``.  ``new_buffer()`` makes an empty buffer (the explorer's
    ``FingerprintTable``)."""

    key_of = staticmethod(fingerprint)

    def __init__(self, directory: SpillDir, new_buffer: Callable[[], Any]):
        self._new_buffer = new_buffer
        self.dir = directory
        self.disk = DiskSet(directory)
        self.mem = new_buffer()
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
        m = self.mem.n
        if not m:
            return
        self.mem.slots = None   # the buffer's index first: room for the sort
        try:
            self._parents.seek(0, os.SEEK_END)
            self._parents.write(self.mem.parents[:m].tobytes())
            self._parents.flush()
        except OSError as e:
            raise self.dir.fail(e) from None
        fps = self.mem.fps[:m]
        new = self.disk.sort_entries(fps[:, 0], fps[:, 1],
                                     np.arange(self.base, self.base + m, dtype=np.uint32))
        del fps
        self.mem = None         # the buffer freed before the merge, the new one after
        self.disk.merge_sorted(new)
        del new
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


def _segment(head: bytes, f, path: str) -> tuple:
    """A level file's record (after its ``head``: a kind, ``M`` MessagePack
    or ``J`` JSON, and an 8-byte length), checked: ``(first number or
    numbers, states)``; a SpillError when it is not one."""
    try:
        if len(head) != 9 or head[:1] not in (b"M", b"J"):
            raise safedata.DataError("not a record")
        size = int.from_bytes(head[1:], "little")
        blob = f.read(size)
        if len(blob) != size or not blob:
            raise safedata.DataError("truncated")
        if head[:1] == b"M":
            first, states = safedata.unpack_segment(blob)
        else:
            seg = safedata.loads(blob)
            if type(seg) is not tuple or len(seg) != 2 or type(seg[1]) is not list:
                raise safedata.DataError("not a segment")
            first, states = seg
        if type(first) is list:
            if len(first) != len(states) or not all(type(i) is int and i >= 0 for i in first):
                raise safedata.DataError("its state numbers do not fit")
        elif type(first) is not int or first < 0:
            raise safedata.DataError("not a state number")
        if not all(type(st) is tuple or type(st) is bytes for st in states):
            raise safedata.DataError("not states")
    except safedata.DataError as e:
        raise SpillError(f"{path}: not a level file this search wrote ({e})") from None
    return first, states


class LevelFile:
    """One BFS level's states on disk, in admission order: segments of
    ``(first state number, states)`` written by :meth:`write` and read
    back, a segment at a time, by :meth:`segments` (which deletes the file).
    On disk a segment is records of at most :attr:`CHUNK` states (a kind
    byte, an 8-byte length, MessagePack: :func:`safedata.pack_segment`), so
    neither writing nor reading holds more than a record's bytes at once."""

    #: states a record holds at most
    CHUNK = 2048

    def __init__(self, directory: SpillDir, name: str):
        self.dir = directory
        self.path = directory.file(name)
        self.f: Any = None
        self.count = 0
        self.last: Any = None

    def write(self, states: list, first) -> None:
        """Append a segment: ``states`` numbered from ``first`` on (an int),
        or numbered ``first`` (a list of numbers: a worker's share of a
        level, :class:`WorkerSpiller`)."""
        try:
            if self.f is None:
                self.f = open(self.path, "wb")
            ints = isinstance(first, int)
            for a in range(0, len(states), self.CHUNK):     # records of CHUNK states
                part = states[a:a + self.CHUNK]
                head = first + a if ints else [int(i) for i in first[a:a + self.CHUNK]]
                try:
                    kind, blob = b"M", safedata.pack_segment(head, part)
                except (TypeError, OverflowError, ValueError):      # an int past 64 bits
                    kind, blob = b"J", safedata.dumps((head, part))
                self.f.write(kind + len(blob).to_bytes(8, "little"))
                self.f.write(blob)
                del blob
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
                    head = f.read(9)
                    if not head:
                        break
                    first, states = _segment(head, f, self.path)
                    yield states, (range(first, first + len(states))
                                   if isinstance(first, int) else first)
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


class _Policy:
    """The rules :class:`Spiller` and :class:`WorkerSpiller` share: when
    the memory is pressed, when the table's buffer and the next level go
    to disk (the module's docstring)."""

    #: spill everything that can go once the resident memory passes this
    #: fraction of ``max_memory``
    PRESSURE = 0.75

    def _limits(self, memory: Optional[int], states: Optional[int]) -> None:
        """``memory``: the bytes this process may use (None: no bound);
        ``states``: :attr:`Spiller.STATES`."""
        self.threshold = None if memory is None else int(memory * self.PRESSURE)
        self.level_limit: Optional[int] = states
        self.table_limit: Optional[int] = states
        if states is None and memory is not None:
            self.table_limit = max(1 << 14, memory // 4 // STATE_BYTES)
        self.levels = 0         # level files written
        self.level_writes = 0   # segments written to them
        self._rss: Any = None

    def rss(self) -> int:
        if self._rss is None:
            import psutil
            self._rss = psutil.Process().memory_info
        return int(self._rss().rss)

    def _pressed(self, rss: int) -> bool:
        """Whether the memory is pressed at ``rss`` bytes resident."""
        return self.threshold is not None and rss > self.threshold

    def _relieve_table(self, table) -> bool:
        """Spill the table's buffer when it is full (or an eighth full and
        the memory pressed); whether the memory is pressed."""
        pressed = self._pressed(self.rss())
        lim = self.table_limit
        if lim is not None and (table.buffered >= lim or (pressed and table.buffered >= lim // 8)):
            table.spill()
        return pressed

    def _level_due(self, n: int, pressed: bool) -> bool:
        """Whether a next level of ``n`` states in memory goes to disk."""
        return bool(n) and (pressed or (self.level_limit is not None and n >= self.level_limit))


class Spiller(_Policy):
    """When and what a search with ``--spill`` moves to disk (see the
    module's docstring): :meth:`relieve` after every admitted batch.

    ``max_memory``: the search's bound in bytes (None: none, and nothing is
    spilled unless :attr:`STATES` says so); ``new_buffer``: as
    :class:`SpillTable`'s."""

    #: spill whenever the buffer or the next level holds this many states
    #: (tests set it: many spills and merges on a small search)
    STATES: Optional[int] = None

    def __init__(self, parent: str, max_memory: Optional[int], new_buffer: Callable[[], Any]):
        states = self.STATES
        import weakref
        self.dir = SpillDir(parent)
        self.table = SpillTable(self.dir, new_buffer)
        # the files go with the table (a counterexample's replay and the
        # graph analyses read it after the search), at the latest at exit
        weakref.finalize(self.table, self.dir.close)
        self._limits(max_memory, states)

    def relieve(self, adm: Any) -> None:
        """After a batch: spill the table's buffer when it is full, or both
        it and the next level's states when the memory is pressed."""
        pressed = self._relieve_table(self.table)
        if self._level_due(len(adm.nxt), pressed):
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

    def note(self) -> str:
        """What the search spilled, for the report's notes."""
        f = self.figures()
        if not f["merges"] and not f["level_segments"]:
            return (f"{{spill={self.dir.parent}}}: nothing spilled (the memory stayed below "
                    f"{self.PRESSURE:.0%} of {{max_memory}})")
        return (f"{{spill={self.dir.parent}}}: the visited states merged to disk "
                f"{f['merges']:,} time(s) ({f['states_on_disk']:,} states on disk at the end), "
                f"{f['level_segments']:,} segment(s) of levels written")


# ---------------------------------------------------------------------------
# The parallel search (``--spill DIR --workers N``, pccl/search/parallel.py)
# ---------------------------------------------------------------------------
#
# Each worker owns a partition of the visited set and holds its share of the
# next level; with ``--spill`` each spills both as one process does, into its
# own directory ``DIR/worker-<i>/pccl-spill-XXXXXXXX/`` (made and removed by
# the coordinator: :func:`worker_dirs`), by :class:`Spiller`'s rules against
# its own process's resident memory, with a share of ``--max-memory`` that
# the coordinator sets by need and moves with the search (:func:`shares`,
# :meth:`WorkerSpiller.relieve`).  The coordinator still stops the search
# when the processes' peaks together pass ``--max-memory``.


def shares(bound: int, peaks: list) -> list:
    """Each process's share of ``bound`` (``--max-memory``) given the
    processes' peaks so far (``peaks``: before the first state, the size
    each process starts at): its own peak plus an even part of what the
    peaks together leave of the bound.  So the shares add up to the bound,
    a process that needs more than another from the start (the
    coordinator's: worker 0, the parent links, the interpreter's pages not
    shared) gets it, and as the peaks grow each process's share shrinks
    towards its peak: the one that grew most is pressed first.  (Split
    evenly, ``bound / N``: fischer k=2 d=2 with 2 workers at 110M, the
    coordinator's process started at 48 MiB, above three quarters of its
    55, and peaked at 61 while the forked worker peaked at 50; the search
    stopped bounded at 307,548 of 1,066,248 states.  docs/scale-out.md.)"""
    slack = bound - sum(peaks)
    n = len(peaks)
    return [int(p) + slack // n for p in peaks]


def worker_dirs(parent: str, n: int) -> list:
    """A fresh :class:`SpillDir` under ``parent/worker-<i>/`` for each of
    ``n`` workers, made (and probed) by the coordinator: an unwritable
    ``parent`` is one :class:`SpillError` before any worker spills.  The
    workers (forked processes) get them as arguments;
    :func:`close_worker_dirs` removes them."""
    dirs: list = []
    try:
        for w in range(n):
            d = SpillDir(os.path.join(os.fspath(parent), f"worker-{w}"))
            d.parent = os.fspath(parent)        # messages name the directory given
            dirs.append(d)
    except SpillError:
        close_worker_dirs(dirs)
        raise SpillError(f"cannot write the search's files to {parent}: "
                         f"{_probe_why(parent)}") from None
    return dirs


def _probe_why(parent: str) -> str:
    try:
        os.makedirs(parent, exist_ok=True)
        tempfile.TemporaryFile(dir=parent).close()
    except OSError as e:
        return _why(e)
    return "a worker's directory cannot be written"     # pragma: no cover - a race


def close_worker_dirs(dirs: list) -> None:
    """Remove the workers' directories (and ``worker-<i>/`` once empty)."""
    for d in dirs:
        d.close()
        try:
            os.rmdir(os.path.dirname(d.path))
        except OSError:
            pass


class PartitionTable:
    """A worker's partition of the visited set with ``--spill``: what the
    parallel search's worker asks of its
    :class:`~pccl.search.explorer.FingerprintTable` (``n``, ``lookup``,
    ``insert``), over an in-memory buffer of the fingerprints recorded since
    the last :meth:`spill` and a :class:`DiskSet` of the others.  A worker's
    table maps a fingerprint to its *global* state number (the buffer keeps
    it in its parent slot, the disk set as its value): :meth:`lookup`
    answers those numbers, -1 where absent.  No parents file: the
    coordinator holds the parent links."""

    def __init__(self, directory: SpillDir, new_buffer: Callable[[], Any]):
        self._new_buffer = new_buffer
        self.dir = directory
        self.disk = DiskSet(directory)
        # smaller steps than one process's: a merge's and a lookup's
        # temporaries (a chunk's records, merged copy and Bloom probes; a
        # page per query) are the part of a worker's memory its share must
        # leave room for (:meth:`spill_cost`; measured with tracemalloc: a
        # merge of 33,000 states into 40,000 took 5.7 MB with 65,536-entry
        # chunks, 2.5 MB with 16,384)
        self.disk.CHUNK = 1 << 14
        self.disk.QUERIES = 256
        self.mem = new_buffer()
        self.n = 0
        #: the largest batch looked up (:meth:`spill_cost`)
        self.batch = 0

    @property
    def buffered(self) -> int:
        return self.mem.n

    def lookup(self, q: np.ndarray) -> np.ndarray:
        """Global state numbers of the fingerprints ``q`` (shape (k, 2)); -1
        where absent."""
        self.batch = max(self.batch, len(q))
        local = self.mem.lookup(q)
        hit = local >= 0
        out = np.full(len(q), -1, dtype=np.int64)
        out[hit] = self.mem.parents[local[hit]]
        if self.disk.n:
            miss = np.flatnonzero(~hit)
            if miss.size:
                out[miss] = self.disk.lookup(q[miss, 0], q[miss, 1])
        return out

    def insert(self, q: np.ndarray, numbers: np.ndarray) -> None:
        """Record fingerprints ``q`` (distinct, absent) as states ``numbers``."""
        if len(q):
            self.mem.insert(q, numbers)
            self.n += len(q)

    def number_of(self, key: bytes) -> int:
        """The global state number of the fingerprint ``key`` (-1: not mine)."""
        return int(self.lookup(np.frombuffer(key, dtype=np.uint64).reshape(1, 2))[0])

    #: bytes a merge holds for a buffered state beyond the buffer (the
    #: sorted entries, the order, the gathered halves: measured 48-54 with
    #: tracemalloc), and per entry of a chunk (its records, the merged copy,
    #: the Bloom filter's probes); bytes a lookup holds per fingerprint
    #: looked up (the answers, the filter's probes: measured 27)
    MERGE_BYTES = 56
    CHUNK_BYTES = 80
    LOOKUP_BYTES = 48

    def spill_cost(self) -> int:
        """The memory a :meth:`spill` of the buffer now would take beyond
        what the process holds (the Bloom filter, when it grows, is made
        anew beside the old one), or a lookup as large as the largest yet
        (a page per query in a step), whichever is more."""
        disk, m = self.disk, self.mem.n
        lookup = self.batch * self.LOOKUP_BYTES + (
            disk.QUERIES * (disk.PAGE + 1) * RECORD.itemsize if disk.n else 0)
        if not m:
            return lookup
        grow = disk._bloom_size(disk.n + m)
        return max(lookup, m * self.MERGE_BYTES + disk.CHUNK * self.CHUNK_BYTES
                   + (grow if grow != len(disk.bloom) else 0))

    def spill(self) -> None:
        """Merge the buffer into the sorted file (as :meth:`SpillTable.spill`)."""
        m = self.mem.n
        if not m:
            return
        self.mem.slots = None
        fps = self.mem.fps[:m]
        new = self.disk.sort_entries(fps[:, 0], fps[:, 1], self.mem.parents[:m])
        del fps
        self.mem = None
        self.disk.merge_sorted(new)
        del new
        self.mem = self._new_buffer()

    def entries(self) -> tuple:
        """Every fingerprint of the partition and its state number:
        ``(fps (n, 2) uint64, numbers uint32)`` (the file read back a chunk
        at a time: the time-lock, stall and temporal checks gather the
        whole table once the search is over)."""
        fps = np.empty((self.n, 2), dtype=np.uint64)
        nums = np.empty(self.n, dtype=np.uint32)
        disk, at = self.disk, 0
        chunk = np.empty(DiskSet.CHUNK, dtype=RECORD)
        try:
            for s in range(0, disk.n, DiskSet.CHUNK):
                got = disk._read(s, DiskSet.CHUNK, chunk)
                fps[at:at + got, 0], fps[at:at + got, 1] = chunk["k0"][:got], chunk["k1"][:got]
                nums[at:at + got] = chunk["num"][:got]
                at += got
        except OSError as e:
            raise self.dir.fail(e) from None
        m = self.mem.n
        fps[at:at + m], nums[at:at + m] = self.mem.fps[:m], self.mem.parents[:m]
        return fps, nums

    def close(self) -> None:
        self.disk.close()


class WorkerSpiller(_Policy):
    """When and what worker ``w`` of a parallel search with ``--spill``
    moves to disk (:meth:`relieve`, after each commit of the coordinator's
    decision): its partition of the visited set (:class:`PartitionTable`)
    and its share of the next level (a :class:`LevelFile`, read back a
    segment at a time when the level is expanded: :meth:`take_level`), by
    :class:`Spiller`'s rules, against its own process's resident memory.
    ``share``: the bytes of ``--max-memory`` this process may peak at (None:
    no bound; the coordinator sets it, :func:`shares`, and moves it with the
    search: :attr:`share`); ``states``: :attr:`Spiller.STATES` as the
    coordinator has it.

    Pressed (everything that can go goes to disk, and the level's
    candidates are freed at once instead of while the process waits) once
    the resident memory passes its share less a reserve: a quarter of the
    room between the process's size at its start (:attr:`start`) and its
    share, or twice the most a level has added to it lately
    (:attr:`excursion`: a level's candidates, measured when they are all
    held) plus what spilling the buffer would take (:meth:`PartitionTable.spill_cost`),
    whichever is larger.  What a level adds cannot be spilled before the
    coordinator has decided it, and a merge needs memory of its own, so the
    reserve is what keeps the peak, which never comes down, within the
    share.  (Without it, measured: a merge's temporaries lifted a process's
    peak 4 MiB above its share in one step.)"""

    def __init__(self, directory: SpillDir, share: Optional[int], states: Optional[int],
                 new_buffer: Callable[[], Any]):
        self.dir = directory
        self.table = PartitionTable(directory, new_buffer)
        self._limits(share, states)
        self._states = states
        self.level: Optional[LevelFile] = None
        #: this process's resident memory before its first state
        self.start = self.rss()
        self.share = share
        #: what a level added lately (bytes, decaying), and the resident
        #: memory after the last relief
        self.excursion = 0
        self._after = self.start
        self.pressed = False

    def set_share(self, share: Optional[int], first: bool = False) -> None:
        """The coordinator's share for this process (:func:`shares`); the
        ``first`` also sets the size of the buffer (a quarter of the share at
        36 bytes a state, as one process's; not moved with the search, which
        would merge ever smaller buffers)."""
        self.share = share
        if first and share is not None and self._states is None:
            self.table_limit = max(1 << 14, (share - self.start) // 4 // STATE_BYTES)

    def _pressed(self, rss: int) -> bool:
        share = self.share
        if share is None:
            return False
        room = max(share - self.start, 0)
        reserve = max(int(room * (1 - self.PRESSURE)),
                      2 * self.excursion + self.table.spill_cost())
        return rss > share - reserve

    def observe(self) -> None:
        """A level's candidates are all held (the worker's ``finish``): what
        the level added to the resident memory since the last relief."""
        if self.share is not None:
            grew = self.rss() - self._after
            self.excursion = max(grew, self.excursion * 15 // 16)

    def relieve(self, w: Any) -> None:
        """After the worker ``w`` recorded new states (its table) and took
        its share of the next level (``w.level``, ``w.level_idx``)."""
        self.pressed = pressed = self._relieve_table(self.table)
        if self._level_due(len(w.level), pressed):
            if self.level is None:
                self.level = LevelFile(self.dir, f"level.{self.levels}")
                self.levels += 1
            self.level.write(w.level, list(w.level_idx))
            self.level_writes += 1
            w.level, w.level_idx = [], []
        if self.share is not None:
            self._after = self.rss()

    def take_level(self) -> Optional[LevelFile]:
        """The part of the worker's level written to disk (before what it
        holds in memory), or None; the next level starts a new file."""
        level, self.level = self.level, None
        return level

    def figures(self) -> dict:
        return {"merges": self.table.disk.merges, "states_on_disk": self.table.disk.n,
                "level_segments": self.level_writes, "start": self.start}

    def close(self) -> None:
        self.table.close()
        if self.level is not None:
            self.level.discard()


class WorkerSpills:
    """What the workers of a parallel search spilled (their
    :meth:`WorkerSpiller.figures`), for the report's notes; ``peaks``: each
    process's peak resident memory (worker 0's: the coordinator's process),
    said with the size each started at when ``max_memory`` bounds them."""

    def __init__(self, parent: str, figures: list, peaks: Optional[list] = None,
                 bound: Optional[int] = None):
        self.parent = parent
        self.per_worker = figures
        self.peaks = peaks
        self.bound = bound

    def figures(self) -> dict:
        return {k: sum(f[k] for f in self.per_worker)
                for k in ("merges", "states_on_disk", "level_segments")}

    def memory(self) -> str:
        """The processes' sizes at their start and their peaks, against
        ``--max-memory`` (what a bound must leave room for)."""
        if self.bound is None or not self.peaks:
            return ""
        from pccl.search.memory import format_size
        mib = 1 << 20
        starts = [f.get("start", 0) for f in self.per_worker]
        return (f"; the processes started at {' + '.join(f'{s / mib:.0f}' for s in starts)} "
                f"= {sum(starts) / mib:.0f} MiB and peaked at "
                f"{' + '.join(f'{p / mib:.0f}' for p in self.peaks)} = "
                f"{sum(self.peaks) / mib:.0f} MiB together "
                f"({{max_memory={format_size(self.bound)}}}: {self.bound / mib:.0f} MiB)")

    def note(self) -> str:
        f, k = self.figures(), len(self.per_worker)
        if not f["merges"] and not f["level_segments"]:
            return (f"{{spill={self.parent}}}: nothing spilled by the {k} workers (each "
                    f"process's memory stayed below its share of {{max_memory}})"
                    + self.memory())
        each = "; ".join(f"worker {w}: {x['merges']:,} merge(s), {x['states_on_disk']:,} states on "
                         f"disk, {x['level_segments']:,} segment(s)"
                         for w, x in enumerate(self.per_worker))
        return (f"{{spill={self.parent}}}: the {k} workers merged their visited states to disk "
                f"{f['merges']:,} time(s) ({f['states_on_disk']:,} states on disk at the end), "
                f"{f['level_segments']:,} segment(s) of levels written ({each})" + self.memory())
