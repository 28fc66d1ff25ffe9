"""The engine's hot path, old against new: ``successors``, ``violations``
and ``key`` over one fixed list of reachable states, without the explorer.

    python benchmarks/hotpath.py [--baseline REV] [--repeat 5] [--states 150000]

Each version runs in a fresh process (the old one from ``git archive REV``,
as benchmarks/run.py does) on fischer k = 2 d = 2, unreduced: it collects
the first ``--states`` states breadth-first, then times each function over
all of them five times and keeps the fastest (CPU seconds).  The versions
alternate ``--repeat`` times; the table shows the medians and every figure.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from run import ROOT, checkout  # noqa: E402

CHILD = r"""
import gc, json, os, sys, time
code = os.environ.get("PCCL_BENCH_CODE")
if code:   # import that tree, not the (editable) install
    sys.path.insert(0, code)
    sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in type(f).__module__]
from pccl.api import make_model
m = make_model("programs/fischer.pccl", overrides={"k": "2", "d": "2"}, reduce="none")
limit = int(sys.argv[1])
states, seen, frontier = [], set(), list(m.init_states())
while frontier and len(states) < limit:
    nxt = []
    for s in frontier:
        if s not in seen:
            seen.add(s)
            states.append(s)
            nxt.extend(t for _, t in m.successors(s))
    frontier = nxt
gc.disable()
best, n = {}, 0
for _ in range(5):
    for name in ("successors", "violations", "key"):
        f = getattr(m, name)
        t = time.process_time()
        out = list(map(f, states))
        best[name] = min(best.get(name, 1e9), time.process_time() - t)
        if name == "successors":
            n = sum(map(len, out))
        del out
print(json.dumps({**best, "states": len(states), "transitions": n,
                  "code": __import__("pccl").__file__}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="HEAD", metavar="REV")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--states", type=int, default=150_000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        old = checkout(args.baseline, tmp)
        runs: dict = {"old": [], "new": []}
        for k in range(args.repeat):
            order = [("old", old), ("new", None)]
            for v, d in (order if k % 2 == 0 else order[::-1]):
                env = dict(os.environ)
                if d is not None:
                    env["PCCL_BENCH_CODE"] = d
                out = subprocess.run([sys.executable, "-c", CHILD, str(args.states)], cwd=ROOT,
                                     env=env, capture_output=True, text=True, check=True)
                r = json.loads(out.stdout.strip().splitlines()[-1])
                assert os.path.realpath(r["code"]).startswith(os.path.realpath(d or ROOT))
                runs[v].append(r)
    o, n = runs["old"][0], runs["new"][0]
    assert (o["states"], o["transitions"]) == (n["states"], n["transitions"]), (o, n)
    print(f"fischer k=2 d=2 unreduced: {o['states']:,} states, {o['transitions']:,} "
          f"transitions; CPU seconds, best of 5 per process, median of {args.repeat} processes")
    for f in ("successors", "violations", "key"):
        a = statistics.median(r[f] for r in runs["old"])
        b = statistics.median(r[f] for r in runs["new"])
        print(f"{f:<11} old {args.baseline:<8} {a:6.3f}  new {b:6.3f}  new/old {b / a:5.3f}   "
              f"old {[round(r[f], 3) for r in runs['old']]}  "
              f"new {[round(r[f], 3) for r in runs['new']]}")


if __name__ == "__main__":
    main()
