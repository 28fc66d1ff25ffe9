"""The native engine: a model's successor function and its fast violation
check generated as C, compiled at run time with the system C compiler into
a CPython extension module (cached by the hash of its source, as SPIN
compiles ``pan.c``), for programs whose configuration is a fixed vector of
integers.

The C that is the same for every program is C source in ``native_c/``
(package data): :class:`~pccl.model.native_gen.Generator` (with the
expressions of :mod:`pccl.model.native_expr`) writes what depends on the
program, a module that includes those files (docs/architecture.md, "The
native engine's C"); :mod:`pccl.model.native_build` compiles, caches and
loads it.  This module is the Python side of the loaded module:
:class:`NativeModel`.

A configuration is then a vector of int64 slots, native byte order::

    time, phase, lockQueue (N slots, agent ids, -1 unused), shared scalars,
    per agent: pc, counter, lockState, status, locals, allread

In a program that does not move (no doReach, nothing reads a position)
positions, reach cells and the blackbox's environment never change, so they
are not in the vector (:meth:`NativeModel.decode` puts them back).  In a
program that moves, the env is a slot after shared and each agent's block
ends with its position, target, obstacles and t0 (interned ids) and
doReach_done, doReach_fail.  Values that are not int, bool or enum scalars
(positions, lists, obstacle lists, floats, arrays, None) are small ints
interned in a table :class:`NativeModel` owns (value <-> id, two values
one id when their marshal encodings, which the fingerprints read, are
equal).  In one process ids follow discovery order (small ints: the
state fits int32 slots); for forked workers (``--workers N``) an id is 31
bits of the xxh3 hash of that encoding (:attr:`NativeModel.stable_ids`),
so that every process gives a value the same id, equal states have equal
vectors and fingerprints everywhere, and a worker learns the coordinator's
ids before it takes the initial states (:meth:`NativeModel.learn_ids`); two
values of one id stop the native search (the Python engine runs).
Undefined is INT64_MIN; an int slot holds INT64_MIN + 4 .. INT64_MAX
(:data:`V_MIN`: the values below are reserved codes), any other int met
when a state is encoded or made by C's arithmetic stops the native
search (:class:`NativeOverflow`).  The explorer holds a state as a
``bytes`` object in one of two forms (:meth:`NativeModel.pack`): int32
slots when every slot fits (undefined as INT32_MIN), else the int64 slots;
half the memory, and CPython's small-object allocator instead of malloc
for the states of a team of four robots (measured: see docs/benchmarks.md).

What C does not compute is memoised in C and computed by Python on a miss,
so the semantics and the geometry stay in one place (semantics/rules.py,
blackboxes/): a *memo site* is a statement C cannot compile (one over
interned values: ``head``, ``remove``, ``contains``, ``getPosition()``,
doReach, ...; an assignment to an interned variable) or DOREACH INVOKE of
a program that moves.  Its key is the values of the slots its rule reads
(a statement: the agent's block but its counter, shared, the slots of other
agents it indexes, the clock for a doReach that records t0; DOREACH INVOKE:
every agent's status, position and reach cells, the env, the clock if the
blackbox reads it); its value the rule's successors: per successor the
label and the values of the slots the site writes.  On a miss
:meth:`NativeModel._miss` decodes the state, runs the Python rule (the
blackbox's ``step`` for DOREACH INVOKE), interns what it returns and
checks that no other slot changed (else the native search stops and Python
runs).  :class:`NativeModel` offers the
explorer's model protocol over these vectors: ``successors`` is one C call
per state (the rules of ``semantics/rules.py``, for each pc of the program,
in the same order, with the same labels); ``violations`` one C call that
returns ``[]`` when no agent is stuck and every invariant holds, otherwise
the Python model's own violations of the decoded configuration; ``key``
drops the clock under time abstraction.  Two batch hooks the explorer uses
when a model has them: ``successor_batch`` expands a chunk of a level in one
C call (successor counts, the successors flat, the labels met), and
``fingerprint_batch`` computes a batch's fingerprints (the very function of
:mod:`pccl.search.fingerprint`, xxh3-128 of the marshalled key, by xxhash's
own exported ``XXH3_128bits``), the first occurrence of each key and each
state's first occurrence (the graph recorder's edges) in one C call.

The reductions of :mod:`pccl.model.reduce` run in C too, with the Python
wrapper's own tables: ``rstep`` is the ample set of partial-order reduction
(the first agent, by index, whose next step :meth:`Por.eligible` finds
independent of what the others can still do before the next TIME ADVANCE,
decided per state over the bitmask tables of
:class:`pccl.model.independence.Independence`, all of its successors
keeping it running), else every successor, then each successor's
statement-merging chain (:meth:`Merger.pc_ok`'s pcs and the steps
:meth:`Por.movable` allows, one step at a time, the same 32-step revisit
test and limit, cut as :meth:`Merger._cut` cuts), with the merged label
``(rule, agent, detail, idx0, (0,) * steps)``; under symmetry the key is the
canonical vector of the state's orbit (agent blocks sorted by their blocks
with ids masked, which shared ids name them and their place in the lock
queue; agents naming others tried in every order among equals, the least
vector wins; ids renamed), a canonical form as reduce.py's key is, so the
two identify the same states (in a program that moves the blocks hold
positions as interned ids, whose order is discovery order: another
representative than Python's, the same orbits).  For the time-lock and stall checks the
graph recorder (:mod:`pccl.search.liveness`) reads ``time_costs`` (one C
call per batch) and ``stall_signature`` (a hash of the fields of
:func:`pccl.model.stall.signature_fn`, one C call per state).

The explorer, its fingerprint table (an injective encoding, so the
collision bound is the same) and the replay of counterexamples are the
Python engine's; traces are decoded to configurations afterwards.  So
states, transitions, depth, verdicts and counterexamples equal the Python
engine's by construction of the same BFS order (tests/model/test_native.py checks
it).

Served (:func:`unsupported` says why not otherwise): variables of type int,
bool or enum, scalars; statements: assignment, skip, if, while, atomic,
assert, exit; expressions: literals, variables, enum members, ``+ - *``,
comparisons, ``&& || -> !``, unary minus, ``getAgentIndex()``,
``getNumAgents()``, ``doReach_done``, ``doReach_fail``; statements over
positions, lists, obstacle lists and floats, ``add``, ``remove`` and
doReach through memo sites (guards and invariants over them are not
served); invariants: the same over shared variables, ``count(v)``
of a per-agent bool, ``forall``/``exists`` with ``v[q]`` indexed by the
quantified agent, ``N``; no ``rand`` outside declarations; the built-in
blackboxes (nondet, nondet-fail, instant, straight); every reduction
(merge, symmetry, por, dead: at most 63 shared and allread variables under
por, 63 loc: variables under dead); the time-lock and stall checks; no temporal
property; int δ.  An int that leaves 64 bits at run time stops the native
search (:class:`NativeOverflow`); the API then runs the Python engine.
"""

from __future__ import annotations

import marshal
from array import array
from typing import Optional
from collections.abc import Callable

import xxhash

from pccl.model.layout import AGS, AR, CNT, DONE, ENV, FAIL, LCK, LOC, LQ, OBSTACLES, PC, PHASE, POS, REACH, SH, \
    STATUS, START, T0, TARGET, TIME
from pccl.model.toolchain import native_unavailable
from pccl.model.native_build import build, source_digest
from pccl.model.native_expr import SCALAR, V_PHASE, V_TIME, Unsupported
from pccl.model.native_gen import MAX_AGENTS, Generator
from pccl.model import native_robots as NR

#: what other modules and the tests read here (the generator's own are in
#: pccl/model/native_gen.py, native_expr.py)
__all__ = ["NativeModel", "NativeOverflow", "Unsupported", "Generator", "unsupported", "check_ids", "describe",
           "ID_CLASH", "MAX_AGENTS", "V_TIME", "V_PHASE", "V_MIN", "V_MAX"]

#: the ints a native slot holds (the generated C's VMIN..INT64_MAX): below
#: V_MIN the reserved codes (INT64_MIN undefined; INT64_MIN + 1, + 2 the
#: symmetry signature's own and other agent ids; INT64_MIN + 3 a dead
#: value).  Any other int (a PCCL int is unbounded) met when a state is
#: encoded (an initial state, a memo miss's successors) or made by C's
#: arithmetic stops the native search (:class:`NativeOverflow`): the Python
#: engine runs from the start, so its verdict is the native one
V_MIN, V_MAX = -(1 << 63) + 4, (1 << 63) - 1
OUT_OF_RANGE = "an int beyond the native range (INT64_MIN + 4 .. INT64_MAX)"
#: interned ids below this have a point class in C (native_c/temporal.h)
TPOINT_CAP = 65536
#: stable interned ids (:attr:`NativeModel.stable_ids`): 31 bits of a hash, never
#: negative, never INT32_MAX (a state of such ids still fits int32 slots:
#: :meth:`NativeModel.pack`); two values of one id anywhere stop the search
#: (:meth:`NativeModel.take_new_ids`, the coordinator's check)
_STABLE_MASK = (1 << 31) - 1


class NativeOverflow(RuntimeError):
    """The native search met what it does not model (an int beyond 64 bits, a
    division by zero, an agent index out of range, a read of an undefined
    variable: the runtime errors that get an agent stuck): the Python engine
    must run."""


def unsupported(model, *, reduce_on: bool = False, recorder: bool = False,
                parallel: bool = False, checkpoint: bool = False) -> Optional[str]:
    """Why the native engine cannot serve this model and search (None: it can).
    ``parallel``: several processes search (forked workers: the model then
    takes stable ids); ``checkpoint``: the search saves or resumes a
    checkpoint (which keeps a moving program's interned values:
    :meth:`NativeModel.checkpoint_tables`)."""
    if getattr(model, "semantics", "pccl") != "pccl":
        return ("the C engine implements PCCL's semantics, not Koord's round semantics "
                "({semantics=koord})")
    why = native_unavailable()
    if why is not None:
        return why
    if parallel and bool(getattr(model, "temporal", None)):
        # (one process records the graph: the level kernel's threads, or none)
        return "a temporal property with {workers} processes"
    why = _replaced(model)
    if why is not None:
        return why
    try:
        gen = Generator(model)
        src = gen.source()
        _LAST[:] = [model, gen, src]
    except Unsupported as e:
        return str(e)
    except RecursionError:      # a 3,000-deep chain: the generator recurses on expressions
        return "an expression nested too deeply for the C generator"
    return None


#: the error when two values hash to one stable id (the API runs the Python engine)
ID_CLASH = "two interned values of the workers share a 31-bit id"


def check_ids(registry: dict, new: list) -> None:
    """Add stable ids ``new`` (:meth:`NativeModel.take_new_ids` of some
    process) to ``registry`` (id -> the value's 128-bit hash); raises
    :class:`NativeOverflow` when an id already names another value."""
    get = registry.setdefault
    for i, h in new:
        if get(i, h) != h:
            raise NativeOverflow(ID_CLASH)


def _replaced(model) -> Optional[str]:
    """Why not native when the model's ``successors``, ``violations`` or
    (without symmetry) ``key`` are not the ones :class:`~pccl.model.reduce.Reduced`
    set up (a caller's own wrapper: the Python engine runs it), else None."""
    from pccl.model.reduce import Reduced
    if not isinstance(model, Reduced):
        return None
    d, base = model.__dict__, model.model
    want = (model.merger.successors if model.merger is not None
            else model.por.successors if model.por is not None else base.plain_successors)
    for name, fn in (("successors", want), ("violations", base.fast_violations),
                     ("key", None if {"symmetry", "dead", "counters"} & set(model.reduction.on)
                             else base.plain_key)):
        if fn is not None and d.get(name) != fn:
            return f"the model's {name} function was replaced (the Python engine runs it)"
    return None


#: [model, generator, source] of the last model :func:`unsupported` accepted:
#: :class:`NativeModel` of that model does not generate its source again
_LAST: list = [None, None, None]


class NativeModel:
    """The explorer's model over native state vectors (see the module's doc);
    ``py`` is the Python :class:`~pccl.model.engine.Model` it was generated from."""

    #: successors admitted per batch: four times the explorer's default (the
    #: numpy table's calls cost per batch; measured 15% less CPU on Fischer)
    BATCH = 16384

    def __init__(self, py, stable_ids: bool = False):
        self.py = py
        if _LAST[0] is py:
            gen, src = _LAST[1], _LAST[2]
        else:
            gen = Generator(py)
            src = gen.source()
        _LAST[:] = [None, None, None]
        self.lib = build(src)
        #: the hash of the generated source and the fixed C: part of a checkpoint's
        #: identity (its states are this source's vectors, pccl/search/checkpoint.py)
        self.source_hash = source_digest(src)[:16]
        xxh = _xxh3_128_address()
        self._init_tables(py, stable_ids)
        #: whether positions, reach cells and env are in the vector
        self.moves = gen.moves
        # the shipped blackboxes' outcomes in C (native_robots.py): their
        # labels are in the list before setup reads it
        rkind, rsite, rworld = NR.plan(py, gen, stable_ids)
        rlabels = NR.labels(gen, rkind, py.N)
        # the label list grows on memo misses (C reads the same list)
        self.lib.setup(gen.labels, NativeOverflow, self._violations, xxh or 0, self._miss)
        NR.take_table(self)         # (another model of this module keeps its values)
        self.lib.robots_setup(rkind, rsite, gen.AG0, gen.A, gen.MV, gen.ENVS if gen.moves else 0,
                              rworld, rlabels)
        #: whether C computes DOREACH INVOKE's outcomes (robots.c)
        self.robots_in_c = bool(rkind)
        self.gen = gen
        #: the label list the C code numbers labels by (it grows on memo misses)
        self.label_list = gen.labels
        self._hooks(xxh)
        #: the level kernel (explore_levels: levels expanded and admitted in
        #: C, on threads) when xxhash's symbol is there; else None
        self.explore_levels: Optional[Callable] = (
            self.lib.explore_levels if xxh is not None else None)
        #: the int64 vector, canonical under symmetry, without the clock under
        #: time abstraction (one C call): the state's identity whichever
        #: form (:meth:`pack`) its bytes take
        self.key = self.lib.key
        #: the reductions of the model it serves (pccl/model/reduce.py's plan)
        self.reduction = getattr(py, "reduction", None)
        #: what the graph recorder reads (pccl/search/liveness.py)
        self.N = py.N
        self.arrival_is_fair = bool(getattr(py, "arrival_is_fair", False))
        self.blackbox = py.blackbox
        self._sig = self.lib.sig
        #: a checkpoint keeps the Python model's lazily interned tables (the
        #: violations and traces are decoded through it) and, for a program
        #: that moves, the interned values (:meth:`checkpoint_tables`)
        self._py_tables = getattr(py, "checkpoint_tables", None)
        self._py_restore = getattr(py, "restore_tables", None)
        st0 = next(iter(py.init_states()))
        # the constant parts of a configuration: positions, reach cells, env
        self._pos = tuple(a[POS] for a in st0[AGS])
        self._reach = tuple(a[REACH] for a in st0[AGS])
        self._env = st0[ENV]
        lay = py.compiled.layout
        self._kinds = ([v.ty.kind for v in lay.shared], [v.ty.kind for v in lay.local],
                       [v.ty.kind for v in lay.allread])
        from pccl.model.reduce import unreduced
        self._base = unreduced(py)

    def _init_tables(self, py, stable_ids: bool) -> None:
        """The Python-side tables of a new model (empty): interned values,
        memos, memo sites' bookkeeping."""
        #: the interned values (positions, lists, obstacle lists, targets,
        #: t0, env) of this process: id -> value and the value's canonical
        #: encoding -> id (:meth:`_put`)
        self._vals: NR.Values = NR.Values(self)
        self._ids: dict = {}
        #: the point classes of the interned values (:meth:`_point_class`)
        self._classes: dict = {}
        #: the temporal properties (the graph recorder reads them,
        #: pccl/search/liveness.py): :meth:`temporal_columns` makes their columns
        self.temporal = tuple(getattr(py, "temporal", ()))
        #: ids that name a value the same way in every process: 31 bits of a
        #: hash of its canonical encoding (for forked workers, whose states and
        #: fingerprints must agree), else small ids in discovery order
        self.stable_ids = stable_ids
        self._new_ids: list = []
        #: id() of a value of the table -> its id (the table keeps them alive)
        self._byobj: dict = {}
        #: encode's memos of agent and shared cells (see :meth:`_cached`)
        self._agenc: dict = {}
        self._shenc: dict = {}
        #: per memo site, the slots it does not write (see :meth:`_miss`)
        self._unwritten: dict = {}
        self._pending: dict = {}
        #: the Python predicates of the property memo sites (:meth:`_pvalue`)
        self._pfns: dict = {}

    def _hooks(self, xxh) -> None:
        """The module's C calls the explorer, the recorder and the table use
        (``xxh``: the address of xxhash's XXH3_128bits, or None)."""
        self.successors = self.lib.successors
        #: one C call per chunk of a level: (successor counts, the successors
        #: flat, the labels met) -- the explorer's batch hook
        self.successor_batch = self.lib.expand
        #: the same with each successor's label number (an int32 bytes object,
        #: into :attr:`label_list`): the frozen-team check's recorded events
        self.successor_batch_ids = self.lib.expand_ids
        self.clock = self.lib.clock
        #: the largest ``clock`` of a list of states, in one C call
        self.max_clock = self.lib.max_clock
        self._ok = self.lib.ok
        #: [] or the Python model's violations of the decoded state: one C call
        self.violations = self.lib.violations
        #: the positions of a list's states whose violations may be non-empty
        #: (one C call for a batch; the explorer asks violations() only there)
        self.suspects = self.lib.suspects
        #: the explorer's batch hook, None when xxhash's symbol is not there
        self.fingerprint_batch: Optional[Callable] = self._fingerprint_batch if xxh is not None else None
        #: the fingerprint table's probes in C (FingerprintTable.kernels)
        self.table_kernels = (self.lib.table_lookup, self.lib.table_place)
        #: the graph analysis' backward reachability in C (Graph.can_reach)
        self.reach_back = self.lib.reach_back
        #: the batch hook with the states' stall signatures (one pass for both)
        self.fingerprint_sig_batch: Optional[Callable] = \
            self._fingerprint_sig_batch if xxh is not None else None

    # -- encoding ----------------------------------------------------------------
    def intern(self, x) -> int:
        """The id of value ``x`` (interned on first sight).  Two values get
        one id when their canonical encodings (marshal, as the fingerprints
        read them) are equal: 1 and 1.0 stay apart, as in the Python engine."""
        i = self._byobj.get(id(x))
        if i is not None:       # one of the table's own objects (decode returns them)
            return i
        k = marshal.dumps(x, 2)
        i = self._ids.get(k)
        if i is None:
            if self.stable_ids:
                i = xxhash.xxh3_64_intdigest(k) & _STABLE_MASK
                if i == _STABLE_MASK:
                    i = 0
                if not self._put(i, k, x):
                    raise NativeOverflow(ID_CLASH)
                self._new_ids.append((i, xxhash.xxh3_128_digest(k)))
            else:           # numbered by C's table (robots.c), which numbers C's values too
                i = len(self._vals) if self._vals.detached else self.lib.vintern(k)
                self._put(i, k, x)
        return i

    def _put(self, i: int, k: bytes, x) -> bool:
        """Value ``x`` (canonical encoding ``k``) as id ``i`` in the table;
        False, and nothing changed, when ``x`` has another id or ``i``
        names another value."""
        if k in self._ids:
            return self._ids[k] == i
        if i in self._vals:
            return False
        self._ids[k] = i
        self._vals[i] = x           # kept alive: its id() names it for good
        self._byobj[id(x)] = i
        self._point_class(i, x)
        return True

    def _point_class(self, i: int, x) -> None:
        """Tell C the point class of id ``i`` (value ``x``): -1 for None, else
        the number of its ``(x[0], x[1])`` among those met (equal as Python
        compares them), which the robots-under-way column compares
        (native_c/temporal.h).  A value without two coordinates gets none
        (C then leaves a column that reads it to Python)."""
        if not self.temporal or not 0 <= i < TPOINT_CAP:
            return
        if x is None:
            cls = -1
        else:
            try:
                pt = (x[0], x[1])
                cls = self._classes.setdefault(pt, len(self._classes))
            except (TypeError, IndexError, KeyError):
                return
        self.lib.pcls_set(i, cls)

    def stuck_table(self) -> dict:
        """The Python model's stuck reasons (stuck statuses are the same
        numbers in the vectors)."""
        return self.py.stuck_table()

    def checkpoint_tables(self) -> dict:
        """What a checkpoint keeps besides the states: the Python model's
        lazily interned tables and the interned values by id (the states
        name them by id: positions, lists, any value the C code holds by id)."""
        out = dict(self._py_tables()) if self._py_tables is not None else {}
        self._vals.complete()       # the values C made (robots.c) too
        if self._vals:
            out["native_ids"] = sorted(self._vals.items())
        return out

    def restore_tables(self, data: dict) -> None:
        """Before a resumed search: the tables :meth:`checkpoint_tables`
        saved; a value this process already gave another id is a
        ValueError (the checkpoint is not this search's)."""
        if self._py_restore is not None:
            self._py_restore(data)
        for i, x in data.get("native_ids", ()):
            k = marshal.dumps(x, 2)
            if not self._put(i, k, x) or not (self.stable_ids or self.lib.vset(i, k)):
                raise ValueError("the checkpoint's interned values are not this search's")

    #: the coordinator's check of the ids each worker interned (:func:`check_ids`)
    check_ids = staticmethod(check_ids)

    def take_new_ids(self) -> list:
        """Stable ids: ``(id, 128-bit hash of the value's encoding)`` of the
        values interned here since the last call (the coordinator checks
        that no id names two values in two processes)."""
        out, self._new_ids = self._new_ids, []
        return out

    def id_table(self) -> Optional[dict]:
        """Stable ids (:attr:`stable_ids`): the interned values by id, for
        another process to learn (:meth:`learn_ids`) before it reads states
        made here; None otherwise."""
        return dict(self._vals) if self.stable_ids else None

    def learn_ids(self, table: dict) -> None:
        """The interned values of another process (:meth:`id_table`)."""
        for i, x in table.items():
            if not self._put(i, marshal.dumps(x, 2), x):
                raise NativeOverflow(ID_CLASH)

    def _v(self, x, kind: str = "int") -> int:
        from pccl.lang.values import UNDEF
        if x is UNDEF:
            return -(1 << 63)
        if kind not in SCALAR:
            return self.intern(x)
        x = int(x)
        if not V_MIN <= x <= V_MAX:
            # undefined and the reserved codes below V_MIN, or beyond 64 bits
            raise NativeOverflow(OUT_OF_RANGE)
        return x

    def encode(self, st) -> bytes:
        """The state's bytes as the explorer holds them (:meth:`pack`)."""
        return self.pack(self.vector(st))

    def vector(self, st) -> array:
        """The int64 vector of configuration ``st``."""
        g = self.gen
        v = [self._v(st[TIME]), st[PHASE]]
        lq = list(st[LQ])
        v += lq + [-1] * (g.N - len(lq))
        v += self._cached(self._shenc, st[SH], self._encode_shared)
        if g.moves:
            v.append(self.intern(st[ENV]))
        agent = self._encode_agent
        cache = self._agenc
        for a in st[AGS]:
            v += self._cached(cache, a, agent)
        return array("q", v)

    def pack(self, v: array) -> bytes:
        """The bytes of the int64 vector ``v`` as the explorer holds them
        (the generated C's ``state_bytes``, one C call): where the model
        packs (:attr:`Generator.packs`), int32 slots when every slot fits,
        undefined (INT64_MIN) as INT32_MIN; else the int64 slots themselves.
        Each vector has one form, so equal states have equal bytes; the C
        calls take either."""
        return self.lib.packed(v.tobytes())

    def unpack(self, b: bytes) -> array:
        """The int64 vector of a state's bytes (either form of :meth:`pack`;
        the generated C's ``arg_state``, one C call)."""
        v = array("q")
        v.frombytes(self.lib.unpacked(b))
        return v

    @staticmethod
    def _cached(cache: dict, x, fn) -> list:
        """``fn(x)``, memoised in ``cache`` by ``x``'s marshal encoding (exact:
        1, 1.0 and True stay apart, as in the fingerprints).  A memo miss
        encodes many successors of one state: their agents and shared
        cells repeat, so each is encoded once (bounded: cleared when full)."""
        k = marshal.dumps(x, 2)
        r = cache.get(k)
        if r is None:
            if len(cache) >= 1 << 16:
                cache.clear()
            r = cache[k] = fn(x)
        return r

    def _encode_shared(self, sh) -> list:
        return [self._v(x, k) for x, k in zip(sh, self._kinds[0])]

    def _encode_agent(self, a) -> list:
        _sk, lk, rk = self._kinds
        v = [a[PC], a[CNT], a[LCK], a[STATUS]]
        v += [self._v(x, k) for x, k in zip(a[LOC], lk)]
        v += [self._v(x, k) for x, k in zip(a[AR], rk)]
        if self.gen.moves:
            r = a[REACH]
            v += [self.intern(a[POS]), self.intern(r[TARGET]), self.intern(r[OBSTACLES]),
                  self.intern(r[T0]), int(r[DONE]), int(r[FAIL]), self.intern(r[START])]
        return v

    def _dec(self, x: int, kind: str):
        from pccl.lang.values import UNDEF
        if x == -(1 << 63):
            return UNDEF
        if kind not in SCALAR:
            return self._vals[x]
        return bool(x) if kind == "bool" else x

    def decode(self, b: bytes) -> tuple:
        g = self.gen
        v = self.unpack(b)
        sk, lk, rk = self._kinds
        lq = tuple(x for x in v[2:2 + g.N] if x >= 0)
        sh = tuple(self._dec(x, k) for x, k in zip(v[g.SH0:g.AG0], sk))
        ags = []
        vals = self._vals
        for i in range(g.N):
            o = g.AG0 + i * g.A
            loc = tuple(self._dec(x, k) for x, k in zip(v[o + 4:o + 4 + g.L], lk))
            ar = tuple(self._dec(x, k) for x, k in zip(v[o + 4 + g.L:o + 4 + g.L + g.R], rk))
            if g.moves:
                mv = o + g.MV
                pos = vals[v[mv]]
                reach = (vals[v[mv + 1]], vals[v[mv + 2]], vals[v[mv + 3]], bool(v[mv + 4]),
                         bool(v[mv + 5]), vals[v[mv + 6]])
            else:
                pos, reach = self._pos[i], self._reach[i]
            ags.append((v[o], v[o + 1], v[o + 2], v[o + 3], loc, ar, pos, reach))
        env = vals[v[g.ENVS]] if g.moves else self._env
        return (v[0], v[1], lq, sh, tuple(ags), env)

    def _miss(self, k: int, b: bytes) -> tuple:
        """Memo site ``k``'s value in state ``b`` (C calls this on a miss):
        the successors of the Python rule (a statement of one agent, or
        DOREACH INVOKE: the blackbox's outcomes) as [n, then per successor
        its label's id and the values of the site's written slots].  A
        successor that changes a slot the site does not write stops the
        native search (the Python engine runs)."""
        from pccl.semantics import rules as R
        kind, i, pc, _rs, ws = self.gen.sites[k]
        st = self.decode(b)
        m = self._base
        out: list = []
        if kind == "prop":
            return (array("q", [self._pvalue(k, pc, st)]).tobytes(), None)
        if kind == "coll":
            return (array("q", [0 if m.checks.collision_violations(st) else 1]).tobytes(), None)
        if kind == "env":
            R.doreach_invoke(m, st, out)
        else:
            info = m.ctl.info(pc)
            m.oracle.agent = i
            ag = st[AGS][i]
            for rule in info.rules:
                rule(m, st, i, ag, info, out)
        src = self.unpack(b)
        keep = self._unwritten.get(k)
        if keep is None:        # the slots site k must leave as they are
            wset = set(ws)
            keep = self._unwritten[k] = [q for q in range(len(src)) if q not in wset]
        val = array("q", [len(out)])
        for label, st2 in out:
            t = self.vector(st2)
            u = array("q", src)         # the state as the site may leave it: one C compare
            for q in ws:
                u[q] = t[q]
            if u != t:
                bad = [q for q in keep if t[q] != src[q]]
                raise NativeOverflow(f"a memoised rule ({label[0]}) changed slot {bad[0]}, "
                                     "which its memo site does not write")
            val.append(self.gen.lab(label))
            val.extend(t[q] for q in ws)
        return (val.tobytes(), None)

    def _pvalue(self, k: int, e, st) -> int:
        """Property memo site ``k``'s value in configuration ``st``: the
        Python model's predicate of expression ``e`` as an int, or undefined
        (INT64_MIN: C then leaves the state to the Python violations) when
        it is not a bool or an int of the native range, or raises."""
        fn = self._pfns.get(k)
        if fn is None:
            fn = self._pfns[k] = self.py.compiled.state_predicate(e)[1]
        try:
            v = fn(st)
        except Exception:       # (the Python violations say what it is)
            return -(1 << 63)
        if type(v) is bool or (type(v) is int and V_MIN <= v <= V_MAX):
            return int(v)
        return -(1 << 63)

    # -- the explorer's protocol -------------------------------------------------------
    def init_states(self):
        return map(self.encode, self.py.init_states())

    def _violations(self, b):
        return self.py.violations(self.decode(b))

    def _fingerprint_batch(self, states: list):
        """The fingerprints of the keys of ``states`` (:func:`pccl.search.fingerprint.fingerprint`'s,
        computed in C) as a one-item list of their concatenation, and the
        positions of each key's first occurrence (ascending), and per state
        the position of its key's first occurrence (for the graph recorder's
        edges): the explorer's batch hook for its admission."""
        import numpy as np
        blob, first, occ = self.lib.fingerprints(states)
        return [blob], np.frombuffer(first, dtype=np.int64), np.frombuffer(occ, dtype=np.int64)

    def _fingerprint_sig_batch(self, states: list):
        """:meth:`_fingerprint_batch`, and the stall signature of each state
        (:meth:`stall_signatures`) as a fourth item, from the same pass over
        the states (the graph recorder's stall check)."""
        import numpy as np
        blob, first, occ, sg = self.lib.fingerprints_sigs(states)
        return ([blob], np.frombuffer(first, dtype=np.int64), np.frombuffer(occ, dtype=np.int64),
                np.frombuffer(sg, dtype=np.int64))

    def terminal_kind(self, b) -> str:
        return self.py.terminal_kind(self.decode(b))

    # -- what the graph recorder of the time-lock and stall checks reads -----------------
    def time_costs(self, states: list) -> bytes:
        """1 into a dynamic state (a TIME ADVANCE), else 0: one C call."""
        return self.lib.phases(states)

    def temporal_columns(self, states: list) -> tuple:
        """The graph recorder's columns of the temporal properties for a list
        of states (:class:`pccl.search.liveness.StateColumns`): per state the
        P/Q bits and the robots whose doReach is under way, as uint64
        arrays; one C call (``tcols``), and the Python model's predicates
        and :func:`~pccl.model.search_view.arrival_pending` on the decoded
        configuration where C cannot decide (an undefined value, an
        overflow, a position without a class)."""
        import numpy as np
        from pccl.model.search_view import arrival_pending
        b, p, u = self.lib.tcolumns(states)
        bits = np.frombuffer(b, dtype=np.uint64).copy()
        pend = np.frombuffer(p, dtype=np.uint64).copy()
        for i in np.frombuffer(u, dtype=np.int64).tolist():
            st = self.decode(states[i])
            v = 0
            for k, tp in enumerate(self.temporal):
                for fn, bit in ((tp.p, 2 * k), (tp.q, 2 * k + 1)):
                    if fn is not None and _holds(fn, st):
                        v |= 1 << bit      # (a runtime error: it does not hold)
            bits[i] = v
            pend[i] = arrival_pending(st) if self.gen.moves else 0
        return bits, pend

    def temporal_scc(self, fptr, fdst, allowed, nodes, comp) -> bytes:
        """Tarjan's components in C (native_c/temporal.c ``scc``): the
        numbering of :meth:`pccl.search.liveness.Graph.sccs`."""
        return self.lib.scc(fptr, fdst, allowed, nodes, comp)

    def stall_signatures(self, states: list):
        """:meth:`stall_signature` of each state of a list, as an int64
        array (one C call)."""
        import numpy as np
        return np.frombuffer(self.lib.sigs(states), dtype=np.int64)

    def progress_signatures(self, states: list):
        """The frozen-team check's progress signature
        (:func:`pccl.model.frozen.progress_signature_fn`'s fields) of each
        state of a list, as an int64 array (one C call)."""
        import numpy as np
        return np.frombuffer(self.lib.psigs(states), dtype=np.int64)

    def stall_signature(self) -> Callable:
        """``sig(state) -> int`` with the equalities of
        :func:`pccl.model.stall.signature_fn`'s (the same fields hashed)."""
        return self._sig

    def arrival_pending(self, b) -> int:
        """:func:`pccl.model.search_view.arrival_pending` of the state (0 when
        the program does not move), memoised per agent's reach ids."""
        if not self.gen.moves:
            return 0
        g = self.gen
        v = self.unpack(b)
        m = 0
        cache, vals = self._pending, self._vals
        for i in range(g.N):
            o = g.AG0 + i * g.A + g.MV
            k = (v[o], v[o + 1], v[o + 4], v[o + 5])
            p = cache.get(k)
            if p is None:
                pos, t = vals[k[0]], vals[k[1]]
                p = cache[k] = (t is not None and not k[2] and not k[3]
                                and (pos[0] != t[0] or pos[1] != t[1]))
            if p:
                m |= 1 << i
        return m

    def deadlock_violation(self, b):
        return self.py.deadlock_violation(self.decode(b))

    def decode_trace(self, trace):
        from pccl.search.explorer import Trace
        return Trace(tuple(map(self.decode, trace.states)), trace.labels)

    def decoding(self, explorer) -> "_Decoding":
        """``explorer`` whose replays return configurations (for the graph
        analysis's counterexamples, :func:`pccl.search.liveness.attach_traces`)."""
        return _Decoding(explorer, self)


class _Decoding:
    """An explorer of a :class:`NativeModel` whose ``replay_chain`` decodes."""

    def __init__(self, ex, native: NativeModel):
        self.ex, self.native = ex, native

    def replay_chain(self, chain: list):
        return self.native.decode_trace(self.ex.replay_chain(chain))

    def __getattr__(self, name):
        return getattr(self.ex, name)


def _holds(fn, st) -> bool:
    """A state predicate's value; a runtime error in it: it does not hold
    (as the graph recorder's Python columns decide it)."""
    try:
        return bool(fn(st))
    except Exception:
        return False


def _xxh3_128_address() -> Optional[int]:
    """The address of ``XXH3_128bits`` in the xxhash module pccl's
    fingerprints come from (the C fingerprints call the very function
    ``xxhash.xxh3_128_digest`` calls), or None where it is not exported."""
    import ctypes
    try:
        import xxhash._xxhash as X
        f = ctypes.CDLL(X.__file__).XXH3_128bits
    except (ImportError, OSError, AttributeError):
        return None
    return ctypes.cast(f, ctypes.c_void_p).value


def describe(model) -> str:
    """The engine line of the header: what ran and why not native."""
    eng = getattr(model, "engine_used", "python")
    why = getattr(model, "engine_reason", None)
    return f"engine {eng}" + (f" ({why})" if why else "")

