"""Robots on threads (issue 43 item 2): race_robust under the default
blackbox (nondet), DOREACH INVOKE's outcomes made by Python at a memo miss
("old", ``PCCL_C_BLACKBOX=0``) against made in C (``native_c/robots.c``,
"new"), one worker and ``--workers 2`` (threads of the level kernel), in
one run.

    python benchmarks/robots.py                      # 4 robots, workers 1 and 2, 1 round
    python benchmarks/robots.py --agents 5 --workers 2 --only new
    python benchmarks/robots.py --repeat 3 --autogroup-nice -20

Each run is ``pccl explore programs/race_robust.pccl --world
programs/race.toml --agents N --no-progress [--workers W]`` in a fresh
process (the default search: merge+symmetry+por+dead, time-lock and stall
checks on), timed here: wall seconds of the process, the search's own
seconds (the report's ``seconds``), CPU seconds (user + system of the
process and its children: the module's compile, when it is not cached,
included) and the peak RSS.  The old side is this checkout with the C
blackbox turned off, which is the code path before it (the misses in
Python); states and transitions must be equal in every run (checked).
The machine may be shared: the load average is printed before each run.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def own_group(nice: int) -> None:
    """Put this process's session in an autogroup weighted ``nice``
    (benchmarks/workers.py says why); silently nothing where not allowed."""
    try:
        os.setsid()
    except OSError:
        pass
    try:
        with open("/proc/self/autogroup", "w") as f:
            f.write(str(nice))
    except OSError:
        pass


def run(agents: int, workers: int, c_blackbox: bool) -> dict:
    exe = os.path.join(os.path.dirname(sys.executable), "pccl")
    cmd = [exe, "explore", "programs/race_robust.pccl",
           "--world", "programs/race.toml", "--agents", str(agents), "--no-progress",
           "--workers", str(workers), "--max-memory", "20G"]
    env = dict(os.environ, PCCL_C_BLACKBOX="1" if c_blackbox else "0")
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = p.stdout + p.stderr

    def num(label: str) -> float:
        m = re.search(rf"^\s*{label}\s+([\d,.]+)", out, re.M)
        return float(m.group(1).replace(",", "")) if m else -1.0
    eng = re.search(r"engine native[^,\n]*(?:\([^)]*\))?|engine python[^,\n]*", out)
    return {"wall": wall, "search": num("seconds"), "states": int(num("states")),
            "transitions": int(num("transitions")),
            "cpu": (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime),
            "rss": r1.ru_maxrss / 1024, "engine": eng.group(0) if eng else "?",
            "exit": p.returncode}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--agents", type=int, default=4)
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--only", choices=("old", "new"), help="one side only")
    ap.add_argument("--autogroup-nice", type=int, default=None)
    a = ap.parse_args()
    if a.autogroup_nice is not None:
        own_group(a.autogroup_nice)
    sides = [("old", False), ("new", True)]
    if a.only:
        sides = [s for s in sides if s[0] == a.only]
    counts = set()
    print(f"race_robust, {a.agents} robots, nondet; cpu count {os.cpu_count()}")
    print("| round | side | workers | load (1, 5, 15 min) before | states | transitions | search s "
          "| process wall s | CPU s | peak RSS MiB | engine |")
    print("|---|---|---:|---|---:|---:|---:|---:|---:|---:|---|")
    for rnd in range(a.repeat):
        for w in (int(x) for x in a.workers.split(",")):
            for name, on in sides:
                ld = load()
                r = run(a.agents, w, on)
                ex = "" if r["exit"] == 0 else f" (exit {r['exit']})"
                counts.add((r["states"], r["transitions"]))
                print(f"| {rnd + 1} | {name} | {w} | {ld} | {r['states']:,} | {r['transitions']:,} "
                      f"| {r['search']:.2f} | {r['wall']:.2f} | {r['cpu']:.2f} | {r['rss']:,.0f} "
                      f"| {r['engine']}{ex} |",
                      flush=True)
    if len(counts) != 1:
        print(f"DIFFERENT COUNTS: {sorted(counts)}")
        sys.exit(1)
    print(f"load after: {load()}")


if __name__ == "__main__":
    main()
