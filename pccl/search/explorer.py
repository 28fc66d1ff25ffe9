"""Breadth-first state-space exploration with shortest counterexamples.

The checker knows nothing of PCCL.  It explores any :class:`Model` (the
split between model and checker is stateright's), breadth-first from all
initial states, so the first counterexample found for a property is a
shortest one.

State identity
    Each state's :meth:`Model.key` is encoded canonically and hashed to a
    128-bit fingerprint (:mod:`pccl.search.fingerprint`).  ``exact=True`` stores the
    canonical encodings themselves instead (no collision possible; more
    memory; for tests and small models).

Visited storage (:class:`FingerprintTable`, in :mod:`pccl.search.visited`)
    Fingerprints and parent links live in numpy arrays indexed by state
    number (16 + 4 bytes per state), with an open-addressing index of
    ``uint32`` state numbers over them (4 bytes per slot, at most half
    full).  Successors are admitted a batch at a time with vectorised
    lookups, so the visited set holds no Python object per state.  Only the
    current and next BFS levels hold full states.

Counterexamples
    A violating state's chain of parent links is turned back into states by
    *replaying* the model from an initial state, choosing at each step the
    successor whose fingerprint has the recorded state number (as TLC and
    stateright do).  This is why the model must be deterministic: a replay
    that cannot find the recorded successor raises :class:`ReplayError`
    saying which step diverged.
"""

from __future__ import annotations

import enum
import gc
import itertools
import marshal
import operator
import time as _time
from dataclasses import dataclass, field
from typing import (Any, Optional, Protocol, runtime_checkable)
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence

import numpy as np

import xxhash

from pccl.search.fingerprint import collision_bound, encode, fingerprint  # noqa: F401  (re-exported)
from pccl.search.visited import (_EMPTY, _MAX_STATES, ExactTable, FingerprintTable,  # noqa: F401  (re-exported)
                                 _reserve, physical_memory)

__all__ = ["Model", "ViolationLike", "Bound", "Stats", "Step", "Trace", "Counterexample",
           "SearchResult", "Explorer", "ReplayError", "FingerprintTable", "ExactTable"]


# ---------------------------------------------------------------------------
# The contract between a model and the checker
# ---------------------------------------------------------------------------

@runtime_checkable
class ViolationLike(Protocol):
    """What the checker needs of a violation: an identity, so that ``--all``
    reports each distinct violation (property and location) once."""

    @property
    def identity(self) -> Hashable: ...


@runtime_checkable
class Model(Protocol):
    """A transition system the explorer can search.

    **Determinism contract.**  Every method is a pure function of its
    arguments: called twice on equal states, :meth:`successors` returns the
    same labelled successors *in the same order*, :meth:`init_states` the
    same states in the same order, :meth:`key` equal keys.  The explorer
    relies on it twice: to identify states (equal keys are one state) and to
    rebuild a counterexample by replaying from the initial state.  A model
    that breaks it (consults a clock, a global random generator, mutable
    caches that change results) makes the verdict meaningless and the replay
    fail with :class:`ReplayError`.

    **Keys.**  :meth:`key` returns the part of a state that identifies it
    (a model may leave out what cannot influence the future or the
    properties, e.g. an abstracted clock).  It must be built from ints,
    floats, bools, ``None``, ``Ellipsis``, strings, bytes and tuples (see
    :mod:`pccl.search.fingerprint`), and two keys must be equal exactly when the
    states are indistinguishable to the model and its properties.
    """

    def init_states(self) -> Iterable[Any]:
        """The initial states (duplicates allowed; the explorer merges them)."""

    def successors(self, state) -> Sequence[tuple[Any, Any]]:
        """The enabled transitions of ``state`` as ``(label, successor)``."""

    def key(self, state) -> Hashable:
        """State identity, canonically encodable."""

    def violations(self, state) -> Sequence[ViolationLike]:
        """The properties ``state`` violates (empty when it satisfies all)."""

    def terminal_kind(self, state) -> str:
        """For a state without successors: ``"final"``, ``"bounded"`` (the
        model's own horizon stopped it; see :attr:`Bound.MODEL`) or
        ``"deadlock"``."""

    def deadlock_violation(self, state) -> Optional[ViolationLike]:
        """The violation to report for a deadlocked state (or ``None``)."""

    # Optional: ``clock(state)``, the state's model time: the statistics and
    # progress show the largest one reached, and a search that goes
    # ``runaway_levels`` levels without it growing reports a runaway.
    #
    # Optional: ``prepare()``, called by the parallel search before it forks
    # its workers.  A model that builds tables lazily which its states refer
    # to (PCCL interns k cells as small ints) must build them there, so that
    # every process numbers them alike.
    #
    # What the rest of the search family reads of a state or a label comes
    # through the model too, never from PCCL's configuration layout or its
    # display (tests/acceptance/test_architecture.py): ``time_costs(states)``, the time
    # steps a transition into each state costs (pccl/search/fastest.py orders on
    # it; pccl/search/liveness.py's dynamic-state column); and for the graph
    # analyses of pccl/search/liveness.py ``arrival_pending(state)``,
    # ``stall_signature()``, ``waiting_note(state)``, ``label_line(label)``
    # and ``expand_trace(trace)`` (see :class:`pccl.model.engine.Model`).


#: The status of a search stopped by a ``MemoryError`` (the process could not
#: allocate, e.g. under ``ulimit -v`` below ``--max-memory``): the figures so
#: far and the violations found, not exhaustive.
OUT_OF_MEMORY = "out-of-memory"


class Bound(enum.Enum):
    """What cut a search short.  The explorer never spells CLI flags; the
    front ends render these (``pccl explore`` as ``--depth 10`` etc.)."""

    DEPTH = "depth"              # states at the depth limit were not expanded
    MAX_STATES = "max_states"    # the state budget was used up
    MODEL = "model"              # the model's own horizon (PCCL: --max-time)
    MAX_MEMORY = "max_memory"    # the process reached its memory budget


# ---------------------------------------------------------------------------
# Results
# ---------------------------------------------------------------------------

@dataclass
class Stats:
    initial_states: int = 0
    states: int = 0
    transitions: int = 0
    max_depth: int = 0
    seconds: float = 0.0
    peak_memory: int = 0          # bytes, peak resident set size of the process
    frontier: int = 0
    #: the largest model time of an admitted state (models with ``clock``)
    max_time: Any = None

    @property
    def states_per_second(self) -> float:
        return self.states / self.seconds if self.seconds > 0 else 0.0

    def as_dict(self) -> dict:
        return {"initial_states": self.initial_states, "states": self.states,
                "transitions": self.transitions, "max_depth": self.max_depth,
                "seconds": round(self.seconds, 3),
                "states_per_second": round(self.states_per_second, 1),
                "peak_memory_bytes": self.peak_memory, "max_time": self.max_time}


@dataclass(frozen=True)
class Step:
    """One transition of a trace: the model's label and the states around it."""
    number: int                   # 1-based
    label: Any
    before: Any
    after: Any


@dataclass(frozen=True)
class Trace:
    """A path of the model: an initial state and the labelled steps from it.

    Iterating yields ``(label, state)`` pairs starting with
    ``(None, initial)``; :attr:`steps` gives :class:`Step` objects;
    ``len(trace)`` is the number of steps.
    """
    states: tuple
    labels: tuple                 # len(labels) == len(states) - 1

    @property
    def initial(self):
        return self.states[0]

    @property
    def last(self):
        return self.states[-1]

    @property
    def steps(self) -> list:
        s = self.states
        return [Step(n + 1, lab, s[n], s[n + 1]) for n, lab in enumerate(self.labels)]

    def __len__(self) -> int:
        return len(self.labels)

    def __iter__(self) -> Iterator[tuple]:
        yield (None, self.states[0])
        yield from zip(self.labels, self.states[1:])

    def to_json(self, step_json: Callable[[Step], dict]) -> list:
        """The steps as JSON-ready dicts; ``step_json`` renders one step (the
        model's display, which the checker does not know)."""
        return [step_json(st) for st in self.steps]


@dataclass
class Counterexample:
    """A violation and a shortest path that reaches it."""
    violation: Any
    index: int                     # state number in the search
    depth: int
    trace: Optional[Trace] = None  # filled by the replay
    #: a lasso (temporal properties, pccl/search/liveness.py): the path's state
    #: numbers, and the step after which the repeated cycle starts
    chain: Optional[list] = None
    cycle_start: Optional[int] = None
    #: what shortening against the unreduced semantics did to ``trace``
    #: (a :class:`pccl.model.shorten.Shortening`; None: not tried)
    shortening: Any = None
    #: the orbit argument (pccl/search/liveness.py): ``[(property, agent)]``
    #: of the other instances of a ``forall i:`` property that get this
    #: counterexample renamed; None: none
    mirrors: Optional[list] = None


@dataclass
class SearchResult:
    status: str                    # violation | exhaustive | bounded | interrupted | out-of-memory
    found: list = field(default_factory=list)       # [Counterexample]
    bounds_hit: list = field(default_factory=list)  # [Bound]
    stats: Stats = field(default_factory=Stats)
    collision_probability: float = 0.0              # 0 when exact
    exact: bool = False


class ReplayError(RuntimeError):
    """A counterexample could not be rebuilt: the model is not deterministic."""


def peak_rss_bytes() -> int:
    from pccl.search.memory import peak_rss_bytes as peak   # portable: units per platform, psutil fallback
    return peak()


#: The level kernel stopped for room: the table's, or the state budget's
_K_ROOM = 3
#: ... the graph recorder's transition arrays are full
_K_EDGES = 5
#: The level kernel's other threads are woken only when two of its chunks
#: (128 states each) are ready to make: a search whose levels are all
#: narrower than this runs as one thread would (:meth:`Explorer.threads_note`)
SHARED_LEVEL = 256
#: ... and a call of the kernel that starts in such a level runs on one
#: thread, returning after this many seconds at most
_NARROW_SECONDS = 0.05
#: Levels the kernel may go on into after the one it is given
_NO_CROSSING = 0
_ANY_CROSSING = 1 << 30


def violations_of(model, states: list) -> list:
    """(position, violations) of the states of ``states`` that have any, in
    order: the model's ``suspects`` (one call for the list: the native
    engine's check in C) narrow down where to ask ``violations``."""
    suspects = getattr(model, "suspects", None)
    if suspects is None:
        vs = list(map(model.violations, states))     # no bytecode per state
        return [(j, vs[j]) for j in itertools.compress(range(len(vs)), vs)]
    return [(j, v) for j in suspects(states) for v in (model.violations(states[j]),) if v]



def max_time(model, states: list) -> Any:
    """The largest model time (``model.clock``) of ``states``: one C call
    where the model has ``max_clock`` (the native engine), else a call a
    state."""
    many = getattr(model, "max_clock", None)
    if many is not None:
        return many(states if type(states) is list else list(states))
    return max(map(model.clock, states))




# ---------------------------------------------------------------------------
# The search
# ---------------------------------------------------------------------------

_NO_PARENT = 0xFFFF_FFFF


# What the three frontiers share: the breadth-first levels here, the fastest
# priority (pccl/search/fastest.py) and the partitioned workers (pccl/search/parallel.py)
# admit initial states by :meth:`Explorer._initial_chunks`, read a state
# without successors by :func:`terminal`, record violations by
# :meth:`Explorer._recorder`, check the bounds by :meth:`Explorer._at_depth_bound`,
# :meth:`Explorer._budget` and :meth:`Explorer._memory_bound`, report by
# :class:`Progress` and finish by :meth:`Explorer._finish`.

def initial_candidate_cap(max_states: Optional[int], batch: int) -> Optional[int]:
    """How many initial configurations a search with the state budget
    ``max_states`` generates at most (None: no budget, no cap)."""
    return None if max_states is None else max_states + batch


def terminal(model: Model, state, deadlock: bool) -> tuple:
    """What a state without successors means to the search: ``(Bound.MODEL,
    None)`` when the model's own horizon stopped it, ``(None, violation)``
    for a deadlock to report (``deadlock``: deadlocks are checked), else
    ``(None, None)`` (a final state)."""
    kind = model.terminal_kind(state)
    if kind == "bounded":
        return Bound.MODEL, None
    if kind == "deadlock" and deadlock:
        return None, model.deadlock_violation(state)
    return None, None


class Progress:
    """The ``progress`` callback, called at most every ``interval`` seconds:
    ``progress(figures)`` calls ``figures(seconds since the start)`` for the
    dict only when it is due."""

    def __init__(self, fn: Optional[Callable[[dict], None]], interval: float, t_start: float):
        self.fn, self.interval, self.t_start = fn, interval, t_start
        self.next = _time.perf_counter() + interval

    def __call__(self, figures: Callable[[float], dict]) -> None:
        if self.fn is None:
            return
        now = _time.perf_counter()
        if now >= self.next:
            self.next = now + self.interval
            self.fn(figures(now - self.t_start))


class _Runaway:
    """Zero-time runaways (``on_runaway``): the depth at which the largest
    model time last grew, told the depth and time after every level."""

    def __init__(self, ex: "Explorer", max_time: Any, start: Optional[dict]):
        self.ex = ex
        runaway: tuple = start["runaway"] if start is not None else (0, max_time, False)
        self.time_depth: int = runaway[0]
        self.last_time: Any = runaway[1]
        warned: bool = runaway[2]
        self.warned = warned or ex.on_runaway is None

    def state(self) -> tuple:
        """What a checkpoint keeps of it."""
        return self.time_depth, self.last_time, self.warned

    def level(self, depth: int, max_time: Any, last: Any) -> None:
        """A new level at ``depth``, the largest time so far ``max_time``,
        ``last`` its last state."""
        if max_time != self.last_time:
            self.time_depth, self.last_time = depth, max_time
        elif not self.warned and self.last_time is not None \
                and depth - self.time_depth >= self.ex.runaway_levels:
            self.warned = True
            ex = self.ex
            assert ex.on_runaway is not None
            ex._runaway_info = {"depth": depth, "levels": depth - self.time_depth,
                                "max_time": self.last_time, "state": last}
            ex.on_runaway(ex._runaway_info)

@dataclass(frozen=True)
class SearchOptions:
    """The options of a search, whole (:class:`Explorer`'s second argument;
    :meth:`pccl.model.options.ExploreOptions.search_options` makes them from
    ``pccl explore``'s).  What each means: :class:`Explorer`."""
    max_depth: Optional[int] = None
    max_states: Optional[int] = None
    deadlock: bool = True
    find_all: bool = False
    exact: bool = False
    progress: Optional[Callable[[dict], None]] = None
    progress_interval: float = 0.5
    batch: int = 4096
    max_memory: Optional[int] = None
    runaway_levels: int = 500
    #: a directory: move the visited set and the frontier to files there
    #: instead of passing ``max_memory`` (pccl/search/spill.py)
    spill: Optional[str] = None
    #: threads of the level kernel (the native engine's ``explore_levels``)
    threads: int = 1


class Explorer:
    """Breadth-first search of a :class:`Model`.

    ``Explorer(model, SearchOptions(...))``; the options may also be given
    as keywords (``Explorer(model, max_depth=3)``).

    Options: ``max_depth`` (do not expand states at this depth),
    ``max_states`` (admit at most this many states), ``deadlock`` (report
    states without successors that are not final), ``find_all`` (keep going
    and report each distinct violation once), ``exact`` (store canonical
    encodings instead of fingerprints), ``max_memory`` (stop, as a bound,
    once the process's peak resident memory passes this many bytes; checked
    after every admitted batch), ``progress`` (called about every
    ``progress_interval`` seconds with a dict of figures), ``batch``
    (successors admitted per vectorised step), ``recorder`` (an object with
    ``states(list)`` and ``edges(src, dst)``, told the states admitted and
    every transition's state numbers: :mod:`pccl.search.liveness` records the graph
    with it; a recorder whose ``wants_candidates`` is true gets the
    successor states as a third argument, aligned with ``dst``),
    ``on_runaway`` (called once with ``{"depth", "levels", "max_time",
    "state"}`` when ``runaway_levels`` levels pass without the model's
    ``clock`` growing: a zero-time loop that keeps making new states;
    ``state`` is one of the deepest level's),
    ``labels`` (a set: every distinct label of a transition taken
    out of a reachable state is added to it; one C-level update per chunk),
    ``checkpoint`` (a :class:`pccl.search.checkpoint.Checkpointer`: write the
    search's state at level boundaries every so often and when interrupted,
    and resume from a checkpoint; the result is the uninterrupted search's),
    ``spill`` (a directory: as the memory nears ``max_memory``, move the
    visited set and the next level to files there instead of stopping,
    :mod:`pccl.search.spill`; the result is the in-memory search's).
    """

    def __init__(self, model: Model, options: Optional[SearchOptions] = None, *, recorder=None,
                 on_runaway: Optional[Callable[[dict], None]] = None,
                 labels: Optional[set] = None, checkpoint=None, **search):
        o = options if options is not None else SearchOptions()
        if search:
            import dataclasses
            o = dataclasses.replace(o, **search)
        self.model = model
        self.options = o
        #: a :class:`pccl.search.checkpoint.Checkpointer` (or None): where the search
        #: writes checkpoints at level boundaries, and what it resumes from
        self.checkpoint = checkpoint
        self._mark: Optional[dict] = None
        self._runaway_info: Optional[dict] = None
        self._peak_before = 0       # peak memory of the search before the checkpoint resumed
        self.runaway_levels = o.runaway_levels
        self.on_runaway = on_runaway
        self.recorder = recorder
        self.labels = labels
        self.max_memory = o.max_memory
        self.max_depth = o.max_depth
        self.max_states = o.max_states
        self.deadlock = o.deadlock
        self.find_all = o.find_all
        self.exact = o.exact
        self.progress = o.progress
        self.progress_interval = o.progress_interval
        self.batch = o.batch
        self.threads = max(1, o.threads)
        #: the level kernel's chunks admitted in the last run, those the
        #: threads other than the search's own made (``threads`` > 1), those
        #: the search's thread made again because another had them in hand,
        #: and the widest level it expanded (:meth:`threads_note`)
        self.kernel_chunks = self.kernel_helped = self.kernel_dups = self.kernel_widest = 0
        self.table: Any = None
        #: with ``spill``: the :class:`pccl.search.spill.Spiller` of the last run
        self.spiller: Any = None
        #: initial configurations generated by the last run (candidates, before
        #: keys merge them: :meth:`_initial_chunks`)
        self.initial_candidates = 0
        self._t_start = 0.0

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
        t_start = self._t_start = _time.perf_counter()
        self.kernel_chunks = self.kernel_helped = self.kernel_dups = self.kernel_widest = 0
        if self.options.spill is not None:
            if self.exact or self.checkpoint is not None:
                raise ValueError("spill stores fingerprints (not exact) and takes no checkpoint")
            from pccl.search.spill import Spiller
            self.spiller = Spiller(self.options.spill, self.max_memory, FingerprintTable)
            self.table = self.spiller.table
        else:
            self.table = ExactTable() if self.exact else \
                FingerprintTable(kernels=getattr(self.model, "table_kernels", None))
        res = SearchResult("exhaustive", stats=Stats(), exact=self.exact)
        adm = _Admission(self, res)
        ck = self.checkpoint
        self._mark = None
        try:
            start = None
            if ck is not None and ck.resume_dir is not None:
                state, arrays = ck.load()
                try:
                    start = self._restore(adm, res, state, arrays)
                except (ValueError, KeyError, TypeError, IndexError, AttributeError) as e:
                    raise ck._bad(f"the checkpoint is corrupt ({e}); write a new one with "
                                  "{checkpoint}") from None
                del state, arrays       # the mapped files: copied into the table by now
                t_start -= start["seconds"]
                stop = False
            else:
                stop = self._initial_states(adm)
            self._levels(adm, t_start, stop, start)
        except KeyboardInterrupt:
            res.status = "interrupted"
            if ck is not None and ck.dir is not None and self._mark is not None:
                self._save(adm, res)
        except MemoryError:
            # the process could not allocate (a limit below --max-memory):
            # drop the frontier, keep the figures and what was found
            adm.out_of_memory()
            res.status = OUT_OF_MEMORY
        return self._result(res, adm, t_start)

    def _initial_states(self, adm: "_Admission") -> bool:
        """Admit the initial states, as batches of successors of nobody;
        True to stop."""
        stop = False
        table = self.table
        for chunk in self._initial_chunks(lambda: adm.budget, adm.bounds, lambda: table.n,
                                          self._t_start):
            adm.cs.extend(chunk)
            if adm.cl is not None:
                adm.cl.extend(itertools.repeat(None, len(chunk)))
            adm.par_idx.append(_NO_PARENT)
            adm.par_n.append(len(chunk))
            stop = adm.flush(0)
            if stop:
                break
        adm.stats.transitions = 0
        adm.stats.initial_states = self.table.n
        return stop or bool(adm.bounds)

    def _levels(self, adm: "_Admission", t_start: float, stop: bool,
                start: Optional[dict] = None) -> None:
        """The breadth-first level loop: expand each level
        (:meth:`_kernel_frontier` or :meth:`_expand_level`), admit what is
        pending, move to the next
        level.  (``stop``: the initial states already stopped the search;
        ``start``: the level, depth and runaway detector of a checkpoint
        resumed.)"""
        table, stats, ck = self.table, adm.stats, self.checkpoint
        depth = 0
        if start is not None:
            depth = start["depth"]
            front = _Frontier(None, start["level"], start["level_idx"])
        else:
            front = adm.take_frontier()
        progress = Progress(self.progress, self.progress_interval, t_start)

        def report(left: int) -> None:
            progress(lambda secs: {"states": table.n, "frontier": left + adm.pending(),
                                   "depth": depth, "seconds": secs,
                                   "memory": peak_rss_bytes(), "max_time": stats.max_time})

        runaway = _Runaway(self, stats.max_time, start)

        def advance(last: Any) -> None:
            """A level the kernel finished: the next (``last`` its last state)
            is the frontier."""
            nonlocal depth
            report(0)
            depth += 1
            stats.max_depth = depth
            runaway.level(depth, stats.max_time, last)

        while front.count and not stop:
            if ck is not None:
                # what a checkpoint of this level's start holds (a level
                # interrupted half way is expanded again on resume; a search
                # with a checkpoint keeps its levels in memory)
                self._mark = self._level_mark(adm, depth, front.states, front.idx, t_start,
                                              runaway.state())
                if ck.due() and ck.last_saved != (depth, table.n):
                    self._save(adm, adm.res)
            kern = self._kernel(adm, depth)
            if kern is not None:
                # the kernel may finish this level and go on into the next
                # ones (advance() moves depth on): it returns at the end of
                # the level it was in, its next level pending
                stop = self._kernel_frontier(adm, kern, front, depth, report, advance)
            else:
                stop = self._expand_frontier(adm, front, depth, report)
            stop = stop or adm.flush(depth + 1)
            report(0)
            front.discard()
            front = adm.take_frontier()
            if front.count:
                depth += 1
                stats.max_depth = depth
                runaway.level(depth, stats.max_time, front.last)
        stats.frontier = front.count
        front.discard()

    def _expand_frontier(self, adm: "_Admission", front: "_Frontier", depth: int,
                         report: Callable[[int], None]) -> bool:
        """Expand a level, a segment at a time (with ``spill`` its first
        segments are on disk).  True to stop."""
        for level, level_idx in front.segments():
            if self._expand_level(adm, level, level_idx, depth, report):
                return True
        return False

    def _kernel(self, adm: "_Admission", depth: int) -> Optional[Callable]:
        """The model's level kernel (the native engine's ``explore_levels``)
        when this level can use it: fingerprints in the table's arrays, no
        graph recorded or one it can record (the time-lock and stall
        checks'), nothing spilled, below the depth bound; else None."""
        kern = getattr(self.model, "explore_levels", None)
        rec = self.recorder
        if kern is None or adm.fp_batch is None or (rec is not None and not rec.kernel_ready) \
                or self.spiller is not None or self._at_depth_bound(depth) \
                or getattr(self.table, "kernels", None) is None:
            return None
        return kern

    def _kernel_frontier(self, adm: "_Admission", kern: Callable, front: "_Frontier",
                         depth: int, report: Callable[[int], None],
                         advance: Callable[[Any], None]) -> bool:
        """Expand ``front`` (at ``depth``) with the level kernel, and the
        levels after it as far as the depth bound lets (one level with a
        checkpoint: its marks are at level starts), calling ``advance`` as
        each next level becomes the frontier.  The kernel admits what
        :meth:`_expand_level` would, in the same order; it stops before a
        chunk that needs the batches (a state without successors, a
        suspected violation, an error, the state budget: they take it), for
        room in the table (which grows) and every ``progress_interval``
        (progress, the memory bound).  Returns with the level it is in
        expanded, its next level pending in ``adm``; True to stop."""
        table, labels = self.table, self.labels
        level = front.states if type(front.states) is list else list(front.states)
        first = front.idx[0]
        assert front.idx[-1] - first == len(level) - 1      # numbered in a row
        cross = _NO_CROSSING if self.checkpoint is not None else (
            self.max_depth - depth - 1 if self.max_depth is not None else _ANY_CROSSING)
        pos, seconds = 0, max(0.05, self.progress_interval)
        rec = self.recorder
        while True:
            budget_end = table.n + adm.budget
            limit = min(len(table.slots) // 2, len(table.parents), budget_end)
            nfirst = table.n - len(adm.nxt)             # the number of adm.nxt[0]
            graph = None if rec is None else rec.kernel_arrays(limit)
            tcol = None if rec is None else rec.kernel_columns()
            threads, secs = self._kernel_threads(len(level), seconds)
            (e, pos, why, cur, adm.nxt, crossed, tmaxes, trans, labs, cend, k, fin, ne, intr,
             (chunks, helped, dups)) = kern(level, first, adm.nxt, pos, threads, table.slots,
                                    table.fps, table.parents, table.n, int(table.mask), limit,
                                    cross, secs, graph, tcol)
            self._note_kernel(len(level), crossed, chunks, helped, dups)
            table.admitted(k)
            if rec is not None:
                rec.kernel_admitted(k, ne)
            adm.budget -= k
            adm.stats.transitions += trans
            if labels is not None:
                labels.update(labs)
            for i in range(e + 1):
                self._note_time(adm, tmaxes[i])
                if i < e:           # a level expanded: the next is the frontier
                    count, last = crossed[i]
                    first, nfirst = nfirst, nfirst + count
                    cross -= 1
                    depth += 1
                    advance(last)
            adm.nxt_idx = list(range(nfirst, nfirst + len(adm.nxt)))
            if intr is not None:        # Ctrl-C in a memo miss (Python code) stopped the kernel
                raise intr
            if fin:
                return False
            if e:
                level = cur
            if why == _K_ROOM and limit < budget_end:
                table.make_room(max(table.n, 1 << 16))
            elif why == _K_ROOM:        # the budget: the batches cut the level where it ends
                return self._expand_level(adm, level[pos:],
                                          list(range(first + pos, first + len(level))),
                                          depth, report)
            elif why == _K_EDGES:       # the recorder's transitions
                rec.kernel_edges_full()
            elif why:                   # the batches take this chunk
                if self._expand_level(adm, level[pos:cend], list(range(first + pos, first + cend)),
                                      depth, report) or adm.flush(depth + 1):
                    return True
                pos = cend
            report(len(level) - pos)
            if self._memory_bound(adm.bounds, peak_rss_bytes()):
                return True

    def _kernel_threads(self, width: int, seconds: float) -> tuple:
        """The threads of a call of the level kernel that starts in a level of
        ``width`` states, and the seconds after which it returns: a level
        narrower than :data:`SHARED_LEVEL` is this thread's alone (no
        thread started), for :data:`_NARROW_SECONDS` at most, so that the
        threads start soon once the levels widen."""
        if self.threads > 1 and width < SHARED_LEVEL:
            return 1, min(seconds, _NARROW_SECONDS)
        return self.threads, seconds

    def _note_kernel(self, width: int, crossed: tuple, chunks: int, helped: int,
                     dups: int) -> None:
        """The figures of one call of the level kernel (:meth:`threads_note`):
        the width of the level it started in and of those it went through,
        its chunks, those the other threads made, those made twice."""
        self.kernel_widest = max(self.kernel_widest, width, *(c for c, _ in crossed))
        self.kernel_chunks += chunks
        self.kernel_helped += helped
        self.kernel_dups += dups

    def threads_note(self) -> Optional[str]:
        """With ``threads`` > 1: what the header says when the level
        kernel's levels were all narrower than :data:`SHARED_LEVEL` states
        (too narrow to share: the search ran as one thread would, the
        others asleep; it never waits for them); else None."""
        if self.threads <= 1 or not self.kernel_chunks or self.kernel_widest >= SHARED_LEVEL:
            return None
        return (f"levels too narrow to share: the widest had {self.kernel_widest:,} states, "
                f"threads share levels of {SHARED_LEVEL:,} or more")

    @staticmethod
    def _note_time(adm: "_Admission", t: Any) -> None:
        """The largest time of the states the kernel admitted (None: none)."""
        if t is not None and adm.clock is not None \
                and (adm.stats.max_time is None or t > adm.stats.max_time):
            adm.stats.max_time = t

    def _expand_level(self, adm: "_Admission", level: list, level_idx: list, depth: int,
                      report: Callable[[int], None]) -> bool:
        """Expand one level, queueing its successors for admission a batch
        at a time: the hot path (its locals are hoisted once per level).
        True to stop."""
        succ_fn = self.model.successors
        cl = adm.cl         # each candidate's label, for the frozen-team check (else None)
        expand = getattr(self.model, "successor_batch" if cl is None else "successor_batch_ids", None)
        ids: Any = None
        batch = self.batch
        flush = adm.flush
        cs, par_idx, par_n = adm.cs, adm.par_idx, adm.par_n
        second = operator.itemgetter(1)
        labels = self.labels
        first = operator.itemgetter(0)
        chain = itertools.chain.from_iterable
        chunk = max(1, batch // 4)
        at_bound = self._at_depth_bound(depth)
        for c0 in range(0, len(level), chunk):
            # a chunk of the level expanded with C-level map()s: no
            # bytecode per state unless the chunk holds a terminal
            # state or the depth bound is reached
            if expand is not None:
                # the model's batch hook (pccl/model/native.py): one call per
                # chunk, the successors flat, the labels met
                if cl is None:
                    ns, flat, labs = expand(level[c0:c0 + chunk])
                else:
                    ns, flat, labs, ids = expand(level[c0:c0 + chunk])
                    ids = np.frombuffer(ids, dtype=np.int32).tolist()
                if labels is not None:
                    labels.update(labs)
            else:
                succs = list(map(succ_fn, level[c0:c0 + chunk]))
                if labels is not None:
                    labels.update(map(first, chain(succs)))
                ns = list(map(len, succs))
                flat = map(second, chain(succs))     # labels are dropped now
            if not at_bound and 0 not in ns:
                par_idx.extend(level_idx[c0:c0 + chunk])
                par_n.extend(ns)
                cs.extend(flat)
                if cl is not None:
                    cl.extend(ids if expand is not None else map(first, chain(succs)))
                del flat
                succs = []
                if len(cs) >= batch:
                    if flush(depth + 1):
                        return True
                    report(len(level) - c0 - len(ns))
                continue
            if expand is not None and not at_bound:
                if self._expand_mixed(adm, level, level_idx, depth, ns, flat, c0, report, ids):
                    return True
                continue
            if expand is not None:
                # the batch's successors per state (labels are not read past
                # here): no second expansion of the chunk
                it = iter(flat)
                il = iter(ids) if ids is not None else itertools.repeat(None)
                succs = [list(zip(itertools.islice(il, n), itertools.islice(it, n))) for n in ns]
            if self._expand_one(adm, level, level_idx, depth, succs, c0, at_bound, report):
                return True
        return False

    def _expand_mixed(self, adm: "_Admission", level: list, level_idx: list, depth: int,
                      ns: list, flat: list, c0: int, report: Callable[[int], None],
                      ids: Any = None) -> bool:
        """A chunk the batch hook expanded that holds terminal states (no
        successors): the runs of states between them queued whole, as the
        fast path queues a chunk, each terminal state by itself, in order
        (:meth:`_expand_one`'s handling).  True to stop."""
        cs, par_idx, par_n = adm.cs, adm.par_idx, adm.par_n
        ends = list(itertools.accumulate(ns, initial=0))   # flat offset of each state
        a = 0
        for t in [j for j, n in enumerate(ns) if not n] + [len(ns)]:
            if t > a:
                par_idx.extend(level_idx[c0 + a:c0 + t])
                par_n.extend(ns[a:t])
                cs.extend(flat[ends[a]:ends[t]])
                if adm.cl is not None:
                    adm.cl.extend(ids[ends[a]:ends[t]])
                if len(cs) >= self.batch:
                    if adm.flush(depth + 1):
                        return True
                    report(len(level) - c0 - t)
            if t == len(ns):
                break
            if self._terminal(adm, level[c0 + t], level_idx[c0 + t], depth):
                return True
            a = t + 1
        return False

    def _terminal(self, adm: "_Admission", state, number: int, depth: int) -> bool:
        """A state without successors (number ``number``): a bound it met,
        or its deadlock recorded after the pending successors of earlier
        states are admitted.  True to stop."""
        bound, v = terminal(self.model, state, self.deadlock)
        if bound is not None:
            adm.flags.setdefault(bound, number)
        elif v is not None:
            # the pending successors of earlier states come first
            if adm.flush(depth + 1) or adm.record([v], number, depth):
                return True
        return False

    def _expand_one(self, adm: "_Admission", level: list, level_idx: list, depth: int,
                    succs: list, c0: int, at_bound: bool,
                    report: Callable[[int], None]) -> bool:
        """The chunk of the level at ``c0`` (its successor lists ``succs``)
        state by state: terminal states, the depth bound.  True to stop."""
        cs, par_idx, par_n, flags = adm.cs, adm.par_idx, adm.par_n, adm.flags
        second = operator.itemgetter(1)
        for j, succ in enumerate(succs):
            pos = c0 + j
            if not succ:
                if self._terminal(adm, level[pos], level_idx[pos], depth):
                    return True
                continue
            if at_bound:
                flags.setdefault(Bound.DEPTH, level_idx[pos])
                continue
            par_idx.append(level_idx[pos])
            par_n.append(len(succ))
            cs.extend(map(second, succ))     # labels are dropped now
            if adm.cl is not None:
                adm.cl.extend(map(operator.itemgetter(0), succ))
            if len(cs) >= self.batch:
                if adm.flush(depth + 1):
                    return True
                report(len(level) - pos)
        return False

    # -- the skeleton's shared steps (see terminal() above) -------------------
    def _initial_chunks(self, room: Callable[[], int], bounds: set,
                        states: Callable[[], int], t_start: float) -> Iterator[list]:
        """The model's initial states in chunks of at most ``batch``, and
        never more than one beyond the ``room()`` left in the state budget
        (so that a small budget does not build all of them).

        The bounds hold here too (a program's initial configurations can be
        astronomically many candidates with few keys: ``rand`` initialisers
        of 50 symmetric agents): at most ``max_states`` *candidates* are
        generated (the enumeration stops with :attr:`Bound.MAX_STATES` in
        ``bounds`` when more remain), the memory bound is checked between
        chunks (:attr:`Bound.MAX_MEMORY`), and progress is reported between
        chunks (``states()``: the states admitted so far) with the number
        of candidates generated.  The candidates' cap is ``max_states +
        batch`` (:func:`initial_candidate_cap`): a budget of S still admits
        S distinct initial states when at most ``batch`` candidates repeat."""
        it = iter(self.model.init_states())
        cap = initial_candidate_cap(self.max_states, self.batch)
        made = 0
        progress = Progress(self.progress, self.progress_interval, t_start)
        while True:
            n = min(self.batch, room() + 1)
            if cap is not None:
                if made >= cap:
                    if next(it, None) is not None:      # more remain: the bound stopped it
                        bounds.add(Bound.MAX_STATES)
                    return
                n = min(n, cap - made)
            chunk = list(itertools.islice(it, n))
            if not chunk:
                return
            if made:        # a second chunk and on: the initial phase is long, say so
                progress(lambda secs: {"states": states(), "frontier": 0, "depth": 0,
                                       "seconds": secs, "memory": peak_rss_bytes(),
                                       "max_time": None, "initial_candidates": self.initial_candidates})
            made += len(chunk)
            self.initial_candidates = made
            yield chunk
            if self.max_memory is not None and self._memory_bound(bounds, peak_rss_bytes()):
                return

    def _budget(self) -> int:
        """How many states the search may admit."""
        return self.max_states if self.max_states is not None else _MAX_STATES

    def _at_depth_bound(self, depth: int) -> bool:
        """States at ``depth`` are not expanded (``max_depth``)."""
        return self.max_depth is not None and depth >= self.max_depth

    def _memory_bound(self, bounds: set, peak: int) -> bool:
        """True (and :attr:`Bound.MAX_MEMORY` in ``bounds``) once ``peak``
        passes ``max_memory``."""
        if self.max_memory is not None and peak > self.max_memory:
            bounds.add(Bound.MAX_MEMORY)
            return True
        return False

    def _finish(self, res: SearchResult, bounds: set, t_start: float,
                peak: int) -> SearchResult:
        """The search's figures and verdict (the states are the table's), and
        a trace per violation found."""
        stats, found = res.stats, res.found
        stats.states = self.table.n
        stats.seconds = _time.perf_counter() - t_start
        stats.peak_memory = peak
        if not res.exact:
            res.collision_probability = collision_bound(stats.states)
        res.bounds_hit = sorted(bounds, key=lambda b: b.value)
        if res.status not in ("interrupted", OUT_OF_MEMORY):
            res.status = "violation" if found else "bounded" if bounds else "exhaustive"
        for f in found:
            f.trace = self.replay(f.index)
        return res

    # -- checkpoints (pccl/search/checkpoint.py) -----------------------------------
    def _level_mark(self, adm: "_Admission", depth: int, level: list, level_idx: list,
                    t_start: float, runaway: tuple) -> dict:
        """The search as it stands at the start of a level: what a checkpoint
        holds besides the arrays (which are cut at ``n`` when written: the
        table and the recorded graph only grow)."""
        stats, rec = adm.stats, self.recorder
        mark = getattr(self.model, "checkpoint_mark", None)
        if mark is not None:        # a model with state of its own (the coverage tallies)
            mark()
        first = level_idx[0] if level_idx else self.table.n
        assert not level_idx or level_idx[-1] - first + 1 == len(level_idx) == self.table.n - first
        return {"depth": depth, "n": self.table.n, "level": level, "first": first,
                "transitions": stats.transitions, "max_time": stats.max_time,
                "max_depth": stats.max_depth, "initial_states": stats.initial_states,
                "budget": adm.budget, "bounds": [b.value for b in adm.bounds],
                "nfound": len(adm.res.found),
                "labels": None if self.labels is None else set(self.labels),
                "runaway": runaway, "runaway_info": self._runaway_info,
                "seconds": _time.perf_counter() - t_start,
                "edges": None if rec is None else rec.src.n,
                "rec_complete": None if rec is None else rec.complete}

    def _save(self, adm: "_Admission", res: SearchResult) -> None:
        """Write the checkpoint of the current level's start."""
        mark = self._mark
        assert mark is not None and self.checkpoint is not None
        n = mark["n"]
        state = {k: v for k, v in mark.items() if k not in ("nfound",)}
        state["found"] = [(f.violation, f.index, f.depth) for f in res.found[:mark["nfound"]]]
        state["peak_memory"] = peak_rss_bytes()
        tables = getattr(self.model, "checkpoint_tables", None)
        state["tables"] = tables() if tables is not None else None
        arrays: dict = {}
        if self.exact:
            state["exact"] = self.table.dump(n)
        else:
            arrays.update(self.table.dump(n))
        if self.recorder is not None:
            arrays.update({f"rec_{k}": v for k, v in
                           self.recorder.dump(n, mark["edges"]).items()})
        try:
            # the table and the graph only grow: each checkpoint writes what is
            # new (the stall check's change flags are set as states are
            # expanded, after their rows were written: written whole, a byte a state)
            self.checkpoint.write(state, arrays, appended=[k for k in arrays if k != "rec_chg"])
        except OSError as e:        # a full disk: the search goes on, the last checkpoint stays
            self.checkpoint.failed(e)

    def _restore_table(self, state: dict, arrays: dict) -> None:
        """From a checkpoint: the model's interned tables and the visited
        table (a ValueError when the state identity differs)."""
        tables = getattr(self.model, "restore_tables", None)
        if tables is not None and state.get("tables") is not None:
            tables(state["tables"])
        if self.exact != ("exact" in state):
            raise ValueError("the checkpoint's state identity ({exact} or not) differs")
        self.table.load(state["exact"] if self.exact else arrays)

    def _restore(self, adm: "_Admission", res: SearchResult, state: dict, arrays: dict) -> dict:
        """Put the search back where the checkpoint ``state``/``arrays`` left it;
        returns what :meth:`_levels` starts from."""
        self._restore_table(state, arrays)
        n, first = state["n"], state["first"]
        if self.table.n != n or len(state["level"]) != n - first:
            raise ValueError("the checkpoint's table and level do not agree")
        stats = adm.stats
        stats.transitions, stats.max_time = state["transitions"], state["max_time"]
        stats.max_depth, stats.initial_states = state["max_depth"], state["initial_states"]
        stats.peak_memory = state["peak_memory"]
        self._peak_before = state["peak_memory"]
        adm.budget = state["budget"]
        adm.bounds.update(Bound(b) for b in state["bounds"])
        for v, idx, d in state["found"]:
            res.found.append(Counterexample(v, idx, d))
            adm.reported.add(v.identity)
        if self.labels is not None and state["labels"] is not None:
            self.labels.update(state["labels"])
        if self.recorder is not None:
            self.recorder.load({k[4:]: v for k, v in arrays.items() if k.startswith("rec_")},
                               state["rec_complete"])
        self._runaway_info = info = state["runaway_info"]
        if info is not None and self.on_runaway is not None:
            self.on_runaway(info)        # the note of the search before the checkpoint
        return {"depth": state["depth"], "level": state["level"],
                "level_idx": list(range(first, n)), "runaway": state["runaway"],
                "seconds": state["seconds"]}

    def _result(self, res: SearchResult, adm: "_Admission", t_start: float) -> SearchResult:
        """The search's figures and verdict, and a trace per violation found."""
        return self._finish(res, adm.bounds, t_start,
                            max(peak_rss_bytes(), getattr(self, "_peak_before", 0)))

    def _recorder(self, found: list, reported: set):
        """``record(violations, state number, depth) -> stop?``: appends each
        violation not reported before (by identity) to ``found``; True at the
        first one unless ``find_all``."""
        find_all = self.find_all

        def record(viols, idx, d) -> bool:
            for v in viols:
                ident = v.identity
                if ident in reported:
                    continue
                reported.add(ident)
                found.append(Counterexample(v, idx, d))
                if not find_all:
                    return True
            return False
        return record

    def peak_memory(self) -> int:
        """Peak resident memory of the search so far (bytes)."""
        return peak_rss_bytes()

    # ------------------------------------------------------------------
    def replay(self, idx: int) -> Trace:
        """Rebuild the path to state number ``idx`` by replaying the model
        from an initial state along the recorded state numbers."""
        table = self.table
        chain = []
        while idx != -1:
            chain.append(idx)
            idx = table.parent(idx)
        chain.reverse()
        return self.replay_chain(chain)

    def replay_chain(self, chain: list) -> Trace:
        """Rebuild the path through the state numbers ``chain`` (from an
        initial state; a lasso may visit a state twice)."""
        m, table = self.model, self.table
        key, key_of = m.key, table.key_of
        state = None
        for s in m.init_states():
            if table.index_of(key_of(key(s))) == chain[0]:
                state = s
                break
        if state is None:
            raise ReplayError(
                f"counterexample replay diverged at its initial state: no initial state of the "
                f"model has the recorded identity (state #{chain[0]}); the model must be "
                f"deterministic (init_states() must return the same states on every call)")
        states, labels = [state], []
        for step, want in enumerate(chain[1:], 1):
            succ = m.successors(state)
            for label, s2 in succ:
                if table.index_of(key_of(key(s2))) == want:
                    state = s2
                    states.append(s2)
                    labels.append(label)
                    break
            else:
                raise ReplayError(
                    f"counterexample replay diverged at step {step} of {len(chain) - 1}: none "
                    f"of the {len(succ)} successors of the state reached after step {step - 1} "
                    f"is the recorded state #{want}; the model must be deterministic "
                    f"(successors() of equal states must be equal, in the same order)")
        return Trace(tuple(states), tuple(labels))


class _Frontier:
    """A breadth-first level: its states written to ``disk`` (a
    :class:`pccl.search.spill.LevelFile`, with ``spill``; else None), then
    ``states`` in memory, numbered ``idx``."""

    def __init__(self, disk: Any, states: list, idx: Any):
        self.disk, self.states, self.idx = disk, states, idx
        self.count = (disk.count if disk is not None else 0) + len(states)

    @property
    def last(self) -> Any:
        """The level's last state (None when it is empty)."""
        if self.states:
            return self.states[-1]
        return self.disk.last if self.disk is not None else None

    def segments(self) -> Iterator[tuple[list, Any]]:
        """The states and their numbers (a list or a range), in order, a
        segment at a time."""
        if self.disk is not None:
            yield from self.disk.segments()
        if self.states:
            yield self.states, self.idx

    def discard(self) -> None:
        """Delete the level's file (expanded, or never to be)."""
        if self.disk is not None:
            self.disk.discard()


class _Admission:
    """The pending batch of one search and its admission (:meth:`flush`).

    The batch holds candidate states and, per expanded parent, its state
    number and successor count.  Their keys are computed at admission with
    one map() chain: no Python bytecode per transition.  Admitted states go
    to the next level (:meth:`take_level`)."""

    def __init__(self, ex: "Explorer", res: SearchResult):
        self.ex = ex
        self.table = ex.table
        self.stats = res.stats
        self.cs: list = []
        #: each candidate's label (the frozen-team check's graph records
        #: them: pccl/search/liveness.py FrozenColumns), else None
        self.cl: Optional[list] = [] if getattr(ex.recorder, "frozen", None) is not None else None
        self.par_idx: list = []
        self.par_n: list = []
        self.flags: dict = {}       # Bound -> first state number that met it, since the last flush
        self.nxt: list = []         # the next level's states, in admission order
        self.nxt_idx: list = []     # ... and their state numbers
        #: with ``spill``: the next level's states written to disk before ``nxt``
        #: (a :class:`pccl.search.spill.LevelFile`)
        self.spilled: Any = None
        self.bounds: set = set()
        self.budget = ex._budget()
        self.res = res
        #: identities of the violations reported (``--all`` reports each once)
        self.reported: set = set()
        self.record = ex._recorder(res.found, self.reported)
        self.clock = getattr(ex.model, "clock", None)
        key: Callable[[Any], Any] = ex.model.key      # a key is marshallable (Model.key)
        dumps, xxh = marshal.dumps, xxhash.xxh3_128_digest
        twos = itertools.repeat(2)
        if ex.exact:
            def keys_of(states):
                return map(dumps, map(key, states), twos)
        else:
            def keys_of(states):
                return map(xxh, map(dumps, map(key, states), twos))
        self.keys_of = keys_of
        #: the model's batch hook (pccl/model/native.py): a batch's fingerprints,
        #: first occurrences and each one's first occurrence in one call (not for
        #: --exact)
        self.fp_batch = (getattr(ex.model, "fingerprint_batch", None)
                         if not ex.exact else None)
        #: the same with each candidate's stall signature, from the same pass,
        #: when the graph recorder's stall check reads them
        rec = ex.recorder
        self.sig_batch = (getattr(ex.model, "fingerprint_sig_batch", None)
                          if self.fp_batch is not None and rec is not None
                          and rec.sig is not None and not rec.changes_given else None)

    def out_of_memory(self) -> None:
        """A MemoryError stopped the search: free the pending states."""
        self.cs.clear()
        if self.cl is not None:
            self.cl.clear()
        self.nxt, self.nxt_idx = [], []
        if self.spilled is not None:
            self.spilled.discard()
            self.spilled = None

    def pending(self) -> int:
        """States admitted to the next level so far (on disk too)."""
        return len(self.nxt) + (self.spilled.count if self.spilled is not None else 0)

    def take_frontier(self) -> "_Frontier":
        """The level admitted since the last call: its states written to
        disk (``spill``), then those in memory."""
        front = _Frontier(self.spilled, self.nxt, self.nxt_idx)
        self.nxt, self.nxt_idx, self.spilled = [], [], None
        return front

    def take_level(self) -> tuple[list, list]:
        """The states admitted since the last call, and their numbers."""
        level, idx = self.nxt, self.nxt_idx
        self.nxt, self.nxt_idx = [], []
        return level, idx

    def _keys(self, cs: list) -> tuple:
        """The batch's keys (fingerprints, or encodings under --exact), the
        positions of each key's first occurrence (ascending), each
        candidate's first occurrence (an array, or a dict from key to it),
        and each candidate's stall signature when the model computes them
        with the fingerprints (else None)."""
        if self.sig_batch is not None:
            return self.sig_batch(cs)
        if self.fp_batch is not None:
            return (*self.fp_batch(cs), None)
        ck = list(self.keys_of(cs))   # one map() chain for the whole batch
        n = len(ck)
        # first occurrence of each key, in batch order (C-level dict build)
        first_of = dict(zip(reversed(ck), range(n - 1, -1, -1)))
        first = np.fromiter(first_of.values(), dtype=np.int64, count=len(first_of))
        first.sort()
        return ck, first, first_of, None

    def flush(self, d) -> bool:
        """Admit the pending batch (successors at depth ``d``); True to stop."""
        cs, par_idx, par_n, flags = self.cs, self.par_idx, self.par_n, self.flags
        bounds, table, stats = self.bounds, self.table, self.stats
        if not cs:
            bounds.update(flags)
            flags.clear()
            return False
        budget = self.budget
        ck, first, first_of, sigs = self._keys(cs)
        n = len(cs)
        new = table.new_positions(ck, first).tolist()
        base = table.n
        cut = len(new)
        halt = False
        stop_at = None      # batch position of the candidate the search stops at
        if cut > budget:
            cut = budget
            bounds.add(Bound.MAX_STATES)
            halt = True
            stop_at = new[budget]       # the first state that does not fit
        states = list(map(cs.__getitem__, new[:cut]))     # no bytecode per state
        for j, v in violations_of(self.ex.model, states):
            if self.record(v, base + j, d):
                cut = j + 1
                halt = True
                stop_at = new[j]
                break
        if self.clock is not None and cut:      # of the states admitted (up to the cut)
            t = max_time(self.ex.model, states[:cut])
            if stats.max_time is None or t > stats.max_time:
                stats.max_time = t
        owners = np.repeat(np.arange(len(par_n)), par_n)
        rec = self.ex.recorder
        if cut:
            kept = np.asarray(new[:cut], dtype=np.int64)
            pidx = np.asarray(par_idx, dtype=np.int64)
            table.add(cut, pidx[owners[kept]])
            self.nxt.extend(states[:cut] if cut < len(states) else states)
            self.nxt_idx.extend(range(base, base + cut))
            if rec is not None:
                if sigs is None:
                    rec.states(states[:cut])
                else:       # (only a GraphRecorder with the stall check asks for them)
                    rec.states(states[:cut], sigs[kept])
        if rec is not None:
            self._record_edges(rec, ck, first_of, first, owners, base, cut, sigs)
        self.budget = budget - cut
        if stop_at is not None:
            # the search stops right after expanding the parent of the
            # candidate it stops at (as if parents were expanded one by one)
            stop_parent = int(owners[stop_at])
            stats.transitions += sum(par_n[:stop_parent + 1])
            bounds.update(b for b, g in flags.items() if g <= par_idx[stop_parent])
        else:
            stats.transitions += n
            bounds.update(flags)
        flags.clear()
        ex = self.ex
        if ex.spiller is not None and not halt:
            ex.spiller.relieve(self)        # memory pressed: to disk, instead of the bound
        if not halt and ex.max_memory is not None and ex._memory_bound(bounds, peak_rss_bytes()):
            halt = True
        cs.clear()
        if self.cl is not None:
            self.cl.clear()
        par_idx.clear()
        par_n.clear()
        return halt

    def _record_edges(self, rec, ck: list, first_of: Any, first: np.ndarray,
                      owners: np.ndarray, base: int, cut: int,
                      sigs: Optional[np.ndarray] = None) -> None:
        """Tell the recorder every transition of the batch (``ck``: the
        candidates' keys; ``first_of``: a dict from key to the position of its
        first occurrence, or that position per candidate as an array) as
        state numbers (``sigs``: the candidates' stall signatures, when the
        model computed them with the fingerprints)."""
        # each candidate's state number, from its key's first occurrence
        # (looked up once, in new_positions): no second lookup of the batch
        num = self.table.found
        num[np.flatnonzero(num < 0)[:cut]] = np.arange(base, base + cut)
        occ = first_of if isinstance(first_of, np.ndarray) else np.fromiter(
            map(first_of.__getitem__, ck), dtype=np.int64, count=len(ck))
        dst = num[np.searchsorted(first, occ)]
        src = np.asarray(self.par_idx, dtype=np.int64)[owners]
        keep = src != _NO_PARENT
        cl = self.cl
        labs = cl if cl is None or keep.all() else list(itertools.compress(cl, keep.tolist()))
        if sigs is not None and getattr(rec, "wants_candidates", False):
            cands = None
            if cl is not None:      # the frozen-team check reads the states too
                cands = self.cs if keep.all() else list(itertools.compress(self.cs, keep.tolist()))
            rec.edges(src[keep], dst[keep], cands, to_sigs=sigs[keep], labs=labs)
        elif getattr(rec, "wants_candidates", False):
            # the successor states too (before the batch is cleared)
            cs = self.cs
            cands = cs if keep.all() else list(itertools.compress(cs, keep.tolist()))
            rec.edges(src[keep], dst[keep], cands, labs=labs)
        elif labs is not None:
            rec.edges(src[keep], dst[keep], labs=labs)
        else:
            rec.edges(src[keep], dst[keep])
