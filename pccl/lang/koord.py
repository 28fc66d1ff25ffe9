"""Koord front end: Koord source text -> :mod:`pccl.lang.ast`.

Koord (Ghosh, Mitra et al., OOPSLA 2020) is PCCL's successor.  This module
reads a Koord program (grammar ``koord.lark``, our own) into the same
:class:`pccl.lang.ast.Program` the PCCL parser builds, every node with its
span in the Koord file, so that the checker, the compiler, the model and
every tool work unchanged.  docs/koord.md lists the constructs and their
PCCL meaning; in short:

* ``using Motion:`` declares ports; ``Motion.target = p`` is
  ``doReach(p, [])``, ``Motion.position``/``psn`` is ``getPosition()``,
  ``Motion.reached``/``done`` is ``doReach_done``;
* ``allread:`` arrays ``T x[]`` (or ``T[] x``) are PCCL allread variables:
  ``x[pid] = e`` writes the robot's own component, ``x[j]`` reads robot j's;
* ``pid`` is ``getAgentIndex()``, ``numAgents`` ``getNumAgents()``,
  ``stop`` is ``exit()``; ``pos(x, y[, z])`` and ``(x, y[, z])`` are
  positions, ``midpoint(p, q)`` their midpoint; ``stdout << ...`` (a log
  line) is a ``skip``;
* events ``name:`` with ``pre: expr`` and ``eff:`` are PCCL events;
  ``init:`` the Init block; ``atomic:``, ``if``/``elif``/``else`` as in
  PCCL; ``and``/``or``/``not`` spell ``&&``/``||``/``!``.

``for i in range(a, b):`` is ``i = a`` and a ``while`` loop; ``for x in
xs:`` walks a hidden copy of the list with ``head``/``remove``; ``any(xs)``
and ``all(xs)`` are ``contains(xs, true)`` and ``!contains(xs, false)``.
Functions ``def fun f(T x, ...):`` are inlined where they are called
(:mod:`pccl.lang.koordfun`).  ``Motion.path = ps`` keeps the waypoints in a
hidden local list that a hidden first event ``Motion_follow`` walks with
``doReach``.  A variable of a record type (``def Name:``) is one variable
per leaf field, ``v_f`` (``v_f_g`` inside a nested record), arrays and
lists of records one array or list per field; ``Name(a, b)`` is a record
literal.  Every problem is a
:class:`pccl.lang.errors.PcclError` with file, line, column and caret.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from typing import Optional

from lark import Lark, Token, v_args
from lark.exceptions import (LarkError, UnexpectedCharacters, UnexpectedEOF,
                             UnexpectedInput, UnexpectedToken, VisitError)
from lark.indenter import DedentError

from pccl.lang import ast
from pccl.lang import koordfun as F
from pccl.lang import parser as P
from pccl.lang.errors import PcclError

#: (which files are Koord, ``is_koord_path``, is pccl.lang.files's: reading a
#: PCCL file imports no Koord front end)
__all__ = ["parse_koord", "parse_koord_file"]

_GRAMMAR_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "koord.lark")


# --------------------------------------------------------------------------
# Lexing: indentation, and the constructs not supported yet
# --------------------------------------------------------------------------

#: Words refused at the lexer with their message (none now: functions and
#: record types are read).
_UNSUPPORTED_TOKENS: dict = {}


class _Unsupported(Exception):
    def __init__(self, message: str, tok: Token):
        super().__init__(message)
        self.message = message
        self.tok = tok


class _KoordIndenter(P._PcclIndenter):
    def _process(self, stream):
        for tok in super()._process(stream):
            if tok.type == "IDENT" and tok.value in _UNSUPPORTED_TOKENS:
                raise _Unsupported(_UNSUPPORTED_TOKENS[tok.value], tok)
            yield tok

    def process(self, stream):
        return _KoordIndenter()._process(stream)


_LARK: Optional[Lark] = None


def _get_lark() -> Lark:
    global _LARK
    if _LARK is None:
        with open(_GRAMMAR_PATH, encoding="utf-8") as f:
            grammar = f.read()
        path = P._lark_cache(grammar)
        _LARK = Lark(grammar, parser="lalr", lexer="basic", start="program",
                     postlex=_KoordIndenter(), propagate_positions=True,
                     maybe_placeholders=False, cache=path if path is not None else False)
    return _LARK


# --------------------------------------------------------------------------
# Tree -> AST
# --------------------------------------------------------------------------

_Syntax = P._Syntax
_tspan = P._tspan
_mspan = P._mspan
_NO_SID = P._NO_SID

_OPS = {"and": "&&", "or": "||", "not": "!"}

#: Koord base types -> PCCL type names.
_BASE_TYPES = {"int": "int", "float": "float", "double": "float", "bool": "bool",
               "boolean": "bool", "pos": "ItemPosition"}
_UNSUPPORTED_TYPES = ("stream", "queue", "map", "inputMap")
#: Koord's ``string``: an enum of this name whose members are the program's
#: string literals, each written with its quotes (docs/koord.md, "Strings";
#: :func:`_strings`)
STRING_TYPE = "string"

#: list methods: ``xs.size()`` is ``size(xs)`` ...
_METHODS = {"size": "size", "isEmpty": "isEmpty", "contains": "contains", "head": "head",
            "empty": "isEmpty", "length": "size"}
_METHOD_STMTS = {"add": "add", "append": "add", "remove": "remove"}

_POS = ast.TypeRef("ItemPosition")
_BOOL = ast.TypeRef("bool")
#: The ports pccl knows: module -> port -> (kind, type or None, meaning).
_PORTS: dict[str, dict[str, tuple[str, Optional[ast.TypeRef]]]] = {
    "Motion": {
        "position": ("sensors", _POS), "psn": ("sensors", _POS),
        "reached": ("sensors", _BOOL), "done": ("sensors", _BOOL),
        "target": ("actuators", _POS),
        "path": ("actuators", ast.TypeRef("List", _POS)),
        "route": ("actuators", ast.TypeRef("List", _POS)),
    },
    "Log": {"stdout": ("actuators", None), "stdin": ("sensors", None)},
}


@dataclasses.dataclass
class _Dim:
    size: Optional[ast.Expr]
    span: ast.Span


@dataclasses.dataclass
class _KType:
    name: str
    elem: Optional["_KType"]
    dims: list
    span: ast.Span
    name_span: ast.Span


@dataclasses.dataclass
class _KDecl:
    type: _KType
    name: str
    dims: list
    init: Optional[ast.Expr]
    span: ast.Span
    name_span: ast.Span


@dataclasses.dataclass
class _KSection:
    kind: str
    decls: list
    span: ast.Span


@dataclasses.dataclass
class _KRecord:
    """``def Name:`` with its field declarations (a record type)."""
    name: str
    span: ast.Span
    fields: list           # _KDecl


@dataclasses.dataclass
class _KModule:
    name: str
    span: ast.Span
    ports: list            # (kind, _KDecl)


@dataclasses.dataclass
class _Ref:
    """A record-valued expression: its record type, and ``leaf(path)`` the
    expression of the leaf field at ``path`` (a tuple of field names)."""
    rec: _KRecord
    leaf: Callable[[tuple], ast.Expr]


@dataclasses.dataclass(frozen=True)
class _ForList(ast.While):
    """``for x in xs:`` while the program is read: ``cond`` holds xs (so that
    the function inliner rewrites it) until the resolver lowers the loop."""
    var: Optional[ast.Name] = None


#: any(xs) / all(xs) over a list of booleans
_ANY_ALL = ("any", "all")


def _pos_call(args, span) -> ast.Call:
    return ast.Call("ItemPosition", tuple(args), span)


def _midpoint(a: ast.Expr, b: ast.Expr, span: ast.Span) -> ast.Expr:
    def half(c):
        total = ast.Binary("+", ast.Field(a, c, span), ast.Field(b, c, span), span)
        return ast.Binary("/", total, ast.FloatLit(2.0, span), span)
    return _pos_call([half("x"), half("y"), half("z")], span)


@v_args(meta=True)
class _ToAst(P._ToAst):
    """The PCCL transformer, with Koord's rules on top: the expression and
    statement methods it inherits build the same nodes."""

    # ---- expressions -----------------------------------------------------

    def binop(self, meta, children):
        left, op, right = children
        return ast.Binary(_OPS.get(str(op), str(op)), left, right, _mspan(meta))

    def unop(self, meta, children):
        op, operand = children
        return ast.Unary(_OPS.get(str(op), str(op)), operand, _mspan(meta))

    def string_lit(self, meta, children):
        """``"text"``: the member ``"text"`` (quotes included) of the enum
        ``string`` (:func:`_strings`)."""
        return ast.Name(str(children[0]), _tspan(children[0]))

    def pid(self, meta, children):
        return ast.Call("getAgentIndex", (), _tspan(children[0]))

    def num_agents(self, meta, children):
        return ast.Call("getNumAgents", (), _tspan(children[0]))

    def tuple_lit(self, meta, children):
        return _pos_call(children, _mspan(meta))

    def call(self, meta, children):
        name, args, span = str(children[0]), list(children[1:]), _mspan(meta)
        if name == "pos":
            if len(args) not in (2, 3):
                raise _Syntax(f"pos takes 2 or 3 coordinates, not {len(args)}", span)
            return _pos_call(args, span)
        if name == "pos3d":
            if len(args) != 3:
                raise _Syntax(f"pos3d takes 3 coordinates, not {len(args)}", span)
            return _pos_call(args, span)
        if name == "midpoint":
            if len(args) != 2:
                raise _Syntax(f"midpoint takes 2 positions, not {len(args)}", span)
            return _midpoint(args[0], args[1], span)
        return ast.Call(name, tuple(args), span)

    def method(self, meta, children):
        base, name, args = children[0], str(children[1]), children[2:]
        span = _mspan(meta)
        if name not in _METHODS:
            raise _Syntax(f"unknown method '{name}' (lists have "
                          f"{', '.join(sorted(_METHODS))}; as statements "
                          f"{', '.join(sorted(_METHOD_STMTS))})", _tspan(children[1]))
        return ast.Call(_METHODS[name], (base, *args), span)

    # ---- statements ------------------------------------------------------

    def method_stmt(self, meta, children):
        base, name, args = children[0], str(children[1]), children[2:]
        if name not in _METHOD_STMTS:
            raise _Syntax(f"'{name}' is not a statement method (lists have "
                          f"{', '.join(sorted(_METHOD_STMTS))})", _tspan(children[1]))
        return ast.CallStmt(_NO_SID, _METHOD_STMTS[name], (base, *args), _mspan(meta))

    def return_stmt(self, meta, children):
        return F.Return(children[1], _mspan(meta))

    # ---- functions -------------------------------------------------------

    def fundef(self, meta, children):
        name, params, body = children[2], children[3:-1], children[-1]
        return F.Function(str(name), _tspan(name), list(params), body, _mspan(meta))

    def recdef(self, meta, children):
        name = children[1]
        return _KRecord(str(name), _tspan(name), [c for c in children[2:] if isinstance(c, _KDecl)])

    def param(self, meta, children):
        return (str(children[1]), _tspan(children[1]))

    def stop_stmt(self, meta, children):
        return ast.CallStmt(_NO_SID, "exit", (), _tspan(children[0]))

    def log_stmt(self, meta, children):
        target = children[0]
        ok = (isinstance(target, ast.Name) and target.name == "stdout") or (
            isinstance(target, ast.Field) and target.name == "stdout"
            and isinstance(target.base, ast.Name) and target.base.name == "Log")
        if not ok:
            raise _Syntax("'<<' writes a log line: its left side is 'stdout' or 'Log.stdout'",
                          target.span)
        # A log line changes nothing pccl models: it is a skip (docs/koord.md).
        return ast.Skip(_NO_SID, _mspan(meta))

    def block(self, meta, children):
        out: list = []
        for c in children:
            out.extend(c if isinstance(c, list) else (c,))
        return tuple(out)

    def for_stmt(self, meta, children):
        """``for i in range(a, b): body`` is ``i = a`` then ``while i < b:
        body; i = i + 1`` (``range(b)``: from 0); ``i`` a declared int."""
        var, span, body = children[1], _mspan(meta), children[-1]
        if not (isinstance(children[2], Token) and children[2].type == "IN"):
            # for i = a, b:  (Koord's form, its bounds' inclusiveness unclear)
            raise _Syntax("Koord's 'for i = a, b:' is not supported: its published grammar "
                          "and documents do not say whether b is included; write 'for i in "
                          "range(a, b):' (i from a to b - 1) or 'range(a, b + 1)'", span)
        rng = children[3]
        if not (isinstance(rng, ast.Call) and rng.name == "range"):
            # for x in xs: over a list, lowered by the resolver (it knows x's type)
            return [_ForList(_NO_SID, rng, body, span, var=ast.Name(str(var), _tspan(var)))]
        if not 1 <= len(rng.args) <= 2:
            raise _Syntax(f"range takes 1 or 2 bounds, not {len(rng.args)}", rng.span)
        lo, hi = (ast.IntLit(0, rng.span), rng.args[0]) if len(rng.args) == 1 else rng.args
        i = ast.Name(str(var), _tspan(var))
        step = ast.Assign(_NO_SID, i, ast.Binary("+", i, ast.IntLit(1, span), span), span)
        return [ast.Assign(_NO_SID, i, lo, span),
                ast.While(_NO_SID, ast.Binary("<", i, hi, span), (*body, step), span)]

    def elif_clause(self, meta, children):
        return ("elif", children[-2], children[-1])

    def effect(self, meta, children):
        return (children[0], children[1])

    def init_sec(self, meta, children):
        return ("init", children[1])

    def guard(self, meta, children):
        return children[1]

    # ---- declarations ----------------------------------------------------

    def dim(self, meta, children):
        return _Dim(children[0] if children else None, _mspan(meta))

    def type_arg(self, meta, children):
        return children[0]

    def type(self, meta, children):
        tok = children[0]
        elem = None
        rest = children[1:]
        if rest and isinstance(rest[0], _KType):
            elem, rest = rest[0], rest[1:]
        return _KType(str(tok), elem, list(rest), _mspan(meta), _tspan(tok))

    def vardecl(self, meta, children):
        typ, tok = children[0], children[1]
        dims = [c for c in children[2:] if isinstance(c, _Dim)]
        init = next((c[1] for c in children[2:] if isinstance(c, tuple)), None)
        return _KDecl(typ, str(tok), dims, init, _mspan(meta), _tspan(tok))

    def decl_sec(self, meta, children):
        return _KSection(str(children[0]), list(children[1:]), _tspan(children[0]))

    def port_sec(self, meta, children):
        return [(str(children[0]), d) for d in children[1:]]

    def module(self, meta, children):
        name = children[1]
        ports = [p for sec in children[2:] for p in sec]
        return _KModule(str(name), _tspan(name), ports)

    # ---- program ---------------------------------------------------------

    def program(self, meta, children):
        modules = [c for c in children if isinstance(c, _KModule)]
        sections = [c for c in children if isinstance(c, _KSection)]
        events = [c for c in children if isinstance(c, ast.Event)]
        init: tuple = ()
        invariants: tuple = ()
        for c in children:
            if isinstance(c, tuple) and c[0] == "init":
                init = c[1]
            elif isinstance(c, tuple) and c[0] == "invariants":
                invariants = c[1]
        try:
            funs = F.Functions([c for c in children if isinstance(c, F.Function)])
            init = funs.stmts(init)
            events = [dataclasses.replace(ev, guard=funs.expr(ev.guard), body=funs.stmts(ev.body))
                      for ev in events]
            invariants = tuple(dataclasses.replace(inv, expr=funs.expr(inv.expr))
                               for inv in invariants)
        except F.FunctionError as e:
            raise _Syntax(e.message, e.span) from None
        records = [c for c in children if isinstance(c, _KRecord)]
        return _Resolver(modules, sections, records).program(init, events, invariants)


# --------------------------------------------------------------------------
# Koord names -> PCCL meaning (ports, allread arrays, types)
# --------------------------------------------------------------------------

class _Resolver:
    def __init__(self, modules: list, sections: list, records: Optional[list] = None):
        #: record types: name -> _KRecord; record variables: name -> its record
        self.records: dict[str, _KRecord] = {}
        self.record_vars: dict[str, _KRecord] = {}
        self.record_spans: dict[str, ast.Span] = {}
        #: a record variable's flat variable -> (the record variable, the field path)
        self.flat_root: dict[str, tuple] = {}
        #: the hidden lists of `for x in xs:` loops (name -> VarDecl), and the
        #: loops being read (to refuse a loop over x inside a loop over x)
        self.hidden: dict[str, ast.VarDecl] = {}
        self._loops: list = []
        names = {r.name for r in records or ()}
        for r in records or ():
            self._record(r, names)
        self.ports: dict[str, dict[str, str]] = {}      # module -> port -> kind
        #: where Motion.path (or route) is declared, if it is
        self.path: Optional[ast.Span] = None
        for m in modules:
            self._module(m)
        self.allread: set[str] = set()
        self.decls: list = []
        seen: set[str] = set()
        for sec in sections:
            if sec.kind in seen:
                raise _Syntax(f"a second '{sec.kind}:' section (declare its variables in the "
                              f"first one)", sec.span)
            seen.add(sec.kind)
            for d in sec.decls:
                if d.type.name in self.records:
                    self.decls.extend(self._record_decls(sec.kind, d))
                else:
                    self.decls.append(self._decl(sec.kind, d))
        self._check_flat_names()

    # ---- records -----------------------------------------------------

    def _record(self, r: _KRecord, names: set) -> None:
        if r.name in self.records:
            raise _Syntax(f"record type '{r.name}' is defined twice", r.span)
        if (r.name in _BASE_TYPES or r.name in ("list", "List", STRING_TYPE)
                or r.name in _UNSUPPORTED_TYPES):
            raise _Syntax(f"'{r.name}' is a type already: choose another name", r.span)
        seen: set = set()
        for f in r.fields:
            if f.name in seen:
                raise _Syntax(f"field '{f.name}' of '{r.name}' is declared twice", f.name_span)
            seen.add(f.name)
            if f.type.name == r.name:
                raise _Syntax(f"record '{r.name}' cannot contain itself", f.type.name_span)
            if f.type.name in names and f.type.name not in self.records:
                raise _Syntax(f"define record type '{f.type.name}' before '{r.name}', which "
                              "uses it", f.type.name_span)
            if f.type.name in self.records and f.init is not None:
                raise _Syntax(f"a record field takes its initial values from 'def "
                              f"{f.type.name}:'", f.init.span)
        if not r.fields:
            raise _Syntax(f"record type '{r.name}' has no field", r.span)
        self.records[r.name] = r

    def _leaves(self, rec: _KRecord) -> list:
        """``(path, leaf field, dims)`` of each scalar, list or array field
        of ``rec``, inside nested records too; ``dims`` are the dimensions
        of the record fields on the way, then the leaf's own."""
        out = []
        for f in rec.fields:
            fdims = list(f.type.dims) + list(f.dims)
            sub = self.records.get(f.type.name)
            if sub is None:
                out.append(((f.name,), f, fdims))
            else:
                out.extend(((f.name,) + p, leaf, fdims + dims) for p, leaf, dims in self._leaves(sub))
        return out

    def _default(self, rec: _KRecord, path: tuple) -> Optional[ast.Expr]:
        f = next(f for f in rec.fields if f.name == path[0])
        sub = self.records.get(f.type.name)
        return self._default(sub, path[1:]) if sub is not None else f.init

    def _record_decls(self, kind: str, d: _KDecl) -> list:
        """``Name v`` (``Name v[]`` in allread:, ``Name v[n]`` an array,
        ``Name[] v`` a list): one variable ``v_f`` per (nested) field ``f``,
        with the field's type, the variable's dimensions first."""
        rec = self.records[d.type.name]
        dims = list(d.type.dims) + list(d.dims)
        if kind == "allread" and (not dims or dims[0].size is not None):
            where = dims[0].span if dims else d.name_span
            raise _Syntax(f"an allread record is an array indexed by robot, written without a "
                          f"size: '{rec.name} {d.name}[]'", where)
        own = dims[1:] if kind == "allread" else dims
        listy = any(x.size is None for x in own)
        init: Optional[_Ref] = None
        items: Optional[list] = None
        if d.init is not None:
            if listy and isinstance(d.init, ast.ListLit):
                items = [self._record_value(x, rec) for x in d.init.items]
            elif listy:
                raise _Syntax(f"a list of {rec.name} records starts as a list of record literals, "
                              f"'[{rec.name}(...), ...]' (or '[]')", d.init.span)
            else:
                init = self._ref(d.init)
                if init is None or init.rec is not rec or not isinstance(d.init, ast.Call):
                    raise _Syntax(f"a {rec.name} variable's initial value is a record literal "
                                  f"'{rec.name}(...)' (or none: the fields' initialisers in "
                                  f"'def {rec.name}:')", d.init.span)
        self.record_vars[d.name] = rec
        self.record_spans[d.name] = d.name_span
        out = []
        for path, leaf, inner in self._leaves(rec):
            name = f"{d.name}_{'_'.join(path)}"
            value: Optional[ast.Expr]
            if items is not None:
                value = ast.ListLit(tuple(r.leaf(path) for r in items), d.span)
            elif init is not None:
                value = init.leaf(path)
            else:
                # an array's initialiser is every element's; a list starts undefined
                value = None if listy else self._default(rec, path)
            fd = _KDecl(dataclasses.replace(leaf.type, dims=[]), name, dims + inner, value,
                        d.span, d.name_span)
            self.flat_root[name] = (d.name, path)
            out.append(self._decl(kind, fd))
        return out

    def _check_flat_names(self) -> None:
        names = [d.name for d in self.decls]
        for flat, (v, path) in self.flat_root.items():
            if names.count(flat) > 1:
                # the other declaration, not the record variable's field
                d = next(d for d in self.decls if d.name == flat
                         and not (d.name_span == self.record_spans.get(v)))
                raise _Syntax(f"'{flat}' is the name pccl gives field '{'.'.join(path)}' of "
                              f"record variable '{v}': choose another name", d.name_span or d.span)

    def _field(self, rec: _KRecord, e: ast.Field):
        f = next((f for f in rec.fields if f.name == e.name), None)
        if f is None:
            raise _Syntax(f"record '{rec.name}' has no field '{e.name}' (its fields: "
                          f"{', '.join(f.name for f in rec.fields)})", e.span)
        return f

    def _ref(self, e) -> Optional["_Ref"]:
        """A record-valued expression (a record variable, an element of an
        array or list of records, a record field of a record, a record
        literal, ``head`` of a list of records): its record type and the
        expression of each leaf field; None for anything else."""
        if isinstance(e, ast.Name) and e.name in self.record_vars:
            v = e.name
            return _Ref(self.record_vars[v], lambda p: ast.Name(f"{v}_{'_'.join(p)}", e.span))
        if isinstance(e, ast.Index):
            b = self._ref(e.base)
            if b is None:
                return None
            k, base = self.expr(e.index), b

            def element(p: tuple) -> ast.Expr:
                return ast.Index(base.leaf(p), k, e.span)
            return _Ref(b.rec, element)
        if isinstance(e, ast.Field):
            b = self._ref(e.base)
            if b is None:
                return None
            sub = self.records.get(self._field(b.rec, e).type.name)
            if sub is None:
                return None
            outer, name = b, e.name

            def inner(p: tuple) -> ast.Expr:
                return outer.leaf((name,) + p)
            return _Ref(sub, inner)
        if isinstance(e, ast.Call):
            if e.name in self.records:
                return self._literal(e)
            if e.name == "head" and len(e.args) == 1:
                b = self._ref(e.args[0])
                if b is not None:
                    return _Ref(b.rec, lambda p: ast.Call("head", (b.leaf(p),), e.span))
        return None

    def _record_value(self, e, rec: _KRecord) -> "_Ref":
        r = self._ref(e)
        if r is None or r.rec is not rec:
            raise _Syntax(f"a {rec.name} record is expected here (a variable, an element or a "
                          f"literal {rec.name}(...))", e.span)
        return r

    def _literal(self, e: ast.Call) -> "_Ref":
        """``Name(a, b, ...)``: a record literal, its fields in declaration
        order; a field left out takes its initialiser in ``def Name:``."""
        rec = self.records[e.name]
        if len(e.args) > len(rec.fields):
            raise _Syntax(f"record '{rec.name}' has {len(rec.fields)} field"
                          f"{'' if len(rec.fields) == 1 else 's'} "
                          f"({', '.join(f.name for f in rec.fields)})", e.args[len(rec.fields)].span)
        vals: dict = {}
        for f, a in zip(rec.fields, e.args):
            sub = self.records.get(f.type.name)
            if sub is not None:
                vals[f.name] = self._record_value(a, sub)
            elif self._ref(a) is not None:
                raise _Syntax(f"field '{f.name}' of '{rec.name}' is not a record", a.span)
            else:
                vals[f.name] = a
        for path, _, _ in self._leaves(rec):
            if path[0] not in vals and self._default(rec, path) is None:
                raise _Syntax(f"'{rec.name}(...)' gives no value to field '{'.'.join(path)}', "
                              f"which has no initialiser in 'def {rec.name}:'", e.span)

        def leaf(p):
            v = vals.get(p[0])
            if v is None:
                return self._default(rec, p)
            return v.leaf(p[1:]) if isinstance(v, _Ref) else v
        return _Ref(rec, leaf)

    def _whole(self, e, r: "_Ref"):
        if isinstance(e, ast.Name):
            return _Syntax(f"'{e.name}' is a record ({r.rec.name}): read one of its fields, e.g. "
                           f"'{e.name}.{r.rec.fields[0].name}'", e.span)
        return _Syntax(f"this is a record ({r.rec.name}): read one of its fields "
                       f"({', '.join(f.name for f in r.rec.fields)})", e.span)

    # ---- modules -----------------------------------------------------

    def _module(self, m: _KModule) -> None:
        known = _PORTS.get(m.name)
        if known is None:
            raise _Syntax(f"unknown module '{m.name}' (pccl knows {', '.join(sorted(_PORTS))})",
                          m.span)
        if m.name in self.ports:
            raise _Syntax(f"module '{m.name}' is declared twice", m.span)
        ports: dict[str, str] = {}
        for kind, d in m.ports:
            if d.name not in known:
                raise _Syntax(f"'{d.name}' is not a port of {m.name} (its ports: "
                              f"{', '.join(sorted(known))})", d.name_span)
            want_kind, want_type = known[d.name]
            if kind != want_kind:
                raise _Syntax(f"{m.name}.{d.name} is one of the {want_kind}, not the {kind}",
                              d.name_span)
            if d.init is not None:
                raise _Syntax(f"port {m.name}.{d.name} cannot be given a value here",
                              d.init.span)
            if want_type is not None:
                got = self._type(d.type, d.dims)
                if got[0] != want_type or got[1] is not None:
                    raise _Syntax(f"port {m.name}.{d.name} has type {_koord_type(want_type)}",
                                  d.type.span)
            if d.name in ports:
                raise _Syntax(f"port {m.name}.{d.name} is declared twice", d.name_span)
            ports[d.name] = kind
            if m.name == "Motion" and d.name in ("path", "route"):
                self.path = d.name_span
        self.ports[m.name] = ports

    # ---- declarations ------------------------------------------------

    def _base(self, t: _KType) -> ast.TypeRef:
        if t.name in ("list", "List"):
            if t.elem is None:
                raise _Syntax("'list' needs an element type, e.g. 'list<int>' or 'int[]'",
                              t.name_span)
            elem, size = self._type(t.elem, [])
            if size is not None:
                raise _Syntax("a list's elements cannot be sized arrays", t.elem.span)
            return ast.TypeRef("List", elem, t.span)
        if t.elem is not None:
            raise _Syntax(f"only 'list' takes a type argument, not '{t.name}'", t.span)
        if t.name in _BASE_TYPES:
            return ast.TypeRef(_BASE_TYPES[t.name], None, t.name_span)
        if t.name == STRING_TYPE:
            return ast.TypeRef(STRING_TYPE, None, t.name_span)
        if t.name in _UNSUPPORTED_TYPES:
            raise _Syntax(f"type '{t.name}' is not supported yet by pccl's Koord front end",
                          t.name_span)
        raise _Syntax(f"unknown type '{t.name}' (Koord types here: int, float, bool/boolean, "
                      f"pos, string, T[] and list<T>)", t.name_span)

    def _type(self, t: _KType, name_dims: list) -> tuple:
        """(TypeRef, size or None) of ``t`` with the dimensions after the name."""
        typ = self._base(t)
        dims = t.dims + name_dims
        size = None
        # the innermost dimension is written last: T[a][b] is a list of b's
        for i, d in enumerate(dims):
            if d.size is None:
                if size is not None:
                    raise _Syntax("a sized array cannot be a list's element", d.span)
                typ = ast.TypeRef("List", typ, t.span)
            else:
                if i != len(dims) - 1:
                    raise _Syntax("only the last dimension may have a size", d.span)
                size = d.size
        return typ, size

    def _decl(self, kind: str, d: _KDecl) -> ast.VarDecl:
        section = {"allwrite": "allwrite", "allread": "allread", "local": "loc"}[kind]
        dims = d.type.dims + d.dims
        if section == "allread":
            if not dims or dims[0].size is not None:
                where = dims[0].span if dims else d.name_span
                raise _Syntax(f"an allread variable is an array indexed by robot, written "
                              f"without a size: '{d.type.name} {d.name}[]' "
                              f"(x[pid] is this robot's entry)", where)
            self.allread.add(d.name)
            if d.type.dims:
                t = dataclasses.replace(d.type, dims=d.type.dims[1:])
                typ, size = self._type(t, d.dims)
            else:
                typ, size = self._type(d.type, d.dims[1:])
        else:
            typ, size = self._type(d.type, d.dims)
        init = self.expr(d.init) if d.init is not None else None
        return ast.VarDecl(section, typ, d.name, self.expr(size) if size is not None else None,
                           init, d.span, name_span=d.name_span)

    # ---- expressions -------------------------------------------------

    def _port(self, e: ast.Field, use: str) -> tuple[str, str]:
        assert isinstance(e.base, ast.Name)
        module, port = e.base.name, e.name
        if module not in self.ports:
            raise _Syntax(f"module '{module}' is not declared: add 'using {module}:' with "
                          f"its sensors: and actuators:", e.base.span)
        if port not in self.ports[module]:
            declared = ", ".join(sorted(self.ports[module])) or "none"
            raise _Syntax(f"'{module}.{port}' is not declared in 'using {module}:' "
                          f"(declared: {declared})", e.span)
        return module, port

    def _is_port(self, e) -> bool:
        return (isinstance(e, ast.Field) and isinstance(e.base, ast.Name)
                and (e.base.name in _PORTS or e.base.name in self.ports))

    def _mentions_module(self, e) -> bool:
        recs = self.record_vars
        return any(self._is_port(n)
                   or (isinstance(n, ast.Name) and (n.name in _PORTS or n.name in recs))
                   or (isinstance(n, ast.Call) and (n.name in self.records or n.name in _ANY_ALL))
                   for n in ast.walk(e))

    def _decl_of(self, name: str) -> Optional[ast.VarDecl]:
        return next((d for d in self.decls if d.name == name), None)

    def _any_all(self, e: ast.Call) -> ast.Expr:
        """``any(xs)`` is ``contains(xs, true)``, ``all(xs)`` is
        ``!contains(xs, false)``: xs a list of booleans."""
        if len(e.args) != 1:
            raise _Syntax(f"{e.name} takes one list of booleans, not {len(e.args)} arguments",
                          e.span)
        arg = e.args[0]
        typ = self._static_type(arg)
        if typ is not None and not (typ.name == "List" and typ.elem is not None
                                    and typ.elem.name == "bool"):
            raise _Syntax(f"{e.name} takes a list of booleans (boolean[]), not "
                          f"{_koord_type(typ)}", arg.span)
        xs = self.expr(arg)
        if e.name == "any":
            return ast.Call("contains", (xs, ast.BoolLit(True, e.span)), e.span)
        return ast.Unary("!", ast.Call("contains", (xs, ast.BoolLit(False, e.span)), e.span),
                         e.span)

    def _static_type(self, e) -> Optional[ast.TypeRef]:
        """The type of a variable or an element of one, as far as the front
        end knows it (None: left to the checker)."""
        if isinstance(e, ast.ListLit):
            if all(isinstance(x, ast.BoolLit) for x in e.items):
                return ast.TypeRef("List", _BOOL)
            return None
        if self._ref(e) is not None:
            return ast.TypeRef("record")
        if isinstance(e, ast.Field):
            b = self._ref(e.base)
            if b is not None:
                flat = self.expr(e)
                return self._static_type(flat)
            return None
        if isinstance(e, ast.Name):
            d = self._decl_of(e.name)
            if d is None:
                return None
            return d.type if d.size is None else ast.TypeRef("array")
        if isinstance(e, ast.Index):
            if isinstance(e.base, ast.Name):
                d = self._decl_of(e.base.name)
                if d is not None and d.section in ("allread", "loc") and d.size is None \
                        and d.type.name != "List":
                    return d.type          # robot j's component
                if d is not None and d.section == "allread":
                    return None            # robot j's list, or an element of one
            bt = self._static_type(e.base)
            if bt is not None and bt.name == "List":
                return bt.elem
            return None
        if isinstance(e, (ast.BoolLit,)):
            return _BOOL
        if isinstance(e, (ast.IntLit,)):
            return ast.TypeRef("int")
        return None

    def _leaf_field(self, e) -> Optional[ast.Expr]:
        """``r.f`` for a record ``r`` and a field ``f`` that is not a record:
        its flat variable (with the indexes on the way); else None."""
        if isinstance(e, ast.Field):
            b = self._ref(e.base)
            if b is not None and self._field(b.rec, e).type.name not in self.records:
                return b.leaf((e.name,))
        return None

    def _port_read(self, e):
        module, port = self._port(e, "read")
        if port in ("position", "psn"):
            return ast.Call("getPosition", (), e.span)
        if port in ("reached", "done"):
            done = ast.Name("doReach_done", e.span)
            if self.path is None:
                return done
            # a path is reached when its last waypoint is
            rest = ast.Call("isEmpty", (ast.Name(PATH_VAR, e.span),), e.span)
            return ast.Binary("&&", done, rest, e.span)
        raise _Syntax(f"{module}.{port} is one of the actuators: it is assigned, not read"
                      + (" (read Motion.position)" if port == "target" else ""), e.span)

    def _call(self, e: ast.Call):
        if e.name in _ANY_ALL:
            return self._any_all(e)
        if e.name in ("size", "isEmpty", "contains") and e.args:
            b = self._ref(e.args[0])
            if b is not None:
                if e.name == "contains":
                    raise _Syntax("'contains' on a list of records is not supported (pccl "
                                  "keeps one list per field): compare a field in a loop",
                                  e.span)
                first = self._leaves(b.rec)[0][0]
                return ast.Call(e.name, (self.expr(b.leaf(first)),), e.span)
        return dataclasses.replace(e, args=tuple(self.expr(x) for x in e.args))

    def expr(self, e):
        if not self._mentions_module(e):
            return e   # nothing to rewrite (and no recursion over a long operator chain)
        if self._is_port(e):
            return self._port_read(e)
        if isinstance(e, ast.Name) and e.name in _PORTS:
            raise _Syntax(f"'{e.name}' is a module: use one of its ports, e.g. "
                          f"'{e.name}.{next(iter(_PORTS[e.name]))}'", e.span)
        leaf = self._leaf_field(e)
        if leaf is not None:
            return self.expr(leaf)
        r = self._ref(e)
        if r is not None:
            raise self._whole(e, r)
        if isinstance(e, (ast.IntLit, ast.FloatLit, ast.BoolLit, ast.Name)):
            return e
        if isinstance(e, ast.ListLit):
            return dataclasses.replace(e, items=tuple(self.expr(x) for x in e.items))
        if isinstance(e, ast.Index):
            return dataclasses.replace(e, base=self.expr(e.base), index=self.expr(e.index))
        if isinstance(e, ast.Field):
            return dataclasses.replace(e, base=self.expr(e.base))
        if isinstance(e, ast.Call):
            return self._call(e)
        if isinstance(e, ast.Unary):
            return dataclasses.replace(e, operand=self.expr(e.operand))
        if isinstance(e, ast.Binary):
            return dataclasses.replace(e, left=self.expr(e.left), right=self.expr(e.right))
        if isinstance(e, ast.Quant):
            return dataclasses.replace(e, body=self.expr(e.body))
        return e  # pragma: no cover - no other expression kinds in Koord

    # ---- statements --------------------------------------------------

    def stmts(self, stmts) -> tuple:
        out: list = []
        for s in stmts:
            r = self.stmt(s)
            out.extend(r if isinstance(r, list) else (r,))
        return tuple(out)

    def _path(self, s: ast.Assign) -> list:
        """``Motion.path = ps``: the waypoints are kept in the hidden local
        list ``Motion_path``; the first one becomes the target at once, and
        the hidden event ``Motion_follow`` (:meth:`program`) makes the next
        one the target each time the last one is reached."""
        sp = s.span
        var = ast.Name(PATH_VAR, sp)
        return [ast.Assign(_NO_SID, ast.Name(PATH_VAR, s.target.span), self.expr(s.value), sp),
                ast.If(_NO_SID, ((ast.Unary("!", ast.Call("isEmpty", (var,), sp), sp),
                                  _next_leg(sp)),), (), sp)]

    def stmt(self, s):
        if isinstance(s, _ForList):
            return self._for_list(s)
        if isinstance(s, ast.Assign):
            return self._assign(s)
        if isinstance(s, ast.If):
            return dataclasses.replace(
                s, branches=tuple((self.expr(c), self.stmts(b)) for c, b in s.branches),
                orelse=self.stmts(s.orelse))
        if isinstance(s, ast.Atomic):
            return dataclasses.replace(s, body=self.stmts(s.body))
        if isinstance(s, ast.While):
            return dataclasses.replace(s, cond=self.expr(s.cond), body=self.stmts(s.body))
        if isinstance(s, ast.CallStmt):
            if s.name in ("add", "remove") and s.args:
                b = self._ref(s.args[0])
                if b is not None:
                    return self._record_list_stmt(s, b)
            return dataclasses.replace(s, args=tuple(self.expr(a) for a in s.args))
        return s

    def _record_list_stmt(self, s: ast.CallStmt, b: "_Ref") -> list:
        """``rs.add(r)`` on a list of records: ``add`` on each field's list."""
        if s.name == "remove":
            raise _Syntax("'remove' on a list of records is not supported (pccl keeps one list "
                          "per field, and a field's value may occur in several records)", s.span)
        if len(s.args) != 2:
            raise _Syntax(f"'add' takes one {b.rec.name} record", s.span)
        r = self._record_value(s.args[1], b.rec)
        return [ast.CallStmt(_NO_SID, "add", (self.expr(b.leaf(p)), self.expr(r.leaf(p))), s.span)
                for p, _, _ in self._leaves(b.rec)]

    def _hidden_list(self, name: str, typ: ast.TypeRef, span: ast.Span) -> None:
        if name not in self.hidden:
            self.hidden[name] = ast.VarDecl("loc", ast.TypeRef("List", typ, span), name, None,
                                            ast.ListLit((), span), span, name_span=span)

    def _for_list(self, s: "_ForList") -> list:
        """``for x in xs: body`` is ``for_x = xs`` then ``while
        !isEmpty(for_x): x = head(for_x); remove(for_x, head(for_x)); body``
        (``for_x`` a hidden local list: the loop walks a copy of xs, and ends
        with it empty).  A record ``x`` walks one hidden list per field."""
        x = s.var
        if not isinstance(x, ast.Name):
            raise _Syntax("the variable of 'for x in xs:' is a local variable (a function's "
                          "parameter cannot be it)", s.span)
        ref = self._ref(x)
        if ref is None:
            d = self._decl_of(x.name)
            if d is None:
                raise _Syntax(f"'{x.name}' is not declared: declare the loop variable in "
                              "'local:'", x.span)
            if d.section != "loc" or d.size is not None:
                raise _Syntax("the variable of 'for x in xs:' is a local variable that is not "
                              "an array (declared in 'local:')", x.span)
            leaves = [(x.name, d.type, lambda p: s.cond, ())]
        else:
            if not isinstance(x, ast.Name):
                raise _Syntax("the variable of 'for x in xs:' is a variable", x.span)
            it = self._ref(s.cond)
            if it is None or it.rec is not ref.rec:
                raise _Syntax(f"'{x.name}' is a {ref.rec.name} record: it walks a list of "
                              f"{ref.rec.name} records", s.cond.span)
            leaves = []
            for p, _, _ in self._leaves(ref.rec):
                flat = f"{x.name}_{'_'.join(p)}"
                d = self._decl_of(flat)
                if d is None or d.section != "loc" or d.size is not None:
                    raise _Syntax("the variable of 'for x in xs:' is a local variable that is "
                                  "not an array (declared in 'local:')", x.span)
                leaves.append((flat, d.type, it.leaf, p))
        if x.name in self._loops:
            raise _Syntax(f"a loop over '{x.name}' inside a loop over '{x.name}'", x.span)
        sp = s.span
        out: list = []
        pre: list = []
        for flat, typ, value, p in leaves:
            hidden = f"for_{flat}"
            self._hidden_list(hidden, typ, sp)
            h = ast.Name(hidden, sp)
            out.append(ast.Assign(_NO_SID, h, self.expr(value(p)), sp))
            first = ast.Call("head", (h,), sp)
            pre += [ast.Assign(_NO_SID, ast.Name(flat, x.span), first, sp),
                    ast.CallStmt(_NO_SID, "remove", (h, first), sp)]
        cond = ast.Unary("!", ast.Call("isEmpty", (ast.Name(f"for_{leaves[0][0]}", sp),), sp), sp)
        self._loops.append(x.name)
        try:
            body = self.stmts(s.body)
        finally:
            self._loops.pop()
        out.append(ast.While(_NO_SID, cond, tuple(pre) + body, sp))
        return out

    def _lvalue(self, t):
        """An assignment's target with its record fields read as their flat
        variables (``rs[i].xs[k]`` -> ``rs_xs[i][k]``)."""
        if isinstance(t, ast.Index):
            return dataclasses.replace(t, base=self._lvalue(t.base))
        if isinstance(t, ast.Field):
            b = self._ref(t.base)
            if b is not None:
                self._field(b.rec, t)
                return b.leaf((t.name,))
        return t

    def _assign(self, s: ast.Assign):
        target = s.target
        if self._is_port(target):
            assert isinstance(target, ast.Field)
            module, port = self._port(target, "write")
            if self.ports[module][port] != "actuators":
                raise _Syntax(f"{module}.{port} is one of the sensors: it is read, not assigned",
                              target.span)
            if module == "Log":
                raise _Syntax("write a log line with 'Log.stdout << ...'", target.span)
            if port in ("path", "route"):
                return self._path(s)
            # Motion.target = p: the controller drives the robot to p
            reach = ast.CallStmt(_NO_SID, "doReach", (self.expr(s.value), ast.ListLit((), s.span)),
                                 s.span)
            if self.path is None:
                return reach
            # a new target ends the path being followed
            clear = ast.Assign(_NO_SID, ast.Name(PATH_VAR, s.span), ast.ListLit((), s.span), s.span)
            return [clear, reach]
        ref = self._ref(target)
        if ref is not None:
            return self._record_assign(s, ref)
        target = self._lvalue(target)
        root, chain = ast.index_chain(target)
        if not isinstance(root, ast.Name):
            raise _Syntax("only a variable or an element of one can be assigned", target.span)
        if root.name in self.allread:
            first = chain[0].index if chain else None
            if not (isinstance(first, ast.Call) and first.name == "getAgentIndex"
                    and not first.args):
                var, path = self.flat_root.get(root.name, (root.name, ()))
                field = "".join(f".{f}" for f in path)
                raise _Syntax(f"'{var}' is allread: a robot writes only its own entry, "
                              f"'{var}[pid]{field} = ...'",
                              chain[0].index.span if chain else target.span)
            # x[pid][k] = v  ->  x[k] = v (PCCL: x is the robot's own component)
            new: ast.Expr = root
            for ix in chain[1:]:
                new = ast.Index(new, ix.index, ix.span)
            target = new
        target = self.expr(target)
        return dataclasses.replace(s, target=target, value=self.expr(s.value))

    def _record_assign(self, s: ast.Assign, ref: "_Ref") -> list:
        """``v = w`` for a record (variable, element, field) and a record
        value of its type (or a list of them and a list literal of records):
        field by field."""
        rec, w = ref.rec, s.value
        if isinstance(w, ast.ListLit):
            items = [self._record_value(x, rec) for x in w.items]

            def value(p):
                return ast.ListLit(tuple(r.leaf(p) for r in items), w.span)
        else:
            r = self._ref(w)
            if r is None or r.rec is not rec:
                raise _Syntax(f"'{_root_name(s.target)}' is a record ({rec.name}): assign another "
                              f"{rec.name} (a variable, an element or a literal {rec.name}(...)), "
                              "or its fields one by one", w.span)
            value = r.leaf
        out: list = []
        for p, _, _ in self._leaves(rec):
            one = self._assign(ast.Assign(_NO_SID, ref.leaf(p), value(p), s.span))
            out.extend(one if isinstance(one, list) else [one])
        return out

    # ---- program -----------------------------------------------------

    def program(self, init, events, invariants) -> ast.Program:
        init = self.stmts(init)
        events = tuple(dataclasses.replace(ev, guard=self.expr(ev.guard), body=self.stmts(ev.body))
                       for ev in events)
        invariants = tuple(dataclasses.replace(inv, expr=self.expr(inv.expr))
                           for inv in invariants)
        for d in self.decls:
            if d.name in self.hidden:
                raise _Syntax(f"'{d.name}' is the name pccl gives the list a 'for "
                              f"{d.name[4:]} in ...:' loop walks: choose another name",
                              d.name_span or d.span)
        decls = tuple(self.decls) + tuple(self.hidden.values())
        if self.path is not None:
            for d in decls:
                if d.name == PATH_VAR:
                    raise _Syntax(f"'{PATH_VAR}' is the name pccl gives Motion.path's waypoints: "
                                  "choose another name", d.name_span or d.span)
            for ev in events:
                if ev.name == FOLLOW_EVENT:
                    raise _Syntax(f"'{FOLLOW_EVENT}' is the name of pccl's waypoint-following "
                                  "event: choose another name", ev.name_span or ev.span)
            sp = self.path
            var = ast.Name(PATH_VAR, sp)
            decls += (ast.VarDecl("loc", ast.TypeRef("List", _POS, sp), PATH_VAR, None,
                                  ast.ListLit((), sp), sp, name_span=sp),)
            # first in source order, so that --events first follows the path too
            guard = ast.Binary("&&", ast.Name("doReach_done", sp),
                               ast.Unary("!", ast.Call("isEmpty", (var,), sp), sp), sp)
            events = (ast.Event(FOLLOW_EVENT, guard, _next_leg(sp), sp, sp),) + events
        return _strings(ast.Program(None, decls, init, events, invariants))


def _is_literal(e) -> bool:
    """Whether ``e`` is a string literal (a ``string`` member, quoted)."""
    return isinstance(e, ast.Name) and e.name.startswith('"')


def _fold(node, types: dict):
    """``node`` with every ``"a" + "b"`` replaced by the literal ``"ab"``
    (innermost first: ``"a" + "b" + "c"`` is ``"abc"``).  A ``+`` with a
    string on one side that is not a literal after folding is an error:
    a string is one of the program's literals (the enum ``string``), so
    only text known when the program is read can be joined.  ``types``:
    each declared variable's TypeRef, to recognise a string variable."""
    if isinstance(node, tuple):
        new = tuple(_fold(x, types) for x in node)
        return node if all(a is b for a, b in zip(new, node)) else new
    if not dataclasses.is_dataclass(node) or isinstance(node, (ast.Span, ast.TypeRef, type)):
        return node
    if isinstance(node, ast.Binary) and node.op == "+":
        # a long chain of '+' without strings is left as it is, without recursion
        left, right = _fold(node.left, types), _fold(node.right, types)
        if _is_literal(left) and _is_literal(right):
            return ast.Name('"' + left.name[1:-1] + right.name[1:-1] + '"', node.span)
        for side in (left, right):
            if _is_literal(side) or _string_var(side, types):
                raise _Syntax("'+' joins strings only when both are known as the program is "
                              "read (string literals, or '+' of them): pccl's Koord strings "
                              "are the program's string literals (docs/koord.md, \"Strings\")",
                              node.span)
        if left is node.left and right is node.right:
            return node
        return dataclasses.replace(node, left=left, right=right)
    changes = {}
    for f in dataclasses.fields(node):
        v = getattr(node, f.name)
        nv = _fold(v, types)
        if nv is not v:
            changes[f.name] = nv
    return dataclasses.replace(node, **changes) if changes else node


def _string_var(e, types: dict) -> bool:
    """Whether ``e`` reads a ``string`` variable (or an element of a string
    array or list)."""
    depth = 0
    while isinstance(e, ast.Index):
        e, depth = e.base, depth + 1
    if not isinstance(e, ast.Name) or e.name not in types:
        return False
    t, size, section = types[e.name]
    depth -= (section == "allread") + (size is not None)
    while depth > 0 and t is not None and t.name == "List":
        t, depth = t.elem, depth - 1
    return depth <= 0 and t is not None and t.name == STRING_TYPE


def _strings(prog: ast.Program) -> ast.Program:
    """Koord's strings as the checked program knows them: the enum
    ``string`` (declared first) whose members are the program's string
    literals after folding ``+`` (:func:`_fold`), in the order they are
    first written (``""`` alone when a string variable is declared but no
    literal written).  A program without strings is returned as it is."""
    uses = any(_mentions_string(d.type) for d in prog.decls if isinstance(d, ast.VarDecl))
    if not uses and not any(_is_literal(n) for n in ast.walk(prog)):
        return prog     # (ast.walk is iterative: a long operator chain is no recursion)
    types = {d.name: (d.type, d.size, d.section) for d in prog.decls
             if isinstance(d, ast.VarDecl)}
    prog = _fold(prog, types)
    members: dict = {}
    for n in ast.walk(prog):
        if _is_literal(n) and n.name not in members:
            members[n.name] = n.span
    if not members:
        members['""'] = next(d.span for d in prog.decls if isinstance(d, ast.VarDecl))
    span = next(iter(members.values()))
    enum = ast.EnumDecl("loc", STRING_TYPE, tuple(members), span, span,
                        member_spans=tuple(members.values()))
    return dataclasses.replace(prog, decls=(enum,) + prog.decls)


def _mentions_string(t: Optional[ast.TypeRef]) -> bool:
    while t is not None:
        if t.name == STRING_TYPE:
            return True
        t = t.elem
    return False


#: Motion.path's hidden local list of the waypoints still to reach, and the
#: hidden event that starts the next leg (docs/koord.md, "Motion.path").
PATH_VAR = "Motion_path"
FOLLOW_EVENT = "Motion_follow"


def _next_leg(sp: ast.Span) -> tuple:
    """``doReach(head(path), []); remove(path, head(path))``: the next
    waypoint becomes the target and leaves the list."""
    var = ast.Name(PATH_VAR, sp)
    first = ast.Call("head", (var,), sp)
    return (ast.CallStmt(_NO_SID, "doReach", (first, ast.ListLit((), sp)), sp),
            ast.CallStmt(_NO_SID, "remove", (var, first), sp))


def _root_name(e) -> str:
    """The variable an lvalue is part of."""
    while isinstance(e, (ast.Field, ast.Index)):
        e = e.base
    return e.name if isinstance(e, ast.Name) else "?"


def _koord_type(t: ast.TypeRef) -> str:
    names = {"ItemPosition": "pos", "bool": "boolean"}
    if t.name == "List" and t.elem is not None:
        return f"{_koord_type(t.elem)}[]"
    return names.get(t.name, t.name)


_TRANSFORMER = _ToAst()


# --------------------------------------------------------------------------
# Error messages
# --------------------------------------------------------------------------

_NAMES = {
    "SEMICOLON": "';'", "COLON": "':'", "COMMA": "','", "DOT": "'.'",
    "LPAR": "'('", "RPAR": "')'", "LSQB": "'['", "RSQB": "']'", "LBRACE": "'{'",
    "RBRACE": "'}'", "EQUAL": "'='", "ARROW": "'->'", "LSHIFT": "'<<'",
    "OR": "'or'", "OROR": "'||'", "AND": "'and'", "ANDAND": "'&&'", "NOT": "'not'",
    "BANG": "'!'", "EQ": "'=='", "NE": "'!='", "LT": "'<'", "LE": "'<='", "GT": "'>'",
    "GE": "'>='", "PLUS": "'+'", "MINUS": "'-'", "STAR": "'*'", "SLASH": "'/'",
    "PERCENT": "'%'", "USING": "'using'", "SENSORS": "'sensors'", "ACTUATORS": "'actuators'",
    "ALLWRITE": "'allwrite'", "ALLREAD": "'allread'", "LOCAL": "'local'", "INIT": "'init'",
    "PRE": "'pre'", "EFF": "'eff'", "INVARIANT": "'invariant'", "IF": "'if'",
    "ELIF": "'elif'", "ELSE": "'else'", "FOR": "'for'", "IN": "'in'", "ATOMIC": "'atomic'", "STOP": "'stop'",
    "SKIP": "'skip'", "TRUE": "'true'", "FALSE": "'false'", "PID": "'pid'",
    "NUMAGENTS": "'numAgents'", "NUMBOTS": "'numBots'", "FORALL": "'forall'",
    "EXISTS": "'exists'", "IDENT": "a name", "INT": "a number", "FLOAT": "a number",
    "STRING": "a string", "_NL": "end of line", "_INDENT": "an indented block",
    "_DEDENT": "end of block", "$END": "end of file", "DEF": "'def'", "FUN": "'fun'",
    "RETURN": "'return'",
}
_BINOPS = {"ARROW", "OR", "OROR", "AND", "ANDAND", "EQ", "NE", "LT", "LE", "GT", "GE",
           "PLUS", "MINUS", "STAR", "SLASH", "PERCENT"}
_CMP_OPS = {"EQ", "NE", "LT", "LE", "GT", "GE"}
_POSTFIX = {"LSQB", "DOT", "LPAR"}
_EXPR_START = {"IDENT", "INT", "FLOAT", "TRUE", "FALSE", "LPAR", "LSQB", "MINUS", "NOT",
               "BANG", "PID", "NUMAGENTS", "NUMBOTS", "FORALL", "EXISTS", "STRING"}
_STMT_START = {"IF", "ATOMIC", "SKIP", "STOP", "IDENT", "FOR", "RETURN"}
_TOP = {"USING", "ALLWRITE", "ALLREAD", "LOCAL", "INIT", "INVARIANT", "DEF"}
_SECTION_ORDER = ("sections come in the order: using Module:, allwrite:/allread:/local:, "
                  "init:, the events name:, invariant: (each optional)")


def _describe(expected: set) -> str:
    exp = set(expected)
    words: list[str] = []
    if {"INT", "FLOAT", "TRUE", "LPAR"} <= exp:
        words.append("an expression")
        exp -= _EXPR_START
    elif "PLUS" in exp and "STAR" in exp:
        rest = exp - _BINOPS - _POSTFIX
        if not rest:
            return "an operator"
        exp = rest
    if _STMT_START <= exp:
        words.insert(0, "a statement")
        exp -= _STMT_START | {"_DEDENT"}
    if "IDENT" in exp and (exp & _TOP or "$END" in exp):
        words.append("an event")
        exp.discard("IDENT")
    if "$END" in exp:
        exp.discard("_NL")
    order = ["_NL", "_DEDENT", "$END"]
    ends = sorted((t for t in exp if t in order), key=order.index)
    named = sorted({_NAMES.get(t, t) for t in exp if t not in order})
    words += named + [_NAMES[t] for t in ends]
    if not words:
        return "something else"
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]


def _token_error(exc: UnexpectedToken, text: str, source: str, filename: str) -> PcclError:
    tok = exc.token
    try:
        expected = exc.interactive_parser.accepts()
    except Exception:  # pragma: no cover - defensive
        expected = set(exc.expected)
    ttype = tok.type
    line, column = getattr(tok, "line", None), getattr(tok, "column", None)
    end_column = None
    at_eof = ttype == "$END" or line is None
    if ttype == "_DEDENT" and not at_eof:
        end_pos = getattr(tok, "end_pos", None)
        if end_pos is not None and text[end_pos:].strip() == "":
            at_eof = True
    if at_eof:
        what = "unexpected end of file"
        line, column = P._eof_position(source)
    elif ttype == "_NL":
        what = "unexpected end of line"
    elif ttype == "_INDENT":
        return PcclError("unexpected indentation", filename=filename, source=source,
                         line=tok.end_line, column=tok.end_column)
    elif ttype == "_DEDENT":
        what = "unexpected dedent"
        line, column = tok.end_line, tok.end_column
    else:
        what = f"unexpected '{tok.value}'"
        if tok.end_line == tok.line:
            end_column = tok.end_column
    if ttype in _CMP_OPS and "OROR" in expected and not expected & _CMP_OPS:
        return PcclError(f"{what}: comparisons cannot be chained (use 'and')",
                         filename=filename, source=source, line=line, column=column,
                         end_column=end_column)
    message = f"{what}: expected {_describe(expected)}"
    if ttype == "EQUAL" and "EQ" in expected:
        message += " (did you mean '=='?)"
    if ttype in ("FORALL", "EXISTS") and ttype not in expected:
        message += " (quantifiers are for the invariant: section)"
    if ttype == "LPAR" and expected == {"COLON"}:
        message += " (a Koord event is written 'name:' without '()')"
    if ttype == "PRE" and "EFF" not in expected and "PRE" not in expected:
        message += " ('pre:' comes first in an event, then 'eff:')"
    if ttype in _TOP and ttype not in expected:
        message += f"; {_SECTION_ORDER}"
    return PcclError(message, filename=filename, source=source, line=line, column=column,
                     end_column=end_column)


# --------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------

def _parse(source: str, filename: str) -> ast.Program:
    if not isinstance(source, str):
        raise PcclError(f"source must be text, not {type(source).__name__}", filename=filename)
    text = P._normalise(source)
    P._check_comments(text, source, filename)
    m = P._FIRST_LINE_INDENT.match(text)
    if m:
        raise PcclError("unexpected indentation", filename=filename, source=source,
                        line=1, column=m.end() + 1)
    try:
        tree = _get_lark().parse(text)
        return _TRANSFORMER.transform(tree)
    except _Unsupported as e:
        raise PcclError(e.message, filename=filename, source=source, span=_tspan(e.tok)) from None
    except UnexpectedToken as e:
        raise _token_error(e, text, source, filename) from None
    except UnexpectedCharacters as e:
        raise P._char_error(e, text, source, filename) from None
    except (UnexpectedEOF, P._IndentError, VisitError, RecursionError, DedentError,
            UnexpectedInput, LarkError) as e:
        raise P.lark_failure(e, source, filename) from None


def parse_koord(source: str, filename: str = "<input>") -> ast.Program:
    """Parse a whole Koord program into a PCCL :class:`ast.Program` (its
    ``filename`` and ``source`` the Koord file's; sids 0..n-1 in source order)."""
    prog = _parse(source, filename)
    try:
        numberer = P._Numberer()
        init = numberer.stmts(prog.init)
        events = tuple(dataclasses.replace(ev, body=numberer.stmts(ev.body))
                       for ev in prog.events)
        prog = dataclasses.replace(prog, init=init, events=events, filename=filename,
                                   source=source, n_statements=numberer.next,
                                   language="koord")
        P._check_no_property_syntax(prog)
    except _Syntax as e:
        raise PcclError(e.message, filename=filename, source=source, span=e.span) from None
    except RecursionError:
        raise PcclError("program is nested too deeply", filename=filename,
                        source=source) from None
    return prog


def parse_koord_file(path) -> ast.Program:
    """Read a UTF-8 file and parse it as a Koord program."""
    return P.read_and_parse(path, parse_koord)
