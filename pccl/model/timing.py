"""The timing a search explores, in words users read in the verdict.

Under the paper's semantics (docs/language.md §12) every agent has a budget
of ``n0`` event-block executions per time step, each costing its rate ρ(i):
with ``n0 = 1`` (the default) the agents run in *lock-step rounds*, one
event block each per time step, so no agent can run a second block while
another agent is still inside (or has not started) its first.  A SPIN or
TLC user reads "every interleaving" as every interleaving of statements;
this module says which interleavings a verdict covers, and when a clean
verdict may depend on it (:func:`lockstep_note`).
"""

from __future__ import annotations

from typing import Optional

from pccl.lang import ast as A


def blocks_per_step(model) -> tuple:
    """Event blocks agent i may run per time step: ``n0 // ρ(i)``."""
    return tuple(model.n0 // r for r in model.rho)


def timing_text(model) -> str:
    """The timing explored, one phrase (the ``timing:`` line of ``checked``)."""
    if getattr(model, "semantics", "pccl") == "koord":
        skip = ", or skips it (SkipEvent)" if getattr(model, "skip_events", False) else ""
        return ("Koord's rounds: every robot runs at most one event per "
                f"round, as one transition{skip}; reads see the round's start")
    per = blocks_per_step(model)
    if all(b == 1 for b in per):
        return (f"lock-step rounds (n0 = {model.n0}): every agent runs one event block "
                f"per time step")
    if len(set(per)) == 1:
        return (f"n0 = {model.n0}: every agent runs up to {per[0]} event blocks per time step, "
                f"their statements interleaved")
    parts = ", ".join(f"agent {i} {b}" for i, b in enumerate(per))
    return (f"n0 = {model.n0} with rates: event blocks per time step {parts}, "
            f"their statements interleaved")


def shared_access_event(program: A.Program) -> Optional[A.Event]:
    """The first event whose guard or body reads or writes a shared
    (``allwrite``/``allread``) variable, or None: with two agents or more such
    an event's outcome can depend on how many blocks another agent ran
    before it."""
    shared = {d.name for d in program.decls
              if isinstance(d, A.VarDecl) and d.section in ("allwrite", "allread")}
    if not shared:
        return None
    for ev in program.events:
        exprs = [ev.guard]
        for s in A.walk_stmts(ev.body):
            exprs.extend(A.own_exprs(s))
        for x in exprs:
            if any(isinstance(e, A.Name) and e.name in shared for e in A.walk_expr(x)):
                return ev
    return None


def lockstep_note(model) -> Optional[str]:
    """For a clean verdict under lock-step rounds (every agent one block per
    time step) of a team whose events touch shared variables: what the
    verdict does not cover, and the option that explores it (a placeholder
    spelt by the caller).  None otherwise."""
    if model.N < 2 or any(b != 1 for b in blocks_per_step(model)):
        return None
    if getattr(model, "semantics", "pccl") == "koord":
        return None         # one event per round is the semantics, not a bound
    ev = shared_access_event(model.program)
    if ev is None:
        return None
    return (f"lock-step rounds, n0 = {model.n0}: one event block per agent per time step; "
            f"{{n0={model.n0 + 1}}} also explores an agent running a second block while "
            f"another is inside its first: event {ev.name} (line {ev.span.line}) touches "
            f"shared variables")
