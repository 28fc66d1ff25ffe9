"""The programs that fell back to the Python engine before issue 43 (item 1):
formation and rendezvous on their shipped worlds, the tutorial's dock, on
the Python engine (old: what ran before) and the native engine (new), in
one run.

    python benchmarks/native_programs.py [--max-states 60000] [--repeat 1]
                                         [--cases formation,rendezvous,dock]

Each search is ``explore`` with the program's default options (blackbox
nondet, the default reductions, the time-lock and stall checks), ``--all``
and ``--max-states`` (the same states for both engines), in its own process;
the native module is compiled by an untimed warm-up run first (it is
cached).  Prints states, transitions (which must be equal: a mismatch exits
1), the CPU seconds of the ``explore`` call (search, graph analysis and the
frozen-team check; the model's parse and build and the native module's load
included, Python's start-up and imports not), the wall seconds the explorer
reports, the whole process's CPU seconds, states per CPU second of the
search, and the ratio Python / native.  CPU seconds, not wall: on a shared
machine the wall clock measures the neighbours.  The fixed cost of an
``explore`` call (parsing, building the model, loading the module: the CPU
of a ``--max-states 1`` run, "fixed") is shown, and the search's own rate
is states / (CPU - fixed).  That difference is noisy where the search is
small beside the fixed cost (formation's and the dock's native searches), so
the steps of the call are also timed on their own ("steps CPU": the CPU of
``explore_model``'s search step and graph-analysis step, the frozen-team
check included, "frozen" that check alone; the process's CPU, by wrapping
``pccl.api._run_search``, ``_analyse`` and ``_frozen_check``), and "steps
rate" is states / steps CPU: the first ratio printed.  With ``PYTHONPATH``
naming an older checkout the children run its pccl (old against new: run the
script twice).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

CASES = {
    "formation": ("programs/formation.pccl", {"world": "programs/formation.toml"}),
    "rendezvous": ("programs/rendezvous.pccl", {"world": "programs/rendezvous.toml"}),
    "rendezvous-straight": ("programs/rendezvous.pccl", {"world": "programs/rendezvous.toml",
                                                         "blackbox": "straight"}),
    "dock": ("docs/examples/dock_retry.pccl", {"world": "docs/examples/dock.toml",
                                               "blackbox": "nondet"}),
}

CHILD = """
import json, sys, time
import pccl.api as A
from pccl.api import explore
prog, kw = sys.argv[1], json.loads(sys.argv[2])
phase = {"search": 0.0, "analysis": 0.0, "frozen": 0.0}
def timed(name, f):
    def g(*a, **k):
        t0 = time.process_time()
        try:
            return f(*a, **k)
        finally:
            phase[name] += time.process_time() - t0
    return g
for name, fn in (("search", "_run_search"), ("analysis", "_analyse"), ("frozen", "_frozen_check")):
    if hasattr(A, fn):      # (the steps of explore_model, by name: an older pccl's too)
        setattr(A, fn, timed(name, getattr(A, fn)))
t = time.process_time()
r = explore(prog, **kw)
t = time.process_time() - t
print(json.dumps({"engine": r.model.engine_used, "why": r.model.engine_reason,
                  "status": r.status, "states": r.stats.states,
                  "transitions": r.stats.transitions, "seconds": r.stats.seconds, "search_cpu": t,
                  "steps_cpu": phase["search"] + phase["analysis"], "frozen_cpu": phase["frozen"]}))
"""


def run(prog: str, kw: dict) -> dict:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([sys.executable, "-c", CHILD, os.path.join(ROOT, prog), json.dumps(kw)],
                       capture_output=True, text=True, cwd=ROOT)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise SystemExit(f"{prog} {kw}: {p.stderr[-2000:]}")
    out = json.loads(p.stdout.strip().splitlines()[-1])
    out["cpu"] = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--max-states", type=int, default=60_000)
    ap.add_argument("--repeat", type=int, default=1)
    a = ap.parse_args()
    bad = 0
    print(f"{'case':12s} {'engine':7s} {'status':10s} {'states':>8s} {'trans':>8s} "
          f"{'CPU s':>7s} {'fixed':>6s} {'wall s':>7s} {'proc CPU':>8s} {'states/CPU s':>12s} "
          f"{'search rate':>11s} {'steps CPU':>9s} {'frozen':>6s} {'steps rate':>10s}")
    for name in a.cases.split(","):
        prog, kw0 = CASES[name]
        kw = dict(kw0, find_all=True, max_states=a.max_states)
        run(prog, dict(kw, engine="native", max_states=100))       # warm-up: the compile
        res = {}
        for eng in ("python", "native"):
            fixed = statistics.median(run(prog, dict(kw, engine=eng, max_states=1))["search_cpu"]
                                      for _ in range(a.repeat))
            runs = [run(prog, dict(kw, engine=eng)) for _ in range(a.repeat)]
            r = runs[0]
            r["seconds"] = statistics.median(x["seconds"] for x in runs)
            r["cpu"] = statistics.median(x["cpu"] for x in runs)
            r["search_cpu"] = statistics.median(x["search_cpu"] for x in runs)
            r["steps_cpu"] = statistics.median(x["steps_cpu"] for x in runs)
            r["frozen_cpu"] = statistics.median(x["frozen_cpu"] for x in runs)
            r["steps_rate"] = r["states"] / max(r["steps_cpu"], 1e-3)
            r["fixed"] = fixed
            r["rate"] = r["states"] / max(r["search_cpu"] - fixed, 1e-3)
            res[eng] = r
            if r["engine"] != eng:
                print(f"  {name}: asked for {eng}, ran {r['engine']} ({r['why']})")
                bad = 1
            print(f"{name:12s} {eng:7s} {r['status']:10s} {r['states']:8,d} {r['transitions']:8,d} "
                  f"{r['search_cpu']:7.2f} {fixed:6.2f} {r['seconds']:7.2f} {r['cpu']:8.2f} "
                  f"{r['states'] / r['search_cpu']:12,.0f} {r['rate']:11,.0f} "
                  f"{r['steps_cpu']:9.3f} {r['frozen_cpu']:6.3f} {r['steps_rate']:10,.0f}")
        p, n = res["python"], res["native"]
        if (p["status"], p["states"], p["transitions"]) != (n["status"], n["states"], n["transitions"]):
            print(f"  {name}: MISMATCH")
            bad = 1
        print(f"  {name}: native {n['steps_rate'] / p['steps_rate']:.1f}x faster (steps rate), "
              f"{n['rate'] / p['rate']:.1f}x (search rate), "
              f"{p['search_cpu'] / n['search_cpu']:.1f}x (explore CPU), "
              f"{p['cpu'] / n['cpu']:.1f}x (process CPU, start-up included)")
    return bad


if __name__ == "__main__":
    sys.exit(main())
