"""A generator of PCCL programs that attack partial-order reduction's
ample sets beyond agent-local steps (issue 23 item 2).

Each program has shared variables read and written by several agents,
variables touched only inside ``atomic`` (lock-protected) and, sometimes,
one outside it, guards that read shared variables or enable a write only
for some agents or some local values (the independence *almost* holds: a
second agent can still write ``s`` in the same time step), several atomics
per event (the lock queue), doReach with the doReach flags, ``exit`` inside
and outside atomics, asserts and invariants over what the steps write.
:func:`check` compares the verdict (status and the set of distinct
violations) under ``por``, ``merge,por`` and ``auto`` with
``reduce="none"``; :func:`diamonds` checks the ample sets themselves, state
by state: in every reduced state whose ample set is one agent's, every
other agent's step in every state the others can reach commutes with the
ample agent's (the diamond: independence and neither disables the other),
and the ample steps keep the violations of the state they leave.

Seeded ``random`` so that a failure names its seed: ``python
tests/porattack.py SEED`` prints the program and the verdicts.
"""

from __future__ import annotations

import random
import sys

from pccl.api import explore, make_model
from pccl.lang.errors import PcclError
from pccl.lang.parser import parse_program
from pccl.model.engine import Model
from pccl.model.layout import DISCRETE, PHASE

HEADER = """Agent::PorAttack

allwrite:
  int s = 0;
  int t = 0;
  int p = 0;
  List<int> q = [];

allread:
  bool flag = false;

loc:
  int a = {a};
  bool b = false;
  int c = 0;
  bool moving = false;

Init:
"""

#: guards: local ones, ones that read shared variables, asymmetric ones
#: (only some agents can select the event: a second writer that exists
#: only sometimes)
GUARDS = ["a < 2", "!b", "b", "a == 0", "c < 2", "s == 0", "s < 2", "t == 0", "p < 2",
          "getAgentIndex() == 1", "getAgentIndex() == 0 && c < 2", "a == 1 && s < 3",
          "!moving", "moving && doReach_done", "moving && doReach_fail", "flag[0]",
          "rand(1) == 0"]

#: statements; ``p`` and ``q`` are touched only inside atomic unless the
#: program is drawn with a leak (a read of ``p`` outside)
STMTS = [
    "a = a + 1;", "b = !b;", "c = c + 1;", "a = rand(1);",
    "s = s + 1;", "s = 0;", "t = t + a;", "a = s;", "c = t;",
    "if (s > a):\n      b = true;",
    "if (t == 0):\n      s = s + 1;\n    else:\n      c = 1;",
    "assert(s < 3);", "assert(t <= 2);",
    "atomic:\n      p = p + 1;",
    "atomic:\n      if (p > 0):\n        p = p - 1;\n      else:\n        a = 1;",
    "atomic:\n      add(q, a);\n      p = size(q);",
    "atomic:\n      if (!isEmpty(q)):\n        c = head(q);\n        remove(q, c);",
    "atomic:\n      s = s + 1;",
    "atomic:\n      t = 1;\n    atomic:\n      t = 0;",
    "flag = true;", "flag = false;",
    "moving = true;\n    doReach(ItemPosition(a, 1), getObs());",
    "moving = false;",
    "while (c < 2):\n      c = c + 1;",
    "while (s == 1 && c < 1):\n      c = c + 1;",
    "exit();",
    "atomic:\n      exit();",
]

#: a read of a protected variable outside atomic: p is then not protected
LEAKS = ["a = p;", "if (p == 1):\n      b = true;"]

INVARIANTS = ["s < 3", "t <= 1", "p < 2", "count(b) <= 1", "forall i: a[i] <= 2",
              "size(q) < 2", "forall i: !flag[i] || a[i] == 0", "forall i: c[i] < 2",
              "forall i: !doReach_fail[i]"]

WORLD = ("agents = {n}\nspeed = 1.0\nradius = 0.1\nresolution = 0.5\n"
         "start = {start}\n")


def program(seed: int) -> tuple:
    """(text, invariants, agents, options) for ``seed``."""
    rng = random.Random(seed)
    text = HEADER.format(a=rng.choice(["0", "1", "rand(1)"]))
    pool = list(STMTS) + (LEAKS if rng.random() < 0.3 else [])
    for e in range(rng.randint(2, 4)):
        guards = [rng.choice(GUARDS) for _ in range(rng.randint(1, 2))]
        body = [rng.choice(pool) for _ in range(rng.randint(1, 3))]
        text += f"\nE{e}():\n  pre({' && '.join(guards)});\n  eff:\n" + "".join(f"    {b}\n" for b in body)
    invariants = rng.sample(INVARIANTS, rng.randint(0, 2))
    agents = rng.choice([2, 2, 3])
    options = {"blackbox": rng.choice(["instant", "nondet", "straight"]),
               "n0": rng.choice([1, 1, 2]),
               "events": rng.choice(["any", "any", "first"])}
    if rng.random() < 0.2:
        options["collisions"] = True
    return text, invariants, agents, options


def verdict(res) -> tuple:
    return res.status, frozenset((v["kind"], v["name"], v["line"]) for v in res.violations)


def _kw(text, invariants, agents, options) -> dict:
    return dict(source=True, agents=agents, invariants=invariants, **options)


def check(seed: int, combos=(("por",), ("merge", "por"), "auto"), limit: int = 6000) -> dict:
    """Verdicts under ``none`` and each of ``combos``: {"invalid": why} for
    a program the checker rejects, {"bounded": True} when ``none`` is cut
    by ``limit``, else {combo: (verdict, equal?)} and "states"."""
    text, invariants, agents, options = program(seed)
    kw = _kw(text, invariants, agents, options)
    try:
        # parsed once: every search below is of this AST (what source=True
        # would parse again for each)
        text = parse_program(text, "<input>")
        base = explore(text, reduce="none", find_all=True, max_states=limit, **kw)
    except PcclError as e:
        return {"invalid": str(e)}
    if base.bounds:
        return {"bounded": True}
    out: dict = {"states": {"none": base.stats.states}}
    for combo in combos:
        res = explore(text, reduce=combo if isinstance(combo, str) else list(combo),
                      find_all=True, **kw)
        name = combo if isinstance(combo, str) else ",".join(combo)
        out[name] = (verdict(res), verdict(res) == verdict(base))
        out["states"][name] = res.stats.states
        out.setdefault("results", []).append(res)
    out["base"] = verdict(base)
    return out


def _by_label(succ) -> dict:
    out: dict = {}
    for lab, s in succ:
        out.setdefault(lab, set()).add(s)
    return out


def diamonds(seed: int, limit: int = 400, inner: int = 300) -> list:
    """Problems with the ample sets of ``por`` alone on program ``seed``
    (empty when sound): for up to ``limit`` reduced states whose ample set
    is agent i's steps, over up to ``inner`` states the other agents can
    reach from it without i, every step u of another agent and every step
    a of i commute (from t, a then u reaches exactly the states u then a
    reaches, neither disabling the other), and a keeps the violations of
    the state it leaves (C2)."""
    text, invariants, agents, options = program(seed)
    kw = _kw(text, invariants, agents, options)
    try:
        m = make_model(text, reduce="por", **kw)
    except PcclError:
        return []
    base = m.model
    succ = lambda s: Model.successors(base, s)  # noqa: E731
    viol = lambda s: {v.identity for v in Model.violations(base, s)}  # noqa: E731
    seen, todo, bad, checked = set(), list(m.init_states()), [], 0
    while todo and checked < limit and len(seen) < 20_000:
        st = todo.pop()
        red = m.successors(st)
        for _, s2 in red:
            if s2 not in seen:
                seen.add(s2)
                todo.append(s2)
        full = succ(st)
        agents_in = {lab[1] for lab, _ in red}
        if st[PHASE] != DISCRETE or len(red) == len(full) or len(agents_in) != 1:
            continue
        (i,) = agents_in
        checked += 1
        bad += _check_ample(st, i, succ, viol, inner)
        if len(bad) > 3:
            break
    return bad


def _check_ample(st, i, succ, viol, inner) -> list:
    bad: list = []
    here, todo = {st}, [st]
    while todo and len(here) < inner:
        t = todo.pop()
        out = succ(t)
        mine = _by_label([x for x in out if x[0][1] == i])
        others = _by_label([x for x in out if x[0][1] != i and x[0][1] is not None])
        if not mine:
            bad.append(f"agent {i}'s ample step is disabled by the others' steps at {t!r}")
            return bad
        vt = viol(t)
        for la, xs in mine.items():
            for x in xs:
                if not vt <= viol(x):
                    bad.append(f"ample step {la} loses violations {vt - viol(x)}")
        for lu, ys in others.items():
            for la, xs in mine.items():
                au = {z for x in xs for lab, z in succ(x) if lab == lu}
                ua = {z for y in ys for lab, z in succ(y) if lab == la}
                if au != ua or not au:
                    bad.append(f"{la} and {lu} do not commute at {t!r}")
                    return bad
            for y in ys:
                if y not in here:
                    here.add(y)
                    todo.append(y)
    return bad


def _main(argv) -> None:
    for a in argv:
        seed = int(a)
        text, invariants, agents, options = program(seed)
        print(text)
        print("invariants:", invariants, "agents:", agents, "options:", options)
        r = check(seed)
        r.pop("results", None)
        print(r)
        print("diamonds:", diamonds(seed))


if __name__ == "__main__":
    _main(sys.argv[1:])
