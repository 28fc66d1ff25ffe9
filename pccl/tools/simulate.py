"""``pccl simulate``: many seeded runs, their outcomes and how to reproduce each.

Run ``k`` uses seed ``seed + k`` exactly as ``pccl run --seed`` does (one
generator for the choice of transitions and for ``rand``, seeded afresh), so
the command printed for an outcome reproduces it.
"""

from __future__ import annotations

import math
import random
import shlex
import statistics
from collections import OrderedDict
from dataclasses import dataclass, field

from pccl.output import display as D
from pccl.model.layout import TIME
from pccl.lang.errors import Spelling, keyword_spelling
from pccl.tools.runner import run as _run


@dataclass
class Outcome:
    key: tuple
    label: str
    seeds: list = field(default_factory=list)
    times: list = field(default_factory=list)
    example: str = ""

    @property
    def first_seed(self) -> int:
        return self.seeds[0]


def replay_run(model, rng: random.Random, *, seed: int, max_steps: int = 100_000,
                stall_steps: int = 20, spelling: Spelling = keyword_spelling):
    """Run ``seed`` again, recording its trace: the same run as the one
    :func:`simulate` made with that seed (rand and choices from ``rng``
    seeded afresh)."""
    rng.seed(seed)
    return _run(model, seed=seed, max_steps=max_steps, rng=rng, stall_steps=stall_steps,
                record_trace=True, spelling=spelling)


def outcome_of(model, res) -> tuple:
    """(key, label, example message) of a run's result."""
    if res.status == "violation" and res.violations:
        v = res.violations[0]
        where = f" at line {v.span.line}" if v.span else ""
        if v.kind == "stuck":
            reason = v.message.split(": ", 1)[1] if ": " in v.message else v.message
            reason = reason.split(": ")[0]
            return ("stuck", reason, where), f"stuck: {reason}{where}", v.message
        return (v.kind, v.name, where), f"{v.kind}: {v.name}{where}", v.message
    if res.status == "deadlock":
        return ("deadlock",), "deadlock", res.message
    return (res.status,), res.status, res.message


def simulate(model, rng: random.Random, *, runs: int, seed: int = 0, max_steps: int = 100_000,
             on_run=None, stall_steps: int = 20,
             spelling: Spelling = keyword_spelling) -> "OrderedDict[tuple, Outcome]":
    """``model`` must draw rand from ``rng`` (make_model(..., rng=rng)); ``spelling``
    writes the options the runs' messages name (:func:`pccl.tools.runner.run`)."""
    out: "OrderedDict[tuple, Outcome]" = OrderedDict()
    for k in range(runs):
        s = seed + k
        rng.seed(s)
        res = _run(model, seed=s, max_steps=max_steps, rng=rng, stall_steps=stall_steps,
                   spelling=spelling)
        key, label, example = outcome_of(model, res)
        o = out.get(key)
        if o is None:
            o = out[key] = Outcome(key, label, example=example)
        o.seeds.append(s)
        o.times.append(res.final[TIME])
        if on_run is not None:
            on_run(k, res)
        if res.status == "out-of-memory":       # the next runs would fail alike
            break
    return out


def run_command(program, *, seed, world=None, blackbox="straight", agents=None, delta=1, n0=1,
                rates=(), events="any", semantics=None, skip_events=False, collisions=False,
                overrides=(), max_time=100, lang=None,
                max_steps=100_000, invariants=(), properties=(), stall_steps=20) -> str:
    """The ``pccl run`` command that repeats run ``seed`` exactly: the same
    options, and the same properties (so that it finds the same violation)."""
    q = shlex.quote
    parts = ["pccl", "run", q(str(program))]
    if lang is not None:
        parts += ["--lang", lang]
    if world:
        parts += ["--world", q(str(world))]
    if blackbox not in (None, "", "straight"):
        parts += ["-b", q(str(blackbox))]
    if agents is not None:
        parts += ["--agents", str(agents)]
    if delta != 1:
        parts += ["--delta", str(delta)]
    if n0 != 1:
        parts += ["--n0", str(n0)]
    for a, r in rates:
        parts += ["--rate", f"{a}={r}"]
    parts += _model_flags(events, semantics, skip_events, collisions)
    for name, expr in overrides:
        parts += ["--set", q(f"{name}={expr}")]
    for inv in invariants:
        parts += ["--invariant", q(inv)]
    for prop in properties:
        parts += ["--property", q(prop)]
    if max_time != 100:
        parts += ["--max-time", str(max_time)]
    if max_steps != 100_000:
        parts += ["--max-steps", str(max_steps)]
    if stall_steps != 20:
        parts += ["--stall-steps", str(stall_steps)]
    parts += ["--seed", str(seed)]
    return " ".join(parts)


def _model_flags(events, semantics, skip_events, collisions) -> list:
    """Step of :func:`run_command`: the flags of the events policy, the
    semantics and collisions."""
    parts = []
    if events != "any":
        parts += ["--events", events]
    if semantics is not None:
        parts += ["--semantics", semantics]
    if skip_events:
        parts += ["--skip-events"]
    if collisions:
        parts += ["--collisions"]
    return parts


def wilson(k: int, n: int, z: float = 1.959964) -> tuple:
    """The Wilson score interval (95 % by default) of a proportion k/n: the
    confidence interval of an outcome's frequency that stays inside [0, 1]
    and is not empty at k = 0 or k = n."""
    if n <= 0:
        return (0.0, 1.0)
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (max(0.0, c - h), min(1.0, c + h))


def frequency(k: int, n: int) -> str:
    """``12 runs (6.0%, 95% CI 3.5–10.2%)``"""
    lo, hi = wilson(k, n)
    return (f"{k} run{'s' if k != 1 else ''} ({100 * k / n:.1f}%, "
            f"95% CI {100 * lo:.1f}–{100 * hi:.1f}%)")


def is_bad(o: Outcome) -> bool:
    """A violation (or a run stopped by --max-steps, or stalled): not final or bounded."""
    return o.key[0] not in ("final", "bounded")


def time_summary(times) -> str:
    f = D.fmt_time
    mean = statistics.fmean(times)
    return (f"time min {f(min(times))}, median {f(statistics.median(times))}, "
            f"mean {mean:.2f}, max {f(max(times))}")


def histogram(times, width=40) -> list:
    """Text histogram of completion times: one line per distinct time (at
    most 12 bins)."""
    lo, hi = min(times), max(times)
    values = sorted(set(times))
    if len(values) <= 12:
        bins = [(v, v, sum(1 for t in times if t == v)) for v in values]
    else:
        step = (hi - lo) / 12
        bins = []
        for b in range(12):
            a, z = lo + b * step, lo + (b + 1) * step
            n = sum(1 for t in times if a <= t < z or (b == 11 and t == hi))
            bins.append((a, z, n))
    top = max(n for _, _, n in bins) or 1
    out = []
    for a, z, n in bins:
        lab = D.fmt_time(a) if a == z else f"{a:.1f}–{z:.1f}"
        out.append(f"  t={lab:<10} {n:>6}  {'#' * max(1 if n else 0, round(width * n / top))}")
    return out
