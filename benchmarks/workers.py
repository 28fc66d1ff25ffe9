"""Two workers against one, on an idle machine and beside a competing
CPU-bound job, new code against old, in one run.

    python benchmarks/workers.py                      # fischer k=2 d=2, 2 rounds
    python benchmarks/workers.py --k 4 --repeat 3     # fischer k=4 d=2
    python benchmarks/workers.py --baseline REV       # the "old" code [default: c8a9cb9]
    python benchmarks/workers.py --no-baseline        # this checkout only
    python benchmarks/workers.py --static             # also new code with PCCL_BALANCE=0
    python benchmarks/workers.py --block              # also new code with PCCL_SPIN=0
    python benchmarks/workers.py --balance            # also new code with PCCL_BALANCE=1
    python benchmarks/workers.py --unpinned           # also new code with PCCL_PIN=0
    python benchmarks/workers.py --new HEAD           # the new code as committed (else the working tree)
    python benchmarks/workers.py --processes          # also new code with PCCL_THREADS=0
    python benchmarks/workers.py --native --no-baseline   # the native engine, large levels:
                                                      # fischer 3 agents k=2 d=2, reduced
    python benchmarks/workers.py --native --k 1 --no-baseline   # ... k=1 (3.0 M states)
    python benchmarks/workers.py --native --checks --baseline REV   # ... with pccl explore's
                                                      # default checks (time-lock, stall)
    python benchmarks/workers.py --checks --k 4 --all --busy yes --new HEAD --baseline REV
                                                      # issue 43's case: fischer 2 agents k=4
                                                      # d=2 unreduced, default checks, --all
                                                      # (levels of ~3,000 states), beside
                                                      # `yes > /dev/null`
    python benchmarks/workers.py --phases --checks --k 4 --all --repeat 3
                                                      # where the time goes: each phase of
                                                      # the process, 1 worker against 2

With ``--phases`` (this checkout only, no busy loop) each run is a fresh
process timing the phases of ``pccl explore``'s work one after the other:
the imports (``pccl.api``: without bytecode, their compiling), building the
model, making the searcher (the native module compiled or loaded), the
search (the level kernel's threads), the graph analysis after it (time-lock
and stall checks), the frozen-team check, the result assembled; each with
its wall time, the process's CPU (all threads) and the main thread's CPU,
and the kernel's chunks (those the other thread made, those made twice).
The phases outside the search run on one thread whatever ``--workers``
says: they bound the speedup of the whole process (Amdahl).

The search is that of ``pccl explore programs/fischer.pccl --set k=K --set
d=2 --reduce none --no-timelock --workers N`` (unreduced, exhaustive).
On the native engine the workers are threads of one process (the native
level kernel), with or without the graph of the stall and time-lock checks
(since 2026-12-03; before, a search recording the graph ran processes);
``--processes`` adds the threads' case run as processes
(``PCCL_THREADS=0``).  Every
run is a fresh process (benchmarks/parallel.py's).  Each round runs every
configuration twice: first with nothing of ours beside it ("idle"), then
beside a busy loop (``python -c 'while True: pass'``, or with ``--busy yes``
``yes > /dev/null``) that this script
starts before and kills after the "busy" half of the round.  With
``--autogroup-nice -20`` the benchmark runs in a scheduler group of its own
weighted far above the other sessions' (Linux autogroups share the CPU
between sessions, not processes): on a machine that other people's jobs
keep busy, that comes close to an idle machine for its runs.  The speedup is
computed within each half-round (1-worker seconds / 2-worker seconds, the
search's own time; with ``--checks`` the processes' wall times) and shown as median (range).  The machine may be
shared: the load average is printed before each half-round, so "idle" means
"nothing of this benchmark's but the search"; other users' jobs count too.

With a busy loop on a 2-core machine that is otherwise idle, one worker
gets a core to itself and two workers share the two cores with the loop:
4/3 of a core in all, so 1.33x is the ideal (less the protocol's own cost).
CPU is the user + system time of the search's process and its forked
workers, polling included; "process s" is the child process's wall time
(start-up, compiling or loading the native module and, with ``--checks``,
the graph analysis included; with workers, code before 2026-12-03 left the
gathering of the recorded graph out of its search seconds, so compare
old code by this column).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from parallel import run_one  # noqa: E402  (one search in a fresh process)
from run import checkout  # noqa: E402  (the git-archive checkout of another revision)

#: main before balanced levels (branch levels)
BASELINE = "c8a9cb9"


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def busy_loop(kind: str = "python") -> subprocess.Popen:
    if kind == "yes":
        return subprocess.Popen(["yes"], stdout=subprocess.DEVNULL)
    return subprocess.Popen([sys.executable, "-c", "while True: pass"])


def fmt(xs, spec=".2f") -> str:
    return f"{statistics.median(xs):{spec}} ({min(xs):{spec}}-{max(xs):{spec}})"


def own_group(nice: int) -> int:
    """This process in a session (and so a scheduler autogroup) of its own,
    whose nice is set to ``nice``; the nice the kernel reports."""
    try:
        os.setsid()
    except OSError:                 # already a session leader
        pass
    with open("/proc/self/autogroup", "w") as f:
        f.write(str(nice))
    with open("/proc/self/autogroup") as f:
        return int(f.read().split()[-1])


def case(args) -> tuple:
    """The search of the options given: its spec (benchmarks/parallel.py's)
    and what the first line says of it."""
    if args.native:
        k = args.k if "--k" in sys.argv else "2"
        agents = args.agents or 3
        checks = dict(timelock=True, stall=True) if args.checks else dict(stall=False)
        spec = dict(program="programs/fischer.pccl", overrides={"k": k, "d": "2"},
                    reduce="auto", agents=agents, engine="native", **checks)
        what = (f"fischer {agents} agents k={k} d=2, reduced (merge+symmetry+por), native engine"
                + (", time-lock and stall checks" if args.checks else ""))
    else:
        checks = dict(timelock=True, stall=True) if args.checks else {}
        spec = dict(program="programs/fischer.pccl", overrides={"k": args.k, "d": "2"},
                    reduce="none", **({"agents": args.agents} if args.agents else {}), **checks)
        what = (f"fischer k={args.k} d=2, unreduced"
                + (", time-lock and stall checks" if args.checks else ""))
    if args.all:
        spec["find_all"] = True
        what += ", --all"
    return spec, what


#: ``--phases``: one search in a fresh process, timed phase by phase
PHASES_CHILD = r"""
import json, os, sys, time
code = os.environ.get("PCCL_BENCH_CODE")
if code:
    sys.path.insert(0, code)
    sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in type(f).__module__]
def clock():
    return time.perf_counter(), time.process_time(), time.thread_time()
phases, kernel = [], {}
def timed(name, f):
    def g(*a, **k):
        t0 = clock()
        try:
            return f(*a, **k)
        finally:
            phases.append((name, *(b - a for a, b in zip(t0, clock()))))
    return g
t0 = clock()
import pccl.api as api
phases.append(("imports", *(b - a for a, b in zip(t0, clock()))))
make_searcher = api._make_searcher
def searcher(plan):
    ex, native = make_searcher(plan)
    kernel["ex"] = ex
    return ex, native
for name, attr in (("searcher (native module)", "_make_searcher"), ("search", "_run_search"),
                   ("frozen-team check", "_frozen_check"), ("assemble", "_assemble")):
    setattr(api, attr, timed(name, searcher if attr == "_make_searcher" else getattr(api, attr)))
analyse = api._analyse
api._analyse = timed("analysis (time-lock, stall; frozen incl.)", analyse)
spec = json.loads(sys.argv[1])
workers = spec.pop("workers")
extra = {k: spec.pop(k) for k in ("engine", "stall", "timelock", "find_all") if k in spec}
extra.setdefault("timelock", False)
m = timed("model", api.make_model)(spec.pop("program"), overrides=spec.pop("overrides", None),
                                   reduce=spec.pop("reduce", "none"),
                                   **({"agents": spec.pop("agents")} if spec.get("agents") else {}))
r = api.explore_model(m, workers=workers, max_memory=None, **extra)
ex = kernel.get("ex")
print(json.dumps({"status": r.status, "states": r.stats.states, "transitions": r.stats.transitions,
                  "engine": getattr(m, "engine_used", "python"), "phases": phases,
                  "chunks": [getattr(ex, a, 0) for a in ("kernel_chunks", "kernel_helped",
                                                          "kernel_dups")]}))
"""


def phases(spec: dict, repeat: int) -> None:
    """``--phases``: 1 and 2 workers alternating, ``repeat`` fresh processes
    each; per phase the median wall, process CPU and main-thread CPU."""
    import json
    import time
    runs: dict = {1: [], 2: []}
    for _ in range(repeat):
        for w in (1, 2):
            t0 = time.perf_counter()
            out = subprocess.run([sys.executable, "-c", PHASES_CHILD, json.dumps({**spec, "workers": w})],
                                 cwd=os.path.dirname(HERE), capture_output=True, text=True)
            if out.returncode != 0:
                sys.exit(f"benchmark child failed:\n{out.stderr}")
            r = json.loads(out.stdout.strip().splitlines()[-1])
            r["process"] = time.perf_counter() - t0
            runs[w].append(r)
    sig = {(r["status"], r["states"], r["transitions"]) for rs in runs.values() for r in rs}
    assert len(sig) == 1, f"results differ: {sig}"
    names = [p[0] for p in runs[1][0]["phases"]]
    med = statistics.median

    def cell(w: int, name: str) -> str:
        xs = [next(p for p in r["phases"] if p[0] == name)[1:] for r in runs[w]]
        return f"{med(x[0] for x in xs):6.2f} {med(x[1] for x in xs):6.2f} {med(x[2] for x in xs):6.2f}"
    print(f"{'phase (median of ' + str(repeat) + ')':<38} {'1 worker: wall  CPU  main':>22}   "
          f"{'2 workers: wall  CPU  main':>26}")
    for name in names:
        print(f"{name:<38} {cell(1, name):>22}   {cell(2, name):>26}")
    for w in (1, 2):
        ch = [r["chunks"] for r in runs[w]]
        print(f"{w} worker{'s' if w > 1 else ''}: the process {fmt([r['process'] for r in runs[w]])} s "
              f"wall; kernel chunks {ch[0][0]:,}, made by the other thread "
              f"{fmt([c[1] for c in ch], ',')}, made twice {fmt([c[2] for c in ch], ',')}")
    st, states, trans = sig.pop()
    print(f"results identical in every run: {st}, {states:,} states, {trans:,} transitions; "
          f"load average at the end: {load()}")


def configurations(args, new, old) -> list:
    """``[(label, workers, code dir, extra env)]``: the runs of each half-round."""
    configs = [("1 worker", 1, new, None), ("2 workers", 2, new, None)]
    if args.static:
        configs.append(("2 workers, PCCL_BALANCE=0", 2, new, {"PCCL_BALANCE": "0"}))
    if args.balance:
        configs.append(("2 workers, PCCL_BALANCE=1", 2, new, {"PCCL_BALANCE": "1"}))
    if args.block:
        configs.append(("2 workers, PCCL_SPIN=0", 2, new, {"PCCL_SPIN": "0"}))
    if args.unpinned:
        configs.append(("2 workers, PCCL_PIN=0", 2, new, {"PCCL_PIN": "0"}))
    if args.processes:
        configs.append(("2 workers, PCCL_THREADS=0", 2, new, {"PCCL_THREADS": "0"}))
    if old is not None and args.old_one:
        configs.append((f"1 worker, old {args.baseline}", 1, old, None))
    if old is not None:
        configs.append((f"2 workers, old {args.baseline}", 2, old, None))
    return configs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--k", default="2", help="fischer's k [default: 2]")
    ap.add_argument("--repeat", type=int, default=2, help="rounds [default: 2]")
    ap.add_argument("--baseline", default=BASELINE, metavar="REV",
                    help=f"git revision of the old code [default: {BASELINE}]")
    ap.add_argument("--no-baseline", action="store_true", help="this checkout only")
    ap.add_argument("--new", metavar="REV",
                    help="the new code from this git revision [default: the working tree]")
    ap.add_argument("--static", action="store_true",
                    help="also the new code with PCCL_BALANCE=0 (each share expanded where it lies)")
    ap.add_argument("--balance", action="store_true",
                    help="also the new code with PCCL_BALANCE=1 (native levels balanced too)")
    ap.add_argument("--block", action="store_true",
                    help="also the new code with PCCL_SPIN=0 (a waiting process blocks at once)")
    ap.add_argument("--unpinned", action="store_true",
                    help="also the new code with PCCL_PIN=0 (workers not pinned to cores)")
    ap.add_argument("--native", action="store_true",
                    help="the native engine's case: fischer with 3 agents (--agents), d=2, the "
                         "default reductions (merge+symmetry+por), no time-lock or stall check "
                         "(`pccl explore programs/fischer.pccl --agents 3 --set k=K --set d=2 "
                         "--no-timelock --no-stall --workers N`), --k 2 unless given")
    ap.add_argument("--checks", action="store_true",
                    help="pccl explore's default checks, the time-lock and the stall check (the "
                         "recorded graph analysed after the search); with --native its case, "
                         "else fischer 2 agents unreduced")
    ap.add_argument("--autogroup-nice", type=int, metavar="N", default=None,
                    help="run in a session of its own whose scheduler group has nice N (Linux "
                         "autogroups; negative needs root): on a machine shared by other "
                         "sessions, -20 gives this benchmark's processes (and its busy loop) "
                         "most of the cores, close to an idle machine")
    ap.add_argument("--old-one", action="store_true",
                    help="also the old code with one worker")
    ap.add_argument("--all", action="store_true",
                    help="the search goes on past violations (pccl explore --all)")
    ap.add_argument("--busy", choices=("python", "yes"), default="python",
                    help="the busy loop: python -c 'while True: pass' [default], or "
                         "yes > /dev/null")
    ap.add_argument("--processes", action="store_true",
                    help="also the new code with PCCL_THREADS=0 (2 worker processes where "
                         "the search would run on 2 threads)")
    ap.add_argument("--phases", action="store_true",
                    help="where the time goes: each phase of the process (imports, model, "
                         "searcher, search, analysis, frozen-team check, assembly), 1 worker "
                         "against 2, this checkout only")
    ap.add_argument("--agents", type=int, default=None,
                    help="fischer's agents [default: 2; 3 with --native]")
    args = ap.parse_args()
    spec, what = case(args)
    if args.autogroup_nice is not None:
        what += f", autogroup nice {own_group(args.autogroup_nice)}"
    print(f"machine: {os.cpu_count()} CPUs, load average {load()} at the start; {what}",
          flush=True)
    if args.phases:
        phases(spec, args.repeat)
        return
    with tempfile.TemporaryDirectory() as tmp, tempfile.TemporaryDirectory() as tmp_new:
        old = None if args.no_baseline else checkout(args.baseline, tmp)
        new = None if args.new is None else checkout(args.new, tmp_new)
        configs = configurations(args, new, old)
        runs: dict = {(mode, c[0]): [] for mode in ("idle", "busy") for c in configs}
        loads: dict = {"idle": [], "busy": []}
        for i in range(args.repeat):
            for mode in ("idle", "busy"):
                loop = busy_loop(args.busy) if mode == "busy" else None
                try:
                    loads[mode].append(load())
                    done = []
                    for label, w, code, env in configs:
                        r = run_one(dict(spec), w, code, None, env)
                        runs[mode, label].append(r)
                        done.append(f"{label} {r['seconds']:.2f} s ({r['process']:.2f} s the "
                                    f"process, {r['cpu']:.1f} CPU, engine {r.get('engine', '?')})")
                finally:
                    if loop is not None:
                        loop.kill()
                        loop.wait()
                print(f"  round {i + 1}, {mode}, load {loads[mode][-1]}: {'; '.join(done)}",
                      flush=True)
    sig = {(r["status"], r["states"], r["transitions"], r["depth"])
           for rs in runs.values() for r in rs}
    engines = {r.get("engine") for rs in runs.values() for r in rs}
    assert len(sig) == 1, f"results differ between configurations: {sig}"
    hdr = (f"{'':<5} {'configuration':<28} {'search s':>20} {'process s':>20} {'CPU s':>20} "
           f"{'speedup vs 1 worker':>20} {'process speedup':>20}")
    print(hdr)
    print("-" * len(hdr))
    # with --checks by the process's wall time (old code's seconds leave the gathering out)
    by = "process" if args.native and args.checks else "seconds"
    for mode in ("idle", "busy"):
        ref = runs[mode, "1 worker"]
        for label, *_ in configs:
            rs = runs[mode, label]
            speed = [a[by] / b[by] for a, b in zip(ref, rs)]
            pspeed = [a["process"] / b["process"] for a, b in zip(ref, rs)]
            print(f"{mode:<5} {label:<28} {fmt([r['seconds'] for r in rs]):>20} "
                  f"{fmt([r['process'] for r in rs]):>20} "
                  f"{fmt([r['cpu'] for r in rs]):>20} {fmt(speed):>20} {fmt(pspeed):>20}")
        print(f"{'':<5} (load average before each round: {'; '.join(loads[mode])})")
    status, states, transitions, depth = sig.pop()
    print(f"results identical in every run: {status}, {states:,} states, "
          f"{transitions:,} transitions, depth {depth}; engine {', '.join(map(str, sorted(engines, key=str)))}")
    print(f"load average at the end: {load()}")


if __name__ == "__main__":
    main()
