"""Exploration benchmarks: states, transitions, seconds, states/s, memory.

    python benchmarks/run.py                   # the fixed cases, old code against new
    python benchmarks/run.py --full            # also the paper's Fischer (k=10) exhaustively
    python benchmarks/run.py --baseline REV    # compare against another git revision
    python benchmarks/run.py --no-baseline     # this checkout only
    python benchmarks/run.py --reduce          # reductions: auto and none side by side
    python benchmarks/run.py --reduce --full   # also the long ones (k=10 none, 3 agents k=2)
    python benchmarks/run.py --no-timelock     # the new code without the time-lock check
    python benchmarks/run.py --instructions    # instructions executed (valgrind), not seconds

The cases run the unreduced semantics (``reduce="none"``; the default
``auto`` is measured by ``--reduce``). Each case prints ``new``, without
the time-lock check (the same work as the baseline, which had none), and
``new+tl``, with it (the default; ``--no-timelock`` leaves this row out);
a compared case also prints the baseline's row first.

The machine may be shared: "seconds" is the search's wall time, "CPU s" the
process's CPU time during the search (time.process_time), which load on
other cores does not inflate; medians are taken by CPU time.

``--instructions`` counts the instructions each search executes instead
(valgrind's callgrind, every thread of the process; the same process with
``max_states=1`` subtracted, so that start-up and compiling the model are
not counted): a figure that load on the machine cannot change, for the
"old against new within 3 %" check when the machine is never idle. It runs
each version once (the count is deterministic up to the threads'
interleaving) and about 80 times slower than a timed run.

Each case runs in its own process so that peak memory is the case's own.
"B/state" is (peak RSS - RSS before the search) / visited states: the whole
cost of the search (visited fingerprints, parent links, index, frontier),
not just the table.

Old against new: cases marked ``compare`` also run on the code of
``--baseline`` (default: the last commit before sound fingerprints), checked
out with ``git archive`` into a temporary directory and imported from there.
The two versions alternate (``--repeat`` runs each) and the table shows the
median, so that load on a shared machine hits both alike.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

#: The last commit with hash()-based fingerprints and a Python-set visited table.
BASELINE = "e58fcde"

# (name, spec, compare with the baseline)
CASES = [
    ("fischer k=2 d=2, exhaustive",
     dict(program="programs/fischer.pccl", overrides={"k": "2", "d": "2"}), True),
    ("fischer k=4 d=2, exhaustive",
     dict(program="programs/fischer.pccl", overrides={"k": "4", "d": "2"}), False),
    ("fischer k=10 d=2 (paper), first violation",
     dict(program="programs/fischer.pccl", invariants=["count(inCs) <= 1"]), False),
    ("race_nonatomic, nondet, 3 agents",
     dict(program="programs/race_nonatomic.pccl", world="programs/race.toml",
          blackbox="nondet", agents=3), False),
    ("race_safe, nondet, 3 agents, exhaustive",
     dict(program="programs/race_safe.pccl", world="programs/race.toml",
          blackbox="nondet", agents=3), False),
]
FULL = [
    ("fischer k=10 d=2 (paper), exhaustive",
     dict(program="programs/fischer.pccl"), False),
]

# Reductions (docs/reductions.md): (name, spec, reductions to run); the
# reductions alternate --repeat times and the table shows each one's median.
REDUCE_CASES = [
    ("fischer k=2 d=2", dict(program="programs/fischer.pccl",
                             overrides={"k": "2", "d": "2"}),
     ("auto", "none", "merge", "symmetry", "por", "merge,symmetry")),
    ("fischer k=10 (paper), exhaustive", dict(program="programs/fischer.pccl"), ("auto",)),
    ("fischer 3 agents k=0", dict(program="programs/fischer.pccl", agents=3,
                                  overrides={"k": "0"}), ("auto", "none")),
    ("race_safe nondet 3 agents", dict(program="programs/race_safe.pccl",
                                       world="programs/race.toml", blackbox="nondet",
                                       agents=3), ("auto", "none")),
    ("race_safe nondet 4 agents", dict(program="programs/race_safe.pccl",
                                       world="programs/race.toml", blackbox="nondet",
                                       agents=4, explore={"max_states": 3_000_000}), ("auto", "none")),
]
REDUCE_FULL = [
    ("fischer k=10 (paper), exhaustive", dict(program="programs/fischer.pccl"), ("none",)),
    ("fischer 3 agents k=2 d=2", dict(program="programs/fischer.pccl", agents=3,
                                      overrides={"k": "2", "d": "2"}), ("auto",)),
    ("race_robust nondet 4 agents, exhaustive",
     dict(program="programs/race_robust.pccl", world="programs/race.toml", blackbox="nondet",
          agents=4), ("auto",)),
]

CHILD = r"""
import json, os, sys, time
code = os.environ.get("PCCL_BENCH_CODE")
if code:   # import that tree, not the (editable) install
    sys.path.insert(0, code)
    sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in type(f).__module__]
from pccl.api import make_model, explore_model
try:
    from pccl.search.memory import peak_rss_bytes
except ImportError:   # an older tree: Linux units
    import resource
    def peak_rss_bytes():
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
spec = json.loads(sys.argv[1])
m = make_model(spec.pop("program"), world=spec.pop("world", None),
               blackbox=spec.pop("blackbox", None), agents=spec.pop("agents", None),
               overrides=spec.pop("overrides", None),
               invariants=tuple(spec.pop("invariants", ())),
               **({"reduce": spec.pop("reduce")} if "reduce" in spec else {}))
rss0 = peak_rss_bytes()
cpu0 = time.process_time()
r = explore_model(m, **spec.pop("explore", {}))
cpu = time.process_time() - cpu0
peak = peak_rss_bytes()
s = r.stats
print(json.dumps({"status": r.status, "states": s.states, "transitions": s.transitions,
                  "seconds": s.seconds, "cpu": cpu, "sps": s.states_per_second, "peak": peak,
                  "bytes_per_state": (peak - rss0) / max(1, s.states),
                  "depth": s.max_depth, "code": __import__("pccl").__file__}))
"""


def checkout(rev: str, into: str) -> str:
    """The package tree of ``rev``, importable from the returned directory
    (``pccl.semantics`` and ``pccl.blackboxes`` linked in as the install does)."""
    from _baseline import tree_of_revision
    return tree_of_revision(rev, into, paths=())


def _has(tree: str, module_file: str) -> bool:
    """Whether the checkout ``tree`` has ``module_file`` anywhere in its package."""
    import glob
    return bool(glob.glob(os.path.join(tree, "pccl", "**", module_file), recursive=True))


def run_case(spec: dict, code_dir: str | None = None, instructions: bool = False) -> dict:
    env = dict(os.environ)
    if code_dir is not None:
        env["PCCL_BENCH_CODE"] = code_dir
    if instructions:
        # the search alone: the whole process minus the same process
        # stopped after one state (start-up, parsing, compiling the model)
        start = {**spec, "explore": {**spec.get("explore", {}), "max_states": 1}}
        r = _counted(spec, env, code_dir)
        r["instructions"] -= _counted(start, env, code_dir)["instructions"]
        return r
    out = subprocess.run([sys.executable, "-c", CHILD, json.dumps(spec)], cwd=ROOT, env=env,
                         capture_output=True, text=True, check=True)
    r = json.loads(out.stdout.strip().splitlines()[-1])
    want = code_dir or ROOT
    assert os.path.realpath(r["code"]).startswith(os.path.realpath(want)), (r["code"], want)
    return r


def _counted(spec: dict, env: dict, code_dir: str | None) -> dict:
    """One run of the child under callgrind: its JSON line and ``instructions``,
    the instructions every thread of the process executed."""
    import re
    exe = os.path.realpath(sys.executable)      # valgrind follows no launcher script
    env = {**env, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    out = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
                          exe, "-c", CHILD, json.dumps(spec)], cwd=ROOT, env=env,
                         capture_output=True, text=True, check=True)
    r = json.loads(out.stdout.strip().splitlines()[-1])
    want = code_dir or ROOT
    assert os.path.realpath(r["code"]).startswith(os.path.realpath(want)), (r["code"], want)
    m = re.search(r"Collected : (\d+)", out.stderr)
    assert m, out.stderr[-2000:]
    r["instructions"] = int(m.group(1))
    return r


def median_run(runs: list) -> dict:
    """The run with the median CPU time (its own figures, not a mix)."""
    runs = sorted(runs, key=lambda r: r.get("cpu", r["seconds"]))
    return runs[len(runs) // 2]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="include the long exhaustive k=10 case")
    ap.add_argument("--json", action="store_true", help="print JSON lines")
    ap.add_argument("--baseline", default=BASELINE, metavar="REV",
                    help=f"git revision to compare against [default: {BASELINE}]")
    ap.add_argument("--no-baseline", action="store_true", help="run this checkout only")
    ap.add_argument("--repeat", type=int, default=3,
                    help="alternating runs per version for compared cases [default: 3]")
    ap.add_argument("--only", metavar="TEXT", help="run the cases whose name contains TEXT")
    ap.add_argument("--reduce", action="store_true",
                    help="the reduction cases: --reduce auto and none side by side")
    ap.add_argument("--compare-all", action="store_true",
                    help="run every case on the baseline too (with --reduce: each "
                         "reduction's row old against new)")
    ap.add_argument("--instructions", action="store_true",
                    help="count the instructions of each search (valgrind's callgrind) "
                         "instead of timing it; each version runs once")
    ap.add_argument("--no-timelock", action="store_true",
                    help="run this checkout without the time-lock check (timelock=False); "
                         "the baseline runs as it is")
    args = ap.parse_args()
    if args.reduce:
        return reduce_main(args)
    cases = CASES + (FULL if args.full else [])
    if args.only:
        cases = [c for c in cases if args.only in c[0]]
    hdr = f"{'case':<44} {'code':<8} {'result':<11} {'states':>11} {'transitions':>12} " \
          f"{'seconds':>8} {'CPU s':>7} {'states/s':>9} {'peak MiB':>9} {'B/state':>8}"
    if args.instructions:
        hdr = f"{'case':<44} {'code':<8} {'result':<11} {'states':>11} {'transitions':>12} " \
              f"{'instructions':>18} {'per state':>15}"
    if not args.json:
        print(hdr)
        print("-" * len(hdr))
    with tempfile.TemporaryDirectory() as tmp:
        old_dir = None if args.no_baseline else checkout(args.baseline, tmp)
        for name, spec, compare in cases:
            compare = compare or args.compare_all
            # The cases are the unreduced semantics (issue 8's figures): this
            # checkout runs with reduce="none", and so does a baseline that
            # has reductions (the default one predates them).
            new_spec = {**spec, "reduce": "none"}
            explore = spec.get("explore", {})
            versions = [("new", None, {**new_spec, "explore": {**explore, "timelock": False}})]
            if not args.no_timelock:
                versions.append(("new+tl", None, {**new_spec, "explore": explore}))
            if compare and old_dir is not None:
                old = f"old {args.baseline}"[:8]
                if _has(old_dir, "reduce.py"):
                    # a baseline with reductions and the time-lock check runs
                    # what the new rows run: old against new, row by row
                    versions[:0] = [(old, old_dir, dict(versions[0][2]))] + (
                        [(f"{old[:5]}+tl", old_dir, dict(versions[1][2]))]
                        if len(versions) > 1 else [])
                else:
                    versions.insert(0, (old, old_dir, dict(spec)))
            runs: dict = {v: [] for v, _, _ in versions}
            repeat = args.repeat if compare and old_dir is not None and not args.instructions else 1
            for _ in range(repeat):
                for v, d, sp in versions:
                    runs[v].append(run_case(dict(sp), d, args.instructions))
            for v, _, _ in versions:
                r = median_run(runs[v])
                if args.instructions and not args.json:
                    print(f"{name:<44} {v:<8} {r['status']:<11} {r['states']:>11,} "
                          f"{r['transitions']:>12,} {r['instructions'] / 1e9:>10.3f} G instr "
                          f"{r['instructions'] / max(1, r['states']):>9,.0f} instr", flush=True)
                    continue
                if args.json:
                    print(json.dumps({"case": name, "version": v,
                                      "all_seconds": [x["seconds"] for x in runs[v]],
                                      "all_cpu": [x["cpu"] for x in runs[v]], **r}))
                    continue
                print(f"{name:<44} {v:<8} {r['status']:<11} {r['states']:>11,} "
                      f"{r['transitions']:>12,} {r['seconds']:>8.2f} {r['cpu']:>7.2f} "
                      f"{r['sps']:>9,.0f} {r['peak'] / 2**20:>9,.0f} "
                      f"{r['bytes_per_state']:>8.0f}", flush=True)


def reduce_main(args) -> None:
    cases = REDUCE_CASES + (REDUCE_FULL if args.full else [])
    if args.only:
        cases = [c for c in cases if args.only in c[0]]
    hdr = f"{'case':<36} {'reduce':<14} {'result':<11} {'states':>11} {'transitions':>12} " \
          f"{'seconds':>8} {'CPU s':>8} {'states/s':>9} {'peak MiB':>9}"
    if not args.json:
        print(hdr)
        print("-" * len(hdr))
    with tempfile.TemporaryDirectory() as tmp:
        old_dir = checkout(args.baseline, tmp) if args.compare_all else None
        for name, spec, reds in cases:
            # (row label, code tree, reduction): with --compare-all the
            # baseline's row precedes each of this checkout's, alternating
            rows = [(f"{red}", None, red) for red in reds]
            if old_dir is not None:
                rows = [row for red in reds
                        for row in ((f"{red} old", old_dir, red), (f"{red} new", None, red))]
            runs: dict = {label: [] for label, _, _ in rows}
            for _ in range(args.repeat if len(rows) > 1 else 1):
                for label, tree, red in rows:
                    runs[label].append(run_case({**spec, "reduce": red}, tree))
            for label, _, red in rows:
                r = median_run(runs[label])
                if args.json:
                    print(json.dumps({"case": name, "reduce": red, "row": label,
                                      "all_seconds": [x["seconds"] for x in runs[label]],
                                      "all_cpu": [x["cpu"] for x in runs[label]], **r}))
                    continue
                print(f"{name:<36} {label:<14} {r['status']:<11} {r['states']:>11,} "
                      f"{r['transitions']:>12,} {r['seconds']:>8.2f} {r['cpu']:>8.2f} "
                      f"{r['sps']:>9,.0f} {r['peak'] / 2**20:>9,.0f}", flush=True)


if __name__ == "__main__":
    main()
