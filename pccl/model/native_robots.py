"""The shipped blackboxes in C (``native_c/robots.c``): which searches the
native engine lets C compute DOREACH INVOKE's outcomes for, and the table
of interned values C and Python share.

A program that moves has a memo site for DOREACH INVOKE (:mod:`pccl.model.native`):
its outcomes, per (every robot's status, position and reach cells, the env),
filled at a miss.  For the built-in ``instant``, ``straight``, ``nondet``
and ``nondet-fail`` C fills it (``robots.c``), on whichever of the level
kernel's threads meets the miss, without the GIL; so a moving program's
``--workers N`` threads no longer wait for one another's Python calls.
Python's blackbox stays the reference: C gives its outcomes exactly (the
same positions, bit for bit, the same order), and leaves to Python (the
Python miss, as before) what it cannot reproduce exactly: obstacles
(shapely), ``nondet``'s distance between regions of three or more corners,
a distance or a rounded step the float rounding of ``math.hypot`` could
decide either way (``robots.c`` says which).

C numbers the positions and leg starts it makes, so the interned values'
ids (discovery order, one process) are given by C's table for Python too
(:meth:`NativeModel.intern` asks ``vintern``); Python reads back a value C
made when it decodes a state that holds it (:class:`Values`).  With stable
ids (forked workers) or another blackbox, C computes nothing and Python
fills every miss, as before.  ``PCCL_C_BLACKBOX=0`` turns it off (the
benchmarks' old side; the tests' Python reference).
"""

from __future__ import annotations

import marshal
import math
import os
import weakref
from typing import Any

#: kinds of ``robots.c`` (``BB_*``): 0 none
KINDS = {"instant": 1, "straight": 2, "nondet": 3, "nondet-fail": 4}
#: the most outcomes C makes (robots.c's ROBOTS_KMAX: labels made ahead)
KMAX = 729
ENV_VAR = "PCCL_C_BLACKBOX"

#: the methods each shipped blackbox's outcomes come from (a class or
#: instance whose methods were replaced is not the shipped blackbox)
_METHODS = {"instant": ("step",), "straight": ("step",),
            "nondet": ("step", "hazards", "_region", "_fail_start", "drift", "retarget")}


def _shipped_kind(bb) -> int:
    """The ``robots.c`` kind of blackbox ``bb`` (0: not one C computes)."""
    from pccl.blackboxes import BLACKBOXES
    from pccl.blackboxes.instant import Instant
    from pccl.blackboxes.nondet import Nondet
    from pccl.blackboxes.straight import Straight
    name = next((n for n, x in BLACKBOXES.items() if x is bb), None)
    if name not in KINDS:
        return 0
    cls = {"instant": Instant, "straight": Straight}.get(name, Nondet)
    if type(bb) is not cls or any(callable(v) for v in vars(bb).values()):
        return 0
    mod = cls.__module__
    for meth in _METHODS["nondet" if cls is Nondet else name]:
        f = getattr(cls, meth, None)
        f = getattr(f, "__func__", f)
        if getattr(f, "__module__", None) != mod or getattr(f, "__qualname__", "") != f"{cls.__name__}.{meth}":
            return 0
    if cls is Nondet and (getattr(bb, "always_fail", None) is not (name == "nondet-fail")
                          or getattr(bb, "uses_time", True)):
        return 0
    return KINDS[name]


def _exact_float(x) -> bool:
    return (isinstance(x, (int, float)) and not isinstance(x, bool)
            and math.isfinite(float(x)) and float(x) == x)


def plan(py, gen, stable_ids: bool) -> tuple:
    """``(kind, site, world numbers)`` for ``robots_setup`` of the model
    ``py`` (a :class:`pccl.model.engine.Model`) and its generator: kind 0
    where C computes nothing (stable ids, no env site, a blackbox C does
    not compute, a world with obstacles, ...)."""
    off = (0, -1, (0.0, 0.0, 0.0, 0.0, 0.0))
    if stable_ids or not gen.moves or os.environ.get(ENV_VAR, "1") == "0":
        return off
    sites = [k for k, (what, *_) in enumerate(gen.sites) if what == "env"]
    if len(sites) != 1:
        return off
    kind = _shipped_kind(py.blackbox)
    w = py.world
    if not kind or w.obstacles or type(py.delta) is not int:
        return off
    nums = (w.resolution, w.speed, py.delta, w.radius, w.tolerance)
    if not all(_exact_float(x) for x in nums) or float(py.delta) * float(w.speed) >= 2.0 ** 53:
        return off
    st0 = next(iter(py.init_states()), None)
    from pccl.model.layout import ENV
    if st0 is None or st0[ENV] is not None:     # the env: None for every shipped blackbox
        return off
    return kind, sites[0], tuple(float(x) for x in nums)


def labels(gen, kind: int, n_agents: int) -> list:
    """The label ids of DOREACH INVOKE's outcomes 0, 1, ... that C may
    give (made before the module's setup reads the label list)."""
    if not kind:
        return []
    most = min(KMAX, 3 ** n_agents) if kind in (3, 4) else 1
    return [gen.lab(("DOREACH INVOKE", None, k)) for k in range(most)]


#: id() of a loaded module -> (a weak reference to) the native model whose
#: values its C table holds
_OWNERS: dict = {}


def take_table(model) -> None:
    """Before ``model`` empties its module's C table (``robots_setup``):
    the model that held it (a search of the same source made earlier in
    this process, whose traces may still be decoded) reads every value C
    made for it and numbers its own from then on."""
    ref = _OWNERS.get(id(model.lib))
    prev = ref() if ref is not None else None
    if prev is not None and prev is not model:
        prev._vals.detach()
    _OWNERS[id(model.lib)] = weakref.ref(model)


class Values(dict):
    """The interned values by id (:attr:`NativeModel._vals`): a value C made
    (``robots.c``) is read from C's table the first time Python needs it."""

    def __init__(self, owner: Any):
        super().__init__()
        self.owner = owner
        #: C's table is another model's now (:func:`take_table`): every
        #: value is here, and new ones are numbered here
        self.detached = False

    def detach(self) -> None:
        self.complete()
        self.detached = True

    def __missing__(self, i: int):
        o = self.owner
        k = None if o.stable_ids or self.detached else o.lib.vvalue(i)
        if k is None:
            raise KeyError(i)
        x = marshal.loads(k)
        self[i] = x
        o._ids[k] = i
        o._byobj[id(x)] = i
        return x

    def complete(self) -> None:
        """Every value C made read (before the table is saved whole)."""
        o = self.owner
        if o.stable_ids or self.detached:
            return
        for i in range(o.lib.vcount()):
            if i not in self:
                try:
                    self[i]
                except KeyError:
                    pass
