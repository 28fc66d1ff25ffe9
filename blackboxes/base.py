"""The blackbox interface: how the physical world advances by one step δ.

The engine calls a blackbox once per DOREACH INVOKE, for all agents at once
(physics couples them).  A blackbox is any object with:

* ``name``: a short string shown in every verdict;
* ``uses_time``: True if outcomes depend on absolute time (``t0`` or
  ``time``).  When False (all shipped blackboxes), the explorer may leave the
  clock out of state identity (time abstraction);
* ``init_env(world, n_agents)``: the blackbox's own initial state (hashable,
  e.g. a tuple of velocities; ``None`` when it keeps none);
* ``step(world, motions, env, time, delta)``: a non-empty list of
  :class:`Outcome`.  One outcome is a deterministic controller; several model
  uncertainty and ``explore`` follows them all;
* optionally ``capabilities``, a class attribute: a :class:`Capabilities`
  that promises what ``explore``'s reductions may rely on.  It counts only
  when the object's own class declares it (:func:`declared_capabilities`):
  a subclass, which may change the behaviour, promises nothing until it
  declares it again.

Positions are ``(x, y, z)`` float tuples.  The engine rounds returned
positions to ``world.resolution``.  Obstacles are tuples of polygons, each a
tuple of ``(x, y)`` points; a blackbox must treat both the obstacles passed to
``doReach`` (``Motion.obstacles``) and the world's own static obstacles
(``world.obstacles``) as solid.

Writing your own::

    from pccl.blackboxes.base import Outcome

    class Teleport:
        name = "teleport"
        uses_time = False

        def init_env(self, world, n_agents):
            return None

        def step(self, world, motions, env, time, delta):
            pos = tuple(m.target if m.target is not None else m.position
                        for m in motions)
            done = tuple(m.target is not None for m in motions)
            return [Outcome(pos, done, (False,) * len(motions), None)]

    BLACKBOX = Teleport()      # pccl run prog.pccl --blackbox mymodule:BLACKBOX
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Protocol
from collections.abc import Hashable, Sequence

Position = tuple  # (x, y, z) floats
Polygon = tuple   # ((x, y), ...)


@dataclass(frozen=True)
class Motion:
    """One agent's input to a step.

    ``target`` is None before the agent's first doReach: its controller holds
    it in place and both flags stay false.  ``active`` is False for agents
    that have exited or are stuck (their robot still occupies space; its
    controller still runs toward the last target).
    """
    position: Position
    target: Optional[Position]
    obstacles: tuple
    t0: Optional[float]
    done: bool
    fail: bool
    active: bool = True
    #: for a blackbox that tracks legs (``tracks_legs = True``): where the
    #: robot may really be when its current leg starts, as the blackbox
    #: last set it (``Outcome.starts``, ``retarget``); ``()`` otherwise
    start: tuple = ()


@dataclass(frozen=True)
class Outcome:
    """One possible result of a step, for all agents (same order as motions).
    ``starts`` (blackboxes that track legs): each agent's new leg start
    (``Motion.start``); None leaves them as they are."""
    positions: tuple
    done: tuple
    fail: tuple
    env: Hashable = None
    starts: Optional[tuple] = field(default=None, repr=False)


def settled(m: Motion):
    """``None`` if the controller moves this agent this step; otherwise the
    ``(done, fail)`` flags of an agent that holds its position: one with no
    target (both false), or whose doReach already succeeded or failed (the
    flags stay set until the next doReach resets them)."""
    if m.target is not None and not (m.fail or m.done):
        return None
    return (m.target is not None and m.done and not m.fail, m.target is not None and m.fail)


@dataclass(frozen=True)
class Capabilities:
    """What a blackbox promises about every call of its ``step`` (for every
    world, motions, env, time and δ), which ``explore``'s reductions rely
    on (docs/blackboxes.md, "Writing your own").  Every field defaults to
    False: no promise, the reduction that needs it stays off (for that
    part).  A wrong promise makes verdicts wrong.

    ``robots_alike``: robots are interchangeable: for every permutation π
    of the robots, the outcomes for the motions permuted by π are the
    outcomes permuted by π (nothing depends on a robot's number).  The
    ``symmetry`` reduction needs it (and, where the program moves, an env
    of ``None``).

    ``settled_robots_hold_still``: a *settled* robot (``settled(m)`` is
    not None: no target yet, or its doReach done or failed) ends every
    outcome at its position with the flags ``settled(m)`` gives, and no
    robot's outcome depends on a settled robot's ``target``, ``t0``,
    ``done`` or ``fail`` (only on its position and its ``obstacles``).  The
    ``dead`` reduction needs it to leave a settled robot's target and
    flags out of state identity (pccl.model.dead.blackbox_settled_hold_still);
    ``symmetry`` needs it with ``robots_alike``
    (pccl.model.reduce.blackbox_treats_robots_alike).

    ``arrival_is_fair``: the blackbox may keep a moving robot under way at
    any step (it offers "stay" beside "arrive"), and only as a way of
    exploring every travel time: a run in which a robot whose doReach is
    under way stays under way for ever is not one of its runs.  Liveness
    checks then drop such cycles (fair arrival: docs/temporal.md;
    pccl.model.engine.blackbox_arrival_is_fair).  A blackbox whose robots
    may really move for ever must not declare it."""
    robots_alike: bool = False
    settled_robots_hold_still: bool = False
    arrival_is_fair: bool = False


#: No promise: what a blackbox that declares nothing (or inherits its
#: declaration) gets.
NO_CAPABILITIES = Capabilities()


def declared_capabilities(bb) -> Capabilities:
    """The :class:`Capabilities` blackbox ``bb`` promises: its class's own
    ``capabilities`` (``vars(type(bb))``, not one inherited from a base
    class: a subclass may override ``step`` or what it calls, so it
    promises only what it declares itself), and none when the object
    itself holds a method or a ``capabilities`` of its own (instance
    attributes that replace the class's behaviour or claims)."""
    caps = vars(type(bb)).get("capabilities")
    if not isinstance(caps, Capabilities):
        return NO_CAPABILITIES
    own = getattr(bb, "__dict__", None) or {}
    if "capabilities" in own or any(callable(v) for v in own.values()):
        return NO_CAPABILITIES
    return caps


def tracks_legs(bb) -> bool:
    """Whether blackbox ``bb`` declares that it tracks legs: it has
    ``tracks_legs = True`` and a method ``retarget(position, reach)``.  The
    engine then keeps a per-robot *leg start* in the state (``Motion.start``,
    set by the blackbox's ``Outcome.starts`` and, at every doReach, by
    ``retarget`` from the robot's position and its previous reach cell
    ``(target, obstacles, t0, done, fail, start)``)."""
    return getattr(bb, "tracks_legs", False) is True and callable(getattr(bb, "retarget", None))


class Blackbox(Protocol):
    name: str
    uses_time: bool

    def init_env(self, world, n_agents: int) -> Hashable: ...

    def step(self, world, motions: Sequence[Motion], env: Hashable,
             time: float, delta: float) -> list[Outcome]: ...
