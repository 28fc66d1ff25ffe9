"""The cost of checkpoints, and a search killed and resumed (docs/scale-out.md,
"Checkpoint and resume").

    python benchmarks/checkpoint.py                     # the issue's target (minutes)
    python benchmarks/checkpoint.py -n 2 --set k=2      # a quick one
    python benchmarks/checkpoint.py --workers 2         # the same with two workers
    python benchmarks/checkpoint.py --target            # the issue's target, measured

``--target``: Fischer with 3 agents at k=2 d=2 (12,271,634 states, the
native engine) uninterrupted without and with ``--checkpoint`` (interval
``--interval``, 10 s by default: several checkpoints), then with
``--checkpoint`` SIGKILLed three times at spread-out points (each run killed
after a quarter of the uninterrupted run's wall time) and resumed: wall and
CPU time (user + system of the pccl processes) of each, the ratios to the
uninterrupted run with ``--checkpoint`` (the issue asks at most 1.2), and the
results compared.

1. The uninterrupted search, timed (``pccl explore ... --format json``).
2. The cost of checkpoints: the uninterrupted search with ``--checkpoint DIR
   --checkpoint-interval I``: checkpoints written, seconds per checkpoint,
   size on disk, wall time over the search without checkpoints.
3. The same search with ``--checkpoint DIR --checkpoint-interval I`` killed
   with SIGKILL ``--kills`` times (each run killed after a fraction of the
   uninterrupted time) and resumed with ``--resume DIR`` until it ends: its
   result must be identical; the total wall time over the uninterrupted one
   is the ratio the issue asks to be at most 1.2.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SAME = ("status", "message", "violations", "bounds", "checked")
STATS = ("initial_states", "states", "transitions", "max_depth", "max_time")


#: CPU seconds (user + system) of the last :func:`pccl` run
LAST_CPU = [0.0]


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def pccl(args, *, kill_after=None):
    """Run ``pccl explore args``; (wall seconds, JSON or None if killed); its
    CPU seconds in ``LAST_CPU[0]``."""
    cmd = [sys.executable, "-m", "pccl.cli", "explore", *args, "--format", "json",
           "--no-progress"]
    c0 = _children_cpu()
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        out, err = proc.communicate(timeout=kill_after)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGKILL)
        proc.communicate()
        LAST_CPU[0] = _children_cpu() - c0
        return time.perf_counter() - t0, None
    LAST_CPU[0] = _children_cpu() - c0
    if proc.returncode not in (0, 1):
        raise SystemExit(f"pccl failed ({proc.returncode}): {err}")
    return time.perf_counter() - t0, json.loads(out)


def load() -> str:
    return (f"{time.strftime('%H:%M:%S', time.gmtime())} UTC, load average "
            f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")


def written(res) -> tuple:
    """(checkpoints written, seconds writing them) from a result's notes."""
    m = [re.search(r"\((\d+) written, ([0-9.]+) s\)", n) for n in res["notes"]]
    return next(((int(x.group(1)), float(x.group(2))) for x in m if x), (0, 0.0))


def target(args, interval: str, kills: int) -> None:
    """``--target``: see the module's doc."""
    print(load())
    t_full, full = pccl(args)
    c_full = LAST_CPU[0]
    st = full["statistics"]
    print(f"uninterrupted, no checkpoint: {t_full:.1f} s wall, {c_full:.1f} s CPU; "
          f"{st['states']:,} states, {st['transitions']:,} transitions, depth "
          f"{st['max_depth']}, {full['status']}, peak {st['peak_memory_bytes'] / 2**20:,.0f} MiB"
          f"  [{load()}]")
    work = tempfile.mkdtemp(prefix="pccl-ck-target-")
    try:
        d0 = os.path.join(work, "uninterrupted")
        t_ck, ck = pccl(args + ["--checkpoint", d0, "--checkpoint-interval", interval])
        c_ck = LAST_CPU[0]
        n_ck, s_ck = written(ck)
        print(f"uninterrupted, --checkpoint-interval {interval}: {t_ck:.1f} s wall, {c_ck:.1f} s "
              f"CPU; {n_ck} checkpoints written in {s_ck:.1f} s ({s_ck / max(1, n_ck):.2f} s "
              f"each; the last {dir_size(d0) / 2**20:,.0f} MiB on disk); over no checkpoint: "
              f"{t_ck / t_full:.2f}x wall, {c_ck / c_full:.2f}x CPU; same result: "
              f"{same(ck, full)}  [{load()}]")
        shutil.rmtree(d0, ignore_errors=True)
        d = os.path.join(work, "killed")
        wall = cpu = 0.0
        runs = done = 0
        res = None
        while res is None:
            resume = os.path.exists(os.path.join(d, "checkpoint.json"))
            extra = ["--resume", d] if resume else ["--checkpoint", d]
            kill = t_ck / (kills + 1) if done < kills else None
            t, res = pccl(args + extra + ["--checkpoint-interval", interval], kill_after=kill)
            wall, cpu, runs = wall + t, cpu + LAST_CPU[0], runs + 1
            how = "resumed, " if resume else ""
            if res is None:
                done += 1
                man = os.path.join(d, "checkpoint.json")
                at = json.load(open(man)) if os.path.exists(man) else None
                print(f"  run {runs}: {how}killed (SIGKILL) after {t:.1f} s wall, "
                      f"{LAST_CPU[0]:.1f} s CPU; last checkpoint: "
                      + (f"depth {at['depth']}, {at['states']:,} states" if at else "none"))
            else:
                n, s = written(res)
                notes = [x for x in res["notes"] if x.startswith("resumed")]
                print(f"  run {runs}: {how}finished after {t:.1f} s wall, {LAST_CPU[0]:.1f} s "
                      f"CPU; {'; '.join(notes)}; {n} checkpoints written in {s:.1f} s")
        print(f"killed {done} times and resumed: {wall:.1f} s wall, {cpu:.1f} s CPU in all; "
              f"over the uninterrupted run with --checkpoint: {wall / t_ck:.2f}x wall, "
              f"{cpu / c_ck:.2f}x CPU (over no checkpoint: {wall / t_full:.2f}x wall, "
              f"{cpu / c_full:.2f}x CPU); same result: {same(res, full)}  [{load()}]")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def same(a, b) -> bool:
    return all(a[k] == b[k] for k in SAME) and \
        all(a["statistics"][k] == b["statistics"][k] for k in STATS)


def dir_size(d) -> int:
    return sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(d) for f in fs)


def cost(args, interval, d0, t_full, full):
    """2.: the uninterrupted search writing checkpoints every ``interval``."""
    t_ck, ck = pccl(args + ["--checkpoint", d0, "--checkpoint-interval", interval])
    m = [re.search(r"\((\d+) written, ([0-9.]+) s\)", n) for n in ck["notes"]]
    n_ck, s_ck = next(((int(x.group(1)), float(x.group(2))) for x in m if x), (0, 0.0))
    print(f"with --checkpoint-interval {interval}: {n_ck} checkpoints, {s_ck:.1f} s writing "
          f"them ({1000 * s_ck / max(1, n_ck):.0f} ms each; the last, of "
          f"{full['statistics']['states']:,} states: {dir_size(d0) / 2**20:,.1f} MiB on disk); "
          f"{t_ck:.1f} s wall ({t_ck / t_full:.2f}x); same result: {same(ck, full)}")
    shutil.rmtree(d0, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-n", "--agents", default="3")
    ap.add_argument("--set", dest="sets", action="append", default=None)
    ap.add_argument("--kills", type=int, default=3)
    ap.add_argument("--interval", default=None,
                    help="--checkpoint-interval of the killed runs [default: 1/20 of the "
                         "uninterrupted time; 10s with --target]")
    ap.add_argument("--target", action="store_true",
                    help="the issue's target: wall and CPU, with and without checkpoints, "
                         "killed --kills times (Fischer, 3 agents, k=2 d=2 unless told)")
    ap.add_argument("--program", default="programs/fischer.pccl")
    ap.add_argument("--workers", default=None, help="--workers of every run")
    ap.add_argument("--no-cost", action="store_true", help="skip the cost measurement (2.)")
    ap.add_argument("--baseline", metavar="FILE", default=None,
                    help="the uninterrupted run's time and result: read from FILE if it "
                         "exists, else measured and written there")
    a = ap.parse_args()
    sets = a.sets if a.sets is not None else ["k=2", "d=2"]
    args = [a.program, "-n", a.agents] + [x for s in sets for x in ("--set", s)]
    if a.workers:
        args += ["--workers", a.workers]
    print(f"pccl explore {' '.join(args)}")
    if a.target:
        target(args, a.interval or "10s", a.kills)
        return
    print(f"{time.strftime('%H:%M:%S', time.gmtime())} UTC, load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if a.baseline and os.path.exists(a.baseline):
        with open(a.baseline) as f:
            t_full, full = json.load(f)
    else:
        t_full, full = pccl(args)
        if a.baseline:
            with open(a.baseline, "w") as f:
                json.dump([t_full, full], f)
    st = full["statistics"]
    print(f"uninterrupted: {t_full:.1f} s wall, {st['states']:,} states, "
          f"{st['transitions']:,} transitions, depth {st['max_depth']}, {full['status']}, "
          f"peak {st['peak_memory_bytes'] / 2**20:,.0f} MiB")

    work = tempfile.mkdtemp(prefix="pccl-ck-bench-")
    try:
        interval = a.interval or f"{max(1.0, t_full / 20):.0f}s"
        if not a.no_cost:
            cost(args, interval, os.path.join(work, "cost"), t_full, full)

        # killed with SIGKILL and resumed
        d = os.path.join(work, "killed")
        total, kills, runs = 0.0, 0, 0
        res = None
        while res is None:
            resume = os.path.exists(os.path.join(d, "checkpoint.json"))
            extra = ["--resume", d] if resume else ["--checkpoint", d]
            kill = t_full / (a.kills + 1) if kills < a.kills else None
            t, res = pccl(args + extra + ["--checkpoint-interval", interval], kill_after=kill)
            total += t
            runs += 1
            how = "resumed, " if resume else ""
            if res is None:
                kills += 1
                print(f"  run {runs}: {how}killed (SIGKILL) after {t:.1f} s")
            else:
                notes = [n for n in res["notes"] if n.startswith(("resumed", "checkpoint"))]
                print(f"  run {runs}: {how}finished after {t:.1f} s; {'; '.join(notes)}; "
                      f"on disk {dir_size(d) / 2**20:,.1f} MiB")
        print(f"killed {kills} times and resumed (--checkpoint-interval {interval}): "
              f"{total:.1f} s wall in all, {total / t_full:.2f}x the uninterrupted run; "
              f"same result: {same(res, full)}")
        print(f"{time.strftime('%H:%M:%S', time.gmtime())} UTC, load average "
              f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
