"""What a verdict covers: the ``checked`` section of ``pccl explore`` and ``pccl run``.

A clean verdict alone does not say what was checked.  :class:`Checked` lists,
as SPIN's "Full statespace search for" does, every invariant and property
with its outcome, the built-in checks on or off, the blackbox and what it
covers, the bounds (and whether one stopped the search), the reductions, the
events that never fired in an exhaustive search, and notes when the verdict
is weak (no property given; defaults used for an absent world).

:func:`for_explore` and :func:`for_run` build it (both through
:func:`build`); :meth:`Checked.lines` renders the text and
:meth:`Checked.to_json` the JSON (``"checked"`` of ``--format json``,
described in docs/trace-format.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from pccl.lang import ast as A
from pccl.lang.errors import Spelling, spell
from pccl.model.options import api_spelling

#: Outcomes of a property (``Checked.properties[k].outcome``).
HELD = "held"                                  # exhaustive search: holds in every run
HELD_WITHIN_BOUNDS = "held within bounds"      # in every state/run the bounded search saw
HELD_EXPLORED = "held in the states explored"  # the search stopped early (a violation, Ctrl-C)
HELD_ON_RUN = "held on this run"               # pccl run: one execution
VIOLATED = "violated"
NOT_CHECKED = "not checked"

#: The note on a clean verdict without any property.
NO_PROPERTY_NOTE = "no invariant or property given: only the built-in checks ran"

#: What each shipped blackbox covers, in one phrase.
BLACKBOX_COVERS = {
    "nondet": "every travel time: each moving robot arrives or stays at every step",
    "straight": "one timing: straight-line travel at the world's speed",
    "instant": "one timing: every robot reaches its target in the next step",
    "pymunk": "one timing: a physics simulation with acceleration and contact",
}


@dataclass(frozen=True)
class PropertyCheck:
    """One invariant or property: ``kind`` (``invariant`` for a state
    property, else the temporal form: ``eventually``, ``leadsto``,
    ``within``, ``reachable``), its name and text, where it was given
    (``program`` or ``option``), the outcome and why (``reason``, or None)."""
    kind: str
    name: str
    text: str
    source: str
    outcome: str
    reason: Optional[str] = None

    def to_json(self) -> dict:
        return {"kind": self.kind, "name": self.name, "text": self.text,
                "source": self.source, "outcome": self.outcome, "reason": self.reason}

    def label(self) -> str:
        what = "invariant" if self.kind == "invariant" else "property"
        if self.name == self.text or self.name.startswith(self.text + " ["):
            return f"{what} '{self.name}'"
        return f"{what} {self.name} '{self.text}'"


@dataclass(frozen=True)
class Checked:
    """What a verdict covers (see the module docstring).  ``builtin`` is
    ``((check, on, detail), ...)``; ``bounds`` ``((label, stopped), ...)``;
    ``never_fired`` ``((event, line), ...)`` or None when not computed (then
    ``events_reason`` says why); ``events`` is the number of events."""
    command: str
    properties: tuple
    builtin: tuple
    blackbox: str
    covers: str
    bounds: tuple
    reductions_on: tuple
    reductions_off: tuple             # ((name, reason), ...)
    never_fired: Optional[tuple]
    events_reason: Optional[str]
    events: int
    notes: tuple
    #: the timing explored (:func:`pccl.model.timing.timing_text`; explore only)
    timing: Optional[str] = None

    def __getitem__(self, key: str):
        return self.to_json()[key]

    def to_json(self) -> dict:
        return {
            "properties": [p.to_json() for p in self.properties],
            "builtin": [{"check": c, "on": on, "detail": d} for c, on, d in self.builtin],
            "blackbox": {"name": self.blackbox, "covers": self.covers},
            "timing": self.timing,
            "bounds": [{"bound": b, "stopped": s} for b, s in self.bounds],
            "reductions": {"on": list(self.reductions_on), "off": dict(self.reductions_off)},
            "events": {"total": self.events,
                       "never_fired": (None if self.never_fired is None else
                                       [{"event": e, "line": ln} for e, ln in self.never_fired]),
                       "reason": self.events_reason},
            "notes": list(self.notes),
        }

    def lines(self) -> list:
        """The text section: ``checked:`` and a few indented lines."""
        out = ["checked:"]
        for p in self.properties:
            out.append(f"  {p.label()}: {p.outcome}" + (f" ({p.reason})" if p.reason else ""))
        out.append("  built-in: " + ", ".join(f"{c} {'+' if on else '-'}"
                                            for c, on, _ in self.builtin))
        out.append(f"  blackbox: {self.blackbox} ({self.covers})")
        if self.timing:
            out.append(f"  timing: {self.timing}")
        if self.bounds:
            parts = [f"{b} ({'stopped the search' if s else 'not reached'})"
                     for b, s in self.bounds]
            out.append("  bounds: " + ", ".join(parts))
        else:
            out.append("  bounds: none")
        red = "+".join(self.reductions_on) if self.reductions_on else "none"
        if self.command == "explore":
            out.append(f"  reductions: {red}")
        if self.never_fired is None:
            if self.command == "explore":
                out.append(f"  events: never-fired not computed ({self.events_reason})")
        elif self.never_fired:
            out.append("  never fired: " + ", ".join(f"event {e} (line {ln})"
                                                     for e, ln in self.never_fired))
        else:
            out.append(f"  events: every event fired ({self.events})")
        for n in self.notes:
            out.append(f"  note: {n}")
        return out


# ---------------------------------------------------------------------------
# what the program reads
# ---------------------------------------------------------------------------

def world_reads(prog: A.Program) -> dict:
    """What ``prog`` reads of the world, by kind (``input``, ``obstacles``,
    ``positions``): the first line where it does."""
    exprs = [d.init for d in prog.decls if isinstance(d, A.VarDecl) and d.init is not None]
    stmts = list(A.walk_stmts(prog.init))
    for ev in prog.events:
        stmts.extend(A.walk_stmts(ev.body))
        exprs.append(ev.guard)
    found: dict = {}
    for s in stmts:
        if isinstance(s, A.CallStmt) and s.name == "doReach":
            found.setdefault("positions", ("doReach", s.span.line))
        exprs.extend(A.own_exprs(s))
    kinds = {"getInput": "input", "getObs": "obstacles", "getPosition": "positions"}
    for x in exprs:
        for e in A.walk_expr(x):
            if isinstance(e, A.Call) and e.name in kinds:
                found.setdefault(kinds[e.name], (f"{e.name}()", e.span.line))
            elif isinstance(e, A.Name) and e.name in ("doReach_done", "doReach_fail"):
                found.setdefault("positions", (e.name, e.span.line))
    return {k: found[k] for k in ("input", "obstacles", "positions") if k in found}


def world_given(model) -> bool:
    """Whether the model's world came from a file or object (``--world``)."""
    given = getattr(model, "world_given", None)
    if given is not None:
        return bool(given)
    from pccl.lang.world import default_world
    return model.world != default_world()


def world_note(model, *, run_result=None) -> Optional[str]:
    """The note for a program that reads getInput(), obstacles or positions
    without a world: the defaults it got.  For a run that ended at t=0
    reading getInput(), also that (the empty list gave it nothing to do)."""
    if world_given(model):
        return None
    reads = world_reads(model.program)
    if not reads:
        return None
    from pccl.output.display import fmt_pos
    parts = []
    if "input" in reads:
        parts.append(f"getInput() = [] (read at line {reads['input'][1]})")
    if "obstacles" in reads:
        parts.append(f"getObs() = [], no obstacles (read at line {reads['obstacles'][1]})")
    if "positions" in reads:
        starts = ", ".join(fmt_pos(p) for p in model.world.start_positions(model.N))
        what, line = reads["positions"]
        parts.append(f"the robots start on a line at {starts} ({what} at line {line})")
    note = "no {world} given, so the defaults are used: " + "; ".join(parts)
    if run_result is not None and "input" in reads and run_result.status == "final":
        from pccl.model.layout import TIME
        if run_result.final[TIME] == 0:
            note += ("; the run ended at t=0 because getInput() is the empty list "
                     "(give the world with {world=FILE})")
    return note


def calls_doreach(prog: A.Program) -> bool:
    stmts = list(A.walk_stmts(prog.init))
    for ev in prog.events:
        stmts.extend(A.walk_stmts(ev.body))
    return any(isinstance(s, A.CallStmt) and s.name == "doReach" for s in stmts)


def blackbox_covers(model) -> str:
    if not calls_doreach(model.program):
        return "not used: the program does not call doReach"
    bb = model.blackbox
    covers = getattr(bb, "covers", None)
    if isinstance(covers, str) and covers:
        return covers
    from pccl.blackboxes import BLACKBOXES
    name = getattr(bb, "name", "?")
    if name in BLACKBOX_COVERS and BLACKBOXES.get(name) is bb:
        return BLACKBOX_COVERS[name]
    return "the outcomes your blackbox returns"


# ---------------------------------------------------------------------------
# building
# ---------------------------------------------------------------------------

def stall_check(command: str, options) -> tuple:
    """``(on, detail)`` of the stall check.  The one place that knows the
    stall options: ``stall_steps`` of a run (0: off); ``stall`` of explore.
    The detail names the option as a placeholder (``{stall=False}``), spelt
    by :func:`build`."""
    if command == "run":
        n = getattr(options, "stall_steps", 0) or 0
        return (n > 0, f"{{stall_steps={n}}}")
    on = bool(options.stall)
    return on, None if on else "{stall=False}"


def event_list(model) -> list:
    return [(ev.name, ev.span.line) for ev in model.program.events]


def build(model, *, command: str, properties: list, builtin: list, bounds: list,
          never_fired: Optional[list], events_reason: Optional[str], clean: bool,
          run_result=None, spelling: Spelling = api_spelling) -> Checked:
    """The one constructor of :class:`Checked`: the parts the front ends
    computed, plus what the model says (blackbox, reductions, notes).  The
    options the texts name (placeholders such as ``{stall=False}``) are
    spelt by ``spelling``: the API's keywords, or the CLI's flags."""
    red = getattr(model, "reduction", None)
    on = tuple(red.on) if red is not None and command == "explore" else ()
    off = tuple(red.off_reasons(spelling).items()) if red is not None and command == "explore" else ()
    builtin = [(c, ok, None if d is None else spell(d, spelling)) for c, ok, d in builtin]
    bounds = [(spell(b, spelling), s) for b, s in bounds]
    events_reason = None if events_reason is None else spell(events_reason, spelling)
    notes = []
    if clean and not properties:
        notes.append(NO_PROPERTY_NOTE)
    w = world_note(model, run_result=run_result)
    if w:
        notes.append(spell(w, spelling))
    timing = None
    if command == "explore":
        from pccl.model.timing import timing_text
        timing = timing_text(model)
    return Checked(command, tuple(properties), tuple(builtin), model.blackbox.name,
                   blackbox_covers(model), tuple(bounds), on, off,
                   None if never_fired is None else tuple(never_fired), events_reason,
                   len(model.program.events), tuple(notes), timing)


def _source(p) -> str:
    return "program" if getattr(p, "span", None) is not None else "option"


def _explore_scope(status: str, complete: bool, stopped: str) -> tuple[str, Optional[str]]:
    """What "held" means for an invariant the search did not violate."""
    if complete:
        return HELD, None
    if status == "bounded":
        return HELD_WITHIN_BOUNDS, f"stopped by {stopped}"
    if status == "interrupted":
        return HELD_EXPLORED, "interrupted"
    return HELD_EXPLORED, "the search stopped at the first violation"


def _temporal_outcome(p, violated: set, holds: set, status: str, complete: bool,
                      why: Optional[str], stopped: str) -> tuple[str, Optional[str]]:
    """The outcome of temporal property ``p`` and the reason for it."""
    if (False, p.name) in violated:
        return VIOLATED, None
    if p.name in holds:
        if p.kind == "reachable":
            return HELD, "a witness reaches it"
        return (HELD, None) if complete else (HELD_WITHIN_BOUNDS, why)
    if status == "violation" and not complete:
        return NOT_CHECKED, "the search stopped at the first violation"
    if status == "interrupted":
        return NOT_CHECKED, "interrupted"
    if status == "bounded":
        return NOT_CHECKED, f"the search did not finish (stopped by {stopped})"
    return NOT_CHECKED, "the analysis stopped at the first violation"


def _explore_builtin(model, res, options) -> list:
    """The built-in checks of an explore run: (name, on, why not)."""
    tl_on = bool(res.timelock)
    tl_why = None
    if not tl_on:
        tl_why = ("{timelock=False}" if not options.timelock
                  else "needs the state graph of one process")
    stall_on, stall_why = stall_check("explore", options)
    if stall_on and not res.stall:
        stall_on, stall_why = False, "needs the state graph of one process"
    return [("assertions", True, None), ("stuck agents", True, None),
            ("deadlock", bool(options.deadlock), None if options.deadlock else "{deadlock=False}"),
            ("stall", stall_on, stall_why),
            ("time-lock", tl_on, tl_why),
            ("collisions", bool(model.collisions),
             None if model.collisions else "{collisions} not given")]


def _never_fired(model, labels: Optional[set], complete: bool, status: str,
                 labels_reason: Optional[str]) -> tuple[Optional[list], Optional[str]]:
    """The events no transition fired (None when unknown) and why unknown."""
    if labels is not None and complete:
        fired = {lab[2] for lab in labels if lab[0] in ("EVENT SELECT", "EVENT TRANS") and lab[2] is not None}
        return [e for k, e in enumerate(event_list(model)) if k not in fired], labels_reason
    if labels is not None:
        return None, ("a bound stopped the search" if status == "bounded" else
                      "interrupted" if status == "interrupted" else
                      "the search stopped at the first violation")
    return None, labels_reason


def for_explore(model, res, options, *, complete: bool, labels: Optional[set],
                labels_reason: Optional[str] = None, bounds: tuple = (),
                spelling: Spelling = api_spelling) -> Checked:
    """``checked`` of an :class:`~pccl.api.ExploreResult` ``res`` searched
    with ``options``.  ``complete``: the search visited every reachable
    state (exhaustive, or ``find_all`` without a bound); ``labels``: the
    distinct transition labels it took (None when not collected, then
    ``labels_reason`` says why); ``bounds``: ``(label, stopped)`` of the
    bounds in force; ``spelling``: how the texts write options."""
    violated = {(v.kind == "invariant", v.name) for v in res.violations}
    status = res.status
    stopped = ", ".join(res.bound_labels)
    scope, why = _explore_scope(status, complete, stopped)
    props = []
    for p in model.properties:
        out, r = (VIOLATED, None) if (True, p.name) in violated else (scope, why)
        props.append(PropertyCheck("invariant", p.name, p.text, _source(p), out, r))
    holds = set(res.holds)
    for p in model.temporal:
        out, r = _temporal_outcome(p, violated, holds, status, complete, why, stopped)
        props.append(PropertyCheck(p.kind, p.name, p.text, _source(p), out, r))
    builtin = _explore_builtin(model, res, options)
    never, reason = _never_fired(model, labels, complete, status, labels_reason)
    clean = not res.violations and status in ("exhaustive", "bounded")
    return build(model, command="explore", properties=props, builtin=builtin,
                 bounds=list(bounds), never_fired=never, events_reason=reason, clean=clean,
                 spelling=spelling)


def for_run(model, res, options, spelling: Spelling = api_spelling) -> Checked:
    """``checked`` of a :class:`~pccl.tools.runner.RunResult` of ``pccl run``."""
    from pccl.output.display import fmt_time
    bad = {v.name for v in res.violations if v.kind == "invariant"}
    props = []
    for p in model.properties:
        out = VIOLATED if p.name in bad else HELD_ON_RUN
        props.append(PropertyCheck("invariant", p.name, p.text, _source(p), out, None))
    outcomes = {o.name: o for o in res.properties}
    for p in model.temporal:
        o = outcomes.get(p.name)
        if o is None:
            out, r = NOT_CHECKED, "the run stopped first"
        elif o.outcome == "holds":
            out, r = HELD_ON_RUN, o.detail
        else:
            out, r = o.outcome, o.detail
        props.append(PropertyCheck(p.kind, p.name, p.text, _source(p), out, r))
    stall_on, stall_why = stall_check("run", options)
    builtin = [("assertions", True, None), ("stuck agents", True, None),
               ("deadlock", True, None), ("stall", stall_on, stall_why),
               ("time-lock", False, "explore only"),
               ("collisions", bool(model.collisions),
                None if model.collisions else "{collisions} not given")]
    bounds = []
    if model.max_time is not None:
        bounds.append((f"{{max_time={fmt_time(model.max_time)}}}", res.status == "bounded"))
    bounds.append((f"{{max_steps={options.max_steps}}}", res.status == "max-steps"))
    clean = res.exit_status == 0
    return build(model, command="run", properties=props, builtin=builtin, bounds=bounds,
                 never_fired=None, events_reason="one run is not a search", clean=clean,
                 run_result=res, spelling=spelling)

