"""Counterexamples as short as the program's bug (issue 44.3).

The reductions (docs/reductions.md) search a smaller graph, so the first
violation they find is reached by a shortest path *of the reduced graph*;
expanded into the rules' steps it may be longer than the shortest path of
the unreduced semantics (partial-order reduction delays steps, statement
merging runs an agent's private statements in one go).  Before a
counterexample is shown, :func:`shortest_paths` searches the unreduced
model breadth-first for a shortest path to a state with the *same*
violation (equal kind, property, message, agent and location), at most as
long as the reduced trace (so it always exists: the expanded trace is such
a path) and within a state budget (:data:`MAX_STATES`), so that a huge
unreduced space cannot hold up the verdict.  The verdict never changes;
only the path shown does.

The graph checks (time-locks, stalls, temporal properties) are decided on
the whole graph; :func:`pccl.api.explore_model` shortens their lassos by a
search without the reductions within the same budget.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

from pccl.search.explorer import Trace, terminal
from pccl.search.fingerprint import encode, fingerprint

__all__ = ["MAX_STATES", "MAX_STATES_NATIVE", "Shortening", "shortest_paths", "STATE_KINDS"]

#: States a search without the reductions may admit to shorten the
#: counterexamples of one verdict (docs/reductions.md, "Counterexamples"):
#: on the Python engine, and on the native engine where it can serve the
#: unreduced model (it then runs that search whichever engine ran the
#: reduced one, so that the path shown does not depend on the engine).
MAX_STATES = 100_000
MAX_STATES_NATIVE = 1_000_000

#: Violations that are a property of one state (found by the search itself);
#: the others (timelock, stall, liveness, response) are the graph analysis's.
STATE_KINDS = frozenset({"invariant", "assert", "stuck", "deadlock", "collision"})


@dataclass(frozen=True)
class Shortening:
    """What shortening did to one counterexample: ``status`` is
    ``"shortened"`` (a shorter path of the unreduced semantics is shown),
    ``"confirmed"`` (the reduced search's path is already a shortest one),
    ``"not-shown"`` (the search without the reductions could not tell:
    ``reason`` says why) or ``"off"`` (not asked for); ``reduced_steps``:
    the steps of the path the reduced search found (expanded), and for a
    lasso ``reduced_cycle_start`` where its cycle began."""
    status: str
    reduced_steps: int
    reason: Optional[str] = None
    reduced_cycle_start: Optional[int] = None

    @property
    def shortest(self) -> bool:
        return self.status in ("shortened", "confirmed")

    def as_dict(self) -> dict:
        out: dict = {"status": self.status, "reduced_steps": self.reduced_steps,
                     "reason": self.reason}
        if self.reduced_cycle_start is not None:
            out["reduced_cycle_start"] = self.reduced_cycle_start
        return out


def shortest_paths(model, targets: list, *, max_states: int = MAX_STATES,
                   deadlock: bool = True, find_all: bool = False) -> tuple:
    """Breadth-first search of ``model`` (the unreduced :class:`Model`) for a
    shortest path to each violation of ``targets`` (``[(violation, steps)]``:
    a violation of :data:`STATE_KINDS` and the length of the path found so
    far; only shorter paths are looked for).  Returns ``(paths, complete)``:
    ``paths[i]`` is a :class:`Trace` shorter than ``targets[i]``'s steps, or
    None when there is none; ``complete`` is False when the state budget
    stopped the search before every target was decided (then a None means
    "not known").  As the explorer does, a state with a violation is not
    expanded unless ``find_all``; deadlocks count only with ``deadlock``."""
    search = _Search(model, targets, max_states, deadlock, find_all)
    return search.paths, search.run()


class _Search:
    """The breadth-first search of :func:`shortest_paths`."""

    def __init__(self, model, targets: list, max_states: int, deadlock: bool, find_all: bool):
        self.model, self.targets, self.max_states = model, targets, max_states
        self.deadlock, self.find_all = deadlock, find_all
        self.want: dict = {}
        for i, (v, steps) in enumerate(targets):
            self.want.setdefault(v, []).append((i, steps))
        self.paths: list = [None] * len(targets)
        #: target numbers not decided yet
        self.open = set(range(len(targets)))
        #: (parent number, position among the parent's successors) per state
        self.parent: list = []
        self.seen: set = set()

    def admit(self, st, parent: int, pos: int, out: list) -> bool:
        """Admit ``st`` unless seen; False when the budget is used up."""
        fp = fingerprint(encode(self.model.plain_key(st)))
        if fp in self.seen:
            return True
        if len(self.seen) >= self.max_states:
            return False
        self.seen.add(fp)
        self.parent.append((parent, pos))
        out.append((len(self.parent) - 1, st))
        return True

    def hit(self, number: int, depth: int, found: list) -> None:
        for v in found:
            for i, steps in self.want.get(v, ()):
                if i in self.open and depth < steps:
                    self.paths[i] = _rebuild(self.model, self.parent, number)
                    self.open.discard(i)

    def run(self) -> bool:
        """Search; True when every target was decided."""
        horizon = max((steps for _, steps in self.targets), default=0) - 1
        level: list = []
        for pos, st in enumerate(self.model.init_states()):
            if not self.admit(st, -1, pos, level):
                return False
        depth = 0
        while level and self.open and depth <= horizon:
            nxt: list = []
            for number, st in level:
                if not self.expand(number, st, depth, depth < horizon, nxt):
                    return not self.open
            level = nxt
            depth += 1
            # a target whose path would now be no shorter is decided
            self.open = {i for i in self.open if self.targets[i][1] > depth}
        return True

    def expand(self, number: int, st, depth: int, deeper: bool, nxt: list) -> bool:
        """Check state ``number`` and admit its successors (``deeper``);
        False when the budget is used up."""
        m = self.model
        found = m.fast_violations(st)
        if found:
            self.hit(number, depth, found)
            if not self.find_all:
                return True
        out = m.plain_successors(st) if self.open else ()
        if self.open and not out:
            _, v = terminal(m, st, self.deadlock)
            if v is not None:
                self.hit(number, depth, [v])
        if deeper:
            for pos, (_, s2) in enumerate(out):
                if not self.admit(s2, number, pos, nxt):
                    return False
        return True


def _rebuild(model, parent: list, number: int) -> Trace:
    """The path to state ``number``, replayed from the recorded positions
    (the model is deterministic: docs/architecture.md)."""
    chain = []
    while number != -1:
        p, pos = parent[number]
        chain.append(pos)
        number = p
    chain.reverse()
    st: Any = list(model.init_states())[chain[0]]
    states, labels = [st], []
    for pos in chain[1:]:
        label, st = model.plain_successors(st)[pos]
        states.append(st)
        labels.append(label)
    return Trace(tuple(states), tuple(labels))
