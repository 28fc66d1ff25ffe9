"""``straight``: each moving agent drives in a straight line toward its
target at ``world.speed`` for the step's duration δ.

Rules, per agent (planar: x and y move, the agent's own z is carried
through unchanged; the robot is treated as a point for the obstacle test):

* no target yet (``target is None``): stays, done = fail = False;
* ``fail`` already set for the current target: stays, fail stays True;
* ``done`` already set: stays, done stays True;
* the closed segment from the position to the target touches an obstacle
  (the agent's ``Motion.obstacles`` plus ``world.obstacles``; a target inside
  or on an obstacle counts): stays, fail = True.  The remaining path is
  checked again at every step, from wherever the agent is;
* the target is within reach, distance <= speed * δ (+1e-9): lands exactly on
  the target, done = True;
* otherwise: moves speed * δ along the segment, both flags False.

Agents do not interact (no robot–robot contact).  Exactly one outcome; no
env state.  Obstacle sets are prepared once (cached by value and identity)
and segment tests are memoised, since ``explore`` calls ``step`` very often.
"""

from __future__ import annotations

import math

from ._geometry import EMPTY, obstacles_of
from .base import Capabilities, Outcome, settled

EPS = 1e-9


class Straight:
    name = "straight"
    uses_time = False
    #: robots are treated alike (no rule reads a robot's number) and a settled
    #: robot stays put, seen by the others as its position (docs/blackboxes.md)
    capabilities = Capabilities(robots_alike=True, settled_robots_hold_still=True)

    def init_env(self, world, n_agents):
        return None

    def step(self, world, motions, env, time, delta):
        reach = world.speed * delta
        wobs = world.obstacles
        positions, done, fail = [], [], []
        for m in motions:
            p, t = m.position, m.target
            held = settled(m)
            if held is not None:
                positions.append(p)
                done.append(held[0])
                fail.append(held[1])
                continue
            x, y = p[0], p[1]
            tx, ty = t[0], t[1]
            obs = obstacles_of(wobs, m.obstacles) if (wobs or m.obstacles) else EMPTY
            if obs is not EMPTY and obs.blocks_segment(x, y, tx, ty):
                positions.append(p)
                done.append(False)
                fail.append(True)
                continue
            z = p[2] if len(p) > 2 else 0.0
            dx, dy = tx - x, ty - y
            d = math.hypot(dx, dy)
            if d <= reach + EPS:
                positions.append((float(tx), float(ty), float(z)))
                done.append(True)
            else:
                k = reach / d
                positions.append((x + dx * k, y + dy * k, float(z)))
                done.append(False)
            fail.append(False)
        return [Outcome(tuple(positions), tuple(done), tuple(fail), None)]


STRAIGHT = Straight()
BLACKBOX = STRAIGHT
