"""State-space reductions behind the explorer's ``Model`` protocol.

Four reductions (:data:`ALL`), each either a different ``successors`` or a
different ``key`` (docs/reductions.md has the soundness arguments):

``merge``
    statement merging (SPIN's statement merging, Lipton reduction): after a
    transition of agent i, the statements that follow and touch only i's own
    ``loc:`` variables that no property reads (and i's COUNTER ADVANCE) run in
    the same transition.  :meth:`Merger.successors` wraps the unreduced
    successors; a merged transition's label is ``(rule, i, detail, idx0,
    choices)`` and :meth:`Merger.expand` re-executes it step by step.

``symmetry``
    agents are interchangeable: :func:`make_symmetric_key` returns a
    canonical representative of a state's orbit under permutations of the
    agent ids (cells sorted, id-valued data renamed).  Successors are still
    computed from the actual state, so replay yields real states.

``por``
    partial-order reduction with ample sets (:class:`Por`; :class:`UnionPor`
    with symmetry).

``dead``
    dead variables: values no future step can read leave the key
    (:mod:`pccl.model.dead`).

:func:`plan` decides which reductions are sound for a model and why the
others are off.
"""

from __future__ import annotations

import functools
import itertools
import marshal
import types
from dataclasses import dataclass, field
from typing import Any, Optional
from collections.abc import Callable

from pccl.lang import ast as A
from pccl.lang.errors import PcclError, Spelling, keyword_spelling, spell
from pccl.semantics import rules as R
from pccl.lang.scalarset import IdTypes, is_own_id, is_sentinel
from pccl.model.layout import (AGS, AR, CNT, DISCRETE, ENV, LCK, LOC, LOCK, LQ, N_STATE_CELLS, PC, PHASE, POS,
                               REACH, RUNNING, SH, STATUS, TIME)
from pccl.semantics.rules import K_EMPTY, K_END, K_IF, K_SIMPLE, K_WHILE
from pccl.model.independence import (ACCESS, EXECUTE, LOCAL, NEVER, PURE_CALLS, RELEASE, REQUEST_LOCK,
                                      Independence, may_wait, property_names)

#: The reductions, in the order they are reported.
ALL = ("merge", "symmetry", "por", "dead", "counters")

#: At most this many statements run in one merged transition.
MERGE_LIMIT = 1000



def blackbox_treats_robots_alike(bb) -> bool:
    """Symmetry's condition on the blackbox: ``bb`` declares (as its own
    class's capability, :func:`pccl.blackboxes.base.declared_capabilities`)
    that robots are interchangeable and that a robot without a target (or
    done, or failed) stays where it is (``robots_alike`` and
    ``settled_robots_hold_still`` of :class:`pccl.blackboxes.base.Capabilities`);
    its name plays no part."""
    from pccl.blackboxes.base import declared_capabilities
    if bb is None:
        return False
    caps = declared_capabilities(bb)
    return caps.robots_alike and caps.settled_robots_hold_still


@dataclass
class Plan:
    """Which reductions are on, and why the others are off."""
    on: tuple = ()
    off: dict = field(default_factory=dict)      # name -> reason
    requested: str = "auto"
    #: under symmetry, the agents kept in place (0 or 1): 1 when the
    #: temporal properties quantified by ``forall i:`` are checked for
    #: i = 0 alone (:func:`orbit_problem`), on the quotient by the
    #: renamings that fix agent 0
    fixed: int = 0

    def describe(self, spelling: Optional[Spelling] = None) -> str:
        """``merge+symmetry`` / ``none``, then ``; X off: reason``; the
        options the reasons name spelt by ``spelling`` (the API's keywords
        by default)."""
        text = "+".join(self.on) if self.on else "none"
        if self.fixed:
            text += ("; symmetry keeps agent 0 in place: each `forall i:` temporal property "
                     "is checked for i = 0 (the orbit argument)")
        by_reason: dict = {}
        for name, why in self.off_reasons(spelling).items():
            by_reason.setdefault(why, []).append(name)
        for why, names in by_reason.items():
            text += f"; {', '.join(names)} off: {why}"
        return text

    def off_reasons(self, spelling: Optional[Spelling] = None) -> dict:
        """``off`` with the options its reasons name (placeholders such as
        ``{collisions}``) spelt by ``spelling`` (default: the API's keywords;
        the properties a reason quotes are in backticks, left alone)."""
        return {name: spell(why, spelling or keyword_spelling) for name, why in self.off.items()}

    def as_dict(self, spelling: Optional[Spelling] = None) -> dict:
        out = {"requested": self.requested, "on": list(self.on), "off": self.off_reasons(spelling)}
        if self.fixed:
            out["fixed_agents"] = list(range(self.fixed))
        return out


def parse_request(reduce) -> Optional[tuple]:
    """``"auto"`` -> None (every sound one), ``"none"`` -> (), a list or
    ``"merge,symmetry"`` -> that tuple; unknown names are errors."""
    if reduce is None or reduce == "auto":
        return None
    if reduce == "none":
        return ()
    if isinstance(reduce, str):
        names = [x.strip() for x in reduce.split(",") if x.strip()]
    else:
        names = list(reduce)
    bad = [n for n in names if n not in ALL]
    if bad or not names:
        raise PcclError(f"unknown reduction {', '.join(map(repr, bad)) or repr(reduce)}; "
                        f"use auto, none or a comma-separated list of {', '.join(ALL)}",
                        filename="{reduce}")
    return tuple(n for n in ALL if n in names)


# ---------------------------------------------------------------------------
# static information
# ---------------------------------------------------------------------------

def _expr_is_local(e, lay, visible: set, funcs: set) -> bool:
    """Whether the node ``e`` (of a statement's expression) reads only the
    agent's own invisible ``loc:`` variables, members and pure calls."""
    if isinstance(e, A.Name):
        vs = lay.vars.get(e.name)
        if vs is None:
            return e.name in lay.members
        return vs.section == "loc" and e.name not in visible
    if isinstance(e, A.Call):
        return e.name in PURE_CALLS or (e.name in funcs and not e.args)
    return not isinstance(e, A.Quant)


def mergeable_sids(m) -> set:
    """Statements that touch only the agent's own invisible ``loc:`` variables."""
    lay = m.compiled.layout
    visible = property_names(m)
    funcs = set(m.compiled.functions)
    ok = set()
    for sid, s in m.compiled.stmts.items():
        if not isinstance(s, (A.Assign, A.If, A.While, A.Skip, A.CallStmt)):
            continue
        if isinstance(s, A.CallStmt) and s.name not in ("add", "remove"):
            continue
        if all(_expr_is_local(e, lay, visible, funcs) for x in A.own_exprs(s) for e in A.walk_expr(x)):
            ok.add(sid)
    return ok


def positions_read(m) -> Optional[str]:
    """Why positions (and the doReach cell) matter, or None."""
    if m.collisions:
        return "{collisions}"
    for s in m.compiled.stmts.values():
        if isinstance(s, A.CallStmt) and s.name == "doReach":
            return f"doReach at line {s.span.line}"
    exprs = [d.init for d in m.program.decls if isinstance(d, A.VarDecl) and d.init is not None]
    exprs += [x for s in m.compiled.stmts.values() for x in A.own_exprs(s)]
    exprs += [ev.guard for ev in m.program.events]
    for x in exprs:
        for e in A.walk_expr(x):
            if isinstance(e, A.Call) and e.name == "getPosition":
                return f"getPosition() at line {e.span.line}"
            if isinstance(e, A.Name) and e.name in ("doReach_done", "doReach_fail"):
                return f"{e.name} at line {e.span.line}"
    for p in list(m.properties) + list(getattr(m, "temporal", ())):
        for e in A.walk_expr(p.expr):
            if isinstance(e, A.Name) and e.name in ("pos", "doReach_done", "doReach_fail"):
                return f"{e.name} in property `{p.text}`"
    return None


def symmetry_problem(m, pointed: bool = False) -> tuple:
    """(reason symmetry is unsound or None, id slots).  ``pointed``: the
    temporal properties quantified by one ``forall i:`` are read as written
    (``i`` an id), not as their instances (``wait[0]`` names agent 0): the
    condition of the quotient that keeps agent 0 in place
    (:func:`orbit_problem`)."""
    if m.N < 2:
        return "one agent", None
    if len(set(m.rho)) > 1:
        return "agents have different rates", None
    bb = getattr(m.blackbox, "name", None)
    if not blackbox_treats_robots_alike(m.blackbox):
        return f"blackbox {bb} may treat agents differently", None
    # positions, targets and reach flags move with their agent under the
    # permutation (issue 23): the built-in blackboxes treat robots alike and
    # keep no per-robot env; when nothing reads positions they leave the key
    motion = positions_read(m) is not None
    if motion and m.blackbox.init_env(m.world, m.N) is not None:
        return f"blackbox {bb} keeps an environment state that is not permuted", None
    info = IdTypes(m.compiled.layout, m.program, m.compiled.stmts.values(),
                   [(p.expr, p.text) for p in m.properties] + _temporal_exprs(m, pointed))
    if info.reason:
        return info.reason, None
    lay = m.compiled.layout
    slots = ([vs.slot for vs in lay.local if vs.name in info.ids],
             [vs.slot for vs in lay.allread if vs.name in info.ids],
             [vs.slot for vs in lay.shared if vs.name in info.ids])
    # per-agent id variables that only ever hold the agent's own id (or a
    # sentinel) need no renaming: the fast canonical form applies
    self_only = all(all(is_sentinel(e) or is_own_id(e) for e in info.defs.get(vs.name, ()))
                    for vs in lay.local + lay.allread if vs.name in info.ids)
    return None, slots + (self_only, motion)


def _temporal_exprs(m, pointed: bool) -> list:
    """The temporal properties' expressions as the symmetry analysis reads
    them: each instance's, or (``pointed``) each ``forall i:`` family once,
    as written."""
    out: list = []
    seen: set = set()
    for p in getattr(m, "temporal", ()):
        if pointed and p.quantified is not None:
            if id(p.quantified) not in seen:
                seen.add(id(p.quantified))
                out.append((p.quantified, p.text))
        else:
            out.append((p.expr, p.text))
    return out


#: Initial states checked one by one for :func:`orbit_problem` (beyond, the
#: orbit argument is not used: the instances are checked as before).
ORBIT_INIT_LIMIT = 20_000


def orbit_problem(m, slots) -> Optional[str]:
    """Why the temporal properties quantified by ``forall i:`` cannot be
    checked for i = 0 alone (the orbit argument, docs/reductions.md
    "Per-agent temporal properties"), or None.  Called with ``slots`` of
    :func:`symmetry_problem` ``(m, pointed=True)`` (the transition relation
    and every property, ``i`` an id, are invariant under renaming agents);
    what remains is that the set of initial states is closed under renaming
    agents.  It is when no position is in the key, each agent's id
    variables hold only its own id or a sentinel (``self_only``) and the
    Init blocks write only their agent's ``loc:`` variables and take no lock
    (:func:`init_is_private`): each agent's initial cell is then drawn by
    the same initialisers, which read only its own id (as an id) and the
    shared values, so renaming an initial state gives an initial state.  Otherwise (robots that start at
    given places, ids of other agents) the initial states are renamed by
    every transposition (0 j), which generate all renamings, and looked up
    (at most :data:`ORBIT_INIT_LIMIT` of them)."""
    if getattr(m, "semantics", "pccl") != "pccl":
        return "the orbit argument is not made for Koord's round semantics"
    loc_s, ar_s, sh_s, self_only, motion = slots
    if self_only and not motion and init_is_private(m):
        return None
    inits: set = set()
    for st in m.init_states():
        if len(inits) >= ORBIT_INIT_LIMIT:
            return (f"more than {ORBIT_INIT_LIMIT:,} initial states to check for the orbit "
                    "argument of `forall i:`")
        inits.add(m.plain_key(st))
    for st in m.init_states():
        for j in range(1, m.N):
            t = rename_state(st, swap(m.N, 0, j), slots)
            if m.plain_key(t) not in inits:
                return (f"the initial states are not symmetric (renaming agents 0 and {j} "
                        "gives a state that is not initial): `forall i:` is checked per agent")
    return None


def init_is_private(m) -> bool:
    """Whether the agents' ``Init`` blocks, which run one after the other in
    the order of the agents' ids, can only make initial states that do not
    depend on that order: they write only the agent's own ``loc:`` variables
    (no shared or allread variable, which a later agent's Init could read
    or overwrite: ``Init: owner = getAgentIndex();`` leaves the last id in
    ``owner``) and take no lock (an agent stuck in its Init holding the lock
    makes every later agent's Init wait)."""
    from pccl.lang import ast as A
    own = {vs.name for vs in m.compiled.layout.local}
    for st in A.walk_stmts(m.program.init):
        if isinstance(st, A.Atomic):
            return False
        if isinstance(st, A.Assign):
            root = A.index_chain(st.target)[0]
            if not (isinstance(root, A.Name) and root.name in own):
                return False
        if isinstance(st, A.CallStmt) and st.name in ("add", "remove"):
            root = A.index_chain(st.args[0])[0] if st.args else None
            if not (isinstance(root, A.Name) and root.name in own):
                return False
    return True


def swap(n: int, a: int, b: int) -> list:
    """The renaming (old id -> new id) that exchanges agents ``a`` and ``b``."""
    r = list(range(n))
    r[a], r[b] = b, a
    return r


def rename_state(st, r: list, slots) -> tuple:
    """The configuration ``st`` with its agents renamed by ``r`` (old id ->
    new id): agent i's whole cell (position and reach included) becomes
    agent r[i]'s, and every id-valued datum (``slots`` of
    :func:`symmetry_problem`: loc:, allread and shared id variables; the
    lock queue) is renamed.  Where no position is in the key (nothing moves
    or reads one) the positions and reach cells stay in place.  Under the
    conditions of symmetry, s -> t is a transition iff rename(s) ->
    rename(t) is (docs/reductions.md)."""
    loc_s, ar_s, sh_s, motion = slots[0], slots[1], slots[2], slots[4]
    ags = st[AGS]
    cells: list = [None] * len(ags)
    for i, a in enumerate(ags):
        if loc_s or ar_s:
            a = (a[:LOC] + (_rename_ids(a[LOC], loc_s, r), _rename_ids(a[AR], ar_s, r))
                 + a[AR + 1:])
        if not motion:
            # positions nothing reads, which never change, stay where they
            # are (the renamed initial state is an initial state)
            a = a[:POS] + ags[r[i]][POS:]
        cells[r[i]] = a
    sh = _rename_ids(st[SH], sh_s, r) if sh_s else st[SH]
    out = list(st)
    out[LQ] = tuple(r[x] for x in st[LQ])
    out[SH] = sh
    out[AGS] = tuple(cells)
    return tuple(out)


#: Uses of a search that some reductions cannot serve: use -> {reduction:
#: reason}.  A use is named by the caller of :func:`plan` (``--coverage``;
#: a property kind such as ``"liveness"`` can be added here with the
#: reductions that are unsound for it).
USE_LIMITS: dict = {
    "coverage": {name: "{coverage} counts the unreduced transitions" for name in ALL},
}


def use_limits(uses) -> dict:
    """{reduction: reason} of the reductions that ``uses`` rule out (the
    first reason given wins)."""
    out: dict = {}
    for u in uses or ():
        for name, why in USE_LIMITS.get(u, {}).items():
            out.setdefault(name, why)
    return out


def _needs_two(name: str) -> PcclError:
    """Asked for by name, a reduction that has nothing to reduce with one
    agent is an error, not a silent no-op (as an unsound one is)."""
    return PcclError(f"{name} reduction needs two or more agents (the team has one); "
                     "drop it from {reduce}", filename="{reduce}", template=True)


def _plan_symmetry(m, want, p: "Plan", on: list):
    """Step of :func:`plan`: turn symmetry on (returning its slots) if it is
    sound, else say why it is off, or raise if it was asked for."""
    # with a liveness property too (issue 46): the properties are symmetric
    # (symmetry_problem reads them), a fair accepting component of the
    # quotient stands for a fair cycle of real states, which the analysis
    # finds for the lasso (pccl/search/lift.py; docs/reductions.md)
    why, slots = symmetry_problem(m)
    if why is not None and m.N >= 2 and getattr(m, "semantics", "pccl") == "pccl" \
            and any(t.quantified is not None for t in m.temporal):
        # the instances of `forall i:` name their agents: symmetry keeping
        # agent 0 in place, instance 0 alone checked (the orbit argument)
        why2, slots2 = symmetry_problem(m, pointed=True)
        if why2 is None:
            why3 = orbit_problem(m, slots2)
            if why3 is None:
                on.append("symmetry")
                p.fixed = 1
                return slots2
            why = why3
    if why is None:
        on.append("symmetry")
    elif want is not None and m.N < 2:
        raise _needs_two("symmetry")
    elif want is not None:
        raise PcclError(f"symmetry reduction is unsound here: {why}; drop it from {{reduce}}",
                        filename="{reduce}", template=True)
    elif m.N >= 2:
        p.off["symmetry"] = why
    return slots


def _plan_por(m, want, p: "Plan", on: list) -> None:
    """Step of :func:`plan`: turn partial-order reduction on if it is sound,
    else say why it is off, or raise if it was asked for."""
    # with temporal properties too (issue 46): every cycle of the reduced
    # graph passes a fully expanded state (the source of its TIME ADVANCE),
    # the cycle proviso under which the reduced graph is stuttering
    # equivalent to the rules' for the properties' variables, the phase and
    # (under fair arrival, Independence.doreach_visible) the robots under
    # way (docs/reductions.md)
    if m.N >= 2:
        on.append("por")
    elif want is not None:
        raise _needs_two("por")


def _plan_dead(m, want, p: "Plan", on: list) -> None:
    """Step of :func:`plan`: turn the dead-variable reduction on, under
    ``auto`` only where something can be dead (elsewhere it is not "off"
    for a reason: there is nothing for it to do).  With a liveness property
    too (issue 46): a cycle of the quotient closes only up to dead values,
    so the lasso is rebuilt over real states (pccl/search/lift.py;
    docs/reductions.md)."""
    from pccl.model.dead import can_be_dead
    if want is not None or can_be_dead(m):
        on.append("dead")


def _plan_counters(m, want, p: "Plan", on: list) -> None:
    """Step of :func:`plan`: turn counter saturation on where it is sound
    (:func:`pccl.model.counters.temporal_problem`; each counter's condition
    is :func:`pccl.model.counters.counter_problem`), under ``auto`` only
    where some counter can exceed its cap (elsewhere there is nothing to
    merge: not "off" for a reason)."""
    from pccl.model.counters import can_saturate, temporal_problem
    why = temporal_problem(m)
    if why is not None:
        if want is not None or can_saturate(m):
            _unsound("counters", why, want, p)
        return
    if want is not None or can_saturate(m):
        on.append("counters")


def _unsound(name: str, why: str, want, p: "Plan") -> None:
    """Reduction ``name`` is unsound here (``why``): an error when it was
    asked for by name, else off with the reason."""
    if want is not None:
        raise PcclError(f"{name} reduction is unsound here: {why}; drop it from {{reduce}}",
                        filename="{reduce}", template=True)
    p.off[name] = why


#: Why the reductions are off under Koord's round semantics (pccl/model/koord.py).
NOT_ARGUED = ("not argued for Koord's round semantics (an event is one transition, "
              "memory is round-consistent)")
#: The reductions argued for Koord's round semantics (docs/koord.md,
#: "Reductions under the round semantics"): symmetry, and dead variables.
KOORD_ARGUED = ("symmetry", "dead")


def _plan_koord(m, want, p: Plan, uses=()) -> tuple:
    """Under Koord's round semantics (pccl/model/koord.py) symmetry
    (:func:`koord_symmetric_key`: the round semantics treats robots alike,
    so the same conditions make it sound) and dead variables are used
    (docs/koord.md, "Reductions under the round semantics": a robot's
    ``loc:`` variables are its own, every state between transitions has
    each running robot at the top of its block, and an event reads its
    locals in the order of its statements, so the liveness PCCL's dead
    analysis computes over statements holds of the round semantics' one
    transition per event); merging and partial-order reduction are argued
    for PCCL's statement-level interleaving.  Asking for one of those by
    name is an error."""
    for name in (want or ()):
        if name not in KOORD_ARGUED:
            raise PcclError(f"{name} reduction cannot be used here: {NOT_ARGUED}; use "
                            "{reduce=none}, {reduce=symmetry}, {reduce=dead} or "
                            "{semantics=pccl}", filename="{reduce}", template=True)
    limits = use_limits(uses)
    for name in (want or ()):
        if name in limits:
            raise PcclError(f"{name} reduction cannot be used here: {limits[name]}; "
                            "drop it from {reduce}", filename="{reduce}", template=True)
    on: list = []
    slots = None
    if "symmetry" not in limits and (want is None or "symmetry" in want):
        slots = _plan_symmetry(m, want, p, on)
    if "dead" not in limits and (want is None or "dead" in want):
        _plan_dead(m, want, p, on)
    if want is None:
        p.off.update({n: NOT_ARGUED for n in ALL if n not in KOORD_ARGUED})
        p.off.update({n: why for n, why in limits.items() if n in KOORD_ARGUED})
    p.on = tuple(on)
    return p, slots


def koord_symmetric_key(m, slots) -> Callable:
    """The symmetry key under Koord's round semantics: a state whose round
    cell is empty (every copy equals the global store) is keyed by its
    canonical representative (:func:`make_symmetric_key`, which reads the
    PCCL cells); one in the middle of a round with values of the round's
    start pending is keyed exactly (not reduced).  Both are sound: a
    permutation of the robots maps the round semantics' successors of a
    state to those of the permuted state (robots act in every order, each
    from its own view), so states identified are bisimilar."""
    sym = make_symmetric_key(m, slots)
    exact = m.plain_key
    rnd = N_STATE_CELLS          # the round cell (pccl.model.koord.RND)

    def key(st):
        if st[rnd] is None:
            return sym(st)
        return (exact(st), None)
    return key


def plan(m, reduce, uses=()) -> tuple:
    """(Plan, symmetry slots): the reductions ``reduce`` asks for that are
    sound for model ``m`` and for ``uses`` (see :data:`USE_LIMITS`), and why
    the others are off.  Asking explicitly for one that is not sound is an
    error."""
    want = parse_request(reduce)
    p = Plan(requested=reduce if isinstance(reduce, str) else ",".join(reduce))
    on: list = []
    slots = None
    if m.oracle.policy is not None:          # run mode: no reduction
        return Plan(requested="none"), None
    if getattr(m, "semantics", "pccl") != "pccl":
        return _plan_koord(m, want, p, uses)
    limits = use_limits(uses)
    for name in (want if want is not None else ()):
        if name in limits:
            raise PcclError(f"{name} reduction cannot be used here: {limits[name]}; "
                            "drop it from {reduce}", filename="{reduce}", template=True)
    if want is None:
        p.off.update({n: why for n, why in limits.items() if n in ALL})
    if "merge" not in limits and (want is None or "merge" in want):
        on.append("merge")
    if "symmetry" not in limits and (want is None or "symmetry" in want):
        slots = _plan_symmetry(m, want, p, on)
    if "por" not in limits and (want is None or "por" in want):
        _plan_por(m, want, p, on)
    if "dead" not in limits and (want is None or "dead" in want):
        _plan_dead(m, want, p, on)
    if "counters" not in limits and (want is None or "counters" in want):
        _plan_counters(m, want, p, on)
    p.on = tuple(on)
    return p, slots


# ---------------------------------------------------------------------------
# the reduced model
# ---------------------------------------------------------------------------

#: What a :class:`Reduced` holds itself; every other attribute is the model's.
_OWN = frozenset({"model", "reduction", "reduce_uses", "successors", "key", "violations",
                  "merger", "por", "init_states", "dead_vars", "counters", "sym_slots"})


class Reduced:
    """Model ``model`` seen through the reductions ``reduce`` asks for (see
    :func:`plan`; ``uses`` names uses of the search that rule some out):
    what the explorer searches, with the model's interface.  ``successors``
    is the merged and/or partial-order reduced relation, ``key`` the
    canonical one under symmetry, ``violations`` the model's fast path; with
    no reduction on they are the model's own generated functions.
    :attr:`reduction` says which are on and why the others are off.  Every
    other attribute is read from (and written to) the model, like
    :class:`pccl.output.coverage.CoverageModel` wrapping it; the model itself is
    never changed, its methods stay the unreduced semantics."""

    successors: Callable[[Any], list]
    key: Callable[[Any], Any]
    violations: Callable[[Any], list]

    def __init__(self, model, reduce="auto", uses=()):
        model = unreduced(model)
        d = self.__dict__
        d["model"] = model
        d["reduce_uses"] = tuple(uses)
        p, slots = plan(model, reduce, self.reduce_uses)
        d["reduction"] = p
        d["sym_slots"] = slots if "symmetry" in p.on else None
        d["successors"], d["key"] = model.plain_successors, model.plain_key
        d["violations"] = model.fast_violations
        d["merger"] = d["por"] = None
        base = None
        if "por" in p.on:
            d["por"] = Por(model)
            d["successors"] = base = self.por.successors
        if "merge" in p.on:
            d["merger"] = Merger(model, base, self.por)
            d["successors"] = self.merger.successors
        if "symmetry" in p.on:
            d["key"] = (koord_symmetric_key(model, slots) if model.semantics == "koord"
                        else make_symmetric_key(model, slots, p.fixed))
        if "dead" in p.on:
            from pccl.model.dead import DeadVars
            d["dead_vars"] = dv = DeadVars(model)
            d["key"] = dv.key_of(d["key"])
            one, values = dv.initial_collapse()
            if one or values:
                # every initial value of these is masked: one stands for all
                # the outcomes that have a value (every failing one is kept)
                d["init_states"] = functools.partial(model.init_states, first_only=one,
                                                     first_value=values)
        d["counters"] = None
        if "counters" in p.on:
            from pccl.model.counters import Counters
            d["counters"] = ctr = Counters.of(model)
            d["key"] = ctr.key_of(d["key"])

    def mirror_trace(self, trace, j: int):
        """A real run of the rules (``trace``, step by step) with agents 0
        and ``j`` exchanged: every state renamed (:func:`rename_state`),
        each step's label the unreduced rule that makes it (the orbit
        argument's counterexample for the instance of agent ``j``,
        docs/reductions.md).  Only under symmetry."""
        from pccl.search.explorer import Trace
        assert self.sym_slots is not None
        r = swap(self.model.N, 0, j)
        states = [rename_state(st, r, self.sym_slots) for st in trace.states]
        labels = []
        for a, b in zip(states, states[1:]):
            lab = next((lab for lab, t in self.model.successors(a) if t == b), None)
            if lab is None:
                raise RuntimeError("internal error: a renamed step of a counterexample is not a "
                                   "step of the rules (please report it)")
            labels.append(lab)
        return Trace(tuple(states), tuple(labels))

    def expand_trace(self, trace):
        """The trace with every merged transition replaced by its steps (for
        the search family: :func:`pccl.model.search_view.expand_trace` on this
        wrapper, which holds the merger)."""
        return expand_trace(self, trace) if self.merger is not None else trace

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        try:
            model = self.__dict__["model"]
        except KeyError:            # unpickling: no model yet
            raise AttributeError(name) from None
        return getattr(model, name)

    def __setattr__(self, name, value) -> None:
        if name in _OWN:
            self.__dict__[name] = value
        else:
            setattr(self.__dict__["model"], name, value)

    def __repr__(self) -> str:
        return f"<Reduced {self.reduction.describe()} of {self.model!r}>"

    def lasso_successors(self) -> tuple:
        """``(successors, expand)`` for a search over real states of a
        lasso (pccl/search/lift.py): this model's transitions, except that
        under partial-order reduction the ample sets of *every* eligible
        agent (:class:`UnionPor`: invariant under renaming agents), merged
        as this model merges; ``expand(trace)`` expands its merged
        transitions (docs/reductions.md, "Temporal properties under the
        reductions")."""
        if self.por is None:
            return self.successors, self.expand_trace
        union = UnionPor(self.por)
        if self.merger is None:
            return union.successors, (lambda trace: trace)
        holder = types.SimpleNamespace(merger=Merger(self.model, union.successors, self.por))
        return holder.merger.successors, functools.partial(expand_trace, holder)

    def with_uses(self, uses) -> "Reduced":
        """The same model, reduced as asked, for these uses of the search."""
        return Reduced(self.model, self.reduction.requested, uses)

    @property
    def reduced(self) -> bool:
        return bool(self.reduction.on)

    def expand(self, before, label) -> list:
        """The unreduced steps ``[(label, state), ...]`` of a transition."""
        if self.merger is None:
            for lab, s in self.model.successors(before):
                if lab == label:
                    return [(lab, s)]
            raise ValueError(f"label {label!r} is not enabled")
        return self.merger.expand(before, label)


def unreduced(m):
    """The model behind ``m`` (``m`` itself when it is not :class:`Reduced`)."""
    return m.model if isinstance(m, Reduced) else m


# ---------------------------------------------------------------------------
# statement merging
# ---------------------------------------------------------------------------

#: The k heads whose step :func:`pccl.semantics.rules.statement` runs.
_STATEMENT_KINDS = frozenset(R.STATEMENT_RULES) - {R.K_ATOMIC}

def _every_rule(m, st, i, ag, info, out) -> None:
    """Every rule of the k head ``info`` (a movable lock step or doReach in a
    merged chain)."""
    for rule in info.rules:
        rule(m, st, i, ag, info, out)


def _visit(seen, ident) -> Optional[set]:
    """``seen`` (the (pc, counter, locals) a chain met after its 32nd step,
    a new set for None) with ``ident`` added; None when ``ident`` is in it
    already: the chain revisits, a local loop."""
    if seen is None:
        return {ident}
    if ident in seen:
        return None
    seen.add(ident)
    return seen


def _push_branches(stack, out, ch, marks, mark) -> None:
    """The branches of a ``rand`` after the first (``out[1:]``), last first,
    onto a chain's ``stack``: (state, choices, marks), the branch's state
    and choices added to ``marks`` when ``mark`` (the step wrote the stall
    signature)."""
    for c in range(len(out) - 1, 0, -1):
        chc = ch + (c,)
        stack.append((out[c][1], chc, marks + ((out[c][1], chc),) if mark else marks))


class Merger:
    """The merged successor relation of a model, and its expansion.
    ``base``: the successor function chains start from (the rules', or the
    partial-order reduced one)."""

    def __init__(self, m, base=None, por=None):
        self.m = m
        sids = mergeable_sids(m)
        self.sids = sids
        self.ok: dict = {}
        if base is None:
            base = m.plain_successors
        self.plain = base
        #: with partial-order reduction, a chain also runs the steps it finds
        #: movable in the current state (:meth:`Por.movable`)
        self.por = por
        self.sig = None
        #: per pc: (info, the rule a chain runs there) (:meth:`_step_of`)
        self.steps: dict = {}

    def __getstate__(self) -> dict:
        d = dict(self.__dict__)
        d["sig"] = None         # generated code: rebuilt where it is needed
        d["steps"] = {}         # rebuilt where it is needed
        return d

    def pc_ok(self, pc) -> bool:
        r = self.ok.get(pc)
        if r is None:
            info = self.m.ctl.info(pc)
            k = info.kind
            r = k == K_END or (k in (K_SIMPLE, K_IF, K_WHILE) and info.sid in self.sids)
            self.ok[pc] = r
        return r

    def micro(self, st, i, ag) -> list:
        m = self.m
        info = m.ctl.info(ag[PC])
        out: list = []
        m.oracle.agent = i
        for rule in info.rules:
            rule(m, st, i, ag, info, out)
        return out

    def successors(self, st) -> list:
        out = self.plain(st)
        if st[PHASE] != DISCRETE:
            return out
        m = self.m
        rho, n0 = m.rho, m.n0
        ok = self.ok
        res: list = []
        for idx0, (lab, s2) in enumerate(out):
            i = lab[1]
            if i is not None:
                ag = s2[AGS][i]
                if ag[STATUS] == RUNNING:
                    if ag[CNT] + rho[i] <= n0:
                        r = ok.get(ag[PC])
                        if r is None:
                            r = self.pc_ok(ag[PC])
                        r = r or (self.por is not None and self.por.movable(s2, i, ag))
                    else:       # spent: its own plain statements (Por, "spent agents")
                        r = self.por is not None and self.por.ind.spent_local(ag[PC])
                    if r:
                        self._chain(lab, idx0, s2, i, res, st)
                        continue
            res.append((lab, s2))
        return res

    def _chain(self, lab, idx0, s, i, res, st0=None):
        """Continue agent i's transition ``lab`` (from ``st0`` to ``s``)
        with the steps merging may run, appending the merged transitions to
        ``res`` (one a branch of the ``rand`` calls met).  A chain that
        writes what the stall signature reads (shared variables, the lock
        queue, a doReach) and ends where it began, as the signature goes, is
        cut after its first change: the stall check sees a change on a
        transition exactly when one of its steps makes one.  (One loop, the
        hot path of a reduced search: the step run at a pc is
        :meth:`_step_of`'s, the other branches of a ``rand`` go onto the
        stack with :func:`_push_branches`.)"""
        m = self.m
        rho, n0 = m.rho[i], m.n0
        ok, steps = self.ok, self.steps
        oracle = m.oracle
        s1 = s
        stack: list[tuple[Any, tuple[int, ...], tuple]] = [(s, (), ())]
        seen = None
        while stack:
            s, ch, marks = stack.pop()
            while True:
                ag = s[AGS][i]
                pc = ag[PC]
                n = len(ch)
                if ag[STATUS] != RUNNING or n >= MERGE_LIMIT:
                    break
                r = ok.get(pc)
                if r is None:
                    r = self.pc_ok(pc)
                mv = 0
                if ag[CNT] + rho > n0 or not r:
                    mv = self._movable(s, i, ag, ag[CNT] + rho > n0)
                    if mv < 0:
                        break
                if n >= 32:
                    # a long chain may be a local loop: stop where it revisits
                    seen = _visit(seen, (pc, ag[CNT], ag[LOC]))
                    if seen is None:
                        break
                step = steps.get(pc)
                if step is None:
                    step = self._step_of(pc)
                info, rule = step
                out: list = []
                oracle.agent = i
                rule(m, s, i, ag, info, out)
                if not out:
                    break
                if len(out) > 1:
                    _push_branches(stack, out, ch, marks, mv == 2)
                s = out[0][1]
                ch = ch + (0,)
                if mv == 2:
                    marks = marks + ((s, ch),)
            if marks and st0 is not None:
                s, ch = self._cut(st0, s1, s, ch, marks)
            res.append(((lab[0], lab[1], lab[2], idx0, ch) if ch else lab, s))

    def _movable(self, s, i, ag, spent: bool) -> int:
        """For a chain of agent i at a step that is not a plain mergeable
        one: -1 the chain stops; else :meth:`Por.movable`'s 1 or 2, or 0
        for a *spent* agent's (it waited for the lock) plain statement of
        its own, which commutes with TIME ADVANCE and DOREACH INVOKE too
        (Independence.spent_local)."""
        por = self.por
        if por is None:
            return -1
        if spent:
            return 0 if por.ind.spent_local(ag[PC]) else -1
        return por.movable(s, i, ag) or -1

    def _step_of(self, pc) -> tuple:
        """(info, rule) for the step at ``pc`` in a chain: TIME COUNTER
        ADVANCE at the end of an event, the statement rule, or (a movable
        lock step, a doReach) every rule of the k head."""
        ctl = self.m.ctl
        info = ctl.infos[pc]
        if info is None:
            info = ctl.info(pc)
        k = info.kind
        if k == K_END:
            rule = R.counter_advance
        elif k in _STATEMENT_KINDS:
            rule = R.statement
        else:
            rule = _every_rule
        got = self.steps[pc] = (info, rule)
        return got

    def _cut(self, st0, s1, s, ch, marks) -> tuple:
        """(state, choices) where a chain from ``st0`` that wrote signature
        data ends: its end, unless the signature there is the one of ``st0``
        although a step changed it; then right after the first change."""
        sig = self.sig
        if sig is None:
            from pccl.model.stall import signature_fn
            sig = self.sig = signature_fn(self.m)
        base = sig(st0)
        if sig(s) != base:
            return s, ch
        for sx, chx in ((s1, ()),) + marks:
            if sig(sx) != base:
                return sx, chx
        return s, ch

    def expand(self, before, label) -> list:
        """``[(micro_label, state), ...]``: the unreduced steps of a merged
        transition (one step for an unmerged label)."""
        if len(label) <= 3:
            for lab, s in self.plain(before):
                if lab == label:
                    return [(lab, s)]
            raise ValueError(f"label {label!r} is not enabled")
        idx0, ch = label[3], label[4]
        lab, s = self.plain(before)[idx0]
        steps = [(lab, s)]
        i = lab[1]
        for c in ch:
            lab, s = self.micro(s, i, s[AGS][i])[c]
            steps.append((lab, s))
        return steps


def expand_trace(m, trace, violation=None):
    """The trace with every merged transition replaced by its steps; with
    ``violation`` (not a deadlock), cut at the first state that has it (a
    merged transition may run invisible steps after the violating one)."""
    from pccl.search.explorer import Trace
    merger = getattr(m, "merger", None)
    if merger is None or trace is None:
        return trace
    states, labels = [trace.states[0]], []
    for st in trace.steps:
        if len(st.label) > 3:
            steps = merger.expand(st.before, st.label)
            assert steps[-1][1] == st.after, "a merged transition did not re-execute"
            for lab, s in steps:
                labels.append(lab)
                states.append(s)
        else:
            labels.append(st.label)
            states.append(st.after)
    if violation is not None and getattr(violation, "kind", None) != "deadlock":
        want = violation.identity
        for n, s in enumerate(states):
            if any(v.identity == want for v in unreduced(m).violations(s)):
                states, labels = states[:n + 1], labels[:n]
                break
    return Trace(tuple(states), tuple(labels))


# ---------------------------------------------------------------------------
# partial-order reduction
# ---------------------------------------------------------------------------

class UnionPor:
    """The ample sets of :class:`Por` for *every* agent that qualifies, not
    the first: a state's successors are the union of the ample sets of all
    its eligible agents (a union of ample sets keeps C0-C3), so the graph is
    invariant under renaming agents (a renamed state's ample agent is one of
    them).  The search over real states of a liveness lasso
    (pccl/search/lift.py) walks it: it contains every transition the
    reduced graph has from a state of the same orbit, renamed
    (docs/reductions.md)."""

    def __init__(self, por: "Por"):
        self.por = por
        self.plain = por.plain

    def successors(self, st) -> list:
        por = self.por
        if st[PHASE] == DISCRETE:
            m = por.m
            rho, n0 = m.rho, m.n0
            out: list = []
            for i, ag in enumerate(st[AGS]):
                if ag[STATUS] == RUNNING and ag[CNT] + rho[i] <= n0 and por.eligible(st, i, ag):
                    out += por._keeps_running(st, i, ag) or []
            if out:
                return out
            spent_local = por.ind.spent_local
            for i, ag in enumerate(st[AGS]):
                if ag[STATUS] == RUNNING and ag[CNT] + rho[i] > n0 and spent_local(ag[PC]):
                    out += por._keeps_running(st, i, ag) or []
            if out:
                return out
        return self.plain(st)


class Por:
    """Partial-order reduction with ample sets (docs/reductions.md).

    In a DISCRETE state, the first agent i (by index) that is running, has
    an execution left (counter + ρ(i) ≤ n0, so TIME ADVANCE is disabled
    until i itself advances its counter) and whose next step is independent
    of everything the other agents can still do before the next TIME
    ADVANCE (:mod:`pccl.model.independence`: a local step, a read or write
    of shared variables no other agent can still write, resp. touch, in
    this time step, a lock step the queue makes independent, a doReach)
    gets ample set = all of i's enabled transitions, provided each keeps i
    running (a runtime error is visible).  Otherwise the state is fully
    expanded.  An ample step writes no variable a property reads (C2); it
    is outside every ``while``, so it is a step of i's progress inside the
    current time step, and the states where TIME ADVANCE is enabled (every
    agent spent) are fully expanded: every cycle of the reduced graph
    passes a fully expanded state (C3, whatever the search order)."""

    def __init__(self, m):
        self.m = m
        self.ind = Independence(m)
        self.plain = m.plain_successors
        self.top_pc = m.ctl.empty_pc
        self._next: dict = {}

    def footprint(self, st, j, b) -> tuple:
        """(reads, writes) of what running agent j (cell ``b``) may still
        do before the next TIME ADVANCE; at the top of its block with local
        guards, only the events enabled now can be selected next."""
        ind = self.ind
        m = self.m
        rho, n0 = m.rho[j], m.n0
        if b[PC] == self.top_pc and ind.guards_local and b[CNT] + 2 * rho > n0:
            if b[CNT] + rho > n0:
                return 0, 0                  # spent at the top: nothing left
            key = (j, b[LOC])
            got = self._next.get(key)
            if got is None:
                try:
                    got = ind.next_events(m.enabled_events(j, b, st[SH], st[AGS]))
                except R.RUNTIME_ERRORS:
                    got = (ind.guard_reads, 0)   # EVENT SELECT gets j stuck
                if len(self._next) > 200_000:
                    self._next.clear()
                self._next[key] = got
            return got
        return ind.footprint(b, rho, n0)

    def eligible(self, st, i, ag) -> bool:
        """Whether agent i's next step (i running, counter + ρ(i) ≤ n0) is
        independent of all the other agents can do in this time step."""
        ind = self.ind
        cls, r, w = ind.step(ag[PC])
        if cls == LOCAL:
            return True
        if cls == NEVER:
            return False
        if cls == EXECUTE:               # ATOMIC EXECUTION, or ATOMIC WAIT
            lq = st[LQ]
            return bool(lq) and lq[0] == i
        if cls == REQUEST_LOCK and ag[LCK] == LOCK:
            return True                  # a nested atomic: k only
        m = self.m
        rho, n0 = m.rho, m.n0
        if cls == RELEASE:
            for j, b in enumerate(st[AGS]):
                if j != i and b[STATUS] == RUNNING and may_wait(ind, b, rho[j], n0):
                    return False
            return True
        if not (r or w):
            return True
        for j, b in enumerate(st[AGS]):
            if j != i and b[STATUS] == RUNNING:
                fr, fw = self.footprint(st, j, b)
                if w & (fr | fw) or r & fw:
                    return False
        return True

    def movable(self, st, i, ag) -> int:
        """Whether statement merging may run agent i's next step (i running
        with an execution left) inside a chain: 0 no; 1 an eligible step that
        changes nothing another agent, a property or the stall signature
        sees (a read of shared variables, ATOMIC EXECUTION at the head of
        the queue, a nested atomic); 2 an eligible step that writes shared
        data (a shared variable, the lock queue, a doReach).  Every
        eligible step but EVENT SELECT is: a left mover that no other
        agent's step can disable and that no property sees
        (docs/reductions.md)."""
        pc = ag[PC]
        ind = self.ind
        cls = ind.step(pc)[0]
        if cls == EXECUTE:
            lq = st[LQ]
            return 1 if lq and lq[0] == i else 0
        if cls == REQUEST_LOCK and ag[LCK] == LOCK:
            return 1
        if cls == ACCESS:
            if self.m.ctl.infos[pc].kind == K_EMPTY:
                return 0
        elif cls not in (REQUEST_LOCK, RELEASE):
            return 0
        if not self.eligible(st, i, ag):
            return 0
        return 2 if cls != ACCESS or pc in ind.writers else 1

    def successors(self, st) -> list:
        if st[PHASE] == DISCRETE:
            rho, n0 = self.m.rho, self.m.n0
            i = 0
            for ag in st[AGS]:
                if ag[STATUS] == RUNNING and ag[CNT] + rho[i] <= n0 and self.eligible(st, i, ag):
                    out = self._keeps_running(st, i, ag)
                    if out:
                        return out
                i += 1
            # no such agent: the first spent agent whose next step is a
            # plain statement of its own (Independence.spent_local)
            spent_local = self.ind.spent_local
            i = 0
            for ag in st[AGS]:
                if ag[STATUS] == RUNNING and ag[CNT] + rho[i] > n0 and spent_local(ag[PC]):
                    out = self._keeps_running(st, i, ag)
                    if out:
                        return out
                i += 1
        return self.plain(st)

    def _keeps_running(self, st, i, ag) -> Optional[list]:
        """Agent i's transitions from ``st`` (its candidate ample set), or
        None when it has none or one of them stops it (a runtime error is
        visible: the state is then fully expanded)."""
        m = self.m
        ctl = m.ctl
        pc = ag[PC]
        info = ctl.infos[pc]
        if info is None:
            info = ctl.info(pc)
        out: list = []
        m.oracle.agent = i
        for rule in info.rules:
            rule(m, st, i, ag, info, out)
        if out and all(s2[AGS][i][STATUS] == RUNNING for _, s2 in out):
            return out
        return None


# ---------------------------------------------------------------------------
# symmetry
# ---------------------------------------------------------------------------

def make_symmetric_key(m, slots, fixed: int = 0):
    """A key function returning a canonical representative of the state's
    orbit under permutations of agent ids (``fixed`` 1: the permutations
    that keep agent 0 in place; its cell stays first)."""
    loc_s, ar_s, sh_s, self_only, motion = slots
    if self_only:
        return _self_only_key(m, loc_s, ar_s, sh_s, motion, fixed)
    return _permuting_key(m, loc_s, ar_s, sh_s, motion, fixed)


def _mask_ids(vals, idx, j):
    """``vals`` with the ids at ``idx`` masked: agent ``j``'s own as "s",
    another's as "o"; and whether another's was there."""
    v = list(vals)
    other = False
    for k in idx:
        x = v[k]
        if type(x) is int and x >= 0:
            if x == j:
                v[k] = "s"
            else:
                v[k] = "o"
                other = True
    return tuple(v), other


def _rename_ids(vals, idx, r):
    """``vals`` with the ids at ``idx`` renamed by ``r``."""
    v = list(vals)
    for k in idx:
        x = v[k]
        if type(x) is int and x >= 0:
            v[k] = r[x]
    return tuple(v)


def _permuting_build(m, loc_s, ar_s, sh_s, motion):
    """The function ``build(st, order)`` of :func:`_permuting_key`: the key
    of ``st`` with its agents put in ``order`` and their ids renamed."""
    abstract = m.abstract_time
    N = m.N
    has_ids = bool(loc_s or ar_s or sh_s)
    ren = _rename_ids

    def build(st, order):
        r = [0] * N
        for new, old in enumerate(order):
            r[old] = new
        ags = st[AGS]
        if has_ids:
            cells = tuple((a[PC], a[CNT], a[LCK], a[STATUS],
                           ren(a[LOC], loc_s, r) if loc_s else a[LOC],
                           ren(a[AR], ar_s, r) if ar_s else a[AR])
                          + ((a[POS], a[REACH]) if motion else ())
                          for a in (ags[o] for o in order))
            sh = ren(st[SH], sh_s, r) if sh_s else st[SH]
        else:
            # the whole cell moves with its agent; unread positions leave the key
            cells = tuple(ags[o] if motion else ags[o][:POS] for o in order)
            sh = st[SH]
        lq = tuple(r[x] for x in st[LQ])
        if abstract:
            return (st[PHASE], lq, sh, cells, st[ENV])
        return (st[TIME], st[PHASE], lq, sh, cells, st[ENV])

    return build


def _permuting_key(m, loc_s, ar_s, sh_s, motion, fixed: int = 0):
    """The canonical key when agents may name other agents: agents are
    sorted by their masked cells, and ties among them are tried in every
    order (the per-state function is one closure; only its construction is
    split into steps)."""
    dumps = marshal.dumps
    N = m.N
    has_ids = bool(loc_s or ar_s or sh_s)
    mask = _mask_ids
    build = _permuting_build(m, loc_s, ar_s, sh_s, motion)
    head, rest = list(range(fixed)), range(fixed, N)

    def key(st):
        ags = st[AGS]
        lq = st[LQ]
        sh = st[SH]
        sk = []
        any_other = False
        for j, a in enumerate(ags):
            if has_ids:
                lv, o1 = mask(a[LOC], loc_s, j) if loc_s else (a[LOC], False)
                av, o2 = mask(a[AR], ar_s, j) if ar_s else (a[AR], False)
                any_other = any_other or o1 or o2
                refs = tuple(sh[k] == j for k in sh_s)
            else:
                lv, av, refs = a[LOC], a[AR], ()
            sk.append(dumps(((a[PC], a[CNT], a[LCK], a[STATUS], lv, av)
                             + ((a[POS], a[REACH]) if motion else ()), refs,
                             lq.index(j) if j in lq else -1), 2))
        order = head + sorted(rest, key=sk.__getitem__)
        if not any_other:
            return build(st, order)
        # agents referring to others: ties must be tried in every order
        # (a fixed agent is a group of its own)
        groups = [[x] for x in head] + [list(g) for _, g in itertools.groupby(
            order[fixed:], key=sk.__getitem__)]
        if all(len(g) == 1 for g in groups):
            return build(st, order)
        best = bestb = None
        for combo in itertools.product(*(itertools.permutations(g) for g in groups)):
            k = build(st, [x for g in combo for x in g])
            b = dumps(k, 2)
            if bestb is None or b < bestb:
                best, bestb = k, b
        return best

    return key


#: Stands for "this agent's own id" in a canonical cell: a float, so it
#: sorts among ints and encodes differently from every int.
SELF = float("-inf")


def _self_only_key(m, loc_s, ar_s, sh_s, motion, fixed: int = 0):  # noqa: C901
    """The canonical key when per-agent id variables hold only the agent's
    own id or a sentinel: such a value is replaced by :data:`SELF` (its
    renamed value is the cell's place, so nothing is lost); agents are
    sorted by (masked cell, which shared id variables name it, its place in
    the lock queue).  Agents that tie are identical in the key whatever
    their order, so no tie needs breaking."""
    dumps = marshal.dumps
    abstract = m.abstract_time
    N = m.N

    l1 = loc_s[0] if len(loc_s) == 1 else None
    s1 = sh_s[0] if len(sh_s) == 1 else None

    # one closure on purpose: the key of every state of a reduced search
    # (a documented exception to the size bounds, docs/architecture.md)
    def key(st):  # noqa: C901
        ags = st[AGS]
        lq = st[LQ]
        sh = st[SH]
        items = []
        j = 0
        for a in ags:
            loc = a[LOC]
            if l1 is not None:
                if loc[l1] == j:
                    loc = loc[:l1] + (SELF,) + loc[l1 + 1:]
            elif loc_s:
                loc = list(loc)
                for k in loc_s:
                    if loc[k] == j:
                        loc[k] = SELF
                loc = tuple(loc)
            ar = a[AR]
            if ar_s:
                ar = list(ar)
                for k in ar_s:
                    if ar[k] == j:
                        ar[k] = SELF
                ar = tuple(ar)
            items.append(((a[PC], a[CNT], a[LCK], a[STATUS], loc, ar)
                          + ((a[POS], a[REACH]) if motion else ()),
                          (sh[s1] == j,) if s1 is not None else
                          tuple([sh[k] == j for k in sh_s]) if sh_s else (),
                          lq.index(j) if j in lq else -1, j))
            j += 1
        if fixed:                  # agent 0 kept first
            head, items = items[:fixed], items[fixed:]
        try:
            items.sort()
        except TypeError:          # undefined (Ellipsis) against a number
            items.sort(key=lambda t: dumps(t[:3], 2))
        if fixed:
            items = head + items
        if lq or sh_s:
            r = [0] * N
            for new, t in enumerate(items):
                r[t[3]] = new
            if lq:
                lq = tuple([r[x] for x in lq])
            if sh_s:
                sh = list(sh)
                for k in sh_s:
                    x = sh[k]
                    if type(x) is int and x >= 0:
                        sh[k] = r[x]
                sh = tuple(sh)
        cells = tuple([t[0] for t in items])
        if abstract:
            return (st[PHASE], lq, sh, cells, st[ENV])
        return (st[TIME], st[PHASE], lq, sh, cells, st[ENV])

    return key
