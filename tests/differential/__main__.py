"""``python -m tests.differential`` (from the repository root) or
``python tests/differential``: run the oracle (docs/oracle.md)."""

from __future__ import annotations

import argparse
import os
import sys

if __package__ in (None, ""):       # python tests/differential
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    __package__ = "tests.differential"
    import tests.differential  # noqa: F401

from . import oracle, run, summary_json  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.differential",
                                 description="differential oracle of pccl explore/run (docs/oracle.md)")
    ap.add_argument("--n", type=int, default=100, help="programs to generate")
    ap.add_argument("--seed", type=int, default=0, help="seed of the first program")
    ap.add_argument("--budget", type=float, default=None, help="stop after this many seconds")
    ap.add_argument("--modes", default="all",
                    help="'all' or a comma-separated list of: " + ", ".join(m.name for m in oracle.MODES))
    ap.add_argument("--sample", type=int, default=0,
                    help="per program the truth, the default and this many modes drawn by the seed")
    ap.add_argument("--families", default=None, help="core,moving,userbb,sym,por,koord,counters,orbit (default: all)")
    ap.add_argument("--findings", default="oracle-findings", help="directory for shrunk disagreements")
    ap.add_argument("--no-shrink", action="store_true", help="report disagreements without shrinking")
    ap.add_argument("--shrink-budget", type=float, default=60.0, help="seconds per shrink")
    ap.add_argument("--json", default=None, help="also write the summary as JSON to this file")
    ap.add_argument("-v", "--verbose", action="store_true", help="one line per program")
    a = ap.parse_args(argv)
    modes = a.modes if a.modes == "all" else ["truth"] + a.modes.split(",")
    unknown = [m for m in (modes if modes != "all" else []) if m not in oracle.BY_NAME]
    if unknown:
        ap.error(f"unknown mode(s) {unknown}")

    def progress(k, case, rep):
        if a.verbose:
            t = rep.outcomes.get("truth")
            print(f"seed {k} [{case.family}] truth {t.status if t else '?'} {t.figures if t else ''}"
                  f"{' inconclusive' if rep.inconclusive else ''}: {rep.agreements} agreements, "
                  f"{len(rep.disagreements)} disagreements", flush=True)
    s = run(a.n, a.seed, a.budget, modes, a.sample,
            a.families.split(",") if a.families else None,
            None if a.no_shrink else a.findings, a.shrink_budget, progress)
    print(s.text())
    if a.json:
        with open(a.json, "w") as f:
            f.write(summary_json(s))
    return 1 if s.unknown() else 0


if __name__ == "__main__":
    sys.exit(main())
