"""The Python API: load, run and explore PCCL programs.

    >>> from pccl.api import explore
    >>> r = explore("programs/fischer.pccl", invariants=["count(inCs) <= 1"])
    >>> r.status, r.verdict
    ('violation', "violation of invariant 'count(inCs) <= 1' ...")
    >>> [step["rule"] for step in r.trace][:3]

``program`` may be a path, source text (with ``source=True``) or an
:class:`~pccl.lang.ast.Program`; ``world`` a path or a :class:`~pccl.lang.world.World`;
``blackbox`` a registry name, ``module:attribute`` or a blackbox object.
"""

from __future__ import annotations

import dataclasses
import json
import os
import random
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Optional, Union

from pccl.lang import ast as A
from pccl.model.engine import Model
from pccl.search.explorer import OUT_OF_MEMORY, Bound, Counterexample, Explorer, ReplayError, SearchResult, Stats, Trace
from pccl.model import validate as V
from pccl.lang.errors import ArgumentError, CheckpointFileError, OptionError, PcclError, Spelling, spell
from pccl.model.options import (IDENTITY_OPTIONS, CommonOptions, ExploreOptions, ModelOptions, RunOptions,
                                api_spelling, conflict, model_choices)
from pccl.model.reduce import Reduced
from pccl.model.compile import program_moves  # noqa: F401  (part of the API)
from pccl.model.build import (EXPLORE_MOVING_DEFAULT, MOVING_DEFAULT_REASON,  # noqa: F401  (part of the API)
                              apply_overrides, build_model, explore_blackbox, load_program,
                              load_world_arg)
from pccl.output.results import Finding, StateView, StepView
from pccl.tools.runner import RunResult, run as _run
from pccl.search.memory import format_size, parse_size  # noqa: F401  (parse_size: part of the API)
from pccl.search.spill import SpillError

#: The options of :func:`explore_model`: the fields ExploreOptions adds to the
#: model's (derived, so a new search option cannot be missing here).
SEARCH_OPTIONS = tuple(f.name for f in dataclasses.fields(ExploreOptions)
                       if f.name not in {g.name for g in dataclasses.fields(ModelOptions)})


def make_model(program, *, seed: Optional[int] = None, rng: Optional[random.Random] = None,
               **options) -> Reduced:
    """Build a :class:`Model`, seen through its reductions (a
    :class:`~pccl.model.reduce.Reduced`, with the model's interface).  ``options`` are those of
    :class:`~pccl.model.options.ModelOptions` (world, blackbox, agents, delta, n0,
    rates, events, collisions, overrides, invariants, max_time,
    abstract_time, reduce, functions, rand_policy, source).  With ``seed`` or
    ``rng`` (run mode), rand is sampled from the generator instead of
    branching.  ``overrides`` maps variable names to PCCL expressions
    replacing their initialisers."""
    V.program("make_model", program, options.get("source", False))
    V.integer("make_model", "seed", seed, optional=True)
    if rng is not None and not isinstance(rng, random.Random):
        raise ArgumentError(f"rng must be a random.Random or None, got {type(rng).__name__}",
                            filename="pccl.api.make_model")
    opts = ModelOptions.from_api("make_model", options)
    if rng is None and seed is not None:
        rng = random.Random(seed)
    return _api_model("make_model", program, opts, rng=rng)


def _api_model(func: str, program, opts: CommonOptions, **kw) -> Reduced:
    """:func:`build_model` for the API: a bad option value the model finds is
    an :class:`ArgumentError` of ``func`` that names the keyword."""
    try:
        return build_model(program, opts, **kw)
    except OptionError as e:
        raise e.for_api(func) from None


# ---------------------------------------------------------------------------
# explore
# ---------------------------------------------------------------------------

#: Shipped blackboxes with exactly one outcome per step (fixed travel times).
DETERMINISTIC_BLACKBOXES = frozenset({"instant", "straight", "pymunk"})


def fixed_timing_note(model, spelling: Spelling = api_spelling) -> Optional[str]:
    """For a program that moves explored with a deterministic blackbox: the
    note that travel times were fixed (None otherwise); the option it names
    spelt by ``spelling``."""
    bb = model.blackbox
    det = getattr(bb, "deterministic", None)
    if det is None:
        from pccl.blackboxes import BLACKBOXES
        name = getattr(bb, "name", None)
        det = name in DETERMINISTIC_BLACKBOXES and BLACKBOXES.get(name) is bb
    if not det or not program_moves(model.program):
        return None
    return spell(f"travel times fixed by {bb.name}; {{blackbox={EXPLORE_MOVING_DEFAULT}}} explores "
                 "every timing", spelling)

#: Shipped blackboxes that cover straight and pymunk, but for positions in
#: mid-motion (docs/blackboxes.md, "What each blackbox covers"): a program
#: that reads positions gets "not exhaustive for straight/pymunk".
COVERING_BLACKBOXES = frozenset({"nondet", "nondet-fail"})


def positions_read_in_motion(model) -> Optional[str]:
    """Where ``model`` reads robots' positions, which a covering blackbox
    (``nondet``) does not enumerate in mid-motion: the first
    ``getPosition()``, ``pos`` in a property, or ``{collisions}`` (the option,
    for the caller to spell); None if the program observes motion only
    through the doReach flags."""
    if model.collisions:
        return "{collisions}"
    lines = [e.span.line for e in A.walk(model.program)
             if isinstance(e, A.Call) and e.name == "getPosition"]
    if lines:
        return f"getPosition() at line {min(lines)}"
    for p in list(model.properties) + list(getattr(model, "temporal", ())):
        for e in A.walk_expr(p.expr):
            if isinstance(e, A.Name) and e.name == "pos":
                return f"pos in property `{p.text}`"
    return None


def _conjuncts(e) -> list:
    if isinstance(e, A.Binary) and e.op == "&&":
        return _conjuncts(e.left) + _conjuncts(e.right)
    return [e]


def _one_shot(prog: A.Program, ev: A.Event) -> bool:
    """Whether event ``ev`` fires at most once per agent: its guard requires
    a ``loc:`` bool ``x`` to be false (``!x``), ``x`` starts false, its
    body sets ``x = true`` outside every branch and loop, and nothing ever
    assigns ``x`` anything but ``true``."""
    local = {d.name: d for d in prog.decls if isinstance(d, A.VarDecl)
             and getattr(d, "section", "loc") == "loc"}
    assigns: dict = {}
    for s in A.walk_stmts(list(prog.init) + [x for e in prog.events for x in e.body]):
        if isinstance(s, A.Assign) and isinstance(s.target, A.Name):
            assigns.setdefault(s.target.name, []).append(s.value)
    for c in _conjuncts(ev.guard):
        if not (isinstance(c, A.Unary) and c.op == "!" and isinstance(c.operand, A.Name)):
            continue
        x = c.operand.name
        d = local.get(x)
        if d is None or not (isinstance(d.init, A.BoolLit) and d.init.value is False):
            continue
        if not all(isinstance(v, A.BoolLit) and v.value is True for v in assigns.get(x, ())):
            continue
        if any(isinstance(s, A.Assign) and isinstance(s.target, A.Name) and s.target.name == x
               for s in ev.body):
            return True
    return False


def second_leg(prog: A.Program) -> Optional[str]:
    """Where a robot of ``prog`` may start a second leg (a doReach after an
    earlier one of the same agent): ``doReach at line N``; None when every
    robot makes at most one trip: the program's only doReach stands in
    ``Init`` or in an event that fires once (:func:`_one_shot`), outside
    every ``while``."""
    def reaches(stmts) -> list:
        return [s for s in A.walk_stmts(stmts) if isinstance(s, A.CallStmt) and s.name == "doReach"]
    looped = [s for w in A.walk_stmts(list(prog.init) + [x for e in prog.events for x in e.body])
              if isinstance(w, A.While) for s in reaches(w.body)]
    sites = reaches(prog.init) + [s for ev in prog.events for s in reaches(ev.body)]
    if not sites:
        return None
    if len(sites) == 1 and not looped:
        init = reaches(prog.init)
        if init or any(_one_shot(prog, ev) for ev in prog.events if reaches(ev.body)):
            return None
    line = min(s.span.line for s in (looped or sites[1:] or sites))
    return f"doReach at line {line}"


def not_covered_note(model, spelling: Spelling = api_spelling) -> Optional[str]:
    """Under a covering blackbox (``nondet``, ``nondet-fail``), what of the
    physical blackboxes' behaviours the search does not cover, for the
    header of ``pccl explore`` and the verdict (docs/blackboxes.md, "What
    each blackbox covers"); None when nothing is left out:

    * a program that reads positions: ``not exhaustive for straight/pymunk:
      positions in mid-motion (getPosition() at line 29)``;
    * under ``nondet``, a program whose robots may start a second leg:
      ``not exhaustive for pymunk: ...`` (where pymunk's detours, pushes and
      failures leave a robot is not followed; ``nondet-fail`` covers it).

    The options it names spelt by ``spelling``."""
    from pccl.blackboxes import BLACKBOXES
    bb = model.blackbox
    name = getattr(bb, "name", None)
    if name not in COVERING_BLACKBOXES or BLACKBOXES.get(name) is not bb:
        return None
    if not program_moves(model.program):
        return None
    why = positions_read_in_motion(model)
    if why:
        return f"{NOT_EXHAUSTIVE_FOR}: positions in mid-motion ({spell(why, spelling)})"
    if getattr(bb, "always_fail", False):
        return None
    where = second_leg(model.program)
    if where:
        return spell(f"not exhaustive for pymunk: a second leg starts where pymunk left the robot "
                     f"({where}; {{blackbox=nondet-fail}} covers it)", spelling)
    return None


#: How a verdict under a covering blackbox starts its reason when the program
#: observes what the blackbox cannot enumerate (docs/blackboxes.md).
NOT_EXHAUSTIVE_FOR = "not exhaustive for straight/pymunk"


@dataclass(repr=False)
class ExploreResult:
    """What :func:`explore` found.  ``violation``/``violations`` are
    :class:`~pccl.output.results.Finding` objects (each with its ``trace`` of
    :class:`~pccl.output.results.StepView` and its violating ``state``, a
    :class:`~pccl.output.results.StateView`); ``bounds`` are the
    :class:`~pccl.search.explorer.Bound` members that cut the search and
    ``bound_labels`` how the caller spells them: ``max_states=100`` in the
    API, ``--max-states 100`` on the command line (the ``spelling`` of
    :func:`explore_model`).  Every text of the result names options so."""
    status: str                       # violation | exhaustive | bounded | interrupted
    verdict: str                      # the one-line verdict
    blackbox: str
    exit_status: int
    stats: Stats
    bounds: list = field(default_factory=list)        # [Bound]
    violation: Optional[Finding] = None               # the first violation
    violations: list = field(default_factory=list)    # every distinct violation (with find_all)
    trace: tuple = ()                                 # steps of the first counterexample
    final_state: Optional[StateView] = None           # its violating state
    collision_probability: float = 0.0
    model: Any = None
    search: Optional[SearchResult] = None
    counterexamples: list = field(default_factory=list)  # [Counterexample], as violations
    coverage: Any = None              # a CoverageReport, with coverage=True
    #: reachable P: [{"name", "text", "trace", "state"}] of the properties with a witness
    witnesses: list = field(default_factory=list)
    #: temporal properties (spec section 9) that hold, and what was not checked
    holds: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    timelock: bool = False            # whether the time-lock check ran
    stall: bool = False               # whether the stall check ran
    bound_labels: list = field(default_factory=list)  # the bounds as the caller spells them
    #: what the covering blackbox leaves out of straight's and pymunk's behaviours
    not_covered: Optional[str] = None
    #: what the verdict covers (:class:`~pccl.output.checked.Checked`: properties and
    #: their outcomes, built-in checks, blackbox, bounds, reductions, events
    #: that never fired, notes); ``.to_json()`` is ``"checked"`` of the JSON
    checked: Any = None

    #: every reachable state was expanded: a clean exhaustive verdict, or
    #: violations found by a search that went on to the end (``find_all``, or
    #: the graph analysis after an exhaustive search)
    complete: bool = False

    @property
    def exhaustive(self) -> bool:
        """Every reachable state was explored (whatever was found)."""
        return self.complete

    def __repr__(self) -> str:
        """One line: the status, the verdict, the counts (the fields hold
        the whole model, traces and states: ``r.trace``, ``r.model``...)."""
        return (f"<ExploreResult {self.status} (exit {self.exit_status}): {self.verdict!r}; "
                f"{self.stats.states:,} states, {self.stats.transitions:,} transitions"
                + (f"; trace of {len(self.trace)} steps" if self.trace else "") + ">")


def explore(program, **options) -> ExploreResult:
    """Explore ``program`` breadth-first.  ``options`` are the fields of
    :class:`~pccl.model.options.ExploreOptions`, spelt like ``pccl explore``'s
    flags (``max_states`` is ``--max-states``).  ``reduce``: ``"auto"`` (every
    reduction sound for this program, blackbox and properties), ``"none"``,
    or a list such as ``["merge"]`` (docs/reductions.md)."""
    V.program("explore", program, options.get("source", False))
    opts = ExploreOptions.from_api("explore", options)
    return explore_model(_api_model("explore", program, opts, explore=True), options=opts)


#: Fraction of the machine's physical memory a search or a run may use by
#: default (``max_memory="default"``): enough to leave the rest of the machine alive.
DEFAULT_MEMORY_FRACTION = 0.8


def default_max_memory() -> int:
    from pccl.search.explorer import physical_memory
    return int(physical_memory() * DEFAULT_MEMORY_FRACTION)


def memory_bound(max_memory) -> Optional[int]:
    """A ``max_memory`` option in bytes (``"default"``: 80 % of physical memory)."""
    return default_max_memory() if max_memory == "default" else max_memory


def require_ray():
    """The ``ray`` module for the option ``ray``, or an :class:`ArgumentError`
    saying ``pip install 'pccl[ray]'``."""
    from pccl.search.parallel import RayUnavailable, import_ray
    try:
        return import_ray()
    except RayUnavailable as e:
        raise _ray_error(e) from None


def _ray_error(e: Exception) -> ArgumentError:
    """Ray missing, unreachable or lost (:class:`~pccl.search.parallel.RayUnavailable`,
    whose text names options as placeholders) as an error of the option ``ray``."""
    return ArgumentError(str(e), where="pccl {ray}", template=True)


def explore_model(model: Union[Reduced, Model], *, options: Optional[ExploreOptions] = None,
                  spelling: Spelling = api_spelling, **search) -> ExploreResult:
    """Explore ``model``.  The search options are those of
    :class:`~pccl.model.options.ExploreOptions` (given as ``options=`` or as
    keywords): ``max_memory`` is bytes of peak resident memory at which the
    search stops with the bound ``max_memory`` (``"default"``: 80 % of
    physical memory; ``None``: no limit); ``workers`` processes (an int >= 1,
    or ``"auto"`` for the usable cores), with results identical for every
    number of workers; ``ray``: ``None`` (processes on this machine),
    ``"local"`` (start a Ray instance here) or a Ray address (``"auto"``,
    ``"HOST:PORT"``), one Ray actor per worker (``workers="auto"``: one per
    CPU of the cluster; needs ``pip install 'pccl[ray]'``); ``progress``
    (if given) is called about every
    ``progress_interval`` seconds with a dict: states, frontier, depth,
    seconds, memory (bytes).  ``spelling`` writes the options the result's
    texts name (verdict, bounds, notes, reasons, ``checked``): the API's
    keywords (``max_states=100``) by default; ``pccl explore`` passes its
    flags' (``--max-states 100``).

    The steps: resolve the model and the options (:func:`_explore_target`,
    :func:`_explore_options`), plan the search (:func:`_plan_search`: memory,
    coverage, workers, the recorder), pick the searcher and the engine
    (:func:`_make_searcher`), run it (:func:`_run_search`), expand and
    analyse the traces (:func:`_analyse`) and assemble the result
    (:func:`_assemble`)."""
    plan = _plan_search(_explore_target(model), _explore_options(options, search), spelling)
    from pccl.search.checkpoint import CheckpointError
    try:
        try:
            ex, native = _make_searcher(plan)
        except KeyboardInterrupt:
            # Ctrl-C or SIGTERM while the native module compiles (a cold
            # cache): the search's report, interrupted with nothing explored
            return _interrupted_before_search(plan)
        ex, sr = _run_search(plan, ex, native)
    except CheckpointError as e:    # a checkpoint unwritable, absent, corrupt, another search's
        raise CheckpointFileError(str(e), filename=e.option, template=e.template) from None
    try:
        # every reachable state was expanded (before the graph analysis, which
        # may turn an exhaustive search into a violation)
        complete = sr.status == "exhaustive" or (
            plan.o.find_all and sr.status == "violation" and not sr.bounds_hit)
        try:
            lv = _analyse(plan, ex, sr)
        except KeyboardInterrupt:
            # Ctrl-C or SIGTERM during the graph analysis (time-locks, stalls,
            # temporal properties): the search's report, interrupted, since
            # not every check ran
            sr.status, lv, complete = "interrupted", None, False
        _shorten(plan, sr)
        return _assemble(plan, ex, sr, lv, complete)
    finally:
        _close(ex)


def _kept(ex: Any) -> Any:
    """``ex``, told to keep its workers after the search (a
    :class:`~pccl.search.parallel.ParallelExplorer`: the analysis replays
    its counterexamples through their tables; :func:`_close` stops them)."""
    if hasattr(ex, "keep_workers"):
        ex.keep_workers = True
    return ex


def _close(ex: Any) -> None:
    close = getattr(ex, "close", None)
    if close is not None:
        close()


def _interrupted_before_search(plan: _SearchPlan) -> ExploreResult:
    """Step of :func:`explore_model`: the result of a search interrupted
    before it started (while the native engine's module compiled): status
    ``interrupted``, no state explored, the engine that would have run,
    and a note that says so."""
    from pccl.search.memory import peak_rss_bytes
    sr = SearchResult("interrupted", stats=Stats(peak_memory=peak_rss_bytes()))
    plan.rec = None         # no graph to analyse
    res = _assemble(plan, None, sr, None, False)
    res.notes.append("interrupted while the native engine's module was compiling: "
                     "no state was explored")
    return res


def _explore_target(model) -> Reduced:
    """Step of :func:`explore_model`: the model seen through the reductions
    it asks for (an :class:`ArgumentError` for anything but a model)."""
    if isinstance(model, Model) and not isinstance(model, Reduced):
        model = Reduced(model, model_choices(model.options)[1])     # the reductions it asks for
    if not isinstance(model, Reduced):
        raise ArgumentError(f"model must be a Model (from make_model), got "
                            f"{type(model).__name__}", filename="pccl.api.explore_model")
    return model


def _explore_options(options: Optional[ExploreOptions], search: dict) -> ExploreOptions:
    """Step of :func:`explore_model`: the search options, given whole or as
    keywords (checked)."""
    if options is None:
        unknown = sorted(set(search) - set(SEARCH_OPTIONS))
        if unknown:
            raise ArgumentError(f"unknown option{'s' if len(unknown) > 1 else ''} "
                                f"{', '.join(unknown)}; options are {', '.join(SEARCH_OPTIONS)}",
                                filename="pccl.api.explore_model")
        options = ExploreOptions(**search)
        options.check("explore_model")
    elif search:
        raise ArgumentError("give the search options either as options= or as keywords",
                            filename="pccl.api.explore_model")
    return options


@dataclass
class _SearchPlan:
    """What :func:`explore_model` resolved before searching: the model (with
    coverage's uses), the options, the memory bound in bytes, the number of
    workers (None: one per CPU of the Ray cluster), the search's options,
    the state-graph recorder, the labels taken and the runaway notes."""
    model: Reduced
    o: ExploreOptions
    cov: Any
    max_memory: Optional[int]
    nworkers: Optional[int]
    one: bool
    sopts: Any
    rec: Any
    labels: Optional[set]
    spelling: Spelling = api_spelling
    runaways: list = field(default_factory=list)
    #: the native model searched (None: the Python engine)
    native: Any = None
    #: --workers N as N threads of one process (the native level kernel),
    #: when the search allows it (:func:`_threads_allowed`)
    threads: bool = False

    def on_runaway_native(self, native) -> Callable[[dict], None]:
        """:meth:`on_runaway` for a search of ``native``'s states."""
        def on_runaway(info: dict) -> None:
            self.on_runaway({**info, "state": native.decode(info["state"])})
        return on_runaway

    def on_runaway(self, info: dict) -> None:
        from pccl.model.stall import runaway_note
        msg = spell(runaway_note(self.model, info), self.spelling)
        self.runaways.append(msg)
        note = getattr(self.o.progress, "note", None)     # the CLI's reporter: at once, on stderr
        if note is not None:
            note(msg)


def _plan_search(model: Reduced, o: ExploreOptions, spelling: Spelling) -> _SearchPlan:
    """Step of :func:`explore_model`: resolve the memory bound, coverage and
    the workers; check the options as resolved; make the recorder."""
    max_memory = default_max_memory() if o.max_memory == "default" else o.max_memory
    cov = None
    if o.coverage:
        if "coverage" not in model.reduce_uses:
            model = model.with_uses(("coverage",))
        from pccl.output.coverage import CoverageModel
        cov = CoverageModel(model)
    nworkers: Optional[int]         # None: with Ray, one per CPU of the cluster
    if o.workers == "auto":
        from pccl.search.parallel import available_workers
        nworkers = None if o.ray is not None else available_workers()
    else:
        assert isinstance(o.workers, int), o.workers        # validated by ExploreOptions
        nworkers = o.workers
    c = conflict(o.replace(workers="auto" if nworkers is None else nworkers))     # as resolved
    if c is not None:
        raise ArgumentError(c.message(api_spelling), filename="pccl.api.explore_model")
    one = o.ray is None and nworkers == 1
    from pccl.search import liveness as L
    # the workers record the state graph too (pccl/search/parallel.py): the same
    # time-lock and temporal analysis runs on the same graph, whatever the backend
    rec = L.make_recorder(model, o.timelock, o.stall)
    threads = _threads_allowed(o, nworkers, rec)
    if rec is not None and _frozen_recorded(o, one or threads):
        rec = L.make_recorder(model, o.timelock, o.stall, frozen=_frozen_sigs(model))
    # the distinct labels of the transitions taken: the events that fired
    labels: Optional[set] = set() if one or threads else None
    return _SearchPlan(model, o, cov, max_memory, nworkers, one, o.search_options(max_memory),
                       rec, labels, spelling, threads=threads)


def _frozen_recorded(o: ExploreOptions, one_process: bool) -> bool:
    """Whether the search records what the frozen-team check reads with its
    graph (:func:`pccl.model.frozen.check_recorded`): with the stall check,
    in one process (:class:`Explorer`: the Python engine, the native
    engine's batches and level kernel), without ``--fastest`` or a
    checkpoint; elsewhere the check explores again (docs/reductions.md)."""
    return (o.stall and one_process and not o.fastest and o.checkpoint is None
            and o.resume is None and os.environ.get("PCCL_FROZEN_GRAPH", "1") != "0")


def _frozen_sigs(model) -> Callable:
    from pccl.model.frozen import progress_signatures_fn
    return progress_signatures_fn(model)


def _threads_allowed(o: ExploreOptions, nworkers: Optional[int], rec: Any) -> bool:
    """Whether ``--workers N`` may run as N threads of this process (the
    native engine's level kernel, which admits exactly what one process
    admits) instead of N processes: a native search of this machine that
    records no graph or one the kernel records (the time-lock and stall
    checks' and a temporal property's), with no ``--fastest``,
    ``--coverage``, checkpoint or spill.  The native model decides the
    rest (no level kernel: processes)."""
    return (o.ray is None and nworkers is not None and nworkers > 1
            and (rec is None or rec.kernel_ready or bool(rec.props))
            and o.engine != "python" and not o.fastest and not o.coverage
            and o.checkpoint is None and o.resume is None and o.spill is None
            and os.environ.get("PCCL_THREADS", "1") != "0")


def _make_searcher(plan: _SearchPlan) -> tuple:
    """Step of :func:`explore_model`: the searcher (plain, native, fastest,
    parallel processes or Ray actors) and the native model (or None)."""
    model, o, sopts = plan.model, plan.o, plan.sopts
    native = _choose_engine(model, o, plan.rec is not None, plan.one or plan.threads,
                            plan.spelling)
    if native is not None and plan.threads and native.explore_levels is not None:
        # --workers N as threads of this process
        model.engine_threads = plan.nworkers
        plan.native = native
        if plan.rec is not None:        # the graph of the native states
            from pccl.search import liveness as L
            plan.rec = L.make_recorder(native, o.timelock, o.stall, frozen=(
                _frozen_sigs(native) if _frozen_recorded(o, True) else None))
        return (Explorer(native, dataclasses.replace(sopts, batch=native.BATCH,
                                                     threads=plan.nworkers),
                         recorder=plan.rec, on_runaway=plan.on_runaway_native(native),
                         labels=plan.labels), native)
    if plan.threads:
        # processes after all (the Python engine, or statements that call
        # Python); a native model for them names values alike in each
        plan.threads, plan.labels = False, None
        if native is not None:
            native = _choose_engine(model, o, False, False, plan.spelling)
        elif plan.rec is not None and plan.rec.frozen is not None:
            # (the workers record no labels: the frozen-team check explores again)
            from pccl.search import liveness as L
            plan.rec = L.make_recorder(model, o.timelock, o.stall)
    if native is not None:
        on_runaway_native = plan.on_runaway_native(native)
        if plan.rec is not None:        # the graph of the native states
            from pccl.search import liveness as L
            plan.rec = L.make_recorder(native, o.timelock, o.stall, frozen=(
                _frozen_sigs(native) if _frozen_recorded(o, plan.one) else None))
        plan.native = native
        if not plan.one:        # --workers N: forked workers over native vectors
            return _parallel_searcher(plan, native), native
        return (Explorer(native, dataclasses.replace(sopts, batch=native.BATCH), recorder=plan.rec,
                         on_runaway=on_runaway_native, labels=plan.labels,
                         checkpoint=_checkpointer(model, o, native)), native)
    opts = {f.name: getattr(sopts, f.name) for f in dataclasses.fields(sopts)}  # as keywords
    if o.ray is not None:
        from pccl.search.parallel import ParallelExplorer
        require_ray()           # the install hint before anything else
        return ParallelExplorer(model, workers=plan.nworkers, ray=o.ray, recorder=plan.rec,
                                fastest=o.fastest, **opts, checkpoint=_checkpointer(model, o)), None
    if plan.nworkers is not None and plan.nworkers > 1:
        return _parallel_searcher(plan, model), None
    if o.fastest:
        from pccl.search.fastest import FastestExplorer
        return FastestExplorer(plan.cov or model, sopts, recorder=plan.rec,
                               labels=plan.labels, checkpoint=_checkpointer(model, o)), None
    return Explorer(plan.cov or model, sopts, recorder=plan.rec, on_runaway=plan.on_runaway,
                    labels=plan.labels, checkpoint=_checkpointer(model, o)), None


def _parallel_searcher(plan: _SearchPlan, model) -> Any:
    """The :class:`~pccl.search.parallel.ParallelExplorer` of ``--workers N``
    (forked processes) over ``model``: the Python model or its native one."""
    from pccl.search.parallel import ParallelExplorer
    o = plan.o
    opts = {f.name: getattr(plan.sopts, f.name) for f in dataclasses.fields(plan.sopts)}
    return ParallelExplorer(model, workers=plan.nworkers, recorder=plan.rec, fastest=o.fastest,
                            **opts, checkpoint=_checkpointer(plan.model, o))


def _run_search(plan: _SearchPlan, ex: Any, native) -> tuple:
    """Step of :func:`explore_model`: run ``ex`` (deadlocks checked as the
    options say); a native search that meets a value its vectors cannot
    hold starts again on the Python engine.  Returns the searcher that ran
    and its :class:`SearchResult`."""
    model = plan.model
    saved, model.lock_deadlocks = model.lock_deadlocks, plan.o.deadlock
    try:
        sr = _kept(ex).run()
        if plan.threads and isinstance(ex, Explorer):
            model.engine_threads_note = ex.threads_note()
        if native is not None:
            try:
                for f in sr.found:
                    if f.trace is not None:
                        f.trace = native.decode_trace(f.trace)
            except BaseException:
                _close(ex)
                raise
    except SpillError as e:        # the spill directory: unwritable, the disk full
        raise PcclError(str(e), filename=e.option, template=True) from None
    except RuntimeError as e:
        from pccl.model.native import ID_CLASH, NativeOverflow
        if isinstance(e, NativeOverflow):
            # a value the vectors cannot hold: the Python engine, from the start
            model.engine_used, model.engine_reason = ("python", str(e) if str(e) == ID_CLASH else
                "the native search met an int beyond 64 bits, a division by zero or "
                "an undefined value")
            from pccl.search import liveness as L
            plan.labels, plan.native = (set() if plan.one else None), None
            model.engine_threads = 1
            plan.rec = L.make_recorder(model, plan.o.timelock, plan.o.stall, frozen=(
                _frozen_sigs(model) if _frozen_recorded(plan.o, plan.one) else None))
            if plan.one:
                # a checkpoint of the native search cannot be continued here: the
                # Python search writes its own (into the checkpoint directory, if any)
                ex = Explorer(model, plan.sopts, recorder=plan.rec, on_runaway=plan.on_runaway,
                              labels=plan.labels,
                              checkpoint=_checkpointer(model, plan.o.replace(
                                  checkpoint=plan.o.checkpoint or plan.o.resume, resume=None)))
            else:       # --workers N: the Python engine's workers
                ex = _parallel_searcher(plan, model)
            sr = _kept(ex).run()
        else:
            from pccl.search.parallel import RayUnavailable
            if isinstance(e, RayUnavailable):       # Ray could not be started or reached
                raise _ray_error(e) from None
            raise
    finally:
        model.lock_deadlocks = saved
    return ex, sr


def _analyse(plan: _SearchPlan, ex: Any, sr: SearchResult):
    """Step of :func:`explore_model`: expand merged labels in the traces
    found; with a recorder, the graph analysis (time-locks, stalls, temporal
    properties), whose findings join the search's.  Returns the analysis
    (None without a recorder)."""
    model = plan.model
    if getattr(model, "merger", None) is not None:
        from pccl.model.reduce import expand_trace
        for f in sr.found:
            f.trace = expand_trace(model, f.trace, f.violation)
    if plan.rec is None:
        return None
    import time as _time
    from pccl.search import liveness as L
    t0 = _time.perf_counter()
    frozen = _frozen_beside(plan, ex, sr)
    lv = L.analyse(model, ex, sr, plan.rec, timelock=plan.o.timelock,
                   find_all=plan.o.find_all, stall=plan.o.stall)
    L.attach_traces(model, ex if plan.native is None else plan.native.decoding(ex), lv)
    # the figures include the analysis of the graph
    sr.stats.seconds += _time.perf_counter() - t0
    sr.stats.peak_memory = max(sr.stats.peak_memory, ex.peak_memory())
    if lv.found and sr.status != "interrupted":
        sr.found.extend(lv.found)
        sr.status = "violation"
    _frozen_check(plan, ex, sr, lv, frozen)
    return lv


def _frozen_over_graph(plan: _SearchPlan, ex: Any, sr: SearchResult) -> bool:
    """Whether :func:`_frozen_check` decides over the search's own graph
    (recorded whole, by one explorer, every state in its table)."""
    from pccl.model import frozen as F
    return F.recorded(plan.rec) and isinstance(ex, Explorer) and ex.table.n == sr.stats.states


def _frozen_beside(plan: _SearchPlan, ex: Any, sr: SearchResult) -> Optional[Callable]:
    """With more than one thread for the search (``--workers N`` on the
    level kernel): the frozen-team check's decision started on a thread of
    its own, beside the time-lock and stall checks (which :func:`_analyse`
    runs meanwhile on the graph's same arrays, only read by both), so that
    the analysis after the search is not one thread's alone.  Returns the
    function that waits for its answer (re-raising its error), or None
    (one thread, or the check will not decide over the graph).  Started
    only where the check may run (stall check on, the search exhaustive and
    clean so far); its answer is dropped when the other checks find a
    violation (the check then does not run), as one thread would not have
    made it."""
    if getattr(ex, "threads", 1) <= 1 or not plan.o.stall or sr.status != "exhaustive" or sr.found \
            or not _frozen_over_graph(plan, ex, sr):
        return None
    import threading
    from pccl.model import frozen as F
    out: dict = {}
    kernel = getattr(ex.model, "reach_back", None)

    def decide() -> None:
        try:
            out["found"] = F.decide_recorded(plan.model, plan.rec, ex.table.n, kernel)
        except BaseException as e:      # handed to the waiting thread
            out["error"] = e
    th = threading.Thread(target=decide, name="pccl-frozen-check", daemon=True)
    th.start()

    def answer():
        th.join()
        if "error" in out:
            raise out["error"]
        return out["found"]
    return answer


def _frozen_check(plan: _SearchPlan, ex: Any, sr: SearchResult, lv,
                  decided: Optional[Callable] = None) -> None:
    """Step of :func:`_analyse`: on a clean exhaustive search with the
    stall check on, is the team frozen somewhere (:mod:`pccl.model.frozen`)?
    Decided over the search's own graph where it recorded what the check
    reads, else by exploring again.  A frozen team joins the violations; a
    check that cannot run says why in a note."""
    if not plan.o.stall or sr.status != "exhaustive" or sr.found:
        return
    import time as _time
    from pccl.model import frozen as F
    if _frozen_over_graph(plan, ex, sr):
        t0 = _time.perf_counter()
        dec = ex if plan.native is None else plan.native.decoding(ex)
        fr = F.check_recorded(plan.model, plan.rec, ex.table.n, dec.replay_chain, ex.table,
                              getattr(ex.model, "reach_back", None), decided)
        sr.stats.seconds += _time.perf_counter() - t0
        _frozen_found(sr, fr)
        return
    if sr.stats.states > F.LIMIT:
        lv.notes.append(f"frozen teams not checked: {sr.stats.states:,} states, more than the "
                        f"{F.LIMIT:,} the check explores again"
                        + (" (in Python)" if plan.native is None else ""))
        return
    t0 = _time.perf_counter()
    fr = F.check(plan.model, F.LIMIT, plan.native)
    sr.stats.seconds += _time.perf_counter() - t0
    if not fr.ran:
        lv.notes.append(f"frozen teams not checked: {fr.reason}")
    else:
        _frozen_found(sr, fr)


def _frozen_found(sr: SearchResult, fr) -> None:
    """A frozen team the check found joins the violations."""
    if fr.violation is not None:
        cx = Counterexample(fr.violation, -1, len(fr.trace))
        cx.trace = fr.trace
        sr.found.append(cx)
        sr.status = "violation"


def _shorten(plan: _SearchPlan, sr: SearchResult) -> None:
    """Step of :func:`explore_model`: under reductions, each counterexample
    found is shortened against the unreduced semantics
    (:mod:`pccl.model.shorten`); the verdict stays, only the path shown may
    change, and ``cx.shortening`` says what happened.  Not for ``fastest``
    (its path is the fastest, not the shortest)."""
    from pccl.model import shorten as S
    model, o = plan.model, plan.o
    # (a frozen team's path is the frozen check's own, on the reduced graph:
    # not shortened yet)
    found = [cx for cx in sr.found if cx.trace is not None and len(cx.trace)
             and cx.violation.kind != "frozen"]
    if not found or not model.reduction.on or o.fastest or sr.status == "interrupted":
        return
    for cx in found:
        cx.shortening = S.Shortening("off" if not o.shorten else "not-shown", len(cx.trace),
                                     None, cx.cycle_start)
    if not o.shorten:
        return
    try:
        state = [cx for cx in found if cx.violation.kind in S.STATE_KINDS and cx.cycle_start is None]
        if state:
            _shorten_states(plan, state)
        graph = [cx for cx in found if cx not in state]
        if graph:
            _shorten_graph(plan, graph, sr)
    except KeyboardInterrupt:
        for cx in found:
            if cx.shortening.status == "not-shown" and cx.shortening.reason is None:
                cx.shortening = dataclasses.replace(cx.shortening, reason="interrupted")


def _shorten_engine(plan: _SearchPlan, recorder: bool) -> tuple:
    """``(budget, engine)`` of the searches without the reductions that
    shorten one verdict's counterexamples: native, within
    :data:`~pccl.model.shorten.MAX_STATES_NATIVE` states, where the native
    engine can serve the unreduced model (whichever engine ran the reduced
    search: the path shown does not depend on the engine), else Python
    within :data:`~pccl.model.shorten.MAX_STATES`."""
    from pccl.model import native as NV
    from pccl.model import shorten as S
    from pccl.model.reduce import unreduced
    if NV.unsupported(Reduced(unreduced(plan.model), "none"), recorder=recorder) is None:
        return S.MAX_STATES_NATIVE, "auto"
    return S.MAX_STATES, "python"


def _shorten_reason(budget: int, spelling: Spelling, sub: Optional[ExploreResult] = None) -> str:
    if sub is not None and sub.status != "bounded" and sub.status not in ("violation", "exhaustive"):
        return f"the search without the reductions ended {sub.status}"
    return (f"the search without the reductions stopped at its budget of {budget:,} "
            f"states ({spell('{reduce=none}', spelling)} searches them all)")


def _unreduced_search(plan: _SearchPlan, budget: int, **changes) -> ExploreResult:
    """A search of the same model without the reductions, every violation
    reported (``find_all``), within ``budget`` states, in this process;
    ``changes`` to the options.  The model's engine fields are restored."""
    from pccl.model.reduce import unreduced
    inner = unreduced(plan.model)
    keep = {a: getattr(inner, a) for a in
            ("engine_used", "engine_reason", "engine_threads", "engine_asked", "lock_deadlocks")
            if hasattr(inner, a)}
    try:
        return explore_model(Reduced(inner, "none"), options=plan.o.replace(**{
            "reduce": "none", "find_all": True, "max_states": budget, "depth": None,
            "workers": 1, "ray": None, "coverage": False, "progress": None, "checkpoint": None,
            "resume": None, "spill": None, "shorten": False, "fastest": False, **changes}),
            spelling=plan.spelling)
    finally:
        for a, v in keep.items():
            setattr(inner, a, v)


def _finished(sub: ExploreResult, allowed=(Bound.MODEL,)) -> bool:
    """Whether the search ``sub`` saw everything it was asked to (bounds
    but ``allowed`` cut it)."""
    return (sub.status in ("violation", "exhaustive", "bounded")
            and not set(sub.bounds) - set(allowed))


def _shorten_states(plan: _SearchPlan, found: list) -> None:
    """Step of :func:`_shorten`: the violations of one state (invariants,
    assertions, stuck agents, deadlocks, collisions).  A search without the
    reductions to the depth of the longest path found reports each
    violation's first instance (breadth-first: a shortest path); a violation
    whose first instance is another (another agent's) is looked for by
    :func:`pccl.model.shorten.shortest_paths`."""
    from pccl.model import shorten as S
    from pccl.model.reduce import unreduced
    o, (budget, engine) = plan.o, _shorten_engine(plan, bool(plan.model.temporal))
    longest = max(len(cx.trace) for cx in found)
    sub = _unreduced_search(plan, budget, depth=longest - 1, timelock=False, stall=False,
                            engine=engine)
    finished = _finished(sub, (Bound.MODEL, Bound.DEPTH))
    seen = {c.violation.identity for c in sub.counterexamples}
    rest = []
    for cx in found:
        other = next((c for c in sub.counterexamples if c.violation == cx.violation
                      and c.trace is not None), None)
        if other is not None and len(other.trace) < len(cx.trace):
            _shortened(cx, other.trace)
        elif not finished:
            cx.shortening = dataclasses.replace(
                cx.shortening, reason=_shorten_reason(budget, plan.spelling, sub))
        elif cx.violation.identity in seen and other is None:
            rest.append(cx)         # found first for another agent: look for this one
        else:
            cx.shortening = dataclasses.replace(cx.shortening, status="confirmed")
    if not rest:
        return
    inner = unreduced(plan.model)
    saved, inner.lock_deadlocks = inner.lock_deadlocks, o.deadlock
    try:
        paths, complete = S.shortest_paths(inner, [(cx.violation, len(cx.trace)) for cx in rest],
                                           deadlock=o.deadlock, find_all=o.find_all)
    finally:
        inner.lock_deadlocks = saved
    for cx, path in zip(rest, paths):
        if path is not None:
            _shortened(cx, path)
        elif complete:
            cx.shortening = dataclasses.replace(cx.shortening, status="confirmed")
        else:
            cx.shortening = dataclasses.replace(
                cx.shortening, reason=_shorten_reason(S.MAX_STATES, plan.spelling))


def _shortened(cx: Counterexample, trace: Trace, cycle_start: Optional[int] = None,
               violation: Any = None) -> None:
    cx.trace, cx.cycle_start, cx.chain = trace, cycle_start, None
    if violation is not None:
        cx.violation = violation
    cx.shortening = dataclasses.replace(cx.shortening, status="shortened")


def _shorten_graph(plan: _SearchPlan, found: list, sr: SearchResult) -> None:
    """Step of :func:`_shorten`: time-locks, stalls and temporal properties
    are decided on the whole graph, so their paths are those of a whole
    search without the reductions (within the budget) that reports the
    same violation (kind and property: the message of a stall or a
    time-lock describes the state its path ends in, and is that path's)."""
    from pccl.model import shorten as S
    budget, engine = _shorten_engine(plan, True)
    if plan.model.temporal:
        # a temporal verdict's lasso is shortened within the budget it had
        # when temporal properties ran on the Python engine alone: the
        # unreduced graph of a search the reductions make small is often
        # far larger, and a search stopped by its budget shortens nothing
        # (race_robust, 3 robots: 6.8 M states; 1 M cost 2 of 3.4 CPU s)
        budget = min(budget, S.MAX_STATES)
    # the reduced search's states stand each for one or more real states
    # (distinct numbers, distinct ones): more of them than the budget, and
    # the search without the reductions cannot finish within it (issue 46:
    # on Fischer, 3 agents, it cost half the temporal search's time)
    sub = None if sr.stats.states > budget else _unreduced_search(plan, budget, engine=engine)
    if sub is None or not _finished(sub):
        for cx in found:
            cx.shortening = dataclasses.replace(
                cx.shortening, reason=_shorten_reason(budget, plan.spelling, sub))
        return
    for cx in found:
        other = next((c for c in sub.counterexamples if c.trace is not None and (
            c.violation == cx.violation or (cx.violation.kind in ("stall", "timelock")
                                            and c.violation.identity == cx.violation.identity))),
                     None)
        if other is None:
            cx.shortening = dataclasses.replace(
                cx.shortening, reason="the search without the reductions does not report it")
        elif len(other.trace) < len(cx.trace):
            _shortened(cx, other.trace, other.cycle_start, other.violation)
            cx.depth = other.depth          # the graph checks' depth: the path's steps
        else:
            cx.shortening = dataclasses.replace(cx.shortening, status="confirmed")


def _verdict(sr: SearchResult, bound_names: list, max_memory: Optional[int],
             spelling: Spelling, find_all: bool = False, complete: bool = False) -> tuple:
    """Step of :func:`explore_model`: the one-line verdict (without the
    blackbox) and the exit status; ``bound_names`` are spelt already, the
    other options it names by ``spelling``.  With ``find_all`` a violation's
    verdict says whether the search went on to the end (``complete``)."""
    n = len(sr.found)
    if sr.status == "violation":
        verdict = f"violation: {sr.found[0].violation.message}"
        if n > 1:
            verdict += f" (and {n - 1} more distinct violation(s))"
        if find_all:
            verdict += (" — search complete: every reachable state explored" if complete else
                        " — not exhaustive: stopped by " + ", ".join(bound_names) if bound_names
                        else " — not exhaustive")
        return verdict, 1
    if sr.status == "exhaustive":
        return "no violation — exhaustive", 0
    if sr.status == "bounded":
        return "no violation within bounds — stopped by " + ", ".join(bound_names), 0
    if sr.status == OUT_OF_MEMORY:
        size = format_size(max_memory) if max_memory else "none"
        verdict = spell(f"out of memory — the process could not allocate more after "
                        f"{sr.stats.states:,} states (not exhaustive; a limit such as ulimit -v is "
                        f"below {{max_memory={size}}}: give a smaller {{max_memory}} to stop as "
                        f"a bound)", spelling)
        if n:
            verdict += (f"; {n} distinct violation(s) found so far, first: "
                        f"{sr.found[0].violation.message}")
        return verdict, 1 if n else 2
    if n:
        return (f"interrupted — {n} distinct violation(s) found in the states explored "
                f"so far (not exhaustive); first: {sr.found[0].violation.message}"), 1
    return "interrupted — no violation found in the states explored so far (not exhaustive)", 130


def _witnesses(model, lv) -> list:
    """Step of :func:`explore_model`: the witnesses of the reachable
    properties, as :attr:`ExploreResult.witnesses`."""
    out = []
    for p, cx in (lv.witnesses if lv is not None else ()):
        steps = tuple(StepView.of(model, st.number, st.label, st.before, st.after)
                      for st in cx.trace.steps)
        out.append({"name": p.name, "text": p.text, "depth": len(cx.trace),
                    "trace": steps, "state": StateView.of(model, cx.trace.last),
                    "initial": StateView.of(model, cx.trace.initial),
                    "_trace": cx.trace})
    return out


def _search_notes(ex: Any) -> list:
    """Step of :func:`explore_model`: the searcher's notes (checkpoints
    written or resumed; with Ray, each actor's node)."""
    notes: list = []
    ck = getattr(ex, "checkpoint", None)
    if ck is not None:
        notes.extend(_checkpoint_notes(ck))
    if getattr(ex, "spiller", None) is not None:
        notes.append(ex.spiller.note())
    transport: Any = getattr(ex, "transport", None)
    if transport is not None and getattr(transport, "placement", None):   # --ray: each actor's node
        notes.append(transport.placement_note())
    return notes


def _assemble(plan: _SearchPlan, ex: Any, sr: SearchResult, lv, complete: bool) -> ExploreResult:
    """Step of :func:`explore_model`: the :class:`ExploreResult`, its verdict
    and its ``checked`` section."""
    model, o, max_memory, spelling = plan.model, plan.o, plan.max_memory, plan.spelling
    bb = model.blackbox.name
    bound_names = [bound_label(b, model, depth=o.depth, max_states=o.max_states,
                               max_memory=max_memory, spelling=spelling) for b in sr.bounds_hit]
    violations = [violation_data(model, f) for f in sr.found]
    verdict, code = _verdict(sr, bound_names, max_memory, spelling, o.find_all, complete)
    uncovered = not_covered_note(model, spelling)
    status = sr.status
    if uncovered and status == "exhaustive":
        # exhaustive for nondet, not for the physical blackboxes it stands
        # for: said, and exiting, as a bounded search
        verdict, status = f"no violation — {uncovered}", "bounded"
    verdict += f" [blackbox {bb}]"
    note = fixed_timing_note(model, spelling) if not violations else None
    if note:
        verdict += f" ({note})"
    if sr.status in ("exhaustive", "bounded") and not violations:
        from pccl.model.timing import lockstep_note
        rounds = lockstep_note(model)
        if rounds:
            verdict += f" ({spell(rounds, spelling)})"
    first = violations[0] if violations else None
    res = ExploreResult(status, verdict, bb, code, sr.stats, list(sr.bounds_hit), first,
                        violations, first.trace if first else (),
                        first.state if first else None,
                        sr.collision_probability, model, sr, list(sr.found),
                        plan.cov.report() if plan.cov is not None else None,
                        _witnesses(model, lv), list(lv.holds) if lv else [],
                        [spell(n, spelling) for n in (list(lv.notes) if lv else []) + _search_notes(ex)
                         + ([STALL_HINT] if any(v.kind == "stall" for v in violations) else [])]
                        + plan.runaways, o.timelock, o.stall, bound_names, uncovered,
                        # exhaustive for the model, but not for straight/pymunk: not "exhaustive"
                        complete=complete and not (uncovered and status == "bounded"))
    growth = _growth_note(plan, ex, sr)
    if growth:
        res.notes.append(growth)
    from pccl.output.checked import for_explore
    hit = {BOUND_OPTIONS.get(b) for b in sr.bounds_hit}
    configured = [(spelling(name, value), name in hit) for name, value in _bounds_in_force(plan)]
    where = "Ray actors" if o.ray is not None else f"{plan.nworkers} worker processes"
    res.checked = for_explore(
        model, res, o, complete=complete, labels=plan.labels, bounds=tuple(configured),
        labels_reason=None if plan.labels is not None else
        spell(f"the transitions are taken in {where}; use {{workers=1}}", spelling),
        spelling=spelling)
    return res


def _growth_note(plan: _SearchPlan, ex: Any, sr: SearchResult) -> Optional[str]:
    """Step of :func:`_assemble`: for a search a bound stopped (states,
    memory, depth), the variable that keeps growing along
    the path to the deepest state admitted (:mod:`pccl.output.growth`), or None."""
    if sr.status != "bounded" or not (
            set(sr.bounds_hit) & {Bound.MAX_STATES, Bound.MAX_MEMORY, Bound.DEPTH}):
        return None
    table = getattr(ex, "table", None)
    if table is None or not getattr(table, "n", 0) or not hasattr(table, "parent"):
        return None             # (workers keep their parents elsewhere: no hint)
    from pccl.output.growth import growth_note
    try:
        chain, idx = [], table.n - 1
        while idx != -1:
            chain.append(idx)
            idx = table.parent(idx)
        chain.reverse()
        tr = (ex if plan.native is None else plan.native.decoding(ex)).replay_chain(chain)
        return growth_note(plan.model, tr.states, len(chain) - 1)
    except (ReplayError, AttributeError, IndexError, KeyError, TypeError, ValueError):
        return None


#: The note beside a stall: a team whose agents have simply finished their
#: work (no ``exit()``) stalls too.
STALL_HINT = ("a stall is also how a team ends whose agents are simply done: end each "
              "finished agent with `exit()`, or turn the check off with {stall=False}")


def _bounds_in_force(plan: _SearchPlan) -> list:
    """The bounds of the search as ``(option, value)`` (the default memory
    bound as ``80% of RAM``)."""
    o, model, max_memory = plan.o, plan.model, plan.max_memory
    return ([("depth", str(o.depth))] if o.depth is not None else []) + \
        ([("max_states", str(o.max_states))] if o.max_states is not None else []) + \
        ([("max_time", str(model.max_time))] if model.max_time is not None else []) + \
        ([("max_memory", "80% of RAM")] if o.max_memory == "default" else
         [("max_memory", format_size(max_memory))] if max_memory is not None else [])


def _choose_engine(model: Reduced, o: ExploreOptions, recorder: bool, one: bool,
                   spelling: Spelling = api_spelling):
    """The native model for this search (pccl/model/native.py), or None for the
    Python engine; sets ``model.engine_used`` and ``model.engine_reason``
    (why not native, the options it names spelt by ``spelling``) for the header."""
    model.engine_asked = o.engine != "auto"
    model.engine_threads = 1
    if o.engine == "python":
        model.engine_used, model.engine_reason = "python", None
        return None
    from pccl.model import native as NV
    why = None
    if o.engine == "auto" and _resumed_engine(o) == "python":
        # a checkpoint is continued by the engine that wrote it (its states
        # and fingerprints are that engine's); first: the C generator interns
        # k cells in its own order, which the checkpoint's tables must not meet
        why = "{resume}: the checkpoint was written by the Python engine"
    if why is None:
        why = NV.unsupported(model, recorder=recorder, parallel=not one,
                             checkpoint=o.checkpoint is not None or o.resume is not None)
    if why is None and o.ray is not None:
        # --workers N (forked processes) runs natively: the workers inherit the
        # module loaded here; an actor would have to generate and build it again
        why = ("{ray}: the actors run the Python engine (the native module is built where "
               "pccl runs and does not travel to them; {workers} runs it in forked processes)")
    if why is None and not one and (o.checkpoint is not None or o.resume is not None):
        why = ("{checkpoint} and {resume} with several workers save the Python engine's "
               "states (one process saves the native engine's)")
    if why is None and o.coverage:
        why = "{coverage} counts guards in Python"
    if why is None and o.fastest:
        why = "{fastest} orders the search in Python"
    if why is not None:
        if o.engine == "native":
            raise ArgumentError(f"the native engine cannot run this search: {why}",
                                where="{engine}", template=True)
        model.engine_used, model.engine_reason = "python", spell(why, spelling)
        return None
    # said before the compile: a search interrupted while it compiles names
    # the engine that would have run
    model.engine_used, model.engine_reason = "native", None
    # forked workers: ids that every process gives a value alike
    return NV.NativeModel(model, stable_ids=not one)


def _resumed_engine(o: ExploreOptions) -> Optional[str]:
    """The engine that wrote the checkpoint ``o.resume`` ("native" or
    "python"; None without ``resume`` or a readable manifest: the resume
    reports what is wrong)."""
    if o.resume is None:
        return None
    from pccl.search.checkpoint import MANIFEST
    try:
        with open(os.path.join(os.fspath(o.resume), MANIFEST), encoding="utf-8") as f:
            ident = json.load(f).get("identity")
        return str(ident.get("engine", "python"))
    except (OSError, ValueError, AttributeError):
        return None


def _checkpointer(model, o: ExploreOptions, native: Any = None):
    """The :class:`~pccl.search.checkpoint.Checkpointer` of ``--checkpoint`` /
    ``--resume`` (None without them); ``native``: the native model searched
    (its generated source is part of the identity), else the Python engine
    runs, for ``model.engine_reason`` (said when the checkpoint is native's)."""
    if o.checkpoint is None and o.resume is None:
        return None
    from pccl.search.checkpoint import Checkpointer, search_identity
    ident = search_identity(model, o, IDENTITY_OPTIONS)
    if native is not None:
        ident.update(engine="native", native=native.source_hash)
    else:
        ident["engine"] = "python"
    ck = Checkpointer(o.checkpoint if o.checkpoint is not None else o.resume,
                      interval=o.checkpoint_interval, resume=o.resume, identity=ident,
                      note=getattr(o.progress, "note", None))
    if native is None:
        why = getattr(model, "engine_reason", None)
        ck.engine_reason = why if why is not None else \
            ("{engine=python}" if o.engine == "python" else None)
    if o.checkpoint is not None or os.path.isdir(o.resume or ""):
        ck.prepare_dir()
    return ck


def _checkpoint_notes(ck) -> list:
    """What the search did with its checkpoints, for the notes."""
    out = []
    if ck.resumed is not None:
        out.append(f"resumed from {ck.resume_dir} at depth {ck.resumed['depth']}, "
                   f"{ck.resumed['states']:,} states")
    if ck.error is not None:
        out.append(ck.error)
    if ck.written is not None:
        out.append(f"checkpoint written to {ck.dir} at depth {ck.written['depth']}, "
                   f"{ck.written['states']:,} states ({ck.writes} written, "
                   f"{ck.write_seconds:.2f} s)")
    return out


#: The option of each bound that can cut a search.
BOUND_OPTIONS = {Bound.DEPTH: "depth", Bound.MAX_STATES: "max_states", Bound.MODEL: "max_time",
                 Bound.MAX_MEMORY: "max_memory"}


def bound_option(bound: Bound, model, *, depth=None, max_states=None,
                 max_memory=None) -> Optional[tuple]:
    """A bound that cut the search as ``(option, value)`` (``("depth", "10")``;
    None for a bound no option sets)."""
    values = {Bound.DEPTH: depth, Bound.MAX_STATES: max_states, Bound.MODEL: model.max_time,
              Bound.MAX_MEMORY: format_size(max_memory) if bound is Bound.MAX_MEMORY else None}
    name = BOUND_OPTIONS.get(bound)
    return None if name is None else (name, str(values[bound]))


def bound_label(bound: Bound, model, *, depth=None, max_states=None, max_memory=None,
                spelling: Spelling = api_spelling) -> str:
    """A bound that cut the search as ``spelling`` writes it: ``depth=10``
    (the API's keyword), ``--depth 10`` (``pccl explore``)."""
    opt = bound_option(bound, model, depth=depth, max_states=max_states, max_memory=max_memory)
    return str(bound) if opt is None else (spelling(*opt) or str(bound))


def violation_data(model, found: Counterexample) -> Finding:
    """A counterexample as a typed :class:`~pccl.output.results.Finding` (its trace
    rendered step by step; ``.to_json()`` for the JSON)."""
    v = found.violation
    # every counterexample carries its trace, but "unreachable" (a failed
    # reachable P: there is no path to show)
    tr: Optional[Trace] = found.trace
    assert tr is not None or v.kind == "unreachable", "a counterexample carries its trace"
    reduced = bool(getattr(getattr(model, "reduction", None), "on", ()))
    sh = found.shortening
    # merged labels were expanded where the traces were made (explore_model,
    # liveness.attach_traces: reduce.expand_trace), not again here
    steps = () if tr is None else tuple(
        StepView.of(model, st.number, st.label, st.before, st.after) for st in tr.steps)
    return Finding(v.kind, v.name, v.message, v.agent,
                   v.span.line if v.span else None, v.span.column if v.span else None,
                   found.depth,
                   "yes" if not reduced or (sh is not None and sh.shortest) else "under the reductions",
                   steps, None if tr is None else StateView.of(model, tr.last),
                   found.cycle_start, None if tr is None else StateView.of(model, tr.initial),
                   sh)


# ---------------------------------------------------------------------------
# run
# ---------------------------------------------------------------------------

def run(program, **options) -> RunResult:
    """Execute ``program`` once.  ``options`` are the fields of
    :class:`~pccl.model.options.RunOptions`, spelt like ``pccl run``'s flags
    (``seed``, ``max_steps``, ``max_time``, ``invariants``, ``stall_steps``,
    ...) plus ``record_trace``.  ``stall_steps``: stop (status ``stalled``,
    exit status 1) when no variable, position or flag changed for this many
    time steps while an agent still runs; 0 turns that off.  ``max_memory``:
    as explore's, bytes of peak resident memory at which the run stops as
    bounded (``"default"``: 80 % of physical memory; ``None``: no limit)."""
    V.program("run", program, options.get("source", False))
    opts = RunOptions.from_api("run", options)
    rng = random.Random(opts.seed)
    model = _api_model("run", program, opts, rng=rng)
    res = _run(model, seed=opts.seed, max_steps=opts.max_steps,
               record_trace=opts.record_trace, rng=rng, stall_steps=opts.stall_steps,
               max_memory=memory_bound(opts.max_memory))
    res.model = model
    return res


# ---------------------------------------------------------------------------
# check
# ---------------------------------------------------------------------------

def check(program, *, world=None, source: bool = False, lang=None):
    """Parse and statically check ``program`` (``pccl check``); the names of
    ``world``'s functions may be called; ``lang`` (``"pccl"``, ``"koord"``)
    the language it is read as (None: a file's suffix decides, text is
    PCCL).  Returns the :class:`~pccl.lang.checker.CheckedProgram`."""
    from pccl.lang.checker import check_program
    V.program("check", program, source)
    V.lang("check", lang)
    V.world("check", world)
    prog = load_program(program, source=source, lang=lang)
    w = load_world_arg(world)
    names = frozenset(dict(w.functions).keys()) if w is not None else frozenset()
    return check_program(prog, functions=names)
