"""One execution of a PCCL program (``pccl run``).

Transitions are chosen among the enabled ones with a seeded generator, and
``rand`` is sampled from the same generator, so the same seed gives the same
run.  The run ends when every agent has exited, in a terminal state, at
``--max-time``, at the first violation (stuck agent, failed assertion,
invariant, collision), when one time step takes more than ``--max-steps``
transitions (an event that never ends, such as ``while (true)``), or when the
team has stalled: no variable, position or flag changed for ``stall_steps``
time steps while some agent still runs (``--stall-steps``).  A run that
passes ``--max-memory`` stops as bounded; one that runs out of memory
(``MemoryError``) stops with status ``out-of-memory`` (exit status 2): both
with what the run did so far.

Memory is linear in the size of a state, whatever the length of the run:
the summary keeps at most :data:`SUMMARY_LIMIT` time steps and at most
:data:`SUMMARY_BUDGET` values' worth of the lists and arrays they hold
(a list that grows each time step made one state per time step quadratic);
beyond either it is thinned evenly.
"""

from __future__ import annotations

import itertools
import random
from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Optional

from pccl.lang.errors import Spelling, keyword_spelling, spell
from pccl.search.explorer import Trace
from pccl.model.layout import (AGS, AR, DONE, FAIL, LOC, LQ, PC, POS, REACH, RUNNING, SH, STATUS,
                               TARGET, TIME)


@dataclass(repr=False)
class RunResult:
    status: str                 # final | bounded | deadlock | violation | max-steps | stalled
                                # | interrupted | out-of-memory
    message: str
    exit_status: int
    final: tuple                # the last configuration
    steps: int
    #: the run's path (:class:`pccl.search.explorer.Trace`: the initial state and
    #: every step) when recorded (``record_trace``), else None
    trace: Optional[Trace] = None
    summary: list = field(default_factory=list)   # [(time, state)] after each environment step
    violations: list = field(default_factory=list)
    looping_agent: Optional[int] = None
    #: a stalled run: the time since which nothing changed, and per running
    #: agent what it waits on
    stalled_since: Optional[float] = None
    waiting: list = field(default_factory=list)
    #: what this run says about each temporal property (PropertyOutcome)
    properties: list = field(default_factory=list)
    #: peak resident memory of the process (bytes) when the run ended
    peak_memory: int = 0
    #: the --max-memory the run was given (bytes, None: none)
    max_memory: Optional[int] = None

    model: Any = None

    def __repr__(self) -> str:
        """One line: the status, the message, the end time and the counts."""
        from pccl.output.display import fmt_time
        return (f"<RunResult {self.status} (exit {self.exit_status}): {self.message!r}; "
                f"t={fmt_time(self.final[TIME])}, {self.steps:,} transitions"
                + (f", {len(self.trace)} recorded" if self.trace else "") + ">")

    @property
    def final_state(self):
        """The last configuration as a named view (:class:`~pccl.output.results.StateView`:
        ``res.final_state.agents[0].variables["inCs"]``), as ``pccl run`` prints it;
        ``final`` is the raw configuration."""
        from pccl.output.results import StateView
        if self.model is None:
            raise ValueError("this RunResult has no model (pccl.api.run sets it)")
        return StateView.of(self.model, self.final)


@dataclass
class PropertyOutcome:
    """What one run says about a temporal property: ``outcome`` is
    ``holds`` (decided on this run), ``violated``, ``witnessed`` (a
    ``reachable P`` reached), ``not reached`` or ``undecided`` (the run was
    cut before it could tell); ``detail`` says when and why."""
    name: str
    kind: str
    outcome: str
    detail: str


class _Monitor:
    """Checks the temporal properties of ``model.temporal`` on one run.

    A run is one path: ``P ~> Q within T`` is violated as soon as T time
    units pass after an unanswered P; ``eventually P`` and ``P ~> Q`` are
    decided only when the run ends for good (every agent exited, a deadlock,
    a stall); a run cut by --max-time or --max-steps leaves them undecided
    (``pccl explore`` decides them over every run).  A runtime error in P or
    Q counts as false, as in explore."""

    def __init__(self, props) -> None:
        self.props = list(props)
        #: eventually/reachable: (step, time) of P
        self.seen: list[Optional[tuple[int, Any]]] = [None] * len(self.props)
        #: ~>: (step, time) of the oldest open P
        self.pending: list[Optional[tuple[int, Any]]] = [None] * len(self.props)
        self.violated: list = [None] * len(self.props)  # within: the message, once violated

    @staticmethod
    def _holds(fn, st) -> bool:
        try:
            return bool(fn(st))
        except Exception:       # noqa: BLE001 - a runtime error in a property is "false"
            return False

    def violations(self, st, step: int) -> list:
        """The violation of a property at ``st`` (after ``step`` transitions),
        as a list (empty: none)."""
        hit = self.observe(st, step)
        if hit is None:
            return []
        from pccl.model.engine import Violation
        p, msg = hit
        return [Violation(p.kind, p.name, msg, None, p.span)]

    def observe(self, st, step: int):
        """Update on state ``st`` (reached after ``step`` transitions); a
        violated ``within`` property as ``(property, message)``, else None."""
        t = st[TIME]
        for k, p in enumerate(self.props):
            if p.kind in ("eventually", "reachable"):
                if self.seen[k] is None and self._holds(p.p, st):
                    self.seen[k] = (step, t)
                continue
            if self.pending[k] is not None and self._holds(p.q, st):
                self.pending[k] = None
            elif self.pending[k] is None and self._holds(p.p, st) and not self._holds(p.q, st):
                self.pending[k] = (step, t)
            pend = self.pending[k]
            if p.kind == "within" and pend is not None and t - pend[1] > p.bound:
                self.violated[k] = (f"the premise held at t = {_t(pend[1])} "
                                    f"and the response did not follow within {_t(p.bound)} "
                                    f"time units (t = {_t(t)})")
                return p, (f"{p.name}: the premise held at t = {_t(pend[1])} "
                           f"(after {pend[0]} transitions) and the response did not "
                           f"follow within {_t(p.bound)} time units (t = {_t(t)})")
        return None

    def outcomes(self, ended: bool, why: str) -> list:
        """Per property, what the run says; ``ended``: the run cannot go on
        (so eventually/leads-to are decided), ``why`` names how it ended."""
        out = []
        for k, p in enumerate(self.props):
            seen = self.seen[k]
            if self.violated[k] is not None:
                out.append(PropertyOutcome(p.name, p.kind, "violated", self.violated[k]))
            elif p.kind == "reachable":
                if seen is not None:
                    out.append(PropertyOutcome(p.name, p.kind, "witnessed",
                                               f"reached after {seen[0]} transitions, "
                                               f"t = {_t(seen[1])}"))
                else:
                    out.append(PropertyOutcome(p.name, p.kind, "not reached",
                                               f"not in this run ({why}); pccl explore decides"))
            elif p.kind == "eventually":
                if seen is not None:
                    out.append(PropertyOutcome(p.name, p.kind, "holds",
                                               f"held after {seen[0]} transitions, "
                                               f"t = {_t(seen[1])}"))
                elif ended:
                    out.append(PropertyOutcome(p.name, p.kind, "violated",
                                               f"never held, and the run ended ({why})"))
                else:
                    out.append(PropertyOutcome(p.name, p.kind, "undecided",
                                               f"has not held yet; the run was cut ({why})"))
            else:
                pend = self.pending[k]
                if pend is None:
                    out.append(PropertyOutcome(p.name, p.kind, "holds" if ended else "undecided",
                                               "every premise was answered" + (
                                                   "" if ended else f" so far ({why})")))
                elif ended:
                    out.append(PropertyOutcome(p.name, p.kind, "violated",
                                               f"the premise held at t = {_t(pend[1])} (after "
                                               f"{pend[0]} transitions) and the response never "
                                               f"followed; the run ended ({why})"))
                else:
                    out.append(PropertyOutcome(p.name, p.kind, "undecided",
                                               f"the premise of t = {_t(pend[1])} is not answered "
                                               f"yet; the run was cut ({why})"))
        return out


def _t(x) -> str:
    from pccl.output.display import fmt_time
    return fmt_time(x)


def _signature(st) -> tuple:
    """What a stall compares: variables, positions, doReach targets and flags,
    statuses and the lock queue (not the clock, counters or pending code)."""
    return (st[LQ], st[SH], tuple((ag[STATUS], ag[LOC], ag[AR], ag[POS], ag[REACH][TARGET],
                                   ag[REACH][DONE], ag[REACH][FAIL]) for ag in st[AGS]))


def unspelt(name: str, value: Optional[str]) -> None:
    """A spelling that writes no option: the message keeps its placeholders."""
    return None


def run(model, *, seed: int = 0, max_steps: int = 100_000, record_trace: bool = False,
        rng: Optional[random.Random] = None, on_step=None, stall_steps: int = 20,
        max_memory: Optional[int] = None, spelling: Spelling = keyword_spelling) -> RunResult:
    """Execute ``model`` once.  ``model`` must have been built with a
    ``rand_policy`` if rand should be sampled (see :func:`pccl.api.make_model`);
    otherwise all rand outcomes are successors and one is picked at random.
    ``stall_steps``: stop when nothing changed for this many time steps
    while an agent still runs (0: never).  ``max_memory``: stop, as
    bounded, once the process's peak resident memory passes this many bytes
    (checked every :data:`MEMORY_CHECK` transitions; None: never).
    ``spelling`` writes the options a message names (``max_time=100`` for the
    API, the default; ``pccl run`` passes its flags; :func:`unspelt` keeps
    the ``{max_time=100}`` placeholders, for replay to compare)."""
    from pccl.search.memory import peak_rss_bytes
    rng = rng or random.Random(seed)
    st = _initial_state(model, rng)
    states: list = [st]         # the recorded path (record_trace): its states and labels
    labels: list = []
    on_step = _recording(states, labels, on_step) if record_trace else on_step
    watch = _TimeSteps(st, stall_steps)
    steps = 0
    since_time = 0
    per_agent: Counter = Counter()

    temporal = getattr(model, "temporal", None)
    mon = _Monitor(temporal) if temporal else None

    def finish(status, message, code, **kw):
        trace = Trace(tuple(states), tuple(labels)) if record_trace and states else None
        res = RunResult(status, spell(message, spelling), code, st, steps, trace, watch.summary, **kw,
                        peak_memory=peak_rss_bytes(), max_memory=max_memory)
        return _with_properties(res, mon, code)

    try:
        while True:
            v = model.violations(st)
            if not v and mon is not None:
                v = mon.violations(st, steps)
            if v:
                return finish("violation", "; ".join(x.message for x in v), 1, violations=v)
            succ = model.successors(st)
            if not succ:
                status, message, code, kw = _terminal(model, st)
                return finish(status, message, code, **kw)
            label, nxt = succ[0] if len(succ) == 1 else succ[rng.randrange(len(succ))]
            if on_step is not None:
                on_step(label, st, nxt)
            steps += 1
            if max_memory is not None and not steps % MEMORY_CHECK \
                    and peak_rss_bytes() > max_memory:
                st = nxt
                from pccl.search.memory import format_size
                return finish("bounded", f"stopped at {{max_memory={format_size(max_memory)}}}: "
                              f"the process's peak memory passed it", 0)
            rule, agent = label[0], label[1]
            if rule == "TIME ADVANCE":
                since_time = 0
                per_agent.clear()
            elif rule == "DOREACH INVOKE":
                if watch.env_step(nxt):
                    st = nxt
                    message, kw = watch.stalled(model, nxt)
                    return finish("stalled", message, 1, **kw)
            else:
                since_time += 1
                if agent is not None:
                    per_agent[agent] += 1
                if since_time > max_steps:
                    st = nxt
                    message, kw = _looping(model, st, per_agent, max_steps)
                    return finish("max-steps", message, 1, **kw)
            st = nxt
    except KeyboardInterrupt:   # Ctrl-C or SIGTERM: the run so far, status 130
        return finish("interrupted", f"interrupted after {steps} transitions", 130)
    except MemoryError:
        return finish("out-of-memory", _out_of_memory(states, labels, steps), 2)


def _out_of_memory(states: list, labels: list, steps: int) -> str:
    """Step of :func:`run`: the message of a run out of memory.  The frames
    that failed are gone; the recorded trace, the likely culprit, is dropped
    so that the result can be shown."""
    dropped = (f"; the recorded trace ({len(labels):,} transitions) was dropped"
               if labels else "")
    labels.clear()
    states.clear()
    return (f"out of memory after {steps} transitions: the process could not "
            f"allocate more (a limit such as ulimit -v, or the machine's memory); "
            f"give {{max_memory}} below that limit to stop as a bound{dropped}")


def _initial_state(model, rng):
    """Step of :func:`run`: the initial state (one picked by ``rng`` when
    the model has no rand policy and every outcome is an initial state)."""
    gen = iter(model.init_states())
    inits = list(itertools.islice(gen, 2))
    if len(inits) > 1:          # no rand policy: every outcome is an initial state
        inits.extend(gen)
    return inits[0] if len(inits) == 1 else rng.choice(inits)


def _recording(states: list, labels: list, on_step):
    """Step of :func:`run` (``record_trace``): an ``on_step`` that records
    each step's label and state, then calls ``on_step`` (if any)."""
    def record(label, st, nxt):
        labels.append(label)
        states.append(nxt)
        if on_step is not None:
            on_step(label, st, nxt)
    return record


def _with_properties(res: RunResult, mon, code: int) -> RunResult:
    """Step of :func:`run`: the run's temporal property outcomes (``mon``)
    in ``res``; a violated one makes a successful run a violation."""
    if mon is None:
        return res
    status = res.status
    res.properties = mon.outcomes(status in ("final", "deadlock", "stalled"),
                                  "every agent exited" if status == "final" else status)
    bad = [o for o in res.properties if o.outcome == "violated"]
    if bad and code == 0:
        from pccl.model.engine import Violation
        res.status, res.exit_status = "violation", 1
        res.message = "; ".join(f"{o.name}: {o.detail}" for o in bad)
        res.violations = [Violation(o.kind, o.name, f"{o.name}: {o.detail}")
                          for o in bad]
    return res


def _terminal(model, st) -> tuple:
    """Step of :func:`run`: (status, message, exit status, extra fields) of
    a state without successors."""
    kind = model.terminal_kind(st)
    if kind == "final":
        return "final", "every agent exited", 0, {}
    if kind == "bounded":
        return "bounded", f"stopped at {{max_time={model.max_time}}}", 0, {}
    dv = model.deadlock_violation(st)
    return "deadlock", dv.message, 1, {"violations": [dv]}


def _looping(model, st, per_agent: Counter, max_steps: int) -> tuple:
    """Step of :func:`run`: (message, extra fields) of a run stopped by
    ``max_steps`` transitions without a time step."""
    from pccl.model.stall import looping_agent
    looping = looping_agent(model, st, per_agent)
    return (f"agent {looping} runs more than {max_steps} transitions without "
            f"letting time advance ({model.compiled.describe_k(st[AGS][looping][PC])}); "
            f"raise {{max_steps}} if this is intended", {"looping_agent": looping})


class _TimeSteps:
    """Step of :func:`run`: what it keeps per time step (each DOREACH
    INVOKE): the summary of the run, thinned to bounded memory, and whether
    the run stalls (nothing changed for ``stall_steps`` time steps)."""

    def __init__(self, st, stall_steps: int) -> None:
        self.summary = [(st[TIME], st)]
        self.weights = [0]          # per summary entry: the list/array values it added
        self.budget = SUMMARY_BUDGET
        self.n_env, self.stride = 0, 1
        self.stall_steps = stall_steps
        self.last_sig, self.still, self.since = _signature(st), 0, st[TIME]

    def env_step(self, nxt) -> bool:
        """Record the time step to ``nxt``; whether the run stalls there."""
        sig = _signature(nxt)
        if sig == self.last_sig:
            self.still += 1
        else:
            self.last_sig, self.still, self.since = sig, 0, nxt[TIME]
        if self.stall_steps and self.still >= self.stall_steps \
                and any(ag[STATUS] == RUNNING for ag in nxt[AGS]):
            return True
        self.n_env += 1
        if self.n_env % self.stride == 0:
            self._add(nxt)
        return False

    def _add(self, nxt) -> None:
        summary, weights = self.summary, self.weights
        w = _weight(nxt, summary[-1][1])
        summary.append((nxt[TIME], nxt))
        weights.append(w)
        self.budget -= w
        if len(summary) > SUMMARY_LIMIT or self.budget < 0:  # bounded memory:
            summary[1:] = summary[2::2]     # keep every other one, and
            weights[1:] = weights[2::2]
            self.stride *= 2                # record half as often from now on
            self.budget = SUMMARY_BUDGET - sum(weights)

    def stalled(self, model, st) -> tuple:
        """(message, extra fields) of a run that stalls at ``st``."""
        self.summary.append((st[TIME], st))
        from pccl.output.display import fmt_time
        from pccl.model.stall import waiting, waiting_text
        waits = waiting(model, st)
        # the cause first (what blocks each waiting agent: only
        # guards that can still hold for it, the flag behind them)
        return ((waiting_text(waits) + "; " if waits else "")
                + f"nothing changed since t = {fmt_time(self.since)} (no variable, "
                f"position or flag for {self.still} time steps) while agents "
                f"still run", {"stalled_since": self.since, "waiting": waits})


#: The most time steps a run's summary keeps; a longer run's summary is
#: thinned evenly (every 2nd, 4th, ... time step), so memory stays bounded.
SUMMARY_LIMIT = 100_000

#: The most list and array elements the summary's states may add to memory
#: (about 8 bytes each): the states of a run whose lists grow each time step
#: would otherwise make memory quadratic in the run's length.  Beyond it the
#: summary is thinned as beyond :data:`SUMMARY_LIMIT`.
SUMMARY_BUDGET = 8_000_000

#: Transitions between two checks of ``--max-memory``.
MEMORY_CHECK = 256


def _weight(st, prev) -> int:
    """About how many list and array elements ``st`` holds that ``prev``
    (the summary's previous state) does not share: the memory a summary
    entry adds beyond its cells.  Values are compared by identity (a list
    that did not change is the same tuple), nested lists one level deep."""
    pairs = [(st[SH], prev[SH])]
    for a, b in zip(st[AGS], prev[AGS]):
        if a is not b:
            pairs.append((a[LOC], b[LOC]))
            pairs.append((a[AR], b[AR]))
    w = 0
    for cur, old in pairs:
        if cur is old:
            continue
        for v, o in zip(cur, old):
            if v is not o and type(v) is tuple:
                w += len(v)
                if v and type(v[0]) is tuple:
                    w += sum(len(x) for x in v if type(x) is tuple)
    return w


