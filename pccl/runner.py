"""One execution of a PCCL program (``pccl run``).

Transitions are chosen among the enabled ones with a seeded generator, and
``rand`` is sampled from the same generator, so the same seed gives the same
run.  The run ends when every agent has exited, in a terminal state, at
``--max-time``, at the first violation (stuck agent, failed assertion,
invariant, collision), or when one time step takes more than ``--max-steps``
transitions (an event that never ends, such as ``while (true)``).
"""

from __future__ import annotations

import itertools
import random
from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Optional


@dataclass
class RunResult:
    status: str                 # final | bounded | deadlock | violation | max-steps
    message: str
    exit_status: int
    final: tuple                # the last configuration
    steps: int
    trace: list = field(default_factory=list)     # [(label, before, after)] if recorded
    summary: list = field(default_factory=list)   # [(time, state)] after each environment step
    violations: list = field(default_factory=list)
    looping_agent: Optional[int] = None
    model: Any = None

    @property
    def final_state(self):
        """The last configuration as a named view (:class:`~pccl.results.StateView`:
        ``res.final_state.agents[0].variables["inCs"]``), as ``pccl run`` prints it;
        ``final`` is the raw configuration."""
        from .results import StateView
        if self.model is None:
            raise ValueError("this RunResult has no model (pccl.api.run sets it)")
        return StateView.of(self.model, self.final)


def run(model, *, seed: int = 0, max_steps: int = 100_000, record_trace: bool = False,
        rng: Optional[random.Random] = None, on_step=None) -> RunResult:
    """Execute ``model`` once.  ``model`` must have been built with a
    ``rand_policy`` if rand should be sampled (see :func:`pccl.api.make_model`);
    otherwise all rand outcomes are successors and one is picked at random."""
    rng = rng or random.Random(seed)
    gen = iter(model.init_states())
    inits = list(itertools.islice(gen, 2))
    if len(inits) > 1:          # no rand policy: every outcome is an initial state
        inits.extend(gen)
    st = inits[0] if len(inits) == 1 else rng.choice(inits)
    trace, summary = [], [(st[0], st)]
    steps = 0
    n_env, stride = 0, 1
    since_time = 0
    per_agent: Counter = Counter()

    def finish(status, message, code, **kw):
        return RunResult(status, message, code, st, steps, trace, summary, **kw)

    try:
        while True:
            v = model.violations(st)
            if v:
                return finish("violation", "; ".join(x.message for x in v), 1, violations=v)
            succ = model.successors(st)
            if not succ:
                kind = model.terminal_kind(st)
                if kind == "final":
                    return finish("final", "every agent exited", 0)
                if kind == "bounded":
                    return finish("bounded", f"stopped at --max-time {model.max_time}", 0)
                dv = model.deadlock_violation(st)
                return finish("deadlock", dv.message, 1, violations=[dv])
            label, nxt = succ[0] if len(succ) == 1 else succ[rng.randrange(len(succ))]
            if record_trace:
                trace.append((label, st, nxt))
            if on_step is not None:
                on_step(label, st, nxt)
            steps += 1
            rule, agent = label[0], label[1]
            if rule == "TIME ADVANCE":
                since_time = 0
                per_agent.clear()
            elif rule == "DOREACH INVOKE":
                n_env += 1
                if n_env % stride == 0:
                    summary.append((nxt[0], nxt))
                    if len(summary) > SUMMARY_LIMIT:    # bounded memory on long runs:
                        summary[1:] = summary[2::2]     # keep every other one, and
                        stride *= 2                     # record half as often from now on
            else:
                since_time += 1
                if agent is not None:
                    per_agent[agent] += 1
                if since_time > max_steps:
                    st = nxt
                    looping = _looping_agent(model, st, per_agent)
                    return finish("max-steps",
                                  f"agent {looping} runs more than {max_steps} transitions without "
                                  f"letting time advance ({model.describe_k(st[4][looping][0])}); "
                                  f"raise --max-steps if this is intended",
                                  1, looping_agent=looping)
            st = nxt
    except KeyboardInterrupt:   # Ctrl-C or SIGTERM: the run so far, status 130
        return finish("interrupted", f"interrupted after {steps} transitions", 130)


#: The most time steps a run's summary keeps; a longer run's summary is
#: thinned evenly (every 2nd, 4th, ... time step), so memory stays bounded.
SUMMARY_LIMIT = 100_000


def _looping_agent(model, st, per_agent: Counter) -> int:
    """The agent that keeps time from advancing: mid-event with the most steps."""
    best, best_n = None, -1
    for i, ag in enumerate(st[4]):
        mid = ag[0] != model.ctl.empty_pc
        n = per_agent.get(i, 0) + (10 ** 9 if mid else 0)
        if ag[3] == 0 and n > best_n:
            best, best_n = i, n
    return best if best is not None else max(per_agent, key=per_agent.get)
