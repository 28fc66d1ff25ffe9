"""Reading a trace file as data: parse it safely and check its structure.

A trace file comes from colleagues, CI artefacts and bug reports, so
:func:`parse` and :func:`check` treat it as untrusted input: invalid UTF-8,
JSON syntax errors, integers of thousands of digits, deep nesting, NaN and
values of the wrong type are each one :class:`~pccl.lang.errors.PcclError` naming
the field (``steps[3].changes: expected a list, got a number``), never a
Python exception.  Nothing here imports or runs anything a file names.

The structure checked is that of ``docs/trace-format.schema.json`` (keys a
newer writer may add are ignored), plus what the schema cannot say: step
indexes in order, one state per agent, cells of agents that exist, a
``cycle_start`` inside the steps, a result that fits the command.
"""

from __future__ import annotations

import json
import os
from typing import Any, NoReturn

from pccl.lang.data import JSON_NAMES, is_finite_number, is_integer, kind
from pccl.lang.errors import PcclError
from pccl.lang.world import MAX_AGENTS

#: Most decimal digits of an integer in a trace file (as in a PCCL literal).
MAX_DIGITS = 4300
#: Deepest nesting of a typed value (a list of lists ...).
MAX_VALUE_DEPTH = 32
#: Largest n0 and per-agent rate a file may ask for.
MAX_N0 = 1_000_000

RULES = ("EVENT SELECT", "IDLE", "STATEMENT", "EXIT", "DOREACH UPDATE", "COUNTER ADVANCE",
         "LOCK REQUEST", "ATOMIC WAIT", "ATOMIC EXECUTION", "LOCK RELEASE", "TIME ADVANCE",
         "DOREACH INVOKE", "EVENT TRANS", "SKIP EVENT")
RUN_STATUSES = ("final", "bounded", "violation", "deadlock", "max-steps", "stalled",
                "interrupted")
EXPLORE_STATUSES = ("violation", "exhaustive", "bounded", "interrupted")
VIOLATION_KINDS = ("invariant", "assert", "stuck", "deadlock", "collision", "liveness",
                   "timelock", "response", "unreachable",
                   # a run's --property monitor: the property's own kind
                   "eventually", "leadsto", "within", "stall", "frozen")
#: Kinds whose counterexample may be a lasso (``cycle_start``).
LASSO_KINDS = ("liveness", "timelock")
STATE_CELLS = ("time", "phase", "lockQueue", "env", "round")
AGENT_CELLS = ("counter", "position", "lockState", "status", "target", "doReach_done",
               "doReach_fail",
               # version 2 (pccl/output/codec.py): the pending computation, doReach's t0 and obstacles
               "k", "t0", "obstacles", "legStart")


class _Bad(Exception):
    def __init__(self, path: str, message: str):
        super().__init__(message)
        self.path = path
        self.message = message


# ---------------------------------------------------------------------------
# parsing
# ---------------------------------------------------------------------------

def _int(text: str) -> int:
    digits = len(text.lstrip("-"))
    if digits > MAX_DIGITS:
        raise ValueError(f"an integer of {digits} digits (at most {MAX_DIGITS})")
    return int(text)


def _constant(name: str):
    raise ValueError(f"{name} is not a JSON number")


def parse(path) -> Any:
    """The JSON value in the file ``path``; any problem is a PcclError."""
    name = os.fspath(path)
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise PcclError(f"cannot read trace: {e.strerror or e}", filename=name) from None
    return parse_bytes(data, name)


def parse_bytes(data: bytes, name: str) -> Any:
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise PcclError(f"not a trace file: not UTF-8 (byte 0x{data[e.start]:02x} at offset "
                        f"{e.start})", filename=name) from None
    if text.startswith("\ufeff"):
        text = text[1:]
    try:
        return json.loads(text, parse_int=_int, parse_constant=_constant)
    except json.JSONDecodeError as e:
        raise PcclError(f"not a JSON trace file: {e.msg}", filename=name, line=e.lineno,
                        column=e.colno) from None
    except (ValueError, RecursionError) as e:     # our limits, Python's int-from-str limit
        what = "nested too deeply" if isinstance(e, RecursionError) else str(e)
        raise PcclError(f"not a trace file: {what}", filename=name) from None


# ---------------------------------------------------------------------------
# structure
# ---------------------------------------------------------------------------

def _what(v) -> str:
    return JSON_NAMES.get(kind(v)) or type(v).__name__     # (the last: not from JSON)


def _fail(path: str, expected: str, v=None, *, got: bool = True) -> NoReturn:
    raise _Bad(path, f"expected {expected}" + (f", got {_show(v)}" if got else ""))


def _show(v) -> str:
    if isinstance(v, (dict, list)) or v is None:
        return _what(v)
    text = json.dumps(v)
    return f"{_what(v)} {text if len(text) <= 40 else text[:37] + '...'}"


def _join(path: str, key) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else str(key)


def _obj(v, path, required=()) -> dict:
    if not isinstance(v, dict):
        _fail(path or "the file", "an object", v)
    for k in required:
        if k not in v:
            raise _Bad(_join(path, k), "missing")
    return v


def _integer(v, path, lo=None, hi=None, null=False):
    if v is None and null:
        return
    if not is_integer(v):
        _fail(path, "an integer" + (" or null" if null else ""), v)
    if lo is not None and v < lo:
        _fail(path, f"an integer >= {lo}", v)
    if hi is not None and v > hi:
        _fail(path, f"an integer <= {hi}", v)


def _number(v, path, lo=None, positive=False, null=False):
    if v is None and null:
        return
    if not is_finite_number(v):
        _fail(path, "a finite number" + (" or null" if null else ""), v)
    if positive and not v > 0:
        _fail(path, "a positive number", v)
    if lo is not None and v < lo:
        _fail(path, f"a number >= {lo}", v)


def _string(v, path, null=False, nonempty=False):
    if v is None and null:
        return
    if not isinstance(v, str):
        _fail(path, "a string" + (" or null" if null else ""), v)
    if nonempty and not v.strip():
        _fail(path, "a non-empty string", v)


def _boolean(v, path):
    if not isinstance(v, bool):
        _fail(path, "true or false", v)


def _enum(v, path, choices):
    if not isinstance(v, str) or v not in choices:
        _fail(path, "one of " + ", ".join(json.dumps(c) for c in choices), v)


def _list(v, path, null=False) -> list:
    if v is None and null:
        return []
    if not isinstance(v, list):
        _fail(path, "a list" + (" or null" if null else ""), v)
    return v


def _value(v, path, depth=0, objects=False):
    """A typed value: number, bool, string, null or a list of values (and,
    with ``objects``, any JSON object: an agent's status, the environment)."""
    if depth > MAX_VALUE_DEPTH:
        raise _Bad(path, f"a value nested more than {MAX_VALUE_DEPTH} levels deep")
    if v is None or isinstance(v, (bool, str)):
        return
    if isinstance(v, (int, float)):
        _number(v, path)
        return
    if isinstance(v, list):
        for n, x in enumerate(v):
            _value(x, _join(path, n), depth + 1, objects)
        return
    if objects and isinstance(v, dict):
        for k, x in v.items():
            _value(x, _join(path, k), depth + 1, objects)
        return
    _fail(path, "a typed value (number, boolean, string, list or null)", v)


def _file(v, path, null=False):
    if v is None and null:
        return
    _obj(v, path, ("path", "sha256"))
    _string(v["path"], _join(path, "path"), nonempty=True)
    for k in ("absolute", "relative"):          # optional: older files have neither
        if k in v:
            _string(v[k], _join(path, k), nonempty=True)
    sha = v["sha256"]
    if sha is not None and not (isinstance(sha, str) and len(sha) == 64
                                and all(c in "0123456789abcdef" for c in sha)):
        _fail(_join(path, "sha256"), "64 lowercase hex digits or null", sha)


def _config(c) -> dict:
    _obj(c, "config", ("command", "program", "world", "blackbox", "agents", "delta", "n0",
                       "rates", "events", "collisions", "overrides", "invariants", "properties",
                       "max_time", "abstract_time", "deadlock", "pccl_version"))
    p = "config"
    _enum(c["command"], f"{p}.command", ("run", "explore"))
    _file(c["program"], f"{p}.program")
    _file(c["world"], f"{p}.world", null=True)
    _string(c["blackbox"], f"{p}.blackbox", nonempty=True)
    _integer(c["agents"], f"{p}.agents", 1, MAX_AGENTS)
    _number(c["delta"], f"{p}.delta", positive=True)
    _integer(c["n0"], f"{p}.n0", 1, MAX_N0)
    rates = _list(c["rates"], f"{p}.rates")
    for n, r in enumerate(rates):
        _integer(r, f"{p}.rates[{n}]", 1, MAX_N0)
    if len(rates) not in (0, c["agents"]):
        _fail(f"{p}.rates", f"one rate per agent ({c['agents']})", rates, got=False)
    _enum(c["events"], f"{p}.events", ("any", "first"))
    _boolean(c["collisions"], f"{p}.collisions")
    ov = _obj(c["overrides"], f"{p}.overrides")
    for k, x in ov.items():
        _string(x, f"{p}.overrides.{k}")
    for key in ("invariants", "property_options", "properties"):
        if key in c:
            for n, x in enumerate(_list(c[key], f"{p}.{key}")):
                _string(x, f"{p}.{key}[{n}]")
    if "reductions" in c:
        for n, x in enumerate(_list(c["reductions"], f"{p}.reductions")):
            _enum(x, f"{p}.reductions[{n}]", ("merge", "symmetry", "por", "dead", "counters"))
    _number(c["max_time"], f"{p}.max_time", lo=0, null=True)
    _boolean(c["abstract_time"], f"{p}.abstract_time")
    _boolean(c["deadlock"], f"{p}.deadlock")
    _string(c["pccl_version"], f"{p}.pccl_version")
    if "seed" in c:
        _integer(c["seed"], f"{p}.seed")
    if "max_steps" in c:
        _integer(c["max_steps"], f"{p}.max_steps", 1)
    if "stall_steps" in c:
        _integer(c["stall_steps"], f"{p}.stall_steps", 0)
    return c


def _position(v, path, null=False):
    if v is None and null:
        return
    if not isinstance(v, list) or len(v) != 3:
        _fail(path, "a position [x, y, z]", v)
    for n, x in enumerate(v):
        _number(x, f"{path}[{n}]")


def _state(s, path, n_agents: int, version: int = 2):
    _obj(s, path, ("time", "phase", "lockQueue", "shared", "agents", "env"))
    _number(s["time"], f"{path}.time", lo=0)
    _enum(s["phase"], f"{path}.phase", ("discrete", "dynamic"))
    for n, x in enumerate(_list(s["lockQueue"], f"{path}.lockQueue")):
        _integer(x, f"{path}.lockQueue[{n}]", 0, n_agents - 1)
    for k, x in _obj(s["shared"], f"{path}.shared").items():
        _value(x, f"{path}.shared.{k}")
    ags = _list(s["agents"], f"{path}.agents")
    if len(ags) != n_agents:
        _fail(f"{path}.agents", f"one entry per agent ({n_agents} in config.agents), got "
              f"{len(ags)}", got=False)
    for i, a in enumerate(ags):
        ap = f"{path}.agents[{i}]"
        _obj(a, ap, ("id", "status", "at", "counter", "lockState", "position", "target",
                     "doReach_done", "doReach_fail", "variables")
             + (("k", "t0", "obstacles") if version >= 2 else ()))
        if version >= 2:
            _list(a["k"], f"{ap}.k")
            if a["t0"] is not None:
                _number(a["t0"], f"{ap}.t0")
            _value(a["obstacles"], f"{ap}.obstacles")
        if a["id"] != i or not is_integer(a["id"]):
            _fail(f"{ap}.id", f"{i}", a["id"])
        st = _obj(a["status"], f"{ap}.status", ("status",))
        _enum(st["status"], f"{ap}.status.status", ("running", "exited", "stuck"))
        _string(a["at"], f"{ap}.at")
        _integer(a["counter"], f"{ap}.counter", 0)
        _enum(a["lockState"], f"{ap}.lockState", ("idle", "request", "lock"))
        _position(a["position"], f"{ap}.position")
        _position(a["target"], f"{ap}.target", null=True)
        _boolean(a["doReach_done"], f"{ap}.doReach_done")
        _boolean(a["doReach_fail"], f"{ap}.doReach_fail")
        for k, x in _obj(a["variables"], f"{ap}.variables").items():
            _value(x, f"{ap}.variables.{k}")
    _value(s["env"], f"{path}.env", objects=True)


def _cell(c, path, n_agents: int):
    _obj(c, path)
    keys = set(c)
    if "agent" in keys:
        _integer(c["agent"], f"{path}.agent", 0, n_agents - 1)
    if keys == {"var"} or keys == {"agent", "var"}:
        _string(c["var"], f"{path}.var", nonempty=True)
    elif keys == {"cell"}:
        _enum(c["cell"], f"{path}.cell", STATE_CELLS)
    elif keys == {"agent", "cell"}:
        _enum(c["cell"], f"{path}.cell", AGENT_CELLS)
    else:
        _fail(path, 'a cell: {"var"}, {"agent", "var"}, {"cell"} or {"agent", "cell"}',
              sorted(keys), got=False)


def _step(s, path, n: int, n_agents: int):
    _obj(s, path, ("index", "time", "agent", "rule", "event", "line", "column", "source",
                   "branch", "changes"))
    if not is_integer(s["index"]) or s["index"] != n:
        _fail(f"{path}.index", f"{n} (steps are numbered from 1, in order)", s["index"])
    _number(s["time"], f"{path}.time", lo=0)
    _integer(s["agent"], f"{path}.agent", 0, n_agents - 1, null=True)
    _enum(s["rule"], f"{path}.rule", RULES)
    _string(s["event"], f"{path}.event", null=True)
    _integer(s["line"], f"{path}.line", 1, null=True)
    _integer(s["column"], f"{path}.column", 1, null=True)
    _string(s["source"], f"{path}.source", null=True)
    br = s["branch"]
    if br is not None:
        _obj(br, f"{path}.branch", ("kind", "index", "taken", "line"))
        _enum(br["kind"], f"{path}.branch.kind", ("if", "while"))
        _integer(br["index"], f"{path}.branch.index", 0)
        _string(br["taken"], f"{path}.branch.taken")
        _integer(br["line"], f"{path}.branch.line", 1, null=True)
    if "outcome" in s:
        _integer(s["outcome"], f"{path}.outcome", 0, null=True)
    for k, ch in enumerate(_list(s["changes"], f"{path}.changes")):
        cp = f"{path}.changes[{k}]"
        _obj(ch, cp, ("cell", "old", "new"))
        _cell(ch["cell"], f"{cp}.cell", n_agents)
        _value(ch["old"], f"{cp}.old", objects=True)
        _value(ch["new"], f"{cp}.new", objects=True)


def _violation(v, path):
    _obj(v, path, ("kind", "name", "message", "agent", "line", "column"))
    _enum(v["kind"], f"{path}.kind", VIOLATION_KINDS)
    _string(v["name"], f"{path}.name")
    _string(v["message"], f"{path}.message")
    _integer(v["agent"], f"{path}.agent", 0, null=True)
    _integer(v["line"], f"{path}.line", 1, null=True)
    _integer(v["column"], f"{path}.column", 1, null=True)


def _result(r, cfg: dict, n_steps: int, has_path: bool):
    p = "result"
    _obj(r, p, ("status", "message", "violation"))
    run = cfg["command"] == "run"
    _enum(r["status"], f"{p}.status", RUN_STATUSES if run else EXPLORE_STATUSES)
    _string(r["message"], f"{p}.message", null=True)
    v = r["violation"]
    if v is not None:
        _violation(v, f"{p}.violation")
    kind = v["kind"] if v is not None else None
    if not run:
        if r["status"] == "violation" and v is None:
            raise _Bad(f"{p}.violation", 'missing: result.status is "violation"')
        if r["status"] in ("exhaustive", "bounded") and v is not None:
            raise _Bad(f"{p}.violation", f"expected null: result.status is "
                                         f"{json.dumps(r['status'])}")
    if "cycle_start" in r:
        _cycle_start(r["cycle_start"], f"{p}.cycle_start", n_steps, kind, run)
    w = r.get("witness")
    if w is not None:
        _witness(w, f"{p}.witness", run or v is not None)
    _result_path(has_path, run, v, kind, w)


def _cycle_start(cs, path: str, n_steps: int, kind, run: bool) -> None:
    """Step of :func:`_result`: a lasso's ``cycle_start``."""
    _integer(cs, path, 0, max(0, n_steps - 1))
    if kind not in LASSO_KINDS:
        raise _Bad(path, "only a liveness or time-lock counterexample is a "
                         "lasso")
    if run:
        raise _Bad(path, "a run is not a lasso")


def _witness(w, path: str, misplaced: bool) -> None:
    """Step of :func:`_result`: the ``witness`` of an explore without a
    violation (``misplaced``: a run's, or one beside a violation)."""
    _obj(w, path, ("name", "text"))
    _string(w["name"], f"{path}.name")
    _string(w["text"], f"{path}.text")
    if misplaced:
        raise _Bad(path, "only an explore without a violation records a witness")


def _result_path(has_path: bool, run: bool, v, kind, w) -> None:
    """Step of :func:`_result`: whether the result's kind agrees with the
    presence of a path (``initial`` not null)."""
    if kind == "unreachable" and has_path:
        raise _Bad("steps", "an unreachable verdict has no path (initial null, no steps)")
    if not has_path:
        if run:
            raise _Bad("initial", "a run has an initial state")
        if v is not None and kind != "unreachable":
            raise _Bad("initial", f"a {kind} violation has a path from an initial state")
        if w is not None:
            raise _Bad("initial", "a witness has a path from an initial state")
    elif not run and v is None and w is None:
        raise _Bad("result", "a path without a violation or a witness to show")


def check(doc: Any, name: str) -> dict:
    """The trace document ``doc`` (parsed JSON) if its structure is that of
    a trace file; else a PcclError naming the first bad field."""
    from pccl.output import traces as T
    if isinstance(doc, dict) and isinstance(doc.get("trace"), dict) and \
            doc.get("format") in (None, "pccl-output"):
        doc = doc["trace"]        # the output of --format json (older ones had no "format")
    if not isinstance(doc, dict) or doc.get("format") != T.FORMAT:
        raise PcclError("not a pccl trace file (no \"format\": \"pccl-trace\")", filename=name)
    from pccl.output.codec import READS
    version = doc.get("version")
    if not is_integer(version) or version not in READS:
        raise PcclError(f"trace format version {_show(version)} is not supported "
                        f"(this pccl reads versions {', '.join(map(str, READS))})",
                        filename=name)
    try:
        _obj(doc, "", ("config", "initial", "steps", "result", "final"))
        cfg = _config(doc["config"])
        n = cfg["agents"]
        steps = _list(doc["steps"], "steps")
        has_path = doc["initial"] is not None
        if has_path:
            _state(doc["initial"], "initial", n, version)
        for k, s in enumerate(steps):
            _step(s, f"steps[{k}]", k + 1, n)
        if doc["final"] is not None:
            _state(doc["final"], "final", n, version)
        if has_path != (doc["final"] is not None):
            raise _Bad("final", "null exactly when initial is null")
        if not has_path and steps:
            raise _Bad("steps", "no steps when initial is null")
        _result(doc["result"], cfg, len(steps), has_path)
    except _Bad as e:
        raise PcclError(f"{e.path}: {e.message}", filename=name) from None
    return doc


def load(path) -> dict:
    """Parse and check the trace file ``path``."""
    return check(parse(path), os.fspath(path))


__all__ = ["parse", "parse_bytes", "check", "load", "MAX_DIGITS"]
