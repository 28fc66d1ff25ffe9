"""Breadth-first state-space exploration with shortest counterexamples.

The checker knows nothing of PCCL.  It explores any *model* offering
(stateright's split between model and checker):

* ``init_states() -> list[state]``
* ``successors(state) -> list[(label, state)]``
* ``key(state) -> hashable``            (state identity)
* ``violations(state) -> list[violation]``  (each with ``.identity``)
* ``terminal_kind(state) -> "final" | "bounded" | "deadlock"``

Visited states are kept as 64-bit fingerprints (``hash(key)``) in a set,
with two parallel arrays (fingerprint, parent index) from which a
counterexample is rebuilt by replaying from the initial state, as TLC and
stateright do.  Only the frontier holds full states.  ``exact=True`` keeps
full keys instead (no hash compaction; for tests and small models).
"""

from __future__ import annotations

import gc
import resource
import time as _time
from array import array
from dataclasses import dataclass, field
from typing import Any, Callable, Optional


@dataclass
class Stats:
    initial_states: int = 0
    states: int = 0
    transitions: int = 0
    max_depth: int = 0
    seconds: float = 0.0
    peak_memory: int = 0          # bytes, peak resident set size of the process
    frontier: int = 0

    @property
    def states_per_second(self) -> float:
        return self.states / self.seconds if self.seconds > 0 else 0.0

    def as_dict(self) -> dict:
        return {"initial_states": self.initial_states, "states": self.states,
                "transitions": self.transitions, "max_depth": self.max_depth,
                "seconds": round(self.seconds, 3),
                "states_per_second": round(self.states_per_second, 1),
                "peak_memory_bytes": self.peak_memory}


@dataclass
class Found:
    """A violation and the shortest path that reaches it."""
    violation: Any
    index: int                     # state index in the search
    depth: int
    trace: Optional[list] = None   # [(label or None, state)], filled by rebuild


@dataclass
class SearchResult:
    status: str                    # violation | exhaustive | bounded | interrupted
    found: list = field(default_factory=list)     # [Found]
    bounds_hit: list = field(default_factory=list)  # e.g. ["--depth 10", "--max-time 5"]
    stats: Stats = field(default_factory=Stats)
    collision_probability: float = 0.0


def peak_rss_bytes() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


class Explorer:
    def __init__(self, model, *, max_depth: Optional[int] = None,
                 max_states: Optional[int] = None, deadlock: bool = True,
                 find_all: bool = False, exact: bool = False,
                 progress: Optional[Callable[[dict], None]] = None,
                 progress_interval: float = 0.5,
                 bounded_time_label: str = "--max-time"):
        self.model = model
        self.max_depth = max_depth
        self.max_states = max_states
        self.deadlock = deadlock
        self.find_all = find_all
        self.exact = exact
        self.progress = progress
        self.progress_interval = progress_interval
        self.bounded_time_label = bounded_time_label

    # ------------------------------------------------------------------
    def run(self) -> SearchResult:
        # States are acyclic tuples: the cyclic garbage collector would only
        # re-traverse the millions of frontier tuples (measured: 40% of the
        # time at 4M states).  Reference counting still frees everything.
        enabled = gc.isenabled()
        gc.disable()
        try:
            return self._run()
        finally:
            if enabled:
                gc.enable()

    def _run(self) -> SearchResult:
        m = self.model
        key = m.key
        succ_fn = m.successors
        viol_fn = m.violations
        exact = self.exact
        t_start = _time.perf_counter()
        stats = Stats()
        res = SearchResult("exhaustive", stats=stats)
        seen: set = set()
        fps = [] if exact else array("q")
        parents = array("q")
        reported: set = set()
        bounds: set = set()
        max_depth = self.max_depth
        max_states = self.max_states
        found = res.found

        def record(viols, idx, depth):
            for v in viols:
                ident = v.identity
                if ident in reported:
                    continue
                reported.add(ident)
                found.append(Found(v, idx, depth))
                if not self.find_all:
                    return True
            return False

        stop = False
        level: list = []      # states of the current depth
        level_idx: list = []
        try:
            for s in m.init_states():
                fp = key(s) if exact else hash(key(s))
                if fp in seen:
                    continue
                seen.add(fp)
                idx = len(parents)
                fps.append(fp)
                parents.append(-1)
                level.append(s)
                level_idx.append(idx)
                v = viol_fn(s)
                if v and record(v, idx, 0):
                    stop = True
                    break
            stats.initial_states = len(level)
            depth = 0
            next_report = _time.perf_counter() + self.progress_interval
            count = 0
            while level and not stop:
                nxt: list = []
                nxt_idx: list = []
                at_bound = max_depth is not None and depth >= max_depth
                for pos in range(len(level)):
                    s = level[pos]
                    succ = succ_fn(s)
                    if not succ:
                        kind = m.terminal_kind(s)
                        if kind == "bounded":
                            bounds.add(self.bounded_time_label)
                        elif kind == "deadlock" and self.deadlock:
                            v = m.deadlock_violation(s) if hasattr(m, "deadlock_violation") else None
                            if v is not None and record([v], level_idx[pos], depth):
                                stop = True
                                break
                        continue
                    if at_bound:
                        bounds.add("--depth")
                        continue
                    stats.transitions += len(succ)
                    pidx = level_idx[pos]
                    for _label, s2 in succ:
                        fp = key(s2) if exact else hash(key(s2))
                        if fp in seen:
                            continue
                        seen.add(fp)
                        idx = len(parents)
                        fps.append(fp)
                        parents.append(pidx)
                        nxt.append(s2)
                        nxt_idx.append(idx)
                        v = viol_fn(s2)
                        if v and record(v, idx, depth + 1):
                            stop = True
                            break
                    if stop:
                        break
                    if max_states is not None and len(parents) >= max_states:
                        bounds.add("--max-states")
                        stop = True
                        break
                    count += 1
                    if self.progress is not None and (count & 255) == 0:
                        now = _time.perf_counter()
                        if now >= next_report:
                            next_report = now + self.progress_interval
                            self.progress({"states": len(parents), "frontier": len(level) - pos + len(nxt),
                                           "depth": depth, "seconds": now - t_start,
                                           "memory": peak_rss_bytes()})
                level[:] = []
                level = nxt
                level_idx = nxt_idx
                if level:
                    depth += 1
                    stats.max_depth = depth
            stats.frontier = len(level)
        except KeyboardInterrupt:
            res.status = "interrupted"
        stats.states = len(parents)
        stats.seconds = _time.perf_counter() - t_start
        stats.peak_memory = peak_rss_bytes()
        if not exact:
            n = stats.states
            res.collision_probability = min(1.0, n * n / 2.0 ** 65)
        res.bounds_hit = sorted(bounds)
        if res.status != "interrupted":
            if found:
                res.status = "violation"
            elif bounds:
                res.status = "bounded"
            else:
                res.status = "exhaustive"
        for f in found:
            f.trace = self.rebuild(fps, parents, f.index)
        return res

    # ------------------------------------------------------------------
    def rebuild(self, fps, parents, idx) -> list:
        """Replay from the initial state along the fingerprints of the path."""
        m = self.model
        key = m.key
        chain = []
        while idx != -1:
            chain.append(fps[idx])
            idx = parents[idx]
        chain.reverse()
        fpof = (lambda s: key(s)) if self.exact else (lambda s: hash(key(s)))
        state = None
        for s in m.init_states():
            if fpof(s) == chain[0]:
                state = s
                break
        if state is None:  # pragma: no cover - would mean a non-deterministic model
            raise RuntimeError("counterexample replay failed: initial state not found")
        trace = [(None, state)]
        for fp in chain[1:]:
            for label, s2 in m.successors(state):
                if fpof(s2) == fp:
                    state = s2
                    trace.append((label, s2))
                    break
            else:  # pragma: no cover
                raise RuntimeError("counterexample replay failed: successor not found")
        return trace
