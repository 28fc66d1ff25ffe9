"""The native engine against the Python engine at equal work (``--reduce
none --no-timelock --no-stall``) on Fischer's protocol, in one run.

    python benchmarks/native.py [--cases 2,2,2 2,1,2 0,2,3] [--repeat 1]

Each case is ``k,d,N``.  Each search runs in its own process (``pccl
explore``, start-up and the native module's compilation included; the
module is cached, so only a first run compiles); the two engines alternate.
Prints states, transitions and depth (which must be equal: a mismatch exits
1) and CPU seconds, median of --repeat, and the speed-up.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import os

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from spin import run_pccl  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["2,2,2", "2,1,2", "0,2,3"])
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args(argv)
    print(f"CPU seconds, median of {args.repeat}")
    print(f"{'case':<14} {'states':>12} {'transitions':>13} {'depth':>6} {'python':>8} "
          f"{'native':>8} {'speed-up':>9}")
    for case in args.cases:
        k, d, n = (int(x) for x in case.split(","))
        runs: dict = {"python": [], "native": []}
        for _ in range(args.repeat):
            for eng in ("python", "native"):
                runs[eng].append(run_pccl(k, d, n, unreduced=True, engine=eng))
        a, b = runs["python"][0][0], runs["native"][0][0]
        if a != b:
            print(f"MISMATCH k={k} d={d} N={n}: python {a} native {b}")
            return 1
        tp = statistics.median(c for _, c in runs["python"])
        tn = statistics.median(c for _, c in runs["native"])
        print(f"k={k} d={d} N={n:<4} {a['states']:>12,} {a['transitions']:>13,} {a['depth']:>6} "
              f"{tp:>8.2f} {tn:>8.2f} {tp / tn:>8.1f}x", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
