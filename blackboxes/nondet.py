"""``nondet``: every travel time, and every failure a physical blackbox
could produce.  ``explore``'s default for programs that move.

Each moving agent, at each step, either stays where it is, or arrives at
its target, or (where ``straight`` or ``pymunk`` could fail it) fails where
it is.  Every combination is an outcome, so ``explore`` covers all travel
times ("never" included: a robot may stay until it fails) and every
``doReach_fail`` of the physical blackboxes.  docs/blackboxes.md has the
"covers" table: what of ``straight`` and ``pymunk`` this includes.

Rules, per agent (planar: the agent's own z is carried through unchanged):

* no target yet: stays, done = fail = False;
* ``fail`` already set: stays, fail stays True;
* ``done`` already set, or already exactly at the target: stays, done = True;
* target inside an obstacle or on its boundary (``Motion.obstacles`` plus
  ``world.obstacles``): stays, fail = True (the only outcome for it, as
  under every shipped blackbox);
* otherwise the agent is *moving*: it stays (flags False), or jumps to the
  target (done = True), or, if it *may fail*, stays with fail = True.

**Legs** (``tracks_legs``): each robot's reach cell holds a *leg start*,
where it may really be when its current leg starts: ``()`` for exactly at
its position, else the vertices of a convex region.  :meth:`Nondet.retarget`
sets it at every doReach: a robot still moving (re-targeted in mid-motion)
may be anywhere between its start and its old target, so the new leg starts
from the hull of its start, position and old target; a robot at rest keeps
its start.  A failure that ``straight`` could produce leaves the start the
leg it failed on (``straight`` fails part-way), but a leg from exactly its
position whose exact segment is blocked fails where it stands (``straight``
checks before it moves); an arrival resets it to ``()``.  The *region* of a
moving robot is the hull of its start, position and target.

A moving agent *may fail* (:meth:`Nondet.may_fail`) when any of these
holds:

* **straight**: its region comes within ``max(resolution, drift)`` of an
  obstacle (the world's or its own doReach's): ``straight`` re-checks the
  rest of its path from positions rounded to the resolution, which stray
  at most :meth:`Nondet.drift` from the exact region;
* **obstacles** (pymunk): its region comes closer than ``radius +
  tolerance`` to an obstacle, the world's or one passed to any agent's
  doReach (pymunk's obstacles are shared; its planner keeps 0.95 radius off
  obstacles, a robot arrives within ``tolerance``);
* **bodies** (pymunk): its region comes closer than ``2 × (radius +
  tolerance)`` to another robot's (a moving one's region, else its position
  and start; exited and stuck robots included);
* **slow steps**: ``world.speed * δ < 10 * world.resolution``, where
  ``pymunk``'s stall detector (progress of more than one resolution per
  step) may fail a robot on free ground.

What ``nondet`` does not follow is where ``pymunk`` leaves a robot after a
detour, a push or a failure: a program that starts a robot's second leg
gets the verdict "not exhaustive for pymunk" (:func:`pccl.api.not_covered_note`);
``nondet-fail`` covers those legs (every leg may fail at every step).

``nondet-fail`` (:data:`NONDET_FAIL`) is the most general variant: every
moving agent may fail at every step, whatever the geometry (for physics
that is not modelled at all).

Outcome order: per moving agent the choices "stay", "arrive", then "fail"
(when it may fail); the outcomes are their product in agent order, the
first agent the most significant (outcome 0: all stay).  No env state.
"""

from __future__ import annotations

import itertools
import math

from ._geometry import convex_hull, hull_diameter, hulls_distance, obstacles_of
from .base import Capabilities, Outcome, settled

#: ``speed * δ`` below this many resolutions: pymunk's stall detector may
#: fail any moving robot.
SLOW_STEPS = 10.0

class Nondet:
    name = "nondet"
    uses_time = False
    #: robots are treated alike (no rule reads a robot's number) and a settled
    #: robot stays put, seen by the others as its position (docs/blackboxes.md)
    capabilities = Capabilities(robots_alike=True, settled_robots_hold_still=True,
                                arrival_is_fair=True)
    #: nondet-fail: every moving agent may fail at every step.
    always_fail = False
    #: the engine keeps each robot's leg start (``Motion.start``) and calls
    #: :meth:`retarget` at every doReach (blackboxes/base.py)
    tracks_legs = True

    def __init__(self, name: str = "nondet", always_fail: bool = False):
        self.name = name
        self.always_fail = always_fail

    def __repr__(self) -> str:
        return f"<blackbox {self.name}>"

    def init_env(self, world, n_agents):
        return None

    def retarget(self, position, reach) -> tuple:
        """The new leg's start when the robot at ``position`` with reach cell
        ``reach`` (target, obstacles, t0, done, fail, start) is given a new
        doReach: a robot still moving (no flag set) may be anywhere on its
        swept region, its start's hull with its target; one at rest keeps
        its start (``()`` after arrival)."""
        target, _obstacles, _t0, done, fail, start = reach
        if target is None or done or fail:
            return start
        return convex_hull((position,) + tuple(start) + (target,))

    def step(self, world, motions, env, time, delta):
        regions = [self._region(m) for m in motions]
        wobs = world.obstacles
        options: list[list[tuple]] = []   # per agent: (position, done, fail, start)
        movers = []
        for i, m in enumerate(motions):
            p, t, st = m.position, m.target, tuple(m.start)
            held = settled(m)
            if held is not None:
                options.append([(p, held[0], held[1], st)])
                continue
            if obstacles_of(wobs, m.obstacles).contains_point(float(t[0]), float(t[1])):
                options.append([(p, False, True, st)])
                continue
            if p[0] == t[0] and p[1] == t[1] and not st:
                options.append([(p, True, False, ())])
                continue
            z = float(p[2]) if len(p) > 2 else 0.0
            options.append([(p, False, False, st),
                            ((float(t[0]), float(t[1]), z), True, False, ())])
            movers.append(i)
        for i in movers:
            fails, straight = self.hazards(world, motions, regions, i, delta)
            if fails:
                m = motions[i]
                options[i].append((m.position, False, True,
                                   self._fail_start(world, m, regions[i]) if straight
                                   else tuple(m.start)))
        return [Outcome(tuple(o[0] for o in combo), tuple(o[1] for o in combo),
                        tuple(o[2] for o in combo), None, tuple(o[3] for o in combo))
                for combo in itertools.product(*options)]

    @staticmethod
    def _fail_start(world, m, region) -> tuple:
        """Where a robot that ``straight`` fails this step may be: on the leg
        it fails on (``straight`` fails part-way where a rounded position
        grazes an obstacle), except for a leg from exactly its position whose
        exact segment is blocked: ``straight`` fails that one where it stands."""
        p, t = m.position, m.target
        if not m.start and obstacles_of(world.obstacles, m.obstacles).blocks_segment(
                float(p[0]), float(p[1]), float(t[0]), float(t[1])):
            return ()
        return region

    @staticmethod
    def _region(m) -> tuple:
        """Where robot ``m`` may be during the step (the vertices of a convex
        region): a moving robot's leg start with its position and target, a
        robot at rest its position with its start (after a failure part-way:
        the leg it failed on)."""
        pts = (m.position,) + tuple(m.start)
        if settled(m) is None:
            pts += (m.target,)
        return convex_hull(pts)

    @staticmethod
    def drift(world, region, delta) -> float:
        """How far ``straight``'s positions, rounded to the resolution at
        every step, may stray from the exact swept ``region`` (docs/blackboxes.md,
        "Rounding"): each rounding moves a point by at most e = resolution·√2/2,
        and each step pulls the robot back toward its target by a fraction
        k >= reach / (diameter + drift) of its distance, so the drift stays
        below e·(diameter + reach) / (reach − e)."""
        # + 1e-9: the engine also rounds each coordinate to 9 decimals
        e = world.resolution * math.sqrt(0.5) + 1e-9
        reach = world.speed * delta
        if reach <= e:
            return math.inf
        return e * (hull_diameter(region) + reach) / (reach - e) + 1e-9

    def hazards(self, world, motions, regions, i: int, delta: float) -> tuple:
        """(may fail, ``straight`` may fail) for moving agent ``i``: whether a
        physical blackbox (``straight``, ``pymunk``) could fail it this step,
        and whether ``straight`` could (module docstring)."""
        r = regions[i]
        obs = obstacles_of(world.obstacles, *(q.obstacles for q in motions))
        own = obstacles_of(world.obstacles, motions[i].obstacles)
        straight = own.near_points(r, max(world.resolution, self.drift(world, r, delta)))
        if straight or self.always_fail:
            return True, straight
        if world.speed * delta < SLOW_STEPS * world.resolution:
            return True, False
        if obs.near_points(r, world.radius + world.tolerance):
            return True, False
        reach = 2.0 * (world.radius + world.tolerance)
        return any(hulls_distance(r, regions[j]) < reach
                   for j in range(len(motions)) if j != i), False

    def may_fail(self, world, motions, i: int, delta: float) -> bool:
        """Whether a physical blackbox (``straight``, ``pymunk``) could fail
        moving agent ``i`` (see the module docstring)."""
        return self.hazards(world, motions, [self._region(m) for m in motions], i, delta)[0]


NONDET = Nondet()
NONDET_FAIL = Nondet("nondet-fail", always_fail=True)
BLACKBOX = NONDET
