"""``instant``: every moving agent reaches its target at the next step.

Rules, per agent (planar: the target's x and y are reached, the agent's own
z is carried through unchanged):

* no target yet (``target is None``): stays, done = fail = False;
* ``fail`` already set for the current target: stays, fail stays True;
* ``done`` already set: stays, done stays True;
* target inside an obstacle or on its boundary (the agent's
  ``Motion.obstacles`` plus ``world.obstacles``): stays, fail = True;
* otherwise: jumps to the target, done = True.

Exactly one outcome; no env state.
"""

from __future__ import annotations

from ._geometry import obstacles_of
from .base import Capabilities, Outcome, settled


class Instant:
    name = "instant"
    uses_time = False
    #: robots are treated alike (no rule reads a robot's number) and a settled
    #: robot stays put, seen by the others as its position (docs/blackboxes.md)
    capabilities = Capabilities(robots_alike=True, settled_robots_hold_still=True)

    def init_env(self, world, n_agents):
        return None

    def step(self, world, motions, env, time, delta):
        positions, done, fail = [], [], []
        wobs = world.obstacles
        for m in motions:
            p, t = m.position, m.target
            held = settled(m)
            if held is not None:
                positions.append(p)
                done.append(held[0])
                fail.append(held[1])
                continue
            obs = obstacles_of(wobs, m.obstacles)
            if obs.contains_point(float(t[0]), float(t[1])):
                positions.append(p)
                done.append(False)
                fail.append(True)
            else:
                positions.append((float(t[0]), float(t[1]), float(p[2]) if len(p) > 2 else 0.0))
                done.append(True)
                fail.append(False)
        return [Outcome(tuple(positions), tuple(done), tuple(fail), None)]


INSTANT = Instant()
BLACKBOX = INSTANT
