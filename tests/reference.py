"""An independent reference implementation of the PCCL rewrite rules.

This module is a *test oracle*.  It is written from the product contract
(docs/language.md §10-§12: the configuration, the rules, and "state identity,
precisely") and deliberately shares nothing with the engine
(``pccl.model.engine``, ``pccl.model.compile``, ``pccl.lang.values``, ``semantics.*``): only
the AST produced by the shared parser is used.  It is a plain tree-walking
interpreter over immutable tuples, written for clarity, not speed.

Configuration (docs/language.md §11), as stored here:

* per agent (:class:`Agent`):
  ``k``         the pending computation: a tuple whose items are statement
                occurrences (their ``sid``, an ``int``) and the markers
                ``END`` (endEventBlock), ``AEND`` (atomicEnd) and
                ``("acquire", sid)`` (acquire the lock for atomic ``sid``);
  ``counter``   event-block executions in this time step;
  ``lock``      ``"idle" | "request" | "lock"``;
  ``status``    ``("running",)``, ``("exited",)`` or
                ``("stuck", location, reason)``;
  ``vars``      local and allread (own component) values, a sorted tuple of
                ``(name, value)`` pairs;
  ``pos``       position ``(x, y, z)`` rounded to the resolution;
  ``target``, ``obstacles``, ``t0``, ``done``, ``fail``: the reach cell
                (``target`` is ``None`` before the first doReach);
* global (:class:`State`): ``shared`` (one value per shared variable,
  sequential consistency), ``time``, ``queue`` (lockQueue), ``phase``
  (``"discrete" | "dynamic"``).

Each rule application is one transition; ``successors`` returns a list of
``(label, state)`` with one entry per rule application (a statement whose
expressions call ``rand(n)`` yields one entry per outcome; the blackbox yields
one entry per outcome).

Nondeterminism inside one atomic evaluation (``rand``) is handled by
re-running the evaluation under every sequence of choices
(:func:`all_outcomes`), so the interpreter itself stays a plain recursive
function.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass, replace
from typing import Any, Optional
from collections.abc import Callable

from pccl.lang import ast as A

END = "endEventBlock"
AEND = "atomicEnd"
RUNNING = ("running",)
EXITED = ("exited",)


class _Undef:
    """The value of a declared variable without an initialiser."""
    _inst = None

    def __new__(cls):
        if cls._inst is None:
            cls._inst = super().__new__(cls)
        return cls._inst

    def __repr__(self):
        return "UNDEF"

    def __hash__(self):
        return 12345

    def __eq__(self, other):
        return isinstance(other, _Undef)


UNDEF = _Undef()


class Stuck(Exception):
    """A runtime error: the agent becomes stuck(reason, location)."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


class _Exit(Exception):
    """exit() while running the Init block to completion."""


# --------------------------------------------------------------------------
# Choices (rand)
# --------------------------------------------------------------------------

class Chooser:
    """Replays a prefix of choices and records every choice made."""

    def __init__(self, prefix):
        self.values = list(prefix)
        self.bounds: list = []
        self.pos = 0

    def choose(self, n: int) -> int:
        """A value in 0..n inclusive."""
        if self.pos < len(self.values):
            v = self.values[self.pos]
        else:
            v = 0
            self.values.append(0)
        self.bounds.append(n)
        self.pos += 1
        return v


def all_outcomes(fn: Callable[[Chooser], Any]) -> list:
    """Run ``fn`` once per sequence of rand outcomes; the list of results."""
    results = []
    prefix: list = []
    while True:
        ch = Chooser(prefix)
        results.append(fn(ch))
        vals = ch.values[:ch.pos]
        bounds = ch.bounds
        i = len(vals) - 1
        while i >= 0 and vals[i] >= bounds[i]:
            i -= 1
        if i < 0:
            return results
        prefix = vals[:i] + [vals[i] + 1]


# --------------------------------------------------------------------------
# Immutable configuration
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class Agent:
    k: tuple
    counter: int
    lock: str
    status: tuple
    vars: tuple
    pos: tuple
    target: Any
    obstacles: Any
    t0: Any
    done: bool
    fail: bool

    def var(self, name):
        return dict(self.vars)[name]


@dataclass(frozen=True)
class State:
    agents: tuple
    shared: tuple
    time: Any
    queue: tuple
    phase: str

    def shared_value(self, name):
        return dict(self.shared)[name]


def _freeze(v):
    if isinstance(v, list):
        return tuple(_freeze(x) for x in v)
    return v


class Work:
    """A mutable working copy of a State, for one rule application."""

    def __init__(self, st: State):
        self.shared = dict(st.shared)
        self.agents = []
        for a in st.agents:
            d = dict(k=a.k, counter=a.counter, lock=a.lock, status=a.status,
                     vars=dict(a.vars), pos=a.pos, target=a.target,
                     obstacles=a.obstacles, t0=a.t0, done=a.done, fail=a.fail)
            self.agents.append(d)
        self.time = st.time
        self.queue = list(st.queue)
        self.phase = st.phase

    def freeze(self) -> State:
        agents = tuple(
            Agent(k=tuple(d["k"]), counter=d["counter"], lock=d["lock"],
                  status=d["status"],
                  vars=tuple(sorted((n, _freeze(v)) for n, v in d["vars"].items())),
                  pos=d["pos"], target=d["target"], obstacles=d["obstacles"],
                  t0=d["t0"], done=d["done"], fail=d["fail"])
            for d in self.agents)
        return State(agents=agents,
                     shared=tuple(sorted((n, _freeze(v)) for n, v in self.shared.items())),
                     time=self.time, queue=tuple(self.queue), phase=self.phase)


# --------------------------------------------------------------------------
# The model
# --------------------------------------------------------------------------

class ReferenceModel:
    def __init__(self, program: A.Program, n_agents: int, *, n0: int = 1, delta=1,
                 rates: Optional[dict] = None, events: str = "any",
                 max_time=None, blackbox: str = "instant",
                 abstract_time: bool = True, functions: Optional[dict] = None,
                 starts=None, resolution: float = 0.01, radius: float = 0.25,
                 speed: float = 1.0):
        assert events in ("any", "first")
        assert blackbox in ("instant", "nondet")
        self.program = program
        self.N = n_agents
        self.n0 = n0
        self.delta = delta
        self.rho = [1] * n_agents
        for a, r in (rates or {}).items():
            self.rho[a] = r
        self.events = events
        self.max_time = max_time
        self.blackbox = blackbox
        self.abstract_time = abstract_time
        self.resolution = resolution
        self.radius = radius
        self.speed = speed
        self.functions = {"getInput": (), "getObs": ()}
        self.functions.update(functions or {})
        if starts is None:
            starts = [(0.75 * i, 0.0, 0.0) for i in range(n_agents)]
        self.starts = [self.mkpos(p) for p in starts[:n_agents]]
        # declarations
        self.shared_decls = [d for d in program.decls
                             if isinstance(d, A.VarDecl) and d.section == "allwrite"]
        self.allread_decls = [d for d in program.decls
                              if isinstance(d, A.VarDecl) and d.section == "allread"]
        self.local_decls = [d for d in program.decls
                            if isinstance(d, A.VarDecl) and d.section == "loc"]
        self.shared_names = {d.name for d in self.shared_decls}
        self.allread_names = {d.name for d in self.allread_decls}
        self.decl_types = {d.name: d.type for d in program.decls if isinstance(d, A.VarDecl)}
        self.enum_members = {}
        for d in program.decls:
            if isinstance(d, A.EnumDecl):
                for m in d.members:
                    self.enum_members[m] = ("enum", d.name, m)
        # statements by sid
        self.stmts = {}
        for block in [program.init] + [ev.body for ev in program.events]:
            for s in A.walk_stmts(block):
                self.stmts[s.sid] = s

    # ------------------------------------------------------------------
    # values
    # ------------------------------------------------------------------
    def mkpos(self, p) -> tuple:
        p = tuple(p)
        if len(p) == 2:
            p = p + (0.0,)
        if len(p) != 3 or not all(isinstance(c, (int, float)) and not isinstance(c, bool)
                                  for c in p):
            raise Stuck("not a position")
        res = self.resolution
        return tuple(round(round(float(c) / res) * res, 9) + 0.0 for c in p)

    def convert(self, v, typ: Optional[A.TypeRef]):
        """Bring a value from outside (a world function) to the declared type."""
        if typ is None or v is UNDEF:
            return v
        if typ.name == "ItemPosition":
            return self.mkpos(v)
        if typ.name == "List" and typ.elem is not None and isinstance(v, (tuple, list)):
            return tuple(self.convert(x, typ.elem) for x in v)
        if typ.name == "float" and isinstance(v, int) and not isinstance(v, bool):
            return float(v)
        if isinstance(v, list):
            return _freeze(v)
        return v

    # ------------------------------------------------------------------
    # expressions
    # ------------------------------------------------------------------
    def eval(self, e, w: Work, i: int, ch: Chooser):
        a = w.agents[i]
        if isinstance(e, A.IntLit):
            return e.value
        if isinstance(e, A.FloatLit):
            return e.value
        if isinstance(e, A.BoolLit):
            return e.value
        if isinstance(e, A.ListLit):
            return tuple(self.eval(x, w, i, ch) for x in e.items)
        if isinstance(e, A.Name):
            n = e.name
            if n in a["vars"]:
                v = a["vars"][n]
            elif n in w.shared:
                v = w.shared[n]
            elif n == "doReach_done":
                v = a["done"]
            elif n == "doReach_fail":
                v = a["fail"]
            elif n in self.enum_members:
                v = self.enum_members[n]
            else:
                raise AssertionError(f"unknown name {n}")
            if v is UNDEF:
                raise Stuck(f"read of undefined {n}")
            return v
        if isinstance(e, A.Index):
            if isinstance(e.base, A.Name) and e.base.name in self.allread_names:
                j = self.eval(e.index, w, i, ch)
                if not (0 <= j < self.N):
                    raise Stuck("index out of range")
                v = w.agents[j]["vars"][e.base.name]
                if v is UNDEF:
                    raise Stuck("read of undefined")
                return v
            base = self.eval(e.base, w, i, ch)
            j = self.eval(e.index, w, i, ch)
            if not (0 <= j < len(base)):
                raise Stuck("index out of range")
            v = base[j]
            if v is UNDEF:
                raise Stuck("read of undefined")
            return v
        if isinstance(e, A.Field):
            p = self.eval(e.base, w, i, ch)
            return p["xyz".index(e.name)]
        if isinstance(e, A.Unary):
            v = self.eval(e.operand, w, i, ch)
            if e.op == "!":
                return not v
            return -v
        if isinstance(e, A.Binary):
            return self.binary(e, w, i, ch)
        if isinstance(e, A.Call):
            return self.call(e, w, i, ch)
        raise AssertionError(f"unexpected expression {e!r}")

    def binary(self, e: A.Binary, w, i, ch):
        op = e.op
        if op == "&&":
            return bool(self.eval(e.left, w, i, ch)) and bool(self.eval(e.right, w, i, ch))
        if op == "||":
            return bool(self.eval(e.left, w, i, ch)) or bool(self.eval(e.right, w, i, ch))
        l = self.eval(e.left, w, i, ch)
        r = self.eval(e.right, w, i, ch)
        if op == "==":
            return l == r
        if op == "!=":
            return l != r
        if op == "<":
            return l < r
        if op == "<=":
            return l <= r
        if op == ">":
            return l > r
        if op == ">=":
            return l >= r
        if op == "+":
            return l + r
        if op == "-":
            return l - r
        if op == "*":
            return l * r
        if op in ("/", "%"):
            if r == 0:
                raise Stuck("division by zero")
            if isinstance(l, int) and isinstance(r, int):
                q = abs(l) // abs(r)
                if (l < 0) != (r < 0):
                    q = -q
                return q if op == "/" else l - r * q
            return l / r if op == "/" else math.fmod(l, r)
        raise AssertionError(f"operator {op}")

    def call(self, e: A.Call, w, i, ch):
        n = e.name
        args = [self.eval(x, w, i, ch) for x in e.args]
        if n == "getAgentIndex":
            return i
        if n == "getNumAgents":
            return self.N
        if n == "rand":
            (m,) = args
            if m < 0:
                raise Stuck("rand of a negative bound")
            return ch.choose(m)
        if n == "getPosition":
            return w.agents[i]["pos"]
        if n == "ItemPosition":
            return self.mkpos(args)
        if n == "dist":
            p, q = args
            return math.sqrt(sum((x - y) ** 2 for x, y in zip(p, q)))
        if n == "head":
            if len(args[0]) == 0:
                raise Stuck("head of an empty list")
            return args[0][0]
        if n == "isEmpty":
            return len(args[0]) == 0
        if n == "size":
            return len(args[0])
        if n == "contains":
            return args[1] in args[0]
        if not args and n in self.functions:
            return _freeze(self.functions[n])
        raise AssertionError(f"unknown function {n}")

    # ------------------------------------------------------------------
    # writes
    # ------------------------------------------------------------------
    def store(self, target, value, w: Work, i: int, ch):
        """``target = value``: target is a Name or an Index chain."""
        if isinstance(target, A.Name):
            self.set_var(target.name, value, w, i)
            return
        # Index chain: x[a][b] = v
        path = []
        t = target
        while isinstance(t, A.Index):
            path.append(self.eval(t.index, w, i, ch))
            t = t.base
        path.reverse()
        assert isinstance(t, A.Name)
        cur = self.get_var(t.name, w, i)
        self.set_var(t.name, self._set_path(cur, path, value), w, i)

    def _set_path(self, cur, path, value):
        if not path:
            return value
        j = path[0]
        if cur is UNDEF or not (0 <= j < len(cur)):
            raise Stuck("index out of range")
        items = list(cur)
        items[j] = self._set_path(items[j], path[1:], value)
        return tuple(items)

    def get_var(self, name, w: Work, i: int):
        a = w.agents[i]
        if name in a["vars"]:
            return a["vars"][name]
        return w.shared[name]

    def set_var(self, name, value, w: Work, i: int):
        typ = self.decl_types.get(name)
        if typ is not None and typ.name == "float" and isinstance(value, int) \
                and not isinstance(value, bool):
            value = float(value)
        a = w.agents[i]
        if name in a["vars"]:
            a["vars"][name] = value
        elif name in w.shared:
            w.shared[name] = value
        else:
            raise AssertionError(f"assignment to unknown variable {name}")

    # ------------------------------------------------------------------
    # initialisation (not interleaved)
    # ------------------------------------------------------------------
    def init_states(self) -> list:
        return [s for s in all_outcomes(self._init) if s is not None]

    def _init(self, ch: Chooser) -> State:
        w = Work(State(agents=(), shared=(), time=0, queue=(), phase="discrete"))
        for i in range(self.N):
            w.agents.append(dict(k=(), counter=0, lock="idle", status=RUNNING, vars={},
                                 pos=self.starts[i], target=None, obstacles=None,
                                 t0=None, done=False, fail=False))
        for d in self.shared_decls:
            w.shared[d.name] = self.declare(d, w, 0, ch)
        for i in range(self.N):
            a = w.agents[i]
            try:
                for d in self.allread_decls + self.local_decls:
                    a["vars"][d.name] = UNDEF  # declared before initialised
                    a["vars"][d.name] = self.declare(d, w, i, ch)
                self.run_block(self.program.init, w, i, ch)
            except Stuck as err:
                a["status"] = ("stuck", "init", err.reason)
            except _Exit:
                a["status"] = EXITED
        return w.freeze()

    def declare(self, d: A.VarDecl, w: Work, i: int, ch):
        if d.size is not None:
            n = self.eval(d.size, w, i, ch)
            if d.init is not None:
                return self.convert(self.eval(d.init, w, i, ch), d.type)
            return tuple([UNDEF] * n)
        if d.init is None:
            return UNDEF
        return self.convert(self.eval(d.init, w, i, ch), d.type)

    def run_block(self, stmts, w: Work, i: int, ch):
        """Run statements to completion (Init only)."""
        for s in stmts:
            if isinstance(s, A.Assign):
                self.store(s.target, self.eval(s.value, w, i, ch), w, i, ch)
            elif isinstance(s, A.If):
                self.run_block(self.choose_branch(s, w, i, ch), w, i, ch)
            elif isinstance(s, A.While):
                steps = 0
                while self.eval(s.cond, w, i, ch):
                    self.run_block(s.body, w, i, ch)
                    steps += 1
                    assert steps < 100000, "Init loop does not terminate"
            elif isinstance(s, A.Atomic):
                self.run_block(s.body, w, i, ch)
            elif isinstance(s, A.Skip):
                pass
            elif isinstance(s, A.CallStmt):
                if s.name == "exit":
                    raise _Exit()
                if s.name == "doReach":
                    self.do_reach(s, w, i, ch)
                else:
                    self.simple_call(s, w, i, ch)
            else:
                raise AssertionError(s)

    def choose_branch(self, s: A.If, w, i, ch):
        for cond, body in s.branches:
            if self.eval(cond, w, i, ch):
                return body
        return s.orelse

    def do_reach(self, s: A.CallStmt, w, i, ch):
        target = self.mkpos(self.eval(s.args[0], w, i, ch))
        obstacles = self.eval(s.args[1], w, i, ch) if len(s.args) > 1 else ()
        a = w.agents[i]
        a["done"] = False
        a["fail"] = False
        a["target"] = target
        a["obstacles"] = obstacles
        a["t0"] = w.time

    def simple_call(self, s: A.CallStmt, w, i, ch):
        """assert, add, remove."""
        if s.name == "assert":
            if not self.eval(s.args[0], w, i, ch):
                raise Stuck("assertion failed")
            return
        if s.name in ("add", "remove"):
            xs_expr, v_expr = s.args
            xs = self.eval(xs_expr, w, i, ch)
            v = self.eval(v_expr, w, i, ch)
            if s.name == "add":
                new = tuple(xs) + (v,)
            else:
                if v not in xs:
                    raise Stuck("remove of an absent element")
                items = list(xs)
                items.remove(v)
                new = tuple(items)
            self.store(xs_expr, new, w, i, ch)
            return
        raise AssertionError(f"unknown statement {s.name}")

    # ------------------------------------------------------------------
    # transitions
    # ------------------------------------------------------------------
    def successors(self, st: State) -> list:
        out = []
        if st.phase == "discrete":
            for i, a in enumerate(st.agents):
                if a.status == RUNNING:
                    out.extend(self.agent_successors(st, i))
            if self.time_advance_enabled(st):
                w = Work(st)
                w.time = st.time + self.delta
                w.phase = "dynamic"
                out.append(("TIME ADVANCE", w.freeze()))
        else:
            out.extend(self.doreach_invoke(st))
        return out

    def time_advance_enabled(self, st: State) -> bool:
        if not any(a.status == RUNNING for a in st.agents):
            return False
        for i, a in enumerate(st.agents):
            if a.status != EXITED and a.counter + self.rho[i] <= self.n0:
                return False
        if self.max_time is not None and st.time + self.delta > self.max_time:
            return False
        return True

    def has_budget(self, st: State, i: int) -> bool:
        return st.agents[i].counter + self.rho[i] <= self.n0

    def agent_successors(self, st: State, i: int) -> list:
        a = st.agents[i]
        k = a.k
        if not k:
            if not self.has_budget(st, i):
                return []
            return self.event_select(st, i)
        head, rest = k[0], k[1:]
        if head == END:
            if not self.has_budget(st, i):
                return []
            w = Work(st)
            w.agents[i]["k"] = ()
            w.agents[i]["counter"] += self.rho[i]
            return [("COUNTER ADVANCE", w.freeze())]
        if head == AEND:
            if a.lock != "lock":
                return []
            w = Work(st)
            w.agents[i]["lock"] = "idle"
            w.queue.remove(i)
            w.agents[i]["k"] = rest
            return [("LOCK RELEASE", w.freeze())]
        if isinstance(head, tuple) and head[0] == "acquire":
            if a.lock != "request":
                return []
            w = Work(st)
            if st.queue and st.queue[0] == i:
                body = tuple(s.sid for s in self.stmts[head[1]].body)
                w.agents[i]["lock"] = "lock"
                w.agents[i]["k"] = body + rest
                return [("ATOMIC EXECUTION", w.freeze())]
            if not self.has_budget(st, i):
                return []
            w.agents[i]["counter"] += self.rho[i]
            return [("ATOMIC WAIT", w.freeze())]
        s = self.stmts[head]
        if isinstance(s, A.Atomic):
            w = Work(st)
            if a.lock == "idle":
                w.agents[i]["lock"] = "request"
                w.queue.append(i)
                w.agents[i]["k"] = (("acquire", s.sid), AEND) + rest
                return [("LOCK REQUEST", w.freeze())]
            if a.lock == "lock":  # nested atomic: just run the body
                w.agents[i]["k"] = tuple(x.sid for x in s.body) + rest
                return [("NESTED ATOMIC", w.freeze())]
            return []
        if isinstance(s, A.CallStmt) and s.name == "exit":
            w = Work(st)
            w.agents[i]["status"] = EXITED
            w.agents[i]["k"] = ()
            return [("EXIT", w.freeze())]
        label = "DOREACH UPDATE" if isinstance(s, A.CallStmt) and s.name == "doReach" \
            else "STATEMENT"

        def step(ch: Chooser):
            w = Work(st)
            try:
                w.agents[i]["k"] = self.exec_statement(s, rest, w, i, ch)
            except Stuck as err:
                w = Work(st)
                w.agents[i]["status"] = ("stuck", s.sid, err.reason)
            return (label, w.freeze())

        return all_outcomes(step)

    def exec_statement(self, s, rest: tuple, w: Work, i: int, ch) -> tuple:
        """Execute statement ``s`` (one transition); return the new k."""
        if isinstance(s, A.Assign):
            self.store(s.target, self.eval(s.value, w, i, ch), w, i, ch)
            return rest
        if isinstance(s, A.If):
            body = self.choose_branch(s, w, i, ch)
            return tuple(x.sid for x in body) + rest
        if isinstance(s, A.While):
            if self.eval(s.cond, w, i, ch):
                return tuple(x.sid for x in s.body) + (s.sid,) + rest
            return rest
        if isinstance(s, A.Skip):
            return rest
        if isinstance(s, A.CallStmt):
            if s.name == "doReach":
                self.do_reach(s, w, i, ch)
            else:
                self.simple_call(s, w, i, ch)
            return rest
        raise AssertionError(s)

    def event_select(self, st: State, i: int) -> list:
        def select(ch: Chooser):
            w = Work(st)
            enabled = []
            try:
                for ev in self.program.events:
                    if self.eval(ev.guard, w, i, ch):
                        enabled.append(ev)
                        if self.events == "first":
                            break
            except Stuck as err:
                w.agents[i]["status"] = ("stuck", f"pre {ev.name}", err.reason)
                return [("STUCK", w.freeze())]
            if not enabled:
                w.agents[i]["k"] = (END,)
                return [("IDLE", w.freeze())]
            out = []
            for ev in enabled:
                w2 = Work(st)
                w2.agents[i]["k"] = tuple(x.sid for x in ev.body) + (END,)
                out.append((f"EVENT {ev.name}", w2.freeze()))
            return out

        return [t for r in all_outcomes(select) for t in r]

    # ------------------------------------------------------------------
    # the environment
    # ------------------------------------------------------------------
    def doreach_invoke(self, st: State) -> list:
        """DOREACH INVOKE with the oracle's own blackboxes (no obstacles).

        instant: an agent with a target is at it after the step, done.
        nondet:  each *moving* agent either arrives (done) or stays (flags
                 false); every combination is one outcome.  The language reference does not
                 define "moving"; here an agent is moving when it has a
                 target, is not done, and is not already at the target
                 (x, y compared after rounding to the resolution; an agent at
                 its target is done).  Agents without a target stay, flags
                 false.  Exited and stuck agents are treated like the others.
                 A moving agent may also fail (stays, fail true) when another
                 robot's body could block it (docs/blackboxes.md): its path
                 comes within 2 radii of the other's path (if that one moves)
                 or position; or when steps are slow (speed * delta < 10
                 resolutions).  A failed agent stays failed.
        """
        moving = [a.target is not None and not a.done and not a.fail
                  and a.pos[:2] != a.target[:2] for a in st.agents]
        per_agent = []
        for i, a in enumerate(st.agents):
            if a.target is None:
                per_agent.append([(a.pos, False, False)])          # held in place
            elif self.blackbox == "instant":
                per_agent.append([(a.target, True, False)])         # arrives
            else:  # nondet
                if a.fail:
                    per_agent.append([(a.pos, False, True)])
                elif a.done or a.pos[:2] == a.target[:2]:
                    # arrived earlier, or asked to go where it already is:
                    # not a moving agent; it is at its target, done
                    per_agent.append([(a.pos, True, False)])
                else:
                    opts = [(a.target, True, False),                # arrives
                            (a.pos, False, False)]                  # stays
                    if self._may_be_blocked(st, moving, i):
                        opts.append((a.pos, False, True))           # fails
                    per_agent.append(opts)
        out = []
        for combo in itertools.product(*per_agent):
            w = Work(st)
            for d, (pos, done, fail) in zip(w.agents, combo):
                d["pos"] = pos
                d["done"] = done
                d["fail"] = fail
                d["counter"] = 0
            w.phase = "discrete"
            out.append(("DOREACH INVOKE", w.freeze()))
        return out

    def _may_be_blocked(self, st: State, moving: list, i: int) -> bool:
        """Whether another robot could block moving agent i (shapely
        distances; no obstacles in the oracle's worlds)."""
        import shapely
        if self.speed * self.delta < 10 * self.resolution:
            return True

        def region(k):
            a = st.agents[k]
            pts = [a.pos[:2], a.target[:2]] if moving[k] else [a.pos[:2]]
            if len(pts) == 2 and pts[0] != pts[1]:
                return shapely.LineString(pts)
            return shapely.Point(pts[0])
        mine = region(i)
        return any(mine.distance(region(k)) < 2 * self.radius
                   for k in range(len(st.agents)) if k != i)

    # ------------------------------------------------------------------
    # identity and properties
    # ------------------------------------------------------------------
    def key(self, st: State):
        if not self.abstract_time:
            return st
        return replace(st, time=None,
                       agents=tuple(replace(a, t0=None) for a in st.agents))

    def count(self, st: State, name: str) -> int:
        return sum(1 for a in st.agents if a.var(name) is True)

    @staticmethod
    def any_stuck(st: State) -> bool:
        return any(a.status[0] == "stuck" for a in st.agents)


# --------------------------------------------------------------------------
# Search
# --------------------------------------------------------------------------

def bfs(model: ReferenceModel, *, max_depth: Optional[int] = None):
    """(states, transitions, depth) reached by breadth-first search.

    States at depth ``max_depth`` are counted but not expanded.  The number
    of transitions is the sum, over expanded states, of their successor
    counts (successors leading to already-seen states included)."""
    seen = set()
    level = []
    for s in model.init_states():
        k = model.key(s)
        if k not in seen:
            seen.add(k)
            level.append(s)
    transitions = 0
    depth = 0
    while level:
        if max_depth is not None and depth >= max_depth:
            break
        nxt = []
        for s in level:
            succ = model.successors(s)
            transitions += len(succ)
            for _, s2 in succ:
                k = model.key(s2)
                if k not in seen:
                    seen.add(k)
                    nxt.append(s2)
        if not nxt:
            break
        level = nxt
        depth += 1
    return len(seen), transitions, depth


def shortest_violation(model: ReferenceModel, predicate, *, max_depth: Optional[int] = None,
                       use_key: bool = False) -> Optional[int]:
    """Length (in transitions) of a shortest path from an initial state to a
    state satisfying ``predicate``, or None.  Plain BFS over full states
    (time included) unless ``use_key``; ``max_depth`` bounds the search."""
    ident = model.key if use_key else (lambda s: s)
    dist = {}
    queue = deque()
    for s in model.init_states():
        if ident(s) in dist:
            continue
        dist[ident(s)] = 0
        if predicate(s):
            return 0
        queue.append(s)
    while queue:
        s = queue.popleft()
        d = dist[ident(s)]
        if max_depth is not None and d >= max_depth:
            continue
        for _, s2 in model.successors(s):
            k = ident(s2)
            if k in dist:
                continue
            dist[k] = d + 1
            if predicate(s2):
                return d + 1
            queue.append(s2)
    return None
