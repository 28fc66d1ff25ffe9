"""``pccl graph``: the reachable state graph as Graphviz DOT or JSON.

Breadth-first from the initial states, at most ``max_states`` states (the
edges into states beyond the bound are left out and the graph is marked
truncated).  Nodes are states, labelled with their number, time and where
each agent is; edges are transitions, labelled with the agent, the rule, the
source line and the variables changed, and coloured per agent.  States are
global (every agent is in every state), so agents are edge colours, and
states are grouped in clusters by time step (when there are at most
:data:`MAX_TIME_CLUSTERS` of them).  Violating states are red, with the
violation in the label; initial states have a double border.
"""

from __future__ import annotations

import json
from collections import deque
from dataclasses import dataclass, field

from pccl.output import display as D
from pccl.output import traces as T
from pccl.model.layout import AGS, PC, STATUS, TIME
from pccl.lang.values import format_value

MAX_TIME_CLUSTERS = 50
AGENT_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                 "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"]


@dataclass
class Graph:
    states: list = field(default_factory=list)      # the states, by number
    depth: list = field(default_factory=list)
    initial: set = field(default_factory=set)
    edges: list = field(default_factory=list)       # (from, to, label)
    violations: dict = field(default_factory=dict)  # number -> [Violation]
    terminal: dict = field(default_factory=dict)    # number -> final | bounded | deadlock
    truncated: bool = False
    out_of_memory: bool = False                     # a MemoryError stopped the build


def build(model, *, max_states: int = 10_000, deadlock: bool = True) -> Graph:
    g = Graph()
    ids: dict = {}
    queue: deque = deque()

    def admit(st, d):
        k = model.key(st)
        n = ids.get(k)
        if n is not None:
            return n
        if len(g.states) >= max_states:
            g.truncated = True
            return None
        n = ids[k] = len(g.states)
        g.states.append(st)
        g.depth.append(d)
        v = list(model.violations(st))
        if v:
            g.violations[n] = v
        queue.append(n)
        return n

    try:
        _explore(model, g, admit, queue, deadlock)
    except MemoryError:         # the states so far are kept; the CLI writes no file
        queue.clear()
        g.out_of_memory = g.truncated = True
    return g


def _explore(model, g, admit, queue, deadlock) -> None:
    for st in model.init_states():
        n = admit(st, 0)
        if n is None:           # --max-states reached: the other initial states are not
            break               # enumerated (fischer with 4 agents has 66**4 of them)
        g.initial.add(n)
    while queue:
        n = queue.popleft()
        st = g.states[n]
        if n in g.violations:          # as in explore: a violating state is not expanded
            continue
        succ = model.successors(st)
        if not succ:
            kind = model.terminal_kind(st)
            g.terminal[n] = kind
            if kind == "deadlock" and deadlock:
                g.violations[n] = [model.deadlock_violation(st)]
        for label, nxt in succ:
            m = admit(nxt, g.depth[n] + 1)
            if m is not None:
                g.edges.append((n, m, label))


def _edge_text(model, label, a, b) -> str:
    head = D.short_label(model, label, a, system="sys")
    br = T.branch_taken(model, label, a, b)
    if br:
        head += " " + T.branch_text(br).split(" (line")[0]
    ch = [f"{c}={nw}" for c, o, nw in D.diff(model, a, b)
          if c not in ("transitionState", "time") and not c.startswith("lockState")]
    return head + ("\n" + ", ".join(ch) if ch else "")


def _node_text(model, n, st, g) -> str:
    parts = [f"s{n} t={D.fmt_time(st[TIME])}"]
    where = []
    for i, ag in enumerate(st[AGS]):
        desc = model.compiled.describe_k(ag[PC]).replace("at the top of the event block", "top") \
            .replace("finishing its event block", "end").replace("at line ", "L")
        st_txt = D.status_text(model, ag[STATUS])
        where.append(f"a{i}:{desc}" + ("" if st_txt == "running" else f" {st_txt.split('(')[0]}"))
    parts.append(" ".join(where))
    sh = ", ".join(f"{n}={format_value(v, t)}" for n, t, v in D.shared_vars(model, st))
    if sh:
        parts.append(sh if len(sh) <= 60 else sh[:59] + "…")
    for v in g.violations.get(n, []):
        parts.append(v.message)
    return "\n".join(parts)


def _q(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def to_dot(model, g: Graph, *, name="pccl") -> str:
    out = [f"digraph {_q(name)} {{", '  rankdir=TB;',
           '  node [shape=box, fontname="Helvetica", fontsize=9];',
           '  edge [fontname="Helvetica", fontsize=8];']
    times = sorted({st[TIME] for st in g.states})
    clusters = 1 < len(times) <= MAX_TIME_CLUSTERS

    def node_line(n, st):
        attrs = [f"label={_q(_node_text(model, n, st, g))}",
                 f"tooltip={_q(D.format_state(model, st, indent=''))}"]
        if n in g.violations:
            attrs += ['color="red"', 'style="filled"', 'fillcolor="#ffd6d6"', 'penwidth=2']
        elif g.terminal.get(n) == "final":
            attrs += ['style="rounded"']
        if n in g.initial:
            attrs += ["peripheries=2"]
        return f"  s{n} [{', '.join(attrs)}];"

    if clusters:
        for t in times:
            out.append(f"  subgraph cluster_t{len(out)} {{")
            out.append(f"    label={_q('t=' + D.fmt_time(t))}; color=\"#cccccc\";")
            out += ["  " + node_line(n, st) for n, st in enumerate(g.states) if st[TIME] == t]
            out.append("  }")
    else:
        out += [node_line(n, st) for n, st in enumerate(g.states)]
    for a, b, label in g.edges:
        agent = label[1]
        colour = "#444444" if agent is None else AGENT_COLOURS[agent % len(AGENT_COLOURS)]
        text = _edge_text(model, label, g.states[a], g.states[b])
        out.append(f"  s{a} -> s{b} [label={_q(text)}, color={_q(colour)}, fontcolor={_q(colour)}];")
    if model.N <= len(AGENT_COLOURS):
        out.append('  subgraph cluster_legend { label="agents"; color="#cccccc";')
        for i in range(model.N):
            c = AGENT_COLOURS[i]
            out.append(f'    legend{i} [label="agent {i}", shape=plaintext, fontcolor={_q(c)}];')
        out.append("  }")
    out.append("}")
    return "\n".join(out) + "\n"


def to_json(model, g: Graph, cfg: dict, max_states: int) -> dict:
    nodes = []
    for n, st in enumerate(g.states):
        nodes.append({"id": n, "depth": g.depth[n], "initial": n in g.initial,
                      "terminal": g.terminal.get(n),
                      "violations": [T.violation_record(model, v) for v in g.violations.get(n, [])],
                      "state": T.state_typed(model, st)})
    edges = []
    for a, b, label in g.edges:
        rec = T.step_record(model, 0, label, g.states[a], g.states[b])
        del rec["index"]
        edges.append({"from": a, "to": b, **rec})
    return {"format": "pccl-graph", "version": 1, "config": cfg, "max_states": max_states,
            "truncated": g.truncated, "states": len(nodes), "transitions": len(edges),
            "nodes": nodes, "edges": edges}


def write(text: str, path) -> None:
    import os
    from pccl.lang.errors import PcclError
    try:
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError as e:
        raise PcclError(f"cannot write graph: {e.strerror or e}", filename=os.fspath(path)) from None


def dumps(doc) -> str:
    return json.dumps(doc, indent=1, default=str) + "\n"
