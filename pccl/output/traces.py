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

from pccl.output import codec as C

FORMAT = C.FORMAT
VERSION = C.VERSION


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
# typed states and changes: the one encoding, pccl/output/codec.py
# ---------------------------------------------------------------------------

state_typed = C.encode_state
changes = C.encode_changes
step_record = C.encode_step
violation_record = C.encode_violation
cell_name = C.cell_name
branch_taken = C.branch_taken


def branch_text(br: Optional[dict]) -> str:
    if not br:
        return ""
    if br["kind"] == "if":
        t = br["taken"]
        if t == "none":
            return "→ no branch (condition false, no else)"
        return f"→ {t}" + (f" (line {br['line']})" if br.get("line") else "")
    return "→ loop body" if br["taken"] == "body" else "→ loop exit"


def document(model, cfg: dict, trace, *, status: str, violation=None,
             message: Optional[str] = None) -> dict:
    """The trace document of a path (a :class:`pccl.search.explorer.Trace`, or
    None: no path): the path as :func:`pccl.output.codec.encode_path` writes it."""
    path = C.encode_path(model, trace)
    return {"format": FORMAT, "version": VERSION, "config": cfg,
            "initial": path["initial"], "steps": path["steps"],
            "result": {"status": status, "message": message,
                       "violation": violation_record(model, violation)},
            "final": path["final"]}


def explore_document(res, cfg: dict) -> dict:
    """The trace document of an :class:`~pccl.api.ExploreResult`: its first
    counterexample; without one the witness of the first ``reachable P``
    that has one (``result.witness``); else no steps."""
    m = res.model
    if res.counterexamples:
        cx = res.counterexamples[0]
        tr = cx.trace
        if tr is None:          # reachable P found unreachable: no path
            return document(m, cfg, None, status=res.status, violation=cx.violation,
                            message=res.verdict)
        doc = document(m, cfg, tr, status=res.status, violation=cx.violation,
                       message=res.verdict)
        if cx.cycle_start is not None:
            doc["result"]["cycle_start"] = cx.cycle_start
        return doc
    if res.witnesses:           # reachable P holds: its (shortest) witness path
        w = res.witnesses[0]
        tr = w["_trace"]
        doc = document(m, cfg, tr, status=res.status, message=res.verdict)
        doc["result"]["witness"] = {"name": w["name"], "text": w["text"]}
        return doc
    return document(m, cfg, None, status=res.status, message=res.verdict)


def run_document(res, cfg: dict) -> dict:
    """The trace document of a :class:`~pccl.tools.runner.RunResult`: its
    recorded path (else its last state alone)."""
    from pccl.search.explorer import Trace
    tr = res.trace if res.trace is not None else Trace((res.final,), ())
    v = res.violations[0] if res.violations else None
    return document(res.model, cfg, tr, status=res.status, violation=v, message=res.message)


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
