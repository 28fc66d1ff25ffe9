"""Parallel search benchmark: 1 worker against 2, old code against new.

    python benchmarks/parallel.py                    # fischer k=2 and k=4, exhaustive
    python benchmarks/parallel.py --full             # also the paper's k=10 exhaustive
    python benchmarks/parallel.py --ray              # also --ray local (2 actors)
    python benchmarks/parallel.py --baseline REV     # the "old" code [default: 19a6888]
    python benchmarks/parallel.py --repeat 5 --only k=2
    python benchmarks/parallel.py --round-trip       # one synchronisation round, alone

The searches are those of ``pccl explore programs/fischer.pccl --set k=K
--reduce none --no-timelock --workers N`` (unreduced; the time-lock check,
which only one worker runs, off).  Every run is a fresh process.  The configurations of a case alternate
(``--repeat`` rounds) so that load on a shared machine hits them alike; the
speedup is computed within each round (1-worker seconds / 2-worker seconds
of the same round) and the table shows the median and the range.

Columns: ``search s`` is the search's own time (``stats.seconds``: no
program loading, no Ray start-up), ``process s`` the whole process's wall
time, ``CPU s`` the user + system time of the process and of the worker
processes it forked and waited for (Ray's actors are not its children: for
``ray`` rows it is the driver's alone), ``CPU/process`` the same per process
(the first process, which runs worker 0 and the coordinator, then the forked
workers').  The load average is printed before every round.  Results (states, transitions,
depth, status) are checked to be identical across configurations.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
from run import checkout  # noqa: E402  (the git-archive checkout of another revision)

#: main before the work on the speed of two workers (par-speed).  (905a05b:
#: before the two-round protocol, the inline worker and --ray.)
BASELINE = "19a6888"

CASES = [
    ("fischer k=2 d=2, exhaustive", dict(program="programs/fischer.pccl",
                                         overrides={"k": "2", "d": "2"}, reduce="none")),
    ("fischer k=4 d=2, exhaustive", dict(program="programs/fischer.pccl",
                                         overrides={"k": "4", "d": "2"}, reduce="none")),
]
FULL = [
    ("fischer k=10 d=2 (paper), exhaustive", dict(program="programs/fischer.pccl",
                                                  reduce="none")),
]

CHILD = r"""
import json, os, resource, sys, time
code = os.environ.get("PCCL_BENCH_CODE")
if code:   # import that tree, not the (editable) install
    sys.path.insert(0, code)
    sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in type(f).__module__]
from pccl.api import make_model, explore_model
spec = json.loads(sys.argv[1])
workers, ray = spec.pop("workers"), spec.pop("ray", None)
extra = {k: spec.pop(k) for k in ("engine", "stall", "timelock", "find_all") if k in spec}
extra.setdefault("timelock", False)
m = make_model(spec.pop("program"), overrides=spec.pop("overrides", None),
               reduce=spec.pop("reduce", "none"),
               **({"agents": spec.pop("agents")} if spec.get("agents") else {}))
r = explore_model(m, workers=workers, max_memory=None,
                  **({"ray": ray} if ray else {}), **extra)
s = r.stats
me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({"status": r.status, "states": s.states, "transitions": s.transitions,
                  "depth": s.max_depth, "seconds": s.seconds, "peak": s.peak_memory,
                  "cpu_self": me.ru_utime + me.ru_stime,
                  "cpu_children": kids.ru_utime + kids.ru_stime,
                  "engine": getattr(m, "engine_used", "python"),
                  "code": __import__("pccl").__file__}))
"""


def run_one(spec: dict, workers: int, code_dir=None, ray=None, extra_env=None) -> dict:
    env = dict(os.environ, **(extra_env or {}))
    if code_dir is not None:
        env["PCCL_BENCH_CODE"] = code_dir
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", CHILD,
                          json.dumps({**spec, "workers": workers, "ray": ray})],
                         cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode != 0:
        sys.exit(f"benchmark child failed:\n{out.stderr}")
    r = json.loads(out.stdout.strip().splitlines()[-1])
    want = code_dir or ROOT
    assert os.path.realpath(r["code"]).startswith(os.path.realpath(want)), (r["code"], want)
    r["process"] = wall
    r["cpu"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return r


def round_trip(rounds: int = 300) -> None:
    """The cost of one round with an empty method: through pipes (2
    workers, one forked) and through a local Ray instance (2 actors)."""
    sys.path.insert(0, ROOT)
    from pccl.api import make_model
    from pccl.search import parallel as P
    m = make_model(os.path.join(ROOT, "programs/fischer.pccl"), overrides={"k": "0"})
    m.prepare()
    transports = [("pipes, 2 workers", lambda: P._Pipes(2))]
    try:
        import ray  # noqa: F401
        transports.append(("ray local, 2 actors", lambda: P._RayTransport(2, "local")))
    except ImportError:
        print("ray is not installed: pipes only")
    for name, make in transports:
        t = make()
        t.start(m, True, False)
        try:
            xs = []
            for _ in range(rounds):
                t0 = time.perf_counter()
                t.all("ready", [()] * 2)
                xs.append(time.perf_counter() - t0)
        finally:
            t.stop()
        xs.sort()
        print(f"{name:<22} one round: median {1e3 * statistics.median(xs):.3f} ms, "
              f"10th-90th percentile {1e3 * xs[len(xs) // 10]:.3f}-"
              f"{1e3 * xs[len(xs) * 9 // 10]:.3f} ms ({rounds} rounds)", flush=True)


def per_process(rs, ray) -> str:
    """Median CPU seconds of the first process / of its forked workers."""
    me = statistics.median(r["cpu_self"] for r in rs)
    if ray or not any(r["cpu_children"] for r in rs):
        return f"{me:.1f}"
    return f"{me:.1f} / {statistics.median(r['cpu_children'] for r in rs):.1f}"


def fmt_range(xs, spec=".2f"):
    return f"{statistics.median(xs):{spec}} ({min(xs):{spec}}-{max(xs):{spec}})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="include the paper's k=10 exhaustive")
    ap.add_argument("--ray", action="store_true", help="also --ray local with 2 actors")
    ap.add_argument("--baseline", default=BASELINE, metavar="REV",
                    help=f"git revision of the old code [default: {BASELINE}]")
    ap.add_argument("--no-baseline", action="store_true", help="this checkout only")
    ap.add_argument("--no-poll", action="store_true",
                    help="also 2 workers that block at once (PCCL_SPIN=0) instead of polling")
    ap.add_argument("--repeat", type=int, default=3, help="rounds [default: 3]")
    ap.add_argument("--only", metavar="TEXT", help="the cases whose name contains TEXT")
    ap.add_argument("--json", action="store_true", help="print JSON lines")
    ap.add_argument("--round-trip", action="store_true",
                    help="only measure one synchronisation round (pipes, Ray)")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} CPUs, load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())} at the start", flush=True)
    if args.round_trip:
        return round_trip()
    cases = CASES + (FULL if args.full else [])
    if args.only:
        cases = [c for c in cases if args.only in c[0]]
    with tempfile.TemporaryDirectory() as tmp:
        old_dir = None if args.no_baseline else checkout(args.baseline, tmp)
        configs = [("1 worker", 1, None, None, None), ("2 workers", 2, None, None, None)]
        if args.no_poll:
            configs.append(("2 workers, PCCL_SPIN=0", 2, None, None, {"PCCL_SPIN": "0"}))
        if old_dir is not None:
            configs.append((f"2 workers old {args.baseline}", 2, old_dir, None, None))
        if args.ray:
            configs.append(("ray local, 2 actors", 2, None, "local", None))
        hdr = f"{'case':<30} {'configuration':<28} {'search s':>19} {'process s':>19} " \
              f"{'CPU s':>19} {'CPU/process s':>13} {'speedup vs 1':>19}"
        if not args.json:
            print(hdr)
            print("-" * len(hdr), flush=True)
        for name, spec in cases:
            runs: dict = {c[0]: [] for c in configs}
            for i in range(args.repeat):
                load = " ".join(f"{x:.2f}" for x in os.getloadavg())
                done = []
                for label, w, code, ray, env in configs:
                    r = run_one(dict(spec), w, code, ray, env)
                    runs[label].append(r)
                    done.append(f"{label} {r['seconds']:.2f} s")
                if not args.json:
                    print(f"  round {i + 1}, load {load}: {'; '.join(done)}", flush=True)
            ref = runs["1 worker"]
            sig = {(r["status"], r["states"], r["transitions"], r["depth"]) for rs in runs.values()
                   for r in rs}
            assert len(sig) == 1, f"results differ between configurations: {sig}"
            for label, _w, _code, on_ray, _env in configs:
                rs = runs[label]
                speed = [a["seconds"] / b["seconds"] for a, b in zip(ref, rs)]
                if args.json:
                    print(json.dumps({"case": name, "configuration": label,
                                      "seconds": [r["seconds"] for r in rs],
                                      "process": [r["process"] for r in rs],
                                      "cpu": [r["cpu"] for r in rs], "speedup": speed,
                                      "cpu_self": [r["cpu_self"] for r in rs],
                                      "cpu_children": [r["cpu_children"] for r in rs],
                                      "states": rs[0]["states"],
                                      "peak": [r["peak"] for r in rs]}))
                    continue
                print(f"{name:<30} {label:<28} {fmt_range([r['seconds'] for r in rs]):>19} "
                      f"{fmt_range([r['process'] for r in rs]):>19} "
                      f"{fmt_range([r['cpu'] for r in rs]):>19} "
                      f"{per_process(rs, on_ray):>13} "
                      f"{fmt_range(speed):>19}", flush=True)
            if not args.json:
                r = ref[0]
                print(f"{'':<30} ({r['status']}, {r['states']:,} states, "
                      f"{r['transitions']:,} transitions, depth {r['depth']})", flush=True)
    print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
