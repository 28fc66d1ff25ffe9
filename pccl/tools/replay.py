"""``pccl replay FILE``: re-execute a trace file through the interpreter.

A trace file is data (from colleagues, CI artefacts, bug reports): reading
one never runs code it names.  :mod:`pccl.output.tracecheck` parses and checks it
first (every malformed file is one error naming the field); the blackbox is
a shipped one named in the file, or the one the user gives (``--blackbox``,
or ``blackbox=`` here), checked against the file's name for it
(:func:`resolve_blackbox`).

The model is rebuilt from the recorded configuration; the replay starts
from the initial state of the model equal to the recorded one and applies
each recorded step: its (rule, agent, event, line, column, outcome) must be
among the enabled transitions, and the transition must make the recorded
changes (and have the recorded time and branch).  The first step where that
fails is the divergence.  The end is re-derived, not trusted: a run's end
status by the runner itself, steered along the recorded steps; a violation
by the model's checks on the last state; a lasso must close and its cycle
must be one the property's verdict needs; a ``reachable P`` witness must end
in a P-state.
"""

from __future__ import annotations

import json
import os
import random
import sys
from dataclasses import dataclass, field
from typing import Any, Optional

from pccl.output import codec as C
from pccl.output import tracecheck as TC
from pccl.output import traces as T
from pccl.lang.errors import ArgumentError, OptionError, PcclError, Spelling, keyword_spelling, spell
from pccl.model.layout import TIME
from pccl.model.options import ModelOptions


@dataclass
class ReplayResult:
    #: violation | clean | witness | diverged | empty | unreachable
    status: str
    #: 1 a violation reproduced; 0 a clean run or a witness reproduced (or
    #: nothing to replay); 2 diverged, or a verdict no trace can reproduce
    exit_status: int
    message: str
    warnings: list = field(default_factory=list)
    model: Any = None
    states: list = field(default_factory=list)
    labels: list = field(default_factory=list)
    diverged_at: Optional[int] = None      # step index (0: the initial state)
    steps_total: int = 0
    doc: dict = field(default_factory=dict)     # the trace document replayed

    @property
    def trace(self):
        """The replayed path (:class:`pccl.search.explorer.Trace`; to the divergence
        when it diverged), or None before the initial state was found."""
        from pccl.search.explorer import Trace
        return Trace(tuple(self.states), tuple(self.labels)) if self.states else None


def replayed_document(res: ReplayResult) -> Optional[dict]:
    """The trace document of a reproduced replay, written anew by this
    pccl (the current version, whatever the file's): the recorded
    configuration and result, the replayed states and steps.  None when
    the replay diverged or had nothing to replay."""
    if res.status not in ("violation", "clean", "witness") or not res.states:
        return None
    doc = res.doc
    out = T.document(res.model, doc["config"], res.trace,
                     status=doc["result"]["status"], message=doc["result"].get("message"))
    out["result"] = dict(doc["result"])
    return out


def load(path) -> dict:
    """The trace document in ``path``, parsed and checked (:mod:`pccl.output.tracecheck`)."""
    return TC.load(path)


def _candidates(rec: dict, trace_path) -> tuple[list, list]:
    """Where a trace's ``config.program``/``config.world`` record may be:
    the recorded path (from the working directory), the path relative to
    the trace file, the absolute path, the path from the trace's directory;
    ``(every place looked at, [(file that exists, its sha256)])``."""
    here = os.path.dirname(os.path.abspath(os.fspath(trace_path)))
    cands = [rec["path"]]
    if rec.get("relative"):
        cands.append(os.path.join(here, rec["relative"]))
    if rec.get("absolute"):
        cands.append(rec["absolute"])
    cands.append(os.path.join(here, rec["path"]))    # older files: next to the trace
    seen, found = [], []
    for c in cands:
        if c in seen:
            continue
        seen.append(c)
        if os.path.isfile(c):
            found.append((c, T.sha256_of(c)))
    return seen, found


def recorded_file(rec: Optional[dict], trace_path) -> tuple[Optional[str], str]:
    """The file a trace's record names *with the recorded SHA-256* (found as
    :func:`_resolve` finds it), else None; and, when None, why (for a
    viewer page, which embeds only such a file: a trace from elsewhere may
    name any file of the reader's)."""
    if rec is None:
        return None, "the trace names no file"
    want = rec.get("sha256")
    if not want:
        return None, "the trace records no sha256 of it"
    seen, found = _candidates(rec, trace_path)
    for c, sha in found:
        if sha == want:
            return c, ""
    return None, (f"no file with the recorded sha256 {want[:12]}… (looked for "
                  f"{', '.join(os.path.basename(c) or c for c in seen)})")


def _resolve(rec: Optional[dict], trace_path, what, warnings, override=None) -> Optional[str]:
    """The file a trace's ``config.program``/``config.world`` names.
    ``override`` (``--program``/``--world``) wins; otherwise the first of the
    recorded path (from the working directory), the path relative to the
    trace file and the absolute path whose bytes have the recorded SHA-256,
    else the first that exists (with a warning that it changed)."""
    if override is not None:
        p = os.fspath(override)
        if not os.path.isfile(p):
            raise PcclError(f"--{what}: no such file: {p}")
        if rec is None:
            warnings.append(f"warning: the trace was recorded without a {what}; using {p}")
            return p
        now = T.sha256_of(p) or ""
        if rec.get("sha256") and now != rec["sha256"]:
            warnings.append(f"warning: {what} {p} (--{what}) is not the recorded {what} "
                            f"{rec['path']}: sha256 {now[:12]}… here, {rec['sha256'][:12]}… "
                            f"recorded; the replay diverges where they differ")
        return p
    if rec is None:
        return None
    seen, found = _candidates(rec, trace_path)
    if not found:
        raise PcclError(f"config.{what}.path: the {what} {rec['path']} recorded in the trace "
                        f"does not exist (looked for {', '.join(seen)}); give it with "
                        f"--{what} FILE", filename=os.fspath(trace_path))
    want = rec.get("sha256")
    for c, sha in found:
        if not want or sha == want:
            return c
    p, got = found[0]
    want, now = want or "", got or ""
    warnings.append(f"warning: {what} {p} has changed since the trace was recorded "
                    f"(sha256 {want[:12]}… recorded, {now[:12]}… now); the replay diverges "
                    f"where they differ (--{what} FILE replays against another file)")
    return p


# ---------------------------------------------------------------------------
# the blackbox: never one the file would make us import
# ---------------------------------------------------------------------------

def _names_object(spec: str, obj) -> bool:
    """Whether ``module:attr`` names ``obj`` (or its class) among the modules
    already imported; nothing is imported here."""
    modname, _, attr = spec.rpartition(":")
    mod = sys.modules.get(modname)
    if mod is None and (modname.endswith(".py") or "/" in modname or os.sep in modname):
        stem = os.path.splitext(os.path.basename(modname))[0]
        mod = sys.modules.get("_pccl_user_blackbox_" + stem)
    if mod is None:
        return False
    x: Any = mod
    for part in attr.split("."):
        x = getattr(x, part, None)
        if x is None:
            return False
    return x is obj or (isinstance(x, type) and isinstance(obj, x))


def resolve_blackbox(recorded: str, given, trace_name: str):
    """The blackbox to replay a trace with.  ``recorded`` is the file's
    ``config.blackbox``; ``given`` the user's choice (None, a ``--blackbox``
    spec, or a blackbox object).  A shipped blackbox is taken by name; a
    user's one only when given, and then it must be the one the file names.
    Nothing the file names is ever imported."""
    from pccl.blackboxes import BLACKBOXES, load_blackbox
    rec = recorded.strip()
    shipped = ":" not in rec and rec.lower() in BLACKBOXES

    def fail(msg: str):
        raise PcclError(f"config.blackbox: {msg}", filename=trace_name)

    def load(spec: str):
        try:
            return load_blackbox(spec)
        except PcclError as e:
            if e.filename is None:
                e.filename = "--blackbox"
            raise

    if given is None:
        if shipped:
            return load(rec)
        if ":" in rec:
            fail(f"the trace names the user blackbox '{rec}'; replay does not import code a "
                 f"trace file names: if you trust it, pass --blackbox {rec}")
        fail(f"the trace names the blackbox '{rec}', which is not a shipped one "
             f"({', '.join(sorted(BLACKBOXES))}): pass the one it was recorded with "
             f"(--blackbox module:attr)")
    if isinstance(given, str):
        g = given.strip()
        if g == rec or (shipped and g.lower() == rec.lower()):
            return load(g)
        if not shipped and ":" not in rec and ":" in g:
            bb = load(g)                # the file has an object's name (the API wrote it)
            if bb.name == rec:
                return bb
            fail(f"the trace was recorded with blackbox '{rec}', but --blackbox {g} is "
                 f"'{bb.name}'")
        fail(f"the trace was recorded with blackbox '{rec}', but --blackbox gives '{g}'")
    name = getattr(given, "name", None)
    if name == rec or (":" in rec and _names_object(rec, given)):
        return given
    fail(f"the trace was recorded with blackbox '{rec}', but the blackbox given is "
         f"'{name}'")


def model_from_config(cfg: dict, trace_path, warnings: list, blackbox=None, program=None,
                      world=None):
    """The model a (checked) trace configuration describes; ``blackbox``:
    the object :func:`resolve_blackbox` chose (default: the file's name,
    which must then be a shipped blackbox)."""
    from pccl.model.build import build_model
    name = os.fspath(trace_path)
    if blackbox is None:
        blackbox = resolve_blackbox(cfg["blackbox"], None, name)
    prog = _resolve(cfg["program"], trace_path, "program", warnings, program)
    world = _resolve(cfg.get("world"), trace_path, "world", warnings, world)
    if cfg.get("pccl_version") not in (None, T.pccl_version()):
        warnings.append(f"warning: the trace was written by pccl {cfg['pccl_version']}, "
                        f"this is pccl {T.pccl_version()}")
    try:
        opts = _options_of(cfg).replace(world=world, blackbox=blackbox, agents=cfg["agents"],
                                        reduce="none")  # a trace records unreduced steps
    except (TypeError, ValueError) as e:
        raise PcclError(f"config.options: {e}", filename=name) from None
    try:
        opts.check("replay")
        return build_model(prog, opts)
    except OptionError as e:
        raise PcclError(f"config.{e.option}: {e.message}", filename=name) from None
    except ArgumentError as e:
        raise PcclError(f"config: {e.message}", filename=name) from None


#: config keys that repeat an option (for readers of the file): they must agree
_MIRRORED = (("invariants", "invariants"), ("property_options", "properties"),
             ("overrides", "overrides"))


def _options_of(cfg: dict) -> ModelOptions:
    """The model options of a trace's configuration: its ``options`` (the
    options whole, :meth:`~pccl.model.options.CommonOptions.from_dict`) with the
    time abstraction it ran with; a file without them (written before the
    options travelled whole) from its flat keys."""
    if "options" in cfg:
        opts = ModelOptions.from_dict(cfg["options"])
        for key, field in _MIRRORED:
            mine = [str(x) for x in getattr(opts, field)] if field != "overrides" else \
                {k: str(v) for k, v in opts.overrides.items()}
            flat = cfg.get(key, mine)
            if (list(flat) if isinstance(flat, (list, tuple)) else flat) != mine:
                raise ValueError(f"options.{field} {mine!r} disagree with {key} {flat!r}")
        return opts.replace(abstract_time=bool(cfg.get("abstract_time")))
    rates = {i: r for i, r in enumerate(cfg.get("rates") or []) if r != 1}
    return ModelOptions(delta=cfg["delta"], n0=cfg["n0"], rates=rates, events=cfg["events"],
                        collisions=cfg["collisions"],
                        overrides=dict(cfg.get("overrides") or {}),
                        invariants=tuple(cfg.get("invariants") or ()),
                        properties=tuple(cfg.get("property_options") or ()),
                        max_time=cfg.get("max_time"),
                        abstract_time=bool(cfg.get("abstract_time")))


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


def _changes_text(chs: list, every: bool = False) -> str:
    """The changes as text; without ``every``, those the text views print
    (not the pending computation ``k``, ``t0``, the obstacles)."""
    shown = [c for c in chs if every or not isinstance(c, dict) or not isinstance(
        c.get("cell"), dict) or c["cell"].get("cell") not in C.INTERNAL_CELLS]
    if not shown:
        return "no change"
    return ", ".join(f"{C.cell_name(c['cell'])} {json.dumps(c['old'])} -> "
                     f"{json.dumps(c['new'])}" for c in shown)


def _state_difference(a, b, prefix: str = "") -> str:
    """The first place where a recorded typed state differs from a replayed
    one (for messages; keys an older file lacks are not compared)."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in a:
            if not _same(a.get(k), b.get(k)):
                return _state_difference(a.get(k), b.get(k), f"{prefix}.{k}" if prefix else k)
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for n, (x, y) in enumerate(zip(a, b)):
            if not _same(x, y):
                return _state_difference(x, y, f"{prefix}[{n}]")
    return f"{prefix}: recorded {json.dumps(a)}, replayed {json.dumps(b)}"


def _same(a, b) -> bool:
    """Equal as JSON text: 1 is not 1.0, false is not 0."""
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def replay(path, *, blackbox=None, program=None, world=None,
           spelling: Spelling = keyword_spelling) -> ReplayResult:
    """Replay the trace file ``path``.  ``blackbox``: the user's blackbox (a
    ``module:attr`` spec or an object) when the file names one of its own;
    a shipped one is taken from the file.  ``program``/``world``: replay
    against these files instead of the recorded ones (checked by hash).
    ``spelling``: how the caller writes options (``pccl replay`` its flags):
    a recorded run's message naming an option (``stopped at --max-time 100``)
    matches when it is the replayed run's message in this spelling or the
    API's (a file written by ``pccl run`` or by :func:`pccl.api.run`)."""
    name = os.fspath(path)
    doc = TC.load(path)
    cfg = doc["config"]
    warnings: list = []
    bb = resolve_blackbox(cfg["blackbox"], blackbox, name)
    m = model_from_config(cfg, path, warnings, bb, program=program, world=world)
    steps = doc["steps"]
    result = doc["result"]
    recorded = result["violation"]
    res = ReplayResult("empty", 0, "", warnings, m, steps_total=len(steps), doc=doc)
    if doc["initial"] is None:
        if recorded is not None:         # (tracecheck: only an unreachable verdict)
            res.status, res.exit_status = "unreachable", 2
            res.message = (f"nothing to replay: the recorded verdict ({recorded['message']}) is "
                           f"about every run of the model, and no trace can reproduce it "
                           f"(pccl explore decides it again)")
            return res
        res.message = (f"nothing to replay: the recorded {cfg['command']} found no "
                       f"counterexample ({result.get('message')})")
        return res

    def diverge(at: int, message: str) -> ReplayResult:
        res.status, res.exit_status, res.diverged_at = "diverged", 2, at
        res.message = message
        return res

    # an edited program (another hash): its statement ids may have moved, so
    # a recorded pending computation that names none of them is not compared
    # (the steps' lines and sources still are: the first that moved is named)
    rec_prog = cfg.get("program") or {}
    lenient = bool(rec_prog.get("sha256")) and \
        T.sha256_of(m.program.filename) != rec_prog.get("sha256")
    state, why = _initial_state(m, doc, lenient)
    if state is None:
        return diverge(0, why)
    res.states = [state]
    # files written before the leg start was recorded do not match it
    legs = all("legStart" in a for a in (doc.get("initial") or {}).get("agents", ()))
    picks: list = []            # per step: (index among the successors, how many)
    for k, rec in enumerate(steps):
        succ = m.successors(state)
        found = _recorded_step(m, state, succ, rec, f"steps[{k}].changes", doc["version"],
                               lenient, legs)
        if isinstance(found, str):
            return diverge(rec["index"], f"diverged at step {rec['index']} of {len(steps)} "
                                         f"({describe(rec)}): {found}")
        picks.append((found[0], len(succ)))
        res.labels.append(found[1])
        state = found[2]
        res.states.append(state)
    try:
        last_ok = C.matches(C.decode_state(m, doc["final"], "final", lenient), state)
    except C.DecodeError:
        last_ok = False
    if not last_ok:
        return diverge(len(steps), f"diverged at the end: every step reproduced, but the "
                                   f"recorded final state is not the last state (final."
                                   f"{_state_difference(doc['final'], C.encode_state(m, state))})")
    if cfg["command"] == "run":
        return _end_of_run(m, cfg, doc, res, picks, diverge, (spelling, keyword_spelling))
    if recorded is None:
        return _end_of_witness(m, result["witness"], res, diverge)
    if recorded["kind"] in ("liveness", "timelock", "response"):
        return _end_of_temporal(m, cfg, recorded, result.get("cycle_start"), res, diverge)
    if recorded["kind"] == "stall":
        return _end_of_stall(m, recorded, result.get("cycle_start"), res, diverge)
    if recorded["kind"] == "frozen":
        return _end_of_frozen(m, recorded, result.get("cycle_start"), res, diverge)
    return _end_of_safety(m, cfg, recorded, res, diverge)


def _initial_state(m, doc: dict, lenient: bool):
    """(the model's initial state the file records, None), or (None, why not)."""
    try:
        want = C.decode_state(m, doc["initial"], "initial", lenient)
    except C.DecodeError as e:
        return None, (f"diverged at the initial state: no state of this model is the "
                      f"recorded one: {e.message}")
    inits = []
    for s in m.init_states():      # a generator: stop at the recorded state
        inits.append(s)
        if C.matches(want, s):
            return s, None
    closest = _state_difference(doc["initial"], C.encode_state(m, inits[0])) if inits else ""
    return None, (f"diverged at the initial state: none of the model's {len(inits)} initial "
                  f"states equals the recorded one (first difference from initial state 1: "
                  f"{closest})")


def _recorded_step(m, state, succ: list, rec: dict, path: str, version: int, lenient: bool,
                   legs: bool = True):
    """The successor ``(index, label, state)`` among ``succ`` that the step
    ``rec`` records: same rule, agent, event, statement and outcome, its
    decoded changes made to ``state``, same time and branch.  Else why
    not (the text after "diverged at step n (...): ")."""
    n = rec["index"]
    ident = _identity(rec)
    try:
        want = C.apply_changes(m, state, rec["changes"], path, version, lenient,
                               leg_starts=legs)
        undecodable = None
    except C.DecodeError as e:
        want, undecodable = None, e.message
    same_label: list = []
    other = None
    for j, (label, nxt) in enumerate(succ):
        head = C.encode_step_head(m, n, label, state, nxt)
        if _identity(head) != ident:
            continue
        if want is None or not C.matches(want, nxt):
            same_label.append(nxt)
        elif not C.matches(rec["time"], state[TIME]):
            other = ("time", head["time"])
        elif not _same(head["branch"], rec["branch"]):
            other = ("branch", head["branch"])
        else:
            return j, label, nxt
    if other is not None:
        return (f"the transition is enabled and makes the recorded changes, but its "
                f"{other[0]} differs: recorded {json.dumps(rec[other[0]])}, replayed "
                f"{json.dumps(other[1])}")
    if same_label:
        got = C.encode_changes(m, state, same_label[0])
        recorded_text, got_text = _changes_text(rec["changes"]), _changes_text(got)
        if recorded_text == got_text:
            recorded_text, got_text = (_changes_text(rec["changes"], every=True),
                                       _changes_text(got, every=True))
        if undecodable:
            recorded_text += f" ({undecodable})"
        return (f"the transition is enabled but its changes differ: recorded {recorded_text}; "
                f"replayed {got_text}")
    recs = [C.encode_step_head(m, n, lab, state, nxt) for lab, nxt in succ]
    moved = [r for r in recs if _identity(r)[:5] == ident[:5]]
    if moved:
        return f"the program differs here: line {rec['line']} now reads '{moved[0]['source']}'"
    enabled = sorted({describe(r) for r in recs})
    return ("that transition is not enabled; enabled here: "
            + ("; ".join(enabled) if enabled else "none"))


def _end_of_safety(m, cfg, recorded, res, diverge):
    """A safety violation of explore: the model's own checks on the last state."""
    state = res.states[-1]
    n = len(res.labels)
    viols = list(m.violations(state))
    if not viols and cfg.get("deadlock", True) and not m.successors(state) \
            and m.terminal_kind(state) == "deadlock":
        viols = [m.deadlock_violation(state)]
    match = [v for v in viols if _same(T.normal(T.violation_record(m, v)), recorded)]
    if match:
        res.status, res.exit_status = "violation", 1
        res.message = f"reproduced: {match[0].message} (after {n} steps)"
        return res
    seen = "; ".join(v.message for v in viols) or "no violation"
    return diverge(n, f"diverged at the end: every step reproduced, but the recorded "
                      f"violation ({recorded['message']}) is not: {seen}")


# ---------------------------------------------------------------------------
# the end of a run: what the runner itself says, steered along the steps
# ---------------------------------------------------------------------------

class _Beyond(Exception):
    """The run would go on past the last recorded step."""


class _Steer(random.Random):
    """A generator that makes :func:`pccl.tools.runner.run` take the recorded
    initial state and the recorded successor at each step."""

    def __init__(self, first, picks: list):
        super().__init__(0)
        self.first = first
        self.picks = picks
        self.n = 0

    def choice(self, seq):
        for s in seq:
            if s == self.first:
                return s
        raise _Beyond()          # pragma: no cover - the replay found it among them

    def randrange(self, start, stop=None, step=1):
        if self.n >= len(self.picks):
            raise _Beyond()
        j, k = self.picks[self.n]
        assert stop is None and start == k, (start, k)
        return j

    def step(self, label, before, after) -> None:
        self.n += 1
        if self.n > len(self.picks):
            raise _Beyond()


def _end_of_run(m, cfg, doc, res, picks, diverge, spellings):
    from pccl.tools.runner import run as run_model, unspelt
    result = doc["result"]
    n = len(picks)
    steer = _Steer(res.states[0], picks)
    stall = cfg.get("stall_steps")
    try:
        rr = run_model(m, max_steps=cfg.get("max_steps") or 100_000, rng=steer,
                       on_step=steer.step, stall_steps=20 if stall is None else stall,
                       spelling=unspelt)
    except _Beyond:
        rr = None
    if rr is None:
        if result["status"] == "interrupted":
            res.status, res.exit_status = "clean", 0
            res.message = (f"reproduced: interrupted — every step re-executes, and the run can "
                           f"go on from there (after {n} steps)")
            return res
        k = len(m.successors(res.states[-1]))
        return diverge(n, f"diverged at the end: every step reproduced, but the recorded run "
                          f"ends here ({result['status']}: {result['message']}) and the "
                          f"replayed one goes on ({k} transition{'s' if k != 1 else ''} "
                          f"enabled, no violation)")
    said = [spell(rr.message, s) for s in spellings]
    rr.message = result.get("message") if result.get("message") in said else said[0]
    if rr.steps < n:
        return diverge(rr.steps, f"diverged at step {rr.steps} of {n}: the run stops there "
                                 f"({rr.status}: {rr.message}), but the trace goes on")
    v = rr.violations[0] if rr.violations else None
    got = {"status": rr.status, "message": rr.message,
           "violation": T.normal(T.violation_record(m, v))}
    want = {k: result[k] for k in got}
    if not _same(got, want):
        return diverge(n, f"diverged at the end: every step reproduced, but the recorded "
                          f"result ({want['status']}: {want['message']}) does not match the "
                          f"replayed run's ({got['status']}: {got['message']})")
    if rr.exit_status == 1:
        res.status, res.exit_status = "violation", 1
        res.message = f"reproduced: {rr.message} (after {n} steps)"
    else:
        res.status, res.exit_status = "clean", 0
        res.message = f"reproduced: {rr.status} — {rr.message} (after {n} steps)"
    return res


# ---------------------------------------------------------------------------
# the end of a temporal counterexample, and of a witness
# ---------------------------------------------------------------------------

def _holds(fn, st) -> bool:
    try:
        return bool(fn(st))
    except Exception:        # noqa: BLE001 - a runtime error in a property is "false"
        return False


def _end_of_witness(m, w, res, diverge):
    n = len(res.labels)
    props = [p for p in m.temporal if p.kind == "reachable" and p.name == w["name"]]
    if not props:
        return diverge(n, f"diverged at the end: the witness's property ({w['name']}) is not "
                          f"a 'reachable P' of config.property_options")
    p = props[0]
    if not _holds(p.p, res.states[-1]):
        return diverge(n, f"diverged at the end: every step reproduced, but `{p.text}` does "
                          f"not hold in the last state, so the path is no witness")
    res.status, res.exit_status = "witness", 0
    res.message = f"reproduced: witness — `{p.text}` holds after {n} steps"
    return res


#: How many states the time-lock and stall checks visit from the last state at most.
TIMELOCK_LIMIT = 100_000


class _BoundedReach:
    """The states reachable from ``start`` (itself included), depth-first,
    each once (up to the model's key), with their successors: iterating
    yields ``(state, successors)``; the successors are followed after the
    loop body has seen them.  It stops after TIMELOCK_LIMIT states (a
    warning in ``res.warnings`` says that ``what`` was checked on the
    states reachable from ``source`` only); ``finished`` tells afterwards
    whether every reachable state was yielded."""

    def __init__(self, m, start, res: ReplayResult, what: str, source: str):
        self.m, self.start, self.res = m, start, res
        self.what, self.source = what, source
        self.finished = False

    def __iter__(self):
        m = self.m
        seen, todo = {m.key(self.start)}, [self.start]
        while todo:
            if len(seen) > TIMELOCK_LIMIT:
                self.res.warnings.append(f"warning: {self.what} was checked on the first "
                                         f"{TIMELOCK_LIMIT:,} states reachable from "
                                         f"{self.source} only")
                return
            st = todo.pop()
            succ = m.successors(st)
            yield st, succ
            for _, nxt in succ:
                k = m.key(nxt)
                if k not in seen:
                    seen.add(k)
                    todo.append(nxt)
        self.finished = True


def _end_of_stall(m, recorded, cycle_start, res, diverge):
    """The last state is stalled (pccl/model/stall.py, docs/temporal.md): from it
    no reachable transition changes the team's visible state, no run ends,
    time advances, and not every agent has exited; the message (with what
    each agent waits on) is made again from the state."""
    from pccl.model.layout import AGS, EXITED, STATUS
    from pccl.search.liveness import STALL_MESSAGE
    from pccl.model.stall import signature_fn, waiting, waiting_text
    n = len(res.labels)

    def bad(why: str):
        return diverge(n, f"diverged at the end: every step reproduced, but {why}")

    if cycle_start is not None:
        return bad("a stall counterexample is not a lasso")
    last = res.states[-1]
    if all(ag[STATUS] == EXITED for ag in last[AGS]):
        return bad("every agent has exited at the recorded stall")
    sig = signature_fn(m)
    want = sig(last)
    advances = False
    reach = _BoundedReach(m, last, res, "the stall", "it")
    for _, succ in reach:
        if not succ:
            return bad("a run can end from the recorded stall")
        for lab, nxt in succ:
            advances = advances or lab[0] == "TIME ADVANCE"
            if sig(nxt) != want:
                return bad(f"the team can still change from the recorded stall ({lab[0]})")
    if not advances and reach.finished:
        return bad("time never advances from the recorded stall (a time-lock, not a stall)")
    waits = waiting(m, last)
    message = STALL_MESSAGE + ("; " + waiting_text(waits) if waits else "")
    if message != recorded["message"]:
        return bad(f"the recorded stall message is not the state's: {message}")
    res.status, res.exit_status = "violation", 1
    res.message = f"reproduced: {message} (after {n} steps)"
    return res


def _end_of_frozen(m, recorded, cycle_start, res, diverge):
    """The last state is frozen (pccl/model/frozen.py, docs/temporal.md): from
    it no reachable transition changes the progress signature, no run
    ends, time advances, the events the message says can never fire again
    do not fire, and those it says still fire are the ones that do."""
    from pccl.model.frozen import FROZEN_MESSAGE, progress_signature_fn
    n = len(res.labels)

    def bad(why: str):
        return diverge(n, f"diverged at the end: every step reproduced, but {why}")

    if cycle_start is not None:
        return bad("a frozen-team counterexample is not a lasso")
    sig = progress_signature_fn(m)
    last = res.states[-1]
    want = sig(last)
    advances, fires = False, set()
    reach = _BoundedReach(m, last, res, "the frozen team", "it")
    for _, succ in reach:
        if not succ:
            return bad("a run can end from the recorded frozen state")
        for lab, nxt in succ:
            advances = advances or lab[0] == "TIME ADVANCE"
            if lab[0] == "EVENT SELECT" and lab[2] is not None:
                fires.add(lab[2])
            if sig(nxt) != want:
                return bad(f"the team can still make progress from the recorded frozen state "
                           f"({lab[0]})")
    if not advances and reach.finished:
        return bad("time never advances from the recorded frozen state (a time-lock)")
    msg = recorded["message"]
    evs = m.program.events
    live = ", ".join(f"{evs[e].name} (line {evs[e].guard.span.line})" for e in sorted(fires))
    frozen = [ev for k, ev in enumerate(evs) if k not in fires]
    if (not msg.startswith(FROZEN_MESSAGE) or not frozen
            or any(f"{ev.name} (line {ev.guard.span.line}:" not in msg for ev in frozen)
            or (reach.finished and not msg.endswith(f"; still firing: {live}" if live else ")"))):
        return bad(f"the recorded message does not name the events that can never fire again "
                   f"({', '.join(ev.name for ev in frozen) or 'none'}) and those that still "
                   f"fire ({live or 'none'})")
    res.status, res.exit_status = "violation", 1
    res.message = f"reproduced: {msg} (after {n} steps)"
    return res


def _end_of_temporal(m, cfg, recorded, cycle_start, res, diverge):
    states, labels = res.states, res.labels
    n = len(labels)
    if recorded["kind"] == "timelock":
        why = _timelock_problem(m, states, labels, cycle_start, res)
    else:
        why = _temporal_problem(m, recorded, states, labels, cycle_start)
    if why is not None:
        return diverge(n, f"diverged at the end: every step reproduced, but {why}")
    res.status, res.exit_status = "violation", 1
    shape = (f"a lasso: the cycle from step {cycle_start} closes" if cycle_start is not None
             else "a path")
    res.message = f"reproduced: {recorded['message']} (after {n} steps; {shape})"
    return res


def _closes(m, states, cycle_start) -> bool:
    """Whether the recorded cycle closes: the last state is (up to the
    model's key) the state after step ``cycle_start``."""
    return m.key(states[-1]) == m.key(states[cycle_start])


def _advances(labels, cycle_start) -> bool:
    """Whether time advances in the recorded cycle (none: False)."""
    cyc_labels = labels[cycle_start:] if cycle_start is not None else []
    return any(lab[0] == "TIME ADVANCE" for lab in cyc_labels)


def _timelock_problem(m, states, labels, cycle_start, res) -> Optional[str]:
    """Step of :func:`_end_of_temporal`: why the replayed path is not the
    recorded time-lock, or None."""
    from pccl.model.layout import AGS, EXITED, STATUS
    if cycle_start is None:
        return "a time-lock counterexample is a lasso, and result.cycle_start is missing"
    if not _closes(m, states, cycle_start):
        return (f"the cycle does not close: the last state is not the state after step "
                f"{cycle_start}")
    if _advances(labels, cycle_start):
        return "time advances in the recorded time-lock cycle"
    if all(ag[STATUS] == EXITED for ag in states[-1][AGS]):
        return "every agent has exited at the recorded time-lock"
    return _timelock_escape(m, states[-1], res)


def _timelock_escape(m, last, res) -> Optional[str]:
    """Step of :func:`_timelock_problem`: whether time can advance again (or
    the run end) from a state reachable from the time-lock's last state;
    searched up to TIMELOCK_LIMIT states (with a warning in ``res``)."""
    from pccl.model.layout import DISCRETE, PHASE
    for st, succ in _BoundedReach(m, last, res, "the time-lock", "its cycle"):
        if not succ or st[PHASE] != DISCRETE:
            return ("time can advance again (or the run end) from the recorded "
                    "time-lock cycle")
    return None


def _temporal_problem(m, recorded, states, labels, cycle_start) -> Optional[str]:
    """Step of :func:`_end_of_temporal`: why the replayed path is not the
    recorded liveness or response counterexample, or None."""
    from pccl.tools.runner import _Monitor
    kind = recorded["kind"]
    props = [p for p in m.temporal if p.name == recorded["name"]]
    want = {"liveness": ("eventually", "leadsto"), "response": ("within",)}[kind]
    props = [p for p in props if p.kind in want]
    if not props:
        return (f"no {kind} property named `{recorded['name']}` is among "
                f"config.property_options")
    p = props[0]
    if kind != "response":
        return _liveness_problem(m, p, states, labels, cycle_start)
    if cycle_start is not None:
        return "a bounded-response counterexample is not a lasso"
    mon = _Monitor([p])
    if not any(mon.observe(st, k) for k, st in enumerate(states)):
        return (f"on this path `{p.text}` is never violated: no premise goes "
                f"unanswered for more than {p.bound} time units")
    return None


def _liveness_problem(m, p, states, labels, cycle_start) -> Optional[str]:
    """Step of :func:`_temporal_problem`: why the path does not violate the
    liveness property ``p``, or None."""
    if p.kind == "eventually":
        hit = [k for k, st in enumerate(states) if _holds(p.p, st)]
        if hit:
            return f"`{p.text}` holds after step {hit[0]}"
    else:
        qs = [k for k, st in enumerate(states) if _holds(p.q, st)]
        after = qs[-1] + 1 if qs else 0
        if cycle_start is not None and after > cycle_start:
            return f"Q holds in the cycle (after step {qs[-1]})"
        if not any(_holds(p.p, st) for st in states[after:]):
            return "P never holds without Q holding then or later"
    if cycle_start is None:
        k = len(m.successors(states[-1]))
        if k:
            return (f"the path does not end in a terminal state ({k} transitions "
                    f"enabled) and is no lasso (no result.cycle_start)")
        return None
    return _lasso_problem(m, states, labels, cycle_start)


def _lasso_problem(m, states, labels, cycle_start) -> Optional[str]:
    """Step of :func:`_liveness_problem`: why the recorded cycle is not a
    fair, time-advancing lasso, or None."""
    if not _closes(m, states, cycle_start):
        return (f"the cycle does not close: the last state is not the state "
                f"after step {cycle_start}")
    if not _advances(labels, cycle_start):
        return ("time never advances in the cycle (a zero-time cycle is a "
                "time-lock, not a liveness counterexample)")
    from pccl.model.engine import blackbox_arrival_is_fair
    if blackbox_arrival_is_fair(m.blackbox):
        cyc = states[cycle_start:]
        for a in range(m.N):
            if all(m.arrival_pending(st) >> a & 1 for st in cyc):
                return (f"the cycle is unfair: agent {a}'s doReach is under "
                        f"way throughout, and {m.blackbox.name} lets it arrive")
    return None
