"""The visited set of a search: :class:`FingerprintTable` (128-bit
fingerprints and parent links in numpy arrays, with an open-addressing
index) and :class:`ExactTable` (``--exact``: the canonical encodings
themselves), and the reserved, lazily committed arrays they grow in
(:func:`_reserve`).  Used by :mod:`pccl.search.explorer` and the parallel
workers."""

from __future__ import annotations

import itertools
import mmap
import os
import sys
from typing import Any, Optional

import numpy as np

from pccl.search.fingerprint import encode, fingerprint


# ---------------------------------------------------------------------------
# Visited storage
# ---------------------------------------------------------------------------

_EMPTY = np.uint32(0xFFFF_FFFF)
_MAX_STATES = 0xFFFF_FFFE


def physical_memory() -> int:
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 1 << 34


def _reserve(shape: tuple, dtype) -> Optional[np.ndarray]:
    """An array over a reserved, lazily committed anonymous mapping: only the
    pages written count towards memory, and it never has to grow by copying.
    ``None`` where the platform cannot do that."""
    nbytes = int(np.prod(shape)) * np.dtype(dtype).itemsize
    try:
        flags = mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS | getattr(
            mmap, "MAP_NORESERVE", 0x4000 if sys.platform.startswith("linux") else 0)
        buf = mmap.mmap(-1, nbytes, flags=flags)
    except (OSError, ValueError, AttributeError, TypeError):
        return None
    return np.frombuffer(buf, dtype=dtype).reshape(shape)


class FingerprintTable:
    """The visited set as arrays: 128-bit fingerprints and parent links by
    state number, plus an open-addressing index (linear probing, load at
    most 1/2) of ``uint32`` state numbers keyed by the fingerprint's low
    64 bits.

    The two per-state arrays are reserved up front for as many states as
    the machine's memory could hold (virtual address space only: pages are
    committed as they are written), so they never grow by copying; where
    that is not available they grow by doubling.  The index is rebuilt from
    the fingerprint array when it passes half full, after the old one is
    freed.
    """

    key_of = staticmethod(fingerprint)

    def __init__(self, capacity: Optional[int] = None, kernels: Optional[tuple] = None):
        self.n = 0
        if capacity is None:
            capacity = min(_MAX_STATES, physical_memory() // 20)
            fps, parents = _reserve((capacity, 2), np.uint64), _reserve((capacity,), np.uint32)
            if fps is None or parents is None:
                fps, parents = None, None
                capacity = 1 << 12
        else:
            fps = parents = None
        self.fps = fps if fps is not None else np.empty((capacity, 2), dtype=np.uint64)
        self.parents = parents if parents is not None else np.empty(capacity, dtype=np.uint32)
        self._new_index(1 << 13)
        self._batch: Any = None         # (fingerprints, positions) of the last batch
        #: state numbers of the last batch's first occurrences (-1: new)
        self.found: Any = None
        #: (lookup, place) of the native engine (its ``table_kernels``): the
        #: index probed and filled in C, the same arrays; None: numpy
        self.kernels = kernels

    def clear(self) -> None:
        """Empty the table (its arrays kept, to fill again)."""
        self.n = 0
        self._batch = None
        self._new_index(1 << 13)

    # -- index --------------------------------------------------------------
    def _new_index(self, size: int) -> None:
        self.slots: Any = None
        self.slots = np.full(size, _EMPTY, dtype=np.uint32)
        self.mask = np.uint64(size - 1)

    def _place(self, idx: np.ndarray) -> None:
        """Index state numbers ``idx`` (distinct, absent fingerprints)."""
        slots, mask = self.slots, self.mask
        if self.kernels is not None:
            self.kernels[1](slots, self.fps, np.ascontiguousarray(idx, dtype=np.uint32), int(mask))
            return
        pos = (self.fps[idx, 1] & mask).astype(np.int64)
        m = int(mask)
        while idx.size:
            free = slots[pos] == _EMPTY
            if free.any():
                slots[pos[free]] = idx[free]          # among equal slots one write wins
                won = free & (slots[pos] == idx)
                keep = ~won
                idx, pos = idx[keep], pos[keep]
            pos = (pos + 1) & m

    def lookup(self, q: np.ndarray) -> np.ndarray:
        """State numbers of the fingerprints ``q`` (shape (k, 2)); -1 where absent."""
        slots, fps, m = self.slots, self.fps, int(self.mask)
        out = np.full(len(q), -1, dtype=np.int64)
        if self.kernels is not None:
            self.kernels[0](slots, fps, np.ascontiguousarray(q, dtype=np.uint64), out, m)
            return out
        act = np.arange(len(q))
        pos = (q[:, 1] & self.mask).astype(np.int64)
        while act.size:
            e = slots[pos]
            occupied = e != _EMPTY
            act, pos, e = act[occupied], pos[occupied], e[occupied]
            hit = (fps[e, 1] == q[act, 1]) & (fps[e, 0] == q[act, 0])
            out[act[hit]] = e[hit]
            miss = ~hit
            act, pos = act[miss], (pos[miss] + 1) & m
        return out

    # -- batches ------------------------------------------------------------
    def new_positions(self, keys: list, first: np.ndarray) -> np.ndarray:
        """Of the batch ``keys`` (fingerprints), the positions ``first``
        (first occurrences, ascending) whose state is not yet visited."""
        q = np.frombuffer(b"".join(keys), dtype=np.uint64).reshape(-1, 2)[first]
        self.found = found = self.lookup(q)
        new = found < 0
        self._batch = (q[new], first[new])
        return first[new]

    def add(self, count: int, parents: np.ndarray) -> None:
        """Admit the first ``count`` of the last :meth:`new_positions`, with
        their parents' state numbers."""
        q = self._batch[0][:count]
        self._batch = None
        n, k = self.n, len(q)
        self.make_room(k)
        self.fps[n:n + k] = q
        self.parents[n:n + k] = parents
        self.n = n + k
        self._place(np.arange(n, n + k, dtype=np.uint32))

    def admitted(self, k: int) -> int:
        """``k`` states admitted by the level kernel, which wrote their
        fingerprints, parents and index slots (within the room
        :meth:`make_room` keeps); the first one's number."""
        base = self.n
        self.n = base + k
        return base

    def make_room(self, k: int) -> None:
        """Room for ``k`` more states without growing: the per-state arrays
        and the index (at most half full), as :meth:`add` grows them."""
        n = self.n + k
        if n > _MAX_STATES:
            raise MemoryError("more than 2**32 - 2 states")
        if n > len(self.parents):
            if self.fps.base is not None:
                raise MemoryError(f"more states than the reserved {len(self.parents):,}")
            cap = max(n, len(self.parents) * 2)
            self.fps.resize((cap, 2), refcheck=False)
            self.parents.resize(cap, refcheck=False)
        if 2 * n > len(self.slots):
            size = len(self.slots)
            while 2 * n > size:
                size *= 2
            self._new_index(size)
            step = 1 << 18          # re-index in slices: bounded temporaries
            for a in range(0, self.n, step):
                self._place(np.arange(a, min(self.n, a + step), dtype=np.uint32))

    def dump(self, n: int) -> dict:
        """The first ``n`` states' arrays (a checkpoint)."""
        return {"fps": self.fps[:n], "parents": self.parents[:n]}

    def load(self, arrays: dict) -> None:
        """Fill an empty table from :meth:`dump`'s arrays."""
        fps, parents = arrays["fps"], arrays["parents"]
        if fps.dtype != np.uint64 or fps.ndim != 2 or fps.shape[1:] != (2,) \
                or parents.dtype != np.uint32 or parents.shape != (len(fps),):
            raise ValueError("the fingerprint arrays have the wrong shape or type")
        self._batch = (np.ascontiguousarray(fps), None)
        self.add(len(fps), parents)

    def insert(self, q: np.ndarray, values: np.ndarray) -> None:
        """Admit fingerprints ``q`` (distinct, absent) with ``values`` stored
        in the parent slot (the parallel search stores global state numbers)."""
        self._batch = (q, None)
        self.add(len(q), values)

    def index_of(self, key: bytes) -> int:
        return int(self.lookup(np.frombuffer(key, dtype=np.uint64).reshape(1, 2))[0])

    def lookup_keys(self, keys: list) -> np.ndarray:
        """State numbers of a batch of fingerprints (-1 where absent)."""
        return self.lookup(np.frombuffer(b"".join(keys), dtype=np.uint64).reshape(-1, 2))

    def parent(self, idx: int) -> int:
        p = int(self.parents[idx])
        return -1 if p == 0xFFFF_FFFF else p


class ExactTable:
    """The visited set as a dict of canonical encodings (``--exact``)."""

    key_of = staticmethod(encode)

    def __init__(self):
        self.n = 0
        self.ids: dict = {}
        self.parents: list = []
        self._batch: Any = None
        self.found: Any = None

    def new_positions(self, keys: list, first: np.ndarray) -> np.ndarray:
        ids = self.ids
        self.found = found = np.fromiter(map(ids.get, [keys[p] for p in first.tolist()],
                                             itertools.repeat(-1)),
                                         dtype=np.int64, count=len(first))
        new = first[found < 0]
        self._batch = [keys[p] for p in new.tolist()]
        return new

    def add(self, count: int, parents: np.ndarray) -> None:
        ids = self.ids
        for key in self._batch[:count]:
            ids[key] = len(ids)
        self._batch = None
        self.parents.extend(parents.tolist())
        self.n = len(ids)

    def dump(self, n: int) -> dict:
        return {"keys": list(itertools.islice(self.ids, n)), "parents": self.parents[:n]}

    def load(self, data: dict) -> None:
        self.ids = dict(zip(data["keys"], itertools.count()))
        self.parents = list(data["parents"])
        self.n = len(self.ids)

    def index_of(self, key: bytes) -> int:
        return self.ids.get(key, -1)

    def lookup_keys(self, keys: list) -> np.ndarray:
        ids = self.ids
        return np.fromiter((ids.get(k, -1) for k in keys), dtype=np.int64, count=len(keys))

    def parent(self, idx: int) -> int:
        p = self.parents[idx]
        return -1 if p == 0xFFFF_FFFF else p
