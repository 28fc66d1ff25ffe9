"""Rendering of configurations, transitions and traces (text, JSON, K style).

Display code is kept apart from the states themselves (pyk style): a state is
plain tuples; everything here reads its cells through the constants of
:mod:`pccl.model.layout` and its variables through the model's slots.
"""

from __future__ import annotations

from typing import Optional

from pccl.model.layout import (AGS, AR, CNT, DISCRETE, DONE, EXITED, FAIL, IDLE, LCK, LOC, LOCK,
                               LQ, N_STATE_CELLS, PC, PHASE, POS, REACH, REQUEST, RUNNING, SH, STATUS,
                               TARGET,
                               TIME, acquire_sid, is_acquire)
from pccl.lang import ast as A
from pccl.lang.values import UNDEF, format_time, format_value

LOCK_NAMES = {IDLE: "idle", REQUEST: "request", LOCK: "lock"}


def fmt_time(t) -> str:
    return format_time(t)


def fmt_pos(p) -> str:
    return format_value(p)


def status_text(model, code) -> str:
    if code == RUNNING:
        return "running"
    if code == EXITED:
        return "exited"
    kind, reason, where = model.compiled.stuck_reasons[code]
    span = model.compiled.span_of(where)
    loc = f" at line {span.line}" if span else ""
    if kind == "assert":
        return f"stuck(assertion failed{loc})"
    return f"stuck({reason}{loc})"


def agent_vars(model, st, i) -> list:
    """[(name, Ty, value)] for agent i's allread and local variables."""
    ag = st[AGS][i]
    lay = model.compiled.layout
    out = [(v.name, v.ty, ag[AR][v.slot]) for v in lay.allread]
    out += [(v.name, v.ty, ag[LOC][v.slot]) for v in lay.local]
    return out


def shared_vars(model, st) -> list:
    return [(v.name, v.ty, st[SH][v.slot]) for v in model.compiled.layout.shared]


def source_line(model, span) -> str:
    return A.source_line(model.program, span)


# ---------------------------------------------------------------------------
# transitions
# ---------------------------------------------------------------------------

def label_info(model, label, before=None) -> dict:
    """Decode a transition label into rule, agent, event, source line."""
    rule, agent, detail = label[:3]
    info = {"rule": rule, "agent": agent, "event": None, "line": None, "source": None}
    sid = None
    if rule in ("EVENT SELECT", "EVENT TRANS") and detail is not None:
        ev = model.program.events[detail]
        info["event"] = ev.name
        info["line"] = ev.guard.span.line
        info["source"] = source_line(model, ev.guard.span)
    elif rule in ("STATEMENT", "EXIT", "DOREACH UPDATE", "LOCK REQUEST", "ATOMIC WAIT",
                  "ATOMIC EXECUTION") and detail is not None:
        sid = detail
    elif rule == "DOREACH INVOKE":
        info["outcome"] = detail
    if sid is not None:
        span = model.compiled.stmt_span(sid)
        info["line"] = span.line if span else None
        info["source"] = source_line(model, span)
        e = model.compiled.stmt_event.get(sid)
        info["event"] = model.program.events[e].name if e is not None else "Init"
    if agent is not None and info["event"] is None and before is not None and rule not in ("IDLE", "SKIP EVENT"):
        info["event"] = current_event(model, before[AGS][agent])
    return info



def short_label(model, label, before, system: str = "system") -> str:
    """A transition in a few words: who (``a0``, or ``system``), the rule,
    and the event it selects or the source line it runs."""
    info = label_info(model, label, before)
    who = f"a{info['agent']}" if info["agent"] is not None else system
    s = f"{who} {info['rule']}"
    if label[0] in ("EVENT SELECT", "EVENT TRANS") and info["event"]:
        s += f" {info['event']}"
    elif info["line"]:
        s += f" L{info['line']}"
    return s

def current_event(model, ag) -> Optional[str]:
    """The event an agent is in the middle of, from the statements in its k."""
    for item in model.ctl.iter_k(ag[PC]):
        sid = item if item >= 0 else (acquire_sid(item) if is_acquire(item) else None)
        if sid is not None:
            e = model.compiled.stmt_event.get(sid)
            return model.program.events[e].name if e is not None else "Init"
    return None


#: A list or array of more elements than this is shortened by
#: :func:`short_value` (the first ``SHORT_HEAD`` and the last two shown).
SHORT_LIMIT = 12
SHORT_HEAD = 8


def short_value(v, ty=None) -> str:
    """:func:`format_value`, with long lists shortened to their first and
    last elements and their length (``[0, 1, …, 999] (1,000 elements)``), at
    any depth: a summary line stays short however large the value (the
    time-step summary of ``pccl run``)."""
    if isinstance(v, tuple) and len(v) > SHORT_LIMIT:
        elem = getattr(ty, "elem", None)
        head = [short_value(x, elem) for x in v[:SHORT_HEAD]]
        tail = [short_value(x, elem) for x in v[-2:]]
        return "[" + ", ".join(head + ["…"] + tail) + f"] ({len(v):,} elements)"
    if isinstance(v, tuple) and any(isinstance(x, tuple) for x in v):
        elem = getattr(ty, "elem", None)
        return "[" + ", ".join(short_value(x, elem) for x in v) + "]"
    return format_value(v, ty)


def diff(model, a, b, fmt=format_value) -> list:
    """[(cell, old, new)] for what changed between two configurations
    (values shown by ``fmt``)."""
    out = []
    if a[TIME] != b[TIME]:
        out.append(("time", fmt_time(a[TIME]), fmt_time(b[TIME])))
    if a[PHASE] != b[PHASE]:
        out.append(("transitionState", _phase(a[PHASE]), _phase(b[PHASE])))
    if a[LQ] != b[LQ]:
        out.append(("lockQueue", _lq(a[LQ]), _lq(b[LQ])))
    for (n, ty, va), (_, _, vb) in zip(shared_vars(model, a), shared_vars(model, b)):
        if va != vb:
            out.append((n, fmt(va, ty), fmt(vb, ty)))
    for i, (ga, gb) in enumerate(zip(a[AGS], b[AGS])):
        if ga is not gb:
            out += _agent_diff(model, a, b, i, fmt)
    return out


def _agent_diff(model, a, b, i, fmt) -> list:
    """Step of :func:`diff`: what changed in agent ``i``'s cell."""
    out = []
    ga, gb = a[AGS][i], b[AGS][i]
    for (n, ty, va), (_, _, vb) in zip(agent_vars(model, a, i), agent_vars(model, b, i)):
        if va != vb:
            out.append((f"{n}[{i}]", fmt(va, ty), fmt(vb, ty)))
    if ga[POS] != gb[POS]:
        out.append((f"pos[{i}]", fmt_pos(ga[POS]), fmt_pos(gb[POS])))
    if ga[LCK] != gb[LCK]:
        out.append((f"lockState[{i}]", LOCK_NAMES[ga[LCK]], LOCK_NAMES[gb[LCK]]))
    if ga[STATUS] != gb[STATUS]:
        out.append((f"status[{i}]", status_text(model, ga[STATUS]),
                    status_text(model, gb[STATUS])))
    ra, rb = ga[REACH], gb[REACH]
    if ra[TARGET] != rb[TARGET]:
        out.append((f"target[{i}]", _opt_pos(ra[TARGET]), _opt_pos(rb[TARGET])))
    if ra[DONE] != rb[DONE]:
        out.append((f"doReach_done[{i}]", format_value(ra[DONE]), format_value(rb[DONE])))
    if ra[FAIL] != rb[FAIL]:
        out.append((f"doReach_fail[{i}]", format_value(ra[FAIL]), format_value(rb[FAIL])))
    return out


def _opt_pos(p):
    return "none" if p is None else fmt_pos(p)


def _phase(p):
    return "discrete" if p == DISCRETE else "dynamic"


def _lq(q):
    return "[" + ", ".join(str(x) for x in q) + "]"


def format_step(model, n, label, before, after, *, show_diff=True) -> str:
    info = label_info(model, label, before)
    who = f"agent {info['agent']}" if info["agent"] is not None else "system"
    parts = [f"{n:>4}. t={fmt_time(before[TIME])}", f"{who:<8}", f"{info['rule']:<16}"]
    if info["event"]:
        parts.append(f"[{info['event']}]")
    if info["line"]:
        parts.append(f"line {info['line']}: {info['source']}")
    text = "  ".join(parts)
    if show_diff:
        ch = diff(model, before, after)
        ch = [c for c in ch if c[0] not in ("transitionState",)]
        if ch:
            text += "\n" + " " * 8 + ", ".join(f"{c} {o} -> {nw}" for c, o, nw in ch)
    return text


# ---------------------------------------------------------------------------
# configurations
# ---------------------------------------------------------------------------

def format_state(model, st, *, indent="  ") -> str:
    lines = [f"{indent}time {fmt_time(st[TIME])}, {_phase(st[PHASE])}, lockQueue {_lq(st[LQ])}"]
    sv = shared_vars(model, st)
    if sv:
        lines.append(indent + "shared: " + ", ".join(f"{n} = {format_value(v, t)}" for n, t, v in sv))
    if len(st) > N_STATE_CELLS and st[N_STATE_CELLS] is not None:
        lines.append(indent + "round start (what robots still to act in this round read): "
                     + round_text(model, st))
    for i, ag in enumerate(st[AGS]):
        head = (f"{indent}agent {i}: {status_text(model, ag[STATUS])}, {model.compiled.describe_k(ag[PC])}, "
                f"counter {ag[CNT]}, lock {LOCK_NAMES[ag[LCK]]}, pos {fmt_pos(ag[POS])}")
        r = ag[REACH]
        if r[TARGET] is not None:
            head += (f", target {fmt_pos(r[TARGET])}, done {format_value(r[DONE])}, "
                     f"fail {format_value(r[FAIL])}")
        lines.append(head)
        av = agent_vars(model, st, i)
        if av:
            lines.append(indent + "  " + ", ".join(f"{n} = {format_value(v, t)}" for n, t, v in av))
    return "\n".join(lines)


def round_text(model, st) -> str:
    """The round cell of a configuration under Koord's semantics
    (pccl/model/koord.py): the values of the round's start that differ from
    the global store."""
    sh0, ar0 = st[N_STATE_CELLS]
    lay = model.compiled.layout
    parts = [f"{v.name} = {format_value(sh0[v.slot], v.ty)}" for v in lay.shared
             if sh0[v.slot] != st[SH][v.slot]]
    for i, ag in enumerate(st[AGS]):
        parts += [f"{v.name}[{i}] = {format_value(ar0[i][v.slot], v.ty)}" for v in lay.allread
                  if ar0[i][v.slot] != ag[AR][v.slot]]
    return ", ".join(parts)


def format_state_k(model, st) -> str:
    """The configuration as the paper's Section 5 prints it: per-agent memory
    maps (variable |-> address), gMemory, MMap (address |-> value), time.
    Under sequential consistency shared variables have one address, which
    every agent's memory map points to."""
    lay = model.compiled.layout
    gmem = {v.name: k for k, v in enumerate(lay.shared)}
    addr = len(lay.shared)
    mmap = {gmem[n]: (v, t) for n, t, v in shared_vars(model, st)}
    out = []
    for i, ag in enumerate(st[AGS]):
        mem = dict(gmem)
        for n, t, v in agent_vars(model, st, i):
            mem[n] = addr
            mmap[addr] = (v, t)
            addr += 1
        out.append("<agent> ... <memory> " + " ".join(f"{n} |-> {a}" for n, a in mem.items())
                   + f"\n</memory> <id> {i} </id> <counter> {ag[CNT]} </counter> "
                   f"<lockState> {LOCK_NAMES[ag[LCK]]} </lockState> "
                   f"<position> {fmt_pos(ag[POS])} </position>"
                   f" <status> {status_text(model, ag[STATUS])} </status>\n</agent>")
    out.append("<gMemory> " + " ".join(f"{n} |-> {a}" for n, a in gmem.items()) + " </gMemory>")
    out.append("<MMap> " + " ".join(f"{a} |-> {_kval(v, t)}" for a, (v, t) in sorted(mmap.items()))
               + "\n</MMap>")
    out.append(f"<lockQueue> {' '.join(map(str, st[LQ])) or '.List'} </lockQueue>")
    out.append(f"<transitionState> {_phase(st[PHASE])} </transitionState>")
    out.append(f"<time> {fmt_time(st[TIME])} </time>")
    return "\n".join(out)


def _kval(v, t):
    if v is UNDEF:
        return "undef"
    return format_value(v, t)
