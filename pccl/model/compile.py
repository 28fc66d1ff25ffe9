"""Compile a checked PCCL program into fast Python closures.

Expressions are translated once into Python source and ``exec``'d into plain
functions (no tree walking per evaluation).  Agent expressions have the
signature ``f(i, ag, sh, ags)``: agent id, the agent's tuple, the shared
variable tuple and the tuple of all agents.  Property expressions have the
signature ``f(st)`` over a whole configuration.

The configuration's layout is :mod:`pccl.model.layout`'s; the generated code
indexes cells with its constants interpolated as numbers (``f"ag[{AR}]"``
becomes a literal subscript), so naming them costs nothing at run time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NoReturn, Optional
from collections.abc import Callable

from pccl.lang import ast as A
from pccl.lang import values as V
from pccl.lang.builtins import BUILTINS, STATEMENTS, UNINTERPRETED
from pccl.lang.checker import CheckedProgram
from pccl.lang.data import is_number
from pccl.lang.errors import PcclError, ToolLimitError
from pccl.model.layout import AGS, AR, DONE, FAIL, LOC, N_AGENT_CELLS, POS, REACH, SH, TIME
from pccl.lang.types import ANY, FLOAT, Ty, indexes_agent


def _rebuild(var: str, index: int, new: str) -> str:
    """Source of the agent tuple ``var`` with cell ``index`` replaced by ``new``:
    a tuple display with numeric subscripts (the fastest rebuild)."""
    cells = [new if k == index else f"{var}[{k}]" for k in range(N_AGENT_CELLS)]
    return "(" + ", ".join(cells) + ")"



@dataclass
class VarSlot:
    name: str
    section: str          # allwrite | allread | loc
    slot: int
    ty: Ty
    decl: A.VarDecl
    may_undef: bool


@dataclass
class Layout:
    shared: list = field(default_factory=list)     # VarSlot, allwrite
    allread: list = field(default_factory=list)
    local: list = field(default_factory=list)
    vars: dict = field(default_factory=dict)       # name -> VarSlot
    enums: dict = field(default_factory=dict)      # enum name -> Ty
    members: dict = field(default_factory=dict)    # member -> (Ty, index)


def build_layout(program: A.Program, info: CheckedProgram) -> Layout:
    """Slots for every variable, in declaration order per section; the types
    are the checker's (``info``), resolved once."""
    lay = Layout()
    for name in info.enums:
        t = info.enum_type(name)
        lay.enums[name] = t
        for k, m in enumerate(t.members or ()):
            lay.members.setdefault(m, (t, k))
    groups = {"allwrite": lay.shared, "allread": lay.allread, "loc": lay.local}
    for v in info.variables.values():
        group = groups[v.section]
        # a variable can be undefined only if it lacks an initialiser
        vs = VarSlot(v.name, v.section, len(group), v.type, v.decl,
                     may_undef=v.decl.init is None)
        group.append(vs)
        lay.vars[v.name] = vs
    return lay


def coerce(value, ty: Ty):
    """Turn a raw world/registered value into a PCCL value of type ``ty``."""
    if value is V.UNDEF or ty.kind == "any":
        return value
    k = ty.kind
    if k == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"expected an int, got {value!r}")
        return value
    if k == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"expected a number, got {value!r}")
        try:
            value = float(value) + 0.0
        except OverflowError:
            raise ValueError(f"expected a float, got {value!r}: too large") from None
        if value - value:
            raise ValueError(f"expected a finite number, got {value!r}")
        return value
    if k == "bool":
        if not isinstance(value, bool):
            raise ValueError(f"expected a bool, got {value!r}")
        return value
    if k == "enum":
        return _coerce_enum(value, ty)
    if k == "pos":
        return _coerce_pos(value)
    if k == "obstacles":
        return _coerce_obstacles(value)
    if k in ("list", "array"):
        return _coerce_sequence(value, ty)
    return value


def _coerce_enum(value, ty: Ty) -> int:
    members = ty.members or ()
    if isinstance(value, str) and value in members:
        return members.index(value)
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value < len(members):
        return value
    raise ValueError(f"expected one of {', '.join(members)}, got {value!r}")


def _coerce_pos(value) -> tuple:
    if isinstance(value, (tuple, list)) and len(value) in (2, 3) and all(is_number(c) for c in value):
        return tuple(coerce(c, _FLOAT) for c in value) + (0.0,) * (3 - len(value))
    raise ValueError(f"expected a position [x, y] or [x, y, z], got {value!r}")


def _coerce_obstacles(value) -> tuple:
    if not isinstance(value, (tuple, list)):
        raise ValueError(f"expected a list of polygons, got {value!r}")
    polys = []
    for poly in value:
        if not isinstance(poly, (tuple, list)) or len(poly) < 3:
            raise ValueError(f"expected a polygon (at least 3 points), got {poly!r}")
        pts = []
        for p in poly:
            if not (isinstance(p, (tuple, list)) and len(p) >= 2 and all(is_number(c) for c in p)):
                raise ValueError(f"expected a point [x, y], got {p!r}")
            pts.append((coerce(p[0], _FLOAT), coerce(p[1], _FLOAT)))
        polys.append(tuple(pts))
    return tuple(polys)


def _coerce_sequence(value, ty: Ty) -> tuple:
    """A List or an array (``ty.kind``) of ``ty.item``."""
    if not isinstance(value, (tuple, list)):
        raise ValueError(f"expected a list, got {value!r}")
    out = tuple(coerce(x, ty.item) for x in value)
    if ty.kind == "array" and len(out) != ty.size:
        raise ValueError(f"expected {ty.size} elements, got {len(out)}")
    return out


_FLOAT = FLOAT


def canon(value, ty: Ty):
    """:func:`coerce` at run time, for a value of no static type (``any``:
    ``getInput()[k]``) or a list that needs widening; a value that does not
    fit gets the agent stuck."""
    try:
        return coerce(value, ty)
    except ValueError as exc:
        raise V.PcclRuntimeError(str(exc)) from None


def widens(src: Ty, dst: Ty) -> bool:
    """Does storing a value of static type ``src`` into a
    ``dst`` slot need a conversion beyond the top level (``List<int>`` into
    ``List<float>``, at any depth)?"""
    if src.kind == "int" and dst.kind == "float":
        return True
    if src.kind == "list" and dst.kind == "list":
        return widens(src.item, dst.item)
    return False


#: The most outcomes of ``rand`` one transition may have in explore (they are
#: built at once): beyond it the agent is stuck with a clear reason.
MAX_OUTCOMES = 1_000_000


class Oracle:
    """Supplies ``rand(n)`` outcomes.

    * enumeration mode (explore): :meth:`outcomes` re-runs a computation
      once per combination of choices (depth-first over choice points);
    * policy mode (run, tests): ``policy(n, agent, span) -> int`` decides.
    """

    def __init__(self, policy: Optional[Callable] = None):
        self.policy = policy
        self.prefix: list = []
        self.trail: list = []
        self.agent: Optional[int] = None
        self.span = None
        self.eager = False      # inside outcomes(): the whole product is built
        self.size = 1           # outcomes of the current evaluation so far
        #: the program's file name and text, for the location of a ToolLimitError
        self.filename: Optional[str] = None
        self.source: Optional[str] = None

    def rand(self, n, span=None):
        if type(n) is not int:
            raise V.PcclRuntimeError(f"rand({n!r}): bound is not an integer")
        if n < 0:
            raise V.PcclRuntimeError(f"rand({n}): bound is negative")
        if self.policy is not None:
            v = self.policy(n, self.agent, span)
            if type(v) is not int or not 0 <= v <= n:
                raise ValueError(f"rand hook returned {v!r}, outside 0..{n}")
            return v
        if self.eager:
            size = self.size * (n + 1)
            if size > MAX_OUTCOMES:
                # a limit of the tool, not a fault of the agent: not a stuck
                # agent (a violation) but an error that stops the search
                self.eager = False
                line = f" at line {span.line}" if span is not None else ""
                raise ToolLimitError(
                    f"rand({n:,}){line}: this transition would have {size:,} outcomes, and "
                    f"explore enumerates at most {MAX_OUTCOMES:,} per transition: a limit of "
                    f"the tool, not a violation of the program (use a smaller range; pccl run "
                    f"draws one outcome and has no such limit)",
                    span=span, filename=self.filename, source=self.source)
            self.size = size
        k = len(self.trail)
        v = self.prefix[k] if k < len(self.prefix) else 0
        self.trail.append((v, n))
        return v

    def iter_outcomes(self, fn, *args):
        """Like :meth:`outcomes`, lazily: one result at a time, the
        enumeration's own position kept locally, so that the consumer may use
        the oracle (for other computations) between two results."""
        if self.policy is not None:
            yield fn(*args)
            return
        prefix: list = []
        while True:
            self.prefix, self.trail = prefix, []
            try:
                r = fn(*args)
                trail = self.trail
            finally:
                self.prefix, self.trail = [], []
            while trail and trail[-1][0] >= trail[-1][1]:
                trail.pop()
            yield r
            if not trail:
                return
            prefix = [c for c, _ in trail[:-1]] + [trail[-1][0] + 1]

    def outcomes(self, fn, *args):
        """All results of ``fn(*args)`` over every combination of rand values."""
        if self.policy is not None:
            return [fn(*args)]
        results = []
        self.prefix = []
        self.eager = True
        while True:
            self.trail = []
            self.size = 1
            try:
                results.append(fn(*args))
            except BaseException:
                self.eager = False
                raise
            trail = self.trail
            while trail and trail[-1][0] >= trail[-1][1]:
                trail.pop()
            if not trail:
                break
            self.prefix = [c for c, _ in trail[:-1]] + [trail[-1][0] + 1]
        self.eager = False
        self.trail = []
        self.prefix = []
        return results


#: Status predicates of properties (spec section 9) as tests of an agent's
#: status cell: RUNNING is 0, EXITED 1, stuck >= 2 (semantics/rules.py).
_STATUS_TEST = {"running": "== 0", "exited": "== 1", "stuck": ">= 2"}


def program_moves(prog: A.Program) -> bool:
    """Whether ``prog`` calls doReach anywhere (Init or an event)."""
    stmts = list(A.walk_stmts(prog.init))
    for ev in prog.events:
        stmts.extend(A.walk_stmts(ev.body))
    return any(isinstance(s, A.CallStmt) and s.name == "doReach" for s in stmts)


def has_rand(node) -> bool:
    """Does evaluating ``node`` draw a ``rand()``?  ``node`` is an expression,
    a statement (its own expressions: an if's conditions, not its branches),
    a tuple of them, or None."""
    if node is None:
        return False
    if isinstance(node, (tuple, list)):
        return any(has_rand(x) for x in node)
    exprs = A.own_exprs(node) if isinstance(node, A.STMT_TYPES) else (node,)
    return any(isinstance(x, A.Call) and x.name == "rand" for e in exprs for x in A.walk(e))


def _may_grow(e: A.Expr) -> bool:
    """Whether an int expression can grow a value without bound when stored
    back repeatedly: a product, or a sum or difference of two non-literals
    (``x = x + 1`` needs 10**4300 steps to overflow, ``x = x + x`` does not)."""
    for x in A.walk_expr(e):
        if isinstance(x, A.Binary) and (x.op == "*" or (
                x.op in ("+", "-") and not isinstance(x.left, A.IntLit)
                and not isinstance(x.right, A.IntLit))):
            return True
    return False


class FunctionValueError(PcclError):
    """A world function's value that does not fit the type the program reads
    it as; the engine moves it to the world file's line when there is one."""
    function: str = ""
    detail: str = ""


class Compiler:
    """Generates Python source for expressions and statements of one program."""

    def __init__(self, program: A.Program, layout: Layout, n_agents: int,
                 functions: dict, oracle: Oracle, info=None):
        self.program = program
        self.info = info                    # the CheckedProgram: static types
        self.lay = layout
        self.N = n_agents
        self.functions = functions          # uninterpreted name -> raw value
        self.oracle = oracle
        self.G: dict[str, Any] = {
            "_d": V.d, "_ix": V.ix, "_av": V.agent_var, "_ag": V.agent,
            "_div": V.div, "_mod": V.mod, "_pos": V.pos,
            "_dist": V.dist, "_head": V.head, "_cl": V.chk_list, "_set_in": V.set_in,
            "_R": oracle.rand, "_E": V.PcclRuntimeError, "UNDEF": V.UNDEF,
            "_fin": V.fin, "_canon": canon, "_ib": V.ib,
        }
        self._nconst = 0
        self._qval: dict = {}               # quantified variable -> agent index (unrolled)

    # -- helpers -----------------------------------------------------------
    def error(self, msg: str, node) -> NoReturn:
        raise PcclError(msg, filename=self.program.filename,
                        source=self.program.source, span=getattr(node, "span", None))

    def impossible(self, msg, node) -> NoReturn:
        """A case the checker has ruled out (an AssertionError if it ever fires)."""
        raise AssertionError(f"the checker should have rejected this: {msg}")

    def const(self, value) -> str:
        name = f"_k{self._nconst}"
        self._nconst += 1
        self.G[name] = value
        return name

    def make(self, params: str, body: str, name: str = "_f"):
        src = f"def {name}({params}):\n" + body
        ns: dict = {}
        try:
            code = compile(src, f"<pccl:{name}>", "exec")
        except (SyntaxError, RecursionError, MemoryError):
            # Python's own limits (nested parentheses, recursion) on deep expressions
            raise PcclError("an expression is nested too deeply to compile (Python allows "
                            "about 200 levels)", filename=self.program.filename) from None
        exec(code, self.G, ns)
        return ns[name]

    def make_expr(self, e: A.Expr, *, prop: bool = False, bound=()):
        src = self.expr(e, prop=prop, bound=bound)
        if prop:
            return self.make("st", f"    sh = st[{SH}]; ags = st[{AGS}]\n    return {src}\n")
        return self.make("i, ag, sh, ags", f"    return {src}\n")

    def uninterpreted_value(self, name, node, ty: Optional[Ty] = None):
        raw = self.functions.get(name, ())
        if callable(raw):
            raw = raw()
        if ty is None:
            return raw
        try:
            return coerce(raw, ty)
        except ValueError as exc:
            hint = ""
            if raw == ():
                hint = (f" ({name}() is the empty list unless the world gives it a value: "
                        f"needs {{world=FILE}} with {name} under [functions])")
            err = FunctionValueError(f"value of {name}() does not fit {ty}: {exc}{hint}",
                                     filename=self.program.filename, source=self.program.source,
                                     span=getattr(node, "span", None), template=bool(hint))
            err.function, err.detail = name, f"does not fit {ty}: {exc}"
            raise err from None

    # -- expressions ---------------------------------------------------------
    def expr(self, e: A.Expr, *, prop: bool = False, bound=(), want: Optional[Ty] = None) -> str:
        ex = lambda x: self.expr(x, prop=prop, bound=bound)  # noqa: E731
        if isinstance(e, A.BoolLit):
            return "True" if e.value else "False"
        if isinstance(e, A.IntLit):
            return repr(e.value)
        if isinstance(e, A.FloatLit):
            if not math.isfinite(e.value):
                self.impossible(f"float literal out of range: {e.value}", e)
            return repr(float(e.value))
        if isinstance(e, A.ListLit):
            if not e.items:
                return "()"
            return "(" + ", ".join(ex(x) for x in e.items) + ",)"
        if isinstance(e, A.Name):
            return self.name(e, prop, bound)
        if isinstance(e, A.Field):
            return self.field(e, ex)
        if isinstance(e, A.Index):
            return self.index(e, prop, bound)
        if isinstance(e, A.Unary):
            if e.op == "!":
                return f"(not {ex(e.operand)})"
            return f"(-{ex(e.operand)})"
        if isinstance(e, A.Binary):
            return self.chain(e, ex)
        if isinstance(e, A.Quant):
            return self.quant(e, prop, bound)
        if isinstance(e, A.Call):
            return self.call(e, prop, bound, want)
        self.error("unsupported expression", e)  # pragma: no cover

    def field(self, e: A.Field, ex) -> str:
        """``p.x``: a component of a position, by index."""
        k = {"x": 0, "y": 1, "z": 2}.get(e.name)
        if k is None:
            self.impossible(f"unknown field '{e.name}'", e)
        return f"{ex(e.base)}[{k}]"

    def quant(self, e: A.Quant, prop: bool, bound) -> str:
        """``forall``/``exists`` over the agents.  The number of agents is
        fixed, so the quantifier is unrolled into an ``and``/``or`` chain
        with the agent index as a literal (no generator per evaluation), in
        the same order and with the same short-circuit as ``all``/``any``;
        large expansions keep the generator."""
        fn = "all" if e.kind == "forall" else "any"
        bound = bound + (e.var,)
        saved = self._qval.pop(e.var, None)
        try:
            if self.N <= 16:
                terms = []
                for q in range(self.N):
                    self._qval[e.var] = repr(q)
                    terms.append(self.expr(e.body, prop=prop, bound=bound))
                del self._qval[e.var]
                if sum(map(len, terms)) <= 20_000:
                    op = " and " if fn == "all" else " or "
                    return f"(True if ({op.join(terms)}) else False)"
            body = self.expr(e.body, prop=prop, bound=bound)
            return f"{fn}({body} for {self.bvar(e.var)} in range({self.N}))"
        finally:
            self._qval.pop(e.var, None)
            if saved is not None:
                self._qval[e.var] = saved

    #: Left-associative chains longer than this are compiled flat.
    CHAIN_FLAT = 8

    def chain(self, e: A.Binary, ex) -> str:
        """A Binary node and the chain of Binary nodes on its left spine
        (``a + b - c …``), without recursion along the spine.  A short chain
        is the nested expression ``((a + b) - c)``; a long one, which Python
        could not compile (200 nested parentheses, and its compiler's
        recursion limit on a 3,000-deep tree), is a tuple of steps through a
        local, evaluated left to right with the same short-circuits:
        ``(_c := a, _c := (_c + b), _c := (_c - c), …)[-1]``."""
        spine = [e]
        x = e.left
        while isinstance(x, A.Binary):
            spine.append(x)
            x = x.left
        acc = ex(x)
        if len(spine) <= self.CHAIN_FLAT:
            for node in reversed(spine):
                acc = self._binop(node.op, acc, ex(node.right))
            return acc
        var = f"_c{self._nconst}"
        self._nconst += 1
        steps = [f"{var} := {acc}"]
        steps.extend(f"{var} := {self._binop(node.op, var, ex(node.right))}"
                     for node in reversed(spine))
        return "(" + ", ".join(f"({s})" for s in steps) + ")[-1]"

    @staticmethod
    def _binop(op, a, b) -> str:
        if op == "&&":
            return f"({a} and {b})"
        if op == "||":
            return f"({a} or {b})"
        if op == "->":
            return f"((not {a}) or {b})"
        if op == "/":
            return f"_div({a}, {b})"
        if op == "%":
            return f"_mod({a}, {b})"
        return f"({a} {op} {b})"

    @staticmethod
    def bvar(name: str) -> str:
        return f"_q_{name}"

    def name(self, e: A.Name, prop: bool, bound) -> str:
        n = e.name
        if prop:
            if n in bound:
                return self._qval.get(n) or self.bvar(n)
            if n == "time":
                return f"st[{TIME}]"
            if n == "N":
                return repr(self.N)
        vs = self.lay.vars.get(n)
        if vs is not None:
            if vs.section == "allwrite":
                ref = f"sh[{vs.slot}]"
            elif prop:
                self.impossible(f"'{n}' is per-agent: write {n}[i]", e)
            elif vs.section == "allread":
                ref = f"ag[{AR}][{vs.slot}]"
            else:
                ref = f"ag[{LOC}][{vs.slot}]"
            if vs.may_undef and vs.ty.kind != "array":
                return f"_d({ref}, {n!r})"
            return ref
        if n in self.lay.members:
            return repr(self.lay.members[n][1])
        if not prop and n == "doReach_done":
            return f"ag[{REACH}][{DONE}]"
        if not prop and n == "doReach_fail":
            return f"ag[{REACH}][{FAIL}]"
        self.impossible(f"undeclared variable '{n}'", e)

    def index(self, e: A.Index, prop: bool, bound) -> str:
        """Index chains.  Whether the first index picks an agent is
        :func:`pccl.lang.types.indexes_agent`'s rule; in properties ``pos[i]``,
        ``doReach_done[i]`` and the status tests take the agent index too."""
        ex = lambda x: self.expr(x, prop=prop, bound=bound)  # noqa: E731
        root, chain = A.index_chain(e)
        idx = [ix.index for ix in chain]
        if isinstance(root, A.Name) and root.name not in bound:
            n = root.name
            vs = self.lay.vars.get(n)
            if prop and vs is None and n in _STATUS_TEST:
                return f"(_ag(ags, {ex(idx[0])}, {n + '[…]'!r})[3] {_STATUS_TEST[n]})"
            if prop and vs is None and n in ("pos", "doReach_done", "doReach_fail"):
                j = ex(idx[0])
                cell = {"pos": f"[{POS}]", "doReach_done": f"[{REACH}][{DONE}]",
                        "doReach_fail": f"[{REACH}][{FAIL}]"}[n]
                ref = f"_ag(ags, {j}, {n + '[…]'!r}){cell}"
                return self._index_rest(ref, idx[1:], ex)
            if vs is not None and indexes_agent(vs.section, vs.ty.kind == "array", len(idx),
                                                in_property=prop):
                part = AR if vs.section == "allread" else LOC
                ref = f"_av(ags, {ex(idx[0])}, {part}, {vs.slot}, {n!r})"
                return self._index_rest(ref, idx[1:], ex)
        return f"_ix({ex(e.base)}, {ex(e.index)})"

    @staticmethod
    def _index_rest(ref, rest, ex) -> str:
        for k in rest:
            ref = f"_ix({ref}, {ex(k)})"
        return ref

    def _count(self, cell: str) -> str:
        """``count(v)``: how many agents have ``ags[j]<cell> is True``.  The
        number of agents is fixed, so the sum is unrolled (no generator per
        evaluation); ``0 +`` keeps the result an int for a single agent."""
        if self.N > 64:
            return f"sum(1 for _a in ags if _a{cell} is True)"
        terms = " + ".join(f"(ags[{j}]{cell} is True)" for j in range(self.N))
        return f"({terms})" if self.N > 1 else f"(0 + {terms})"

    def count_call(self, e: A.Call) -> str:
        """``count(v)`` in a property: how many agents have ``v`` true."""
        a = e.args[0]
        if isinstance(a, A.Name) and a.name in ("doReach_done", "doReach_fail") \
                and a.name not in self.lay.vars:
            k = DONE if a.name == "doReach_done" else FAIL
            return self._count(f"[{REACH}][{k}]")
        vs = self.lay.vars.get(a.name) if isinstance(a, A.Name) else None
        if vs is None and isinstance(a, A.Name) and a.name in _STATUS_TEST:
            test = _STATUS_TEST[a.name]
            if self.N > 64:
                return f"sum(1 for _a in ags if _a[3] {test})"
            terms = " + ".join(f"(ags[{j}][3] {test})" for j in range(self.N))
            return f"(0 + {terms})"
        if vs is None or vs.section == "allwrite":
            self.impossible("count(v) needs a per-agent boolean variable", e)
        slot = LOC if vs.section == "loc" else AR
        return self._count(f"[{slot}][{vs.slot}]")

    def call(self, e: A.Call, prop: bool, bound, want) -> str:
        ex = lambda x: self.expr(x, prop=prop, bound=bound)  # noqa: E731
        n, args = e.name, e.args
        if prop and n == "count":
            return self.count_call(e)
        if n == "getAgentIndex":
            return "i"
        if n == "getNumAgents":
            return repr(self.N)
        if n == "rand":
            return f"_R({ex(args[0])}, {self.const(e.span)})"
        if n == "getPosition":
            return f"ag[{POS}]"
        if n == "ItemPosition":
            return "_pos(" + ", ".join(ex(a) for a in args) + ")"
        if n == "dist":
            return f"_dist({ex(args[0])}, {ex(args[1])})"
        if n == "head":
            return f"_head({ex(args[0])})"
        if n == "isEmpty":
            return f"(len(_cl({ex(args[0])})) == 0)"
        if n == "size":
            return f"len(_cl({ex(args[0])}))"
        if n == "contains":
            return f"({ex(args[1])} in _cl({ex(args[0])}))"
        assert n not in STATEMENTS, f"the checker lets no statement {n!r} be a value"
        assert n in self.functions or n in UNINTERPRETED, f"the checker knows no function {n!r}"
        return self.const(self.uninterpreted_value(n, e, want))

    # -- canonical values: every write path goes through value() ---------------
    def value(self, e: A.Expr, want: Ty) -> str:
        """Source for ``e`` as the canonical value of a ``want`` slot (one
        representation per PCCL value; docs/decisions.md, "Canonical values").
        Conversions are inserted only where the static type needs them: an
        int expression stored in an int slot costs nothing."""
        k = want.kind
        if k == "any":
            return self.expr(e)
        if isinstance(e, A.Call) and (e.name not in BUILTINS
                                      or BUILTINS[e.name].kind == "uninterpreted"):
            return self.expr(e, want=want)          # uninterpreted: coerced at load time
        if isinstance(e, A.ListLit) and k == "list":
            if not e.items:
                return "()"
            return "(" + ", ".join(self.value(x, want.item) for x in e.items) + ",)"
        src = self.expr(e, want=want)
        st = self.static_type(e)
        if st is None:                              # no checker info: convert blindly
            if k == "float":
                return f"_fin(float({src}))"
            return src if k not in ("list", "pos") else f"_canon({src}, {self.const(want)})"
        if st.kind == "any":
            return f"_canon({src}, {self.const(want)})"
        if k == "float":
            if st.kind == "int":
                return f"float({src})"
            # a float read from the state is canonical; a computed one may be
            # inf, nan or -0.0
            if not isinstance(e, (A.Name, A.Index, A.Field, A.FloatLit)) and not (
                    isinstance(e, A.Call) and e.name == "head"):
                return f"_fin({src})"
            return src
        if k == "list" and widens(st, want):
            return f"_canon({src}, {self.const(want)})"
        if k == "int" and st.kind == "int" and _may_grow(e):
            return f"_ib({src})"
        return src

    def static_type(self, e: A.Expr):
        """The checker's type of a program expression (None without ``info``)."""
        if self.info is None:
            return None
        return self.info.expr_type(e)

    # -- assignment targets -----------------------------------------------------
    def target(self, t: A.Expr):
        """Return (VarSlot, [index source, ...]) for an assignment target."""
        t, chain = A.index_chain(t)
        path = [self.expr(ix.index) for ix in chain]
        assert isinstance(t, A.Name), "the checker allows only variables as targets"
        vs = self.lay.vars.get(t.name)
        assert vs is not None, f"the checker knows no variable {t.name!r} (or it is read-only)"
        assert not (vs.section == "allread" and path and vs.ty.kind != "array"), \
            "the checker forbids writing another agent's allread component"
        return vs, path

    def elem_type(self, vs: VarSlot, depth: int) -> Ty:
        ty = vs.ty
        for _ in range(depth):
            ty = ty.elem if ty.elem is not None else ANY
        return ty

    def write_code(self, vs: VarSlot, path: list, value_src: str, indent="    ") -> str:
        """Code that writes ``value_src`` into the target and builds ``ag2``/``sh2``."""
        lines = [f"v = {value_src}"]
        j = vs.slot
        if vs.section == "allwrite":
            cont = "sh"
        elif vs.section == "allread":
            cont = f"ag[{AR}]"
        else:
            cont = f"ag[{LOC}]"
        if path:
            lines.append(f"v = _set_in({cont}[{j}], ({', '.join(path)},), v)")
        new = f"{cont}[:{j}] + (v,) + {cont}[{j + 1}:]"
        if vs.section == "allwrite":
            lines.append(f"sh2 = {new}")
            lines.append("ag2 = ag")
        elif vs.section == "allread":
            lines.append(f"sh2 = sh; ag2 = {_rebuild('ag', AR, new)}")
        else:
            lines.append(f"sh2 = sh; ag2 = {_rebuild('ag', LOC, new)}")
        return "".join(indent + ln + "\n" for ln in lines)

    def read_target(self, vs: VarSlot, path: list) -> str:
        if vs.section == "allwrite":
            ref = f"sh[{vs.slot}]"
        elif vs.section == "allread":
            ref = f"ag[{AR}][{vs.slot}]"
        else:
            ref = f"ag[{LOC}][{vs.slot}]"
        for p in path:
            ref = f"_ix({ref}, {p})"
        return ref

    # -- statements ------------------------------------------------------------------
    def effect(self, s: A.Stmt):
        """A function ``f(i, ag, sh, ags) -> (ag2, sh2)`` for a simple statement
        (assignment, add, remove, skip), ``ag2`` without the pc update."""
        if isinstance(s, A.Assign):
            vs, path = self.target(s.target)
            val = self.value(s.value, self.elem_type(vs, len(path)))
            body = self.write_code(vs, path, val)
            return self.make("i, ag, sh, ags", body + "    return ag2, sh2\n", f"_s{s.sid}")
        if isinstance(s, A.CallStmt) and s.name in ("add", "remove"):
            vs, path = self.target(s.args[0])
            fn = "list_add" if s.name == "add" else "list_remove"
            self.G["_" + fn] = getattr(V, fn)
            elem = self.elem_type(vs, len(path) + 1)
            x = (self.value(s.args[1], elem) if s.name == "add"
                 else self.expr(s.args[1], want=elem))
            val = f"_{fn}({self.read_target(vs, path)}, {x})"
            body = self.write_code(vs, path, val)
            return self.make("i, ag, sh, ags", body + "    return ag2, sh2\n", f"_s{s.sid}")
        if isinstance(s, A.Skip):
            return self.make("i, ag, sh, ags", "    return ag, sh\n", f"_s{s.sid}")
        self.error("not a simple statement", s)  # pragma: no cover

    def if_chooser(self, s: A.If):
        """``f(i, ag, sh, ags) -> branch index`` (len(branches) = else)."""
        body = ""
        for k, (c, _) in enumerate(s.branches):
            body += f"    if {self.expr(c)}:\n        return {k}\n"
        body += f"    return {len(s.branches)}\n"
        return self.make("i, ag, sh, ags", body, f"_if{s.sid}")
