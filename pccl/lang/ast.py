"""PCCL abstract syntax: frozen dataclasses that carry their source span.

Every node has a ``span`` (line, column, end line, end column, all 1-based,
end column exclusive) so that every message can point at the source.  Spans do
not take part in equality or hashing, but every *statement* also carries a
unique ``sid`` (statement occurrence id, assigned by the parser in source
order) so that two textually equal statements at different places are
different items of an agent's pending computation ``k`` (docs/language.md
§11, "The configuration").

Declarations (variables, enums and their members, events, named invariants)
also carry the span of the declared name itself (``name_span``), so that a
message about a name points at the name.

The parser (``pccl.lang.parser``) builds these; the static checker
(``pccl.lang.checker``) reads them and fills in nothing: it only reports errors.
The compiler (``pccl.model.compile``) turns them into closures.  Traversals use
:func:`children` (the one function that knows each node's sub-nodes) through
:func:`walk`, :func:`walk_stmts` and :func:`walk_expr`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, Optional, Union


@dataclass(frozen=True)
class Span:
    line: int
    column: int
    end_line: int
    end_column: int
    #: (filename, source) of text that is not the program's own, such as an
    #: option's value (``--set k=...``); errors at this span point there.
    origin: Optional[tuple] = field(default=None, compare=False, repr=False)

    @staticmethod
    def unknown() -> "Span":
        return Span(0, 0, 0, 0)


def _span() -> Span:
    return field(default_factory=Span.unknown, compare=False, repr=False)


# --------------------------------------------------------------------------
# Types
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class TypeRef:
    """A written type.

    ``name`` is one of ``int``, ``bool``, ``float``, ``ItemPosition``,
    ``ObstacleList``, ``List`` or the name of a declared enum.  Aliases are
    normalised by the parser: ``boolean`` -> ``bool``, ``double`` -> ``float``.
    ``elem`` is the element type of ``List<T>``, else None.
    """
    name: str
    elem: Optional["TypeRef"] = None
    span: Span = _span()

    def __str__(self) -> str:
        return f"List<{self.elem}>" if self.name == "List" else self.name


# --------------------------------------------------------------------------
# Expressions
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class IntLit:
    value: int
    span: Span = _span()


@dataclass(frozen=True)
class FloatLit:
    value: float
    span: Span = _span()


@dataclass(frozen=True)
class BoolLit:
    value: bool
    span: Span = _span()


@dataclass(frozen=True)
class ListLit:
    items: tuple["Expr", ...]
    span: Span = _span()


@dataclass(frozen=True)
class Name:
    """A variable, enum member, or (in properties) ``time``/``N``/a bound id."""
    name: str
    span: Span = _span()


@dataclass(frozen=True)
class Index:
    """``base[index]``: array element, or agent j's component of an allread
    variable (``x[j]``), or in properties agent i's local (``v[i]``)."""
    base: "Expr"
    index: "Expr"
    span: Span = _span()


@dataclass(frozen=True)
class Field:
    """``base.name``: ``p.x``, ``p.y``, ``p.z``."""
    base: "Expr"
    name: str
    span: Span = _span()


@dataclass(frozen=True)
class Call:
    """``name(args)``: a built-in or uninterpreted function."""
    name: str
    args: tuple["Expr", ...]
    span: Span = _span()


@dataclass(frozen=True)
class Unary:
    """``op`` is ``-`` or ``!``."""
    op: str
    operand: "Expr"
    span: Span = _span()


@dataclass(frozen=True)
class Binary:
    """``op`` is one of ``|| && == != < <= > >= + - * / %`` and, in
    properties only, ``->``."""
    op: str
    left: "Expr"
    right: "Expr"
    span: Span = _span()


@dataclass(frozen=True)
class Quant:
    """Properties only: ``forall i: body`` / ``exists i: body`` over agent ids."""
    kind: str  # "forall" | "exists"
    var: str
    body: "Expr"
    span: Span = _span()


@dataclass(frozen=True)
class Temporal:
    """Properties only, at the top (under ``forall`` at most; spec section 9):
    ``eventually p``, ``reachable p``, ``p ~> q`` and ``p ~> q within bound``.
    ``kind`` is ``"eventually"``, ``"reachable"`` or ``"leadsto"``."""
    kind: str
    p: "Expr"
    q: Optional["Expr"] = None
    bound: Optional["Expr"] = None
    span: Span = _span()


Expr = Union[IntLit, FloatLit, BoolLit, ListLit, Name, Index, Field, Call,
             Unary, Binary, Quant, Temporal]


# --------------------------------------------------------------------------
# Statements (each has a unique sid)
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class Assign:
    """``target = value`` where target is a Name or an Index chain."""
    sid: int
    target: Expr
    value: Expr
    span: Span = _span()


@dataclass(frozen=True)
class If:
    """``if (c1): b1 else if (c2): b2 ... else: e``.

    ``branches`` holds (condition, body) pairs in order; ``orelse`` the else
    body (empty tuple when absent).  The whole chain is one statement.
    """
    sid: int
    branches: tuple[tuple[Expr, tuple["Stmt", ...]], ...]
    orelse: tuple["Stmt", ...]
    span: Span = _span()


@dataclass(frozen=True)
class While:
    sid: int
    cond: Expr
    body: tuple["Stmt", ...]
    span: Span = _span()


@dataclass(frozen=True)
class Atomic:
    sid: int
    body: tuple["Stmt", ...]
    span: Span = _span()


@dataclass(frozen=True)
class CallStmt:
    """A call used as a statement: ``doReach(t, o)``, ``exit()``,
    ``assert(e)``, ``add(xs, v)``, ``remove(xs, v)`` (or any other name,
    which the checker rejects)."""
    sid: int
    name: str
    args: tuple[Expr, ...]
    span: Span = _span()


@dataclass(frozen=True)
class Skip:
    sid: int
    span: Span = _span()


Stmt = Union[Assign, If, While, Atomic, CallStmt, Skip]


# --------------------------------------------------------------------------
# Declarations and program
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class VarDecl:
    """``T name = init;`` or ``T name[size];``.

    ``section`` is ``allwrite``, ``allread`` or ``loc`` (aliases MW, SW,
    local, Loc are normalised by the parser).
    """
    section: str
    type: TypeRef
    name: str
    size: Optional[Expr]
    init: Optional[Expr]
    span: Span = _span()
    name_span: Span = _span()        #: where ``name`` is written


@dataclass(frozen=True)
class EnumDecl:
    """``enum Stage { PICK, GO, DONE };`` in any declaration section."""
    section: str
    name: str
    members: tuple[str, ...]
    span: Span = _span()
    name_span: Span = _span()        #: where ``name`` is written
    #: where each member is written (parallel to ``members``)
    member_spans: tuple[Span, ...] = field(default=(), compare=False, repr=False)


@dataclass(frozen=True)
class Event:
    name: str
    guard: Expr
    body: tuple[Stmt, ...]
    span: Span = _span()
    name_span: Span = _span()        #: where ``name`` is written


@dataclass(frozen=True)
class Invariant:
    """``name: expr;`` (or unnamed ``expr;``) in the ``invariant:`` section."""
    name: Optional[str]
    expr: Expr
    span: Span = _span()
    name_span: Span = _span()        #: where ``name`` is written (when named)


@dataclass(frozen=True)
class Program:
    name: Optional[str]                 # from ``Agent::Name``
    decls: tuple[Union[VarDecl, EnumDecl], ...]
    init: tuple[Stmt, ...]
    events: tuple[Event, ...]
    invariants: tuple[Invariant, ...]
    filename: str = field(default="<input>", compare=False)
    source: str = field(default="", compare=False, repr=False)
    n_statements: int = field(default=0, compare=False)  # sids are 0..n-1
    #: the language of the source: "pccl", or "koord" for a Koord file read
    #: by pccl/lang/koord.py (it decides the default ``semantics``)
    language: str = field(default="pccl", compare=False)


Node = Union[Expr, Stmt, VarDecl, EnumDecl, Event, Invariant, Program]

#: Statement classes (the nodes with a ``sid``).
STMT_TYPES = (Assign, If, While, Atomic, CallStmt, Skip)


def _if_children(node: If) -> tuple:
    out: list = []
    for cond, body in node.branches:
        out.append(cond)
        out.extend(body)
    return (*out, *node.orelse)


#: node class -> its direct sub-nodes, in source order (read by ``children``)
_CHILDREN: dict[type, Callable[[Any], tuple]] = {
    **{k: lambda n: () for k in (IntLit, FloatLit, BoolLit, Name, Skip, TypeRef, EnumDecl)},
    ListLit: lambda n: n.items,
    Index: lambda n: (n.base, n.index),
    Field: lambda n: (n.base,),
    Call: lambda n: n.args,
    CallStmt: lambda n: n.args,
    Unary: lambda n: (n.operand,),
    Binary: lambda n: (n.left, n.right),
    Quant: lambda n: (n.body,),
    Temporal: lambda n: tuple(x for x in (n.p, n.q, n.bound) if x is not None),
    Assign: lambda n: (n.target, n.value),
    If: _if_children,
    While: lambda n: (n.cond, *n.body),
    Atomic: lambda n: n.body,
    VarDecl: lambda n: tuple(e for e in (n.size, n.init) if e is not None),
    Event: lambda n: (n.guard, *n.body),
    Invariant: lambda n: (n.expr,),
    Program: lambda n: (*n.decls, *n.init, *n.events, *n.invariants),
}


def children(node) -> tuple:
    """The direct sub-nodes of ``node`` in source order: expressions and
    statements, never types or spans.  Every traversal of the AST is built
    on this one function (as pyk's ``map_inner``), so a new node kind is
    added here (in ``_CHILDREN``) and nowhere else."""
    for cls in type(node).__mro__:
        sub = _CHILDREN.get(cls)
        if sub is not None:
            return sub(node)
    raise TypeError(f"not an AST node: {node!r}")


def walk(node):
    """Yield ``node`` and every node below it, in pre-order (source order).
    Iterative: a chain of 3,000 operators is 3,000 levels deep."""
    stack = [node]
    while stack:
        n = stack.pop()
        yield n
        stack.extend(reversed(children(n)))


def walk_stmts(stmts):
    """Yield every statement in ``stmts`` and its nested blocks, in order."""
    stack = list(reversed(stmts))
    while stack:
        s = stack.pop()
        yield s
        stack.extend(c for c in reversed(children(s)) if isinstance(c, STMT_TYPES))


def with_blocks(stmt, f):
    """``stmt`` with each block nested in it (if/else branches, a while's or
    an atomic's body) replaced by ``f(block)``; other statements unchanged."""
    if isinstance(stmt, If):
        return replace(stmt, branches=tuple((c, f(b)) for c, b in stmt.branches),
                       orelse=f(stmt.orelse))
    if isinstance(stmt, (While, Atomic)):
        return replace(stmt, body=f(stmt.body))
    return stmt


def own_exprs(stmt) -> tuple:
    """The expressions a statement evaluates itself (conditions, operands),
    not those of the statements nested in its blocks."""
    return tuple(c for c in children(stmt) if not isinstance(c, STMT_TYPES))


def index_chain(e):
    """Unwind ``a[i][j]`` into ``(a, (Index a[i], Index a[i][j]))``: the root
    expression and the Index nodes from the innermost out (source order)."""
    chain = []
    while isinstance(e, Index):
        chain.append(e)
        e = e.base
    chain.reverse()
    return e, tuple(chain)


def walk_expr(e):
    """Yield ``e`` and every sub-expression, in pre-order."""
    return walk(e)


def source_line(program: "Program", span) -> str:
    """The stripped text of the line ``span`` starts on ("" if none)."""
    if span is None or span.line <= 0:
        return ""
    lines = program.source.splitlines()
    if span.line <= len(lines):
        return lines[span.line - 1].strip()
    return ""
