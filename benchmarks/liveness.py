"""Liveness at the scale of invariants (issue 46): old against new in one run.

    python benchmarks/liveness.py              # race_robust 3 robots, Fischer 3 agents
    python benchmarks/liveness.py --full       # also race_robust 4 robots (new only)
    python benchmarks/liveness.py --repeat 3   # medians of 3 alternating runs
    python benchmarks/liveness.py --no-old     # without the 2-minute "old" run
    python benchmarks/liveness.py --only fischer   # the cases whose name says fischer

Per case, the codes that run (each in its own process, so that peak memory
is the case's own, alternating so that load on a shared machine hits them
alike; the table shows the median by CPU time):

``old``
    what a liveness search ran before issue 46: statement merging alone
    (``--reduce merge``: symmetry, dead and por were off for a liveness
    property) on the Python engine;
``python``
    the reductions of issue 46 part 1 (``--reduce auto``: merge, symmetry,
    por and dead where sound) on the Python engine (the engine a temporal
    property ran on before the native one served it);
``new``
    the default: the reductions and the native engine (the graph recorded
    by the level kernel, Tarjan in C), counterexamples shortened as the CLI
    does;
``new-ns``
    the same without shortening (``--no-shorten``: the search without the
    reductions that tries to shorten a lasso is left out);
``inv``
    the case's program searched for its invariants alone (no temporal
    property): the invariant search the temporal one is compared with;
``base``, ``base-ns``, ``base-inv`` (with ``--baseline REV``)
    ``new``, ``new-ns`` and ``inv`` run by the package of git revision REV
    (old code against new in one run, benchmarks/_baseline.py).

Each case's native module is compiled (and cached) by a first short run
before any run is timed.  It prints ``uptime`` before and after: wall seconds on a loaded machine are
up to several times the CPU seconds (the CPU seconds include the level
kernel's threads).
"""

from __future__ import annotations

import argparse
import sys

from _baseline import run_explore, tree_of_revision, uptime

PROP = "eventually forall i: exited[i]"
RACE = dict(program="programs/race_robust.pccl", world="programs/race.toml", blackbox="nondet",
            properties=[PROP])
FISCHER = dict(program="programs/fischer.pccl", agents=3, overrides={"k": 2, "d": 2})
#: (name, spec, codes, only with --full)
CASES = [
    ("race_robust, nondet, 3 robots", dict(RACE, agents=3), ("old", "python", "new", "new-ns"), False),
    ("race_robust, nondet, 4 robots", dict(RACE, agents=4), ("new", "new-ns"), True),
    ("fischer k=2 d=2, 3 agents, invariant", FISCHER, ("inv",), False),
    ("fischer, count(wait) >= 1 ~> count(inCs) >= 1",
     dict(FISCHER, properties=["count(wait) >= 1 ~> count(inCs) >= 1"]), ("python", "new", "new-ns"),
     False),
    ("fischer, forall i: wait[i] ~> inCs[i]",
     dict(FISCHER, properties=["forall i: wait[i] ~> inCs[i]"]), ("python", "new", "new-ns"), False),
]
#: the options of each code
CODES = {"old": dict(reduce="merge", engine="python"), "python": dict(reduce="auto", engine="python"),
         "new": dict(reduce="auto"), "new-ns": dict(reduce="auto", shorten=False),
         "inv": dict(reduce="auto")}

#: the package of ``--baseline REV`` (its codes are ``base*``)
BASE_TREE: list = []


def run_case(spec: dict, code: str, timeout: float) -> dict:
    tree = None
    if code.startswith("base"):
        tree = BASE_TREE[0]
        code = {"base": "new", "base-ns": "new-ns", "base-inv": "inv"}[code]
    return run_explore(dict(spec, **CODES[code]), timeout, tree)


def ratios(spec: dict, med: dict, inv_cpu, base_inv_cpu) -> None:
    """The ratios of a case's medians (``med``: code -> run)."""
    if "old" in med and "new" in med:
        o, n = med["old"], med["new"]
        print(f"{'':46} new/old: {n['cpu'] / o['cpu']:.3f} of the CPU time, "
              f"{n['states'] / o['states']:.3f} of the states")
    if "python" in med and "new" in med:
        print(f"{'':46} new/python: {med['new']['cpu'] / med['python']['cpu']:.3f} of the CPU time")
    for code in ("new", "new-ns", "base", "base-ns"):
        inv = base_inv_cpu if code.startswith("base") else inv_cpu
        if inv and code in med and "properties" in spec and spec.get("program") == FISCHER["program"]:
            print(f"{'':46} {code}/invariant search: {med[code]['cpu'] / inv:.2f}x the CPU time")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="also the 4-robot case (new only)")
    ap.add_argument("--no-old", action="store_true", help="leave the old code out (2 minutes)")
    ap.add_argument("--only", help="the cases whose name contains this text")
    ap.add_argument("--codes", help="only these codes (comma-separated: old,python,new,new-ns,inv)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per run")
    ap.add_argument("--baseline", help="also run new, new-ns and inv with the package of this git "
                    "revision (codes base, base-ns, base-inv)")
    a = ap.parse_args(argv)
    if a.baseline:
        import tempfile
        tmp = tempfile.mkdtemp(prefix="pccl-liveness-base-")
        BASE_TREE[:] = [tree_of_revision(a.baseline, tmp)]
    print("uptime before:", uptime())
    print(f"{'case':46} {'code':8} {'states':>10} {'transitions':>12} "
          f"{'CPU s':>7} {'wall s':>7} {'MiB':>6}  engine, reductions; verdict")
    inv_cpu = base_inv_cpu = None
    for name, spec, codes, full in CASES:
        if (full and not a.full) or (a.only and a.only not in name and "invariant" not in name):
            continue
        if a.baseline:
            codes = codes + tuple({"new": "base", "new-ns": "base-ns", "inv": "base-inv"}[c]
                                  for c in codes if c in ("new", "new-ns", "inv"))
        codes = tuple(c for c in codes if not (a.no_old and c == "old")
                      and (not a.codes or c in a.codes.split(",")))
        if not codes:
            continue
        rows: dict = {c: [] for c in codes}
        # the native module compiled (and cached) before any run is timed
        run_case(dict(spec, max_states=1), "new", a.timeout)
        for _ in range(a.repeat):
            for code in codes:
                rows[code].append(run_case(spec, code, a.timeout))
        med: dict = {}
        for code in codes:
            rs = [r for r in rows[code] if "cpu" in r]
            if not rs:
                print(f"{name:46} {code:8} {rows[code][0]['status']}")
                continue
            r = med[code] = sorted(rs, key=lambda x: x["cpu"])[len(rs) // 2]
            print(f"{name:46} {code:8} {r['states']:>10,} {r['transitions']:>12,} "
                  f"{r['cpu']:>7.2f} {r['wall']:>7.2f} {r['peak_mib']:>6.0f}  "
                  f"{r['engine']}, {r['reductions']}; {r['verdict'][:60]}")
        if "inv" in med:
            inv_cpu = med["inv"]["cpu"]
        if "base-inv" in med:
            base_inv_cpu = med["base-inv"]["cpu"]
        ratios(spec, med, inv_cpu, base_inv_cpu)
    print("uptime after: ", uptime())
    return 0


if __name__ == "__main__":
    sys.exit(main())
