"""``nondet``: each moving agent either arrives at its target or stays put;
every combination is an outcome, so ``explore`` covers all travel times
(including "never": a verdict under ``nondet`` holds whatever the speeds).

Rules, per agent (planar: the agent's own z is carried through unchanged):

* no target yet: stays, done = fail = False;
* ``fail`` already set: stays, fail stays True;
* ``done`` already set, or already exactly at the target: stays, done = True;
* target inside an obstacle or on its boundary (``Motion.obstacles`` plus
  ``world.obstacles``): stays, fail = True (the only outcome for it; the
  path itself is not checked);
* otherwise the agent is *moving*: it either stays (flags False) or jumps to
  the target (done = True).

With m moving agents there are 2**m outcomes, in a fixed order: binary
counting over the moving agents in agent order, "stay" before "arrive",
the first agent the most significant (outcome 0: all stay; last: all
arrive).  No env state.
"""

from __future__ import annotations

import itertools

from ._geometry import obstacles_of
from .base import Outcome, settled


class Nondet:
    name = "nondet"
    uses_time = False

    def init_env(self, world, n_agents):
        return None

    def step(self, world, motions, env, time, delta):
        base_pos, base_done, base_fail = [], [], []
        arrive = {}   # agent index -> arrival position
        wobs = world.obstacles
        for i, m in enumerate(motions):
            p, t = m.position, m.target
            base_pos.append(p)
            held = settled(m)
            if held is not None:
                base_done.append(held[0])
                base_fail.append(held[1])
                continue
            if obstacles_of(wobs, m.obstacles).contains_point(float(t[0]), float(t[1])):
                base_done.append(False)
                base_fail.append(True)
                continue
            z = float(p[2]) if len(p) > 2 else 0.0
            if p[0] == t[0] and p[1] == t[1]:
                base_done.append(True)
            else:
                base_done.append(False)
                arrive[i] = (float(t[0]), float(t[1]), z)
            base_fail.append(False)
        fail = tuple(base_fail)
        movers = list(arrive)
        outcomes = []
        for choice in itertools.product((False, True), repeat=len(movers)):
            pos, done = list(base_pos), list(base_done)
            for i, go in zip(movers, choice):
                if go:
                    pos[i] = arrive[i]
                    done[i] = True
            outcomes.append(Outcome(tuple(pos), tuple(done), fail, None))
        return outcomes


NONDET = Nondet()
BLACKBOX = NONDET
