"""`--workers 2` against one worker on every shipped program and on the
benchmark cases: never slower (issue 43).

    python benchmarks/workers_shapes.py                  # every case, 2 rounds
    python benchmarks/workers_shapes.py --repeat 3 --only fischer
    python benchmarks/workers_shapes.py --busy           # beside a busy loop too

Each case is ``pccl explore PROGRAM [options] --no-progress --workers N``
(the default checks, the default reductions unless the case says
otherwise) in a fresh process of this checkout, one worker and two
alternating within each round so that the machine's load hits both alike.
It prints, per case, the median (range) of the search's seconds (the
report's ``seconds``) and of the process's wall time, the ratio 1 worker /
2 workers of each (above 1: two are faster), and what the header says of
the engine (threads, or why not).  The states and the verdict must be the
same for both (checked).  With ``--busy`` each round runs again beside a
busy loop (``python -c 'while True: pass'``).  The load average is
printed with every round: on a shared machine, compare ratios, not
seconds.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: (name, the arguments after `pccl explore`)
CASES = [
    ("fischer (k=10, paper), default", ["programs/fischer.pccl"]),
    ("fischer k=0 d=1, default (narrow levels)", ["programs/fischer.pccl", "--set", "k=0",
                                                   "--set", "d=1"]),
    ("fischer k=2 d=2 unreduced", ["programs/fischer.pccl", "--set", "k=2", "--set", "d=2",
                                   "--reduce", "none"]),
    ("fischer k=4 d=2 unreduced --all (issue 43)", ["programs/fischer.pccl", "--set", "k=4",
                                                    "--set", "d=2", "--reduce", "none", "--all"]),
    ("fischer 3 agents k=0 d=2", ["programs/fischer.pccl", "--agents", "3", "--set", "k=0",
                                  "--set", "d=2"]),
    ("leader", ["programs/leader.pccl"]),
    ("race (violated)", ["programs/race.pccl", "--world", "programs/race.toml"]),
    ("race_safe", ["programs/race_safe.pccl", "--world", "programs/race.toml"]),
    ("race_nonatomic", ["programs/race_nonatomic.pccl", "--world", "programs/race.toml"]),
    ("race_robust 3 robots", ["programs/race_robust.pccl", "--world", "programs/race.toml",
                              "--agents", "3"]),
    ("collide", ["programs/collide.pccl", "--world", "programs/collide.toml"]),
    ("collide_fixed", ["programs/collide_fixed.pccl", "--world", "programs/collide.toml"]),
    ("rendezvous", ["programs/rendezvous.pccl", "--world", "programs/rendezvous.toml"]),
    ("formation", ["programs/formation.pccl", "--world", "programs/formation.toml"]),
]


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def run(args: list, workers: int) -> dict:
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "pccl.cli", "explore", *args, "--no-progress",
                        "--workers", str(workers)], cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode not in (0, 1):
        sys.exit(f"pccl explore {' '.join(args)} --workers {workers} failed:\n{p.stderr}")
    out = p.stdout
    head = out.splitlines()[0]
    engine = head[head.index(", engine ") + 2:] if ", engine " in head else "engine python"
    m = re.search(r"^  seconds +([0-9.]+)", out, re.M)
    states = re.search(r"^  states +([0-9,]+)", out, re.M)
    return {"seconds": float(m.group(1)) if m else wall, "process": wall, "engine": engine,
            "states": states.group(1) if states else "?", "verdict": out.splitlines()[1]}


def fmt(xs) -> str:
    return f"{statistics.median(xs):.2f} ({min(xs):.2f}-{max(xs):.2f})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2, help="rounds [default: 2]")
    ap.add_argument("--only", metavar="TEXT", help="the cases whose name contains TEXT")
    ap.add_argument("--skip", metavar="TEXT", action="append", default=[],
                    help="leave out the cases whose name contains TEXT (repeatable)")
    ap.add_argument("--busy", action="store_true", help="also beside a busy loop")
    a = ap.parse_args()
    cases = [c for c in CASES if (a.only is None or a.only in c[0])
             and not any(t in c[0] for t in a.skip)]
    print(f"machine: {os.cpu_count()} CPUs, load average {load()} at the start", flush=True)
    rows = []
    for name, args in cases:
        for mode in ("idle", "busy") if a.busy else ("idle",):
            rs: dict = {1: [], 2: []}
            loads = []
            for _ in range(a.repeat):
                loop = subprocess.Popen([sys.executable, "-c", "while True: pass"]) \
                    if mode == "busy" else None
                try:
                    loads.append(load().split()[0])
                    for w in (1, 2):
                        rs[w].append(run(args, w))
                finally:
                    if loop is not None:
                        loop.kill()
                        loop.wait()
            sig = {(r["states"], r["verdict"]) for w in rs for r in rs[w]}
            assert len(sig) == 1, f"{name}: results differ: {sig}"
            ratio = [x["seconds"] / y["seconds"] if y["seconds"] else 1.0
                     for x, y in zip(rs[1], rs[2])]
            pratio = [x["process"] / y["process"] for x, y in zip(rs[1], rs[2])]
            rows.append((name, mode, rs, ratio, pratio, loads))
            print(f"{name} [{mode}, load {', '.join(loads)}]: {rs[1][0]['states']} states; "
                  f"1 worker {fmt([r['seconds'] for r in rs[1]])} s, "
                  f"2 workers {fmt([r['seconds'] for r in rs[2]])} s: "
                  f"{fmt(ratio)}x search, {fmt(pratio)}x process; {rs[2][0]['engine']}",
                  flush=True)
    print(f"load average at the end: {load()}")


if __name__ == "__main__":
    main()
