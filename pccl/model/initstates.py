"""The initial configurations of a model: the Init-block search.

One initial configuration per combination of ``rand`` outcomes in the
declarations and the ``Init`` block, generated lazily by a depth-first
search over *stages* (the shared initialisers once, then per agent its
declarations and its Init block run to completion); see
:meth:`InitSearch.states`.  The engine's :meth:`pccl.model.engine.Model.init_states`
is this search.
"""

from __future__ import annotations

import itertools
from typing import Optional

from pccl.model.compile import has_rand
from pccl.lang.errors import PcclError
from pccl.model.layout import (AGS, BLANK_REACH, CNT, DISCRETE, IDLE, LCK, LQ, PC, POS, REACH, RUNNING, SH,
                     STATUS, make_agent, make_state, put_agent, with_pc, with_status)
from pccl.lang.values import UNDEF
from pccl.semantics import rules as R


class InitSearch:
    """The Init-block search of model ``m`` (a :class:`pccl.model.engine.Model`:
    its compiled program, world, team, environment and rule context)."""

    #: Initial states remembered to drop duplicates early (fewer with many
    #: agents); beyond that the explorer merges them (it admits initial
    #: states by identity).
    INIT_DEDUP = 1 << 16
    #: Most steps of one path through an agent's Init block.
    INIT_LIMIT = 100_000

    def __init__(self, m, first_only=frozenset(), first_value=frozenset()):
        self.m = m
        #: ``loc:`` variables whose ``rand`` initialiser takes its first outcome only
        #: (pccl.model.dead.can_collapse_initial_rand)
        self.first_only = first_only
        #: ``loc:`` variables whose ``rand`` initialiser takes the first outcome
        #: that has a value and every outcome that fails, each reason once
        #: (pccl.model.dead.initial_rand_unread, when some outcome may fail)
        self.first_value = first_value
        #: per declaration (section, name): does its initialiser draw a ``rand()``?
        #: (has_rand walks the expression: once per declaration, not once per
        #: agent and path of the search)
        self._draws: dict = {}

    def _has_rand(self, vs) -> bool:
        d = self._draws.get((vs.section, vs.name))
        if d is None:
            d = self._draws[(vs.section, vs.name)] = has_rand(vs.decl.init)
        return d

    def states(self):
        """The initial configurations, one per combination of ``rand``
        outcomes in declarations and ``Init``, generated lazily (depth-first,
        in increasing outcome order): the product of the agents' outcomes is
        never built, so a consumer can stop after as many as it admits."""
        m = self.m
        lay, N = m.compiled.layout, m.N
        starts = m.world.start_positions(N)
        loc0 = tuple(UNDEF if v.ty.kind != "array" else (UNDEF,) * v.ty.size for v in lay.local)
        ar0 = tuple(UNDEF if v.ty.kind != "array" else (UNDEF,) * v.ty.size for v in lay.allread)
        agents = tuple(
            make_agent(m.ctl.empty_pc, 0, IDLE, RUNNING, loc0, ar0, m.round_pos(starts[i]),
                       BLANK_REACH)
            for i in range(N))
        shared0 = tuple(UNDEF if v.ty.kind != "array" else (UNDEF,) * v.ty.size for v in lay.shared)
        env0 = m.env.call(0, "init_env", m.world, N)
        m.env.check_env(env0, 0)
        # the stages: shared initialisers once (in agent 0's context), then per
        # agent its declarations and its Init block
        stages: list = [(-1, vs) for vs in lay.shared if vs.decl.init is not None]
        per_agent = [vs for vs in lay.allread + lay.local if vs.decl.init is not None]
        has_init = bool(m.program.init)
        for i in range(N):
            stages.extend((i, vs) for vs in per_agent)
            if has_init:
                stages.append((i, None))
        n = len(stages)
        seen: set = set()
        cap = min(self.INIT_DEDUP, max(16, (1 << 22) // N))   # states of N agents each
        if not n:
            yield make_state(0, DISCRETE, (), shared0, agents, env0)
            return
        # Depth-first over the stages with an explicit stack (no recursion:
        # 10,000 agents make 10,000s of stages).  Memory is linear in the
        # configuration: the path's configuration is kept in mutable form
        # (the shared variables and the locals and allread of the agents
        # whose declarations are being evaluated as lists, the agent cells as
        # a list) and a level of the stack is a generator that writes its
        # outcome there and undoes it when it moves on or is popped, so a
        # level holds one slot's value, never a copy of a tuple (one copy of
        # the locals per declaration was quadratic: 10,000 declarations took
        # 1.7 GiB).  Tuples are built once per agent (when its declarations
        # are done), per Init block and per yield.
        w = _InitPath(agents, shared0, loc0, ar0, has_init)
        stack: list = []

        def push(k):
            i, vs = stages[k]
            prev = stages[k - 1][0] if k else None
            if i >= 0 and prev != i:
                w.begin_agent(i, prev)
            if vs is None:
                stack.append(self._init_stage(w, i, env0))
            elif i < 0:
                stack.append(self._shared_decl_stage(w, vs))
            else:
                stack.append(self._decl_stage(w, i, vs))

        push(0)
        while stack:
            if next(stack[-1], None) is None:
                stack.pop()
                k = len(stack)
                i = stages[k][0]
                if i >= 0 and (k == 0 or stages[k - 1][0] != i):
                    w.end_agent(i)
                continue
            if len(stack) < n:
                push(len(stack))
                continue
            w.finish_last(stages[-1][0])
            st = make_state(0, DISCRETE, w.lq, w.sh_tuple(), tuple(w.cells), env0)
            if st in seen:
                continue
            if len(seen) < cap:
                seen.add(st)
            yield st

    def _shared_decl_stage(self, w, vs):
        """Stage: the initialiser of the shared (allwrite) variable ``vs``,
        evaluated once in agent 0's context; one outcome per ``rand``
        outcome.  A runtime error is an error of the program's initial
        configuration (no agent runs it): a :class:`PcclError` at the
        declaration (docs/decisions.md)."""
        m = self.m
        fn = m.compiled.decl_init(vs)
        oracle, j, shl, cells, blank = m.oracle, vs.slot, w.shl, w.cells, w.shared0[vs.slot]

        def guarded(*a):
            oracle.agent = 0
            try:
                return fn(*a)
            except R.RUNTIME_ERRORS as exc:
                return R.Err.of(exc)
            finally:
                oracle.agent = None
        results = (oracle.iter_outcomes(guarded, 0, cells[0], shl, cells)
                   if self._has_rand(vs) else (guarded(0, cells[0], shl, cells),))
        try:
            for res in results:
                if isinstance(res, R.Err):
                    raise PcclError(f"the initialiser of `{vs.name}` at line "
                                    f"{vs.decl.span.line}: {res.reason}",
                                    span=vs.decl.span, filename=m.program.filename,
                                    source=m.program.source)
                shl[j] = (res,) * vs.ty.size if vs.ty.kind == "array" else res
                yield True
                shl[j] = blank
        finally:
            shl[j] = blank

    def _decl_stage(self, w, i, vs):
        """Stage: agent i's declaration ``vs`` initialised, one outcome per
        ``rand`` outcome, lazily; the value is written into the agent's
        slot list (or its status set to stuck) and undone on resumption."""
        m = self.m
        if w.bases[i][STATUS] != RUNNING:
            yield True
            return
        fn = m.compiled.decl_init(vs)
        oracle, cells, sh = m.oracle, w.cells, w.sh_tuple()
        slots = w.locs[i] if vs.section == "loc" else w.ars[i]
        j = vs.slot
        blank = slots[j]
        base = w.bases[i]

        def guarded(*a):
            oracle.agent = i
            # the agent as its initialisers see it: the slot lists as its
            # locals and allread (compiled expressions only subscript them)
            cells[i] = w.view(i)      # the path may have moved on since the last outcome
            try:
                return fn(i, cells[i], sh, cells)
            except R.RUNTIME_ERRORS as exc:
                return R.Err.of(exc)
            finally:
                oracle.agent = None
        results = (oracle.iter_outcomes(guarded) if self._has_rand(vs) else (guarded(),))
        if vs.section == "loc":
            if vs.name in self.first_only:
                results = itertools.islice(results, 1)
            elif vs.name in self.first_value:
                results = _first_value(results)
        try:
            for res in results:
                if isinstance(res, R.Err):
                    code = m.stuck_code("error", res.reason, ("decl", vs.decl.span))
                    w.bases[i] = with_status(base, code)
                    yield True
                    w.bases[i] = base
                    continue
                # the value is canonical (Compiler.value); `bool f[3] = false;` fills
                slots[j] = (res,) * vs.ty.size if vs.ty.kind == "array" else res
                yield True
                slots[j] = blank
        finally:
            slots[j] = blank
            w.bases[i] = base

    def _init_stage(self, w, i, env0):
        """Stage: agent i's Init block run to completion; one outcome per
        state it can end in (lockQueue, shared and agent i's cell set)."""
        w.finish_agent(i)
        lq, sh, cell = w.lq, w.sh_tuple(), w.cells[i]
        ends = [(s[LQ], s[SH], s[AGS][i]) for s in self._init_paths(
            make_state(0, DISCRETE, lq, sh, tuple(w.cells), env0), i)]
        try:
            for w.lq, w.sh, w.cells[i] in ends:
                yield True
        finally:
            w.lq, w.sh, w.cells[i] = lq, sh, cell

    def _init_paths(self, st, i) -> list:
        """Run agent i's Init block to completion from ``st`` (not
        interleaved): the states in which it ends, in depth-first order.

        Every ``rand`` outcome is a branch; branches that reach equal states
        merge (a state is expanded again only when reached in fewer steps).
        The step limit is per path: a path longer than :attr:`INIT_LIMIT`
        steps, or one that returns to a state on itself (a loop that never
        ends), leaves the agent stuck."""
        m = self.m
        ag = st[AGS][i]
        if ag[STATUS] != RUNNING:
            return [st]
        limit = self.INIT_LIMIT
        empty = m.ctl.empty_pc
        where = ("decl", m.program.init[0].span)
        init_pc = m.ctl.intern(tuple(x.sid for x in m.program.init))
        start = put_agent(st, i, with_pc(ag, init_pc))
        done: dict = {}
        best: dict = {}
        on_path: set = set()
        stack: list = []
        oracle = m.oracle

        def enter(s, d):
            a = s[AGS][i]
            if a[STATUS] != RUNNING or a[PC] == empty:
                done[s] = None
            elif s in on_path:
                done[R.stuck_successor(m, s, i, a, "Init does not finish (it can loop forever)",
                                       where)] = None
            elif d >= limit:
                done[R.stuck_successor(m, s, i, a, f"Init does not finish within {limit:,} steps",
                                       where)] = None
            elif best.get(s, limit) > d:
                best[s] = d
                on_path.add(s)
                out: list = []
                oracle.agent = i
                head = m.ctl.info(a[PC])
                for rule in head.rules:
                    rule(m, s, i, a, head, out)
                # Init runs untimed: an atomic wait cannot happen (nobody else holds
                # the lock), unless an agent got stuck holding it in its own Init:
                # then this agent's Init can never go on (it was a configuration
                # with no initial state at all, and a clean verdict)
                if not out:
                    done[R.stuck_successor(m, s, i, a, "Init waits for the lock, which an agent "
                                           "stuck in its atomic block holds", where)] = None
                    on_path.discard(s)
                    return
                stack.append((s, d, iter(out)))

        try:
            enter(start, 0)
            while stack:
                s, d, it = stack[-1]
                nxt = next(it, None)
                if nxt is None:
                    stack.pop()
                    on_path.discard(s)
                else:
                    enter(nxt[1], d + 1)
        finally:
            oracle.agent = None
        return list(done)



def _first_value(results):
    """``results`` (values and :class:`~semantics.rules.Err`) with every
    value after the first left out, and every failure reason once: the
    outcomes of an initialiser whose value nobody reads that are different
    states (the values are one under the masking)."""
    have_value = False
    reasons: set = set()
    for res in results:
        if isinstance(res, R.Err):
            if res.reason in reasons:
                continue
            reasons.add(res.reason)
        elif have_value:
            continue
        else:
            have_value = True
        yield res


class _InitPath:
    """The configuration on the path of :meth:`InitSearch.states`'s
    depth-first search, in mutable form (see there): ``cells`` the agent
    cells; ``shl`` the shared variables while their initialisers run, then
    ``sh`` (a tuple); for an agent whose declarations are being evaluated,
    ``bases[i]`` (its cell, for the status) and ``locs[i]``/``ars[i]``
    (its locals and allread as lists); ``lq`` the lock queue."""

    def __init__(self, agents, shared0, loc0, ar0, has_init):
        self.agents, self.shared0, self.loc0, self.ar0 = agents, shared0, loc0, ar0
        self.has_init = has_init
        self.cells = list(agents)
        self.shl = list(shared0)
        self.sh: Optional[tuple] = None      # set once the shared stages are done
        self.lq: tuple = ()
        n = len(agents)
        self.bases: list = [None] * n
        self.locs: list = [None] * n
        self.ars: list = [None] * n

    def sh_tuple(self) -> tuple:
        if self.sh is None:
            return tuple(self.shl)
        return self.sh

    def begin_agent(self, i, prev) -> None:
        """The first stage of agent i is pushed (``prev``: the agent of the
        stage before, -1 for a shared one, None for none)."""
        if prev is not None and prev >= 0:
            if not self.has_init:           # else its Init stage set its cell
                self.finish_agent(prev)
        elif self.sh is None:
            self.sh = tuple(self.shl)           # the shared initialisers are done
        self.bases[i] = self.agents[i]
        self.locs[i], self.ars[i] = list(self.loc0), list(self.ar0)

    def end_agent(self, i) -> None:
        """The first stage of agent i is popped: agent i is blank again."""
        self.cells[i] = self.agents[i]
        self.bases[i] = self.locs[i] = self.ars[i] = None
        if i == 0:
            self.sh = None                      # back to the shared stages (if any)

    def view(self, i) -> tuple:
        b = self.bases[i]
        return (b[PC], b[CNT], b[LCK], b[STATUS], self.locs[i], self.ars[i], b[POS], b[REACH])

    def finish_agent(self, i) -> None:
        """Agent i's declarations are done: its cell as a tuple."""
        b = self.bases[i]
        self.cells[i] = make_agent(b[PC], b[CNT], b[LCK], b[STATUS], tuple(self.locs[i]),
                                   tuple(self.ars[i]), b[POS], b[REACH])

    def finish_last(self, i) -> None:
        """Before a yield: the last stage's agent (i) as a tuple, unless its
        Init stage set it."""
        if i >= 0 and not self.has_init:
            self.finish_agent(i)
