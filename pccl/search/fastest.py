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
from collections.abc import Callable, Iterable, Sequence
from typing import Any, Protocol, cast

import numpy as np
import xxhash

from pccl.search.explorer import (OUT_OF_MEMORY, Bound, Counterexample, Explorer, Model, ExactTable, FingerprintTable,
                       Progress, SearchResult, Stats, _NO_PARENT, peak_rss_bytes, terminal)

__all__ = ["FastestExplorer", "TimedModel"]


class TimedModel(Model, Protocol):
    """What the fastest search needs besides :class:`~pccl.search.explorer.Model`:
    the cost in time steps of a transition into each of ``states`` (PCCL: 1
    into a dynamic state, i.e. a TIME ADVANCE; 0 otherwise)."""

    def time_costs(self, states: Sequence[Any]) -> Iterable[int]: ...


class FastestExplorer(Explorer):
    """An :class:`~pccl.search.explorer.Explorer` whose search is ordered on global
    time first, transitions second (same options, same results).  The
    frontier is :class:`_Buckets`; initial-state admission, terminal states,
    bounds, recording, progress and the result are the shared steps of
    :class:`~pccl.search.explorer.Explorer`."""

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
        self.table = ExactTable() if self.exact else FingerprintTable()
        stats = Stats()
        res = SearchResult("exhaustive", stats=stats, exact=self.exact)
        t_start = _time.perf_counter()
        fr = _Buckets(self, res)
        ck = self.checkpoint
        self._mark = None
        try:
            if ck is not None and ck.resume_dir is not None:
                t_start -= self._resume(fr, res)
            else:
                table = self.table
                for chunk in self._initial_chunks(lambda: fr.budget, fr.bounds, lambda: table.n,
                                                  t_start):
                    fr.push_new(chunk, 0, 0, _NO_PARENT, [0] * len(chunk))
                stats.initial_states = self.table.n
                if fr.bounds:       # a bound stopped the initial states
                    fr.heap.clear()
            progress = Progress(self.progress, self.progress_interval, t_start)
            stop = False
            while fr.heap and not stop:
                if ck is not None:
                    self._mark = fr.mark(t_start)
                    if ck.due() and ck.last_saved != (stats.max_depth, self.table.n):
                        self._save_buckets(fr, res)
                stop = fr.expand_bucket()
                if not stop and self.max_memory is not None:
                    stop = self._memory_bound(fr.bounds, peak_rss_bytes())
                progress(lambda secs: {"states": self.table.n, "frontier": fr.waiting(),
                                       "depth": stats.max_depth, "seconds": secs,
                                       "memory": peak_rss_bytes(), "max_time": stats.max_time})
        except KeyboardInterrupt:
            res.status = "interrupted"
            if ck is not None and ck.dir is not None and self._mark is not None:
                self._save_buckets(fr, res)
        except MemoryError:                 # as Explorer: the figures so far
            fr.buckets.clear()
            res.status = OUT_OF_MEMORY
        stats.frontier = fr.waiting()
        return self._finish(res, fr.bounds, t_start, max(peak_rss_bytes(), self._peak_before))

    # -- checkpoints (pccl/search/checkpoint.py): the buckets are the frontier ------
    def _save_buckets(self, fr: "_Buckets", res: SearchResult) -> None:
        """Write the checkpoint of the search as it stood at the mark (the
        start of the bucket under way: :meth:`_Buckets.at_mark`)."""
        assert self._mark is not None
        self._mark["buckets"] = fr.at_mark(self._mark["n"])
        try:
            self._save(cast(Any, None), res)      # (no admission batch: the buckets)
        finally:
            self._mark["buckets"] = None

    def _resume(self, fr: "_Buckets", res: SearchResult) -> float:
        """Put the search back where the checkpoint left it; the seconds
        spent before it."""
        ck = self.checkpoint
        state, arrays = ck.load()
        try:
            if state.get("kind") != "fastest":
                raise ValueError("it was not written by a {fastest} search")
            self._restore_table(state, arrays)
            if self.table.n != state["n"]:
                raise ValueError("the checkpoint's table and figures do not agree")
            fr.restore(state, res)
            if self.recorder is not None:
                self.recorder.load({k[4:]: v for k, v in arrays.items() if k.startswith("rec_")},
                                   state["rec_complete"])
        except (ValueError, KeyError, TypeError, IndexError, AttributeError) as e:
            raise ck._bad(f"the checkpoint is corrupt ({e}); write a new one with "
                          "{checkpoint}") from None
        self._peak_before = state["peak_memory"]
        if self.labels is not None and state["labels"] is not None:
            self.labels.update(state["labels"])
        return state["seconds"]


class _Buckets:
    """The fastest search's frontier: states waiting in buckets keyed by
    (time steps, transitions), expanded smallest key first."""

    def __init__(self, ex: FastestExplorer, res: SearchResult):
        self.ex = ex
        self.m = m = cast(TimedModel, ex.model)
        self.time_costs = m.time_costs       # a step's time cost comes from the model
        #: the largest model time of an admitted state (``stats.max_time``)
        self.clock = getattr(m, "clock", None)
        key: Callable[[Any], Any] = m.key    # a key is marshallable (Model.key)
        if ex.exact:
            def key_of(s):
                return marshal.dumps(key(s), 2)
        else:
            def key_of(s):
                return xxhash.xxh3_128_digest(marshal.dumps(key(s), 2))
        self.key_of = key_of
        self.table = ex.table
        self.rec = ex.recorder
        self.stats = res.stats
        self.found = res.found
        self.reported: set = set()
        self.record = ex._recorder(res.found, self.reported)
        self.bounds: set = set()
        self.budget = ex._budget()
        self.buckets: dict = {}
        self.heap: list = []
        #: the bucket taken off the heap since the last :meth:`mark`
        self.current: Any = None

    def waiting(self) -> int:
        return sum(len(b) for b in self.buckets.values())

    def admit(self, states: list, parent: int) -> tuple[list, list]:
        """Admit the new ones among ``states`` (successors of the state
        numbered ``parent``); their state numbers (-1 for those already
        visited or beyond the budget), and their keys."""
        table, rec = self.table, self.rec
        keys = [self.key_of(s) for s in states]
        n = len(keys)
        first = np.fromiter(dict(zip(reversed(keys), range(n - 1, -1, -1))).values(),
                            dtype=np.int64, count=-1)
        first.sort()
        new = table.new_positions(keys, first).tolist()
        cnt = min(len(new), self.budget)
        if cnt < len(new):
            self.bounds.add(Bound.MAX_STATES)
        out = [-1] * n
        if cnt:
            base = table.n
            table.add(cnt, np.full(cnt, parent, dtype=np.int64))
            self.budget -= cnt
            for r, p in enumerate(new[:cnt]):
                out[p] = base + r
            if self.clock is not None:
                t = max(self.clock(states[p]) for p in new[:cnt])
                if self.stats.max_time is None or t > self.stats.max_time:
                    self.stats.max_time = t
            if rec is not None:
                rec.states([states[p] for p in new[:cnt]])
        return out, keys

    def push_new(self, states: list, ticks: int, depth: int, parent: int, costs) -> list:
        """Admit ``states`` and queue the new ones, each at ``ticks`` plus
        its time cost, ``depth`` transitions; their keys."""
        new, keys = self.admit(states, parent)
        buckets, heap = self.buckets, self.heap
        for s, i, c in zip(states, new, costs):
            if i >= 0:
                k = (ticks + c, depth)
                b = buckets.get(k)
                if b is None:
                    b = buckets[k] = []
                    heapq.heappush(heap, k)
                b.append((s, i))
        return keys

    def expand_bucket(self) -> bool:
        """Expand the smallest bucket; True to stop."""
        k = heapq.heappop(self.heap)
        ticks, depth = k
        self.stats.max_depth = max(self.stats.max_depth, depth)
        self.current = (k, self.buckets.pop(k))
        for s, idx in self.current[1]:
            if self._expand(s, idx, ticks, depth):
                return True
        return False

    # -- checkpoints --------------------------------------------------------------
    def mark(self, t_start: float) -> dict:
        """The search between two buckets: what a checkpoint holds besides
        the table and the graph (cut at ``n`` when written: they only grow)
        and the buckets (:meth:`at_mark`, when written)."""
        ex, stats, rec = self.ex, self.stats, self.rec
        self.current = None
        model_mark = getattr(self.m, "checkpoint_mark", None)
        if model_mark is not None:      # a model with state of its own (the coverage tallies)
            model_mark()
        return {"kind": "fastest", "depth": stats.max_depth, "n": self.table.n,
                "transitions": stats.transitions, "max_depth": stats.max_depth,
                "initial_states": stats.initial_states, "max_time": stats.max_time,
                "budget": self.budget, "bounds": [b.value for b in self.bounds],
                "nfound": len(self.found),
                "labels": None if ex.labels is None else set(ex.labels),
                "runaway": None, "runaway_info": None,
                "seconds": _time.perf_counter() - t_start,
                "edges": None if rec is None else rec.src.n,
                "rec_complete": None if rec is None else rec.complete, "buckets": None}

    def at_mark(self, n: int) -> list:
        """The buckets as they stood at the mark, when ``n`` states were
        visited: the states queued since (numbered ``n`` or more) dropped,
        the bucket under way put back (it is expanded again on resume;
        nothing queued since went into it: its successors are one
        transition deeper).  ``[(key, [(state, number)])]``."""
        out = {k: [e for e in b if e[1] < n] for k, b in self.buckets.items()}
        if self.current is not None:
            k, b = self.current
            out[k] = b
        return [(k, b) for k, b in sorted(out.items()) if b]

    def restore(self, state: dict, res: SearchResult) -> None:
        """The buckets and figures of a checkpoint (:meth:`mark`)."""
        stats = self.stats
        stats.transitions, stats.max_depth = state["transitions"], state["max_depth"]
        stats.initial_states, stats.max_time = state["initial_states"], state["max_time"]
        self.budget = state["budget"]
        self.bounds.update(Bound(b) for b in state["bounds"])
        for v, idx, d in state["found"]:
            res.found.append(Counterexample(v, idx, d))
            self.reported.add(v.identity)
        self.buckets = {tuple(k): list(b) for k, b in state["buckets"]}
        self.heap = list(self.buckets)
        heapq.heapify(self.heap)

    def _expand(self, s, idx: int, ticks: int, depth: int) -> bool:
        """Check and expand one state; True to stop."""
        ex, m = self.ex, self.m
        viols = m.violations(s)
        if viols and self.record(viols, idx, depth):
            return True
        succ = m.successors(s)
        if ex.labels is not None:
            ex.labels.update(lab for lab, _ in succ)
        if not succ:
            bound, v = terminal(m, s, ex.deadlock)
            if bound is not None:
                self.bounds.add(bound)
            return v is not None and self.record([v], idx, depth)
        if ex._at_depth_bound(depth):
            self.bounds.add(Bound.DEPTH)
            return False
        self.stats.transitions += len(succ)
        states = [s2 for _, s2 in succ]
        keys = self.push_new(states, ticks, depth + 1, idx, self.time_costs(states))
        rec = self.rec
        if rec is not None:
            dst = self.table.lookup_keys(keys)
            src = np.full(len(dst), idx, dtype=np.int64)
            if getattr(rec, "wants_candidates", False):
                rec.edges(src, dst, states)
            else:
                rec.edges(src, dst)
        return False
