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
"""

from __future__ import annotations

import gc
import io
import itertools
import marshal
import multiprocessing
import multiprocessing.connection
import operator
import os
import pickle
import signal
import struct
import time as _time
from collections.abc import Callable
from multiprocessing.reduction import ForkingPickler
from typing import Any, Optional

import numpy as np
import xxhash

from pccl.search.explorer import (Bound, Explorer, FingerprintTable, Progress, SearchResult,
                                  Stats, _MAX_STATES, _reserve, fingerprint, max_time,
                                  peak_rss_bytes, terminal, violations_of)

__all__ = ["ParallelExplorer", "available_workers", "RAY_MISSING", "RayUnavailable", "RayWorkerLost",
           "import_ray"]

_SHIFT = 24                     # successors per state < 2**24
_NONE = 0xFFFF_FFFF

#: The message when ``--ray`` is asked for without Ray installed.
def _ray_hint() -> str:
    """pccl.lang.errors.install_hint("ray"), spelt here (the same two cases): this module imports only
    generic modules (tests/acceptance/test_architecture.py).  realpath: from the editable install's
    link tree (build/__editable__.pccl-*/), this file is a link to the checkout's."""
    import os
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.realpath(__file__))))
    if os.path.isfile(os.path.join(root, "pyproject.toml")):
        return f"pip install -e '{root}[ray]'"
    import importlib.metadata       # installed from a wheel: the extra's packages
    try:
        reqs = importlib.metadata.requires("pccl") or []
    except importlib.metadata.PackageNotFoundError:
        reqs = []
    wanted = [r.split(";", 1)[0].strip() for r in reqs if 'extra == "ray"' in r.replace("'", '"')]
    if wanted:
        return "pip install " + " ".join(f"'{r}'" for r in wanted)
    return "pip install -e '.[ray]' in the pccl checkout"


RAY_MISSING = "{ray} needs Ray, an optional extra: " + _ray_hint()


def available_workers() -> int:
    """The number of cores this process may use (``--workers auto``)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):   # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


def _changed(here: np.ndarray, there: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Per parent, whether one of its successors' stall signatures
    (``there``, ``counts[i]`` of them for parent ``i``, none zero) differs
    from its own (``here``)."""
    diff = there != np.repeat(here, counts)
    return np.logical_or.reduceat(diff, np.cumsum(counts) - counts)


def _split_like(arr: np.ndarray, parts: list) -> list:
    """``arr`` cut into consecutive pieces as long as the ``parts``."""
    out, a = [], 0
    for p in parts:
        out.append(arr[a:a + len(p)])
        a += len(p)
    return out


def _owner_split(fps: np.ndarray, keys: np.ndarray, n: int) -> list:
    """Candidates grouped by owning worker: [(fps, keys)] * n."""
    if n == 1:
        return [(fps, keys)]
    owner = (fps[:, 1] % np.uint64(n)).astype(np.int64) if len(fps) else np.zeros(0, np.int64)
    return [(fps[owner == w], keys[owner == w]) for w in range(n)]


# ---------------------------------------------------------------------------
# A worker: one partition of the visited set, and the states it generated
# ---------------------------------------------------------------------------

class _Worker:
    """Engine-neutral: the transports call these methods in a process of
    their own (or, for worker 0 of :class:`_Pipes`, in the coordinator's)."""

    def __init__(self, model, wid: int, n: int, deadlock: bool, find_all: bool,
                 columns=None, fastest: bool = False):
        self.m, self.wid, self.n = model, wid, n
        self.deadlock, self.find_all = deadlock, find_all
        # the fastest search (pccl/search/fastest.py): the states I hold wait
        # in buckets keyed by (time steps, transitions); a bucket is a level
        self.fastest = fastest
        table = self._stuck_table()
        self._stuck_known = len(table) if table is not None else 0   # see new_stuck
        self.buckets: dict = {}         # (ticks, depth) -> [numbers, states]
        self.x_bucket: Any = None       # the bucket expanded last
        self.cand_cost: Any = None      # time cost of each candidate (fastest)
        self.table = FingerprintTable(kernels=getattr(model, "table_kernels", None))
        self.level: list = []          # states of the current level I hold
        self.level_idx: list = []      # ... their global numbers, ascending
        self.cand: list = []           # candidate successors of the level
        self.cand_keys: Any = None     # their keys (ascending)
        self.pending: Any = None       # owner side: (fps, keys) of new states
        self.defer_free = False        # see _discard
        self.own: Any = None           # my candidates that I own myself (never sent)
        self.par_idx: Any = None       # the parents I expanded last, their numbers
        self.par_n: Any = None         # ... and successor counts
        key = model.key
        twos = itertools.repeat(2)
        dumps, xxh = marshal.dumps, xxhash.xxh3_128_digest
        self.keys_of = lambda states: map(xxh, map(dumps, map(key, states), twos))
        # the model's batch hooks (the native engine, pccl/model/native.py):
        # one C call per chunk of states for their successors, one per level
        # for the candidates' fingerprints and first occurrences
        self.succ_batch = getattr(model, "successor_batch", None) if not fastest else None
        self.fp_batch = getattr(model, "fingerprint_batch", None) if not fastest else None
        # ... the same with each candidate's stall signature from the same pass,
        # when the stall check rides along: a state's signature is then hashed
        # once as a candidate (for its parent's change and for its own
        # column), where it was hashed three times
        self.sig_batch = getattr(model, "fingerprint_sig_batch", None) \
            if self.fp_batch is not None and columns is not None \
            and columns.sig_of is not None else None
        self.cand_sigs: Any = None     # the candidates' signatures (with sig_batch)
        # The state graph, when a recorder rides along (time-lock check,
        # temporal properties): per expanded level the sources' numbers and
        # the targets' fingerprints of every transition, and per admitted
        # state its number and ``columns(states)`` (see :meth:`graph`).
        self.columns = columns
        self.g_src: list = []
        self.g_fps: list = []
        self.g_idx: list = []
        self.g_cols: list = []
        # the stall check: per expanded state whether a transition changes
        # the team's signature (decided here, on the actual successors)
        self.g_chg_idx: list = []
        self.g_chg: list = []
        #: the largest model time of the states admitted here (models with
        #: ``clock``): :meth:`max_time`, the one-process ``stats.max_time``
        self.clock = getattr(model, "clock", None)
        self.t_max: Any = None
        #: with ``--spill``: a :class:`pccl.search.spill.WorkerSpiller`
        #: (:meth:`spill_start`); the level's part on disk while it is expanded
        self.spill: Any = None
        self.x_disk: Any = None
        self.x_disk_left = 0
        #: the fingerprints of the level's candidates met so far (:meth:`_fp_more`)
        self.x_seen: Any = None

    def _note_states(self, idx, states: list, sigs: Optional[np.ndarray] = None) -> None:
        """The states admitted to my level (numbers ``idx``; ``sigs``: their
        stall signatures, when known): their columns and the largest model
        time."""
        if self.clock is not None and states:
            t = max_time(self.m, states)
            if self.t_max is None or t > self.t_max:
                self.t_max = t
        if self.columns is not None and states:
            self.g_idx.append(np.asarray(idx, dtype=np.int64))
            self.g_cols.append(self.columns(states, sigs))

    def _discard(self, states: list) -> None:
        """States no longer needed: freed now, or (``defer_free``, set by
        the pipes transport) while this process waits for its next message
        (:func:`_recv`), off the critical path; at once when my spilling
        process is pressed (:class:`pccl.search.spill.WorkerSpiller`)."""
        if self.defer_free and states and not (self.spill is not None and self.spill.pressed):
            _litter(states)

    def ready(self) -> int:
        """Called once by :class:`_RayTransport` in the actor's process."""
        gc.disable()            # as in the one-process search: states are acyclic
        return self.wid

    def expand(self, at_bound: bool):
        """Successors of my share of the level.  Returns the candidates
        grouped by owner (first occurrences only, my own already-visited
        ones dropped), the number of successors generated, deadlocks
        ``[(number, violation)]``, the smallest numbers that met the depth
        and model bounds, the violating candidates ``[(key, violations)]``,
        my peak memory and the numbers of the parents I expanded for
        another worker (:meth:`take`).

        The same as :meth:`begin`, :meth:`expand_some` until nothing is
        left, :meth:`finish`: a transport that balances the level (the
        pipes) expands it a chunk at a time and lets an idle worker take
        part of what is left (:meth:`give`, :meth:`take`)."""
        self.begin(at_bound)
        self.expand_some(None)
        return self.finish()

    def begin(self, at_bound: bool) -> None:
        """Start expanding my share of the level (see :meth:`expand`)."""
        # the work: blocks [numbers, states, position, foreign], expanded
        # from the front, given away (:meth:`give`) from the back
        self.work: list = [[self.level_idx, self.level, 0, False]] if self.level else []
        self.level, self.level_idx = [], []
        self.x_disk, self.x_disk_left = None, 0
        if self.spill is not None:          # --spill: the part of my share on disk too
            disk = self.spill.take_level()
            if disk is not None:
                self.x_disk, self.x_disk_left = disk.segments(), disk.count
        self.x_bound = at_bound
        self.x_cs: list = []
        self.x_par_idx: list = []
        self.x_par_n: list = []
        self.x_dead: list = []
        self.x_depth_min: Optional[int] = None
        self.x_model_min: Optional[int] = None
        self.x_moved: list = []
        # the candidates' fingerprints (bytes), or None: computed by the
        # model's batch hook (:meth:`_fp_more`)
        self.x_ck: Optional[list] = [] if self.fp_batch is None else None
        # the native engine: the candidates fingerprinted a chunk at a time,
        # while they are in the cache (:meth:`_fp_more`): their fingerprints,
        # the first occurrences, how many are done; off once a block of
        # another worker's states is taken (keys no longer ascend: then
        # :meth:`finish` fingerprints the whole level in key order)
        self.x_fps: list = []
        self.x_first: list = []
        self.x_fp_done = 0
        # with sig_batch: the candidates' signatures a chunk at a time
        # (:meth:`_fp_more`), and the chunks of parents whose change waits
        # for them: (first in par_n, how many, their numbers, their signatures)
        self.x_sigs: list = []
        self.x_defer: list = []
        lv = self.work[0][1] if self.work else ()
        self.x_inc = self.fp_batch is not None and len(lv) * len(lv[0]) > _FP_LEVEL_BYTES \
            if lv else False
        if self.x_inc:
            if self.x_seen is None:
                self.x_seen = FingerprintTable(capacity=1 << 16,
                                               kernels=getattr(self.m, "table_kernels", None))
            else:
                self.x_seen.clear()

    def remaining(self) -> int:
        """States of the level not expanded (nor given away) yet."""
        return sum(len(b[1]) - b[2] for b in self.work) + self.x_disk_left

    def _more(self) -> bool:
        """``--spill``: the next segment of my share of the level on disk
        into the work (False: none left)."""
        if self.x_disk is None:
            return False
        seg = next(self.x_disk, None)
        if seg is None:
            self.x_disk = None
            return False
        states, nums = seg
        self.x_disk_left -= len(states)
        self.work.append([list(nums), states, 0, False])
        return True

    def expand_some(self, limit: Optional[int]) -> int:
        """Expand up to ``limit`` (None: all) of the states left; returns how
        many are left."""
        m, succ_fn, at_bound = self.m, self.m.successors, self.x_bound
        cs, par_idx, par_n = self.x_cs, self.x_par_idx, self.x_par_n
        ck, keys_of = self.x_ck, self.keys_of
        cols = self.columns
        chg_of = cols.changed if cols is not None and cols.sig_of is not None else None
        work = self.work
        viol_fn = m.violations if self.fastest else None
        batch = self.succ_batch
        while (limit is None or limit > 0) and (work or self._more()):
            blk = work[0]
            nums, states, pos, foreign = blk
            end = len(states) if limit is None else min(len(states), pos + limit)
            if batch is not None:
                end = min(end, pos + _FP_CHUNK)
                if foreign:
                    self.x_inc = False
                # the native engine: the chunk's successors in one C call; a
                # chunk without terminal states, off the depth bound and
                # without the stall check's per-state look needs no bytecode
                # per state
                ns, flat, _ = batch(states[pos:end])
                if not at_bound and 0 not in ns:
                    par_idx.extend(nums[pos:end])
                    par_n.extend(ns)
                    cs.extend(flat)
                    if chg_of is not None and self.sig_batch is not None:
                        # decided in finish(), on the signatures of the fingerprints' pass
                        chunk = states[pos:end]
                        self.x_defer.append((len(par_n) - len(ns), len(ns), nums[pos:end],
                                             self.columns.signatures(chunk if type(chunk) is list
                                                                     else list(chunk))))
                    elif chg_of is not None:
                        self._changes(nums[pos:end], states[pos:end], ns, flat)
                else:
                    self._expand_flat(nums[pos:end], states[pos:end], ns, flat, chg_of)
                del flat
                if ck is not None:
                    ck.extend(keys_of(cs[len(ck):]))
                elif self.x_inc:
                    self._fp_more()
            else:
                self._expand_each(nums[pos:end], states[pos:end], succ_fn, viol_fn, chg_of)
                assert ck is not None       # the Python engine has no fingerprint hook
                ck.extend(keys_of(cs[len(ck):]))     # hashed here: part of the balanced work
            if foreign:
                self.x_moved.extend(nums[pos:end])
            if limit is not None:
                limit -= end - pos
            if end < len(states):
                blk[2] = end
            else:
                work.pop(0)
                self._discard(states)
        return self.remaining()

    def _fp_more(self) -> None:
        """Fingerprint the candidates made since the last call (one C call,
        while they are in the cache; the whole level at once at the end ran
        about three times slower per candidate on wide levels), and keep the
        first occurrence of each: the first in this chunk (the C call) and
        not met in an earlier one (:attr:`x_seen`)."""
        cs, a = self.x_cs, self.x_fp_done
        if len(cs) == a:
            return
        assert self.fp_batch is not None
        if self.sig_batch is not None:
            blobs, first, _, sg = self.sig_batch(cs[a:])
            self.x_sigs.append(sg)
        else:
            blobs, first, _ = self.fp_batch(cs[a:])
        fps = np.frombuffer(blobs[0] if len(blobs) == 1 else b"".join(blobs),
                            dtype=np.uint64).reshape(-1, 2)
        uf = fps[first]
        seen = self.x_seen
        if seen.n:
            new = seen.lookup(uf) < 0
            first, uf = first[new], uf[new]
        first = first + a
        seen.insert(uf, first.astype(np.uint32))
        self.x_fps.append(fps)
        self.x_first.append(first)
        self.x_fp_done = len(cs)

    def _changes(self, nums: list, states: list, ns: list, flat: list) -> None:
        """The stall check (:meth:`liveness.StateColumns.changed`) of a chunk
        of states, none terminal, whose successors are ``flat`` (``ns`` per
        state): whether some successor's signature differs from its
        source's, for all at once."""
        sigs = self.columns.signatures      # one C call per list on the native engine
        here = sigs(states if type(states) is list else list(states))
        there = sigs(flat if type(flat) is list else list(flat))
        self._note_changes(nums, _changed(here, there, np.asarray(ns, dtype=np.int64)))

    def _cut(self, g: int, s, terminal_state: bool) -> None:
        """State ``g`` (``s``) is not expanded: without successors (a model
        bound, or a deadlock's violation, recorded), else at the depth bound."""
        if terminal_state:
            bound, v = terminal(self.m, s, self.deadlock)
            if bound is not None:
                if self.x_model_min is None or g < self.x_model_min:
                    self.x_model_min = g
            elif v is not None:
                self.x_dead.append((g, [v]))
        elif self.x_depth_min is None or g < self.x_depth_min:
            self.x_depth_min = g

    def _expand_flat(self, nums: list, states: list, ns: list, flat: list, chg_of) -> None:
        """:meth:`expand_some` of a chunk whose successors came from the batch
        hook (``ns`` per state, ``flat`` all of them), state by state."""
        cs, par_idx, par_n = self.x_cs, self.x_par_idx, self.x_par_n
        at_bound, a = self.x_bound, 0
        ci: list = []
        cv: list = []
        for g, s, k in zip(nums, states, ns):
            succ_states = flat[a:a + k]
            a += k
            if not k or at_bound:
                self._cut(g, s, not k)
                continue
            par_idx.append(g)
            par_n.append(k)
            cs.extend(succ_states)
            if chg_of is not None:
                ci.append(g)
                cv.append(chg_of(s, succ_states))
        self._note_changes(ci, cv)

    def _note_changes(self, nums, changed) -> None:
        """The stall check's flags of states ``nums``: whether a successor's
        signature differs from theirs (kept as arrays, a chunk at a time)."""
        if len(nums):
            self.g_chg_idx.append(np.asarray(nums, dtype=np.int64))
            self.g_chg.append(np.asarray(changed, dtype=np.uint8))

    def _expand_each(self, nums: list, states: list, succ_fn, viol_fn, chg_of) -> None:
        """:meth:`expand_some` of a chunk, state by state (the Python engine)."""
        at_bound = self.x_bound
        second = operator.itemgetter(1)
        cs, par_idx, par_n, dead = self.x_cs, self.x_par_idx, self.x_par_n, self.x_dead
        ci: list = []
        cv: list = []
        for g, s in zip(nums, states):
            if viol_fn is not None:     # the fastest search: checked when expanded
                vs = viol_fn(s)
                if vs:
                    dead.append((g, vs))
            succ = succ_fn(s)
            if not succ or at_bound:
                self._cut(g, s, not succ)
                continue
            par_idx.append(g)
            par_n.append(len(succ))
            cs.extend(map(second, succ))
            if chg_of is not None:
                ci.append(g)
                cv.append(chg_of(s, list(map(second, succ))))
        self._note_changes(ci, cv)

    def give(self, most: int):
        """Hand over up to ``most`` of the states left, from the back (for
        another worker to expand: :meth:`take`): ``(numbers, states)``, or
        None when there is nothing to give."""
        nums: list = []
        states: list = []
        while self.work and len(nums) < most:
            blk = self.work[-1]
            k = min(most - len(nums), len(blk[1]) - blk[2])
            cut = len(blk[1]) - k
            nums[:0], states[:0] = blk[0][cut:], blk[1][cut:]
            del blk[0][cut:], blk[1][cut:]
            if cut <= blk[2]:
                self.work.pop()
                self._discard(blk[1])
        return (nums, states) if nums else None

    def take(self, nums: list, states: list) -> None:
        """States of the level handed over by another worker (:meth:`give`),
        to expand after mine: their successors are mine (I hold those that
        are admitted), and :meth:`finish` names them (the coordinator's
        record of who holds which state)."""
        if nums:
            self.work.append([nums, states, 0, True])

    def finish(self):
        """The reply of :meth:`expand`, once the level is expanded."""
        assert not self.work, "finish() before the level is expanded"
        cs, par_idx, par_n, ck = self.x_cs, self.x_par_idx, self.x_par_n, self.x_ck
        self.x_cs, self.x_par_idx, self.x_par_n = [], [], []
        self.x_ck = [] if self.fp_batch is None else None
        total = len(cs)
        inc = self.x_inc and self.x_fp_done == total
        x_fps, x_first, x_sigs = self.x_fps, self.x_first, self.x_sigs
        self.x_fps, self.x_first, self.x_fp_done, self.x_sigs = [], [], 0, []
        pi = np.asarray(par_idx, dtype=np.uint64)
        pn = np.asarray(par_n, dtype=np.int64)
        moved = np.asarray(self.x_moved, dtype=np.int64)
        viol: list = []
        self.cand_cost = np.zeros(total, dtype=np.int64) if self.fastest else None
        if total:
            starts = np.repeat(np.cumsum(pn) - pn, pn)
            keys = (np.repeat(pi << np.uint64(_SHIFT), pn)
                    + (np.arange(total, dtype=np.int64) - starts).astype(np.uint64))
            order = None
            if len(pi) > 1 and not bool((pi[1:] > pi[:-1]).all()):
                # parents handed over by others (:meth:`take`): back in key order
                inc = False
                order = np.argsort(keys, kind="stable")
                keys = keys[order]
                ol = order.tolist()
                cs = [cs[p] for p in ol]
                if ck is not None:
                    ck = [ck[p] for p in ol]
                del ol
            fps, first, self.cand_sigs = self._level_fps(
                cs, ck, (x_fps, x_first, x_sigs) if inc else None)
            if self.x_defer:
                self._deferred_changes(pn, self.cand_sigs, order)
            del order
            if self.columns is not None:
                self.g_src.append((keys >> np.uint64(_SHIFT)).astype(np.uint32))
                self.g_fps.append(fps)
            f, k = fps[first], keys[first]
            if self.n > 1:
                mine = (f[:, 1] % np.uint64(self.n)) == np.uint64(self.wid)
            else:
                mine = np.ones(len(k), dtype=bool)
            seen = np.zeros(len(k), dtype=bool)
            if mine.any() and self.table.n:
                seen[mine] = self.table.lookup(f[mine]) >= 0
            keep = ~seen
            first, f, k = first[keep], f[keep], k[keep]
            if self.fastest:            # violations: when expanded; the time costs instead
                costs = np.fromiter(self.m.time_costs([cs[p] for p in first.tolist()]),
                                    dtype=np.int64, count=len(first))
                self.cand_cost[first] = costs
                timed = costs != 0
                viol = [(k[timed], costs[timed])]
            else:
                found = violations_of(self.m, list(map(cs.__getitem__, first.tolist())))
                if found:
                    kl = k.tolist()
                    viol = [(kl[j], v) for j, v in found]
        else:
            keys = np.zeros(0, np.uint64)
            f, k = np.zeros((0, 2), np.uint64), keys
            self.cand_sigs = None
        self.cand, self.cand_keys = cs, keys
        self.par_idx, self.par_n = pi, pn
        dead, self.x_dead = self.x_dead, []
        if self.spill is not None:          # the level's candidates all held: how much
            self.spill.observe()
        take = getattr(self.m, "take_new_ids", None)      # stable ids: for the check
        return (_owner_split(f, k, self.n), total, dead, self.x_depth_min, self.x_model_min,
                viol, peak_rss_bytes(), moved, take() if take is not None else (),
                self.new_stuck())

    def _level_fps(self, cs: list, ck: Optional[list], chunks: Optional[tuple]) -> tuple:
        """The fingerprints of the level's candidates ``cs`` (in key order),
        the positions of each one's first occurrence, ascending, and (with
        :attr:`sig_batch`, else None) their stall signatures: from the
        ``chunks`` fingerprinted as they were made (:meth:`_fp_more`), else
        from the model's batch hook in one C call (native), else from
        ``ck``, the candidates' fingerprints as bytes (the Python engine)."""
        if chunks is not None:
            x_fps, x_first, x_sigs = chunks
            return (np.concatenate(x_fps) if len(x_fps) > 1 else x_fps[0],
                    np.concatenate(x_first) if len(x_first) > 1 else x_first[0],
                    (np.concatenate(x_sigs) if len(x_sigs) > 1 else x_sigs[0]) if x_sigs
                    else None)
        if ck is None:
            sigs = None
            if self.sig_batch is not None:
                blobs, first, _, sigs = self.sig_batch(cs)
            else:
                assert self.fp_batch is not None
                blobs, first, _ = self.fp_batch(cs)
            return np.frombuffer(b"".join(blobs), dtype=np.uint64).reshape(-1, 2), first, sigs
        fps = np.frombuffer(b"".join(ck), dtype=np.uint64).reshape(-1, 2)
        # first occurrence of each fingerprint (the smallest key: keys ascend)
        first = np.fromiter(dict(zip(reversed(ck), range(len(ck) - 1, -1, -1))).values(),
                            dtype=np.int64, count=-1)
        first.sort()
        return fps, first, None

    def _deferred_changes(self, pn: np.ndarray, sigs: np.ndarray,
                          order: Optional[np.ndarray]) -> None:
        """The stall check's changes of the parents whose chunks waited for
        their candidates' signatures (``sigs``, in key order; ``order``: the
        positions the candidates were generated at, when parents handed
        over by others put them out of key order; ``pn``: each parent's
        successor count, in the order generated)."""
        defer, self.x_defer = self.x_defer, []
        if order is not None:
            made = np.empty_like(sigs)
            made[order] = sigs
            sigs = made
        ends = np.cumsum(pn)
        for start, cnt, nums, here in defer:
            counts = pn[start:start + cnt]
            a, b = int(ends[start] - counts[0]), int(ends[start + cnt - 1])
            self._note_changes(nums, _changed(here, sigs[a:b], counts))

    def transitions_upto(self, parent: int) -> int:
        """Of the level I expanded last, the successors of the parents
        numbered ``parent`` or less (where the search stopped)."""
        return int(self.par_n[self.par_idx <= np.uint64(parent)].sum())

    def decide(self, *parts):
        """Owner side: of the candidates sent to me (one ``(fps, keys)`` part
        per generator; ``None`` for mine, which stayed here and were checked
        against my table by :meth:`expand`), the new ones (smallest key per
        fingerprint); their keys go back to the coordinator."""
        own, self.own = self.own, None
        others = [p for p in parts if p is not None and len(p[1])]
        if others:
            f = np.concatenate([p[0] for p in others]) if len(others) > 1 else others[0][0]
            k = np.concatenate([p[1] for p in others]) if len(others) > 1 else others[0][1]
            if self.table.n:
                new = self.table.lookup(f) < 0
                f, k = f[new], k[new]
            if own is not None and len(own[1]):
                f, k = np.concatenate([own[0], f]), np.concatenate([own[1], k])
            return self._decided(f, k, False)
        if own is None:
            own = (np.zeros((0, 2), np.uint64), np.zeros(0, np.uint64))
        return self._decided(own[0], own[1], True)

    def decide_initial(self, part):
        """:meth:`decide` for a chunk of initial states (which may repeat)."""
        f, k = part
        if self.table.n:
            new = self.table.lookup(f) < 0
            f, k = f[new], k[new]
        return self._decided(f, k, False)

    def _decided(self, f, k, distinct: bool):
        """Keep the new candidates ``(f, k)`` (none in my table) until the
        coordinator's decision; answer their keys.  Unless ``distinct``,
        equal fingerprints (from several generators: rare) keep the smallest
        key: sorting by the low word alone finds them, and only then the
        full sort runs."""
        if not distinct and len(k) > 1:
            low = f[:, 1]
            lo = np.sort(low)
            dup = lo[1:] == lo[:-1]
            if dup.any():
                # only the candidates whose low word repeats are sorted (a
                # lexsort of them all cost ~200 ns a candidate, and its order
                # made the coordinator's sort of the keys slow too); the rest
                # keep their order (runs of ascending keys)
                dl = np.unique(lo[1:][dup])
                at = np.minimum(np.searchsorted(dl, low), len(dl) - 1)
                idx = np.flatnonzero(dl[at] == low)
                sf, sk = f[idx], k[idx]
                order = np.lexsort((sk, sf[:, 1], sf[:, 0]))
                sf = sf[order]
                later = np.zeros(len(order), dtype=bool)
                later[1:] = (sf[1:] == sf[:-1]).all(axis=1)
                if later.any():
                    keep = np.ones(len(k), dtype=bool)
                    keep[idx[order[later]]] = False
                    f, k = f[keep], k[keep]
        self.pending = (f, k)
        return k

    def commit(self, decision):
        """Record the coordinator's decision on the last level: ``(base,
        cut, owner_ranks, won_keys, won_ranks)`` -- the first new state's
        number, how many new states are admitted, the ranks of the keys my
        :meth:`decide` returned, and the keys (ascending) and ranks of the
        admitted states I generated."""
        if decision is None:
            return peak_rss_bytes()
        base, cut, owner_ranks, won_keys, won_ranks = decision[:5]
        if len(decision) > 5 and self.spill is not None:    # --spill: my share, moved
            self.spill.set_share(decision[5])
        if self.cand_keys is not None:
            pos = np.searchsorted(self.cand_keys, won_keys).tolist()
            cs = self.cand
            self.level = [cs[p] for p in pos]
            self.level_idx = (won_ranks + base).tolist()
            self._note_states(self.level_idx, self.level,
                              None if self.cand_sigs is None else self.cand_sigs[pos])
            if self.fastest:
                self._file(self.level_idx, self.level, self.cand_cost[pos].tolist())
                self.level, self.level_idx, self.cand_cost = [], [], None
            self._discard(cs)
            del cs
            self.cand, self.cand_keys, self.cand_sigs = [], None, None
        if self.pending is not None:
            f, _ = self.pending
            self.pending = None
            keep = owner_ranks < cut
            if keep.any():
                self.table.insert(f[keep], (base + owner_ranks[keep]).astype(np.int64))
        if self.spill is not None:
            self.spill.relieve(self)        # memory pressed: to disk, instead of the bound
            if self.spill.pressed and self.defer_free:
                _LITTER.clear()             # and the states waiting to be freed: now
        return peak_rss_bytes()

    def _file(self, idx: list, states: list, costs: list) -> None:
        """The fastest search: new states (numbers ``idx``, ascending), each
        into the bucket of the one expanded last plus its time cost."""
        ticks, depth = self.x_bucket
        for g, st, c in zip(idx, states, costs):
            b = self.buckets.get((ticks + c, depth + 1))
            if b is None:
                b = self.buckets[ticks + c, depth + 1] = [[], []]
            b[0].append(g)
            b[1].append(st)

    def start_level(self, decision, at_bound: bool, bucket=None) -> None:
        """Commit the last level's decision and begin expanding the next:
        my share of the level, or (the fastest search) of ``bucket``."""
        self.commit(decision)
        if bucket is not None:
            self.level_idx, self.level = self.buckets.pop(bucket, ([], []))
            self.x_bucket = bucket
        self.begin(at_bound)

    def step(self, decision, at_bound: bool, bucket=None):
        """One round: commit the last level, expand the next.  Returns the
        candidates for each owner, then the rest of :meth:`expand`'s reply,
        as ``n + 1`` values (so that Ray can hand each part to its owner
        without the coordinator fetching it)."""
        self.start_level(decision, at_bound, bucket)
        self.expand_some(None)
        return self.finish_step()

    def finish_step(self):
        """:meth:`step`'s reply, once the level is expanded (for a transport
        that expands it a chunk at a time)."""
        r = self.finish()
        parts = list(r[0])
        self.own, parts[self.wid] = parts[self.wid], None     # mine stay here
        return (*parts, r[1:])

    def handoff(self, k: int) -> tuple:
        """The last ``k`` states of my level (committed, not begun), handed
        to another worker that holds too few (:func:`_rebalance`):
        ``(numbers, states, the model's interned values or None)``."""
        k = min(k, len(self.level))     # (--spill: only what is in memory)
        nums, states = self.level_idx[len(self.level_idx) - k:], self.level[len(self.level) - k:]
        del self.level_idx[len(self.level_idx) - k:], self.level[len(self.level) - k:]
        table = self.m.id_table() if getattr(self.m, "stable_ids", False) else None
        return nums, states, table

    def receive(self, loot: tuple) -> None:
        """States of another worker's level (:meth:`handoff`), into mine in
        number order (so the candidates' keys still ascend)."""
        nums, states, table = loot
        if table is not None:
            self.m.learn_ids(table)
        allnums = self.level_idx + list(nums)
        allstates = self.level + list(states)
        order = np.argsort(np.asarray(allnums, dtype=np.int64), kind="stable").tolist()
        self.level_idx = [allnums[i] for i in order]
        self.level = [allstates[i] for i in order]

    def _stuck_table(self) -> Optional[dict]:
        table = getattr(self.m, "stuck_table", None)
        return table() if table is not None else None

    def new_stuck(self) -> dict:
        """The stuck reasons this process met since it last reported or
        learned (:meth:`pccl.model.compiled.CompiledProgram.stuck_code`): a
        stuck status is a hash of its reason, so it means the same in every
        process, but the reason itself is known only where an agent got
        stuck.  The coordinator gathers them with each step and hands them
        to every worker (:meth:`learn_stuck`) before the next level, in
        which another worker may expand (and check) a successor of that
        state: the stuck agent's status is carried into it."""
        table = self._stuck_table()
        if table is None or len(table) == self._stuck_known:
            return {}
        new = dict(itertools.islice(table.items(), self._stuck_known, None))
        self._stuck_known = len(table)
        return new

    def learn_stuck(self, reasons: dict) -> None:
        """Stuck reasons met by other workers (:meth:`new_stuck`)."""
        table = self._stuck_table()
        if table is not None:
            table.update(reasons)
            self._stuck_known = len(table)

    def learn_ids(self, table: dict) -> None:
        """The coordinator's interned values (a native model with stable
        ids, :meth:`pccl.model.native.NativeModel.learn_ids`), before it
        hands me states that name them."""
        self.m.learn_ids(table)

    def adopt(self, idx, states):
        if self.fastest:        # initial states: bucket (0, 0)
            b = self.buckets.setdefault((0, 0), [[], []])
            b[0].extend(idx)
            b[1].extend(states)
        else:
            self.level_idx.extend(idx)
            self.level.extend(states)
        self._note_states(idx, states)
        if self.spill is not None:
            self.spill.relieve(self)

    def graph_head(self):
        """What this worker knows of the state graph besides the visited set
        and the transitions, handed over once at the end of the search: the
        columns of the states I held, the stall check's flags and my peak
        memory.  The transitions follow a chunk at a time, their targets
        numbered by their owners (:meth:`resolve_edges`, :meth:`numbers_of`)."""
        idx = np.concatenate(self.g_idx) if self.g_idx else np.zeros(0, np.int64)
        cols = [np.concatenate(c) for c in zip(*self.g_cols)] if self.g_cols else None
        self.g_idx, self.g_cols = [], []
        chg = (np.concatenate(self.g_chg_idx) if self.g_chg_idx else np.zeros(0, np.int64),
               np.concatenate(self.g_chg) if self.g_chg else np.zeros(0, np.uint8))
        self.g_chg_idx, self.g_chg = [], []
        return idx, cols, peak_rss_bytes(), chg

    def graph_part(self):
        """My partition of the visited set (fingerprints and their state
        numbers), handed over when the coordinator must replay
        counterexamples after the workers are gone; the table is dropped
        here (the coordinator's table numbers the states from then on)."""
        t = self.table
        # from disk when I spilled it (entries() reads it back)
        mine = self.spill.table.entries() if self.spill is not None else \
            (t.fps[:t.n], t.parents[:t.n])
        self.table = FingerprintTable()
        return mine

    def numbers_of(self, q: np.ndarray) -> np.ndarray:
        """The state numbers of fingerprints ``q`` (shape (k, 2)) of my
        partition; -1 where absent (a successor not admitted)."""
        if self.spill is not None:          # the spilled partition answers global numbers
            return self.spill.table.lookup(q)
        t = self.table
        local = t.lookup(q)
        hit = local >= 0
        out = np.full(len(q), -1, dtype=np.int64)
        out[hit] = t.parents[local[hit]]
        return out

    def resolve_edges(self, most: int):
        """The next of the transitions I generated (:meth:`graph_edges`):
        their sources, their targets' numbers where I own the target (-1
        elsewhere), each target's owner, and per owner the fingerprints it
        must number (None for me); None once all are handed over."""
        part = self.graph_edges(most)
        if part is None:
            return None
        src, fps = part
        n = self.n
        if n == 1:
            return src, self.numbers_of(fps), None, [None]
        owner = (fps[:, 1] % np.uint64(n)).astype(np.uint16)
        dst = np.full(len(src), -1, dtype=np.int64)
        mine = owner == self.wid
        dst[mine] = self.numbers_of(fps[mine])
        asks = [None if o == self.wid else fps[owner == o] for o in range(n)]
        return src, dst, owner, asks

    def index_of(self, fp: bytes) -> int:
        return int(self.numbers_of(np.frombuffer(fp, dtype=np.uint64).reshape(1, 2))[0])

    def graph_edges(self, most: int):
        """The next of the transitions I generated, in the order generated,
        about ``most`` of them (source numbers, target fingerprints: the
        coordinator numbers the targets), dropped here as they go; None once
        all are handed over.  In chunks: whole, they were copied once to be
        joined and once more to be sent (a peak of three times their size
        here, twice at the coordinator)."""
        src: list = []
        fps: list = []
        k = 0
        while self.g_src and k < most:
            s, f = self.g_src[0], self.g_fps[0]
            if k + len(s) > most:           # a long part (one level, or a checkpoint's join)
                cut = max(most - k, 1)
                s, f, self.g_src[0], self.g_fps[0] = s[:cut], f[:cut], s[cut:], f[cut:]
            else:
                del self.g_src[0], self.g_fps[0]
            src.append(s)
            fps.append(f)
            k += len(s)
        if not src:
            return None
        return (np.concatenate(src) if len(src) > 1 else src[0],
                np.concatenate(fps) if len(fps) > 1 else fps[0])

    def max_time(self):
        """The largest model time of the states admitted here (None: no
        clock, or none admitted)."""
        return self.t_max

    def spill_start(self, directory, share: Optional[int], states: Optional[int]) -> int:
        """``--spill``: spill my partition and my share of the levels into
        ``directory`` (a :class:`pccl.search.spill.SpillDir`), with ``share``
        bytes of ``--max-memory`` for this process (before any state; None:
        set later, :meth:`spill_share`).  Returns this process's resident
        memory now (what it needs before its first state)."""
        from pccl.search.spill import WorkerSpiller
        assert not self.table.n, "spill_start() before the first state"
        self.spill = WorkerSpiller(directory, share, states, FingerprintTable)
        self.table = self.spill.table
        return self.spill.start

    def spill_share(self, share: Optional[int]) -> None:
        """``--spill``: my first share of ``--max-memory`` (by need: the
        coordinator's :func:`pccl.search.spill.shares`)."""
        self.spill.set_share(share, first=True)

    def spill_figures(self) -> Optional[dict]:
        """What I spilled (:meth:`pccl.search.spill.WorkerSpiller.figures`)."""
        return self.spill.figures() if self.spill is not None else None

    def spill_close(self) -> None:
        if self.spill is not None:
            self.spill.close()

    def checkpoint(self, fn, *args):
        """Checkpoints (pccl/search/checkpoint.py): ``fn(self, *args)`` here,
        in the worker's process (save or load my partition)."""
        return fn(self, *args)


# ---------------------------------------------------------------------------
# Transports: how the rounds reach the workers
# ---------------------------------------------------------------------------

def _spin_seconds(default: float = 0.05) -> float:
    """Seconds a process polls for a message before it blocks (see
    :func:`_recv`): ``PCCL_SPIN`` in the environment (``0``: block at once),
    else 50 ms."""
    try:
        return max(0.0, float(os.environ.get("PCCL_SPIN", default)))
    except ValueError:
        return default


_SPIN = _spin_seconds()
#: without ``PCCL_SPIN``, poll only while the machine is not overloaded
_SPIN_AUTO = "PCCL_SPIN" not in os.environ
_LOAD = [0.0, False]         # when last read, and whether overloaded then


def _runnable() -> Optional[int]:
    """The processes running or waiting for a core right now (the kernel's
    count in ``/proc/loadavg``, this one included), or None where there is
    no such file."""
    try:
        with open("/proc/loadavg", "rb") as f:
            return int(f.read().split()[3].split(b"/")[0])
    except (OSError, ValueError, IndexError):
        return None


def _overloaded() -> bool:
    """Whether a waiting process should block at once instead of polling:
    when more processes are runnable right now than the machine has cores
    (a poller would then take a core from its partner or from another job;
    5 us to read; the machine's cores, not this process's: a pinned worker
    may use one).  Beside one busy loop on 2 cores, fischer 3 agents k=2
    with 2 native workers: 0.82x one worker polling, 0.84x blocking;
    pinned (:func:`_pin`) 0.89x polling, 0.96x blocking; idle the same
    either way (docs/scale-out.md).  Without the kernel's count: the
    1-minute load average against four times the cores (read at most once
    a second; measured on a shared machine at load 11, blocking won 2x; at
    load 3.8 polling did)."""
    cores = os.cpu_count() or 1     # the kernel's counts are the machine's, not this process's
    now = _runnable()
    if now is not None:
        return now > cores
    t = _time.monotonic()
    if t - _LOAD[0] > 1.0:
        _LOAD[0] = t
        try:
            _LOAD[1] = os.getloadavg()[0] > 4 * cores
        except (OSError, AttributeError):      # pragma: no cover - no load average
            _LOAD[1] = False
    return bool(_LOAD[1])


#: ``PCCL_PIN=0`` in the environment: never pin a worker to a core
_PIN = os.environ.get("PCCL_PIN", "1") != "0"


def _pin(wid: int, n: int) -> Optional[set]:
    """Pin worker ``wid`` of ``n`` to one core of its own when the workers
    are exactly as many as the cores this process may use (so no core is
    left out, and two such searches on one machine still share every core);
    returns the cores it had, to restore, or None when not pinned.  Beside a
    competing job the scheduler then moves only that job between the cores,
    instead of moving the workers away from their caches: fischer 3 agents
    k=2 with 2 native workers beside one busy loop 0.86x one worker
    unpinned, 0.95x pinned; idle 1.72x and 1.71x (docs/scale-out.md).
    ``PCCL_PIN=0`` turns it off."""
    if not _PIN:
        return None
    try:
        cpus = sorted(os.sched_getaffinity(0))
        if len(cpus) != n or n < 2:
            return None
        os.sched_setaffinity(0, {cpus[wid]})
    except (AttributeError, OSError):       # pragma: no cover - non-Linux
        return None
    return set(cpus)


#: balanced levels (see :meth:`_Pipes.level`); ``PCCL_BALANCE=0``: off
_BALANCE = os.environ.get("PCCL_BALANCE", "1") != "0"
#: ... with the native engine only when asked for (``PCCL_BALANCE=1``): measured
#: on fischer 3 agents k=2 (docs/scale-out.md, "Native workers"), the static
#: split spent 15-20 % less CPU and was faster in 6 of 7 pairs, idle and beside
#: a busy loop (moving native states and sorting the candidates back into key
#: order cost more than the imbalance)
_BALANCE_NATIVE = os.environ.get("PCCL_BALANCE") == "1"
#: ... for levels of at least this many states (~15 ms of work or more
#: for one worker; measured: on a loaded machine, balancing fischer k=2's
#: levels of ~1,600 states cost more than it gained)
_BALANCE_LEVEL = 8192


#: Lists of states to free while waiting (:meth:`_Worker._discard`).
_LITTER: list = []
#: ... at most this many states: a process that never waits (its message is
#: there whenever it asks) frees the oldest at once instead (measured before
#: this cap, fischer k=2 d=2 with 2 workers spilling: the coordinator's held
#: up to 58,000 states, 37 levels' candidates, and its peak varied with it)
_LITTER_MOST = 1 << 15


def _litter(states: list) -> None:
    """Free ``states`` while waiting (:func:`_ready`), the oldest of those
    waiting at once when more than :data:`_LITTER_MOST` would wait."""
    _LITTER.append(states)
    held = sum(map(len, _LITTER))
    while held > _LITTER_MOST and len(_LITTER) > 1:
        held -= len(_LITTER.pop(0))


def _recv(conn):
    """``conn.recv()``, first freeing discarded states (a slice at a time,
    while no message is there: freeing a level's candidates costs about as
    much as a tenth of expanding it) and polling for up to :data:`_SPIN`
    seconds.  A process that blocks gives up its core; when its message
    arrives it waits for the scheduler (on a busy machine, behind other jobs
    for a time slice; on an idle virtual machine, for the core to wake up),
    twice per BFS level.  The wait between rounds is short (the other
    workers' share of a level), so polling through it keeps the core."""
    return _read(_ready([conn]))


def _ready(conns: list):
    """The first of ``conns`` with a message waiting (see :func:`_recv`:
    frees discarded states, polls, then blocks)."""
    def first():
        for c in conns:
            if c.poll(0):
                return c
        return None
    c = first()
    while _LITTER and c is None:
        states = _LITTER[-1]
        if states:
            del states[-2048:]
        else:
            _LITTER.pop()
        c = first()
    if _SPIN > 0 and c is None and not (_SPIN_AUTO and _overloaded()):
        clock, pass_turn = _time.perf_counter, getattr(os, "sched_yield", lambda: None)
        end = clock() + _SPIN
        while c is None and clock() < end:
            pass_turn()     # a process waiting for a core (my partner?) gets this one
            c = first()
    if c is None:
        c = multiprocessing.connection.wait(conns)[0]
    return c


#: Native states a worker expands per C call, their successors then
#: fingerprinted at once (:meth:`_Worker._fp_more`)
_FP_CHUNK = 4096
#: ... on levels of more bytes than this (the states of the level: their
#: candidates no longer stay in the cache until the end of the level); a
#: smaller level is fingerprinted in one call at its end, which costs less
#: (measured on fischer with 3 agents, levels of at most ~20 MB: 5.3-5.5 s
#: against 5.7-5.8 s chunked; race_robust with 4 robots, levels up to
#: ~250 MB: chunked 3.5 s faster)
_FP_LEVEL_BYTES = 32 << 20
#: States a worker expands between two looks for another worker's request
#: (:func:`_balanced_step`, :meth:`_Pipes._balance`): ~0.2-0.5 ms of work.
_CHUNK = 64
#: ... times this for the native engine (a state costs ~0.5 us to expand there,
#: against ~3.5 us in Python; a look costs a poll of the pipe: measured on
#: fischer 3 agents k=1, 8.18 s of CPU with 8 times, 7.70 s with 32, 7.48 s
#: unbalanced)
_NATIVE_CHUNK = 32


def _chunk(w: "_Worker") -> int:
    """The states ``w`` expands between two looks for a request."""
    return _CHUNK * _NATIVE_CHUNK if w.succ_batch is not None else _CHUNK
#: A worker asked for work hands over half of what it has left, if that is
#: at least this many states (moving a state costs about as much as
#: expanding it: pickled, sent, unpickled).
_MIN_GIVE = 32


def _half(left: int) -> int:
    return left // 2 if left >= _MIN_GIVE else 0


def _balanced_step(w: "_Worker", conn, *args) -> None:
    """A forked worker's side of a balanced level (:meth:`_Pipes.level`):
    commit the decision, expand my share a chunk at a time, answering the
    coordinator's requests for work (``("steal", None)`` -> ``("loot",
    (numbers, states) or None)``) in between; then say ``("hungry", None)``
    and expand the states the coordinator hands over (``("work", (numbers,
    states))``) until it says ``("finish", None)``; the caller then finishes
    the step (:meth:`_Worker.finish_step`), while worker 0 finishes its own."""
    w.start_level(*args)
    poll = conn.poll

    def recv():
        return _read(conn)

    def send(msg) -> None:
        _send(conn, msg)

    chunk = _chunk(w)

    def expand_all():
        while w.expand_some(chunk):
            while poll(0):
                kind, _ = recv()
                assert kind == "steal", kind
                send(("loot", w.give(_half(w.remaining()))))
    expand_all()
    while True:
        send(("hungry", None))
        kind, value = _recv(conn)
        while kind == "steal":          # asked before my "hungry" arrived
            send(("loot", None))
            kind, value = _recv(conn)
        if kind == "work":
            w.take(*value)
            expand_all()
            continue
        assert kind == "finish", kind
        return


#: Levels of at least this many states are rebalanced (:func:`_rebalance`)
_REBALANCE_LEVEL = 1024
#: ... when a worker holds more than this much above an even share
_REBALANCE_SLACK = 0.1


def _rebalance(holder: np.ndarray, n: int) -> list:
    """Moves ``[(giver, receiver, count)]`` that even out the workers'
    shares of a level (``holder``: who holds each state), or [] when no
    worker holds more than :data:`_REBALANCE_SLACK` above an even share.
    States stay with the worker that generated them, so without this a
    search from one initial state is expanded by one worker alone (race
    with 4 robots, 2 native workers: worker 1 expanded none of 16.5 M
    states); a move costs a pickle of the state, and the states it moves
    are the givers' last (their successors stay with the receiver)."""
    counts = np.bincount(holder, minlength=n)
    even = len(holder) / n
    if counts.max() <= even * (1 + _REBALANCE_SLACK):
        return []
    target = np.full(n, len(holder) // n)
    target[:len(holder) % n] += 1
    surplus = counts - target
    givers = [[int(w), int(x)] for w, x in enumerate(surplus) if x > 0]
    takers = [[int(w), int(-x)] for w, x in enumerate(surplus) if x < 0]
    plan = []
    while givers and takers:
        g, r = givers[0], takers[0]
        k = min(g[1], r[1])
        plan.append((g[0], r[0], k))
        g[1] -= k
        r[1] -= k
        if not g[1]:
            givers.pop(0)
        if not r[1]:
            takers.pop(0)
    return plan


#: ``prctl`` option: the signal a process gets when its parent dies (Linux).
_PR_SET_PDEATHSIG = 1


def _die_with_parent(parent: int) -> None:
    """Ask the kernel to kill this process when its parent dies (Linux:
    ``prctl(PR_SET_PDEATHSIG, SIGKILL)``); a parent already gone by now
    means exit at once.  ``PCCL_PDEATHSIG=0`` in the environment skips the
    ``prctl`` (the tests use it to check the portable fallback: the pipe to
    the parent closes, and :func:`_serve` returns)."""
    if os.environ.get("PCCL_PDEATHSIG") == "0" or not hasattr(os, "getppid"):
        return
    try:
        import ctypes
        import ctypes.util
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):       # not Linux: the closed pipe tells
        return
    if os.getppid() != parent:              # died before the prctl
        os._exit(0)


def _serve(conn, model, wid, n, deadlock, find_all, columns=None, parent=None,
           inherited=(), fastest=False):
    # The coordinator alone handles Ctrl-C and SIGTERM (sent to the whole
    # process group by a terminal or a job control): a worker ignores both
    # and stops when the coordinator says so, or when its pipe closes.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    for c in inherited:     # the coordinator's ends of the pipes: else its death is no EOF
        c.close()
    if parent is not None:
        _die_with_parent(parent)
    gc.disable()
    _pin(wid, n)
    w = _Worker(model, wid, n, deadlock, find_all, columns, fastest)
    w.defer_free = True
    while True:
        try:
            cmd, args = _recv(conn)
        except EOFError:
            return
        if cmd == "stop":
            return
        try:
            if cmd == "lstep":
                _balanced_step(w, conn, *args)
                reply = ("ok", w.finish_step())
            elif cmd == "pstep":      # a step that moves states first (_rebalance)
                (decision, at_bound), gives, expect = args
                w.commit(decision)
                for k in gives:           # one hand-over per receiver, in the plan's order
                    _send(conn, ("loot", w.handoff(k)))
                for _ in range(expect):
                    kind, loot = _recv(conn)
                    assert kind == "work", kind
                    w.receive(loot)
                w.begin(at_bound)
                w.expand_some(None)
                reply = ("ok", w.finish_step())
            else:
                reply = ("ok", getattr(w, cmd)(*args))
        except BaseException as exc:         # report, do not hang the coordinator
            reply = ("error", exc)
        try:
            _send(conn, reply)
        except (OSError, BrokenPipeError):
            return


#: A message this small is sent without waiting for the receiver to read
#: (the socket buffers hold ~200 KB; see :meth:`_Pipes.level`).
_EARLY = 64 * 1024


#: Buffers (numpy arrays) of at least this many bytes travel beside a
#: message's pickle, not inside it (:func:`_dumps`)
_ASIDE_BYTES = 1 << 16


def _dumps(obj) -> list:
    """A message as the frames :func:`_send_frames` writes: its pickle
    (protocol 5) behind a header of the sizes of its large buffers, then
    those buffers as they lie in memory.  ``Connection.send`` copied each
    array into the pickle and the receiver copied it out of a stream again:
    measured, forked from a process of 1.6 GB, 208 MB of arrays took 1.46 s
    that way and 0.54 s as frames (race_robust with 4 robots, 2 workers:
    worker 1's part of the recorded graph 2.27 s against 0.84 s)."""
    bufs: list = []

    def aside(b: pickle.PickleBuffer) -> bool:
        raw = b.raw()
        if raw.nbytes < _ASIDE_BYTES:
            return True         # in the pickle
        bufs.append(raw)
        return False
    f = io.BytesIO()
    ForkingPickler(f, 5, True, aside).dump(obj)
    head = struct.pack(f"<I{len(bufs)}Q", len(bufs), *(b.nbytes for b in bufs))
    return [head + f.getbuffer(), *bufs]


def _size(frames: list) -> int:
    return sum(memoryview(fr).nbytes for fr in frames)


def _send_frames(conn, frames: list) -> None:
    for fr in frames:
        conn.send_bytes(fr)


def _send(conn, obj) -> None:
    """``conn.send(obj)``, its large arrays beside the pickle (:func:`_dumps`)."""
    _send_frames(conn, _dumps(obj))


def _read(conn):
    """The message :func:`_send` wrote, read from ``conn`` (its large
    arrays straight into their own memory, writable)."""
    first = conn.recv_bytes()
    k, = struct.unpack_from("<I", first)
    sizes = struct.unpack_from(f"<{k}Q", first, 4)
    bufs = []
    for n in sizes:
        b = np.empty(n, dtype=np.uint8)
        conn.recv_bytes_into(b)
        bufs.append(b)
    return pickle.loads(memoryview(first)[4 + 8 * k:], buffers=bufs)


class _Pipes:
    """Worker 0 in this process; workers 1..n-1 forked, behind pipes.  A
    round sends to the forked workers first, runs worker 0 meanwhile, then
    collects the replies."""

    #: the workers see the coordinator's files (they write their checkpoint partitions)
    shared_files = True

    def __init__(self, n: int):
        self.n = n
        self.conns: list = []
        self.procs: list = []
        self.outstanding = [0] * n
        self.local: Optional[_Worker] = None
        #: the cores this process had before worker 0 was pinned to one (:func:`_pin`)
        self.unpinned: Optional[set] = None
        #: the last rebalanced step's moves: (receiver, the states' numbers)
        self.handed: list = []

    def start(self, model, deadlock: bool, find_all: bool, columns=None,
              fastest: bool = False) -> None:
        ctx = multiprocessing.get_context("fork")
        me = os.getpid()
        for w in range(1, self.n):
            a, b = ctx.Pipe()
            p = ctx.Process(target=_serve, args=(b, model, w, self.n, deadlock, find_all,
                                                 columns, me, [*self.conns, a], fastest),
                            daemon=True)
            p.start()
            b.close()
            self.conns.append(a)
            self.procs.append(p)
        self.local = _Worker(model, 0, self.n, deadlock, find_all, columns, fastest)
        self.local.defer_free = self.n > 1     # freed while waiting for the others
        self.unpinned = _pin(0, self.n)        # (after the fork: the workers pin themselves)

    def stop(self) -> None:
        for c in self.conns:
            try:
                _send(c, ("stop", ()))
            except (OSError, BrokenPipeError):
                pass
            c.close()
        for p in self.procs:
            p.join(timeout=5)
            if p.is_alive():
                p.kill()
                p.join()
        self.conns, self.procs, self.local = [], [], None
        _LITTER.clear()
        if self.unpinned is not None:
            os.sched_setaffinity(0, self.unpinned)
            self.unpinned = None

    def _result(self, w):
        status, value = _recv(self.conns[w - 1])
        self.outstanding[w] -= 1
        if status == "error":
            raise value
        return value

    def all(self, cmd: str, per_worker: list) -> list:
        for w in range(1, self.n):
            _send(self.conns[w - 1], (cmd, per_worker[w]))
            self.outstanding[w] += 1
        mine = getattr(self.local, cmd)(*per_worker[0])
        return [mine] + [self._result(w) for w in range(1, self.n)]

    #: the pipes can move a level's states between workers (:func:`_rebalance`)
    moves_states = True

    def level(self, per_worker: list, size: int = 0, plan=None):
        """One level: the *step* round, then the *decide* round, pipelined:
        an owner's *decide* is sent as soon as the coordinator holds the
        candidates of every other generator for it (``--workers 2``: with
        the message that ends worker 1's step, so it decides straight after
        its step, without waiting for the coordinator to read its reply).

        The step is *balanced* (:meth:`_balance`): the workers expand their
        shares a chunk at a time, and one that runs out of work gets half of
        what another has left, so that a worker slowed down (by another job
        on its core) does not hold the level up.  The moved states' successors
        stay with the worker that expanded them (it holds those admitted),
        so the shares of the next level follow the workers' speeds and
        states move again only when the speeds change.  Results do not depend
        on who expanded what: candidates are ordered by their keys.
        Only a level of at least :data:`_BALANCE_LEVEL` states (``size``) is
        balanced: a request for work waits for the other worker to be
        running, and on a small level that wait costs more than the
        imbalance.  ``PCCL_BALANCE=0`` in the environment expands each share
        where it lies, as before (for comparison).

        Returns (the rest of each step reply, each owner's new keys)."""
        n, local = self.n, self.local
        assert local is not None, "start() first"
        parts: list = [None] * n            # parts[g]: generator g's candidates by owner
        sent = [False] * n
        if plan:
            self._moved_step(per_worker, plan)
            parts[0] = local.finish_step()
        elif n > 1 and _BALANCE and size >= _BALANCE_LEVEL and (
                local.succ_batch is None or (_BALANCE_NATIVE and not getattr(local.m, "stable_ids", False))):
            for w in range(1, n):
                _send(self.conns[w - 1], ("lstep", per_worker[w]))
                self.outstanding[w] += 1
            local.start_level(*per_worker[0])
            self._balance()
            for o in range(1, n):           # every forked worker waits for this
                _send(self.conns[o - 1], ("finish", None))
            parts[0] = local.finish_step()  # meanwhile they finish theirs
        else:
            for w in range(1, n):
                _send(self.conns[w - 1], ("step", per_worker[w]))
                self.outstanding[w] += 1
            parts[0] = local.step(*per_worker[0])
        ready: list = [None] * n            # pickled decide messages not sent yet

        def send_ready():
            for o in range(1, n):
                if sent[o]:
                    continue
                if ready[o] is None and all(parts[g] is not None for g in range(n) if g != o):
                    ready[o] = _dumps(("decide", tuple(
                        None if g == o else parts[g][o] for g in range(n))))
                # Worker o may itself be writing its (large) step reply: a
                # message larger than what the socket buffers could block
                # both writers.  So early only if small, else once o's reply is in.
                if ready[o] is not None and (_size(ready[o]) <= _EARLY or parts[o] is not None):
                    _send_frames(self.conns[o - 1], ready[o])
                    self.outstanding[o] += 1
                    sent[o], ready[o] = True, None
        send_ready()
        for w in range(1, n):
            parts[w] = self._result(w)
            send_ready()
        mine = local.decide(*(parts[g][0] for g in range(n)))
        return [p[n] for p in parts], [mine] + [self._result(o) for o in range(1, n)]

    def _moved_step(self, per_worker: list, plan: list) -> None:
        """A step that first moves states ``plan`` (``[(giver, receiver,
        count)]``, :func:`_rebalance`): each giver hands the last ``count``
        states of its level over (through this process when neither is
        worker 0), then every worker expands its share as in a static step;
        worker 0's is expanded here, the forked workers' replies follow."""
        local = self.local
        assert local is not None
        gives: list = [[] for _ in range(self.n)]
        expects = [0] * self.n
        for g, r, k in plan:
            gives[g].append(k)
            expects[r] += 1
        for w in range(1, self.n):
            if gives[w] or expects[w]:
                assert not (gives[w] and expects[w]), plan
                msg = ("pstep", (per_worker[w], gives[w], expects[w]))
            else:
                msg = ("step", per_worker[w])
            _send(self.conns[w - 1], msg)
            self.outstanding[w] += 1
        decision, at_bound = per_worker[0]
        local.commit(decision)
        self.handed = []                # (receiver, numbers) of the states moved
        for g, r, k in plan:
            if g == 0:
                loot = local.handoff(k)
            else:
                kind, loot = _recv(self.conns[g - 1])
                if kind == "error":
                    self.outstanding[g] -= 1
                    raise loot
                assert kind == "loot", kind
            self.handed.append((r, loot[0]))
            if r == 0:
                local.receive(loot)
            else:
                _send(self.conns[r - 1], ("work", loot))
        local.begin(at_bound)
        local.expand_some(None)

    def _balance(self) -> None:
        """Worker 0's side of a balanced step, in this process
        (:class:`_Balancer`)."""
        assert self.local is not None
        _Balancer(self.local, self.conns, self.outstanding).run()

    def call(self, w: int, cmd: str, *args):
        if w == 0:
            return getattr(self.local, cmd)(*args)
        _send(self.conns[w - 1], (cmd, args))
        self.outstanding[w] += 1
        return self._result(w)

    def drain(self) -> None:
        """After an interrupt: collect the replies still on their way."""
        for w in range(1, self.n):
            while self.outstanding[w] > 0:
                try:
                    self._result(w)
                except Exception:
                    pass


class _Balancer:
    """Worker 0's side of a balanced step (:meth:`_Pipes.level`), in the
    coordinator's process: expand its share a chunk at a time; between
    chunks hand half of what is left to a forked worker that says it is
    ``hungry``; once its own share is done, ask the busy workers for work
    (``steal``, one request at a time) and expand what they hand over, until
    every forked worker is hungry and nothing is left (the other side:
    :func:`_balanced_step`)."""

    def __init__(self, local: "_Worker", conns: list, outstanding: list):
        self.local, self.conns, self.outstanding = local, conns, outstanding
        n = len(conns) + 1
        self.hungry = [True] + [False] * (n - 1)
        self.asked = [False] * n        # a steal request is on its way to worker o
        self.dry = [False] * n          # ... and o had too little to hand over
        self.turn = 0

    def run(self) -> None:
        local, conns = self.local, self.conns
        chunk = _chunk(local)
        while True:
            if local.expand_some(chunk):
                self.pump()
                continue
            self.pump()
            if local.remaining():
                continue
            if all(self.hungry) and not any(self.asked):
                return
            if not any(self.asked):
                self.ask()
            c = _ready(conns)
            self.handle(conns.index(c) + 1, _read(c))

    def handle(self, o: int, msg) -> None:
        kind, value = msg
        if kind == "hungry":
            self.hungry[o] = True
        elif kind == "loot":
            self.asked[o] = False
            if value is None:
                self.dry[o] = True
            else:
                self.local.take(*value)
        elif kind == "error":
            self.outstanding[o] -= 1
            raise value
        else:                   # pragma: no cover - a protocol error
            raise RuntimeError(f"worker {o}: unexpected {kind!r} during a level")

    def pump(self) -> None:
        """Read what has come, and feed the hungry from what I have left."""
        local, conns, hungry = self.local, self.conns, self.hungry
        for o, c in enumerate(conns, 1):
            while c.poll(0):
                self.handle(o, _read(c))
        for o, c in enumerate(conns, 1):
            if hungry[o]:
                loot = local.give(_half(local.remaining()))
                if loot is None:
                    break
                _send(c, ("work", loot))
                hungry[o], self.dry[o] = False, False

    def ask(self) -> None:
        """Ask a busy worker (the next in turn) for half of what it has left."""
        m = len(self.conns)
        for i in range(1, m + 1):
            o = 1 + (self.turn + i) % m
            if not self.hungry[o] and not self.dry[o]:
                _send(self.conns[o - 1], ("steal", None))
                self.asked[o], self.turn = True, o
                return


#: seconds to wait for a Ray head's port to answer before giving up
RAY_CONNECT_TIMEOUT = 10.0


def probe_ray_address(address: str, timeout: float = RAY_CONNECT_TIMEOUT) -> None:
    """Raise :class:`RayUnavailable` unless something accepts a TCP
    connection at ``address`` (``HOST:PORT`` or ``ray://HOST:PORT``; other
    forms, such as ``auto``, are left to Ray).  Without this, ``ray.init``
    keeps retrying an address where nothing listens."""
    import socket
    rest = address[len("ray://"):] if address.startswith("ray://") else address
    host, sep, port = rest.rpartition(":")
    if not sep or not port.isdigit() or not host:
        return
    host = host.strip("[]")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as exc:
        why = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise RayUnavailable(
            f"{{ray={address}}}: nothing answers at {host}:{port} ({why}); start the head "
            f"there with `ray start --head --port {port}`, or use {{ray=local}}") from None


class RayUnavailable(RuntimeError):
    """Ray is not installed, or cannot be started or reached (the front
    ends turn this into their own error message)."""


def import_ray():
    """The ``ray`` module, or :class:`RayUnavailable` saying how to install it."""
    try:
        import ray
    except ImportError:
        raise RayUnavailable(RAY_MISSING) from None
    return ray


class RayWorkerLost(RayUnavailable):
    """A Ray actor (a worker) died, or its node did, during the search: its
    partition of the visited states is gone, so the search cannot go on and
    has no verdict.  The message names the worker, its node and Ray's reason
    (the front ends report it with exit status 2, as Ray's other failures)."""


class _RayWorker(_Worker):
    """A worker as a Ray actor: :meth:`ready` also says where it runs."""

    def ready(self):
        super().ready()
        import ray
        return (self.wid, ray.get_runtime_context().get_node_id(),
                ray.util.get_node_ip_address(), os.getpid())


#: seconds between two looks at the cluster (are the actors' nodes alive?)
#: while a round waits for the actors' replies
RAY_POLL = 5.0


def _env_seconds(name: str, default: float) -> float:
    """A number of seconds from the environment (``default`` when unset)."""
    text = os.environ.get(name)
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value > 0 or value == float("inf"):
        raise RayUnavailable(f"{name}={text}: expected a number of seconds above 0")
    return value


#: The prefix of the module names a blackbox loaded from a ``.py`` file gets
#: (``pccl.blackboxes._import``): no other process can import them by name.
_FILE_MODULE_PREFIX = "_pccl_user_blackbox_"


def _pickle_user_code_by_value(ray) -> None:
    """A user blackbox loaded from a file (``--blackbox FILE.py:ATTR``)
    lives in a module the actors cannot import: its classes and functions
    go to them by value (cloudpickle), not as a reference to that module
    (oracle finding R1: the actors died, "worker 0 of 2 was lost")."""
    import sys
    for name, module in list(sys.modules.items()):
        if name.startswith(_FILE_MODULE_PREFIX):
            ray.cloudpickle.register_pickle_by_value(module)


class _RayTransport:
    """One Ray actor per partition.  ``address``: ``"local"`` starts a Ray
    instance on this machine (stopped again after the search); anything
    else is passed to ``ray.init(address=...)`` (``"auto"``, ``HOST:PORT``,
    ``ray://HOST:PORT``).  If this process is already connected to Ray
    (``ray.is_initialized()``), that connection is used and left open.

    The actors are spread over the cluster's nodes (``SPREAD``); each says
    where it runs (:attr:`placement`, in the result's notes).  An actor that
    dies, or whose node does, stops the search with :class:`RayWorkerLost`
    naming it: Ray reports the death to a waiting call, and while a round
    waits the transport also looks every :data:`RAY_POLL` seconds whether
    the actors' nodes are still alive, so a lost node never leaves the
    search waiting.  Actors that cannot be placed (a cluster without room)
    fail after ``PCCL_RAY_START_TIMEOUT`` seconds (default 300)."""

    #: actors may run on machines that do not see the coordinator's files:
    #: their checkpoint partitions travel to the coordinator, which writes them
    shared_files = False

    def __init__(self, n: Optional[int], address: str):
        self.n: Any = n                # None until start(): one per CPU of the cluster
        self.address = address
        self.actors: list = []
        self.actor_ids: dict = {}      # actor id (hex) -> worker number
        self.placement: list = []      # per worker: (node id, node address, pid)
        self.owned = False
        self.ray = import_ray()

    @staticmethod
    def connect(ray, address: str, cpus: int) -> bool:
        """Connect to Ray; True when this call started (and must stop) it."""
        import logging
        if ray.is_initialized():
            return False
        quiet = dict(include_dashboard=False, logging_level=logging.WARNING,
                     log_to_driver=False, configure_logging=True)
        if address != "local":
            probe_ray_address(address)      # ray.init retries an address that never answers
        try:
            if address == "local":
                ray.init(num_cpus=cpus, **quiet)
            else:
                ray.init(address=address, **quiet)
        except Exception as exc:
            hint = ""
            if address != "local" and "RAY_AUTH_MODE" not in os.environ:
                hint = ("; if the cluster uses token authentication (recent Ray turns it on "
                        "for a new head), set RAY_AUTH_MODE=token and RAY_AUTH_TOKEN to the "
                        "head's token (its ~/.ray/auth_token)")
            raise RayUnavailable(f"{{ray={address}}}: cannot start or reach Ray: {exc}{hint}") from None
        return True

    def start(self, model, deadlock: bool, find_all: bool, columns=None,
              fastest: bool = False) -> None:
        ray = self.ray
        limit = _env_seconds("PCCL_RAY_START_TIMEOUT", 300.0)
        self.owned = self.connect(ray, self.address, self.n or available_workers())
        cpus = ray.cluster_resources().get("CPU", 0)
        if self.n is None:          # workers="auto": one per CPU of the cluster
            self.n = max(1, int(cpus))
        per = 1 if cpus >= self.n else max(0.01, cpus / self.n)
        actor = ray.remote(num_cpus=per, scheduling_strategy="SPREAD")(_RayWorker)
        _pickle_user_code_by_value(ray)
        ref = ray.put(model)
        self.actors = [actor.remote(ref, w, self.n, deadlock, find_all, columns, fastest)
                       for w in range(self.n)]
        self.actor_ids = {a._actor_id.hex(): w for w, a in enumerate(self.actors)}
        refs = [a.ready.remote() for a in self.actors]
        _, pending = ray.wait(refs, num_returns=len(refs), timeout=limit)
        if pending:
            waiting = [w for w, r in enumerate(refs) if r in pending]
            raise RayUnavailable(
                f"{{ray={self.address}}}: {len(waiting)} of the {self.n} actors (worker"
                f"{'s' if len(waiting) > 1 else ''} {', '.join(map(str, waiting))}) did not "
                f"start within {limit:g} s (the cluster has {cpus:g} CPUs); give fewer "
                f"{{workers}} or add nodes (PCCL_RAY_START_TIMEOUT=SECONDS waits longer)")
        self.placement = [tuple(r[1:]) for r in self._get(refs)]

    def placement_note(self) -> str:
        """Where the actors ran, for the result's notes: ``Ray: 2 actors on
        2 nodes: worker 0 on node 1a2b3c4d (10.0.0.1, pid 123); ...``."""
        k, nodes = len(self.placement), len({p[0] for p in self.placement})
        where = "; ".join(f"worker {w} on node {node[:8]} ({ip}, pid {pid})"
                          for w, (node, ip, pid) in enumerate(self.placement))
        return (f"Ray: {k} actor{'s' if k != 1 else ''} on {nodes} "
                f"node{'s' if nodes != 1 else ''}: {where}")

    def _who(self, w: int) -> str:
        if w < len(self.placement):
            node, ip, pid = self.placement[w]
            return f"worker {w} of {self.n} (the Ray actor on node {node[:8]} at {ip}, pid {pid})"
        return f"worker {w} of {self.n}"

    def _lost(self, exc: BaseException, workers=()) -> "RayWorkerLost":
        """The error for a lost actor: which one (from Ray's error, or the
        nodes the cluster reports dead), and Ray's reason."""
        w = self.actor_ids.get(getattr(exc, "actor_id", None) or "")
        lost = [w] if w is not None else list(workers) or self._on_dead_nodes()
        who = " and ".join(self._who(v) for v in lost) if lost else "a worker (a Ray actor)"
        reason = " ".join(str(exc).split())
        if len(reason) > 300:
            reason = reason[:300] + "…"
        return RayWorkerLost(
            f"{{ray={self.address}}}: {who} was lost during the search ({type(exc).__name__}: "
            f"{reason}). Its part of the visited states is gone: the search stops without a "
            f"verdict; resume it from its last checkpoint with {{resume=DIR}} if it ran with "
            f"{{checkpoint=DIR}}, else start it again")

    def _on_dead_nodes(self) -> list:
        """The workers whose node the cluster reports dead (none if the
        cluster cannot be asked)."""
        try:
            dead = {n["NodeID"] for n in self.ray.nodes() if not n.get("Alive", True)}
        except Exception:
            return []
        return [w for w, p in enumerate(self.placement) if p[0] in dead]

    def _get(self, refs):
        ray = self.ray
        errors = ray.exceptions
        lost_kinds = (errors.RayActorError, errors.ObjectLostError, errors.NodeDiedError,
                      errors.WorkerCrashedError)
        while True:
            try:
                return ray.get(refs, timeout=RAY_POLL)
            except errors.GetTimeoutError:
                lost = self._on_dead_nodes()
                if lost:
                    raise self._lost(errors.NodeDiedError(
                        "the cluster reports the node dead"), lost) from None
            except errors.RayTaskError as exc:
                cause = getattr(exc, "cause", None)
                if isinstance(cause, lost_kinds):       # an input from a lost actor
                    raise self._lost(cause) from None
                if isinstance(cause, Exception):    # as the pipes transport: the worker's own error
                    raise cause from None
                raise
            except lost_kinds as exc:
                raise self._lost(exc) from None

    def all(self, cmd: str, per_worker: list) -> list:
        return self._get([getattr(a, cmd).remote(*args)
                          for a, args in zip(self.actors, per_worker)])

    def level(self, per_worker: list, size: int = 0):
        """One level: the *step* round, then the *decide* round.  Only the
        small part of each step reply comes to the coordinator; the
        candidates stay in the object store as references, which the
        *decide* calls pass to their owners (Ray moves them actor to actor,
        and starts an owner's *decide* once its inputs exist)."""
        n = self.n
        refs = [a.step.options(num_returns=n + 1).remote(*args)
                for a, args in zip(self.actors, per_worker)]
        decided = [a.decide.remote(*(refs[g][o] for g in range(n)))
                   for o, a in enumerate(self.actors)]
        return self._get([r[n] for r in refs]), self._get(decided)

    def call(self, w: int, cmd: str, *args):
        return self._get(getattr(self.actors[w], cmd).remote(*args))

    def drain(self) -> None:
        pass            # the actors are killed by stop()

    def stop(self) -> None:
        ray = self.ray
        for a in self.actors:
            try:
                ray.kill(a)
            except Exception:
                pass
        self.actors = []
        if self.owned:
            ray.shutdown()
            self.owned = False


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
