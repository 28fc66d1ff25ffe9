"""Parallel breadth-first search: ``--workers N`` processes on one machine,
or ``--ray ADDRESS`` actors on a Ray cluster.

The design (TLC's and PReach's, adapted to CPython processes):

* **Partitioned fingerprints.**  Worker ``w`` owns the fingerprints whose
  low 64 bits are ``w`` modulo ``N`` (fingerprints are canonical, so every
  process agrees on owners) in its own :class:`FingerprintTable`, storing
  the *global* state number in the table's parent slot.
* **States stay where they were generated.**  Each worker expands its share
  of the current level and keeps the new states it generated; only
  fingerprints and 8-byte ordering keys travel, never states (except the
  initial states, handed out once, and the states the coordinator moves
  when the shares of a level are uneven: :func:`_rebalance`, the pipes).
* **Level-synchronous, with the serial order.**  A candidate successor's key
  is ``(parent number << 24) | position among the parent's successors``:
  the order in which the one-process search meets it.  An owner keeps, of
  equal fingerprints, the smallest key; the coordinator sorts the new
  states' keys, which numbers them exactly as the one-process search does.
  Stop events (a violation, a deadlock, the ``--max-states`` budget) are
  ordered by the same keys, so states, transitions, depth, verdict and the
  very counterexample equal those of ``workers=1``.

Per level the coordinator makes two rounds with every worker:

1. ``step``: *commit* the previous level (owners record the numbers of the
   states they own; generators keep the states they won as their level),
   then *expand* it: successors, their fingerprints, deduplicated locally
   (and, for the fingerprints a worker owns itself, filtered against its
   own table), grouped by owner, and the keys of the candidates that
   violate a property (checked once per distinct fingerprint: equal keys
   have equal violations).  The candidates a worker owns itself stay with
   it; only the others travel.
2. ``decide``: owners answer which candidates are new (smallest key first).

The coordinator then numbers the new states, orders the stop events and
sends each worker its share of the decision with the next ``step``.

With :class:`_Pipes` the step is *balanced*: the workers expand their shares
a chunk at a time, and one that runs out of work gets half of what another
has left (:meth:`_Worker.give`, :meth:`_Worker.take`); the moved states'
successors stay with the worker that expanded them, and the coordinator
learns who that was from the step replies.  The keys do not depend on who
expanded a state, so the results do not either.

``fastest=True`` (``--fastest``): the states wait in buckets keyed by (time
steps, transitions), held by their generators; the coordinator expands the
smallest bucket as a level (:meth:`ParallelExplorer._bucket_rounds`), which
gives the one-process fastest search's numbering and results.

The partitioning code (:class:`_Worker`, the coordinator loop) is
engine-neutral; a *transport* moves the two rounds:

* :class:`_Pipes` (``--workers N``): worker 0 runs inside the coordinator
  process, workers 1..N-1 are forked processes behind
  :mod:`multiprocessing` pipes.  The two rounds of a level are pipelined
  (an owner's ``decide`` goes out as soon as the coordinator holds the
  other generators' candidates for it: with two workers, right after
  worker 0's step); a process polls for its next message for a while
  before it blocks, and frees the states it discarded while it waits.
* :class:`_RayTransport` (``--ray``): one Ray actor per partition; the
  arguments and replies of a round travel through Ray's object store, and
  the candidates go from their generator to their owner as object
  references (actor to actor; the coordinator fetches only the small part
  of each reply).

The coordinator holds the global parent links (4 bytes per state) and
replays counterexamples, asking owners for state numbers.

With a recorder (the time-lock check, temporal properties: see
:mod:`pccl.search.liveness`) each worker also records the transitions it
generated (source number, target fingerprint) and the recorder's columns of
the states it held; after an exhaustive or bounded search the coordinator
gathers them (:meth:`ParallelExplorer._gather_graph`), so that the analysis
runs on the graph the one-process search records.

Signals: the workers ignore SIGINT and SIGTERM and die with the
coordinator (:func:`_serve`); the coordinator acts on a signal between
levels (:class:`_Signals`).

The modules, by what changes together:

* this one: the coordinator (:class:`ParallelExplorer`: the level protocol,
  numbering, stop events, the graph for the checks, signals);
* :mod:`pccl.search.parallel_worker`: a partition (:class:`_Worker`) and the
  partitioning helpers (owners, :func:`_rebalance`);
* :mod:`pccl.search.parallel_pipes`: the processes transport (:class:`_Pipes`,
  balancing, message framing, waiting, pinning, :func:`_serve`);
* :mod:`pccl.search.parallel_ray`: the Ray transport (:class:`_RayTransport`,
  Ray's errors).  A new backend is a transport module of its own with the
  methods of these two (``start``, ``all``, ``level``, ``call``, ``drain``,
  ``stop``), chosen in :meth:`ParallelExplorer.__init__`.
"""

from __future__ import annotations

import gc
import itertools
import signal
import time as _time
from collections.abc import Callable
from typing import Any, Optional

import numpy as np

from pccl.search.explorer import (Bound, Explorer, FingerprintTable, Progress, SearchResult,
                                  Stats, _MAX_STATES, _reserve, fingerprint, peak_rss_bytes)
from pccl.search.parallel_pipes import _Pipes
from pccl.search.parallel_ray import (RAY_MISSING, RayUnavailable, RayWorkerLost, _RayTransport,
                                      import_ray, probe_ray_address)
from pccl.search.parallel_worker import (_NONE, _REBALANCE_LEVEL, _SHIFT, _owner_split, _rebalance,
                                         _split_like, available_workers)
from pccl.search.parallel_worker import _Worker  # noqa: F401  (re-exported: tests, benchmarks)

__all__ = ["ParallelExplorer", "available_workers", "RAY_MISSING", "RayUnavailable", "RayWorkerLost",
           "import_ray", "probe_ray_address"]


# ---------------------------------------------------------------------------
# The coordinator
# ---------------------------------------------------------------------------

class _Signals:
    """Ctrl-C and SIGTERM during a parallel search, handled between levels.

    Raised at an arbitrary point, the ``KeyboardInterrupt`` that Python's
    handlers raise can cut a message to a worker in half, or land while the
    coordinator collects the replies of an interrupted round, and the search
    then has no consistent figures to print.  So while the search runs, a
    handler only notes the signal; :meth:`check`, called before each round
    (and before each chunk of initial states), runs the handler that was
    there before (the command line's: it raises ``KeyboardInterrupt`` and
    remembers SIGTERM for the exit status), where nothing is in flight.  A
    signal stops the search within one level's work.  Further signals are
    noted and dropped: the search reports once.  A signal whose handler is
    not a Python function (ignored, or the default action of SIGTERM) is
    left alone; the workers ignore both signals (:func:`_serve`)."""

    SIGNALS = ("SIGINT", "SIGTERM")

    def __init__(self):
        import threading
        self.saved: dict = {}
        self.pending: Optional[tuple] = None
        self.fired = False
        if threading.current_thread() is not threading.main_thread():
            return
        for name in self.SIGNALS:
            sig = getattr(signal, name, None)
            if sig is None:
                continue
            prev = signal.getsignal(sig)
            if callable(prev):
                self.saved[sig] = prev
                signal.signal(sig, self._note)

    def _note(self, signum, frame) -> None:
        if self.pending is None and not self.fired:
            self.pending = (signum, frame)

    def check(self) -> None:
        """Run the handler of a signal noted since the last check (once)."""
        if self.pending is not None:
            signum, frame = self.pending
            self.pending, self.fired = None, True
            self.saved[signum](signum, frame)

    def restore(self) -> None:
        for sig, prev in self.saved.items():
            signal.signal(sig, prev)
        self.saved = {}


class _RemoteTable:
    """What :meth:`Explorer.replay` needs, answered by the owners."""

    key_of = staticmethod(fingerprint)

    def __init__(self, coord: "ParallelExplorer"):
        self.c = coord
        self.n = 0          # the states admitted, once the search is over

    def index_of(self, fp: bytes) -> int:
        lo = int(np.frombuffer(fp, dtype=np.uint64)[1])
        return self.c.transport.call(lo % self.c.workers, "index_of", fp)

    def parent(self, idx: int) -> int:
        p = int(self.c.parents[idx])
        return -1 if p == _NONE else p


#: transitions per message when a worker hands its part of the state graph
#: over (:meth:`_Worker.graph_edges`): 20 bytes each, 20 MiB a message
_GRAPH_CHUNK = 1 << 20


class ParallelExplorer(Explorer):
    """:class:`Explorer` over ``workers`` partitions.

    ``ray=None``: processes on this machine (fork start method; worker 0
    runs in the calling process).  ``ray="local"`` or an address: one Ray
    actor per partition (needs ``pip install 'pccl[ray]'``; ``workers=None``:
    one per CPU of the cluster).

    Same options and results as :class:`Explorer` (``exact`` is not
    supported: canonical encodings would have to travel instead of
    fingerprints).  ``max_memory`` applies to the sum of the processes' peak
    resident memory, checked once per level.
    """

    #: checkpoints (pccl/search/checkpoint.py): the checkpoint read before the
    #: workers start, and the level boundary a checkpoint is taken at
    _resume: Optional[tuple] = None
    _ck_mark: Optional[dict] = None
    #: keep the workers after a search whose graph the recorder analyses,
    #: to replay the analysis' counterexamples through their tables, until
    #: :meth:`close` (``pccl explore`` does); else the coordinator builds a
    #: table of every state for them (the partitions sent and put in number
    #: order, the table filled: about 0.9 s of Fischer 3 agents k=2's 2.9 s
    #: gathering before the owners numbered the targets)
    keep_workers = False
    #: the workers were kept (:meth:`close` stops them)
    _open = False
    _shutdown: Optional[Callable[[], None]] = None

    def __init__(self, model, *, workers: Optional[int] = 2, ray: Optional[str] = None,
                 fastest: bool = False, **options):
        if options.get("exact"):
            raise ValueError("exact state storage runs in one process (workers=1)")
        if options.get("spill") is not None and (ray is not None or fastest
                                                 or options.get("checkpoint") is not None):
            raise ValueError("spill runs with forked workers, breadth first, without checkpoints")
        super().__init__(model, **options)
        self.workers: Any = workers    # an int once the transport has started
        self.ray = ray
        #: the fastest search (:class:`~pccl.search.fastest.FastestExplorer`'s
        #: order): time buckets, each expanded as a level (:meth:`_bucket_rounds`)
        self.fastest = fastest
        self.transport: Any
        if ray is not None:
            self.transport = _RayTransport(workers, ray)
        else:
            assert workers is not None, "workers=None (one per cluster CPU) needs ray"
            self.transport = _Pipes(workers)

    # -- the search ---------------------------------------------------------
    def run(self) -> SearchResult:
        ck = self.checkpoint
        # checkpoints: the coordinator's part read (and the model's tables
        # restored) before the workers start
        self._resume = ck.load_parallel(self) \
            if ck is not None and ck.resume_dir is not None else None
        # (a native model: its Python model's, whose violations and terminal
        # states it decodes to read)
        prepare = getattr(self.model, "prepare", None) or getattr(
            getattr(self.model, "py", None), "prepare", None)
        if prepare is not None:
            prepare()       # lazily built tables that states refer to, before the fork
        enabled = gc.isenabled()
        gc.disable()
        rec = self.recorder
        columns = getattr(rec, "columns", None) if rec is not None else None
        # installed before the fork: a worker never runs a handler that raises
        self.signals = _Signals()
        spill_dirs: list = []
        def shutdown() -> None:
            try:
                if spill_dirs:      # worker 0's files are open in this process
                    self.transport.call(0, "spill_close")
                self.transport.stop()
            finally:
                if spill_dirs:
                    from pccl.search.spill import close_worker_dirs
                    close_worker_dirs(spill_dirs)

        done = False
        try:
            self.transport.start(self.model, self.deadlock, self.find_all, columns,
                                 fastest=self.fastest)
            self.workers = self.transport.n         # Ray with workers=None: the cluster's CPUs
            if self.options.spill is not None:
                from pccl.search.spill import worker_dirs
                spill_dirs = worker_dirs(self.options.spill, self.workers)
                self._spill_start(spill_dirs)
            res = self._run()
            done = True
            return res
        finally:
            try:
                if done and self._open:
                    self._shutdown = shutdown       # at close()
                else:
                    self._open = False
                    shutdown()
            finally:
                self.signals.restore()
                if enabled:
                    gc.enable()

    def close(self) -> None:
        """Stop the workers kept after the search (:attr:`keep_workers`);
        the coordinator's table answers no more lookups then."""
        stop, self._shutdown, self._open = self._shutdown, None, False
        if stop is not None:
            stop()

    def _spill_start(self, dirs: list) -> None:
        """``spill``: each worker spills its partition and its share of the
        levels into a directory of its own (``dirs``: ``spill/worker-<i>/``),
        with a share of ``max_memory`` for its process by need: the size it
        starts at plus an even part of the rest (:func:`spill.shares`), moved
        with the search (:meth:`_spill_shares`)."""
        from pccl.search.spill import Spiller
        self._spill_starts = self.transport.all(
            "spill_start", [(d, None, Spiller.STATES) for d in dirs])
        if self.max_memory is not None:
            self.transport.all("spill_share", [(s,) for s in self._spill_shares()])

    def _spill_shares(self) -> list:
        """The processes' shares of ``max_memory`` now (:func:`spill.shares`)
        from their peaks so far (a forked worker's before it reported one:
        its start)."""
        from pccl.search.spill import shares
        pw = getattr(self, "peak_workers", None) or [0] * self.workers
        peaks = [max(p, s) for p, s in zip(self._process_peaks(pw), self._spill_starts)]
        assert self.max_memory is not None
        return shares(self.max_memory, peaks)

    def _process_peaks(self, peaks: list) -> list:
        """The workers' peaks (``peaks``, as they reported them), worker 0's
        being this process's own when the workers are forked (not Ray)."""
        peaks = list(peaks)
        if self.ray is None:
            peaks[0] = max(peaks[0], peak_rss_bytes())     # worker 0: this process
        return peaks

    def _run(self) -> SearchResult:
        """The coordinator: the initial states (:meth:`_initial_rounds`),
        then level by level (:meth:`_level_rounds`), then the shared finish."""
        n: int = self.workers
        t_start = _time.perf_counter()
        res = SearchResult("exhaustive", stats=Stats())
        self._res = res
        self._bounds: set = set()
        self._reported: set = set()
        self._record = self._recorder(res.found, self._reported)
        self._budget_all = budget = self._budget()
        cap = min(_MAX_STATES, budget + 1)
        self.parents: Any = _reserve((cap,), np.uint32)
        if self.parents is None:
            self.parents = np.empty(min(cap, 1 << 26), dtype=np.uint32)
        self.table = _RemoteTable(self)
        self._total = 0
        self._waiting: dict = {}       # the fastest search: states waiting per bucket
        #: states expanded by another worker than the one that generated them
        self.moved = 0
        #: stuck reasons met by the workers, not yet shared (_share_stuck)
        self._stuck_news: dict = {}
        self._stuck_shared = 0
        #: stable interned ids (a native model with workers): id -> value's hash
        self._ids: Optional[dict] = {} if getattr(self.model, "stable_ids", False) else None
        self.peak_workers = [0] * n
        #: per worker: the decision on the last level, sent with the next step
        self._decisions: Any = None
        ck, self._ck_mark, self._t_start = self.checkpoint, None, t_start
        try:
            if self._resume is not None:        # from a checkpoint (pccl/search/checkpoint.py)
                start = ck.restore_parallel(self, *self._resume)
                self._resume = None
                self._t_start = t_start = t_start - start["seconds"]
                if self.fastest:
                    self._bucket_rounds(t_start, start)
                else:
                    self._level_rounds(t_start, False, start)
            else:
                stop = self._initial_rounds()
                res.stats.initial_states = self._total
                if self.fastest:
                    self._bucket_rounds(t_start)
                else:
                    self._level_rounds(t_start, stop)
        except KeyboardInterrupt:
            res.status = "interrupted"
            self.transport.drain()
            if ck is not None and ck.dir is not None and self._ck_mark is not None:
                ck.save_parallel(self)          # the level under way is expanded again
            if self._decisions and res.found:     # the owners must know the states to replay
                try:
                    self.transport.all("commit", [(d,) for d in self._decisions])
                except Exception:
                    res.found.clear()
        self.table.n = self._total
        res.stats.max_time = self.max_time_now(interrupted=res.status == "interrupted")
        if self.fastest:
            res.fastest = True          # type: ignore[attr-defined]  # read by the CLI
            res.stats.frontier = sum(self._waiting.values())
        self._finish(res, self._bounds, t_start, self._memory(self.peak_workers))
        if self._ids is not None:       # and what the counterexamples' replay interned
            native: Any = self.model
            self._check_ids([native.take_new_ids()])
        if self.recorder is not None and res.status in ("exhaustive", "bounded"):
            t = _time.perf_counter()
            self._gather_graph(self._total)
            # part of the search's time (one process records the graph as it
            # goes; before 2026-12-03 the seconds left it out)
            res.stats.seconds += _time.perf_counter() - t
        if self.options.spill is not None:      # what each worker spilled, for the notes
            from pccl.search.spill import WorkerSpills
            self.spiller = WorkerSpills(self.options.spill,
                                        self.transport.all("spill_figures", [()] * n),
                                        self._process_peaks(self.peak_workers), self.max_memory)
        return res

    def max_time_now(self, interrupted: bool = False) -> Any:
        """The largest model time of the states admitted so far (the
        one-process ``stats.max_time``): the workers' and a resumed
        checkpoint's.  After an interrupt a worker that cannot answer
        leaves the figure as it is."""
        t = self._res.stats.max_time
        if getattr(self.model, "clock", None) is None:
            return t
        try:
            times = self.transport.all("max_time", [()] * self.workers)
        except Exception:
            if not interrupted:
                raise
            return t
        for x in times:
            if x is not None and (t is None or x > t):
                t = x
        return t

    def _put_parents(self, base: int, values: np.ndarray) -> None:
        """The global parent links of the states numbered from ``base``."""
        need = base + len(values)
        if need > len(self.parents):
            if self.parents.base is not None:
                raise MemoryError("more states than reserved")
            self.parents.resize(max(need, 2 * len(self.parents)), refcheck=False)
        self.parents[base:need] = values
        self._total = need

    def _note_peaks(self, peaks: list) -> None:
        pw = self.peak_workers
        for w, p in enumerate(peaks):
            pw[w] = max(pw[w], p)

    def _initial_rounds(self) -> bool:
        """The initial states, numbered here in chunks and handed out
        round-robin; True to stop."""
        m: Any = self.model
        T, n = self.transport, self.workers
        key, budget = m.key, self._budget_all
        empty_u64, empty_i64 = np.zeros(0, np.uint64), np.zeros(0, np.int64)
        for chunk in self._initial_chunks(lambda: budget - self._total, self._bounds,
                                          lambda: self._total, self._t_start):
            self.signals.check()
            fps = np.frombuffer(b"".join(fingerprint(key(s)) for s in chunk),
                                dtype=np.uint64).reshape(-1, 2)
            keys = np.arange(len(chunk), dtype=np.uint64)
            new_keys = T.all("decide_initial", [(p,) for p in _owner_split(fps, keys, n)])
            order = np.sort(np.concatenate(new_keys))
            base = self._total
            cut, stop = len(order), False
            if cut > budget - base:
                # the fastest search admits no more states, and goes on
                cut, stop = budget - base, not self.fastest
                self._bounds.add(Bound.MAX_STATES)
            for r in range(0 if self.fastest else cut):    # fastest: when expanded
                v = m.violations(chunk[int(order[r])])
                if v and self._record(v, base + r, 0):
                    cut, stop = r + 1, True
                    break
            ranks = np.searchsorted(order, np.concatenate(new_keys)) if len(order) \
                else empty_i64
            self._note_peaks(T.all("commit", [((base, cut, orr, empty_u64, empty_i64),)
                                              for orr in _split_like(ranks, new_keys)]))
            table = m.id_table() if getattr(m, "stable_ids", False) else None
            for w in range(n):
                idx = [g for g in range(base, base + cut) if g % n == w]
                if table is not None and w:     # the values of the states' ids first
                    T.call(w, "learn_ids", table)
                T.call(w, "adopt", idx, [chunk[int(order[g - base])] for g in idx])
            self._put_parents(base, np.full(cut, _NONE, dtype=np.uint32))
            if stop:
                return True
        return bool(self._bounds)       # a bound stopped the initial states

    def _level_rounds(self, t_start: float, stop: bool, start: Optional[dict] = None) -> None:
        """Level by level: every worker expands its share (and commits the
        last decision), the coordinator orders the new states and the stop
        events by key (:meth:`_stop_events`) and decides (:meth:`_decide`).
        (``start``: where a checkpoint resumed left it.)"""
        n, T, stats = self.workers, self.transport, self._res.stats
        cut = self._total
        holder = np.arange(cut, dtype=np.int64) % n      # who holds each state of the level
        level_base, level_size, depth = 0, cut, 0
        if start is not None:
            depth, level_base, holder = start["depth"], start["level_base"], start["holder"]
            level_size = self._total - level_base
        progress = Progress(self.progress, self.progress_interval, t_start)
        while level_size and not stop:
            self._ck_level(depth, level_base, holder)
            self.signals.check()
            at_bound = self._at_depth_bound(depth)
            decisions, self._decisions = self._decisions, None
            self._ck_mark = None        # mid-level: no checkpoint until the next boundary
            plan = None
            if getattr(T, "moves_states", False) and n > 1 and level_size >= _REBALANCE_LEVEL:
                plan = _rebalance(holder, n)
            self._share_stuck()
            per_worker = [(decisions[w] if decisions else None, at_bound) for w in range(n)]
            replies, new_keys = T.level(per_worker, level_size, plan) if plan else \
                T.level(per_worker, level_size)
            if plan:
                for r, nums in T.handed:    # the states moved: now the receiver's
                    holder[np.asarray(nums, dtype=np.int64) - level_base] = r
                    self.moved += len(nums)
            # replies[w]: (successors generated, deadlocks, first number at
            # the depth bound, ... at the model bound, violating candidates,
            # peak memory, the parents it expanded for other workers)
            sorted_keys, ranks = self._gather(replies, new_keys, holder, level_base)
            cut, stop_key = self._stop_events(replies, sorted_keys, depth)
            # transitions: parents expanded up to the stop
            if stop_key is None:
                stats.transitions += sum(r[0] for r in replies)
            else:
                stats.transitions += sum(T.all("transitions_upto", [(stop_key >> _SHIFT,)] * n))
                stop = True
            # bounds met before the stop
            for r in replies:
                for b, g in ((Bound.DEPTH, r[2]), (Bound.MODEL, r[3])):
                    if g is not None and (stop_key is None or g <= stop_key >> _SHIFT):
                        self._bounds.add(b)
            level_base, holder = self._total, self._decide(
                sorted_keys, _split_like(ranks, new_keys), cut, holder, level_base)
            if self.options.spill is not None and self.max_memory is not None:
                # each process's share, moved by the peaks (sent with the decision)
                self._decisions = [d + (s,) for d, s in zip(self._decisions,
                                                             self._spill_shares())]
            level_size = cut
            if cut:
                depth += 1
                stats.max_depth = depth
            stats.frontier = cut
            if not stop and self.max_memory is not None:
                stop = self._memory_bound(self._bounds, self._memory(self.peak_workers))
            if not stop and self.checkpoint is not None:
                self._ck_mark = {"depth": depth, "level_base": level_base, "holder": holder}
            self._report(progress, cut, depth)
        if self._decisions:       # the last level's decision: owners record its states
            self._note_peaks(T.all("commit", [(d,) for d in self._decisions]))
            self._decisions = None

    def _gather(self, replies: list, new_keys: list, holder: np.ndarray, base: int) -> tuple:
        """A step's replies joined: the workers' peaks noted, the states each
        expanded for another recorded as now held by it (``holder``, indexed
        from ``base``), and the candidates' keys sorted: ``(sorted_keys,
        ranks)``, ``ranks`` each candidate's place in the sorted order."""
        self._note_peaks([r[5] for r in replies])
        self._check_ids(r[7] for r in replies)
        self._gather_stuck(r[8] for r in replies)
        for w, r in enumerate(replies):     # moved: their successors are w's
            if len(r[6]):
                holder[r[6] - base] = w
                self.moved += len(r[6])
        allk = np.concatenate(new_keys)
        order = np.argsort(allk, kind="stable")
        ranks = np.empty(len(allk), dtype=np.int64)
        ranks[order] = np.arange(len(allk))
        return allk[order], ranks

    def _gather_stuck(self, news) -> None:
        """The stuck reasons the workers met in a step (:meth:`_Worker.new_stuck`),
        kept until :meth:`_share_stuck` hands them to every worker."""
        for new in news:
            self._stuck_news.update(new)

    def _share_stuck(self) -> None:
        """Before a level: every worker learns every stuck reason met so
        far (the initial states' included), so that whoever expands a state
        with a stuck agent can name its reason.  One round only on a level
        after new reasons appeared."""
        m: Any = self.model
        get = getattr(m, "stuck_table", None)
        if get is None:
            return
        table = get()
        new = self._stuck_news
        if len(table) != self._stuck_shared:   # the coordinator's own (initial states)
            new.update(itertools.islice(table.items(), self._stuck_shared, None))
        if new:
            table.update(new)
            self.transport.all("learn_stuck", [(new,)] * self.workers)
            self._stuck_news = {}
        self._stuck_shared = len(table)

    def _check_ids(self, news) -> None:
        """A native model with stable ids (forked workers): no id may name
        two values in two processes (the model's ``check_ids``;
        the API then runs the Python engine).  Every value of a state the
        search meets is interned by the worker that makes the state, and
        reported with its step, so the check sees them all."""
        if self._ids is None:
            return
        model: Any = self.model
        for new in news:
            if new:
                model.check_ids(self._ids, new)

    def _ck_level(self, depth: int, level_base: int, holder: np.ndarray) -> None:
        """Checkpoints: at a level boundary (the mark an interrupt saves),
        written when due (pccl/search/checkpoint.py)."""
        ck = self.checkpoint
        if ck is None:
            return
        self._ck_mark = {"depth": depth, "level_base": level_base, "holder": holder}
        if ck.due() and ck.last_saved != (depth, self._total):
            ck.save_parallel(self)

    def _bucket_rounds(self, t_start: float, start: Optional[dict] = None) -> None:
        """The fastest search (:mod:`pccl.search.fastest`'s order): the
        states wait in buckets keyed by (time steps, transitions), held by
        the workers that generated them; the coordinator knows how many
        each bucket holds and expands the smallest one as a level.  Within
        a bucket the one-process search expands the states in number order
        (a bucket fills in admission order), so the keys order the
        candidates as it meets them, and the new states are numbered as it
        numbers them; its stop events (a violation, checked when a state is
        expanded; a deadlock) are ordered by parent.  A new state's bucket
        is its parent's plus its time cost (the generators report the keys
        of the candidates that cost time).  (``start``: where a checkpoint
        resumed left it; checkpoints are taken between two buckets.)"""
        import heapq
        n, T, stats = self.workers, self.transport, self._res.stats
        total = self._total
        if start is None:
            #: who holds each state (the generator of its bucket's entry)
            self._held = (np.arange(max(total, 1024), dtype=np.int64) % n).astype(np.uint16)
            #: states waiting, per bucket (the serial search's frontier)
            self._waiting = {(0, 0): total} if total else {}
        else:
            self._held, self._waiting = start["held"], start["waiting"]
        heap = list(self._waiting)
        heapq.heapify(heap)
        progress = Progress(self.progress, self.progress_interval, t_start)
        stop = False
        ck = self.checkpoint
        while heap and not stop:
            if ck is not None:          # between two buckets: the mark an interrupt saves
                self._ck_mark = {"depth": stats.max_depth}
                if ck.due() and ck.last_saved != (stats.max_depth, self._total):
                    ck.save_parallel(self)
            self.signals.check()
            self._ck_mark = None
            bucket = heapq.heappop(heap)
            ticks, depth = bucket
            size = self._waiting.pop(bucket)
            stats.max_depth = max(stats.max_depth, depth)
            decisions, self._decisions = self._decisions, None
            self._share_stuck()
            replies, new_keys = T.level([(decisions[w] if decisions else None,
                                          self._at_depth_bound(depth), bucket)
                                         for w in range(n)], size)
            sorted_keys, ranks = self._gather(replies, new_keys, self._held, 0)
            cut, stop_key = self._stop_events_fastest(replies, sorted_keys, depth)
            upto = None if stop_key is None else (stop_key >> _SHIFT) - 1
            if upto is None:
                stats.transitions += sum(r[0] for r in replies)
            else:                   # the stopping state is not expanded
                stats.transitions += sum(T.all("transitions_upto", [(upto,)] * n))
                stop = True
            for r in replies:
                for b, g in ((Bound.DEPTH, r[2]), (Bound.MODEL, r[3])):
                    if g is not None and (upto is None or g <= upto):
                        self._bounds.add(b)
            self._decide_fastest(sorted_keys, _split_like(ranks, new_keys), cut,
                                 [r[4][0] for r in replies if r[4]], bucket, heap)
            if not stop and self.max_memory is not None:
                stop = self._memory_bound(self._bounds, self._memory(self.peak_workers))
            if not stop and ck is not None:
                self._ck_mark = {"depth": stats.max_depth}
            self._report(progress, sum(self._waiting.values()), stats.max_depth)
        if self._decisions:       # the last decision: owners record its states
            self._note_peaks(T.all("commit", [(d,) for d in self._decisions]))
            self._decisions = None

    def _stop_events_fastest(self, replies: list, sorted_keys: np.ndarray, depth: int) -> tuple:
        """:meth:`_stop_events` for the fastest search: the events are the
        expanded states' violations and deadlocks (the one-process search
        checks a state when it expands it, and stops before its successors);
        the state budget admits no more states but does not stop it."""
        events = [(g << _SHIFT, (g, vs)) for r in replies for g, vs in r[1]]
        events.sort(key=lambda e: e[0])     # stable: a state's violations before its deadlock
        room = self._budget_all - self._total
        stop_key = None
        for ek, (g, vs) in events:
            if self._record(vs, g, depth):
                stop_key = ek
                break
        new = len(sorted_keys) if stop_key is None else \
            int(np.searchsorted(sorted_keys, np.uint64(stop_key)))
        if new > room:
            self._bounds.add(Bound.MAX_STATES)
        return min(new, room), stop_key

    def _decide_fastest(self, sorted_keys: np.ndarray, owner_ranks: list, cut: int,
                        timed: list, bucket: tuple, heap: list) -> None:
        """:meth:`_decide` for the fastest search: the new states' holders
        (their parents' expanders) from the global record, and the counts of
        the buckets they go to (``timed``: per worker, the keys and time
        costs of the candidates that cost time)."""
        import heapq
        n, base = self.workers, self._total
        parents = (sorted_keys[:cut] >> np.uint64(_SHIFT)).astype(np.int64)
        gen = self._held[parents].astype(np.int64)
        decisions = []
        for w in range(n):
            sel = np.nonzero(gen == w)[0] if n > 1 else np.arange(cut)
            decisions.append((base, cut, owner_ranks[w], sorted_keys[sel], sel))
        self._decisions = decisions
        self._put_parents(base, parents.astype(np.uint32))
        if len(self._held) < base + cut:
            grown = np.zeros(max(base + cut, 2 * len(self._held)), dtype=np.uint16)
            grown[:len(self._held)] = self._held
            self._held = grown
        self._held[base:base + cut] = gen
        costs = np.zeros(cut, dtype=np.int64)
        if timed and cut:
            tk = np.concatenate([t[0] for t in timed])
            tc = np.concatenate([t[1] for t in timed])
            o = np.argsort(tk)
            tk, tc = tk[o], tc[o]
            pos = np.minimum(np.searchsorted(tk, sorted_keys[:cut]), max(len(tk) - 1, 0))
            if len(tk):
                hit = tk[pos] == sorted_keys[:cut]
                costs[hit] = tc[pos[hit]]
        ticks, depth = bucket
        for c, k in zip(*np.unique(costs, return_counts=True)):
            b = (ticks + int(c), depth + 1)
            if b not in self._waiting:
                self._waiting[b] = 0
                heapq.heappush(heap, b)
            self._waiting[b] += int(k)

    def _report(self, progress: Progress, frontier: int, depth: int) -> None:
        progress(lambda secs: {"states": self._total, "frontier": frontier, "depth": depth,
                               "seconds": secs, "memory": self._memory(self.peak_workers)})

    def _stop_events(self, replies: list, sorted_keys: np.ndarray, depth: int) -> tuple:
        """The level's stop events (deadlocks, violating new candidates, the
        state budget) in the one-process search's order (by key): how many
        of the new states are admitted, and the key the search stops at
        (None: it goes on)."""
        events = []                  # (key, kind, payload)
        for r in replies:
            for g, vs in r[1]:
                events.append((g << _SHIFT, 0, (g, vs)))
            for k, v in r[4]:        # violating candidates: those that are new
                pos = int(np.searchsorted(sorted_keys, np.uint64(k)))
                if pos < len(sorted_keys) and int(sorted_keys[pos]) == k:
                    events.append((k, 1, (pos, v)))
        total, room = self._total, self._budget_all - self._total
        cut = len(sorted_keys)
        budget_key = None
        if cut > room:
            cut = room
            budget_key = int(sorted_keys[room])
        events.sort(key=lambda e: (e[0], e[1]))
        for ek, kind, payload in events:
            if budget_key is not None and ek >= budget_key:
                break
            if kind == 0:
                g, vs = payload
                # states admitted before the deadlocked parent's turn
                if self._record(vs, g, depth):
                    return min(cut, int(np.searchsorted(sorted_keys, np.uint64(ek)))), ek
            else:
                r, v = payload
                if self._record(v, total + r, depth + 1):
                    return r + 1, ek
        if budget_key is not None:
            self._bounds.add(Bound.MAX_STATES)
        return cut, budget_key

    def _decide(self, sorted_keys: np.ndarray, owner_ranks: list, cut: int,
                holder: np.ndarray, level_base: int) -> np.ndarray:
        """Number the ``cut`` new states from the next free number, make
        each worker's decision (sent with the next step) and record the
        parent links; returns who generated (and now holds) each new state."""
        n, base = self.workers, self._total
        # who generated each admitted state: its parent's holder
        gen = holder[(sorted_keys[:cut] >> np.uint64(_SHIFT)).astype(np.int64)
                     - level_base] if cut else np.zeros(0, np.int64)
        decisions = []
        for w in range(n):
            sel = np.nonzero(gen == w)[0] if n > 1 else np.arange(cut)
            decisions.append((base, cut, owner_ranks[w], sorted_keys[sel], sel))
        self._decisions = decisions
        self._put_parents(base, (sorted_keys[:cut] >> np.uint64(_SHIFT)).astype(np.uint32))
        return gen

    def _gather_graph(self, total: int) -> None:
        """Hand the state graph to the recorder, as the one-process search
        records it: every worker sends the columns of its states and the
        transitions it generated, whose targets the targets' owners number
        (all workers at once, a chunk at a time: :meth:`_owners_number`);
        the states' columns are put in number order.  The recorder's
        analysis (:func:`pccl.search.liveness.analyse`) then runs on
        exactly the graph the one-process search records.  Counterexamples
        found there are replayed through the workers' tables when they are
        kept (:attr:`keep_workers`: until :meth:`close`), else through one
        :class:`FingerprintTable` of every partition built here."""
        rec, n = self.recorder, self.workers
        heads = self.transport.all("graph_head", [()] * n)
        self.peak_workers = [max(a, h[2]) for a, h in zip(self.peak_workers, heads)]
        idx = [h[0] for h in heads if h[1] is not None]
        cols = [h[1] for h in heads if h[1] is not None]
        chg = [h[3] for h in heads]
        del heads
        rec.changes_given = True
        self._owners_number(rec)
        rec.put_states(total, idx, cols)
        rec.put_changes(total, [c[0] for c in chg], [c[1] for c in chg])
        if self.keep_workers:
            self._open = True
            return
        parts = self.transport.all("graph_part", [()] * n)
        fps = np.zeros((total, 2), dtype=np.uint64)
        while parts:            # each partition dropped once in place
            p = parts.pop(0)
            fps[p[1]] = p[0]
            del p
        table = FingerprintTable(kernels=getattr(self.model, "table_kernels", None))
        if total:
            table.insert(fps, self.parents[:total])
        self.table = table

    def _owners_number(self, rec) -> None:
        """Every worker's transitions to the recorder, a chunk of each at a
        time (about :data:`_GRAPH_CHUNK`): each worker numbers the targets
        it owns, then every owner the targets the others sent it."""
        n = self.workers
        empty = np.zeros((0, 2), dtype=np.uint64)
        while True:
            got = self.transport.all("resolve_edges", [(_GRAPH_CHUNK,)] * n)
            if all(g is None for g in got):
                return
            asks: list = [[] for _ in range(n)]
            for g in got:
                if g is not None:
                    for o, q in enumerate(g[3]):
                        if q is not None and len(q):
                            asks[o].append(q)
            answers = self.transport.all(
                "numbers_of", [(np.concatenate(a) if len(a) > 1 else a[0] if a else empty,)
                               for a in asks])
            del asks
            at = [0] * n
            for g in got:
                if g is None:
                    continue
                src, dst, owner, qs = g
                if not dst.flags.writeable:         # Ray's, from its object store
                    dst = dst.copy()
                for o, q in enumerate(qs):
                    if q is not None and len(q):
                        dst[owner == o] = answers[o][at[o]:at[o] + len(q)]
                        at[o] += len(q)
                rec.edges(src.astype(np.int64), dst)
            del got, answers

    def peak_memory(self) -> int:
        """Peak memory of the search so far, summed over its processes."""
        return self._memory(getattr(self, "peak_workers", [0] * int(self.workers or 1)))

    def _memory(self, peak_workers) -> int:
        """Peak memory summed over the processes: with pipes worker 0 is
        this process; with Ray every worker is an actor of its own."""
        if self.ray is None:
            return peak_rss_bytes() + sum(peak_workers[1:])
        return peak_rss_bytes() + sum(peak_workers)
