"""``--fastest``: the counterexample that reaches its violation at the
smallest global time (ties: the fewest transitions), as UPPAAL's fastest
trace.

A search ordered on (time steps, transitions): every transition costs one
transition, and TIME ADVANCE also one time step δ.  States wait in buckets
keyed by that pair and are expanded smallest key first, so this is a
Dijkstra search over a lexicographic cost; with edge costs of 0 or 1 time
steps it is a 0-1 BFS.  A state is admitted to the visited table when first
generated: the edge into a state decides its time cost (an edge into a
*dynamic* state is exactly a TIME ADVANCE, any other edge costs no time),
so the first generation in key order is already the cheapest.  Violations
are checked when a state is *expanded* (in key order), not when generated,
so the first one found is the fastest.

Memory discipline as in the breadth-first search: the visited set is the
same :class:`~pccl.search.explorer.FingerprintTable` (fingerprints and parent
links in numpy arrays); only the states waiting in buckets are held whole.
Under time abstraction the clock is not part of a state; the time of a
state is its bucket's time-step count, and the replayed trace shows it.
"""

from __future__ import annotations

import gc
import heapq
import marshal
import time as _time

import numpy as np
import xxhash

from pccl.search.explorer import (OUT_OF_MEMORY, Bound, Explorer, ExactTable, FingerprintTable, SearchResult, Stats,
                                  _MAX_STATES, _NO_PARENT, peak_rss_bytes)
from pccl.search.fingerprint import collision_bound

__all__ = ["FastestExplorer"]


class FastestExplorer(Explorer):
    """An :class:`~pccl.search.explorer.Explorer` whose search is ordered on global
    time first, transitions second (same options, same results)."""

    def run(self) -> SearchResult:
        enabled = gc.isenabled()
        gc.disable()
        try:
            res = self._run_fastest()
        finally:
            if enabled:
                gc.enable()
        res.fastest = True          # type: ignore[attr-defined]  # read by the CLI
        return res

    def _run_fastest(self) -> SearchResult:
        from pccl.model.layout import DISCRETE, PHASE
        m = self.model
        key = m.key
        exact = self.exact
        table = self.table = ExactTable() if exact else FingerprintTable()
        if exact:
            def key_of(s):
                return marshal.dumps(key(s), 2)
        else:
            def key_of(s):
                return xxhash.xxh3_128_digest(marshal.dumps(key(s), 2))
        rec = self.recorder
        stats = Stats()
        res = SearchResult("exhaustive", stats=stats, exact=exact)
        t_start = _time.perf_counter()
        found = res.found
        record = self._recorder(found, set())
        bounds: set = set()
        budget = self.max_states if self.max_states is not None else _MAX_STATES
        buckets: dict = {}
        heap: list = []

        def push(k, s, idx):
            b = buckets.get(k)
            if b is None:
                b = buckets[k] = []
                heapq.heappush(heap, k)
            b.append((s, idx))

        def admit(states, parent):
            """Admit the new ones among ``states`` (successors of the state
            numbered ``parent``); their state numbers (-1 for those already
            visited or beyond the budget), and their keys."""
            nonlocal budget
            keys = [key_of(s) for s in states]
            n = len(keys)
            first = np.fromiter(dict(zip(reversed(keys), range(n - 1, -1, -1))).values(),
                                dtype=np.int64, count=-1)
            first.sort()
            new = table.new_positions(keys, first).tolist()
            cnt = min(len(new), budget)
            if cnt < len(new):
                bounds.add(Bound.MAX_STATES)
            out = [-1] * n
            if cnt:
                base = table.n
                table.add(cnt, np.full(cnt, parent, dtype=np.int64))
                budget -= cnt
                for r, p in enumerate(new[:cnt]):
                    out[p] = base + r
                if rec is not None:
                    rec.states([states[p] for p in new[:cnt]])
            return out, keys

        stop = False
        try:
            inits = list(m.init_states())
            idxs, _ = admit(inits, _NO_PARENT)
            for s, i in zip(inits, idxs):
                if i >= 0:
                    push((0, 0), s, i)
            stats.initial_states = table.n
            while heap and not stop:
                k = heapq.heappop(heap)
                bucket = buckets.pop(k)
                ticks, depth = k
                stats.max_depth = max(stats.max_depth, depth)
                for s, idx in bucket:
                    viols = m.violations(s)
                    if viols and record(viols, idx, depth):
                        stop = True
                        break
                    succ = m.successors(s)
                    if self.labels is not None:
                        self.labels.update(lab for lab, _ in succ)
                    if not succ:
                        kind = m.terminal_kind(s)
                        if kind == "bounded":
                            bounds.add(Bound.MODEL)
                        elif kind == "deadlock" and self.deadlock:
                            v = m.deadlock_violation(s)
                            if v is not None and record([v], idx, depth):
                                stop = True
                                break
                        continue
                    if self.max_depth is not None and depth >= self.max_depth:
                        bounds.add(Bound.DEPTH)
                        continue
                    stats.transitions += len(succ)
                    states = [s2 for _, s2 in succ]
                    new, keys = admit(states, idx)
                    if rec is not None:
                        dst = table.lookup_keys(keys)
                        if getattr(rec, "wants_candidates", False):
                            rec.edges(np.full(len(dst), idx, dtype=np.int64), dst, states)
                        else:
                            rec.edges(np.full(len(dst), idx, dtype=np.int64), dst)
                    for s2, i2 in zip(states, new):
                        if i2 >= 0:
                            push((ticks + (s2[PHASE] != DISCRETE), depth + 1), s2, i2)
                if (self.max_memory is not None and not stop
                        and peak_rss_bytes() > self.max_memory):
                    bounds.add(Bound.MAX_MEMORY)
                    stop = True
        except KeyboardInterrupt:
            res.status = "interrupted"
        except MemoryError:                 # as Explorer: the figures so far
            buckets.clear()
            res.status = OUT_OF_MEMORY
        stats.states = table.n
        stats.frontier = sum(len(b) for b in buckets.values())
        stats.seconds = _time.perf_counter() - t_start
        stats.peak_memory = peak_rss_bytes()
        if not exact:
            res.collision_probability = collision_bound(stats.states)
        res.bounds_hit = sorted(bounds, key=lambda b: b.value)
        if res.status not in ("interrupted", OUT_OF_MEMORY):
            res.status = "violation" if found else ("bounded" if bounds else "exhaustive")
        for f in found:
            f.trace = self.replay(f.index)
        return res
