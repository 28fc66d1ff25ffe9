"""The partitions of a parallel search (:mod:`pccl.search.parallel`): a
:class:`_Worker` holds one partition of the visited fingerprints and the
states it generated, and answers the level protocol's calls (``step``,
``decide``, ``commit``, the balancing hand-overs, the graph for the checks,
spilling, checkpoints).  Engine- and transport-neutral: the transports
(:mod:`pccl.search.parallel_pipes`, :mod:`pccl.search.parallel_ray`) call
these methods in a process of their own.  Also the partitioning helpers
(owners by fingerprint, :func:`_rebalance`)."""

from __future__ import annotations

import gc
import itertools
import marshal
import operator
import os
from typing import Any, Optional

import numpy as np
import xxhash

from pccl.search.explorer import (FingerprintTable, max_time,
                                  peak_rss_bytes, terminal, violations_of)


_SHIFT = 24                     # successors per state < 2**24
_NONE = 0xFFFF_FFFF


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
