"""What the search family (pccl/search/) reads of a PCCL state or label,
offered as :class:`pccl.model.engine.Model`'s methods: the search knows no
configuration layout and no display (tests/acceptance/test_architecture.py)."""

from __future__ import annotations

import itertools
import operator
from collections.abc import Callable

from pccl.model.layout import AGS, DISCRETE, DONE, FAIL, PHASE, POS, REACH, TARGET

__all__ = ["time_costs", "arrival_pending", "label_line", "stall_signature", "waiting_note",
           "expand_trace"]

_PHASE_OF = operator.itemgetter(PHASE)
#: the rules whose label's detail is a statement id
_STATEMENT_RULES = frozenset({"STATEMENT", "EXIT", "DOREACH UPDATE", "LOCK REQUEST", "ATOMIC WAIT",
                              "ATOMIC EXECUTION"})


def time_costs(states) -> list:
    """The time steps (of δ) a transition into each of ``states`` costs:
    1 into a dynamic state (exactly a TIME ADVANCE), else 0.  A plain
    function (picklable by name: the parallel workers' graph columns)."""
    return list(map(operator.ne, map(_PHASE_OF, states), itertools.repeat(DISCRETE)))


def arrival_pending(st) -> int:
    """The agents of ``st`` whose doReach is under way, as a bit mask (fair
    arrival: nondet may still let them arrive)."""
    m = 0
    for i, ag in enumerate(st[AGS]):
        reach = ag[REACH]
        t, pos = reach[TARGET], ag[POS]
        if (t is not None and not reach[DONE] and not reach[FAIL]
                and (pos[0] != t[0] or pos[1] != t[1])):
            m |= 1 << i
    return m


def label_line(m, label) -> tuple:
    """Who takes the transition ``label`` and the source line it runs:
    ``(agent or None, line or None)`` (the line of an event's guard for
    EVENT SELECT, of the statement for the statement rules; the same as
    :func:`pccl.output.display.label_info`'s, without the display)."""
    rule, agent, detail = label[:3]
    if detail is None:
        return agent, None
    if rule in ("EVENT SELECT", "EVENT TRANS"):
        return agent, m.program.events[detail].guard.span.line
    if rule in _STATEMENT_RULES:
        span = m.compiled.stmt_span(detail)
        return agent, span.line if span else None
    return agent, None


def stall_signature(m) -> Callable:
    """``sig(state) -> int``, what the stall check compares (pccl/model/stall.py)."""
    from pccl.model.stall import signature_fn
    return signature_fn(m)


def waiting_note(m, st) -> tuple[list, str]:
    """What each running agent of a stalled ``st`` waits on: ``([(agent,
    text)], one line)`` (pccl/model/stall.py)."""
    from pccl.model.stall import waiting, waiting_text
    waits = waiting(m, st)
    return waits, waiting_text(waits)


def expand_trace(m, trace):
    """``trace`` with every merged transition replaced by its steps
    (itself when statements are not merged)."""
    if getattr(m, "merger", None) is None:
        return trace
    from pccl.model.reduce import expand_trace as expand
    return expand(m, trace)
