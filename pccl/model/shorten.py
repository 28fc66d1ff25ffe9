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

__all__ = ["MAX_STATES", "Shortening", "shortest_paths", "STATE_KINDS"]

#: States the search without the reductions may admit to shorten the
#: counterexamples of one verdict (docs/reductions.md, "Counterexamples").
MAX_STATES = 100_000

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
    want: dict = {}
    for i, (v, steps) in enumerate(targets):
        want.setdefault(v, []).append((i, steps))
    paths: list = [None] * len(targets)
    horizon = max((steps for _, steps in targets), default=0) - 1
    if horizon < 0:
        return paths, True
    key, succ, viols = model.plain_key, model.plain_successors, model.fast_violations
    # (parent number, position among the parent's successors) per admitted state
    parent: list = []
    seen: set = set()
    level: list = []
    for pos, st in enumerate(model.init_states()):
        fp = fingerprint(encode(key(st)))
        if fp in seen:
            continue
        seen.add(fp)
        parent.append((-1, pos))
        level.append((len(parent) - 1, st))
    open_ = {v: [i for i, _ in ws] for v, ws in want.items()}

    def hit(number: int, depth: int, found: list) -> None:
        for v in found:
            for i, steps in want.get(v, ()):
                if paths[i] is None and depth < steps:
                    paths[i] = _rebuild(model, parent, number)
                    open_[v].remove(i)
            if v in open_ and not open_[v]:
                del open_[v]

    depth = 0
    while level and open_:
        nxt: list = []
        for number, st in level:
            found = viols(st)
            if found:
                hit(number, depth, found)
                if not find_all:
                    continue
            if not open_:
                break
            out = succ(st)
            if not out:
                _, v = terminal(model, st, deadlock)
                if v is not None:
                    hit(number, depth, [v])
                continue
            if depth >= horizon:
                continue
            for pos, (_, s2) in enumerate(out):
                fp = fingerprint(encode(key(s2)))
                if fp in seen:
                    continue
                if len(seen) >= max_states:
                    return paths, not open_
                seen.add(fp)
                parent.append((number, pos))
                nxt.append((len(parent) - 1, s2))
        level = nxt
        depth += 1
        # every target whose path would now be no shorter is decided
        for v in list(open_):
            open_[v] = [i for i in open_[v] if targets[i][1] > depth]
            if not open_[v]:
                del open_[v]
    return paths, True


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
