"""Counter saturation (``--reduce counters``): a region equivalence for
PCCL's discrete counters.

A ``loc:`` int variable ``x`` is a *saturable counter* when the program
only counts with it towards bounds it compares it with (the predicate
:func:`counter_problem` is the condition; docs/reductions.md, "Counter
saturation", has the proof):

* every read of ``x`` is an operand of a comparison ``x OP c`` or
  ``c OP x`` (``OP`` one of ``< <= > >= == !=``) whose other operand ``c``
  is a *bounded constant*: an int literal (or ``-literal``), or an int
  variable no statement assigns whose initialiser is a bounded constant or
  ``rand(c)`` of one (:func:`constant_max`), so that ``c`` never exceeds a
  number known before the search;
* or the right-hand side of its own increment ``x = x + n`` / ``x = n + x``
  with ``n`` an int literal >= 0;
* every other assignment to ``x`` (``x = e``) has a right-hand side that does
  not read ``x``;
* no property reads ``x``, and no temporal property is checked (a lasso of
  the quotient need not close over real states: a saturated counter may
  grow along it for ever).

Then with ``T`` = 1 + the largest bound ``x`` is compared with, two states
that differ only in values of saturable counters that are ``>= T`` are
bisimilar: every comparison gives the same result in both, an increment
keeps both ``>= T``, any other assignment gives both the same value.  The
key (:meth:`Counters.clamp`) stores ``min(x, T)``; the states themselves
keep their real values, so every trace is a run of the program.  The
native engine applies the same clamp in ``canon``
(:meth:`Counters.c_tables`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

from pccl.lang import ast as A
from pccl.model.layout import AGS, LOC

__all__ = ["COMPARISONS", "Counters", "constant_max", "counter_problem", "saturable_counters"]

#: The comparison operators a counter may be an operand of.
COMPARISONS = frozenset({"<", "<=", ">", ">=", "==", "!="})


def _program_stmts(program) -> list:
    """Every statement of the program (Init and the events, nested ones too)."""
    out = list(A.walk_stmts(program.init))
    for ev in program.events:
        out += list(A.walk_stmts(ev.body))
    return out


def _assigned(program) -> set:
    """Names some statement writes (an assignment to it or to a part of it,
    ``add``/``remove`` of it)."""
    out = set()
    for s in _program_stmts(program):
        if isinstance(s, A.Assign):
            t = s.target
            while isinstance(t, (A.Index, A.Field)):
                t = t.base
            if isinstance(t, A.Name):
                out.add(t.name)
        elif isinstance(s, A.CallStmt) and s.name in ("add", "remove") and s.args:
            t = s.args[0]
            while isinstance(t, (A.Index, A.Field)):
                t = t.base
            if isinstance(t, A.Name):
                out.add(t.name)
    return out


def _int_literal(e) -> Optional[int]:
    if isinstance(e, A.IntLit) and not isinstance(e.value, bool):
        return e.value
    if isinstance(e, A.Unary) and e.op == "-" and isinstance(e.operand, A.IntLit):
        return -e.operand.value
    return None


def constant_max(m, e, _seen: Optional[frozenset] = None) -> Optional[int]:
    """The largest value expression ``e`` can ever have in model ``m`` when
    ``e`` is a *bounded constant*, else None: an int literal or ``-literal``;
    the name of a scalar ``int`` variable (shared, allread or loc) that no
    statement writes and whose initialiser is a bounded constant, or
    ``rand(c)`` with ``c`` a bounded constant (``rand(c)`` is 0..c)."""
    v = _int_literal(e)
    if v is not None:
        return v
    if not isinstance(e, A.Name):
        return None
    seen = _seen or frozenset()
    vs = m.compiled.layout.vars.get(e.name)
    if vs is None or e.name in seen or vs.ty.kind != "int" or vs.decl.size is not None:
        return None
    if e.name in _assigned(m.program):
        return None
    init = vs.decl.init
    if init is None:
        return None
    seen = seen | {e.name}
    if isinstance(init, A.Call) and init.name == "rand" and len(init.args) == 1:
        return constant_max(m, init.args[0], seen)
    return constant_max(m, init, seen)


def _is_name(e, name: str) -> bool:
    return isinstance(e, A.Name) and e.name == name


def _uses(m, e, name: str, bounds: list) -> Optional[Any]:
    """Check the reads of ``name`` in expression ``e``: None when each is an
    operand of a comparison with a bounded constant (their maxima appended
    to ``bounds``), else the offending node."""
    stack = [e]
    while stack:
        n = stack.pop()
        if isinstance(n, A.Binary) and n.op in COMPARISONS and (
                _is_name(n.left, name) or _is_name(n.right, name)):
            other = n.right if _is_name(n.left, name) else n.left
            c = constant_max(m, other)
            if c is None:
                return n
            bounds.append(c)
            continue
        if _is_name(n, name):
            return n
        stack.extend(A.children(n))
    return None


def _increment(s, name: str) -> bool:
    """Whether ``s`` is ``name = name + n`` or ``name = n + name``, n an int literal >= 0."""
    v = s.value
    if not (isinstance(v, A.Binary) and v.op == "+"):
        return False
    if _is_name(v.left, name):
        n = _int_literal(v.right)
    elif _is_name(v.right, name):
        n = _int_literal(v.left)
    else:
        return False
    return n is not None and n >= 0


def _reads_problem(m, name: str, bounds: list) -> Optional[str]:
    """Why some read of ``name`` is not a comparison with a bounded constant
    or its own increment (None: each is; the constants' maxima appended to
    ``bounds``)."""
    prog = m.program

    def bad(node) -> str:
        return f"{name} is read other than compared with a bounded constant at line {node.span.line}"

    for d in prog.decls:
        if isinstance(d, A.VarDecl) and d.name != name:
            for x in (d.init, d.size):
                node = None if x is None else _uses(m, x, name, bounds)
                if node is not None:
                    return bad(node)
    for ev in prog.events:
        node = _uses(m, ev.guard, name, bounds)
        if node is not None:
            return bad(node)
    for s in _program_stmts(prog):
        if isinstance(s, A.Assign) and _is_name(s.target, name):
            if not _increment(s, name) and _uses(m, s.value, name, bounds) is not None:
                return (f"{name} is assigned a value that reads it other than as an increment by "
                        f"a literal >= 0 at line {s.span.line}")
            continue
        for x in A.own_exprs(s):
            node = _uses(m, x, name, bounds)
            if node is not None:
                return bad(node)
    return None


def counter_problem(m, name: str) -> tuple:
    """``(reason, cap)``: why ``loc:`` variable ``name`` of model ``m`` is
    not a saturable counter (reason None: it is, and values ``>= cap`` are
    interchangeable).  The soundness condition of docs/reductions.md:
    a scalar ``int`` ``loc:`` variable that no property reads, read only as
    an operand of a comparison with a bounded constant
    (:func:`constant_max`) or in its own increment by an int literal >= 0,
    every other assignment to it not reading it."""
    from pccl.model.independence import property_names
    vs = m.compiled.layout.vars.get(name)
    if vs is None or vs.section != "loc":
        return f"{name} is not a loc: variable", None
    if vs.ty.kind != "int" or vs.decl.size is not None:
        return f"{name} is not a scalar int", None
    if name in property_names(m):
        return f"a property reads {name}", None
    bounds: list = []
    why = _reads_problem(m, name, bounds)
    if why is not None:
        return why, None
    if not bounds:
        return f"nothing compares {name} (a value never read is the dead-variable reduction's)", None
    return None, 1 + max(bounds)


#: Caps beyond this are not used (the native vector's reserved codes sit
#: just above INT64_MIN; no real program compares with such numbers).
CAP_LIMIT = 1 << 62


def _compared_names(prog) -> set:
    """The names that stand as an operand of a comparison somewhere in the
    program: a counter is one of them ("something compares it"), so only
    they need :func:`counter_problem`'s walk over the whole program (which,
    for every ``loc:`` variable, made building a model of 2,000
    declarations quadratic)."""
    exprs: list = [x for d in prog.decls if isinstance(d, A.VarDecl)
                   for x in (d.init, d.size) if x is not None]
    exprs += [ev.guard for ev in prog.events]
    for s in _program_stmts(prog):
        exprs += A.own_exprs(s)
    out: set = set()
    for e in exprs:
        for n in A.walk_expr(e):
            if isinstance(n, A.Binary) and n.op in COMPARISONS:
                out |= {x.name for x in (n.left, n.right) if isinstance(x, A.Name)}
    return out


def saturable_counters(m) -> dict:
    """``{loc slot: cap}`` of every saturable counter of model ``m``
    (:func:`counter_problem`)."""
    out = {}
    compared = _compared_names(m.program)
    for vs in m.compiled.layout.local:
        if vs.name not in compared:      # nothing compares it: not a counter
            continue
        why, cap = counter_problem(m, vs.name)
        if why is None and -CAP_LIMIT < cap < CAP_LIMIT:
            out[vs.slot] = cap
    return out


def _conjuncts(e) -> list:
    """The operands of a chain of ``&&`` (``[e]`` for anything else)."""
    if isinstance(e, A.Binary) and e.op == "&&":
        return _conjuncts(e.left) + _conjuncts(e.right)
    return [e]


def _bounds_result(m, cond, name: str, n: int, cap: int) -> bool:
    """Whether comparison ``cond`` holding keeps ``name + n`` at most ``cap``:
    ``name < c`` (or ``c > name``) with c's maximum + n - 1 <= cap,
    ``name <= c`` (or ``c >= name``) with c's maximum + n <= cap."""
    if not isinstance(cond, A.Binary):
        return False
    if _is_name(cond.left, name) and cond.op in ("<", "<="):
        op, other = cond.op, cond.right
    elif _is_name(cond.right, name) and cond.op in (">", ">="):
        op, other = {">": "<", ">=": "<="}[cond.op], cond.left
    else:
        return False
    mx = constant_max(m, other)
    if mx is None:
        return False
    return mx + n - 1 <= cap if op == "<" else mx + n <= cap


def _guarded_increment(m, cond, body, name: str, cap: int) -> bool:
    """Whether ``body`` (an ``if`` branch taken, or an event's effect run,
    when ``cond`` holds) holds exactly one assignment to ``name``, a direct
    statement ``name = name + n``, and a conjunct of ``cond`` keeps the
    result at most ``cap`` (:func:`_bounds_result`).  ``name`` is ``loc:``
    and that increment is the body's only write to it: nothing changes it
    between the test and the increment."""
    writes = [s for s in A.walk_stmts(body) if isinstance(s, A.Assign) and _is_name(s.target, name)]
    if len(writes) != 1 or not any(s is writes[0] for s in body) or not _increment(writes[0], name):
        return False
    v = writes[0].value
    assert isinstance(v, A.Binary)          # _increment: name + n or n + name
    n = _int_literal(v.right if _is_name(v.left, name) else v.left) or 0
    return any(_bounds_result(m, c, name, n, cap) for c in _conjuncts(cond))


def can_exceed(m, name: str, cap: int) -> bool:
    """Whether saturable counter ``name`` may ever hold a value above ``cap``
    (False only when provably not: its initialiser and every assignment that
    is not an increment have a bounded-constant maximum <= cap, and every
    increment sits in an ``if`` branch whose own condition bounds the result
    by ``cap``, or is a direct statement of an event whose guard does,
    :func:`_guarded_increment`).  Where it cannot, the clamp never
    changes a key and ``auto`` leaves the reduction out."""
    vs = m.compiled.layout.vars[name]
    init = vs.decl.init
    if init is not None:
        if isinstance(init, A.Call) and init.name == "rand" and len(init.args) == 1:
            mx = constant_max(m, init.args[0])
        else:
            mx = constant_max(m, init)
        if mx is None or mx > cap:
            return True
    guarded: list = []
    stmts = _program_stmts(m.program)
    for ev in m.program.events:
        if _guarded_increment(m, ev.guard, ev.body, name, cap):
            guarded += ev.body
    for s in stmts:
        if isinstance(s, A.If):
            for cond, body in s.branches:
                if _guarded_increment(m, cond, body, name, cap):
                    guarded += body
    for s in stmts:
        if isinstance(s, A.Assign) and _is_name(s.target, name):
            if _increment(s, name):
                if not any(s is g for g in guarded):
                    return True
            else:
                mx = constant_max(m, s.value)
                if mx is None or mx > cap:
                    return True
    return False


def can_saturate(m) -> bool:
    """Whether some saturable counter of ``m`` may exceed its cap
    (:func:`can_exceed`): then the reduction merges something."""
    caps = saturable_counters(m)
    return any(can_exceed(m, vs.name, caps[vs.slot]) for vs in m.compiled.layout.local
               if vs.slot in caps)


def temporal_problem(m) -> Optional[str]:
    """Why counter saturation is off for the model's uses, or None."""
    if getattr(m, "temporal", None):
        return ("a temporal property needs real cycles for its lassos (a saturated "
                "counter may grow along a cycle of the quotient)")
    return None


@dataclass
class Counters:
    """The clamp of a model's saturable counters (slot -> cap)."""
    caps: dict

    @classmethod
    def of(cls, m) -> "Counters":
        return cls(saturable_counters(m))

    def clamp(self, st):
        """``st`` with every saturable counter ``x >= cap`` replaced by
        ``cap`` (a state for keys only)."""
        caps = self.caps
        ags = st[AGS]
        out: Optional[list] = None
        for i, ag in enumerate(ags):
            loc = ag[LOC]
            new = None
            for slot, cap in caps.items():
                v = loc[slot]
                if type(v) is int and v > cap:
                    if new is None:
                        new = list(loc)
                    new[slot] = cap
            if new is not None:
                if out is None:
                    out = list(ags)
                out[i] = ag[:LOC] + (tuple(new),) + ag[LOC + 1:]
        if out is None:
            return st
        return st[:AGS] + (tuple(out),) + st[AGS + 1:]

    def key_of(self, key) -> Any:
        """``key`` with saturable counters clamped first."""
        clamp = self.clamp

        def counters_key(st):
            return key(clamp(st))
        return counters_key

    def c_tables(self) -> list:
        """The C tables of ``ctrs_need(s)`` and ``ctrs_apply(s)`` over the
        native vector (pccl/model/native_c/reduced.c: every agent's loc:
        slot ``CTRSLOT[c]`` clamped to ``CTRCAP[c]``, the same clamp:
        reserved codes, below 0 of any cap's reach, are never > cap)."""
        if not self.caps:
            return ["#define CTRS 0"]
        caps = sorted(self.caps.items())
        return ["#define CTRS 1", f"#define NCTR {len(caps)}",
                f"static const int CTRSLOT[] = {{{', '.join(str(q) for q, _ in caps)}}};",
                f"static const V CTRCAP[] = {{{', '.join(f'{c}LL' for _, c in caps)}}};"]
