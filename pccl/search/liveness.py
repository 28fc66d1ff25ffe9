"""Temporal properties over the stored state graph (spec section 9).

The breadth-first search (:class:`pccl.search.explorer.Explorer`) stays as it is;
when a temporal property or the time-lock check asks for it, a
:class:`GraphRecorder` rides along and keeps, in numpy arrays,

* per transition: source and target state numbers (``uint32`` each: 8 bytes
  per transition);
* per state: whether it is a *dynamic* state (the phase after TIME ADVANCE:
  an edge into a dynamic state is exactly a TIME ADVANCE, 1 byte), and only
  when there are temporal properties a bit per predicate P, Q (``uint64``:
  8 bytes) and, under ``nondet``, the agents whose ``doReach`` is still
  under way (``uint64``, fair arrival).

After the search everything is decided on these arrays, vectorised where it
can be (breadth-first frontiers over CSR arrays), with an iterative Tarjan
only over the part of the graph a liveness property can use:

time-lock
    states from which no dynamic state and no terminal state can be reached
    (backward reachability over the reversed edges): from them time never
    advances again, and some agent has not exited.  Zero-time cycles that
    can be left reach a dynamic or terminal state, so they are not locks.
``eventually P`` / ``P ~> Q``
    a start state (an initial state, resp. a reachable state where P holds)
    where Q (resp. P) is false, from which the states where it stays false
    lead either to a terminal state or to a *fair accepting* cycle: a
    strongly connected component of those states that contains a TIME
    ADVANCE (zero-time cycles are time-locks, not liveness counterexamples)
    and, for every agent, a state where that agent is not waiting for
    ``nondet`` to let it arrive (fair arrival).  A component passes that
    test exactly when it contains a fair cycle (walk it all).
``P ~> Q within T``
    a breadth-first search over (state, monitor clock) pairs, the clock
    counting the time steps since the oldest P that Q has not answered yet
    (0..T/δ); a larger clock dominates a smaller one, so each state keeps
    only the largest clock it was reached with.  Exact in real time: the
    clock is part of the searched state, so time abstraction stays sound.
``reachable P``
    the first state in breadth-first order where P holds (a shortest
    witness), from the per-state bits.
"""

from __future__ import annotations

import itertools
import operator
from dataclasses import dataclass, field
from typing import Any, Optional
from collections.abc import Callable

import numpy as np

from pccl.search.explorer import Counterexample
from pccl.search.scc import tarjan

__all__ = ["GraphRecorder", "analyse", "LivenessResult"]

_CHUNK = 1 << 16


class _Grow:
    """A growable 1-D numpy array.  Like the explorer's visited table it
    lives in a reserved, lazily committed mapping (only the pages written
    count, and it never grows by copying); where that is not available it
    grows by doubling."""

    def __init__(self, dtype, cap: Optional[int] = None):
        from pccl.search.explorer import _reserve, physical_memory
        a = None
        if cap is None:
            cap = max(_CHUNK, physical_memory() // np.dtype(dtype).itemsize)
            a = _reserve((cap,), dtype)
        self.a = a if a is not None else np.empty(_CHUNK, dtype=dtype)
        self.n = 0

    def extend(self, x: np.ndarray) -> None:
        k = len(x)
        self.reserve(self.n + k)
        self.a[self.n:self.n + k] = x
        self.n += k

    def view(self) -> np.ndarray:
        return self.a[:self.n]

    def reserve(self, cap: int) -> None:
        """Room for ``cap`` items in :attr:`a` (by doubling)."""
        if cap > len(self.a):
            b = np.empty(max(cap, 2 * len(self.a)), dtype=self.a.dtype)
            b[:self.n] = self.a[:self.n]
            self.a = b

    def adopt(self, x: np.ndarray) -> None:
        """Hold ``x`` (of my dtype) as my whole content, without a copy."""
        assert x.dtype == self.a.dtype and x.ndim == 1
        self.a, self.n = x, len(x)


class StateColumns:
    """The per-state part of the graph, as a pure function of the states:
    ``columns(states)`` returns one array per recorded column (dynamic or
    not; the property bits, with temporal properties; the pending
    doReach agents, under fair arrival).  Small and picklable (the
    properties' closures travel as the model does), so that the workers of
    the parallel search compute the columns of the states they hold.

    What it reads of a state comes from the model (no configuration layout
    here): ``time_costs(states)`` (1 into a dynamic state), and, under fair
    arrival, ``pending(state)``, the bit mask of agents whose doReach is
    under way (:meth:`pccl.model.engine.Model.arrival_pending`)."""

    def __init__(self, props=(), fairness: bool = False, sig_of=None, *,
                 time_costs=None, pending=None, sigs_of=None, native=None):
        self.props = list(props)
        #: the native engine's columns of the temporal properties, or None
        #: (pccl/search/native_liveness.py: one C call per batch)
        self.native = native if self.props else None
        self.fairness = fairness
        self.time_costs = time_costs
        self.pending = pending
        #: the stall check's signature hash (pccl/model/stall.py), or None
        self.sig_of = sig_of
        #: the same for a list of states at once (an int64 array), when the
        #: model has it (the native engine's one C call)
        self.sigs_of = sigs_of if sig_of is not None else None

    def signatures(self, states) -> np.ndarray:
        """:attr:`sig_of` of each of ``states`` (a list), as int64s."""
        if self.sigs_of is not None and type(states) is list:
            return self.sigs_of(states)
        return np.fromiter(map(self.sig_of, states), dtype=np.int64, count=len(states))

    def dtypes(self) -> list:
        return [np.uint8] + ([np.uint64] if self.props else []) + \
            ([np.uint64] if self.fairness else []) + ([np.int64] if self.sig_of else [])

    def changed(self, st, succ_states) -> bool:
        """Does some transition out of ``st`` (to the actual successor
        states, before any renaming) change the stall signature?"""
        sig = self.sig_of
        here = sig(st)
        return any(sig(t) != here for t in succ_states)

    def __call__(self, states: list, sigs: Optional[np.ndarray] = None) -> list:
        """The columns of ``states`` (``sigs``: their stall signatures, when
        already computed)."""
        n = len(states)
        cols: list = [np.fromiter(self.time_costs(states), dtype=np.uint8, count=n)]
        if self.native is not None:
            bits, pend = self.native(states)
            cols.append(bits)
            if self.fairness:
                cols.append(pend)
        elif self.props:
            vals = np.zeros(n, dtype=np.uint64)
            for k, p in enumerate(self.props):
                for fn, b in ((p.p, 2 * k), (p.q, 2 * k + 1)):
                    if fn is None:
                        continue
                    col = np.fromiter((_holds(fn, s) for s in states), dtype=bool, count=n)
                    vals |= col.astype(np.uint64) << np.uint64(b)
            cols.append(vals)
        if self.fairness and self.native is None:
            cols.append(np.fromiter(map(self.pending, states), dtype=np.uint64, count=n))
        if self.sig_of is not None:
            cols.append(self.signatures(states) if sigs is None else sigs)
        return cols


class GraphRecorder:
    """Collects the state graph during a search (see the module docstring)."""

    def __init__(self, model, props=(), fairness: bool = False, stall: bool = False,
                 frozen: Optional[Callable] = None):
        self.model = model
        self.props = list(props)
        if 2 * len(self.props) > 64:
            raise ValueError("at most 32 temporal properties at a time")
        self.fairness = fairness and model.N <= 64
        sig_of = None
        if stall:
            sig_of = model.stall_signature()
        #: the per-state columns (the parallel search runs it in its workers)
        self.columns = StateColumns(self.props, self.fairness, sig_of,
                                    time_costs=model.time_costs,
                                    pending=model.arrival_pending if self.fairness else None,
                                    sigs_of=getattr(model, "stall_signatures", None),
                                    native=getattr(model, "temporal_columns", None))
        self.src = _Grow(np.uint32)
        self.dst = _Grow(np.uint32)
        self.dyn = _Grow(np.uint8)
        self.bits = _Grow(np.uint64) if self.props else None
        self.pend = _Grow(np.uint64) if self.fairness else None
        self.complete = True
        # the stall check (pccl/model/stall.py): per state its signature's hash and
        # whether some transition out of it changes the signature
        self.sig_of: Any = None
        self.sig: Optional[_Grow] = None
        self.chg: Optional[_Grow] = None
        #: edges() wants the successor states themselves: under symmetry a
        #: state number stands for a renamed state (under dead, where a
        #: robot's reach can be masked, one whose target and flags, which
        #: the signature holds, may differ), so a transition's change is
        #: decided on the actual successor
        self.wants_candidates = False
        #: the parallel search computes the changes in its workers
        #: (:meth:`put_changes`), not from the edges
        self.changes_given = False
        if stall:
            self.sig_of = sig_of
            self.sig = _Grow(np.int64)
            self.chg = _Grow(np.uint8)
            red = getattr(model, "reduction", None)
            self.wants_candidates = ("symmetry" in getattr(red, "on", ())
                                     or getattr(getattr(model, "dead_vars", None), "reach_masked", False))
        #: the frozen-team check's part (pccl/model/frozen.py, :class:`FrozenColumns`:
        #: ``frozen`` computes the progress signatures), with the stall check
        #: only; None: not recorded
        self.frozen: Optional[FrozenColumns] = (FrozenColumns(model, frozen)
                                                if frozen is not None and stall else None)

    def _grows(self) -> list:
        return [g for g in (self.dyn, self.bits, self.pend, self.sig) if g is not None]

    def put_changes(self, n: int, idx: list, flags: list) -> None:
        """The stall check's per-state "some transition changes the team"
        flags, computed where the states were expanded (the workers)."""
        if self.frozen is not None:         # (the workers record no events)
            self.frozen.whole = False
        if self.chg is None:
            return
        full = np.zeros(n, dtype=np.uint8)
        for ix, fl in zip(idx, flags):
            full[ix] = fl
        self.chg.adopt(full)

    # -- called by the explorer -------------------------------------------------
    def states(self, states: list, sigs: Optional[np.ndarray] = None) -> None:
        """The states just admitted, in state-number order (``sigs``: their
        stall signatures, when the model computed them with the fingerprints)."""
        for grow, col in zip(self._grows(), self.columns(states, sigs)):
            grow.extend(col)
        if self.chg is not None:
            self.chg.extend(np.zeros(len(states), dtype=np.uint8))
        if self.frozen is not None:
            self.frozen.states(states)

    def put_states(self, n: int, idx: list, cols: list) -> None:
        """The columns of all ``n`` states at once, in any order: ``idx[j]``
        the state numbers whose columns are ``cols[j]`` (the parallel search:
        one part per worker).  A state no part names stays 0."""
        if self.frozen is not None:         # (the workers record no events)
            self.frozen.whole = False
        for c, (grow, dtype) in enumerate(zip(self._grows(), self.columns.dtypes())):
            full = np.zeros(n, dtype=dtype)
            for ix, cs in zip(idx, cols):
                full[ix] = cs[c]
            grow.adopt(full)        # (extend() copied it once more)

    def edges(self, src: np.ndarray, dst: np.ndarray, cands: Optional[list] = None,
              to_sigs: Optional[np.ndarray] = None, labs: Optional[list] = None) -> None:
        """Transitions by state number (``dst`` -1: a successor not admitted);
        ``cands``: the successor states, when :attr:`wants_candidates`, or
        ``to_sigs``: their stall signatures; ``labs``: their labels (label
        numbers on the native engine), for the frozen-team check."""
        ok = (dst >= 0) & (src >= 0)
        if not ok.all():
            if (dst < 0).any():
                self.complete = False
            src, dst = src[ok], dst[ok]
            if to_sigs is not None:
                to_sigs = to_sigs[ok]
            if cands is not None:
                cands = list(itertools.compress(cands, ok.tolist()))
            if labs is not None:
                labs = list(itertools.compress(labs, ok.tolist()))
        if self.frozen is not None:
            self.frozen.edges(src, dst, labs, cands if self.wants_candidates else None,
                              self.wants_candidates)
        if self.sig is not None and self.chg is not None and len(src) and not self.changes_given:
            sig = self.sig.view()
            if self.wants_candidates and to_sigs is not None:
                to = to_sigs
            elif self.wants_candidates:
                assert cands is not None, "the recorder needs the successor states"
                to = self.columns.signatures(cands)
            else:
                to = sig[dst]
            changed = to != sig[src]
            if changed.any():
                self.chg.view()[src[changed]] = 1
        self.src.extend(src.astype(np.uint32))
        self.dst.extend(dst.astype(np.uint32))

    # -- the native level kernel (pccl/model/native.py explore_levels) -------------------
    @property
    def kernel_ready(self) -> bool:
        """Whether the level kernel can record this graph: the time-lock and
        stall checks' columns, and temporal properties (with fair arrival)
        only when the model makes their columns in C (the native engine:
        :meth:`kernel_columns`), the changes computed here."""
        return (not self.props or self.columns.native is not None) and not self.changes_given

    def kernel_arrays(self, limit: int) -> tuple:
        """The arrays the kernel writes the graph into (its ``rec``
        argument): the transitions' sources and targets with the count so
        far, the time costs and, with the stall check, the signatures, the
        change flags and whether changes are decided on the successors as
        made.  The state columns have room for states numbered below
        ``limit``."""
        for g in self._columns().values():
            g.reserve(limit)
        cap = min(len(self.src.a), len(self.dst.a))
        fz = self.frozen
        if fz is not None:
            fz.lab.reserve(len(self.src.a))
            cap = min(cap, len(fz.lab.a))
        out: tuple = (self.src.a[:cap], self.dst.a[:cap], self.src.n, self.dyn.a)
        if self.sig is not None and self.chg is not None:
            out += (self.sig.a, self.chg.a, int(self.wants_candidates))
            if fz is not None:
                out += (fz.lab.a[:cap], fz.psig.a, fz.pchg.a)
        return out

    def kernel_columns(self) -> Optional[tuple]:
        """The temporal columns' arrays the kernel writes (its ``tcol``
        argument: the P/Q bits and, under fair arrival, the robots under
        way), or None without temporal properties; :meth:`kernel_arrays`
        made their room."""
        if self.bits is None:
            return None
        return (self.bits.a,) + ((self.pend.a,) if self.pend is not None else ())

    def kernel_admitted(self, states: int, edges: int) -> None:
        """The kernel wrote ``states`` more states' columns and the
        transitions up to ``edges``."""
        self.src.n = self.dst.n = edges
        if self.frozen is not None:
            self.frozen.lab.n = edges
        for g in self._columns().values():
            g.n += states

    def kernel_edges_full(self) -> None:
        """The kernel filled the transition arrays (it stopped, why 5):
        twice the room."""
        self.src.reserve(2 * len(self.src.a))
        self.dst.reserve(2 * len(self.dst.a))
        if self.frozen is not None:
            self.frozen.lab.reserve(2 * len(self.frozen.lab.a))

    # -- checkpoints (pccl/search/checkpoint.py) -------------------------------------------
    def _columns(self) -> dict:
        fz = self.frozen
        return {name: g for name, g in (("dyn", self.dyn), ("bits", self.bits),
                                        ("pend", self.pend), ("sig", self.sig),
                                        ("chg", self.chg),
                                        ("psig", None if fz is None else fz.psig),
                                        ("pchg", None if fz is None else fz.pchg)) if g is not None}

    def dump(self, n: int, edges: int) -> dict:
        """The graph as it stood when a level was about to be expanded: ``n``
        states, ``edges`` transitions.  (The stall check's change flags a
        partial expansion of that level set are kept: the resumed search
        expands the level again and sets exactly those.)"""
        out = {"src": self.src.view()[:edges], "dst": self.dst.view()[:edges]}
        if self.frozen is not None:
            out["lab"] = self.frozen.lab.view()[:edges]
        for name, g in self._columns().items():
            out[name] = g.view()[:n]
        return out

    def load(self, arrays: dict, complete: bool) -> None:
        """Fill an empty recorder from :meth:`dump`'s arrays."""
        want = {"src", "dst", *self._columns()} | ({"lab"} if self.frozen is not None else set())
        if set(arrays) != want:
            raise ValueError(f"the recorded graph holds {', '.join(sorted(arrays)) or 'nothing'}, "
                             f"this search records {', '.join(sorted(want))}")
        self.src.extend(arrays["src"])
        self.dst.extend(arrays["dst"])
        if self.frozen is not None:
            self.frozen.lab.extend(arrays["lab"])
        for name, g in self._columns().items():
            if arrays[name].dtype != g.a.dtype:
                raise ValueError(f"the recorded column {name} has the wrong type")
            g.extend(arrays[name])
        self.complete = bool(complete)

    # -- the graph ---------------------------------------------------------------
    def freeze(self, n: int) -> "Graph":
        """The graph in CSR form (no copy when the edges came by source, as
        the breadth-first search records them)."""
        src, dst = self.src.view(), self.dst.view()
        last = len(src) - 1
        if not all(bool((src[a + 1:min(a + _EDGE_CHUNK, last) + 1]
                         >= src[a:min(a + _EDGE_CHUNK, last)]).all())
                   for a in range(0, max(0, last), _EDGE_CHUNK)):
            order = np.argsort(src, kind="stable")
            src, dst = src[order], dst[order]
            del order
        return Graph(n, None, dst, src, self.dyn.view()[:n].astype(bool),
                     None if self.bits is None else self.bits.view()[:n],
                     None if self.pend is None else self.pend.view()[:n])


class FrozenColumns:
    """What the frozen-team check (pccl/model/frozen.py) reads of the
    search's graph, recorded with it: per transition its label's number
    (:attr:`lab`, into :meth:`label_list`), per state its progress
    signature (:attr:`psig`) and whether some transition out of it changes
    that signature (:attr:`pchg`, decided as the stall check's change
    flags are: on the successor as made where a state number stands for
    renamed or masked states).  :attr:`whole` turns False when some part
    of the graph came without them (the parallel search's workers): the
    check then explores again."""

    def __init__(self, model, sigs: Callable):
        self.lab = _Grow(np.int32)
        self.psig = _Grow(np.int64)
        self.pchg = _Grow(np.uint8)
        self.whole = True
        #: the native engine numbers its labels itself (its label list);
        #: the Python engine's labels are numbered here
        self.native = getattr(model, "label_list", None)
        self._ids: dict = {}
        self._labels: list = []
        #: ``sigs(states) -> int64 array``: the progress signatures (the model's)
        self._sigs = sigs

    def label_list(self) -> list:
        """The labels, by number."""
        return list(self.native) if self.native is not None else self._labels

    def _numbers(self, labs: list) -> np.ndarray:
        if self.native is not None:
            return np.asarray(labs, dtype=np.int32)
        ids, out = self._ids, []
        for lab in labs:
            k = ids.get(lab)
            if k is None:
                k = ids[lab] = len(self._labels)
                self._labels.append(lab)
            out.append(k)
        return np.asarray(out, dtype=np.int32)

    def states(self, states: list) -> None:
        self.psig.extend(self._sigs(states) if len(states) else np.zeros(0, dtype=np.int64))
        self.pchg.extend(np.zeros(len(states), dtype=np.uint8))

    def edges(self, src: np.ndarray, dst: np.ndarray, labs: Optional[list],
              cands: Optional[list], by_candidates: bool) -> None:
        """Transitions (:meth:`GraphRecorder.edges`'s, admitted ones only),
        their labels and, where :attr:`GraphRecorder.wants_candidates`
        (``by_candidates``), the successor states as made."""
        if not len(src):
            return
        if labs is None or len(labs) != len(src) or (by_candidates and cands is None):
            self.whole = False          # a transition without its label
            self.lab.extend(np.full(len(src), -1, dtype=np.int32))
            return
        self.lab.extend(self._numbers(labs))
        psig = self.psig.view()
        to = self._sigs(cands) if cands is not None else psig[dst]
        changed = to != psig[src]
        if changed.any():
            self.pchg.view()[src[changed]] = 1


def _holds(fn, st) -> bool:
    try:
        return bool(fn(st))
    except Exception:        # a runtime error in a property: it does not hold
        return False


class Graph:
    """The recorded graph in CSR form (forward, and reversed on demand)."""

    def __init__(self, n, fptr, fdst, esrc, dyn, bits, pend):
        self.n = n
        self._fptr, self.fdst = fptr, fdst
        self.esrc = esrc                  # the source of each edge, aligned with fdst
        self._rev = None
        #: the model's backward reachability in C (the native engine's
        #: ``reach_back``), or None: :meth:`can_reach` in numpy alone
        self.kernel: Optional[Callable] = None
        self.dyn = dyn
        self.bits = bits
        self.pend = pend
        self.terminal = np.ones(n, dtype=bool)
        _mark(self.terminal, esrc, False)

    @property
    def fptr(self) -> np.ndarray:
        """Forward CSR offsets (4 bytes per state while the edges fit in 32
        bits, else 8), built on first use: the time-lock and stall checks
        alone do not need them."""
        if self._fptr is None:
            self._fptr = _offsets(self.n, self.esrc)
        return self._fptr

    def bit(self, b: int) -> np.ndarray:
        return ((self.bits >> np.uint64(b)) & np.uint64(1)).astype(bool)

    def rev(self):
        """The reversed CSR arrays, built on first use (:func:`_reverse`: 4
        bytes per transition and 4 or 8 per state kept, a bounded chunk
        while it runs)."""
        if self._rev is None:
            self._rev = _reverse(self.n, self.esrc, self.fdst)
        return self._rev

    def can_reach(self, goal: np.ndarray, rounds: int = 64) -> np.ndarray:
        """The states from which some state of ``goal`` can be reached.  A few
        vectorised relaxation rounds over the edge arrays, a chunk of edges
        at a time (no reversed graph: about 3 bytes per transition of a
        chunk while it runs) settle it when every state is close to the
        goal, as within a time step; otherwise the rest is a backward
        search over the reversed graph of the transitions whose source is
        not settled yet (usually few, reversed as sorted keys: nothing per
        state; the reversed graph of all of them only when they are more
        than a quarter).  The same set either way."""
        can = goal.copy()
        src, dst = self.esrc, self.fdst
        m = len(src)
        if self.kernel is not None and src.dtype == np.uint32 and dst.dtype == np.uint32 \
                and can.dtype == np.bool_ and self.kernel(src, dst, can.view(np.uint8), rounds) >= 0:
            return can      # settled in C (else can holds part of it: go on from there)
        for _ in range(rounds):
            moved = False
            for a in range(0, m, _EDGE_CHUNK):
                s, d = src[a:a + _EDGE_CHUNK], dst[a:a + _EDGE_CHUNK]
                hit = can[d]
                hit &= ~can[s]
                if hit.any():
                    can[s[hit]] = True
                    moved = True
            if not moved:
                return can
        # the transitions out of states not settled: only they can add any
        left = 0
        for a in range(0, m, _EDGE_CHUNK):
            left += int(np.count_nonzero(~can[src[a:a + _EDGE_CHUNK]]))
        if 4 * left > m:
            ptr, tgt = self.rev()
            _bfs(lambda f: Graph._gather(ptr, tgt, f)[0], can, _mask_chunks(can), None)
            return can
        keys, tgt = _unsettled_reverse(src, dst, can, left)
        entry = keys[can[keys]]         # settled states with a transition in from the rest
        _bfs(lambda f: _gather_sorted(keys, tgt, f), can, [np.unique(entry).astype(np.int64)], None)
        return can

    def succ(self, v: int) -> np.ndarray:
        return self.fdst[self.fptr[v]:self.fptr[v + 1]]

    @staticmethod
    def _gather(ptr, targets, frontier):
        starts = ptr[frontier].astype(np.int64)
        counts = ptr[frontier + 1].astype(np.int64) - starts
        total = int(counts.sum())
        if not total:
            return np.empty(0, dtype=np.int64), counts
        offs = np.repeat(starts - np.cumsum(counts) + counts, counts) + np.arange(total)
        return targets[offs].astype(np.int64), counts

    def reach(self, seeds: np.ndarray, allowed: Optional[np.ndarray] = None, *,
              backward: bool = False) -> np.ndarray:
        """States reachable from ``seeds`` (forward, or backward: that can
        reach them) through ``allowed`` states only."""
        ptr, tgt = self.rev() if backward else (self.fptr, self.fdst)
        seen = np.zeros(self.n, dtype=bool)
        seeds = np.asarray(seeds, dtype=np.int64)
        if allowed is not None:
            seeds = seeds[allowed[seeds]]
        seen[seeds] = True
        _bfs(lambda f: self._gather(ptr, tgt, f)[0], seen, [np.unique(seeds)], allowed)
        return seen

    def path(self, start: int, goal: np.ndarray, allowed: np.ndarray) -> list:
        """A shortest path ``[start, ..., g]`` through ``allowed`` states to a
        state of ``goal`` (boolean mask); ``start`` itself counts."""
        if goal[start]:
            return [start]
        parent = {start: -1}
        frontier = [start]
        while frontier:
            nxt = []
            for v in frontier:
                for w in self.succ(v).tolist():
                    if w in parent or not allowed[w]:
                        continue
                    parent[w] = v
                    if goal[w]:
                        out = [w]
                        while parent[out[-1]] != -1:
                            out.append(parent[out[-1]])
                        return out[::-1]
                    nxt.append(w)
            frontier = nxt
        return []

    def sccs(self, nodes: np.ndarray, allowed: np.ndarray) -> tuple:
        """Strongly connected components of the subgraph induced by
        ``allowed``, for the states ``nodes`` (iterative Tarjan,
        :func:`pccl.search.scc.tarjan`).  Returns ``(comp, nontrivial)``:
        the component id per state (-1 outside) and per component whether
        it has a cycle."""
        return tarjan(self.n, nodes.tolist(), self.succ, allowed)

    def cycle_through(self, c: int, comp: np.ndarray, musts: list) -> list:
        """A cycle ``[c, ..., c]`` inside c's component visiting, in order, a
        state of each mask in ``musts``."""
        inside = comp == comp[c]
        out = [c]
        cur = c
        for mask in musts:
            goal = mask & inside
            if goal[cur]:
                continue
            p = self.path(cur, goal, inside)
            out.extend(p[1:])
            cur = out[-1]
        # back to c: a path of at least one step
        best = None
        for w in self.succ(cur).tolist():
            if not inside[w]:
                continue
            goal = np.zeros(self.n, dtype=bool)
            goal[c] = True
            p = self.path(w, goal, inside)
            if p and (best is None or len(p) < len(best)):
                best = p
        out.extend(best or [])
        return out


#: transitions handled at once by the graph analysis's vectorised steps (the
#: relaxation rounds, the reversed graph's construction): their temporary
#: arrays are a few bytes per transition of a chunk, not of the graph
_EDGE_CHUNK = 1 << 16
#: states whose transitions a breadth-first step gathers at once
_STATE_CHUNK = 1 << 16


def _ptr_dtype(m: int):
    """The dtype of CSR offsets up to ``m``."""
    return np.uint32 if m < (1 << 32) else np.int64


def _offsets(n: int, keys: np.ndarray) -> np.ndarray:
    """CSR offsets (``n + 1``) of the transitions grouped by ``keys``,
    counted a chunk at a time (``np.bincount`` would copy all the keys to
    8 bytes each)."""
    ptr = np.zeros(n + 1, dtype=_ptr_dtype(len(keys)))
    for a in range(0, len(keys), _EDGE_CHUNK):
        u, c = np.unique(keys[a:a + _EDGE_CHUNK], return_counts=True)
        ptr[1 + u.astype(np.int64)] += c.astype(ptr.dtype)
    np.cumsum(ptr, out=ptr)
    return ptr


def _mark(mask: np.ndarray, idx: np.ndarray, value: bool) -> None:
    """``mask[idx] = value``, a chunk at a time (an index array of 4-byte
    state numbers is copied to 8 bytes each by numpy's indexing)."""
    for a in range(0, len(idx), _EDGE_CHUNK):
        mask[idx[a:a + _EDGE_CHUNK]] = value


def _reverse(n: int, src: np.ndarray, dst: np.ndarray) -> tuple:
    """The reversed CSR arrays ``(rptr, rsrc)`` of the transitions
    ``src -> dst``: ``rsrc`` the sources grouped by target, in transition
    order within a target (as a stable argsort of ``dst`` would give them),
    placed a chunk at a time (a counting sort), so that nothing of 8 bytes
    per transition is ever allocated."""
    rptr = _offsets(n, dst)
    cursor = rptr[:-1].copy()
    rsrc = np.empty(len(dst), dtype=src.dtype)
    for a in range(0, len(dst), _EDGE_CHUNK):
        d, s = dst[a:a + _EDGE_CHUNK], src[a:a + _EDGE_CHUNK]
        order = np.argsort(d, kind="stable")
        d, s = d[order], s[order]
        del order
        first = np.ones(len(d), dtype=bool)
        first[1:] = d[1:] != d[:-1]
        heads = np.flatnonzero(first)
        sizes = np.diff(np.append(heads, len(d)))
        rank = np.arange(len(d)) - np.repeat(heads, sizes)
        rsrc[cursor[d].astype(np.int64) + rank] = s
        cursor[d[heads]] += sizes.astype(cursor.dtype)
    return rptr, rsrc


def _mask_chunks(mask: np.ndarray):
    """The states of ``mask`` as int64 arrays of at most
    :data:`_STATE_CHUNK` states (lazily: never all of them at once)."""
    for a in range(0, len(mask), _STATE_CHUNK):
        ix = np.flatnonzero(mask[a:a + _STATE_CHUNK])
        if ix.size:
            yield ix + a


def _unsettled_reverse(src: np.ndarray, dst: np.ndarray, can: np.ndarray, left: int) -> tuple:
    """The ``left`` transitions whose source is not in ``can``, reversed:
    ``(keys, rsrc)``, their targets sorted and the sources in that order
    (one 8-byte key per transition sorted in place: 16 bytes per such
    transition while it is built, 8 kept, nothing per state)."""
    key = np.empty(left, dtype=np.uint64)
    at = 0
    for a in range(0, len(src), _EDGE_CHUNK):
        s, d = src[a:a + _EDGE_CHUNK], dst[a:a + _EDGE_CHUNK]
        keep = ~can[s]
        k = int(np.count_nonzero(keep))
        part = key[at:at + k]
        part[:] = d[keep]
        part <<= np.uint64(32)
        part |= s[keep]
        at += k
    key.sort()
    keys = np.empty(left, dtype=np.uint32)
    rsrc = np.empty(left, dtype=np.uint32)
    for a in range(0, left, _EDGE_CHUNK):
        part = key[a:a + _EDGE_CHUNK]
        keys[a:a + _EDGE_CHUNK] = part >> np.uint64(32)
        rsrc[a:a + _EDGE_CHUNK] = part & np.uint64(0xFFFFFFFF)
    return keys, rsrc


def _gather_sorted(keys: np.ndarray, targets: np.ndarray, frontier: np.ndarray) -> np.ndarray:
    """The targets of the transitions out of ``frontier``, the transitions
    given by their sorted sources ``keys`` (no offsets per state)."""
    f = frontier.astype(keys.dtype)
    lo = np.searchsorted(keys, f, "left").astype(np.int64)
    counts = np.searchsorted(keys, f, "right").astype(np.int64) - lo
    total = int(counts.sum())
    if not total:
        return np.empty(0, dtype=np.int64)
    offs = np.repeat(lo - np.cumsum(counts) + counts, counts) + np.arange(total)
    return targets[offs].astype(np.int64)


def _bfs(gather, seen: np.ndarray, frontier, allowed: Optional[np.ndarray]) -> None:
    """Breadth-first over the transitions ``gather(states)`` gives (their
    targets) from ``frontier``
    (an iterable of state arrays, already in ``seen``) through ``allowed``
    states only, marking ``seen`` in place.  The frontier is gathered
    :data:`_STATE_CHUNK` states at a time, so the temporary arrays stay
    bounded by a chunk's transitions whatever the frontier's size (and one
    4-byte stamp per state, made on first use: a chunk's new states are
    made distinct by writing each one's place at its state and keeping the
    places that stayed, one pass where ``np.unique`` sorted or hashed;
    issue 46: half of a leads-to analysis's time on Fischer)."""
    stamp: Optional[np.ndarray] = None
    while True:
        nxt_parts = []
        for part in frontier:
            for a in range(0, len(part), _STATE_CHUNK):
                nxt = gather(part[a:a + _STATE_CHUNK])
                if allowed is not None:
                    nxt = nxt[allowed[nxt]]
                nxt = nxt[~seen[nxt]]
                if nxt.size:
                    if nxt.size > 1:
                        if stamp is None:
                            stamp = np.empty(len(seen), dtype=np.int64 if len(seen) >> 31 else np.int32)
                        at = np.arange(nxt.size, dtype=stamp.dtype)
                        stamp[nxt] = at
                        nxt = nxt[stamp[nxt] == at]
                    seen[nxt] = True
                    nxt_parts.append(nxt)
        if not nxt_parts:
            return
        frontier = nxt_parts


# ---------------------------------------------------------------------------
# Results
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class TemporalViolation:
    """A temporal verdict that fails: ``kind`` is ``liveness``, ``response``,
    ``unreachable``, ``timelock`` or ``stall``."""
    kind: str
    name: str
    message: str
    agent: Optional[int] = None
    span: object = None
    loops: tuple = ()            # time-lock: (agent, (lines...)) per looping agent
    waits: tuple = ()            # stall: (agent, what it waits on) per running agent

    @property
    def identity(self):
        return (self.kind, self.name)


@dataclass
class LivenessResult:
    found: list = field(default_factory=list)        # [Counterexample] (with cycle_start)
    witnesses: list = field(default_factory=list)    # [(property, Counterexample)]
    holds: list = field(default_factory=list)        # names of properties that hold
    notes: list = field(default_factory=list)        # what could not be decided, and why


def wants_graph(model, timelock: bool, stall: bool = False) -> bool:
    return timelock or stall or bool(getattr(model, "temporal", ()))


def make_recorder(model, timelock: bool, stall: bool = False,
                  frozen: Optional[Callable] = None) -> Optional[GraphRecorder]:
    """The graph recorder of a search of ``model`` (None: no graph check
    asks for one); ``frozen`` (the states' progress signatures, as
    :class:`FrozenColumns` reads them): with the stall check, record what
    the frozen-team check reads too."""
    if not wants_graph(model, timelock, stall):
        return None
    props = list(model.temporal)
    # fair arrival (a robot under way settles eventually) only where the model
    # says its blackbox declares it (pccl.model.engine.blackbox_arrival_is_fair)
    fair = bool(getattr(model, "arrival_is_fair", False)) and any(p.liveness for p in props)
    return GraphRecorder(model, props, fairness=fair, stall=stall, frozen=frozen)


def _chain_to(table, idx: int) -> list:
    chain = []
    while idx != -1:
        chain.append(idx)
        idx = table.parent(idx)
    return chain[::-1]


def analyse(model, explorer, sr, rec: GraphRecorder, *, timelock: bool,
            find_all: bool = False, stall: bool = False) -> LivenessResult:
    """Decide the temporal properties, the time-lock check and the stall
    check on the graph ``rec`` recorded during the search ``sr``: the steps
    of :class:`_Analysis`, in this order (without ``find_all`` the first
    response or liveness violation ends it)."""
    from pccl.search.explorer import Bound
    out = LivenessResult()
    if sr.status in ("violation", "interrupted", "out-of-memory"):
        if rec.props:
            out.notes.append("temporal properties not checked: the search stopped at "
                             + {"violation": "a violation", "interrupted": "an interrupt",
                                "out-of-memory": "out of memory"}[sr.status])
        return out
    complete = rec.complete and sr.status in ("exhaustive", "bounded") and all(
        b in (Bound.MODEL,) for b in sr.bounds_hit)
    depth_only = rec.complete and sr.status == "bounded" and all(
        b in (Bound.MODEL, Bound.DEPTH) for b in sr.bounds_hit)
    a = _Analysis(model, explorer, sr, rec, out, complete, find_all)
    a.reachable()
    if a.within() or a.liveness(depth_only):
        return out
    do_stall = stall and rec.chg is not None and (complete or depth_only)
    if timelock and (complete or depth_only):
        if do_stall and getattr(explorer, "threads", 1) > 1:
            a.decide_beside()
        a.timelock()
    if do_stall and (find_all or not out.found):
        a.stall()
    return out


def quotient_of(model) -> tuple:
    """(renamed, quotient): whether a state number of ``model``'s graph
    stands for an orbit under renaming agents (symmetry), and whether it
    stands for more than one real state at all (symmetry or dead)."""
    on = getattr(getattr(model, "reduction", None), "on", ())
    renamed = "symmetry" in on
    return renamed, renamed or "dead" in on


class _Analysis:
    """The steps of :func:`analyse` over one frozen graph."""

    def __init__(self, model, explorer, sr, rec: GraphRecorder, out: LivenessResult,
                 complete: bool, find_all: bool):
        table = explorer.table
        self.model, self.table, self.sr, self.rec, self.out = model, table, sr, rec, out
        self.complete, self.find_all = complete, find_all
        self.n = table.n
        self.g = rec.freeze(self.n)
        self.g.kernel = getattr(getattr(explorer, "model", None), "reach_back", None)
        from pccl.search.native_liveness import attach_scc, lasso_view
        # Tarjan in C when the native engine recorded the graph
        attach_scc(self.g, getattr(getattr(explorer, "model", None), "temporal_scc", None))
        self.n_init = sr.stats.initial_states
        self.props = rec.props
        #: the search over configurations (a native one seen through the model)
        self.explorer = lasso_view(explorer, model)
        #: a state number stands for an orbit under renaming agents; or (or
        #: also) for states that differ in dead values: a cycle of the graph
        #: closes only up to them, lassos are rebuilt on real states
        self.renamed, self.quotient = quotient_of(model)
        #: the time-lock and stall checks' decisions when made beside each
        #: other (:meth:`decide_beside`), else None
        self._locked_set: Optional[np.ndarray] = None
        self._stalled_first: Optional[tuple] = None
        #: symmetry keeps agent 0 in place: each `forall i:` property is
        #: decided by its instance for agent 0, the others share its verdict
        #: (the orbit argument, docs/reductions.md)
        self.fixed = self.renamed and bool(getattr(getattr(model, "reduction", None), "fixed", 0))

    def skipped(self, p) -> bool:
        """An instance the orbit argument decides by instance 0's verdict."""
        return self.fixed and p.agent is not None and p.agent != 0

    def mirrors(self, p) -> list:
        """The instances of ``p``'s `forall i:` family that share its verdict
        (none unless :attr:`fixed` and ``p`` is instance 0)."""
        if not self.fixed or p.agent != 0:
            return []
        return [q for q in self.props if q.quantified is p.quantified and q.agent not in (None, 0)]

    def shared(self, p, holds: bool) -> None:
        """The verdict of ``p`` (instance 0) given to its mirrors: their names
        hold, or (a violation just recorded) each gets the counterexample
        renamed, made in :func:`attach_traces`."""
        ms = self.mirrors(p)
        if not ms:
            return
        if holds:
            self.out.holds.extend(q.name for q in ms)
        elif self.find_all:
            self.out.found[-1].mirrors = [(q, q.agent) for q in ms]

    def _exact_fair(self, inside: np.ndarray) -> bool:
        """Under symmetry: whether the component ``inside`` of the quotient
        stands for a fair cycle of the rules (docs/reductions.md): a search
        over real states from a real state of it."""
        from pccl.search.lift import RealCycles
        v = int(np.flatnonzero(inside)[0])
        c = self.explorer.replay(v).states[-1]
        rc = RealCycles(self.explorer, self.g.dyn, self.model.N, self.model.arrival_pending)
        return rc.has_fair_cycle(c, inside)

    @staticmethod
    def lasso(prefix_chain: list, cycle: Optional[list]) -> tuple:
        chain = prefix_chain + (cycle[1:] if cycle else [])
        start = len(prefix_chain) - 1 if cycle else None
        return chain, start

    def record(self, v, chain: list, cycle_start: Optional[int]) -> None:
        cx = Counterexample(v, chain[-1] if chain else -1, max(0, len(chain) - 1))
        cx.chain = chain
        cx.cycle_start = cycle_start
        self.out.found.append(cx)

    def reachable(self) -> None:
        """reachable P: witnesses from the bits (BFS order: shortest)."""
        out, g = self.out, self.g
        for k, p in enumerate(self.props):
            if p.kind != "reachable" or self.skipped(p):
                continue
            hits = np.flatnonzero(g.bit(2 * k))
            if hits.size:
                cx = Counterexample(None, int(hits[0]), 0)
                cx.chain = _chain_to(self.table, int(hits[0]))
                cx.depth = len(cx.chain) - 1
                cx.cycle_start = None
                out.witnesses.append((p, cx))
                out.holds.append(p.name)
                if self.mirrors(p):
                    cx.mirrors = [(q, q.agent) for q in self.mirrors(p)]
                    out.holds.extend(q.name for q in self.mirrors(p))
            else:
                where = "" if self.complete else " within the bounds (the search was not exhaustive)"
                for q in [p] + self.mirrors(p):
                    v = TemporalViolation("unreachable", q.name,
                                          f"unreachable: no reachable state satisfies `{q.text}`{where}",
                                          None, q.span)
                    self.record(v, [], None)

    def within(self) -> bool:
        """P ~> Q within T: a (state, clock) search.  True to stop."""
        out, g = self.out, self.g
        for k, p in enumerate(self.props):
            if p.kind != "within" or self.skipped(p):
                continue
            res = _bounded_response(g, self.table, self.n_init, g.bit(2 * k), g.bit(2 * k + 1),
                                    p.ticks)
            if res is None:
                out.holds.append(p.name)
                self.shared(p, True)
                continue
            v = TemporalViolation("response", p.name,
                                  f"bounded response `{p.name}` violated: more than "
                                  f"{_fmt(p.bound)} time units pass after P without Q",
                                  None, p.span)
            self.record(v, res[0], None)
            out.found[-1].p_at = res[1]
            self.shared(p, False)
            if not self.find_all:
                return True
        return False

    def liveness(self, depth_only: bool) -> bool:
        """eventually P, P ~> Q: a lasso that avoids Q.  True to stop."""
        out, g, sr = self.out, self.g, self.sr
        live = [(k, p) for k, p in enumerate(self.props) if p.liveness]
        if live and not (self.complete or depth_only):
            out.notes.append("liveness properties not checked: the search did not finish "
                             "(" + ", ".join(b.value for b in sr.bounds_hit) + ")")
            return False
        if live and not self.complete:
            out.notes.append("liveness properties not checked: the search was bounded by {depth}")
            return False
        for k, p in live:
            if self.skipped(p):
                continue
            qmask = g.bit(2 * k) if p.kind == "eventually" else g.bit(2 * k + 1)
            if p.kind == "eventually":
                starts = np.zeros(self.n, dtype=bool)
                starts[:self.n_init] = True
            else:
                starts = g.bit(2 * k)
            res = _leadsto(g, starts, qmask, self.model.N if self.rec.fairness else 0,
                           self._exact_fair if self.renamed else None)
            if res is None:
                out.holds.append(p.name)
                self.shared(p, True)
                continue
            self.record(*self._liveness_violation(p, res))
            if self.quotient and res[2] is not None:
                # the cycle is rebuilt over real states (pccl/search/lift.py)
                comp = res[4]
                self.out.found[-1].rebuild = (comp == comp[res[1][-1]], g.dyn,
                                              self.model.N if self.rec.fairness else 0)
            self.shared(p, False)
            if not self.find_all:
                return True
        return False

    def _liveness_violation(self, p, res) -> tuple:
        """The violation of ``p`` and its lasso (chain, cycle start)."""
        s, path, cycle, terminal = res[:4]
        to_s = _chain_to(self.table, s)
        chain, cstart = self.lasso(to_s[:-1] + path, cycle)
        if terminal:
            tail = "a run ends (terminal state) without it ever holding"
        else:
            tail = "a run loops forever, time advancing, without it ever holding"
        if p.kind == "eventually":
            msg = f"liveness `{p.name}` violated: {tail}"
        else:
            msg = (f"leads-to `{p.name}` violated: P holds at step {len(to_s) - 1}, "
                   f"then Q never holds ({'the run ends' if terminal else 'the run loops forever'})")
        return TemporalViolation("liveness", p.name, msg, None, p.span), chain, cstart

    def decide_beside(self) -> None:
        """With more than one thread for the search (``--workers N`` on the
        level kernel): the time-lock check's decision (:meth:`_locked`) made
        on a thread of its own while this one makes the stall check's
        (:func:`_first_stalled`); :meth:`timelock` and :meth:`stall` then
        take them, in their order, as one thread would have made them
        (the stall's is dropped where the time-lock ends the analysis).
        Both only read the graph."""
        import threading
        out: dict = {}

        def locked() -> None:
            try:
                out["locked"] = self._locked()
            except BaseException as e:      # handed to the waiting thread
                out["error"] = e
        th = threading.Thread(target=locked, name="pccl-timelock-check", daemon=True)
        th.start()
        assert self.rec.chg is not None
        try:
            self._stalled_first = (_first_stalled(self.g, self.rec.chg.view()[:self.n].view(bool)),)
        finally:
            th.join()
        if "error" in out:
            raise out["error"]
        self._locked_set = out["locked"]

    def _locked(self) -> np.ndarray:
        """The states from which no dynamic or terminal state can be reached."""
        g = self.g
        return ~g.can_reach(g.dyn | g.terminal)

    def timelock(self) -> None:
        """A reachable state from which no dynamic or terminal state can be
        reached: a zero-time cycle that cannot be left."""
        g = self.g
        locked = self._locked_set if self._locked_set is not None else self._locked()
        if not locked.any():
            return
        s = int(np.flatnonzero(locked)[0])
        comp, nontrivial = g.sccs(g.reach(np.asarray([s]), locked).nonzero()[0], locked)
        in_cycle = np.zeros(self.n, dtype=bool)
        ok = comp >= 0
        in_cycle[ok] = nontrivial[comp[ok]]
        path = g.path(s, in_cycle, locked)
        cycle = g.cycle_through(path[-1], comp, [])
        chain, cstart = self.lasso(_chain_to(self.table, s)[:-1] + path, cycle)
        v = TemporalViolation("timelock", "time-lock",
                              "time-lock: time can never advance again, though not every "
                              "agent has exited (a zero-time cycle that cannot be left)")
        self.record(v, chain, cstart)

    def stall(self) -> None:
        """The first stalled state (pccl/model/stall.py's signature)."""
        assert self.rec.chg is not None
        s = self._stalled_first[0] if self._stalled_first is not None \
            else _first_stalled(self.g, self.rec.chg.view()[:self.n].view(bool))
        if s is not None:
            self.record(TemporalViolation("stall", "stall", STALL_MESSAGE),
                        _chain_to(self.table, s), None)


#: The verdict of a stall, before attach_traces adds what each agent waits on.
STALL_MESSAGE = ("stall: the team can never change again (no variable, position or flag), "
                 "though not every agent has exited and time goes on")


def _first_stalled(g: "Graph", changes: np.ndarray) -> Optional[int]:
    """The first stalled state in search order (breadth-first: a shortest
    path): a state that reaches no transition changing the signature
    (``changes``: the states with such a transition out), no terminal state
    and no state from which time can never advance (a time-lock, reported as
    such), or None.  Every state it reaches is stalled too, and, the graph
    being finite, it reaches a cycle through TIME ADVANCE."""
    bad = g.terminal | changes
    bad |= ~g.can_reach(g.dyn)
    stalled = ~g.can_reach(bad)
    hits = np.flatnonzero(stalled)
    return int(hits[0]) if hits.size else None


def _fmt(x) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def _leadsto(g: Graph, starts: np.ndarray, qmask: np.ndarray, n_fair: int,
             exact_fair: Optional[Callable] = None):
    """A counterexample to ``starts ~> Q``: ``(s, path, cycle, terminal,
    comp)`` with ``path`` from s through not-Q states to a bad state (a
    terminal one, or the entry of a fair accepting cycle ``cycle``; ``comp``
    the component id per state), or None.

    ``exact_fair`` (under symmetry): a state number stands for an orbit, and
    its recorded pending robots are those of one renaming, so fairness is
    decided per component: fair when some state has no robot under way
    (every renaming of it too), unfair when every state has every robot
    under way, and otherwise by ``exact_fair(component mask)``, a search
    over real states (docs/reductions.md)."""
    allowed = ~qmask
    seeds = np.flatnonzero(starts & allowed)
    if not seeds.size:
        return None
    region = g.reach(seeds, allowed)                 # not-Q states reachable from a start
    nodes = np.flatnonzero(region)
    comp, nontrivial = g.sccs(nodes, region)
    ncomp = len(nontrivial)
    ok = comp >= 0
    accepting = nontrivial.copy()
    undecided = np.zeros(ncomp, dtype=bool)       # for exact_fair
    fair_masks: list = []
    if ncomp:
        has_dyn = np.zeros(ncomp, dtype=bool)
        np.logical_or.at(has_dyn, comp[ok], g.dyn[ok])
        accepting &= has_dyn
        if n_fair and exact_fair is not None:
            full = np.uint64((1 << n_fair) - 1)
            pend = g.pend & full
            all_idle = np.zeros(ncomp, dtype=bool)
            np.logical_or.at(all_idle, comp[ok], pend[ok] == 0)
            some_idle = np.zeros(ncomp, dtype=bool)
            np.logical_or.at(some_idle, comp[ok], pend[ok] != full)
            undecided = accepting & ~all_idle & some_idle
            accepting &= all_idle
            fair_masks.append(pend == 0)
        else:
            for a in range(n_fair):
                idle = ((g.pend >> np.uint64(a)) & np.uint64(1)) == 0
                has_idle = np.zeros(ncomp, dtype=bool)
                np.logical_or.at(has_idle, comp[ok], idle[ok])
                accepting &= has_idle
                fair_masks.append(idle)
    found = _first_bad(g, starts, region, comp, accepting, undecided, exact_fair)
    if found is None:
        return None
    s, path, bad_cycle = found
    b = path[-1]
    if g.terminal[b] and not bad_cycle[b]:
        return s, path, None, True, comp
    musts = [g.dyn] + [m for m in fair_masks]
    if exact_fair is not None and n_fair and not (fair_masks[0] & (comp == comp[b])).any():
        musts = [g.dyn]         # fair only as real states: lift.py's cycle visits the witnesses
    cycle = g.cycle_through(b, comp, musts)
    return s, path, cycle, False, comp


def _first_bad(g: Graph, starts: np.ndarray, region: np.ndarray, comp: np.ndarray,
               accepting: np.ndarray, undecided: np.ndarray,
               exact_fair: Optional[Callable]) -> Optional[tuple]:
    """Step of :func:`_leadsto`: the first start (in search order) from which
    a bad state (a terminal state or a state of an accepting component of
    ``region``) can be reached, and a shortest path to one: ``(s, path,
    bad_cycle)`` (``bad_cycle``: the states of accepting components), or
    None.

    The components ``undecided`` are decided by ``exact_fair`` lazily: the
    search takes them as accepting, and only the one its path ends in is
    decided (an unfair one is dropped and the search runs again).  The first
    start that reaches a state of the larger set, and the first such state
    its breadth-first path meets, are those of the decided set when that
    state is truly bad, so the lasso is the one that deciding every
    component first would give (docs/reductions.md)."""
    ok = comp >= 0
    while True:
        bad_cycle = np.zeros(g.n, dtype=bool)
        bad_cycle[ok] = (accepting | undecided)[comp[ok]]
        bad = bad_cycle | (region & g.terminal)
        if not bad.any():
            return None
        coreach = g.reach(np.flatnonzero(bad), region, backward=True)
        cand = np.flatnonzero(starts & coreach)
        if not cand.size:
            return None
        s = int(cand[0])
        path = g.path(s, bad, region)
        cb = int(comp[path[-1]])
        if cb < 0 or not undecided[cb]:
            return s, path, bad_cycle
        undecided[cb] = False
        assert exact_fair is not None
        if exact_fair(comp == cb):
            accepting[cb] = True
            return s, path, bad_cycle


def _bounded_response(g: Graph, table, n_init: int, pmask, qmask, ticks: int):
    """A shortest path violating ``P ~> Q within T`` (T = ticks time steps):
    ``(chain, index of the P step)`` or None.  Breadth-first over (state,
    clock); clock -1 is idle, 0..ticks the time steps since the oldest
    unanswered P; a state keeps the largest clock it was reached with."""
    n = g.n
    best = np.full(n, -2, dtype=np.int64)
    init = np.arange(n_init, dtype=np.int64)
    ids: Any
    c0 = np.where(pmask[init] & ~qmask[init], 0, -1)
    node_state = [init]
    node_clock = [c0]
    node_parent = [np.full(n_init, -1, dtype=np.int64)]
    best[init] = c0
    base = 0
    front_s, front_c, front_id = init, c0, np.arange(n_init, dtype=np.int64)
    total = n_init
    while front_s.size:
        dst, counts = g._gather(g.fptr, g.fdst, front_s)
        if not dst.size:
            break
        c = np.repeat(front_c, counts)
        par = np.repeat(front_id, counts)
        tick = g.dyn[dst]
        c = np.where((c >= 0) & tick, c + 1, c)
        viol = c > ticks
        if viol.any():
            j = int(np.flatnonzero(viol)[0])
            ids = [int(par[j])]
            states = np.concatenate(node_state)
            parents = np.concatenate(node_parent)
            clocks = np.concatenate(node_clock)
            while parents[ids[-1]] >= 0:
                ids.append(int(parents[ids[-1]]))
            ids.reverse()
            chain_states = [int(states[i]) for i in ids] + [int(dst[j])]
            # the step at which the unanswered P began: the last idle -> 0
            p_at = 0
            for pos, i in enumerate(ids):
                if clocks[i] == 0 and (pos == 0 or clocks[ids[pos - 1]] == -1):
                    p_at = pos
            prefix = _chain_to(table, chain_states[0])[:-1]
            return prefix + chain_states, len(prefix) + p_at
        c = np.where(qmask[dst], -1, c)
        c = np.where((c == -1) & pmask[dst] & ~qmask[dst], 0, c)
        better = c > best[dst]
        dst, c, par = dst[better], c[better], par[better]
        if not dst.size:
            break
        # one node per state: the largest clock (first such in order)
        order = np.lexsort((np.arange(len(dst)), -c, dst))
        dst, c, par = dst[order], c[order], par[order]
        first = np.ones(len(dst), dtype=bool)
        first[1:] = dst[1:] != dst[:-1]
        dst, c, par = dst[first], c[first], par[first]
        best[dst] = c
        ids = np.arange(total, total + len(dst), dtype=np.int64)
        total += len(dst)
        node_state.append(dst)
        node_clock.append(c)
        node_parent.append(par)
        front_s, front_c, front_id = dst, c, ids
    del base
    return None


def loops_of(model, steps) -> list:
    """For a cycle's steps: ``[(agent, [source lines])]`` of the agents that
    take steps in it."""
    by: dict = {}
    for st in steps:
        a, line = model.label_line(st.label)
        if a is None:
            continue
        lines = by.setdefault(a, [])
        if line and line not in lines:
            lines.append(line)
    return sorted((a, sorted(ls)) for a, ls in by.items())


def attach_traces(model, explorer, lv: LivenessResult) -> None:
    """Replay the recorded state numbers of every counterexample and witness
    into real traces (statement by statement under statement merging)."""
    import dataclasses
    from pccl.search.explorer import Trace

    def replay(chain):
        return model.expand_trace(explorer.replay_chain(chain))

    for cx in lv.found:
        if not cx.chain:
            cx.trace = None
            continue
        if getattr(cx, "rebuild", None) is not None:
            _rebuild_lasso(model, explorer, cx)
            continue
        tr = replay(cx.chain)
        if cx.cycle_start is not None:
            pre = replay(cx.chain[:cx.cycle_start + 1])
            cx.cycle_start = len(pre)
            if cx.violation.kind == "timelock":
                loops = loops_of(model, tr.steps[cx.cycle_start:])
                parts = [f"agent {a} (line{'s' if len(ls) > 1 else ''} "
                         f"{', '.join(map(str, ls))})" for a, ls in loops]
                loop = (tuple((a, tuple(ls)) for a, ls in loops))
                cx.violation = dataclasses.replace(
                    cx.violation, loops=loop,
                    message=cx.violation.message + "; looping: " + ", ".join(parts),
                    agent=loops[0][0] if loops else None)
        if cx.violation.kind == "stall":
            waits, text = model.waiting_note(tr.last)
            cx.violation = dataclasses.replace(
                cx.violation, waits=tuple(waits),
                message=cx.violation.message + ("; " + text if waits else ""),
                agent=waits[0][0] if waits else None)
        cx.trace = Trace(tr.states, tr.labels)
        cx.depth = len(tr)
    for _, cx in lv.witnesses:
        cx.trace = replay(cx.chain)
        cx.depth = len(cx.trace)
    _mirror_all(model, lv)


def _mirror_all(model, lv: LivenessResult) -> None:
    """The orbit argument's verdicts (symmetry keeping agent 0 in place):
    after each counterexample or witness of a ``forall i:`` property's
    instance 0 that asks for them (``mirrors``), the same for each other
    instance j, its trace renamed by exchanging agents 0 and j
    (``model.mirror_trace``: a real run, each step a rule's)."""
    import copy
    import dataclasses

    def mirrored(cx, q, j):
        out = copy.copy(cx)
        out.mirrors = None
        out.chain = None
        if cx.trace is not None:
            out.trace = model.mirror_trace(cx.trace, j)
        v = cx.violation
        if v is not None:
            out.violation = dataclasses.replace(
                v, name=q.name, span=q.span,
                message=v.message.replace(f"`{v.name}`", f"`{q.name}`", 1))
        return out

    found = []
    for cx in lv.found:
        found.append(cx)
        found.extend(mirrored(cx, q, j) for q, j in cx.mirrors or ())
    lv.found = found
    wit = []
    for p, cx in lv.witnesses:
        wit.append((p, cx))
        wit.extend((q, mirrored(cx, q, j)) for q, j in cx.mirrors or ())
    lv.witnesses = wit


def _rebuild_lasso(model, explorer, cx) -> None:
    """The lasso of ``cx`` found on a quotient graph (symmetry, dead) as a
    real run: its prefix replayed to the cycle's entry, then a fair
    accepting cycle of real states inside the component (pccl/search/lift.py),
    which exists there whatever real state the prefix reached
    (docs/reductions.md)."""
    from pccl.search.explorer import Trace
    from pccl.search.lift import RealCycles
    from pccl.search.native_liveness import lasso_view
    explorer = lasso_view(explorer, model)
    inside, dyn, n_fair = cx.rebuild
    pre = explorer.replay_chain(cx.chain[:cx.cycle_start + 1])
    rc = RealCycles(explorer, dyn, n_fair, model.arrival_pending)
    found = rc.fair_component(pre.states[-1], inside)
    if found is None:
        raise RuntimeError("internal error: the accepting component of the reduced graph has "
                           "no fair cycle of real states (please report it)")
    steps, k = found
    pre = model.expand_trace(pre)

    def expanded(part: list):
        """The steps ``part`` from the prefix's last state, expanded."""
        tr = Trace((pre.last,) + tuple(s for _, s in part), tuple(lab for lab, _ in part))
        tr = rc.expand(tr)
        return tr.states[1:], tr.labels
    ps, pl = expanded(steps[:k])
    cs, cl = expanded(steps)
    cx.chain = list(cx.chain[:cx.cycle_start + 1]) + [rc.number(s) for _, s in steps]
    cx.cycle_start = len(pre) + len(pl)
    cx.trace = Trace(pre.states + cs, pre.labels + cl)
    cx.depth = len(cx.trace)
    cx.rebuild = None


__all__ += ["TemporalViolation", "make_recorder", "wants_graph", "loops_of", "FrozenColumns"]
_ = operator
