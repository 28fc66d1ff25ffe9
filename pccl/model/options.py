"""The options of ``run`` and ``explore``: one object shared by the CLI and the API.

``pccl explore --max-states 100 --set k=2`` and
``pccl.api.explore(..., max_states=100, overrides={"k": "2"})`` build the same
:class:`ExploreOptions`; ``pccl run`` and ``pccl.api.run`` the same
:class:`RunOptions`.  A field is spelt like its command-line flag
(``max_states`` is ``--max-states``) except where ``pccl.cli.FLAGS`` says
otherwise, and a test checks that every field is a flag of its command and
every flag of the command is a field or a presentation option
(:data:`PRESENTATION`: how the result is shown, not what is computed).
Fields in :data:`API_ONLY` are hooks a command line cannot express
(callables, pre-built objects).

Checks run once, in :meth:`~ModelOptions.check`, with messages that name the
option as the API spells it (``max_states must be an integer >= 1, got 0``);
the CLI's own parameter types reject the same values earlier with the flag's
name.  A text below the CLI that names an option writes a placeholder
(``{workers=1}``, :func:`pccl.lang.errors.spell`): the API spells it as its
keyword (:func:`api_spelling`), the CLI as its flag; no module here writes a flag.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from typing import Any, Optional, Union
from collections.abc import Callable, Mapping

from pccl.model import validate as V
from pccl.lang.world import MAX_AGENTS
from pccl.lang.errors import ArgumentError, OptionError, Spelling, keyword_spelling, spell

#: Fields a command line cannot express: callables, objects, source text.
API_ONLY = frozenset({"functions", "rand_policy", "source", "progress", "progress_interval",
                      "record_trace"})

#: The version of the options' JSON form (:meth:`CommonOptions.to_dict`).
OPTIONS_VERSION = 1

#: Command-line parameters that choose how a result is shown, per command.
PRESENTATION = {
    "run": frozenset({"trace", "fmt", "plot", "html", "trace_out", "view", "full", "exit_codes",
                      "watch"}),
    "explore": frozenset({"fmt", "plot", "html", "progress", "progress_interval", "trace_out",
                          "view", "full", "exit_codes", "watch"}),
}


@dataclass(frozen=True)
class CommonOptions:
    """What every command's model needs: the program's world, blackbox, team
    and timing, and the properties checked on it."""
    agents: Optional[int] = None
    world: Any = None                       # a path or a World
    blackbox: Any = None                    # a name, module:attribute, or an object
    delta: Union[int, float] = 1
    n0: int = 1
    rates: Mapping[int, int] = field(default_factory=dict)
    events: str = "any"
    #: the execution model: "pccl" (spec section 4), "koord" (Koord's round
    #: semantics, spec section 14; Koord programs only), None: the program's
    #: language decides (pccl/model/koord.py)
    semantics: Optional[str] = None
    #: Koord's SkipEvent: a robot may skip its round although an event is
    #: enabled (semantics "koord" only)
    skip_events: bool = False
    collisions: bool = False
    overrides: Mapping[str, str] = field(default_factory=dict)
    invariants: tuple = ()
    #: property forms of spec section 9 (docs/temporal.md)
    properties: tuple = ()
    max_time: Optional[Union[int, float]] = None
    functions: Optional[Mapping[str, Any]] = None
    rand_policy: Optional[Callable] = None
    source: bool = False
    #: the language the program is read as: "pccl", "koord" (docs/koord.md),
    #: None: a file's suffix decides (``.koord``/``.krd`` Koord), text is PCCL
    lang: Optional[str] = None

    @classmethod
    def from_api(cls, func: str, kwargs: Mapping[str, Any]):
        """Options from keyword arguments of ``pccl.api.FUNC``; an unknown
        keyword is an error that lists the known ones."""
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(kwargs) - set(names))
        if unknown:
            raise ArgumentError(
                f"unknown option{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; "
                f"options are {', '.join(names)}", filename=f"pccl.api.{func}")
        opts = cls(**kwargs)
        opts.check(func)
        return opts

    @classmethod
    def from_cli(cls, params: Mapping[str, Any]):
        """Options from a click command's parameters (presentation ones are
        ignored).  Repeated flags arrive as tuples of pairs."""
        names = {f.name for f in dataclasses.fields(cls)} - API_ONLY
        kw = {k: v for k, v in params.items() if k in names}
        for k in MAPPING_OPTIONS:
            if k in kw:
                kw[k] = dict(kw[k])
        for k in LIST_OPTIONS:
            if k in kw:
                kw[k] = tuple(kw[k])
        for k in TIME_OPTIONS:
            if kw.get(k) is not None:
                kw[k] = integral(kw[k])
        return cls(**kw)

    def replace(self, **changes):
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """The options as JSON data, versioned (:data:`OPTIONS_VERSION`): a
        trace file's ``config["options"]``.  What a command line cannot
        express (:data:`API_ONLY`: callables, objects) is left out; a
        blackbox object is given by its name, a world object as None (the
        trace records the world's file)."""
        out: dict[str, Any] = {"version": OPTIONS_VERSION}
        for f in dataclasses.fields(self):
            if f.name in API_ONLY:
                continue
            v = getattr(self, f.name)
            if f.name == "world":
                v = os.fspath(v) if isinstance(v, (str, os.PathLike)) else None
            elif f.name == "blackbox" and v is not None and not isinstance(v, str):
                v = getattr(v, "name", None)
            elif f.name == "rates":
                v = {str(a): r for a, r in dict(v or {}).items()}
            elif isinstance(v, Mapping):
                v = dict(v)
            elif isinstance(v, (tuple, list)):
                v = list(v)
            elif isinstance(v, os.PathLike):
                v = os.fspath(v)
            out[f.name] = v
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]):
        """Options from :meth:`to_dict`'s form.  The fields of other option
        classes (a search's options, read for a model) are skipped; a name
        no options class has, or another version, is a :class:`ValueError`."""
        if not isinstance(data, Mapping):
            raise ValueError(f"options must be an object, got {type(data).__name__}")
        if data.get("version") != OPTIONS_VERSION:
            raise ValueError(f"options version {data.get('version')!r} is not "
                             f"{OPTIONS_VERSION}, the one this pccl reads")
        known = {f.name for c in (ExploreOptions, RunOptions) for f in dataclasses.fields(c)}
        unknown = sorted(set(data) - known - {"version"})
        if unknown:
            raise ValueError(f"unknown option{'s' if len(unknown) > 1 else ''} "
                             f"{', '.join(unknown)}")
        mine = {f.name for f in dataclasses.fields(cls)} - API_ONLY
        kw = {k: v for k, v in data.items() if k in mine}
        try:
            for k in MAPPING_OPTIONS:
                if k in kw:     # JSON keys are strings: the agents of rates are ints
                    kw[k] = {(int(a) if k == "rates" else a): r for a, r in dict(kw[k] or {}).items()}
        except (TypeError, ValueError) as e:
            raise ValueError(f"{' and '.join(MAPPING_OPTIONS)} must be objects: {e}") from None
        for k in LIST_OPTIONS:
            if k in kw:
                kw[k] = tuple(kw[k] or ())
        return cls(**kw)

    def check(self, func: str) -> None:
        """Raise :class:`ArgumentError` naming the first bad option."""
        V.boolean(func, "source", self.source)
        V.lang(func, self.lang)
        V.world(func, self.world)
        V.blackbox(func, self.blackbox)
        V.integer(func, "agents", self.agents, minimum=1, optional=True)
        V.overrides(func, self.overrides)
        raw = {k: getattr(self, k, None) for k in MODEL_OPTIONS}
        V.model_options(func, {k: v for k, v in raw.items()
                               if v is not None or k in ("max_time", "abstract_time")},
                        MODEL_OPTIONS)


#: The options that map keys to values (``--rate 1=2``, ``--set k=2``): the
#: fields whose default is an empty dict (derived).
MAPPING_OPTIONS = tuple(f.name for f in dataclasses.fields(CommonOptions) if f.default_factory is dict)
#: The options that list texts (``--invariant``, ``--property``): the fields
#: whose default is the empty tuple (derived).
LIST_OPTIONS = tuple(f.name for f in dataclasses.fields(CommonOptions) if f.default == ())
#: The options that are times (written back as the user wrote them,
#: :func:`integral`): the common fields typed ``Union[int, float]`` (derived).
TIME_OPTIONS = tuple(f.name for f in dataclasses.fields(CommonOptions)
                     if "Union[int, float]" in str(f.type))


@dataclass(frozen=True)
class ModelOptions(CommonOptions):
    """A model to explore (:func:`pccl.api.make_model`): the common options,
    time abstraction (None: on when sound) and the reductions."""
    abstract_time: Optional[bool] = None
    reduce: Any = "auto"


#: Model options with checks of their own in :meth:`CommonOptions.check` (the
#: source flag, the language, the world, the blackbox, the team size, the overrides).
CHECKED_ALONE = frozenset({"source", "lang", "world", "blackbox", "agents", "overrides"})
#: The model options :func:`pccl.model.validate.model_options` checks: the
#: fields of :class:`ModelOptions` but :data:`CHECKED_ALONE` (derived, so a new
#: model option cannot be missing).
def model_option_names(cls: Optional[type] = None) -> tuple:
    """The fields of ``cls`` (:class:`ModelOptions`) that :func:`pccl.model.validate.model_options` checks."""
    return tuple(f.name for f in dataclasses.fields(cls or ModelOptions) if f.name not in CHECKED_ALONE)


MODEL_OPTIONS = model_option_names()


@dataclass(frozen=True)
class ExploreOptions(ModelOptions):
    """``pccl explore`` / :func:`pccl.api.explore`: the model's options and
    the search's bounds and modes."""
    depth: Optional[int] = None
    max_states: Optional[int] = None
    max_memory: Any = "default"             # bytes, None (no limit) or "default"
    deadlock: bool = True
    find_all: bool = False
    exact: bool = False
    workers: Union[int, str] = 1
    ray: Optional[str] = None               # None, "local" or a Ray address
    coverage: bool = False
    progress_interval: float = 0.5
    progress: Optional[Callable] = None
    timelock: bool = True                   # report time-locks (docs/temporal.md)
    stall: bool = True                      # report stalls (docs/temporal.md)
    fastest: bool = False                   # order the search on global time
    #: under reductions, search the unreduced semantics for a shorter path to
    #: each violation found before showing it (pccl/model/shorten.py)
    shorten: bool = True
    #: the successor engine: auto (native where it can serve), native, python
    engine: str = "auto"
    #: write checkpoints into this directory (pccl/search/checkpoint.py), every
    #: checkpoint_interval seconds (0: every level) and when interrupted
    checkpoint: Optional[str] = None
    checkpoint_interval: Union[int, float] = 1800
    #: resume the search from the checkpoint in this directory (and keep
    #: writing checkpoints there unless checkpoint names another)
    resume: Optional[str] = None
    #: when the search's memory nears max_memory, move the visited set and
    #: the frontier to files under this directory instead of stopping
    #: (pccl/search/spill.py)
    spill: Optional[str] = None

    @classmethod
    def from_cli(cls, params: Mapping[str, Any]):
        opts = super().from_cli(params)
        if opts.max_memory is None:
            opts = opts.replace(max_memory="default")
        if opts.workers is None:        # --workers unset: 1, or with --ray one per cluster CPU
            opts = opts.replace(workers="auto" if opts.ray is not None else 1)
        return opts

    def check(self, func: str) -> None:
        super().check(func)
        V.search_args(func, depth=self.depth, max_states=self.max_states,
                      deadlock=self.deadlock, find_all=self.find_all, exact=self.exact,
                      progress=self.progress, max_memory=self.max_memory)
        V.number(func, "progress_interval", self.progress_interval, positive=True)
        V.boolean(func, "coverage", self.coverage)
        V.boolean(func, "timelock", self.timelock)
        V.boolean(func, "stall", self.stall)
        V.boolean(func, "fastest", self.fastest)
        V.boolean(func, "shorten", self.shorten)
        if self.engine not in ENGINES:
            raise ArgumentError(f"engine must be one of {', '.join(ENGINES)}, got "
                                f"{self.engine!r}", filename=f"pccl.api.{func}")
        w = self.workers
        if w != "auto" and (not isinstance(w, int) or isinstance(w, bool) or w < 1):
            raise ArgumentError(f"workers must be an integer >= 1 or 'auto', got {w!r}",
                                filename=f"pccl.api.{func}")
        r = self.ray
        if r is not None and (not isinstance(r, str) or not r.strip()):
            raise ArgumentError(f"ray must be None, 'local' or a Ray address such as "
                                f"'HOST:PORT', got {r!r}", filename=f"pccl.api.{func}")
        for name in ("checkpoint", "resume", "spill"):
            v = getattr(self, name)
            if v is not None and (not isinstance(v, (str, os.PathLike)) or not os.fspath(v)):
                raise ArgumentError(f"{name} must be a directory path, got {v!r}",
                                    filename=f"pccl.api.{func}")
        V.number(func, "checkpoint_interval", self.checkpoint_interval, minimum=0)
        c = conflict(self)
        if c is not None:
            raise ArgumentError(c.message(api_spelling), filename=f"pccl.api.{func}")


    def search_options(self, max_memory: Optional[int] = None):
        """The search's options (:class:`pccl.search.explorer.SearchOptions`),
        ``max_memory`` resolved to bytes by the caller."""
        from pccl.search.explorer import SearchOptions
        return SearchOptions(max_depth=self.depth, max_states=self.max_states,
                             deadlock=self.deadlock, find_all=self.find_all, exact=self.exact,
                             progress=self.progress, progress_interval=self.progress_interval,
                             max_memory=max_memory, spill=self.spill)


#: Search options a resumed search may change (pccl/search/checkpoint.py): the
#: resources (memory, workers, Ray), the engine, progress and where the
#: checkpoints go; the hooks a checkpoint cannot hold (API-only); and the world,
#: identified by its file's hash instead.
NOT_IDENTITY = frozenset({"world", "max_memory", "spill", "workers", "ray", "engine", "progress", "shorten",
                          "progress_interval", "checkpoint", "checkpoint_interval", "resume"}) | API_ONLY
#: The options that define a search, in the order a checkpoint's mismatch is
#: reported: a resumed search must be the same search (derived from
#: :class:`ExploreOptions`, so a new option is part of the identity unless
#: :data:`NOT_IDENTITY` says otherwise).
def identity_option_names(cls: Optional[type] = None) -> tuple:
    """The fields of ``cls`` (:class:`ExploreOptions`) that define a search."""
    return tuple(f.name for f in dataclasses.fields(cls or ExploreOptions) if f.name not in NOT_IDENTITY)


IDENTITY_OPTIONS = identity_option_names()


@dataclass(frozen=True)
class Conflict:
    """Search options that do not go together.  ``option`` is the one the
    error is reported at; ``text`` names options as placeholders, spelt by
    the caller (:meth:`message`): ``{fastest}`` is the option itself,
    ``{workers=1}`` the option with that value.  The API spells them
    ``fastest``/``workers=1`` (:func:`api_spelling`), the command line as
    its flags."""
    option: str
    text: str

    def message(self, spelling: Spelling) -> str:
        return spell(self.text, spelling)


def option_names() -> frozenset:
    """Every option of ``run`` and ``explore``: the fields of the options dataclasses."""
    return frozenset(f.name for c in (ExploreOptions, RunOptions) for f in dataclasses.fields(c))


def api_spelling(name: str, value: Optional[str]) -> Optional[str]:
    """An option as the API's keyword (``workers=1``, ``rates={1: 2}``:
    :func:`~pccl.lang.errors.keyword_spelling`); None for a name that is no
    option (the text is left as written)."""
    return keyword_spelling(name, value) if name in OPTION_NAMES else None


def conflict(o: "ExploreOptions") -> Optional[Conflict]:
    """The first search options of ``o`` that do not go together (None: they
    do): every cross-option check of a search, for the API and the CLI."""
    w, r = o.workers, o.ray
    if (r is not None or (w != 1 and w != "auto")) and (o.exact or o.coverage):
        return Conflict("workers", f"{{{'exact' if o.exact else 'coverage'}=True}} runs in one "
                                   "process: use {workers=1} without {ray}")
    return spill_conflict(o) or checkpoint_conflict(o)


def spill_conflict(o: "ExploreOptions") -> Optional[Conflict]:
    """Why ``o`` cannot spill to disk (None: it can, or does not ask to)."""
    if o.spill is None:
        return None
    if o.ray is not None:
        return Conflict("spill", "{spill} runs on this machine's processes: use {workers=N} "
                                 "without {ray} (Ray's actors may run on nodes that do not "
                                 "see the directory)")
    for name, why in (("exact", "it stores fingerprints"), ("fastest", "not yet"),
                      ("checkpoint", "not yet"), ("resume", "not yet")):
        v = getattr(o, name)
        if v is not None and v is not False:
            return Conflict("spill", f"{{spill}} does not run with {{{name}}} ({why})")
    return None


def checkpoint_conflict(o: "ExploreOptions") -> Optional[Conflict]:
    """Why ``o`` cannot checkpoint or resume (None: it can)."""
    if o.checkpoint is None and o.resume is None:
        return None
    what = "resume" if o.checkpoint is None else "checkpoint"
    for name in ("functions", "rand_policy"):
        if getattr(o, name) is not None:
            return Conflict(what, f"{{{what}}} does not run with {name}= (a Python object is "
                                  "not checkpointed)")
    return None


#: The successor engines (pccl/model/native.py).
ENGINES = ("auto", "native", "python")


#: Model options that a run does not take, and why.
NOT_FOR_RUN = {"abstract_time": "a run keeps the clock",
               "reduce": "a run executes the unreduced semantics"}


@dataclass(frozen=True)
class RunOptions(CommonOptions):
    """``pccl run`` / :func:`pccl.api.run`: the common options, the seed and
    the limits of one execution."""
    max_time: Optional[Union[int, float]] = 100
    seed: int = 0
    max_steps: int = 100_000
    record_trace: bool = False
    stall_steps: int = 20                   # 0: no stall detection
    max_memory: Any = "default"             # bytes, None (no limit) or "default", as explore's

    @classmethod
    def from_cli(cls, params: Mapping[str, Any]):
        opts = super().from_cli(params)
        if opts.max_memory is None:
            opts = opts.replace(max_memory="default")
        return opts

    @classmethod
    def from_api(cls, func: str, kwargs: Mapping[str, Any]):
        for name, why in NOT_FOR_RUN.items():
            if name in kwargs:
                raise ArgumentError(f"{name} is not an option of run ({why})",
                                    filename=f"pccl.api.{func}")
        return super().from_api(func, kwargs)

    def check(self, func: str) -> None:
        V.integer(func, "seed", self.seed)
        super().check(func)
        V.integer(func, "max_steps", self.max_steps, minimum=1)
        V.integer(func, "stall_steps", self.stall_steps, minimum=0)
        V.boolean(func, "record_trace", self.record_trace)
        if self.max_memory != "default":
            V.integer(func, "max_memory", self.max_memory, minimum=1, optional=True)


def model_choices(opts: CommonOptions) -> tuple:
    """``(abstract_time, reduce)`` of the model ``opts`` describe: a
    :class:`ModelOptions`' own; a run's (:data:`NOT_FOR_RUN`) keeps the clock
    and executes the unreduced semantics."""
    if isinstance(opts, ModelOptions):
        return opts.abstract_time, opts.reduce
    return False, "none"


def check_model_values(n_agents: int, *, delta, max_time, n0, rates, events) -> list:
    """The checks of :class:`pccl.model.engine.Model`'s team and timing, made once
    the team size is known (the world may give it): an :class:`OptionError`
    naming the option, for every caller of the model (the API re-raises it
    as an :class:`ArgumentError` of the function called, the CLI names the
    flag).  Returns the rate map ρ, one rate per agent."""
    if n_agents < 1:
        raise OptionError("agents", f"the number of agents must be at least 1, got {n_agents}")
    if n_agents > MAX_AGENTS:
        raise OptionError(
            "agents", f"the number of agents must be at most {MAX_AGENTS:,}, got "
            f"{n_agents:,}")
    if not (isinstance(delta, (int, float)) and not isinstance(delta, bool) and delta > 0
            and math.isfinite(delta)):
        raise OptionError("delta", f"δ must be a positive finite number, got {delta}")
    if max_time is not None and not (isinstance(max_time, (int, float))
                                     and not isinstance(max_time, bool)
                                     and math.isfinite(max_time) and max_time >= 0):
        raise OptionError("max_time", f"must be a finite number >= 0, got {max_time}")
    if not (isinstance(n0, int) and n0 >= 1):
        raise OptionError("n0", f"n0 must be a positive integer, got {n0}")
    rho = [1] * n_agents
    for a, r in (rates or {}).items():
        if not (isinstance(a, int) and 0 <= a < n_agents):
            raise OptionError("rates", f"agent {a} does not exist (agents are 0..{n_agents - 1})")
        if not (isinstance(r, int) and r >= 1):
            raise OptionError("rates", f"rate of agent {a} must be a positive integer, got {r}")
        if r > n0:
            # counter + ρ ≤ n0 never holds: the agent would never run an event
            # and a search would "explore clean" without it
            raise OptionError(
                "rates", f"rate {r} of agent {a} is above n0 = {n0}, so agent {a} "
                f"would never run an event (it runs while counter + rate ≤ n0); "
                f"use a rate of at most {n0}, or raise n0 ({{n0={r}}} {{rates={a}={r}}})")
        rho[a] = r
    if events not in ("any", "first"):
        raise OptionError("events", f"must be 'any' or 'first', got {events!r}")
    return rho


def resolve_semantics(language: str, opts: CommonOptions) -> str:
    """The execution model of a program in ``language`` ("pccl" or
    "koord") under ``opts``: ``opts.semantics``, else the language's own
    (Koord's round semantics for a Koord file).  An
    :class:`OptionError` when the options do not fit it: Koord's semantics
    for a PCCL program, ``n0``/``rates`` under it (a robot runs at most one
    event per round), SkipEvent without it."""
    sem = opts.semantics or ("koord" if language == "koord" else "pccl")
    if sem == "koord":
        if language != "koord":
            raise OptionError(
                "semantics", "{semantics=koord} is Koord's execution model (rounds in which "
                "every robot runs at most one event, as one transition): it applies to Koord "
                "programs (.koord, .krd, or {lang=koord}) only; a PCCL program runs under PCCL's semantics "
                "(drop {semantics=koord})")
        if opts.n0 != 1 or opts.rates:
            name = "n0" if opts.n0 != 1 else "rates"
            raise OptionError(
                name, f"{{{name}}} does not apply under Koord's round semantics, where every "
                "robot runs at most one event per round: drop it, or use {semantics=pccl}")
    elif opts.skip_events:
        raise OptionError("skip_events", "{skip_events} is Koord's SkipEvent rule: it needs "
                          "{semantics=koord} (a Koord program)")
    return sem


#: Every option's name (:func:`option_names`).
OPTION_NAMES = option_names()


def integral(x):
    """2.0 is 2 (so that times print as the user wrote them); a huge integral
    float stays a float (its int would print 300 digits)."""
    if isinstance(x, float) and x.is_integer() and abs(x) < 2 ** 53:
        return int(x)
    return x


def cli_fields(cls) -> set:
    """The fields of ``cls`` that the command line sets (all but API-only)."""
    return {f.name for f in dataclasses.fields(cls)} - API_ONLY
