"""Counter saturation (issue 46 part 2): old against new in one run.

    python benchmarks/counters.py              # the quick cases
    python benchmarks/counters.py --full       # also Fischer k=100 and 3 agents (minutes, GiB)
    python benchmarks/counters.py --repeat 3   # medians of 3 alternating runs

"old" is the default before issue 46 part 2 (``--reduce
merge,symmetry,por,dead``), "new" the default now (``--reduce auto``, which
adds ``counters`` where some counter can pass its cap).  Each run is its own
process, alternating old and new so that load on a shared machine hits both
alike; the table shows the median by CPU time, and ``uptime`` before and
after.  Every search runs with ``--all``; "old" of the watchdog cases is
stopped by ``--max-states`` (its state space is infinite).

The cases: the paper's Fischer (``programs/fischer.pccl``, k = 10 and more,
d = 2: its counters are bounded by their own guards, so the reduction
merges nothing there and "new" is "old"; docs/reductions.md says why), and
WATCHDOG below: agent 0 beats a shared counter a few times and stops, the
others count the time steps since the last beat they saw and raise an alarm
past ``T`` (a counter that only grows once the beats stop).
"""

from __future__ import annotations

import argparse
import statistics
import sys

from _baseline import run_explore, uptime

WATCHDOG = """Agent::Watchdog

allwrite:
  int beat = 0;
  int T = 20;
  int alarms = 0;

allread:

loc:
  int id = getAgentIndex();
  int since = 0;
  int last = 0;
  bool alarmed = false;

Beat():
  pre(id == 0 && beat < 3);
  eff:
    atomic:
      beat = beat + 1;

Watch():
  pre(id != 0);
  eff:
    since = since + 1;
    if (last != beat):
      last = beat;
      since = 0;
    if (since > T && !alarmed):
      alarmed = true;
      atomic:
        alarms = alarms + 1;
"""

MUTEX = "count(inCs) <= 1"
CASES = [
    ("fischer k=10, 2 agents", dict(program="programs/fischer.pccl", agents=2, invariants=[MUTEX],
                                    overrides={"k": "10"}), False),
    ("fischer k=30, 2 agents", dict(program="programs/fischer.pccl", agents=2, invariants=[MUTEX],
                                    overrides={"k": "30"}), False),
    ("watchdog T=20, 3 agents", dict(program=WATCHDOG, source=True, agents=3,
                                     invariants=["alarms < 2"]), False),
    ("watchdog T=200, 3 agents", dict(program=WATCHDOG, source=True, agents=3,
                                      invariants=["alarms < 2"], overrides={"T": "200"}), False),
    ("watchdog T=20, 4 agents", dict(program=WATCHDOG, source=True, agents=4,
                                     invariants=["alarms < 3"]), False),
    ("fischer k=10, 3 agents", dict(program="programs/fischer.pccl", agents=3, invariants=[MUTEX],
                                    overrides={"k": "10"}), True),
    ("fischer k=100, 2 agents", dict(program="programs/fischer.pccl", agents=2, invariants=[MUTEX],
                                     overrides={"k": "100"}), True),
]

OLD, NEW = "merge,symmetry,por,dead", "auto"


#: old for a program where symmetry is unsound (WATCHDOG: ``id == 0``)
OLD_NO_SYM = "merge,por,dead"


def run_case(spec: dict, reduce: str, timeout: float, max_states: int) -> dict:
    if reduce == OLD and spec.get("program") == WATCHDOG:
        reduce = OLD_NO_SYM
    return run_explore(dict(spec, reduce=reduce, max_states=max_states, find_all=True), timeout)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="also Fischer k=100 and 3 agents")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per run")
    ap.add_argument("--max-states", type=int, default=2_000_000, help="--max-states of every run")
    a = ap.parse_args(argv)
    print("uptime before:", uptime())
    print(f"{'case':26} {'code':4} {'reductions':34} {'states':>10} {'transitions':>12} "
          f"{'CPU s':>7} {'wall s':>7} {'MiB':>6}  verdict")
    for name, spec, full in CASES:
        if full and not a.full:
            continue
        rows: dict = {"old": [], "new": []}
        for _ in range(a.repeat):
            for code, red in (("old", OLD), ("new", NEW)):
                rows[code].append(run_case(spec, red, a.timeout, a.max_states))
        for code in ("old", "new"):
            rs = [r for r in rows[code] if "cpu" in r]
            if not rs:
                print(f"{name:26} {code:4} {rows[code][0]['status']}")
                continue
            r = sorted(rs, key=lambda x: x["cpu"])[len(rs) // 2]
            print(f"{name:26} {code:4} {r['reductions']:34} {r['states']:>10,} {r['transitions']:>12,} "
                  f"{r['cpu']:>7.1f} {r['wall']:>7.1f} {r['peak_mib']:>6.0f}  {r['status']}: {r['verdict']}")
        old = [r for r in rows["old"] if "cpu" in r]
        new = [r for r in rows["new"] if "cpu" in r]
        if old and new:
            o = statistics.median(r["cpu"] for r in old)
            n = statistics.median(r["cpu"] for r in new)
            print(f"{'':26} new/old: {n / max(o, 1e-9):.2f} of the CPU time, "
                  f"{new[0]['states'] / old[0]['states']:.3f} of the states")
    print("uptime after: ", uptime())
    return 0


if __name__ == "__main__":
    sys.exit(main())
