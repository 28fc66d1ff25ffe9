"""What a model's robots move in: the world, the blackbox and the clock.

:class:`Clock` is time as n·δ (exact in decimal, rounded once to a float;
``--max-time`` as a number of steps).  :class:`Environment` is the world and
the blackbox: the positions rounded to the world's resolution, and the
blackbox's outcomes for DOREACH INVOKE, each checked (the blackbox is user
code, so every failure names it).  The engine (:class:`pccl.model.engine.Model`)
holds one of each and hands their methods to the rules.
"""

from __future__ import annotations

import decimal
import marshal
import math
from typing import Any, NoReturn, Optional

from pccl.blackboxes.base import Motion
from pccl.lang.errors import OptionError, PcclError, keyword_spelling
from pccl.search.fingerprint import check_canonical
from pccl.model.layout import AGS, ENV, POS, REACH, RUNNING, START, STATUS, TIME

_EXACT = decimal.Context(prec=60)


def decimal_of(x) -> decimal.Decimal:
    """``x`` as the decimal it was written as (0.1 is 1/10, not the binary float)."""
    return decimal.Decimal(x) if isinstance(x, int) else decimal.Decimal(repr(float(x)))


def fmt_time(t) -> str:
    return f"{t:g}" if isinstance(t, float) else str(t)


class Clock:
    """Time is n·δ for an integer n, computed exactly in decimal from δ as
    written (0.1 is 1/10), then rounded once to a float; so no δ is too
    small to advance it and 0.1 + 0.2 is 0.3.  ``max_ticks`` is
    ``--max-time`` as a number of steps (None: unbounded)."""

    def __init__(self, delta, max_time) -> None:
        self.delta = delta
        self.max_time = max_time
        self.delta_dec = decimal_of(delta)
        self.max_ticks = (None if max_time is None
                          else int((decimal_of(max_time) / self.delta_dec).to_integral_value(
                              rounding=decimal.ROUND_FLOOR)))
        self._next: dict = {}

    def next_time(self, t):
        """The clock after TIME ADVANCE from ``t`` = n·δ: (n + 1)·δ, exactly
        as a decimal and rounded once to a float (an int when δ is an int);
        None if that is beyond ``--max-time``."""
        try:
            return self._next[t]
        except KeyError:
            pass
        d = self.delta
        nxt: Any
        if type(d) is int and type(t) is int:
            n = t // d
            nxt = t + d
        else:
            with decimal.localcontext(_EXACT):
                n = int((decimal_of(t) / self.delta_dec).to_integral_value())
                nxt = float(self.delta_dec * (n + 1))
            if self.max_ticks is not None and n + 1 > self.max_ticks:
                pass                                    # beyond the bound anyway
            elif not nxt > t or not math.isfinite(nxt):
                raise OptionError(
                    "delta", f"the clock cannot advance from {fmt_time(t)} by δ = {d:g}: "
                    f"time {fmt_time(t)} + δ is not representable as a float")
        if self.max_ticks is not None and n + 1 > self.max_ticks:
            nxt = None
        if len(self._next) >= 1 << 20:
            self._next.clear()
        self._next[t] = nxt
        return nxt


_BLACKBOX_ATTRS = ("name", "uses_time", "init_env", "step")


def load_blackbox_arg(blackbox):
    """The blackbox: a name, or an object with the blackbox protocol
    (default: ``straight``); a bad one is an error naming ``blackbox``."""
    from pccl.blackboxes import load_blackbox
    try:
        if blackbox is None:
            return load_blackbox("straight")
        if isinstance(blackbox, str):          # '' is an error, not the default
            return load_blackbox(blackbox)
        _check_blackbox_object(blackbox)
        return blackbox
    except PcclError as e:
        if e.filename is None:
            e.where = "{blackbox}"          # the option, spelt by the front end
            e.respell(keyword_spelling)
        raise


def _check_blackbox_object(bb):
    missing = [a for a in _BLACKBOX_ATTRS if not hasattr(bb, a)]
    if missing:
        raise PcclError(f"blackbox {bb!r:.60} is not a blackbox (missing {', '.join(missing)}; "
                        "see pccl.blackboxes.base)")
    if not callable(bb.step) or not callable(bb.init_env):
        raise PcclError(f"blackbox '{bb.name}': step and init_env must be methods")


def at_world_file(world, e) -> PcclError:
    """A world function's bad value, at the world file's line and column
    (where the user must fix it), naming the program line that reads it; the
    error as it is when the value does not come from a file."""
    from pccl.lang.world import function_location
    loc = function_location(world, e.function)
    if loc is None:
        return e
    fn, source, line, col, end = loc
    read = f" (read at {e.filename}:{e.line}:{e.column})" if e.line else ""
    return PcclError(f"value of {e.function}(){read} {e.detail}", filename=fn, source=source,
                     line=line, column=col, end_column=end)


class Environment:
    """The world and the blackbox of a team of ``n`` agents, stepped by δ."""

    def __init__(self, world, blackbox, n: int, delta) -> None:
        self.world = world
        self.blackbox = blackbox
        self.N = n
        self.delta = delta
        self._cache: dict = {}
        from pccl.blackboxes.base import tracks_legs
        #: whether the blackbox keeps each robot's leg start (Motion.start)
        self.tracks_legs = tracks_legs(blackbox)
        #: a position's marshal encoding -> the position checked and rounded
        self._rounded: dict = {}

    def step(self, st):
        """The blackbox's outcomes for DOREACH INVOKE: [(positions, done, fail, env,
        starts)]."""
        ags = st[AGS]
        bb = self.blackbox
        ckey = (tuple((ag[POS], ag[REACH], ag[STATUS] == RUNNING) for ag in ags), st[ENV],
                st[TIME] if getattr(bb, "uses_time", False) else None)
        hit = self._cache.get(ckey)
        if hit is not None:
            return hit
        # Motion's fields: the position, the reach cells in order, active
        motions = tuple(Motion(ag[POS], r[0], r[1], r[2], r[3], r[4], ag[STATUS] == RUNNING, r[5])
                        for ag in ags for r in (ag[REACH],))
        outcomes = self.call(st[TIME], "step", self.world, motions, st[ENV], st[TIME],
                             self.delta)
        if isinstance(outcomes, (str, bytes)) or not hasattr(outcomes, "__iter__"):
            self.error(st[TIME], f"step() must return a list of Outcome, got "
                                 f"{_type_of(outcomes)}")
        outcomes = list(outcomes)
        if not outcomes:
            self.error(st[TIME], "step() returned no outcome (it must return at least one)")
        res = []
        seen = set()
        for n, o in enumerate(outcomes):
            r = self._check_outcome(st[TIME], n + 1, o, ags)
            if r not in seen:
                seen.add(r)
                res.append(r)
        if len(self._cache) > 200_000:
            self._cache.clear()
        self._cache[ckey] = res
        return res

    # -- blackbox calls: user code, so every failure names the blackbox ------------------
    def error(self, time, what) -> NoReturn:
        name = getattr(self.blackbox, "name", type(self.blackbox).__name__)
        raise OptionError("blackbox", f"blackbox '{name}' failed at time {fmt_time(time)}: {what}")

    def call(self, time, method, *args):
        try:
            return getattr(self.blackbox, method)(*args)
        except (PcclError, KeyboardInterrupt):
            raise
        except Exception as e:
            self.error(time, f"{method}() raised {type(e).__name__}: {e}")

    def leg_start(self, position, reach) -> tuple:
        """The leg start a doReach gives a robot at ``position`` whose reach
        cell was ``reach``: the blackbox's ``retarget`` when it tracks legs
        (checked like an outcome's), else ()."""
        if not self.tracks_legs:
            return ()
        st = self.call(None, "retarget", position, reach)
        return self._check_start(st, None, "retarget()")

    def _check_start(self, st, time, where) -> tuple:
        if not isinstance(st, tuple):
            self.error(time, f"{where}: a leg start must be a tuple, got {_type_of(st)}")
        self.check_env(st, time, where=where)
        return st

    def _check_outcome(self, time, n, o, ags):
        """One outcome as the engine's tuple, or a PcclError saying what is wrong."""
        N = self.N
        missing = [a for a in ("positions", "done", "fail", "env") if not hasattr(o, a)]
        if missing:
            self.error(time, f"outcome {n} is {_type_of(o)}, not an Outcome "
                             f"(missing {', '.join(missing)})")
        for what in ("positions", "done", "fail"):
            v = getattr(o, what)
            if not isinstance(v, (tuple, list)) or len(v) != N:
                got = f"{len(v)} entries" if isinstance(v, (tuple, list)) else _type_of(v)
                self.error(time, f"outcome {n}: '{what}' must have one entry per agent "
                                 f"({N}), got {got}")
        poss = []
        cache = self._rounded
        for i, p in enumerate(o.positions):
            # a blackbox returns the same few positions over and over: each is
            # checked and rounded once, memoised by its marshal encoding (exact:
            # True, 1 and 1.0 stay apart)
            try:
                k: Optional[bytes] = marshal.dumps(p)
            except ValueError:
                k = None
            r = cache.get(k) if k is not None else None
            if r is None:
                if (not isinstance(p, (tuple, list)) or len(p) not in (2, 3)
                        or not all(isinstance(c, (int, float)) and not isinstance(c, bool)
                                   and math.isfinite(c) for c in p)):
                    self.error(time, f"outcome {n}: position of agent {i} must be "
                                     f"(x, y, z) finite numbers, got {p!r:.80}")
                r = self.round_pos(p)
                if k is not None:
                    if len(cache) >= 1 << 16:
                        cache.clear()
                    cache[k] = r
            poss.append(r)
        self.check_env(o.env, time, n)
        starts = getattr(o, "starts", None) if self.tracks_legs else None
        if starts is None:
            starts = tuple(ag[REACH][START] for ag in ags)
        else:
            if not isinstance(starts, (tuple, list)) or len(starts) != N:
                self.error(time, f"outcome {n}: 'starts' must have one entry per agent ({N})")
            starts = tuple(self._check_start(x, time, f"outcome {n}") for x in starts)
        return (tuple(poss), tuple(map(bool, o.done)), tuple(map(bool, o.fail)), o.env, starts)

    def check_env(self, env, time, n: Optional[int] = None, where: Optional[str] = None) -> None:
        try:
            check_canonical(env, "env")
        except TypeError as exc:
            if where is None:
                where = "init_env() returned" if n is None else f"outcome {n}:"
            self.error(time, f"{where} {exc} (the env is part of the state, which "
                             f"must have one canonical encoding: use tuples, not lists, "
                             f"sets or dicts)")

    def round_pos(self, p):
        res = self.world.resolution
        if not res:
            out = tuple(float(c) + 0.0 for c in p)
            return out if len(out) == 3 else out + (0.0,) * (3 - len(out))
        try:
            out = tuple(round(round(float(c) / res) * res, 9) + 0.0 for c in p)
        except (OverflowError, ValueError):     # inf, nan, or c / res beyond the float range
            raise PcclError(f"position ({', '.join(f'{float(c):g}' for c in p)}) cannot be "
                            f"rounded to the resolution {res:g}: coordinates must be finite "
                            f"and far from the float limit") from None
        return out if len(out) == 3 else out + (0.0,) * (3 - len(out))


def _type_of(v) -> str:
    return "None" if v is None else type(v).__name__
