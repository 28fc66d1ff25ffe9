"""Parallel breadth-first search: ``--workers N`` processes on one machine.

The design (TLC's and PReach's, adapted to CPython processes):

* **Partitioned fingerprints.**  Worker ``w`` owns the fingerprints whose
  low 64 bits are ``w`` modulo ``N`` (fingerprints are canonical, so every
  process agrees on owners) in its own :class:`FingerprintTable`, storing
  the *global* state number in the table's parent slot.
* **States stay where they were generated.**  Each worker expands its share
  of the current level and keeps the new states it generated; only
  fingerprints and 8-byte ordering keys travel, never states (except the
  initial states, handed out once).
* **Level-synchronous, with the serial order.**  A candidate successor's key
  is ``(parent number << 24) | position among the parent's successors``:
  the order in which the one-process search meets it.  An owner keeps, of
  equal fingerprints, the smallest key; the coordinator sorts the new
  states' keys, which numbers them exactly as the one-process search does.
  Stop events (a violation, a deadlock, the ``--max-states`` budget) are
  ordered by the same keys, so states, transitions, depth, verdict and the
  very counterexample equal those of ``workers=1``.

Per level the coordinator exchanges four messages with every worker
(expand, decide, check, commit).  Transport is :mod:`multiprocessing`
pipes between forked processes; the coordinator holds the global parent
links (4 bytes per state) and replays counterexamples, asking owners for
state numbers.
"""

from __future__ import annotations

import gc
import itertools
import marshal
import multiprocessing
import operator
import os
import signal
import time as _time
from typing import Any

import numpy as np
import xxhash

from .explorer import (Bound, Explorer, FingerprintTable, SearchResult,
                       Stats, _MAX_STATES, _reserve, collision_bound, fingerprint,
                       peak_rss_bytes)

__all__ = ["ParallelExplorer", "available_workers"]

_SHIFT = 24                     # successors per state < 2**24
_NONE = 0xFFFF_FFFF


def available_workers() -> int:
    """The number of cores this process may use (``--workers auto``)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):   # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


def _owner_split(fps: np.ndarray, keys: np.ndarray, n: int) -> list:
    """Candidates grouped by owning worker: [(fps, keys)] * n."""
    owner = (fps[:, 1] % np.uint64(n)).astype(np.int64) if len(fps) else np.zeros(0, np.int64)
    return [(fps[owner == w], keys[owner == w]) for w in range(n)]


# ---------------------------------------------------------------------------
# The worker process
# ---------------------------------------------------------------------------

class _Worker:
    def __init__(self, model, wid: int, n: int, deadlock: bool, find_all: bool):
        self.m, self.wid, self.n = model, wid, n
        self.deadlock, self.find_all = deadlock, find_all
        self.table = FingerprintTable()
        self.level: list = []          # states of the current level I hold
        self.level_idx: list = []      # ... their global numbers, ascending
        self.cand: list = []           # candidate (label, state) pairs of the level
        self.cand_keys: Any = None         # their keys (ascending)
        self.pending: Any = None           # owner side: (fps, keys) of new states
        self.won: Any = None               # generator side: (ranks, states)
        key = model.key
        second, twos = operator.itemgetter(1), itertools.repeat(2)
        dumps, xxh = marshal.dumps, xxhash.xxh3_128_digest
        self.keys_of = lambda pairs: map(xxh, map(dumps, map(key, map(second, pairs)), twos))

    def expand(self, at_bound: bool):
        m, succ_fn = self.m, self.m.successors
        ck: list = []
        cs: list = []
        par_idx: list = []
        par_n: list = []
        dead: list = []
        depth_min = model_min = None
        for g, s in zip(self.level_idx, self.level):
            succ = succ_fn(s)
            if not succ:
                kind = m.terminal_kind(s)
                if kind == "bounded":
                    model_min = g if model_min is None else model_min
                elif kind == "deadlock" and self.deadlock:
                    v = m.deadlock_violation(s)
                    if v is not None:
                        dead.append((g, v))
                continue
            if at_bound:
                depth_min = g if depth_min is None else depth_min
                continue
            par_idx.append(g)
            par_n.append(len(succ))
            cs.extend(succ)
            ck.extend(self.keys_of(succ))
        self.level = []
        total = len(ck)
        pi = np.asarray(par_idx, dtype=np.uint64)
        pn = np.asarray(par_n, dtype=np.int64)
        if total:
            starts = np.repeat(np.cumsum(pn) - pn, pn)
            keys = (np.repeat(pi << np.uint64(_SHIFT), pn)
                    + (np.arange(total, dtype=np.int64) - starts).astype(np.uint64))
            fps = np.frombuffer(b"".join(ck), dtype=np.uint64).reshape(-1, 2)
        else:
            keys = np.zeros(0, np.uint64)
            fps = np.zeros((0, 2), np.uint64)
        self.cand, self.cand_keys = cs, keys
        return (_owner_split(fps, keys, self.n), pi, pn, dead, depth_min, model_min)

    def decide(self, parts):
        """Owner side: of the candidates sent to me, the new ones (smallest
        key per fingerprint); their keys go back to the coordinator."""
        fps = np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, 2), np.uint64)
        keys = np.concatenate([p[1] for p in parts]) if parts else np.zeros(0, np.uint64)
        if len(keys):
            order = np.lexsort((keys, fps[:, 1], fps[:, 0]))
            f, k = fps[order], keys[order]
            first = np.ones(len(k), dtype=bool)
            first[1:] = (f[1:] != f[:-1]).any(axis=1)
            f, k = f[first], k[first]
            new = self.table.lookup(f) < 0
            f, k = f[new], k[new]
        else:
            f, k = fps, keys
        self.pending = (f, k)
        return k

    def check(self, keys, ranks, limit):
        """Generator side: violations of the new states I generated (those
        with rank < ``limit``), in rank order; all of them with --all, else
        the first."""
        pos = np.searchsorted(self.cand_keys, keys).tolist()
        cs = self.cand
        states = [cs[p][1] for p in pos]
        self.cand, self.cand_keys = [], None
        ranks = ranks.tolist()
        self.won = (ranks, states)
        out = []
        viol_fn = self.m.violations
        for r, s in zip(ranks, states):
            if r >= limit:
                break
            v = viol_fn(s)
            if v:
                out.append((r, v))
                if not self.find_all:
                    break
        return out

    def commit(self, base: int, cut: int, owner_ranks):
        if self.won is not None:
            ranks, states = self.won
            self.won = None
            self.level = [s for r, s in zip(ranks, states) if r < cut]
            self.level_idx = [base + r for r in ranks if r < cut]
        f, k = self.pending
        self.pending = None
        keep = owner_ranks < cut
        if keep.any():
            self.table.insert(f[keep], (base + owner_ranks[keep]).astype(np.int64))
        return peak_rss_bytes()

    def adopt(self, idx, states):
        self.level_idx.extend(idx)
        self.level.extend(states)

    def index_of(self, fp: bytes) -> int:
        local = self.table.index_of(fp)
        return -1 if local < 0 else int(self.table.parents[local])


def _serve(conn, model, wid, n, deadlock, find_all):
    signal.signal(signal.SIGINT, signal.SIG_IGN)     # the coordinator handles Ctrl-C
    gc.disable()
    w = _Worker(model, wid, n, deadlock, find_all)
    while True:
        try:
            cmd, args = conn.recv()
        except EOFError:
            return
        if cmd == "stop":
            return
        try:
            conn.send(("ok", getattr(w, cmd)(*args)))
        except BaseException as exc:         # report, do not hang the coordinator
            conn.send(("error", exc))


# ---------------------------------------------------------------------------
# The coordinator
# ---------------------------------------------------------------------------

class _RemoteTable:
    """What :meth:`Explorer.replay` needs, answered by the owners."""

    key_of = staticmethod(fingerprint)

    def __init__(self, coord: "ParallelExplorer"):
        self.c = coord

    def index_of(self, fp: bytes) -> int:
        lo = int(np.frombuffer(fp, dtype=np.uint64)[1])
        return self.c._call(lo % self.c.workers, "index_of", fp)

    def parent(self, idx: int) -> int:
        p = int(self.c.parents[idx])
        return -1 if p == _NONE else p


class ParallelExplorer(Explorer):
    """:class:`Explorer` over ``workers`` processes (fork start method).

    Same options and results as :class:`Explorer` (``exact`` is not
    supported: canonical encodings would have to travel instead of
    fingerprints).  ``max_memory`` applies to the sum of the processes' peak
    resident memory, checked once per level.
    """

    def __init__(self, model, *, workers: int = 2, **options):
        if options.get("exact"):
            raise ValueError("exact state storage runs in one process (workers=1)")
        super().__init__(model, **options)
        self.workers = workers
        self.conns: list = []
        self.procs: list = []
        self.outstanding: list = [0] * workers

    # -- transport --------------------------------------------------------
    def _start(self):
        ctx = multiprocessing.get_context("fork")
        for w in range(self.workers):
            a, b = ctx.Pipe()
            p = ctx.Process(target=_serve, args=(b, self.model, w, self.workers, self.deadlock,
                                                 self.find_all), daemon=True)
            p.start()
            b.close()
            self.conns.append(a)
            self.procs.append(p)

    def _stop(self):
        for c in self.conns:
            try:
                c.send(("stop", ()))
            except (OSError, BrokenPipeError):
                pass
        for p in self.procs:
            p.join(timeout=5)
            if p.is_alive():
                p.kill()
        self.conns, self.procs = [], []

    def _send(self, w, cmd, args):
        self.conns[w].send((cmd, args))
        self.outstanding[w] += 1

    def _result(self, w):
        status, value = self.conns[w].recv()
        self.outstanding[w] -= 1
        if status == "error":
            raise value
        return value

    def _call(self, w, cmd, *args):
        self._send(w, cmd, args)
        return self._result(w)

    def _all(self, cmd, per_worker):
        for w, args in enumerate(per_worker):
            self._send(w, cmd, args)
        return [self._result(w) for w in range(self.workers)]

    def _drain(self):
        """After an interrupt: collect the replies still on their way."""
        for w in range(self.workers):
            while self.outstanding[w] > 0:
                try:
                    self._result(w)
                except Exception:
                    pass

    # -- the search ---------------------------------------------------------
    def run(self) -> SearchResult:
        prepare = getattr(self.model, "prepare", None)
        if prepare is not None:
            prepare()       # lazily built tables that states refer to, before the fork
        enabled = gc.isenabled()
        gc.disable()
        self._start()
        try:
            return self._run()
        finally:
            self._stop()
            if enabled:
                gc.enable()

    def _run(self) -> SearchResult:
        m, n = self.model, self.workers
        key = m.key
        t_start = _time.perf_counter()
        stats = Stats()
        res = SearchResult("exhaustive", stats=stats)
        found, bounds = res.found, set()
        reported: set = set()
        budget = self.max_states if self.max_states is not None else _MAX_STATES
        cap = min(_MAX_STATES, budget + 1)
        self.parents: Any = _reserve((cap,), np.uint32)
        if self.parents is None:
            self.parents = np.empty(min(cap, 1 << 26), dtype=np.uint32)
        self.table = _RemoteTable(self)
        total = 0
        peak_workers = [0] * n

        record = self._recorder(found, reported)

        def put_parents(base, values):
            nonlocal total
            need = base + len(values)
            if need > len(self.parents):
                if self.parents.base is not None:
                    raise MemoryError("more states than reserved")
                self.parents.resize(max(need, 2 * len(self.parents)), refcheck=False)
            self.parents[base:need] = values
            total = need

        stop = False
        depth = 0
        try:
            # -- initial states: numbered here in chunks, handed out round-robin
            it = iter(m.init_states())
            while not stop:
                chunk = list(itertools.islice(it, min(self.batch, budget - total + 1)))
                if not chunk:
                    break
                fps = np.frombuffer(b"".join(fingerprint(key(s)) for s in chunk),
                                    dtype=np.uint64).reshape(-1, 2)
                keys = np.arange(len(chunk), dtype=np.uint64)
                new_keys = self._all("decide", [([p],) for p in _owner_split(fps, keys, n)])
                order = np.sort(np.concatenate(new_keys))
                base = total
                cut = len(order)
                if cut > budget - base:
                    cut = budget - base
                    bounds.add(Bound.MAX_STATES)
                    stop = True
                for r in range(cut):
                    v = m.violations(chunk[int(order[r])])
                    if v and record(v, base + r, 0):
                        cut, stop = r + 1, True
                        break
                rank_of = {int(k): r for r, k in enumerate(order.tolist())}
                owner_ranks = [np.array([rank_of[int(k)] for k in nk.tolist()], dtype=np.int64)
                               for nk in new_keys]
                peaks = self._all("commit", [(base, cut, orr) for orr in owner_ranks])
                peak_workers = [max(a, b) for a, b in zip(peak_workers, peaks)]
                for w in range(n):
                    idx = [g for g in range(base, base + cut) if g % n == w]
                    self._call(w, "adopt", idx, [chunk[int(order[g - base])] for g in idx])
                put_parents(base, np.full(cut, _NONE, dtype=np.uint32))
            cut = total
            stats.initial_states = total
            level_size = cut
            holder = np.arange(cut, dtype=np.int64) % n      # who holds each state of the level
            level_base = 0
            next_report = _time.perf_counter() + self.progress_interval
            while level_size and not stop:
                at_bound = self.max_depth is not None and depth >= self.max_depth
                replies = self._all("expand", [(at_bound,)] * n)
                # route the candidates to their owners
                per_owner = [[r[0][w] for r in replies] for w in range(n)]
                new_keys = self._all("decide", [(parts,) for parts in per_owner])
                allk = np.concatenate(new_keys)
                order = np.argsort(allk, kind="stable")
                sorted_keys = allk[order]
                ranks = np.empty(len(allk), dtype=np.int64)
                ranks[order] = np.arange(len(allk))
                owner_ranks, a = [], 0
                for nk in new_keys:
                    owner_ranks.append(ranks[a:a + len(nk)])
                    a += len(nk)
                # the stop events, in the serial search's order (by key)
                events = []                  # (key, kind, payload)
                for r in replies:
                    for g, v in r[3]:
                        events.append((g << _SHIFT, 0, (g, v)))
                limit = len(sorted_keys)
                budget_key = None
                if limit > budget - total:
                    limit = budget - total
                    budget_key = int(sorted_keys[limit])
                # generators check violations of the states they won
                gen = holder[(sorted_keys >> np.uint64(_SHIFT)).astype(np.int64) - level_base] \
                    if len(sorted_keys) else np.zeros(0, np.int64)
                per_gen = []
                for w in range(n):
                    sel = np.nonzero(gen == w)[0]
                    per_gen.append((sorted_keys[sel], sel, limit))
                for vs in self._all("check", per_gen):
                    for r, v in vs:
                        events.append((int(sorted_keys[r]), 1, (r, v)))
                events.sort(key=lambda e: (e[0], e[1]))
                stop_key = None
                cut = limit
                for ek, kind, payload in events:
                    if budget_key is not None and ek >= budget_key:
                        break
                    if kind == 0:
                        g, v = payload
                        # states admitted before the deadlocked parent's turn
                        before = int(np.searchsorted(sorted_keys, np.uint64(ek)))
                        if record([v], g, depth):
                            cut, stop_key = min(cut, before), ek
                            break
                    else:
                        r, v = payload
                        if record(v, total + r, depth + 1):
                            cut, stop_key = r + 1, ek
                            break
                if stop_key is None and budget_key is not None:
                    stop_key = budget_key
                    bounds.add(Bound.MAX_STATES)
                # transitions: parents expanded up to the stop
                pis = np.concatenate([r[1] for r in replies])
                pns = np.concatenate([r[2] for r in replies])
                if stop_key is None:
                    stats.transitions += int(pns.sum())
                else:
                    stats.transitions += int(pns[pis <= np.uint64(stop_key >> _SHIFT)].sum())
                    stop = True
                # bounds met before the stop
                for r in replies:
                    for b, g in ((Bound.DEPTH, r[4]), (Bound.MODEL, r[5])):
                        if g is not None and (stop_key is None or g <= stop_key >> _SHIFT):
                            bounds.add(b)
                base = total
                peaks = self._all("commit", [(base, cut, orr) for orr in owner_ranks])
                peak_workers = [max(a, b) for a, b in zip(peak_workers, peaks)]
                put_parents(base, (sorted_keys[:cut] >> np.uint64(_SHIFT)).astype(np.uint32))
                holder = gen[:cut]
                level_base, level_size = base, cut
                if cut:
                    depth += 1
                    stats.max_depth = depth
                stats.frontier = cut
                if self.max_memory is not None and not stop and \
                        peak_rss_bytes() + sum(peak_workers) > self.max_memory:
                    bounds.add(Bound.MAX_MEMORY)
                    stop = True
                if self.progress is not None:
                    now = _time.perf_counter()
                    if now >= next_report:
                        next_report = now + self.progress_interval
                        self.progress({"states": total, "frontier": cut, "depth": depth,
                                       "seconds": now - t_start,
                                       "memory": peak_rss_bytes() + sum(peak_workers)})
        except KeyboardInterrupt:
            res.status = "interrupted"
            self._drain()
        stats.states = total
        stats.seconds = _time.perf_counter() - t_start
        stats.peak_memory = peak_rss_bytes() + sum(peak_workers)
        res.collision_probability = collision_bound(stats.states)
        res.bounds_hit = sorted(bounds, key=lambda b: b.value)
        if res.status != "interrupted":
            res.status = "violation" if found else "bounded" if bounds else "exhaustive"
        for f in found:
            f.trace = self.replay(f.index)
        return res
