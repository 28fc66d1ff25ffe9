"""``pccl replay FILE``: re-execute a trace file through the interpreter.

The model is rebuilt from the recorded configuration; the replay starts
from the initial state of the model equal to the recorded one and applies
each recorded step: its (rule, agent, event, line, column, outcome) must be
among the enabled transitions, and the transition must make the recorded
changes.  The first step where that fails is the divergence.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Optional

from . import traces as T
from .errors import PcclError


@dataclass
class ReplayResult:
    status: str                    # violation | clean | diverged | empty
    exit_status: int               # 1 violation reproduced, 0 clean run reproduced, 2 diverged
    message: str
    warnings: list = field(default_factory=list)
    model: object = None
    states: list = field(default_factory=list)
    labels: list = field(default_factory=list)
    diverged_at: Optional[int] = None      # step index (0: the initial state)
    steps_total: int = 0
    doc: Optional[dict] = None


def load(path) -> dict:
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except OSError as e:
        raise PcclError(f"cannot read trace: {e.strerror or e}", filename=os.fspath(path)) from None
    except json.JSONDecodeError as e:
        raise PcclError(f"not a JSON trace file: {e}", filename=os.fspath(path)) from None
    if isinstance(doc, dict) and isinstance(doc.get("trace"), dict) and "format" not in doc:
        doc = doc["trace"]        # the output of --format json
    if not isinstance(doc, dict) or doc.get("format") != T.FORMAT:
        raise PcclError("not a pccl trace file (no \"format\": \"pccl-trace\")",
                        filename=os.fspath(path))
    if doc.get("version") != T.VERSION:
        raise PcclError(f"trace format version {doc.get('version')!r} is not supported "
                        f"(this pccl reads version {T.VERSION})", filename=os.fspath(path))
    return doc


def _resolve(rec: Optional[dict], trace_path, what, warnings) -> Optional[str]:
    if rec is None:
        return None
    p = rec["path"]
    if not os.path.exists(p):
        alt = os.path.join(os.path.dirname(os.fspath(trace_path)), p)
        if os.path.exists(alt):
            p = alt
    now = T.sha256_of(p)
    if now is None:
        raise PcclError(f"the {what} {rec['path']} recorded in the trace does not exist",
                        filename=os.fspath(trace_path))
    if rec.get("sha256") and now != rec["sha256"]:
        warnings.append(f"warning: {what} {rec['path']} has changed since the trace was "
                        f"recorded (sha256 {rec['sha256'][:12]}… recorded, {now[:12]}… now)")
    return p


def model_from_config(cfg: dict, trace_path, warnings: list):
    from .api import make_model
    prog = _resolve(cfg["program"], trace_path, "program", warnings)
    world = _resolve(cfg.get("world"), trace_path, "world", warnings)
    rates = {i: r for i, r in enumerate(cfg.get("rates") or []) if r != 1}
    opts = dict(delta=cfg["delta"], n0=cfg["n0"], rates=rates, events=cfg["events"],
                collisions=cfg["collisions"], overrides=dict(cfg.get("overrides") or {}),
                invariants=tuple(cfg.get("invariants") or ()),
                properties=tuple(cfg.get("property_options") or ()),
                max_time=cfg.get("max_time"),
                abstract_time=bool(cfg.get("abstract_time")),
                reduce="none")      # a trace records unreduced steps
    if cfg.get("pccl_version") not in (None, T.pccl_version()):
        warnings.append(f"warning: the trace was written by pccl {cfg['pccl_version']}, "
                        f"this is pccl {T.pccl_version()}")
    return make_model(prog, world=world, blackbox=cfg["blackbox"], agents=cfg["agents"], **opts)


_IDENTITY = ("rule", "agent", "event", "line", "column", "source")


def _identity(rec: dict) -> tuple:
    return tuple(rec.get(k) for k in _IDENTITY) + (rec.get("outcome"),)


def describe(rec: dict) -> str:
    who = f"agent {rec['agent']}" if rec.get("agent") is not None else "system"
    s = f"{who} {rec['rule']}"
    if rec.get("event"):
        s += f" [{rec['event']}]"
    if rec.get("line"):
        s += f" line {rec['line']}"
        if rec.get("source"):
            s += f": {rec['source']}"
    if rec.get("outcome") is not None:
        s += f" outcome {rec['outcome']}"
    return s


def _changes_text(chs: list) -> str:
    if not chs:
        return "no change"
    return ", ".join(f"{T.cell_name(c['cell'])} {json.dumps(c['old'])} -> {json.dumps(c['new'])}"
                     for c in chs)


def _state_difference(a, b, prefix: str = "") -> str:
    """The first place where two typed states differ (for messages)."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in list(a) + [k for k in b if k not in a]:
            if a.get(k) != b.get(k):
                return _state_difference(a.get(k), b.get(k), f"{prefix}.{k}" if prefix else k)
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for n, (x, y) in enumerate(zip(a, b)):
            if x != y:
                return _state_difference(x, y, f"{prefix}[{n}]")
    return f"{prefix}: recorded {json.dumps(a)}, replayed {json.dumps(b)}"


#: Violation kinds of temporal properties (pccl/liveness.py).
_TEMPORAL_KINDS = ("liveness", "timelock", "response", "unreachable", "stall")


def replay(path) -> ReplayResult:
    doc = load(path)
    warnings: list = []
    m = model_from_config(doc["config"], path, warnings)
    steps = doc.get("steps") or []
    res = ReplayResult("empty", 0, "", warnings, m, steps_total=len(steps), doc=doc)
    if doc.get("initial") is None:
        res.message = (f"nothing to replay: the recorded {doc['config']['command']} found no "
                       f"counterexample ({(doc.get('result') or {}).get('message')})")
        return res
    want0 = T.normal(doc["initial"])
    inits = []
    state = None
    for s in m.init_states():      # a generator: stop at the recorded state
        inits.append(s)
        if T.normal(T.state_typed(m, s)) == want0:
            state = s
            break
    if state is None:
        res.status, res.exit_status, res.diverged_at = "diverged", 2, 0
        closest = _state_difference(want0, T.normal(T.state_typed(m, inits[0]))) if inits else ""
        res.message = (f"diverged at the initial state: none of the model's {len(inits)} initial "
                       f"states equals the recorded one (first difference from initial state 1: "
                       f"{closest})")
        return res
    res.states = [state]
    for rec in steps:
        n = rec["index"]
        succ = m.successors(state)
        ident = _identity(rec)
        want = T.normal(rec["changes"])
        same_label, found = [], None
        for label, nxt in succ:
            got = T.step_record(m, n, label, state, nxt)
            if _identity(got) != ident:
                continue
            chs = T.normal(got["changes"])
            if chs == want:
                found = (label, nxt)
                break
            same_label.append(chs)
        if found is None:
            res.status, res.exit_status, res.diverged_at = "diverged", 2, n
            where = f"diverged at step {n} of {len(steps)} ({describe(rec)})"
            if same_label:
                res.message = (f"{where}: the transition is enabled but its changes differ: "
                               f"recorded {_changes_text(rec['changes'])}; replayed "
                               f"{_changes_text(same_label[0])}")
            else:
                recs = [T.step_record(m, n, lab, state, nxt) for lab, nxt in succ]
                moved = [r for r in recs if _identity(r)[:5] == ident[:5]]
                if moved:
                    res.message = (f"{where}: the program differs here: line {rec['line']} now "
                                   f"reads '{moved[0]['source']}'")
                else:
                    enabled = sorted({describe(r) for r in recs})
                    res.message = (f"{where}: that transition is not enabled; enabled here: "
                                   + ("; ".join(enabled) if enabled else "none"))
            return res
        res.labels.append(found[0])
        state = found[1]
        res.states.append(state)
    # the end: does the violation (or its absence) reproduce?
    viols = list(m.violations(state))
    result = doc.get("result") or {}
    if not viols and doc["config"].get("deadlock", True) and not m.successors(state) \
            and m.terminal_kind(state) == "deadlock":
        viols = [m.deadlock_violation(state)]
    recorded = result.get("violation")
    if recorded and recorded.get("kind") in _TEMPORAL_KINDS:
        # a lasso or a bounded-response path: the steps are what can be
        # re-executed; the verdict is over the whole state graph
        res.status, res.exit_status = "violation", 1
        res.message = (f"reproduced: every step of the recorded {recorded['kind']} "
                       f"counterexample ({recorded['message']}) re-executes "
                       f"(after {len(steps)} steps; the temporal verdict itself is "
                       f"decided by explore)")
        return res
    if recorded:
        match = [v for v in viols if v.kind == recorded["kind"] and v.message == recorded["message"]]
        if match:
            res.status, res.exit_status = "violation", 1
            res.message = f"reproduced: {match[0].message} (after {len(steps)} steps)"
        else:
            res.status, res.exit_status, res.diverged_at = "diverged", 2, len(steps)
            seen = "; ".join(v.message for v in viols) or "no violation"
            res.message = (f"diverged at the end: every step reproduced, but the recorded "
                           f"violation ({recorded['message']}) is not: {seen}")
        return res
    if viols:
        res.status, res.exit_status, res.diverged_at = "diverged", 2, len(steps)
        res.message = (f"diverged at the end: the recorded {result.get('status')} run ended "
                       f"without a violation, the replay ends with {viols[0].message}")
        return res
    if result.get("status") == "max-steps":
        res.status, res.exit_status = "violation", 1
        res.message = f"reproduced: {result.get('message')} (after {len(steps)} steps)"
        return res
    res.status, res.exit_status = "clean", 0
    res.message = f"reproduced: {result.get('status')} — {result.get('message')} (after {len(steps)} steps)"
    return res
