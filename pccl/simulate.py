"""``pccl simulate``: many seeded runs, their outcomes and how to reproduce each.

Run ``k`` uses seed ``seed + k`` exactly as ``pccl run --seed`` does (one
generator for the choice of transitions and for ``rand``, seeded afresh), so
the command printed for an outcome reproduces it.
"""

from __future__ import annotations

import random
import shlex
import statistics
from collections import OrderedDict
from dataclasses import dataclass, field

from . import display as D
from .layout import TIME
from .runner import run as _run


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
             on_run=None) -> "OrderedDict[tuple, Outcome]":
    """``model`` must draw rand from ``rng`` (make_model(..., rng=rng))."""
    out: "OrderedDict[tuple, Outcome]" = OrderedDict()
    for k in range(runs):
        s = seed + k
        rng.seed(s)
        res = _run(model, seed=s, max_steps=max_steps, rng=rng)
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
                rates=(), events="any", collisions=False, overrides=(), max_time=100,
                max_steps=100_000) -> str:
    q = shlex.quote
    parts = ["pccl", "run", q(str(program))]
    if world:
        parts += ["--world", q(str(world))]
    if blackbox != "straight":
        parts += ["-b", q(blackbox)]
    if agents is not None:
        parts += ["--agents", str(agents)]
    if delta != 1:
        parts += ["--delta", str(delta)]
    if n0 != 1:
        parts += ["--n0", str(n0)]
    for a, r in rates:
        parts += ["--rate", f"{a}={r}"]
    if events != "any":
        parts += ["--events", events]
    if collisions:
        parts += ["--collisions"]
    for name, expr in overrides:
        parts += ["--set", q(f"{name}={expr}")]
    if max_time != 100:
        parts += ["--max-time", str(max_time)]
    if max_steps != 100_000:
        parts += ["--max-steps", str(max_steps)]
    parts += ["--seed", str(seed)]
    return " ".join(parts)


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
