"""Pictures of the physical world (``--plot FILE`` in ``run`` and ``explore``).

:func:`plot_run` draws one execution (a :class:`~pccl.tools.runner.RunResult`),
:func:`plot_trace` a counterexample (a :class:`~pccl.search.explorer.Trace`, from an
initial state, as the explorer rebuilds it).  Both draw, in world
coordinates with equal aspect:

* the arena (``world.arena``, a dashed grey box; without one the view is a
  box around everything drawn, with a margin);
* the world's obstacles, filled grey polygons numbered as in ``--collisions``
  messages (from 1);
* destinations: the initial value of every shared ``List<ItemPosition>``
  variable (gold stars), and every target an agent was sent to by
  ``doReach`` (crosses in the agent's colour);
* each agent's trajectory: its positions after every environment step
  (DOREACH INVOKE), one colour per agent, with small time labels (a robot
  parked for several steps gets one ``t=a–b`` label; labels are thinned when
  there are many); its footprint, a disc of ``world.radius``, dashed at the
  start and filled at the end, with the agent's number;
* failed ``doReach`` calls: a red X where an agent's ``doReach_fail``
  became true, labelled "doReach failed (i)";
* the verdict: for a counterexample, or a run that ended badly, the title's
  second line is the message in red and red rings mark the agents involved
  at the last state (the colliding agents and obstacle, the stuck agent, the
  agents still running in a deadlock; every agent for an invariant).

A program without motion (no ``doReach`` statement) draws a *timeline*
instead of discs that never move (:func:`_draw_timeline`): one lane per
agent, a bar per event block coloured by event (grey for IDLE, hatched for
ATOMIC WAIT), a bar at an agent's exit, and the violating moment marked in
red on the agents involved.

The figure is 8 x 6 inches at 100 dpi (an 800 x 600 PNG).  The format
follows the file's extension when matplotlib supports it (``.svg``, ``.pdf``
…), PNG otherwise.  Only matplotlib's object API and the Agg canvas are
used: importing this module does not change the pyplot backend of a
program that embeds pccl.  Importing it raises ImportError when matplotlib
is missing (the CLI turns that into a one-line message).
"""

from __future__ import annotations

import math
import os
import textwrap
from typing import Optional

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Polygon as PolygonPatch, Rectangle

from pccl.model.layout import AGS, EXITED, FAIL, POS, REACH, RUNNING, SH, STATUS, TARGET, TIME

FIGSIZE = (8.0, 6.0)
DPI = 100
MAX_TIME_LABELS = 12          # per agent
MAX_LEGEND_AGENTS = 10

WAIT = "\0wait"              # an ATOMIC WAIT in the timeline


# ---------------------------------------------------------------------------
# public API
# ---------------------------------------------------------------------------

def plot_run(model, run_result, path) -> None:
    """Draw one execution: the positions after every environment step
    (``run_result.summary``), the targets seen in ``run_result.trace`` (when
    recorded) and the final state, to ``path``."""
    summary = list(getattr(run_result, "summary", None) or [])
    final = getattr(run_result, "final", None)
    states = [s for _, s in summary]
    if final is not None and (not states or states[-1] is not final):
        states.append(final)
    if not states:
        raise ValueError("plot_run: the run result has no state to draw")
    frames = _frames_from_states(states)
    trace = getattr(run_result, "trace", None)
    scan = list(trace.states[1:]) if trace is not None and len(trace) else states
    status = getattr(run_result, "status", "")
    message = getattr(run_result, "message", "")
    bad = status not in ("final", "bounded", "")
    last = states[-1]
    ring = None
    if bad:
        ring = _culprits(model, last, getattr(run_result, "violations", None) or [],
                         looping=getattr(run_result, "looping_agent", None),
                         deadlock=status == "deadlock")
    head = f"{_program_name(model)} — run, blackbox {model.blackbox.name}: {status}"
    sub = message if bad else (message or None)
    if not has_motion(model) and trace is not None and len(trace):
        _draw_timeline(model, list(trace), path,
                       head.replace(f", blackbox {model.blackbox.name}", ""), sub, bad, ring)
        return
    _draw(model, states[0], frames, scan, last, path, head, sub, bad, ring)


def plot_trace(model, trace, path, title: Optional[str] = None) -> None:
    """Draw a counterexample ``trace`` (a :class:`pccl.search.explorer.Trace`) to
    ``path``; ``title`` (the violation message) is shown in red and the
    agents involved at the last state are ringed in red."""
    trace = list(trace)         # [(None, initial), (label, state), ...]
    if not trace:
        raise ValueError("plot_trace: empty trace")
    states = [s for _, s in trace]
    frames = _frames_from_trace(trace)
    last = states[-1]
    ring = _culprits(model, last, _violations(model, last), looping=None,
                     deadlock=_is_deadlock(model, last))
    if not has_motion(model):
        _draw_timeline(model, trace, path, f"{_program_name(model)} — counterexample", title,
                       True, ring)
        return
    head = f"{_program_name(model)} — counterexample, blackbox {model.blackbox.name}"
    _draw(model, states[0], frames, states, last, path, head, title, True, ring)


def has_motion(model) -> bool:
    """Whether the program can move a robot (has a ``doReach`` statement)."""
    from pccl.lang import ast as A
    return any(isinstance(s, A.CallStmt) and s.name == "doReach"
               for s in model.compiled.stmts.values())


# ---------------------------------------------------------------------------
# collecting what to draw
# ---------------------------------------------------------------------------

def _xy(p):
    return (float(p[0]), float(p[1]))


def _frame(st):
    return (st[TIME], tuple(_xy(ag[POS]) for ag in st[AGS]), tuple(ag[STATUS] for ag in st[AGS]))


def _frames_from_states(states) -> list:
    """[(time, positions, statuses)], one per state, consecutive duplicates
    (same time and positions) merged."""
    out: list = []
    for st in states:
        f = _frame(st)
        if out and out[-1][0] == f[0] and out[-1][1] == f[1]:
            out[-1] = f
        else:
            out.append(f)
    return out


def _frames_from_trace(trace) -> list:
    """The initial state, the state after every DOREACH INVOKE, and the last
    state (its statuses count: exited/stuck at the violation)."""
    picked = [trace[0][1]]
    for label, st in trace[1:]:
        if label is not None and label[0] == "DOREACH INVOKE":
            picked.append(st)
    if picked[-1] is not trace[-1][1]:
        picked.append(trace[-1][1])
    return _frames_from_states(picked)


def _destinations(model, st) -> list:
    """[(name, [(x, y), ...])] for the shared List<ItemPosition> variables."""
    out: list = []
    for v in model.compiled.layout.shared:
        ty = v.ty
        if ty.kind != "list" or ty.elem is None or ty.elem.kind != "pos":
            continue
        val = st[SH][v.slot]
        if not isinstance(val, tuple):
            continue
        pts = [_xy(p) for p in val if isinstance(p, tuple) and len(p) >= 2]
        if pts:
            out.append((v.name, pts))
    return out


def _targets(states, n) -> list:
    """Per agent, the distinct doReach targets in order of first appearance."""
    seen: list[dict] = [{} for _ in range(n)]
    for st in states:
        for i, ag in enumerate(st[AGS]):
            t = ag[REACH][TARGET]
            if t is not None:
                seen[i].setdefault(_xy(t), None)
    return [list(s) for s in seen]


def _failures(states, n) -> list:
    """[(agent, xy)]: where each agent's doReach_fail turned true (each time)."""
    out, prev = [], [False] * n
    for st in states:
        for i, ag in enumerate(st[AGS]):
            f = bool(ag[REACH][FAIL])
            if f and not prev[i]:
                out.append((i, _xy(ag[POS])))
            prev[i] = f
    return out


def _violations(model, st) -> list:
    try:
        return list(model.violations(st))
    except Exception:  # a drawing must not fail on a property that cannot be evaluated
        return []


def _is_deadlock(model, st) -> bool:
    try:
        return not model.successors(st) and model.terminal_kind(st) == "deadlock"
    except Exception:
        return False


def _culprits(model, st, violations, *, looping, deadlock) -> dict:
    """{'agents': sorted ids, 'obstacles': 1-based ids, 'all': bool}."""
    agents, obstacles = set(), set()
    for v in violations:
        kind = getattr(v, "kind", None)
        if kind == "collision":
            from pccl.model.collide import contacts
            for c in contacts(model.world, tuple(ag[POS] for ag in st[AGS])):
                agents.add(c.i)
                if c.j is not None:
                    agents.add(c.j)
                if c.obstacle is not None:
                    obstacles.add(c.obstacle)
        elif getattr(v, "agent", None) is not None:
            agents.add(v.agent)
    if looping is not None:
        agents.add(looping)
    if not agents and deadlock:
        agents = {i for i, ag in enumerate(st[AGS]) if ag[STATUS] != EXITED}
    everyone = not agents
    if everyone:
        agents = set(range(len(st[AGS])))
    return {"agents": sorted(agents), "obstacles": sorted(obstacles), "all": everyone}


def _program_name(model) -> str:
    fn = getattr(model.program, "filename", None)
    return os.path.basename(fn) if fn else "program"


# ---------------------------------------------------------------------------
# drawing
# ---------------------------------------------------------------------------

def _colours(n):
    from matplotlib import colormaps
    if n <= 10:
        cmap = colormaps["tab10"]
        return [cmap(i) for i in range(n)]
    cmap = colormaps["turbo"]
    return [cmap(0.05 + 0.9 * i / max(1, n - 1)) for i in range(n)]


def _fmt_t(t) -> str:
    if isinstance(t, float):
        if t.is_integer():
            return str(int(t))
        return f"{t:.3f}".rstrip("0").rstrip(".")
    return str(t)


def _runs(frames, i) -> list:
    """Agent i's positions with the times it was there: [(xy, t_first, t_last)]."""
    out: list = []
    for t, pos, _ in frames:
        p = pos[i]
        if out and out[-1][0] == p:
            out[-1][2] = t
        else:
            out.append([p, t, t])
    return out


def _thin(runs: list, limit: int) -> list:
    if len(runs) <= limit:
        return runs
    k = math.ceil((len(runs) - 1) / (limit - 1))
    keep = runs[::k]
    if keep[-1] is not runs[-1]:
        keep.append(runs[-1])
    return keep


def _groups(points, tol) -> list:
    """Indexes of ``points`` grouped by proximity (within ``tol`` of the
    group's first point), in order."""
    groups: list = []
    for k, (x, y) in enumerate(points):
        for g in groups:
            gx, gy = points[g[0]]
            if math.hypot(x - gx, y - gy) <= tol:
                g.append(k)
                break
        else:
            groups.append([k])
    return groups


def _status_word(code) -> str:
    return "running" if code == RUNNING else "exited" if code == EXITED else "stuck"


class _Canvas:
    """The axes of a trajectory plot, the points the view must show and the
    legend entries, filled in layer by layer."""

    def __init__(self, fig):
        fig.subplots_adjust(left=0.07, right=0.73, bottom=0.08, top=0.87)
        ax = self.ax = fig.add_subplot(1, 1, 1)
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, color="#e6e6e6", linewidth=0.6, zorder=0)
        ax.set_axisbelow(True)
        ax.set_xlabel("x", fontsize=8)
        ax.set_ylabel("y", fontsize=8)
        ax.tick_params(labelsize=7)
        self.xs: list = []
        self.ys: list = []
        self.handles: list = []

    def extend(self, pts, pad=0.0):
        for x, y in pts:
            self.xs.extend((x - pad, x + pad))
            self.ys.extend((y - pad, y + pad))


def _draw(model, st0, frames, scan_states, last, path, head, sub, bad, ring) -> None:
    """The trajectory plot: arena, obstacles, destinations, doReach targets
    and failures, each agent's path, the violating moment; then the view and
    the titles."""
    world = model.world
    n = len(st0[AGS])
    r = float(world.radius)
    colours = _colours(n)
    fig = Figure(figsize=FIGSIZE, dpi=DPI)
    FigureCanvasAgg(fig)
    cv = _Canvas(fig)
    _draw_world(cv, world, ring)
    _draw_marks(cv, model, st0, scan_states, n, colours)
    _draw_trajectories(cv, frames, n, r, colours)
    if bad and ring:
        _draw_violation(cv, last, ring, r)
    _fit_view(cv, world, r)
    _draw_titles(fig, cv, head, sub, bad)
    _save(fig, path)


def _draw_world(cv: _Canvas, world, ring) -> None:
    """The arena (dashed, not solid) and the numbered obstacles (those of
    a collision outlined in red)."""
    # arena
    if world.arena is not None:
        (x0, y0), (x1, y1) = world.arena
        cv.ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor="#888888",
                                  linestyle="--", linewidth=1.0, zorder=1))
        cv.extend([(x0, y0), (x1, y1)])
        cv.handles.append(Line2D([], [], color="#888888", linestyle="--", label="arena"))

    # obstacles
    bad_obs = set(ring["obstacles"]) if ring else set()
    if world.obstacles:
        for k, poly in enumerate(world.obstacles, start=1):
            pts = [_xy(p) for p in poly]
            hit = k in bad_obs
            cv.ax.add_patch(PolygonPatch(pts, closed=True, facecolor="#9e9e9e", alpha=0.85,
                                         edgecolor="red" if hit else "#505050",
                                         linewidth=2.5 if hit else 1.0, zorder=2))
            cx = sum(p[0] for p in pts) / len(pts)
            cy = sum(p[1] for p in pts) / len(pts)
            cv.ax.text(cx, cy, str(k), ha="center", va="center", fontsize=7, color="white",
                       zorder=3, fontweight="bold")
            cv.extend(pts)
        cv.handles.append(Patch(facecolor="#9e9e9e", edgecolor="#505050", label="obstacle"))


def _draw_marks(cv: _Canvas, model, st0, scan_states, n, colours) -> None:
    """Destinations (shared List<ItemPosition> variables), each agent's
    doReach targets, and where a doReach failed."""
    # destinations (shared List<ItemPosition> variables, initial value)
    dests = _destinations(model, st0)
    if dests:
        names = ", ".join(name for name, _ in dests)
        allpts = [p for _, pts in dests for p in pts]
        cv.ax.plot([p[0] for p in allpts], [p[1] for p in allpts], linestyle="none", marker="*",
                   markersize=14, markerfacecolor="gold", markeredgecolor="#7a5c00",
                   markeredgewidth=0.8, zorder=4)
        cv.extend(allpts)
        cv.handles.append(Line2D([], [], linestyle="none", marker="*", markersize=11,
                                 markerfacecolor="gold", markeredgecolor="#7a5c00",
                                 label=f"destinations ({names})"))

    # doReach targets
    targets = _targets(scan_states, n)
    if any(targets):
        for i, ts in enumerate(targets):
            if ts:
                cv.ax.plot([p[0] for p in ts], [p[1] for p in ts], linestyle="none", marker="x",
                           markersize=9, markeredgewidth=2.0, color=colours[i], zorder=6)
                cv.extend(ts)
        cv.handles.append(Line2D([], [], linestyle="none", marker="x", markersize=8,
                                 markeredgewidth=2.0, color="#333333", label="doReach targets"))

    # failed doReach: where each agent's doReach_fail became true
    fails = _failures(scan_states, n)
    if fails:
        for i, p in fails:
            cv.ax.plot([p[0]], [p[1]], linestyle="none", marker="X", markersize=13,
                       markerfacecolor="red", markeredgecolor="black", markeredgewidth=0.8, zorder=11)
            cv.ax.annotate(f"doReach failed ({i})", p, xytext=(6, -12), textcoords="offset points",
                           fontsize=6, color="red", zorder=11)
            cv.extend([p])
        cv.handles.append(Line2D([], [], linestyle="none", marker="X", markersize=9,
                                 markerfacecolor="red", markeredgecolor="black",
                                 label="doReach failed"))


def _draw_trajectories(cv: _Canvas, frames, n, r, colours) -> None:
    """Each agent's path with time labels, its footprint at start (dashed)
    and at the end (filled, numbered)."""
    # trajectories
    final_status = frames[-1][2]
    offsets = [(5, 5), (5, -11), (-22, 5), (-22, -11)]
    ends: list = []
    for i in range(n):
        c = colours[i]
        pts = [f[1][i] for f in frames]
        cv.extend(pts, pad=r)
        cv.ax.plot([p[0] for p in pts], [p[1] for p in pts], color=c, linewidth=1.6,
                   marker="o", markersize=2.5, zorder=5, alpha=0.9)
        start, end = pts[0], pts[-1]
        cv.ax.add_patch(Circle(start, r, fill=False, edgecolor=c, linestyle="--",
                               linewidth=1.2, zorder=5))
        cv.ax.add_patch(Circle(end, r, facecolor=c, alpha=0.45, edgecolor=c, linewidth=1.4,
                               zorder=7))
        ends.append(end)
        dx, dy = offsets[i % len(offsets)]
        for p, ta, tb in _thin(_runs(frames, i), MAX_TIME_LABELS):
            text = f"t={_fmt_t(ta)}" if ta == tb else f"t={_fmt_t(ta)}–{_fmt_t(tb)}"
            cv.ax.annotate(text, p, xytext=(dx, dy), textcoords="offset points", fontsize=6,
                           color=c, zorder=9)
        if i < MAX_LEGEND_AGENTS:
            cv.handles.append(Line2D([], [], color=c, marker="o", markersize=4, linewidth=1.6,
                                     label=f"agent {i} ({_status_word(final_status[i])})"))
    # agent numbers on the end footprints; robots ending on top of each other share one label
    for group in _groups(ends, 0.3 * r):
        x, y = ends[group[0]]
        cv.ax.text(x, y, ",".join(map(str, group)), ha="center", va="center", fontsize=7,
                   fontweight="bold", color="black", zorder=8)
    if n > MAX_LEGEND_AGENTS:
        cv.handles.append(Line2D([], [], color="none", label=f"… {n - MAX_LEGEND_AGENTS} more agents"))
    cv.handles.append(Line2D([], [], linestyle="none", marker="o", markersize=10,
                             markerfacecolor="none", markeredgecolor="#555555",
                             label="footprint at start (dashed)"))
    cv.handles.append(Line2D([], [], linestyle="none", marker="o", markersize=10,
                             markerfacecolor="#bbbbbb", markeredgecolor="#555555",
                             label="footprint at end"))


def _draw_violation(cv: _Canvas, last, ring, r) -> None:
    """Red rings around the agents of the violation, where they are at it."""
    pos = [_xy(ag[POS]) for ag in last[AGS]]
    style = "--" if ring["all"] else "-"
    for i in ring["agents"]:
        if i < len(pos):
            cv.ax.add_patch(Circle(pos[i], 1.6 * r, fill=False, edgecolor="red",
                                   linewidth=2.2, linestyle=style, zorder=10))
    cv.handles.append(Line2D([], [], linestyle="none", marker="o", markersize=12,
                             markerfacecolor="none", markeredgecolor="red", markeredgewidth=2,
                             label=f"violation at t={_fmt_t(last[TIME])}"))


def _fit_view(cv: _Canvas, world, r) -> None:
    """Limits that show every point drawn, grown to the axes' shape."""
    xs, ys = cv.xs, cv.ys
    if not xs:
        xs, ys = [0.0], [0.0]
    xmin, xmax, ymin, ymax = min(xs), max(xs), min(ys), max(ys)
    span = max(xmax - xmin, ymax - ymin, 4 * r, 1e-6)
    m = 0.06 * span + 0.5 * r
    if world.arena is not None:
        m = max(0.03 * span, 0.25 * r)
    xmin, xmax, ymin, ymax = xmin - m, xmax + m, ymin - m, ymax + m
    # grow the view to the axes' shape, so that equal aspect fills the box
    box = cv.ax.get_position(original=True)
    want = (box.width * FIGSIZE[0]) / (box.height * FIGSIZE[1])
    w, h = xmax - xmin, ymax - ymin
    if w / h < want:
        grow = (want * h - w) / 2
        xmin, xmax = xmin - grow, xmax + grow
    else:
        grow = (w / want - h) / 2
        ymin, ymax = ymin - grow, ymax + grow
    cv.ax.set_xlim(xmin, xmax)
    cv.ax.set_ylim(ymin, ymax)


def _draw_titles(fig, cv: _Canvas, head, sub, bad) -> None:
    """The legend right of the axes, the title and the subtitle (red for a
    violation)."""
    cv.ax.legend(handles=cv.handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=7,
                 frameon=True, borderaxespad=0.0)
    fig.text(0.5, 0.955, head, ha="center", va="center", fontsize=10, fontweight="bold")
    if sub:
        wrapped = textwrap.shorten(sub, width=220, placeholder=" …")
        wrapped = "\n".join(textwrap.wrap(wrapped, width=110)[:2])
        fig.text(0.5, 0.91, wrapped, ha="center", va="center", fontsize=8,
                 color="red" if bad else "#333333")


def _timeline_blocks(trace, events: list) -> dict:
    """Step of :func:`_draw_timeline`: {(agent, time): [event name, None for
    an idle step, or WAIT]} of the trace's event blocks."""
    blocks: dict = {}
    for label, st in trace[1:]:
        if label is None:
            continue
        rule, i = label[0], label[1]
        if rule in ("EVENT SELECT", "EVENT TRANS") and label[2] is not None:
            blocks.setdefault((i, float(st[TIME])), []).append(events[label[2]])
        elif rule == "IDLE":
            blocks.setdefault((i, float(st[TIME])), []).append(None)
        elif rule == "ATOMIC WAIT":
            blocks.setdefault((i, float(st[TIME])), []).append(WAIT)
    return blocks


def _draw_blocks(ax, blocks: dict, ecol: dict, delta: float) -> set:
    """Step of :func:`_draw_timeline`: a bar per event block; the names of
    the events drawn."""
    used = set()
    for (i, t), names in blocks.items():
        w = delta / len(names)
        for k, name in enumerate(names):
            x = t + k * w
            if name is None or name is WAIT:
                ax.broken_barh([(x, w * 0.92)], (i - 0.3, 0.6), facecolors="#eeeeee",
                               edgecolors="#bbbbbb", linewidth=0.5, zorder=2,
                               hatch="///" if name is WAIT else None)
                continue
            used.add(name)
            ax.broken_barh([(x, w * 0.92)], (i - 0.3, 0.6), facecolors=ecol[name],
                           edgecolors="#333333", linewidth=0.5, zorder=2)
            if w >= delta * 0.5 and len(blocks) <= 60:
                ax.text(x + w * 0.46, i, name, ha="center", va="center", fontsize=6, zorder=3)
    return used


def _draw_exits(ax, states: list, delta: float) -> None:
    """Step of :func:`_draw_timeline`: a mark where each agent exited, a
    cross at the end for each stuck one."""
    last = states[-1]
    t_end = float(last[TIME])
    for i, ag in enumerate(last[AGS]):
        if ag[STATUS] == EXITED:
            t_exit = next((float(st[TIME]) for st in states if st[AGS][i][STATUS] == EXITED), t_end)
            ax.plot([t_exit + delta], [i], marker="|", markersize=16, color="black", zorder=4)
        elif ag[STATUS] != RUNNING:
            ax.plot([t_end + delta * 0.5], [i], marker="X", markersize=11, color="red", zorder=5)


def _draw_timeline(model, trace, path, head, sub, bad, ring) -> None:
    """For programs without motion: one lane per agent, the events each agent
    ran over time (a bar per event block, coloured by event), exits and stuck
    agents marked, and the violating moment."""
    from matplotlib import colormaps
    states = [s for _, s in trace]
    n = len(states[0][AGS])
    delta = float(model.delta)
    events = [ev.name for ev in model.program.events]
    cmap = colormaps["tab20"]
    ecol = {name: cmap(k % 20) for k, name in enumerate(events)}
    fig = Figure(figsize=FIGSIZE, dpi=DPI)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(left=0.1, right=0.73, bottom=0.1, top=0.87)
    ax = fig.add_subplot(1, 1, 1)
    ax.grid(True, axis="x", color="#e6e6e6", linewidth=0.6, zorder=0)
    ax.set_axisbelow(True)
    ax.set_xlabel("time", fontsize=8)
    ax.tick_params(labelsize=7)
    # event blocks: EVENT SELECT at time t opens a block of agent i; within one
    # time step an agent may run several (n0 > 1): they share the step's width
    blocks = _timeline_blocks(trace, events)
    used = _draw_blocks(ax, blocks, ecol, delta)
    # exits and stuck agents
    last = states[-1]
    t_end = float(last[TIME])
    _draw_exits(ax, states, delta)
    handles: list = [Patch(facecolor=ecol[e], edgecolor="#333333", label=e)
                     for e in events if e in used]
    if any(None in v for v in blocks.values()):
        handles.append(Patch(facecolor="#eeeeee", edgecolor="#bbbbbb", label="idle"))
    if any(WAIT in v for v in blocks.values()):
        handles.append(Patch(facecolor="#eeeeee", edgecolor="#bbbbbb", hatch="///",
                             label="waits for the lock"))
    handles.append(Line2D([], [], linestyle="none", marker="|", markersize=12, color="black",
                          label="exit"))
    if bad and ring:
        for i in ring["agents"]:
            ax.plot([t_end + delta * 0.5], [i], linestyle="none", marker="o", markersize=16,
                    markerfacecolor="none", markeredgecolor="red", markeredgewidth=2,
                    zorder=6)
        ax.axvline(t_end + delta * 0.5, color="red", linestyle=":", linewidth=1.2, zorder=1)
        handles.append(Line2D([], [], linestyle="none", marker="o", markersize=12,
                              markerfacecolor="none", markeredgecolor="red", markeredgewidth=2,
                              label=f"violation at t={_fmt_t(last[TIME])}"))
    ax.set_yticks(range(n))
    ax.set_yticklabels([f"agent {i}" for i in range(n)], fontsize=7)
    ax.set_ylim(n - 0.4, -0.6)
    ax.set_xlim(float(states[0][TIME]) - 0.1 * delta, t_end + 1.2 * delta)
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=7,
              frameon=True, borderaxespad=0.0, title="events", title_fontsize=7)
    fig.text(0.5, 0.955, head + " (timeline: no robot moves)", ha="center", va="center",
             fontsize=10, fontweight="bold")
    if sub:
        wrapped = textwrap.shorten(sub, width=220, placeholder=" …")
        wrapped = "\n".join(textwrap.wrap(wrapped, width=110)[:2])
        fig.text(0.5, 0.91, wrapped, ha="center", va="center", fontsize=8,
                 color="red" if bad else "#333333")
    _save(fig, path)


def _save(fig, path) -> None:
    from pccl.lang.errors import PcclError
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower().lstrip(".")
    fmt = ext if ext in fig.canvas.get_supported_filetypes() else "png"
    try:
        fig.savefig(path, format=fmt, dpi=DPI)
    except OSError as e:
        raise PcclError(f"cannot write plot: {e.strerror or e}", filename=path) from None
