"""The oracle's program generator (issue 41, "The oracle").

``case(seed)`` is a :class:`Case`: a well-formed PCCL program, and what it
is explored with (agents, world file, ``--invariant``/``--property`` forms,
a user blackbox module).  Families, chosen by the seed:

* ``core``: shared (allwrite), allread and ``loc:`` declarations of every
  type (int, float, bool, ``List<int>``, ``ItemPosition``, arrays), their
  initialisers (``rand``, world functions, ids), guards, statements,
  ``if``/``else``, ``while``, ``atomic``, ``assert``, ``add``/``remove``,
  ``exit``; every runtime error kind (division and modulo by zero, index
  out of range, head of an empty list, ``remove`` of an absent element,
  negative ``rand`` bound, float overflow, undefined reads, a world value
  that does not fit, failed assertions) in initialisers, guards,
  statements, ``atomic`` blocks, ``while`` tests and properties; ints at
  and past the 64-bit edges (±(2^63−1), −2^63, 2^64); symmetric uses of
  agent ids and subtle symmetry breakers (``me[i]``-style reads, an
  allread array indexed by the agent's own id, ids compared or used in
  arithmetic); the program's ``invariant:`` section, ``--invariant`` and
  ``--property`` forms (``eventually``, ``~>``, ``~> within``,
  ``reachable``; docs/temporal.md).
* ``moving``: robots with a world (start positions, obstacles,
  ``resolution``, ``radius``, ``speed``), ``doReach`` to targets behind,
  beside and near-tangent to obstacles, re-targets in mid-motion,
  ``doReach_fail`` handled (an assertion, a counter) and not.
* ``userbb``: a moving program under a user blackbox that subclasses a
  shipped one (``straight``, ``instant``, ``nondet``) and overrides its
  ``step`` (written to a temporary module, ``--blackbox FILE:BLACKBOX``).
* ``sym``, ``por``: the attack generators of ``tests/symattack.py`` and
  ``tests/porattack.py`` (issues 20 and 23), as cases of this module.
* ``orbit`` (a share of the ``core`` draws, as ``counters``): programs with
  per-agent temporal properties (``forall i: P(i) ~> Q(i)`` and the other
  forms), checked for i = 0 alone where symmetry keeps agent 0 in place
  (issue 46, docs/reductions.md "Per-agent temporal properties").

Every program keeps its state space small (a per-agent step counter bounds
every event), so that the unreduced search is exhaustive within the
oracle's ``max_states`` and verdicts can be compared exactly.
"""

from __future__ import annotations

import random
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Optional

MAX = "9223372036854775807"                 # 2^63 - 1
MIN = "(-9223372036854775807 - 1)"          # -2^63
P64 = "18446744073709551616"                # 2^64
EDGE_INTS = [MAX, MIN, P64, f"-{MAX}", f"({MAX} + 1)", f"({MIN} - 1)"]


@dataclass
class Case:
    """One generated program and how it is explored."""
    seed: int
    family: str
    text: str
    agents: Optional[int] = 2               # None: the world's count
    world: Optional[str] = None             # the world file's text
    invariants: list = field(default_factory=list)
    properties: list = field(default_factory=list)
    blackbox: Optional[str] = None          # a user blackbox module's text (attribute BLACKBOX)
    moves: bool = False
    options: dict = field(default_factory=dict)   # more explore options (blackbox, n0, events, ...)
    lang: str = "pccl"                      # the text's language: pccl | koord (docs/koord.md)

    def with_text(self, text: str) -> "Case":
        return replace(self, text=text)

    @property
    def filename(self) -> str:
        """The program's file name: its suffix says the language."""
        return "program.koord" if self.lang == "koord" else "program.pccl"


def parse(case: Case):
    """The case's text parsed by its language's front end (a PcclError when
    it is malformed)."""
    if case.lang == "koord":
        from pccl.lang.koord import parse_koord
        return parse_koord(case.text, "<input>.koord")
    from pccl.lang.parser import parse_program
    return parse_program(case.text, "<input>")


# ---------------------------------------------------------------------------
# core
# ---------------------------------------------------------------------------

INT_ATOMS = ["0", "1", "2", "s", "x", "y", "c", "size(q)", "arr[0]", "arr[1]"]
#: asymmetric int expressions (ids in arithmetic, own-element indexing)
ID_ARITH = ["me", "me + 1", "getAgentIndex()", "arr[me]", "arr[getAgentIndex()]", "me[0]", "x * me"]
#: the probability of an asymmetric use, per program (0: a symmetric family)
_P = {"asym": 0.1, "err": 0.05, "subtle": 0.0, "plain": False}
#: what keeps a program off the native engine (its engine_reason): floats,
#: positions, indexed assignments, temporal properties; a *plain* program
#: has none of them, so that the native modes really run native code
NOT_NATIVE = ("h ", "h)", "h[", "p.", "(p,", "p[", "h *", "1e308", "arr[", "q", "(l", "head", "size", "isEmpty",
              "contains", P64, "rand(", "0.5", "1.5")


def _pick(rng, pool):
    """rng.choice(pool), but from what the native engine serves in a plain program."""
    if _P["plain"]:
        pool = [e for e in pool if not any(t in e for t in NOT_NATIVE)] or ["0"]
    return rng.choice(pool)
ERR_INT = [  # an int expression that fails for some reachable values
    "10 / (x - 1)", "s % (y - 1)", "q[x]", "arr[y]", "head(l)", "rand(x - 1)", "arr[s]",
    "q[size(q) - x]", "u", "me[x]",
]
ID_SYM = ["me[me] == me", "owner == me", "owner != -1", "flag[owner]", "me == me"]
ID_ASYM = ["me == 0", "me[0] == 0", "arr[me] == 1", "me < 1", "(me + 1) % 2 == 0",
           "flag[me]", "owner == 1", "getAgentIndex() + x == 1"]


def _int(rng, depth=1, err=None, edge=0.06) -> str:
    err = _P["err"] if err is None else err
    r = rng.random()
    if r < err:
        return _pick(rng, ERR_INT if _P["asym"] else ERR_INT[:-1])
    if r < err + edge:
        return _pick(rng, EDGE_INTS)
    if r < err + edge + _P["asym"] / 2:
        return _pick(rng, ID_ARITH)
    if r < err + edge + _P["asym"] / 2 + 0.04:
        return _pick(rng, ["me[me]", "me[getAgentIndex()]", "arr[me]", "arr[getAgentIndex()]"])  # subtle
    if depth <= 0 or r < 0.55:
        return _pick(rng, INT_ATOMS)
    op = rng.choice(["+", "-", "*", "/", "%"])
    a, b = _int(rng, depth - 1, err / 2, edge), _int(rng, depth - 1, err / 2, edge)
    if op in "/%" and rng.random() < 0.8:
        b = rng.choice(["2", "3", "(1 + c)"])
    return f"({a} {op} {b})"


def _bool(rng, asym=None, err=None) -> str:
    asym = _P["asym"] if asym is None else asym
    err = _P["err"] if err is None else err
    r = rng.random()
    if r < err:
        return _pick(rng, ["10 / (x - 1) > 0", "q[x] == 1", "head(l) > 0", "u == 0",
                           "h * 1e308 * 10.0 > 1.0", "arr[y] == 0"])
    if r < err + asym:
        return _pick(rng, ID_ASYM)
    if r < err + asym + 0.08:
        return _pick(rng, ID_SYM)
    k = rng.random()
    if k < 0.25:
        return _pick(rng, ["g", "!g", "flag", "!flag", "isEmpty(q)", "contains(q, x)", "x < 0.5",
                           "y > 1.5", "x <= s", "isEmpty(l)"]
                          + ([] if _P["plain"] else ["p.x > 0.5", "h < 2.0",
                                                     "dist(p, ItemPosition(0, 0)) < 3.0"]))
    cmp = rng.choice(["==", "!=", "<", "<=", ">", ">="])
    return f"{_int(rng, 1, 0.0)} {cmp} {_int(rng, 0, 0.0)}"


def _stmt(rng, ind: int, depth: int, ctx: dict) -> str:
    pad = "  " * ind
    kinds = ["assign", "assign", "shared", "shared", "assert", "list", "flag", "arr", "float",
             "pos", "skip", "owner"]
    if _P["plain"]:
        kinds = [k for k in kinds if k not in ("float", "pos", "arr", "list")]
    if rng.random() < _P["subtle"]:
        # a subtle symmetry breaker: the allread array's own element picked by the id
        return _pick(rng, [f"{pad}arr[me] = arr[me] + 1;\n", f"{pad}arr[getAgentIndex()] = 1;\n",
                           f"{pad}y = arr[me];\n", f"{pad}flag = arr[getAgentIndex()] == 1;\n",
                           f"{pad}y = me[me] + 1;\n", f"{pad}x = me[getAgentIndex()];\n"])
    if depth > 0:
        kinds += ["if", "atomic", "while"]
    if not ctx.get("in_atomic"):
        kinds += ["exit"] if rng.random() < 0.15 else []
    k = rng.choice(kinds)
    if k == "assign":
        return f"{pad}{rng.choice(['x', 'y'])} = {_int(rng, 2)};\n"
    if k == "shared":
        return f"{pad}s = {_int(rng, 2)};\n"
    if k == "owner":
        odd = ['x', 'me + 1'] if rng.random() < _P['asym'] else []
        return f"{pad}owner = {rng.choice(['me', '-1', 'getAgentIndex()', 'me[owner]'] + odd)};\n"
    if k == "assert":
        if not _P["err"]:           # an assertion that holds, mostly
            return f"{pad}assert(c <= 3 || {_bool(rng)});\n"
        return f"{pad}assert({_bool(rng)});\n"
    if k == "list":
        return rng.choice([f"{pad}if (size(q) < 3):\n{pad}  add(q, {_int(rng, 0, 0.0)});\n",
                           (f"{pad}remove(q, {rng.choice(['1', 'x', 's'])});\n" if _P["err"] else
                            f"{pad}if (contains(q, x)):\n{pad}  remove(q, x);\n"),
                           f"{pad}add(l, {rng.choice(['1', 'x', 'me' if rng.random() < _P['asym'] else '2'])});\n",
                           f"{pad}if (!isEmpty(q)):\n{pad}  y = head(q);\n{pad}  remove(q, y);\n"])
    if k == "flag":
        return f"{pad}flag = {_bool(rng)};\n"
    if k == "arr":
        idx = ['0', '1', 'x'] + (['me', 'getAgentIndex()'] if rng.random() < _P["asym"] * 3 else [])
        return f"{pad}arr[{rng.choice(idx)}] = {_int(rng, 1)};\n"
    if k == "float":
        big = ['h * 1e308'] if _P['err'] else []
        return f"{pad}h = {rng.choice(['h * 2.0', 'h + 0.5', 'h / 3.0', 'h - x', '1.5', 'p.y'] + big)};\n"
    if k == "pos":
        return f"{pad}p = ItemPosition({rng.choice(['x', '1.5', 'h'])}, {rng.choice(['0', 'y', '2.5'])});\n"
    if k == "exit":
        return f"{pad}exit();\n"
    if k == "skip":
        return f"{pad}skip;\n"
    if k == "if":
        body = "".join(_stmt(rng, ind + 1, depth - 1, ctx) for _ in range(rng.randint(1, 2)))
        out = f"{pad}if ({_bool(rng)}):\n{body}"
        if rng.random() < 0.4:
            out += f"{pad}else:\n" + _stmt(rng, ind + 1, depth - 1, ctx)
        return out
    if k == "atomic":
        sub = dict(ctx, in_atomic=True)
        body = "".join(_stmt(rng, ind + 1, depth - 1, sub) for _ in range(rng.randint(1, 2)))
        return f"{pad}atomic:\n{body}"
    # while: bounded by w, reset first
    cond = "w < 2" if rng.random() < 0.7 else f"w < 2 && {_bool(rng)}"
    body = "".join(_stmt(rng, ind + 1, 0, ctx) for _ in range(rng.randint(0, 1)))
    return f"{pad}w = 0;\n{pad}while ({cond}):\n{pad}  w = w + 1;\n{body}"


SHARED_INITS = ["0", "1", "2", "rand(1)", MAX, MIN, "-1", "rand(2) - 1", f"{MAX} - rand(1)"]
LOC_INITS = ["0", "1", "rand(1)", "rand(2)", "10 / (rand(2) - 2)",
             "[7, 8][rand(2)]", "q0[rand(2)]", "rand(1) * " + MAX, MIN, "w0()",
             "head(getInput())", "getNumAgents() - 1", "s + 1"]
SAFE_LOC_INITS = ["0", "1", "rand(1)", "rand(2)", "q0[rand(1)]", "w0()", "getNumAgents() - 1",
                  "s + 1", MIN, "rand(1) * " + MAX]
INVARIANTS = ["s < 3", "s != 2", "forall i: c[i] <= 3", "count(flag) <= 1", "exists i: x[i] == 0",
              "forall i: x[i] < 2 || y[i] > 0", "size(q) < 3", "!contains(q, 2)",
              "forall i: forall j: (flag[i] && flag[j]) -> i == j", "owner != 1",
              "forall i: me[i] == i", "forall i: arr[i][0] < 2", "forall i: h[i] < 100.0",
              "forall i: 10 / (x[i] - 1) > -100", "q[0] >= 0 || isEmpty(q)", "forall i: p[i].x < 3.0",
              "forall i: arr[i][i] == 0", "!g || s > 0", f"s < {MAX}", "forall i: exited[i] -> c[i] > 0",
              "forall i: running[i] || exited[i]"]
#: invariants that often hold
LIKELY = ["forall i: c[i] <= 3", "size(q) < 4", "forall i: running[i] || exited[i]",
          "forall i: exited[i] -> c[i] > 0", "forall i: h[i] < 1e307 || h[i] > 1e299",
          "forall i: me[i] == i", "count(flag) <= N", "s != 12345"]
PROPERTIES = ["eventually (forall i: exited[i])", "g ~> s > 0", "forall i: flag[i] ~> c[i] >= 2",
              "reachable s == 2", "reachable count(flag) == 2", "s == 1 ~> s != 1 within 2",
              "eventually s > 0", "forall i: x[i] == 0 ~> exited[i]"]


def core(seed: int, rng: random.Random, orbit: bool = False) -> Case:
    """A ``core`` program; ``orbit``: one of the ``orbit`` family (see
    :func:`orbit`)."""
    _P["asym"] = rng.choice([0.0, 0.0, 0.0, 0.03, 0.15]) if not orbit else rng.choice([0.0] * 4 + [0.03])
    # about half the programs inject no runtime error: their verdicts are
    # mostly clean, where a false "exhaustive" would hide
    _P["err"] = rng.choice([0.0, 0.0, 0.03, 0.08])
    _P["subtle"] = rng.choice([0.0, 0.0, 0.0, 0.15]) if not _P["asym"] else 0.0
    _P["plain"] = rng.random() < 0.4
    bound = rng.choice([1, 2, 2])
    world = None
    funcs = rng.random() < 0.25          # world functions in the initialisers
    # a shared initialiser that fails for one rand outcome is an error at load time (exit 2)
    bad_shared = ["10 / (rand(1) - 1)", "[1, 2][rand(2)]"] if _P["err"] and rng.random() < 0.15 else []
    shared = [f"  int s = {rng.choice(SHARED_INITS + (['w0()'] if funcs else []) + bad_shared)};",
              "  bool g = false;",
              f"  List<int> q = {rng.choice(['[]', '[1]', '[1, 2]'])};",
              "  List<int> q0 = [7, 8];", f"  int owner = {rng.choice(['-1', '-1', '0'])};"]
    allread = ["  int me = getAgentIndex();", "  bool flag = false;"]
    if rng.random() < 0.3:
        # an allread initialiser: rand, a world function, one that may fail
        ar = ["rand(1)", "s + 1"] + (["w0()"] if funcs else []) + (["10 / (rand(1) - 1)"] if _P["err"] else [])
        allread.append(f"  int ar = {rng.choice(ar)};")
    if not _P["plain"]:
        allread.append(f"  int arr[2] = {rng.choice(['0', '0', 'rand(1)'])};")
    else:
        shared = [d for d in shared if "List" not in d]
    loc_init = _pick(rng, (LOC_INITS if _P["err"] else SAFE_LOC_INITS)
                          + (["getAgentIndex()", "me + 1"] if _P["asym"] else []))
    if funcs or "w0()" in loc_init or "getInput" in loc_init:
        world = (f"[functions]\nw0 = {rng.choice(['0', '1', '3', MAX])}\n"
                 f"getInput = {rng.choice(['[1]', '[1.5]', '[[1, 2]]', '[true]', '[]'])}\n")
    loc = ["  int c = 0;", f"  int x = {loc_init};", f"  int y = {rng.choice(['0', '1', 'x', 'rand(1)'])};",
           "  int w = 0;"] + ([] if _P["plain"] else ["  List<int> l = [];"])
    if not _P["plain"]:
        loc += [f"  float h = {rng.choice(['1.5', '0.5', '1e300', '-0.0'])};",
                "  ItemPosition p = ItemPosition(1, 2);"]
    loc.append("  int u;")                    # undefined: a read gets the agent stuck
    text = "Agent::Gen\n\nallwrite:\n" + "\n".join(shared) + "\n\nallread:\n" + "\n".join(allread)
    text += "\n\nloc:\n" + "\n".join(loc) + "\n"
    if rng.random() < 0.4:
        text += "\nInit:\n" + "".join(_stmt(rng, 1, 1, {"in_atomic": True})
                                      for _ in range(rng.randint(1, 2)))
    for e in range(rng.randint(1, 3)):
        guard = f"c < {bound}"
        if rng.random() < 0.6:
            guard += f" && {_bool(rng)}"
        body = "".join(_stmt(rng, 2, 2, {}) for _ in range(rng.randint(1, 3)))
        text += f"\nE{e}():\n  pre({guard});\n  eff:\n    c = c + 1;\n{body}"
    if rng.random() < 0.2:
        # an int at a 64-bit edge held in the state, compared with a float,
        # and grown past 64 bits
        text = text.replace("  int u;\n", f"  int u;\n  int e = {rng.choice([MIN, MAX, MIN + ' + rand(1)'])};\n")
        text += (f"\nEdge():\n  pre(c < {bound} && e {rng.choice(['<', '>', '!='])} 0.5);\n  eff:\n"
                 f"    c = c + 1;\n    y = {rng.choice(['(e + ' + MAX + ') - 1', 'e * 2', 'e - 1', 'e / 3', '-e'])};\n"
                 f"    x = {rng.choice(['y % 7', 'y / ' + MAX, '0'])};\n")
    if rng.random() < (0.8 if _P["err"] else 0.95):
        text += f"\nDone():\n  pre(c >= {bound});\n  eff:\n    exit();\n"
    if rng.random() < 0.4:
        text += "\ninvariant:\n" + "".join(f"  inv{k}: {rng.choice(INVARIANTS)};\n"
                                          for k in range(rng.randint(1, 2)))
    invariants = [rng.choice(INVARIANTS if _P["err"] else LIKELY)
                  for _ in range(rng.choice([0, 0, 1, 2]))]
    properties = [rng.choice(PROPERTIES)] if rng.random() < 0.2 and not _P["plain"] else []
    if orbit:
        properties = rng.sample(ORBIT_PROPERTIES, rng.choice([1, 1, 2]))
    if _P["plain"]:
        # no float, position or allread array element in the program's properties either
        keep = [ln for ln in text.split("\n") if not (ln.startswith("  inv") and any(t in ln for t in NOT_NATIVE))]
        text = "\n".join(keep)
        if text.rstrip().endswith("invariant:"):
            text = text.rstrip()[:-len("invariant:")]
        invariants = [i for i in invariants if not any(t in i for t in NOT_NATIVE)]
    return Case(seed, "orbit" if orbit else "core", text,
                agents=rng.choice([1, 2, 2, 2, 2, 3] if not orbit else [2, 2, 3]), world=world,
                invariants=invariants, properties=properties)


#: per-agent temporal properties (``forall i:``, one instance per agent):
#: symmetric formulas, decided for i = 0 alone where the program is
#: symmetric (docs/reductions.md, "Per-agent temporal properties"); the
#: last ones name agent 0 besides i (symmetry stays off)
ORBIT_PROPERTIES = ["forall i: eventually exited[i]", "forall i: flag[i] ~> c[i] >= 2",
                    "forall i: x[i] == 0 ~> exited[i]", "forall i: reachable c[i] == 2",
                    "forall i: c[i] == 1 ~> c[i] != 1 within 2", "forall i: owner == i ~> owner != i",
                    "forall i: eventually (exited[i] || owner == i)", "forall i: reachable flag[i] && !g",
                    "forall i: flag[i] ~> exited[i] || count(flag) == 2",
                    "forall i: c[i] == 1 ~> c[0] == 1"]


#: the same over tests/symattack.py's programs (ids held, compared, queued)
ORBIT_SYM_PROPERTIES = ["forall i: eventually exited[i]", "forall i: owner == i ~> owner != i",
                        "forall i: done[i] ~> exited[i]", "forall i: reachable done[i]",
                        "forall i: !b[i] ~> b[i] within 1", "forall i: peer[i] != -1 ~> done[i]",
                        "forall i: eventually (done[i] || owner == i)", "forall i: reachable owner == i",
                        "forall i: eventually me[i] == i && count(done) >= 1",
                        "forall i: done[i] ~> done[0]"]


def orbit(seed: int, rng: random.Random) -> Case:
    """Programs with one or two per-agent temporal properties, 2 or 3
    agents: the orbit argument's cases (issue 46).  Half are ``core``
    programs, symmetric but for a few (asymmetric uses in one in five), with
    :data:`ORBIT_PROPERTIES`; half the attack programs of
    tests/symattack.py (symmetric in about two in five: ids stored,
    compared, named by shared variables) with :data:`ORBIT_SYM_PROPERTIES`."""
    if rng.random() < 0.5:
        return core(seed, rng, orbit=True)
    text, invariants, agents = _attack_module("symattack").program(seed + 500_000)
    return Case(seed, "orbit", text, agents=rng.choice([2, 2, 3]), invariants=invariants,
                properties=rng.sample(ORBIT_SYM_PROPERTIES, rng.choice([1, 1, 2])),
                options={"blackbox": "instant"})


# ---------------------------------------------------------------------------
# moving robots
# ---------------------------------------------------------------------------

def _box(x0, y0, x1, y1) -> str:
    return f"[[obstacles]]\npolygon = [[{x0}, {y0}], [{x1}, {y0}], [{x1}, {y1}], [{x0}, {y1}]]\n"


def moving(seed: int, rng: random.Random, family="moving") -> Case:
    agents = rng.choice([1, 1, 2])
    radius = rng.choice([0.1, 0.25])
    res = rng.choice([0.01, 0.05, 0.25, 0.5])
    speed = rng.choice([0.7, 1.0, 1.5])
    starts = [[0, 0], [0, 3]][:agents]
    wall_y = rng.choice([-1, -0.5, 0.5])
    # near-tangent: the wall's edge at the robot's path +- a radius, give or take an epsilon
    gap = rng.choice([0.0, radius, radius - 1e-9, radius + 1e-9, 0.3, 1.0])
    obstacles = _box(3, wall_y if wall_y < 0 else gap, 4, (wall_y if wall_y > 0 else 0) + 1)
    if rng.random() < 0.5:
        obstacles += "[[obstacles]]\npolygon = [[4.5, 4], [5.5, 4], [5, 6]]\n"   # a triangle
    world = (f"agents = {agents}\nresolution = {res}\nradius = {radius}\nspeed = {speed}\n"
             f"start = {starts}\n\n" + obstacles)
    targets = ["ItemPosition(6.0, 0.0)", "ItemPosition(2.0, 0.0)", "ItemPosition(5.0, 10.0)",
               "ItemPosition(3.5, 0.5)", "ItemPosition(0.95, 2.0)", "ItemPosition(6.0, 3.0)",
               f"ItemPosition({rng.choice(['1.0', '2.5', '3.0'])}, {gap + radius})",
               "ItemPosition(rand(1) * 10.0, 0.0)", "ItemPosition(x, y)"]
    handled = rng.random() < 0.6
    # nothing reads the doReach flags: the program ends by its ticks
    blind = rng.random() < (0.6 if family == "userbb" else 0.3)
    retarget = rng.random() < 0.6
    ticks = rng.choice([1, 2, 3, 5])
    turn_wall = rng.random() < 0.3
    if turn_wall:
        # a re-target in mid-motion across a wall that the leg from the last
        # rest position misses (issue 41 hole 3's shape)
        world += _box(4.5, 4, 5.5, 6)
    if random.Random(seed * 104729 + 7).random() < 0.35:
        # an open world (its own draw: the program is the seed's as before),
        # where the native engine computes the shipped blackboxes in C
        # (native_c/robots.c; obstacles are left to Python's shapely)
        world = world.split("[[obstacles]]")[0]
    text = ("Agent::Mover\n\nallwrite:\n  int failed = 0;\n  int arrived = 0;\n\n"
            "loc:\n  int st = 0;\n  int t = 0;\n"
            f"  int x = {rng.choice(['0', '1', 'rand(1)'])};\n  int y = 0;\n\n")
    first = targets[-2] if family == "userbb" and rng.random() < 0.5 else rng.choice(targets)
    if turn_wall and rng.random() < 0.7:
        first = "ItemPosition(10.0, 0.0)"
    text += (f"Go():\n  pre(st == 0);\n  eff:\n    doReach({first}, "
             f"{rng.choice(['getObs()', '[]'])});\n    st = 1;\n\n")
    text += f"Tick():\n  pre(st == 1 && t < {ticks});\n  eff:\n    t = t + 1;\n\n"
    if blind:
        text += (f"Done():\n  pre(st == 1 && t >= {ticks});\n  eff:\n    exit();\n")
        invariants = rng.sample(["failed == 0", "arrived <= 1"], rng.choice([0, 1]))
        return Case(seed, family, text, agents=None, world=world, invariants=invariants, moves=True)
    if retarget:
        cond = rng.choice([f"t == {ticks}", f"t == {ticks} && !doReach_done", "doReach_done"])
        second = "ItemPosition(5.0, 10.0)" if turn_wall else rng.choice(targets)
        text += (f"Turn():\n  pre(st == 1 && {cond});\n  eff:\n    doReach({second}, "
                 f"{rng.choice(['getObs()', '[]'])});\n    st = 2;\n\n")
        last = 2
    else:
        last = 1
    text += f"Arrived():\n  pre(st == {last} && doReach_done);\n  eff:\n"
    text += rng.choice(["    atomic:\n      arrived = arrived + 1;\n", "    arrived = arrived + 1;\n"])
    text += "    exit();\n\n"
    if handled:
        text += ("Failed():\n  pre(st >= 1 && doReach_fail);\n  eff:\n"
                 + rng.choice(["    assert(false);\n", "    failed = failed + 1;\n    exit();\n"]) + "\n")
    invariants = rng.sample(["failed == 0", "arrived <= 1", "failed <= 1",
                             "forall i: doReach_fail[i] -> st[i] >= 1", "arrived + failed <= 2"],
                            rng.choice([0, 1, 1, 2]))
    return Case(seed, family, text, agents=None, world=world, invariants=invariants, moves=True)


USER_BB = {
    "straight": '''from pccl.blackboxes.base import Outcome
from pccl.blackboxes.straight import Straight


class Retry(Straight):          # keeps the name "straight"
    def step(self, world, motions, env, time, delta):
        out = super().step(world, motions, env, time, delta)[0]
        pos = list(out.positions)
        for i, m in enumerate(motions):
            if m.fail and m.target is not None:
                z = m.position[2] if len(m.position) > 2 else 0.0
                pos[i] = (float(m.target[0]), float(m.target[1]), float(z))
        return [Outcome(tuple(pos), out.done, out.fail, None)]


BLACKBOX = Retry()
''',
    "instant": '''from pccl.blackboxes.base import Outcome
from pccl.blackboxes.instant import Instant


class Slow(Instant):            # keeps the name "instant"; a settled robot drifts
    def step(self, world, motions, env, time, delta):
        out = super().step(world, motions, env, time, delta)[0]
        pos = tuple((p[0], p[1] + (0.5 if m.done else 0.0), p[2] if len(p) > 2 else 0.0)
                    for p, m in zip(out.positions, motions))
        return [Outcome(pos, out.done, out.fail, None)]


BLACKBOX = Slow()
''',
    "nondet": '''from pccl.blackboxes.base import Outcome
from pccl.blackboxes.nondet import Nondet


class Sticky(Nondet):           # keeps the name "nondet"; a failed robot recovers
    def step(self, world, motions, env, time, delta):
        outs = super().step(world, motions, env, time, delta)
        res = []
        for o in outs:
            fail = tuple(f and not m.fail for f, m in zip(o.fail, motions))
            res.append(Outcome(o.positions, o.done, fail, None))
        return res


BLACKBOX = Sticky()
''',
}


def userbb(seed: int, rng: random.Random) -> Case:
    c = moving(seed, rng, "userbb")
    base = rng.choice(sorted(USER_BB))
    extra = ["forall i: pos[i].x < 5", "forall i: pos[i].y < 1"]
    return replace(c, blackbox=USER_BB[base], invariants=c.invariants + [rng.choice(extra)])


# ---------------------------------------------------------------------------
# the attack generators of issues 20 and 23
# ---------------------------------------------------------------------------

def _attack_module(name):
    here = str(Path(__file__).resolve().parent.parent)
    if here not in sys.path:
        sys.path.insert(0, here)
    return __import__(name)


# ---------------------------------------------------------------------------
# counters (issue 46): loc: ints that count and are compared with constants
# ---------------------------------------------------------------------------

#: what a counter is compared with: literals, a shared constant, a frozen rand
CTR_BOUNDS = ["0", "1", "2", "3", "K", "lim", "-1"]
#: statements a counter comparison guards, each with a runtime error for some
#: reachable values (division by zero, index out of range, a failed
#: assertion, an undefined read) or none
CTR_EFFECTS = ["s = (s + 1) % 4;", "s = 10 / (s - 2);", "s = arr[s];", "assert(s < 3);", "s = u;",
               "flag = !flag;", "g = true;", "s = (s + 3) % 4;"]


def _ctr_cmp(rng, name: str) -> str:
    op = rng.choice(["<", "<=", ">", ">=", "==", "!="])
    b = rng.choice(CTR_BOUNDS)
    return f"{name} {op} {b}" if rng.random() < 0.7 else f"{b} {op} {name}"


def counters(seed: int, rng: random.Random) -> Case:
    """Counters that only count towards bounds they are compared with
    (docs/reductions.md, "Counter saturation"), and counters that break the
    condition (read in arithmetic, decremented, read by a property), with
    runtime errors in the statements their comparisons guard.  Most
    programs bound their events (``c < bound``) so that the unreduced
    search is exhaustive; some tick for ever (the unreduced search is then
    bounded: only its violations are compared)."""
    bound = rng.choice([2, 3, 3])
    forever = rng.random() < 0.2
    shared = ["  int s = 0;", "  bool g = false;", f"  int K = {rng.choice(['1', '2'])};",
              "  int arr[3] = 0;"]
    loc = ["  int c = 0;", f"  int t = {rng.choice(['0', '0', '1', 'rand(2)'])};",
           f"  int v = {rng.choice(['0', '2'])};", f"  int lim = rand({rng.choice(['1', 'K'])});",
           "  int u;", "  bool flag = false;"]
    text = ("Agent::Counters\n\nallwrite:\n" + "\n".join(shared) + "\n\nallread:\n\nloc:\n"
            + "\n".join(loc) + "\n")
    breakers = ["v = v - 1;", "s = t % 2;", "v = t;", "t = t - 1;", "t = t * 2;", "arr[t] = 1;"]
    for e in range(rng.randint(1, 3)):
        guard = "true" if forever and e == 0 else f"c < {bound}"
        if rng.random() < 0.6:
            guard += f" && {_ctr_cmp(rng, rng.choice(['t', 'v']))}"
        body = [] if forever and e == 0 else ["c = c + 1;"]
        body.append(rng.choice(["t = t + 1;", "t = t + 1;", "t = t + 2;", "v = v + 1;",
                                "t = 0;", "t = lim;"]))
        for _ in range(rng.randint(1, 2)):
            r = rng.random()
            name = rng.choice(["t", "v"])
            if r < 0.55:
                eff = rng.choice(CTR_EFFECTS)
                br = (f"if ({_ctr_cmp(rng, name)}):\n      {eff}" +
                      (f"\n    else:\n      {rng.choice(CTR_EFFECTS)}" if rng.random() < 0.3 else ""))
                body.append(br)
            elif r < 0.7:
                body.append(f"if ({_ctr_cmp(rng, name)}):\n      atomic:\n        {rng.choice(CTR_EFFECTS)}")
            elif r < 0.8:
                body.append(rng.choice(breakers))
            elif r < 0.9:
                body.append(f"if ({name} < {rng.choice(['2', 'K'])}):\n      {name} = {name} + 1;")
            else:
                body.append(f"assert({_ctr_cmp(rng, name)} || c < {bound});")
        text += f"\nE{e}():\n  pre({guard});\n  eff:\n" + "".join(f"    {b}\n" for b in body)
    if rng.random() < 0.85:
        text += f"\nDone():\n  pre(c >= {bound});\n  eff:\n    exit();\n"
    invariants = [rng.choice(["s < 3", "count(flag) <= 1", "!g", "s != -2", "forall i: c[i] <= 3",
                              "forall i: t[i] < 4"])
                  for _ in range(rng.choice([0, 1, 1, 2]))]
    return Case(seed, "counters", text, agents=rng.choice([1, 2, 2, 3]), invariants=invariants)


def sym(seed: int, rng: random.Random) -> Case:
    text, invariants, agents = _attack_module("symattack").program(seed)
    return Case(seed, "sym", text, agents=agents, invariants=invariants,
                options={"blackbox": "instant"})


def por(seed: int, rng: random.Random) -> Case:
    text, invariants, agents, options = _attack_module("porattack").program(seed)
    return Case(seed, "por", text, agents=agents, invariants=invariants, options=options)


# ---------------------------------------------------------------------------
# Koord programs (issue 47; docs/koord.md)
# ---------------------------------------------------------------------------

#: Koord int expressions: variables of every section, list methods, allread
#: reads (own entry, another robot's), function calls
K_INT = ["0", "1", "2", "s", "x", "y", "c", "q.size()", "me[pid]", "(numAgents - 1)", "(y % 3)"]
K_ID = ["pid", "(pid + 1)", "me[0]", "(x * pid)", "(numAgents - pid)"]
#: Koord int expressions that fail for some reachable values: division and
#: modulo by zero, a list index, an allread entry of a robot that does not
#: exist, head of an empty list, a negative rand bound, an undefined read
K_ERR_INT = ["(10 / (x - 1))", "(s % (y - 1))", "q[x]", "me[x + 1]", "l.head()", "rand(x - 1)", "u",
             "q[q.size() - x]", "(l.head() + 1)", "rand(y - 1)"]
K_BOOL = ["g", "not g", "flag[pid]", "not flag[pid]", "q.isEmpty()", "q.contains(x)", "x <= s",
          "h < 2.0", "p.x > 0.5", "owner == me[pid]", "owner != -1", "l.isEmpty()"]
K_ASYM_BOOL = ["pid == 0", "me[0] == 0", "pid < 1", "(pid + 1) % 2 == 0", "owner == 1"]
K_ERR_BOOL = ["10 / (x - 1) > 0", "q[x] == 1", "l.head() > 0", "u == 0", "h * 1e308 * 10.0 > 1.0",
              "flag[y + 2]", "q.head() == l.head()", "rand(x - 1) == 0"]
#: the functions a program may define: (definition, expression calls, statement calls)
K_FUNS = {
    "half": ("def fun half(int v):\n  return v / 2\n", ["half(x)", "half(y + 1)", "half(c)"], []),
    "ratio": ("def fun ratio(int v):\n  return 10 / (v - 1)\n", ["ratio(x)", "ratio(c + 1)"], []),
    "bump": ("def fun bump(int v):\n  s = s + v\n  stdout << \"bump \" << v\n", [],
             ["bump(x)", "bump(1)", "bump(pid)"]),
    "mark": ("def fun mark(boolean b):\n  flag[pid] = b\n  if b:\n    owner = pid\n", [],
             ["mark(true)", "mark(x > 0)", "mark(not g)"]),
    "push": ("def fun push(int v):\n  atomic:\n    q.add(v)\n    s = s + 1\n", [],
             ["push(x)", "push(c)"]),
}
K_INVARIANTS = ["s < 3", "s != 2", "forall i: c[i] <= 3", "count(flag) <= 1", "exists i: x[i] == 0",
                "forall i: x[i] < 2 or y[i] > 0", "q.size() < 3", "not q.contains(2)",
                "forall i: forall j: flag[i] and flag[j] -> i == j", "owner != 1",
                "forall i: me[i] == i", "forall i: h[i] < 100.0", "forall i: 10 / (x[i] - 1) > -100",
                "forall i: exited[i] -> c[i] > 0"]
#: the same, for --invariant (PCCL's property syntax over the program read)
K_CLI_INVARIANTS = ["s < 3", "forall i: c[i] <= 3", "count(flag) <= 1", "size(q) < 4",
                    "forall i: running[i] || exited[i]", "forall i: exited[i] -> c[i] > 0",
                    "forall i: me[i] == i", "!contains(q, 2)", "forall i: 10 / (x[i] - 1) > -100"]
K_PROPERTIES = ["eventually (forall i: exited[i])", "g ~> s > 0", "reachable s == 2",
                "reachable count(flag) == 2", "s == 1 ~> s != 1 within 2",
                "forall i: flag[i] ~> c[i] >= 2"]


def _k_int(rng, ks, depth=1, err=None) -> str:
    err = ks["err"] if err is None else err
    r = rng.random()
    if r < err:
        return rng.choice(K_ERR_INT)
    if r < err + ks["asym"] / 2:
        return rng.choice(K_ID)
    if r < err + ks["asym"] / 2 + 0.08 and ks["expr_funs"]:
        return rng.choice(ks["expr_funs"])
    if depth <= 0 or r < 0.55:
        return rng.choice(K_INT + (["rc.n", "rw.n"] if ks.get("rec") else []))
    op = rng.choice(["+", "-", "*", "/", "%"])
    a, b = _k_int(rng, ks, depth - 1, err / 2), _k_int(rng, ks, depth - 1, err / 2)
    if op in "/%" and rng.random() < 0.8:
        b = rng.choice(["2", "3", "(1 + c)"])
    return f"({a} {op} {b})"


def _k_bool(rng, ks, err=None) -> str:
    err = ks["err"] if err is None else err
    r = rng.random()
    if r < err:
        return rng.choice(K_ERR_BOOL)
    if r < err + ks["asym"]:
        return rng.choice(K_ASYM_BOOL)
    if r < err + ks["asym"] + 0.3:
        return rng.choice(K_BOOL + (["rc.ok", "rw.ok or rc.n > 0"] if ks.get("rec") else []))
    if r < err + ks["asym"] + 0.4:
        return f"{_k_bool(rng, ks, 0.0)} {rng.choice(['and', 'or', '&&', '||'])} {_k_bool(rng, ks, 0.0)}"
    cmp = rng.choice(["==", "!=", "<", "<=", ">", ">="])
    return f"{_k_int(rng, ks, 1, 0.0)} {cmp} {_k_int(rng, ks, 0, 0.0)}"


def _k_stmt(rng, ks, ind: int, depth: int, ctx: dict) -> str:
    pad = "  " * ind
    kinds = ["assign", "assign", "shared", "shared", "flag", "list", "float", "pos", "log", "skip",
             "owner", "assert"]
    if ks["stmt_funs"] and not ctx.get("in_for"):
        kinds += ["call"]
    if ks["ar"]:
        kinds += ["ar"]
    if ks.get("rec"):
        kinds += ["rec", "rec"]
    if depth > 0:
        kinds += ["if", "if", "atomic", "for"]
    if not ctx.get("in_atomic") and rng.random() < 0.12:
        kinds += ["stop"]
    k = rng.choice(kinds)
    if k == "assign":
        return f"{pad}{rng.choice(['x', 'y'] if not ctx.get('in_for') else ['y'])} = {_k_int(rng, ks, 2)}\n"
    if k == "shared":
        return f"{pad}s = {_k_int(rng, ks, 2)}\n"
    if k == "flag":
        return f"{pad}flag[pid] = {_k_bool(rng, ks)}\n"
    if k == "ar":
        return f"{pad}ar[pid] = {_k_int(rng, ks, 1)}\n"
    if k == "rec":
        # a record's fields, a whole-record copy, the shared record
        return pad + rng.choice([f"rc.n = {_k_int(rng, ks, 1)}", f"rc.ok = {_k_bool(rng, ks)}",
                                 "rc = rc0", "rw.n = rc.n + 1", "rw.ok = not rw.ok"]) + "\n"
    if k == "owner":
        odd = ["x", "pid + 1"] if rng.random() < ks["asym"] else []
        return f"{pad}owner = {rng.choice(['pid', '-1', 'me[pid]'] + (['me[owner]'] if ks['err'] else []) + odd)}\n"
    if k == "list":
        return pad + rng.choice(["q.add(y)", "q.remove(y)", "l.add(1)", "q.append(c)",
                                 "l.remove(1)" if ks["err"] else "l.add(2)"]) + "\n"
    if k == "float":
        big = ["h * 1e308"] if ks["err"] else []
        return f"{pad}h = {rng.choice(['h * 2.0', 'h + 0.5', 'h / 3.0', 'h - x', '1.5', 'p.y'] + big)}\n"
    if k == "pos":
        return pad + rng.choice(["p = pos(x, 1.5)", "p = (h, 2.5)", "p = midpoint(p, pos(0, 0))",
                                 "p = pos3d(1, y, 0)"]) + "\n"
    if k == "log":
        return f"{pad}stdout << \"s \" << s << {_k_int(rng, ks, 0, 0.0)}\n"
    if k == "skip":
        return f"{pad}skip\n"
    if k == "stop":
        return f"{pad}stop\n"
    if k == "assert":
        return f"{pad}assert({_k_bool(rng, ks) if ks['err'] else rng.choice(['c >= 1', 'c > 0 or x != 0'])})\n"
    if k == "call":
        calls = [c for c in ks["stmt_funs"] if not (ctx.get("in_atomic") and c.startswith("push"))]
        return f"{pad}{rng.choice(calls or ['skip'])}\n"
    if k == "if":
        body = "".join(_k_stmt(rng, ks, ind + 1, depth - 1, ctx) for _ in range(rng.randint(1, 2)))
        out = f"{pad}if {_k_bool(rng, ks)}:\n{body}"
        if rng.random() < 0.3:
            out += f"{pad}{rng.choice(['elif', 'else if'])} {_k_bool(rng, ks)}:\n" \
                   + _k_stmt(rng, ks, ind + 1, depth - 1, ctx)
        if rng.random() < 0.4:
            out += f"{pad}else:\n" + _k_stmt(rng, ks, ind + 1, depth - 1, ctx)
        return out
    if k == "atomic":
        sub = dict(ctx, in_atomic=True)
        body = "".join(_k_stmt(rng, ks, ind + 1, depth - 1, sub) for _ in range(rng.randint(1, 2)))
        return f"{pad}atomic:\n{body}"
    # for: over a range whose bounds the block does not change (the block
    # writes neither i nor x)
    sub = dict(ctx, in_for=True)
    bounds = rng.choice(["2", "0, 2", "1, 3", "x % 3", "c"] + (["10 / (x - 1)"] if ks["err"] else []))
    body = "".join(_k_stmt(rng, ks, ind + 1, 0, sub) for _ in range(rng.randint(1, 2)))
    return f"{pad}for i in range({bounds}):\n{body}"


K_SHARED_INITS = ["0", "1", "2", "rand(1)", "-1", "rand(2) - 1"]
K_LOC_INITS = ["0", "1", "rand(1)", "rand(2)", "numAgents - 1", "s + 1", "q0[rand(1)]"]
K_ERR_LOC_INITS = ["10 / (rand(2) - 2)", "[7, 8][rand(2)]", "q0[rand(2)]", "rand(rand(2) - 1)"]


def _k_motion(seed: int, rng: random.Random, ks: dict) -> tuple:
    """A moving Koord program: Motion.target legs, Motion.reached, a world."""
    base = moving(seed, rng, "moving")
    targets = ["pos(6.0, 0.0)", "pos(2.0, 0.0)", "(3.5, 0.5)", "pos(0.95, 2.0)", "(x, y)",
               "midpoint(Motion.position, pos(4.0, 0.0))", "pos(rand(1) * 10.0, 0.0)"]
    legs = rng.choice([1, 2])
    text = ("using Motion:\n  sensors:\n    pos position\n    boolean reached\n"
            "  actuators:\n    pos target\n\n"
            "allwrite:\n  int arrived = 0\n\nlocal:\n  int st = 0\n  int t = 0\n"
            f"  int x = {rng.choice(['0', '1', 'rand(1)'])}\n  int y = 0\n  pos at = pos(0, 0)\n\n")
    text += (f"Go:\n  pre: st < {legs} and (st == 0 or Motion.reached)\n  eff:\n"
             f"    Motion.target = {rng.choice(targets)}\n    st = st + 1\n\n")
    text += f"Tick:\n  pre: st >= 1 and t < {rng.choice([1, 2, 3])}\n  eff:\n    t = t + 1\n" \
            f"    at = Motion.position\n\n"
    text += (f"Arrive:\n  pre: st == {legs} and Motion.reached\n  eff:\n"
             + rng.choice(["    atomic:\n      arrived = arrived + 1\n", "    arrived = arrived + 1\n"])
             + "    stop\n")
    invariants = rng.sample(["arrived <= 1", "forall i: st[i] <= 2", "arrived <= N"], rng.choice([0, 1]))
    return text, base.world, invariants


#: Koord's lists and records (docs/koord.md, "Records"): nested records, an
#: array and a list of records, record literals, ``for x in xs:`` over a
#: list of ints and of records, ``any``/``all``; drawn by a generator of
#: their own (:func:`_k_lists`), so that the rest of each program is as
#: before
K_RECORD_DEFS = "def Pt:\n  int a = 0\n  int b = {b}\n\ndef Box:\n  Pt at\n  boolean on = false\n\n"
K_LIST_LOCALS = ("  Box[] bl = [Box(Pt(1, 0))]\n  Box bs[2]\n  Box b\n  boolean[] fl = [false]\n"
                 "  int v = 0\n")
K_LIST_STMTS = ["for v in q:\n{p}  y = y + v", "for v in q:\n{p}  s = s + v",
                "for b in bl:\n{p}  y = y + b.at.a\n{p}  b.on = not b.on",
                "bl.add(Box(Pt(x, c), g))", "bl = [Box(Pt(y, 1)), Box()]", "bs[c % 2] = Box(Pt(y, c))",
                "bs[0].at.b = bs[1].at.a + 1", "b = bs[1]", "b = bl.head()", "fl.add(x > 0)",
                "fl = [g, flag[pid]]", "if any(fl):\n{p}  y = y + 1",
                "if all(fl):\n{p}  s = s + 1\n{p}else:\n{p}  ab[pid].on = true",
                "ab[pid] = b", "ab[pid].at.a = c", "atomic:\n{p}  for v in q:\n{p}    s = s + v"]
K_PICK_EVENTS = ("\nPickA:\n  pre: k == 0\n  eff:\n    pk[pid] = true\n    k = 1\n"
                 "\nPickB:\n  pre: k == 0\n  eff:\n    k = 1\n"
                 "\nCheck:\n  pre: k == 1\n  eff:\n    k = 2\n    if pid == 0 and numAgents > 1:\n"
                 "      assert(not (pk[0] and not pk[1]))\n")
K_LIST_ERR_STMTS = ["y = bs[x].at.a", "b = bl[x + 1]"]
K_LIST_GUARDS = ["", " and any(fl)", " and not all(fl)", " and bl.size() < 3", " and not bs[0].on"]
K_LIST_INVARIANTS = ["forall i: bl[i].size() >= 1", "forall i: not bs[i][0].on or bs[i][0].at.b >= 0",
                     "forall i: ab[i].at.a <= 2", "forall i: y[i] < 6", "forall i: not ab[i].on"]


def _k_lists(seed: int, err: float) -> Optional[dict]:
    """The pieces of a program's lists and records, or None (most programs
    have none): its own generator, keyed by the seed."""
    rng = random.Random(seed * 7_919 + 47)
    if rng.random() >= 0.4:
        return None
    stmts = K_LIST_STMTS + (K_LIST_ERR_STMTS if err else [])
    body = "".join("    " + rng.choice(stmts).format(p="    ") + "\n" for _ in range(rng.randint(1, 3)))
    out = {"defs": K_RECORD_DEFS.format(b=rng.choice(["0", "rand(1)"])),
           "allread": "  Box ab[]\n", "local": K_LIST_LOCALS,
           "guard": rng.choice(K_LIST_GUARDS), "body": body,
           "invariant": rng.choice(K_LIST_INVARIANTS) if rng.random() < 0.5 else None,
           "events": ""}
    if rng.random() < 0.3:
        # robots pick one of two events; robot 0 then asserts on the pair
        # of picks, which tells (A, B) from its mirror (B, A): an asymmetric
        # program that the default must explore as the truth does
        out["allread"] += "  boolean pk[] = false\n"
        out["local"] += "  int k = 0\n"
        out["events"] = K_PICK_EVENTS
    return out


def koord(seed: int, rng: random.Random) -> Case:
    """A Koord program (docs/koord.md's constructs) under Koord's round
    semantics, with its options drawn: ``--events first`` (the deployed
    runtime), ``--skip-events`` (SkipEvent), or ``--semantics pccl`` (the
    program read, under PCCL's rules: then every reduction and the native
    engine apply)."""
    options = rng.choice([{}, {}, {}, {"events": "first"}, {"skip_events": True},
                          {"semantics": "pccl"}])
    ks = {"err": rng.choice([0.0, 0.0, 0.06, 0.15]), "asym": rng.choice([0.0, 0.0, 0.0, 0.1]),
          "ar": rng.random() < 0.3}
    if rng.random() < 0.2:
        text, world, invariants = _k_motion(seed, rng, ks)
        return Case(seed, "koord", text, agents=None, world=world, invariants=invariants,
                    moves=True, options=options, lang="koord")
    funs = rng.sample(sorted(K_FUNS), rng.choice([0, 0, 1, 2, 3]))
    if not ks["err"]:
        funs = [f for f in funs if f != "ratio"]
    ks["expr_funs"] = [c for f in funs for c in K_FUNS[f][1]]
    ks["stmt_funs"] = [c for f in funs for c in K_FUNS[f][2]]
    bound = rng.choice([1, 2, 2])
    text = "".join(K_FUNS[f][0] + "\n" for f in funs)
    ks["rec"] = rng.random() < 0.3
    if ks["rec"]:
        text += ("def Rec:\n  int n = " + rng.choice(["0", "1", "rand(2)"])
                 + "\n  boolean ok = false\n\n")
    kl = _k_lists(seed, ks["err"])
    if kl:
        text += kl["defs"]
    if rng.random() < 0.15:
        text += "using Log:\n  actuators:\n    stream stdout\n\n"
    shared_init = rng.choice(K_SHARED_INITS
                             + (["10 / (rand(1) - 1)"] if ks["err"] and rng.random() < 0.15 else []))
    text += (f"allwrite:\n  int s = {shared_init}\n  boolean g = false\n"
             f"  list<int> q = {rng.choice(['[]', '[1]', '[1, 2]'])}\n  list<int> q0 = [7, 8]\n"
             f"  int owner = {rng.choice(['-1', '-1', '0'])}\n"
             + ("  Rec rw\n" if ks["rec"] else "") + "\n")
    text += "allread:\n  int me[] = pid\n  boolean flag[] = false\n"
    if ks["ar"]:
        ar_inits = ["0", "rand(1)", "s + 1"] + (["10 / (rand(1) - 1)"] if ks["err"] else [])
        text += f"  int ar[] = {rng.choice(ar_inits)}\n"
    if kl:
        text += kl["allread"]
    loc_init = rng.choice(K_LOC_INITS + (K_ERR_LOC_INITS if ks["err"] else [])
                          + (["pid", "pid + 1"] if ks["asym"] else []))
    text += (f"\nlocal:\n  int c = 0\n  int x = {loc_init}\n"
             f"  int y = {rng.choice(['0', '1', 'x', 'rand(1)'])}; int i = 0\n"
             f"  float h = {rng.choice(['1.5', '0.5', '1e300'])}\n  pos p = pos(1, 2)\n"
             "  list<int> l = []\n  int u\n" + ("  Rec rc\n  Rec rc0\n" if ks["rec"] else "")
             + (kl["local"] if kl else ""))
    if rng.random() < 0.4:
        text += "\ninit:\n" + "".join(_k_stmt(rng, ks, 1, 1, {"in_atomic": True})
                                      for _ in range(rng.randint(1, 2)))
    for e in range(rng.randint(1, 3)):
        guard = f"c < {bound}"
        if rng.random() < 0.6:
            guard += f" and {_k_bool(rng, ks)}"
        body = "".join(_k_stmt(rng, ks, 2, 2, {}) for _ in range(rng.randint(1, 3)))
        text += f"\nE{e}:\n  pre: {guard}\n  eff:\n    c = c + 1\n{body}"
    if ks["err"] and rng.random() < 0.5:
        # one more event with a runtime error behind a condition
        bad = rng.choice(["y = l.head()", "y = rand(x - 2)", "h = h * 1e308", "q.remove(5)",
                          "y = q[q.size()]", "atomic:\n        y = 10 / (x - x)"])
        text += (f"\nRisk:\n  pre: c < {bound}\n  eff:\n    c = c + 1\n"
                 f"    if {rng.choice(['x >= 0', 'x > 0', 'not g', 'y != 1'])}:\n      {bad}\n")
    if kl:
        text += f"\nL0:\n  pre: c < {bound}{kl['guard']}\n  eff:\n    c = c + 1\n{kl['body']}"
        text += kl["events"]
    if rng.random() < 0.85:
        text += f"\nDone:\n  pre: c >= {bound}\n  eff:\n    stop\n"
    inv_section = rng.random() < 0.4
    if inv_section:
        text += "\ninvariant:\n" + "".join(f"  inv{k}: {rng.choice(K_INVARIANTS)}\n"
                                          for k in range(rng.randint(1, 2)))
    if kl and kl["invariant"]:
        text += ("" if inv_section else "\ninvariant:\n") + f"  invL: {kl['invariant']}\n"
    invariants = [rng.choice(K_CLI_INVARIANTS) for _ in range(rng.choice([0, 0, 1, 2]))]
    properties = [rng.choice(K_PROPERTIES)] if rng.random() < 0.2 else []
    return Case(seed, "koord", text, agents=rng.choice([1, 2, 2, 2, 3]), invariants=invariants,
                properties=properties, options=options, lang="koord")


FAMILIES = {"core": (core, 10), "moving": (moving, 3), "userbb": (userbb, 1), "sym": (sym, 2),
            "por": (por, 2), "koord": (koord, 4)}


#: ``counters`` is not in the weighted draw: it takes this share of the
#: ``core`` draws (decided by a generator of its own, so that the other
#: seeds keep their programs), or every draw when it is the only family asked for
COUNTERS_SHARE = 0.2


#: ``orbit`` likewise: this share of the remaining ``core`` draws
ORBIT_SHARE = 0.15


def case(seed: int, families=None) -> Case:
    """The program of ``seed`` (deterministic)."""
    rng = random.Random(seed * 7919 + 41)
    names = [n for n in FAMILIES if families is None or n in families]
    want_ctr = families is None or "counters" in families
    want_orbit = families is None or "orbit" in families
    if not names:
        return counters(seed, rng) if want_ctr else orbit(seed, rng)
    fam = rng.choices(names, weights=[FAMILIES[n][1] for n in names])[0]
    if fam == "core" and want_ctr and random.Random(seed * 104729 + 7).random() < COUNTERS_SHARE:
        return counters(seed, rng)
    if fam == "core" and want_orbit and random.Random(seed * 130363 + 11).random() < ORBIT_SHARE:
        return orbit(seed, rng)
    return FAMILIES[fam][0](seed, rng)
