"""The rewrite rules of PCCL, one function per rule of the paper
(docs/language.md §11, "The rules").

Each agent rule has the signature ``rule(m, st, i, ag, info, out)``: ``m`` is
the :class:`pccl.engine.Model`, ``st`` the configuration, ``i`` the agent id,
``ag`` its agent cell, ``info`` the decoded head of its ``k`` cell (see
:class:`pccl.engine.Control`), and ``out`` a list to which the rule appends
``(label, successor)`` pairs, one per way it applies.  A rule that does not
apply appends nothing.  Global rules take ``(m, st, out)``.

Labels are ``(RULE NAME, agent, detail)``; traces print the rule name.

Configuration layout::

    state = (time, phase, lockQueue, shared, agents, env)
    agent = (pc, counter, lockState, status, locals, allread, position, reach)
    reach = (target, obstacles, t0, doReach_done, doReach_fail)
"""

from __future__ import annotations

from pccl.errors import PcclRuntimeError

# phases
DISCRETE, DYNAMIC = 0, 1
# lock states
IDLE, REQUEST, LOCK = 0, 1, 2
# agent status (>= 2: stuck, a key of Model.stuck_reasons)
RUNNING, EXITED = 0, 1

# k-cell head kinds (Control.info(pc)[0])
K_EMPTY, K_END, K_AEND, K_ACQ, K_SIMPLE, K_IF, K_WHILE, K_ATOMIC, \
    K_DOREACH, K_EXIT, K_ASSERT = range(11)

_RUNTIME_ERRORS = (PcclRuntimeError, ZeroDivisionError, OverflowError,
                   TypeError, IndexError, ValueError)


def _put(st, i, ag2, sh2=None):
    """``st`` with agent i's cell replaced by ``ag2`` (and shared by ``sh2``)."""
    ags = st[4]
    n = len(ags)
    # small teams: build the tuple directly (3-4x cheaper than slicing)
    if n == 2:
        ags = (ag2, ags[1]) if i == 0 else (ags[0], ag2)
    elif n == 3:
        ags = ((ag2, ags[1], ags[2]) if i == 0 else (ags[0], ag2, ags[2]) if i == 1
               else (ags[0], ags[1], ag2))
    else:
        ags = list(ags)      # 2x cheaper than ags[:i] + (ag2,) + ags[i + 1:]
        ags[i] = ag2
        ags = tuple(ags)
    return (st[0], st[1], st[2], st[3] if sh2 is None else sh2, ags, st[5])


def _with_pc(ag, pc):
    return (pc, ag[1], ag[2], ag[3], ag[4], ag[5], ag[6], ag[7])


def _outcomes(m, fn, has_rand, *args):
    """Evaluate ``fn(*args)``; with rand, every outcome (explore) or the
    policy's (run).  Runtime errors become :class:`_Err` results."""
    if not has_rand:
        try:
            return [fn(*args)]
        except _RUNTIME_ERRORS as exc:
            return [_Err.of(exc)]

    def guarded(*a):
        try:
            return fn(*a)
        except _RUNTIME_ERRORS as exc:
            return _Err.of(exc)
    return m.oracle.outcomes(guarded, *args)


class _Err:
    __slots__ = ("reason", "where")

    def __init__(self, reason, where=None):
        self.reason = reason
        self.where = where

    @staticmethod
    def of(exc) -> "_Err":
        return _Err(getattr(exc, "reason", None) or _describe(exc), getattr(exc, "where", None))


def _describe(exc):
    if isinstance(exc, ZeroDivisionError):
        return "division by zero"
    return f"{type(exc).__name__}: {exc}"


def _stuck(m, st, i, ag, reason, where, kind="error"):
    """The successor in which agent i is stuck(reason, location)."""
    code = m.stuck_code(kind, reason, where)
    return _put(st, i, (ag[0], ag[1], ag[2], code, ag[4], ag[5], ag[6], ag[7]))


# ---------------------------------------------------------------------------
# Agent rules
# ---------------------------------------------------------------------------

def event_select(m, st, i, ag, info, out):
    """EVENT SELECT.

    Paper §4.4: "given an event block pre(C); eff: S Es where C is a
    condition evaluating to true, S is the list of statements in the effect
    of that event, Es is the list of events following that; this event block
    rewrites to S.  If C evaluates to false, this block rewrites to Es."

    Rule: k empty, counter + ρ(i) ≤ n0.  For each event whose guard holds,
    k := its effect ~> endEventBlock (label ``EVENT Name``); if none holds,
    k := endEventBlock (label ``IDLE``).  ``--events first`` keeps only the
    first enabled event in source order.
    """
    if ag[1] + m.rho[i] > m.n0:
        return
    sh, ags = st[3], st[4]
    if m.guards_rand:
        results = _outcomes(m, m.enabled_events, True, i, ag, sh, ags)
    else:
        # the common case, without _outcomes' wrapper
        try:
            results = (m.enabled_events(i, ag, sh, ags),)
        except _RUNTIME_ERRORS as exc:
            results = (_Err.of(exc),)
    for res in results:
        if isinstance(res, _Err):
            out.append((("EVENT SELECT", i, None), _stuck(m, st, i, ag, res.reason, res.where)))
            continue
        if not res:
            out.append((("IDLE", i, None), _put(st, i, _with_pc(ag, m.ctl.idle_pc))))
            continue
        if m.first_only:
            res = res[:1]
        for e in res:
            out.append((("EVENT SELECT", i, e), _put(st, i, _with_pc(ag, m.ctl.event_pcs[e]))))


def statement(m, st, i, ag, info, out):
    """STATEMENT.

    Rule: the head of k is a statement — assignment, ``if``, ``while``
    (one test per transition), list mutator, ``assert``, ``skip`` — executed
    in one transition, its expressions evaluated atomically.  A runtime
    error sets status stuck(reason, location) instead.
    """
    kind = info[0]
    if kind == K_ATOMIC:
        if ag[2] == LOCK:
            # A nested atomic inside a held lock just runs its body.
            _, _req, nested_pc, sid = info
            out.append((("STATEMENT", i, sid), _put(st, i, _with_pc(ag, nested_pc))))
        return
    # K_SIMPLE, K_IF, K_WHILE, K_ASSERT: info = (kind, fn, ..., sid, has_rand)
    fn, sid, rnd = info[1], info[-2], info[-1]
    sh, ags = st[3], st[4]
    if rnd:
        results = _outcomes(m, fn, True, i, ag, sh, ags)
    else:
        # the common case, without _outcomes' wrapper
        try:
            results = (fn(i, ag, sh, ags),)
        except _RUNTIME_ERRORS as exc:
            results = (_Err.of(exc),)
    label = ("STATEMENT", i, sid)
    for res in results:
        if isinstance(res, _Err):
            out.append((label, _stuck(m, st, i, ag, res.reason, sid)))
        elif kind == K_SIMPLE:
            ag2, sh2 = res
            ag2 = (info[2], ag2[1], ag2[2], ag2[3], ag2[4], ag2[5], ag2[6], ag2[7])
            out.append((label, _put(st, i, ag2, sh2)))
        elif kind == K_IF:
            out.append((label, _put(st, i, _with_pc(ag, info[2][res]))))
        elif kind == K_WHILE:
            out.append((label, _put(st, i, _with_pc(ag, info[2] if res else info[3]))))
        elif res:    # K_ASSERT
            out.append((label, _put(st, i, _with_pc(ag, info[2]))))
        else:
            out.append((label, _stuck(m, st, i, ag, "assertion failed", sid, kind="assert")))


def exit_rule(m, st, i, ag, info, out):
    """EXIT.

    Rule: ``exit()``: status exited, k empty.  Exited agents never block
    time.
    """
    sid = info[1]
    ag2 = (m.ctl.empty_pc, ag[1], ag[2], EXITED, ag[4], ag[5], ag[6], ag[7])
    out.append((("EXIT", i, sid), _put(st, i, ag2)))


def doreach_update(m, st, i, ag, info, out):
    """DOREACH UPDATE.

    Paper §4.6: "When a doReach statement is encountered in the program, the
    statement itself is rewritten to empty ... after rewriting the doReach to
    empty, the doReach flags should be reset (doReach_done, doReach_fail are
    both set to false), which should in turn be followed by setting the
    target of this agent, and the list of obstacles.  The setTargetObs
    function sets the values of target, obstacle, and current time."

        ⟨⟨doReach(T,O) ⇒ · ~> resetFlags(i) ~> setTargetObs(T,O,T0,i) ...⟩k ⟨i⟩id ...⟩agent ⟨T0⟩time
    """
    _, fn, nxt, sid, rnd = info
    for res in _outcomes(m, fn, rnd, i, ag, st[3], st[4]):
        if isinstance(res, _Err):
            out.append((("DOREACH UPDATE", i, sid), _stuck(m, st, i, ag, res.reason, sid)))
            continue
        target, obstacles = res
        target = m.round_pos(target)      # positions are compared at the world's resolution
        t0 = st[0] if m.record_t0 else None
        ag2 = (nxt, ag[1], ag[2], ag[3], ag[4], ag[5], ag[6], (target, obstacles, t0, False, False))
        out.append((("DOREACH UPDATE", i, sid), _put(st, i, ag2)))


def counter_advance(m, st, i, ag, info, out):
    """COUNTER ADVANCE.

    Paper §4.4: "If an endEventBlock is encountered in its k cell, there is
    nothing more to do in the current execution.  Given further, that the
    count cell value of the agent is N, the k cell is rewritten to empty.
    The counter cell is rewritten to N+1 ... This transition is enabled only
    as long as N is less than n0."

        ⟨⟨endEventBlock ⇒ ·⟩k ⟨i⟩id ⟨N ⇒ N +Int 1⟩counter⟩agent ⟨... i ↦ N ⇒ i ↦ N +Int 1 ...⟩counterMap
        requires N <Int n0

    With the rate map ρ: counter += ρ(i), enabled while counter + ρ(i) ≤ n0.
    """
    c = ag[1] + m.rho[i]
    if c > m.n0:
        return
    ag2 = (m.ctl.empty_pc, c, ag[2], ag[3], ag[4], ag[5], ag[6], ag[7])
    out.append((("COUNTER ADVANCE", i, None), _put(st, i, ag2)))


def lock_request(m, st, i, ag, info, out):
    """LOCK REQUEST.

    Paper §4.5: "The lock request transition is enabled when an agent with id
    i, encounters an atomic block containing statements Ss, when its
    lockstate is idle.  Then, the agent adds a terminal atomicEnd just after
    the atomic block ... At the same time, the agent adds itself to the end
    of the lock queue."

        ⟨⟨atomic: Ss ~> ·⇒atomicEnd ...⟩k ⟨i⟩id ⟨idle ⇒ request⟩lockState ...⟩agent ⟨... ·⇒i⟩lockQueue
    """
    if ag[2] != IDLE:
        return
    req_pc, sid = info[1], info[3]
    ag2 = (req_pc, ag[1], REQUEST, ag[3], ag[4], ag[5], ag[6], ag[7])
    st2 = _put(st, i, ag2)
    st2 = (st2[0], st2[1], st2[2] + (i,), st2[3], st2[4], st2[5])
    out.append((("LOCK REQUEST", i, sid), st2))


def atomic_wait(m, st, i, ag, info, out):
    """ATOMIC WAIT.

    Paper §4.5: "we capture the fact that locks may not be granted
    immediately by enabling counter increment transitions when the lockState
    is request and the agent id is not at the head of the lockQueue."

        ⟨... ⟨i1⟩id ⟨request⟩lockState ⟨N ⇒ N +Int 1⟩counter ...⟩agent ⟨i2 ...⟩lockQueue
        requires i1 =/=Int i2 and N <Int n0
    """
    lq = st[2]
    if ag[2] != REQUEST or (lq and lq[0] == i):
        return
    c = ag[1] + m.rho[i]
    if c > m.n0:
        return
    ag2 = (ag[0], c, ag[2], ag[3], ag[4], ag[5], ag[6], ag[7])
    out.append((("ATOMIC WAIT", i, info[2]), _put(st, i, ag2)))


def atomic_execution(m, st, i, ag, info, out):
    """ATOMIC EXECUTION.

    Paper §4.5: "The agent aquires the lock when it is at the beginning of
    the lockQueue and starts processing the statements inside the atomic
    block.  The counter does not increase in this rewrite."

        ⟨⟨atomic: Ss ⇒ Ss ...⟩k ⟨i⟩id ⟨request ⇒ lock⟩lockState ...⟩agent ⟨i ...⟩lockQueue
    """
    lq = st[2]
    if ag[2] != REQUEST or not lq or lq[0] != i:
        return
    ag2 = (info[1], ag[1], LOCK, ag[3], ag[4], ag[5], ag[6], ag[7])
    out.append((("ATOMIC EXECUTION", i, info[2]), _put(st, i, ag2)))


def lock_release(m, st, i, ag, info, out):
    """LOCK RELEASE.

    Paper §4.5: "Once the atomic block has been executed, the lock must be
    released, the agent must take itself out of the lockQueue, and set its
    own lockState to idle.  The rest of the event continues to execute."

        ⟨⟨atomicEnd ⇒ · ...⟩k ⟨i⟩id ⟨lock ⇒ idle⟩lockState ...⟩agent ⟨i ⇒ · ...⟩lockQueue
    """
    if ag[2] != LOCK:
        return
    lq = st[2]
    ag2 = (info[1], ag[1], IDLE, ag[3], ag[4], ag[5], ag[6], ag[7])
    st2 = _put(st, i, ag2)
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
    multiples n·δ (see :meth:`pccl.engine.Model.next_time`).

    ``enabled``, if given, is :func:`time_advance_enabled` already computed
    by the caller (``Model.successors`` gathers it while visiting the agents).
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
    """
    if st[1] != DYNAMIC:
        return
    ags = st[4]
    for k, (positions, done, fail, env) in enumerate(m.environment_step(st)):
        new = tuple(
            (ag[0], 0, ag[2], ag[3], ag[4], ag[5], positions[j],
             ag[7] if (ag[7][3] == done[j] and ag[7][4] == fail[j])
             else (ag[7][0], ag[7][1], ag[7][2], done[j], fail[j]))
            for j, ag in enumerate(ags))
        out.append((("DOREACH INVOKE", None, k), (st[0], DISCRETE, st[2], st[3], new, env)))


# Dispatch: k-head kind -> the agent rules that may apply to it.
AGENT_RULES = {
    K_EMPTY: (event_select,),
    K_END: (counter_advance,),
    K_AEND: (lock_release,),
    K_ACQ: (atomic_execution, atomic_wait),
    K_SIMPLE: (statement,),
    K_IF: (statement,),
    K_WHILE: (statement,),
    K_ASSERT: (statement,),
    K_ATOMIC: (lock_request, statement),
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
