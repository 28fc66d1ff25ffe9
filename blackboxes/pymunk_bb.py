"""``pymunk``: 2-D rigid-body physics for disc robots (docs/blackboxes.md).

Model
-----
* Every agent is a dynamic disc of ``world.radius`` and ``world.mass`` (no
  rotation, no friction, no bounce).  Robots collide with each other; an
  agent that has exited or is stuck still occupies space.
* Obstacles are static and solid for every robot: ``world.obstacles`` plus
  the ``Motion.obstacles`` of every agent (physics is shared).  Convex
  polygons become one ``pymunk.Poly``; non-convex ones are triangulated.
  The arena is not a wall.
* The space is rebuilt from the inputs at every step (no cached contact
  impulses), and δ is split into a fixed number of sub-steps
  (``max(20, ceil(speed * δ / (r / 4)))``), so a step is a pure function of
  its inputs: the same inputs always give the same outcome.

Controller (per agent, at every sub-step)
-----------------------------------------
* Steering: at the start of the step the agent plans a shortest path to its
  target in the visibility graph of the obstacles inflated by the radius
  (see :class:`pccl.blackboxes._geometry.Roadmap`): straight at the target
  when the line is free, otherwise via corners of the inflated obstacles.
  During the step it follows that polyline, passing to the next corner when
  within ``max(r / 2, 2 * speed * dt)`` of the current one.
* Desired velocity: toward the current waypoint at ``speed``; toward the
  final target at ``min(speed, GAIN * distance)`` (GAIN = 6 per time unit).
  A done robot keeps driving to its target (it holds station there).
  Agents with no target, or whose doReach failed, hold still (desired
  velocity 0: they can be pushed, and brake afterwards).
* The velocity moves toward the desired one by at most ``ACCEL * speed * dt``
  per sub-step (ACCEL = 10 per time unit): robots have momentum, which is
  why velocities are part of the env.

Flags
-----
* done: the robot's centre came within ``world.tolerance`` of the target
  (x, y) during the step.  If it is within the tolerance at the end of the
  step it is snapped exactly onto the target and its velocity zeroed.  done
  is sticky until the next doReach (a done robot keeps holding its target).
* fail: immediately (robot held still) if the target lies inside or on an
  obstacle.  Otherwise a step *makes progress* if the remaining path length
  (the planned path's length, from the position at the start of the step
  vs. from the end position rounded to ``world.resolution``) went down by
  more than ``world.resolution``.  A step without progress adds δ to the
  agent's stall time, a step with progress resets it to 0; fail is raised
  when the stall time reaches ``world.no_progress_time`` (with δ = 1 and the
  default 3.0: the third step in a row without progress).  The path length,
  not the straight distance, is measured so that a detour around an
  obstacle counts as progress.  fail is sticky until the next doReach; a
  failed robot holds still.
* no target yet: both flags False.

Env: ``(velocities, stalls)``: per agent ``(vx, vy)`` rounded to
``world.resolution`` (fed back as the initial body velocities of the next
step) and the stall time (rounded to 1e-6; 0 for agents that are not
driving toward an unreached target).  Contacts: collision slop
``SLOP * r``, collision bias ``BIAS``, ``SOLVER_ITERATIONS`` iterations.  Positions are
returned unrounded (the engine rounds them); z is carried through unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from pccl.lang.errors import PcclError, install_hint

from ._geometry import EMPTY, obstacles_of
from .base import Capabilities, Outcome

#: What ``--blackbox pymunk`` says when pymunk is not installed (an extra).
MISSING = "the pymunk blackbox needs pymunk: " + install_hint("physics")


def available() -> bool:
    """Whether pymunk can be imported (without importing it)."""
    import importlib.util
    return importlib.util.find_spec("pymunk") is not None


def require():
    """The pymunk module, imported on first use (it is the optional extra
    ``pccl[physics]``); a PcclError saying how to install it if missing."""
    try:
        import pymunk
    except ImportError:
        raise PcclError(MISSING, filename="--blackbox") from None
    return pymunk

MIN_SUBSTEPS = 20
GAIN = 6.0       # 1 / time unit: proportional approach to the final target
ACCEL = 10.0     # speeds per time unit: maximum acceleration
SOLVER_ITERATIONS = 20
SLOP = 0.01      # allowed contact overlap, in radii
BIAS = 1e-6      # overlap left after one time unit (chipmunk's default 0.9**60)


def _round(x: float, res: float) -> float:
    return round(round(x / res) * res, 9) + 0.0


class Mode(IntEnum):
    """What an agent's body does during one step."""
    HOLD = 0     # no target, or the motion failed: no driving force
    DRIVE = 1    # drive along the planned path toward the target
    DONE = 2     # already done: hold the target


@dataclass
class _Plans:
    """Per-agent plans for one step (lists indexed by agent)."""
    mode: list
    done: list
    fail: list
    paths: list       # the legs (waypoints) to the target, or None
    length0: list     # the path length at the start of the step
    targets: list     # (x, y), or None


class PymunkBlackbox:
    name = "pymunk"
    uses_time = False
    #: no promise: the discs push settled robots and the planner may number
    #: robots (docs/blackboxes.md, "Writing your own")
    capabilities = Capabilities()

    def init_env(self, world, n_agents):
        require()
        return (((0.0, 0.0),) * n_agents, (0.0,) * n_agents)

    # ------------------------------------------------------------------
    def step(self, world, motions, env, time, delta):
        vels, stalls = self._unpack(env, len(motions))
        obs, roadmap = self._obstacles(world, motions)
        plans = self._plan(motions, obs, roadmap)
        if delta <= 0:
            positions = tuple(tuple(float(c) for c in m.position) for m in motions)
            return [Outcome(positions, tuple(plans.done), tuple(plans.fail),
                            (vels, stalls))]
        space, bodies = self._build_space(world, motions, vels, obs)
        reached = self._simulate(world, space, bodies, plans, delta)
        return [self._results(world, motions, bodies, plans, reached, stalls,
                              roadmap, delta)]

    @staticmethod
    def _obstacles(world, motions):
        """The world's obstacles and those the motions name, merged; and
        their roadmap for the robots' radius (None without obstacles)."""
        parts = [world.obstacles]
        for m in motions:
            if m.obstacles and not any(m.obstacles is q or m.obstacles == q
                                       for q in parts):
                parts.append(m.obstacles)
        obs = obstacles_of(*parts) if any(parts) else EMPTY
        roadmap = obs.roadmap(world.radius) if obs is not EMPTY else None
        return obs, roadmap

    @staticmethod
    def _plan(motions, obs, roadmap) -> _Plans:
        """Each agent's mode, flags, path and target."""
        n = len(motions)
        plans = _Plans([Mode.HOLD] * n, [False] * n, [False] * n, [None] * n,
                       [0.0] * n, [None] * n)
        for i, m in enumerate(motions):
            t = m.target
            if t is None:
                continue
            if m.fail:
                plans.fail[i] = True
                continue
            tx, ty = float(t[0]), float(t[1])
            plans.targets[i] = (tx, ty)
            if obs.contains_point(tx, ty):
                plans.fail[i] = True
                continue
            p = (float(m.position[0]), float(m.position[1]))
            if roadmap is not None:
                legs, L = roadmap.path(p, (tx, ty))
            else:
                legs, L = ((tx, ty),), math.hypot(tx - p[0], ty - p[1])
            plans.paths[i] = legs
            plans.length0[i] = L
            if m.done:
                plans.done[i] = True
                plans.mode[i] = Mode.DONE
            else:
                plans.mode[i] = Mode.DRIVE
        return plans

    @staticmethod
    def _build_space(world, motions, vels, obs):
        """A pymunk space with the obstacles (static, frictionless) and one
        disc body per agent at its position and velocity."""
        r = world.radius
        pymunk = require()
        space = pymunk.Space()
        space.gravity = (0.0, 0.0)
        space.iterations = SOLVER_ITERATIONS
        space.collision_slop = SLOP * r
        space.collision_bias = BIAS
        if obs is not EMPTY:
            convex, segments = obs.pymunk_parts()
            sb = space.static_body
            shapes = []
            for verts in convex:
                s = pymunk.Poly(sb, verts)
                s.friction = 0.0
                s.elasticity = 0.0
                shapes.append(s)
            for a, b in segments:
                s = pymunk.Segment(sb, a, b, 0.01)
                s.friction = 0.0
                s.elasticity = 0.0
                shapes.append(s)
            if shapes:
                space.add(*shapes)
        bodies = []
        for i, m in enumerate(motions):
            body = pymunk.Body(world.mass, math.inf)
            body.position = (float(m.position[0]), float(m.position[1]))
            body.velocity = vels[i]
            shape = pymunk.Circle(body, r)
            shape.friction = 0.0
            shape.elasticity = 0.0
            space.add(body, shape)
            bodies.append(body)
        return space, bodies

    @staticmethod
    def _simulate(world, space, bodies, plans: _Plans, delta) -> list:
        """Advance the space by ``delta`` in substeps, steering each driving
        body along its path; which agents came within tolerance of their
        target at some substep."""
        n = len(bodies)
        r, speed, tol = world.radius, world.speed, world.tolerance
        mode, paths, targets = plans.mode, plans.paths, plans.targets
        substeps = max(MIN_SUBSTEPS, math.ceil(speed * delta / (r / 4)))
        dt = delta / substeps
        dv_max = ACCEL * speed * dt
        force_k = world.mass / dt
        switch = max(r / 2, 2 * speed * dt)
        leg = [0] * n
        reached = [False] * n
        pos = [body.position for body in bodies]
        for _ in range(substeps):
            for i in range(n):
                body = bodies[i]
                px, py = pos[i]
                wx = wy = None
                if mode[i]:
                    legs = paths[i]
                    k = leg[i]
                    while k < len(legs) - 1 and math.hypot(
                            legs[k][0] - px, legs[k][1] - py) < switch:
                        k += 1
                    leg[i] = k
                    wx, wy = legs[k]
                if wx is None:
                    dvx, dvy = 0.0, 0.0
                else:
                    dx, dy = wx - px, wy - py
                    d = math.hypot(dx, dy)
                    if d < 1e-12:
                        dvx = dvy = 0.0
                    else:
                        last = leg[i] == len(paths[i]) - 1
                        s = min(speed, GAIN * d) if last else speed
                        dvx, dvy = dx / d * s, dy / d * s
                vx, vy = body.velocity
                ex, ey = dvx - vx, dvy - vy
                e = math.hypot(ex, ey)
                if e > dv_max:
                    ex, ey = ex * dv_max / e, ey * dv_max / e
                # a force (not a velocity write): chipmunk integrates it
                # before solving contacts, so robots never push into each
                # other or into obstacles
                body.force = (ex * force_k, ey * force_k)
            space.step(dt)
            pos = [body.position for body in bodies]
            for i in range(n):
                if mode[i] == Mode.DRIVE and not reached[i]:
                    px, py = pos[i]
                    tx, ty = targets[i]
                    if math.hypot(tx - px, ty - py) <= tol:
                        reached[i] = True
        return reached

    @staticmethod
    def _results(world, motions, bodies, plans: _Plans, reached, stalls, roadmap,
                 delta) -> Outcome:
        """Positions (snapped to the target when within tolerance), the done
        and fail flags, and the next environment (velocities, stall times: a
        driving agent that made no progress for ``no_progress_time`` fails)."""
        res, tol = world.resolution, world.tolerance
        mode, done, fail, targets = plans.mode, plans.done, plans.fail, plans.targets
        positions, new_vels, new_stalls = [], [], []
        for i, m in enumerate(motions):
            body = bodies[i]
            px, py = body.position
            vx, vy = body.velocity
            z = float(m.position[2]) if len(m.position) > 2 else 0.0
            stall = 0.0
            if mode[i]:
                tx, ty = targets[i]
                if reached[i]:
                    done[i] = True
                if math.hypot(tx - px, ty - py) <= tol:
                    done[i] = True
                    px, py, vx, vy = tx, ty, 0.0, 0.0
                elif mode[i] == Mode.DRIVE and not done[i]:
                    q = (_round(px, res), _round(py, res))
                    if roadmap is not None:
                        L1 = roadmap.path(q, (tx, ty))[1]
                    else:
                        L1 = math.hypot(tx - q[0], ty - q[1])
                    if plans.length0[i] - L1 > res:
                        stall = 0.0
                    else:
                        stall = round(stalls[i] + delta, 6)
                        if stall >= world.no_progress_time - 1e-9:
                            fail[i] = True
                            stall = 0.0
            positions.append((float(px), float(py), z))
            new_vels.append((_round(vx, res), _round(vy, res)))
            new_stalls.append(stall)
        env_out = (tuple(new_vels), tuple(new_stalls))
        return Outcome(tuple(positions), tuple(done), tuple(fail), env_out)

    @staticmethod
    def _unpack(env, n):
        try:
            vels, stalls = env
            vels = tuple((float(v[0]), float(v[1])) for v in vels)
            stalls = tuple(float(s) for s in stalls)
            if len(vels) == n and len(stalls) == n:
                return vels, stalls
        except (TypeError, ValueError, IndexError):
            pass
        return ((0.0, 0.0),) * n, (0.0,) * n


PYMUNK = PymunkBlackbox()
BLACKBOX = PYMUNK
