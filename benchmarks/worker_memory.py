"""Each process's resident memory over time in a ``pccl explore`` run
(with ``--workers N``: the coordinator and the forked workers), sampled
with psutil every ``--every`` seconds; with ``--spill``: when it spilled.

    python benchmarks/worker_memory.py [--every 0.02] [--rows 12] -- \\
        explore programs/fischer.pccl --set k=2 --set d=2 --reduce none \\
        --no-timelock --no-stall --workers 2 --max-memory 110M --spill /var/tmp/pccl

Prints the search's result (status, states, its peak figure: the
processes' peaks together), each process's peak RSS and PSS (PSS splits
the pages a forked worker shares with the coordinator between them; RSS,
what ``--max-memory`` bounds, counts them in each), the largest sum of the
processes' RSS at one moment, and ``--rows`` samples of the RSS per
process, in MiB.  (``--format json`` is added to the arguments.)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import psutil

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MIB = 1 << 20


def sample(args: list, every: float) -> tuple:
    """Run pccl with ``args``; its JSON report and the samples ``(seconds,
    [(pid, rss, pss)])`` of it and its children."""
    p = subprocess.Popen([sys.executable, "-c", "from pccl.cli import main; main()", *args,
                          "--format", "json"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, cwd=ROOT)
    me = psutil.Process(p.pid)
    t0 = time.perf_counter()
    rows: list = []
    while p.poll() is None:
        try:
            procs = [me] + me.children(recursive=True)
        except psutil.Error:
            break
        row = []
        for q in procs:
            try:
                mi = q.memory_full_info()
            except psutil.Error:
                continue
            row.append((q.pid, mi.rss, mi.pss))
        rows.append((time.perf_counter() - t0, row))
        time.sleep(every)
    out, err = p.communicate()
    if p.returncode not in (0, 1):
        sys.exit(f"pccl exited {p.returncode}: {err.strip()}")
    return json.loads(out), rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--every", type=float, default=0.02)
    ap.add_argument("--rows", type=int, default=12)
    ap.add_argument("args", nargs=argparse.REMAINDER)
    o = ap.parse_args()
    args = o.args[1:] if o.args[:1] == ["--"] else o.args
    report, rows = sample(args, o.every)
    st = report["statistics"]
    print(f"{report['status']}: {st['states']:,} states, {st['transitions']:,} transitions, "
          f"depth {st['max_depth']}, peak {st['peak_memory_bytes'] / MIB:.1f} MiB, "
          f"{st['seconds']} s")
    for n in report.get("notes", []):
        if n.startswith("--spill"):
            print(f"note: {n}")
    # the processes that lived long enough to matter (not a passing `cc`)
    peak: dict = {}
    pss: dict = {}
    for _, row in rows:
        for pid, r, s in row:
            peak[pid] = max(peak.get(pid, 0), r)
            pss[pid] = max(pss.get(pid, 0), s)
    main_pids = [pid for pid in peak if peak[pid] > 16 * MIB]
    print("peak RSS per process: " + " + ".join(f"{peak[p] / MIB:.1f}" for p in main_pids)
          + f" = {sum(peak[p] for p in main_pids) / MIB:.1f} MiB")
    print("peak PSS per process: " + " + ".join(f"{pss[p] / MIB:.1f}" for p in main_pids)
          + f" = {sum(pss[p] for p in main_pids) / MIB:.1f} MiB")
    at = max(rows, key=lambda x: sum(r for pid, r, _ in x[1] if pid in main_pids))
    print(f"largest sum of RSS at one moment: "
          f"{sum(r for pid, r, _ in at[1] if pid in main_pids) / MIB:.1f} MiB at {at[0]:.2f} s")
    step = max(1, len(rows) // max(o.rows, 1))
    for t, row in rows[::step]:
        got = dict((pid, r) for pid, r, _ in row)
        print(f"  {t:6.2f} s  " + "  ".join(
            f"{got[p] / MIB:5.1f}" if p in got else "    -" for p in main_pids))


if __name__ == "__main__":
    main()
