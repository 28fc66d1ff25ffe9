"""What compiling a PCCL program produces: :class:`CompiledProgram`.

The checker's :class:`~pccl.lang.types.CheckedProgram`, the slots of the
configuration (:class:`~pccl.model.compile.Layout`), the statements' closures, the
guards and the enabled-events function, and the tables that give a
configuration's numbers their meaning: :class:`Control` interns k cells as
pcs, :attr:`CompiledProgram.stuck_reasons` maps stuck statuses to reasons.
It knows nothing of the world, the blackbox, time or the search: the
transition system over these configurations is :class:`pccl.model.engine.Model`,
which holds one ``CompiledProgram`` (``model.compiled``).
"""

from __future__ import annotations

from typing import Optional
from collections.abc import Callable, Mapping

import xxhash

from pccl.lang import ast as A
from pccl.model.compile import Compiler, Layout, Oracle, VarSlot, build_layout, has_rand
from pccl.lang.errors import PcclError, PcclRuntimeError
from pccl.model.layout import AEND, AGS, END, SH, acq, acquire_sid, is_acquire
# (the types of doReach's arguments)
from pccl.lang.types import OBSTACLES as OBSTACLES_TY, POS as POS_TY
from pccl.semantics import rules as R
from pccl.semantics.rules import (K_AEND, K_ACQ, K_ASSERT, K_ATOMIC, K_DOREACH, K_EMPTY, K_END, K_EXIT, K_IF, K_SIMPLE,
                                  K_WHILE, KHead)


class CompiledProgram:
    """A checked and compiled PCCL program for a team of ``n_agents``.

    ``functions`` are the uninterpreted functions' values (the world's, and
    the caller's); ``rand_policy`` chooses ``rand`` outcomes in a run (None:
    every outcome, for a search); ``first_only`` compiles ``--events first``
    into the enabled-events function."""

    def __init__(self, program: A.Program, *, functions: Mapping, n_agents: int,
                 rand_policy: Optional[Callable] = None, first_only: bool = False):
        from pccl.lang.checker import check_program
        self.program = program
        self.functions = dict(functions)
        self.first_only = first_only
        #: the checker's result: variables, types, enums, built-ins
        self.info = check_program(program, functions=frozenset(self.functions))
        #: the slots of the variables in the configuration's cells
        self.layout: Layout = build_layout(program, self.info)
        #: ``rand`` outcomes: every one (explore) or the policy's (run)
        self.oracle = Oracle(rand_policy)
        self.oracle.filename, self.oracle.source = program.filename, program.source
        self.comp = Compiler(program, self.layout, n_agents, self.functions, self.oracle,
                             self.info)
        #: statement id -> statement, and -> its event (None: Init)
        self.stmts, self.stmt_event = _index_statements(program)
        #: statement id -> its compiled closure (None for atomic and exit)
        self.code = {sid: self._compile_stmt(s) for sid, s in self.stmts.items()}
        self.guards = [self.comp.make_expr(ev.guard) for ev in program.events]
        self.guards_rand = any(has_rand(ev.guard) for ev in program.events)
        self.enabled_events = self._compile_enabled_events()
        #: the k cells, interned as pcs
        self.ctl = Control(self)
        self._decl_fns: dict[int, Callable] = {}     # id(VarSlot) -> its initialiser
        #: status code -> (kind, reason, where) of a stuck agent
        self.stuck_reasons: dict = {}

    # -- statements and guards ------------------------------------------------------------
    def _compile_stmt(self, s: A.Stmt):
        c = self.comp
        if isinstance(s, A.If):
            return c.if_chooser(s)
        if isinstance(s, A.While):
            return c.make_expr(s.cond)
        if isinstance(s, A.Atomic):
            return None
        if isinstance(s, A.CallStmt):
            if s.name == "doReach":
                assert len(s.args) == 2, "the checker counts arguments"
                t = c.value(s.args[0], POS_TY)
                o = c.value(s.args[1], OBSTACLES_TY)
                return c.make("i, ag, sh, ags", f"    return ({t}, {o})\n", f"_dr{s.sid}")
            if s.name == "exit":
                return None
            if s.name == "assert":
                return c.make_expr(s.args[0])
            assert s.name in ("add", "remove"), f"the checker knows no statement {s.name!r}"
            return c.effect(s)
        return c.effect(s)

    def enabled_events_slow(self, i, ag, sh, ags) -> list:
        """The events whose guard holds, in source order (only the first with
        ``--events first``), one guard call at a time: the reference for
        :attr:`enabled_events`, the same function compiled in one piece."""
        out = []
        for e, g in enumerate(self.guards):
            try:
                ok = g(i, ag, sh, ags)
            except R.RUNTIME_ERRORS as exc:
                raise guard_error(exc, e) from None
            if ok:
                out.append(e)
                if self.first_only:
                    break
        return out

    def _compile_enabled_events(self) -> Callable:
        """``enabled_events(i, ag, sh, ags)`` as one generated function: every
        guard inline, one call per EVENT SELECT instead of one per guard."""
        comp = self.comp
        comp.G["_guard_error"] = guard_error
        comp.G["_RTE"] = R.RUNTIME_ERRORS
        body = "    out = []\n"
        for e, ev in enumerate(self.program.events):
            hit = f"return [{e}]" if self.first_only else f"out.append({e})"
            body += (f"    try:\n        if {comp.expr(ev.guard)}:\n            {hit}\n"
                     f"    except _RTE as exc:\n        raise _guard_error(exc, {e}) from None\n")
        body += "    return out\n"
        return comp.make("i, ag, sh, ags", body, "_enabled_events")

    def decl_init(self, vs: VarSlot) -> Callable:
        """``fn(i, ag, sh, ags)``: the value of declaration ``vs``'s
        initialiser (an array's is one element's value, filling the array),
        compiled once."""
        fn = self._decl_fns.get(id(vs))
        if fn is None:
            want = vs.ty.elem if vs.ty.kind == "array" else vs.ty
            assert vs.decl.init is not None and want is not None, vs
            src = self.comp.value(vs.decl.init, want)
            fn = self._decl_fns[id(vs)] = self.comp.make("i, ag, sh, ags", f"    return {src}\n",
                                                         f"_init_{vs.name}")
        return fn

    # -- properties -----------------------------------------------------------------------
    def check_property(self, expr: A.Expr, *, filename, source) -> None:
        """Check a property against the program (a PcclError if it is wrong)."""
        from pccl.lang.checker import check_property
        check_property(expr, self.info, filename=filename, source=source)

    def state_predicate(self, expr: A.Expr) -> tuple[str, Callable]:
        """A checked property as Python source (over ``st``, ``sh``, ``ags``)
        and as a function ``fn(st) -> bool``."""
        src = self.comp.expr(expr, prop=True)
        return src, self.comp.make("st", f"    sh = st[{SH}]; ags = st[{AGS}]\n    return {src}\n")

    def constant(self, expr: A.Expr):
        """The value of a checked constant expression of a property (Python
        exceptions escape)."""
        return eval(self.comp.expr(expr, prop=True), dict(self.comp.G))

    def make_function(self, params: str, body: str, name: str, **names) -> Callable:
        """Generated code over the compiled program's globals and ``names``."""
        self.comp.G.update(names)
        return self.comp.make(params, body, name)

    # -- stuck statuses -------------------------------------------------------------------
    def stuck_code(self, kind, reason, where) -> int:
        """The status of an agent stuck for ``reason``: a function of the
        reason's content (2 + 62 bits of its xxh3 hash), not of the order in
        which a search meets reasons, so that every process of a parallel
        search gives a stuck agent the same status.  Two different reasons
        share a code with probability 2**-62 per pair."""
        key = (kind, reason, where)
        code = 2 + (xxhash.xxh3_64_intdigest(repr(key).encode()) >> 2)
        known = self.stuck_reasons.setdefault(code, key)
        if known != key:     # pragma: no cover - a 62-bit collision
            raise PcclError(f"internal: stuck reasons {known!r} and {key!r} share a code")
        return code

    # -- source locations -----------------------------------------------------------------
    def span_of(self, where) -> Optional[A.Span]:
        """The source span of a stuck reason's ``where``: a statement id, a
        guard ``("guard", e)`` or a declaration ``("decl", span)``."""
        if isinstance(where, int):
            return self.stmts[where].span
        if isinstance(where, tuple) and where and where[0] == "guard":
            return self.program.events[where[1]].guard.span
        if isinstance(where, tuple) and where and where[0] == "decl":
            return where[1]
        return None

    def stmt_span(self, sid) -> Optional[A.Span]:
        s = self.stmts.get(sid)
        return s.span if s is not None else None

    def describe_k(self, pc) -> str:
        """A short description of an agent's pending computation."""
        cell = self.ctl.cells[pc]
        if not cell:
            return "at the top of the event block"
        h = cell[0]
        if h == END:
            return "finishing its event block"      # endEventBlock: COUNTER ADVANCE next
        if h == AEND:
            return "releasing the lock"             # atomicEnd: LOCK RELEASE next
        if is_acquire(h):
            s = self.stmts[acquire_sid(h)]
            return f"waiting for the lock at line {s.span.line}"
        s = self.stmts[h]
        return f"at line {s.span.line}"


def _index_statements(program: A.Program) -> tuple[dict, dict]:
    """Every statement by id, and the event it belongs to (None: Init)."""
    stmts: dict[int, A.Stmt] = {}
    stmt_event: dict[int, Optional[int]] = {}
    for s in A.walk_stmts(program.init):
        stmts[s.sid] = s
        stmt_event[s.sid] = None
    for k, ev in enumerate(program.events):
        for s in A.walk_stmts(ev.body):
            stmts[s.sid] = s
            stmt_event[s.sid] = k
    return stmts, stmt_event


def guard_error(exc, e) -> PcclRuntimeError:
    """A runtime error in event e's guard, located there."""
    err = PcclRuntimeError(getattr(exc, "reason", None) or R.describe_error(exc))
    err.where = ("guard", e)
    return err


class Control:
    """Interns k cells as integers and decodes their head once.

    A k cell is a cons list: pc ``p`` stands for ``(head, rest_pc)`` (or the
    empty k), hash-consed so that equal k cells get equal pcs.  Interning a
    statement list in front of a continuation costs one entry per
    statement, so an effect of n statements costs O(n) memory, not the
    O(n²) of storing every suffix as a tuple."""

    def __init__(self, compiled: "CompiledProgram"):
        self.prog = compiled
        self.cells: list = []
        self.ids: dict = {}
        self.infos: list = []
        self.ks = _KView(self)
        self.empty_pc = self._cell(())
        self.idle_pc = self.cons(END, self.empty_pc)
        self.event_pcs = [self.seq(tuple(s.sid for s in ev.body), self.idle_pc)
                          for ev in compiled.program.events]

    def close(self) -> None:
        """Intern every k cell reachable from the event bodies and Init, in a
        fixed order, so that pc numbers do not depend on the order in which
        a search meets them (worker processes of a parallel search must
        agree on them)."""
        if self.prog.program.init:
            self.intern(tuple(s.sid for s in self.prog.program.init))
        pc = 0
        while pc < len(self.cells):
            self.info(pc)
            pc += 1

    def _cell(self, cell) -> int:
        pc = self.ids.get(cell)
        if pc is None:
            pc = len(self.cells)
            self.ids[cell] = pc
            self.cells.append(cell)
            self.infos.append(None)
        return pc

    def cons(self, head: int, rest: int) -> int:
        """The pc of ``head ~> k(rest)``."""
        return self._cell((head, rest))

    def seq(self, items, rest: int) -> int:
        """The pc of ``items ~> k(rest)``."""
        pc = rest
        for x in reversed(items):
            pc = self._cell((x, pc))
        return pc

    def intern(self, k: tuple) -> int:
        """The pc of the k cell given as a tuple."""
        return self.seq(k, self.empty_pc)

    def iter_k(self, pc: int):
        """The items of k(pc), head first."""
        cell = self.cells[pc]
        while cell:
            yield cell[0]
            cell = self.cells[cell[1]]

    def info(self, pc: int) -> KHead:
        """The decoded head of k(pc), built once."""
        inf = self.infos[pc]
        if inf is None:
            inf = self.infos[pc] = self._decode(pc)
        return inf

    def _decode(self, pc: int) -> KHead:
        cell = self.cells[pc]
        if not cell:
            return KHead(K_EMPTY)
        head, rest = cell
        seq = self.seq
        if head == END:
            return KHead(K_END)
        if head == AEND:
            return KHead(K_AEND, next_pc=rest)
        if is_acquire(head):
            sid = acquire_sid(head)
            atomic = self.prog.stmts[sid]
            assert isinstance(atomic, A.Atomic), atomic      # acq(sid) heads an atomic block
            body = tuple(s.sid for s in atomic.body)
            return KHead(K_ACQ, body_pc=seq(body, rest), sid=sid)
        s = self.prog.stmts[head]
        c = self.prog.code[head]
        if isinstance(s, A.If):
            pcs = tuple(seq(tuple(x.sid for x in body), rest) for _, body in s.branches)
            pcs += (seq(tuple(x.sid for x in s.orelse), rest),)
            return KHead(K_IF, fn=c, branch_pcs=pcs, sid=head, has_rand=has_rand(s))
        if isinstance(s, A.While):
            return KHead(K_WHILE, fn=c, body_pc=seq(tuple(x.sid for x in s.body), pc),
                         next_pc=rest, sid=head, has_rand=has_rand(s))
        if isinstance(s, A.Atomic):
            return KHead(K_ATOMIC, request_pc=seq((acq(head), AEND), rest),
                         body_pc=seq(tuple(x.sid for x in s.body), rest), sid=head)
        if isinstance(s, A.CallStmt) and s.name == "doReach":
            return KHead(K_DOREACH, fn=c, next_pc=rest, sid=head, has_rand=has_rand(s))
        if isinstance(s, A.CallStmt) and s.name == "exit":
            return KHead(K_EXIT, sid=head)
        if isinstance(s, A.CallStmt) and s.name == "assert":
            return KHead(K_ASSERT, fn=c, next_pc=rest, sid=head, has_rand=has_rand(s))
        return KHead(K_SIMPLE, fn=c, next_pc=rest, sid=head, has_rand=has_rand(s))


class _KView:
    """``ctl.ks[pc]``: the k cell of ``pc`` as a tuple (built on demand)."""

    def __init__(self, ctl: Control):
        self.ctl = ctl

    def __getitem__(self, pc: int) -> tuple:
        return tuple(self.ctl.iter_k(pc))

    def __len__(self) -> int:
        return len(self.ctl.cells)
