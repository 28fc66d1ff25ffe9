"""Text views of a trace (``--view steps|swimlane`` in run, explore, replay).

``steps``
    The initial state first, then one line per step as the default trace
    prints it, with the branch an ``if``/``while`` took; runs of steps that
    change nothing (and take no branch) are folded into one line unless
    ``full``.
``swimlane``
    One column per agent and one for the shared variables; a block per time
    step; one row per step, in the column of the agent that made it, saying
    what it did (the event it selected, the branch it took, what it
    changed).  The width follows the terminal (:func:`shutil.get_terminal_size`).
"""

from __future__ import annotations

import shutil
import textwrap

from pccl.output import display as D
from pccl.output import traces as T
from pccl.model.layout import AGS, POS, STATUS, TIME
from pccl.lang.values import format_value


def render(view, model, trace, *, full=False, width=None) -> str:
    """The text view ``view`` of a path (a :class:`pccl.search.explorer.Trace`)."""
    states, labels = trace.states, trace.labels
    if view == "swimlane":
        return swimlane(model, states, labels, full=full, width=width)
    return steps(model, states, labels, full=full, width=width)


def terminal_width(width=None) -> int:
    if width is not None:
        return width
    return max(40, shutil.get_terminal_size((100, 24)).columns)


def _visible_changes(model, a, b) -> list:
    return [c for c in D.diff(model, a, b) if c[0] != "transitionState"]


# ---------------------------------------------------------------------------
# steps
# ---------------------------------------------------------------------------

def steps(model, states, labels, *, full=False, width=None) -> str:
    w = terminal_width(width)
    out = ["initial state:", D.format_state(model, states[0])]
    folded: list = []

    def flush():
        if not folded:
            return
        first, last = folded[0][0], folded[-1][0]
        num = f"{first:>4}." if first == last else f"{first:>4}–{last}."
        what = ", ".join(D.short_label(model, lab, a) for _, lab, a, _ in folded)
        line = f"{num} no change: {what}"
        out.append(line if len(line) <= w else line[:w - 1] + "…")
        folded.clear()

    for n, lab in enumerate(labels):
        a, b = states[n], states[n + 1]
        br = T.branch_taken(model, lab, a, b)
        if not full and not br and not _visible_changes(model, a, b):
            folded.append((n + 1, lab, a, b))
            continue
        flush()
        text = D.format_step(model, n + 1, lab, a, b)
        if br:
            head, sep, rest = text.partition("\n")
            text = f"{head}  {T.branch_text(br)}{sep}{rest}"
        out.append(text)
    flush()
    return "\n".join(out)




# ---------------------------------------------------------------------------
# swimlane
# ---------------------------------------------------------------------------

_RULE_WORDS = {"IDLE": "idle (no guard holds)", "LOCK REQUEST": "requests the lock",
               "ATOMIC WAIT": "waits for the lock", "ATOMIC EXECUTION": "takes the lock",
               "LOCK RELEASE": "releases the lock", "EXIT": "exit()",
               "COUNTER ADVANCE": "end of event block"}


def _agent_change_text(model, name, i, old, new) -> str:
    base = name[:-len(f"[{i}]")] if name.endswith(f"[{i}]") else name
    return f"{base}={new}"


def _initial_cells(model, s0) -> list:
    """Step of :func:`swimlane`: the initial state's cells, every agent's
    position and variables, and the shared variables."""
    cells = []
    for i in range(model.N):
        ag = s0[AGS][i]
        vs = ", ".join(f"{n}={format_value(v, t)}" for n, t, v in D.agent_vars(model, s0, i))
        cells.append(f"pos {D.fmt_pos(ag[POS])}" + (f"; {vs}" if vs else ""))
    cells.append(", ".join(f"{n}={format_value(v, t)}" for n, t, v in D.shared_vars(model, s0)))
    return cells


def _step_text(model, lab, a, b, changes: bool, full: bool) -> str | None:
    """Step of :func:`swimlane`: the text of an agent's step ``lab`` from
    ``a`` to ``b`` in its lane, without its changes (``changes``: whether it
    has visible ones), or None when the step is not shown."""
    rule, _, detail = lab
    info = D.label_info(model, lab, a)
    br = T.branch_taken(model, lab, a, b)
    if rule == "EVENT SELECT" and detail is not None:
        return f"{info['event']}()"
    if rule == "STATEMENT" and br:
        src = info["source"] or ""
        word = "while" if br["kind"] == "while" else "if"
        arrow = T.branch_text(br).split(" (line")[0]
        return f"L{info['line']} {src.rstrip(':') if src else word} {arrow}"
    if rule in ("STATEMENT", "DOREACH UPDATE"):
        if not changes and not full:
            return None
        return f"L{info['line']}" + (f" {info['source']}" if full or not changes else "")
    if rule == "COUNTER ADVANCE" and not full:
        return None
    return _RULE_WORDS.get(rule, rule)


def swimlane(model, states, labels, *, full=False, width=None) -> str:
    N = model.N
    W = terminal_width(width)
    ncol = N + 1
    sep = " │ "
    colw = max(10, (W - len(sep) * (ncol - 1)) // ncol)

    def row(cells) -> list:
        wrapped = [textwrap.wrap(c, colw) or [""] if c else [""] for c in cells]
        h = max(len(x) for x in wrapped)
        lines = []
        for k in range(h):
            parts = [(x[k] if k < len(x) else "").ljust(colw) for x in wrapped]
            lines.append(sep.join(parts).rstrip())
        return lines

    def rule_line(text) -> str:
        text = f"── {text} "
        total = colw * ncol + len(sep) * (ncol - 1)
        return text + "─" * max(0, total - len(text))

    out = row([f"agent {i}" for i in range(N)] + ["shared"])
    # initial state: every agent's variables, shared variables beside
    s0 = states[0]
    out.append(rule_line(f"initial state, t={D.fmt_time(s0[TIME])}"))
    out += row(_initial_cells(model, s0))
    out.append(rule_line(f"t={D.fmt_time(s0[TIME])}"))
    for n, lab in enumerate(labels):
        a, b = states[n], states[n + 1]
        rule, i, detail = lab
        ch = _visible_changes(model, a, b)
        shared_names = {v.name for v in model.compiled.layout.shared}
        shared = [f"{c}={nw}" for c, o, nw in ch if c in shared_names or c == "lockQueue"]
        if rule == "TIME ADVANCE":
            out.append(rule_line(f"t={D.fmt_time(b[TIME])}"))
            continue
        if rule == "DOREACH INVOKE":
            cells = []
            for k in range(N):
                mine = [f"{c.split('[')[0]}={nw}" for c, o, nw in ch if c.endswith(f"[{k}]")]
                cells.append("moves: " + ", ".join(mine) if mine else "")
            if any(cells) or full:
                out += row(cells + [""])
            continue
        own = [_agent_change_text(model, c, i, o, nw) for c, o, nw in ch
               if c not in shared_names and c != "lockQueue" and not c.startswith("lockState[")]
        text = _step_text(model, lab, a, b, bool(own or shared), full)
        if text is None:
            continue
        if own:
            text += ": " + ", ".join(own)
        cells = ["" for _ in range(N)] + [", ".join(shared)]
        cells[i] = text
        out += row(cells)
    return "\n".join(out)


# ---------------------------------------------------------------------------
# time steps (the summary of ``pccl run``, and the viewer's "time steps" panel)
# ---------------------------------------------------------------------------

def summary_of(states, labels) -> list:
    """``[(time, state, k)]``: the states a run's summary keeps, from its
    whole path: the initial one (``k`` 0) and the one after each DOREACH
    INVOKE (the environment's step, which ends a time step: ``k`` is the
    number of that step), as :class:`pccl.tools.runner._TimeSteps` records
    them before it thins a long run's."""
    out = [(states[0][TIME], states[0], 0)]
    for n, lab in enumerate(labels):
        if lab[0] == "DOREACH INVOKE":
            out.append((states[n + 1][TIME], states[n + 1], n + 1))
    return out


def time_steps(model, summary) -> list:
    """The per-time-step lines of a run (``[(k, line)]``, ``k`` the third
    element of the summary entry the line starts with, else None);
    consecutive identical ones (nothing moved or changed) are one line
    ``t=A–B: … (N identical time steps)``."""
    out: list = []
    prev = None
    group: list = []            # [(time, text, k)] with the same text

    def flush():
        if not group:
            return
        (t0, text, k), (t1, _, _) = group[0], group[-1]
        if len(group) == 1:
            out.append((k, f"  t={D.fmt_time(t0)}: {text}"))
        else:
            out.append((k, f"  t={D.fmt_time(t0)}–{D.fmt_time(t1)}: {text} "
                           f"({len(group)} identical time steps)"))
        group.clear()
    for entry in summary:
        t, st = entry[0], entry[1]
        text = step_summary(model, prev, st)
        if group and text != group[-1][1]:
            flush()
        group.append((t, text, entry[2] if len(entry) > 2 else None))
        prev = st
    flush()
    return out


def step_summary(model, prev, s) -> str:
    """One time step of a run: every agent's position (and status when not
    running), then what changed since ``prev`` (the previous summary state)."""
    parts = []
    for i, ag in enumerate(s[AGS]):
        st = D.status_text(model, ag[STATUS])
        parts.append(f"a{i} {D.fmt_pos(ag[POS])}" + ("" if st == "running" else f" {st}"))
    if prev is not None:
        ch = [c for c in D.diff(model, prev, s, fmt=D.short_value)
              if not c[0].startswith(("pos[", "time", "transitionState"))]
        if ch:
            parts.append("; ".join(f"{c}={nw}" for c, _, nw in ch))
    return "  ".join(parts)
