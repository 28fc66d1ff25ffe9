"""The frozen-team check's cost per search: over the search's own graph
(today) against exploring the reduced model again in Python (before;
``PCCL_FROZEN_GRAPH=0`` still runs that path, as ``--workers N`` processes
do), in one run (docs/reductions.md, "Frozen teams").

    python benchmarks/frozen.py                 # the programs below, 3 rounds each
    python benchmarks/frozen.py --rounds 5 --limit 10000000
    python benchmarks/frozen.py --only --pytest tests/model/test_stall.py tests/model/test_shorten.py

For each program it explores through the API (default options, the stall
check on) with the check over the graph and with the re-exploration, the
rounds interleaved, and prints the best CPU seconds of this process for
each, their difference and whether the verdicts agree.  The
re-exploration stops at ``LIMIT`` states (20,000; ``--limit`` raises it,
to time what a check of every state would cost it): above that it says
"frozen teams not checked", so the verdicts of the larger programs differ
unless ``--limit`` covers them.  The native modules are built before the
timed rounds (a compile is not the check's).  ``--pytest PATHS`` also runs
``python -m pytest -q -n 0 PATHS`` once each way, in a child process, and
prints the children's CPU seconds.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

PROGRAMS = [
    ("patrol pillar (frozen)", "tests/programs/patrol.pccl",
     dict(world="tests/programs/patrol_pillar.toml", blackbox="straight")),
    ("patrol open", "tests/programs/patrol.pccl",
     dict(world="tests/programs/patrol.toml", blackbox="straight")),
    ("leader", "programs/leader.pccl", {}),
    ("race_robust", "programs/race_robust.pccl",
     dict(world="programs/race.toml", blackbox="straight")),
    ("eng_lock", "tests/programs/eng_lock.pccl", {}),
    ("fischer k=1", "programs/fischer.pccl", dict(overrides={"k": "1"})),
    ("fischer k=2", "programs/fischer.pccl", dict(overrides={"k": "2"})),
    ("fischer k=2 unreduced", "programs/fischer.pccl", dict(overrides={"k": "2"}, reduce="none")),
]


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def one(program: str, kw: dict, graph: bool, limit: int) -> tuple:
    from pccl.api import explore
    from pccl.model import frozen as F
    F.LIMIT = limit
    if graph:
        os.environ.pop("PCCL_FROZEN_GRAPH", None)
    else:
        os.environ["PCCL_FROZEN_GRAPH"] = "0"
    c = _cpu()
    res = explore(str(ROOT / program), **{k: str(ROOT / v) if k == "world" else v
                                          for k, v in kw.items()})
    return _cpu() - c, res


def pytest_cpu(paths: list, graph: bool) -> tuple:
    env = dict(os.environ)
    if graph:
        env.pop("PCCL_FROZEN_GRAPH", None)
    else:
        env["PCCL_FROZEN_GRAPH"] = "0"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    w = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider",
                        *paths], cwd=ROOT, env=env, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    tail = p.stdout.strip().splitlines()[-1] if p.stdout.strip() else p.stderr[-200:]
    return cpu, time.perf_counter() - w, tail


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--limit", type=int, default=20_000,
                    help="the re-exploration's state limit (default: the product's)")
    ap.add_argument("--pytest", nargs="*", default=None, metavar="PATH")
    ap.add_argument("--only", nargs="*", default=None, help="substrings of the programs' names "
                    "(none: the --pytest part only)")
    a = ap.parse_args()
    print(f"{'program':24} {'states':>8} {'graph s':>8} {'again s':>8} {'saved s':>8}  verdicts")
    for name, program, kw in PROGRAMS:
        if a.only is not None and not any(x in name for x in a.only):
            continue
        one(program, kw, True, a.limit)         # (the native module built)
        best = {True: float("inf"), False: float("inf")}
        out = {}
        for _ in range(a.rounds):
            for graph in (True, False):
                t, res = one(program, kw, graph, a.limit)
                best[graph] = min(best[graph], t)
                out[graph] = res
        same = ("same" if (out[True].verdict, out[True].notes) == (out[False].verdict, out[False].notes)
                else "differ: " + "; ".join(n for n in out[False].notes if "frozen" in n))
        print(f"{name:24} {out[True].stats.states:>8,} {best[True]:8.2f} {best[False]:8.2f} "
              f"{best[False] - best[True]:8.2f}  {same}", flush=True)
    if a.pytest:
        for graph in (True, False):
            cpu, wall, tail = pytest_cpu(a.pytest, graph)
            print(f"pytest {' '.join(a.pytest)} ({'graph' if graph else 'explored again'}): "
                  f"{cpu:.1f} CPU s, {wall:.1f} s wall: {tail}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
