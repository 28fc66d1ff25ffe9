"""Typed results of the API: named views of configurations, steps and findings.

The CLI prints these same views: ``str(view)`` is the text ``pccl run`` and
``pccl explore`` print for a state, and ``view.to_json()`` the JSON of
``--format json``.  Every view is frozen; values are as the JSON shows them
(numbers, booleans, strings, lists; positions as ``(x, y, z)``).  A view is
also readable by the JSON key (``step["source"]``), which keeps scripts
written against the JSON working.

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

from pccl.output import display as D


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
    _json: dict = field(default_factory=dict, repr=False, compare=False)

    def to_json(self) -> dict:
        return self._json


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
    _json: dict = field(default_factory=dict, repr=False, compare=False)
    _text: str = field(default="", repr=False, compare=False)

    @classmethod
    def of(cls, model, st) -> "StateView":
        """The view of the configuration ``st`` of ``model``."""
        data = D.state_json(model, st)
        agents = []
        for a in data["agents"]:
            r = a["reach"]
            stuck = (Stuck(a["kind"], a["reason"], a["line"], a["column"])
                     if a["status"] == "stuck" else None)
            agents.append(AgentView(
                a["id"], a["status"], a["k"], a["counter"], a["lockState"],
                tuple(a["position"]), None if r["target"] is None else tuple(r["target"]),
                r["t0"], r["doReach_done"], r["doReach_fail"], _frozen(a["variables"]),
                stuck, a))
        return cls(data["time"], data["transitionState"], tuple(data["lockQueue"]),
                   _frozen(data["shared"]), tuple(agents), data, D.format_state(model, st))

    def to_json(self) -> dict:
        return self._json

    def __str__(self) -> str:
        return self._text


@dataclass(frozen=True)
class Change(_Keyed):
    """One cell a step changed, as data: ``cell`` its name as the trace
    prints it (``inCs[0]``, ``status[1]``, ``time``), ``path`` the structured
    cell of the trace format (``{"agent": 0, "var": "inCs"}``,
    ``{"agent": 1, "cell": "status"}``, ``{"cell": "time"}``), ``agent`` (None
    for a shared or global cell), ``old`` and ``new`` the values as data
    (numbers, booleans, strings, lists; a position is ``[x, y, z]``; a
    status ``"running"`` or ``{"status": "stuck", ...}``), and
    ``old_text``/``new_text`` as the trace prints them.  ``to_json()`` (the
    CLI's JSON) keeps the printed form."""
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
        return {"cell": self.cell, "old": self.old_text, "new": self.new_text}


_TEXT_NAME = {"phase": "transitionState"}


def _changes(model, before, after) -> tuple:
    """The typed changes of a step (pccl/output/traces.py), with the printed text
    of each (pccl/output/display.py); the cells the trace prints, in its order."""
    from pccl.output import traces as T
    texts = {c: (o, n) for c, o, n in D.diff(model, before, after)}
    out = []
    for c in T.changes(model, before, after):
        name = T.cell_name(c["cell"])
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

    @classmethod
    def of(cls, model, n, label, before, after) -> "StepView":
        d = D.step_json(model, n, label, before, after)
        return cls(d["step"], d["time"], d["agent"], d["rule"], d["event"], d["line"],
                   d["source"], _changes(model, before, after))

    def to_json(self) -> dict:
        return {"step": self.step, "time": self.time, "agent": self.agent, "rule": self.rule,
                "event": self.event, "line": self.line, "source": self.source,
                "changes": [c.to_json() for c in self.changes]}

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

    def to_json(self) -> dict:
        out = {"kind": self.kind, "name": self.name, "message": self.message,
               "agent": self.agent, "line": self.line, "column": self.column,
               "depth": self.depth, "shortest": self.shortest,
               "trace": [s.to_json() for s in self.trace],
               "state": None if self.state is None else self.state.to_json()}
        if self.cycle_start is not None:
            out["cycle_start"] = self.cycle_start
        return out
