"""The native engine at equal work (``--reduce none --no-timelock
--no-stall``) on Fischer's protocol, in one run: beside SPIN BFS (where
``spin`` and a C compiler are installed), beside a baseline checkout of pccl
(``--baseline DIR``, e.g. ``git worktree add /tmp/base <commit>``), and
beside the Python engine (``--python``).  With ``--default``, default
against default: pccl's default search (reductions merge+symmetry+por, the
time-lock and stall checks) beside SPIN DFS with its partial-order
reduction (``-DSAFETY``), the ratio native / SPIN DFS.

    python benchmarks/native.py [--cases 2,2,2 2,1,2 0,2,3] [--repeat 1]
                                [--baseline DIR] [--python] [--default] [--bytecode]

Each case is ``k,d,N``.  Each search runs in its own process (``pccl
explore``, start-up included); the native module is compiled by an untimed
warm-up run first (it is cached, as SPIN's compilation of pan.c is not
counted).  The runs alternate.  Prints states, transitions and depth (which
must be equal: a mismatch exits 1), CPU seconds (median of --repeat) and
the ratio of the native engine to SPIN BFS.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import spin  # noqa: E402


def one(col: str, k: int, d: int, n: int, exe, baseline) -> tuple:
    """One timed run of column ``col``: (pccl's counts, CPU seconds)."""
    if col == "spin BFS":
        st, cpu = spin.run_pan(exe, bfs=True, n=n)
        return spin.spin_counts(st, spin.n_initial(k, n)), cpu
    if col == "spin DFS":
        # SPIN's own counts (its reduction is not pccl's): not compared
        st, cpu = spin.run_pan(exe, bfs=False, n=n)
        return None, cpu
    root = baseline if col == "baseline native" else None
    eng = "python" if col == "python" else "native"
    return spin.run_pccl(k, d, n, unreduced=not DEFAULT, engine=eng, root=root)


#: --default: pccl's default search against SPIN DFS
DEFAULT = False


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["2,2,2", "2,1,2", "0,2,3"])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--baseline", default=None, help="a checkout of pccl to compare with")
    ap.add_argument("--python", action="store_true", help="the Python engine too")
    ap.add_argument("--no-spin", action="store_true", help="no SPIN column")
    ap.add_argument("--default", action="store_true",
                    help="pccl's default search against SPIN DFS (its POR on)")
    ap.add_argument("--bytecode", action="store_true",
                    help="let pccl's processes cache their bytecode (unset "
                         "PYTHONDONTWRITEBYTECODE: an installed package has its .pyc files)")
    args = ap.parse_args(argv)
    if args.bytecode:
        os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    global DEFAULT
    DEFAULT = args.default
    sp = "spin DFS" if DEFAULT else "spin BFS"
    why = None if not args.no_spin else "--no-spin"
    why = why or spin.missing_tools()
    if why:
        print(f"SPIN skipped: {why}")
    cols = [sp] if why is None else []
    if args.baseline:
        cols.append("baseline native")
    cols.append("native")
    if args.python:
        cols.append("python")
    print(f"CPU seconds, median of {args.repeat}; load average at the start "
          f"{os.getloadavg()[0]:.1f}; bytecode cached: "
          f"{'no' if os.environ.get('PYTHONDONTWRITEBYTECODE') else 'yes'}", flush=True)
    print(f"{'case':<14} {'states':>12} {'transitions':>13} {'depth':>6} "
          + " ".join(f"{c:>16}" for c in cols)
          + (f" {'native/SPIN':>11}" if sp in cols else "")
          + (f" {'python/SPIN':>11}" if sp in cols and "python" in cols else ""), flush=True)
    work = tempfile.mkdtemp(prefix="pccl-native-")
    for case in args.cases:
        k, d, n = (int(x) for x in case.split(","))
        exe = None
        if sp in cols:
            exe = spin.build(k, d, n, os.path.join(work, f"k{k}d{d}n{n}"), bfs=not DEFAULT)

        for col in cols:        # the warm-up: the native modules compiled
            if col in ("baseline native", "native"):
                spin.run_pccl(k, d, n, unreduced=not DEFAULT, engine="native",
                              root=args.baseline if col == "baseline native" else None,
                              extra=("--max-states", "10"))
        runs: dict = {c: [] for c in cols}
        for _ in range(args.repeat):
            for col in cols:
                runs[col].append(one(col, k, d, n, exe, args.baseline))
        ref = runs["native"][0][0]
        for col in cols:
            if col != "spin DFS" and runs[col][0][0] != ref:
                print(f"MISMATCH k={k} d={d} N={n}: {col} {runs[col][0][0]} native {ref}")
                return 1
        med = {c: statistics.median(cpu for _, cpu in runs[c]) for c in cols}
        line = (f"k={k} d={d} N={n:<4} {ref['states']:>12,} {ref['transitions']:>13,} "
                f"{ref['depth']:>6} " + " ".join(f"{med[c]:>16.2f}" for c in cols))
        if sp in cols:
            line += f" {med['native'] / med[sp]:>10.2f}x"
            if "python" in cols:
                line += f" {med['python'] / med[sp]:>10.2f}x"
        print(line, flush=True)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
