"""The one encoding of configurations and steps, and its decoder.

Every JSON form of a state or a step (trace files, ``--format json`` of
``run``/``explore``/``simulate``/``replay``, the HTML viewer's data, the
browser explorer's API) is made here, in one vocabulary: the trace format
of ``docs/trace-format.md`` (version :data:`VERSION`).  The text views and
the API views read the same cells through :mod:`pccl.output.display`; the API's
typed views are built from the *decoded* values (:func:`decode_state`), not
from JSON.

Encoding (``encode_*``): a configuration of a model to typed JSON data.
Values are typed: numbers as numbers (an ``int`` variable an integer, a
``float`` variable a number with ``.0``), bools as bools, positions as
``[x, y, z]``, enums as member names, undefined as ``null``.  Cells of a
change are structured paths: ``{"var": "reqid"}`` (a shared variable),
``{"agent": 0, "var": "waitTime"}`` (a per-agent variable), ``{"cell":
"time"}``, ``{"agent": 1, "cell": "position"}`` (the other cells).

Decoding (``decode_*``): typed JSON data back to the configuration, checked
against the model (an ``int`` variable must hold a JSON integer, an enum one
of its members, a pending computation ``k`` statements of the program).
``decode_state(model, encode_state(model, st)) == st`` for every state
(tests/output/test_codec.py).  Version-1 data (pccl before this module) lacks the
pending computation ``k``, ``t0``, the obstacles and the stuck codes: those
cells decode to :data:`ANY`, which :func:`matches` accepts for any value.
"""

from __future__ import annotations

import math
from typing import Optional

from pccl.output import display as D
from pccl.lang.data import is_integer
from pccl.lang.errors import PcclError
from pccl.semantics.rules import K_IF, K_WHILE
from pccl.model.layout import (AEND, AGS, AR, CNT, DISCRETE, DONE, DYNAMIC, END, ENV, EXITED, FAIL,
                               IDLE, LCK, LOC, LOCK, LQ, N_STATE_CELLS, OBSTACLES, PC, PHASE, POS, REACH, REQUEST,
                               RUNNING, SH, START, STATUS, T0, TARGET, TIME, acq, acquire_sid)
from pccl.lang.values import UNDEF, to_json

#: The round cell of Koord's semantics (pccl/model/koord.py's ``RND``)
RND = N_STATE_CELLS

#: The trace format: its name and the version this module writes.
FORMAT = "pccl-trace"
VERSION = 2
#: The versions :func:`decode_state` and ``pccl replay`` read.
READS = (1, 2)


class DecodeError(PcclError):
    """Data that is not an encoding of a configuration of this model; the
    message names the field (``initial.shared.total: expected an int, got 1.0``)."""


class _Any:
    """A cell an older encoding does not record: it matches any value."""

    _inst: Optional["_Any"] = None

    def __new__(cls):
        if cls._inst is None:
            cls._inst = super().__new__(cls)
        return cls._inst

    def __repr__(self) -> str:
        return "ANY"


ANY = _Any()

_PHASES = {DISCRETE: "discrete", DYNAMIC: "dynamic"}
_PHASE_CODES = {v: k for k, v in _PHASES.items()}
_LOCK_CODES = {v: k for k, v in D.LOCK_NAMES.items()}
assert set(_LOCK_CODES.values()) == {IDLE, REQUEST, LOCK}


# ---------------------------------------------------------------------------
# encoding
# ---------------------------------------------------------------------------

def encode_status(model, code) -> dict:
    """``{"status": "running" | "exited"}``, or ``{"status": "stuck", "kind",
    "reason", "line", "column", "code"}`` (``code``: the status's identity,
    :meth:`pccl.model.compiled.CompiledProgram.stuck_code`, as hex text)."""
    if code == RUNNING:
        return {"status": "running"}
    if code == EXITED:
        return {"status": "exited"}
    kind, reason, where = model.compiled.stuck_reasons[code]
    span = model.compiled.span_of(where)
    return {"status": "stuck", "kind": kind, "reason": reason,
            "line": span.line if span else None, "column": span.column if span else None,
            "code": format(code, "x")}


def encode_k(model, pc) -> list:
    """The pending computation as its items, head first: statement ids,
    ``"end"`` (endEventBlock), ``"atomicEnd"``, ``{"acquire": sid}``."""
    out: list = []
    for item in model.ctl.iter_k(pc):
        if item >= 0:
            out.append(item)
        elif item == END:
            out.append("end")
        elif item == AEND:
            out.append("atomicEnd")
        else:
            out.append({"acquire": acquire_sid(item)})
    return out


def _pos(p):
    return None if p is None else list(p)


def _start(s):
    """A leg start (the reach cell's last entry, blackboxes/nondet.py) as JSON:
    a list of [x, y] points."""
    return [list(p) for p in s]


def _decode_start(x, path):
    if not isinstance(x, list):
        raise _fail(path, "a list of [x, y] points", x)
    out = []
    for k, p in enumerate(x):
        if (not isinstance(p, list) or len(p) != 2
                or not all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in p)):
            raise _fail(f"{path}[{k}]", "an [x, y] point", p)
        out.append((float(p[0]), float(p[1])))
    return tuple(out)


def encode_agent(model, st, i) -> dict:
    ag = st[AGS][i]
    r = ag[REACH]
    return {"id": i, "status": encode_status(model, ag[STATUS]),
            "at": model.compiled.describe_k(ag[PC]), "k": encode_k(model, ag[PC]),
            "counter": ag[CNT], "lockState": D.LOCK_NAMES[ag[LCK]],
            "position": list(ag[POS]), "target": _pos(r[TARGET]), "t0": r[T0],
            "obstacles": to_json(r[OBSTACLES]),
            "doReach_done": r[DONE], "doReach_fail": r[FAIL], "legStart": _start(r[START]),
            "variables": {n: to_json(v, t) for n, t, v in D.agent_vars(model, st, i)}}


def encode_state(model, st) -> dict:
    """A configuration as typed JSON data (with ``round`` under Koord's
    semantics: :func:`encode_round`)."""
    out = {"time": st[TIME], "phase": _PHASES[st[PHASE]], "lockQueue": list(st[LQ]),
           "shared": {n: to_json(v, t) for n, t, v in D.shared_vars(model, st)},
           "agents": [encode_agent(model, st, i) for i in range(len(st[AGS]))],
           "env": to_json(st[ENV])}
    if len(st) > RND:
        out["round"] = encode_round(model, st[RND])
    return out


def encode_round(model, rnd) -> Optional[dict]:
    """The round cell of Koord's semantics (pccl/model/koord.py): null, or
    the values of the round's start, ``{"shared": {name: value}, "allread":
    [{name: value} per agent]}``."""
    if rnd is None:
        return None
    lay = model.compiled.layout
    sh0, ar0 = rnd
    return {"shared": {v.name: to_json(sh0[v.slot], v.ty) for v in lay.shared},
            "allread": [{v.name: to_json(ar[v.slot], v.ty) for v in lay.allread} for ar in ar0]}


def decode_round(model, j, path: str):
    """The round cell :func:`encode_round` wrote."""
    if j is None:
        return None
    j = _dict(j, path)
    lay = model.compiled.layout
    sh0 = _variables(model, _get(j, "shared", path), f"{path}.shared", lay.shared)
    ars = _get(j, "allread", path)
    if not isinstance(ars, list) or len(ars) != model.N:
        raise _fail(f"{path}.allread", f"a list of {model.N} objects", ars)
    return (sh0, tuple(_variables(model, a, f"{path}.allread[{n}]", lay.allread)
                       for n, a in enumerate(ars)))


def encode_changes(model, a, b) -> list:
    """Every cell whose value differs between two configurations:
    ``[{"cell", "old", "new"}]`` with typed values, in a fixed order."""
    out = []

    def add(cell, old, new):
        out.append({"cell": cell, "old": old, "new": new})

    if a[TIME] != b[TIME]:
        add({"cell": "time"}, a[TIME], b[TIME])
    if a[PHASE] != b[PHASE]:
        add({"cell": "phase"}, _PHASES[a[PHASE]], _PHASES[b[PHASE]])
    if a[LQ] != b[LQ]:
        add({"cell": "lockQueue"}, list(a[LQ]), list(b[LQ]))
    if a[SH] is not b[SH]:
        for (n, ty, va), (_, _, vb) in zip(D.shared_vars(model, a), D.shared_vars(model, b)):
            if va != vb or type(va) is not type(vb):
                add({"var": n}, to_json(va, ty), to_json(vb, ty))
    for i, (ga, gb) in enumerate(zip(a[AGS], b[AGS])):
        if ga is not gb:
            _agent_changes(model, a, b, i, add)
    if a[ENV] != b[ENV]:
        add({"cell": "env"}, to_json(a[ENV]), to_json(b[ENV]))
    if len(a) > RND and a[RND] != b[RND]:
        add({"cell": "round"}, encode_round(model, a[RND]), encode_round(model, b[RND]))
    return out


def _agent_changes(model, a, b, i, add) -> None:
    """The changes of agent ``i``'s cells, in :func:`encode_changes`' order."""
    ga, gb = a[AGS][i], b[AGS][i]
    for (n, ty, va), (_, _, vb) in zip(D.agent_vars(model, a, i), D.agent_vars(model, b, i)):
        if va != vb or type(va) is not type(vb):
            add({"agent": i, "var": n}, to_json(va, ty), to_json(vb, ty))
    ra, rb = ga[REACH], gb[REACH]
    cells = (("k", ga[PC], gb[PC], lambda pc: encode_k(model, pc)),
             ("counter", ga[CNT], gb[CNT], None),
             ("position", ga[POS], gb[POS], list),
             ("lockState", ga[LCK], gb[LCK], D.LOCK_NAMES.get),
             ("status", ga[STATUS], gb[STATUS], lambda code: encode_status(model, code)),
             ("target", ra[TARGET], rb[TARGET], _pos),
             ("t0", ra[T0], rb[T0], None),
             ("obstacles", ra[OBSTACLES], rb[OBSTACLES], to_json),
             ("doReach_done", ra[DONE], rb[DONE], None),
             ("doReach_fail", ra[FAIL], rb[FAIL], None),
             ("legStart", ra[START], rb[START], _start))
    for name, x, y, enc in cells:
        if x != y or type(x) is not type(y):
            add({"agent": i, "cell": name}, x if enc is None else enc(x),
                y if enc is None else enc(y))


#: Agent cells of a change that the text views and the HTML viewer do not
#: print (the pending computation shows as the next step's line; t0 and the
#: obstacles as the doReach call that set them).
INTERNAL_CELLS = frozenset({"k", "t0", "obstacles", "legStart"})


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


def encode_step(model, n, label, before, after) -> dict:
    """One step: where it is in the program (:func:`encode_step_head`) and
    what it did (``changes``)."""
    rec = encode_step_head(model, n, label, before, after)
    rec["changes"] = encode_changes(model, before, after)
    if "outcome" in rec:             # the key order of the file: changes, then outcome
        rec["outcome"] = rec.pop("outcome")
    return rec


def encode_step_head(model, n, label, before, after) -> dict:
    """A step without its changes: the rule, the agent, the event, the
    statement (line, column, source), the branch an ``if``/``while`` took,
    the time before it and, for ``DOREACH INVOKE``, the blackbox's outcome."""
    info = D.label_info(model, label, before)
    rule, agent, detail = label[:3]
    column = None
    if rule in ("EVENT SELECT", "EVENT TRANS") and detail is not None:
        column = model.program.events[detail].guard.span.column
    elif info["line"] is not None and isinstance(detail, int) and rule != "DOREACH INVOKE":
        sp = model.compiled.stmt_span(detail)
        column = sp.column if sp else None
    rec = {"index": n, "time": before[TIME], "agent": agent, "rule": info["rule"],
           "event": info["event"], "line": info["line"], "column": column,
           "source": info["source"] or None,
           "branch": branch_taken(model, label, before, after)}
    if rule == "DOREACH INVOKE":
        rec["outcome"] = detail
    return rec


def encode_path(model, trace) -> dict:
    """A path (:class:`pccl.search.explorer.Trace`, or None: no path) as every JSON
    output writes one: ``{"initial", "steps", "final"}`` (null states and no
    steps without a path)."""
    if trace is None:
        return {"initial": None, "steps": [], "final": None}
    states = trace.states
    return {"initial": encode_state(model, states[0]),
            "steps": [encode_step(model, n + 1, lab, states[n], states[n + 1])
                      for n, lab in enumerate(trace.labels)],
            "final": encode_state(model, states[-1])}


def encode_violation(model, v) -> Optional[dict]:
    if v is None:
        return None
    span = getattr(v, "span", None)
    return {"kind": v.kind, "name": v.name, "message": v.message, "agent": v.agent,
            "line": span.line if span else None, "column": span.column if span else None}


# ---------------------------------------------------------------------------
# decoding
# ---------------------------------------------------------------------------

def _kind(x) -> str:
    if x is None:
        return "null"
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, int):
        return f"the integer {x}" if abs(x) < 10 ** 12 else "an integer"
    if isinstance(x, float):
        return f"the number {x!r}"
    if isinstance(x, str):
        return f"the string {x[:40]!r}"
    return "a list" if isinstance(x, list) else "an object"


def _fail(path: str, want: str, got) -> DecodeError:
    return DecodeError(f"{path}: expected {want}, got {_kind(got)}")


def _float(x, path):
    if isinstance(x, float) and math.isfinite(x):
        return x + 0.0
    raise _fail(path, "a number with a fraction or .0", x)


def decode_value(j, ty, path: str):
    """A typed JSON value of type ``ty`` as the configuration holds it."""
    if j is None:
        return UNDEF
    kind = getattr(ty, "kind", "any")
    if kind == "int":
        if is_integer(j):
            return j
        raise _fail(path, "an int", j)
    if kind == "float":
        return _float(j, path)
    if kind == "bool":
        if isinstance(j, bool):
            return j
        raise _fail(path, "a bool", j)
    if kind == "enum":
        members = ty.members or ()
        if isinstance(j, str) and j in members:
            return members.index(j)
        raise _fail(path, f"a member of {ty.enum} ({', '.join(members)})", j)
    if kind == "pos":
        return decode_position(j, path)
    if kind in ("list", "array"):
        if not isinstance(j, list):
            raise _fail(path, f"a list ({ty})", j)
        if kind == "array" and ty.size is not None and len(j) != ty.size:
            raise DecodeError(f"{path}: expected {ty.size} elements, got {len(j)}")
        return tuple(decode_value(x, ty.elem, f"{path}[{n}]") for n, x in enumerate(j))
    return decode_data(j, path)


def decode_data(j, path: str = "value"):
    """Untyped data (the blackbox's env, obstacles, ``any`` values): lists as
    tuples, everything else as it is."""
    if isinstance(j, list):
        return tuple(decode_data(x, f"{path}[{n}]") for n, x in enumerate(j))
    if isinstance(j, dict):
        raise _fail(path, "plain data (numbers, booleans, lists)", j)
    return j


def decode_position(j, path: str) -> tuple:
    if not isinstance(j, list) or len(j) != 3:
        raise _fail(path, "a position [x, y, z]", j)
    return tuple(_float(x, f"{path}[{n}]") for n, x in enumerate(j))


def _bool(j, path):
    if isinstance(j, bool):
        return j
    raise _fail(path, "true or false", j)


def _int(j, path):
    if is_integer(j):
        return j
    raise _fail(path, "an integer", j)


def _number(j, path):
    if is_integer(j) or (isinstance(j, float) and math.isfinite(j)):
        return j
    raise _fail(path, "a number", j)


def _dict(j, path) -> dict:
    if isinstance(j, dict):
        return j
    raise _fail(path, "an object", j)


def decode_status(model, j, path: str):
    j = _dict(j, path)
    s = j.get("status")
    if s == "running":
        return RUNNING
    if s == "exited":
        return EXITED
    if s != "stuck":
        raise _fail(f"{path}.status", "running, exited or stuck", s)
    reasons = model.compiled.stuck_reasons
    code = j.get("code")
    if isinstance(code, str):
        try:
            c = int(code, 16)
        except ValueError:
            raise _fail(f"{path}.code", "a hexadecimal stuck code", code) from None
        if c in reasons:
            return c
    # an older file, or a code this model has not met: by what the status says
    want = (j.get("kind"), j.get("reason"), j.get("line"), j.get("column"))
    for c, (kind, reason, where) in reasons.items():
        span = model.compiled.span_of(where)
        if (kind, reason, span.line if span else None, span.column if span else None) == want:
            return c
    raise DecodeError(f"{path}: no agent of this program gets stuck so "
                      f"({j.get('reason')!s:.60} at line {j.get('line')})")


def decode_k(model, j, path: str, lenient: bool = False):
    """The pc of a pending computation :func:`encode_k` wrote; only k cells
    the program's control has (:meth:`pccl.model.compiled.Control.close`).  With
    ``lenient`` (the program was edited since the data was written, so its
    statement ids may have moved), one that is not decodes to :data:`ANY`."""
    try:
        return _decode_k(model, j, path)
    except DecodeError:
        if lenient:
            return ANY
        raise


def _decode_k(model, j, path: str) -> int:
    if not isinstance(j, list):
        raise _fail(path, "a list of k items", j)
    stmts = model.compiled.stmts
    items = []
    for n, x in enumerate(j):
        if x == "end":
            items.append(END)
        elif x == "atomicEnd":
            items.append(AEND)
        elif is_integer(x) and x in stmts:
            items.append(x)
        elif isinstance(x, dict) and is_integer(x.get("acquire")) and x["acquire"] in stmts:
            items.append(acq(x["acquire"]))
        else:
            raise _fail(f"{path}[{n}]", "a statement id, \"end\", \"atomicEnd\" or "
                        "{\"acquire\": id} of this program", x)
    ctl = model.ctl
    for attempt in (0, 1):
        pc = ctl.empty_pc
        for item in reversed(items):
            pc = ctl.ids.get((item, pc))
            if pc is None:
                break
        if pc is not None:
            return pc
        if attempt == 0:
            ctl.close()         # k cells are interned lazily: intern them all, once
    raise DecodeError(f"{path}: not a pending computation of this program")


def _lock_queue(j, path, n_agents) -> tuple:
    if not isinstance(j, list) or not all(is_integer(x) and 0 <= x < n_agents for x in j):
        raise _fail(path, "a list of agent ids", j)
    return tuple(j)


def _variables(model, j, path, decls) -> tuple:
    j = _dict(j, path)
    return tuple(decode_value(j[v.name], v.ty, f"{path}.{v.name}") if v.name in j
                 else _missing(f"{path}.{v.name}") for v in decls)


def _missing(path):
    raise DecodeError(f"{path}: missing")


def _get(j: dict, key: str, path: str):
    if key not in j:
        raise DecodeError(f"{path}.{key}: missing")
    return j[key]


def decode_agent(model, j, path: str, lenient: bool = False) -> tuple:
    j = _dict(j, path)
    lay = model.compiled.layout
    variables = _dict(_get(j, "variables", path), f"{path}.variables")
    loc = _variables(model, variables, f"{path}.variables", lay.local)
    ar = _variables(model, variables, f"{path}.variables", lay.allread)
    lock = _get(j, "lockState", path)
    if not isinstance(lock, str) or lock not in _LOCK_CODES:
        raise _fail(f"{path}.lockState", "idle, request or lock", lock)
    target = _get(j, "target", path)
    t0 = j.get("t0", ANY)
    reach = (None if target is None else decode_position(target, f"{path}.target"),
             decode_data(j["obstacles"], f"{path}.obstacles") if "obstacles" in j else ANY,
             t0 if t0 is None or t0 is ANY else _number(t0, f"{path}.t0"),
             _bool(_get(j, "doReach_done", path), f"{path}.doReach_done"),
             _bool(_get(j, "doReach_fail", path), f"{path}.doReach_fail"),
             _decode_start(j["legStart"], f"{path}.legStart") if "legStart" in j else ANY)
    pc = decode_k(model, j["k"], f"{path}.k", lenient) if "k" in j else ANY
    return (pc, _int(_get(j, "counter", path), f"{path}.counter"), _LOCK_CODES[lock],
            decode_status(model, _get(j, "status", path), f"{path}.status"), loc, ar,
            decode_position(_get(j, "position", path), f"{path}.position"), reach)


def decode_state(model, j, path: str = "state", lenient: bool = False) -> tuple:
    """The configuration a typed state (:func:`encode_state`, or version 1's
    ``state_typed``) describes; cells version 1 lacks are :data:`ANY` (and,
    ``lenient``, pending computations of an edited program: :func:`decode_k`)."""
    j = _dict(j, path)
    phase = _get(j, "phase", path)
    if not isinstance(phase, str) or phase not in _PHASE_CODES:
        raise _fail(f"{path}.phase", "discrete or dynamic", phase)
    agents = _get(j, "agents", path)
    if not isinstance(agents, list) or len(agents) != model.N:
        raise _fail(f"{path}.agents", f"a list of {model.N} agents", agents)
    shared = _variables(model, _get(j, "shared", path), f"{path}.shared",
                        model.compiled.layout.shared)
    return (_number(_get(j, "time", path), f"{path}.time"), _PHASE_CODES[phase],
            _lock_queue(_get(j, "lockQueue", path), f"{path}.lockQueue", model.N), shared,
            tuple(decode_agent(model, a, f"{path}.agents[{n}]", lenient)
                  for n, a in enumerate(agents)),
            decode_data(j["env"], f"{path}.env") if "env" in j else ANY) + (
        (decode_round(model, j["round"], f"{path}.round") if "round" in j else ANY,)
        if getattr(model, "semantics", "pccl") == "koord" else ())


def _decode_cell(model, cell: dict, value, path: str, lenient: bool = False):
    """(where, decoded value) of one change's value: ``where`` is
    ``("state", index)``, ``("shared", slot)``, ``("agent", i, index)``,
    ``("local"|"allread", i, slot)`` or ``("reach", i, index)``."""
    c = cell.get("cell")
    lay = model.compiled.layout
    if "agent" in cell:
        i = cell["agent"]
        if not is_integer(i) or not 0 <= i < model.N:
            raise _fail(f"{path}.cell.agent", f"an agent id below {model.N}", i)
        if "var" in cell:
            for sec, decls in (("local", lay.local), ("allread", lay.allread)):
                for v in decls:
                    if v.name == cell["var"]:
                        return (sec, i, v.slot), decode_value(value, v.ty, path)
            raise DecodeError(f"{path}.cell.var: no agent variable {cell['var']!r}")
        simple = {"k": (PC, lambda x, p: decode_k(model, x, p, lenient)), "counter": (CNT, _int),
                  "position": (POS, decode_position),
                  "lockState": (LCK, lambda x, p: _LOCK_CODES[x]
                                if isinstance(x, str) and x in _LOCK_CODES
                                else _raise(_fail(p, "idle, request or lock", x))),
                  "status": (STATUS, lambda x, p: decode_status(model, x, p))}
        if c in simple:
            idx, fn = simple[c]
            return ("agent", i, idx), fn(value, path)
        reach = {"target": (TARGET, lambda x, p: None if x is None else decode_position(x, p)),
                 "t0": (T0, lambda x, p: None if x is None else _number(x, p)),
                 "obstacles": (OBSTACLES, decode_data),
                 "doReach_done": (DONE, _bool), "doReach_fail": (FAIL, _bool),
                 "legStart": (START, _decode_start)}
        if c in reach:
            idx, fn = reach[c]
            return ("reach", i, idx), fn(value, path)
        raise _fail(f"{path}.cell.cell", "a cell of an agent", c)
    if "var" in cell:
        for v in lay.shared:
            if v.name == cell["var"]:
                return ("shared", v.slot), decode_value(value, v.ty, path)
        raise DecodeError(f"{path}.cell.var: no shared variable {cell['var']!r}")
    glob = {"time": (TIME, _number),
            "phase": (PHASE, lambda x, p: _PHASE_CODES[x] if isinstance(x, str) and x in _PHASE_CODES
                      else _raise(_fail(p, "discrete or dynamic", x))),
            "lockQueue": (LQ, lambda x, p: _lock_queue(x, p, model.N)),
            "env": (ENV, decode_data)}
    if getattr(model, "semantics", "pccl") == "koord":
        glob["round"] = (RND, lambda x, p: decode_round(model, x, p))
    if c in glob:
        idx, fn = glob[c]
        return ("state", idx), fn(value, path)
    raise _fail(f"{path}.cell.cell", "time, phase, lockQueue, env or round", c)


def _raise(e: Exception):
    raise e


def _set(tup: tuple, k: int, v) -> tuple:
    return tup[:k] + (v,) + tup[k + 1:]


def apply_changes(model, st: tuple, changes: list, path: str = "changes",
                  version: int = VERSION, lenient: bool = False,
                  leg_starts: bool = True) -> tuple:
    """The configuration ``st`` with the recorded changes made: each
    change's ``old`` must be the cell's value in ``st`` (else a
    :class:`DecodeError` naming it) and differ from its ``new``, which it
    becomes.  After a version-1 step the cells that version does not record
    (every agent's ``k``, ``t0`` and obstacles) are :data:`ANY`, and so is
    every agent's leg start without ``leg_starts`` (a file written before it
    was recorded); ``lenient``: as in :func:`decode_state`."""
    if not isinstance(changes, list):
        raise _fail(path, "a list", changes)
    st = tuple(st)
    for n, ch in enumerate(changes):
        p = f"{path}[{n}]"
        ch = _dict(ch, p)
        cell = _dict(ch.get("cell"), f"{p}.cell")
        where, old = _decode_cell(model, cell, ch.get("old"), f"{p}.old", lenient)
        _, v = _decode_cell(model, cell, ch.get("new"), f"{p}.new", lenient)
        if not matches(old, _cell_value(st, where)):
            raise DecodeError(f"{p}.old: {cell_name(cell)} is not {ch.get('old')!r} before "
                              f"this step")
        if matches(old, v) and old is not ANY:
            raise DecodeError(f"{p}: {cell_name(cell)} does not change")
        if where[0] == "state":
            st = _set(st, where[1], v)
        elif where[0] == "shared":
            st = _set(st, SH, _set(st[SH], where[1], v))
        else:
            i = where[1]
            ag = st[AGS][i]
            if where[0] == "agent":
                ag = _set(ag, where[2], v)
            elif where[0] == "reach":
                ag = _set(ag, REACH, _set(ag[REACH], where[2], v))
            else:
                part = LOC if where[0] == "local" else AR
                ag = _set(ag, part, _set(ag[part], where[2], v))
            st = _set(st, AGS, _set(st[AGS], i, ag))
    if version < 2:
        ags = tuple((ANY,) + ag[1:REACH] + ((ag[REACH][TARGET], ANY, ANY) + ag[REACH][DONE:],)
                    for ag in st[AGS])
        st = _set(st, AGS, ags)
    if not leg_starts:
        # the leg start (blackboxes that track legs), recorded since
        # 2026-12-07: a file written before lacks it, so it is not matched
        st = _set(st, AGS, tuple(ag[:REACH] + (ag[REACH][:START] + (ANY,),) + ag[REACH + 1:]
                                 for ag in st[AGS]))
    return st


def _cell_value(st: tuple, where: tuple):
    """The value of the cell :func:`_decode_cell` located in ``st``."""
    if where[0] == "state":
        return st[where[1]]
    if where[0] == "shared":
        return st[SH][where[1]]
    ag = st[AGS][where[1]]
    if where[0] == "agent":
        return ag[where[2]]
    if where[0] == "reach":
        return ag[REACH][where[2]]
    return ag[LOC if where[0] == "local" else AR][where[2]]


def matches(pattern, value) -> bool:
    """Whether a decoded configuration (or any part of one) is ``value``:
    equal with the same types at every depth (1 is not 1.0 nor true), where
    :data:`ANY` matches anything."""
    if pattern is ANY:
        return True
    if isinstance(pattern, tuple):
        return (isinstance(value, tuple) and len(pattern) == len(value)
                and all(matches(p, v) for p, v in zip(pattern, value)))
    return type(pattern) is type(value) and pattern == value


def is_complete(st) -> bool:
    """Whether a decoded configuration determines every cell (no :data:`ANY`)."""
    if st is ANY:
        return False
    if isinstance(st, tuple):
        return all(is_complete(x) for x in st)
    return True


__all__ = ["ANY", "FORMAT", "READS", "VERSION", "DecodeError", "apply_changes", "cell_name",
           "decode_state", "decode_value", "encode_changes", "encode_state", "encode_step", "encode_step_head",
           "encode_status", "encode_violation", "is_complete", "matches"]


# ---------------------------------------------------------------------------
# the top level of every --format json output
# ---------------------------------------------------------------------------

#: The ``format`` of the JSON that ``run``, ``explore``, ``simulate`` and
#: ``replay`` print with ``--format json`` (its ``version`` is :data:`VERSION`:
#: one vocabulary with the trace files it carries).
OUTPUT = "pccl-output"


def output(command: str, *, status: str, message: Optional[str], exit_status: int,
           trace: Optional[dict] = None, **fields) -> dict:
    """The JSON a command prints: ``format``, ``version``, ``command``, the
    verdict as ``status`` (one word), ``message`` (the verdict line) and
    ``exit_status``, the command's own fields, and ``trace``: the trace
    document (the trace file's contents) or null."""
    return {"format": OUTPUT, "version": VERSION, "command": command, "status": status,
            "message": message, "exit_status": exit_status, **fields, "trace": trace}
