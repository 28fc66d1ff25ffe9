"""How long parsing takes, per shipped program (the goal: under
0.1 s each on this machine; it was a timed unit test, and speed goals live
here, not in tests).

    python benchmarks/parse.py [--repeat N]

Prints, per program, the best of N wall-clock times for ``parse_program``,
and the grammar's build time once.
"""
from __future__ import annotations

import argparse
import gc
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GOAL = 0.1


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        gc.collect()
        gc.disable()
        try:
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        finally:
            gc.enable()
    return min(times)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    from pccl.lang.parser import parse_program
    t0 = time.perf_counter()
    parse_program("")
    print(f"grammar built in {time.perf_counter() - t0:.3f} s")
    over = 0
    print(f"{'program':<28} {'parse s':>8}")
    for path in sorted((ROOT / "programs").glob("*.pccl")):
        src = path.read_text()
        tp = best(lambda src=src, name=str(path): parse_program(src, name), args.repeat)
        flag = "  over the goal" if tp > GOAL else ""
        over += tp > GOAL
        print(f"{path.name:<28} {tp:>8.4f}{flag}")
    print(f"{over} program(s) over {GOAL} s to parse")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
