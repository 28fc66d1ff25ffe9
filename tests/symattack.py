"""A generator of PCCL programs that *try* to tell agents apart (issue 20).

Each program declares agent ids in every place one can live — an allread
``me``, a local ``id``, a shared ``owner``, a local ``peer`` copied from
another agent's ``me``, an allread array indexed by an id, a list that
may receive one — and builds guards, statements, initialisers and
properties from a pool of expressions that mixes symmetric uses of ids
(``==`` with another id or ``-1``, agent indexes) with asymmetric ones
(``me[i] == 1``, ``flags[getAgentIndex()]``, ``id + 1``, ``x = id``,
``a[0]``-style constant agent indexes, ``id < peer``, ids in lists).  The
symmetry analysis must turn symmetry off for every program that can tell
agents apart; :func:`check` compares verdicts with ``reduce="none"``.

Seeded ``random`` (not hypothesis) so that 2,000 programs are cheap and a
failure names its seed: ``python tests/symattack.py SEED`` prints that
program and both verdicts.
"""

from __future__ import annotations

import random
import re
import sys

from pccl.api import explore, make_model
from pccl.lang.errors import PcclError
from pccl.lang.parser import parse_program


from pccl.lang import scalarset as SS

#: The symmetry analysis's own methods, which the old holes below wrap.
ORIG_TYPEOF = SS.IdTypes.typeof
ORIG_AGENT_INDEX = SS.IdTypes.agent_index


def weak_reads(self, e, prop, bound):
    """Hole 1 (for teeth: ``monkeypatch.setattr(SS.IdTypes, "typeof",
    weak_reads)``): an indexed read is never an agent id."""
    if isinstance(e, SS.A.Index):
        return False
    return ORIG_TYPEOF(self, e, prop, bound)


def weak_arrays(self, e, prop, bound):
    """Hole 2 (``"agent_index"``): every first index of an allread variable
    picks an agent."""
    root, chain = SS.A.index_chain(e)
    if isinstance(root, SS.A.Name):
        vs = self.lay.vars.get(root.name)
        if vs is not None and vs.section == "allread":
            return root.name, chain[0].index, chain[1:]
    return ORIG_AGENT_INDEX(self, e, prop, bound)


HEADER = """Agent::Attack

allwrite:
  int owner = {owner};
  int s = 0;
  List<int> seen = [];

allread:
  int me = getAgentIndex();
  bool done = false;
  bool flags[3] = false;
  int arr[3] = 0;

loc:
  int id = {id};
  int peer = -1;
  int x = 0;
  bool b = false;

Init:
"""

#: id-valued expressions (in the program)
IDS = ["getAgentIndex()", "id", "me[getAgentIndex()]", "me[id]", "owner", "peer", "me[peer]",
       "me[owner]"]
#: int expressions that are not ids
INTS = ["0", "1", "2", "x", "s", "arr[0]", "arr[1]", "size(seen)", "(x + 1) % 3", "(s + 1) % 3"]
#: asymmetric int expressions built from ids
ID_ARITH = ["(id + 1) % getNumAgents()", "getAgentIndex() + 0", "arr[getAgentIndex()]", "arr[id]",
            "me[0]", "me[1]", "x * id"]
#: bool expressions: symmetric uses first, then asymmetric ones
SYM_BOOLS = ["!done", "done", "b", "!b", "owner == -1", "owner != -1", "owner == id",
             "owner == getAgentIndex()", "me[peer] == id", "peer == -1", "peer != id",
             "done[owner]", "!done[peer]", "x == 0", "x < 2", "s < 2", "arr[0] == 0",
             "flags[0]", "!flags[1]", "contains(seen, 1)", "me[id] == id"]
ASYM_BOOLS = ["id == 0", "me[getAgentIndex()] == 1", "getAgentIndex() < peer", "owner == 1",
              "flags[getAgentIndex()]", "!flags[id]", "done[0]", "!done[1]", "contains(seen, id)",
              "x == id", "owner < id", "me[owner] == 0", "arr[id] == 1"]
#: properties: symmetric, then asymmetric
SYM_PROPS = ["count(done) <= 1", "forall i: done[i] -> me[i] == i",
             "forall i: forall j: (done[i] && done[j]) -> i == j", "owner != -1 -> done[owner]",
             "forall i: peer[i] == -1 || peer[i] != i", "s < 2", "exists i: !done[i]",
             "forall i: !flags[i][2]", "forall i: arr[i][0] < 2", "forall i: x[i] < 2",
             "forall i: owner == i -> b[i]", "size(seen) < 2"]
ASYM_PROPS = ["forall i: (me[i] == 1 && done[i]) -> (exists j: me[j] == 0 && done[j])",
              "!done[0]", "forall i: done[i] -> i == 0", "owner != 1", "forall i: peer[i] != 0",
              "forall i: flags[i][i] -> false", "forall i: !(done[i] && arr[i][i] == 1)",
              "exists i: me[i] == 0 && !done[i]", "count(done) < 1 || done[1]",
              "forall i: x[i] != i + 1"]


#: names of the feature families a program may leave out (so that an
#: analysis that refuses one family is still attacked by the others)
FAMILIES = ("arr", "flags", "seen", "peer", "owner", "me[", "constidx")
_OFF: set = set()
#: an array read or written at a constant element in the program, or any
#: element in a property: off with the family "constidx", so that some
#: programs use their arrays only through an id (``flags[getAgentIndex()]``)
_CONSTIDX = re.compile(r"(arr|flags)\[([0-9x]|i\])")


def _ok(text: str) -> bool:
    if "constidx" in _OFF and _CONSTIDX.search(text):
        return False
    return not any(f in text for f in _OFF if f != "constidx")


def _pick(rng, pool):
    return rng.choice([x for x in pool if _ok(x)] or ["0" if pool is INTS or pool is ID_ARITH else "b"])


def _choice(rng, sym, asym, p_asym):
    return _pick(rng, asym) if rng.random() < p_asym else _pick(rng, sym)


def _int_expr(rng, p_asym):
    return _choice(rng, INTS, ID_ARITH, p_asym)


def _stmt(rng, p_asym, depth, ind):
    pad = "  " * ind
    asym = rng.random() < p_asym
    kinds = ["x", "s", "done", "b", "other"]
    if depth > 0:
        kinds += ["if", "atomic"]
    kinds += [k for k in ("owner", "peer", "flags", "arr", "seen") if _ok(k)]
    kind = rng.choice(kinds)
    if kind in ("if", "atomic"):
        body = "".join(_stmt(rng, p_asym, depth - 1, ind + 1) for _ in range(rng.randint(1, 2)))
        if kind == "atomic":
            return f"{pad}atomic:\n{body}"
        return f"{pad}if ({_choice(rng, SYM_BOOLS, ASYM_BOOLS, p_asym)}):\n{body}"
    if kind == "owner":
        return f"{pad}owner = {_pick(rng, ['getAgentIndex()', 'id', '-1', 'peer', 'me[peer]'])};\n"
    if kind == "peer":
        src = _pick(rng, ["me[owner]", "owner", "me[getAgentIndex()]", "-1"] +
                    (["x", "id + 0", "arr[0]"] if asym else []))
        return f"{pad}peer = {src};\n"
    if kind in ("x", "s"):
        return f"{pad}{kind} = {_int_expr(rng, p_asym)};\n"
    if kind in ("done", "b"):
        return f"{pad}{kind} = {_choice(rng, SYM_BOOLS, ASYM_BOOLS, p_asym)};\n"
    if kind in ("flags", "arr"):
        idx = [i for i in ("0", "1", "x") if _ok(f"{kind}[{i}]")] + (["getAgentIndex()", "id"] if asym else [])
        if not idx:
            return f"{pad}skip;\n"
        value = (_choice(rng, SYM_BOOLS, ASYM_BOOLS, p_asym) if kind == "flags"
                 else _int_expr(rng, p_asym))
        return f"{pad}{kind}[{rng.choice(idx)}] = {value};\n"
    if kind == "seen":
        v = rng.choice(["1", "2"] + (["id", "getAgentIndex()"] if asym else []))
        return f"{pad}if (size(seen) < 2):\n{pad}  add(seen, {v});\n"
    return f"{pad}exit();\n" if rng.random() < 0.3 else f"{pad}skip;\n"


def program(seed: int) -> tuple:
    """(text, invariants, agents) for ``seed``."""
    rng = random.Random(seed)
    _OFF.clear()
    _OFF.update(f for f in FAMILIES if rng.random() < 0.4)
    p_asym = rng.choice([0.0, 0.0, 0.05, 0.15, 0.4])
    owner = rng.choice(["-1", "-1", "-1", "0"] if p_asym else ["-1"])
    id_init = "getAgentIndex()" if rng.random() > p_asym else _pick(rng, ["0", "me[0]", "me[1]"])
    text = HEADER.format(owner=owner, id=id_init)
    if rng.random() < 0.3:
        text += f"  peer = {_pick(rng, ['me[getAgentIndex()]', 'owner', '-1'])};\n" if _ok('peer') else ''
    for e in range(rng.randint(1, 3)):
        guard = _choice(rng, SYM_BOOLS, ASYM_BOOLS, p_asym)
        if rng.random() < 0.5:
            guard = f"{guard} && {_choice(rng, SYM_BOOLS, ASYM_BOOLS, p_asym)}"
        body = "".join(_stmt(rng, p_asym, 2, 2) for _ in range(rng.randint(1, 3)))
        text += f"\nE{e}():\n  pre({guard});\n  eff:\n{body}"
    invariants = [_choice(rng, SYM_PROPS, ASYM_PROPS, p_asym) for _ in range(rng.randint(1, 2))]
    if p_asym == 0 and rng.random() < 0.5:
        # one asymmetric use in an otherwise symmetric program: the analysis
        # must find it wherever it hides
        where = rng.randrange(3)
        if where == 0:
            invariants.append(_pick(rng, ASYM_PROPS))
        else:
            guard = _pick(rng, ASYM_BOOLS) if where == 1 else _pick(rng, SYM_BOOLS)
            body = _stmt(rng, 1.0 if where == 2 else 0.0, 1, 2)
            text += f"\nOdd():\n  pre({guard});\n  eff:\n{body}"
    return text, invariants, rng.choice([2, 2, 3])


def verdict(res) -> tuple:
    return res.status, sorted({(v["kind"], v["name"], v["line"]) for v in res.violations})


def check(seed: int, reductions=("symmetry", "merge", "por")) -> dict:
    """Explore program ``seed`` unreduced and under each reduction that its
    analysis allows; returns {reduction: (verdict, same as none?)}, or
    {"invalid": message} when the generated text does not check."""
    text, invariants, agents = program(seed)
    # the Python engine, the reference: the attack is on the symmetry
    # analysis; the native engine's agreement with it is tests/test_native*.py's
    # (auto would compile a module for each of 2,000 programs)
    kw = dict(source=True, agents=agents, blackbox="instant", invariants=invariants)
    try:
        # parsed once: every model below is built from this AST (what
        # source=True would parse again for each)
        text = parse_program(text, "<input>")
        plan = make_model(text, reduce="auto", **kw).reduction
    except PcclError as e:
        return {"invalid": str(e)}
    kw.update(find_all=True, max_states=5_000, engine="python")
    base = explore(text, reduce="none", **kw)
    if base.bounds:
        return {"bounded": True}
    out = {}
    if "symmetry" in reductions and "symmetry" in plan.on:
        out["orbits"] = orbits_agree(text, agents, invariants)
    for name in reductions:
        if name not in plan.on:
            out[name] = None
            continue
        res = explore(text, reduce=name, **kw)
        out[name] = (verdict(res), verdict(res) == verdict(base))
    return out


def orbits_agree(text, agents, invariants, limit=5_000, **options) -> bool:
    """The symmetry key is a bisimulation that respects the properties: over
    the unreduced reachable states, all states with one canonical key have
    the same set of successor keys and the same violations (kind, name,
    line).  This is the soundness argument itself, checked state by state:
    far finer than the verdict, it fails on a program that tells agents
    apart even where no property happens to notice.  ``text``: the source
    or its parsed Program."""
    kw = dict(source=True, agents=agents, blackbox="instant", invariants=invariants)
    kw.update(options)
    if agents is None:
        del kw["agents"]                # the world's count
    if isinstance(text, str):
        text = parse_program(text, "<input>")     # once for both models
    sym = make_model(text, reduce="symmetry", **kw)
    full = make_model(text, reduce="none", **kw)
    key = sym.key
    seen: set = set()
    todo = list(full.init_states())
    orbit: dict = {}
    while todo and len(seen) < limit:
        st = todo.pop()
        k = full.key(st)
        if k in seen:
            continue
        seen.add(k)
        succ = [t for _, t in full.successors(st)]
        sig = (frozenset(key(t) for t in succ),
               frozenset((v.kind, v.name, v.span.line if v.span else None)
                         for v in full.violations(st)))
        if orbit.setdefault(key(st), sig) != sig:
            return False
        todo.extend(succ)
    return True


if __name__ == "__main__":
    seed = int(sys.argv[1])
    text, invariants, agents = program(seed)
    print(text)
    print("invariants:", invariants, "agents:", agents)
    print(check(seed))


# ---------------------------------------------------------------------------
# robots that move (issue 23): symmetry with positions in the key
# ---------------------------------------------------------------------------

MOVING = """Agent::Movers

allwrite:
  List<ItemPosition> dests = getInput();
  int owner = -1;

allread:
  bool arrived = false;

loc:
  ItemPosition goal;
  bool going = false;
  bool gaveUp = false;
  int tries = 0;
  int id = getAgentIndex();

Init:
"""

#: guards and statements for movers; the second lists tell agents apart
MOVE_GUARDS = ["!going && !arrived && !gaveUp", "going && doReach_done", "going && doReach_fail",
               "going && !doReach_done && !doReach_fail", "arrived", "owner == -1",
               "owner == id", "tries < 2", "dist(getPosition(), ItemPosition(4, 0)) < 1",
               "!isEmpty(dests)"]
MOVE_GUARDS_ASYM = ["id == 0", "arrived[0]", "getPosition().x < 0", "owner == 1"]
MOVE_STMTS = ["goal = ItemPosition(4, 0);\n", "goal = ItemPosition(2, 3);\n",
              "going = true;\n    doReach(goal, getObs());\n", "going = false;\n",
              "arrived = true;\n", "gaveUp = true;\n", "tries = tries + 1;\n",
              "owner = id;\n", "owner = -1;\n", "exit();\n",
              "atomic:\n      if (!isEmpty(dests)):\n        goal = head(dests);\n        remove(dests, goal);\n",
              "doReach(getPosition(), getObs());\n"]
MOVE_STMTS_ASYM = ["goal = ItemPosition(getAgentIndex(), 0);\n", "tries = id;\n",
                   "goal = ItemPosition(4 + id, 0);\n"]
MOVE_PROPS = ["forall i: forall j: (i != j && arrived[i] && arrived[j]) -> dist(pos[i], pos[j]) > 0.1",
              "count(arrived) <= 1", "forall i: !doReach_fail[i]", "forall i: pos[i].y < 3",
              "forall i: exited[i] -> arrived[i]", "owner == -1 || arrived[owner]"]
MOVE_PROPS_ASYM = ["!arrived[0]", "pos[1].x < 3", "forall i: doReach_done[i] -> i == 0"]
MOVE_WORLDS = [
    "agents = 2\nspeed = 2.0\nradius = 0.25\nstart = [[0, 0], [-3, 1]]\n"
    "[functions]\ngetInput = [[4, 0], [2, 3]]\n",
    "agents = 3\nspeed = 2.0\nradius = 0.25\nstart = [[0, 0], [-3, 1], [0, 3]]\n"
    "[functions]\ngetInput = [[4, 0], [2, 3]]\n",
    "agents = 2\nspeed = 1.5\nradius = 0.25\nstart = [[0, 0], [0, 3]]\n"
    "[functions]\ngetInput = [[4, 0]]\n"
    "[[obstacles]]\npolygon = [[1.9, -1], [2.1, -1], [2.1, 1], [1.9, 1]]\n",
]


def moving_program(seed: int) -> tuple:
    """(text, invariants, world text, blackbox) for ``seed``."""
    rng = random.Random(seed)
    p_asym = rng.choice([0.0, 0.0, 0.0, 0.1])
    text = MOVING
    for e in range(rng.randint(2, 4)):
        gs = [rng.choice(MOVE_GUARDS_ASYM if rng.random() < p_asym else MOVE_GUARDS)
              for _ in range(rng.randint(1, 2))]
        body = "".join("    " + rng.choice(MOVE_STMTS_ASYM if rng.random() < p_asym else MOVE_STMTS)
                       for _ in range(rng.randint(1, 3)))
        text += f"\nM{e}():\n  pre({' && '.join(gs)});\n  eff:\n{body}"
    invariants = [rng.choice(MOVE_PROPS_ASYM if rng.random() < p_asym else MOVE_PROPS)]
    return text, invariants, rng.choice(MOVE_WORLDS), rng.choice(["nondet", "straight", "instant"])


def check_moving(seed: int, tmpdir) -> dict:
    """As :func:`check`, for :func:`moving_program` (symmetry only)."""
    import pathlib
    text, invariants, world_text, bb = moving_program(seed)
    world = pathlib.Path(tmpdir) / f"w{seed}.toml"
    world.write_text(world_text)
    kw = dict(source=True, world=str(world), blackbox=bb, invariants=invariants)
    try:
        text = parse_program(text, "<input>")      # once, as in check()
        plan = make_model(text, reduce="auto", **kw).reduction
    except PcclError as e:
        return {"invalid": str(e)}
    if "symmetry" not in plan.on:
        return {"symmetry": None}
    base = explore(text, reduce="none", find_all=True, max_states=5_000, engine="python", **kw)
    if base.bounds:
        return {"bounded": True}
    res = explore(text, reduce="symmetry", find_all=True, max_states=5_000, engine="python",
                  **kw)
    return {"symmetry": (verdict(res), verdict(res) == verdict(base)),
            "orbits": orbits_agree(text, None, invariants, world=str(world), blackbox=bb),
            "states": (res.stats.states, base.stats.states)}
