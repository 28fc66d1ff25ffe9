"""How long the language server's check of a large document takes (issue 42,
hole 5: a 60,000-line document got no answer within 14 s; the goal is well
under 5 s).

    python benchmarks/lsp_large.py [LINES ...]

For each size (default 10,000, 30,000 and 60,000 lines of the program
tests/test_lsp_robust.py generates: a quarter shared declarations, the rest
events of five lines), prints the wall-clock and CPU seconds of
``pccl.tools.lsp.analyse`` (parse, check, index) in a process that already
holds a 20,000-line analysis (as a server holding open documents does), and
the CPU seconds per 10,000 lines: constant when checking is linear.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))


def main(argv: list) -> None:
    from test_lsp_robust import generated
    from pccl.tools.lsp import analyse
    sizes = [int(a) for a in argv] or [10_000, 30_000, 60_000]
    keep = [analyse(generated(20_000), "/nowhere/keep.pccl")]
    for n in sizes:
        text = generated(n)
        w, c = time.perf_counter(), time.process_time()
        an = analyse(text, f"/nowhere/g{n}.pccl")
        w, c = time.perf_counter() - w, time.process_time() - c
        keep.append(an)
        print(f"{n:>7,} lines: {w:6.2f} s wall, {c:6.2f} s CPU, "
              f"{c / n * 10_000:5.2f} s CPU per 10,000 lines"
              f"{'' if not an.diagnostics else ' (diagnostics!)'}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
