"""A model's properties: what is checked on its states.

The front end gives the properties as written (:func:`sources`: the
program's ``invariant:`` section, then ``--invariant`` and ``--property``
texts, parsed here); :class:`Checks` checks them against the compiled
program (the checker's types), instantiates the temporal ones (one instance
per agent of a ``forall``) and compiles them, and gives the model its
violations: stuck agents and assertions, state properties, collisions, a
lock held by an exited agent, deadlocks.

The engine (:class:`pccl.model.engine.Model`) holds one :class:`Checks` and
imports nothing of the parser: every property expression it sees comes
from here.
"""

from __future__ import annotations

import dataclasses
import decimal
import math
from dataclasses import dataclass
from typing import Any, Optional
from collections.abc import Callable, Iterable, Iterator

from pccl.lang import ast as A
from pccl.search import safedata
from pccl.lang.errors import PcclError
from pccl.model.layout import AGS, CNT, EXITED, LQ, PC, POS, RUNNING, SH, STATUS, STUCK, acquire_sid, is_acquire
from pccl.lang.parser import parse_property
from pccl.semantics import rules as R


@dataclass(frozen=True)
class Violation:
    kind: str                 # invariant | assert | stuck | deadlock | collision
    name: str                 # property name / short description
    message: str
    agent: Optional[int] = None
    span: Optional[A.Span] = None

    @property
    def identity(self):
        """Distinct violations for ``--all``: property and source location."""
        loc = (self.span.line, self.span.column) if self.span else None
        return (self.kind, self.name, loc)


def _span_of(fields: tuple) -> A.Span:
    if len(fields) != 4 or any(type(f) is not int for f in fields):
        raise safedata.DataError("a source span: expected four integers")
    return A.Span(*fields)


def _violation_of(fields: tuple) -> "Violation":
    if len(fields) != 5:
        raise safedata.DataError("a violation: expected five fields")
    kind, name, message, agent, span = fields
    if not all(type(f) is str for f in (kind, name, message)):
        raise safedata.DataError("a violation: kind, name and message are strings")
    if agent is not None and type(agent) is not int:
        raise safedata.DataError("a violation's agent: expected an integer")
    if span is not None and type(span) is not A.Span:
        raise safedata.DataError("a violation's span: expected a source span")
    return Violation(kind, name, message, agent, span)


# checkpoints hold violations found (pccl/search/safedata.py: data, never a pickle)
safedata.register_record("p", A.Span, lambda s: (s.line, s.column, s.end_line, s.end_column),
                         _span_of)
safedata.register_record("v", Violation, lambda v: (v.kind, v.name, v.message, v.agent, v.span),
                         _violation_of)


@dataclass
class Property:
    name: str
    text: str
    fn: Callable
    span: Optional[A.Span]
    uses_time: bool
    src: str = ""             # the compiled Python expression (over st, sh, ags)
    expr: Optional[A.Expr] = None


@dataclass
class TemporalProperty:
    """One temporal property of spec section 9 (one instance per agent of a
    ``forall``-quantified one): ``kind`` is ``eventually``, ``leadsto``,
    ``within`` (``P ~> Q within T``) or ``reachable``.  ``p``/``q`` are
    compiled state predicates ``fn(st) -> bool``; ``ticks`` is T as a whole
    number of time steps δ (``within`` only)."""
    kind: str
    name: str
    text: str
    p: Callable
    q: Optional[Callable]
    span: Optional[A.Span]
    expr: A.Expr              # the instance's Temporal node (reductions read it)
    uses_time: bool = False
    ticks: Optional[int] = None
    bound: Optional[float] = None
    #: of one instance of ``forall i: F(i)`` (one quantifier): the agent it
    #: is for, and the quantified expression as written (the symmetry
    #: analysis reads it with ``i`` bound; the orbit argument checks the
    #: instance for agent 0 alone, docs/reductions.md); None otherwise
    agent: Optional[int] = None
    quantified: Optional[A.Expr] = None

    @property
    def liveness(self) -> bool:
        return self.kind in ("eventually", "leadsto")


@dataclass(frozen=True)
class Source:
    """A property as written and parsed, not yet checked: its expression,
    the name it is reported under, its text, and where it was written
    (``span`` in the program, or None for a command-line text whose
    ``filename`` is ``{invariants} #1``: the option as a placeholder, spelt
    ``--invariant #1`` by the CLI, ``invariants #1`` by the API)."""
    expr: A.Expr
    name: str
    text: str
    span: Optional[A.Span]
    filename: Optional[str]
    source: str

    @property
    def temporal(self) -> bool:
        return is_temporal(self.expr)


def sources(program: A.Program, invariants: Iterable[str] = (),
            properties: Iterable[str] = ()) -> Iterator[Source]:
    """The properties to check, in order: the program's own, then the
    ``--invariant`` texts (state properties only), then the ``--property``
    texts (any form of spec section 9).  Lazily: a text is parsed when the
    ones before it are checked, so the first error is reported first."""
    for inv in program.invariants:
        text = src_text(program.source, inv.expr.span)
        yield Source(inv.expr, inv.name or text, text, inv.span, program.filename,
                     program.source)
    for k, text in enumerate(invariants):
        fname = f"{{invariants}} #{k + 1}"
        expr = parse_property(text, filename=fname)
        if is_temporal(expr):
            raise PcclError("{invariants} takes a state property; a temporal property "
                            "(eventually, ~>, within, reachable) goes with {properties}",
                            filename=fname, source=text, span=top_temporal(expr).span,
                            template=True)
        yield Source(expr, text, text, None, fname, text)
    for k, text in enumerate(properties):
        if not isinstance(text, str):
            raise PcclError(f"a property must be text, got {type(text).__name__}",
                            filename="{properties}")
        fname = f"{{properties}} #{k + 1}"
        expr = parse_property(text, filename=fname)
        if is_temporal(expr):
            yield Source(expr, text.strip(), text.strip(), None, fname, text)
        else:
            yield Source(expr, text, text, None, fname, text)


class Checks:
    """The properties of model ``m`` checked and compiled, and the
    violations of a state.  ``m`` gives the compiled program, the team size
    ``N``, the clock (``delta``: a ``within`` bound as a number of time
    steps), ``collisions``, the world, and ``lock_deadlocks`` (read at each
    check: the search may turn it off)."""

    def __init__(self, m, props: Iterable[Source]):
        self.m = m
        self.compiled = m.compiled
        self.properties: list[Property] = []
        #: the temporal properties (spec section 9), see pccl/search/liveness.py
        self.temporal: list[TemporalProperty] = []
        self._collision_cache: dict = {}
        for s in props:
            if s.temporal:
                self.add_temporal(s)
            else:
                self.add_property(s)

    @property
    def uses_time(self) -> bool:
        """Whether a property reads the clock (time abstraction is then unsound)."""
        return any(p.uses_time for p in self.properties) or any(p.uses_time for p in self.temporal)

    @property
    def exprs(self) -> list:
        """Every property's expression (the reductions read which names they use)."""
        return ([p.expr for p in self.properties if p.expr is not None]
                + [p.expr for p in self.temporal])

    def add_property(self, s: Source) -> None:
        """Check and compile a state property."""
        self.compiled.check_property(s.expr, filename=s.filename, source=s.source)
        src, fn = self.compiled.state_predicate(s.expr)
        self.properties.append(Property(s.name, s.text, fn, s.span, _reads_time(s.expr), src,
                                        s.expr))

    def add_temporal(self, s: Source) -> None:
        """Check and compile a temporal property; a ``forall``-quantified one
        becomes one instance per agent (``name [i=0]``, …)."""
        self.compiled.check_property(s.expr, filename=s.filename, source=s.source)
        qvars = []
        top = s.expr
        while isinstance(top, A.Quant):
            qvars.append(top.var)
            top = top.body
        combos: list[tuple] = [()]
        for _ in qvars:
            combos = [c + (k,) for c in combos for k in range(self.m.N)]
        for combo in combos:
            env: dict[str, int] = dict(zip(qvars, combo))
            t: Any = subst(top, env) if env else top
            suffix = (" [" + ", ".join(f"{v}={k}" for v, k in env.items()) + "]") if env else ""
            kind = t.kind
            ticks = bound = None
            if t.bound is not None:
                kind = "within"
                bound, ticks = self._within_bound(t.bound, s)
            self.temporal.append(TemporalProperty(
                kind, s.name + suffix, s.text, self._predicate(t.p),
                self._predicate(t.q) if t.q is not None else None,
                s.span, t, _reads_time(t), ticks, bound,
                combo[0] if len(qvars) == 1 else None, s.expr if len(qvars) == 1 else None))

    def _predicate(self, e: A.Expr) -> Callable:
        return self.compiled.state_predicate(e)[1]

    def _within_bound(self, e: A.Expr, s: Source) -> tuple:
        """``within T``: T, and T as a whole number of time steps δ."""
        try:
            bound = self.compiled.constant(e)
        except Exception as exc:
            raise PcclError(f"the bound of 'within' cannot be evaluated: {exc}",
                            filename=s.filename, source=s.source, span=e.span) from None
        if not (isinstance(bound, (int, float)) and math.isfinite(bound) and bound >= 0):
            raise PcclError(f"the bound of 'within' must be a finite number >= 0, "
                            f"got {bound}", filename=s.filename, source=s.source, span=e.span)
        ticks = int((decimal_of(bound) / decimal_of(self.m.delta)).to_integral_value(
            rounding=decimal.ROUND_FLOOR))
        return bound, ticks

    # -- the violations of a state ------------------------------------------------------
    def compile_violations(self) -> Callable[[Any], list]:
        """A compiled fast path for :meth:`violations`: if no agent is stuck
        and every property holds (the common case) it returns ``[]`` at once;
        otherwise it defers to :meth:`violations` (the properties are pure, so
        evaluating them again is harmless).  Not with collision checking,
        which always takes the full path, nor for large teams."""
        m = self.m
        if m.collisions or m.N > 64:
            return self.violations
        ok = " and ".join(f"ags[{j}][{STATUS}] < {STUCK}" for j in range(m.N))
        # ... and the lock is free or its holder has not exited
        ok += f" and (not st[{LQ}] or ags[st[{LQ}][0]][{STATUS}] != {EXITED})"
        body = f"    ags = st[{AGS}]\n    if {ok}:\n"
        if self.properties:
            conj = " and ".join(f"({p.src})" for p in self.properties)
            body += (f"        sh = st[{SH}]\n        try:\n"
                     f"            if {conj}:\n                return []\n"
                     "        except Exception:\n            pass\n")
        else:
            body += "        return []\n"
        body += "    return _full(st)\n"
        return self.compiled.make_function("st", body, "_violations", _full=self.violations)

    def violations(self, st) -> list:
        """Every violation in ``st``: stuck agents, then properties, then
        collisions, then a lock held by an exited agent."""
        out = []
        for i, ag in enumerate(st[AGS]):
            s = ag[STATUS]
            if s >= STUCK:
                kind, reason, where = self.compiled.stuck_reasons[s]
                span = self.compiled.span_of(where)
                if kind == "assert":
                    out.append(Violation("assert", "assertion", f"agent {i}: assertion failed", i, span))
                else:
                    out.append(Violation("stuck", "stuck agent", f"agent {i} stuck: {reason}", i, span))
        for p in self.properties:
            try:
                ok = p.fn(st)
            except R.RUNTIME_ERRORS as exc:
                out.append(Violation("invariant", p.name,
                                     f"invariant '{p.name}' could not be evaluated: "
                                     f"{getattr(exc, 'reason', None) or R.describe_error(exc)}",
                                     None, p.span))
                continue
            if not ok:
                out.append(Violation("invariant", p.name, f"invariant '{p.name}' violated",
                                     None, p.span))
        if self.m.collisions:
            out.extend(self.collision_violations(st))
        lq = st[LQ]
        if lq and self.m.lock_deadlocks and st[AGS][lq[0]][STATUS] == EXITED:
            v = self.lock_violation(st)
            if v is not None:
                out.append(v)
        return out

    def lock_violation(self, st) -> Optional[Violation]:
        """The lock is held by an agent that has exited (``exit()`` inside
        ``atomic`` keeps the lock) and a running agent waits for it: that
        agent can never progress, although time may advance forever."""
        lq, ags = st[LQ], st[AGS]
        holder = lq[0]
        waiting = [j for j in lq[1:] if ags[j][STATUS] == RUNNING]
        if not waiting:
            return None
        w = waiting[0]
        k = self.compiled.ctl.cells[ags[w][PC]]
        span = self.compiled.stmts[acquire_sid(k[0])].span if k and is_acquire(k[0]) else None
        where = f" (atomic at line {span.line})" if span is not None else ""
        others = (f"; agents {', '.join(map(str, waiting[1:]))} wait too"
                  if len(waiting) > 1 else "")
        msg = (f"deadlock: agent {w} waits forever for the lock{where}: agent {holder} holds "
               f"it and has exited, so it never releases it{others}")
        return Violation("deadlock", "lock held by an exited agent", msg, w, span)

    def collision_violations(self, st) -> list:
        poss = tuple([ag[POS] for ag in st[AGS]])
        hit = self._collision_cache.get(poss)
        if hit is None:
            from pccl.model.collide import contacts
            hit = [Violation("collision",
                             f"collision of agents {c.i} and {c.j}" if c.j is not None
                             else f"collision of agent {c.i} with obstacle {c.obstacle}",
                             c.message, c.i, None)
                   for c in contacts(self.m.world, poss)]
            if len(self._collision_cache) > 100_000:
                self._collision_cache.clear()
            self._collision_cache[poss] = hit
        return hit

    def deadlock_violation(self, st) -> Violation:
        waiting = []
        for i, ag in enumerate(st[AGS]):
            if ag[STATUS] == RUNNING:
                waiting.append(f"agent {i} ({self.compiled.describe_k(ag[PC])}, counter {ag[CNT]})")
        msg = "deadlock: no rule applies and not every agent has exited"
        if waiting:
            msg += "; " + "; ".join(waiting)
        return Violation("deadlock", "deadlock", msg, None, None)


def _reads_time(e: A.Expr) -> bool:
    return any(isinstance(x, A.Name) and x.name == "time" for x in A.walk_expr(e))


def decimal_of(x) -> decimal.Decimal:
    """``x`` as the decimal it was written as (0.1 is 1/10, not the binary float)."""
    return decimal.Decimal(x) if isinstance(x, int) else decimal.Decimal(repr(float(x)))


def top_temporal(e):
    while isinstance(e, A.Quant):
        e = e.body
    return e


def is_temporal(e) -> bool:
    """Whether a property is one of the temporal forms (under ``forall`` at most)."""
    return isinstance(top_temporal(e), A.Temporal)


def subst(e, env: dict) -> Any:
    """``e`` with the bound names of ``env`` replaced by agent ids (int
    literals); an inner quantifier over the same name shadows it."""
    if isinstance(e, A.Name) and e.name in env:
        return A.IntLit(env[e.name], e.span)
    if isinstance(e, A.Quant) and e.var in env:
        env = {k: v for k, v in env.items() if k != e.var}
        if not env:
            return e
    if not dataclasses.is_dataclass(e) or isinstance(e, A.Span):
        return e
    changes = {}
    for f in dataclasses.fields(e):
        v = getattr(e, f.name)
        if isinstance(v, tuple):
            nv = tuple(subst(x, env) for x in v)
        elif dataclasses.is_dataclass(v) and not isinstance(v, A.Span):
            nv = subst(v, env)
        else:
            continue
        if nv is not v:
            changes[f.name] = nv
    return dataclasses.replace(e, **changes) if changes else e  # type: ignore[type-var]


def src_text(source: str, span: A.Span) -> str:
    if not source or span is None or span.line <= 0:
        return ""
    lines = source.splitlines()
    if span.line == span.end_line and span.line <= len(lines):
        return lines[span.line - 1][span.column - 1:span.end_column - 1].strip()
    if span.line <= len(lines):
        return lines[span.line - 1][span.column - 1:].strip()
    return ""
