"""Exploration benchmarks: states, transitions, seconds, states/s, memory.

    python benchmarks/run.py            # the fixed cases
    python benchmarks/run.py --full     # also the paper's Fischer (k=10) exhaustively

Each case runs in its own process so that peak memory is the case's own.
"bytes/state" is (peak RSS - RSS before the search) / visited states: the
whole cost of the search (visited fingerprints, parent links, frontier),
not just the table.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

CASES = [
    ("fischer k=2 d=2, exhaustive",
     dict(program="programs/fischer.pccl", overrides={"k": "2", "d": "2"})),
    ("fischer k=10 d=2 (paper), first violation",
     dict(program="programs/fischer.pccl", invariants=["count(inCs) <= 1"])),
    ("race_nonatomic, nondet, 3 agents",
     dict(program="programs/race_nonatomic.pccl", world="programs/race.toml",
          blackbox="nondet", agents=3)),
    ("race_safe, nondet, 3 agents, exhaustive",
     dict(program="programs/race_safe.pccl", world="programs/race.toml",
          blackbox="nondet", agents=3)),
]
FULL = [
    ("fischer k=10 d=2 (paper), exhaustive",
     dict(program="programs/fischer.pccl")),
]

CHILD = r"""
import json, resource, sys, time
from pccl.api import make_model, explore_model
spec = json.loads(sys.argv[1])
m = make_model(spec.pop("program"), world=spec.pop("world", None),
               blackbox=spec.pop("blackbox", None), agents=spec.pop("agents", None),
               overrides=spec.pop("overrides", None),
               invariants=tuple(spec.pop("invariants", ())))
rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
r = explore_model(m)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
s = r.stats
print(json.dumps({"status": r.status, "states": s.states, "transitions": s.transitions,
                  "seconds": s.seconds, "sps": s.states_per_second, "peak": peak,
                  "bytes_per_state": (peak - rss0) / max(1, s.states),
                  "depth": s.max_depth}))
"""


def run_case(spec: dict) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, json.dumps(spec)], cwd=ROOT,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="include the long exhaustive k=10 case")
    ap.add_argument("--json", action="store_true", help="print JSON lines")
    args = ap.parse_args()
    cases = CASES + (FULL if args.full else [])
    hdr = f"{'case':<44} {'result':<11} {'states':>11} {'transitions':>12} {'seconds':>8} " \
          f"{'states/s':>9} {'peak MiB':>9} {'B/state':>8}"
    if not args.json:
        print(hdr)
        print("-" * len(hdr))
    for name, spec in cases:
        r = run_case(spec)
        if args.json:
            print(json.dumps({"case": name, **r}))
            continue
        print(f"{name:<44} {r['status']:<11} {r['states']:>11,} {r['transitions']:>12,} "
              f"{r['seconds']:>8.2f} {r['sps']:>9,.0f} {r['peak'] / 2**20:>9,.0f} "
              f"{r['bytes_per_state']:>8.0f}", flush=True)


if __name__ == "__main__":
    main()
