"""The differential oracle of issue 41 (docs/oracle.md): generated programs
explored in every configuration, compared with the truth, disagreements
shrunk and written with the commands that show them.

    python -m tests.differential --n 200 --seed 7 --budget 300 --modes all
"""

from __future__ import annotations

import json
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Optional

from . import gen, oracle, shrink


@dataclass
class Summary:
    programs: int = 0
    inconclusive: int = 0
    invalid: int = 0
    agreements: int = 0
    modes: Counter = field(default_factory=Counter)
    families: Counter = field(default_factory=Counter)
    truth: Counter = field(default_factory=Counter)
    disagreements: list = field(default_factory=list)
    findings: list = field(default_factory=list)
    seconds: float = 0.0
    stopped_by_budget: bool = False

    def unknown(self) -> list:
        return [d for d in self.disagreements if not d.known]

    def text(self) -> str:
        lines = [f"programs {self.programs} ({dict(self.families)}), truth verdicts {dict(self.truth)}, "
                 f"inconclusive (truth bounded) {self.inconclusive}, invalid {self.invalid}",
                 f"mode runs {sum(self.modes.values())}: {dict(sorted(self.modes.items()))}",
                 f"agreements {self.agreements}, disagreements {len(self.disagreements)} "
                 f"({len(self.unknown())} not a known open hole), {self.seconds:.0f} s"
                 + (" (stopped by --budget)" if self.stopped_by_budget else "")]
        for d in self.disagreements:
            lines.append(f"  seed {d.seed} [{d.family}] {d.check} {d.mode} vs {d.against or 'truth'}"
                         f"{' — ' + d.known if d.known else ' — NEW'}: "
                         + d.detail.strip().splitlines()[-1][:200])
        for f in self.findings:
            lines.append(f"  shrunk: {f}")
        return "\n".join(lines)


def run(n: int, seed: int = 0, budget: Optional[float] = None, modes="all", sample: int = 0,
        families=None, findings: Optional[str] = None, shrink_budget: float = 60.0,
        progress=None) -> Summary:
    """Generate ``n`` programs from ``seed`` on and compare each in ``modes``
    (or the truth, the default and ``sample`` modes drawn per program);
    stop early after ``budget`` seconds.  With ``findings``, shrink each
    disagreement not seen before (by check and mode) and write it there."""
    s = Summary()
    t0 = time.monotonic()
    seen: set = set()
    for k in range(seed, seed + n):
        if budget is not None and time.monotonic() - t0 > budget:
            s.stopped_by_budget = True
            break
        case = gen.case(k, families)
        rep = oracle.compare(case, oracle.choose_modes(modes, k, sample))
        s.programs += 1
        s.families[case.family] += 1
        truth = rep.outcomes.get("truth")
        s.truth[truth.status if truth else "?"] += 1
        if truth and truth.status == "invalid":
            s.invalid += 1
        s.inconclusive += rep.inconclusive
        s.agreements += rep.agreements
        s.modes.update(m for m, o in rep.outcomes.items() if o.status != "n/a")
        s.disagreements += rep.disagreements
        if findings:
            for d in rep.disagreements:
                # a known hole is shrunk once, a new disagreement once per check and mode
                sig = (d.check, d.known) if d.known else (d.check, d.mode)
                if sig in seen:
                    continue
                seen.add(sig)
                small = shrink.shrink(case, d, shrink_budget)
                s.findings.append(shrink.write_finding(findings, small, d, case))
        if progress:
            progress(k, case, rep)
    s.seconds = time.monotonic() - t0
    return s


def summary_json(s: Summary) -> str:
    return json.dumps({"programs": s.programs, "inconclusive": s.inconclusive,
                       "agreements": s.agreements, "modes": s.modes, "families": s.families,
                       "truth": s.truth, "seconds": round(s.seconds, 1),
                       "disagreements": [vars(d) for d in s.disagreements],
                       "findings": s.findings}, indent=1, default=lambda o: sorted(o, key=str))
