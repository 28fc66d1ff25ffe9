"""How long checking a large document takes (issue 42, hole 5: a 60,000-line
document got no answer within 14 s; the goal is well under 5 s).

    python benchmarks/lsp_large.py [LINES ...]                  # this checkout only
    python benchmarks/lsp_large.py --baseline REV [LINES ...]   # old (a git revision) against new
    python benchmarks/lsp_large.py --repeat 3 60000

For each size (default 10,000, 30,000 and 60,000 lines of the program
tests/tools/test_lsp_robust.py generates: a quarter shared declarations, the rest
events of five lines), prints

* ``analyse``: the wall-clock and CPU seconds of ``pccl.tools.lsp.analyse``
  (parse, check, index: what the language server does for a document) in a
  process that already holds a 20,000-line analysis (as a server holding
  open documents does), and the CPU seconds per 10,000 lines (constant when
  checking is linear);
* ``pccl check``: the whole command, as a process of its own (start-up
  included): its wall-clock seconds and CPU seconds (user + system).

Each version runs in processes of its own with its code copied to a
temporary directory (this working tree's, or ``git archive REV``'s for the
baseline, as benchmarks/startup.py does); with ``--repeat N`` old and new
alternate and the medians are printed.  On a busy machine (this one is
shared) compare the CPU figures.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _baseline import run_pccl  # noqa: E402

#: in a child: argv = tree, the kept document, the documents to analyse
ANALYSE = """
import json, sys, time
sys.path.insert(0, sys.argv[1])
from pccl.tools.lsp import analyse
keep = [analyse(open(sys.argv[2]).read(), "/nowhere/keep.pccl")]
for path in sys.argv[3:]:
    text = open(path).read()
    w, c = time.perf_counter(), time.process_time()
    an = analyse(text, "/nowhere/" + path.rsplit("/", 1)[-1])
    w, c = time.perf_counter() - w, time.process_time() - c
    keep.append(an)
    print(json.dumps([w, c, len(an.diagnostics)]), flush=True)
"""
def analyse_in(tree: str, keep: str, paths: list[str], env: dict) -> list[list[float]]:
    p = subprocess.run([sys.executable, "-c", ANALYSE, tree, keep, *paths], env=env,
                       capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"analyse in {tree}: exit {p.returncode}\n{p.stderr[-2000:]}")
    return [json.loads(line) for line in p.stdout.splitlines()]


def check_in(tree: str, path: str, env: dict) -> tuple[float, float]:
    """``pccl check PATH`` with the code of ``tree``: (wall s, CPU s)."""
    return run_pccl(tree, ["check", path], env, ok=(0,))


def main() -> int:
    from _baseline import versions as baseline_versions
    from sources import generated
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("lines", nargs="*", type=int, help="sizes [10000 30000 60000]")
    ap.add_argument("--baseline", metavar="REV", help="compare against this git revision")
    ap.add_argument("--repeat", type=int, default=1, help="runs per version [1]")
    args = ap.parse_args()
    sizes = args.lines or [10_000, 30_000, 60_000]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    with tempfile.TemporaryDirectory(prefix="pccl-lsp-large-") as tmp:
        versions = baseline_versions(tmp, args.baseline)
        keep = os.path.join(tmp, "keep.pccl")
        Path(keep).write_text(generated(20_000))
        paths = []
        for n in sizes:
            paths.append(os.path.join(tmp, f"g{n}.pccl"))
            Path(paths[-1]).write_text(generated(n))
        runs: dict = {name: [] for name, _ in versions}
        for _, tree in versions:                        # warm-up: bytecode, the parser's cache
            check_in(tree, paths[0], env)
        for _ in range(args.repeat):
            for name, tree in versions:                 # alternating
                res = analyse_in(tree, keep, paths, env)
                checks = [check_in(tree, p, env) for p in paths]
                runs[name].append((res, checks))
        print(f"python {sys.version.split()[0]}, load average {os.getloadavg()[0]:.2f}, "
              f"{args.repeat} run(s) per version, medians")
        print(f"{'lines':>7} {'version':<12} {'analyse wall':>12} {'CPU s':>6} "
              f"{'CPU/10k':>7}   {'pccl check wall':>15} {'CPU s':>6}")
        for k, n in enumerate(sizes):
            for name, _ in versions:
                aw = statistics.median(r[0][k][0] for r in runs[name])
                ac = statistics.median(r[0][k][1] for r in runs[name])
                diags = max(r[0][k][2] for r in runs[name])
                cw = statistics.median(r[1][k][0] for r in runs[name])
                cc = statistics.median(r[1][k][1] for r in runs[name])
                print(f"{n:>7,} {name:<12} {aw:>10.2f} s {ac:>6.2f} {ac / n * 10_000:>7.2f}   "
                      f"{cw:>13.2f} s {cc:>6.2f}{'  (diagnostics!)' if diags else ''}",
                      flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
