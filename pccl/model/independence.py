"""The static analysis behind partial-order reduction's ample sets
(docs/reductions.md, "Partial-order reduction"): which step of an agent is
independent of everything the other agents can still do before the next
TIME ADVANCE.

Every ``allwrite`` and ``allread`` variable gets a bit; so does the lock
queue's tail (:data:`LQ_BIT`, "may append itself to the lock queue").  For
each k cell (pc) the analysis knows

* the *step* an agent at that pc takes: the variables it reads and writes
  (:meth:`Independence.step`), or that it is never ample (a ``while`` or a
  statement inside one, ``exit``, a write of a variable a property reads, a
  doReach when a property reads the doReach flags);
* the *rest*: the union of the reads and writes of every statement left in
  the k cell (all branches, loop bodies, atomic bodies), whether an
  ``atomic`` is among them, and whether the k cell ends the event execution
  (``endEventBlock``) or is the top / Init.

An agent j that is running can, before the next TIME ADVANCE, execute only
the statements of its rest, and the bodies of new events only if its
counter still allows another EVENT SELECT (:meth:`Independence.footprint`).
Counters only grow inside a time step, so this over-approximates every
path.  A step of agent i is independent of all that when its writes meet
none of j's reads or writes and its reads none of j's writes; reads and
writes of a *lock-protected* variable (one the program touches only inside
``atomic`` bodies) by an agent that holds the lock are left out, since no
other agent can touch it before that agent's next step (its release).

The lock rules: ATOMIC EXECUTION (i at the head of the queue) changes only
i's cell and nobody can take i off the head, so it is local; LOCK REQUEST
appends to the queue and commutes with everything but another agent's
LOCK REQUEST; LOCK RELEASE takes i off the head, which disables the ATOMIC
WAIT of the next agent in the queue, so it is independent when no other
agent can still perform ATOMIC WAIT in this time step.  ATOMIC WAIT itself
is never ample.
"""

from __future__ import annotations

from typing import Optional

from pccl.lang import ast as A
from pccl.model.layout import AEND, CNT, END, LCK, LOCK, PC, REQUEST, is_acquire, acquire_sid
from pccl.semantics.rules import (K_ACQ, K_AEND, K_ASSERT, K_ATOMIC, K_DOREACH, K_EMPTY, K_END, K_IF,
                                  K_SIMPLE, K_WHILE)

#: "may perform LOCK REQUEST" (in a rest or footprint's writes; a LOCK
#: REQUEST step writes it): the one bit of the lock queue's tail.
LQ_BIT = 1

#: Step classes (:meth:`Independence.step`).
NEVER, LOCAL, ACCESS, REQUEST_LOCK, RELEASE, EXECUTE = range(6)

#: The built-in calls a statement of the program may make that read state
#: other than their arguments: none but getPosition (the agent's own
#: position, which only DOREACH INVOKE changes, after TIME ADVANCE).  The
#: uninterpreted functions (world constants) take no arguments.  So calls
#: add no variable to a footprint.


#: Built-in expressions that read nothing but their arguments (and the
#: agent's own id); getPosition reads the position, which the environment
#: writes.
PURE_CALLS = frozenset({"rand", "getAgentIndex", "getNumAgents", "ItemPosition", "dist",
                        "head", "isEmpty", "size", "contains"})

def property_names(m) -> set:
    names = set()
    for p in m.property_exprs:
        for e in A.walk_expr(p):
            if isinstance(e, A.Name):
                names.add(e.name)
    return names


def local_guards(m) -> bool:
    """Whether every event guard reads only the agent's own ``loc:``
    variables (any of them: reading a property's variable is invisible),
    enum members and pure calls: then EVENT SELECT and IDLE touch only the
    agent's own k cell."""
    lay = m.compiled.layout
    funcs = set(m.compiled.functions)
    for ev in m.program.events:
        for e in A.walk_expr(ev.guard):
            if isinstance(e, A.Name):
                vs = lay.vars.get(e.name)
                if vs is None:
                    if e.name not in lay.members:
                        return False
                elif vs.section != "loc":
                    return False
            elif isinstance(e, A.Call):
                if e.name not in PURE_CALLS and not (e.name in funcs and not e.args):
                    return False
            elif isinstance(e, A.Quant):
                return False
    return True


def _own_exprs(s) -> tuple:
    if isinstance(s, A.STMT_TYPES):
        return A.own_exprs(s)
    return ()


def _root(t):
    while isinstance(t, (A.Index, A.Field)):
        t = t.base
    return t


def _written(s) -> Optional[str]:
    """The variable statement ``s`` writes (an assignment's target, the set
    of an ``add`` or ``remove``, down to its root), or None."""
    t = None
    if isinstance(s, A.Assign):
        t = s.target
    elif isinstance(s, A.CallStmt) and s.name in ("add", "remove") and s.args:
        t = s.args[0]
    t = _root(t)
    return t.name if isinstance(t, A.Name) else None


def _union(pairs, r: int = 0, w: int = 0) -> tuple:
    """The union of (reads, writes) masks ``pairs``, and of ``r`` and ``w``."""
    for pr, pw in pairs:
        r |= pr
        w |= pw
    return r, w


class Independence:
    """Footprints of the steps and of the rest of every k cell of model
    ``m`` (see the module docstring).  Plain data: picklable."""

    def __init__(self, m):
        comp = m.compiled
        self.lay = lay = comp.layout
        self.stmts = comp.stmts
        self.ctl = m.ctl
        self.visible = property_names(m)
        self.bit: dict = {}
        b = 2
        for vs in lay.shared + lay.allread:
            self.bit[vs.name] = b
            b <<= 1
        # statements inside an atomic body, and the lock-protected variables
        inside: set = set()
        for s in self.stmts.values():
            if isinstance(s, A.Atomic):
                for x in A.walk_stmts(list(s.body)):
                    inside.add(x.sid)
        self.inside_atomic = inside
        outside = 0
        for sid, s in self.stmts.items():
            if sid not in inside:
                r, w = self._own_rw(s)
                outside |= r | w
        for ev in m.program.events:
            outside |= self._expr_reads(ev.guard)
        for d in m.program.decls:
            if isinstance(d, A.VarDecl) and d.init is not None:
                outside |= self._expr_reads(d.init)
        self.protected = self._protected(outside)
        # per statement id: the reads/writes of its whole subtree, and
        # whether an atomic is in it
        self.tree: dict = {}
        for sid, s in self.stmts.items():
            sub = list(A.walk_stmts([s]))
            r, w = _union(self._own_rw(x) for x in sub)
            atomic = any(isinstance(x, A.Atomic) for x in sub)
            self.tree[sid] = (r, w | (LQ_BIT if atomic else 0))
        gr = 0
        for ev in m.program.events:
            gr |= self._expr_reads(ev.guard)
        self.guard_reads = gr
        er, ew = gr, 0
        #: per event: (reads, writes) of its guard and body
        self.event_fps: list = []
        for ev in m.program.events:
            r0, w0 = _union((self.tree[s.sid] for s in ev.body), gr)
            self.event_fps.append((r0, w0))
            er |= r0
            ew |= w0
        self.events = (er, ew)
        #: the guards read only the agent's own ``loc:`` variables, members
        #: and pure calls, without rand: the events an agent at the top of
        #: its block will select next are the ones enabled now (its locals
        #: change only by its own steps)
        self.guards_local = local_guards(m) and not comp.guards_rand
        # under fair arrival a liveness property sees whether a robot is
        # under way (pccl/search/liveness.py's pending bits), which a doReach
        # changes: then it is visible too (issue 46, docs/reductions.md)
        fair = bool(getattr(m, "arrival_is_fair", False)) and any(
            p.liveness for p in getattr(m, "temporal", ()))
        self.doreach_visible = fair or bool(self.visible & {"doReach_done", "doReach_fail"})
        self._rest: dict = {}
        self._step: dict = {}
        self._spent: dict = {}
        self.functions = set(comp.functions)
        #: pcs of statements that write a shared or allread variable or a
        #: reach cell (filled by :meth:`step`)
        self.writers: set = set()

    # -- expressions and statements ----------------------------------------------------
    def _protected(self, outside: int) -> int:
        """The lock-protected variables: those not in ``outside`` (the
        accesses outside atomic bodies, guards and initialisers)."""
        return self._all_bits() & ~outside

    def _all_bits(self) -> int:
        out = 0
        for v in self.bit.values():
            out |= v
        return out

    def _expr_reads(self, e) -> int:
        out = 0
        for x in A.walk_expr(e):
            if isinstance(x, A.Name):
                out |= self.bit.get(x.name, 0)
        return out

    def _own_rw(self, s) -> tuple:
        """(reads, writes) of the statement's own expressions (not its
        nested blocks)."""
        r = 0
        for e in _own_exprs(s):
            r |= self._expr_reads(e)
        name = _written(s)
        return r, (0 if name is None else self.bit.get(name, 0))

    def _writes_visible(self, s) -> bool:
        return _written(s) in self.visible

    # -- k cells -------------------------------------------------------------------------
    def rest(self, pc) -> tuple:
        """(reads, writes, ends): the footprint of what is left in k(pc)
        (the lock bit among the writes when an atomic is), and whether
        k(pc) holds the event's endEventBlock (else it is the top of the
        block or Init)."""
        got = self._rest.get(pc)
        if got is None:
            items = list(self.ctl.iter_k(pc))
            r, w = _union(self.tree[acquire_sid(i) if is_acquire(i) else i]
                          for i in items if i != END and i != AEND)
            got = self._rest[pc] = (r, w, END in items)
        return got

    def in_loop(self, pc) -> bool:
        """Whether k(pc) lies in a while loop (its continuation holds the loop)."""
        for item in self.ctl.iter_k(pc):
            if item >= 0 and isinstance(self.stmts[item], A.While):
                return True
        return False

    def step(self, pc) -> tuple:
        """(class, reads, writes) of the step an agent at ``pc`` takes (the
        lock-protected variables left out of a step inside an atomic body)."""
        got = self._step.get(pc)
        if got is None:
            got = self._step[pc] = self._classify(pc)
        return got

    def _classify(self, pc) -> tuple:
        info = self.ctl.info(pc)
        k = info.kind
        if k == K_END:
            return (LOCAL, 0, 0)
        if k == K_EMPTY:
            return (ACCESS, self.guard_reads, 0)
        if self.in_loop(pc):
            return (NEVER, 0, 0)
        if k == K_AEND:
            return (RELEASE, 0, 0)
        if k == K_ACQ:
            return (EXECUTE, 0, 0)
        if k == K_ATOMIC:
            return (REQUEST_LOCK, 0, LQ_BIT)
        if k in (K_SIMPLE, K_IF, K_WHILE, K_ASSERT, K_DOREACH):
            # (a while is always in_loop: the rule above keeps it out)
            s = self.stmts[info.sid]
            if self._writes_visible(s):
                return (NEVER, 0, 0)
            if k == K_DOREACH and self.doreach_visible:
                return (NEVER, 0, 0)
            r, w = self._own_rw(s)
            if k == K_DOREACH or w:
                self.writers.add(pc)      # changes the stall signature
            if info.sid in self.inside_atomic:
                r &= ~self.protected
                w &= ~self.protected
            return (ACCESS, r, w)
        return (NEVER, 0, 0)          # exit, while

    def spent_local(self, pc) -> bool:
        """Whether the step of a *spent* agent (counter + ρ > n0: TIME
        ADVANCE may come before it) at ``pc`` is independent of everything
        that can happen before it: a plain statement (assignment, if,
        assert, outside every while, not a doReach) that reads and writes
        no shared or allread variable (lock-protected ones left out inside
        an atomic body: i holds the lock until its release), no doReach
        flag, no position, and writes nothing a property reads.  TIME
        ADVANCE and DOREACH INVOKE read and write none of that (they change
        time, counters, positions, reach flags and env), and no other
        agent can touch i's own variables, in this time step or the next
        (docs/reductions.md, "Spent agents")."""
        got = self._spent.get(pc)
        if got is None:
            got = self._spent[pc] = self._spent_local(pc)
        return got

    def _spent_local(self, pc) -> bool:
        info = self.ctl.info(pc)
        if info.kind not in (K_SIMPLE, K_IF, K_ASSERT):
            return False
        cls, r, w = self.step(pc)
        if cls != ACCESS or r or w:
            return False
        for e in _own_exprs(self.stmts[info.sid]):
            for x in A.walk_expr(e):
                if isinstance(x, A.Name) and x.name in ("doReach_done", "doReach_fail"):
                    return False
                if isinstance(x, A.Call) and x.name not in PURE_CALLS and \
                        not (x.name in self.functions and not x.args):
                    return False
                if isinstance(x, A.Quant):
                    return False
        return True

    def footprint(self, ag, rho: int, n0: int) -> tuple:
        """(reads, writes) of everything a running agent with cell ``ag``
        may still do before the next TIME ADVANCE."""
        r, w, ends = self.rest(ag[PC])
        c = ag[CNT]
        if c + (2 * rho if ends else rho) <= n0:
            er, ew = self.events
            r |= er
            w |= ew
        return r, w

    def next_events(self, enabled: list) -> tuple:
        """(reads, writes) of the events ``enabled`` (and the guards)."""
        r, w = self.guard_reads, 0
        fps = self.event_fps
        for e in enabled:
            er, ew = fps[e]
            r |= er
            w |= ew
        return r, w


def may_wait(ind: Independence, ag, rho: int, n0: int) -> bool:
    """Whether a running agent may still perform ATOMIC WAIT in this time
    step (it waits now, or can reach an atomic, and its counter allows)."""
    if ag[CNT] + rho > n0:
        return False
    if ag[LCK] == REQUEST:
        return True
    return bool(ind.footprint(ag, rho, n0)[1] & LQ_BIT)


def holds_lock(ag) -> bool:
    return ag[LCK] == LOCK


__all__ = ["PURE_CALLS", "property_names", "local_guards",
           "Independence", "LQ_BIT", "NEVER", "LOCAL", "ACCESS", "REQUEST_LOCK", "RELEASE",
           "EXECUTE", "may_wait", "holds_lock", "Optional"]
