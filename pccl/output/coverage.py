"""``explore --coverage``: which events fired, which statements never ran.

The explorer keeps no states, so coverage is tallied on the way: a
:class:`CoverageModel` wraps the model (it satisfies the explorer's ``Model``
protocol) and counts the labels of the successors of every state the search
expands.  Counts are per expanded state: "fired 12" means that 12 expanded
states had a transition selecting the event (one per ``rand`` outcome).
The rebuilding of counterexamples after the search is not counted (it starts
with a second call of ``init_states``).

Under Koord's round semantics (pccl/model/koord.py) an event runs to its end
inside one transition (EVENT TRANS): the model records which statements
each successor's event ran, and each counts once per such transition; an
ATOMIC WAIT runs nothing; a guard is evaluated on the round's start values
the robot reads.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from pccl.output import display as D
from pccl.model.layout import AGS, SH

_STMT_RULES = ("STATEMENT", "EXIT", "DOREACH UPDATE", "LOCK REQUEST", "ATOMIC EXECUTION",
               "ATOMIC WAIT")


class CoverageModel:
    """A model that tallies the transitions the search takes."""

    def __init__(self, model):
        self.model = model
        self.key = model.key
        self.violations = model.violations
        self.terminal_kind = model.terminal_kind
        self.deadlock_violation = model.deadlock_violation
        self.time_costs = model.time_costs
        self.held: Counter = Counter()      # event -> expanded (state, agent) where its guard held
        self.fired: Counter = Counter()     # event -> EVENT SELECT transitions
        self.executed: Counter = Counter()  # statement id -> transitions
        self.rules: Counter = Counter()
        self.expanded = 0
        self._inits = 0
        self.counting = True
        #: Koord's round semantics (pccl/model/koord.py): an event's statements
        #: run inside its one transition; the model tells which
        self.koord = getattr(model, "semantics", "pccl") == "koord"
        if self.koord:
            model.record_statements()

    def init_states(self):
        self._inits += 1
        if self._inits > 1:          # the counterexample replay: not part of the search
            self.counting = False
        return self.model.init_states()

    def successors(self, st):
        out = self.model.successors(st)
        if not self.counting:
            return out
        self.expanded += 1
        selecting = set()
        koord = self.koord
        for (rule, agent, detail), _ in out:
            self.rules[rule] += 1
            if rule in ("EVENT SELECT", "EVENT TRANS") and detail is not None:
                self.fired[detail] += 1
                selecting.add(agent)
            elif rule in ("IDLE", "SKIP EVENT"):
                selecting.add(agent)
            elif rule in _STMT_RULES and detail is not None and not koord:
                self.executed[detail] += 1
        m = self.model
        if koord:
            # each statement an event ran inside its transition, once per transition
            for stmts in m.statements_ran:
                for sid in stmts:
                    self.executed[sid] += 1
        if selecting and not m.guards_rand:
            for i in selecting:
                # under Koord's semantics a robot reads the round's start
                view = m._round_start_view(st, i) if koord else st
                sh, ags = view[SH], view[AGS]
                ag = ags[i]
                for e, g in enumerate(m.compiled.guards):
                    try:
                        if g(i, ag, sh, ags):
                            self.held[e] += 1
                    except Exception:       # the agent gets stuck; reported as a violation
                        pass
        return out

    # -- checkpoints (pccl/search/checkpoint.py) ---------------------------------------
    _COUNTS = ("held", "fired", "executed", "rules")

    def checkpoint_mark(self) -> None:
        """The search is where a checkpoint may be taken (a level's or a
        bucket's start): the tallies as they stand, which
        :meth:`checkpoint_tables` reports (a checkpoint written later, on
        an interrupt, must not count the expansions the resumed search
        repeats)."""
        self._marked = ({name: Counter(getattr(self, name)) for name in self._COUNTS},
                        self.expanded)

    def checkpoint_tables(self) -> dict:
        inner = getattr(self.model, "checkpoint_tables", None)
        marked = getattr(self, "_marked", None)
        if marked is None:
            self.checkpoint_mark()
            marked = self._marked
        return {"model": inner() if inner is not None else None,
                "coverage": {"counts": {k: dict(v) for k, v in marked[0].items()},
                             "expanded": marked[1]}}

    def restore_tables(self, data: dict) -> None:
        inner = getattr(self.model, "restore_tables", None)
        if inner is not None and data.get("model") is not None:
            inner(data["model"])
        cov = data["coverage"]
        for name in self._COUNTS:
            setattr(self, name, Counter(cov["counts"][name]))
        self.expanded = int(cov["expanded"])
        self._inits = max(self._inits, 1)   # the search's own call: a later one is a replay

    def prepare(self) -> None:
        inner = getattr(self.model, "prepare", None)
        if inner is not None:
            inner()

    def report(self) -> "CoverageReport":
        m = self.model
        rep = CoverageReport(expanded=self.expanded, filename=m.program.filename,
                             guards_exact=not m.guards_rand)
        for e, ev in enumerate(m.program.events):
            fired = self.fired.get(e, 0)
            held = self.held.get(e, 0) if not m.guards_rand else fired
            rep.events.append({"event": ev.name, "line": ev.guard.span.line,
                               "guard_held": held, "fired": fired})
        for sid, s in sorted(m.compiled.stmts.items(), key=lambda kv: (kv[1].span.line, kv[1].span.column)):
            ev = m.compiled.stmt_event.get(sid)
            if ev is None:           # Init runs before the search, outside it
                continue
            if not self.executed.get(sid):
                rep.unexecuted.append({"event": m.program.events[ev].name, "line": s.span.line,
                                       "column": s.span.column, "source": D.source_line(m, s.span)})
        return rep


@dataclass
class CoverageReport:
    expanded: int
    filename: str
    guards_exact: bool = True
    events: list = field(default_factory=list)
    unexecuted: list = field(default_factory=list)

    @property
    def never_fired(self) -> list:
        return [e["event"] for e in self.events if e["fired"] == 0]

    def as_dict(self) -> dict:
        return {"states_expanded": self.expanded, "events": self.events,
                "never_fired": self.never_fired, "unexecuted": self.unexecuted}

    def lines(self) -> list:
        out = [f"coverage ({self.expanded:,} states expanded; Init is not counted):"]
        w = max([len(e["event"]) for e in self.events] + [5])
        out.append(f"  {'event':<{w}}  {'line':>5}  {'guard held':>10}  {'fired':>10}")
        for e in self.events:
            flag = "  never fired" if e["fired"] == 0 else ""
            out.append(f"  {e['event']:<{w}}  {e['line']:>5}  {e['guard_held']:>10,}  "
                       f"{e['fired']:>10,}{flag}")
        if self.unexecuted:
            out.append("statements never executed:")
            for s in self.unexecuted:
                out.append(f"  {self.filename}:{s['line']}: [{s['event']}] {s['source']}")
        else:
            out.append("statements never executed: none")
        return out
