"""What ``--spill DIR`` costs: the same search in memory, stopped by a
``--max-memory`` below its peak, and spilling to disk under that bound.

    python benchmarks/spill.py [--repeat 2] [--dir /var/tmp/pccl-spill]
        [--set k=2 --set d=2] [--bound 80M] [--bound 70M]
        [--workers 2 [--workers-bound 130M]]

Each configuration runs ``pccl explore ... --format json`` in a fresh
process, the configurations alternating (``--repeat`` rounds, the median
shown); CPU seconds are the child's user + system time (getrusage), wall
the process's, peak the search's own figure (the process's peak RSS).  The
spilled searches must give the in-memory figures (states, transitions,
depth, status): the script says so or exits 1.

``--workers N``: the same with ``--workers N`` too (in memory, stopped by
the bound, spilling), and the ratios of the spilling workers' CPU time to
the N workers' in memory and to one process spilling.  The workers' bound
is ``--workers-bound`` (repeatable; by default each ``--bound`` plus 48 MiB
per further worker: each forked process needs about that before it holds a
state, and ``--max-memory`` bounds the processes' peaks together).  CPU
time counts every process (the workers are the pccl process's children).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(args: list) -> dict:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", "from pccl.cli import main; main()", *args],
                       capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode not in (0, 1):
        sys.exit(f"pccl {' '.join(args)} exited {p.returncode}: {p.stderr.strip()}")
    out = json.loads(p.stdout)
    st = out["statistics"]
    return {"status": out["status"], "states": st["states"], "transitions": st["transitions"],
            "depth": st["max_depth"], "peak": st["peak_memory_bytes"], "wall": wall,
            "cpu": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
            "notes": [n for n in out.get("notes", []) if n.startswith("--spill")]}


def _mib(text: str) -> int:
    """``80M``, ``1G``, ``83886080`` in MiB."""
    t = text.strip().upper()
    scale = {"K": 1 / 1024, "M": 1, "G": 1024}.get(t[-1:], None)
    return int(float(t[:-1]) * scale) if scale else int(t) >> 20


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--dir", default="/var/tmp/pccl-spill")
    ap.add_argument("--program", default="programs/fischer.pccl")
    ap.add_argument("--set", dest="sets", action="append", default=None)
    ap.add_argument("--bound", dest="bounds", action="append", default=None)
    ap.add_argument("--extra", default="--reduce none --no-timelock --no-stall")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--workers-bound", dest="wbounds", action="append", default=None)
    a = ap.parse_args()
    sets = a.sets or ["k=2", "d=2"]
    bounds = a.bounds or ["80M", "70M"]
    base = ["explore", a.program, *[x for s in sets for x in ("--set", s)], *a.extra.split(),
            "--format", "json", "--no-progress"]
    configs = [("in memory", [])]
    for b in bounds:
        configs += [(f"--max-memory {b}", ["--max-memory", b]),
                    (f"--max-memory {b} --spill", ["--max-memory", b, "--spill", a.dir])]
    pairs = []          # (workers spilling, workers in memory, one process spilling)
    if a.workers > 1:
        w = ["--workers", str(a.workers)]
        wmem = f"--workers {a.workers}, in memory"
        configs.append((wmem, w))
        wbounds = a.wbounds or [f"{_mib(b) + 48 * (a.workers - 1)}M" for b in bounds]
        for i, wb in enumerate(wbounds):
            b = bounds[min(i, len(bounds) - 1)]        # the one-process run it is compared with
            spill = f"--workers {a.workers} --max-memory {wb} --spill"
            configs += [(f"--workers {a.workers} --max-memory {wb}", w + ["--max-memory", wb]),
                        (spill, w + ["--max-memory", wb, "--spill", a.dir])]
            pairs.append((spill, wmem, f"--max-memory {b} --spill"))
    results: dict = {name: [] for name, _ in configs}
    for _ in range(a.repeat):
        for name, extra in configs:
            results[name].append(run(base + extra))
    ref = results["in memory"][0]
    ok = True
    print(f"pccl {' '.join(base)}  (load average {os.getloadavg()[0]:.1f} at the end)\n")
    print("| configuration | result | states | CPU s | wall s | peak MiB | CPU vs in memory |")
    print("|---|---|---:|---:|---:|---:|---:|")
    cpu0 = statistics.median(r["cpu"] for r in results["in memory"])
    for name, _ in configs:
        rs = results[name]
        cpu = statistics.median(r["cpu"] for r in rs)
        wall = statistics.median(r["wall"] for r in rs)
        peak = max(r["peak"] for r in rs) / 2**20
        r = rs[0]
        if name.endswith("--spill"):
            same = all((x["status"], x["states"], x["transitions"], x["depth"]) ==
                       (ref["status"], ref["states"], ref["transitions"], ref["depth"]) for x in rs)
            ok &= same
        print(f"| {name} | {r['status']} | {r['states']:,} | {cpu:.2f} | {wall:.2f} | {peak:.1f} | "
              f"{cpu / cpu0:.2f}x |")
    for name, _ in configs:
        for n in results[name][0]["notes"]:
            print(f"\n{name}: {n}")
    if pairs:
        print("\n| spilling workers | CPU vs the workers in memory | CPU vs one process spilling |")
        print("|---|---:|---:|")

        def med(name):
            return statistics.median(r["cpu"] for r in results[name])
        for spill, wmem, one in pairs:
            print(f"| {spill} | {med(spill) / med(wmem):.2f}x | {med(spill) / med(one):.2f}x |")
    if not ok:
        sys.exit("a spilled search differs from the in-memory one")
    print("\nevery spilled search gave the in-memory states, transitions, depth and status")


if __name__ == "__main__":
    main()
