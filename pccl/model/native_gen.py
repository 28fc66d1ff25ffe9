"""The C source of one model's native module (:mod:`pccl.model.native`):
:class:`Generator` writes what depends on the program (its constants, the
agents' rules per pc, the memo sites, the reductions' tables, the
invariants' check) around the fixed C of ``native_c/`` it includes
(docs/architecture.md, "The native engine's C"); the expressions are
:class:`~pccl.model.native_expr.ExprC`'s."""

from __future__ import annotations

from typing import Any, NamedTuple, Optional

from pccl.lang import ast as A
from pccl.model.layout import (AGS, DISCRETE, DONE, DYNAMIC, ENV, EXITED, FAIL, IDLE, LOCK, POS, REACH, REQUEST,
                               RUNNING, STATUS, STUCK, START)
from pccl.semantics.rules import (K_AEND, K_ACQ, K_ASSERT, K_ATOMIC, K_DOREACH, K_EMPTY, K_END, K_EXIT, K_IF,
                                  K_SIMPLE, K_WHILE)
from pccl.model.reduce import MERGE_LIMIT
from pccl.model.native_expr import MOVE_SLOTS, SCALAR, V_PHASE, V_TIME, ExprC, Unsupported

MAX_AGENTS = 64
#: the kinds of control cell whose rule a memo site may run (one statement
#: of one agent, no lock, no counter)
MEMO_KINDS = (K_SIMPLE, K_IF, K_WHILE, K_ASSERT, K_DOREACH)
#: kinds of values held as interned ids (value <-> small int, NativeModel's
#: table); C compares them only for equality, Python computes on them
INTERNED = ("pos", "list", "obstacles", "float", "array")


class _Regs(NamedTuple):
    """Where an agent's control cells are in a native state: its pc, counter,
    lock state and status, and its rate."""
    PC: int
    CNT: int
    LCK: int
    ST: int
    rho: Any



class Generator(ExprC):
    """The C source of one model's native module."""

    # -- support -----------------------------------------------------------------
    def check(self) -> None:
        m = self.m
        if self.N > MAX_AGENTS:
            raise Unsupported(f"more than {MAX_AGENTS} agents")
        if type(m.delta) is not int:
            raise Unsupported("a non-integer δ")
        from pccl.blackboxes import BLACKBOXES
        if not any(m.blackbox is bb for bb in BLACKBOXES.values()):
            raise Unsupported(f"the blackbox '{getattr(m.blackbox, 'name', '?')}' is not built in")
        for vs in self.lay.vars.values():
            if vs.ty.kind not in SCALAR and vs.ty.kind not in INTERNED:
                raise Unsupported(f"variable '{vs.name}' has type {vs.ty} (the native engine "
                                  "holds int, bool and enum scalars, and interns positions, "
                                  "lists and obstacle lists)")
        if m.guards_rand:
            raise Unsupported("rand() in a guard")
        for s in self.c.stmts.values():
            self.stmt_ok(s)
        for ev in self.c.program.events:
            self.expr(ev.guard, 0)
        nsites = len(self.sites)
        for p in m.properties:
            if p.expr is None:
                raise Unsupported(f"invariant '{p.name}' has no expression")
            try:
                self.pexpr(p.expr, {})
            except Unsupported as e:
                raise Unsupported(f"invariant '{p.name}': {e}") from None
        for tp in m.temporal:
            try:
                self.temporal_exprs(tp)
            except Unsupported as e:
                raise Unsupported(f"temporal property '{tp.name}': {e}") from None
        del self.sites[nsites:], self.pdecls[:]      # (source() makes them again)
        self.env_constant()


    def stmt_ok(self, s) -> None:
        if isinstance(s, A.CallStmt) and s.name not in ("exit", "assert", "doReach", "add", "remove"):
            raise Unsupported(f"the statement {s.name}() (line {s.span.line})")

    def env_constant(self) -> None:
        """A program without doReach whose DOREACH INVOKE leaves positions,
        reach cells and env as they are (checked on the initial state, with
        every agent running, exited and stuck) keeps them out of the vector;
        otherwise the program moves (:attr:`moves`)."""
        m = self.m
        if self.moves:
            return
        st = next(iter(m.init_states()), None)
        if st is None:
            return
        for status in (RUNNING, EXITED, STUCK):
            ags = tuple(a[:STATUS] + (status,) + a[STATUS + 1:] for a in st[AGS])
            s2 = st[:AGS] + (ags,) + st[AGS + 1:]
            outs = m.environment_step(s2)
            want = (tuple(a[POS] for a in ags), tuple(a[REACH][DONE] for a in ags),
                    tuple(a[REACH][FAIL] for a in ags), s2[ENV],
                    tuple(a[REACH][START] for a in ags))
            if len(outs) != 1 or tuple(outs[0]) != want:
                self.moves = True
                return

    # -- labels --------------------------------------------------------------------
    def lab(self, label) -> int:
        k = self.label_ids.get(label)
        if k is None:
            k = self.label_ids[label] = len(self.labels)
            self.labels.append(label)
        return k

    # -- rules ---------------------------------------------------------------------
    def emit(self, lines: list, label, sets: list, ind: str) -> None:
        """Append code that copies the state, applies ``sets`` and emits."""
        lines.append(f"{ind}{{ V t[NS]; memcpy(t, s, sizeof t);")
        for x in sets:
            lines.append(f"{ind}  {x};")
        lines.append(f"{ind}  if (EMIT({self.lab(label)}, t)) return -1; }}")

    def agent_code(self, i: int) -> list:
        m, ctl = self.m, self.m.ctl
        A_ = self.AG0 + i * self.A
        r = _Regs(A_, A_ + 1, A_ + 2, A_ + 3, m.rho[i])
        out = [f"static int agent{i}(const V *s) {{",
               # (an error met before, in the ample set's footprints: the
               # search fails, as before; a cell's own error falls back to
               # its Python rule below)
               "  if (ovf) return -1;",
               f"  int spent = s[{r.CNT}] + {r.rho} > {m.n0};",
               f"  switch (s[{r.PC}]) {{"]
        cases = {K_EMPTY: self.case_empty, K_END: self.case_end, K_AEND: self.case_aend,
                 K_ACQ: self.case_acq, K_SIMPLE: self.case_simple, K_IF: self.case_if,
                 K_WHILE: self.case_while, K_ASSERT: self.case_assert,
                 K_ATOMIC: self.case_atomic, K_EXIT: self.case_exit}
        for pc in range(len(ctl.cells)):
            h = ctl.info(pc)
            out.append(f"  case {pc}: {{")
            case = cases.get(h.kind)
            body: list = []
            try:
                if case is None:
                    raise Unsupported("doReach")
                case(body, i, h, r, "    ")
                if h.kind in MEMO_KINDS or h.kind == K_EMPTY:
                    # a runtime error in C (a division by zero, an int beyond
                    # 64 bits, an undefined value, an agent index out of
                    # range): the Python rule's successors in this state (an
                    # agent stuck with its reason), through a memo site
                    fall = None
                    for q, line in enumerate(body):
                        if line.strip() == "if (ovf) return -1;":
                            if fall is None:
                                fall = " ".join(x.strip() for x in self.case_memo(i, pc, h, ""))
                            body[q] = line.replace("return -1;", f"{{ ovf = 0; {fall} break; }}")
            except Unsupported:
                if h.kind not in MEMO_KINDS:
                    raise
                body = self.case_memo(i, pc, h, "    ")
            out += body
            out.append("    break; }")
        out.append("  default: if (!KT) PyErr_SetString(PyExc_ValueError, \"unknown pc\"); return -1;")
        out.append("  }")
        out.append("  return 0;")
        out.append("}")
        return out

    # -- memo sites: what C does not compute, Python does once per read values --------
    def memo_reads(self, s) -> list:
        """The variables statement ``s``'s rule reads beyond the agent's own
        block and shared ((name, every agent) for an agent-indexed read).  A
        ``rand(n)`` is no read: the rule's successors are every outcome
        (explore's enumeration), a function of the values read."""
        out: list = []
        for x in A.own_exprs(s):
            out += self.expr_reads(x)
        return out

    def expr_reads(self, x) -> list:
        """The per-agent variables expression ``x`` indexes (read in every
        agent's block: :meth:`memo_reads`)."""
        out = []
        for e in A.walk_expr(x):
            if isinstance(e, A.Index):
                root, _chain = A.index_chain(e)
                if isinstance(root, A.Name) and root.name in self.lay.vars:
                    vs = self.lay.vars[root.name]
                    if vs.section != "allwrite":
                        out.append(vs)
        return out

    def own_slots(self, i: int) -> list:
        """Agent ``i``'s block without its counter (a statement never reads it)."""
        a0 = self.AG0 + i * self.A
        return [a0 + q for q in range(self.A) if q != 1]

    def case_memo(self, i: int, pc: int, h, ind: str) -> list:
        """C of a statement the generator does not compute: the rule's
        successors looked up in the memo by the values of the slots it reads
        (the agent's block but its counter, shared, the slots of other
        agents it indexes, the clock for a doReach that records t0), run by
        the Python rule on a miss (NativeModel._miss)."""
        if h.kind == K_EMPTY:       # the guards (a runtime error in one: the rule's stuck agent)
            extra = [v for ev in self.c.program.events for v in self.expr_reads(ev.guard)]
        else:
            extra = self.memo_reads(self.c.stmts[h.sid])
        shared = list(range(self.SH0, self.SH0 + len(self.lay.shared)))
        rs = self.own_slots(i) + shared
        for vs in extra:
            off = 4 + vs.slot if vs.section == "loc" else 4 + self.L + vs.slot
            rs += [self.AG0 + j * self.A + off for j in range(self.N)]
        if h.kind == K_DOREACH and self.m.record_t0:
            rs.append(V_TIME)
        rs = sorted(set(rs))
        ws = self.own_slots(i) + shared
        return [f"{ind}{self.site_call('stmt', i, pc, rs, ws)}"]

    def site_call(self, kind: str, i, pc, rs: list, ws: list) -> str:
        k = len(self.sites)
        self.sites.append((kind, i, pc, tuple(rs), tuple(ws)))
        return (f"{{ static const int R_[] = {{{', '.join(map(str, rs)) or '0'}}}; "
                f"static const int W_[] = {{{', '.join(map(str, ws)) or '0'}}}; "
                f"if (memo_site(s, {k}, R_, {len(rs)}, W_, {len(ws)})) return -1; }}")

    def env_site(self) -> list:
        """The memo site of DOREACH INVOKE for a program that moves
        (pccl/model/native_c/step.c): the blackbox's outcomes memoised by
        every agent's status, position and reach cells and the env (the
        clock too if the blackbox reads it); the slots it reads and writes."""
        rs = [self.ENVS] + ([V_TIME] if getattr(self.m.blackbox, "uses_time", False) else [])
        ws = [V_PHASE, self.ENVS]
        for j in range(self.N):
            a0 = self.AG0 + j * self.A
            rs += [a0 + 3] + [a0 + self.MV + q for q in range(MOVE_SLOTS)]
            ws += [a0 + 1, a0 + self.MV, a0 + self.MV + 4, a0 + self.MV + 5, a0 + self.MV + 6]
        k = len(self.sites)
        self.sites.append(("env", None, None, tuple(rs), tuple(ws)))
        return [f"#define ENV_SITE {k}", self.c_array("ENVR", "int", rs), self.c_array("ENVW", "int", ws),
                f"#define NENVR {len(rs)}", f"#define NENVW {len(ws)}"]

    # the cases of agent_code, one per kind of control cell: each appends to
    # ``out`` the C of agent ``i`` at cell ``h`` (``r``: its cells in a state)
    def case_empty(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        m, ctl = self.m, self.m.ctl
        out.append(f"{ind}if (spent) break;")
        evs = self.c.program.events
        for e, ev in enumerate(evs):
            out.append(f"{ind}V g{e} = {self.expr(ev.guard, i)};")
        out.append(f"{ind}if (ovf) return -1;")
        out.append(f"{ind}int any = 0;")
        for e in range(len(evs)):
            out.append(f"{ind}if (g{e}{' && !any' if m.first_only else ''}) {{ any = 1;")
            self.emit(out, ("EVENT SELECT", i, e), [f"t[{r.PC}] = {ctl.event_pcs[e]}"],
                      ind + "  ")
            out.append(f"{ind}}}")
        out.append(f"{ind}if (!any)")
        self.emit(out, ("IDLE", i, None), [f"t[{r.PC}] = {ctl.idle_pc}"], ind + "  ")

    def case_end(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        out.append(f"{ind}if (spent) break;")
        self.emit(out, ("COUNTER ADVANCE", i, None),
                  [f"t[{r.PC}] = {self.m.ctl.empty_pc}", f"t[{r.CNT}] = s[{r.CNT}] + {r.rho}"], ind)

    def case_aend(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        out.append(f"{ind}if (s[{r.LCK}] != {LOCK}) break;")
        self.emit(out, ("LOCK RELEASE", i, None),
                  [f"t[{r.PC}] = {h.next_pc}", f"t[{r.LCK}] = {IDLE}",
                   f"lq_remove(t, {i})"], ind)

    def case_acq(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        head = f"(s[{self.LQ0}] == {i})"
        out.append(f"{ind}if (s[{r.LCK}] == {REQUEST} && {head})")
        self.emit(out, ("ATOMIC EXECUTION", i, h.sid),
                  [f"t[{r.PC}] = {h.body_pc}", f"t[{r.LCK}] = {LOCK}"], ind + "  ")
        out.append(f"{ind}if (!spent && s[{r.LCK}] == {REQUEST} && !{head})")
        self.emit(out, ("ATOMIC WAIT", i, h.sid), [f"t[{r.CNT}] = s[{r.CNT}] + {r.rho}"],
                  ind + "  ")

    def case_simple(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        s = self.c.stmts[h.sid]
        sets = [f"t[{r.PC}] = {h.next_pc}"]
        if isinstance(s, A.Assign):
            if not isinstance(s.target, A.Name):
                raise Unsupported(f"an indexed assignment (line {s.span.line})")
            vs = self.lay.vars[s.target.name]
            if vs.ty.kind not in SCALAR:
                raise Unsupported(f"an assignment to the {vs.ty} variable '{vs.name}' in C")
            out.append(f"{ind}V v = {self.expr(s.value, i)};")
            out.append(f"{ind}if (ovf) return -1;")
            sets.append(f"t[{self.var_ref(vs, i)[2:-1]}] = v")
        elif not isinstance(s, A.Skip):
            raise Unsupported(f"the statement at line {s.span.line}")
        self.emit(out, ("STATEMENT", i, h.sid), sets, ind)

    def case_if(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        s = self.c.stmts[h.sid]
        out.append(f"{ind}V pc2 = {h.branch_pcs[-1]};")
        chain = ""
        for b, (cond, _) in enumerate(s.branches):
            chain += f"{ind}{'else ' if b else ''}if ({self.expr(cond, i)}) pc2 = {h.branch_pcs[b]};\n"
        out.append(chain.rstrip("\n"))
        out.append(f"{ind}if (ovf) return -1;")
        self.emit(out, ("STATEMENT", i, h.sid), [f"t[{r.PC}] = pc2"], ind)

    def case_while(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        s = self.c.stmts[h.sid]
        out.append(f"{ind}V b = {self.expr(s.cond, i)};")
        out.append(f"{ind}if (ovf) return -1;")
        self.emit(out, ("STATEMENT", i, h.sid),
                  [f"t[{r.PC}] = b ? {h.body_pc} : {h.next_pc}"], ind)

    def case_assert(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        s = self.c.stmts[h.sid]
        code = self.m.stuck_code("assert", "assertion failed", h.sid)
        out.append(f"{ind}V b = {self.expr(s.args[0], i)};")
        out.append(f"{ind}if (ovf) return -1;")
        self.emit(out, ("STATEMENT", i, h.sid),
                  [f"if (b) t[{r.PC}] = {h.next_pc}; else t[{r.ST}] = {code}"], ind)

    def case_atomic(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        out.append(f"{ind}if (s[{r.LCK}] == {IDLE})")
        self.emit(out, ("LOCK REQUEST", i, h.sid),
                  [f"t[{r.PC}] = {h.request_pc}", f"t[{r.LCK}] = {REQUEST}",
                   f"lq_append(t, {i})"], ind + "  ")
        out.append(f"{ind}if (s[{r.LCK}] == {LOCK})")
        self.emit(out, ("STATEMENT", i, h.sid), [f"t[{r.PC}] = {h.body_pc}"], ind + "  ")

    def case_exit(self, out: list, i: int, h, r: "_Regs", ind: str) -> None:
        self.emit(out, ("EXIT", i, h.sid),
                  [f"t[{r.PC}] = {self.m.ctl.empty_pc}", f"t[{r.ST}] = {EXITED}"], ind)

    # -- the reductions (docs/reductions.md), natively --------------------------------
    @property
    def sym_fixed(self) -> int:
        """The agents symmetry keeps in place (:attr:`pccl.model.reduce.Plan.fixed`)."""
        return int(getattr(getattr(self.m, "reduction", None), "fixed", 0))

    def reductions(self) -> tuple:
        """(por, merge, symmetry slots or None) of the model's reductions: the
        ample-set and merge tests of :class:`pccl.model.reduce.Por` and
        :class:`~pccl.model.reduce.Merger` asked per pc (so the tables are
        theirs), the id slots of :func:`~pccl.model.reduce.symmetry_problem`."""
        from pccl.model import reduce as RD
        on = getattr(getattr(self.m, "reduction", None), "on", ())
        base = RD.unreduced(self.m)
        npc = len(self.m.ctl.cells)
        por = merge = None
        if "por" in on:
            por = self.por_tables(base, npc)
        if "merge" in on:
            mg = RD.Merger(base)
            merge = [bool(mg.pc_ok(pc)) for pc in range(npc)]
            self.rand_unchained(merge, por)
        sym = None
        if "symmetry" in on:
            why, slots = RD.symmetry_problem(base, pointed=bool(self.sym_fixed))
            if why is not None or slots is None:
                raise Unsupported(f"symmetry: {why}")
            loc_s, ar_s, sh_s, _self_only, motion = slots
            if motion and not self.moves:
                raise Unsupported("symmetry over positions that are not in the native vector")
            sym = ([4 + k for k in loc_s] + [4 + self.L + k for k in ar_s],
                   [self.SH0 + k for k in sh_s])
        return por, merge, sym

    def rand_unchained(self, merge: list, por: Optional[dict]) -> None:
        """Unsupported when a merged chain may run a statement that draws
        ``rand()`` (Merger._chain branches there, one merged transition per
        outcome; C's chain follows one successor): a step at a pc merging
        allows, or one partial-order reduction may move (its class)."""
        from pccl.model.compile import has_rand
        from pccl.model import independence as I
        movable = (I.ACCESS, I.REQUEST_LOCK, I.RELEASE, I.EXECUTE)
        for pc in range(len(merge)):
            h = self.m.ctl.info(pc)
            if h.kind not in MEMO_KINDS or h.sid is None or not has_rand(self.c.stmts[h.sid]):
                continue
            if merge[pc] or (por is not None and (por["cls"][pc] in movable or por["spent"][pc])):
                raise Unsupported(f"rand() in a statement that statement merging runs through "
                                  f"(line {self.c.stmts[h.sid].span.line}: a merged chain "
                                  "branches at each outcome in the Python engine only)")

    def por_tables(self, base, npc: int) -> dict:
        """The tables of :class:`pccl.model.independence.Independence` (the
        analysis :class:`pccl.model.reduce.Por` decides with), per pc: the
        step's class, reads and writes, the rest's reads, writes and whether
        it ends the event, whether the step writes the stall signature's
        data; per event its reads and writes.  One bit per shared/allread
        variable and the lock bit: at most 64."""
        from pccl.model.independence import Independence
        ind = Independence(base)
        top = 1
        for b in ind.bit.values():
            top = max(top, b)
        if top >= 1 << 64:
            raise Unsupported("partial-order reduction over more than 63 shared and allread variables")
        steps = [ind.step(pc) for pc in range(npc)]
        rests = [ind.rest(pc) for pc in range(npc)]
        return {"cls": [x[0] for x in steps], "sr": [x[1] for x in steps], "sw": [x[2] for x in steps],
                "rr": [x[0] for x in rests], "rw": [x[1] for x in rests], "ends": [x[2] for x in rests],
                "writer": [pc in ind.writers for pc in range(npc)],
                "spent": [ind.spent_local(pc) for pc in range(npc)],
                "empty": [self.m.ctl.info(pc).kind == K_EMPTY for pc in range(npc)],
                "evr": [x[0] for x in ind.event_fps], "evw": [x[1] for x in ind.event_fps],
                "er": ind.events[0], "ew": ind.events[1], "gr": ind.guard_reads,
                "local": bool(ind.guards_local)}

    def por_c(self, por: dict) -> list:
        """The tables of :meth:`por_tables` the per-state ample test reads
        (pccl/model/native_c/por.c: reduce.Por.eligible, footprint, movable,
        ample; independence.may_wait)."""
        from pccl.model import independence as I
        m = self.m
        return [self.c_array("PCLS", "unsigned char", por["cls"]),
                self.u64_array("PSR", por["sr"]), self.u64_array("PSW", por["sw"]),
                self.u64_array("PRR", por["rr"]), self.u64_array("PRW", por["rw"]),
                self.c_array("PENDS", "unsigned char", por["ends"]),
                self.c_array("PWRITER", "unsigned char", por["writer"]),
                self.c_array("PEMPTY", "unsigned char", por["empty"]),
                self.c_array("PSPENT", "unsigned char", por["spent"]),
                # (the events' footprints: read under local guards only)
                *([self.u64_array("EVR", por["evr"]), self.u64_array("EVW", por["evw"])] if por["local"] else []),
                f"#define EVR_ALL {por['er']}ULL", f"#define EVW_ALL {por['ew']}ULL",
                f"#define GUARDR {por['gr']}ULL", f"#define GUARDS_LOCAL {int(por['local'])}",
                f"#define TOP_PC {m.ctl.empty_pc}", f"#define LQ_BIT {I.LQ_BIT}ULL",
                f"#define C_NEVER {I.NEVER}", f"#define C_LOCAL {I.LOCAL}", f"#define C_ACCESS {I.ACCESS}",
                f"#define C_REQUEST {I.REQUEST_LOCK}", f"#define C_RELEASE {I.RELEASE}",
                f"#define C_EXECUTE {I.EXECUTE}",
                f"#define L_LOCK {LOCK}", f"#define L_REQUEST {REQUEST}",
                # an agent's block of the vector: pc, counter, lock state, status, locals
                "#define VA_PC 0", "#define VA_LCK 2"]

    def guard_c(self) -> list:
        """C of ``guard(j, e, s)``: event ``e``'s guard for agent ``j`` (the
        program's guards, per agent: what the partial-order reduction's
        footprint and the dead-variable reduction's live events read)."""
        evs = self.c.program.events
        out = ["static MAYBE_UNUSED V guard(int j, int e, const V *s) {",
               "  (void)s;", "  switch (j * NEV + e) {"]
        for j in range(self.N):
            for e, ev in enumerate(evs):
                out.append(f"  case {j * len(evs) + e}: return {self.expr(ev.guard, j)};")
        out += ["  }", "  return 0;", "}"]
        return out

    def dead_vars(self):
        """The dead-variable reduction's analysis (:class:`pccl.model.dead.DeadVars`,
        the Reduced's own tables) when the reduction is on, else None."""
        m = self.m
        if "dead" not in getattr(getattr(m, "reduction", None), "on", ()):
            return None
        from pccl.model.dead import DeadVars
        from pccl.model.reduce import unreduced
        d = getattr(m, "dead_vars", None) or DeadVars(unreduced(m))
        if d.nloc > 63:
            raise Unsupported("the dead-variable reduction over more than 63 loc: variables")
        return d

    def dead_c(self, d) -> list:
        """The tables ``dead_bits(s, d)`` and ``dead_apply(s, d)`` read
        (pccl/model/native_c/dead.c; ``d``: :meth:`dead_vars`, every agent's
        dead values in the vector set to DEADV, before the key; no copy of a
        state where nothing is dead): the analysis' tables, every row of them."""
        m = self.m
        if d is None:
            return ["#define DEAD 0"]
        rows = 1 << len(d.cond)
        npc = len(m.ctl.cells)
        return ["#define DEAD 1", "#define DEADV (INT64_MIN + 3)", f"#define DROWS {rows}",
                f"#define DLOCAL {int(bool(d.local_guards))}",
                f"#define DEVALL {(1 << len(d.events)) - 1}ULL",
                *([self.u64_array("LIVEEV", [d.entry(e, r) for e in range(len(d.events)) for r in range(rows)])]
                  if d.local_guards else []),
                f"#define DKEEP {d.keep}ULL", f"#define DALL {d.all}ULL", f"#define DGR {d.guard_reads}ULL",
                f"#define DTOP {d.top}ULL",
                # the loc: slots (in an agent's block, after its 4 control cells) of the row's conditions
                f"#define NDCOND {len(d.cond_slots)}", self.c_array("DCOND", "int", list(d.cond_slots)),
                # per agent the mask of its dead values (nonzero: some)
                self.u64_array("DEADPC", [d.all & ~(d.live_pc(pc, r) | d.keep)
                                          for pc in range(npc) for r in range(rows)])]

    @staticmethod
    def c_array(name: str, ctype: str, vals: list) -> str:
        """A C constant array (one dummy element when ``vals`` is empty)."""
        body = ", ".join(str(int(v)) for v in vals) or "0"
        return f"static const {ctype} {name}[] = {{{body}}};"

    @classmethod
    def u64_array(cls, name: str, vals: list) -> str:
        """:meth:`c_array` of uint64_t constants."""
        return cls.c_array(name, "uint64_t", vals).replace(",", "ULL,").replace("}", "ULL}")

    def reduced_c(self) -> str:
        """The tables of the reductions that are on (:meth:`reductions`) and
        the stall signature's slots, which the reduced step ``rstep``
        (partial-order reduction, then statement merging, as
        :class:`pccl.model.reduce.Reduced` composes them), the canonical key
        ``canon`` (symmetry) and the stall signature ``sigstall`` read
        (pccl/model/native_c/reduced.c, por.c, dead.c)."""
        m, N, A_ = self.m, self.N, self.A
        if any(type(x) is not int for x in (*m.rho, m.n0)):
            raise Unsupported("a rate or n0 that is not an integer")
        por, merge, sym = self.reductions()
        out = [f"#define POR {int(por is not None)}", f"#define MERGE {int(merge is not None)}",
               f"#define SYM {int(sym is not None)}",
               f"#define SYMFIX {self.sym_fixed if sym is not None else 0}",
               f"#define MERGE_LIMIT {MERGE_LIMIT}",
               f"#define NBID {len(sym[0]) if sym else 0}",
               f"#define NSHID {len(sym[1]) if sym else 0}"]
        # the tables of the reductions that are on (no unused one)
        if sym is not None:
            out += [self.c_array("BID", "int", sym[0]), self.c_array("SHID", "int", sym[1])]
        if merge is not None:
            out.append(self.c_array("MERGEOK", "unsigned char", merge))
        d = self.dead_vars()
        if por is not None or (d is not None and d.local_guards):
            out += self.guard_c()
        if por is not None:
            out += self.por_c(por)
            out.append('#include "por.c"')
        out += self.dead_c(d)
        out.append('#include "dead.c"')
        ctr = getattr(m, "counters", None) if "counters" in getattr(getattr(m, "reduction", None), "on", ()) else None
        out += ctr.c_tables() if ctr is not None else ["#define CTRS 0"]
        # the stall signature (pccl/model/stall.py): the lock queue, shared,
        # and per agent its status, allread and the loc: variables a property reads
        from pccl.model.stall import _visible_locals
        from pccl.model.reduce import unreduced
        vis = _visible_locals(unreduced(m))
        slots = list(range(self.LQ0, self.AG0))
        for i in range(N):
            a0 = self.AG0 + i * A_
            slots += [a0 + 3] + [a0 + 4 + k for k in vis] + \
                [a0 + 4 + self.L + k for k in range(self.R)]
            if self.moves:      # position, target, done, fail
                slots += [a0 + self.MV, a0 + self.MV + 1, a0 + self.MV + 4, a0 + self.MV + 5]
        out.append(self.c_array("SIGSLOTS", "int", slots))
        out.append(f"#define NSIGSLOTS {len(slots)}")
        # the frozen-team check's progress signature (pccl/model/frozen.py): the
        # same without the lock queue, the env and the doReach flags (hashed:
        # native_c/module.c's psighash; as they are: its progsig)
        pslots = list(range(self.SH0, self.SH0 + len(self.lay.shared)))
        for i in range(N):
            a0 = self.AG0 + i * A_
            pslots += [a0 + 3] + [a0 + 4 + k for k in vis] + \
                [a0 + 4 + self.L + k for k in range(self.R)]
            if self.moves:      # position, target
                pslots += [a0 + self.MV, a0 + self.MV + 1]
        out.append(self.c_array("PSIGSLOTS", "int", pslots))
        out.append(f"#define NPSIGSLOTS {len(pslots)}")
        out.append('#include "reduced.c"')
        return "\n".join(out)

    def source(self) -> str:
        m = self.m
        m.prepare()                 # every k cell interned
        self.check()
        N, NS = self.N, self.NS
        agents = []
        for i in range(N):
            agents += self.agent_code(i)
        ta = self.lab(("TIME ADVANCE", None, None))
        dr = self.lab(("DOREACH INVOKE", None, 0))
        props = " && ".join(f"({self.pexpr(p.expr, {})})" for p in m.properties) or "1"
        if m.collisions:
            props += f" && {self.collision_site()}"
        reduced = self.reduced_c()
        envc = self.env_site() if self.moves else []
        # (before the property memo sites' declarations are written: the
        # temporal columns' predicates may add sites of their own)
        tcols = self.temporal_c()
        return "\n".join([
            "/* pccl native engine: the module of one program, generated by pccl/model/native_gen.py;",
            "   the fixed C it includes is pccl/model/native_c/ (native.h says how the two meet) */",
            f"#define NS {NS}", f"#define NAG {N}", f"#define LQ0 {self.LQ0}",
            # the key: the vector without the clock under time abstraction (one module per key)
            f"#define KEYSKIP {8 if m.abstract_time else 0}",
            f"#define PACK {1 if self.packs else 0}",
            "#define VMIN (INT64_MIN + 4)",         # V_MIN
            f"#define V_TIME {V_TIME}", f"#define V_PHASE {V_PHASE}",
            f"#define PH_DISCRETE {DISCRETE}", f"#define PH_DYNAMIC {DYNAMIC}",
            f"#define S_RUNNING {RUNNING}", f"#define S_EXITED {EXITED}", f"#define S_STUCK {STUCK}",
            # an agent's block: AW slots from AG0 + AW * j (pc, counter, lock
            # state, status, NLOC locals, allread; MV: where a moving robot's start)
            f"#define AG0 {self.AG0}", f"#define AW {self.A}", f"#define NLOC {self.L}",
            f"#define MOVES {int(self.moves)}", f"#define MV {self.MV}",
            f"#define NPC {len(m.ctl.cells)}", f"#define EMPTY_PC {m.ctl.empty_pc}",
            f"#define IDLE_PC {m.ctl.idle_pc}",
            # the clock: δ, the bound of ticks (--max-time; 0: none), the labels of its rules
            f"#define KEEPN0 {m.n0}", f"#define DELTA {m.delta}LL",
            f"#define MAXTICKS {0 if m.max_ticks is None else m.max_ticks}LL",
            f"#define HAS_MAXTICKS {int(m.max_ticks is not None)}",
            f"#define L_TA {ta}", f"#define L_DR {dr}",
            f"#define FIRST_ONLY {int(bool(m.first_only))}", f"#define NEV {len(self.c.program.events)}",
            '#include "native.h"',
            '#include "memo.c"',
            '#include "robots.c"',
            *agents,
            self.c_array("RHO", "V", list(m.rho)),
            "static int (*const AGENT[NAG])(const V *s) = {"
            + ", ".join(f"agent{i}" for i in range(N)) + "};",
            *envc,
            *self.pdecls,
            "/* every invariant holds (okexpr, step.c, checks the rest) */",
            "static inline int invariants(const V *s) {",
            "  (void)s;",
            f"  return {props};",
            "}",
            '#include "step.c"',
            reduced,
            '#include "temporal.h"',
            tcols,
            '#include "temporal.c"',
            '#include "module.c"',
            '#include "kernel.c"',
            ""])
