"""The PCCL engine: configurations and the model interface the explorer uses.

A :class:`Model` offers, stateright-style,

* :meth:`Model.init_states` — one initial configuration per combination of
  ``rand`` outcomes in declarations and ``Init``, generated lazily
  (the Init-block search is :mod:`pccl.model.initstates`);
* :meth:`Model.successors` — the enabled transitions of a configuration,
  each ``(label, successor)`` with ``label = (RULE NAME, agent, detail)``;
* :meth:`Model.key` — state identity (time left out under time abstraction);
* :meth:`Model.violations` / :meth:`Model.terminal_kind` — the properties
  (checked and compiled by :mod:`pccl.model.properties`).

The search sees a model through its reductions
(:class:`pccl.model.reduce.Reduced`, a wrapper offering the same interface); the
model's own methods are the unreduced semantics.

Configurations are nested tuples (compact, immutable, hashable)::

    state = (time, phase, lockQueue, shared, agents, env)
    agent = (pc, counter, lockState, status, locals, allread, position, reach)
    reach = (target, obstacles, t0, doReach_done, doReach_fail, leg start)

``pc`` interns the agent's pending computation ``k`` (a tuple of statement
occurrence ids and markers, docs/language.md §11) as a small integer; the
compiled program's :class:`~pccl.model.compiled.Control` maps it back and decodes
its head once.  What compiling the program produced (the checker's result,
the slots, the closures, the guards) is :attr:`Model.compiled`, a
:class:`~pccl.model.compiled.CompiledProgram`; the model adds the world and the
blackbox (:mod:`pccl.model.environment`), the clock, the properties and the
transitions.
"""

from __future__ import annotations

import operator

from abc import ABCMeta
from typing import Any, Optional
from collections.abc import Callable, Mapping

from pccl.lang import ast as A
from pccl.model.compiled import CompiledProgram
from pccl.model.environment import Clock, Environment, at_world_file, load_blackbox_arg
from pccl.lang.errors import OptionError
from pccl.model.initstates import InitSearch
from pccl.model.layout import (AGS, CNT, DISCRETE, EXITED, PC, PHASE, RUNNING, STATUS, TIME)
from pccl.model import search_view as SV
from pccl.model.options import CommonOptions, ModelOptions, check_model_values, model_choices
from pccl.model.properties import Checks, Property, TemporalProperty, Violation, sources
from pccl.model.reduce import Reduced
from pccl.semantics import rules as R

__all__ = ["Model", "Property", "TemporalProperty", "Violation", "compile_successors"]


def blackbox_arrival_is_fair(bb) -> bool:
    """Whether liveness may assume that a robot under way settles (arrives
    or fails) eventually under blackbox ``bb``: the capability
    ``arrival_is_fair`` it declares itself (``nondet``, ``nondet-fail``;
    pccl.blackboxes.base.Capabilities), never its name: a user blackbox
    called ``nondet`` whose robots may move for ever gets no fairness."""
    from pccl.blackboxes.base import declared_capabilities
    return declared_capabilities(bb).arrival_is_fair


class Model(metaclass=ABCMeta):
    """A PCCL program, its world and its blackbox, as a transition system:
    what the explorer sees (:meth:`init_states`, :meth:`successors`,
    :meth:`key`, :meth:`violations`, :meth:`terminal_kind`), the clock
    (:meth:`next_time`), the environment step and the properties.  What
    compiling the program produced is :attr:`compiled` (a
    :class:`~pccl.model.compiled.CompiledProgram`).

    Built from a program (overrides applied) and its options whole:
    ``Model(program, ModelOptions(...))`` (a :class:`~pccl.model.options.RunOptions`
    builds a run's model: the clock kept).  The options are checked by
    their class; the checks that need the team size raise an
    :class:`~pccl.lang.errors.OptionError` naming the option.

    The model is the rules' :class:`~pccl.semantics.rules.RuleContext`: the
    members that the compiled program owns (``ctl``, ``oracle``,
    ``guards_rand``, ``enabled_events``, ``stuck_code``) and those of the
    clock and the environment (``next_time``, ``environment_step``,
    ``round_pos``) are bound to it once, as plain attributes, so that a rule
    reads each with one lookup.

    A :class:`~pccl.model.reduce.Reduced` (the model seen through its reductions)
    is registered as a virtual subclass: it offers the same interface."""

    #: A state's model time: the explorer's ``max time`` (statistics,
    #: progress) and its note on zero-time runaways read it.
    clock = staticmethod(operator.itemgetter(TIME))
    #: the execution model (pccl/model/koord.py's KoordModel: "koord")
    semantics = "pccl"
    #: teams up to this size get :meth:`successors` unrolled (generated code)
    UNROLL_AGENTS = 16
    #: Initial states remembered to drop duplicates early, and most steps of
    #: one path through an agent's Init block (:class:`~pccl.model.initstates.InitSearch`).
    INIT_DEDUP = InitSearch.INIT_DEDUP
    INIT_LIMIT = InitSearch.INIT_LIMIT

    # set once per model (bound methods and generated functions)
    next_time: Callable[[Any], Any]
    environment_step: Callable[[Any], list]
    round_pos: Callable[[Any], tuple]
    #: :meth:`successors` generated for the team (:func:`compile_successors`)
    plain_successors: Callable[[Any], list]
    #: :meth:`key` as a C-level ``itemgetter``
    plain_key: Callable[[Any], Any]
    #: :meth:`violations` with a compiled fast path for the common case
    fast_violations: Callable[[Any], list]

    def __init__(self, program: A.Program, options: Optional[CommonOptions] = None):
        opts = options if options is not None else ModelOptions()
        self.program = program
        #: the options the model was built from (a trace file's ``config``)
        self.options = opts
        #: why the search picked its blackbox (set by the API and the CLI)
        self.blackbox_reason: Optional[str] = None
        #: whether the world came from --world (None: not known; pccl.checked
        #: then compares it with the default world)
        self.world_given: Optional[bool] = None
        #: the engine that explored (None: not explored yet), why not native,
        #: and whether it was asked for (set by the API; pccl/model/native.py)
        self.engine_used: Optional[str] = None
        self.engine_reason: Optional[str] = None
        self.engine_asked = False
        #: threads of the native level kernel (``--workers N`` run as threads),
        #: and why they ran as one (the levels too narrow to share), or None
        self.engine_threads = 1
        self.engine_threads_note: Optional[str] = None
        self._set_world(opts.world, opts.blackbox)
        n_agents = opts.agents if opts.agents is not None else (self.world.n_agents or 2)
        rho = check_model_values(n_agents, delta=opts.delta, max_time=opts.max_time,
                                 n0=opts.n0, rates=opts.rates, events=opts.events)
        self._set_team(n_agents, opts.n0, rho, opts.events)
        self._set_clock(opts.delta, opts.max_time)
        self.collisions = opts.collisions
        from pccl.model.compile import FunctionValueError
        try:
            self.compiled = CompiledProgram(program, functions=self._functions(opts.functions),
                                            n_agents=self.N, rand_policy=opts.rand_policy,
                                            first_only=self.first_only)
        except FunctionValueError as e:
            raise at_world_file(self.world, e) from None
        self._bind_rule_context(self.compiled)
        #: report agents waiting for a lock held by an exited agent (off with
        #: --no-deadlock)
        self.lock_deadlocks = True
        #: the properties, checked and compiled (pccl/model/properties.py)
        self.checks = Checks(self, sources(program, opts.invariants, opts.properties))
        self.properties: list[Property] = self.checks.properties
        #: the temporal properties (spec section 9), see pccl/search/liveness.py
        self.temporal: list[TemporalProperty] = self.checks.temporal
        self._set_time_abstraction(model_choices(opts)[0])
        self.plain_successors = compile_successors(self)
        self.plain_key = operator.itemgetter(slice(PHASE, None) if self.abstract_time else slice(None))
        self.fast_violations = self.checks.compile_violations()

    # -- construction, step by step -----------------------------------------------------
    def _set_world(self, world, blackbox) -> None:
        """The world (default: the empty one; a path is loaded) and the
        blackbox (a name, or an object with the blackbox protocol; default:
        ``straight``)."""
        from pccl.lang.world import World, default_world, load_world
        if world is not None and not isinstance(world, World):
            world = load_world(str(world))
        self.world = world if world is not None else default_world()
        self.blackbox = load_blackbox_arg(blackbox)
        #: liveness may assume a robot under way settles eventually (fair arrival)
        self.arrival_is_fair = blackbox_arrival_is_fair(self.blackbox)

    def _set_team(self, n_agents: int, n0: int, rho: list, events: str) -> None:
        """The team: its size, n0, the rate map ρ (one rate per agent) and
        the events policy."""
        self.N = n_agents
        self.rho = rho
        self.n0 = n0
        self.first_only = events == "first"
        self.events_policy = events

    def _set_clock(self, delta, max_time) -> None:
        """The clock (:class:`~pccl.model.environment.Clock`) and the environment
        (:class:`~pccl.model.environment.Environment`), whose methods the rules call."""
        self.delta = delta
        self.max_time = max_time
        self.time = Clock(delta, max_time)
        self.max_ticks = self.time.max_ticks
        self.next_time = self.time.next_time
        self.env = Environment(self.world, self.blackbox, self.N, delta)
        self.environment_step = self.env.step
        self.round_pos = self.env.round_pos
        self.leg_start = self.env.leg_start

    def _functions(self, functions: Optional[Mapping[str, Any]]) -> dict:
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

    def _set_time_abstraction(self, abstract_time: Optional[bool]) -> None:
        """Time abstraction (leave the clock out of a state's identity): on
        when sound unless asked (None); an error when asked and unsound."""
        bb_time = getattr(self.blackbox, "uses_time", False)
        uses_time = self.checks.uses_time or bb_time
        sound = not uses_time and self.max_time is None
        if abstract_time is None:
            abstract_time = sound
        elif abstract_time and uses_time:
            raise OptionError(
                "abstract_time", "time abstraction is unsound here: a property or the blackbox "
                "reads the clock")
        elif abstract_time and self.max_time is not None:
            raise OptionError(
                "abstract_time", "time abstraction cannot be combined with a bound on time: "
                "the bound reads the clock")
        self.abstract_time = bool(abstract_time)
        self.record_t0 = not self.abstract_time or bb_time

    @property
    def property_exprs(self) -> list:
        """Every property's expression (the reductions read the names they use)."""
        return self.checks.exprs

    def prepare(self) -> None:
        """Build every lazily interned table now (see :meth:`pccl.model.compiled.Control.close`):
        after this, equal configurations are equal tuples in every process."""
        self.ctl.close()

    def stuck_table(self) -> dict:
        """The stuck reasons by status (:meth:`pccl.model.compiled.CompiledProgram.stuck_code`):
        a status is a hash of its reason, the same in every process, but a
        process knows the reasons it met (a parallel search shares them,
        :meth:`pccl.search.parallel._Worker.new_stuck`)."""
        return self.compiled.stuck_reasons

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

    # -- the transition system -----------------------------------------------------------
    def init_states(self, first_only=frozenset(), first_value=frozenset()):
        """The initial configurations (:class:`~pccl.model.initstates.InitSearch`);
        a world function's value that does not fit is reported at the world file.
        ``first_only``: ``loc:`` variables whose ``rand`` initialiser takes only
        its first outcome; ``first_value``: those whose initialiser takes its
        first outcome with a value and every outcome that fails (values
        nothing reads: the dead-variable reduction's, pccl/model/dead.py)."""
        from pccl.model.compile import FunctionValueError
        search = InitSearch(self, first_only, first_value)
        search.INIT_DEDUP, search.INIT_LIMIT = self.INIT_DEDUP, self.INIT_LIMIT
        try:
            yield from search.states()
        except FunctionValueError as e:
            raise at_world_file(self.world, e) from None

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

    def key(self, st):
        """State identity: the configuration, without the clock under time
        abstraction (:attr:`plain_key` is the same as an ``itemgetter``)."""
        return st[PHASE:] if self.abstract_time else st

    def violations(self, st) -> list:
        """Every violation in ``st``: stuck agents, then properties, then
        collisions, then a lock held by an exited agent
        (:meth:`pccl.model.properties.Checks.violations`; :attr:`fast_violations`
        answers the common case first)."""
        return self.checks.violations(st)

    def deadlock_violation(self, st) -> Violation:
        return self.checks.deadlock_violation(st)

    # what the search family reads through the model (pccl/model/search_view.py)
    time_costs = staticmethod(SV.time_costs)
    arrival_pending = staticmethod(SV.arrival_pending)
    label_line = SV.label_line
    stall_signature = SV.stall_signature
    waiting_note = SV.waiting_note
    expand_trace = SV.expand_trace

    def terminal_kind(self, st) -> str:
        """For a state with no successor: final, bounded (only --max-time
        stopped time) or deadlock."""
        if all(ag[STATUS] == EXITED for ag in st[AGS]):
            return "final"
        if self.max_time is not None and R.time_advance_enabled(self, st):
            return "bounded"
        return "deadlock"


def compile_successors(m: "Model") -> Callable[[Any], list]:
    """``plain_successors``: :meth:`Model.successors` generated for the team,
    the loop over agents unrolled and ``counter + ρ(i) ≤ n0`` folded to
    ``counter ≤ n0 - ρ(i)`` (the same transitions in the same order;
    tests/model/test_engine_compiled.py compares them).  Larger teams use the
    method itself."""
    if m.N > m.UNROLL_AGENTS:
        return m.successors
    lines = ["    out = []", f"    if st[{PHASE}] != {DISCRETE}:", "        _dr(_m, st, out)",
             "        return out", f"    ags = st[{AGS}]", "    running = blocked = False"]
    for i in range(m.N):
        cap = m.n0 - m.rho[i]
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
    g: dict[str, Any] = dict(_m=m, _infos=m.ctl.infos, _info=m.ctl.info, _oracle=m.oracle,
                             _ta=R.time_advance, _dr=R.doreach_invoke)
    src = "def _successors(st):\n" + "\n".join(lines) + "\n"
    exec(compile(src, "<pccl:_successors>", "exec"), g)
    return g["_successors"]


Model.register(Reduced)
