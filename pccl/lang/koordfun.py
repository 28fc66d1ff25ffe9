"""Koord functions (``def fun name(T x, ...):``), inlined where they are
called (docs/koord.md, "Functions").

pccl's programs have no procedures, so the Koord front end
(:mod:`pccl.lang.koord`) replaces every call of a Koord function by the
function's body with each parameter replaced by its argument (the
argument's syntax tree: precedence is kept):

* a call used as an **expression** needs a function whose body is a single
  ``return e``: the call is ``e`` with the arguments in place;
* a call used as a **statement** is the body's statements (a last
  ``return e`` is dropped: its value is not used).

Substitution is call-by-value only when no argument can change between its
uses, so the front end refuses (with the call's place) a body that assigns
a parameter or a variable an argument reads, and an argument that calls
``rand``.  ``return`` elsewhere than last in a function, recursion, a
wrong number of arguments and two functions of one name are errors too.
The inlined statements keep the spans of the function's body: traces show
those lines.
"""

from __future__ import annotations

import dataclasses
from typing import Optional

from pccl.lang import ast


class FunctionError(Exception):
    """A problem with a function or a call, at ``span``."""

    def __init__(self, message: str, span: ast.Span):
        super().__init__(message)
        self.message = message
        self.span = span


@dataclasses.dataclass
class Return:
    """``return e`` while the front end reads a function's body."""
    value: ast.Expr
    span: ast.Span


@dataclasses.dataclass
class Function:
    """``def fun name(params): body``."""
    name: str
    name_span: ast.Span
    params: list            # (name, span)
    body: tuple
    span: ast.Span


def _subst(node, mapping: dict):
    """``node`` with every :class:`ast.Name` in ``mapping`` replaced."""
    if isinstance(node, ast.Name):
        return mapping.get(node.name, node)
    if isinstance(node, tuple):
        new = tuple(_subst(x, mapping) for x in node)
        return node if all(a is b for a, b in zip(new, node)) else new
    if not dataclasses.is_dataclass(node) or isinstance(node, (ast.Span, ast.TypeRef, type)):
        return node
    changes = {}
    for f in dataclasses.fields(node):
        v = getattr(node, f.name)
        nv = _subst(v, mapping)
        if nv is not v:
            changes[f.name] = nv
    return dataclasses.replace(node, **changes) if changes else node


def _assigned(stmts) -> set:
    """Names a block assigns (the root of an assignment's target, the list
    of ``add``/``remove``), at any depth."""
    out: set = set()
    for s in ast.walk_stmts(stmts):
        target = None
        if isinstance(getattr(s, "var", None), ast.Name):
            out.add(s.var.name)         # the variable of `for x in xs:`
        if isinstance(s, ast.Assign):
            target = s.target
        elif isinstance(s, ast.CallStmt) and s.name in ("add", "remove") and s.args:
            target = s.args[0]
        port = _port(target)
        if port is not None:
            # `Motion.target = p` starts a motion: it resets Motion.reached/done
            # (the robot moves only between rounds: Motion.position stays)
            module = port[0]
            out |= {f"{module}.reached", f"{module}.done"}
            continue
        while isinstance(target, (ast.Index, ast.Field)):
            target = target.base
        if isinstance(target, ast.Name):
            out.add(target.name)
    return out


def _port(e) -> Optional[tuple]:
    """``(Module, port)`` for ``Module.port`` (a capitalised name's field)."""
    if isinstance(e, ast.Field) and isinstance(e.base, ast.Name) and e.base.name[:1].isupper():
        return e.base.name, e.name
    return None


def _names(e) -> set:
    """The variables (and ``Module.port`` sensors) an expression reads."""
    out: set = set()
    bases = set()
    for n in ast.walk_expr(e):
        p = _port(n)
        if p is not None:
            out.add(f"{p[0]}.{p[1]}")
            bases.add(id(n.base))
        elif isinstance(n, ast.Name) and id(n) not in bases:
            out.add(n.name)
    return out


def _calls_rand(e) -> bool:
    return any(isinstance(n, ast.Call) and n.name == "rand" for n in ast.walk_expr(e))


class Functions:
    """The program's functions, and the inlining of their calls."""

    def __init__(self, functions: list):
        self.funs: dict = {}
        for f in functions:
            if f.name in self.funs:
                raise FunctionError(f"function '{f.name}' is defined twice (first at line "
                                    f"{self.funs[f.name].name_span.line})", f.name_span)
            seen: dict = {}
            for name, span in f.params:
                if name in seen:
                    raise FunctionError(f"parameter '{name}' of '{f.name}' is named twice", span)
                seen[name] = span
            for k, s in enumerate(f.body):
                if isinstance(s, Return) and k != len(f.body) - 1:
                    raise FunctionError("'return' ends a function: it is its last statement",
                                        s.span)
            self.funs[f.name] = f
        self._active: list = []       # the calls being inlined (recursion)

    # -- expressions -------------------------------------------------------------
    def expr(self, e):
        if not self.funs or not any(isinstance(n, ast.Call) and n.name in self.funs
                                    for n in ast.walk_expr(e)):
            return e
        if isinstance(e, ast.Call) and e.name in self.funs:
            return self._inline_expr(e)
        return _map_exprs(e, self.expr)

    def _enter(self, f: Function, call) -> list:
        if f.name in self._active:
            raise FunctionError(f"function '{f.name}' calls itself (through "
                                f"{' -> '.join([*self._active, f.name])}): pccl inlines "
                                "functions, so they cannot be recursive", call.span)
        if len(call.args) != len(f.params):
            raise FunctionError(f"'{f.name}' takes {len(f.params)} argument"
                                f"{'' if len(f.params) == 1 else 's'}, not {len(call.args)}",
                                call.span)
        args = [self.expr(a) for a in call.args]
        for a in args:
            if _calls_rand(a):
                raise FunctionError("an argument that calls rand() is not supported (pccl "
                                    "inlines functions: the argument would be drawn at each use); "
                                    "assign it to a variable first", a.span)
        return args

    def _inline_expr(self, call: ast.Call):
        f = self.funs[call.name]
        if not (len(f.body) == 1 and isinstance(f.body[0], Return)):
            raise FunctionError(f"'{f.name}' is used in an expression: its body must be a "
                                "single 'return e' (call it as a statement otherwise)", call.span)
        args = self._enter(f, call)
        body = _subst(f.body[0].value, {p: a for (p, _), a in zip(f.params, args)})
        self._active.append(f.name)
        try:
            return self.expr(body)
        finally:
            self._active.pop()

    # -- statements --------------------------------------------------------------
    def stmts(self, stmts) -> tuple:
        out: list = []
        for s in stmts:
            if isinstance(s, Return):
                raise FunctionError("'return' outside a function", s.span)
            if isinstance(s, ast.CallStmt) and s.name in self.funs:
                out.extend(self._inline_stmt(s))
            else:
                out.append(self._stmt(s))
        return tuple(out)

    def _stmt(self, s):
        if isinstance(s, (ast.If, ast.While, ast.Atomic)):
            s = ast.with_blocks(s, self.stmts)
        if isinstance(s, ast.If):
            return dataclasses.replace(
                s, branches=tuple((self.expr(c), b) for c, b in s.branches))
        if isinstance(s, ast.While):
            return dataclasses.replace(s, cond=self.expr(s.cond))
        if isinstance(s, ast.Assign):
            return dataclasses.replace(s, target=self.expr(s.target), value=self.expr(s.value))
        if isinstance(s, ast.CallStmt):
            return dataclasses.replace(s, args=tuple(self.expr(a) for a in s.args))
        return s

    def _assigned_deep(self, body, seen: set) -> set:
        """:func:`_assigned`, with the names the functions it calls assign."""
        out = _assigned(body)
        for s in ast.walk_stmts(body):
            if isinstance(s, ast.CallStmt) and s.name in self.funs and s.name not in seen:
                seen.add(s.name)
                out |= self._assigned_deep(self.funs[s.name].body, seen)
        return out

    def _inline_stmt(self, call: ast.CallStmt) -> tuple:
        f = self.funs[call.name]
        args = self._enter(f, call)
        body = f.body[:-1] if f.body and isinstance(f.body[-1], Return) else f.body
        assigned = self._assigned_deep(body, {f.name})
        for (p, span), a in zip(f.params, args):
            if p in assigned:
                raise FunctionError(f"'{f.name}' assigns its parameter '{p}': pccl inlines "
                                    "functions, so a parameter cannot be assigned (use a local "
                                    "variable)", span)
            clash = sorted(_names(a) & assigned)
            if clash:
                verb = "changes (assigning Motion.target resets it)" if "." in clash[0] \
                    else "assigns"
                raise FunctionError(f"this argument reads '{clash[0]}', which '{f.name}' "
                                    f"{verb}: pccl inlines functions, so the argument would be "
                                    "read again after the assignment; pass a copy (assign it "
                                    "to a variable first)", a.span)
        body = _subst(body, {p: a for (p, _), a in zip(f.params, args)})
        self._active.append(f.name)
        try:
            return self.stmts(body)
        finally:
            self._active.pop()


def _map_exprs(e, fn):
    """``e`` with ``fn`` applied to each direct sub-expression."""
    if isinstance(e, ast.Call):
        return dataclasses.replace(e, args=tuple(fn(a) for a in e.args))
    if isinstance(e, ast.ListLit):
        return dataclasses.replace(e, items=tuple(fn(x) for x in e.items))
    if isinstance(e, (ast.Index,)):
        return dataclasses.replace(e, base=fn(e.base), index=fn(e.index))
    if isinstance(e, ast.Field):
        return dataclasses.replace(e, base=fn(e.base))
    if isinstance(e, ast.Unary):
        return dataclasses.replace(e, operand=fn(e.operand))
    if isinstance(e, ast.Binary):
        return dataclasses.replace(e, left=fn(e.left), right=fn(e.right))
    if isinstance(e, ast.Quant):
        return dataclasses.replace(e, body=fn(e.body))
    return e
