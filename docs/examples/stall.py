"""A blackbox of our own (docs/blackboxes.md): robots that may stall.

Each moving robot either advances ``world.speed * delta`` in a straight line
toward its target (landing on it when it is that close) or stalls where it
is for the whole step.  Every combination is an outcome, so ``pccl explore``
covers every pattern of stalls.  A target inside or on an obstacle (the
world's or those passed to doReach) fails at once.

    pccl explore PROGRAM --blackbox docs/examples/stall.py:BLACKBOX
"""

import itertools
import math

import shapely

from pccl.blackboxes.base import Outcome, settled


class Stall:
    name = "stall"          # shown in every verdict
    uses_time = False       # outcomes do not depend on the clock

    def init_env(self, world, n_agents):
        return None         # no state of its own

    def step(self, world, motions, env, time, delta):
        reach = world.speed * delta
        options = []        # per agent: the (position, done, fail) it may end with
        for m in motions:
            held = settled(m)
            if held is not None:        # no target yet, or already done or failed
                options.append([(m.position, *held)])
                continue
            (x, y, z), (tx, ty) = m.position, m.target[:2]
            target = shapely.Point(tx, ty)
            if any(shapely.Polygon(p).intersects(target)
                   for p in world.obstacles + tuple(m.obstacles)):
                options.append([(m.position, False, True)])
                continue
            d = math.hypot(tx - x, ty - y)
            if d <= reach:
                moved = ((tx, ty, z), True, False)
            else:
                f = reach / d
                moved = ((x + (tx - x) * f, y + (ty - y) * f, z), False, False)
            options.append([(m.position, False, False), moved])   # stall, or move
        return [Outcome(positions=tuple(o[0] for o in combo),
                        done=tuple(o[1] for o in combo),
                        fail=tuple(o[2] for o in combo),
                        env=None)
                for combo in itertools.product(*options)]


BLACKBOX = Stall()
