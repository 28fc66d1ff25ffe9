"""Trace files: counterexamples and runs people can read, keep and replay.

A *trace document* (``--trace-out FILE``, and ``"trace"`` in ``--format
json``) records the whole configuration of the command that produced it, the
typed initial state, every step with its typed changes, and the result.  The
format is described in ``docs/trace-format.md`` and by the JSON Schema
``docs/trace-format.schema.json``; :func:`replay` re-executes one.

Values are typed JSON: numbers as numbers, bools as bools, positions as
``[x, y, z]``, enums as member names, undefined as ``null``.  Cells are
named by structured paths: ``{"var": "reqid"}`` (a shared variable),
``{"agent": 0, "var": "waitTime"}`` (a per-agent variable),
``{"cell": "time"}``, ``{"agent": 1, "cell": "position"}`` (parts of the
configuration that are not program variables).
"""

from __future__ import annotations

import hashlib
import json
import os
from typing import Optional

from pccl.output import display as D
from pccl.model.layout import AGS, CNT, DONE, ENV, FAIL, LCK, LQ, PC, PHASE, POS, REACH, SH, STATUS, TARGET, TIME
from pccl.semantics.rules import K_IF, K_WHILE
from pccl.lang.values import to_json

FORMAT = "pccl-trace"
VERSION = 1


def pccl_version() -> str:
    try:
        from importlib.metadata import version
        return version("pccl")
    except Exception:  # pragma: no cover - not installed
        return "unknown"


def sha256_of(path) -> Optional[str]:
    try:
        with open(path, "rb") as f:
            return hashlib.sha256(f.read()).hexdigest()
    except OSError:
        return None


def _file(path) -> Optional[dict]:
    """A file the trace depends on: the path as given (relative to the
    working directory), the absolute path and the SHA-256 of its bytes;
    :func:`write` adds the path relative to the trace file."""
    if path is None:
        return None
    return {"path": os.fspath(path), "sha256": sha256_of(path),
            "absolute": os.path.abspath(os.fspath(path))}


def _relative_to(doc: dict, trace_path) -> None:
    """Add ``relative`` (the path from the trace file's directory) to the
    files of ``doc``'s configuration, so that replay finds them from
    anywhere as long as the trace moves with the program."""
    base = os.path.dirname(os.path.abspath(os.fspath(trace_path)))
    for key in ("program", "world"):
        rec = (doc.get("config") or {}).get(key)
        if isinstance(rec, dict) and rec.get("absolute"):
            try:
                rec["relative"] = os.path.relpath(rec["absolute"], base)
            except ValueError:          # another drive (Windows): no relative path
                pass


def config(command: str, model, *, program, seed=None, deadlock=None) -> dict:
    """The configuration of a ``run``/``explore`` command: the files it read,
    the model as resolved (team, rates per agent, properties, reductions,
    time abstraction: what readers of the trace show) and, under
    ``"options"``, the options whole as :meth:`pccl.model.options.CommonOptions.to_dict`
    writes them, from which replay rebuilds the model
    (:func:`pccl.tools.replay.model_from_config`).  ``seed`` and ``deadlock``
    replace the options' (``simulate`` records its first bad seed; ``graph``
    its deadlock check)."""
    m = model
    o = m.options
    world = o.world if isinstance(o.world, (str, os.PathLike)) else None
    options = o.to_dict()
    if seed is not None and "seed" in options:
        options["seed"] = seed
    if deadlock is None:
        deadlock = getattr(o, "deadlock", True)
    elif "deadlock" in options:
        options["deadlock"] = bool(deadlock)
    cfg = {"command": command,
           "program": _file(program),
           "world": _file(world),
           "blackbox": o.blackbox if isinstance(o.blackbox, str) else m.blackbox.name,
           "agents": m.N,
           "delta": m.delta,
           "n0": m.n0,
           "rates": list(m.rho),
           "events": m.events_policy,
           "collisions": bool(m.collisions),
           "overrides": {k: str(v) for k, v in dict(o.overrides or {}).items()},
           "invariants": list(o.invariants),
           "property_options": list(o.properties),
           "properties": [p.name for p in m.properties],
           "reductions": list(m.reduction.on),
           "max_time": m.max_time,
           "abstract_time": m.abstract_time,
           "deadlock": bool(deadlock),
           "pccl_version": pccl_version(),
           "options": options}
    if command == "run":
        cfg["seed"] = options.get("seed") if seed is None else seed
        cfg["max_steps"] = options.get("max_steps")
        cfg["stall_steps"] = options.get("stall_steps")
    return cfg


# ---------------------------------------------------------------------------
# typed states and changes
# ---------------------------------------------------------------------------

def _status(model, code):
    return D.status_json(model, code)


def state_typed(model, st) -> dict:
    """A configuration as typed JSON data (without the pending computation k,
    which ``at`` describes)."""
    agents = []
    for i, ag in enumerate(st[AGS]):
        r = ag[REACH]
        agents.append({
            "id": i, "status": _status(model, ag[STATUS]), "at": model.compiled.describe_k(ag[PC]),
            "counter": ag[CNT], "lockState": D.LOCK_NAMES[ag[LCK]],
            "position": list(ag[POS]),
            "target": None if r[TARGET] is None else list(r[TARGET]),
            "doReach_done": r[DONE], "doReach_fail": r[FAIL],
            "variables": {n: to_json(v, t) for n, t, v in D.agent_vars(model, st, i)}})
    return {"time": st[TIME], "phase": D._phase(st[PHASE]), "lockQueue": list(st[LQ]),
            "shared": {n: to_json(v, t) for n, t, v in D.shared_vars(model, st)},
            "agents": agents, "env": to_json(st[ENV])}


def changes(model, a, b) -> list:
    """Typed changes between two configurations: [{"cell", "old", "new"}]."""
    out = []

    def add(cell, old, new):
        out.append({"cell": cell, "old": old, "new": new})

    if a[TIME] != b[TIME]:
        add({"cell": "time"}, a[TIME], b[TIME])
    if a[PHASE] != b[PHASE]:
        add({"cell": "phase"}, D._phase(a[PHASE]), D._phase(b[PHASE]))
    if a[LQ] != b[LQ]:
        add({"cell": "lockQueue"}, list(a[LQ]), list(b[LQ]))
    if a[SH] is not b[SH]:
        for (n, ty, va), (_, _, vb) in zip(D.shared_vars(model, a), D.shared_vars(model, b)):
            if va != vb:
                add({"var": n}, to_json(va, ty), to_json(vb, ty))
    for i, (ga, gb) in enumerate(zip(a[AGS], b[AGS])):
        if ga is gb:
            continue
        for (n, ty, va), (_, _, vb) in zip(D.agent_vars(model, a, i), D.agent_vars(model, b, i)):
            if va != vb:
                add({"agent": i, "var": n}, to_json(va, ty), to_json(vb, ty))
        if ga[CNT] != gb[CNT]:
            add({"agent": i, "cell": "counter"}, ga[CNT], gb[CNT])
        if ga[POS] != gb[POS]:
            add({"agent": i, "cell": "position"}, list(ga[POS]), list(gb[POS]))
        if ga[LCK] != gb[LCK]:
            add({"agent": i, "cell": "lockState"}, D.LOCK_NAMES[ga[LCK]], D.LOCK_NAMES[gb[LCK]])
        if ga[STATUS] != gb[STATUS]:
            add({"agent": i, "cell": "status"}, _status(model, ga[STATUS]), _status(model, gb[STATUS]))
        ra, rb = ga[REACH], gb[REACH]
        if ra[TARGET] != rb[TARGET]:
            add({"agent": i, "cell": "target"}, None if ra[TARGET] is None else list(ra[TARGET]),
                None if rb[TARGET] is None else list(rb[TARGET]))
        if ra[DONE] != rb[DONE]:
            add({"agent": i, "cell": "doReach_done"}, ra[DONE], rb[DONE])
        if ra[FAIL] != rb[FAIL]:
            add({"agent": i, "cell": "doReach_fail"}, ra[FAIL], rb[FAIL])
    if a[ENV] != b[ENV]:
        add({"cell": "env"}, to_json(a[ENV]), to_json(b[ENV]))
    return out


def cell_name(cell: dict) -> str:
    """``waitTime[0]``, ``reqid``, ``pos[1]``, ``time``: as the text views print cells."""
    c = str(cell.get("cell"))
    name = cell.get("var") or {"position": "pos"}.get(c, c)
    return f"{name}[{cell['agent']}]" if "agent" in cell else name


def branch_taken(model, label, before, after) -> Optional[dict]:
    """For an ``if`` or ``while`` step: which branch was taken, derived from
    the agent's pending computation before and after (None otherwise, and
    when the agent got stuck evaluating the condition)."""
    rule, i, sid = label
    if rule != "STATEMENT" or i is None:
        return None
    ag, ag2 = before[AGS][i], after[AGS][i]
    if ag2[STATUS] != ag[STATUS]:
        return None
    info = model.ctl.info(ag[PC])
    if info.kind == K_IF:
        pcs = info.branch_pcs
        stmt = model.compiled.stmts[info.sid]
        try:
            k = pcs.index(ag2[PC])
        except ValueError:
            return None
        n = len(stmt.branches)
        if k == n:
            taken = "else" if stmt.orelse else "none"
        elif k == 0:
            taken = "then"
        else:
            taken = f"else if #{k}"
        if k < n:
            span = stmt.branches[k][1][0].span if stmt.branches[k][1] else None
        else:
            span = stmt.orelse[0].span if stmt.orelse else None
        return {"kind": "if", "index": k, "taken": taken,
                "line": span.line if span else None}
    if info.kind == K_WHILE:
        body = ag2[PC] == info.body_pc
        return {"kind": "while", "index": 0 if body else 1, "taken": "body" if body else "exit",
                "line": None}
    return None


def branch_text(br: Optional[dict]) -> str:
    if not br:
        return ""
    if br["kind"] == "if":
        t = br["taken"]
        if t == "none":
            return "→ no branch (condition false, no else)"
        return f"→ {t}" + (f" (line {br['line']})" if br.get("line") else "")
    return "→ loop body" if br["taken"] == "body" else "→ loop exit"


def step_record(model, n, label, before, after) -> dict:
    info = D.label_info(model, label, before)
    rule, agent, detail = label
    column = None
    if rule == "EVENT SELECT" and detail is not None:
        column = model.program.events[detail].guard.span.column
    elif info["line"] is not None and isinstance(detail, int) and rule not in ("DOREACH INVOKE",):
        sp = model.compiled.stmt_span(detail)
        column = sp.column if sp else None
    rec = {"index": n, "time": before[TIME], "agent": agent, "rule": info["rule"],
           "event": info["event"], "line": info["line"], "column": column,
           "source": info["source"] or None,
           "branch": branch_taken(model, label, before, after),
           "changes": changes(model, before, after)}
    if rule == "DOREACH INVOKE":
        rec["outcome"] = detail
    return rec


def violation_record(model, v) -> Optional[dict]:
    if v is None:
        return None
    span = getattr(v, "span", None)
    return {"kind": v.kind, "name": v.name, "message": v.message, "agent": v.agent,
            "line": span.line if span else None, "column": span.column if span else None}


def document(model, cfg: dict, states: list, labels: list, *, status: str,
             violation=None, message: Optional[str] = None) -> dict:
    """The trace document of a path (``states[0]`` initial; ``labels[k]`` leads
    from ``states[k]`` to ``states[k + 1]``)."""
    steps = [step_record(model, n + 1, lab, states[n], states[n + 1])
             for n, lab in enumerate(labels)]
    return {"format": FORMAT, "version": VERSION, "config": cfg,
            "initial": state_typed(model, states[0]) if states else None,
            "steps": steps,
            "result": {"status": status, "message": message,
                       "violation": violation_record(model, violation)},
            "final": state_typed(model, states[-1]) if states else None}


def explore_document(res, cfg: dict) -> dict:
    """The trace document of an :class:`~pccl.api.ExploreResult`: its first
    counterexample; without one the witness of the first ``reachable P``
    that has one (``result.witness``); else no steps."""
    m = res.model
    if res.counterexamples:
        cx = res.counterexamples[0]
        tr = cx.trace
        if tr is None:          # reachable P found unreachable: no path
            return document(m, cfg, [], [], status=res.status, violation=cx.violation,
                            message=res.verdict)
        doc = document(m, cfg, list(tr.states), list(tr.labels), status=res.status,
                       violation=cx.violation, message=res.verdict)
        if cx.cycle_start is not None:
            doc["result"]["cycle_start"] = cx.cycle_start
        return doc
    if res.witnesses:           # reachable P holds: its (shortest) witness path
        w = res.witnesses[0]
        tr = w["_trace"]
        doc = document(m, cfg, list(tr.states), list(tr.labels), status=res.status,
                       message=res.verdict)
        doc["result"]["witness"] = {"name": w["name"], "text": w["text"]}
        return doc
    return document(m, cfg, [], [], status=res.status, message=res.verdict)


def run_document(res, cfg: dict) -> dict:
    m = res.model
    if res.trace:
        states = [res.trace[0][1]] + [b for _, _, b in res.trace]
        labels = [lab for lab, _, _ in res.trace]
    else:
        states, labels = [res.final], []
    v = res.violations[0] if res.violations else None
    return document(m, cfg, states, labels, status=res.status, violation=v, message=res.message)


def write(doc: dict, path) -> None:
    from pccl.lang.errors import PcclError
    _relative_to(doc, path)
    try:
        with open(path, "w", encoding="utf-8") as f:
            json.dump(doc, f, indent=1, default=str)
            f.write("\n")
    except OSError as e:
        raise PcclError(f"cannot write trace: {e.strerror or e}", filename=os.fspath(path)) from None


def normal(x):
    """JSON round trip: tuples become lists, as in a file."""
    return json.loads(json.dumps(x, default=str))
