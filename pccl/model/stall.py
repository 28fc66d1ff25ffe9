"""Stalls: what ``pccl explore`` compares, and what a stalled agent waits on.

A *stall* (docs/temporal.md) is a reachable state from which every run only
lets time pass: no transition can ever change the team's *signature* —
shared and allread variables, the ``loc:`` variables a property reads,
positions, doReach targets and flags, statuses and the lock queue — though
not every agent has exited and time still advances.  The check itself runs
on the recorded state graph (:func:`pccl.search.liveness.analyse`); this module
gives it the signature of a state (:func:`signature_fn`) and, for the
report, what each running agent of a stalled state waits on
(:func:`waiting`).

A ``loc:`` variable that no property reads is private to its agent: no
other agent, no guard of another agent, no property and no blackbox reads
it, so changing it alone is not progress (an agent that spins on a private
counter while it waits is stalled).  Leaving these variables out is also
what makes the check exact under statement merging and partial-order
reduction, whose hidden steps change only such variables (docs/reductions.md).
"""

from __future__ import annotations

import marshal
from collections.abc import Callable

import xxhash

from pccl.lang import ast as A
from pccl.model.layout import AGS, AR, DONE, END, FAIL, LOC, LQ, PC, POS, REACH, RUNNING, SH, STATUS, TARGET

__all__ = ["signature_fn", "waiting", "waiting_text"]


def _visible_locals(model) -> list:
    """Slots of the ``loc:`` variables some property reads."""
    from pccl.model.independence import property_names
    names = property_names(model)
    return sorted(vs.slot for vs in model.compiled.layout.local if vs.name in names)


def signature_fn(model, progress: bool = False) -> Callable:
    """``sig(state) -> int``: a 64-bit hash of the state's signature (the
    clock, the phase, pcs, counters, private locals and the blackbox's own
    state left out), as a signed int64 (the graph recorder's column).
    ``progress``: the frozen-team check's progress signature
    (:mod:`pccl.model.frozen`), the same without the lock queue and the
    doReach flags.  Generated per model: one tuple, one encoding and one
    hash per call (the agents' part a list: cheaper to make than a tuple).
    The hash is xxh3-64 of the signature's marshal encoding (the values the
    native engine's signature tells apart, as its interned ids do), not
    Python's ``hash()``: that one is equal for -1 and -2 and for ints
    2**61 - 1 apart, so a transition from ``s = -1`` to ``s = -2`` read as
    no change (a merged chain cut where it did not end where it began; the
    stall check blind to that change)."""
    slots = _visible_locals(model)
    loc = "(" + "".join(f"ag[{LOC}][{s}], " for s in slots) + ")" if slots else "()"
    lq = "" if progress else f"st[{LQ}], "
    flags = "" if progress else f"ag[{REACH}][{DONE}], ag[{REACH}][{FAIL}], "
    src = (f"def _sig(st):\n"
           f"    return _h(_dumps(({lq}st[{SH}], [(ag[{STATUS}], ag[{AR}], ag[{POS}], "
           f"ag[{REACH}][{TARGET}], {flags}{loc}) "
           f"for ag in st[{AGS}]]), 2)) - 0x8000000000000000\n")
    ns: dict = {}
    exec(compile(src, "<pccl progress signature>" if progress else "<pccl stall signature>", "exec"),
         {"_h": xxhash.xxh3_64_intdigest, "_dumps": marshal.dumps}, ns)
    return ns["_sig"]


# ---------------------------------------------------------------------------
# what a stalled agent waits on
# ---------------------------------------------------------------------------

def _conjuncts(e) -> list:
    if isinstance(e, A.Binary) and e.op == "&&":
        return _conjuncts(e.left) + _conjuncts(e.right)
    return [e]


def _written(model) -> set:
    """Names of the variables some statement writes (assignment targets,
    ``add``/``remove`` lists)."""
    out = set()
    for s in model.compiled.stmts.values():
        t = None
        if isinstance(s, A.Assign):
            t = s.target
        elif isinstance(s, A.CallStmt) and s.name in ("add", "remove") and s.args:
            t = s.args[0]
        while isinstance(t, A.Index):
            t = t.base
        if isinstance(t, A.Name):
            out.add(t.name)
    return out


#: Calls whose value never changes for an agent.
_CONSTANT_CALLS = frozenset({"getAgentIndex", "getNumAgents", "ItemPosition"})


def _never_changes(model, e, written: set) -> bool:
    """Whether ``e`` reads only values that no transition changes: variables
    no statement writes, enum members, constants, the agent's id."""
    lay = model.compiled.layout
    for x in A.walk_expr(e):
        if isinstance(x, A.Name):
            if x.name in lay.members:
                continue
            vs = lay.vars.get(x.name)
            if vs is None or x.name in written:
                return False        # a controller flag, a position, or a written variable
        elif isinstance(x, A.Call):
            if x.name not in _CONSTANT_CALLS and x.name not in model.compiled.functions:
                return False
        elif isinstance(x, A.Quant):
            return False
    return True


def _src(model, span) -> str:
    lines = model.program.source.splitlines()
    if span is None or span.line <= 0 or span.line > len(lines):
        return ""
    if span.line == span.end_line:
        return lines[span.line - 1][span.column - 1:span.end_column - 1].strip()
    return lines[span.line - 1][span.column - 1:].strip()


def _names(e) -> list:
    out: list = []
    for x in A.walk_expr(e):
        if isinstance(x, A.Name) and x.name not in out:
            out.append(x.name)
    return out


def _why(model, i, ag, sh, e) -> str:
    """Why conjunct ``e`` is false for agent i: the values it reads, and for
    ``doReach_done`` the failed doReach behind it."""
    from pccl.lang.values import format_value
    lay = model.compiled.layout
    parts = []
    for n in _names(e):
        if n == "doReach_done":
            if ag[REACH][FAIL]:
                parts.append(f"doReach_fail[{i}] is true: its doReach to "
                             f"{_pos(ag[REACH][TARGET])} failed, so doReach_done[{i}] never "
                             f"becomes true")
            elif ag[REACH][TARGET] is None:
                parts.append(f"doReach_done[{i}] is false (no doReach was called)")
            else:
                parts.append(f"doReach_done[{i}] is false")
        elif n == "doReach_fail":
            parts.append(f"doReach_fail[{i}] is {format_value(ag[REACH][FAIL])}")
        else:
            vs = lay.vars.get(n)
            if vs is None:
                continue
            if vs.section == "allwrite":
                parts.append(f"{n} = {format_value(sh[vs.slot], vs.ty)}")
            elif vs.ty.kind != "array":
                cell = ag[AR] if vs.section == "allread" else ag[LOC]
                parts.append(f"{n}[{i}] = {format_value(cell[vs.slot], vs.ty)}")
    return ", ".join(parts)


def _pos(p) -> str:
    from pccl.lang.values import format_value
    return format_value(p) if p is not None else "?"


def waiting(model, st) -> list:
    """Per running agent of ``st``, what it waits on: ``[(agent, text)]``.
    An agent at the top of its event block lists the events whose guard
    could still hold for it (a guard with a false conjunct that reads only
    values nothing changes, such as ``id == 0`` for agent 1, never will),
    each with the conjuncts that are false and the values behind them."""
    comp = model.compiled
    written = _written(model)
    sh, ags = st[SH], st[AGS]
    out = []
    cache: dict = {}
    for i, ag in enumerate(ags):
        if ag[STATUS] != RUNNING:
            continue
        pc = ag[PC]
        failed = ""
        if ag[REACH][FAIL]:
            failed = (f"; doReach_fail[{i}] is true: its doReach to {_pos(ag[REACH][TARGET])} "
                      f"failed")
        if pc != model.ctl.empty_pc and model.ctl.cells[pc][0] != END:
            out.append((i, f"is {comp.describe_k(pc)}, in an event that changes nothing "
                           f"visible{failed}"))
            continue
        blocked, enabled = _event_waits(model, i, ag, sh, ags, cache, written)
        if any("doReach_done" in _names(ev.guard) for ev in model.program.events):
            failed = ""             # said at the guard that reads doReach_done
        if enabled:
            out.append((i, f"runs {', '.join(enabled)} but changes nothing"
                        + (f", and waits for {' or '.join(blocked)}" if blocked else "")
                        + failed))
        elif blocked:
            out.append((i, "waits for " + " or ".join(blocked) + failed))
        elif model.program.events:
            out.append((i, "waits for nothing: no event of it can ever be enabled again"
                        + failed))
        else:
            out.append((i, "has no event"))
    return out


def _event_waits(model, i, ag, sh, ags, cache: dict, written: set) -> tuple[list, list]:
    """For agent ``i`` at the top of its event block: the events whose guard
    could still hold but does not (with the false conjuncts and the values
    behind them), and the events whose guard holds."""
    comp = model.compiled
    blocked, enabled = [], []
    for ev in model.program.events:
        false = []
        for c in _conjuncts(ev.guard):
            fn = cache.get(id(c))
            if fn is None:
                fn = cache[id(c)] = comp.comp.make_expr(c)
            try:
                ok = bool(fn(i, ag, sh, ags))
            except Exception:       # noqa: BLE001 - a guard error: it does not hold
                ok = False
            if not ok:
                false.append(c)
        if not false:
            enabled.append(ev.name)
            continue
        if any(_never_changes(model, c, written) for c in false):
            continue
        conds = ", ".join(f"`{_src(model, c.span)}` is false"
                          + (f" — {w}" if (w := _why(model, i, ag, sh, c)) else "")
                          for c in false)
        blocked.append(f"{ev.name} (line {ev.guard.span.line}: {conds})")
    return blocked, enabled


def waiting_text(waits: list) -> str:
    return "; ".join(f"agent {i} {w}" for i, w in waits)


# ---------------------------------------------------------------------------
# zero-time runaways
# ---------------------------------------------------------------------------

def runaway_note(model, info: dict) -> str:
    """The note for a search that went ``info["levels"]`` levels without its
    largest model time growing (:class:`pccl.search.explorer.Explorer`'s
    ``on_runaway``): the agent that keeps time from advancing in one of the
    deepest states, and its line, as ``pccl run``'s --max-steps message names
    them."""
    from collections import Counter
    from pccl.lang.values import format_time as fmt_time
    st = info["state"]
    i = looping_agent(model, st, Counter())
    pc = st[AGS][i][PC]
    where = model.compiled.describe_k(pc)
    cell = model.ctl.cells[pc]
    if cell and isinstance(cell[0], int) and cell[0] in model.compiled.stmts:
        text = A.source_line(model.program, model.compiled.stmts[cell[0]].span)
        if text:
            where += f": {text}"
    return (f"zero-time runaway: {info['levels']} levels of the search (to depth "
            f"{info['depth']}) found new states without the model time passing "
            f"t = {fmt_time(info['max_time'])}; agent {i} keeps time from advancing "
            f"({where}); a zero-time loop makes new states for ever: bound the search "
            f"({{max_states}}, {{depth}}, {{max_memory}}) or let time advance in the loop")


def looping_agent(model, st, per_agent) -> int:
    """The agent that keeps time from advancing: mid-event with the most steps."""
    best, best_n = None, -1
    for i, ag in enumerate(st[AGS]):
        mid = ag[PC] != model.ctl.empty_pc
        n = per_agent.get(i, 0) + (10 ** 9 if mid else 0)
        if ag[STATUS] == RUNNING and n > best_n:
            best, best_n = i, n
    return best if best is not None else max(per_agent, key=lambda i: per_agent[i])
