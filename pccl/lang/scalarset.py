"""Agent ids as a type: the scalarset analysis behind the symmetry reduction.

Symmetry reduction (pccl/model/reduce.py) is sound when the transition relation
and every property are invariant under renaming the agents.  That holds
when agent ids are a *scalarset* (Murphi's term; UPPAAL's ``scalar``): values
that may only be compared for equality with each other, stored, and used to
pick an agent.  This module infers, for every expression of the program and
of its properties, whether it is an **id** (its value is an agent id, or a
negative sentinel such as ``-1``) or **plain**, and checks that every id is
used symmetrically.  The rules (docs/reductions.md, "The id type"):

Typing, ``Γ`` the id-valued variables (inferred below) and the quantified
variables of a property::

    getAgentIndex() : id              i : id   (i bound by forall/exists)
    x : id            if x ∈ Γ (an int scalar variable)
    x[j] : id         if x ∈ Γ and [j] is x's agent index (pccl.lang.types.indexes_agent)
    e : plain         otherwise

Uses: an expression of type id may appear only

* as an operand of ``==`` / ``!=`` whose other operand is an id or a
  negative integer constant;
* as the agent index of a per-agent variable (``x[j]``, ``x[j][k]``,
  ``pos[i]``, ``exited[i]`` … — the first index when indexes_agent says so);
* as the value assigned to (or initialising) a variable of Γ.

And an agent index must be an id (``inCs[0]`` names agent 0).  Everything
else — arithmetic, ``<``, an array or list index (``a[getAgentIndex()]``,
including an allread array's own element ``flags[getAgentIndex()]``), a
function argument, a list element, storing into a plain variable or an
array — turns symmetry off, with the expression and its line as the reason.

Γ is the greatest set of ``int`` scalar variables such that every
initialiser of and assignment to a member is an id (under Γ) or a negative
constant, and at least one is an id.  A variable without an initialiser
starts undefined, which is never an agent's id.

The one indexing rule (which index picks an agent) is
:func:`pccl.lang.types.indexes_agent`, the rule the checker types by and the
compiler compiles by.
"""

from __future__ import annotations

from typing import Optional

from pccl.lang import ast as A
from pccl.lang.types import indexes_agent

#: Per-agent names that exist only in properties (``pos[i]``, ``exited[i]``).
AGENT_PSEUDO = frozenset({"pos", "doReach_done", "doReach_fail", "exited", "stuck", "running"})


class Asymmetric(Exception):
    """An expression that tells agents apart; ``str()`` is the reason."""


def show(e) -> str:
    """An expression as PCCL text, parenthesised where the tree needs it."""
    if isinstance(e, A.Name):
        return e.name
    if isinstance(e, A.IntLit):
        return str(e.value)
    if isinstance(e, A.FloatLit):
        return repr(e.value)
    if isinstance(e, A.BoolLit):
        return "true" if e.value else "false"
    if isinstance(e, A.ListLit):
        return f"[{', '.join(show(x) for x in e.items)}]"
    if isinstance(e, A.Call):
        return f"{e.name}({', '.join(show(a) for a in e.args)})"
    if isinstance(e, A.Index):
        return f"{_operand(e.base)}[{show(e.index)}]"
    if isinstance(e, A.Field):
        return f"{_operand(e.base)}.{e.name}"
    if isinstance(e, A.Unary):
        return f"{e.op}{_operand(e.operand)}"
    if isinstance(e, A.Binary):
        return f"{_operand(e.left)} {e.op} {_operand(e.right)}"
    if isinstance(e, A.Quant):
        return f"{e.kind} {e.var}: {show(e.body)}"
    return "…"


def _operand(e) -> str:
    text = show(e)
    return f"({text})" if isinstance(e, (A.Binary, A.Quant)) else text


def is_sentinel(e) -> bool:
    """A negative integer constant (``-1``): never an agent id."""
    if isinstance(e, A.IntLit):
        return e.value < 0
    return (isinstance(e, A.Unary) and e.op == "-" and isinstance(e.operand, A.IntLit)
            and e.operand.value > 0)


def is_own_id(e) -> bool:
    """``getAgentIndex()``."""
    return isinstance(e, A.Call) and e.name == "getAgentIndex" and not e.args


class IdTypes:
    """The id type of a program and its properties.

    ``layout``: the configuration layout (``vars``: name -> slot with
    ``section``, ``ty``); ``program``: the AST (after ``--set``);
    ``stmts``: every statement (Init block and events);
    ``properties``: (expression, text) pairs.  After construction,
    ``ids`` is Γ and ``reason`` is None when every use is symmetric, else
    why not (the first asymmetric use found)."""

    def __init__(self, layout, program: A.Program, stmts, properties):
        self.lay = layout
        self.program = program
        self.stmts = list(stmts)
        self.properties = list(properties)
        self.defs = self._definitions()
        self.ids: frozenset = self._infer_ids()
        #: int variables that only ever hold negative constants: they may
        #: stand where an id or a sentinel is expected (and anywhere else)
        self.neutral = frozenset(n for n, es in self.defs.items()
                                 if self._scalar_int(n) and all(map(is_sentinel, es)))
        self.reason: Optional[str] = None
        try:
            self._check_all()
        except Asymmetric as e:
            self.reason = str(e)
        except RecursionError:
            self.reason = "an expression is too deeply nested for the agent-id analysis"

    # -- Γ -----------------------------------------------------------------------------
    def _definitions(self) -> dict:
        """name -> every expression assigned to the variable as a whole."""
        defs: dict = {}
        for d in self.program.decls:
            if isinstance(d, A.VarDecl) and d.init is not None:
                defs.setdefault(d.name, []).append(d.init)
        for s in self.stmts:
            if isinstance(s, A.Assign) and isinstance(s.target, A.Name):
                defs.setdefault(s.target.name, []).append(s.value)
        return defs

    def _scalar_int(self, name: str) -> bool:
        vs = self.lay.vars.get(name)
        return vs is not None and vs.ty.kind == "int"

    def _infer_ids(self) -> frozenset:
        cand = frozenset(n for n in self.defs if self._scalar_int(n))
        while True:
            self.ids = cand
            keep = frozenset(
                n for n in cand
                if all(is_sentinel(e) or self.typeof(e, False, frozenset()) for e in self.defs[n])
                and any(self.typeof(e, False, frozenset()) for e in self.defs[n]))
            if keep == cand:
                return cand
            cand = keep

    # -- typing ------------------------------------------------------------------------
    def agent_index(self, e: A.Index, prop: bool, bound) -> tuple:
        """``(root name, agent index, rest of the chain)`` when the first index
        of ``e``'s chain picks an agent, else ``(None, None, chain)``."""
        root, chain = A.index_chain(e)
        if isinstance(root, A.Name) and root.name not in bound:
            vs = self.lay.vars.get(root.name)
            if vs is not None:
                if indexes_agent(vs.section, vs.ty.kind == "array", len(chain), in_property=prop):
                    return root.name, chain[0].index, chain[1:]
            elif prop and root.name in AGENT_PSEUDO:
                return root.name, chain[0].index, chain[1:]
        return None, None, chain

    def typeof(self, e, prop: bool, bound) -> bool:
        """Is ``e`` of type id?"""
        if isinstance(e, A.Call):
            return is_own_id(e)
        if isinstance(e, A.Name):
            return e.name in bound or e.name in self.ids
        if isinstance(e, A.Index):
            name, _, rest = self.agent_index(e, prop, bound)
            return name is not None and not rest and name in self.ids
        return False

    def no_id(self, e) -> bool:
        """A negative constant, or a variable that only holds them."""
        return is_sentinel(e) or (isinstance(e, A.Name) and e.name in self.neutral)

    # -- uses --------------------------------------------------------------------------
    def _check_all(self) -> None:
        for d in self.program.decls:
            if isinstance(d, A.VarDecl):
                where = f"at line {d.span.line}"
                if d.size is not None:
                    self.use(d.size, None, where)
                if d.init is not None:
                    self.use(d.init, d.name if d.name in self.ids else None, where,
                             into=d.name)
        for s in self.stmts:
            where = f"at line {s.span.line}"
            if isinstance(s, A.Assign) and isinstance(s.target, A.Name):
                t = s.target.name
                self.use(s.value, t if t in self.ids else None, where, into=t)
            elif isinstance(s, A.Assign):
                self.use(s.target, None, where)
                self.use(s.value, None, where, into=show(s.target))
            else:
                for x in A.own_exprs(s):
                    self.use(x, None, where)
        for ev in self.program.events:
            self.use(ev.guard, None, f"in the guard of {ev.name} (line {ev.guard.span.line})")
        for expr, text in self.properties:
            self.use(expr, None, f"in property `{text}`", prop=True)

    def use(self, e, ok: Optional[str], where: str, *, prop: bool = False,
            bound=frozenset(), into: Optional[str] = None) -> None:
        """Check ``e`` where an id is welcome only if ``ok`` (a description of
        why, or None); raise :class:`Asymmetric` at the first bad use."""
        if self.typeof(e, prop, bound) and ok is None:
            if into is not None:
                raise Asymmetric(f"an agent id ({show(e)}) is stored in `{into}`, which does not "
                                 f"only hold agent ids, {where}")
            raise Asymmetric(f"an agent id ({show(e)}) is used other than in == or != with "
                             f"another id, or as an agent index, {where}")
        if isinstance(e, A.Quant):
            self.use(e.body, None, where, prop=prop, bound=bound | {e.var})
            return
        if isinstance(e, A.Binary) and e.op in ("==", "!="):
            li, ri = self.typeof(e.left, prop, bound), self.typeof(e.right, prop, bound)
            if li or ri:
                if (li or self.no_id(e.left)) and (ri or self.no_id(e.right)):
                    self.use(e.left, "compared", where, prop=prop, bound=bound)
                    self.use(e.right, "compared", where, prop=prop, bound=bound)
                    return
                raise Asymmetric(f"an agent id is compared with a value that is not an id "
                                 f"({show(e)}) {where}")
        if isinstance(e, A.Index):
            name, j, rest = self.agent_index(e, prop, bound)
            if name is not None:
                if not (self.typeof(j, prop, bound) or self.no_id(j)):
                    raise Asymmetric(f"{show(e)} names agent {show(j)} {where}")
                self.use(j, "agent index", where, prop=prop, bound=bound)
                for node in rest:
                    self.use(node.index, None, where, prop=prop, bound=bound)
                return
            root, chain = A.index_chain(e)
            self.use(root, None, where, prop=prop, bound=bound)
            for node in chain:
                if self.typeof(node.index, prop, bound):
                    raise Asymmetric(f"an agent id indexes {show(node.base)}, which is not "
                                     f"indexed by agent ({show(node)}) {where}")
                self.use(node.index, None, where, prop=prop, bound=bound)
            return
        for c in A.children(e):
            self.use(c, None, where, prop=prop, bound=bound)
