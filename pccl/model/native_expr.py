"""The C of a model's expressions over the native state vector
(:mod:`pccl.model.native`): the vector's layout, an agent's expressions, the
properties' expressions (in C, or as property memo sites: what C cannot
compute, Python evaluates once per values of the slots it reads) and the
temporal properties' per-state columns.  :class:`ExprC` is the base of
:class:`pccl.model.native_gen.Generator`, which writes the module around
them."""

from __future__ import annotations

import sys

from pccl.lang import ast as A
from pccl.lang.types import indexes_agent
from pccl.model.compile import _STATUS_TEST

#: The native state vector's own layout (not a configuration): the clock and
#: the phase first, then the lock queue, shared, and the agents (see
#: :meth:`pccl.model.native.NativeModel.vector`).
V_TIME, V_PHASE = 0, 1
#: the slots of a moving agent's block after its variables: position,
#: target, obstacles, t0 (interned ids), doReach_done, doReach_fail
MOVE_SLOTS = 7
#: CPython's small-object allocator serves at most this many bytes; a bytes
#: object takes its length plus this header
_SMALL_OBJECT, _BYTES_HEADER = 512, sys.getsizeof(b"")
SCALAR = ("int", "bool", "enum")
_CMP = ("<", "<=", ">", ">=", "==", "!=")


class Unsupported(Exception):
    """What the native engine does not serve (the message says what): the
    Python engine runs."""


class ExprC:
    """The layout of one model's native vector and the C of its expressions."""
    def __init__(self, model):
        self.m = model
        c = model.compiled
        self.c = c
        self.lay = c.layout
        self.N = model.N
        self.labels: list = []
        self.label_ids: dict = {}
        #: whether the program moves (doReach, or a blackbox that moves the
        #: initial state): then positions, reach cells and env are slots of
        #: the vector, holding interned ids (:class:`NativeModel` owns the table)
        from pccl.model.reduce import positions_read, unreduced
        self.moves = any(isinstance(s, A.CallStmt) and s.name == "doReach"
                         for s in c.stmts.values()) or (
            not model.collisions and positions_read(unreduced(model)) is not None)
        #: the memo sites: (kind, agent, pc, read slots, written slots), kind
        #: "stmt" (a statement's rule run by Python on a miss) or "env"
        #: (DOREACH INVOKE, the blackbox's outcomes)
        self.sites: list = []
        #: the C arrays of the property memo sites' read slots (:meth:`pmemo`)
        self.pdecls: list = []


    # -- layout ------------------------------------------------------------------
    @property
    def L(self) -> int:
        return len(self.lay.local)

    @property
    def R(self) -> int:
        return len(self.lay.allread)

    @property
    def A(self) -> int:
        return 4 + self.L + self.R + (MOVE_SLOTS if self.moves else 0)

    @property
    def MV(self) -> int:
        """The offset in an agent's block of its position id (then target,
        obstacles, t0, done, fail, leg start): only when the program moves."""
        return 4 + self.L + self.R

    @property
    def ENVS(self) -> int:
        """The slot of the blackbox's env id (only when the program moves)."""
        return self.SH0 + len(self.lay.shared)

    @property
    def LQ0(self) -> int:
        return 2

    @property
    def SH0(self) -> int:
        return 2 + self.N

    @property
    def AG0(self) -> int:
        return self.SH0 + len(self.lay.shared) + (1 if self.moves else 0)

    @property
    def NS(self) -> int:
        return self.AG0 + self.N * self.A

    @property
    def packs(self) -> bool:
        """Whether states are held packed where they fit (:meth:`NativeModel.pack`):
        when their int64 bytes pass CPython's small-object limit, so that
        the int32 form moves them from malloc to its faster allocator.
        Below it packing costs more than it saves (measured on Fischer, 53
        slots: 8-14 % more CPU); docs/benchmarks.md."""
        return 8 * self.NS + _BYTES_HEADER > _SMALL_OBJECT

    def ag(self, j, field: int) -> str:
        return f"s[{self.AG0 + j * self.A + field}]"

    def ag_cell(self, j, field: int) -> str:
        """:meth:`ag` for an agent given as an int or a C expression."""
        if isinstance(j, int):
            return self.ag(j, field)
        return f"s[{self.AG0 + field} + {self.A} * ({j})]"


    # -- expressions ----------------------------------------------------------------
    def var_ref(self, vs, j) -> str:
        """The slot of variable ``vs`` (of agent ``j``: an int or a C expression)."""
        if vs.section == "allwrite":
            return f"s[{self.SH0 + vs.slot}]"
        off = 4 + vs.slot if vs.section == "loc" else 4 + self.L + vs.slot
        if isinstance(j, int):
            return self.ag(j, off)
        return f"s[{self.AG0 + off} + {self.A} * ({j})]"

    def read(self, ref: str, vs) -> str:
        if vs.ty.kind not in SCALAR:
            raise Unsupported(f"the {vs.ty} variable '{vs.name}': its values live in Python's "
                              f"table of positions and lists, which the C engine does not read")
        if vs.may_undef:
            return f"U({ref})"
        return ref

    def binop(self, op, a, b) -> str:
        if op == "&&":
            return f"({a} && {b})"
        if op == "||":
            return f"({a} || {b})"
        if op == "->":
            return f"(!{a} || {b})"
        if op == "+":
            return f"ADD({a}, {b})"
        if op == "-":
            return f"SUB({a}, {b})"
        if op == "*":
            return f"MUL({a}, {b})"
        if op == "/":
            return f"DIV({a}, {b})"
        if op == "%":
            return f"MOD({a}, {b})"
        if op in ("<", "<=", ">", ">=", "==", "!="):
            return f"((V)({a} {op} {b}))"
        raise Unsupported(f"the operator '{op}'")

    def expr(self, e, i) -> str:
        """C for an agent expression of agent ``i``."""
        if isinstance(e, A.BoolLit):
            return "1" if e.value else "0"
        if isinstance(e, A.IntLit):
            if not -(1 << 62) < e.value < (1 << 62):
                raise Unsupported("an int literal beyond 62 bits")
            return f"((V){e.value}LL)"
        if isinstance(e, A.Name):
            vs = self.lay.vars.get(e.name)
            if vs is not None:
                return self.read(self.var_ref(vs, i), vs)
            if e.name in self.lay.members:
                return str(self.lay.members[e.name][1])
            if self.moves and e.name in ("doReach_done", "doReach_fail"):
                return self.ag(i, self.MV + (4 if e.name == "doReach_done" else 5))
            raise Unsupported(f"the name '{e.name}'")
        if isinstance(e, A.Unary):
            x = self.expr(e.operand, i)
            return f"((V)!{x})" if e.op == "!" else f"NEG({x})"
        if isinstance(e, A.Binary):
            return self.binop(e.op, self.expr(e.left, i), self.expr(e.right, i))
        if isinstance(e, A.Index) and isinstance(e.base, A.Name):
            vs = self.lay.vars.get(e.base.name)
            if vs is not None and indexes_agent(vs.section, False, 1, in_property=False):
                return self.read(self.var_ref(vs, f"AIX({self.expr(e.index, i)})"), vs)
        if isinstance(e, A.Call) and not e.args and e.name == "getAgentIndex":
            return f"((V){i})"
        if isinstance(e, A.Call) and not e.args and e.name == "getNumAgents":
            return f"((V){self.N})"
        what = f"{e.name}()" if isinstance(e, A.Call) else type(e).__name__.lower()
        span = getattr(e, "span", None)
        raise Unsupported(f"the expression {what}" + (f" at line {span.line}:{span.column}"
                                                     if span is not None else ""))

    def pexpr(self, e, bound: dict, boolean: bool = True) -> str:
        """C for a property expression (``bound``: quantified name -> agent).
        ``boolean``: ``e``'s value is a truth value (an operand of ``&& || ->
        !``, a quantifier's body, the property): where C cannot compute such
        an expression, or a comparison (over positions, floats, lists,
        ``dist()``, ...), it is a *property memo site* (:meth:`pmemo`):
        Python evaluates it once per values of the slots it reads."""
        try:
            return self.pexpr_c(e, bound)
        except Unsupported:
            if not (boolean or (isinstance(e, A.Binary) and e.op in _CMP)):
                raise
            return self.pmemo(e, bound)

    def pmemo(self, e, bound: dict) -> str:
        """C of property expression ``e`` (bound names substituted by their
        agents) as a memo site of kind "prop": its value (bool or int) looked
        up by the values of the slots it reads (:meth:`preads`), computed by
        the Python model's own predicate on a miss (:meth:`NativeModel._miss`);
        a value C does not hold (an error, a float) marks the state a suspect
        (``okstate`` fails: the Python model's violations decide it)."""
        from pccl.model.properties import subst
        if any(isinstance(x, A.Call) and x.name == "rand" for x in A.walk_expr(e)):
            raise Unsupported("rand() in a property")
        t = subst(e, bound) if bound else e
        try:
            rs: set = set()
            self.preads(t, rs)
            reads = sorted(rs)
        except Unsupported:         # what it reads is not known: every slot
            reads = list(range(self.NS))
        k = len(self.sites)
        self.sites.append(("prop", None, t, tuple(reads), ()))
        self.pdecls.append(f"static const int PR{k}[] = {{{', '.join(map(str, reads)) or '0'}}};")
        return f"memo_value(s, {k}, PR{k}, {len(reads)})"

    def collision_site(self) -> str:
        """C of the collision check (``--collisions``): a memo site of kind
        "coll" over every agent's position slot (none when positions are not
        in the vector: one lookup), 1 when no robots touch each other or an
        obstacle (the Python model's own check on a miss), else 0: the
        state is a suspect and the Python model's violations name them."""
        reads = [self.AG0 + j * self.A + self.MV for j in range(self.N)] if self.moves else []
        k = len(self.sites)
        self.sites.append(("coll", None, None, tuple(reads), ()))
        self.pdecls.append(f"static const int PR{k}[] = {{{', '.join(map(str, reads)) or '0'}}};")
        return f"memo_value(s, {k}, PR{k}, {len(reads)})"

    def preads(self, e, out: set) -> None:
        """The slots property expression ``e`` (bound names substituted)
        reads, into ``out``; Unsupported when it is not known."""
        if isinstance(e, (A.IntLit, A.FloatLit, A.BoolLit)):
            return
        if isinstance(e, A.Name):
            vs = self.lay.vars.get(e.name)
            if e.name == "time":
                out.add(V_TIME)
            elif vs is not None and vs.section == "allwrite":
                out.add(self.SH0 + vs.slot)
            elif vs is not None:
                raise Unsupported("an unindexed per-agent variable")
            return              # N, an enum member, a quantified name
        if isinstance(e, (A.Unary, A.Field)):
            return self.preads(e.operand if isinstance(e, A.Unary) else e.base, out)
        if isinstance(e, A.Binary):
            self.preads(e.left, out)
            return self.preads(e.right, out)
        if isinstance(e, A.Quant):
            return self.preads(e.body, out)
        if isinstance(e, (A.ListLit, A.Call)) and not (isinstance(e, A.Call) and e.name == "count"):
            if isinstance(e, A.Call) and e.name in ("getAgentIndex", "getPosition", "getNumAgents", "rand"):
                raise Unsupported(f"{e.name}() in a property")
            for x in (e.items if isinstance(e, A.ListLit) else e.args):
                self.preads(x, out)     # (the built-ins and the world's functions: pure)
            return
        if isinstance(e, A.Index):
            return self.pindex_reads(e, out)
        if isinstance(e, A.Call) and len(e.args) == 1 and isinstance(e.args[0], A.Name):   # count(v)
            return self.preads(A.Index(e.args[0], A.Name("_any_agent")), out)
        raise Unsupported(f"a {type(e).__name__} in a property")

    def pindex_reads(self, e, out: set) -> None:
        """Step of :meth:`preads`: an index chain ``v[j]...``: agent ``j``'s
        slot of a per-agent variable (every agent's when ``j`` is not a
        literal), its status, position or reach flags."""
        N = self.N
        root, chain = A.index_chain(e)
        for ix in chain:
            self.preads(ix.index, out)
        i0 = chain[0].index
        agents = ([i0.value] if isinstance(i0, A.IntLit) and 0 <= i0.value < N
                  else range(N))
        if not isinstance(root, A.Name):
            return self.preads(root, out)
        n = root.name
        vs = self.lay.vars.get(n)
        if vs is not None and vs.section == "allwrite":
            out.add(self.SH0 + vs.slot)
            return
        if vs is not None and indexes_agent(vs.section, vs.ty.kind == "array", len(chain),
                                            in_property=True):
            off = 4 + vs.slot if vs.section == "loc" else 4 + self.L + vs.slot
            out.update(self.AG0 + j * self.A + off for j in agents)
            return
        if vs is None and n in ("running", "exited", "stuck"):
            out.update(self.AG0 + j * self.A + 3 for j in agents)
            return
        if vs is None and n in ("pos", "doReach_done", "doReach_fail"):
            if self.moves:      # (else constant: not in the vector)
                q = {"pos": 0, "doReach_done": 4, "doReach_fail": 5}[n]
                out.update(self.AG0 + j * self.A + self.MV + q for j in agents)
            return
        raise Unsupported(f"an index of '{n}'")

    def pexpr_c(self, e, bound: dict) -> str:
        """Step of :meth:`pexpr`: ``e`` computed in C, or Unsupported."""
        if isinstance(e, (A.BoolLit, A.IntLit)):
            return self.expr(e, 0)
        if isinstance(e, A.Name):
            return self.pname(e, bound)
        if isinstance(e, A.Unary):
            x = self.pexpr(e.operand, bound, e.op == "!")
            return f"((V)!{x})" if e.op == "!" else f"NEG({x})"
        if isinstance(e, A.Binary):
            logic = e.op in ("&&", "||", "->")
            return self.binop(e.op, self.pexpr(e.left, bound, logic), self.pexpr(e.right, bound, logic))
        if isinstance(e, A.Quant):
            terms = [self.pexpr(e.body, {**bound, e.var: q}) for q in range(self.N)]
            op = " && " if e.kind == "forall" else " || "
            return "((V)(" + op.join(f"({t})" for t in terms) + "))"
        if isinstance(e, A.Call) and e.name == "count" and len(e.args) == 1 \
                and isinstance(e.args[0], A.Name):
            return self.pcount(e.args[0])
        if isinstance(e, A.Index) and isinstance(e.base, A.Name) and e.base.name in _STATUS_TEST \
                and e.base.name not in self.lay.vars:
            # exited[i], stuck[i], running[i]: a test of agent i's status cell
            j = (bound[e.index.name] if isinstance(e.index, A.Name) and e.index.name in bound
                 else f"AIX({self.pexpr(e.index, bound)})")
            return f"((V)({self.ag_cell(j, 3)} {_STATUS_TEST[e.base.name]}))"
        if isinstance(e, A.Index) and isinstance(e.base, A.Name):
            vs = self.lay.vars.get(e.base.name)
            if vs is not None and indexes_agent(vs.section, False, 1, in_property=True):
                if isinstance(e.index, A.Name) and e.index.name in bound:
                    return self.read(self.var_ref(vs, bound[e.index.name]), vs)
                return self.read(self.var_ref(vs, f"AIX({self.pexpr(e.index, bound)})"), vs)
        what = f"{e.name}()" if isinstance(e, A.Call) else type(e).__name__.lower()
        raise Unsupported(f"the property expression {what} is beyond the native subset")

    def pname(self, e, bound: dict) -> str:
        """Step of :meth:`pexpr`: C for a name in a property."""
        if e.name in bound:
            return f"((V){bound[e.name]})"
        if e.name == "N":
            return f"((V){self.N})"
        if e.name == "time":
            return f"s[{V_TIME}]"
        vs = self.lay.vars.get(e.name)
        if vs is not None and vs.section == "allwrite":
            return self.read(self.var_ref(vs, 0), vs)
        if e.name in self.lay.members and vs is None:
            return str(self.lay.members[e.name][1])
        raise Unsupported(f"the name '{e.name}' in a property")

    def pcount(self, arg) -> str:
        """Step of :meth:`pexpr`: C for ``count(arg)`` of a per-agent bool."""
        vs = self.lay.vars.get(arg.name)
        if vs is None and arg.name in _STATUS_TEST:       # count(exited), ...
            return "((V)(" + " + ".join(f"({self.ag(j, 3)} {_STATUS_TEST[arg.name]})"
                                        for j in range(self.N)) + "))"
        if vs is None or vs.section == "allwrite" or vs.ty.kind != "bool":
            raise Unsupported("count() of something other than a per-agent bool")
        # Python counts values that are True: undefined counts as not True
        return "((V)(" + " + ".join(f"({self.var_ref(vs, j)} == 1)"
                                    for j in range(self.N)) + "))"


    def temporal_exprs(self, tp) -> list:
        """C of a temporal property's state predicates, P then Q (when it has
        one): :meth:`pexpr` over the instance's ``Temporal`` node."""
        t = tp.expr
        out = [self.pexpr(t.p, {})]
        if getattr(t, "q", None) is not None:
            out.append(self.pexpr(t.q, {}))
        return out

    def temporal_c(self) -> str:
        """C of ``tpred(n, s)``, the temporal properties' state predicates
        in the order of ``TPBIT`` (bit 2k for property k's P and 2k + 1 for
        its Q, as :class:`pccl.search.liveness.StateColumns` sets them), and
        the constants ``tcols`` reads (pccl/model/native_c/temporal.c, which
        also computes the robots whose doReach is under way when the program
        moves and arrival is fair: ``TPEND``)."""
        m = self.m
        preds = []
        for k, tp in enumerate(m.temporal):
            t = tp.expr
            preds += [(t.p, 2 * k)] + ([(t.q, 2 * k + 1)] if getattr(t, "q", None) is not None else [])
        fair = bool(getattr(m, "arrival_is_fair", False)) and any(p.liveness for p in m.temporal)
        out = [f"#define NTP {len(preds)}", f"#define TPEND {int(self.moves and fair)}",
               f"static const int TPBIT[] = {{{', '.join(str(bit) for _, bit in preds) or '0'}}};",
               "static MAYBE_UNUSED V tpred(int n, const V *s) {",
               "  (void)s;", "  switch (n) {"]
        for n, (e, _bit) in enumerate(preds):
            out.append(f"  case {n}: return {self.pexpr(e, {})};")
        out += ["  }", "  return 0;", "}"]
        return "\n".join(out)
