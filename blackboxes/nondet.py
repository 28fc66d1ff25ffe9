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
import math

from ._geometry import convex_hull, hull_diameter, hulls_distance, obstacles_of
from .base import Outcome, settled

#: ``speed * δ`` below this many resolutions: pymunk's stall detector may
#: fail any moving robot.
SLOW_STEPS = 10.0

#: A leg's start when the robot may be anywhere (``Motion.start``): after
#: ``pymunk`` may have carried it off its segment (a detour round an
#: obstacle, a push by another robot).
UNKNOWN_START = ("anywhere",)


class Nondet:
    name = "nondet"
    uses_time = False
    #: nondet-fail: every moving agent may fail at every step.
    always_fail = False
    #: the engine keeps each robot's leg start (``Motion.start``) and calls
    #: :meth:`retarget` at every doReach (blackboxes/base.py)
    tracks_legs = True
    #: whether pymunk's detours and pushes make a robot's start "anywhere"
    pushes = True

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
        if target is None or done or fail or start == UNKNOWN_START:
            return start
        return convex_hull((position,) + tuple(start) + (target,))

    def step(self, world, motions, env, time, delta):
        # where each robot may be during this step: hull points, or None (anywhere)
        regions: list = []
        for m in motions:
            regions.append(self._region(m))
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
            options.append([(p, False, False, st), ((float(t[0]), float(t[1]), z), True, False, ())])
            movers.append(i)
        for i in movers:
            fails, off = self.hazards(world, motions, regions, i, delta)
            off = off and self.pushes
            if off:       # pymunk may carry the robot off its swept region
                p, st = options[i][0][0], UNKNOWN_START
                options[i][0] = (p, False, False, st)
            if fails:
                options[i].append((motions[i].position, False, True,
                                   UNKNOWN_START if off else self._fail_start(world, motions[i],
                                                                              regions[i])))
        # robots at rest that a moving one may push (pymunk): anywhere afterwards
        for j, m in enumerate(motions):
            if not self.pushes or settled(m) is None or regions[j] is None:
                continue
            if any(self._bodies_meet(world, regions[i], regions[j]) for i in movers):
                options[j] = [(q[0], q[1], q[2], UNKNOWN_START) for q in options[j]]
        return [Outcome(tuple(o[0] for o in combo), tuple(o[1] for o in combo),
                        tuple(o[2] for o in combo), None, tuple(o[3] for o in combo))
                for combo in itertools.product(*options)]

    @staticmethod
    def _fail_start(world, m, region):
        """Where a robot that fails this step may be: on the leg it fails on
        (``straight`` fails part-way where a rounded position grazes an
        obstacle), except for a leg from exactly its position whose exact
        segment is blocked: ``straight`` fails that one where it stands."""
        if region is None:
            return UNKNOWN_START
        p, t = m.position, m.target
        if not m.start and obstacles_of(world.obstacles, m.obstacles).blocks_segment(
                float(p[0]), float(p[1]), float(t[0]), float(t[1])):
            return ()
        return region

    @staticmethod
    def _region(m):
        """Where robot ``m`` may be during the step (the hull points), or
        None for anywhere: a moving robot's leg start with its target, a
        robot at rest its start (after a failure part-way: the leg it failed on)."""
        st = tuple(m.start)
        if st == UNKNOWN_START:
            return None
        pts = (m.position,) + st
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
        e = world.resolution * math.sqrt(0.5)
        reach = world.speed * delta
        if reach <= e:
            return math.inf
        return e * (hull_diameter(region) + reach) / (reach - e) + 1e-9

    def _bodies_meet(self, world, a, b) -> bool:
        """Whether robots on the regions ``a`` and ``b`` (None: anywhere) may
        touch under pymunk: closer than two radii (and the arrival tolerance
        each)."""
        if a is None or b is None:
            return True
        return hulls_distance(a, b) < 2.0 * (world.radius + world.tolerance)

    def hazards(self, world, motions, regions, i: int, delta: float) -> tuple:
        """(may fail, may leave its swept region) for moving agent ``i``:
        whether a physical blackbox (``straight``, ``pymunk``) could fail it
        this step, and whether ``pymunk`` could carry it off the region it
        sweeps (module docstring)."""
        r = regions[i]
        if r is None:
            return True, True
        obs = obstacles_of(world.obstacles, *(q.obstacles for q in motions))
        detour = obs.near_points(r, world.radius + world.tolerance)
        bodies = any(self._bodies_meet(world, r, regions[j]) for j in range(len(motions)) if j != i)
        off = detour or bodies
        if off or self.always_fail:
            return True, off
        if world.speed * delta < SLOW_STEPS * world.resolution:
            return True, False
        if obs.near_points(r, max(world.resolution, self.drift(world, r, delta))):
            return True, False
        return False, False

    def may_fail(self, world, motions, i: int, delta: float) -> bool:
        """Whether a physical blackbox (``straight``, ``pymunk``) could fail
        moving agent ``i`` (see the module docstring)."""
        return self.hazards(world, motions, [self._region(m) for m in motions], i, delta)[0]


NONDET = Nondet()
NONDET_FAIL = Nondet("nondet-fail", always_fail=True)
BLACKBOX = NONDET
