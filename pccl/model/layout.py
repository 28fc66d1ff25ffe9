"""The configuration: the one place that knows the layout of a PCCL state.

A configuration (the paper's K configuration, docs/architecture.md "The
configuration") is a nested tuple — compact, immutable, hashable::

    state = (time, phase, lockQueue, shared, agents, env)
    agent = (pc, counter, lockState, status, locals, allread, position, reach)
    reach = (target, obstacles, t0, doReach_done, doReach_fail, leg start)

Every other module reads and rebuilds configurations through this module:

* **index constants** (``st[AGS]``, ``ag[STATUS]``, ``ag[REACH][DONE]``) for
  reading a cell;
* **let-style helpers** (``with_pc(ag, pc)``, ``put_agent(st, i, ag)``, as
  pyk's ``let``) for a configuration with some cells replaced;
* **views** (:class:`State`, :class:`Agent`, :class:`Reach`, named tuples
  built by :func:`view`) for display, plots, tests and the API.

Hot paths (the rule kernel ``semantics/rules.py``, generated code) keep plain
tuples: generated code interpolates the constants as numbers, so naming
costs nothing there.  Building a view is 2.5–7x the cost of a plain tuple,
so views are never built on a hot path.  A view is a tuple: it is equal to,
and hashes like, the plain configuration it shows.

A configuration is meaningful only together with the :class:`pccl.model.engine.Model`
that made it: ``pc`` is an interned k cell (``CompiledProgram.ctl``), a status of
:data:`STUCK` or more is a key of ``CompiledProgram.stuck_reasons``, and ``locals``,
``allread`` and ``shared`` are indexed by the slots of ``CompiledProgram.layout``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

# -- index constants -----------------------------------------------------------------
# state cells
TIME, PHASE, LQ, SH, AGS, ENV = range(6)
# agent cells
PC, CNT, LCK, STATUS, LOC, AR, POS, REACH = range(8)
# reach cells (the doReach bookkeeping of one agent)
TARGET, OBSTACLES, T0, DONE, FAIL, START = range(6)
N_STATE_CELLS, N_AGENT_CELLS, N_REACH_CELLS = 6, 8, 6

# -- cell values -------------------------------------------------------------------
# phase (the paper's transitionState)
DISCRETE, DYNAMIC = 0, 1
# lockState
IDLE, REQUEST, LOCK = 0, 1, 2
# status: RUNNING, EXITED, or stuck: a code >= STUCK, a key of CompiledProgram.stuck_reasons
RUNNING, EXITED, STUCK = 0, 1, 2

# k items (the cons cells behind a pc, CompiledProgram.ctl): a statement id (>= 0),
# endEventBlock, atomicEnd, or "acquire the lock of atomic statement sid"
END, AEND = -1, -2


def acq(sid: int) -> int:
    """The k item "acquire the lock of atomic statement ``sid``"."""
    return -3 - sid


def is_acquire(item: int) -> bool:
    """Whether a k item is an :func:`acq` marker."""
    return item <= -3


def acquire_sid(item: int) -> int:
    """The atomic statement of an :func:`acq` marker."""
    return -3 - item


#: The reach cell of an agent that has not called doReach.
BLANK_REACH = (None, (), None, False, False, ())


# -- construction and let-style updates (plain tuples) -------------------------------

def make_state(time, phase, lock_queue, shared, agents, env) -> tuple:
    return (time, phase, lock_queue, shared, agents, env)


def make_agent(pc, counter, lock_state, status, locals_, allread, position,
               reach=BLANK_REACH) -> tuple:
    return (pc, counter, lock_state, status, locals_, allread, position, reach)


def with_pc(ag, pc) -> tuple:
    """``ag`` with its k cell replaced."""
    return (pc, ag[1], ag[2], ag[3], ag[4], ag[5], ag[6], ag[7])


def with_counter(ag, counter) -> tuple:
    return (ag[0], counter, ag[2], ag[3], ag[4], ag[5], ag[6], ag[7])


def with_lock(ag, lock_state) -> tuple:
    return (ag[0], ag[1], lock_state, ag[3], ag[4], ag[5], ag[6], ag[7])


def with_status(ag, status) -> tuple:
    return (ag[0], ag[1], ag[2], status, ag[4], ag[5], ag[6], ag[7])


def with_locals(ag, locals_) -> tuple:
    return (ag[0], ag[1], ag[2], ag[3], locals_, ag[5], ag[6], ag[7])


def with_allread(ag, allread) -> tuple:
    return (ag[0], ag[1], ag[2], ag[3], ag[4], allread, ag[6], ag[7])


def with_cell(ag, index: int, value) -> tuple:
    """``ag`` with cell ``index`` (one of the agent constants) replaced."""
    return ag[:index] + (value,) + ag[index + 1:]


def put_agent(st, i, ag2, sh2=None) -> tuple:
    """``st`` with agent i's cell replaced by ``ag2`` (and shared by ``sh2``)."""
    ags = st[4]
    n = len(ags)
    # small teams: build the tuple directly (3-4x cheaper than slicing)
    if n == 2:
        ags = (ag2, ags[1]) if i == 0 else (ags[0], ag2)
    elif n == 3:
        ags = ((ag2, ags[1], ags[2]) if i == 0 else (ags[0], ag2, ags[2]) if i == 1
               else (ags[0], ags[1], ag2))
    else:
        ags = list(ags)      # 2x cheaper than ags[:i] + (ag2,) + ags[i + 1:]
        ags[i] = ag2
        ags = tuple(ags)
    return (st[0], st[1], st[2], st[3] if sh2 is None else sh2, ags, st[5])


def with_lock_queue(st, lock_queue) -> tuple:
    return (st[0], st[1], lock_queue, st[3], st[4], st[5])


def with_shared(st, shared) -> tuple:
    return (st[0], st[1], st[2], shared, st[4], st[5])


def with_agents(st, agents) -> tuple:
    return (st[0], st[1], st[2], st[3], agents, st[5])


def without_time(st) -> tuple:
    """The configuration's identity under time abstraction (``st[PHASE:]``)."""
    return st[1:]


def is_stuck(status) -> bool:
    return status >= STUCK


# -- views (for display, plots, tests and the API; never on a hot path) --------------

class Reach(NamedTuple):
    target: Any          # ItemPosition or None before the first doReach
    obstacles: Any
    t0: Any              # the time of the doReach (None unless recorded)
    done: bool           # doReach_done
    fail: bool           # doReach_fail
    #: where the robot may really be when its current leg starts, for a
    #: blackbox that tracks legs (``tracks_legs``, blackboxes/nondet.py): ()
    #: for "exactly at its position", else the points whose convex hull
    #: holds it; always () otherwise
    start: Any = ()


class Agent(NamedTuple):
    pc: int              # the interned k cell (CompiledProgram.ctl)
    counter: int
    lock_state: int      # IDLE, REQUEST or LOCK
    status: int          # RUNNING, EXITED or a stuck code (>= STUCK)
    locals: tuple        # indexed by the slots of CompiledProgram.layout.local
    allread: tuple       # indexed by the slots of CompiledProgram.layout.allread
    position: tuple      # (x, y, z)
    reach: Reach


class State(NamedTuple):
    time: Any            # an int or float multiple of δ
    phase: int           # DISCRETE or DYNAMIC
    lock_queue: tuple    # agent ids, the holder first
    shared: tuple        # indexed by the slots of CompiledProgram.layout.shared
    agents: tuple        # Agent views
    env: Any             # the blackbox's state


def agent_view(ag) -> Agent:
    """A named view of one agent cell."""
    return Agent(ag[0], ag[1], ag[2], ag[3], ag[4], ag[5], ag[6], Reach(*ag[7]))


def view(st) -> State:
    """A named view of a configuration (equal to it, with the same hash)."""
    return State(st[0], st[1], st[2], st[3], tuple(agent_view(ag) for ag in st[4]), st[5])


def _check_layout() -> None:
    """The constants and the views name the same cells in the same places."""
    assert State._fields == ("time", "phase", "lock_queue", "shared", "agents", "env")
    assert (TIME, PHASE, LQ, SH, AGS, ENV) == tuple(range(len(State._fields))) \
        == tuple(range(N_STATE_CELLS))
    assert (PC, CNT, LCK, STATUS, LOC, AR, POS, REACH) == tuple(range(len(Agent._fields))) \
        == tuple(range(N_AGENT_CELLS))
    assert (TARGET, OBSTACLES, T0, DONE, FAIL, START) == tuple(range(len(Reach._fields))) \
        == tuple(range(N_REACH_CELLS))


_check_layout()
