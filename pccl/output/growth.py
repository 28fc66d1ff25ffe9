"""A hint for a search that grows without bound (issue 44.6): the int
variable that keeps growing along the path to the deepest state a bounded
search reached.  An unbounded counter makes the state space infinite; the
bound stops the search, and this names what to bound."""

from __future__ import annotations

from typing import Optional

from pccl.output import display as D

#: A series must take at least this many distinct values, and end at least
#: this far from where it started, to be called growing.
MIN_DISTINCT = 4
MIN_GROWTH = 4


def _series(model, states) -> dict:
    """``{(agent or None, name): [int values along the path]}`` of the int
    variables (shared ones with agent None); undefined values skipped."""
    out: dict = {}
    for st in states:
        for name, ty, v in D.shared_vars(model, st):
            if ty.kind == "int" and isinstance(v, int) and not isinstance(v, bool):
                out.setdefault((None, name), []).append(v)
        for i in range(model.N):
            for name, ty, v in D.agent_vars(model, st, i):
                if ty.kind == "int" and isinstance(v, int) and not isinstance(v, bool):
                    out.setdefault((i, name), []).append(v)
    return out


def _scale(model, series: dict) -> int:
    """The largest magnitude the program itself names: its int literals and
    the int values of the initial state (``--set`` constants, initialisers).
    A counter that stays within it (Fischer's ``c1`` up to ``k``) is bounded
    by the program; one that passes twice it is growing."""
    from pccl.lang import ast as A
    lits = [abs(e.value) for e in A.walk(model.program) if isinstance(e, A.IntLit)]
    firsts = [abs(vals[0]) for vals in series.values()]
    return max(lits + firsts + [0])


def growing_variable(model, states) -> Optional[tuple]:
    """``(agent or None, name, first, last)`` of the int variable that grows
    most along ``states`` (a path from an initial state): its magnitude at
    the end is the largest on the path, beyond anything in the path's first
    half and beyond twice every magnitude the program names (:func:`_scale`),
    over at least :data:`MIN_DISTINCT` values; None if none does."""
    best = None
    half = max(1, len(states) // 2)
    series = _series(model, states)
    scale = 2 * _scale(model, series)
    for (agent, name), vals in series.items():
        if len(vals) < 2 or len(set(vals)) < MIN_DISTINCT:
            continue
        mags = [abs(v) for v in vals]
        end = mags[-1]
        if end < max(mags) or end <= max(mags[:half]) or end - mags[0] < MIN_GROWTH \
                or end <= scale:
            continue
        grow = end - mags[0]
        if best is None or grow > best[0]:
            best = (grow, agent, name, vals[0], vals[-1])
    return None if best is None else best[1:]


def growth_note(model, states, depth: int) -> Optional[str]:
    """The note for a bounded search whose deepest path ``states`` (at
    ``depth``) shows a variable growing, or None."""
    g = growing_variable(model, states)
    if g is None:
        return None
    agent, name, first, last = g
    who = f"`{name}`" + (f" of agent {agent}" if agent is not None else "")
    return (f"the search grows without bound: {who} went from {first} to {last} along the path "
            f"to the deepest state reached (depth {depth}); a variable that keeps growing makes "
            f"new states for ever: bound it in the program (a guard, a modulo) to let the "
            f"search end")
