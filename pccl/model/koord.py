"""Koord's round semantics (spec section 14; docs/koord.md, "Semantics"):
``semantics="koord"``, the default for Koord programs, as a mode of the
model.

:class:`KoordModel` is a :class:`~pccl.model.engine.Model` with the same
program, compiled code, initial states, properties and blackbox; only its
transitions differ.  A round of δ is:

* **EventTrans** — each running robot that has not acted in this round
  performs one event as *one* transition: among the events whose guard
  holds (``--events any``: each of them; ``--events first``: the first in
  source order), the whole effect runs to its end (PCCL's statement rules
  applied to that robot alone, inside the transition).  No event enabled:
  **IDLE**.  With ``skip_events`` (Koord's **SkipEvent**) a robot with an
  enabled event may also do nothing this round.  Robots act in any order;
  each acts at most once per round (its counter becomes 1).
* **Round-consistent shared memory** — a robot reads the values its copy
  had at the round's start: the ``allwrite`` variables and the other
  robots' ``allread`` components as they were when the round began, even
  if another robot wrote them earlier in this round.  A write updates the
  global store (what properties read) and the writer's copy; the other
  copies are refreshed at the round's end.  A variable is written by an
  assignment to it (or to a part of it) or a list mutator on it that the
  event executed, whatever the value: the last writer in the round wins.
* **atomic: as a per-round mutex** — the first robot in a round whose
  event enters an ``atomic:`` block holds the round's mutex (the
  ``lockQueue`` cell holds it); a later robot of the same round whose event
  would enter one does not perform it (**ATOMIC WAIT**: nothing of the event
  happens, its turn is spent) and retries next round.
* **End of the round** — when every robot that has not exited has acted,
  TIME ADVANCE (Koord's EndProgTrans: the copies are refreshed, the mutex
  freed) and the environment's step DOREACH INVOKE (EnvTrans), as under
  PCCL's semantics.

A configuration carries one more cell, ``round`` (:data:`RND`): None when
every copy equals the global store, else ``(shared, allread)``, the values
of the round's start (the shared slots, and each robot's allread tuple)
that the robots still to act read.

Symmetry and dead variables are argued again for this semantics and used
(docs/koord.md, "Reductions under the round semantics");
merging, partial-order reduction and counter saturation are argued for
PCCL's statement-level interleaving and are not, and the native engine
does not run it (pccl/model/reduce.py, pccl/model/native.py say so in the
header).
"""

from __future__ import annotations

from typing import Optional

from pccl.lang import ast as A
from pccl.model.engine import Model
from pccl.model.layout import (AGS, AR, CNT, DISCRETE, ENV, EXITED, IDLE, LCK, LQ, N_STATE_CELLS,
                               PC, PHASE, RUNNING, SH, STATUS, TIME)
from pccl.model.options import CommonOptions, resolve_semantics
from pccl.semantics import rules as R

__all__ = ["KoordModel", "RND", "model_for", "shared_writes"]

#: The round cell (under Koord's semantics only): None, or the round's
#: start values ``(shared, allread per robot)``.
RND = N_STATE_CELLS



#: the rules whose label's detail is the statement they run (coverage)
_SID_RULES = frozenset({"STATEMENT", "EXIT", "DOREACH UPDATE", "LOCK REQUEST", "ATOMIC EXECUTION"})


def model_for(program: A.Program, opts: CommonOptions) -> Model:
    """The model of ``program`` under ``opts``: a :class:`KoordModel` when
    its semantics (:func:`pccl.model.options.resolve_semantics`) is Koord's,
    else the PCCL :class:`~pccl.model.engine.Model`."""
    if resolve_semantics(program.language, opts) == "koord":
        return KoordModel(program, opts)
    return Model(program, opts)


def _root(e) -> Optional[str]:
    """The variable an assignment target or list argument is part of."""
    while True:
        if isinstance(e, A.Name):
            return e.name
        if isinstance(e, (A.Index, A.Field)):
            e = e.base
            continue
        return None


def shared_writes(compiled) -> dict:
    """sid -> the shared (allwrite) slots the statement writes when it runs:
    an assignment to the variable or a part of it, ``add``/``remove`` on
    it.  (Allread writes go to the writer's own cell.)"""
    shared = {v.name: v.slot for v in compiled.layout.shared}
    out: dict = {}
    for sid, s in compiled.stmts.items():
        root = None
        if isinstance(s, A.Assign):
            root = _root(s.target)
        elif isinstance(s, A.CallStmt) and s.name in ("add", "remove") and s.args:
            root = _root(s.args[0])
        if root in shared:
            out[sid] = (shared[root],)
    return out


class KoordModel(Model):
    """A Koord program under Koord's round semantics (module docstring):
    the model's interface, with the transitions EventTrans, SkipEvent,
    IDLE, ATOMIC WAIT, TIME ADVANCE and DOREACH INVOKE, and the round
    cell in every configuration."""

    semantics = "koord"
    #: most rule applications one event may take (a loop in an event must
    #: end: an event is one transition); beyond, the robot is stuck
    EVENT_STEPS = 10_000
    #: most turns remembered (:meth:`_robot_turn`); the table is emptied when
    #: full; 0: no table, every turn computed afresh
    TURN_CACHE = 100_000

    def __init__(self, program: A.Program, options: Optional[CommonOptions] = None):
        super().__init__(program, options)
        self.skip_events = bool(getattr(self.options, "skip_events", False))
        self.writes = shared_writes(self.compiled)
        #: what a robot's turn reads -> the ways it ends (:meth:`_robot_turn`):
        #: in a round, every order of the robots runs its event from one view
        self._turns: dict = {}
        from pccl.model.compile import program_moves
        self._turn_reads_clock = self.record_t0 and program_moves(program)
        self.plain_successors = self.successors
        #: with :meth:`record_statements`: per successor of the last call of
        #: :meth:`successors`, the statement ids its event ran (coverage)
        self.statements_ran: Optional[list] = None

    def record_statements(self) -> None:
        """From now on, :meth:`successors` leaves in :attr:`statements_ran`
        the statements each successor's event ran inside its one transition
        (``explore --coverage``: pccl/output/coverage.py)."""
        self.statements_ran = []
        self._turns.clear()

    # -- the transition system ----------------------------------------------------------
    def init_states(self, first_only=frozenset(), first_value=frozenset()):
        """PCCL's initial states (declarations and ``init:``), each with an
        empty round cell."""
        for st in super().init_states(first_only, first_value):
            yield st + (None,)

    def successors(self, st) -> list:
        out: list = []
        ran = self.statements_ran
        if ran is not None:
            ran.clear()
        if st[PHASE] != DISCRETE:
            tmp: list = []
            R.doreach_invoke(self, st[:RND], tmp)
            if ran is not None:
                ran.extend(() for _ in tmp)
            return [(lab, s2 + (None,)) for lab, s2 in tmp]
        running = blocked = False
        for i, ag in enumerate(st[AGS]):
            s = ag[STATUS]
            if s == RUNNING:
                running = True
                if ag[CNT] == 0:
                    blocked = True
                    self._robot_turn(st, i, ag, out)
            elif s != EXITED and ag[CNT] == 0:
                blocked = True       # a stuck robot blocks the clock, as under PCCL
        if running and not blocked:
            tmp = []
            # EndProgTrans: the copies are refreshed (round cell None), the mutex freed
            R.time_advance(self, st[:LQ] + ((),) + st[SH:RND], tmp, True)
            out.extend((lab, s2 + (None,)) for lab, s2 in tmp)
            if ran is not None:
                ran.extend(() for _ in tmp)
        return out

    def _round_start_view(self, st, i) -> tuple:
        """The configuration robot ``i`` runs its event in: the shared
        values and the other robots' allread values of the round's start,
        an empty lock queue."""
        rnd = st[RND]
        ags = st[AGS]
        if rnd is None:
            return (st[TIME], DISCRETE, (), st[SH], ags, st[ENV])
        sh0, ar0 = rnd
        vags = tuple(ag if j == i else ag[:AR] + (ar0[j],) + ag[AR + 1:]
                     for j, ag in enumerate(ags))
        return (st[TIME], DISCRETE, (), sh0, vags, st[ENV])

    def _robot_turn(self, st, i, ag, out) -> None:
        """Robot ``i``'s transitions in this round: EventTrans for each way
        an enabled event runs to its end (or IDLE), ATOMIC WAIT when the
        round's mutex is taken, SkipEvent."""
        seen: dict = {}
        ran = self.statements_ran
        enabled = False
        view = self._round_start_view(st, i)
        key = self._turn_key(i, ag, view)
        cache = self._turns
        turns = cache.get(key) if self.TURN_CACHE else None
        if turns is None:
            turns = [(first, sids, atom, fin[AGS][i], fin[SH], stmts)
                     for first, sids, atom, fin, stmts in self._run_turn(view, i)]
            # a run samples rand afresh each time; TURN_CACHE 0: no table
            # (the differential oracle's truth computes every turn afresh)
            if self.oracle.policy is None and self.TURN_CACHE:
                if len(cache) >= self.TURN_CACHE:
                    cache.clear()
                cache[key] = turns
        for first, sids, atom, fag, fsh, stmts in turns:
            rule, _, e = first
            if rule == "EVENT SELECT" and e is not None:
                enabled = True
            if atom is not None and st[LQ] and st[LQ][0] != i:
                lab = ("ATOMIC WAIT", i, atom)
                succ = self._spend_turn(st, i, ag)
                stmts = ()          # nothing of the event happens
            else:
                lab = ("IDLE", i, None) if rule == "IDLE" else ("EVENT TRANS", i, e)
                succ = self._commit(st, i, sids, atom, fag, fsh)
            k = seen.get((lab, succ))
            if k is None:
                seen[(lab, succ)] = len(out)
                out.append((lab, succ))
                if ran is not None:
                    ran.append(stmts)
            elif ran is not None and stmts:
                # two ways to one successor (rand): the statements of both
                ran[k] = tuple(dict.fromkeys(ran[k] + stmts))
        if enabled and self.skip_events:
            out.append((("SKIP EVENT", i, None), self._spend_turn(st, i, ag)))
            if ran is not None:
                ran.append(())

    def _turn_key(self, i, ag, view) -> tuple:
        """What robot ``i``'s turn from ``view`` can read, the key of the
        turn table: its own cell, the shared values and the allread entries
        it sees (compiled code reads no other cell of another robot), and
        the clock when doReach records it."""
        return (i, ag, view[SH], tuple(a[AR] for a in view[AGS]),
                view[TIME] if self._turn_reads_clock else None)

    @staticmethod
    def _spend_turn(st, i, ag) -> tuple:
        """``st`` with robot ``i``'s turn in this round spent, nothing done."""
        ag2 = ag[:CNT] + (1,) + ag[CNT + 1:]
        ags = st[AGS][:i] + (ag2,) + st[AGS][i + 1:]
        return st[:AGS] + (ags,) + st[AGS + 1:]

    def _run_turn(self, view, i) -> list:
        """Every way robot ``i``'s turn ends, its rules applied to it alone
        from ``view`` until none applies (the counter advanced, exited or
        stuck): ``[(first label, sids run, sid of the first atomic entered
        or None, final configuration)]``."""
        infos, info_of, oracle = self.ctl.infos, self.ctl.info, self.oracle
        record = self.statements_ran is not None
        done: list = []
        stack: list = [(view, None, (), None, 0, ())]
        while stack:
            st, first, sids, atom, n, stmts = stack.pop()
            ag = st[AGS][i]
            if ag[STATUS] != RUNNING:
                done.append((first, sids, atom, st, stmts))
                continue
            info = infos[ag[PC]]
            if info is None:
                info = info_of(ag[PC])
            out: list = []
            oracle.agent = i
            for rule in (info.rules if ag[CNT] == 0 else info.rules_spent):
                rule(self, st, i, ag, info, out)
            if not out:
                done.append((first, sids, atom, st, stmts))
                continue
            if n >= self.EVENT_STEPS:
                where = info.sid if info.sid is not None else None
                reason = (f"its event did not end within {self.EVENT_STEPS:,} steps (under "
                          "Koord's semantics an event is one transition: a loop in it must end)")
                done.append((first, sids, atom, R.stuck_successor(self, st, i, ag, reason, where),
                             stmts))
                continue
            for lab, st2 in out:
                rule, _, detail = lab
                f2 = first if first is not None else lab
                a2 = detail if atom is None and rule == "LOCK REQUEST" else atom
                s2 = sids + (detail,) if rule == "STATEMENT" else sids
                r2 = stmts + (detail,) if record and rule in _SID_RULES and detail is not None \
                    else stmts
                stack.append((st2, f2, s2, a2, n + 1, r2))
        return done

    def _commit(self, st, i, sids, atom, ag2, fsh) -> tuple:
        """The configuration after robot ``i``'s event ended with its cell
        ``ag2`` and the shared values ``fsh`` of its round-start view: the
        shared slots its statements wrote from ``fsh``, the others from the
        global store; the round's mutex held if it entered ``atomic:``; the
        round cell."""
        if ag2[LCK] != IDLE:
            ag2 = ag2[:LCK] + (IDLE,) + ag2[LCK + 1:]
        ags = st[AGS]
        ags2 = ags[:i] + (ag2,) + ags[i + 1:]
        sh = st[SH]
        written = {slot for sid in sids for slot in self.writes.get(sid, ())}
        if written:
            new = fsh
            sh2 = tuple(new[k] if k in written else v for k, v in enumerate(sh))
        else:
            sh2 = sh
        rnd = st[RND]
        if rnd is None and (sh2 != sh or ag2[AR] != ags[i][AR] or written):
            rnd = (sh, tuple(a[AR] for a in ags))
        if rnd is not None and rnd == (sh2, tuple(a[AR] for a in ags2)):
            rnd = None
        lq = (i,) if atom is not None else st[LQ]
        return (st[TIME], DISCRETE, lq, sh2, ags2, st[ENV], rnd)
