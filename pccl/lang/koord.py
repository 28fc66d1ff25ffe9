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

``for i in range(a, b):`` is ``i = a`` and a ``while`` loop.
Functions ``def fun f(T x, ...):`` are inlined where they are called
(:mod:`pccl.lang.koordfun`).  ``Motion.path = ps`` keeps the waypoints in a
hidden local list that a hidden first event ``Motion_follow`` walks with
``doReach``.  A variable of a record type (``def Name:``) is one variable
per field, ``v_f``.  Every problem is a
:class:`pccl.lang.errors.PcclError` with file, line, column and caret.
"""

from __future__ import annotations

import dataclasses
import os
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
_UNSUPPORTED_TYPES = ("stream", "string", "queue", "map", "inputMap")

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
            raise _Syntax("write a bounded loop as 'for i in range(a, b):' (i from a to b - 1)",
                          span)
        rng = children[3]
        if not (isinstance(rng, ast.Call) and rng.name == "range" and 1 <= len(rng.args) <= 2):
            raise _Syntax("'for' iterates over 'range(b)' or 'range(a, b)' only (lists: "
                          "an index and 'xs[i]')", rng.span)
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
        for r in records or ():
            self._record(r)
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

    def _record(self, r: _KRecord) -> None:
        if r.name in self.records:
            raise _Syntax(f"record type '{r.name}' is defined twice", r.span)
        if r.name in _BASE_TYPES or r.name in ("list", "List") or r.name in _UNSUPPORTED_TYPES:
            raise _Syntax(f"'{r.name}' is a type already: choose another name", r.span)
        seen: set = set()
        for f in r.fields:
            if f.name in seen:
                raise _Syntax(f"field '{f.name}' of '{r.name}' is declared twice", f.name_span)
            seen.add(f.name)
            if f.type.name in self.records or f.type.name == r.name:
                raise _Syntax("a record's field cannot be a record (not supported yet)",
                              f.type.name_span)
        if not r.fields:
            raise _Syntax(f"record type '{r.name}' has no field", r.span)
        self.records[r.name] = r

    def _record_decls(self, kind: str, d: _KDecl) -> list:
        """``Name v`` (``Name v[]`` in allread:): one variable ``v_f`` per
        field ``f``, with the field's type and initialiser."""
        rec = self.records[d.type.name]
        dims = d.type.dims + d.dims
        if kind == "allread":
            if len(dims) != 1 or dims[0].size is not None:
                where = dims[0].span if dims else d.name_span
                raise _Syntax(f"an allread record is an array indexed by robot, written without a "
                              f"size: '{rec.name} {d.name}[]'", where)
        elif dims:
            raise _Syntax("arrays and lists of records are not supported yet: declare one "
                          "record per variable", dims[0].span)
        if d.init is not None:
            raise _Syntax(f"a record variable takes its fields' initial values from 'def "
                          f"{rec.name}:' (Koord has no record literal)", d.init.span)
        self.record_vars[d.name] = rec
        self.record_spans[d.name] = d.name_span
        out = []
        for f in rec.fields:
            name = f"{d.name}_{f.name}"
            fd = dataclasses.replace(f, name=name, span=d.span, name_span=d.name_span,
                                     dims=(d.dims[:1] if kind == "allread" else []) + f.dims)
            if kind == "allread":
                # the robot dimension first, as `T x[]` reads
                fd = dataclasses.replace(fd, dims=[d.dims[0] if d.dims else d.type.dims[0]] + f.dims,
                                         type=dataclasses.replace(f.type))
            out.append(self._decl(kind, fd))
        return out

    def _check_flat_names(self) -> None:
        names = [d.name for d in self.decls]
        for v, rec in self.record_vars.items():
            for f in rec.fields:
                flat = f"{v}_{f.name}"
                if names.count(flat) > 1:
                    # the other declaration, not the record variable's field
                    d = next(d for d in self.decls if d.name == flat and d.name_span.line != -1
                             and not (d.name_span == self.record_spans.get(v)))
                    raise _Syntax(f"'{flat}' is the name pccl gives field '{f.name}' of record "
                                  f"variable '{v}': choose another name", d.name_span or d.span)

    def _record_field(self, e: ast.Field) -> Optional[ast.Expr]:
        """``v.f`` -> ``v_f``; ``v[j].f`` -> ``v_f[j]`` (v a record variable)."""
        base = e.base
        idx = None
        if isinstance(base, ast.Index) and isinstance(base.base, ast.Name):
            idx, base = base, base.base
        if not (isinstance(base, ast.Name) and base.name in self.record_vars):
            return None
        rec = self.record_vars[base.name]
        if e.name not in {f.name for f in rec.fields}:
            raise _Syntax(f"record '{rec.name}' has no field '{e.name}' (its fields: "
                          f"{', '.join(f.name for f in rec.fields)})", e.span)
        flat = ast.Name(f"{base.name}_{e.name}", e.span)
        if idx is None:
            return flat
        return ast.Index(flat, self.expr(idx.index), idx.span)

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
        if t.name in _UNSUPPORTED_TYPES:
            raise _Syntax(f"type '{t.name}' is not supported yet by pccl's Koord front end",
                          t.name_span)
        raise _Syntax(f"unknown type '{t.name}' (Koord types here: int, float, bool/boolean, "
                      f"pos, T[] and list<T>)", t.name_span)

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
        return any(self._is_port(n) or (isinstance(n, ast.Name) and (n.name in _PORTS or n.name in recs))
                   for n in ast.walk(e))

    def _named(self, e) -> Optional[ast.Expr]:
        """A module's or a record's name, or a record's field: its meaning
        (or an error); None for anything else."""
        if isinstance(e, ast.Name) and e.name in _PORTS:
            raise _Syntax(f"'{e.name}' is a module: use one of its ports, e.g. "
                          f"'{e.name}.{next(iter(_PORTS[e.name]))}'", e.span)
        if isinstance(e, ast.Field):
            return self._record_field(e)
        if isinstance(e, ast.Name) and e.name in self.record_vars:
            rec = self.record_vars[e.name]
            raise _Syntax(f"'{e.name}' is a record ({rec.name}): read one of its fields, e.g. "
                          f"'{e.name}.{rec.fields[0].name}'", e.span)
        return None

    def expr(self, e):
        if not self._mentions_module(e):
            return e   # nothing to rewrite (and no recursion over a long operator chain)
        if self._is_port(e):
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
        special = self._named(e)
        if special is not None:
            return special
        if isinstance(e, (ast.IntLit, ast.FloatLit, ast.BoolLit, ast.Name)):
            return e
        if isinstance(e, ast.ListLit):
            return dataclasses.replace(e, items=tuple(self.expr(x) for x in e.items))
        if isinstance(e, ast.Index):
            return dataclasses.replace(e, base=self.expr(e.base), index=self.expr(e.index))
        if isinstance(e, ast.Field):
            return dataclasses.replace(e, base=self.expr(e.base))
        if isinstance(e, ast.Call):
            return dataclasses.replace(e, args=tuple(self.expr(x) for x in e.args))
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
            return dataclasses.replace(s, args=tuple(self.expr(a) for a in s.args))
        return s

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
        if isinstance(target, ast.Name) and target.name in self.record_vars:
            return self._record_assign(s)
        if isinstance(target, ast.Field):
            flat: Optional[ast.Expr] = self._record_field(target)
            if flat is not None:
                if isinstance(flat, ast.Index):
                    # v[j].f = e: an allread record's own entry only
                    own = flat.index
                    if not (isinstance(own, ast.Call) and own.name == "getAgentIndex"
                            and not own.args):
                        var = _root_name(target)
                        raise _Syntax(f"'{var}' is allread: a robot writes only its own entry, "
                                      f"'{var}[pid].{target.name} = ...'", own.span)
                    flat = flat.base
                return dataclasses.replace(s, target=flat, value=self.expr(s.value))
        root, chain = ast.index_chain(target)
        if not isinstance(root, ast.Name):
            raise _Syntax("only a variable or an element of one can be assigned", target.span)
        if root.name in self.allread:
            first = chain[0].index if chain else None
            if not (isinstance(first, ast.Call) and first.name == "getAgentIndex"
                    and not first.args):
                raise _Syntax(f"'{root.name}' is allread: a robot writes only its own entry, "
                              f"'{root.name}[pid] = ...'",
                              chain[0].index.span if chain else target.span)
            # x[pid][k] = v  ->  x[k] = v (PCCL: x is the robot's own component)
            new: ast.Expr = root
            for ix in chain[1:]:
                new = ast.Index(new, ix.index, ix.span)
            target = new
        target = self.expr(target)
        return dataclasses.replace(s, target=target, value=self.expr(s.value))

    def _record_assign(self, s: ast.Assign) -> list:
        """``v = w`` for two record variables of one type: field by field."""
        assert isinstance(s.target, ast.Name)
        v, rec = s.target.name, self.record_vars[s.target.name]
        w = s.value
        if not (isinstance(w, ast.Name) and self.record_vars.get(w.name) is rec):
            raise _Syntax(f"'{v}' is a record ({rec.name}): assign another {rec.name} variable, "
                          "or its fields one by one", w.span)
        return [ast.Assign(_NO_SID, ast.Name(f"{v}_{f.name}", s.target.span),
                           ast.Name(f"{w.name}_{f.name}", w.span), s.span) for f in rec.fields]

    # ---- program -----------------------------------------------------

    def program(self, init, events, invariants) -> ast.Program:
        init = self.stmts(init)
        events = tuple(dataclasses.replace(ev, guard=self.expr(ev.guard), body=self.stmts(ev.body))
                       for ev in events)
        invariants = tuple(dataclasses.replace(inv, expr=self.expr(inv.expr))
                           for inv in invariants)
        decls = tuple(self.decls)
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
        return ast.Program(None, decls, init, events, invariants)


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
               "BANG", "PID", "NUMAGENTS", "NUMBOTS", "FORALL", "EXISTS"}
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
