"""The native engine: a model's successor function and its fast violation
check generated as C, compiled at run time with the system C compiler into
a CPython extension module (cached by the hash of its source, as SPIN
compiles ``pan.c``), for programs whose configuration is a fixed vector of
integers.

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
engine's by construction of the same BFS order (tests/test_native.py checks
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

import hashlib
import marshal
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import importlib.util
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
from pccl.model.toolchain import compiler, native_unavailable
from pccl.lang.cachedir import cache_dir, private_cache_dir, private_file

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

MAX_AGENTS = 16
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
    why = native_unavailable()
    if why is not None:
        return why
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
                     ("key", None if {"symmetry", "dead"} & set(model.reduction.on) else base.plain_key)):
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

    # -- support -----------------------------------------------------------------
    def check(self) -> None:
        m = self.m
        if self.N > MAX_AGENTS:
            raise Unsupported(f"more than {MAX_AGENTS} agents")
        if m.collisions:
            raise Unsupported("collision checking")
        if m.temporal:
            raise Unsupported("a temporal property")
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
        for p in m.properties:
            if p.expr is None:
                raise Unsupported(f"invariant '{p.name}' has no expression")
            try:
                self.pexpr(p.expr, {})
            except Unsupported as e:
                raise Unsupported(f"invariant '{p.name}': {e}") from None
        self.env_constant()

    def stmt_ok(self, s) -> None:
        from pccl.model.compile import has_rand
        if has_rand(s) and not isinstance(s, (A.Atomic,)):
            raise Unsupported(f"rand() in a statement (line {s.span.line})")
        if isinstance(s, A.CallStmt) and s.name not in ("exit", "assert") and not (
                s.name in ("doReach", "add", "remove") and self.memo_reads(s) is not None):
            raise Unsupported(f"the statement {s.name}() (line {s.span.line})")
        if isinstance(s, A.Assign) and not isinstance(s.target, A.Name):
            raise Unsupported(f"an indexed assignment (line {s.span.line})")

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

    def pexpr(self, e, bound: dict) -> str:
        """C for a property expression (``bound``: quantified name -> agent)."""
        if isinstance(e, (A.BoolLit, A.IntLit)):
            return self.expr(e, 0)
        if isinstance(e, A.Name):
            return self.pname(e, bound)
        if isinstance(e, A.Unary):
            x = self.pexpr(e.operand, bound)
            return f"((V)!{x})" if e.op == "!" else f"NEG({x})"
        if isinstance(e, A.Binary):
            return self.binop(e.op, self.pexpr(e.left, bound), self.pexpr(e.right, bound))
        if isinstance(e, A.Quant):
            terms = [self.pexpr(e.body, {**bound, e.var: q}) for q in range(self.N)]
            op = " && " if e.kind == "forall" else " || "
            return "((V)(" + op.join(f"({t})" for t in terms) + "))"
        if isinstance(e, A.Call) and e.name == "count" and len(e.args) == 1 \
                and isinstance(e.args[0], A.Name):
            return self.pcount(e.args[0])
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
    def memo_reads(self, s) -> Optional[list]:
        """The variables statement ``s``'s rule reads beyond the agent's own
        block and shared ((name, every agent) for an agent-indexed read), or
        None when it reads what a memo key cannot hold (rand)."""
        from pccl.model.compile import has_rand
        if has_rand(s):
            return None
        out: list = []
        for x in _stmt_exprs(s):
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
        s = self.c.stmts[h.sid]
        extra = self.memo_reads(s)
        if extra is None:
            raise Unsupported(f"rand() in a statement (line {s.span.line})")
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
        sym = None
        if "symmetry" in on:
            why, slots = RD.symmetry_problem(base)
            if why is not None or slots is None:
                raise Unsupported(f"symmetry: {why}")
            loc_s, ar_s, sh_s, _self_only, motion = slots
            if motion and not self.moves:
                raise Unsupported("symmetry over positions that are not in the native vector")
            sym = ([4 + k for k in loc_s] + [4 + self.L + k for k in ar_s],
                   [self.SH0 + k for k in sh_s])
        return por, merge, sym

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
            return ["static const unsigned char PSPENT[] = {0};",
                    "static int eligible(const V *s, int i) { (void)s; (void)i; return 0; }",
                    "static int movable(const V *s, int i) { (void)s; (void)i; return 0; }"]
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
               f"#define S_RUNNING {RUNNING}", f"#define L_LOCK {LOCK}", f"#define L_REQUEST {REQUEST}",
               # an agent's block of the vector: pc, counter, lock state, status, locals
               "#define VA_PC 0", "#define VA_LCK 2"]
        # the events agent j at the top of its block selects next (local guards)
        out.append("static void evfp(int j, const V *s, uint64_t *r, uint64_t *w) {")
        out.append("  *r = GUARDR; *w = 0;")
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
        else:
            out.append("  (void)j; (void)s;")
        out.append("}")
        out.append(_POR_C)
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
               arr("LIVEEV", [d.entry(e, r) for e in range(len(d.events)) for r in range(rows)]),
               f"#define DKEEP {d.keep}ULL", f"#define DALL {d.all}ULL", f"#define DGR {d.guard_reads}ULL",
               f"#define DTOP {d.top}ULL"]
        # dead_bits: per agent the mask of its dead values (nonzero: some)
        out.append(arr("DEADPC", [d.all & ~(d.live_pc(pc, r) | d.keep)
                                  for pc in range(npc) for r in range(rows)]))
        out.append("static int dead_bits(const V *s, uint64_t *d) {")
        out.append("  uint64_t live; int row; uint64_t any = 0; const V *b;")
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
               f"#define MERGE_LIMIT {MERGE_LIMIT}",
               self.c_array("MERGEOK", "unsigned char", merge or []),
               self.c_array("RHO", "V", list(m.rho)),
               self.c_array("BID", "int", sym[0] if sym else []),
               self.c_array("SHID", "int", sym[1] if sym else []),
               f"#define NBID {len(sym[0]) if sym else 0}",
               f"#define NSHID {len(sym[1]) if sym else 0}",
               "static int agent_of(int i, const V *s) {", "  switch (i) {"]
        out += [f"  case {i}: return agent{i}(s);" for i in range(N)]
        out += ["  }", "  return 0;", "}"]
        out += self.por_c(por)
        out += self.dead_c()
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
                    f"      if (all) goto chains;\n"
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
        out.append(_REDUCED_C.replace("@AMPLE@", "\n".join(ample))
                   .replace("@RUNNING@", str(RUNNING)).replace("@DISCRETE@", str(DISCRETE))
                   .replace("@V_PHASE@", str(V_PHASE)))
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
        return f"""/* pccl native engine: generated by pccl/model/native.py */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>
#include <stdlib.h>
typedef int64_t V;
#define NS {NS}
#define NAG {N}
#define LQ0 {self.LQ0}
/* the key: the vector without the clock under time abstraction (a constant
   of the source: one module per key) */
#define KEYSKIP {8 if m.abstract_time else 0}
/* per thread: the level kernel (explore_levels) runs the successor code on
   several threads at once, each with its own overflow flag and buffer; KT
   is set while a thread runs it without the GIL (no Python call then) */
static __thread int ovf;
static __thread int KT;
static PyObject *OverflowExc;
/* ints: VMIN..INT64_MAX; below VMIN the reserved codes (undefined, the
   symmetry signature's MSELF and MOTHER, dead's DEADV): a result out of
   range is an overflow (the Python engine runs) */
#define VMIN (INT64_MIN + 4)
static inline V ADD(V a, V b) {{ V r; if (__builtin_add_overflow(a, b, &r) || r < VMIN) ovf = 1; return r; }}
static inline V SUB(V a, V b) {{ V r; if (__builtin_sub_overflow(a, b, &r) || r < VMIN) ovf = 1; return r; }}
static inline V MUL(V a, V b) {{ V r; if (__builtin_mul_overflow(a, b, &r) || r < VMIN) ovf = 1; return r; }}
static inline V NEG(V a) {{ if (a < -INT64_MAX || -a < VMIN) {{ ovf = 1; return 0; }} return -a; }}
static inline V DIV(V a, V b) {{
  if (b == 0 || (a == INT64_MIN && b == -1)) {{ ovf = 1; return 0; }}
  V r = a / b; if (r < VMIN) ovf = 1; return r;
}}
static inline V MOD(V a, V b) {{ if (b == 0 || (a == INT64_MIN && b == -1)) {{ ovf = 1; return 0; }} return a % b; }}
static inline V AIX(V j) {{ if (j < 0 || j >= NAG) {{ ovf = 1; return 0; }} return j; }}
static inline V U(V a) {{ if (a == INT64_MIN) ovf = 1; return a; }}
static void lq_append(V *t, V i) {{ for (int k = 0; k < NAG; k++) if (t[LQ0 + k] < 0) {{ t[LQ0 + k] = i; return; }} }}
static void lq_remove(V *t, V i) {{
  int w = 0;
  for (int k = 0; k < NAG; k++) if (t[LQ0 + k] >= 0 && t[LQ0 + k] != i) t[LQ0 + w++] = t[LQ0 + k];
  for (; w < NAG; w++) t[LQ0 + w] = -1;
}}
/* the successor buffer: step() and rstep() append each successor's vector,
   its label, its place in the unmerged relation and its merged chain length */
static __thread V *BUF;
static __thread int32_t *BLAB, *BIDX, *BCH;
static __thread Py_ssize_t BN, BCAP;
static int grow(void) {{
  Py_ssize_t cap = BCAP ? 2 * BCAP : 1024;
  V *b = realloc(BUF, sizeof(V) * NS * cap);
  if (!b) {{ if (!KT) PyErr_NoMemory(); return -1; }}
  BUF = b;
  int32_t *x[3] = {{BLAB, BIDX, BCH}};
  for (int q = 0; q < 3; q++) {{
    int32_t *y = realloc(x[q], sizeof(int32_t) * cap);
    if (!y) {{ if (!KT) PyErr_NoMemory(); return -1; }}
    x[q] = y;
  }}
  BLAB = x[0]; BIDX = x[1]; BCH = x[2];
  BCAP = cap;
  return 0;
}}
static inline int EMIT(int lab, const V *t) {{
  if (BN == BCAP && grow()) return -1;
  memcpy(BUF + NS * BN, t, sizeof(V) * NS);
  BLAB[BN] = lab; BIDX[BN] = 0; BCH[BN] = 0;
  BN++;
  return 0;
}}
/* A state as Python holds it (NativeModel.pack's form): int32 slots when
   every slot fits (undefined, INT64_MIN, as INT32_MIN), else int64.  Half
   the bytes, and a 64-slot state then fits CPython's small-object
   allocator instead of malloc.  The slots' values, not the bytes, are the
   state: fingerprints, keys and memo keys read the int64 vector. */
#define PACK {1 if self.packs else 0}
static PyObject *state_bytes(const V *t) {{
  int fit = PACK;
  for (int q = 0; q < NS; q++) fit &= (t[q] == INT64_MIN) | ((t[q] > INT32_MIN) & (t[q] <= INT32_MAX));
  if (!fit) return PyBytes_FromStringAndSize((const char *)t, sizeof(V) * NS);
  PyObject *b = PyBytes_FromStringAndSize(NULL, sizeof(int32_t) * NS);
  if (!b) return NULL;
  int32_t *p = (int32_t *)PyBytes_AS_STRING(b);
  for (int q = 0; q < NS; q++) p[q] = t[q] == INT64_MIN ? INT32_MIN : (int32_t)t[q];
  return b;
}}
/* the int64 vector of state arg: in place, or unpacked into buf; NULL
   when it is not a state of this model, without a Python error (the level
   kernel's threads call it without the GIL) */
static const V *raw_state(PyObject *arg, V *buf) {{
  if (!PyBytes_Check(arg)) return NULL;
  Py_ssize_t n = PyBytes_GET_SIZE(arg);
  if (PACK && n == (Py_ssize_t)(sizeof(int32_t) * NS)) {{
    const int32_t *p = (const int32_t *)PyBytes_AS_STRING(arg);
    for (int q = 0; q < NS; q++) buf[q] = p[q] == INT32_MIN ? INT64_MIN : (V)p[q];
    return buf;
  }}
  return n == (Py_ssize_t)(sizeof(V) * NS) ? (const V *)PyBytes_AS_STRING(arg) : NULL;
}}
/* ... with the Python error */
static const V *arg_state(PyObject *arg, V *buf) {{
  const V *s = raw_state(arg, buf);
  if (!s) PyErr_SetString(PyExc_TypeError, "not a native state of this model");
  return s;
}}
{_MEMO_C}
{chr(10).join(agents)}
/* the successors of s, emitted into OUT; -1 on an error (ovf or Python's) */
static int step(const V *s) {{
  if (s[{V_PHASE}] == {DISCRETE}) {{
{agent_calls}
    if (({' || '.join(running)}) && !({' || '.join(blocked)}) && {tcheck}) {{
      V t[NS]; memcpy(t, s, sizeof t);
      t[{V_TIME}] = ADD(s[{V_TIME}], {m.delta}); t[{V_PHASE}] = {DYNAMIC};
      if (EMIT({ta}, t)) return -1;
    }}
  }} else {{
{envc}
  }}
  return ovf ? -1 : 0;
}}
static void overflowed(void) {{
  if (ovf && !PyErr_Occurred())
    PyErr_SetString(OverflowExc, "an int beyond 64 bits, a division by zero or an undefined value");
}}
{reduced}
/* the label of buffer entry k: the rule's, or (rule, agent, detail, idx0,
   (0,) * chain length) for a merged transition (reduce.Merger's) */
static PyObject *label_of(Py_ssize_t k) {{
  PyObject *l = PyList_GET_ITEM(LABELS, BLAB[k]);
  if (!BCH[k]) {{ Py_INCREF(l); return l; }}
  PyObject *ch = PyTuple_New(BCH[k]);
  if (!ch) return NULL;
  for (Py_ssize_t q = 0; q < BCH[k]; q++) PyTuple_SET_ITEM(ch, q, PyLong_FromLong(0));
  return Py_BuildValue("(OOOiN)", PyTuple_GET_ITEM(l, 0), PyTuple_GET_ITEM(l, 1),
                       PyTuple_GET_ITEM(l, 2), (int)BIDX[k], ch);
}}
static PyObject *successors(PyObject *self, PyObject *arg) {{
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  BN = 0; ovf = 0;
  if (rstep(s)) {{ overflowed(); return NULL; }}
  PyObject *out = PyList_New(BN);
  if (!out) return NULL;
  for (Py_ssize_t k = 0; k < BN; k++) {{
    PyObject *b = state_bytes(BUF + NS * k);
    PyObject *l = label_of(k);
    if (!b || !l) {{ Py_XDECREF(b); Py_XDECREF(l); Py_DECREF(out); return NULL; }}
    PyList_SET_ITEM(out, k, Py_BuildValue("(NN)", l, b));
  }}
  return out;
}}
/* expand(states): (successor counts, the successors of all in order, the
   labels met): one call per chunk of a level */
static PyObject *expand(PyObject *self, PyObject *arg) {{
  if (!PyList_Check(arg)) {{ PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }}
  Py_ssize_t n = PyList_GET_SIZE(arg), seen = 0;
  PyObject *ns = PyList_New(n), *flat = PyList_New(0), *labs = NULL;
  if (!ns || !flat) goto fail;
  memset(LABSEEN, 0, NLABELS);
  ovf = 0;
  for (Py_ssize_t i = 0; i < n; i++) {{
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) goto fail;
    BN = 0;
    if (rstep(s)) goto fail;
    for (Py_ssize_t k = 0; k < BN; k++) {{
      PyObject *b = state_bytes(BUF + NS * k);
      if (!b) goto fail;
      int r = PyList_Append(flat, b);
      Py_DECREF(b);
      if (r) goto fail;
      LABSEEN[BLAB[k]] = 1;
    }}
    PyObject *c = PyLong_FromSsize_t(BN);
    if (!c) goto fail;
    PyList_SET_ITEM(ns, i, c);
  }}
  for (Py_ssize_t k = 0; k < NLABELS; k++) seen += LABSEEN[k];
  labs = PyTuple_New(seen);
  if (!labs) goto fail;
  for (Py_ssize_t k = 0, w = 0; k < NLABELS; k++)
    if (LABSEEN[k]) {{
      PyObject *l = PyList_GET_ITEM(LABELS, k);
      Py_INCREF(l);
      PyTuple_SET_ITEM(labs, w++, l);
    }}
  return Py_BuildValue("(NNN)", ns, flat, labs);
fail:
  Py_XDECREF(ns); Py_XDECREF(flat);
  overflowed();
  return NULL;
}}
/* key(state): the state's identity: the canonical vector (symmetry), without
   the clock under time abstraction */
static PyObject *key(PyObject *self, PyObject *arg) {{
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  V c[NS];
  canon(s, c);
  return PyBytes_FromStringAndSize((const char *)c + KEYSKIP, sizeof(V) * NS - KEYSKIP);
}}
/* xxhash's XXH3_128bits (setup() passes its address; NULL when the xxhash
   module does not export it) */
typedef struct {{ uint64_t lo, hi; }} H128;
typedef H128 (*xxh128_fn)(const void *, size_t);
static xxh128_fn XXH;
/* the stall signature's hash (pccl/model/stall.py's fields): xxh3 of the
   signature's slots gathered, else a slot-by-slot mix (equal signatures
   give equal hashes either way; only equality is read) */
static int64_t sighash(const V *s) {{
  if (XXH) {{
    V g[NSIGSLOTS];
    for (int q = 0; q < NSIGSLOTS; q++) g[q] = s[SIGSLOTS[q]];
    H128 x = XXH(g, sizeof g);
    return (int64_t)(x.lo ^ x.hi);
  }}
  uint64_t h = 0x9E3779B97F4A7C15ULL;
  for (int q = 0; q < NSIGSLOTS; q++) {{
    uint64_t z = (uint64_t)s[SIGSLOTS[q]] + 0x9E3779B97F4A7C15ULL * (uint64_t)(q + 1);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    h = (h ^ (z ^ (z >> 31))) * 0x100000001B3ULL;
    h ^= h >> 29;
  }}
  return (int64_t)h;
}}
/* packed(state): the state's bytes in the form the explorer holds (state_bytes) */
static PyObject *packed(PyObject *self, PyObject *arg) {{
  V sb[NS]; const V *s = arg_state(arg, sb);
  return s ? state_bytes(s) : NULL;
}}
/* unpacked(state): the state's int64 vector, as bytes (arg_state) */
static PyObject *unpacked(PyObject *self, PyObject *arg) {{
  V sb[NS]; const V *s = arg_state(arg, sb);
  return s ? PyBytes_FromStringAndSize((const char *)s, sizeof(V) * NS) : NULL;
}}
/* sig(state): the stall signature's hash */
static PyObject *sig(PyObject *self, PyObject *arg) {{
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  return PyLong_FromLongLong((long long)sighash(s));
}}
/* sigs(states): sig of each state of a list, as int64s in one bytes object */
static PyObject *sigs(PyObject *self, PyObject *arg) {{
  if (!PyList_Check(arg)) {{ PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }}
  Py_ssize_t n = PyList_GET_SIZE(arg);
  PyObject *out = PyBytes_FromStringAndSize(NULL, n * (Py_ssize_t)sizeof(int64_t));
  if (!out) return NULL;
  int64_t *o = (int64_t *)PyBytes_AS_STRING(out);
  for (Py_ssize_t i = 0; i < n; i++) {{
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) {{ Py_DECREF(out); return NULL; }}
    o[i] = sighash(s);
  }}
  return out;
}}
/* reach_back(src, dst, can, sweeps): marks in can (bytes 0/1, writable) every
   state with a transition into a marked one, until nothing changes: the
   transitions src[e] -> dst[e] (uint32s, sorted by source) are swept from the
   last to the first, so a breadth-first graph (most transitions lead to a
   later state) settles in a few sweeps.  Returns the sweeps made, or -1 when
   the last of at most `sweeps` still changed something (not settled: can
   holds a part of the answer).  The graph analysis' backward reachability
   (pccl/search/liveness.py Graph.can_reach) */
static PyObject *reach_back(PyObject *self, PyObject *args) {{
  Py_buffer bs, bd, bc;
  int most;
  if (!PyArg_ParseTuple(args, "y*y*w*i", &bs, &bd, &bc, &most)) return NULL;
  if (bs.len != bd.len || bs.itemsize != 4 || bd.itemsize != 4) {{
    PyBuffer_Release(&bs); PyBuffer_Release(&bd); PyBuffer_Release(&bc);
    PyErr_SetString(PyExc_ValueError, "two uint32 arrays of one length");
    return NULL;
  }}
  const uint32_t *src = (const uint32_t *)bs.buf, *dst = (const uint32_t *)bd.buf;
  unsigned char *can = (unsigned char *)bc.buf;
  Py_ssize_t m = bs.len / 4, lim = bc.len;
  int sweeps = 0, changed = 1, bad = 0;
  Py_BEGIN_ALLOW_THREADS
  for (Py_ssize_t e = 0; e < m; e++)
    if (src[e] >= (uint64_t)lim || dst[e] >= (uint64_t)lim) {{ bad = 1; break; }}
  while (!bad && changed && sweeps < most) {{
    changed = 0;
    sweeps++;
    for (Py_ssize_t e = m - 1; e >= 0; e--)
      if (can[dst[e]] && !can[src[e]]) {{ can[src[e]] = 1; changed = 1; }}
  }}
  Py_END_ALLOW_THREADS
  PyBuffer_Release(&bs); PyBuffer_Release(&bd); PyBuffer_Release(&bc);
  if (bad) {{ PyErr_SetString(PyExc_ValueError, "a state number out of range"); return NULL; }}
  return PyLong_FromLong(changed ? -1 : sweeps);
}}
/* The fingerprint table's index (pccl/search/explorer.py FingerprintTable:
   linear probing of uint32 state numbers, keyed by the fingerprint's second
   word, 0xFFFFFFFF empty) probed and filled in C, the arrays numpy's.
   table_lookup(slots, fps, q, out, mask): out[i] = the state number of
   fingerprint q[i] (two uint64s), or -1.  table_place(slots, fps, idx, mask):
   index the state numbers idx (uint32s, distinct, absent). */
#define TEMPTY 0xFFFFFFFFu
static PyObject *table_lookup(PyObject *self, PyObject *args) {{
  Py_buffer bs, bf, bq, bo;
  unsigned long long mask;
  if (!PyArg_ParseTuple(args, "y*y*y*w*K", &bs, &bf, &bq, &bo, &mask)) return NULL;
  const uint32_t *slots = (const uint32_t *)bs.buf;
  const uint64_t *fps = (const uint64_t *)bf.buf, *q = (const uint64_t *)bq.buf;
  int64_t *out = (int64_t *)bo.buf;
  Py_ssize_t k = bq.len / 16, nf = bf.len / 16;
  int bad = (Py_ssize_t)(bo.len / 8) < k || (Py_ssize_t)(bs.len / 4) <= (Py_ssize_t)mask;
  Py_BEGIN_ALLOW_THREADS
  for (Py_ssize_t i = 0; i < k && !bad; i++) {{
    if (i + 8 < k) __builtin_prefetch(&slots[q[2 * (i + 8) + 1] & mask]);
    uint64_t lo = q[2 * i], hi = q[2 * i + 1];
    size_t pos = hi & mask;
    for (;;) {{
      uint32_t e = slots[pos];
      if (e == TEMPTY) {{ out[i] = -1; break; }}
      if ((Py_ssize_t)e >= nf) {{ bad = 1; break; }}
      if (fps[2 * (size_t)e + 1] == hi && fps[2 * (size_t)e] == lo) {{ out[i] = e; break; }}
      pos = (pos + 1) & mask;
    }}
  }}
  Py_END_ALLOW_THREADS
  PyBuffer_Release(&bs); PyBuffer_Release(&bf); PyBuffer_Release(&bq); PyBuffer_Release(&bo);
  if (bad) {{ PyErr_SetString(PyExc_ValueError, "table arrays of the wrong size"); return NULL; }}
  Py_RETURN_NONE;
}}
static PyObject *table_place(PyObject *self, PyObject *args) {{
  Py_buffer bs, bf, bi;
  unsigned long long mask;
  if (!PyArg_ParseTuple(args, "w*y*y*K", &bs, &bf, &bi, &mask)) return NULL;
  uint32_t *slots = (uint32_t *)bs.buf;
  const uint64_t *fps = (const uint64_t *)bf.buf;
  const uint32_t *idx = (const uint32_t *)bi.buf;
  Py_ssize_t k = bi.len / 4, nf = bf.len / 16;
  int bad = (Py_ssize_t)(bs.len / 4) <= (Py_ssize_t)mask;
  Py_BEGIN_ALLOW_THREADS
  for (Py_ssize_t i = 0; i < k && !bad; i++) {{
    if ((Py_ssize_t)idx[i] >= nf) {{ bad = 1; break; }}
    size_t pos = fps[2 * (size_t)idx[i] + 1] & mask;
    while (slots[pos] != TEMPTY) pos = (pos + 1) & mask;
    slots[pos] = idx[i];
  }}
  Py_END_ALLOW_THREADS
  PyBuffer_Release(&bs); PyBuffer_Release(&bf); PyBuffer_Release(&bi);
  if (bad) {{ PyErr_SetString(PyExc_ValueError, "table arrays of the wrong size"); return NULL; }}
  Py_RETURN_NONE;
}}
/* 1 into a dynamic state (a TIME ADVANCE), else 0: the graph's time cost */
static inline unsigned char phase_cost(const V *s) {{
  return s[{V_PHASE}] != {DISCRETE};
}}
/* phases(states): per state 1 if it is dynamic (after TIME ADVANCE), as bytes */
static PyObject *phases(PyObject *self, PyObject *arg) {{
  if (!PyList_Check(arg)) {{ PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }}
  Py_ssize_t n = PyList_GET_SIZE(arg);
  PyObject *out = PyBytes_FromStringAndSize(NULL, n);
  if (!out) return NULL;
  char *o = PyBytes_AS_STRING(out);
  for (Py_ssize_t i = 0; i < n; i++) {{
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) {{ Py_DECREF(out); return NULL; }}
    o[i] = phase_cost(s);
  }}
  return out;
}}
/* fingerprints(states): (the 16-byte fingerprints of their keys, in order,
   as one bytes object; the positions, ascending, of each key's first
   occurrence, as int64s; per state the position of its key's first
   occurrence, as int64s).  A fingerprint is pccl.search.fingerprint's: xxh3_128 of
   marshal version 2 of the key (a bytes object: 's', its length as a
   little-endian int32, its bytes), in xxhash's canonical (big-endian) form */
/* fingerprint_of(t, out): state t's fingerprint as the table holds it, two
   words whose bytes are the canonical form */
static void fingerprint_of(const V *t, uint64_t *out) {{
  size_t klen = sizeof(V) * NS - KEYSKIP;
  unsigned char buf[5 + sizeof(V) * NS];
  buf[0] = 's';
  buf[1] = klen & 255; buf[2] = (klen >> 8) & 255; buf[3] = (klen >> 16) & 255; buf[4] = (klen >> 24) & 255;
  V c[NS];
  canon(t, c);
  memcpy(buf + 5, (const char *)c + KEYSKIP, klen);
  H128 h = XXH(buf, 5 + klen);
#if __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
  out[0] = h.hi; out[1] = h.lo;
#else
  out[0] = __builtin_bswap64(h.hi); out[1] = __builtin_bswap64(h.lo);
#endif
}}
static PyObject *fingerprints_(PyObject *arg, int want_sigs) {{
  if (!PyList_Check(arg) || !XXH) {{ PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }}
  Py_ssize_t n = PyList_GET_SIZE(arg), m = 0;
  PyObject *sgs = want_sigs ? PyBytes_FromStringAndSize(NULL, 8 * n) : NULL;
  if (want_sigs && !sgs) return NULL;
  int64_t *sg = sgs ? (int64_t *)PyBytes_AS_STRING(sgs) : NULL;
  size_t size = 16;
  while (size < 2 * (size_t)n) size <<= 1;
  uint32_t *tab = calloc(size, sizeof(uint32_t));
  PyObject *blob = PyBytes_FromStringAndSize(NULL, 16 * n);
  PyObject *first = PyBytes_FromStringAndSize(NULL, 8 * n);
  PyObject *occ = PyBytes_FromStringAndSize(NULL, 8 * n);
  if (!tab || !blob || !first || !occ) goto fail;
  unsigned char *out = (unsigned char *)PyBytes_AS_STRING(blob);
  int64_t *fo = (int64_t *)PyBytes_AS_STRING(first);
  int64_t *oc = (int64_t *)PyBytes_AS_STRING(occ);
  for (Py_ssize_t i = 0; i < n; i++) {{
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) goto fail;
    if (sg) sg[i] = sighash(s);       /* while the state is in the cache */
    uint64_t f[2];
    fingerprint_of(s, f);
    memcpy(out + 16 * i, f, 16);
    size_t slot = (size_t)(f[0] ^ f[1]) & (size - 1);
    for (;;) {{
      uint32_t e = tab[slot];
      if (!e) {{ tab[slot] = (uint32_t)i + 1; fo[m++] = i; oc[i] = i; break; }}
      if (!memcmp(out + 16 * (e - 1), out + 16 * i, 16)) {{ oc[i] = e - 1; break; }}
      slot = (slot + 1) & (size - 1);
    }}
  }}
  free(tab);
  if (_PyBytes_Resize(&first, 8 * m)) {{ Py_DECREF(blob); Py_DECREF(occ); Py_XDECREF(sgs); return NULL; }}
  if (sgs) return Py_BuildValue("(NNNN)", blob, first, occ, sgs);
  return Py_BuildValue("(NNN)", blob, first, occ);
fail:
  free(tab);
  Py_XDECREF(blob); Py_XDECREF(first); Py_XDECREF(occ); Py_XDECREF(sgs);
  return NULL;
}}
static PyObject *fingerprints(PyObject *self, PyObject *arg) {{
  return fingerprints_(arg, 0);
}}
/* fingerprints_sigs(states): fingerprints(states) and a fourth bytes object,
   sig of each state (int64s), computed in the same pass */
static PyObject *fingerprints_sigs(PyObject *self, PyObject *arg) {{
  return fingerprints_(arg, 1);
}}
static inline int okstate(const V *s) {{
  ovf = 0;
  int r = {' && '.join(oks)} && ({lq_ok}) && ({props});
  return ovf ? 0 : r;
}}
static PyObject *ok(PyObject *self, PyObject *arg) {{
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  return PyBool_FromLong(okstate(s));
}}
/* violations(state): [] when okstate, else SLOWVIOL(state) (the Python
   model's own violations of the decoded configuration) */
static PyObject *SLOWVIOL;
static PyObject *violations(PyObject *self, PyObject *arg) {{
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  if (okstate(s)) return PyList_New(0);
  return PyObject_CallOneArg(SLOWVIOL, arg);
}}
/* suspects(states): the positions, ascending, of the states of a list that
   okstate does not pass (violations(state) may be non-empty only there):
   one call for a batch instead of one per state */
static PyObject *suspects(PyObject *self, PyObject *arg) {{
  if (!PyList_Check(arg)) {{ PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }}
  Py_ssize_t n = PyList_GET_SIZE(arg);
  PyObject *out = PyList_New(0);
  if (!out) return NULL;
  for (Py_ssize_t i = 0; i < n; i++) {{
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) {{ Py_DECREF(out); return NULL; }}
    if (!okstate(s)) {{
      PyObject *j = PyLong_FromSsize_t(i);
      if (!j || PyList_Append(out, j)) {{ Py_XDECREF(j); Py_DECREF(out); return NULL; }}
      Py_DECREF(j);
    }}
  }}
  return out;
}}
static PyObject *memo_stats(PyObject *self, PyObject *unused) {{
  return Py_BuildValue("(nnn)", (Py_ssize_t)MEMO_N, (Py_ssize_t)MEMO_MISS, (Py_ssize_t)MEMO_HIT);
}}
static PyObject *clock_(PyObject *self, PyObject *arg) {{
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  return PyLong_FromLongLong(s[{V_TIME}]);
}}
/* max_clock(states): the largest time of a list of states (None: empty) */
static PyObject *max_clock(PyObject *self, PyObject *arg) {{
  if (!PyList_Check(arg)) {{ PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }}
  Py_ssize_t n = PyList_GET_SIZE(arg);
  if (!n) Py_RETURN_NONE;
  long long m = 0;
  for (Py_ssize_t i = 0; i < n; i++) {{
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) return NULL;
    if (!i || s[{V_TIME}] > m) m = s[{V_TIME}];
  }}
  return PyLong_FromLongLong(m);
}}
static PyObject *setup(PyObject *self, PyObject *args) {{
  PyObject *labels, *exc, *slow, *miss;
  unsigned long long xxh;
  if (!PyArg_ParseTuple(args, "O!OOKO", &PyList_Type, &labels, &exc, &slow, &xxh, &miss))
    return NULL;
  Py_XDECREF(LABELS); Py_XDECREF(OverflowExc); Py_XDECREF(SLOWVIOL); Py_XDECREF(MISS);
  Py_INCREF(labels); Py_INCREF(exc); Py_INCREF(slow); Py_INCREF(miss);
  LABELS = labels; OverflowExc = exc; SLOWVIOL = slow; MISS = miss;
  memo_clear();
  NLABELS = 0;
  if (labels_grown()) return NULL;
  XXH = (xxh128_fn)(uintptr_t)xxh;
  Py_RETURN_NONE;
}}
{_KERNEL_C}
static PyMethodDef methods[] = {{
  {{"successors", successors, METH_O, "labelled successors of a state"}},
  {{"ok", ok, METH_O, "no stuck agent, the lock fine, every invariant holds"}},
  {{"expand", expand, METH_O, "successor counts, flat successors and labels of a list of states"}},
  {{"fingerprints", fingerprints, METH_O, "fingerprints and first occurrences of a list of states"}},
  {{"fingerprints_sigs", fingerprints_sigs, METH_O, "fingerprints, first occurrences and stall signatures"}},
  {{"reach_back", reach_back, METH_VARARGS, "backward reachability over a transition list"}},
  {{"table_lookup", table_lookup, METH_VARARGS, "the fingerprint table's lookups"}},
  {{"table_place", table_place, METH_VARARGS, "the fingerprint table's index filled"}},
  {{"violations", violations, METH_O, "[] or the Python model's violations"}},
  {{"suspects", suspects, METH_O, "the positions of the states okstate does not pass"}},
  {{"clock", clock_, METH_O, "the state's time"}},
  {{"max_clock", max_clock, METH_O, "the largest time of a list of states"}},
  {{"key", key, METH_O, "the state's identity (canonical under symmetry)"}},
  {{"sig", sig, METH_O, "the stall signature's hash"}},
  {{"sigs", sigs, METH_O, "the stall signatures' hashes of a list of states, as int64s"}},
  {{"packed", packed, METH_O, "a state's bytes in the form the explorer holds"}},
  {{"unpacked", unpacked, METH_O, "a state's int64 vector, as bytes"}},
  {{"phases", phases, METH_O, "1 per dynamic state"}},
  {{"setup", setup, METH_VARARGS, "labels and the overflow exception"}},
  {{"memo_stats", memo_stats, METH_NOARGS, "(entries, misses, hits) of the memo"}},
  {{"explore_levels", explore_levels, METH_VARARGS, "levels expanded and admitted, on threads"}},
  {{NULL, NULL, 0, NULL}}
}};
static struct PyModuleDef mod = {{PyModuleDef_HEAD_INIT, MODNAME, NULL, -1, methods}};
PyMODINIT_FUNC INITFN(void) {{ return PyModule_Create(&mod); }}
"""


#: C of the level kernel (explore_levels), after the successor code
_KERNEL_C = r"""
/* ---- the level kernel ---------------------------------------------------
   explore_levels(level, first, out, start, threads, slots, fps, parents,
   n, mask, limit, cross, seconds[, rec]): breadth-first search in C from
   level[start:] (level[i] is state number first + i), admitting as the
   explorer's batches would admit: a chunk of KCH states at a time, chunks
   in order, each new successor (its fingerprint not in the table) numbered
   n, n + 1, ... (fps[n] its fingerprint, parents[n] its parent's number,
   indexed in slots) and its state appended to the next level's list (out,
   the next level as far as it is admitted: its states numbered n - len(out)
   on).  Once a level's every chunk is admitted the next level's chunks
   follow, up to `cross` levels after `level`: so that threads never wait
   for a level to end.  With threads > 1 that many threads, this one among
   them, each make chunks (expand, fingerprint, check: no Python, no GIL)
   at most KWIN ahead of the admission, and whichever finds the next chunk
   made and no one admitting admits it (holding the GIL, one at a time): a
   slow or descheduled thread holds no one up but for the chunk in its
   hands, and the result does not depend on the threads.  It stops before
   admitting a chunk that holds a state without successors (why 1), an
   error (2), more successors than room under `limit` (3: the table is to
   grow, or the state budget is met) or a successor that fails okstate and
   is not in the table (4): the explorer's own path takes that chunk; and
   at a chunk's end once `seconds` have passed (why 0, more to do).
   With `rec` (the graph recorder's arrays, GraphRecorder.kernel_arrays:
   transitions' sources and targets as uint32 with the count so far, time
   costs, and with the stall check signatures, change flags and whether a
   change is decided on the successor as made) the admission records every
   transition and new state there (krecord), and stops before a chunk whose
   transitions do not fit (why 5: the arrays grow).
   Returns (e: the level it stopped in, 0 for `level`, e >= 1 the e-th
   level after it; the position in it; why; level e's list (None for level
   0, or once it is expanded); its next level's list (out when e is 0);
   (length, last state) of each level 1..e; the largest time of the new
   states of each level 1..e+1, or None; the transitions admitted; the
   labels met; the end of the chunk stopped at; the states admitted; 1
   when nothing more was allowed (the last level it may go into is
   expanded, or a level came out empty), else 0; the transitions recorded
   in all, 0 without `rec`; an interruption raised in a memo miss's Python
   code, which stopped the kernel, or None: the caller raises it once it has
   taken the figures). */
#include <pthread.h>
#include <time.h>
/* compiled at -O1: 0.1-0.25 s less per module than -O2 and no slower (its
   hot loops are the successor code's, compiled at -O2; Fischer 3 agents
   k=2: 7.75-7.93 s against 7.97-8.23 s, 2026-12-03).  In every module: a
   memo site's miss (the env's included) takes the GIL to call Python, the
   memo's locks held (_MEMO_C) */
#pragma GCC push_options
#pragma GCC optimize ("O1")
#define KCH 128
#define KWIN 512
#define KMAXLV 4096
#define KBLK 65536
typedef struct {
  V *vec; uint64_t *fp; unsigned char *sus, *labs; int32_t *ns;
  int64_t *sg;                      /* the candidates' stall signatures (recording them) */
  Py_ssize_t labcap;                /* labs' size (labels grow on memo misses) */
  Py_ssize_t nc, cap;
  int flag;
} KChunk;
typedef struct {
  /* level 0: the list given; levels 1...: the states admitted, in blocks
     of KBLK pointers (ptr index q is state number pfirst + q; the lists
     hold the references), level L >= 1 from index lo[L]; chunk ids run
     on across levels, level L's from cbase[L] */
  PyObject *level;
  Py_ssize_t first, start, end0;
  PyObject ***blk;
  Py_ssize_t nblk, pfirst, cross;
  Py_ssize_t nptr;                  /* admitted so far (release-stored) */
  Py_ssize_t lo[KMAXLV + 2], cbase[KMAXLV + 2];
  int known;                        /* levels 0..known-1 have their final size */
  int exhausted;                    /* a level came out empty: no chunk from endc on */
  Py_ssize_t endc;
  PyObject *lists[KMAXLV + 1];      /* lists[L]: level L's (L >= 1), until expanded */
  Py_ssize_t llen[KMAXLV + 1];      /* ... then its length and last state */
  PyObject *llast[KMAXLV + 1];
  /* the last level expanded: its states freed one per state admitted, so
     that a new state takes the place of an old one (a whole level freed at
     once empties the allocator's arenas, which go back to the system and
     must be mapped again: measured 8x the page faults, 10% of the time) */
  PyObject *grave;
  long long tmax[KMAXLV + 1];
  Py_ssize_t tn[KMAXLV + 1];        /* new states admitted into lists[L] in this call */
  /* chunk c's buffer (once made) in slot c % KWIN; the buffers (KRING, kept
     between calls) not in use on a stack, the last freed on top: a buffer
     taken is most likely still in the cache */
  KChunk **slot;
  KChunk *free_[KWIN];
  int nfree;
  int next, done, stop, sleepers, admitting;
  /* the admission's (the thread admitting holds them) */
  uint32_t *slots, *parents;
  uint64_t *fps, mask;
  Py_ssize_t n, n0, limit, trans;
  unsigned char *seen;
  Py_ssize_t nseen;
  int why, lv;                      /* lv: the level of the last chunk admitted, */
  Py_ssize_t pend;                  /* ... and its end */
  double deadline;
  /* the graph recorder's arrays (rec: recording), written by the admission:
     per transition its source and target numbers (ne so far, room for
     ecap), per new state its time cost (dyn) and, with the stall check
     (sig not NULL), its signature and a change flag set on a source when
     a transition out of it changes the signature: of the successor as made
     (bycand: under symmetry a number stands for a renamed state) or of the
     state its number stands for */
  int rec, bycand;
  uint32_t *esrc, *edst;
  Py_ssize_t ne, ecap;
  unsigned char *dyn, *chg;
  int64_t *sig;
  pthread_mutex_t mu;
  pthread_cond_t cv;
} KJob;
static KChunk KRING[KWIN];
static KChunk *KSLOT[KWIN];
static int KBUSY;
static double know(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}
static void kfree_tls(void) {
  free(BUF); free(BLAB); free(BIDX); free(BCH);
  BUF = NULL; BLAB = BIDX = BCH = NULL; BN = BCAP = 0;
#ifdef IDW
  free(SEEN); free(SLOT); SEEN = NULL; SLOT = NULL;
#endif
}
static int kroom(KChunk *k, Py_ssize_t need) {
  if (need <= k->cap) return 0;
  Py_ssize_t cap = k->cap ? 2 * k->cap : 512;
  while (cap < need) cap *= 2;
  V *v = realloc(k->vec, sizeof(V) * NS * cap);
  if (v) k->vec = v;
  uint64_t *f = realloc(k->fp, 16 * cap);
  if (f) k->fp = f;
  unsigned char *s = realloc(k->sus, cap);
  if (s) k->sus = s;
  int64_t *g = realloc(k->sg, sizeof(int64_t) * cap);
  if (g) k->sg = g;
  if (!v || !f || !s || !g) return -1;
  k->cap = cap;
  return 0;
}
/* room in k->labs for label nl (a label a memo miss added), zeroed */
static int klabs(KChunk *k, Py_ssize_t nl) {
  if (nl < k->labcap) return 0;
  Py_ssize_t cap = k->labcap ? 2 * k->labcap : 256;
  while (cap <= nl) cap *= 2;
  unsigned char *x = realloc(k->labs, cap);
  if (!x) return -1;
  memset(x + k->labcap, 0, cap - k->labcap);
  k->labs = x; k->labcap = cap;
  return 0;
}
/* a chunk made or admitted, the admission free, the end: the waiting
   threads look again (under the lock: a thread checks what it waits for
   under it, so no wake-up is lost) */
static void kwake(KJob *j) {
  pthread_mutex_lock(&j->mu);
  if (j->sleepers) pthread_cond_broadcast(&j->cv);
  pthread_mutex_unlock(&j->mu);
}
/* chunk c's states: level *lv, positions [*a, *b) of it (level 0: of the
   list given; level L >= 1: of the states admitted); 1 when it can be
   made, 0 when not yet (its level's states not all admitted: a whole chunk
   is waited for), -1 never (past the last level or `cross`) */
static int kwhere(KJob *j, Py_ssize_t c, int *lv, Py_ssize_t *a, Py_ssize_t *b) {
  int known = __atomic_load_n(&j->known, __ATOMIC_ACQUIRE);
  int L = 0;
  while (L < known && c >= j->cbase[L + 1]) L++;
  *lv = L;
  if (L > j->cross || (__atomic_load_n(&j->exhausted, __ATOMIC_ACQUIRE) && c >= j->endc)) {
    *a = *b = 0;
    return -1;
  }
  if (L == 0) {
    *a = j->start + c * KCH;
    *b = *a + KCH < j->end0 ? *a + KCH : j->end0;
    return 1;
  }
  *a = j->lo[L] + (c - j->cbase[L]) * KCH;
  if (L < known) {                  /* level L's size is final */
    *b = *a + KCH < j->lo[L + 1] ? *a + KCH : j->lo[L + 1];
    return 1;
  }
  *b = *a + KCH;
  return __atomic_load_n(&j->nptr, __ATOMIC_ACQUIRE) >= *b ? 1 : 0;
}
static inline PyObject *kptr(KJob *j, Py_ssize_t q) {
  return j->blk[q / KBLK][q % KBLK];
}
/* make chunk c: its states' successors, their fingerprints and checks */
static void kmake(KJob *j, Py_ssize_t c, int L, Py_ssize_t a, Py_ssize_t b) {
  pthread_mutex_lock(&j->mu);
  KChunk *k = j->free_[--j->nfree];
  pthread_mutex_unlock(&j->mu);
  k->nc = 0;
  k->flag = 0;
  if (klabs(k, __atomic_load_n(&NLABELS, __ATOMIC_ACQUIRE))) k->flag = 2;
  memset(k->labs, 0, k->labcap);
  for (Py_ssize_t i = a; i < b && !k->flag; i++) {
    V sb[NS];
    const V *s = raw_state(L ? kptr(j, i) : PyList_GET_ITEM(j->level, i), sb);
    BN = 0; ovf = 0;
    if (!s || rstep(s)) { k->flag = 2; break; }
    k->ns[i - a] = (int32_t)BN;
    if (!BN) { k->flag = 1; break; }
    if (kroom(k, k->nc + BN)) { k->flag = 2; break; }
    for (Py_ssize_t q = 0; q < BN; q++) {
      const V *t = BUF + NS * q;
      Py_ssize_t w = k->nc++;
      memcpy(k->vec + NS * w, t, sizeof(V) * NS);
      if (BLAB[q] >= k->labcap && klabs(k, BLAB[q])) { k->flag = 2; break; }
      k->labs[BLAB[q]] = 1;
      fingerprint_of(t, k->fp + 2 * w);
      if (j->sig) k->sg[w] = sighash(t);
      k->sus[w] = !okstate(t);
    }
  }
  __atomic_store_n(&j->slot[c % KWIN], k, __ATOMIC_RELEASE);
  kwake(j);
}
static inline int64_t klookup(const uint32_t *slots, const uint64_t *fps, uint64_t mask, const uint64_t *q) {
  size_t pos = q[1] & mask;
  for (;;) {
    uint32_t e = slots[pos];
    if (e == TEMPTY) return -1;
    if (fps[2 * (size_t)e + 1] == q[1] && fps[2 * (size_t)e] == q[0]) return e;
    pos = (pos + 1) & mask;
  }
}
/* the recorder's transition par -> dst (candidate w of chunk k) */
static inline void krecord(KJob *j, KChunk *k, Py_ssize_t w, Py_ssize_t par, int64_t dst) {
  j->esrc[j->ne] = (uint32_t)par;
  j->edst[j->ne++] = (uint32_t)dst;
  if (j->sig && (j->bycand ? k->sg[w] : j->sig[dst]) != j->sig[par]) j->chg[par] = 1;
}
/* admit chunk k, the next in order, of level L, positions [a, b) (the GIL
   held): 0, else why not */
static int kadmit1(KJob *j, KChunk *k, int L, Py_ssize_t a, Py_ssize_t b) {
  uint32_t *slots = j->slots, *parents = j->parents;
  uint64_t *fps = j->fps, mask = j->mask;
  if (k->flag) return k->flag;
  if (j->n + k->nc > j->limit) return 3;
  if (j->rec && j->ne + k->nc > j->ecap) return 5;
  for (Py_ssize_t q = 0; q < k->nc; q++)
    if (k->sus[q] && klookup(slots, fps, mask, k->fp + 2 * q) < 0) return 4;
  if (!j->lists[L + 1]) {
    if (!(j->lists[L + 1] = PyList_New(0))) return -1;
    j->tn[L + 1] = 0;
  }
  PyObject *out = j->lists[L + 1];
  Py_ssize_t w = 0, n = j->n, base = L ? j->pfirst : j->first;
  /* the table's lines fetched ahead: its slot 16 candidates on, the
     fingerprints of the slots a probe will pass 8 on (the table is far
     larger than the cache) */
  for (Py_ssize_t q = 0; q < 16 && q < k->nc; q++) __builtin_prefetch(slots + (k->fp[2 * q + 1] & mask));
  for (Py_ssize_t i = a; i < b; i++) {
    Py_ssize_t par = base + i;
    for (int32_t r = 0; r < k->ns[i - a]; r++, w++) {
      const uint64_t *f = k->fp + 2 * w;
      if (w + 16 < k->nc) __builtin_prefetch(slots + (k->fp[2 * (w + 16) + 1] & mask));
      if (w + 8 < k->nc)
        for (size_t p8 = k->fp[2 * (w + 8) + 1] & mask, r8 = 0; r8 < 4; r8++, p8 = (p8 + 1) & mask) {
          uint32_t e8 = slots[p8];
          if (e8 == TEMPTY) break;
          __builtin_prefetch(fps + 2 * (size_t)e8);
        }
      int64_t hit = klookup(slots, fps, mask, f);
      if (hit >= 0) {
        if (j->rec) krecord(j, k, w, par, hit);
        continue;
      }
      const V *t = k->vec + NS * w;
      Py_ssize_t q = j->nptr;
      if (q / KBLK >= j->nblk) { j->n = n; return 3; }
      if (!j->blk[q / KBLK] && !(j->blk[q / KBLK] = malloc(sizeof(PyObject *) * KBLK))) {
        PyErr_NoMemory(); j->n = n; return -1;
      }
      if (j->grave) {               /* an old state's place for the new one */
        Py_ssize_t g = PyList_GET_SIZE(j->grave);
        if (g) {
          PyObject *old = PyList_GET_ITEM(j->grave, g - 1);
          Py_SET_SIZE(j->grave, g - 1);
          Py_DECREF(old);
        }
      }
      PyObject *st = state_bytes(t);
      if (!st || PyList_Append(out, st)) { Py_XDECREF(st); j->n = n; return -1; }
      j->blk[q / KBLK][q % KBLK] = st;
      Py_DECREF(st);                /* the list holds it */
      __atomic_store_n(&j->nptr, q + 1, __ATOMIC_RELEASE);
      fps[2 * n] = f[0]; fps[2 * n + 1] = f[1];
      parents[n] = (uint32_t)par;
      size_t pos = f[1] & mask;
      while (slots[pos] != TEMPTY) pos = (pos + 1) & mask;
      slots[pos] = (uint32_t)n;
      if (!j->tn[L + 1]++ || t[0] > j->tmax[L + 1]) j->tmax[L + 1] = t[0];
      if (j->rec) {
        j->dyn[n] = phase_cost(t);
        if (j->sig) { j->sig[n] = k->sg[w]; j->chg[n] = 0; }
        krecord(j, k, w, par, n);
      }
      n++;
    }
  }
  j->n = n;
  if (k->labcap > j->nseen) {       /* labels a memo miss added */
    unsigned char *x = realloc(j->seen, k->labcap);
    if (!x) { PyErr_NoMemory(); return -1; }
    memset(x + j->nseen, 0, k->labcap - j->nseen);
    j->seen = x; j->nseen = k->labcap;
  }
  for (Py_ssize_t q = 0; q < k->labcap; q++) j->seen[q] |= k->labs[q];
  j->trans += k->nc;
  return 0;
}
/* level L's every chunk admitted: level L + 1's size is final (its end,
   its chunks' ids); an empty one ends the search */
static void kclose(KJob *j, int L) {
  Py_ssize_t size = j->nptr - j->lo[L + 1];
  if (L >= 1 && j->lists[L]) {      /* expanded: its states are the next level's parents only */
    PyObject *l = j->lists[L];
    j->llen[L] = PyList_GET_SIZE(l);
    j->llast[L] = j->llen[L] ? PyList_GET_ITEM(l, j->llen[L] - 1) : Py_None;
    Py_INCREF(j->llast[L]);
    if (L > 1) {                    /* (level 1 is the caller's list) */
      Py_XDECREF(j->grave);         /* (its states freed as many new ones are made) */
      j->grave = l;
    }
    j->lists[L] = NULL;
  }
  j->lo[L + 2] = j->nptr;
  j->cbase[L + 2] = j->cbase[L + 1] + (size + KCH - 1) / KCH;
  if (L + 2 >= KMAXLV && j->cross > L + 1) j->cross = L + 1;
  if (!size) {
    j->endc = j->cbase[L + 2];
    __atomic_store_n(&j->exhausted, 1, __ATOMIC_RELEASE);
  }
  __atomic_store_n(&j->known, L + 2, __ATOMIC_RELEASE);
}
/* admit the chunks made, in order, while this thread is the one admitting */
static void kadmit(KJob *j, PyThreadState **ts) {
  int held = 0;
  for (;;) {
    int c = __atomic_load_n(&j->done, __ATOMIC_ACQUIRE);
    if (j->why || __atomic_load_n(&j->stop, __ATOMIC_ACQUIRE) || __atomic_load_n(&KINTR, __ATOMIC_ACQUIRE))
      break;
    KChunk *k = __atomic_load_n(&j->slot[c % KWIN], __ATOMIC_ACQUIRE);
    if (!k) break;
    int L;
    Py_ssize_t a, b;
    kwhere(j, c, &L, &a, &b);
    if (!held) { PyEval_RestoreThread(*ts); held = 1; }
    int why = kadmit1(j, k, L, a, b);
    if (why) { j->why = why; break; }
    __atomic_store_n(&j->slot[c % KWIN], NULL, __ATOMIC_RELEASE);
    pthread_mutex_lock(&j->mu);
    j->free_[j->nfree++] = k;
    pthread_mutex_unlock(&j->mu);
    if (c + 1 == j->cbase[L + 1]) kclose(j, L);     /* the last chunk of level L */
    j->lv = L;
    j->pend = b;
    __atomic_store_n(&j->done, c + 1, __ATOMIC_RELEASE);
    if (know() > j->deadline) __atomic_store_n(&j->stop, 1, __ATOMIC_RELEASE);
    kwake(j);
  }
  if (held) *ts = PyEval_SaveThread();
}
/* a thread's part: admit when the next chunk is made and no one admits,
   else make the next chunk within the window, else wait */
static void kwork(KJob *j, PyThreadState **ts) {
  for (;;) {
    int c = __atomic_load_n(&j->done, __ATOMIC_ACQUIRE), L;
    Py_ssize_t a, b;
    if (__atomic_load_n(&j->stop, __ATOMIC_ACQUIRE) || __atomic_load_n(&KINTR, __ATOMIC_ACQUIRE)) break;
    if (__atomic_load_n(&j->slot[c % KWIN], __ATOMIC_ACQUIRE)) {
      int z = 0;
      if (__atomic_compare_exchange_n(&j->admitting, &z, 1, 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE)) {
        kadmit(j, ts);
        if (j->why) __atomic_store_n(&j->stop, 1, __ATOMIC_RELEASE);
        __atomic_store_n(&j->admitting, 0, __ATOMIC_RELEASE);
        kwake(j);
        continue;
      }
    }
    int d = __atomic_load_n(&j->next, __ATOMIC_ACQUIRE);
    int r = d < c + KWIN ? kwhere(j, d, &L, &a, &b) : 0;
    if (r == 1) {
      if (__atomic_compare_exchange_n(&j->next, &d, d + 1, 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE))
        kmake(j, d, L, a, b);
      continue;
    }
    if (r < 0 && d == c) break;     /* every chunk there will be is admitted */
    /* nothing to make now: wait for the next chunk, the window, more
       states of an open level or the end */
    pthread_mutex_lock(&j->mu);
    j->sleepers++;
    c = __atomic_load_n(&j->done, __ATOMIC_ACQUIRE);
    d = __atomic_load_n(&j->next, __ATOMIC_ACQUIRE);
    if (!__atomic_load_n(&j->stop, __ATOMIC_ACQUIRE)
        && (!__atomic_load_n(&j->slot[c % KWIN], __ATOMIC_ACQUIRE)
            || __atomic_load_n(&j->admitting, __ATOMIC_ACQUIRE))
        && (d >= c + KWIN || kwhere(j, d, &L, &a, &b) == 0))
      pthread_cond_wait(&j->cv, &j->mu);
    j->sleepers--;
    pthread_mutex_unlock(&j->mu);
  }
  __atomic_store_n(&j->stop, 1, __ATOMIC_RELEASE);
  kwake(j);
}

static void *kthread(void *arg) {
  KJob *j = arg;
  PyGILState_STATE g = PyGILState_Ensure();
  PyThreadState *ts = PyEval_SaveThread();
  KT = 1;
  kwork(j, &ts);
  kfree_tls();
  KT = 0;
  PyEval_RestoreThread(ts);
  PyGILState_Release(g);
  return NULL;
}
static PyObject *explore_levels(PyObject *self, PyObject *args) {
  PyObject *level, *out;
  Py_ssize_t first, start, n, limit, cross;
  int threads;
  double seconds;
  Py_buffer bs, bf, bp, bes = {0}, bed = {0}, bdy = {0}, bsg = {0}, bch = {0};
  unsigned long long mask;
  PyObject *rec = Py_None;
  if (!PyArg_ParseTuple(args, "O!nO!niw*w*w*nKnnd|O", &PyList_Type, &level, &first, &PyList_Type,
                        &out, &start, &threads, &bs, &bf, &bp, &n, &mask, &limit, &cross,
                        &seconds, &rec))
    return NULL;
  Py_ssize_t ne = 0;
  int bycand = 0;
  if (rec != Py_None && !PyArg_ParseTuple(rec, "w*w*nw*|w*w*i", &bes, &bed, &ne, &bdy, &bsg,
                                          &bch, &bycand)) {
    PyBuffer_Release(&bs); PyBuffer_Release(&bf); PyBuffer_Release(&bp);
    return NULL;
  }
  PyObject *res = NULL, *labs = NULL, *lists = NULL, *tms = NULL;
  KJob *j = calloc(1, sizeof(KJob));
  unsigned char *seen = calloc(NLABELS + 1, 1);
  int nth = 0, mine = 0;
  pthread_t th[64];
  Py_ssize_t end0 = PyList_GET_SIZE(level), nout = PyList_GET_SIZE(out);
  if (start > end0) start = end0;
  if (!j || !seen) { PyErr_NoMemory(); goto done; }
  if (out == level || first < 0 || n < nout || cross < 0 || (Py_ssize_t)(bs.len / 4) <= (Py_ssize_t)mask
      || (Py_ssize_t)(bf.len / 16) < limit || (Py_ssize_t)(bp.len / 4) < limit || limit < n || !XXH
      || (rec != Py_None && (bes.len != bed.len || bes.itemsize != 4 || bed.itemsize != 4
                             || ne < 0 || ne > bes.len / 4 || bdy.len < limit
                             || (bsg.buf && (bsg.itemsize != 8 || bsg.len / 8 < limit
                                               || !bch.buf || bch.len < limit))))) {
    PyErr_SetString(PyExc_ValueError, "explore_levels: arguments out of range");
    goto done;
  }
  if (KBUSY) { PyErr_SetString(PyExc_RuntimeError, "explore_levels is running"); goto done; }
  memo_lock_init();
  for (Py_ssize_t q = 0; q < KWIN; q++) {
    KChunk *k = KRING + q;
    KSLOT[q] = NULL;
    j->free_[KWIN - 1 - q] = k;
    if (!k->ns) k->ns = malloc(sizeof(int32_t) * KCH);
    if (klabs(k, NLABELS) || !k->ns) { PyErr_NoMemory(); goto done; }
  }
  /* the admitted states' pointers: out's first, then room for `limit` */
  j->nblk = (nout + (limit - n) + KBLK) / KBLK + 1;
  if (!(j->blk = calloc(j->nblk, sizeof(PyObject **)))) { PyErr_NoMemory(); goto done; }
  for (Py_ssize_t q = 0; q < nout; q++) {
    if (!j->blk[q / KBLK] && !(j->blk[q / KBLK] = malloc(sizeof(PyObject *) * KBLK))) {
      PyErr_NoMemory(); goto done;
    }
    j->blk[q / KBLK][q % KBLK] = PyList_GET_ITEM(out, q);
  }
  KBUSY = mine = 1;
  j->level = level; j->first = first; j->start = start; j->end0 = end0;
  j->pfirst = n - nout; j->nptr = nout; j->cross = cross < KMAXLV - 2 ? cross : KMAXLV - 2;
  j->lists[1] = out; j->tn[1] = 0;
  j->known = 1; j->cbase[0] = 0; j->cbase[1] = (end0 - start + KCH - 1) / KCH; j->lo[1] = 0;
  j->slot = KSLOT; j->nfree = KWIN;
  j->slots = bs.buf; j->fps = bf.buf; j->parents = bp.buf; j->mask = mask;
  j->n = j->n0 = n; j->limit = limit; j->seen = seen; j->nseen = NLABELS + 1;
  j->lv = 0; j->pend = end0;
  j->deadline = know() + seconds;
  if (rec != Py_None) {
    j->rec = 1; j->bycand = bycand;
    j->esrc = bes.buf; j->edst = bed.buf; j->ne = ne; j->ecap = bes.len / 4;
    j->dyn = bdy.buf;
    j->sig = bsg.buf; j->chg = bch.buf;
  }
  if (j->cbase[1] == 0) kclose(j, 0);           /* level 0 has nothing left */
  pthread_mutex_init(&j->mu, NULL);
  pthread_cond_init(&j->cv, NULL);
  if (threads > 64) threads = 64;
  PyThreadState *ts = PyEval_SaveThread();
  for (; nth < threads - 1; nth++)
    if (pthread_create(&th[nth], NULL, kthread, j)) break;
  KT = 1;
  kwork(j, &ts);
  KT = 0;
  for (int q = 0; q < nth; q++) pthread_join(th[q], NULL);
  PyEval_RestoreThread(ts);
  pthread_mutex_destroy(&j->mu);
  pthread_cond_destroy(&j->cv);
  seen = j->seen;                   /* (grown with the labels) */
  if (j->why < 0) goto done;
  /* where it stopped: the chunk not admitted (a reason, the deadline), or
     the end of the last level expanded */
  int e, fin = 0;
  Py_ssize_t p, cend;
  if (kwhere(j, j->done, &e, &p, &cend) < 0 && !j->why) {
    fin = 1;                        /* all it was allowed to do */
    e = j->lv;
    p = cend = j->done ? j->pend : end0;
  }
  if (e > 0) { p -= j->lo[e]; cend -= j->lo[e]; }      /* positions in level e's list */
  /* the levels crossed (1..e-1 expanded: their lengths and last states),
     level e's list when e >= 1, its next level's list (made empty if none) */
  Py_ssize_t nl = 0;
  for (Py_ssize_t q = 0; q < NLABELS && q < j->nseen; q++) nl += seen[q];
  if (!(labs = PyTuple_New(nl)) || !(lists = PyTuple_New(e > 0 ? e : 0)) || !(tms = PyTuple_New(e + 1)))
    goto done;
  for (Py_ssize_t q = 0, w = 0; q < NLABELS && q < j->nseen; q++)
    if (seen[q]) {
      PyObject *l = PyList_GET_ITEM(LABELS, q);
      Py_INCREF(l);
      PyTuple_SET_ITEM(labs, w++, l);
    }
  for (int q = 1; q <= e; q++) {    /* (length, last state) of levels 1..e */
    Py_ssize_t len = j->lists[q] ? PyList_GET_SIZE(j->lists[q]) : j->llen[q];
    PyObject *last = j->lists[q] ? (len ? PyList_GET_ITEM(j->lists[q], len - 1) : Py_None) : j->llast[q];
    PyObject *x = Py_BuildValue("(nO)", len, last);
    if (!x) goto done;
    PyTuple_SET_ITEM(lists, q - 1, x);
  }
  for (int q = 1; q <= e + 1; q++) {
    PyObject *tm = j->tn[q] ? PyLong_FromLongLong(j->tmax[q]) : (Py_INCREF(Py_None), Py_None);
    if (!tm) goto done;
    PyTuple_SET_ITEM(tms, q - 1, tm);
  }
  if (!j->lists[e + 1] && !(j->lists[e + 1] = PyList_New(0))) goto done;
  /* (level e's list: None when it is level 0 or expanded, at the end) */
  res = Py_BuildValue("(iniOOOOnOnninO)", e, p, j->why, e > 0 && j->lists[e] ? j->lists[e] : Py_None,
                      j->lists[e + 1], lists, tms, j->trans, labs, cend, j->n - j->n0, fin, j->ne,
                      KEXC ? KEXC : Py_None);
done:
  if (mine) {                       /* (the interruption handed back, or dropped on an error) */
    Py_CLEAR(KEXC);
    KINTR = 0;
    KBUSY = 0;
  }
  if (j) {
    for (Py_ssize_t q = 2; q <= KMAXLV; q++) Py_XDECREF(j->lists[q]);
    for (Py_ssize_t q = 1; q <= KMAXLV; q++) Py_XDECREF(j->llast[q]);
    Py_XDECREF(j->grave);
    if (j->blk) for (Py_ssize_t q = 0; q < j->nblk; q++) free(j->blk[q]);
    free(j->blk);
  }
  if (j) seen = j->seen;
  free(j); free(seen);
  Py_XDECREF(labs); Py_XDECREF(lists); Py_XDECREF(tms);
  PyBuffer_Release(&bs); PyBuffer_Release(&bf); PyBuffer_Release(&bp);
  Py_buffer *rbs[] = {&bes, &bed, &bdy, &bsg, &bch};
  for (int q = 0; q < 5; q++) if (rbs[q]->obj) PyBuffer_Release(rbs[q]);
  return res;
}
#pragma GCC pop_options
"""


#: C of the memo sites (Generator.case_memo, env_site): a hash table from
#: (site, the values of the slots the site reads) to its successors' labels
#: and the values of the slots it writes, filled by NativeModel._miss
_MEMO_C = r"""
#include <pthread.h>
static PyObject *MISS, *LABELS;
static unsigned char *LABSEEN;
static Py_ssize_t NLABELS;
/* per label its agent (-1: none): labels grow on memo misses.  The level
   kernel's threads read it while another thread's miss adds labels, so it
   is never moved: a larger one is made, filled and published, the old one
   left as it is (the labels are hundreds at most) */
static int *LABAG;
static Py_ssize_t LABCAP;
static int labels_grown(void) {
  Py_ssize_t nl = PyList_GET_SIZE(LABELS), cap = LABCAP;
  unsigned char *x = realloc(LABSEEN, nl + 1);
  if (!x) { PyErr_NoMemory(); return -1; }
  LABSEEN = x;
  int *y = LABAG;
  if (nl + 1 > cap) {
    cap = cap ? 2 * cap : 256;
    while (cap < nl + 1) cap *= 2;
    if (!(y = malloc(sizeof(int) * cap))) { PyErr_NoMemory(); return -1; }
    if (NLABELS) memcpy(y, LABAG, sizeof(int) * NLABELS);
  }
  for (Py_ssize_t k = NLABELS; k < nl; k++) {
    LABSEEN[k] = 0;
    PyObject *a = PyTuple_GetItem(PyList_GET_ITEM(LABELS, k), 1);
    if (!a) { if (y != LABAG) free(y); return -1; }
    y[k] = a == Py_None ? -1 : (int)PyLong_AsLong(a);
  }
  __atomic_store_n(&LABAG, y, __ATOMIC_RELEASE);
  LABCAP = cap;
  __atomic_store_n(&NLABELS, nl, __ATOMIC_RELEASE);
  return 0;
}
/* the arena: per entry [klen, vlen, key..., value...]; value = [n, then n
   times (label, the written slots' values)] */
static V *MA;
static size_t MA_N, MA_CAP;
static size_t *MSLOT, MSLOT_CAP, MEMO_N, MEMO_MISS, MEMO_HIT;
static void memo_clear(void) {
  free(MA); free(MSLOT);
  MA = NULL; MSLOT = NULL; MA_N = MA_CAP = MSLOT_CAP = MEMO_N = MEMO_MISS = MEMO_HIT = 0;
}
static uint64_t mhash(const V *k, int n) {
  uint64_t h = 0x9E3779B97F4A7C15ULL ^ (uint64_t)n;
  for (int q = 0; q < n; q++) { h ^= (uint64_t)k[q]; h *= 0xBF58476D1CE4E5B9ULL; h ^= h >> 31; }
  return h;
}
static const V *memo_find(const V *key, int kl) {
  if (!MSLOT_CAP) return NULL;
  size_t sl = mhash(key, kl) & (MSLOT_CAP - 1);
  for (;;) {
    size_t o = MSLOT[sl];
    if (!o) return NULL;
    const V *e = MA + (o - 1);
    if (e[0] == kl && !memcmp(e + 2, key, sizeof(V) * kl)) return e + 2 + kl;
    sl = (sl + 1) & (MSLOT_CAP - 1);
  }
}
static int memo_rehash(void) {
  size_t cap = MSLOT_CAP ? 2 * MSLOT_CAP : 4096;
  size_t *t = calloc(cap, sizeof(size_t));
  if (!t) { PyErr_NoMemory(); return -1; }
  for (size_t o = 0; o < MA_N; ) {
    const V *e = MA + o;
    size_t sl = mhash(e + 2, (int)e[0]) & (cap - 1);
    while (t[sl]) sl = (sl + 1) & (cap - 1);
    t[sl] = o + 1;
    o += 2 + e[0] + e[1];
  }
  free(MSLOT); MSLOT = t; MSLOT_CAP = cap;
  return 0;
}
static const V *memo_put(const V *key, int kl, const V *val, Py_ssize_t vl) {
  if (2 * (MEMO_N + 1) > MSLOT_CAP && memo_rehash()) return NULL;
  size_t need = MA_N + 2 + kl + vl;
  if (need > MA_CAP) {
    size_t cap = MA_CAP ? MA_CAP : 65536;
    while (cap < need) cap *= 2;
    V *a = realloc(MA, sizeof(V) * cap);
    if (!a) { PyErr_NoMemory(); return NULL; }
    MA = a; MA_CAP = cap;
  }
  V *e = MA + MA_N;
  e[0] = kl; e[1] = vl;
  memcpy(e + 2, key, sizeof(V) * kl);
  memcpy(e + 2 + kl, val, sizeof(V) * vl);
  size_t sl = mhash(key, kl) & (MSLOT_CAP - 1);
  while (MSLOT[sl]) sl = (sl + 1) & (MSLOT_CAP - 1);
  MSLOT[sl] = MA_N + 1;
  MA_N = need; MEMO_N++;
  return e + 2 + kl;
}
/* a miss: MISS(site, state) -> (value as int64 bytes, the label list grew) */
/* wl: the lock to hold alone while inserting (the level kernel's), or NULL */
static const V *memo_miss(const V *s, const V *key, int kl, pthread_rwlock_t *wl) {
  MEMO_MISS++;
  PyObject *st = state_bytes(s);
  if (!st) return NULL;
  PyObject *r = PyObject_CallFunction(MISS, "nN", (Py_ssize_t)key[0], st);
  if (!r) return NULL;
  PyObject *val = PyTuple_GetItem(r, 0);
  if (!val || !PyBytes_Check(val)) {
    Py_DECREF(r);
    if (!PyErr_Occurred()) PyErr_SetString(PyExc_TypeError, "memo miss: not bytes");
    return NULL;
  }
  if (wl) pthread_rwlock_wrlock(wl);
  const V *out = PyList_GET_SIZE(LABELS) > NLABELS && labels_grown() ? NULL
      : memo_put(key, kl, (const V *)PyBytes_AS_STRING(val),
                 PyBytes_GET_SIZE(val) / (Py_ssize_t)sizeof(V));
  if (wl) pthread_rwlock_unlock(wl);
  Py_DECREF(r);
  return out;
}
static int EMIT(int lab, const V *t);
#define MEMO_KMAX (NS + 1)
/* the level kernel's threads (KT) share the memo: a reader holds MLOCK
   shared while it reads an entry (an insertion may move the arena).  A
   miss, one at a time (MMISS), calls Python with the GIL taken (the kernel
   runs without it) while the others go on reading, and holds MLOCK alone
   only to insert its entry.  Lock order: MMISS, the GIL, MLOCK; the thread
   admitting (the GIL held) takes none of them.  An error in the miss is
   left to the explorer's batches, which expand the chunk again holding the
   GIL and raise it. */
static pthread_rwlock_t MLOCK;
static pthread_mutex_t MMISS = PTHREAD_MUTEX_INITIALIZER;
static int MLOCK_READY;
/* an interruption (KeyboardInterrupt: Ctrl-C, SIGTERM) raised in a miss's
   Python code: kept for explore_levels to hand back with its figures, and
   KINTR stops the kernel's threads */
static PyObject *KEXC;
static int KINTR;
static void memo_lock_init(void) {       /* (before the kernel's threads start) */
  if (MLOCK_READY) return;
  pthread_rwlockattr_t at;
  pthread_rwlockattr_init(&at);
#ifdef __GLIBC__                          /* a waiting insertion goes before new readers */
  pthread_rwlockattr_setkind_np(&at, PTHREAD_RWLOCK_PREFER_WRITER_NONRECURSIVE_NP);
#endif
  pthread_rwlock_init(&MLOCK, &at);
  pthread_rwlockattr_destroy(&at);
  MLOCK_READY = 1;
}
/* in the kernel, MLOCK not held: the entry of key, filled if missing;
   returns with MLOCK held shared (NULL: an error, MLOCK not held) */
static const V *memo_miss_kernel(const V *s, const V *key, int kl) {
  pthread_mutex_lock(&MMISS);
  pthread_rwlock_rdlock(&MLOCK);
  const V *val = memo_find(key, kl);      /* (another thread's miss may have filled it) */
  if (val) { pthread_mutex_unlock(&MMISS); return val; }
  pthread_rwlock_unlock(&MLOCK);
  PyGILState_STATE g = PyGILState_Ensure();
  KT = 0;
  int ok = memo_miss(s, key, kl, &MLOCK) != NULL;   /* (the entry is found again below) */
  if (!ok && !KEXC && PyErr_ExceptionMatches(PyExc_BaseException)
      && !PyErr_ExceptionMatches(PyExc_Exception)) {
    PyObject *et, *ev, *tb;
    PyErr_Fetch(&et, &ev, &tb);
    PyErr_NormalizeException(&et, &ev, &tb);
    if (tb && ev) PyException_SetTraceback(ev, tb);
    Py_XDECREF(et); Py_XDECREF(tb);
    KEXC = ev;
    __atomic_store_n(&KINTR, 1, __ATOMIC_RELEASE);
  }
  if (!ok) PyErr_Clear();
  KT = 1;
  PyGILState_Release(g);
  if (ok) {
    pthread_rwlock_rdlock(&MLOCK);
    val = memo_find(key, kl);
  }
  pthread_mutex_unlock(&MMISS);
  return val;
}
/* the successors of site k in state s: each a copy of s with the written
   slots W_ set (the rule's own label) */
static int memo_site(const V *s, int k, const int *R_, int nr, const int *W_, int nw) {
  V key[MEMO_KMAX];
  key[0] = k;
  for (int q = 0; q < nr; q++) key[1 + q] = s[R_[q]];
  int kt = KT;
  if (kt) pthread_rwlock_rdlock(&MLOCK);
  const V *val = memo_find(key, nr + 1);
  if (val) {
    if (kt) __atomic_fetch_add(&MEMO_HIT, 1, __ATOMIC_RELAXED);
    else MEMO_HIT++;
  } else if (!kt) {
    if (!(val = memo_miss(s, key, nr + 1, NULL))) { ovf = 1; return -1; }
  } else {
    pthread_rwlock_unlock(&MLOCK);
    if (!(val = memo_miss_kernel(s, key, nr + 1))) { ovf = 1; return -1; }
  }
  V n = val[0];
  const V *p = val + 1;
  int r = 0;
  for (V c = 0; c < n && !r; c++, p += 1 + nw) {
    V t[NS];
    memcpy(t, s, sizeof t);
    for (int q = 0; q < nw; q++) t[W_[q]] = p[1 + q];
    r = EMIT((int)p[0], t);
  }
  if (kt) pthread_rwlock_unlock(&MLOCK);
  return r ? -1 : 0;
}
"""


#: C of partial-order reduction's per-state test (see Generator.por_c):
#: reduce.Por.footprint / eligible / movable, independence.may_wait
_POR_C = r"""
/* what running agent j may still do before the next TIME ADVANCE
   (Por.footprint): at the top of its block with local guards, the events
   enabled now; else the rest of its k cell, plus every event body if its
   counter allows another EVENT SELECT (Independence.footprint) */
static void ind_footprint(const V *b, int j, uint64_t *r, uint64_t *w) {
  V pc = b[0];
  *r = PRR[pc]; *w = PRW[pc];
  if (b[1] + (PENDS[pc] ? 2 * RHO[j] : RHO[j]) <= KEEPN0) { *r |= EVR_ALL; *w |= EVW_ALL; }
}
static void footprint(const V *s, int j, uint64_t *r, uint64_t *w) {
  const V *b = s + AG0 + AW * j;
  if (GUARDS_LOCAL && b[0] == TOP_PC && b[1] + 2 * RHO[j] > KEEPN0) {
    if (b[1] + RHO[j] > KEEPN0) { *r = 0; *w = 0; return; }
    evfp(j, s, r, w);
    return;
  }
  ind_footprint(b, j, r, w);
}
static int may_wait(const V *s, int j) {
  const V *b = s + AG0 + AW * j;
  if (b[1] + RHO[j] > KEEPN0) return 0;
  if (b[2] == L_REQUEST) return 1;
  uint64_t r, w;
  ind_footprint(b, j, &r, &w);
  return (w & LQ_BIT) != 0;
}
/* whether agent i's next step (i running, an execution left) is
   independent of all the others can do in this time step (Por.eligible) */
static int eligible(const V *s, int i) {
  const V *ag = s + AG0 + AW * i;
  V pc = ag[VA_PC];
  if ((uint64_t)pc >= NPC) return 0;
  int cls = PCLS[pc];
  if (cls == C_LOCAL) return 1;
  if (cls == C_NEVER) return 0;
  if (cls == C_EXECUTE) return s[LQ0] == i;
  if (cls == C_REQUEST && ag[VA_LCK] == L_LOCK) return 1;
  if (cls == C_RELEASE) {
    for (int j = 0; j < NAG; j++)
      if (j != i && s[AG0 + AW * j + 3] == S_RUNNING && may_wait(s, j)) return 0;
    return 1;
  }
  uint64_t r = PSR[pc], w = PSW[pc];
  if (!(r | w)) return 1;
  for (int j = 0; j < NAG; j++)
    if (j != i && s[AG0 + AW * j + 3] == S_RUNNING) {
      uint64_t fr, fw;
      footprint(s, j, &fr, &fw);
      if ((w & (fr | fw)) || (r & fw)) return 0;
    }
  return 1;
}
/* whether merging may run agent i's next step (Por.movable): 0 no, 1 a
   step the stall signature does not see, 2 one that writes its data */
static int movable(const V *s, int i) {
  const V *ag = s + AG0 + AW * i;
  V pc = ag[VA_PC];
  if ((uint64_t)pc >= NPC) return 0;
  int cls = PCLS[pc];
  if (cls == C_EXECUTE) return s[LQ0] == i;
  if (cls == C_REQUEST && ag[VA_LCK] == L_LOCK) return 1;
  if (cls == C_ACCESS) { if (PEMPTY[pc]) return 0; }
  else if (cls != C_REQUEST && cls != C_RELEASE) return 0;
  if (!eligible(s, i)) return 0;
  return (cls != C_ACCESS || PWRITER[pc]) ? 2 : 1;
}
"""


#: C of the reduced step, the canonical key (see Generator.reduced_c)
_REDUCED_C = r"""
/* statement merging: run agent i's following mergeable steps in the
   successor at BUF[k] (Merger._chain: one successor per step, a chain
   stops where it revisits (pc, counter, locals) after 32 steps: those
   identities kept in SEEN, found through the open-addressing table SLOT) */
#define IDW (2 + NLOC)
#define NSLOT 4096
static __thread V *SEEN;           /* per thread, on the heap (kfree_tls) */
static __thread int16_t *SLOT;
static uint64_t idhash(const V *id) {
  uint64_t h = 0x9E3779B97F4A7C15ULL;
  for (int q = 0; q < IDW; q++) { h ^= (uint64_t)id[q]; h *= 0xBF58476D1CE4E5B9ULL; h ^= h >> 31; }
  return h;
}
static int sigeq(const V *a, const V *b) {
  for (int q = 0; q < NSIGSLOTS; q++) if (a[SIGSLOTS[q]] != b[SIGSLOTS[q]]) return 0;
  return 1;
}
/* s0: the state the transition leaves.  A chain that ran a step writing
   the stall signature's data (movable 2) and ends with the signature of
   s0 is cut right after its first change (Merger._cut) */
static int chain(const V *s0, Py_ssize_t k, int i) {
  V cur[NS], cut[NS];
  memcpy(cur, BUF + NS * k, sizeof cur);
  const int a0 = AG0 + AW * i;
  int n = 0, nseen = 0, marks = 0, ncut = -1;
  if (POR && !sigeq(cur, s0)) { memcpy(cut, cur, sizeof cut); ncut = 0; }
  for (;;) {
    V pc = cur[a0];
    if ((uint64_t)pc >= NPC || cur[a0 + 3] != @RUNNING@ || n >= MERGE_LIMIT) break;
    int mv = 0;
    if (cur[a0 + 1] + RHO[i] > KEEPN0) {
      /* spent: only its own plain statements (Independence.spent_local) */
      if (!(POR && PSPENT[pc])) break;
    } else if (!MERGEOK[pc]) {
      if (!POR) break;
      mv = movable(cur, i);
      if (!mv) break;
    }
    if (n >= 32) {
      if (!SEEN) {
        SEEN = malloc(sizeof(V) * (MERGE_LIMIT + 1) * IDW);
        SLOT = malloc(sizeof(int16_t) * NSLOT);
        if (!SEEN || !SLOT) { free(SEEN); free(SLOT); SEEN = NULL; SLOT = NULL; ovf = 1; return -1; }
      }
      V *id = SEEN + IDW * nseen;
      id[0] = pc; id[1] = cur[a0 + 1];
      memcpy(id + 2, cur + a0 + 4, sizeof(V) * NLOC);
      if (!nseen) memset(SLOT, -1, sizeof(int16_t) * NSLOT);
      size_t sl = idhash(id) & (NSLOT - 1);
      int hit = 0;
      while (SLOT[sl] >= 0) {
        if (!memcmp(SEEN + IDW * SLOT[sl], id, sizeof(V) * IDW)) { hit = 1; break; }
        sl = (sl + 1) & (NSLOT - 1);
      }
      if (hit) break;
      SLOT[sl] = (int16_t)nseen++;
    }
    Py_ssize_t b = BN;
    if (agent_of(i, cur)) return -1;
    if (BN == b) break;
    memcpy(cur, BUF + NS * b, sizeof cur);
    BN = b;
    n++;
    if (mv == 2) {
      marks = 1;
      if (ncut < 0 && !sigeq(cur, s0)) { memcpy(cut, cur, sizeof cut); ncut = n; }
    }
  }
  if (marks && ncut >= 0 && sigeq(cur, s0)) { memcpy(cur, cut, sizeof cur); n = ncut; }
  if (n) { memcpy(BUF + NS * k, cur, sizeof cur); BCH[k] = n; }
  return 0;
}
/* the reduced successors of s appended to the buffer: the ample set of
   partial-order reduction (else every successor), each merged */
static int rstep(const V *s) {
  Py_ssize_t b0 = BN;
#if POR
  if (s[@V_PHASE@] == @DISCRETE@) {
@AMPLE@
  }
#endif
  if (step(s)) return -1;
  goto chains;
chains:
#if MERGE
  if (s[@V_PHASE@] == @DISCRETE@)
    for (Py_ssize_t k = b0; k < BN; k++) {
      BIDX[k] = (int32_t)(k - b0);
      int i = __atomic_load_n(&LABAG, __ATOMIC_ACQUIRE)[BLAB[k]];   /* the label's agent (-1: none) */
      if (i >= 0 && chain(s, k, i)) return -1;
    }
#endif
  return ovf ? -1 : 0;
}
/* symmetry: the canonical representative of s's orbit under permutations
   of the agents (each agent's whole block moves; id-valued slots BID of a
   block and SHID of shared, and the lock queue, renamed).  Agents are
   sorted by their blocks with ids masked (own id, another's), which shared
   id variables name them and their place in the lock queue; agents that
   name others are tried in every order among equals, the least vector
   wins.  A canonical form of the orbit, as reduce.py's key is: the two
   keys identify the same states. */
#define SIGW (AW + NSHID + 1)
#define MSELF (INT64_MIN + 1)
#define MOTHER (INT64_MIN + 2)
static int vcmp(const V *a, const V *b, int n) {
  for (int q = 0; q < n; q++) if (a[q] != b[q]) return a[q] < b[q] ? -1 : 1;
  return 0;
}
static void build(const V *s, const int *order, V *out) {
  int r[NAG];
  for (int p = 0; p < NAG; p++) r[order[p]] = p;
  memcpy(out, s, sizeof(V) * AG0);
  for (int k = 0; k < NAG; k++) if (out[LQ0 + k] >= 0 && out[LQ0 + k] < NAG) out[LQ0 + k] = r[out[LQ0 + k]];
  for (int q = 0; q < NSHID; q++) {
    V x = out[SHID[q]];
    if (x >= 0 && x < NAG) out[SHID[q]] = r[x];
  }
  for (int p = 0; p < NAG; p++) {
    V *b = out + AG0 + AW * p;
    memcpy(b, s + AG0 + AW * order[p], sizeof(V) * AW);
    for (int q = 0; q < NBID; q++) {
      V x = b[BID[q]];
      if (x >= 0 && x < NAG) b[BID[q]] = r[x];
    }
  }
}
static int next_perm(int *a, int n) {
  int i = n - 2;
  while (i >= 0 && a[i] >= a[i + 1]) i--;
  if (i < 0) { for (int l = 0, h = n - 1; l < h; l++, h--) { int t = a[l]; a[l] = a[h]; a[h] = t; } return 0; }
  int j = n - 1;
  while (a[j] <= a[i]) j--;
  int t = a[i]; a[i] = a[j]; a[j] = t;
  for (int l = i + 1, h = n - 1; l < h; l++, h--) { t = a[l]; a[l] = a[h]; a[h] = t; }
  return 1;
}
static void canon(const V *s0, V *out) {
#if DEAD
  uint64_t dd[NAG];
  V dm[NS];
  const V *s = s0;
  if (dead_bits(s0, dd)) { memcpy(dm, s0, sizeof dm); dead_apply(dm, dd); s = dm; }
#else
  const V *s = s0;
#endif
#if SYM
  V g[NAG][SIGW];
  int order[NAG], other = 0;
  for (int j = 0; j < NAG; j++) {
    V *x = g[j];
    memcpy(x, s + AG0 + AW * j, sizeof(V) * AW);
    for (int q = 0; q < NBID; q++) {
      V v = x[BID[q]];
      if (v >= 0) { if (v == j) x[BID[q]] = MSELF; else { x[BID[q]] = MOTHER; other = 1; } }
    }
    for (int q = 0; q < NSHID; q++) x[AW + q] = s[SHID[q]] == j;
    V p = -1;
    for (int k = 0; k < NAG; k++) if (s[LQ0 + k] == j) { p = k; break; }
    x[AW + NSHID] = p;
    order[j] = j;
  }
  for (int a = 1; a < NAG; a++) {          /* stable insertion sort */
    int t = order[a], b = a;
    while (b > 0 && vcmp(g[order[b - 1]], g[t], SIGW) > 0) { order[b] = order[b - 1]; b--; }
    order[b] = t;
  }
  int ties = 0;
  if (other)
    for (int a = 1; a < NAG; a++) if (!vcmp(g[order[a - 1]], g[order[a]], SIGW)) { ties = 1; break; }
  build(s, order, out);
  if (!ties) return;
  /* the groups of equal agents, each tried in every order */
  int start[NAG], len[NAG], ng = 0;
  for (int a = 0; a < NAG; ) {
    int b = a + 1;
    while (b < NAG && !vcmp(g[order[a]], g[order[b]], SIGW)) b++;
    start[ng] = a; len[ng] = b - a; ng++;
    a = b;
  }
  V tmp[NS];
  for (;;) {
    int gi = ng - 1;
    while (gi >= 0 && !next_perm(order + start[gi], len[gi])) gi--;
    if (gi < 0) break;
    build(s, order, tmp);
    if (vcmp(tmp, out, NS) < 0) memcpy(out, tmp, sizeof tmp);
  }
#else
  memcpy(out, s, sizeof(V) * NS);
#endif
}
"""


# ---------------------------------------------------------------------------
# Building and loading
# ---------------------------------------------------------------------------

# The module cache ($PCCL_CACHE or ~/.cache/pccl): one file per generated
# source, written atomically (compiled in a temporary directory of the cache,
# then renamed: a half-written module is never under a module's name), kept
# under a size bound ($PCCL_CACHE_SIZE) by removing the least recently used
# modules after a new one is written.  A module is touched when it is
# loaded (its mtime is its last use).  The cache's lock file orders loading
# and pruning between processes: a process holds it shared from the look
# for its module to the end of loading it, the pruner exclusively, so no
# module is removed while another process loads it (a module another
# process has loaded may go: on Linux its mapping stays).  A process never
# removes a module it has loaded itself.

#: the cache's bound when $PCCL_CACHE_SIZE is not set (a module is 25-60 KB:
#: about 2,500 modules)
CACHE_SIZE_DEFAULT = 100 * 2**20
CACHE_SIZE_ENV = "PCCL_CACHE_SIZE"
#: a compile's temporary directory left by a killed process is removed by
#: the pruner once it is this old (seconds)
STALE_TMP = 3600.0
_PREFIX = "pccl_native_"
_LOCK = ".native.lock"
#: the modules this process has loaded (never pruned by it)
_LOADED: set = set()


def cache_bound() -> Optional[int]:
    """The cache's bound in bytes from $PCCL_CACHE_SIZE (a size: bytes, or a
    number with K, M, G; ``0``: no bound), :data:`CACHE_SIZE_DEFAULT` when
    unset; a :class:`~pccl.lang.errors.PcclError` naming the variable when
    it is not a size."""
    text = os.environ.get(CACHE_SIZE_ENV)
    if text is None or not text.strip():
        return CACHE_SIZE_DEFAULT
    if text.strip() == "0":
        return None
    from pccl.search.memory import parse_size
    from pccl.lang.errors import PcclError
    try:
        return parse_size(text)
    except ValueError:
        raise PcclError(f"expected a size such as 100M or 1G (0: no bound) for the native "
                        f"module cache, got {text!r}", filename=CACHE_SIZE_ENV) from None


def _module_ext() -> str:
    return sysconfig.get_config_var("EXT_SUFFIX") or ".so"


class _Lock:
    """The cache's lock file, held shared (loading) or exclusive (pruning)
    while the ``with`` block runs; a no-op where there is no ``fcntl``."""

    def __init__(self, d: str, exclusive: bool):
        self.path, self.exclusive = os.path.join(d, _LOCK), exclusive
        self.f: Any = None

    def __enter__(self):
        try:
            import fcntl
        except ImportError:         # pragma: no cover - not POSIX
            return self
        try:
            self.f = open(self.path, "a")
        except OSError:             # a cache that cannot be written: nothing is pruned
            return self
        fcntl.flock(self.f, fcntl.LOCK_EX if self.exclusive else fcntl.LOCK_SH)
        return self

    def __exit__(self, *exc) -> None:
        if self.f is not None:
            self.f.close()          # releases the lock
            self.f = None


def cache_modules(d: Optional[str] = None) -> list:
    """The native modules in the cache: ``(last use, size, path)``, least
    recently used first."""
    d = cache_dir() if d is None else d
    ext = _module_ext()
    out = []
    try:
        names = os.listdir(d)
    except OSError:
        return []
    for n in names:
        if n.startswith(_PREFIX) and n.endswith(ext):
            p = os.path.join(d, n)
            try:
                st = os.stat(p)
            except OSError:         # removed meanwhile
                continue
            out.append((st.st_mtime, st.st_size, p))
    out.sort()
    return out


def prune_cache(d: Optional[str] = None, bound: Optional[int] = None, *,
                keep=()) -> list:
    """Remove the least recently used modules until the cache holds at most
    ``bound`` bytes of them (never one in ``keep`` or loaded by this
    process), and compile directories older than :data:`STALE_TMP`; the
    paths removed.  ``bound`` None: only the stale directories."""
    import time
    d = cache_dir() if d is None else d
    removed: list = []
    spare = {os.path.abspath(p) for p in (*keep, *_LOADED)}
    with _Lock(d, exclusive=True):
        now = time.time()
        for n in os.listdir(d):
            p = os.path.join(d, n)
            if n.startswith("tmp") and os.path.isdir(p):
                try:
                    if now - os.stat(p).st_mtime > STALE_TMP:
                        shutil.rmtree(p, ignore_errors=True)
                except OSError:
                    pass
        if bound is None:
            return removed
        mods = cache_modules(d)
        total = sum(m[1] for m in mods)
        for _, size, p in mods:
            if total <= bound:
                break
            if os.path.abspath(p) in spare:
                continue
            try:
                os.unlink(p)
            except FileNotFoundError:       # another pruner was first
                pass
            except OSError:
                continue
            total -= size
            removed.append(p)
    return removed


def clear_cache(d: Optional[str] = None) -> tuple:
    """Remove every native module of the cache (and stale compile
    directories); ``(modules removed, bytes)``."""
    d = cache_dir() if d is None else d
    mods = cache_modules(d)
    if not mods:
        return 0, 0
    gone = prune_cache(d, 0)
    sizes = {p: size for _, size, p in mods}
    return len(gone), sum(sizes[p] for p in gone)


def _compile(d: str, name: str, src: str, path: str) -> None:
    """Compile the module ``name`` of source ``src`` to ``path`` (atomically:
    in a temporary directory of the cache, then renamed)."""
    cc = compiler()
    assert cc is not None
    full = f"#define MODNAME \"{name}\"\n#define INITFN PyInit_{name}\n" + src
    with tempfile.TemporaryDirectory(dir=d) as tmp:
        c_path = os.path.join(tmp, name + ".c")
        with open(c_path, "w") as f:
            f.write(full)
        out = os.path.join(tmp, name + _module_ext())
        inc = sysconfig.get_paths()["include"]
        p = subprocess.run([cc, "-O2", "-shared", "-fPIC", "-pthread", "-w", f"-I{inc}", "-o", out,
                            c_path], capture_output=True, text=True)
        if p.returncode != 0:
            raise RuntimeError(f"the C compiler failed on the native module:\n{p.stderr[-2000:]}")
        os.chmod(out, 0o755)        # whatever the umask: no one else may write it
        os.replace(out, path)


#: the directory of this process's modules when the cache directory is not
#: private (:func:`module_dir`)
_PROCESS_DIR: list = []


def module_dir() -> str:
    """Where native modules are compiled to and loaded from: the cache
    directory when it is private to this user (a shared object runs when
    it is loaded: :mod:`pccl.lang.cachedir`), else a directory of this
    process's own (mode 0700, removed at exit): nothing is reused then."""
    d = private_cache_dir()
    if d is not None:
        return d
    if not _PROCESS_DIR:
        import atexit
        _PROCESS_DIR.append(tempfile.mkdtemp(prefix="pccl-native-"))
        atexit.register(shutil.rmtree, _PROCESS_DIR[0], True)
    return _PROCESS_DIR[0]


def build(src: str):
    """Compile ``src`` into an extension module (cached by the hash of the
    source and the Python ABI); the module.  After compiling a new one, the
    cache is pruned to its bound (:func:`prune_cache`)."""
    bound = cache_bound()           # a bad $PCCL_CACHE_SIZE: before any work
    tag = sysconfig.get_config_var("SOABI") or sys.implementation.cache_tag
    digest = hashlib.sha256((src + tag).encode()).hexdigest()[:20]
    name = f"{_PREFIX}{digest}"
    d = module_dir()
    path = os.path.join(d, name + _module_ext())
    built = False
    mod = None
    for _ in range(3):      # a module pruned by another process between the two looks
        if not os.path.exists(path) or not private_file(path):
            _compile(d, name, src, path)
            built = True
        with _Lock(d, exclusive=False):
            if not os.path.exists(path):
                continue
            try:
                os.utime(path)      # its last use: the pruner removes the least recent
            except OSError:         # a cache that cannot be written
                pass
            spec = importlib.util.spec_from_file_location(name, path)
            assert spec is not None and spec.loader is not None
            mod = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(mod)
            _LOADED.add(os.path.abspath(path))
            break
    if mod is None:
        raise RuntimeError(f"the native module {path} was removed three times while loading")
    if built:
        prune_cache(d, bound, keep=(path,))
    return mod


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
        #: the generated source's hash: part of a checkpoint's identity (its
        #: states are this source's vectors, pccl/search/checkpoint.py)
        self.source_hash = hashlib.sha256(src.encode()).hexdigest()[:16]
        xxh = _xxh3_128_address()
        #: the interned values (positions, lists, obstacle lists, targets,
        #: t0, env) of this process: id -> value and the value's canonical
        #: encoding -> id (:meth:`_put`)
        self._vals: dict = {}
        self._ids: dict = {}
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
        #: whether positions, reach cells and env are in the vector
        self.moves = gen.moves
        # the label list grows on memo misses (C reads the same list)
        self.lib.setup(gen.labels, NativeOverflow, self._violations, xxh or 0, self._miss)
        self.gen = gen
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
        #: what the graph recorder reads (pccl/search/liveness.py): no
        #: temporal property is served
        self.N = py.N
        self.temporal = ()
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
            else:
                i = len(self._vals)
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
        return True

    def stuck_table(self) -> dict:
        """The Python model's stuck reasons (stuck statuses are the same
        numbers in the vectors)."""
        return self.py.stuck_table()

    def checkpoint_tables(self) -> dict:
        """What a checkpoint keeps besides the states: the Python model's
        lazily interned tables and, for a program that moves, the interned
        values by id (the states name them by id: positions, lists, any
        value the C code holds by id)."""
        out = dict(self._py_tables()) if self._py_tables is not None else {}
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
            if not self._put(i, marshal.dumps(x, 2), x):
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

    def stall_signatures(self, states: list):
        """:meth:`stall_signature` of each state of a list, as an int64
        array (one C call)."""
        import numpy as np
        return np.frombuffer(self.lib.sigs(states), dtype=np.int64)

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
