"""Liveness under the reductions, attacked with generated programs (issue 46).

The programs of tests/symattack.py (agent ids in every place one can live,
symmetric and asymmetric uses), tests/porattack.py (shared variables,
atomics, locks, several blackboxes, n0 2) and symattack's movers
(``doReach`` under ``nondet``, ``straight``, ``instant``), each given one or
two liveness properties from a pool (symmetric ones, which keep symmetry
on, and per-agent ones).  :func:`check` explores each program with
``--reduce none --engine python`` and under every combination of the
reductions its analysis allows (``auto``, ``symmetry``, ``dead``, ``por``,
``merge,por``, ``merge,symmetry,por,dead``), and compares the verdict:
the status, the distinct violations and the properties that hold.  Every
lasso found under a reduction must be a run of the unreduced rules that
comes back to its own first state (tests/search/test_liveness_reduced.py's
``real_lasso``).

``python tests/liveattack.py FIRST N`` runs seeds FIRST.. and prints the
figures (docs/reductions.md quotes them); ``python tests/liveattack.py FIRST
N engines`` compares the native engine with the Python engine instead
(:func:`check_engines`, issue 46: docs/temporal.md quotes it).
"""

from __future__ import annotations

import pathlib
import random
import sys
import tempfile

from pccl.api import explore, make_model
from pccl.lang.errors import PcclError
from pccl.lang.parser import parse_program

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

import porattack  # noqa: E402
import symattack  # noqa: E402

#: liveness forms per family: symmetric ones first
LIVE = {
    "sym": ["eventually forall i: exited[i]", "eventually count(done) >= 1", "eventually s > 0",
            "eventually forall i: done[i]", "s == 0 ~> s > 0", "owner == -1 ~> owner != -1",
            "forall i: done[i] ~> s > 0", "eventually done[0]"],
    "por": ["eventually forall i: exited[i]", "eventually s > 0", "s == 0 ~> t > 0",
            "eventually count(flag) >= 1", "p == 0 ~> p != 0", "forall i: flag[i] ~> s > 0"],
    "moving": ["eventually forall i: exited[i]", "eventually count(arrived) >= 1",
               "eventually forall i: arrived[i]", "owner == -1 ~> owner != -1",
               "forall i: arrived[i] ~> count(arrived) == 2"],
}
COMBOS = ("auto", "symmetry", "dead", "por", "merge,por", "merge,symmetry,por,dead")
LIMIT = 5_000


def program(seed: int) -> tuple:
    """(family, text, kw) for ``seed``: the explore keywords but ``reduce``."""
    rng = random.Random(seed * 31 + 7)
    fam = rng.choice(["sym", "sym", "por", "moving"])
    props = rng.sample(LIVE[fam], rng.choice([1, 1, 2]))
    if fam == "sym":
        text, _, agents = symattack.program(seed)
        kw = dict(agents=agents, blackbox="instant")
    elif fam == "por":
        text, _, agents, options = porattack.program(seed)
        options.pop("collisions", None)
        kw = dict(agents=agents, **options)
    else:
        text, _, world, bb = symattack.moving_program(seed)
        path = pathlib.Path(tempfile.mkdtemp(prefix="liveattack-")) / "w.toml"
        path.write_text(world)
        kw = dict(world=str(path), blackbox=bb)
    return fam, text, dict(source=True, properties=props, **kw)


def verdict(res) -> tuple:
    return (res.status, frozenset((v["kind"], v["name"]) for v in res.violations),
            frozenset(res.holds))


def check(seed: int, real_lasso=None) -> dict:
    """{"invalid"|"bounded": ...} or {"family", "on": reductions of auto,
    combo: (equal verdict?, lassos real?)} for the combos the analysis
    allows."""
    fam, text, kw = program(seed)
    try:
        ast = parse_program(text, "<input>")
        plan = make_model(ast, reduce="auto", **kw).reduction
        base = explore(ast, reduce="none", engine="python", find_all=True, max_states=LIMIT, **kw)
    except PcclError as e:
        return {"invalid": str(e).splitlines()[0]}
    if base.bounds:
        return {"bounded": True}
    out: dict = {"family": fam, "on": plan.on, "base": verdict(base)}
    for combo in COMBOS:
        try:
            res = explore(ast, reduce=combo, find_all=True, **kw)
        except PcclError as e:
            if "unsound here" in str(e) or "needs two or more agents" in str(e):
                continue
            raise
        out[combo] = (verdict(res) == verdict(base),
                      real_lasso(res) if real_lasso is not None else None)
    return out


def check_engines(seed: int, real_lasso=None) -> dict:
    """The native engine against the Python engine on the program of
    ``seed`` (issue 46): {"invalid"|"bounded": ...}, or per reduction
    (``auto``, ``none``) ``(native ran?, the same verdict, states and
    transitions?, the native lassos real?)``."""
    _fam, text, kw = program(seed)
    out: dict = {}
    try:
        ast = parse_program(text, "<input>")
        for red in ("auto", "none"):
            py = explore(ast, reduce=red, engine="python", find_all=True, max_states=LIMIT,
                         shorten=False, **kw)
            if py.bounds:
                return {"bounded": True}
            nat = explore(ast, reduce=red, find_all=True, max_states=LIMIT, shorten=False, **kw)
            same = (verdict(nat) == verdict(py) and nat.stats.states == py.stats.states
                    and nat.stats.transitions == py.stats.transitions)
            out[red] = (nat.model.engine_used == "native", same,
                        real_lasso(nat) if real_lasso is not None else None)
    except PcclError as e:
        return {"invalid": str(e).splitlines()[0]}
    return out


def _main(argv) -> None:
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent / "search"))
    from test_liveness_reduced import real_lasso
    first, n = int(argv[0]), int(argv[1])
    import collections
    if len(argv) > 2 and argv[2] == "engines":
        e: collections.Counter = collections.Counter()
        for seed in range(first, first + n):
            r = check_engines(seed, real_lasso)
            for red, (native, same, real) in ((k, v) for k, v in r.items() if k in ("auto", "none")):
                e["runs"] += 1
                e["native"] += native
                e["agree" if same and real is not False else "DISAGREE"] += 1
                if not (same and real is not False):
                    print("disagreement:", seed, red, native, same, real)
        print(dict(e))
        return
    c: collections.Counter = collections.Counter()
    bad = []
    for seed in range(first, first + n):
        r = check(seed, real_lasso)
        if "invalid" in r or "bounded" in r:
            c["invalid" if "invalid" in r else "bounded"] += 1
            continue
        c["programs"] += 1
        c["family " + r["family"]] += 1
        c["violation" if r["base"][1] else "holds"] += 1
        for red in ("symmetry", "por", "dead"):
            if red in r["on"]:
                c["auto has " + red] += 1
        for combo in COMBOS:
            if combo in r:
                c["compared"] += 1
                ok, real = r[combo]
                if ok and real is not False:
                    c["agree"] += 1
                else:
                    bad.append((seed, combo, ok, real))
    print(dict(c))
    print("disagreements:", bad)


if __name__ == "__main__":
    _main(sys.argv[1:])
