"""``nondet``: every travel time, and every failure a physical blackbox
could produce.  ``explore``'s default for programs that move.

Each moving agent, at each step, either stays where it is, or arrives at
its target, or (where ``straight`` or ``pymunk`` could fail it) fails where
it is.  Every combination is an outcome, so ``explore`` covers all travel
times ("never" included: a robot may stay until it fails) and every
``doReach_fail`` of the physical blackboxes.  docs/blackboxes.md has the
"covers" table: what of ``straight`` and ``pymunk`` this includes, and what
it leaves out (positions in mid-motion).

Rules, per agent (planar: the agent's own z is carried through unchanged):

* no target yet: stays, done = fail = False;
* ``fail`` already set: stays, fail stays True;
* ``done`` already set, or already exactly at the target: stays, done = True;
* target inside an obstacle or on its boundary (``Motion.obstacles`` plus
  ``world.obstacles``): stays, fail = True (the only outcome for it, as
  under every shipped blackbox);
* otherwise the agent is *moving*: it stays (flags False), or jumps to the
  target (done = True), or, if it *may fail*, stays with fail = True.

A moving agent *may fail* (:meth:`Nondet.may_fail`) when any of these
holds, from its position ``p`` to its target ``t``:

* **obstacles**: the segment p–t comes closer than ``max(world.radius,
  world.resolution)`` to an obstacle: the world's, or one passed to any
  agent's doReach (pymunk's obstacles are shared).  ``straight`` fails
  exactly when the segment touches one (distance 0, or a position rounded
  to the resolution grazes one); ``pymunk`` leaves the line only then
  (its planner keeps 0.95 radius off obstacles), and a disc that keeps a
  radius off every obstacle cannot be stopped by one;
* **bodies**: the segment p–t comes closer than ``2 * world.radius`` to
  another robot: to the segment from its position to its target if it is
  moving, else to its position (exited and stuck robots included).
  ``pymunk``'s discs block one another; ``straight``'s robots never do;
* **slow steps**: ``world.speed * δ < 10 * world.resolution``, where
  ``pymunk``'s stall detector (progress of more than one resolution per
  step) may fail a robot on free ground.

``nondet-fail`` (:data:`NONDET_FAIL`) is the most general variant: every
moving agent may fail at every step, whatever the geometry (for physics
that is not modelled at all).

Outcome order: per moving agent the choices "stay", "arrive", then "fail"
(when it may fail); the outcomes are their product in agent order, the
first agent the most significant (outcome 0: all stay).  No env state.
"""

from __future__ import annotations

import itertools

from ._geometry import obstacles_of, segment_distance
from .base import Capabilities, Outcome, settled

#: ``speed * δ`` below this many resolutions: pymunk's stall detector may
#: fail any moving robot.
SLOW_STEPS = 10.0


class Nondet:
    name = "nondet"
    uses_time = False
    #: robots are treated alike (no rule reads a robot's number) and a settled
    #: robot stays put, seen by the others as its position (docs/blackboxes.md)
    capabilities = Capabilities(robots_alike=True, settled_robots_hold_still=True)
    #: nondet-fail: every moving agent may fail at every step.
    always_fail = False

    def __init__(self, name: str = "nondet", always_fail: bool = False):
        self.name = name
        self.always_fail = always_fail

    def __repr__(self) -> str:
        return f"<blackbox {self.name}>"

    def init_env(self, world, n_agents):
        return None

    def step(self, world, motions, env, time, delta):
        options: list[list[tuple]] = []   # per agent: the (position, done, fail) it may end with
        moving = []       # agents that move this step
        wobs = world.obstacles
        for i, m in enumerate(motions):
            p, t = m.position, m.target
            held = settled(m)
            if held is not None:
                options.append([(p, held[0], held[1])])
                continue
            if obstacles_of(wobs, m.obstacles).contains_point(float(t[0]), float(t[1])):
                options.append([(p, False, True)])
                continue
            if p[0] == t[0] and p[1] == t[1]:
                options.append([(p, True, False)])
                continue
            z = float(p[2]) if len(p) > 2 else 0.0
            options.append([(p, False, False), ((float(t[0]), float(t[1]), z), True, False)])
            moving.append(i)
        for i in moving:
            if self.may_fail(world, motions, i, delta):
                options[i].append((motions[i].position, False, True))
        return [Outcome(tuple(o[0] for o in combo), tuple(o[1] for o in combo),
                        tuple(o[2] for o in combo), None)
                for combo in itertools.product(*options)]

    def may_fail(self, world, motions, i: int, delta: float) -> bool:
        """Whether a physical blackbox (``straight``, ``pymunk``) could fail
        moving agent ``i`` (see the module docstring)."""
        if self.always_fail:
            return True
        if world.speed * delta < SLOW_STEPS * world.resolution:
            return True
        m = motions[i]
        p, t = m.position, m.target
        obs = obstacles_of(world.obstacles, *(q.obstacles for q in motions))
        if obs.near_segment(float(p[0]), float(p[1]), float(t[0]), float(t[1]),
                            max(world.radius, world.resolution)):
            return True
        reach = 2.0 * world.radius
        for j, q in enumerate(motions):
            if j == i:
                continue
            end = q.target if q.target is not None and settled(q) is None else q.position
            if segment_distance(p, t, q.position, end) < reach:
                return True
        return False


NONDET = Nondet()
NONDET_FAIL = Nondet("nondet-fail", always_fail=True)
BLACKBOX = NONDET
