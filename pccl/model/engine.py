"""The PCCL engine: configurations and the model interface the explorer uses.

A :class:`Model` offers, stateright-style,

* :meth:`Model.init_states` — one initial configuration per combination of
  ``rand`` outcomes in declarations and ``Init``, generated lazily;
* :meth:`Model.successors` — the enabled transitions of a configuration,
  each ``(label, successor)`` with ``label = (RULE NAME, agent, detail)``;
* :meth:`Model.key` — state identity (time left out under time abstraction);
* :meth:`Model.violations` / :meth:`Model.terminal_kind` — the properties.

Configurations are nested tuples (compact, immutable, hashable)::

    state = (time, phase, lockQueue, shared, agents, env)
    agent = (pc, counter, lockState, status, locals, allread, position, reach)
    reach = (target, obstacles, t0, doReach_done, doReach_fail)

``pc`` interns the agent's pending computation ``k`` (a tuple of statement
occurrence ids and markers, docs/language.md §11) as a small integer; the
compiled program's :class:`~pccl.model.compiled.Control` maps it back and decodes
its head once.  What compiling the program produced (the checker's result,
the slots, the closures, the guards) is :attr:`Model.compiled`, a
:class:`~pccl.model.compiled.CompiledProgram`; the model adds the world, the
blackbox, the clock, the properties and the transitions.
"""

from __future__ import annotations

import decimal
import math
import operator

from dataclasses import dataclass
from typing import Any, Optional
from collections.abc import Callable

from pccl.lang import ast as A
from pccl.model.compile import has_rand
from pccl.model.compiled import CompiledProgram
from pccl.blackboxes.base import Motion
from pccl.lang.errors import OptionError, PcclError
from pccl.search.fingerprint import check_canonical
from pccl.model.layout import (AGS, BLANK_REACH, CNT, DISCRETE, ENV, EXITED, IDLE, LCK, LQ, PC, PHASE, POS, REACH,
                               RUNNING, SH, STATUS, STUCK, TIME, acquire_sid, is_acquire, make_agent, make_state,
                               put_agent, with_pc, with_status, without_time)
from pccl.lang.values import UNDEF
from pccl.model.options import check_model_values
from pccl.semantics import rules as R


@dataclass(frozen=True)
class Violation:
    kind: str                 # invariant | assert | stuck | deadlock | collision
    name: str                 # property name / short description
    message: str
    agent: Optional[int] = None
    span: Optional[A.Span] = None

    @property
    def identity(self):
        """Distinct violations for ``--all``: property and source location."""
        loc = (self.span.line, self.span.column) if self.span else None
        return (self.kind, self.name, loc)


@dataclass
class Property:
    name: str
    text: str
    fn: Callable
    span: Optional[A.Span]
    uses_time: bool
    src: str = ""             # the compiled Python expression (over st, sh, ags)
    expr: Optional[A.Expr] = None


@dataclass
class TemporalProperty:
    """One temporal property of spec section 9 (one instance per agent of a
    ``forall``-quantified one): ``kind`` is ``eventually``, ``leadsto``,
    ``within`` (``P ~> Q within T``) or ``reachable``.  ``p``/``q`` are
    compiled state predicates ``fn(st) -> bool``; ``ticks`` is T as a whole
    number of time steps δ (``within`` only)."""
    kind: str
    name: str
    text: str
    p: Callable
    q: Optional[Callable]
    span: Optional[A.Span]
    expr: A.Expr              # the instance's Temporal node (reductions read it)
    uses_time: bool = False
    ticks: Optional[int] = None
    bound: Optional[float] = None

    @property
    def liveness(self) -> bool:
        return self.kind in ("eventually", "leadsto")


class Model:
    """A PCCL program, its world and its blackbox, as a transition system:
    what the explorer sees (:meth:`init_states`, :meth:`successors`,
    :meth:`key`, :meth:`violations`, :meth:`terminal_kind`), the clock
    (:meth:`next_time`), the environment step and the properties.  What
    compiling the program produced is :attr:`compiled` (a
    :class:`~pccl.model.compiled.CompiledProgram`).

    The model is the rules' :class:`~pccl.semantics.rules.RuleContext`: the
    members that the compiled program owns (``ctl``, ``oracle``,
    ``guards_rand``, ``enabled_events``, ``stuck_code``) are bound to it
    once, as plain attributes, so that a rule reads each with one lookup."""

    #: A state's model time: the explorer's ``max time`` (statistics,
    #: progress) and its note on zero-time runaways read it.
    clock = staticmethod(operator.itemgetter(TIME))

    def __init__(self, program: A.Program, *, world=None, blackbox=None,
                 n_agents: Optional[int] = None, delta=1, n0: int = 1,
                 rates: Optional[dict] = None, events: str = "any",
                 max_time=None, abstract_time: Optional[bool] = None,
                 invariants=(), functions: Optional[dict] = None,
                 rand_policy: Optional[Callable] = None, collisions: bool = False,
                 reduce="none", properties=()):
        self.program = program
        #: why the search picked its blackbox (set by the API and the CLI)
        self.blackbox_reason: Optional[str] = None
        #: whether the world came from --world (None: not known; pccl.output.checked
        #: then compares it with the default world)
        self.world_given: Optional[bool] = None
        #: the engine that explored (None: not explored yet), why not native,
        #: and whether it was asked for (set by the API; pccl/model/native.py)
        self.engine_used: Optional[str] = None
        self.engine_reason: Optional[str] = None
        self.engine_asked = False
        self._set_world(world, blackbox)
        if n_agents is None:
            n_agents = self.world.n_agents or 2
        rho = check_model_values(n_agents, delta=delta, max_time=max_time, n0=n0, rates=rates,
                                 events=events)
        self._set_team(n_agents, n0, rho, events)
        self._set_clock(delta, max_time)
        self.collisions = collisions
        from pccl.model.compile import FunctionValueError
        try:
            self.compiled = CompiledProgram(program, functions=self._functions(functions),
                                            n_agents=self.N, rand_policy=rand_policy,
                                            first_only=self.first_only)
        except FunctionValueError as e:
            raise _at_world_file(self.world, e) from None
        self._bind_rule_context(self.compiled)
        self._add_properties(program, invariants, properties)
        self._set_time_abstraction(abstract_time)
        self._env_cache: dict = {}
        self._collision_cache: dict = {}
        #: report agents waiting for a lock held by an exited agent (off with
        #: --no-deadlock)
        self.lock_deadlocks = True
        self._compile_successors()
        self.set_reduce(reduce)

    # -- construction, step by step -----------------------------------------------------
    def _set_world(self, world, blackbox) -> None:
        """The world (default: the empty one) and the blackbox (a name, or an
        object with the blackbox protocol; default: ``straight``)."""
        from pccl.lang.world import default_world
        from pccl.blackboxes import load_blackbox
        self.world = world if world is not None else default_world()
        try:
            if blackbox is None:
                blackbox = load_blackbox("straight")
            elif isinstance(blackbox, str):          # '' is an error, not the default
                blackbox = load_blackbox(blackbox)
            else:
                _check_blackbox_object(blackbox)
        except PcclError as e:
            if e.filename is None:
                e.filename = "--blackbox"
            raise
        self.blackbox = blackbox

    def _set_team(self, n_agents: int, n0: int, rho: list, events: str) -> None:
        """The team: its size, n0, the rate map ρ (one rate per agent) and
        the events policy."""
        self.N = n_agents
        self.rho = rho
        self.n0 = n0
        self.first_only = events == "first"
        self.events_policy = events

    def _set_clock(self, delta, max_time) -> None:
        """The clock: time is n·δ for an integer n, computed exactly in
        decimal from δ as written (0.1 is 1/10), then rounded once to a
        float; so no δ is too small to advance it and 0.1 + 0.2 is 0.3."""
        self.delta = delta
        self.max_time = max_time
        self._delta_dec = _decimal(delta)
        self.max_ticks = (None if max_time is None
                          else int((_decimal(max_time) / self._delta_dec).to_integral_value(
                              rounding=decimal.ROUND_FLOOR)))
        self._next_time: dict = {}

    def _functions(self, functions: Optional[dict]) -> dict:
        """The uninterpreted functions' values: the world's (``getObs`` is
        its obstacles, ``getInput`` empty unless given), then the caller's."""
        funcs = dict(self.world.functions_dict()) if hasattr(self.world, "functions_dict") else {}
        if "getObs" not in funcs:
            funcs["getObs"] = tuple(self.world.obstacles)
        funcs.setdefault("getInput", ())
        funcs.update(functions or {})
        return funcs

    def _bind_rule_context(self, compiled: CompiledProgram) -> None:
        """The RuleContext members that the compiled program owns."""
        self.ctl = compiled.ctl
        self.oracle = compiled.oracle
        self.guards_rand = compiled.guards_rand
        self.enabled_events = compiled.enabled_events
        self.stuck_code = compiled.stuck_code

    def _add_properties(self, program: A.Program, invariants, properties) -> None:
        """The program's own properties, then ``--invariant`` and
        ``--property`` texts, checked and compiled."""
        self.properties: list[Property] = []
        #: the temporal properties (spec section 9), see pccl/search/liveness.py
        self.temporal: list[TemporalProperty] = []
        self._compile_violations()
        for inv in program.invariants:
            text = _src_text(program.source, inv.expr.span)
            if _is_temporal(inv.expr):
                self.add_temporal(inv.expr, name=inv.name or text, text=text, span=inv.span,
                                  filename=program.filename, source=program.source)
                continue
            self.add_property(inv.expr, name=inv.name, text=text,
                              span=inv.span, filename=program.filename, source=program.source)
        for k, inv in enumerate(invariants):
            self.add_invariant_text(inv, index=k)
        for k, text in enumerate(properties):
            self.add_property_text(text, index=k)

    def _set_time_abstraction(self, abstract_time: Optional[bool]) -> None:
        """Time abstraction (leave the clock out of a state's identity): on
        when sound unless asked (None); an error when asked and unsound."""
        bb_time = getattr(self.blackbox, "uses_time", False)
        uses_time = (any(p.uses_time for p in self.properties)
                     or any(p.uses_time for p in self.temporal) or bb_time)
        sound = not uses_time and self.max_time is None
        if abstract_time is None:
            abstract_time = sound
        elif abstract_time and uses_time:
            raise OptionError(
                "abstract_time", "time abstraction is unsound here: a property or the blackbox "
                "reads the clock; drop --abstract-time")
        elif abstract_time and self.max_time is not None:
            raise OptionError(
                "abstract_time", "time abstraction cannot be combined with --max-time: the bound "
                "reads the clock; drop --abstract-time")
        self.abstract_time = bool(abstract_time)
        self.record_t0 = not self.abstract_time or bb_time

    # -- reductions (pccl/model/reduce.py) -------------------------------------------------
    @property
    def property_exprs(self) -> list:
        return ([p.expr for p in self.properties if p.expr is not None]
                + [p.expr for p in self.temporal])

    def set_reduce(self, reduce="auto", uses=None):
        """Turn on the reductions ``reduce`` asks for (``auto``: every sound
        one; ``none``; a list of names): installs per instance a merged
        ``successors`` and/or a canonical ``key``.  ``uses`` (kept from the
        last call when None) names uses of the search that rule some
        reductions out (``reduce.USE_LIMITS``, e.g. ``("coverage",)``).
        :attr:`reduction` says which are on and why the others are off."""
        from pccl.model import reduce as RD
        if uses is not None:
            self.reduce_uses = tuple(uses)
        for attr in ("successors", "key", "merger", "por"):
            self.__dict__.pop(attr, None)
        self.successors = self.plain_successors
        self.key = operator.itemgetter(slice(PHASE, None) if self.abstract_time else slice(None))
        plan, slots = RD.plan(self, reduce, getattr(self, "reduce_uses", ()))
        self.reduction = plan
        base = None
        if "por" in plan.on:
            self.por = RD.Por(self)
            self.successors = base = self.por.successors
        if "merge" in plan.on:
            self.merger = RD.Merger(self, base)
            self.successors = self.merger.successors
        if "symmetry" in plan.on:
            self.key = RD.make_symmetric_key(self, slots)

    @property
    def reduced(self) -> bool:
        return bool(self.reduction.on)

    def expand(self, before, label) -> list:
        """The unreduced steps ``[(label, state), ...]`` of a transition."""
        merger = self.__dict__.get("merger")
        if merger is None:
            for lab, s in Model.successors(self, before):
                if lab == label:
                    return [(lab, s)]
            raise ValueError(f"label {label!r} is not enabled")
        return merger.expand(before, label)

    # -- adding properties (checked and compiled by the compiled program) --------------
    def add_property(self, expr: A.Expr, *, name, text, span, filename, source):
        self.compiled.check_property(expr, filename=filename, source=source)
        src, fn = self.compiled.state_predicate(expr)
        uses_time = any(isinstance(x, A.Name) and x.name == "time" for x in A.walk_expr(expr))
        self.properties.append(Property(name or text, text, fn, span, uses_time, src, expr))
        self._compile_violations()
        if hasattr(self, "reduction"):
            self.set_reduce(self.reduction.requested)

    def _compile_violations(self):
        """Install, as the instance's ``violations``, a compiled fast path:
        if no agent is stuck and every property holds (the common case) it
        returns ``[]`` at once; otherwise it defers to :meth:`Model.violations`
        (the properties are pure, so evaluating them again is harmless).
        Not used with collision checking, which always takes the full path."""
        if self.collisions or self.N > 64:
            self.__dict__.pop("violations", None)
            return
        ok = " and ".join(f"ags[{j}][{STATUS}] < {STUCK}" for j in range(self.N))
        # ... and the lock is free or its holder has not exited
        ok += f" and (not st[{LQ}] or ags[st[{LQ}][0]][{STATUS}] != {EXITED})"
        body = f"    ags = st[{AGS}]\n    if {ok}:\n"
        if self.properties:
            conj = " and ".join(f"({p.src})" for p in self.properties)
            body += (f"        sh = st[{SH}]\n        try:\n"
                     f"            if {conj}:\n                return []\n"
                     "        except Exception:\n            pass\n")
        else:
            body += "        return []\n"
        body += "    return _full(st)\n"
        self.violations = self.compiled.make_function("st", body, "_violations",
                                                      _full=Model.violations.__get__(self))

    def add_invariant_text(self, text: str, index: int = 0):
        from pccl.lang.parser import parse_property
        fname = f"--invariant #{index + 1}"
        expr = parse_property(text, filename=fname)
        if _is_temporal(expr):
            t = _top_temporal(expr)
            raise PcclError("--invariant takes a state property; a temporal property "
                            "(eventually, ~>, within, reachable) goes with --property",
                            filename=fname, source=text, span=t.span)
        self.add_property(expr, name=text, text=text, span=None, filename=fname, source=text)

    def add_property_text(self, text: str, index: int = 0):
        """``--property FORM``: any form of spec section 9."""
        from pccl.lang.parser import parse_property
        if not isinstance(text, str):
            raise PcclError(f"a property must be text, got {type(text).__name__}",
                            filename="--property")
        fname = f"--property #{index + 1}"
        expr = parse_property(text, filename=fname)
        if _is_temporal(expr):
            self.add_temporal(expr, name=text.strip(), text=text.strip(), span=None,
                              filename=fname, source=text)
        else:
            self.add_property(expr, name=text, text=text, span=None, filename=fname,
                              source=text)

    def add_temporal(self, expr: A.Expr, *, name, text, span, filename, source):
        """Check and compile a temporal property; a ``forall``-quantified one
        becomes one instance per agent (``name [i=0]``, …)."""
        self.compiled.check_property(expr, filename=filename, source=source)
        qvars = []
        top = expr
        while isinstance(top, A.Quant):
            qvars.append(top.var)
            top = top.body
        combos: list[tuple] = [()]
        for _ in qvars:
            combos = [c + (k,) for c in combos for k in range(self.N)]
        for combo in combos:
            env: dict[str, int] = dict(zip(qvars, combo))
            t: Any = _subst(top, env) if env else top
            suffix = (" [" + ", ".join(f"{v}={k}" for v, k in env.items()) + "]") if env else ""

            def pred(e):
                return self.compiled.state_predicate(e)[1]
            kind = t.kind
            ticks = bound = None
            if t.bound is not None:
                kind = "within"
                try:
                    bound = self.compiled.constant(t.bound)
                except Exception as exc:
                    raise PcclError(f"the bound of 'within' cannot be evaluated: {exc}",
                                    filename=filename, source=source,
                                    span=t.bound.span) from None
                if not (isinstance(bound, (int, float)) and math.isfinite(bound) and bound >= 0):
                    raise PcclError(f"the bound of 'within' must be a finite number >= 0, "
                                    f"got {bound}", filename=filename, source=source,
                                    span=t.bound.span)
                ticks = int((_decimal(bound) / self._delta_dec).to_integral_value(
                    rounding=decimal.ROUND_FLOOR))
            uses_time = any(isinstance(x, A.Name) and x.name == "time" for x in A.walk_expr(t))
            self.temporal.append(TemporalProperty(
                kind, name + suffix, text, pred(t.p), pred(t.q) if t.q is not None else None,
                span, t, uses_time, ticks, bound))
        if hasattr(self, "reduction"):
            self.set_reduce(self.reduction.requested)

    def prepare(self) -> None:
        """Build every lazily interned table now (see :meth:`pccl.model.compiled.Control.close`):
        after this, equal configurations are equal tuples in every process."""
        self.ctl.close()

    def checkpoint_tables(self) -> dict:
        """The lazily interned tables states refer to (k cells, stuck
        reasons), for a checkpoint (pccl/search/checkpoint.py)."""
        return {"cells": list(self.ctl.cells), "stuck": dict(self.compiled.stuck_reasons)}

    def restore_tables(self, data: dict) -> None:
        """Intern the cells of :meth:`checkpoint_tables` in their order, so
        that pcs (and fingerprints) are numbered as in the search that wrote it."""
        ctl, cells = self.ctl, data["cells"]
        have = len(ctl.cells)
        if list(ctl.cells) != list(cells[:have]):
            raise ValueError("the checkpoint's k cells are not this program's")
        for cell in cells[have:]:
            ctl._cell(cell)
        if len(ctl.cells) != len(cells):
            raise ValueError("the checkpoint's k cells repeat")
        self.compiled.stuck_reasons.update(data["stuck"])

    # -- initial states -------------------------------------------------------------------
    #: Initial states remembered to drop duplicates early (fewer with many
    #: agents); beyond that the explorer merges them (it admits initial
    #: states by identity).
    INIT_DEDUP = 1 << 16

    def init_states(self):
        """The initial configurations (:meth:`_init_states`); a world
        function's value that does not fit is reported at the world file."""
        from pccl.model.compile import FunctionValueError
        try:
            yield from self._init_states()
        except FunctionValueError as e:
            raise _at_world_file(self.world, e) from None

    def _init_states(self):
        """The initial configurations, one per combination of ``rand``
        outcomes in declarations and ``Init``, generated lazily (depth-first,
        in increasing outcome order): the product of the agents' outcomes is
        never built, so a consumer can stop after as many as it admits."""
        lay, N = self.compiled.layout, self.N
        starts = self.world.start_positions(N)
        loc0 = tuple(UNDEF if v.ty.kind != "array" else (UNDEF,) * v.ty.size for v in lay.local)
        ar0 = tuple(UNDEF if v.ty.kind != "array" else (UNDEF,) * v.ty.size for v in lay.allread)
        agents = tuple(
            make_agent(self.ctl.empty_pc, 0, IDLE, RUNNING, loc0, ar0, self.round_pos(starts[i]),
                       BLANK_REACH)
            for i in range(N))
        shared0 = tuple(UNDEF if v.ty.kind != "array" else (UNDEF,) * v.ty.size for v in lay.shared)
        env0 = self._call_blackbox(0, "init_env", self.world, N)
        _check_env(self, env0, 0)
        # the stages: shared initialisers once (in agent 0's context), then per
        # agent its declarations and its Init block
        stages: list = [(-1, vs) for vs in lay.shared if vs.decl.init is not None]
        per_agent = [vs for vs in lay.allread + lay.local if vs.decl.init is not None]
        has_init = bool(self.program.init)
        for i in range(N):
            stages.extend((i, vs) for vs in per_agent)
            if has_init:
                stages.append((i, None))
        n = len(stages)
        seen: set = set()
        cap = min(self.INIT_DEDUP, max(16, (1 << 22) // N))   # states of N agents each
        if not n:
            yield make_state(0, DISCRETE, (), shared0, agents, env0)
            return
        # Depth-first over the stages with an explicit stack (no recursion:
        # 10,000 agents make 10,000s of stages).  Memory is linear in the
        # configuration: the path's configuration is kept in mutable form
        # (the shared variables and the locals and allread of the agents
        # whose declarations are being evaluated as lists, the agent cells as
        # a list) and a level of the stack is a generator that writes its
        # outcome there and undoes it when it moves on or is popped, so a
        # level holds one slot's value, never a copy of a tuple (one copy of
        # the locals per declaration was quadratic: 10,000 declarations took
        # 1.7 GiB).  Tuples are built once per agent (when its declarations
        # are done), per Init block and per yield.
        w = _InitPath(agents, shared0, loc0, ar0, has_init)
        stack: list = []

        def push(k):
            i, vs = stages[k]
            prev = stages[k - 1][0] if k else None
            if i >= 0 and prev != i:
                w.begin_agent(i, prev)
            if vs is None:
                stack.append(self._init_stage(w, i, env0))
            elif i < 0:
                stack.append(self._shared_decl_stage(w, vs))
            else:
                stack.append(self._decl_stage(w, i, vs))

        push(0)
        while stack:
            if next(stack[-1], None) is None:
                stack.pop()
                k = len(stack)
                i = stages[k][0]
                if i >= 0 and (k == 0 or stages[k - 1][0] != i):
                    w.end_agent(i)
                continue
            if len(stack) < n:
                push(len(stack))
                continue
            w.finish_last(stages[-1][0])
            st = make_state(0, DISCRETE, w.lq, w.sh_tuple(), tuple(w.cells), env0)
            if st in seen:
                continue
            if len(seen) < cap:
                seen.add(st)
            yield st

    def _shared_decl_stage(self, w, vs):
        """Stage: the initialiser of the shared (allwrite) variable ``vs``,
        evaluated once in agent 0's context; one outcome per ``rand``
        outcome.  A runtime error is an error of the program's initial
        configuration (no agent runs it): a :class:`PcclError` at the
        declaration (docs/decisions.md)."""
        fn = self.compiled.decl_init(vs)
        oracle, j, shl, cells, blank = self.oracle, vs.slot, w.shl, w.cells, w.shared0[vs.slot]

        def guarded(*a):
            oracle.agent = 0
            try:
                return fn(*a)
            except R.RUNTIME_ERRORS as exc:
                return R.Err.of(exc)
            finally:
                oracle.agent = None
        results = (oracle.iter_outcomes(guarded, 0, cells[0], shl, cells)
                   if has_rand(vs.decl.init) else (guarded(0, cells[0], shl, cells),))
        try:
            for res in results:
                if isinstance(res, R.Err):
                    raise PcclError(f"the initialiser of `{vs.name}` at line "
                                    f"{vs.decl.span.line}: {res.reason}",
                                    span=vs.decl.span, filename=self.program.filename,
                                    source=self.program.source)
                shl[j] = (res,) * vs.ty.size if vs.ty.kind == "array" else res
                yield True
                shl[j] = blank
        finally:
            shl[j] = blank

    def _decl_stage(self, w, i, vs):
        """Stage: agent i's declaration ``vs`` initialised, one outcome per
        ``rand`` outcome, lazily; the value is written into the agent's
        slot list (or its status set to stuck) and undone on resumption."""
        if w.bases[i][STATUS] != RUNNING:
            yield True
            return
        fn = self.compiled.decl_init(vs)
        oracle, cells, sh = self.oracle, w.cells, w.sh_tuple()
        slots = w.locs[i] if vs.section == "loc" else w.ars[i]
        j = vs.slot
        blank = slots[j]
        base = w.bases[i]

        def guarded(*a):
            oracle.agent = i
            # the agent as its initialisers see it: the slot lists as its
            # locals and allread (compiled expressions only subscript them)
            cells[i] = w.view(i)      # the path may have moved on since the last outcome
            try:
                return fn(i, cells[i], sh, cells)
            except R.RUNTIME_ERRORS as exc:
                return R.Err.of(exc)
            finally:
                oracle.agent = None
        results = (oracle.iter_outcomes(guarded) if has_rand(vs.decl.init) else (guarded(),))
        try:
            for res in results:
                if isinstance(res, R.Err):
                    code = self.stuck_code("error", res.reason, ("decl", vs.decl.span))
                    w.bases[i] = with_status(base, code)
                    yield True
                    w.bases[i] = base
                    continue
                # the value is canonical (Compiler.value); `bool f[3] = false;` fills
                slots[j] = (res,) * vs.ty.size if vs.ty.kind == "array" else res
                yield True
                slots[j] = blank
        finally:
            slots[j] = blank
            w.bases[i] = base

    def _init_stage(self, w, i, env0):
        """Stage: agent i's Init block run to completion; one outcome per
        state it can end in (lockQueue, shared and agent i's cell set)."""
        w.finish_agent(i)
        lq, sh, cell = w.lq, w.sh_tuple(), w.cells[i]
        ends = [(s[LQ], s[SH], s[AGS][i]) for s in self._init_paths(
            make_state(0, DISCRETE, lq, sh, tuple(w.cells), env0), i)]
        try:
            for w.lq, w.sh, w.cells[i] in ends:
                yield True
        finally:
            w.lq, w.sh, w.cells[i] = lq, sh, cell

    #: Most steps of one path through an agent's Init block.
    INIT_LIMIT = 100_000

    def _init_paths(self, st, i) -> list:
        """Run agent i's Init block to completion from ``st`` (not
        interleaved): the states in which it ends, in depth-first order.

        Every ``rand`` outcome is a branch; branches that reach equal states
        merge (a state is expanded again only when reached in fewer steps).
        The step limit is per path: a path longer than :attr:`INIT_LIMIT`
        steps, or one that returns to a state on itself (a loop that never
        ends), leaves the agent stuck."""
        ag = st[AGS][i]
        if ag[STATUS] != RUNNING:
            return [st]
        limit = self.INIT_LIMIT
        empty = self.ctl.empty_pc
        where = ("decl", self.program.init[0].span)
        init_pc = self.ctl.intern(tuple(x.sid for x in self.program.init))
        start = put_agent(st, i, with_pc(ag, init_pc))
        done: dict = {}
        best: dict = {}
        on_path: set = set()
        stack: list = []
        oracle = self.oracle

        def enter(s, d):
            a = s[AGS][i]
            if a[STATUS] != RUNNING or a[PC] == empty:
                done[s] = None
            elif s in on_path:
                done[R.stuck_successor(self, s, i, a, "Init does not finish (it can loop forever)",
                              where)] = None
            elif d >= limit:
                done[R.stuck_successor(self, s, i, a, f"Init does not finish within {limit:,} steps",
                              where)] = None
            elif best.get(s, limit) > d:
                best[s] = d
                on_path.add(s)
                out: list = []
                oracle.agent = i
                head = self.ctl.info(a[PC])
                for rule in head.rules:
                    rule(self, s, i, a, head, out)
                # Init runs untimed: an atomic wait cannot happen (nobody else holds the lock)
                stack.append((s, d, iter(out)))

        try:
            enter(start, 0)
            while stack:
                s, d, it = stack[-1]
                nxt = next(it, None)
                if nxt is None:
                    stack.pop()
                    on_path.discard(s)
                else:
                    enter(nxt[1], d + 1)
        finally:
            oracle.agent = None
        return list(done)

    # -- transitions ------------------------------------------------------------------
    def successors(self, st) -> list:
        out: list = []
        if st[PHASE] == DISCRETE:
            infos = self.ctl.infos
            oracle = self.oracle
            rho, n0 = self.rho, self.n0
            # TIME ADVANCE's guard (R.time_advance_enabled) gathered on the
            # way: some agent running, none that has not exited with
            # counter + rho(i) <= n0
            running = blocked = False
            i = 0
            for ag in st[AGS]:
                s = ag[STATUS]
                if s == RUNNING:
                    running = True
                    info = infos[ag[PC]]
                    if info is None:
                        info = self.ctl.info(ag[PC])
                    if ag[CNT] + rho[i] <= n0:
                        blocked = True
                        rules = info.rules
                    else:
                        rules = info.rules_spent
                    oracle.agent = i
                    for rule in rules:
                        rule(self, st, i, ag, info, out)
                elif s != EXITED and ag[CNT] + rho[i] <= n0:
                    blocked = True
                i += 1
            if running and not blocked:
                R.time_advance(self, st, out, True)
        else:
            R.doreach_invoke(self, st, out)
        return out

    #: teams up to this size get :meth:`successors` unrolled (generated code)
    UNROLL_AGENTS = 16

    def _compile_successors(self) -> None:
        """``plain_successors``: :meth:`successors` generated for this team,
        the loop over agents unrolled and ``counter + ρ(i) ≤ n0`` folded to
        ``counter ≤ n0 - ρ(i)`` (the same transitions in the same order;
        tests/test_engine_compiled.py compares them).  Larger teams use the
        method itself."""
        if self.N > self.UNROLL_AGENTS:
            self.plain_successors = self.successors
            return
        lines = ["    out = []", f"    if st[{PHASE}] != {DISCRETE}:", "        _dr(_m, st, out)",
                 "        return out", f"    ags = st[{AGS}]", "    running = blocked = False"]
        for i in range(self.N):
            cap = self.n0 - self.rho[i]
            lines += [
                f"    ag = ags[{i}]",
                f"    s = ag[{STATUS}]",
                f"    if s == {RUNNING}:",
                "        running = True",
                f"        info = _infos[ag[{PC}]]",
                "        if info is None:",
                f"            info = _info(ag[{PC}])",
                f"        if ag[{CNT}] <= {cap}:",
                "            blocked = True",
                "            rules = info.rules",
                "        else:",
                "            rules = info.rules_spent",
                f"        _oracle.agent = {i}",
                "        for rule in rules:",
                f"            rule(_m, st, {i}, ag, info, out)",
                f"    elif s != {EXITED} and ag[{CNT}] <= {cap}:",
                "        blocked = True",
            ]
        lines += ["    if running and not blocked:", "        _ta(_m, st, out, True)",
                  "    return out"]
        g: dict[str, Any] = dict(_m=self, _infos=self.ctl.infos, _info=self.ctl.info, _oracle=self.oracle,
                 _ta=R.time_advance, _dr=R.doreach_invoke)
        src = "def _successors(st):\n" + "\n".join(lines) + "\n"
        exec(compile(src, "<pccl:_successors>", "exec"), g)
        self.plain_successors = g["_successors"]

    def next_time(self, t):
        """The clock after TIME ADVANCE from ``t`` = n·δ: (n + 1)·δ, exactly
        as a decimal and rounded once to a float (an int when δ is an int);
        None if that is beyond ``--max-time``."""
        try:
            return self._next_time[t]
        except KeyError:
            pass
        d = self.delta
        if type(d) is int and type(t) is int:
            n = t // d
            nxt = t + d
        else:
            with decimal.localcontext(_EXACT):
                n = int((_decimal(t) / self._delta_dec).to_integral_value())
                nxt = float(self._delta_dec * (n + 1))
            if self.max_ticks is not None and n + 1 > self.max_ticks:
                pass                                    # beyond the bound anyway
            elif not nxt > t or not math.isfinite(nxt):
                raise OptionError(
                    "delta", f"the clock cannot advance from {_fmt_time(t)} by δ = {d:g}: "
                    f"time {_fmt_time(t)} + δ is not representable as a float")
        if self.max_ticks is not None and n + 1 > self.max_ticks:
            nxt = None
        if len(self._next_time) >= 1 << 20:
            self._next_time.clear()
        self._next_time[t] = nxt
        return nxt

    def key(self, st):
        """State identity: the configuration, without the clock under time
        abstraction.  (Replaced per instance by an equivalent C-level
        ``itemgetter``; the explorer calls it once per transition.)"""
        return without_time(st) if self.abstract_time else st

    def environment_step(self, st):
        """The blackbox's outcomes for DOREACH INVOKE: [(positions, done, fail, env)]."""
        ags = st[AGS]
        bb = self.blackbox
        ckey = (tuple((ag[POS], ag[REACH], ag[STATUS] == RUNNING) for ag in ags), st[ENV],
                st[TIME] if getattr(bb, "uses_time", False) else None)
        hit = self._env_cache.get(ckey)
        if hit is not None:
            return hit
        # Motion's fields: the position, the reach cells in order, active
        motions = tuple(Motion(ag[POS], *ag[REACH], ag[STATUS] == RUNNING) for ag in ags)
        outcomes = self._call_blackbox(st[TIME], "step", self.world, motions, st[ENV], st[TIME],
                                       self.delta)
        if isinstance(outcomes, (str, bytes)) or not hasattr(outcomes, "__iter__"):
            self.blackbox_error(st[TIME], f"step() must return a list of Outcome, got "
                                       f"{_type_of(outcomes)}")
        outcomes = list(outcomes)
        if not outcomes:
            self.blackbox_error(st[TIME], "step() returned no outcome (it must return at least one)")
        res = []
        seen = set()
        for n, o in enumerate(outcomes):
            r = self._check_outcome(st[TIME], n + 1, o)
            if r not in seen:
                seen.add(r)
                res.append(r)
        if len(self._env_cache) > 200_000:
            self._env_cache.clear()
        self._env_cache[ckey] = res
        return res

    # -- blackbox calls: user code, so every failure names the blackbox ------------------
    def blackbox_error(self, time, what):
        name = getattr(self.blackbox, "name", type(self.blackbox).__name__)
        raise OptionError("blackbox", f"blackbox '{name}' failed at time {_fmt_time(time)}: {what}")

    def _call_blackbox(self, time, method, *args):
        try:
            return getattr(self.blackbox, method)(*args)
        except (PcclError, KeyboardInterrupt):
            raise
        except Exception as e:
            self.blackbox_error(time, f"{method}() raised {type(e).__name__}: {e}")

    def _check_outcome(self, time, n, o):
        """One outcome as the engine's tuple, or a PcclError saying what is wrong."""
        N = self.N
        missing = [a for a in ("positions", "done", "fail", "env") if not hasattr(o, a)]
        if missing:
            self.blackbox_error(time, f"outcome {n} is {_type_of(o)}, not an Outcome "
                                      f"(missing {', '.join(missing)})")
        for what in ("positions", "done", "fail"):
            v = getattr(o, what)
            if not isinstance(v, (tuple, list)) or len(v) != N:
                got = f"{len(v)} entries" if isinstance(v, (tuple, list)) else _type_of(v)
                self.blackbox_error(time, f"outcome {n}: '{what}' must have one entry per agent "
                                          f"({N}), got {got}")
        poss = []
        for i, p in enumerate(o.positions):
            if (not isinstance(p, (tuple, list)) or len(p) not in (2, 3)
                    or not all(isinstance(c, (int, float)) and not isinstance(c, bool)
                               and math.isfinite(c) for c in p)):
                self.blackbox_error(time, f"outcome {n}: position of agent {i} must be "
                                          f"(x, y, z) finite numbers, got {p!r:.80}")
            poss.append(self.round_pos(p))
        _check_env(self, o.env, time, n)
        return (tuple(poss), tuple(bool(x) for x in o.done),
                tuple(bool(x) for x in o.fail), o.env)

    def round_pos(self, p):
        res = self.world.resolution
        if not res:
            out = tuple(float(c) + 0.0 for c in p)
            return out if len(out) == 3 else out + (0.0,) * (3 - len(out))
        try:
            out = tuple(round(round(float(c) / res) * res, 9) + 0.0 for c in p)
        except (OverflowError, ValueError):     # inf, nan, or c / res beyond the float range
            raise PcclError(f"position ({', '.join(f'{float(c):g}' for c in p)}) cannot be "
                            f"rounded to the resolution {res:g}: coordinates must be finite "
                            f"and far from the float limit") from None
        return out if len(out) == 3 else out + (0.0,) * (3 - len(out))

    # -- checking properties ---------------------------------------------------------------
    def violations(self, st) -> list:
        """Every violation in ``st``: stuck agents, then properties, then
        collisions.  (Instances shadow this with the fast path compiled by
        :meth:`_compile_violations`, which falls back to it.)"""
        out = []
        for i, ag in enumerate(st[AGS]):
            s = ag[STATUS]
            if s >= STUCK:
                kind, reason, where = self.compiled.stuck_reasons[s]
                span = self.compiled.span_of(where)
                if kind == "assert":
                    out.append(Violation("assert", "assertion", f"agent {i}: assertion failed", i, span))
                else:
                    out.append(Violation("stuck", "stuck agent", f"agent {i} stuck: {reason}", i, span))
        for p in self.properties:
            try:
                ok = p.fn(st)
            except R.RUNTIME_ERRORS as exc:
                out.append(Violation("invariant", p.name,
                                     f"invariant '{p.name}' could not be evaluated: "
                                     f"{getattr(exc, 'reason', None) or R.describe_error(exc)}",
                                     None, p.span))
                continue
            if not ok:
                out.append(Violation("invariant", p.name, f"invariant '{p.name}' violated",
                                     None, p.span))
        if self.collisions:
            out.extend(self.collision_violations(st))
        lq = st[LQ]
        if lq and self.lock_deadlocks and st[AGS][lq[0]][STATUS] == EXITED:
            v = self.lock_violation(st)
            if v is not None:
                out.append(v)
        return out

    def lock_violation(self, st) -> Optional[Violation]:
        """The lock is held by an agent that has exited (``exit()`` inside
        ``atomic`` keeps the lock) and a running agent waits for it: that
        agent can never progress, although time may advance forever."""
        lq, ags = st[LQ], st[AGS]
        holder = lq[0]
        waiting = [j for j in lq[1:] if ags[j][STATUS] == RUNNING]
        if not waiting:
            return None
        w = waiting[0]
        k = self.ctl.cells[ags[w][PC]]
        span = self.compiled.stmts[acquire_sid(k[0])].span if k and is_acquire(k[0]) else None
        where = f" (atomic at line {span.line})" if span is not None else ""
        others = (f"; agents {', '.join(map(str, waiting[1:]))} wait too"
                  if len(waiting) > 1 else "")
        msg = (f"deadlock: agent {w} waits forever for the lock{where}: agent {holder} holds "
               f"it and has exited, so it never releases it{others}")
        return Violation("deadlock", "lock held by an exited agent", msg, w, span)

    def collision_violations(self, st) -> list:
        poss = tuple([ag[POS] for ag in st[AGS]])
        hit = self._collision_cache.get(poss)
        if hit is None:
            from pccl.model.collide import contacts
            hit = [Violation("collision",
                             f"collision of agents {c.i} and {c.j}" if c.j is not None
                             else f"collision of agent {c.i} with obstacle {c.obstacle}",
                             c.message, c.i, None)
                   for c in contacts(self.world, poss)]
            if len(self._collision_cache) > 100_000:
                self._collision_cache.clear()
            self._collision_cache[poss] = hit
        return hit

    def terminal_kind(self, st) -> str:
        """For a state with no successor: final, bounded (only --max-time
        stopped time) or deadlock."""
        if all(ag[STATUS] == EXITED for ag in st[AGS]):
            return "final"
        if self.max_time is not None and R.time_advance_enabled(self, st):
            return "bounded"
        return "deadlock"

    def deadlock_violation(self, st) -> Violation:
        waiting = []
        for i, ag in enumerate(st[AGS]):
            if ag[STATUS] == RUNNING:
                waiting.append(f"agent {i} ({self.compiled.describe_k(ag[PC])}, counter {ag[CNT]})")
        msg = "deadlock: no rule applies and not every agent has exited"
        if waiting:
            msg += "; " + "; ".join(waiting)
        return Violation("deadlock", "deadlock", msg, None, None)

_EXACT = decimal.Context(prec=60)


class _InitPath:
    """The configuration on the path of :meth:`Model.init_states`'s
    depth-first search, in mutable form (see there): ``cells`` the agent
    cells; ``shl`` the shared variables while their initialisers run, then
    ``sh`` (a tuple); for an agent whose declarations are being evaluated,
    ``bases[i]`` (its cell, for the status) and ``locs[i]``/``ars[i]``
    (its locals and allread as lists); ``lq`` the lock queue."""

    def __init__(self, agents, shared0, loc0, ar0, has_init):
        self.agents, self.shared0, self.loc0, self.ar0 = agents, shared0, loc0, ar0
        self.has_init = has_init
        self.cells = list(agents)
        self.shl = list(shared0)
        self.sh: Optional[tuple] = None      # set once the shared stages are done
        self.lq: tuple = ()
        n = len(agents)
        self.bases: list = [None] * n
        self.locs: list = [None] * n
        self.ars: list = [None] * n

    def sh_tuple(self) -> tuple:
        if self.sh is None:
            return tuple(self.shl)
        return self.sh

    def begin_agent(self, i, prev) -> None:
        """The first stage of agent i is pushed (``prev``: the agent of the
        stage before, -1 for a shared one, None for none)."""
        if prev is not None and prev >= 0:
            if not self.has_init:           # else its Init stage set its cell
                self.finish_agent(prev)
        elif self.sh is None:
            self.sh = tuple(self.shl)           # the shared initialisers are done
        self.bases[i] = self.agents[i]
        self.locs[i], self.ars[i] = list(self.loc0), list(self.ar0)

    def end_agent(self, i) -> None:
        """The first stage of agent i is popped: agent i is blank again."""
        self.cells[i] = self.agents[i]
        self.bases[i] = self.locs[i] = self.ars[i] = None
        if i == 0:
            self.sh = None                      # back to the shared stages (if any)

    def view(self, i) -> tuple:
        b = self.bases[i]
        return (b[PC], b[CNT], b[LCK], b[STATUS], self.locs[i], self.ars[i], b[POS], b[REACH])

    def finish_agent(self, i) -> None:
        """Agent i's declarations are done: its cell as a tuple."""
        b = self.bases[i]
        self.cells[i] = make_agent(b[PC], b[CNT], b[LCK], b[STATUS], tuple(self.locs[i]),
                                   tuple(self.ars[i]), b[POS], b[REACH])

    def finish_last(self, i) -> None:
        """Before a yield: the last stage's agent (i) as a tuple, unless its
        Init stage set it."""
        if i >= 0 and not self.has_init:
            self.finish_agent(i)


def _top_temporal(e):
    while isinstance(e, A.Quant):
        e = e.body
    return e


def _is_temporal(e) -> bool:
    """Whether a property is one of the temporal forms (under ``forall`` at most)."""
    return isinstance(_top_temporal(e), A.Temporal)


def _subst(e, env: dict) -> Any:
    """``e`` with the bound names of ``env`` replaced by agent ids (int
    literals); an inner quantifier over the same name shadows it."""
    import dataclasses
    if isinstance(e, A.Name) and e.name in env:
        return A.IntLit(env[e.name], e.span)
    if isinstance(e, A.Quant) and e.var in env:
        env = {k: v for k, v in env.items() if k != e.var}
        if not env:
            return e
    if not dataclasses.is_dataclass(e) or isinstance(e, A.Span):
        return e
    changes = {}
    for f in dataclasses.fields(e):
        v = getattr(e, f.name)
        if isinstance(v, tuple):
            nv = tuple(_subst(x, env) for x in v)
        elif dataclasses.is_dataclass(v) and not isinstance(v, A.Span):
            nv = _subst(v, env)
        else:
            continue
        if nv is not v:
            changes[f.name] = nv
    return dataclasses.replace(e, **changes) if changes else e  # type: ignore[type-var]


def _decimal(x) -> decimal.Decimal:
    """``x`` as the decimal it was written as (0.1 is 1/10, not the binary float)."""
    return decimal.Decimal(x) if isinstance(x, int) else decimal.Decimal(repr(float(x)))


def _fmt_time(t) -> str:
    return f"{t:g}" if isinstance(t, float) else str(t)


def _type_of(v) -> str:
    return "None" if v is None else type(v).__name__


def _check_env(model, env, time, n=None):
    try:
        check_canonical(env, "env")
    except TypeError as exc:
        where = "init_env() returned" if n is None else f"outcome {n}:"
        model.blackbox_error(time, f"{where} {exc} (the env is part of the state, which "
                                   f"must have one canonical encoding: use tuples, not lists, "
                                   f"sets or dicts)")


_BLACKBOX_ATTRS = ("name", "uses_time", "init_env", "step")


def _at_world_file(world, e) -> PcclError:
    """A world function's bad value, at the world file's line and column
    (where the user must fix it), naming the program line that reads it; the
    error as it is when the value does not come from a file."""
    from pccl.lang.world import function_location
    loc = function_location(world, e.function)
    if loc is None:
        return e
    fn, source, line, col, end = loc
    read = f" (read at {e.filename}:{e.line}:{e.column})" if e.line else ""
    return PcclError(f"value of {e.function}(){read} {e.detail}", filename=fn, source=source,
                     line=line, column=col, end_column=end)


def _check_blackbox_object(bb):
    missing = [a for a in _BLACKBOX_ATTRS if not hasattr(bb, a)]
    if missing:
        raise PcclError(f"blackbox {bb!r:.60} is not a blackbox (missing {', '.join(missing)}; "
                        "see pccl.blackboxes.base)")
    if not callable(bb.step) or not callable(bb.init_env):
        raise PcclError(f"blackbox '{bb.name}': step and init_env must be methods")


def _src_text(source: str, span: A.Span) -> str:
    if not source or span is None or span.line <= 0:
        return ""
    lines = source.splitlines()
    if span.line == span.end_line and span.line <= len(lines):
        return lines[span.line - 1][span.column - 1:span.end_column - 1].strip()
    if span.line <= len(lines):
        return lines[span.line - 1][span.column - 1:].strip()
    return ""
