"""Dead variables (``dead``): values no future step can read leave the key.

SPIN resets a variable that is *dead* (no path reads it before writing it
again) so that states differing only there are one state; this is the same
for PCCL's agents.  A ``loc:`` variable is private to its agent, so whether
it is dead depends only on the agent's own k cell (docs/reductions.md,
"Dead variables"):

* **inside an event** (or Init), at pc: the variables read before written
  by the statements left in k(pc) (a backwards pass over them: an
  assignment to the whole variable, or ``doReach`` for its flags, kills,
  ``exit()`` kills everything), then by whatever the agent does at the top
  of its block after ``endEventBlock`` (below, over every event);
* **at the top of its block**: the variables the guards read, and those
  live at the entry of the events it can select next.  When every guard
  reads only the agent's own ``loc:`` variables (:func:`local_guards`, no
  ``rand``), those are the events whose guard holds now: nothing else can
  change their guards before the agent's own next step.  Otherwise every
  event;
* **exited**: every variable.

The doReach flags and the target (the *reach* of an agent) are one more
variable: read by ``doReach_done``/``doReach_fail``, written by a doReach
call.  They are dead only while the agent has arrived or failed, and only
under a blackbox that declares it keeps such an agent where it is whatever
its reach says (:func:`blackbox_settled_hold_still`, the capability
``settled_robots_hold_still`` of :class:`pccl.blackboxes.base.Capabilities`;
:func:`reach_can_be_masked`); its position and its doReach obstacles stay
in the key (other robots' outcomes read them).  Variables a property or
invariant reads are never dead, nor is anything of a stuck agent.

The initial-state search takes fewer outcomes of a ``rand`` initialiser
whose value nobody reads (:func:`initial_rand_unread`): one outcome when
no outcome can make the initialiser fail other than every outcome does
(:func:`rand_outcomes_fail_alike`, :func:`can_collapse_initial_rand`),
else every outcome is evaluated and the first one with a value stands for
all those with a value, every failing one is kept.

The soundness conditions are the module-level predicates
(:func:`blackbox_settled_hold_still`, :func:`reach_can_be_masked`,
:func:`initial_rand_unread`, :func:`rand_outcomes_fail_alike`,
:func:`can_collapse_initial_rand`): the reduction calls them,
docs/reductions.md quotes them, a test may call them.
The leg start of a robot that tracks legs (``nondet``: the next doReach
starts from it; its ``retarget`` reads only the start of a robot at rest)
stays in the key with its position and doReach obstacles.

The reduction is a different ``key``: :meth:`DeadVars.key_of` masks dead
values before the key (the symmetric one under ``symmetry``), so states are
still the ones made and shown; only which of them are "the same state"
changes.  Two states with equal masked keys have the same futures up to
the masked values, and no check reads those, so every verdict is kept.
"""

from __future__ import annotations

from typing import Any, Optional

from pccl.blackboxes.base import declared_capabilities
from pccl.lang import ast as A
from pccl.lang.types import Ty
from pccl.model.compile import _may_grow, has_rand, program_moves
from pccl.model.independence import local_guards, property_names
from pccl.model.layout import (AEND, AGS, DONE, END, EXITED, FAIL, LOC, OBSTACLES, PC, REACH, RUNNING, SH, START,
                               STATUS,
                               acquire_sid, is_acquire)

#: The value a dead variable has in a key (the Python engine's; the native
#: engine's keys use their own, DEADV): not a PCCL value.
DEAD = ("<dead>",)

_FLAGS = ("doReach_done", "doReach_fail")

#: At most this many values index the liveness tables (2 ** MAX_COND rows per pc
#: and per event, in the generated C too).
MAX_COND = 4

#: Operators deep the walk evaluates a condition before it calls it unknown.
EVAL_DEPTH = 64

#: Statements the path walk of one table entry may visit before it falls
#: back to every path.
BUDGET = 2000


class DeadVars:
    """The liveness tables of model ``m`` (module docstring).  Bits
    ``1 << slot`` are the ``loc:`` variables, :attr:`reach_bit` the reach."""

    def __init__(self, m):
        comp = m.compiled
        self.m = m
        self.ctl = m.ctl
        lay = comp.layout
        self.nloc = len(lay.local)
        self.bit = {vs.name: 1 << vs.slot for vs in lay.local}
        self.reach_bit = 1 << self.nloc
        self.all = (1 << (self.nloc + 1)) - 1
        visible = property_names(m)
        keep = 0
        for name in visible:
            keep |= self.bit.get(name, 0)
        if not reach_can_be_masked(m):
            keep |= self.reach_bit
        #: never masked: read by a property, or (the reach) where a blackbox may tell
        self.keep = keep
        self.stmts = comp.stmts
        self.events = list(m.program.events)
        gr = 0
        for ev in self.events:
            gr |= self._reads(ev.guard)
        self.guard_reads = gr
        self.local_guards = local_guards(m) and not comp.guards_rand
        # live at the top of the block, whatever the agent selects (a fixpoint)
        top = gr
        while True:
            new = gr
            for ev in self.events:
                new |= self._block(ev.body, top)
            if new == top:
                break
            top = new
        self.top = top
        #: the values the tables are indexed by (:meth:`_cond_vars`)
        self.cond = self._cond_vars(m)
        self.cond_slots = [lay.vars[name].slot for name in self.cond]
        self._pc: dict = {}
        self._ev: dict = {}
        self._top: dict = {}      # (agent, locals) -> live at the top
        self._init_reads: Optional[set] = None   # the names initialisers and Init read

    @property
    def reach_masked(self) -> bool:
        """Whether a robot's reach (in the stall signature) can be masked."""
        return bool(self.all & ~self.keep & self.reach_bit)

    # -- reads and the backwards pass ------------------------------------------------
    def _reads(self, e) -> int:
        out = 0
        for x in A.walk_expr(e):
            if isinstance(x, A.Name):
                out |= self.bit.get(x.name, 0)
                if x.name in _FLAGS:
                    out |= self.reach_bit
        return out

    def _block(self, stmts, live: int) -> int:
        for s in reversed(stmts):
            live = self._stmt(s, live)
        return live

    def _stmt(self, s, live: int) -> int:
        """Live before ``s``, given ``live`` after it (every path)."""
        if isinstance(s, A.Assign):
            t = s.target
            if isinstance(t, A.Name):
                live &= ~self.bit.get(t.name, 0)
                return live | self._reads(s.value)
            return live | self._reads(t) | self._reads(s.value)
        if isinstance(s, A.If):
            out = self._block(s.orelse, live)
            for cond, body in s.branches:
                out |= self._reads(cond) | self._block(body, live)
            return out
        if isinstance(s, A.While):
            cur = live
            while True:
                new = live | self._reads(s.cond) | self._block(s.body, cur)
                if new == cur:
                    return cur
                cur = new
        if isinstance(s, A.Atomic):
            return self._block(s.body, live)
        if isinstance(s, A.CallStmt):
            if s.name == "exit":
                return 0
            reads = 0
            for a in s.args:
                reads |= self._reads(a)
            if s.name == "doReach":
                live &= ~self.reach_bit
            return live | reads
        return live                                  # skip

    # -- the paths a body can take, given some of the agent's values ----------------------
    def _cond_vars(self, m) -> list:
        """The values a state's liveness is worked out under (at most
        :data:`MAX_COND`): ``bool`` ``loc:`` variables that always have a
        value, read by a condition (only the agent's own steps change them;
        not the doReach flags, which DOREACH INVOKE may change before the
        condition is reached)."""
        read: set = set()
        for s in self.stmts.values():
            conds = (s.cond,) if isinstance(s, A.While) else \
                tuple(c for c, _ in s.branches) if isinstance(s, A.If) else ()
            for c in conds:
                read |= {x.name for x in A.walk_expr(c) if isinstance(x, A.Name)}
        out = []
        for vs in m.compiled.layout.local:
            if vs.name in read and vs.ty.kind == "bool" and not vs.may_undef:
                out.append(vs.name)
        return out[:MAX_COND]

    def _eval(self, e, env: dict, depth: int = 0):
        """``e``'s value where ``env`` decides it, else None (also below
        :data:`EVAL_DEPTH` levels of operators)."""
        if depth > EVAL_DEPTH:
            return None
        depth += 1
        if isinstance(e, A.BoolLit):
            return e.value
        if isinstance(e, A.Name):
            return env.get(e.name)
        if isinstance(e, A.Unary) and e.op == "!":
            v = self._eval(e.operand, env, depth)
            return None if v is None else not v
        if isinstance(e, A.Binary) and e.op in ("&&", "||"):
            a, b = self._eval(e.left, env, depth), self._eval(e.right, env, depth)
            if e.op == "&&":
                return False if a is False or b is False else (True if a and b else None)
            return True if a is True or b is True else (False if a is False and b is False else None)
        return None

    def _paths(self, items: list, env: dict, budget: list, depth: int = 0) -> int:
        """Live before the statements ``items`` (then the top of the block)
        over the paths ``env``'s values allow.  Straight-line statements are
        walked in a loop; a branch recurses.  ``budget``: statements the
        walk may still visit; out of it, or :data:`EVAL_DEPTH` branches deep,
        the rest is taken over every path (:meth:`_block`)."""
        done: list = []             # the straight-line statements walked, in order
        live = self.top
        n = 0
        while n < len(items):
            s = items[n]
            budget[0] -= 1
            if budget[0] <= 0 or depth > EVAL_DEPTH:
                live = self._block(items[n:], self.top)
                break
            rest = items[n + 1:]
            if isinstance(s, A.If):
                live = self._branches(s, rest, env, budget, depth + 1)
                break
            if isinstance(s, A.Atomic):
                items, n = list(s.body) + rest, 0
                continue
            if isinstance(s, A.While):
                for x in A.walk_stmts(list(s.body)):
                    if isinstance(x, A.Assign) and isinstance(x.target, A.Name):
                        env.pop(x.target.name, None)
                live = self._stmt(s, self._paths(rest, env, budget, depth + 1))
                break
            if isinstance(s, A.CallStmt) and s.name == "exit":
                live = 0
                break
            if isinstance(s, A.Assign) and isinstance(s.target, A.Name) and s.target.name in self.bit:
                v = self._eval(s.value, env)
                if v is None:
                    env.pop(s.target.name, None)
                else:
                    env[s.target.name] = v
            done.append(s)
            n += 1
        for s in reversed(done):
            live = self._stmt(s, live)
        return live

    def _branches(self, s, rest: list, env: dict, budget: list, depth: int) -> int:
        """:meth:`_paths` of the ``if`` ``s`` then ``rest``: the branches
        ``env`` does not rule out, each with its own copy of ``env``."""
        out = 0
        for cond, body in s.branches:
            out |= self._reads(cond)
            v = self._eval(cond, env)
            if v is not False:
                out |= self._paths(list(body) + rest, dict(env), budget, depth)
            if v is True:
                return out
        return out | self._paths(list(s.orelse) + rest, dict(env), budget, depth)

    def _env(self, idx: int) -> dict:
        return {name: bool(idx >> k & 1) for k, name in enumerate(self.cond)}

    def _items(self, pc: int) -> list:
        out = []
        for it in self.ctl.iter_k(pc):
            if it == END or it == AEND:
                continue
            if is_acquire(it):
                out += list(self.stmts[acquire_sid(it)].body)
            else:
                out.append(self.stmts[it])
        return out

    def live_pc(self, pc: int, idx: int) -> int:
        """Live at ``pc`` below the top of the block (the statements left in
        k(pc), then :attr:`top`) when the values :attr:`cond` are ``idx``'s bits."""
        got = self._pc.get((pc, idx))
        if got is None:
            got = self._pc[pc, idx] = self._paths(self._items(pc), self._env(idx), [BUDGET])
        return got

    def entry(self, e: int, idx: int) -> int:
        """Live at the entry of event ``e``'s body (values as :meth:`live_pc`)."""
        got = self._ev.get((e, idx))
        if got is None:
            got = self._ev[e, idx] = self._paths(list(self.events[e].body), self._env(idx), [BUDGET])
        return got

    def live_top(self, enabled, idx: int) -> int:
        """Live at the top of the block when ``enabled`` (event indexes) are
        the events the agent can select next (local guards: else :attr:`top`)."""
        live = self.guard_reads
        for e in enabled:
            live |= self.entry(e, idx)
        return live

    # -- the key ----------------------------------------------------------------------------
    def dead_mask(self, st, i: int) -> int:
        """The masks of agent ``i``'s dead variables in configuration ``st``."""
        ag = st[AGS][i]
        status = ag[STATUS]
        if status == EXITED:
            live = 0
        elif status != RUNNING:
            return 0
        elif ag[PC] == self.ctl.empty_pc or ag[PC] == self.ctl.idle_pc:
            # (at endEventBlock the locals are the ones the top will see)
            if self.local_guards:
                k = (i, ag[LOC])
                got = self._top.get(k)
                if got is None:
                    if len(self._top) > 200_000:
                        self._top.clear()
                    got = self._top[k] = self.live_top(self.enabled(st, i), self.index(ag[LOC]))
                live = got
            else:
                live = self.top
        else:
            live = self.live_pc(ag[PC], self.index(ag[LOC]))
        dead = self.all & ~(live | self.keep)
        if dead & self.reach_bit:
            r = ag[REACH]
            if not (r[DONE] or r[FAIL]):      # moving, or never moved: kept
                dead &= ~self.reach_bit
        return dead

    def index(self, loc) -> int:
        """The table row of an agent's locals ``loc``: bit k is :attr:`cond`'s k-th value."""
        idx = 0
        for k, slot in enumerate(self.cond_slots):
            if loc[slot] is True:
                idx |= 1 << k
        return idx

    def _unread(self, vs) -> bool:
        """:func:`initial_rand_unread` of the variable ``vs``."""
        got = self._init_reads
        if got is None:
            prog = self.m.program
            got = set()
            exprs = [d.init for d in prog.decls if isinstance(d, A.VarDecl) and d.init is not None]
            exprs += [e for s in A.walk_stmts(list(prog.init)) for e in A.own_exprs(s)]
            for e in exprs:
                got |= {x.name for x in A.walk_expr(e) if isinstance(x, A.Name)}
            self._init_reads = got
        return (vs.section == "loc" and vs.decl.init is not None and has_rand(vs.decl.init)
                and vs.name not in got and not (self.top | self.keep) & (1 << vs.slot))

    def initial_collapse(self) -> tuple:
        """``(one, values)``: the ``loc:`` variables whose ``rand``
        initialiser the initial-state search takes one outcome of
        (:func:`can_collapse_initial_rand`), and those of which it merges
        the outcomes that have a value into the first, keeping every
        outcome that fails (unread, but some outcome may fail where
        another does not)."""
        one: set = set()
        values: set = set()
        for vs in self.m.compiled.layout.local:
            if initial_rand_unread(self.m, vs.name, self):
                (one if can_collapse_initial_rand(self.m, vs.name, self) else values).add(vs.name)
        return frozenset(one), frozenset(values)

    def enabled(self, st, i: int) -> list:
        ags = st[AGS]
        try:
            return list(self.m.compiled.enabled_events(i, ags[i], st[SH], ags))
        except Exception:       # a guard that errs: keep everything (its agent gets stuck)
            return list(range(len(self.events)))

    def mask(self, st):
        """``st`` with every dead value replaced by :data:`DEAD` (a tuple that
        is not a configuration: for keys only)."""
        ags = st[AGS]
        out: Optional[list] = None
        for i in range(len(ags)):
            dead = self.dead_mask(st, i)
            if not dead:
                continue
            ag = ags[i]
            loc = tuple(DEAD if dead >> k & 1 else x for k, x in enumerate(ag[LOC]))
            reach = ag[REACH]
            if dead & self.reach_bit:
                # the leg start stays: the next doReach starts the leg from it
                reach = (DEAD, reach[OBSTACLES], DEAD, DEAD, DEAD, reach[START])
            if out is None:
                out = list(ags)
            out[i] = ag[:LOC] + (loc,) + ag[LOC + 1:REACH] + (reach,) + ag[REACH + 1:]
        if out is None:
            return st
        return st[:AGS] + (tuple(out),) + st[AGS + 1:]

    def key_of(self, key) -> Any:
        """``key`` with dead values masked first."""
        mask = self.mask

        def dead_key(st):
            return key(mask(st))
        return dead_key


# -- the soundness conditions, as predicates (docs/reductions.md quotes them) -------------

def blackbox_settled_hold_still(bb) -> bool:
    """Whether blackbox ``bb`` declares (as its own class's capability,
    :func:`pccl.blackboxes.base.declared_capabilities`) that a robot whose
    doReach is done or failed stays where it is with its flags, and that
    no robot's outcome depends on such a robot's target, ``t0`` or flags
    (only on its position and doReach obstacles).  False for no blackbox,
    one that declares nothing, a subclass that does not declare it again."""
    if bb is None:
        return False
    return declared_capabilities(bb).settled_robots_hold_still


def reach_can_be_masked(m) -> bool:
    """Whether a settled robot's reach (target, ``t0``, flags) may leave the
    key in model ``m``: the program calls doReach, the blackbox holds
    settled robots still (:func:`blackbox_settled_hold_still`) and no
    property reads ``doReach_done``/``doReach_fail``."""
    return (program_moves(m.program) and blackbox_settled_hold_still(getattr(m, "blackbox", None))
            and not property_names(m) & set(_FLAGS))


def initial_rand_unread(m, name: str, dv: Optional[DeadVars] = None) -> bool:
    """Whether ``loc:`` variable ``name`` of model ``m`` has a ``rand``
    initialiser whose value nothing reads: no initialiser, no statement of
    Init, no path from the top of the block and no property.  Every
    initial state then has it masked (after Init an agent is at the top,
    exited, or stuck before reading it), so the initial states that differ
    only in the *values* its outcomes give are one; an outcome that fails
    is a different state (a stuck agent) and is kept.  ``dv``: ``m``'s
    :class:`DeadVars` if already built."""
    dv = dv if dv is not None else _dead_vars(m)
    vs = dv.m.compiled.layout.vars.get(name)
    return vs is not None and dv._unread(vs)


#: Operators on ``rand`` values that no operand value can make fail
#: (comparisons: ints, floats, bools and enums compare totally).
_TOTAL_COMPARE = frozenset({"==", "!=", "<", "<=", ">", ">="})


def rand_outcomes_fail_alike(expr, want: Ty) -> bool:
    """Whether no ``rand`` outcome can make ``expr``, stored as a ``want``
    value, fail where another outcome does not (statically: every outcome
    then fails the same way, or none does, and only the value differs).

    Every sub-expression holding a ``rand`` is ``rand(a)`` with ``a``
    free of ``rand`` (its bound and its error do not depend on an
    outcome), ``-x``, ``!x``, ``x + c``/``c + x``/``x - c``/``c - x`` with
    ``c`` an int literal, or a comparison; nothing short-circuits on an
    outcome (``&&``, ``||``, ``->``), indexes, divides, calls another
    function or builds a value with one.  The stored value is an int or a
    bool and needs no check (an int slot's overflow check applies to a
    product or a sum of two non-literals: excluded; a float conversion
    of a huge int may fail: excluded).  Sound, not complete: what it
    rejects is evaluated outcome by outcome."""
    if want.kind not in ("int", "bool"):
        return False
    if want.kind == "int" and _may_grow(expr):
        return False
    nodes = list(A.walk(expr))
    tainted: set = set()
    for x in reversed(nodes):           # children before parents
        if (isinstance(x, A.Call) and x.name == "rand") or any(id(c) in tainted for c in A.children(x)):
            tainted.add(id(x))
    for x in nodes:
        if id(x) not in tainted:
            continue
        if isinstance(x, A.Call):
            if x.name != "rand" or any(id(a) in tainted for a in x.args):
                return False
        elif isinstance(x, A.Unary):
            if x.op not in ("-", "!"):
                return False
        elif isinstance(x, A.Binary):
            if x.op in _TOTAL_COMPARE:
                continue
            if x.op not in ("+", "-"):
                return False
            if not (isinstance(x.left, A.IntLit) or isinstance(x.right, A.IntLit)):
                return False
        else:
            return False
    return True


def can_collapse_initial_rand(m, name: str, dv: Optional[DeadVars] = None) -> bool:
    """Whether the initial-state search may take one outcome of ``loc:``
    variable ``name``'s ``rand`` initialiser without evaluating the others:
    its value is never read (:func:`initial_rand_unread`) and no outcome
    fails unlike another (:func:`rand_outcomes_fail_alike`)."""
    dv = dv if dv is not None else _dead_vars(m)
    vs = dv.m.compiled.layout.vars.get(name)
    return (vs is not None and initial_rand_unread(m, name, dv)
            and rand_outcomes_fail_alike(vs.decl.init, _want(vs)))


def _want(vs) -> Ty:
    """The type of the value a declaration's initialiser is stored as (an
    array's: one element's)."""
    return vs.ty.elem if vs.ty.kind == "array" and vs.ty.elem is not None else vs.ty


def _dead_vars(m) -> DeadVars:
    """``m``'s own tables when it is reduced with ``dead``, else new ones
    (a reduced model reads through to its model: the same tables)."""
    got = getattr(m, "dead_vars", None)
    if isinstance(got, DeadVars):
        return got
    return DeadVars(m)


def can_be_dead(m) -> bool:
    """Whether some value of ``m`` can ever be masked (a ``loc:`` variable no
    property reads, or a robot's reach): else the reduction has nothing to do."""
    d = DeadVars(m)
    return bool(d.all & ~d.keep)
