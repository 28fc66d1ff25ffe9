"""The static checker: names, types and the rules of docs/language.md §4-§10.

``check_program`` walks a parsed :class:`pccl.lang.ast.Program` and either returns
a :class:`CheckedProgram` (names, resolved types, enums, functions) or raises the first problem, in source
order, as a :class:`PcclError` whose span points at the offending node.
``check_property`` does the same for a property expression (the program's
``invariant:`` section, ``--invariant EXPR``) against a checked program.

Type rules (where docs/language.md is silent, the choice is written here):

* Types: ``int bool float ItemPosition ObstacleList List<T>``, enums, arrays
  ``T[n]`` (n a constant), and ``any``: the type of an uninterpreted function's
  value (``getInput()``), which fits every slot.
* An int widens to float (also inside lists: ``List<int>`` fits
  ``List<float>``); a float never narrows to int.  ``[]`` fits every
  ``List<T>`` and ``ObstacleList``.
* ``+ - * /``: numbers; int op int is int, otherwise float.  ``%``: ints.
  Arithmetic on an ``any`` value is refused (its static type, hence the
  meaning of ``/``, is unknown): store it in a typed variable first.
* ``< <= > >=``: numbers; ``== !=``: two values of which one fits the other's
  type (enums only with the same enum); ``&& || !``: bool.
* Arrays are not values: an array is always indexed (``a[i]``), never read,
  assigned or compared whole.  An array initialiser gives every element the
  same value: ``bool flags[3] = false;``.
* Allread variables: in a program, a scalar ``x`` is this agent's component
  and ``x[j]`` agent j's; for an allread *array* ``x[k]`` is this agent's
  element k and ``x[j][k]`` agent j's element k.  Further indexes index lists.
  A program writes only its own component.
* Properties: every per-agent variable (local or allread, and the flags
  ``doReach_done``/``doReach_fail``) takes the agent index first: ``v[i]``,
  ``v[i][k]`` for arrays.
* Shared (allwrite) initialisers are evaluated once, outside any agent: they
  may not use per-agent variables, the flags, ``getAgentIndex()`` or
  ``getPosition()``.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from typing import NoReturn, Optional

from pccl.lang import ast
from pccl.lang.ast import Span
from pccl.lang.builtins import BUILTINS, READONLY_FLAGS, Builtin, uninterpreted
from pccl.lang.errors import PcclError
from pccl.lang.types import (ANY, BOOL, BUILTIN_TYPE_NAMES, DESCRIPTORS, FLOAT, INT, POS, TYPE_NAMES, Ty, array_of,
                             assignable, compatible, indexes_agent, join, list_of)
from pccl.lang.values import div, mod


# --------------------------------------------------------------------------
# Types
# --------------------------------------------------------------------------

# The types live in pccl/lang/types.py (shared with the compiler and the display).
_DESCRIPTORS = DESCRIPTORS
_TYPE_NAMES = TYPE_NAMES
_BUILTIN_TYPE_NAMES = BUILTIN_TYPE_NAMES


# --------------------------------------------------------------------------
# The symbol table
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class VarInfo:
    name: str
    section: str                 # allwrite | allread | loc
    type: Ty                     # declared type; Ty("array", ...) for arrays
    decl: ast.VarDecl = field(compare=False, repr=False)

    @property
    def is_array(self) -> bool:
        return self.type.kind == "array"

    @property
    def size(self) -> Optional[int]:
        return self.type.size if self.is_array else None

    @property
    def value_type(self) -> Ty:
        """The type of one element (arrays) or of the variable."""
        return self.type.item if self.is_array else self.type

    @property
    def per_agent(self) -> bool:
        return self.section != "allwrite"


#: Deepest expression nesting accepted: compiled expressions must stay within
#: Python's own limits (about 200 nested parentheses).
MAX_NESTING = 100

#: Most elements of an array (a state holds every element; a write copies them).
MAX_ARRAY = 1_000_000

#: Levels a left-associative chain of operators counts for at most (the
#: compiler emits a long chain flat, see Compiler.chain).
CHAIN_LEVELS = 8


@dataclass
class CheckedProgram:
    """What the checker learnt, and all the compiler needs to know about
    names: variables with their section and resolved :class:`Ty` (in
    declaration order), enums and their members, events, and the functions
    that may be called (the built-ins of :mod:`pccl.lang.builtins` and a world's
    uninterpreted ones)."""
    name: Optional[str]
    filename: str
    source: str
    variables: dict[str, VarInfo] = field(default_factory=dict)   # in declaration order
    enums: dict[str, tuple[str, ...]] = field(default_factory=dict)
    members: dict[str, tuple[str, int]] = field(default_factory=dict)  # member -> (enum, index)
    events: tuple[str, ...] = ()
    functions: frozenset[str] = frozenset()   # extra uninterpreted functions

    def type_of(self, name: str) -> Ty:
        """Type of a variable (an array type for arrays), an enum member or a
        controller flag.  KeyError for anything else."""
        if name in self.variables:
            return self.variables[name].type
        if name in self.members:
            return self.enum_type(self.members[name][0])
        if name in READONLY_FLAGS:
            return _DESCRIPTORS[READONLY_FLAGS[name]]
        raise KeyError(name)

    def enum_type(self, name: str) -> Ty:
        """The type of the enum called ``name`` (with its members)."""
        return Ty("enum", enum=name, members=tuple(self.enums[name]))

    def section_of(self, name: str) -> str:
        return self.variables[name].section

    def vars_in(self, section: str) -> list[VarInfo]:
        return [v for v in self.variables.values() if v.section == section]

    def function(self, name: str) -> Optional[Builtin]:
        """The built-in or uninterpreted function called ``name``, or None."""
        if name in BUILTINS:
            return BUILTINS[name]
        if name in self.functions:
            return uninterpreted(name)
        return None

    def expr_type(self, expr: ast.Expr, *, in_property: bool = False,
                  bound: frozenset[str] = frozenset()) -> Ty:
        """The type of an expression of this program (or of a property, with
        the quantified agent ids ``bound`` in scope): for the compiler, which
        needs e.g. to know whether ``/`` divides ints.  An array variable
        gives its array type.  Raises PcclError if the expression does not
        check (meant for expressions that already passed the checker)."""
        c = _Checker(self, "property" if in_property else "program")
        c.bound = {b: 1 for b in bound}
        return c.expr(expr)


#: The name this class had before it was the compiler's input.
ProgramInfo = CheckedProgram


# --------------------------------------------------------------------------
# Entry points
# --------------------------------------------------------------------------

def check_program(program: ast.Program, *,
                  functions: frozenset[str] = frozenset()) -> CheckedProgram:
    info = CheckedProgram(name=program.name, filename=program.filename,
                       source=program.source, functions=frozenset(functions))
    _Checker(info, "program").program(program)
    return info


def check_property(expr: ast.Expr, info: CheckedProgram, *, filename: str,
                   source: str) -> None:
    c = _Checker(info, "property", filename=filename, source=source)
    c.property(expr)


def check_watch(expr: ast.Expr, info: CheckedProgram, *, filename: str,
                source: str) -> Ty:
    """The type of a watched expression (the viewer's ``--watch``): any
    state expression of a property, of any type; not a temporal form."""
    c = _Checker(info, "property", filename=filename, source=source)
    top = _under_quants(expr)
    if isinstance(top, ast.Temporal):
        c.fail("a watched expression is a state expression, not a temporal property", top.span)
    return c.value(expr)


# --------------------------------------------------------------------------
# The checker
# --------------------------------------------------------------------------

_AGENT_FUNCTIONS = ("getAgentIndex", "getPosition")
_PROPERTY_NAMES = ("time", "N")
#: Status predicates of properties (spec section 9): ``exited[i]``,
#: ``stuck[i]``, ``running[i]``; a program variable of the same name wins.
STATUS_PREDICATES = ("exited", "stuck", "running")
_PROGRAM_ONLY_HINTS = {
    "getAgentIndex": "quantify over agent ids instead, forall i: …",
    "getPosition": "write pos[i] for agent i's position",
    "rand": "a property is evaluated on a state, not sampled",
}


class _Checker:
    def __init__(self, info: CheckedProgram, mode: str, *,
                 filename: Optional[str] = None, source: Optional[str] = None):
        self.info = info
        self.mode = mode                          # program | property
        self.filename = info.filename if filename is None else filename
        self.source = info.source if source is None else source
        self.bound: dict[str, int] = {}           # property: quantified ids
        # declaration pass state
        self.first_decl: dict[str, ast.VarDecl] = {}
        self.init_of: Optional[VarInfo] = None     # variable being initialised

    @property
    def lines(self) -> list:
        """The program's lines, split once when first needed (a checker is
        made per compiled expression: splitting eagerly was quadratic)."""
        lines = self.__dict__.get("_lines")
        if lines is None:
            lines = self._lines = self.source.splitlines()
        return lines

    # ---- reporting -------------------------------------------------------

    def fail(self, message: str, span: Optional[Span], template: bool = False) -> NoReturn:
        """Raise the error ``message`` at ``span``; ``template``: the message
        names options as placeholders (:func:`pccl.lang.errors.spell`)."""
        raise PcclError(message, filename=self.filename, source=self.source,
                        span=span, template=template)

    def text(self, node, default: str) -> str:
        """The source text of a one-line node, else ``default``."""
        s = getattr(node, "span", None)
        lines = self.lines_of(s)
        if s is None or s.line < 1 or s.line != s.end_line or s.line > len(lines):
            return default
        t = lines[s.line - 1][s.column - 1:s.end_column - 1].strip()
        return t or default

    @staticmethod
    def declared_at(name_span: Span, whole: Span) -> Span:
        """Where a declared name is written (the parser records it); the
        whole declaration for an AST built without positions."""
        return name_span if name_span.line > 0 else whole

    def name_span(self, node) -> Span:
        """The span of a call's function name (calls start with the name)."""
        s = node.span
        if s.line < 1:
            return s
        return Span(s.line, s.column, s.line, s.column + len(node.name), s.origin)

    def lines_of(self, span) -> list:
        """The lines ``span`` refers to: the program's, or an option's text."""
        origin = getattr(span, "origin", None)
        if origin is not None and origin[1] is not None:
            return origin[1].splitlines()
        return self.lines

    # ---- program ---------------------------------------------------------

    def program(self, p: ast.Program) -> None:
        """Check a whole program, in source order: declarations, Init, the
        events, the invariants."""
        self.collect_enums(p.decls)
        self.declared: dict[str, tuple[str, int]] = {}     # name -> (what, line)
        for d in p.decls:
            if isinstance(d, ast.EnumDecl):
                self.enum_decl(d)
            else:
                self.var_decl(d)
        self.first_decl = {}
        self.stmts(p.init)
        self.events(p.events)
        self.invariants(p.invariants)

    def collect_enums(self, decls) -> None:
        """Enums are constants visible everywhere: collect them first so that
        a type or a member may be used above its enum's declaration (and note
        each variable's first declaration, for initialisers)."""
        info = self.info
        for d in decls:
            if isinstance(d, ast.EnumDecl):
                if d.name not in info.enums and d.name not in _BUILTIN_TYPE_NAMES:
                    info.enums[d.name] = d.members
                for k, m in enumerate(d.members):
                    info.members.setdefault(m, (d.name, k))
            else:
                self.first_decl.setdefault(d.name, d)

    def claim(self, name: str, what: str, span: Span, where: Span) -> None:
        """Declare ``name`` as a ``what`` (variable, enum, enum member): one
        name, one meaning; flags cannot be declared."""
        if name in READONLY_FLAGS:
            self.fail(f"'{name}' is a read-only flag of the controller; "
                      f"it cannot be declared", where)
        if name in self.declared:
            prev, line = self.declared[name]
            if prev == what:
                self.fail(f"duplicate {what} '{name}'{_first_at(line)}", where)
            at_line = f" at line {line}" if line > 0 else ""
            self.fail(f"'{name}' is already declared as {_article(prev)}{at_line}",
                      where)
        self.declared[name] = (what, span.line)

    def enum_decl(self, d: ast.EnumDecl) -> None:
        at = self.declared_at(d.name_span, d.span)
        if d.name in _BUILTIN_TYPE_NAMES:
            self.fail(f"'{d.name}' is a built-in type; it cannot name an enum", at)
        self.claim(d.name, "enum", d.span, at)
        seen: set[str] = set()
        for k, m in enumerate(d.members):
            ms = (self.declared_at(d.member_spans[k], d.span)
                  if k < len(d.member_spans) else d.span)
            if m in seen:
                self.fail(f"duplicate member '{m}' in enum '{d.name}'", ms)
            seen.add(m)
            self.claim(m, "enum member", d.span, ms)

    def var_decl(self, d: ast.VarDecl) -> None:
        """A variable: its name, type, array size and initialiser."""
        self.claim(d.name, "variable", d.span, self.declared_at(d.name_span, d.span))
        ty = self.declared_type(d.type, d.span)
        if d.size is not None:
            ty = array_of(ty, self.array_size(d.size))
        v = VarInfo(d.name, d.section, ty, d)
        if d.init is not None:
            self.init_of = v
            t = self.value(d.init)
            if not assignable(v.value_type, t):
                self.fail(f"cannot initialise '{d.name}' of type {v.value_type} "
                          f"with {t}", d.init.span)
            self.init_of = None
        self.info.variables.setdefault(d.name, v)

    def array_size(self, size: ast.Expr) -> int:
        """A constant array size in 1..MAX_ARRAY."""
        try:
            n = self.const_int(size)
        except RecursionError:
            self.fail("array size expression is nested too deeply", size.span)
        if n < 1:
            self.fail(f"array size must be at least 1, got {n}", size.span)
        if n > MAX_ARRAY:
            self.fail(f"array size must be at most {MAX_ARRAY:,}, got "
                      f"{n if n < 10 ** 30 else f'a number of {len(str(n))} digits'}"
                      f" (every state holds every element, and a write copies them)",
                      size.span)
        return n

    def events(self, events) -> None:
        seen: dict[str, int] = {}
        for ev in events:
            if ev.name in seen:
                self.fail(f"duplicate event '{ev.name}'{_first_at(seen[ev.name])}",
                          self.declared_at(ev.name_span, ev.span))
            seen[ev.name] = ev.span.line
            self.condition(ev.guard, "pre")
            self.stmts(ev.body)
        self.info.events = tuple(seen)

    def invariants(self, invariants) -> None:
        seen: dict[str, int] = {}
        for inv in invariants:
            if inv.name is not None:
                if inv.name in seen:
                    self.fail(f"duplicate invariant '{inv.name}'{_first_at(seen[inv.name])}",
                              self.declared_at(inv.name_span, inv.span))
                seen[inv.name] = inv.span.line
            _Checker(self.info, "property").property(inv.expr)

    def declared_type(self, t: ast.TypeRef, where: Span) -> Ty:
        span = t.span if t.span.line > 0 else where
        if t.name in _TYPE_NAMES:
            return _TYPE_NAMES[t.name]
        if t.name == "List":
            if t.elem is None:
                self.fail("List needs an element type: List<T>", span)
            return list_of(self.declared_type(t.elem, where))
        if t.name in self.info.enums:
            return self.info.enum_type(t.name)
        self.fail(f"unknown type '{t.name}'", span)

    def const_int(self, e: ast.Expr) -> int:
        """An array size: an int literal or arithmetic on int literals."""
        if isinstance(e, ast.IntLit):
            return e.value
        if isinstance(e, ast.Unary) and e.op == "-":
            return -self.const_int(e.operand)
        if isinstance(e, ast.Binary) and e.op in ("+", "-", "*", "/", "%"):
            a, b = self.const_int(e.left), self.const_int(e.right)
            if e.op == "+":
                return a + b
            if e.op == "-":
                return a - b
            if e.op == "*":
                return a * b
            if b == 0:
                self.fail("division by zero in array size", e.span)
            return div(a, b) if e.op == "/" else mod(a, b)
        self.fail("array size must be a constant int expression", e.span)

    # ---- statements ------------------------------------------------------

    def stmts(self, body) -> None:
        for s in body:
            self.stmt(s)

    def stmt(self, s) -> None:
        if isinstance(s, ast.Assign):
            t = self.lvalue(s.target)
            v = self.value(s.value)
            if not assignable(t, v):
                self.fail(f"cannot assign {v} to '{self.text(s.target, 'the target')}' "
                          f"of type {t}", s.value.span)
        elif isinstance(s, ast.If):
            for cond, body in s.branches:
                self.condition(cond, "if")
                self.stmts(body)
            self.stmts(s.orelse)
        elif isinstance(s, ast.While):
            self.condition(s.cond, "while")
            self.stmts(s.body)
        elif isinstance(s, ast.Atomic):
            self.stmts(s.body)
        elif isinstance(s, ast.CallStmt):
            b = self.info.function(s.name)
            if b is None:
                self.fail(f"unknown function '{s.name}'"
                          f"{self.suggest_function(s.name, statement=True)}",
                          self.name_span(s))
            if b.kind == "property":
                self.fail(f"'{s.name}' is only available in properties", self.name_span(s))
            if not b.is_statement:
                self.fail(f"'{s.name}' returns a value; it is not a statement",
                          self.name_span(s))
            self.args(b, s)
        elif isinstance(s, ast.Skip):
            pass
        else:  # pragma: no cover - the parser builds only the above
            self.fail(f"unexpected statement {type(s).__name__}", getattr(s, "span", None))

    def condition(self, e: ast.Expr, what: str) -> None:
        t = self.value(e)
        if t.kind not in ("bool", "any"):
            self.fail(f"condition of '{what}' must be bool, got {t}", e.span)

    def lvalue(self, target: ast.Expr) -> Ty:
        """Check that ``target`` may be written by this agent; its type."""
        if isinstance(target, ast.Field):
            self.fail(f"cannot assign to field '.{target.name}': assign a whole "
                      f"ItemPosition instead", target.span)
        root, chain = ast.index_chain(target)
        if not isinstance(root, ast.Name):
            self.fail("cannot assign to this expression: the target must be a "
                      "variable or an element of one", target.span)
        name = root.name
        var = self.info.variables.get(name)
        if var is None:
            if name in READONLY_FLAGS:
                self.fail(f"'{name}' is read-only: set by the controller", root.span)
            if name in self.info.members:
                self.fail(f"cannot assign to enum member '{name}'", root.span)
            if self.info.function(name) is not None:
                self.fail(f"cannot assign to function '{name}'", root.span)
            self.fail(f"undeclared variable '{name}'"
                      f"{did_you_mean(name, self.info.variables)}", root.span)
        if var.section == "allread":
            agent_index = len(chain) >= (2 if var.is_array else 1)
            if agent_index:
                j = chain[0].index
                own = f"{name}[k] = …" if var.is_array else f"{name} = …"
                self.fail(f"cannot write agent {self.text(j, 'j')}'s component of allread "
                          f"variable '{name}': an agent writes only its own component, "
                          f"`{own}`", target.span)
        if not chain and var.is_array:
            self.fail(f"cannot assign to array '{name}' as a whole: assign its "
                      f"elements, {name}[i] = …", target.span)
        return self.value(target)

    def args(self, b: Builtin, call) -> Ty:
        """Check a call's arguments against the table; its result type."""
        n = len(call.args)
        if n not in b.arities:
            if b.arities == (0,):
                self.fail(f"'{b.name}' takes no arguments, got {n}", call.span)
            plural = "argument" if b.arities == (1,) else "arguments"
            self.fail(f"'{b.name}' takes {b.arity_text()} {plural}, got {n}", call.span)
        elem = ANY
        for k, (a, p) in enumerate(zip(call.args, b.params), start=1):
            elem = self.arg(b, k, a, p, elem)
        if b.result is None:
            return ANY
        return elem if b.result == "elem" else _DESCRIPTORS[b.result]

    def arg(self, b: Builtin, k: int, a: ast.Expr, p: str, elem: Ty) -> Ty:
        """Check argument ``k`` (``a``, described as ``p`` in the table) of a
        call of ``b``; the element type of the call's list so far."""
        what = f"argument {k} of '{b.name}'"
        if p == "list-var":
            if not isinstance(a, (ast.Name, ast.Index)):
                self.value(a)
                self.fail(f"{what} must be a List variable (it is rewritten in "
                          f"place), not an expression", a.span)
            t = self.lvalue(a)
            if t.kind != "list" and t.kind != "any":
                self.fail(f"{what} must be a List variable, got {t}", a.span)
            return t.item if t.kind == "list" else ANY
        t = self.value(a)
        if p == "list":
            if t.kind not in ("list", "any"):
                self.fail(f"{what} must be a List, got {t}", a.span)
            return t.item if t.kind == "list" else ANY
        if p == "elem":
            if not assignable(elem, t):
                self.fail(f"{what} must be {elem} (the list's element type), "
                          f"got {t}", a.span)
        elif p == "float":
            if not (t.is_number or t.kind == "any"):
                self.fail(f"{what} must be a number, got {t}", a.span)
        elif p == "bool" and b.name == "assert":
            if t.kind not in ("bool", "any"):
                self.fail(f"condition of 'assert' must be bool, got {t}", a.span)
        else:
            want = _DESCRIPTORS[p]
            if not assignable(want, t):
                self.fail(f"{what} must be {want}, got {t}", a.span)
        return elem

    # ---- expressions -----------------------------------------------------

    def value(self, e: ast.Expr) -> Ty:
        """The type of ``e`` used as a value (arrays must be indexed)."""
        t = self.expr(e)
        if t.kind == "array":
            name = self.text(e, "the array")
            self.fail(f"array '{name}' must be indexed: write {name}[i]", e.span)
        return t

    def expr(self, e: ast.Expr) -> Ty:
        depth = self.__dict__.get("_depth", 0)
        if depth >= MAX_NESTING:
            self.fail(f"expression nested too deeply (more than {MAX_NESTING} levels)", e.span)
        self._depth = depth + 1
        try:
            return self._expr(e)
        finally:
            self._depth = depth

    def _expr(self, e: ast.Expr) -> Ty:
        if isinstance(e, ast.IntLit):
            return INT
        if isinstance(e, ast.FloatLit):
            return FLOAT
        if isinstance(e, ast.BoolLit):
            return BOOL
        if isinstance(e, ast.ListLit):
            return self.list_lit(e)
        if isinstance(e, ast.Name):
            return self.name(e)
        if isinstance(e, ast.Index):
            return self.index(e)
        if isinstance(e, ast.Field):
            return self.field(e)
        if isinstance(e, ast.Call):
            return self.call(e)
        if isinstance(e, ast.Unary):
            return self.unary(e)
        if isinstance(e, ast.Binary):
            return self.binary(e)
        if isinstance(e, ast.Temporal):
            word = "~>" if e.kind == "leadsto" else e.kind
            self.fail(f"'{word}' must stand at the top of a property (under 'forall' at "
                      f"most): it is not a value", e.span)
        if isinstance(e, ast.Quant):
            return self.quant(e)
        self.fail(f"unexpected expression {type(e).__name__}",  # pragma: no cover
                  getattr(e, "span", None))

    def list_lit(self, e: ast.ListLit) -> Ty:
        t = ANY
        for x in e.items:
            u = self.value(x)
            j = join(t, u)
            if j is None:
                self.fail(f"list elements disagree: {u} after {t}", x.span)
            t = j
        return list_of(t)

    def field(self, e: ast.Field) -> Ty:
        t = self.value(e.base)
        if t.kind not in ("pos", "any"):
            self.fail(f"field '.{e.name}' needs an ItemPosition, got {t}", e.span)
        if e.name not in ("x", "y", "z"):
            self.fail(f"ItemPosition has no field '.{e.name}' (only .x, .y, .z)",
                      e.span)
        return FLOAT

    def unary(self, e: ast.Unary) -> Ty:
        t = self.value(e.operand)
        if e.op == "!":
            if t.kind not in ("bool", "any"):
                self.fail(f"operand of '!' must be bool, got {t}", e.operand.span)
            return BOOL
        self.arith_operand(e.op, t, e.operand, "operand")
        return t

    def quant(self, e: ast.Quant) -> Ty:
        if self.mode != "property":
            self.fail(f"'{e.kind}' is only allowed in properties", e.span)
        saved = dict(self.bound)
        self.bound[e.var] = 1
        t = self.value(e.body)
        if t.kind not in ("bool", "any"):
            self.fail(f"the body of '{e.kind}' must be bool, got {t}", e.body.span)
        self.bound = saved
        return BOOL

    def arith_operand(self, op: str, t: Ty, node, operands: str = "operands") -> None:
        if t.kind == "any":
            self.fail(f"operand of '{op}' has no static type (a value from the "
                      f"world file): store it in a typed variable first", node.span)
        if op == "%":
            if t.kind != "int":
                self.fail(f"{operands} of '%' must be int, got {t}", node.span)
        elif not t.is_number:
            numbers = "a number" if operands == "operand" else "numbers"
            self.fail(f"{operands} of '{op}' must be {numbers}, got {t}", node.span)

    def binary(self, e: ast.Binary) -> Ty:
        """A left-associative chain ``a + b - c …`` (the left spine of Binary
        nodes) is checked iteratively from its innermost operand, and counts
        as at most :data:`CHAIN_LEVELS` levels of nesting: a flat sum of 3,000
        terms is not nested.  Its right operands are one level deeper."""
        spine = [e]
        x = e.left
        while isinstance(x, ast.Binary) and x.op != "->":
            spine.append(x)
            x = x.left
        depth = self._depth
        extra = min(len(spine), CHAIN_LEVELS) - 1
        if extra:
            if depth + extra > MAX_NESTING:
                self.fail(f"expression nested too deeply (more than {MAX_NESTING} levels)",
                          spine[MAX_NESTING - depth + 1].span)
            self._depth = depth + extra
        try:
            a = self.value(x)
            for node in reversed(spine):
                a = self.binary_node(node, a)
            return a
        finally:
            self._depth = depth

    def binary_node(self, e: ast.Binary, a: Ty) -> Ty:
        """The type of ``e`` whose left operand has type ``a``."""
        op = e.op
        if op == "->" and self.mode != "property":
            self.fail("'->' is only allowed in properties", e.span)
        b = self.value(e.right)
        if op in ("||", "&&", "->"):
            for t, n in ((a, e.left), (b, e.right)):
                if t.kind not in ("bool", "any"):
                    self.fail(f"operands of '{op}' must be bool, got {t}", n.span)
            return BOOL
        if op in ("==", "!="):
            if not compatible(a, b):
                self.fail(f"cannot compare {a} with {b} using '{op}'", e.span)
            return BOOL
        if op in ("<", "<=", ">", ">="):
            for t, n in ((a, e.left), (b, e.right)):
                if not (t.is_number or t.kind == "any"):
                    self.fail(f"operands of '{op}' must be numbers, got {t}", n.span)
            return BOOL
        if op in ("+", "-", "*", "/", "%"):
            self.arith_operand(op, a, e.left)
            self.arith_operand(op, b, e.right)
            return INT if a.kind == b.kind == "int" else FLOAT
        self.fail(f"unknown operator '{op}'", e.span)  # pragma: no cover

    def undeclared(self, n: ast.Name) -> NoReturn:
        if self.info.function(n.name) is not None:
            self.fail(f"'{n.name}' is a function: call it, {n.name}()", n.span)
        if self.mode == "program" and n.name == "time":
            self.fail("undeclared variable 'time' (a program cannot read the clock)",
                      n.span)
        self.fail(f"undeclared variable '{n.name}'{self.suggest_name(n.name)}", n.span)

    def suggest_name(self, name: str) -> str:
        """" (did you mean 'x'?)" for a readable name close to ``name``, else ""."""
        names = [*self.info.variables, *self.first_decl, *READONLY_FLAGS, *self.info.members]
        if self.mode == "property":
            names += [*self.bound, *_PROPERTY_NAMES, "pos", *STATUS_PREDICATES]
        return did_you_mean(name, names)

    def suggest_function(self, name: str, *, statement: bool = False) -> str:
        """" (did you mean 'f'?)" for a function callable here close to ``name``."""
        funcs = {n: BUILTINS[n] for n in BUILTINS}
        funcs.update({n: uninterpreted(n) for n in self.info.functions})
        if statement:
            names = [n for n, b in funcs.items() if b.is_statement]
        elif self.mode == "property":
            names = [n for n, b in funcs.items() if b.in_properties]
        else:
            names = [n for n, b in funcs.items()
                     if not b.is_statement and b.kind != "property"]
        return did_you_mean(name, names)

    def per_agent_in_property(self, n: ast.Name):
        self.fail(f"'{n.name}' is per-agent: write {n.name}[i]", n.span)

    def ambiguous(self, n: ast.Name):
        if n.name in self.info.variables:
            self.fail(f"'{n.name}' is ambiguous in a property: the program declares a "
                      f"variable '{n.name}'; rename it", n.span)

    def name(self, n: ast.Name) -> Ty:
        name = n.name
        if self.mode == "property":
            if name in self.bound:
                return INT
            if name in _PROPERTY_NAMES:
                self.ambiguous(n)
                return FLOAT if name == "time" else INT
            if name == "pos":
                self.ambiguous(n)
                self.per_agent_in_property(n)
            if name in STATUS_PREDICATES and name not in self.info.variables:
                self.per_agent_in_property(n)
        if self.init_of is not None:
            var = self.visible_in_init(n)
        else:
            var = self.info.variables.get(name)
        if var is not None:
            if self.mode == "property" and var.per_agent:
                self.per_agent_in_property(n)
            return var.type
        if name in READONLY_FLAGS:
            if self.mode == "property":
                self.per_agent_in_property(n)
            if self.init_of is not None and self.init_of.section == "allwrite":
                self.fail(f"'{name}' is per-agent: a shared (allwrite) initialiser "
                          f"cannot use it", n.span)
            return BOOL
        if name in self.info.members:
            return self.info.enum_type(self.info.members[name][0])
        self.undeclared(n)

    def visible_in_init(self, n: ast.Name) -> Optional[VarInfo]:
        """The variable ``n`` names, as seen from an initialiser."""
        d = self.first_decl.get(n.name)
        if d is None:
            return None
        assert self.init_of is not None, "only called inside an initialiser"
        if self.init_of.section == "allwrite" and d.section != "allwrite":
            self.fail(f"shared (allwrite) variable '{self.init_of.name}' cannot be "
                      f"initialised from per-agent ({d.section}) variable '{n.name}'",
                      n.span)
        var = self.info.variables.get(n.name)
        if var is None or var.decl is not d:
            self.fail(f"'{n.name}' is not declared yet: an initialiser can use only "
                      f"variables declared above it", n.span)
        return var

    def index(self, e: ast.Index) -> Ty:
        root, chain = ast.index_chain(e)
        t = None
        if isinstance(root, ast.Name) and root.name not in self.bound:
            t = self.agent_root(root, chain)
        if t is None:
            t = self.expr(root)
        else:
            chain = chain[1:]                  # the agent index is consumed
        for node in chain:
            if t.kind not in ("array", "list", "any"):
                self.fail(f"cannot index a value of type {t}", node.span)
            self.index_value(node.index)
            t = ANY if t.kind == "any" else t.item
        return t

    def index_value(self, ix: ast.Expr, what: str = "index") -> None:
        u = self.value(ix)
        if u.kind not in ("int", "any"):
            self.fail(f"{what} must be int, got {u}", ix.span)

    def agent_root(self, root: ast.Name, chain) -> Optional[Ty]:
        """``x[j]…`` where j picks an agent: check j and return the type of
        agent j's component, or None when the first index is not an agent's."""
        name = root.name
        var = self.info.variables.get(name)
        if self.mode == "property":
            if name == "pos":
                self.ambiguous(root)
                t = POS
            elif var is not None:
                if not indexes_agent(var.section, var.is_array, len(chain), in_property=True):
                    return None
                t = var.type
            elif name in READONLY_FLAGS or name in STATUS_PREDICATES:
                t = BOOL
            else:
                return None
        else:
            if var is None or not indexes_agent(var.section, var.is_array, len(chain),
                                                in_property=False):
                return None                    # e.g. x[k]: this agent's element k
            if self.init_of is not None:
                var = self.visible_in_init(root)
                assert var is not None, name          # declared: found above
            t = var.type
        self.index_value(chain[0].index, "agent index")
        return t

    def call(self, e: ast.Call) -> Ty:
        b = self.info.function(e.name)
        if b is None:
            hint = self.suggest_function(e.name)
            if not hint and self.mode == "program" and not e.args:
                # a zero-argument call the world could define (uninterpreted)
                hint = (f": not a built-in; a function the world provides needs {{world=FILE}} "
                        f"defining {e.name} under [functions]")
            self.fail(f"unknown function '{e.name}'{hint}", self.name_span(e), template=bool(hint))
        if b.is_statement:
            self.fail(f"'{e.name}' is a statement, not a value", self.name_span(e))
        if self.mode == "property":
            if not b.in_properties:
                why = _PROGRAM_ONLY_HINTS.get(e.name)
                if b.kind == "uninterpreted":
                    why = "its value belongs to the world, not to the state"
                self.fail(f"'{e.name}' cannot be used in a property: {why}",
                          self.name_span(e))
            if b.kind == "property":
                return self.count(e)
        elif b.kind == "property":
            self.fail(f"'{e.name}' is only available in properties", self.name_span(e))
        if (self.init_of is not None and self.init_of.section == "allwrite"
                and e.name in _AGENT_FUNCTIONS):
            self.fail(f"'{e.name}' needs an agent: a shared (allwrite) initialiser "
                      f"cannot call it", self.name_span(e))
        return self.args(b, e)

    def count(self, e: ast.Call) -> Ty:
        if len(e.args) != 1:
            self.fail(f"'count' takes 1 argument, got {len(e.args)}", e.span)
        a = e.args[0]
        var = self.info.variables.get(a.name) if isinstance(a, ast.Name) else None
        ok = (isinstance(a, ast.Name) and a.name not in self.bound
              and ((var is not None and var.per_agent and var.type == BOOL)
                   or (var is None and (a.name in READONLY_FLAGS
                                        or a.name in STATUS_PREDICATES))))
        if (not ok and isinstance(a, ast.Name) and var is None and a.name not in self.bound
                and a.name not in READONLY_FLAGS and a.name not in self.info.members):
            self.fail(f"undeclared variable '{a.name}'{self.suggest_name(a.name)}", a.span)
        if not ok:
            self.fail("'count' takes the name of a bool local or allread variable, "
                      "count(v)", a.span)
        return INT

    # ---- properties ------------------------------------------------------

    def property(self, e: ast.Expr) -> None:
        """A property: a bool state expression, or one of the temporal forms
        of spec section 9 at the top, under ``forall`` quantifiers at most
        (``forall i: want[i] ~> has[i]`` is one property per agent)."""
        top, saved = e, dict(self.bound)
        while isinstance(top, ast.Quant) and isinstance(_under_quants(top.body), ast.Temporal):
            if top.kind != "forall":
                self.fail(f"only 'forall' may quantify a temporal property ('{top.kind}' "
                          f"would need a branching-time check)", top.span)
            self.bound[top.var] = 1
            top = top.body
        if isinstance(top, ast.Temporal):
            for x in (top.p, top.q):
                if x is not None:
                    t = self.value(x)
                    if t.kind not in ("bool", "any"):
                        self.fail(f"a property must be bool, got {t}", x.span)
            if top.bound is not None:
                self.time_bound(top.bound)
            self.bound = saved
            return
        t = self.value(e)
        if t.kind not in ("bool", "any"):
            self.fail(f"a property must be bool, got {t}", e.span)

    def time_bound(self, b: ast.Expr) -> None:
        """The T of ``P ~> Q within T``: a constant number >= 0."""
        for x in ast.walk_expr(b):
            if not isinstance(x, (ast.IntLit, ast.FloatLit, ast.Unary, ast.Binary)):
                self.fail("the bound of 'within' must be a constant number of time units, "
                          "e.g. 'within 3'", b.span)
        t = self.value(b)
        if not t.is_number:
            self.fail(f"the bound of 'within' must be a number, got {t}", b.span)


def _under_quants(e):
    while isinstance(e, ast.Quant):
        e = e.body
    return e


def did_you_mean(name: str, candidates) -> str:
    """" (did you mean 'x'?)" for the candidate closest to ``name`` (a
    difference of case first), or "" when none is close."""
    candidates = sorted(set(candidates) - {name})
    same = [c for c in candidates if c.lower() == name.lower()]
    close = same or difflib.get_close_matches(name, candidates, n=1, cutoff=0.75)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _article(what: str) -> str:
    return ("an " if what[0] in "aeiou" else "a ") + what


def _first_at(line: int) -> str:
    return f" (first declared at line {line})" if line > 0 else ""
