"""Counterexample lengths under the default reductions against `--reduce
none` (issue 44, point 3: the default counterexample within 10 % of the
unreduced search's shortest, on every shipped and test program).

    python benchmarks/shorten.py                   # every program, one table
    python benchmarks/shorten.py --max-states 300000 race fischer   # a subset (substrings)

For every program of `programs/`, `programs/koord/`, `tests/programs/`,
`tests/programs/covering/` and `docs/examples/` (with the world of the same
name when there is one), and for the documented property cases below, it
explores three times through the API: the default (reductions, the
counterexample shortened against the unreduced semantics), `shorten=False`
(the reduced search's own path) and `reduce="none"`; each within
`--max-states` states.  It prints the steps of each first counterexample (a
lasso as `stem+cycle`), what shortening did, the seconds of the default and
of `--no-shorten` (the cost of shortening is their difference) and whether
the default is within 10 % of `--reduce none`; a program without a
violation is listed as clean.  The exit status is 1 when a program misses
the target (a `--reduce none` search that does not finish cannot be
compared: `n/a`).
"""
from __future__ import annotations

import argparse
import glob
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: cases with options (the docs' temporal examples, Fischer's mutex, the issue's loop)
CASES = [
    ("programs/fischer.pccl", dict(overrides={"k": "1"}, invariants=("count(inCs) <= 1",))),
    ("tests/programs/token_keep.pccl", dict(agents=3, properties=("forall i: want[i] ~> has[i]",))),
    ("tests/programs/rdv_meet.pccl", dict(world="tests/programs/rdv_wall.toml", blackbox="straight",
                                          properties=("eventually forall i: exited[i]",))),
    ("tests/programs/rdv_meet.pccl", dict(world="tests/programs/rdv_open.toml",
                                          properties=("eventually forall i: exited[i]",))),
    ("docs/examples/lost_update.pccl", dict(invariants=("forall i: rounds[i] <= 2", "total <= 2 * N"),
                                            deadlock=False, max_states=40)),
]


def cases() -> list:
    out = []
    for pattern in ("programs/*.pccl", "programs/koord/*.koord", "tests/programs/*.pccl",
                    "tests/programs/covering/*.pccl", "docs/examples/*.pccl"):
        for p in sorted(glob.glob(str(ROOT / pattern))):
            w = p.rsplit(".", 1)[0] + ".toml"
            out.append((os.path.relpath(p, ROOT), dict(world=os.path.relpath(w, ROOT))
                        if os.path.exists(w) else {}))
    return out + CASES


def one(program: str, kw: dict, max_states: int, **more):
    from pccl import api
    from pccl.lang.errors import PcclError
    kw = {"max_states": max_states, **kw, **more}
    t = time.perf_counter()
    try:
        res = api.explore(str(ROOT / program), **kw)
    except PcclError as e:
        return None, str(e).splitlines()[0], 0.0
    return res, None, time.perf_counter() - t


def steps(res) -> str:
    if res is None or res.status != "violation" or res.counterexamples[0].trace is None:
        return "clean" if res is not None else "error"
    cx = res.counterexamples[0]
    n = len(cx.trace)
    return str(n) if cx.cycle_start is None else f"{cx.cycle_start}+{n - cx.cycle_start}"


def length(res):
    if res is None or res.status != "violation" or res.counterexamples[0].trace is None:
        return None
    return len(res.counterexamples[0].trace)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-states", type=int, default=300_000)
    ap.add_argument("only", nargs="*", help="substrings of the programs to run")
    a = ap.parse_args()
    os.chdir(ROOT)
    print(f"{'program':58} {'kind':10} {'default':>8} {'reduced':>8} {'none':>8}  "
          f"{'shortening':11} {'s':>6} {'s off':>6}  target")
    missed = 0
    for program, kw in cases():
        if a.only and not any(s in program for s in a.only):
            continue
        res, err, sec = one(program, kw, a.max_states)
        if err is not None or length(res) is None:
            continue        # clean or an error: nothing to shorten
        off, _, sec_off = one(program, kw, a.max_states, shorten=False)
        none, _, _ = one(program, kw, a.max_states, reduce="none")
        d, n = length(res), length(none)
        if n is None or none.violation.kind != res.violation.kind:
            verdict = "n/a (--reduce none: " + (none.status if none is not None else "error") + ")"
        elif d <= 1.1 * n:
            verdict = "ok"
        else:
            verdict, missed = "MISSED", missed + 1
        sh = res.counterexamples[0].shortening
        name = program + ("" if not kw or list(kw) == ["world"] else " *")
        print(f"{name:58} {res.violation.kind:10} {steps(res):>8} {steps(off):>8} "
              f"{steps(none):>8}  {sh.status if sh else '-':11} {sec:6.2f} {sec_off:6.2f}  {verdict}",
              flush=True)
    print(f"(* with options: see CASES in {os.path.relpath(__file__, ROOT)}); "
          f"{missed} program(s) missed the 10 % target")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
