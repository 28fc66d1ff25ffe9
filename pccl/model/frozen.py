"""Frozen teams: a team that runs for ever, busy, but can never do anything
useful again (docs/temporal.md#frozen-teams).

The stall check (:mod:`pccl.model.stall`) catches a team that can never
change again.  A team can also be *frozen* while it keeps changing
something: a robot whose doReach fails retries it for ever (its
``doReach_fail`` flag goes false and true again), and the others
busy-wait on the corner it holds (taking and releasing the lock at every
step).  A reachable state is **frozen** when

* no run from it ends (no terminal state is reachable) and time advances
  (a time-locked state is the time-lock check's);
* no transition reachable from it changes the team's *progress
  signature*: the stall signature (shared and allread variables, the
  ``loc:`` variables a property reads, positions, doReach targets,
  statuses) without the lock queue and the doReach flags, so that taking
  and releasing the lock and retrying a doReach to the same target do not
  count as progress;
* and some event of the program can never fire again from it (for any
  agent): it fired before, or it never fires at all.

The first frozen state in breadth-first order is reported as a violation
``frozen``, with the shortest path to it and the events that can never
fire again (with their guards) and those that still do.

**One-shot events.** An event that fires once and never again (``Start()``
guarded by ``!started``) is not a frozen team by itself: a team that
keeps making progress (a variable, a position or a target keeps changing)
is never reported, whatever events stopped firing.  So only a team that
keeps running without progress is, and it is named by the events that it
can no longer fire.

**How it is decided.** On a clean exhaustive verdict (and with the stall
check on), over the search's own graph: a search of one process (the
Python engine, the native engine's batches and its level kernel, on one
thread or several) records with the graph the time-lock and stall checks
read each transition's label and each state's progress signature and
whether some transition out of it changes it
(:class:`pccl.search.liveness.FrozenColumns`); :func:`check_recorded`
decides on them, whatever the number of states.  Where the graph came
without them (``--workers N`` as processes, Ray, ``--fastest``, a
checkpoint), :func:`check` explores the reduced model again, in Python,
with every transition's event label and progress change kept, up to
:data:`LIMIT` states; above that the check does not run and the verdict
says so.  Both are the same graph (the reduced model of the search,
breadth-first, in the same order) and the same decision
(:func:`_decide`); :func:`check` stays as the reference the tests hold
:func:`check_recorded` to (docs/reductions.md, "Frozen teams").
Backward reachability over that graph (:class:`pccl.search.liveness.Graph`)
then finds the states that can reach a progress change, a terminal state
or a firing of each event.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np


__all__ = ["LIMIT", "FrozenResult", "progress_signature_fn", "progress_signatures_fn", "check",
           "check_recorded", "FROZEN_MESSAGE"]

#: the most states the check explores again (in Python: about 30,000 states per CPU
#: second and 1.3 KB per state on fischer, measured 2026-12-07: at most about
#: 0.7 s and 26 MB more than the search; fischer's 46,108 states took 1.9 s, 4 times
#: its native search, and doubled its peak memory)
LIMIT = 20_000

#: The start of a frozen team's verdict (the events follow).
FROZEN_MESSAGE = ("frozen: the team runs for ever, but nothing it does can change a variable, "
                  "a position or a doReach target again")


@dataclass
class FrozenResult:
    """The outcome of :func:`check`: ``ran`` (False: ``reason`` says why
    not), and for a frozen team the violation and its trace (states and
    labels of the model, merged transitions expanded)."""
    ran: bool
    reason: Optional[str] = None
    violation: Any = None
    trace: Any = None
    states: int = 0
    seconds: float = 0.0


def progress_signature_fn(model) -> Callable:
    """``sig(state) -> int``: a 64-bit hash of the state's progress
    signature (the stall signature without the lock queue and the doReach
    flags), as a signed int64: :func:`pccl.model.stall.signature_fn`'s
    ``progress``."""
    from pccl.model.stall import signature_fn
    return signature_fn(model, progress=True)


def progress_signatures_fn(model) -> Callable:
    """``sigs(states) -> int64 array``: :func:`progress_signature_fn` of a
    list of states (the native model's own C call where it has one: the
    same fields), as the graph recorder reads them."""
    many = getattr(model, "progress_signatures", None)
    if many is not None:
        return many
    one = progress_signature_fn(model)
    return lambda states: np.fromiter(map(one, states), dtype=np.int64, count=len(states))


@dataclass
class _Graph:
    """The labelled graph :func:`_explore` builds."""
    states: list
    parent: list           # per state: (parent number, label), or None for an initial state
    src: np.ndarray
    dst: np.ndarray
    event: np.ndarray      # per transition: the event it fires (EVENT SELECT), else -1
    changes: np.ndarray    # per state: some transition out of it changes the progress signature


def _explore(model, limit: int, native: Any = None) -> Optional[_Graph]:
    """Breadth-first over ``model`` (the reduced model of the search), with
    each transition's event and progress change; None past ``limit``
    states.  A change is decided on the successor as made, before the
    symmetry reduction renames it (as the stall check does).  With
    ``native`` (the search's :class:`pccl.model.native.NativeModel` of
    ``model``) its successors and keys (the same relation, in the same
    order), the states its vectors, the signature its slots (in C)."""
    if native is not None:      # (the signature's slots, compared as bytes)
        sig, key, succ, first = native.lib.progsig, native.key, native.successors, native.init_states()
    else:
        sig, key, succ = progress_signature_fn(model), model.key, model.successors
        first = model.init_states()
    index: dict = {}
    states: list = []
    parent: list = []
    for s in first:
        k = key(s)
        if k not in index:
            index[k] = len(states)
            states.append(s)
            parent.append(None)
    src: list = []
    dst: list = []
    event: list = []
    changes = []
    i = 0
    while i < len(states):
        s = states[i]
        here = sig(s)
        changed = False
        for lab, t in succ(s):
            k = key(t)
            j = index.get(k)
            if j is None:
                if len(states) >= limit:
                    return None
                j = index[k] = len(states)
                states.append(t)
                parent.append((i, lab))
            src.append(i)
            dst.append(j)
            event.append(_event_of(lab))
            if not changed and sig(t) != here:
                changed = True
        changes.append(changed)
        i += 1
    return _Graph(states, parent, np.asarray(src, dtype=np.uint32), np.asarray(dst, dtype=np.uint32),
                  np.asarray(event, dtype=np.int32), np.asarray(changes, dtype=bool))


def _frozen_events(model, gr: _Graph, native: Any = None):
    """The first frozen state (breadth-first), the events that can never
    fire again from it and those that still fire there, or None."""
    n = len(gr.states)
    dyn = np.fromiter((native or model).time_costs(gr.states), dtype=np.uint8, count=n).astype(bool)
    return _decide(model, n, gr.src, gr.dst, gr.event, gr.changes, dyn)


def _decide(model, n: int, src: np.ndarray, dst: np.ndarray, event: np.ndarray,
            changes: np.ndarray, dyn: np.ndarray, kernel: Optional[Callable] = None):
    """The decision of both checks over a graph of ``n`` states (its
    transitions ``src -> dst`` by source, each one's ``event`` or -1, per
    state ``changes`` and ``dyn``): the first frozen state, the events that
    can never fire again from it, those that still fire there and those
    that fired anywhere; or None.  (``kernel``: the native engine's
    backward reachability, :attr:`pccl.search.liveness.Graph.kernel`.)"""
    from pccl.search.liveness import Graph
    g = Graph(n, None, dst, src, dyn, None, None)
    g.kernel = kernel
    bad = g.terminal | changes
    bad |= ~g.can_reach(g.dyn)
    frozen = ~g.can_reach(bad)
    if not frozen.any():
        return None
    first, dead = None, {}
    for e in range(len(model.program.events)):
        fires = np.zeros(n, dtype=bool)
        fires[src[event == e]] = True
        mask = frozen & ~g.can_reach(fires)
        hits = np.flatnonzero(mask)
        if hits.size:
            dead[e] = mask
            if first is None or hits[0] < first:
                first = int(hits[0])
    if first is None:
        return None
    never = [e for e, mask in dead.items() if mask[first]]
    after = g.reach(np.asarray([first]))
    live = sorted({int(e) for e in np.unique(event[after[src]]) if e >= 0})
    fired = {int(e) for e in np.unique(event) if e >= 0}
    return first, never, live, fired


def _guard(model, e: int) -> str:
    from pccl.model.stall import _src
    ev = model.program.events[e]
    return f"{ev.name} (line {ev.guard.span.line}: `{_src(model, ev.guard.span)}`)"


def _message(model, never: list, live: list, fired: set) -> str:
    """The verdict: the events that can never fire again, with their
    guards (those that fired before first), and those that still fire."""
    evs = model.program.events
    parts = []
    for group, tail in (([e for e in never if e in fired], "can never fire again (fired before)"),
                        ([e for e in never if e not in fired], "never fire")):
        if group:
            names = [_guard(model, e) for e in group]
            text = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
            parts.append(f"event{'s' if len(group) > 1 else ''} {text} "
                         + (tail if len(group) > 1 or tail.startswith("can")
                            else "never fires"))
    msg = FROZEN_MESSAGE + ": " + "; ".join(parts)
    if live:
        msg += "; still firing: " + ", ".join(f"{evs[e].name} (line {evs[e].guard.span.line})"
                                             for e in live)
    return msg


def _expanded(model, trace):
    """``trace`` with its merged transitions replaced by their steps (the
    last one whole: its end is the frozen state the graph found)."""
    if getattr(model, "merger", None) is None:
        return trace
    return model.expand_trace(trace)


def check(model, limit: int = LIMIT, native: Any = None) -> FrozenResult:
    """Is the team of ``model`` (a reduced model, :class:`pccl.model.reduce.Reduced`)
    frozen somewhere?  Explores it again (see the module docstring); with
    ``native`` (the search's native model of ``model``) on the native
    engine, the same graph in the same order."""
    import time
    from pccl.search.explorer import Trace
    t0 = time.perf_counter()
    gr = _explore(model, limit, native)
    if gr is None:
        return FrozenResult(False, f"more than {limit:,} states: the check explores the "
                                   f"graph again up to {limit:,}",
                            seconds=time.perf_counter() - t0)

    def trace_to(first: int):
        states, labels = [gr.states[first]], []
        at = first
        while gr.parent[at] is not None:
            at, lab = gr.parent[at]
            states.append(gr.states[at])
            labels.append(lab)
        if native is not None:      # (the native vectors as configurations)
            states = [native.decode(b) for b in states]
        return Trace(tuple(reversed(states)), tuple(reversed(labels)))
    return _result(model, len(gr.states), _frozen_events(model, gr, native), trace_to, t0)


def _result(model, n: int, found, trace_to: Callable[[int], Any], t0: float) -> FrozenResult:
    """The outcome of both checks over a graph of ``n`` states: ``found``
    (:func:`_decide`'s) as a violation ``frozen`` with the path to its
    first frozen state (``trace_to(first)``: the states and labels of the
    model), merged transitions expanded."""
    import time
    from pccl.search.liveness import TemporalViolation
    out = FrozenResult(True, states=n)
    if found is not None:
        first, never, live, fired = found
        out.trace = _expanded(model, trace_to(first))
        out.violation = TemporalViolation("frozen", "frozen", _message(model, never, live, fired))
    out.seconds = time.perf_counter() - t0
    return out


def _event_of(label) -> int:
    """The event a transition's label fires (EVENT SELECT), else -1."""
    return (label[2] if isinstance(label, tuple) and len(label) > 2 and label[0] == "EVENT SELECT"
            and label[2] is not None else -1)


def recorded(rec) -> bool:
    """Whether the graph recorder ``rec`` (:class:`pccl.search.liveness.GraphRecorder`)
    holds all that :func:`check_recorded` reads: every transition with its
    label, every state with its progress signature and change flag."""
    fz = getattr(rec, "frozen", None)
    return fz is not None and fz.whole and rec.complete


def decide_recorded(model, rec, n: int, kernel: Optional[Callable] = None):
    """The decision of :func:`check_recorded` (:func:`_decide` over the
    recorded graph), without the trace: arrays in, arrays out, the model
    only read (its events), so that it can run on a thread of its own
    beside the search's other graph checks (``--workers N``: :func:`pccl.api._analyse`)."""
    fz = rec.frozen
    m = rec.src.n
    src, dst = rec.src.view()[:m], rec.dst.view()[:m]
    lab = fz.lab.view()[:m]
    labels = fz.label_list()
    ev_of = np.asarray([_event_of(x) for x in labels] + [-1], dtype=np.int32)
    event = ev_of[np.where(lab < 0, len(labels), lab)]
    if len(src) > 1 and not bool((src[1:] >= src[:-1]).all()):      # by source
        order = np.argsort(src, kind="stable")
        src, dst, event = src[order], dst[order], event[order]
    changes = fz.pchg.view()[:n].astype(bool)
    dyn = rec.dyn.view()[:n].astype(bool)
    return _decide(model, n, src, dst, event, changes, dyn, kernel)


def check_recorded(model, rec, n: int, replay: Callable[[list], Any], table,
                   kernel: Optional[Callable] = None, decided: Optional[Callable] = None) -> FrozenResult:
    """:func:`check` over the graph the search recorded (``rec``, with
    :func:`recorded`; ``n`` states): no second exploration.  ``replay``
    turns a chain of state numbers into the trace of the model's states
    (the explorer's, decoded on the native engine); ``table`` gives the
    breadth-first parents; ``kernel`` the native engine's backward
    reachability (or None); ``decided``: returns :func:`decide_recorded`'s
    answer, made already (on another thread), instead of deciding here."""
    import time
    from pccl.search.liveness import _chain_to
    t0 = time.perf_counter()
    found = decided() if decided is not None else decide_recorded(model, rec, n, kernel)
    return _result(model, n, found, lambda first: replay(_chain_to(table, first)), t0)
