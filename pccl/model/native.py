"""The native engine: a model's successor function and its fast violation
check generated as C, compiled at run time with the system C compiler into
a CPython extension module (cached by the hash of its source, as SPIN
compiles ``pan.c``), for programs whose configuration is a fixed vector of
integers.

The C that is the same for every program is C source in ``native_c/``
(package data): :class:`Generator` writes what depends on the program, a
module that includes those files (docs/architecture.md, "The native engine's
C"); :mod:`pccl.model.native_build` compiles, caches and loads it.

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
import sys
from array import array
from typing import Any, NamedTuple, Optional
from collections.abc import Callable

import xxhash

from pccl.lang import ast as A
from pccl.model.layout import (AGS, AR, CNT, DISCRETE, DONE, DYNAMIC, ENV, EXITED, FAIL, IDLE, LCK, LOC, LOCK, LQ,
                               OBSTACLES, PC, PHASE, POS, REACH, REQUEST, RUNNING, SH, STATUS, STUCK, START, T0, TARGET,
                               TIME)
from pccl.semantics.rules import (K_AEND, K_ACQ, K_ASSERT, K_ATOMIC, K_DOREACH, K_EMPTY, K_END, K_EXIT, K_IF,
                                  K_SIMPLE, K_WHILE)
from pccl.lang.types import indexes_agent
from pccl.model.reduce import MERGE_LIMIT, _stmt_exprs
from pccl.model.compile import _STATUS_TEST
from pccl.model.toolchain import native_unavailable
from pccl.model.native_build import build, source_digest
from pccl.model import native_robots as NR

#: The native state vector's own layout (not a configuration): the clock and
#: the phase first, then the lock queue, shared, and the agents (see encode).
V_TIME, V_PHASE = 0, 1

UNDEF_C = "INT64_MIN"
#: the ints a native slot holds (the generated C's VMIN..INT64_MAX): below
#: V_MIN the reserved codes (INT64_MIN undefined; INT64_MIN + 1, + 2 the
#: symmetry signature's own and other agent ids; INT64_MIN + 3 a dead
#: value).  Any other int (a PCCL int is unbounded) met when a state is
#: encoded (an initial state, a memo miss's successors) or made by C's
#: arithmetic stops the native search (:class:`NativeOverflow`): the Python
#: engine runs from the start, so its verdict is the native one
V_MIN, V_MAX = -(1 << 63) + 4, (1 << 63) - 1
OUT_OF_RANGE = "an int beyond the native range (INT64_MIN + 4 .. INT64_MAX)"
#: the slots of a moving agent's block after its variables: position,
#: target, obstacles, t0 (interned ids), doReach_done, doReach_fail
MOVE_SLOTS = 7

MAX_AGENTS = 64
#: interned ids below this have a point class in C (native_c/temporal.h)
TPOINT_CAP = 65536
#: CPython's small-object allocator serves at most this many bytes; a bytes
#: object takes its length plus this header
_SMALL_OBJECT, _BYTES_HEADER = 512, sys.getsizeof(b"")
#: the kinds of control cell whose rule a memo site may run (one statement
#: of one agent, no lock, no counter)
MEMO_KINDS = (K_SIMPLE, K_IF, K_WHILE, K_ASSERT, K_DOREACH)
SCALAR = ("int", "bool", "enum")
#: stable interned ids (:attr:`NativeModel.stable_ids`): 31 bits of a hash, never
#: negative, never INT32_MAX (a state of such ids still fits int32 slots:
#: :meth:`NativeModel.pack`); two values of one id anywhere stop the search
#: (:meth:`NativeModel.take_new_ids`, the coordinator's check)
_STABLE_MASK = (1 << 31) - 1
#: kinds of values held as interned ids (value <-> small int, NativeModel's
#: table); C compares them only for equality, Python computes on them
INTERNED = ("pos", "list", "obstacles", "float", "array")
_CMP = ("<", "<=", ">", ">=", "==", "!=")


class NativeOverflow(RuntimeError):
    """The native search met what it does not model (an int beyond 64 bits, a
    division by zero, an agent index out of range, a read of an undefined
    variable: the runtime errors that get an agent stuck): the Python engine
    must run."""


class Unsupported(Exception):
    pass


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


# ---------------------------------------------------------------------------
# C generation
# ---------------------------------------------------------------------------

class _Regs(NamedTuple):
    """Where an agent's control cells are in a native state: its pc, counter,
    lock state and status, and its rate."""
    PC: int
    CNT: int
    LCK: int
    ST: int
    rho: Any


class Generator:
    """The C source of one model's native module."""

    def __init__(self, model):
        self.m = model
        c = model.compiled
        self.c = c
        self.lay = c.layout
        self.N = model.N
        self.labels: list = []
        self.label_ids: dict = {}
        #: whether the program moves (doReach, or a blackbox that moves the
        #: initial state): then positions, reach cells and env are slots of
        #: the vector, holding interned ids (:class:`NativeModel` owns the table)
        from pccl.model.reduce import positions_read, unreduced
        self.moves = any(isinstance(s, A.CallStmt) and s.name == "doReach"
                         for s in c.stmts.values()) or (
            not model.collisions and positions_read(unreduced(model)) is not None)
        #: the memo sites: (kind, agent, pc, read slots, written slots), kind
        #: "stmt" (a statement's rule run by Python on a miss) or "env"
        #: (DOREACH INVOKE, the blackbox's outcomes)
        self.sites: list = []
        #: the C arrays of the property memo sites' read slots (:meth:`pmemo`)
        self.pdecls: list = []

    # -- layout ------------------------------------------------------------------
    @property
    def L(self) -> int:
        return len(self.lay.local)

    @property
    def R(self) -> int:
        return len(self.lay.allread)

    @property
    def A(self) -> int:
        return 4 + self.L + self.R + (MOVE_SLOTS if self.moves else 0)

    @property
    def MV(self) -> int:
        """The offset in an agent's block of its position id (then target,
        obstacles, t0, done, fail, leg start): only when the program moves."""
        return 4 + self.L + self.R

    @property
    def ENVS(self) -> int:
        """The slot of the blackbox's env id (only when the program moves)."""
        return self.SH0 + len(self.lay.shared)

    @property
    def LQ0(self) -> int:
        return 2

    @property
    def SH0(self) -> int:
        return 2 + self.N

    @property
    def AG0(self) -> int:
        return self.SH0 + len(self.lay.shared) + (1 if self.moves else 0)

    @property
    def NS(self) -> int:
        return self.AG0 + self.N * self.A

    @property
    def packs(self) -> bool:
        """Whether states are held packed where they fit (:meth:`NativeModel.pack`):
        when their int64 bytes pass CPython's small-object limit, so that
        the int32 form moves them from malloc to its faster allocator.
        Below it packing costs more than it saves (measured on Fischer, 53
        slots: 8-14 % more CPU); docs/benchmarks.md."""
        return 8 * self.NS + _BYTES_HEADER > _SMALL_OBJECT

    def ag(self, j, field: int) -> str:
        return f"s[{self.AG0 + j * self.A + field}]"

    def ag_cell(self, j, field: int) -> str:
        """:meth:`ag` for an agent given as an int or a C expression."""
        if isinstance(j, int):
            return self.ag(j, field)
        return f"s[{self.AG0 + field} + {self.A} * ({j})]"

    # -- support -----------------------------------------------------------------
    def check(self) -> None:
        m = self.m
        if self.N > MAX_AGENTS:
            raise Unsupported(f"more than {MAX_AGENTS} agents")
        if type(m.delta) is not int:
            raise Unsupported("a non-integer δ")
        from pccl.blackboxes import BLACKBOXES
        if not any(m.blackbox is bb for bb in BLACKBOXES.values()):
            raise Unsupported(f"the blackbox '{getattr(m.blackbox, 'name', '?')}' is not built in")
        for vs in self.lay.vars.values():
            if vs.ty.kind not in SCALAR and vs.ty.kind not in INTERNED:
                raise Unsupported(f"variable '{vs.name}' has type {vs.ty} (the native engine "
                                  "holds int, bool and enum scalars, and interns positions, "
                                  "lists and obstacle lists)")
        if m.guards_rand:
            raise Unsupported("rand() in a guard")
        for s in self.c.stmts.values():
            self.stmt_ok(s)
        for ev in self.c.program.events:
            self.expr(ev.guard, 0)
        nsites = len(self.sites)
        for p in m.properties:
            if p.expr is None:
                raise Unsupported(f"invariant '{p.name}' has no expression")
            try:
                self.pexpr(p.expr, {})
            except Unsupported as e:
                raise Unsupported(f"invariant '{p.name}': {e}") from None
        for tp in m.temporal:
            try:
                self.temporal_exprs(tp)
            except Unsupported as e:
                raise Unsupported(f"temporal property '{tp.name}': {e}") from None
        del self.sites[nsites:], self.pdecls[:]      # (source() makes them again)
        self.env_constant()

    def temporal_exprs(self, tp) -> list:
        """C of a temporal property's state predicates, P then Q (when it has
        one): :meth:`pexpr` over the instance's ``Temporal`` node."""
        t = tp.expr
        out = [self.pexpr(t.p, {})]
        if getattr(t, "q", None) is not None:
            out.append(self.pexpr(t.q, {}))
        return out

    def temporal_c(self) -> str:
        """C of ``tcols(s, &bits, &pend)`` (pccl/model/native_c/temporal.c):
        the graph recorder's per-state columns of the temporal properties, bit
        2k for property k's P and 2k + 1 for its Q (as
        :class:`pccl.search.liveness.StateColumns` sets them), and the robots
        whose doReach is under way (:func:`pccl.model.search_view.arrival_pending`,
        by the classes of the interned position ids, ``TPOINT``).  Returns 1
        when Python must decide a column (a predicate met an undefined value,
        an overflow, a division by zero; a position id without a class)."""
        m = self.m
        out = ["static int tcols(const V *s, uint64_t *bits, uint64_t *pend) {",
               "  int saved = ovf, unsure = 0; uint64_t b = 0, pm = 0; V x;",
               "  (void)x; (void)s;"]
        for k, tp in enumerate(m.temporal):
            t = tp.expr
            preds = [(t.p, 2 * k)] + ([(t.q, 2 * k + 1)] if getattr(t, "q", None) is not None else [])
            for e, bit in preds:
                out.append(f"  ovf = 0; x = {self.pexpr(e, {})}; "
                           f"if (ovf) unsure = 1; else if (x) b |= 1ULL << {bit};")
        fair = bool(getattr(m, "arrival_is_fair", False)) and any(p.liveness for p in m.temporal)
        if self.moves and fair:
            for i in range(self.N):
                o = self.AG0 + i * self.A + self.MV
                out.append(f"  if (!s[{o + 4}] && !s[{o + 5}]) {{ int ct = pcls(s[{o + 1}]); "
                           f"if (ct != -1) {{ int cp = pcls(s[{o}]); "
                           f"if (ct < -1 || cp < -1) unsure = 1; else if (ct != cp) pm |= 1ULL << {i}; }} }}")
        out += ["  ovf = saved;", "  *bits = b; *pend = pm;", "  return unsure;", "}"]
        return "\n".join(out)

    def stmt_ok(self, s) -> None:
        if isinstance(s, A.CallStmt) and s.name not in ("exit", "assert", "doReach", "add", "remove"):
            raise Unsupported(f"the statement {s.name}() (line {s.span.line})")

    def env_constant(self) -> None:
        """A program without doReach whose DOREACH INVOKE leaves positions,
        reach cells and env as they are (checked on the initial state, with
        every agent running, exited and stuck) keeps them out of the vector;
        otherwise the program moves (:attr:`moves`)."""
        m = self.m
        if self.moves:
            return
        st = next(iter(m.init_states()), None)
        if st is None:
            return
        for status in (RUNNING, EXITED, STUCK):
            ags = tuple(a[:STATUS] + (status,) + a[STATUS + 1:] for a in st[AGS])
            s2 = st[:AGS] + (ags,) + st[AGS + 1:]
            outs = m.environment_step(s2)
            want = (tuple(a[POS] for a in ags), tuple(a[REACH][DONE] for a in ags),
                    tuple(a[REACH][FAIL] for a in ags), s2[ENV],
                    tuple(a[REACH][START] for a in ags))
            if len(outs) != 1 or tuple(outs[0]) != want:
                self.moves = True
                return

    # -- labels --------------------------------------------------------------------
    def lab(self, label) -> int:
        k = self.label_ids.get(label)
        if k is None:
            k = self.label_ids[label] = len(self.labels)
            self.labels.append(label)
        return k

    # -- expressions ----------------------------------------------------------------
    def var_ref(self, vs, j) -> str:
        """The slot of variable ``vs`` (of agent ``j``: an int or a C expression)."""
        if vs.section == "allwrite":
            return f"s[{self.SH0 + vs.slot}]"
        off = 4 + vs.slot if vs.section == "loc" else 4 + self.L + vs.slot
        if isinstance(j, int):
            return self.ag(j, off)
        return f"s[{self.AG0 + off} + {self.A} * ({j})]"

    def read(self, ref: str, vs) -> str:
        if vs.ty.kind not in SCALAR:
            raise Unsupported(f"the {vs.ty} variable '{vs.name}': its values live in Python's "
                              f"table of positions and lists, which the C engine does not read")
        if vs.may_undef:
            return f"U({ref})"
        return ref

    def binop(self, op, a, b) -> str:
        if op == "&&":
            return f"({a} && {b})"
        if op == "||":
            return f"({a} || {b})"
        if op == "->":
            return f"(!{a} || {b})"
        if op == "+":
            return f"ADD({a}, {b})"
        if op == "-":
            return f"SUB({a}, {b})"
        if op == "*":
            return f"MUL({a}, {b})"
        if op == "/":
            return f"DIV({a}, {b})"
        if op == "%":
            return f"MOD({a}, {b})"
        if op in ("<", "<=", ">", ">=", "==", "!="):
            return f"((V)({a} {op} {b}))"
        raise Unsupported(f"the operator '{op}'")

    def expr(self, e, i) -> str:
        """C for an agent expression of agent ``i``."""
        if isinstance(e, A.BoolLit):
            return "1" if e.value else "0"
        if isinstance(e, A.IntLit):
            if not -(1 << 62) < e.value < (1 << 62):
                raise Unsupported("an int literal beyond 62 bits")
            return f"((V){e.value}LL)"
        if isinstance(e, A.Name):
            vs = self.lay.vars.get(e.name)
            if vs is not None:
                return self.read(self.var_ref(vs, i), vs)
            if e.name in self.lay.members:
                return str(self.lay.members[e.name][1])
            if self.moves and e.name in ("doReach_done", "doReach_fail"):
                return self.ag(i, self.MV + (4 if e.name == "doReach_done" else 5))
            raise Unsupported(f"the name '{e.name}'")
        if isinstance(e, A.Unary):
            x = self.expr(e.operand, i)
            return f"((V)!{x})" if e.op == "!" else f"NEG({x})"
        if isinstance(e, A.Binary):
            return self.binop(e.op, self.expr(e.left, i), self.expr(e.right, i))
        if isinstance(e, A.Index) and isinstance(e.base, A.Name):
            vs = self.lay.vars.get(e.base.name)
            if vs is not None and indexes_agent(vs.section, False, 1, in_property=False):
                return self.read(self.var_ref(vs, f"AIX({self.expr(e.index, i)})"), vs)
        if isinstance(e, A.Call) and not e.args and e.name == "getAgentIndex":
            return f"((V){i})"
        if isinstance(e, A.Call) and not e.args and e.name == "getNumAgents":
            return f"((V){self.N})"
        what = f"{e.name}()" if isinstance(e, A.Call) else type(e).__name__.lower()
        span = getattr(e, "span", None)
        raise Unsupported(f"the expression {what}" + (f" at line {span.line}:{span.column}"
                                                     if span is not None else ""))

    def pexpr(self, e, bound: dict, boolean: bool = True) -> str:
        """C for a property expression (``bound``: quantified name -> agent).
        ``boolean``: ``e``'s value is a truth value (an operand of ``&& || ->
        !``, a quantifier's body, the property): where C cannot compute such
        an expression, or a comparison (over positions, floats, lists,
        ``dist()``, ...), it is a *property memo site* (:meth:`pmemo`):
        Python evaluates it once per values of the slots it reads."""
        try:
            return self.pexpr_c(e, bound)
        except Unsupported:
            if not (boolean or (isinstance(e, A.Binary) and e.op in _CMP)):
                raise
            return self.pmemo(e, bound)

    def pmemo(self, e, bound: dict) -> str:
        """C of property expression ``e`` (bound names substituted by their
        agents) as a memo site of kind "prop": its value (bool or int) looked
        up by the values of the slots it reads (:meth:`preads`), computed by
        the Python model's own predicate on a miss (:meth:`NativeModel._miss`);
        a value C does not hold (an error, a float) marks the state a suspect
        (``okstate`` fails: the Python model's violations decide it)."""
        from pccl.model.properties import subst
        if any(isinstance(x, A.Call) and x.name == "rand" for x in A.walk_expr(e)):
            raise Unsupported("rand() in a property")
        t = subst(e, bound) if bound else e
        try:
            rs: set = set()
            self.preads(t, rs)
            reads = sorted(rs)
        except Unsupported:         # what it reads is not known: every slot
            reads = list(range(self.NS))
        k = len(self.sites)
        self.sites.append(("prop", None, t, tuple(reads), ()))
        self.pdecls.append(f"static const int PR{k}[] = {{{', '.join(map(str, reads)) or '0'}}};")
        return f"memo_value(s, {k}, PR{k}, {len(reads)})"

    def collision_site(self) -> str:
        """C of the collision check (``--collisions``): a memo site of kind
        "coll" over every agent's position slot (none when positions are not
        in the vector: one lookup), 1 when no robots touch each other or an
        obstacle (the Python model's own check on a miss), else 0: the
        state is a suspect and the Python model's violations name them."""
        reads = [self.AG0 + j * self.A + self.MV for j in range(self.N)] if self.moves else []
        k = len(self.sites)
        self.sites.append(("coll", None, None, tuple(reads), ()))
        self.pdecls.append(f"static const int PR{k}[] = {{{', '.join(map(str, reads)) or '0'}}};")
        return f"memo_value(s, {k}, PR{k}, {len(reads)})"

    def preads(self, e, out: set) -> None:
        """The slots property expression ``e`` (bound names substituted)
        reads, into ``out``; Unsupported when it is not known."""
        if isinstance(e, (A.IntLit, A.FloatLit, A.BoolLit)):
            return
        if isinstance(e, A.Name):
            vs = self.lay.vars.get(e.name)
            if e.name == "time":
                out.add(V_TIME)
            elif vs is not None and vs.section == "allwrite":
                out.add(self.SH0 + vs.slot)
            elif vs is not None:
                raise Unsupported("an unindexed per-agent variable")
            return              # N, an enum member, a quantified name
        if isinstance(e, (A.Unary, A.Field)):
            return self.preads(e.operand if isinstance(e, A.Unary) else e.base, out)
        if isinstance(e, A.Binary):
            self.preads(e.left, out)
            return self.preads(e.right, out)
        if isinstance(e, A.Quant):
            return self.preads(e.body, out)
        if isinstance(e, (A.ListLit, A.Call)) and not (isinstance(e, A.Call) and e.name == "count"):
            if isinstance(e, A.Call) and e.name in ("getAgentIndex", "getPosition", "getNumAgents", "rand"):
                raise Unsupported(f"{e.name}() in a property")
            for x in (e.items if isinstance(e, A.ListLit) else e.args):
                self.preads(x, out)     # (the built-ins and the world's functions: pure)
            return
        if isinstance(e, A.Index):
            return self.pindex_reads(e, out)
        if isinstance(e, A.Call) and len(e.args) == 1 and isinstance(e.args[0], A.Name):   # count(v)
            return self.preads(A.Index(e.args[0], A.Name("_any_agent")), out)
        raise Unsupported(f"a {type(e).__name__} in a property")

    def pindex_reads(self, e, out: set) -> None:
        """Step of :meth:`preads`: an index chain ``v[j]...``: agent ``j``'s
        slot of a per-agent variable (every agent's when ``j`` is not a
        literal), its status, position or reach flags."""
        N = self.N
        root, chain = A.index_chain(e)
        for ix in chain:
            self.preads(ix.index, out)
        i0 = chain[0].index
        agents = ([i0.value] if isinstance(i0, A.IntLit) and 0 <= i0.value < N
                  else range(N))
        if not isinstance(root, A.Name):
            return self.preads(root, out)
        n = root.name
        vs = self.lay.vars.get(n)
        if vs is not None and vs.section == "allwrite":
            out.add(self.SH0 + vs.slot)
            return
        if vs is not None and indexes_agent(vs.section, vs.ty.kind == "array", len(chain),
                                            in_property=True):
            off = 4 + vs.slot if vs.section == "loc" else 4 + self.L + vs.slot
            out.update(self.AG0 + j * self.A + off for j in agents)
            return
        if vs is None and n in ("running", "exited", "stuck"):
            out.update(self.AG0 + j * self.A + 3 for j in agents)
            return
        if vs is None and n in ("pos", "doReach_done", "doReach_fail"):
            if self.moves:      # (else constant: not in the vector)
                q = {"pos": 0, "doReach_done": 4, "doReach_fail": 5}[n]
                out.update(self.AG0 + j * self.A + self.MV + q for j in agents)
            return
        raise Unsupported(f"an index of '{n}'")

    def pexpr_c(self, e, bound: dict) -> str:
        """Step of :meth:`pexpr`: ``e`` computed in C, or Unsupported."""
        if isinstance(e, (A.BoolLit, A.IntLit)):
            return self.expr(e, 0)
        if isinstance(e, A.Name):
            return self.pname(e, bound)
        if isinstance(e, A.Unary):
            x = self.pexpr(e.operand, bound, e.op == "!")
            return f"((V)!{x})" if e.op == "!" else f"NEG({x})"
        if isinstance(e, A.Binary):
            logic = e.op in ("&&", "||", "->")
            return self.binop(e.op, self.pexpr(e.left, bound, logic), self.pexpr(e.right, bound, logic))
        if isinstance(e, A.Quant):
            terms = [self.pexpr(e.body, {**bound, e.var: q}) for q in range(self.N)]
            op = " && " if e.kind == "forall" else " || "
            return "((V)(" + op.join(f"({t})" for t in terms) + "))"
        if isinstance(e, A.Call) and e.name == "count" and len(e.args) == 1 \
                and isinstance(e.args[0], A.Name):
            return self.pcount(e.args[0])
        if isinstance(e, A.Index) and isinstance(e.base, A.Name) and e.base.name in _STATUS_TEST \
                and e.base.name not in self.lay.vars:
            # exited[i], stuck[i], running[i]: a test of agent i's status cell
            j = (bound[e.index.name] if isinstance(e.index, A.Name) and e.index.name in bound
                 else f"AIX({self.pexpr(e.index, bound)})")
            return f"((V)({self.ag_cell(j, 3)} {_STATUS_TEST[e.base.name]}))"
        if isinstance(e, A.Index) and isinstance(e.base, A.Name):
            vs = self.lay.vars.get(e.base.name)
            if vs is not None and indexes_agent(vs.section, False, 1, in_property=True):
                if isinstance(e.index, A.Name) and e.index.name in bound:
                    return self.read(self.var_ref(vs, bound[e.index.name]), vs)
                return self.read(self.var_ref(vs, f"AIX({self.pexpr(e.index, bound)})"), vs)
        what = f"{e.name}()" if isinstance(e, A.Call) else type(e).__name__.lower()
        raise Unsupported(f"the property expression {what} is beyond the native subset")

    def pname(self, e, bound: dict) -> str:
        """Step of :meth:`pexpr`: C for a name in a property."""
        if e.name in bound:
            return f"((V){bound[e.name]})"
        if e.name == "N":
            return f"((V){self.N})"
        if e.name == "time":
            return f"s[{V_TIME}]"
        vs = self.lay.vars.get(e.name)
        if vs is not None and vs.section == "allwrite":
            return self.read(self.var_ref(vs, 0), vs)
        if e.name in self.lay.members and vs is None:
            return str(self.lay.members[e.name][1])
        raise Unsupported(f"the name '{e.name}' in a property")

    def pcount(self, arg) -> str:
        """Step of :meth:`pexpr`: C for ``count(arg)`` of a per-agent bool."""
        vs = self.lay.vars.get(arg.name)
        if vs is None and arg.name in _STATUS_TEST:       # count(exited), ...
            return "((V)(" + " + ".join(f"({self.ag(j, 3)} {_STATUS_TEST[arg.name]})"
                                        for j in range(self.N)) + "))"
        if vs is None or vs.section == "allwrite" or vs.ty.kind != "bool":
            raise Unsupported("count() of something other than a per-agent bool")
        # Python counts values that are True: undefined counts as not True
        return "((V)(" + " + ".join(f"({self.var_ref(vs, j)} == 1)"
                                    for j in range(self.N)) + "))"

    # -- rules ---------------------------------------------------------------------
    def emit(self, lines: list, label, sets: list, ind: str) -> None:
        """Append code that copies the state, applies ``sets`` and emits."""
        lines.append(f"{ind}{{ V t[NS]; memcpy(t, s, sizeof t);")
        for x in sets:
            lines.append(f"{ind}  {x};")
        lines.append(f"{ind}  if (EMIT({self.lab(label)}, t)) return -1; }}")

    def agent_code(self, i: int) -> list:
        m, ctl = self.m, self.m.ctl
        A_ = self.AG0 + i * self.A
        r = _Regs(A_, A_ + 1, A_ + 2, A_ + 3, m.rho[i])
        out = [f"static int agent{i}(const V *s) {{",
               # (an error met before, in the ample set's footprints: the
               # search fails, as before; a cell's own error falls back to
               # its Python rule below)
               "  if (ovf) return -1;",
               f"  int spent = s[{r.CNT}] + {r.rho} > {m.n0};",
               f"  switch (s[{r.PC}]) {{"]
        cases = {K_EMPTY: self.case_empty, K_END: self.case_end, K_AEND: self.case_aend,
                 K_ACQ: self.case_acq, K_SIMPLE: self.case_simple, K_IF: self.case_if,
                 K_WHILE: self.case_while, K_ASSERT: self.case_assert,
                 K_ATOMIC: self.case_atomic, K_EXIT: self.case_exit}
        for pc in range(len(ctl.cells)):
            h = ctl.info(pc)
            out.append(f"  case {pc}: {{")
            case = cases.get(h.kind)
            body: list = []
            try:
                if case is None:
                    raise Unsupported("doReach")
                case(body, i, h, r, "    ")
                if h.kind in MEMO_KINDS or h.kind == K_EMPTY:
                    # a runtime error in C (a division by zero, an int beyond
                    # 64 bits, an undefined value, an agent index out of
                    # range): the Python rule's successors in this state (an
                    # agent stuck with its reason), through a memo site
                    fall = None
                    for q, line in enumerate(body):
                        if line.strip() == "if (ovf) return -1;":
                            if fall is None:
                                fall = " ".join(x.strip() for x in self.case_memo(i, pc, h, ""))
                            body[q] = line.replace("return -1;", f"{{ ovf = 0; {fall} break; }}")
            except Unsupported:
                if h.kind not in MEMO_KINDS:
                    raise
                body = self.case_memo(i, pc, h, "    ")
            out += body
            out.append("    break; }")
        out.append("  default: if (!KT) PyErr_SetString(PyExc_ValueError, \"unknown pc\"); return -1;")
        out.append("  }")
        out.append("  return 0;")
        out.append("}")
        return out

    # -- memo sites: what C does not compute, Python does once per read values --------
    def memo_reads(self, s) -> list:
        """The variables statement ``s``'s rule reads beyond the agent's own
        block and shared ((name, every agent) for an agent-indexed read).  A
        ``rand(n)`` is no read: the rule's successors are every outcome
        (explore's enumeration), a function of the values read."""
        out: list = []
        for x in _stmt_exprs(s):
            out += self.expr_reads(x)
        return out

    def expr_reads(self, x) -> list:
        """The per-agent variables expression ``x`` indexes (read in every
        agent's block: :meth:`memo_reads`)."""
        out = []
        for e in A.walk_expr(x):
            if isinstance(e, A.Index):
                root, _chain = A.index_chain(e)
                if isinstance(root, A.Name) and root.name in self.lay.vars:
                    vs = self.lay.vars[root.name]
                    if vs.section != "allwrite":
                        out.append(vs)
        return out

    def own_slots(self, i: int) -> list:
        """Agent ``i``'s block without its counter (a statement never reads it)."""
        a0 = self.AG0 + i * self.A
        return [a0 + q for q in range(self.A) if q != 1]

    def case_memo(self, i: int, pc: int, h, ind: str) -> list:
        """C of a statement the generator does not compute: the rule's
        successors looked up in the memo by the values of the slots it reads
        (the agent's block but its counter, shared, the slots of other
        agents it indexes, the clock for a doReach that records t0), run by
        the Python rule on a miss (NativeModel._miss)."""
        if h.kind == K_EMPTY:       # the guards (a runtime error in one: the rule's stuck agent)
            extra = [v for ev in self.c.program.events for v in self.expr_reads(ev.guard)]
        else:
            extra = self.memo_reads(self.c.stmts[h.sid])
        shared = list(range(self.SH0, self.SH0 + len(self.lay.shared)))
        rs = self.own_slots(i) + shared
        for vs in extra:
            off = 4 + vs.slot if vs.section == "loc" else 4 + self.L + vs.slot
            rs += [self.AG0 + j * self.A + off for j in range(self.N)]
        if h.kind == K_DOREACH and self.m.record_t0:
            rs.append(V_TIME)
        rs = sorted(set(rs))
        ws = self.own_slots(i) + shared
        return [f"{ind}{self.site_call('stmt', i, pc, rs, ws)}"]

    def site_call(self, kind: str, i, pc, rs: list, ws: list) -> str:
        k = len(self.sites)
        self.sites.append((kind, i, pc, tuple(rs), tuple(ws)))
        return (f"{{ static const int R_[] = {{{', '.join(map(str, rs)) or '0'}}}; "
                f"static const int W_[] = {{{', '.join(map(str, ws)) or '0'}}}; "
                f"if (memo_site(s, {k}, R_, {len(rs)}, W_, {len(ws)})) return -1; }}")

    def env_site(self) -> str:
        """C of DOREACH INVOKE for a program that moves: the blackbox's
        outcomes memoised by every agent's status, position and reach cells
        and the env (the clock too if the blackbox reads it)."""
        rs = [self.ENVS] + ([V_TIME] if getattr(self.m.blackbox, "uses_time", False) else [])
        ws = [V_PHASE, self.ENVS]
        for j in range(self.N):
            a0 = self.AG0 + j * self.A
            rs += [a0 + 3] + [a0 + self.MV + q for q in range(MOVE_SLOTS)]
            ws += [a0 + 1, a0 + self.MV, a0 + self.MV + 4, a0 + self.MV + 5, a0 + self.MV + 6]
        return self.site_call("env", None, None, rs, ws)

    # the cases of agent_code, one per kind of control cell: each appends to
    # ``out`` the C of agent ``i`` at cell ``h`` (``r``: its cells in a state)
    def case_empty(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        m, ctl = self.m, self.m.ctl
        out.append(f"{ind}if (spent) break;")
        evs = self.c.program.events
        for e, ev in enumerate(evs):
            out.append(f"{ind}V g{e} = {self.expr(ev.guard, i)};")
        out.append(f"{ind}if (ovf) return -1;")
        out.append(f"{ind}int any = 0;")
        for e in range(len(evs)):
            out.append(f"{ind}if (g{e}{' && !any' if m.first_only else ''}) {{ any = 1;")
            self.emit(out, ("EVENT SELECT", i, e), [f"t[{r.PC}] = {ctl.event_pcs[e]}"],
                      ind + "  ")
            out.append(f"{ind}}}")
        out.append(f"{ind}if (!any)")
        self.emit(out, ("IDLE", i, None), [f"t[{r.PC}] = {ctl.idle_pc}"], ind + "  ")

    def case_end(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        out.append(f"{ind}if (spent) break;")
        self.emit(out, ("COUNTER ADVANCE", i, None),
                  [f"t[{r.PC}] = {self.m.ctl.empty_pc}", f"t[{r.CNT}] = s[{r.CNT}] + {r.rho}"], ind)

    def case_aend(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        out.append(f"{ind}if (s[{r.LCK}] != {LOCK}) break;")
        self.emit(out, ("LOCK RELEASE", i, None),
                  [f"t[{r.PC}] = {h.next_pc}", f"t[{r.LCK}] = {IDLE}",
                   f"lq_remove(t, {i})"], ind)

    def case_acq(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        head = f"(s[{self.LQ0}] == {i})"
        out.append(f"{ind}if (s[{r.LCK}] == {REQUEST} && {head})")
        self.emit(out, ("ATOMIC EXECUTION", i, h.sid),
                  [f"t[{r.PC}] = {h.body_pc}", f"t[{r.LCK}] = {LOCK}"], ind + "  ")
        out.append(f"{ind}if (!spent && s[{r.LCK}] == {REQUEST} && !{head})")
        self.emit(out, ("ATOMIC WAIT", i, h.sid), [f"t[{r.CNT}] = s[{r.CNT}] + {r.rho}"],
                  ind + "  ")

    def case_simple(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        s = self.c.stmts[h.sid]
        sets = [f"t[{r.PC}] = {h.next_pc}"]
        if isinstance(s, A.Assign):
            if not isinstance(s.target, A.Name):
                raise Unsupported(f"an indexed assignment (line {s.span.line})")
            vs = self.lay.vars[s.target.name]
            if vs.ty.kind not in SCALAR:
                raise Unsupported(f"an assignment to the {vs.ty} variable '{vs.name}' in C")
            out.append(f"{ind}V v = {self.expr(s.value, i)};")
            out.append(f"{ind}if (ovf) return -1;")
            sets.append(f"t[{self.var_ref(vs, i)[2:-1]}] = v")
        elif not isinstance(s, A.Skip):
            raise Unsupported(f"the statement at line {s.span.line}")
        self.emit(out, ("STATEMENT", i, h.sid), sets, ind)

    def case_if(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        s = self.c.stmts[h.sid]
        out.append(f"{ind}V pc2 = {h.branch_pcs[-1]};")
        chain = ""
        for b, (cond, _) in enumerate(s.branches):
            chain += f"{ind}{'else ' if b else ''}if ({self.expr(cond, i)}) pc2 = {h.branch_pcs[b]};\n"
        out.append(chain.rstrip("\n"))
        out.append(f"{ind}if (ovf) return -1;")
        self.emit(out, ("STATEMENT", i, h.sid), [f"t[{r.PC}] = pc2"], ind)

    def case_while(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        s = self.c.stmts[h.sid]
        out.append(f"{ind}V b = {self.expr(s.cond, i)};")
        out.append(f"{ind}if (ovf) return -1;")
        self.emit(out, ("STATEMENT", i, h.sid),
                  [f"t[{r.PC}] = b ? {h.body_pc} : {h.next_pc}"], ind)

    def case_assert(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        s = self.c.stmts[h.sid]
        code = self.m.stuck_code("assert", "assertion failed", h.sid)
        out.append(f"{ind}V b = {self.expr(s.args[0], i)};")
        out.append(f"{ind}if (ovf) return -1;")
        self.emit(out, ("STATEMENT", i, h.sid),
                  [f"if (b) t[{r.PC}] = {h.next_pc}; else t[{r.ST}] = {code}"], ind)

    def case_atomic(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        out.append(f"{ind}if (s[{r.LCK}] == {IDLE})")
        self.emit(out, ("LOCK REQUEST", i, h.sid),
                  [f"t[{r.PC}] = {h.request_pc}", f"t[{r.LCK}] = {REQUEST}",
                   f"lq_append(t, {i})"], ind + "  ")
        out.append(f"{ind}if (s[{r.LCK}] == {LOCK})")
        self.emit(out, ("STATEMENT", i, h.sid), [f"t[{r.PC}] = {h.body_pc}"], ind + "  ")

    def case_exit(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        self.emit(out, ("EXIT", i, h.sid),
                  [f"t[{r.PC}] = {self.m.ctl.empty_pc}", f"t[{r.ST}] = {EXITED}"], ind)

    # -- the reductions (docs/reductions.md), natively --------------------------------
    @property
    def sym_fixed(self) -> int:
        """The agents symmetry keeps in place (:attr:`pccl.model.reduce.Plan.fixed`)."""
        return int(getattr(getattr(self.m, "reduction", None), "fixed", 0))

    def reductions(self) -> tuple:
        """(por, merge, symmetry slots or None) of the model's reductions: the
        ample-set and merge tests of :class:`pccl.model.reduce.Por` and
        :class:`~pccl.model.reduce.Merger` asked per pc (so the tables are
        theirs), the id slots of :func:`~pccl.model.reduce.symmetry_problem`."""
        from pccl.model import reduce as RD
        on = getattr(getattr(self.m, "reduction", None), "on", ())
        base = RD.unreduced(self.m)
        npc = len(self.m.ctl.cells)
        por = merge = None
        if "por" in on:
            por = self.por_tables(base, npc)
        if "merge" in on:
            mg = RD.Merger(base)
            merge = [bool(mg.pc_ok(pc)) for pc in range(npc)]
            self.rand_unchained(merge, por)
        sym = None
        if "symmetry" in on:
            why, slots = RD.symmetry_problem(base, pointed=bool(self.sym_fixed))
            if why is not None or slots is None:
                raise Unsupported(f"symmetry: {why}")
            loc_s, ar_s, sh_s, _self_only, motion = slots
            if motion and not self.moves:
                raise Unsupported("symmetry over positions that are not in the native vector")
            sym = ([4 + k for k in loc_s] + [4 + self.L + k for k in ar_s],
                   [self.SH0 + k for k in sh_s])
        return por, merge, sym

    def rand_unchained(self, merge: list, por: Optional[dict]) -> None:
        """Unsupported when a merged chain may run a statement that draws
        ``rand()`` (Merger._chain branches there, one merged transition per
        outcome; C's chain follows one successor): a step at a pc merging
        allows, or one partial-order reduction may move (its class)."""
        from pccl.model.compile import has_rand
        from pccl.model import independence as I
        movable = (I.ACCESS, I.REQUEST_LOCK, I.RELEASE, I.EXECUTE)
        for pc in range(len(merge)):
            h = self.m.ctl.info(pc)
            if h.kind not in MEMO_KINDS or h.sid is None or not has_rand(self.c.stmts[h.sid]):
                continue
            if merge[pc] or (por is not None and (por["cls"][pc] in movable or por["spent"][pc])):
                raise Unsupported(f"rand() in a statement that statement merging runs through "
                                  f"(line {self.c.stmts[h.sid].span.line}: a merged chain "
                                  "branches at each outcome in the Python engine only)")

    def por_tables(self, base, npc: int) -> dict:
        """The tables of :class:`pccl.model.independence.Independence` (the
        analysis :class:`pccl.model.reduce.Por` decides with), per pc: the
        step's class, reads and writes, the rest's reads, writes and whether
        it ends the event, whether the step writes the stall signature's
        data; per event its reads and writes.  One bit per shared/allread
        variable and the lock bit: at most 64."""
        from pccl.model.independence import Independence
        ind = Independence(base)
        top = 1
        for b in ind.bit.values():
            top = max(top, b)
        if top >= 1 << 64:
            raise Unsupported("partial-order reduction over more than 63 shared and allread variables")
        steps = [ind.step(pc) for pc in range(npc)]
        rests = [ind.rest(pc) for pc in range(npc)]
        return {"cls": [x[0] for x in steps], "sr": [x[1] for x in steps], "sw": [x[2] for x in steps],
                "rr": [x[0] for x in rests], "rw": [x[1] for x in rests], "ends": [x[2] for x in rests],
                "writer": [pc in ind.writers for pc in range(npc)],
                "spent": [ind.spent_local(pc) for pc in range(npc)],
                "empty": [self.m.ctl.info(pc).kind == K_EMPTY for pc in range(npc)],
                "evr": [x[0] for x in ind.event_fps], "evw": [x[1] for x in ind.event_fps],
                "er": ind.events[0], "ew": ind.events[1], "gr": ind.guard_reads,
                "local": bool(ind.guards_local)}

    def por_c(self, por: Optional[dict]) -> list:
        """C of the per-state ample test (reduce.Por.eligible, footprint,
        movable; independence.may_wait) over the tables of :meth:`por_tables`."""
        from pccl.model import independence as I
        if por is None:
            return ["static const unsigned char PSPENT[] = {0};",     # what merging reads of por
                    "static inline int movable(const V *s, int i) { (void)s; (void)i; return 0; }"]
        m = self.m
        u64 = "uint64_t"
        out = [self.c_array("PCLS", "unsigned char", por["cls"]),
               self.c_array("PSR", u64, por["sr"]).replace(",", "ULL,").replace("}", "ULL}"),
               self.c_array("PSW", u64, por["sw"]).replace(",", "ULL,").replace("}", "ULL}"),
               self.c_array("PRR", u64, por["rr"]).replace(",", "ULL,").replace("}", "ULL}"),
               self.c_array("PRW", u64, por["rw"]).replace(",", "ULL,").replace("}", "ULL}"),
               self.c_array("PENDS", "unsigned char", por["ends"]),
               self.c_array("PWRITER", "unsigned char", por["writer"]),
               self.c_array("PEMPTY", "unsigned char", por["empty"]),
               self.c_array("PSPENT", "unsigned char", por["spent"]),
               f"#define EVR_ALL {por['er']}ULL", f"#define EVW_ALL {por['ew']}ULL",
               f"#define GUARDR {por['gr']}ULL", f"#define GUARDS_LOCAL {int(por['local'])}",
               f"#define TOP_PC {m.ctl.empty_pc}", f"#define LQ_BIT {I.LQ_BIT}ULL",
               f"#define C_NEVER {I.NEVER}", f"#define C_LOCAL {I.LOCAL}", f"#define C_ACCESS {I.ACCESS}",
               f"#define C_REQUEST {I.REQUEST_LOCK}", f"#define C_RELEASE {I.RELEASE}",
               f"#define C_EXECUTE {I.EXECUTE}",
               f"#define L_LOCK {LOCK}", f"#define L_REQUEST {REQUEST}",
               # an agent's block of the vector: pc, counter, lock state, status, locals
               "#define VA_PC 0", "#define VA_LCK 2"]
        # the events agent j at the top of its block selects next (local guards)
        out.append("static void evfp(int j, const V *s, uint64_t *r, uint64_t *w) {")
        out.append("  *r = GUARDR; *w = 0; (void)j; (void)s;")
        if por["local"]:
            out.append("  switch (j) {")
            for j in range(self.N):
                out.append(f"  case {j}: {{")
                for e, ev in enumerate(self.c.program.events):
                    hit = " return;" if m.first_only else ""
                    out.append(f"    if ({self.expr(ev.guard, j)}) {{ *r |= {por['evr'][e]}ULL; "
                               f"*w |= {por['evw'][e]}ULL;{hit} }}")
                out.append("    break; }")
            out.append("  }")
        out.append("}")
        out.append('#include "por.c"')
        return out

    def dead_c(self) -> list:
        """C of ``dead_bits(s, d)`` and ``dead_apply(s, d)`` (:class:`pccl.model.dead.DeadVars`:
        every agent's dead values in the vector set to DEADV, before the
        key; no copy of a state where nothing is dead), over the analysis'
        tables, every row of them, and the guards."""
        m = self.m
        if "dead" not in getattr(getattr(m, "reduction", None), "on", ()):
            return ["#define DEAD 0"]
        from pccl.model.dead import DeadVars
        from pccl.model.reduce import unreduced
        d = getattr(m, "dead_vars", None) or DeadVars(unreduced(m))   # the Reduced's own tables
        if d.nloc > 63:
            raise Unsupported("the dead-variable reduction over more than 63 loc: variables")
        rows = 1 << len(d.cond)
        npc = len(m.ctl.cells)
        u64 = "uint64_t"

        def arr(name: str, vals: list) -> str:
            return self.c_array(name, u64, vals).replace(",", "ULL,").replace("}", "ULL}")
        out = ["#define DEAD 1", "#define DEADV (INT64_MIN + 3)", f"#define DROWS {rows}",
               *([arr("LIVEEV", [d.entry(e, r) for e in range(len(d.events)) for r in range(rows)])]
                 if d.local_guards else []),
               f"#define DKEEP {d.keep}ULL", f"#define DALL {d.all}ULL", f"#define DGR {d.guard_reads}ULL",
               f"#define DTOP {d.top}ULL"]
        # dead_bits: per agent the mask of its dead values (nonzero: some)
        out.append(arr("DEADPC", [d.all & ~(d.live_pc(pc, r) | d.keep)
                                  for pc in range(npc) for r in range(rows)]))
        out.append("static int dead_bits(const V *s, uint64_t *d) {")
        out.append(f"  {'uint64_t live; ' if d.local_guards else ''}int row; uint64_t any = 0; const V *b;")
        for j in range(self.N):
            a0 = self.AG0 + j * self.A
            row = " | ".join(f"((s[{a0 + 4 + q}] == 1) << {k})" for k, q in enumerate(d.cond_slots)) or "0"
            out.append(f"  b = s + {a0};")
            out.append(f"  if (b[3] != {RUNNING}) d[{j}] = b[3] == {EXITED} ? DALL & ~DKEEP : 0;")
            out.append(f"  else if (b[0] == {m.ctl.empty_pc} || b[0] == {m.ctl.idle_pc}) {{")
            if d.local_guards:
                out.append(f"    int o = ovf; uint64_t ev = 0; row = {row};")
                for e, ev in enumerate(m.program.events):
                    hit = f" goto top{j};" if m.first_only else ""
                    out.append(f"    if ({self.expr(ev.guard, j)}) {{ ev |= 1ULL << {e};{hit} }}")
                if m.first_only:
                    out.append(f"  top{j}:")
                out.append(f"    if (ovf && !o) {{ ovf = 0; ev = {(1 << len(d.events)) - 1}ULL; }}")
                out.append("    live = DGR;")
                out.append(f"    for (int e = 0; e < {len(d.events)}; e++) "
                           "if (ev >> e & 1) live |= LIVEEV[e * DROWS + row];")
                out.append(f"    d[{j}] = DALL & ~(live | DKEEP);")
            else:
                out.append(f"    d[{j}] = DALL & ~(DTOP | DKEEP);")
            out.append(f"  }} else {{ row = {row}; "
                       f"d[{j}] = (uint64_t)b[0] < NPC ? DEADPC[b[0] * DROWS + row] : 0; }}")
            if self.moves:      # a reach is masked only where the robot has arrived or failed
                out.append(f"  if (!(b[{self.MV + 4}] || b[{self.MV + 5}])) d[{j}] &= ~(1ULL << NLOC);")
            out.append(f"  any |= d[{j}];")
        out.append("  return any != 0;")
        out.append("}")
        # dead_apply: those values set to DEADV (the reach: target, t0, flags)
        mv = self.MV
        reach = (f"b[{mv + 1}] = DEADV; b[{mv + 3}] = DEADV; b[{mv + 4}] = DEADV; b[{mv + 5}] = DEADV;"
                 if self.moves else "")
        out += ["static void dead_apply(V *s, const uint64_t *d) {",
                "  for (int j = 0; j < NAG; j++) {",
                "    uint64_t x = d[j];",
                "    if (!x) continue;",
                "    V *b = s + AG0 + AW * j;",
                f"    if (x >> NLOC & 1) {{ {reach} }}",
                "    x &= ~(1ULL << NLOC);",
                "    while (x) { b[4 + __builtin_ctzll(x)] = DEADV; x &= x - 1; }",
                "  }",
                "}"]
        return out

    @staticmethod
    def c_array(name: str, ctype: str, vals: list) -> str:
        """A C constant array (one dummy element when ``vals`` is empty)."""
        body = ", ".join(str(int(v)) for v in vals) or "0"
        return f"static const {ctype} {name}[] = {{{body}}};"

    def reduced_c(self) -> str:
        """C of the reduced step ``rstep`` (partial-order reduction, then
        statement merging, as :class:`pccl.model.reduce.Reduced` composes
        them), the canonical key ``canon`` (symmetry) and the stall
        signature ``sigstall``."""
        m, N, A_ = self.m, self.N, self.A
        if any(type(x) is not int for x in (*m.rho, m.n0)):
            raise Unsupported("a rate or n0 that is not an integer")
        por, merge, sym = self.reductions()
        npc = len(m.ctl.cells)
        out = [f"#define NPC {npc}", f"#define AG0 {self.AG0}", f"#define AW {A_}",
               f"#define NLOC {self.L}", f"#define KEEPN0 {m.n0}",
               f"#define POR {int(por is not None)}", f"#define MERGE {int(merge is not None)}",
               f"#define SYM {int(sym is not None)}",
               f"#define SYMFIX {self.sym_fixed if sym is not None else 0}",
               f"#define MERGE_LIMIT {MERGE_LIMIT}",
               f"#define NBID {len(sym[0]) if sym else 0}",
               f"#define NSHID {len(sym[1]) if sym else 0}"]
        # the tables and functions of the reductions that are on (no unused one)
        if por is not None or merge is not None:
            out.append(self.c_array("RHO", "V", list(m.rho)))
        if sym is not None:
            out += [self.c_array("BID", "int", sym[0]), self.c_array("SHID", "int", sym[1])]
        if merge is not None:
            out += [self.c_array("MERGEOK", "unsigned char", merge),
                    "static int agent_of(int i, const V *s) {", "  switch (i) {",
                    *(f"  case {i}: return agent{i}(s);" for i in range(N)),
                    "  }", "  return 0;", "}"]
        if por is not None or merge is not None:
            out += self.por_c(por)
        out += self.dead_c()
        ctr = getattr(m, "counters", None) if "counters" in getattr(getattr(m, "reduction", None), "on", ()) else None
        out += ctr.c_source(self.AG0, A_, N) if ctr is not None else ["#define CTRS 0"]
        # the ample set (Por.successors): the first agent with an execution
        # left whose next step is independent of what the others can still
        # do; else the first spent agent whose next step is a plain statement
        # of its own (Independence.spent_local)
        def try_agent(i: int, cond: str) -> str:
            a0 = self.AG0 + i * A_
            return (f"    if (s[{a0 + 3}] == {RUNNING} && {cond}) {{\n"
                    f"      if (agent{i}(s)) return -1;\n"
                    f"      int all = BN > b0;\n"
                    f"      for (Py_ssize_t k = b0; k < BN && all; k++) all = BUF[NS * k + {a0 + 3}] == {RUNNING};\n"
                    f"      if (all) return 1;\n"
                    f"      BN = b0;\n"
                    f"    }}")
        ample = [try_agent(i, f"s[{self.AG0 + i * A_ + 1}] <= {m.n0 - m.rho[i]} && eligible(s, {i})")
                 for i in range(N)]
        if por is not None:
            ample += [try_agent(i, f"s[{a0 + 1}] > {m.n0 - m.rho[i]} && (uint64_t)s[{a0}] < NPC "
                                   f"&& PSPENT[s[{a0}]]")
                      for i in range(N) for a0 in (self.AG0 + i * A_,)]
        # the stall signature (pccl/model/stall.py): the lock queue, shared,
        # and per agent its status, allread and the loc: variables a property reads
        from pccl.model.stall import _visible_locals
        from pccl.model.reduce import unreduced
        vis = _visible_locals(unreduced(m))
        slots = list(range(self.LQ0, self.AG0))
        for i in range(N):
            a0 = self.AG0 + i * A_
            slots += [a0 + 3] + [a0 + 4 + k for k in vis] + \
                [a0 + 4 + self.L + k for k in range(self.R)]
            if self.moves:      # position, target, done, fail
                slots += [a0 + self.MV, a0 + self.MV + 1, a0 + self.MV + 4, a0 + self.MV + 5]
        out.append(self.c_array("SIGSLOTS", "int", slots))
        out.append(f"#define NSIGSLOTS {len(slots)}")
        # the frozen-team check's progress signature (pccl/model/frozen.py): the
        # same without the lock queue, the env and the doReach flags
        pslots = list(range(self.SH0, self.SH0 + len(self.lay.shared)))
        for i in range(N):
            a0 = self.AG0 + i * A_
            pslots += [a0 + 3] + [a0 + 4 + k for k in vis] + \
                [a0 + 4 + self.L + k for k in range(self.R)]
            if self.moves:      # position, target
                pslots += [a0 + self.MV, a0 + self.MV + 1]
        out.append(self.c_array("PSIGSLOTS", "int", pslots))
        out.append(f"#define NPSIGSLOTS {len(pslots)}")
        # (the native engine's own re-exploration of the frozen-team check
        # reads the same slots: native_c/module.c's progsig)
        out.append("#define PROGSLOTS PSIGSLOTS")
        out.append("#define NPROGSLOTS NPSIGSLOTS")
        if por is not None:     # rstep's ample set: 1 found (its successors in the buffer), -1 an error
            out += ["static inline int ample(const V *s, Py_ssize_t b0) {", *ample, "  return 0;", "}"]
        out.append('#include "reduced.c"')
        return "\n".join(out)

    def source(self) -> str:
        m = self.m
        m.prepare()                 # every k cell interned
        self.check()
        N, NS = self.N, self.NS
        agents = []
        for i in range(N):
            agents += self.agent_code(i)
        ta = self.lab(("TIME ADVANCE", None, None))
        dr = self.lab(("DOREACH INVOKE", None, 0))
        blocked = []
        running = []
        for i in range(N):
            A_ = self.AG0 + i * self.A
            cap = m.n0 - m.rho[i]
            running.append(f"s[{A_ + 3}] == {RUNNING}")
            blocked.append(f"(s[{A_ + 3}] != {EXITED} && s[{A_ + 1}] <= {cap})")
        max_ticks = m.max_ticks
        tcheck = ("1" if max_ticks is None
                  else f"(s[{V_TIME}] / {m.delta} + 1 <= {max_ticks}LL)")
        oks = [f"s[{self.AG0 + i * self.A + 3}] < {STUCK}" for i in range(N)]
        lq_ok = " && ".join(
            f"(s[{self.LQ0}] != {i} || s[{self.AG0 + i * self.A + 3}] != {EXITED})"
            for i in range(N))
        props = " && ".join(f"({self.pexpr(p.expr, {})})" for p in m.properties) or "1"
        if m.collisions:
            props += f" && {self.collision_site()}"
        reduced = self.reduced_c()
        if self.moves:
            envc = "    " + self.env_site()
        else:
            envc = (f"    V t[NS]; memcpy(t, s, sizeof t);\n    t[1] = {DISCRETE};\n"
                    f"    for (int j = 0; j < NAG; j++) t[{self.AG0 + 1} + {self.A} * j] = 0;\n"
                    f"    if (EMIT({dr}, t)) return -1;")
        agent_calls = "\n".join(
            f"    if (s[{self.AG0 + i * self.A + 3}] == {RUNNING} && agent{i}(s)) return -1;"
            for i in range(N))
        ok = " && ".join(oks) + f" && ({lq_ok}) && ({props})"
        # (before the property memo sites' declarations are written: the
        # temporal columns' predicates may add sites of their own)
        tcols = self.temporal_c()
        return "\n".join([
            "/* pccl native engine: the module of one program, generated by pccl/model/native.py;",
            "   the fixed C it includes is pccl/model/native_c/ (native.h says how the two meet) */",
            f"#define NS {NS}", f"#define NAG {N}", f"#define LQ0 {self.LQ0}",
            # the key: the vector without the clock under time abstraction (one module per key)
            f"#define KEYSKIP {8 if m.abstract_time else 0}",
            f"#define PACK {1 if self.packs else 0}",
            "#define VMIN (INT64_MIN + 4)",         # V_MIN
            f"#define V_TIME {V_TIME}", f"#define V_PHASE {V_PHASE}",
            f"#define PH_DISCRETE {DISCRETE}", f"#define S_RUNNING {RUNNING}",
            '#include "native.h"',
            '#include "memo.c"',
            '#include "robots.c"',
            *agents,
            "/* the successors of s, emitted into OUT; -1 on an error (ovf or Python's) */",
            "static int step(const V *s) {",
            "  if (s[V_PHASE] == PH_DISCRETE) {",
            agent_calls,
            f"    if (({' || '.join(running)}) && !({' || '.join(blocked)}) && {tcheck}) {{",
            "      V t[NS]; memcpy(t, s, sizeof t);",
            f"      t[V_TIME] = ADD(s[V_TIME], {m.delta}); t[V_PHASE] = {DYNAMIC};",
            f"      if (EMIT({ta}, t)) return -1;",
            "    }",
            "  } else {",
            envc,
            "  }",
            "  return ovf ? -1 : 0;",
            "}",
            reduced,
            *self.pdecls,
            "/* no agent stuck, the lock's holder not exited, every invariant holds */",
            "static inline int okexpr(const V *s) {",
            f"  return {ok};",
            "}",
            '#include "temporal.h"',
            tcols,
            '#include "temporal.c"',
            '#include "module.c"',
            '#include "kernel.c"',
            ""])


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


_ = Any
