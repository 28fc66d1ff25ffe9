"""Typed results of the API: named views of configurations, steps and findings.

The CLI prints these same views: ``str(view)`` is the text ``pccl run`` and
``pccl explore`` print for a state, and ``view.to_json()`` the JSON of
``--format json``: the one encoding of :mod:`pccl.output.codec` (the trace
format's states and steps).  A view is built from the configuration itself
(the model's cells and types), never from JSON.  Every view is frozen;
values are data (numbers, booleans, enum member names, lists; positions as
``(x, y, z)``).  A view is also readable by the JSON key
(``step["source"]``).

    >>> from pccl.api import explore
    >>> r = explore("programs/race.pccl", world="programs/race.toml", blackbox="instant")
    >>> r.violation.kind, r.trace[-1].source
    ('stuck', 'currentDest = head(dests);')
    >>> r.final_state.agents[0].status
    'stuck'
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Optional
from collections.abc import Mapping

from pccl.output import codec as C
from pccl.output import display as D
from pccl.model.layout import (AGS, CNT, DISCRETE, DONE, FAIL, LCK, LQ, PC, PHASE, POS, REACH,
                               STATUS, T0, TARGET, TIME)
from pccl.lang.values import to_json


class _Keyed:
    """Read a view by the key of its JSON form."""

    def to_json(self) -> dict:          # pragma: no cover - every view overrides it
        raise NotImplementedError

    def __getitem__(self, key: str):
        return self.to_json()[key]

    def keys(self):
        return self.to_json().keys()


def _frozen(d: Mapping) -> Mapping:
    return MappingProxyType(dict(d))


@dataclass(frozen=True)
class Stuck(_Keyed):
    """Why an agent is stuck: ``kind`` (``error`` or ``assert``), the
    reason, and the source line and column of the statement."""
    kind: str
    reason: str
    line: Optional[int]
    column: Optional[int]

    def to_json(self) -> dict:
        return {"status": "stuck", "kind": self.kind, "reason": self.reason,
                "line": self.line, "column": self.column}


@dataclass(frozen=True)
class AgentView(_Keyed):
    """One agent's cell: status (``running``, ``exited`` or ``stuck``, with
    ``stuck`` saying why), its place in the program (``k``), event-block
    counter, lock state, position, doReach record and variables (allread
    and local, by name)."""
    id: int
    status: str
    k: str
    counter: int
    lock: str
    position: tuple
    target: Optional[tuple]
    t0: Any
    doReach_done: Any
    doReach_fail: Any
    variables: Mapping[str, Any]
    stuck: Optional[Stuck] = None
    _model: Any = field(default=None, repr=False, compare=False)
    _state: Any = field(default=None, repr=False, compare=False)

    @classmethod
    def of(cls, model, st, i) -> "AgentView":
        """The view of agent ``i`` of the configuration ``st`` of ``model``."""
        ag = st[AGS][i]
        code = ag[STATUS]
        status = C.encode_status(model, code)
        stuck = (Stuck(status["kind"], status["reason"], status["line"], status["column"])
                 if status["status"] == "stuck" else None)
        r = ag[REACH]
        return cls(i, status["status"], model.compiled.describe_k(ag[PC]), ag[CNT],
                   D.LOCK_NAMES[ag[LCK]], tuple(ag[POS]),
                   None if r[TARGET] is None else tuple(r[TARGET]), r[T0], r[DONE], r[FAIL],
                   _frozen({n: to_json(v, t) for n, t, v in D.agent_vars(model, st, i)}),
                   stuck, model, st)

    def to_json(self) -> dict:
        return C.encode_agent(self._model, self._state, self.id)


@dataclass(frozen=True)
class StateView(_Keyed):
    """A configuration: global time, the transition phase (``discrete`` or
    ``continuous``), the lock queue, shared variables by name, and the
    agents."""
    time: Any
    phase: str
    lock_queue: tuple
    shared: Mapping[str, Any]
    agents: tuple
    _model: Any = field(default=None, repr=False, compare=False)
    _state: Any = field(default=None, repr=False, compare=False)

    @classmethod
    def of(cls, model, st) -> "StateView":
        """The view of the configuration ``st`` of ``model``."""
        return cls(st[TIME], "discrete" if st[PHASE] == DISCRETE else "dynamic", tuple(st[LQ]),
                   _frozen({n: to_json(v, t) for n, t, v in D.shared_vars(model, st)}),
                   tuple(AgentView.of(model, st, i) for i in range(len(st[AGS]))), model, st)

    @property
    def state(self):
        """The configuration itself (the model's plain tuple)."""
        return self._state

    def to_json(self) -> dict:
        return C.encode_state(self._model, self._state)

    def __str__(self) -> str:
        return D.format_state(self._model, self._state)


@dataclass(frozen=True)
class Change(_Keyed):
    """One cell a step changed, as data: ``cell`` its name as the trace
    prints it (``inCs[0]``, ``status[1]``, ``time``), ``path`` the structured
    cell of the trace format (``{"agent": 0, "var": "inCs"}``,
    ``{"agent": 1, "cell": "status"}``, ``{"cell": "time"}``), ``agent`` (None
    for a shared or global cell), ``old`` and ``new`` the values as data
    (numbers, booleans, strings, lists; a position is ``[x, y, z]``; a
    status ``"running"`` or ``{"status": "stuck", ...}``), and
    ``old_text``/``new_text`` as the trace prints them.  ``to_json()`` is
    the change as the trace format writes it (:func:`pccl.output.codec.encode_changes`)."""
    cell: str
    old: Any
    new: Any
    path: Mapping = field(default_factory=dict, compare=False)
    old_text: str = ""
    new_text: str = ""

    @property
    def agent(self) -> Optional[int]:
        return self.path.get("agent")

    def to_json(self) -> dict:
        return {"cell": dict(self.path), "old": self.old, "new": self.new}


_TEXT_NAME = {"phase": "transitionState"}


def _changes(model, before, after) -> tuple:
    """The typed changes of a step (pccl/output/traces.py), with the printed text
    of each (pccl/output/display.py); the cells the trace prints, in its order."""
    texts = {c: (o, n) for c, o, n in D.diff(model, before, after)}
    out = []
    for c in C.encode_changes(model, before, after):
        name = C.cell_name(c["cell"])
        name = _TEXT_NAME.get(name, name)
        if name not in texts:           # counter, env: not printed
            continue
        o, n = texts[name]
        out.append(Change(name, c["old"], c["new"], _frozen(c["cell"]), o, n))
    return tuple(out)


@dataclass(frozen=True)
class StepView(_Keyed):
    """One step of a trace: its number, the time before it, the agent (None
    for a system step), the rule's name, the event, the source line and its
    text, and what changed."""
    step: int
    time: Any
    agent: Optional[int]
    rule: str
    event: Optional[str]
    line: Optional[int]
    source: Optional[str]
    changes: tuple
    _model: Any = field(default=None, repr=False, compare=False)
    _step: Any = field(default=None, repr=False, compare=False)     # (label, before, after)

    @classmethod
    def of(cls, model, n, label, before, after) -> "StepView":
        info = D.label_info(model, label, before)
        return cls(n, before[TIME], info["agent"], info["rule"], info["event"], info["line"],
                   info["source"], _changes(model, before, after), model, (label, before, after))

    def to_json(self) -> dict:
        """The step as the trace format writes it (:func:`pccl.output.codec.encode_step`)."""
        label, before, after = self._step
        return C.encode_step(self._model, self.step, label, before, after)

    def __str__(self) -> str:
        where = f"line {self.line}: {self.source}" if self.line else ""
        who = "system" if self.agent is None else f"agent {self.agent}"
        return f"{self.step}. t={D.fmt_time(self.time)} {who} {self.rule} {where}".rstrip()


@dataclass(frozen=True)
class Finding(_Keyed):
    """A violation with its counterexample: the kind (``invariant``,
    ``stuck``, ``assert``, ``deadlock``, ``collision``, and for temporal
    properties ``liveness``, ``timelock``, ``response``, ``unreachable``), the property's
    name, the message, the agent and source location where there is one, the
    depth (transitions in the reduced graph), whether the trace is shortest
    (``"yes"`` or ``"under the reductions"``), the steps and the violating
    state."""
    kind: str
    name: Optional[str]
    message: str
    agent: Optional[int]
    line: Optional[int]
    column: Optional[int]
    depth: int
    shortest: str
    trace: tuple
    state: Optional[StateView]          # None for "unreachable" (no path)
    #: a lasso (temporal properties): the steps after this many repeat forever
    cycle_start: Optional[int] = None
    #: the path's initial state (None for "unreachable")
    initial: Optional[StateView] = field(default=None, repr=False)
    #: under reductions, what shortening against the unreduced semantics
    #: did (a :class:`pccl.model.shorten.Shortening`: ``status``
    #: shortened, confirmed, not-shown or off; ``reduced_steps``; ``reason``),
    #: None without reductions
    shortening: Any = None

    def to_json(self) -> dict:
        """The finding; its path as the trace format writes one
        (``{"initial", "steps", "final"}``, :func:`path_json`), or null."""
        out = {"kind": self.kind, "name": self.name, "message": self.message,
               "agent": self.agent, "line": self.line, "column": self.column,
               "depth": self.depth, "shortest": self.shortest,
               "trace": path_json(self.initial, self.trace, self.state)}
        if self.cycle_start is not None:
            out["cycle_start"] = self.cycle_start
        if self.shortening is not None:
            out["shortening"] = self.shortening.as_dict()
        return out


def path_json(initial: Optional[StateView], steps, final: Optional[StateView]) -> Optional[dict]:
    """A path as every JSON output writes one: the trace format's
    ``initial``, ``steps`` and ``final`` (null without a path)."""
    if initial is None or final is None:
        return None
    return {"initial": initial.to_json(), "steps": [s.to_json() for s in steps],
            "final": final.to_json()}
