"""The rewrite rules of PCCL, one function per rule of the paper
(docs/language.md §11, "The rules").

Each agent rule has the signature ``rule(m, st, i, ag, head, out)``: ``m`` is
the model, read only through :class:`RuleContext`; ``st`` the configuration,
``i`` the agent id, ``ag`` its agent cell, ``head`` the decoded head of its
``k`` cell (a :class:`KHead`, built once per pc by
:class:`pccl.model.compiled.Control`), and ``out`` a list to which the rule appends
``(label, successor)`` pairs, one per way it applies.  A rule that does not
apply appends nothing.  Global rules take ``(m, st, out)``.

Labels are ``(RULE NAME, agent, detail)``; traces print the rule name.  The
paper's STATEMENT rule is one function per kind of statement (as K's
labelled rules ``[assign]``, ``[if]``, ``[while]``), all labelled
``STATEMENT``.

A configuration is meaningful only together with the model that made it:
``pc`` is an interned k cell and a stuck status a key of
``CompiledProgram.stuck_reasons``.  Its layout is :mod:`pccl.model.layout`'s::

    state = (time 0, phase 1, lockQueue 2, shared 3, agents 4, env 5)
    agent = (pc 0, counter 1, lockState 2, status 3, locals 4, allread 5, position 6, reach 7)
    reach = (target 0, obstacles 1, t0 2, doReach_done 3, doReach_fail 4, start 5)

This module is the hot kernel of a search: its bodies index cells by these
numbers (the layout's constants cost 1.5-3 % here) and rebuild agent cells
with tuple displays; everywhere else, code reads cells by name.
"""

from __future__ import annotations

from typing import Any, Optional, Protocol
from collections.abc import Callable, Sequence

from pccl.lang.errors import PcclRuntimeError
from pccl.model.layout import (DISCRETE, DYNAMIC, EXITED, IDLE, LOCK, REQUEST, RUNNING,  # noqa: F401
                               put_agent, with_pc, with_status)

# k-cell head kinds (KHead.kind)
K_EMPTY, K_END, K_AEND, K_ACQ, K_SIMPLE, K_IF, K_WHILE, K_ATOMIC, \
    K_DOREACH, K_EXIT, K_ASSERT = range(11)

# -- the configuration kernel's public API (the engine uses it too) ------------------

#: The exceptions that a compiled expression or statement may raise at run
#: time; each gets the agent stuck (:func:`stuck_successor`), never the search.
RUNTIME_ERRORS = (PcclRuntimeError, ZeroDivisionError, OverflowError,
                  TypeError, IndexError, ValueError)


class KCells(Protocol):
    """The interned k cells a rule may jump to (:class:`pccl.model.compiled.Control`)."""
    empty_pc: int              # ·  (the top of the event block)
    idle_pc: int               # endEventBlock
    event_pcs: Sequence[int]   # event e's effect ~> endEventBlock


class RuleContext(Protocol):
    """Exactly what a rule may read from the model (:class:`pccl.model.engine.Model`
    implements it).  tests/semantics/test_kernel.py checks that the rules read nothing
    else."""
    rho: Sequence[int]         # the rate map ρ: counter increment per agent
    n0: int                    # event-block executions per time step
    first_only: bool           # --events first
    guards_rand: bool          # some guard calls rand()
    record_t0: bool            # doReach records the time it was called
    ctl: KCells
    oracle: Any                # rand outcomes: .outcomes(fn, *args) -> list

    def enabled_events(self, i: int, ag: tuple, sh: tuple, ags: tuple) -> list: ...
    def stuck_code(self, kind: str, reason: str, where: Any) -> int: ...
    def round_pos(self, p: Sequence[float]) -> tuple: ...
    def next_time(self, t: Any) -> Any: ...
    def environment_step(self, st: tuple) -> list: ...
    def leg_start(self, position: tuple, reach: tuple) -> tuple: ...


class KHead:
    """The decoded head of a k cell: what the rules need of ``k(pc)``,
    built once per pc and cached (:meth:`pccl.model.compiled.Control.info`).

    Each kind sets the fields it has (the others are None):

    ==========  =================================================================
    kind        fields
    ==========  =================================================================
    K_EMPTY     —  (k is empty: the top of the event block)
    K_END       —  (endEventBlock)
    K_AEND      ``next_pc`` (atomicEnd ~> k(next_pc))
    K_ACQ       ``body_pc`` (the atomic body ~> atomicEnd ...), ``sid``
    K_SIMPLE    ``fn`` (the effect: ``(ag2, sh2)``), ``next_pc``, ``sid``, ``has_rand``
    K_IF        ``fn`` (the index of the branch taken), ``branch_pcs``, ``sid``, ``has_rand``
    K_WHILE     ``fn`` (the test), ``body_pc``, ``next_pc``, ``sid``, ``has_rand``
    K_ASSERT    ``fn`` (the condition), ``next_pc``, ``sid``, ``has_rand``
    K_ATOMIC    ``request_pc`` (acquire ~> atomicEnd ...), ``body_pc``, ``sid``
    K_DOREACH   ``fn`` (``(target, obstacles)``), ``next_pc``, ``sid``, ``has_rand``
    K_EXIT      ``sid``
    ==========  =================================================================

    ``rules`` and ``rules_spent`` are the agent rules that may apply to the
    head (:data:`AGENT_RULES`, :data:`AGENT_RULES_SPENT`).
    """
    __slots__ = ("kind", "fn", "next_pc", "body_pc", "branch_pcs", "request_pc", "sid",
                 "has_rand", "rules", "rules_spent")

    def __init__(self, kind: int, *, fn: Optional[Callable] = None, next_pc: Optional[int] = None,
                 body_pc: Optional[int] = None, branch_pcs: Optional[tuple] = None,
                 request_pc: Optional[int] = None, sid: Optional[int] = None,
                 has_rand: bool = False):
        self.kind = kind
        self.fn = fn
        self.next_pc = next_pc
        self.body_pc = body_pc
        self.branch_pcs = branch_pcs
        self.request_pc = request_pc
        self.sid = sid
        self.has_rand = has_rand
        self.rules = AGENT_RULES[kind]
        self.rules_spent = AGENT_RULES_SPENT[kind]

    def __repr__(self) -> str:
        fields = ", ".join(f"{f}={getattr(self, f)!r}" for f in self.__slots__[1:8]
                           if getattr(self, f) is not None)
        return f"KHead({_KIND_NAMES[self.kind]}{', ' if fields else ''}{fields})"


_KIND_NAMES = ("K_EMPTY", "K_END", "K_AEND", "K_ACQ", "K_SIMPLE", "K_IF", "K_WHILE",
               "K_ATOMIC", "K_DOREACH", "K_EXIT", "K_ASSERT")


def _outcomes(m, fn, has_rand, *args):
    """Evaluate ``fn(*args)``; with rand, every outcome (explore) or the
    policy's (run).  Runtime errors become :class:`Err` results."""
    if not has_rand:
        try:
            return [fn(*args)]
        except RUNTIME_ERRORS as exc:
            return [Err.of(exc)]

    def guarded(*a):
        try:
            return fn(*a)
        except RUNTIME_ERRORS as exc:
            return Err.of(exc)
    return m.oracle.outcomes(guarded, *args)


class Err:
    """A runtime error as the result of an evaluation: ``reason`` (the
    message of a stuck agent) and ``where`` (a location, when the error
    carries one, e.g. a guard)."""
    __slots__ = ("reason", "where")

    def __init__(self, reason, where=None):
        self.reason = reason
        self.where = where

    @staticmethod
    def of(exc) -> "Err":
        return Err(getattr(exc, "reason", None) or describe_error(exc), getattr(exc, "where", None))


def describe_error(exc) -> str:
    """The reason of a stuck agent for a Python exception in compiled code,
    in PCCL's terms: never Python's text (``OverflowError: int too large to
    convert to float``), which names nothing of the program.  The location
    (the statement's line) is added where the reason is shown."""
    if isinstance(exc, PcclRuntimeError):
        return str(exc)
    if isinstance(exc, ZeroDivisionError):
        return "division by zero"
    if isinstance(exc, OverflowError):
        # an int beyond a float's range met a float (x * 1.5, x / 2.5,
        # ItemPosition(x, 0)), or a float result beyond it (dist of huge positions)
        return ("arithmetic overflow: a number beyond the range of a float "
                "(about ±1.8e308)")
    if isinstance(exc, IndexError):
        return "index out of range"
    if isinstance(exc, ValueError):
        text = str(exc)
        if "integer string conversion" in text:
            return "arithmetic overflow: an integer too large to convert"
        if "math domain error" in text:
            return "arithmetic error: an argument outside the domain of the function"
        if text.startswith("rand hook returned"):     # the API's rand_policy: its own words
            return text
        return "invalid value"
    if isinstance(exc, TypeError):
        return "a value of the wrong type in an operation"
    return "runtime error"


def stuck_successor(m, st, i, ag, reason, where, kind="error"):
    """The successor in which agent i is stuck(reason, location)."""
    code = m.stuck_code(kind, reason, where)
    return put_agent(st, i, with_status(ag, code))


# ---------------------------------------------------------------------------
# Agent rules
# ---------------------------------------------------------------------------

def event_select(m, st, i, ag, head, out):
    """EVENT SELECT.

    Paper §4.4: "given an event block pre(C); eff: S Es where C is a
    condition evaluating to true, S is the list of statements in the effect
    of that event, Es is the list of events following that; this event block
    rewrites to S.  If C evaluates to false, this block rewrites to Es."

    Rule: k empty, counter + ρ(i) ≤ n0.  For each event whose guard holds,
    k := its effect ~> endEventBlock (label ``EVENT Name``); if none holds,
    k := endEventBlock (label ``IDLE``).  ``--events first`` keeps only the
    first enabled event in source order.

    Changes k (or, on a runtime error in a guard, status).
    """
    if ag[1] + m.rho[i] > m.n0:
        return
    sh, ags = st[3], st[4]
    if not m.guards_rand:
        # the common case: one outcome, without _outcomes' wrapper
        try:
            res = m.enabled_events(i, ag, sh, ags)
        except RUNTIME_ERRORS as exc:
            err = Err.of(exc)
            out.append((("EVENT SELECT", i, None), stuck_successor(m, st, i, ag, err.reason, err.where)))
            return
        if not res:
            out.append((("IDLE", i, None), put_agent(st, i, with_pc(ag, m.ctl.idle_pc))))
            return
        if m.first_only:
            res = res[:1]
        pcs = m.ctl.event_pcs
        for e in res:
            # with_pc(ag, pcs[e]), inlined
            out.append((("EVENT SELECT", i, e),
                        put_agent(st, i, (pcs[e], ag[1], ag[2], ag[3], ag[4], ag[5], ag[6],
                                          ag[7]))))
        return
    for res in _outcomes(m, m.enabled_events, True, i, ag, sh, ags):
        if isinstance(res, Err):
            out.append((("EVENT SELECT", i, None), stuck_successor(m, st, i, ag, res.reason, res.where)))
            continue
        if not res:
            out.append((("IDLE", i, None), put_agent(st, i, with_pc(ag, m.ctl.idle_pc))))
            continue
        if m.first_only:
            res = res[:1]
        for e in res:
            out.append((("EVENT SELECT", i, e), put_agent(st, i, with_pc(ag, m.ctl.event_pcs[e]))))


def _evaluate(m, fn, i, ag, st):
    """Every ``rand`` outcome of ``fn(i, ag, sh, ags)`` (a statement with rand)."""
    return _outcomes(m, fn, True, i, ag, st[3], st[4])


def statement_assign(m, st, i, ag, head, out):
    """STATEMENT (assign): an assignment, list mutator (``add``, ``remove``)
    or ``skip`` at the head of k runs in one transition, its expressions
    evaluated atomically; k moves on.  In K (imp-semantics ``[assign]``)::

        ⟨X = V ; ⇒ · ...⟩k ⟨E ⇒ E[X ← V]⟩memory

    Changes k, and the variable's cell (locals, allread or shared).  A runtime
    error makes the agent stuck(reason, location) instead.
    """
    label = ("STATEMENT", i, head.sid)
    if not head.has_rand:       # the common case: one outcome, no wrapper
        try:
            ag2, sh2 = head.fn(i, ag, st[3], st[4])
        except RUNTIME_ERRORS as exc:
            r = Err.of(exc)
            out.append((label, stuck_successor(m, st, i, ag, r.reason, head.sid)))
            return
        # with_pc(ag2, head.next_pc), inlined
        ag2 = (head.next_pc, ag2[1], ag2[2], ag2[3], ag2[4], ag2[5], ag2[6], ag2[7])
        out.append((label, put_agent(st, i, ag2, sh2)))
        return
    for r in _evaluate(m, head.fn, i, ag, st):
        if isinstance(r, Err):
            out.append((label, stuck_successor(m, st, i, ag, r.reason, head.sid)))
        else:
            ag2, sh2 = r
            ag2 = (head.next_pc, ag2[1], ag2[2], ag2[3], ag2[4], ag2[5], ag2[6], ag2[7])
            out.append((label, put_agent(st, i, ag2, sh2)))


def statement_if(m, st, i, ag, head, out):
    """STATEMENT (if): the first branch whose condition holds (else the
    ``else`` branch, possibly empty) replaces the ``if`` at the head of k, in
    one transition.  In K (``[if-true]``, ``[if-false]``)::

        ⟨if (true) S1 else S2 ⇒ S1 ...⟩k     ⟨if (false) S1 else S2 ⇒ S2 ...⟩k

    Changes k only.
    """
    label = ("STATEMENT", i, head.sid)
    if not head.has_rand:       # the common case: one outcome, no wrapper
        try:
            r = head.fn(i, ag, st[3], st[4])
        except RUNTIME_ERRORS as exc:
            r = Err.of(exc)
            out.append((label, stuck_successor(m, st, i, ag, r.reason, head.sid)))
            return
        # with_pc(ag, head.branch_pcs[r]), inlined
        out.append((label, put_agent(st, i, (head.branch_pcs[r], ag[1], ag[2], ag[3], ag[4],
                                             ag[5], ag[6], ag[7]))))
        return
    for r in _evaluate(m, head.fn, i, ag, st):
        if isinstance(r, Err):
            out.append((label, stuck_successor(m, st, i, ag, r.reason, head.sid)))
        else:
            out.append((label, put_agent(st, i, with_pc(ag, head.branch_pcs[r]))))


def statement_while(m, st, i, ag, head, out):
    """STATEMENT (while): one test per transition; if it holds, the body
    followed by the loop again replaces the head of k, else the loop is
    done.  In K (``[while]`` unrolled one test at a time)::

        ⟨while (B) S ⇒ if (B) { S while (B) S } else {} ...⟩k

    Changes k only.
    """
    try:
        res = _evaluate(m, head.fn, i, ag, st) if head.has_rand \
            else (head.fn(i, ag, st[3], st[4]),)
    except RUNTIME_ERRORS as exc:
        res = (Err.of(exc),)
    label = ("STATEMENT", i, head.sid)
    for r in res:
        if isinstance(r, Err):
            out.append((label, stuck_successor(m, st, i, ag, r.reason, head.sid)))
        else:
            out.append((label, put_agent(st, i, with_pc(ag, head.body_pc if r else head.next_pc))))


def statement_assert(m, st, i, ag, head, out):
    """STATEMENT (assert): ``assert(C)`` with C true is done; with C false
    the agent is stuck (an assertion violation)::

        ⟨assert(true) ⇒ · ...⟩k        ⟨assert(false) ...⟩k ⟨running ⇒ stuck⟩status

    Changes k, or status.
    """
    try:
        res = _evaluate(m, head.fn, i, ag, st) if head.has_rand \
            else (head.fn(i, ag, st[3], st[4]),)
    except RUNTIME_ERRORS as exc:
        res = (Err.of(exc),)
    label = ("STATEMENT", i, head.sid)
    for r in res:
        if isinstance(r, Err):
            out.append((label, stuck_successor(m, st, i, ag, r.reason, head.sid)))
        elif r:
            out.append((label, put_agent(st, i, with_pc(ag, head.next_pc))))
        else:
            out.append((label, stuck_successor(m, st, i, ag, "assertion failed", head.sid,
                                               kind="assert")))


def statement_nested_atomic(m, st, i, ag, head, out):
    """STATEMENT (nested atomic): an ``atomic`` block met while the agent
    holds the lock just runs its body (the lock is not requested again)::

        ⟨atomic: Ss ⇒ Ss ...⟩k ⟨lock⟩lockState

    Changes k only.
    """
    if ag[2] == LOCK:
        out.append((("STATEMENT", i, head.sid), put_agent(st, i, with_pc(ag, head.body_pc))))


#: STATEMENT, one function per kind of statement at the head of k.
STATEMENT_RULES = {
    K_SIMPLE: statement_assign,
    K_IF: statement_if,
    K_WHILE: statement_while,
    K_ASSERT: statement_assert,
    K_ATOMIC: statement_nested_atomic,
}


def statement(m, st, i, ag, head, out):
    """STATEMENT, whatever the kind of statement at the head of k (see
    :data:`STATEMENT_RULES`): for callers that hold a head of any kind."""
    STATEMENT_RULES[head.kind](m, st, i, ag, head, out)


def exit_rule(m, st, i, ag, head, out):
    """EXIT.

    Rule: ``exit()``: status exited, k empty.  Exited agents never block
    time.

    Changes k and status.
    """
    ag2 = (m.ctl.empty_pc, ag[1], ag[2], EXITED, ag[4], ag[5], ag[6], ag[7])
    out.append((("EXIT", i, head.sid), put_agent(st, i, ag2)))


def doreach_update(m, st, i, ag, head, out):
    """DOREACH UPDATE.

    Paper §4.6: "When a doReach statement is encountered in the program, the
    statement itself is rewritten to empty ... after rewriting the doReach to
    empty, the doReach flags should be reset (doReach_done, doReach_fail are
    both set to false), which should in turn be followed by setting the
    target of this agent, and the list of obstacles.  The setTargetObs
    function sets the values of target, obstacle, and current time."

        ⟨⟨doReach(T,O) ⇒ · ~> resetFlags(i) ~> setTargetObs(T,O,T0,i) ...⟩k ⟨i⟩id ...⟩agent ⟨T0⟩time

    Changes k and reach (target, obstacles, t0, both flags, and the leg's
    start for a blackbox that tracks legs: ``m.leg_start``).
    """
    sid = head.sid
    for res in _outcomes(m, head.fn, head.has_rand, i, ag, st[3], st[4]):
        if isinstance(res, Err):
            out.append((("DOREACH UPDATE", i, sid), stuck_successor(m, st, i, ag, res.reason, sid)))
            continue
        target, obstacles = res
        target = m.round_pos(target)      # positions are compared at the world's resolution
        t0 = st[0] if m.record_t0 else None
        ag2 = (head.next_pc, ag[1], ag[2], ag[3], ag[4], ag[5], ag[6],
               (target, obstacles, t0, False, False, m.leg_start(ag[6], ag[7])))
        out.append((("DOREACH UPDATE", i, sid), put_agent(st, i, ag2)))


def counter_advance(m, st, i, ag, head, out):
    """COUNTER ADVANCE.

    Paper §4.4: "If an endEventBlock is encountered in its k cell, there is
    nothing more to do in the current execution.  Given further, that the
    count cell value of the agent is N, the k cell is rewritten to empty.
    The counter cell is rewritten to N+1 ... This transition is enabled only
    as long as N is less than n0."

        ⟨⟨endEventBlock ⇒ ·⟩k ⟨i⟩id ⟨N ⇒ N +Int 1⟩counter⟩agent ⟨... i ↦ N ⇒ i ↦ N +Int 1 ...⟩counterMap
        requires N <Int n0

    With the rate map ρ: counter += ρ(i), enabled while counter + ρ(i) ≤ n0.

    Changes k and counter.
    """
    c = ag[1] + m.rho[i]
    if c > m.n0:
        return
    ag2 = (m.ctl.empty_pc, c, ag[2], ag[3], ag[4], ag[5], ag[6], ag[7])
    out.append((("COUNTER ADVANCE", i, None), put_agent(st, i, ag2)))


def lock_request(m, st, i, ag, head, out):
    """LOCK REQUEST.

    Paper §4.5: "The lock request transition is enabled when an agent with id
    i, encounters an atomic block containing statements Ss, when its
    lockstate is idle.  Then, the agent adds a terminal atomicEnd just after
    the atomic block ... At the same time, the agent adds itself to the end
    of the lock queue."

        ⟨⟨atomic: Ss ~> ·⇒atomicEnd ...⟩k ⟨i⟩id ⟨idle ⇒ request⟩lockState ...⟩agent ⟨... ·⇒i⟩lockQueue

    Changes k, lockState and lockQueue.
    """
    if ag[2] != IDLE:
        return
    ag2 = (head.request_pc, ag[1], REQUEST, ag[3], ag[4], ag[5], ag[6], ag[7])
    st2 = put_agent(st, i, ag2)
    st2 = (st2[0], st2[1], st2[2] + (i,), st2[3], st2[4], st2[5])
    out.append((("LOCK REQUEST", i, head.sid), st2))


def atomic_wait(m, st, i, ag, head, out):
    """ATOMIC WAIT.

    Paper §4.5: "we capture the fact that locks may not be granted
    immediately by enabling counter increment transitions when the lockState
    is request and the agent id is not at the head of the lockQueue."

        ⟨... ⟨i1⟩id ⟨request⟩lockState ⟨N ⇒ N +Int 1⟩counter ...⟩agent ⟨i2 ...⟩lockQueue
        requires i1 =/=Int i2 and N <Int n0

    Changes counter.
    """
    lq = st[2]
    if ag[2] != REQUEST or (lq and lq[0] == i):
        return
    c = ag[1] + m.rho[i]
    if c > m.n0:
        return
    ag2 = (ag[0], c, ag[2], ag[3], ag[4], ag[5], ag[6], ag[7])
    out.append((("ATOMIC WAIT", i, head.sid), put_agent(st, i, ag2)))


def atomic_execution(m, st, i, ag, head, out):
    """ATOMIC EXECUTION.

    Paper §4.5: "The agent aquires the lock when it is at the beginning of
    the lockQueue and starts processing the statements inside the atomic
    block.  The counter does not increase in this rewrite."

        ⟨⟨atomic: Ss ⇒ Ss ...⟩k ⟨i⟩id ⟨request ⇒ lock⟩lockState ...⟩agent ⟨i ...⟩lockQueue

    Changes k and lockState.
    """
    lq = st[2]
    if ag[2] != REQUEST or not lq or lq[0] != i:
        return
    ag2 = (head.body_pc, ag[1], LOCK, ag[3], ag[4], ag[5], ag[6], ag[7])
    out.append((("ATOMIC EXECUTION", i, head.sid), put_agent(st, i, ag2)))


def lock_release(m, st, i, ag, head, out):
    """LOCK RELEASE.

    Paper §4.5: "Once the atomic block has been executed, the lock must be
    released, the agent must take itself out of the lockQueue, and set its
    own lockState to idle.  The rest of the event continues to execute."

        ⟨⟨atomicEnd ⇒ · ...⟩k ⟨i⟩id ⟨lock ⇒ idle⟩lockState ...⟩agent ⟨i ⇒ · ...⟩lockQueue

    Changes k, lockState and lockQueue.
    """
    if ag[2] != LOCK:
        return
    lq = st[2]
    ag2 = (head.next_pc, ag[1], IDLE, ag[3], ag[4], ag[5], ag[6], ag[7])
    st2 = put_agent(st, i, ag2)
    lq2 = tuple(x for x in lq if x != i)
    out.append((("LOCK RELEASE", i, None), (st2[0], st2[1], lq2, st2[3], st2[4], st2[5])))


# ---------------------------------------------------------------------------
# Global rules
# ---------------------------------------------------------------------------

def time_advance_enabled(m, st):
    """TIME ADVANCE's guard without the ``--max-time`` bound: True when time
    may advance, False when it may not (whatever the bound)."""
    if st[1] != DISCRETE:
        return False
    n0, rho = m.n0, m.rho
    running = False
    for i, ag in enumerate(st[4]):
        s = ag[3]
        if s == EXITED:
            continue
        if s == RUNNING:
            running = True
        if ag[1] + rho[i] <= n0:
            return False
    return running


def time_advance(m, st, out, enabled=None):
    """TIME ADVANCE.

    Paper §4.4: "given that the current global time is T, if all the counter
    values in CM are equal to n0, the global time is rewritten to T+δ.  The
    transitionState is set to dynamic from discrete."

        ⟨CM⟩counterMap ⟨T ⇒ T +Int δ⟩time ⟨discrete ⇒ dynamic⟩transitionState
        requires n0 ==Int findMin(CM) and n0 ==Int findMax(CM)

    Rule: at least one agent running; every agent that has not exited has
    counter + ρ(i) > n0; and time + δ ≤ --max-time.  The clock holds exact
    multiples n·δ (see :meth:`pccl.model.engine.Model.next_time`).

    ``enabled``, if given, is :func:`time_advance_enabled` already computed
    by the caller (``Model.successors`` gathers it while visiting the agents).

    Changes time and transitionState.
    """
    if not (time_advance_enabled(m, st) if enabled is None else enabled):
        return
    # (time_advance_enabled ignores --max-time; terminal_kind uses it to tell
    # a bounded state from a deadlock)
    t = m.next_time(st[0])     # exact multiples of δ; None beyond --max-time
    if t is None:
        return
    out.append((("TIME ADVANCE", None, None), (t, DYNAMIC, st[2], st[3], st[4], st[5])))


def doreach_invoke(m, st, out):
    """DOREACH INVOKE.

    Paper §4.6: "Suppose the current time is T0.  The time advances by δ.  We
    then invoke the blackbox doReachBB to compute the new contents of the
    position cell of each agent at time T0 + δ, given that the position of
    the agent at time T0 was P, the target ItemPosition is T, obstacles were
    stored in O, and the time increment was δ."

        ⟨⟨i⟩id ⟨N ⇒ 0⟩counter ⟨P ⇒ P1⟩position ...⟩agent ⟨... i ↦ N ⇒ i ↦ 0 ...⟩counterMap ⟨dynamic⟩transitionState
        requires N ==Int n0 and P1 = doReachBB(P, T, O, T0, δ, i)

    Rule: the blackbox advances the world by δ for all agents at once; each
    outcome it returns is one successor: positions, flags and env updated,
    every counter := 0, transitionState := discrete.

    Changes every agent's counter, position and reach flags (and leg start),
    env and transitionState.
    """
    if st[1] != DYNAMIC:
        return
    ags = st[4]
    for k, (positions, done, fail, env, starts) in enumerate(m.environment_step(st)):
        new = tuple(
            (ag[0], 0, ag[2], ag[3], ag[4], ag[5], positions[j],
             ag[7] if (ag[7][3] == done[j] and ag[7][4] == fail[j] and ag[7][5] == starts[j])
             else (ag[7][0], ag[7][1], ag[7][2], done[j], fail[j], starts[j]))
            for j, ag in enumerate(ags))
        out.append((("DOREACH INVOKE", None, k), (st[0], DISCRETE, st[2], st[3], new, env)))


# Dispatch: k-head kind -> the agent rules that may apply to it.
AGENT_RULES = {
    K_EMPTY: (event_select,),
    K_END: (counter_advance,),
    K_AEND: (lock_release,),
    K_ACQ: (atomic_execution, atomic_wait),
    K_SIMPLE: (statement_assign,),
    K_IF: (statement_if,),
    K_WHILE: (statement_while,),
    K_ASSERT: (statement_assert,),
    K_ATOMIC: (lock_request, statement_nested_atomic),
    K_DOREACH: (doreach_update,),
    K_EXIT: (exit_rule,),
}

# The same, for an agent whose counter is spent (counter + ρ(i) > n0): EVENT
# SELECT, COUNTER ADVANCE and ATOMIC WAIT need a counter step and cannot
# apply, so Model.successors does not call them.
AGENT_RULES_SPENT = {
    kind: tuple(r for r in rules if r not in (event_select, counter_advance, atomic_wait))
    for kind, rules in AGENT_RULES.items()
}
