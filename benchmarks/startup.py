"""Start-up: how long the quick commands take, whole process (issue 43, item
4: `pccl --version` under 0.08 s and `pccl check programs/race.pccl` under
0.2 s on this machine, idle).

    python benchmarks/startup.py                      # this checkout only
    python benchmarks/startup.py --baseline REV       # old (a git revision) against new
    python benchmarks/startup.py --repeat 21 --no-bytecode

Each command runs as a process of its own, the way a shell, an editor or a
pre-commit hook runs `pccl`: `python -c "from pccl.cli import main; main()"
ARGS` (what the `pccl` console script does) with the code of the revision on
`sys.path` and nothing else of the checkout (the working tree's `pccl/`,
`semantics/` and `blackboxes/` are copied to a temporary directory, as
`git archive REV` is for the baseline).  Old and new alternate, after one
warm-up run each; the table gives the best and the median wall time and the
median and the best CPU time (user + system of the child: on a busy
machine, the figures to compare); the load average is printed before and
after.  `--imports N` adds, for each version, the N modules that take longest
to import on the `--version` and `check` paths (``python -X importtime``,
each module's own time, the best of the runs).

By default the copies keep their compiled bytecode (`__pycache__`, written
by the warm-up), as an installed wheel does; `--no-bytecode` measures with
`PYTHONDONTWRITEBYTECODE=1` and no bytecode, where every import compiles its
module (how a checkout runs when that variable is set, as on this project's
machines).  The parser's table cache ($PCCL_CACHE) is the user's, warm after
the warm-up, for both.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

from _baseline import run_pccl
from _baseline import versions as baseline_versions

ROOT = Path(__file__).resolve().parent.parent
RACE = str(ROOT / "programs" / "race.pccl")
FISCHER = str(ROOT / "programs" / "fischer.pccl")
#: (label, arguments, goal in seconds or None)
COMMANDS = [
    ("pccl --version", ["--version"], 0.08),
    ("pccl check race.pccl", ["check", RACE], 0.2),
    ("pccl explore fischer k=1", ["explore", FISCHER, "--set", "k=1", "--invariant", "count(inCs) <= 1"], None),
]


def once(tree: str, args: list[str], env: dict, cwd: str) -> tuple[float, float]:
    """One run: (wall s, the child's user + system CPU s)."""
    return run_pccl(tree, args, env, cwd)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", metavar="REV", help="compare against this git revision")
    ap.add_argument("--repeat", type=int, default=20, help="runs per command and version [20]")
    ap.add_argument("--imports", type=int, default=0, metavar="N",
                    help="also list the N slowest imports of --version and check (-X importtime)")
    ap.add_argument("--no-bytecode", action="store_true",
                    help="PYTHONDONTWRITEBYTECODE=1 and no __pycache__: every import compiles")
    args = ap.parse_args()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    if args.no_bytecode:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
    else:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
    with tempfile.TemporaryDirectory(prefix="pccl-startup-") as tmp:
        versions = baseline_versions(tmp, args.baseline)
        print(f"python {sys.version.split()[0]}, load average {os.getloadavg()[0]:.2f}, "
              f"{'no bytecode' if args.no_bytecode else 'bytecode cached'}, {args.repeat} runs each")
        print(f"{'command':<28} {'version':<12} {'best s':>8} {'median s':>9} {'CPU s':>7} {'best CPU':>8}"
              f"  goal (wall median)")
        missed = 0
        for label, cargs, goal in COMMANDS:
            times: dict[str, list[tuple[float, float]]] = {name: [] for name, _ in versions}
            for _, tree in versions:
                once(tree, cargs, env, tmp)                 # warm-up: bytecode, the parser's cache
            for _ in range(args.repeat):
                for name, tree in versions:                 # alternating
                    times[name].append(once(tree, cargs, env, tmp))
            for name, _ in versions:
                walls = [w for w, _ in times[name]]
                best, med = min(walls), statistics.median(walls)
                cpu = statistics.median(c for _, c in times[name])
                cpu_best = min(c for _, c in times[name])
                verdict = ""
                if goal is not None and name == "new":
                    verdict = f"< {goal} s: {'met' if med < goal else 'NOT met'}"
                    missed += med >= goal
                print(f"{label:<28} {name:<12} {best:>8.3f} {med:>9.3f} {cpu:>7.3f} {cpu_best:>8.3f}  {verdict}")
        print(f"load average after: {os.getloadavg()[0]:.2f}")
        if args.imports:
            for label, cargs, _ in COMMANDS[:2]:
                for name, tree in versions:
                    print(f"\n{label}, {name}: the {args.imports} slowest imports (self ms, best of {args.repeat})")
                    for ms, module in slowest_imports(tree, cargs, env, tmp, args.repeat)[:args.imports]:
                        print(f"  {ms:7.2f}  {module}")
        return 1 if missed else 0


def slowest_imports(tree: str, args: list[str], env: dict, cwd: str, runs: int) -> list[tuple[float, str]]:
    """``[(ms, module)]``, slowest first: each module's own import time
    (``-X importtime``'s "self" column, without its imports), the best of
    ``runs`` runs of ``pccl ARGS`` with the package of ``tree``."""
    import re
    import subprocess
    from _baseline import CHILD
    best: dict[str, int] = {}
    for _ in range(runs):
        p = subprocess.run([sys.executable, "-X", "importtime", "-c", CHILD, tree, *args], env=env,
                           cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        for m in re.finditer(r"^import time:\s+(\d+) \|\s+\d+ \| *(\S+)$", p.stderr, re.M):
            best[m[2]] = min(best.get(m[2], 1 << 62), int(m[1]))
    return sorted(((us / 1000, mod) for mod, us in best.items()), reverse=True)


if __name__ == "__main__":
    raise SystemExit(main())
