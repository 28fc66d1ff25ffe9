"""Liveness under the reductions (issue 46): old against new in one run.

    python benchmarks/liveness.py              # race_robust, 3 robots
    python benchmarks/liveness.py --full       # also 4 robots (new only: old is out of reach)
    python benchmarks/liveness.py --repeat 3   # medians of 3 alternating runs

"old" is what a liveness search ran before issue 46: statement merging
alone (``--reduce merge``: symmetry, dead and por were off for a liveness
property); "new" is the default (``--reduce auto``: merge, symmetry, por
and dead where sound).  Both run on this checkout, each in its own process
(peak memory is the case's own), alternating so that load on a shared
machine hits both alike; the table shows the median by CPU time.  It
prints ``uptime`` before and after: wall seconds on a loaded machine are
up to several times the CPU seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

PROP = "eventually forall i: exited[i]"
CASES = [
    ("race_robust, nondet, 3 robots", dict(program="programs/race_robust.pccl",
                                            world="programs/race.toml", agents=3,
                                            blackbox="nondet", properties=[PROP]), False),
    ("race_robust, nondet, 4 robots", dict(program="programs/race_robust.pccl",
                                            world="programs/race.toml", agents=4,
                                            blackbox="nondet", properties=[PROP]), True),
]

CHILD = r"""
import json, resource, sys, time
from pccl import api
spec = json.loads(sys.argv[1])
prog = spec.pop("program")
t0, c0 = time.perf_counter(), time.process_time()
r = api.explore(prog, **spec)
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps(dict(status=r.status, verdict=r.verdict.splitlines()[0][:100],
                      states=r.stats.states, transitions=r.stats.transitions, wall=wall, cpu=cpu,
                      peak_mib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)))
"""


def run_case(spec: dict, reduce: str, timeout: float) -> dict:
    spec = dict(spec, reduce=reduce)
    try:
        p = subprocess.run([sys.executable, "-c", CHILD, json.dumps(spec)], cwd=ROOT,
                           capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return dict(status=f"not finished in {timeout:.0f} s")
    if p.returncode != 0:
        return dict(status="error: " + p.stderr.strip().splitlines()[-1][:200])
    return json.loads(p.stdout.strip().splitlines()[-1])


def uptime() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return "(uptime not available)"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="also the 4-robot case (new only)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per run")
    a = ap.parse_args(argv)
    print("uptime before:", uptime())
    print(f"{'case':32} {'code':4} {'reductions':24} {'states':>10} {'transitions':>12} "
          f"{'CPU s':>7} {'wall s':>7} {'MiB':>6}  verdict")
    for name, spec, full in CASES:
        if full and not a.full:
            continue
        rows: dict = {"old": [], "new": []}
        for _ in range(a.repeat):
            for code, red in (("old", "merge"), ("new", "auto")):
                if full and code == "old":
                    continue
                rows[code].append(run_case(spec, red, a.timeout))
        for code, red in (("old", "merge"), ("new", "auto")):
            rs = [r for r in rows[code] if "cpu" in r]
            if not rows[code]:
                continue
            if not rs:
                print(f"{name:32} {code:4} {red:24} {rows[code][0]['status']}")
                continue
            r = sorted(rs, key=lambda x: x["cpu"])[len(rs) // 2]
            print(f"{name:32} {code:4} {red:24} {r['states']:>10,} {r['transitions']:>12,} "
                  f"{r['cpu']:>7.1f} {r['wall']:>7.1f} {r['peak_mib']:>6.0f}  {r['verdict']}")
        old = [r for r in rows["old"] if "cpu" in r]
        new = [r for r in rows["new"] if "cpu" in r]
        if old and new:
            o = statistics.median(r["cpu"] for r in old)
            n = statistics.median(r["cpu"] for r in new)
            print(f"{'':32} new/old: {n / o:.2f} of the CPU time, "
                  f"{new[0]['states'] / old[0]['states']:.3f} of the states")
    print("uptime after: ", uptime())
    return 0


if __name__ == "__main__":
    sys.exit(main())
