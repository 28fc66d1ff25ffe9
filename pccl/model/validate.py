"""Argument checks for the Python API (:mod:`pccl.api`).

Every public function of the API checks its arguments first and raises
:class:`~pccl.lang.errors.ArgumentError` (a :class:`~pccl.lang.errors.PcclError` and a
``ValueError``) naming the function and the argument, instead of letting a
``TypeError`` escape from deep inside the engine::

    pccl.api.explore: error: max_states must be an integer >= 1, got 0
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping

from pccl.lang.data import is_integer, is_number
from pccl.lang.errors import ArgumentError


def _fail(func: str, message: str):
    raise ArgumentError(message, filename=f"pccl.api.{func}")


def _show(v) -> str:
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def integer(func, name, v, *, minimum=None, optional=False):
    if v is None and optional:
        return
    if not is_integer(v):
        _fail(func, f"{name} must be an integer{' or None' if optional else ''}, got {_show(v)}")
    if minimum is not None and v < minimum:
        _fail(func, f"{name} must be an integer >= {minimum}, got {v}")


def number(func, name, v, *, minimum=None, positive=False, optional=False):
    if v is None and optional:
        return
    if not is_number(v):
        _fail(func, f"{name} must be a number{' or None' if optional else ''}, got {_show(v)}")
    if not math.isfinite(v):
        _fail(func, f"{name} must be a finite number, got {v}")
    if positive and not v > 0:
        _fail(func, f"{name} must be positive, got {v}")
    if minimum is not None and v < minimum:
        _fail(func, f"{name} must be >= {minimum}, got {v}")


def boolean(func, name, v, *, optional=False):
    if v is None and optional:
        return
    if not isinstance(v, bool):
        _fail(func, f"{name} must be True or False{' or None' if optional else ''}, "
                    f"got {_show(v)}")


def callable_(func, name, v):
    if v is not None and not callable(v):
        _fail(func, f"{name} must be callable or None, got {_show(v)}")


def texts(func, name, v):
    """An iterable of strings (a lone string is the usual mistake)."""
    if isinstance(v, (str, bytes)):
        _fail(func, f"{name} must be a list of strings, not one string: write [{v!r}]")
    if not isinstance(v, Iterable):
        _fail(func, f"{name} must be a list of strings, got {_show(v)}")
    for x in v:
        if not isinstance(x, str):
            _fail(func, f"{name} must contain strings, got {_show(x)}")


def program(func, v, source):
    from pccl.lang.ast import Program
    boolean(func, "source", source)
    if isinstance(v, Program) or isinstance(v, str):
        return
    if isinstance(v, os.PathLike) and not source:
        return
    _fail(func, f"program must be a path, source text (with source=True) or a Program, "
                f"got {_show(v)}")


def lang(func, v):
    """The language a program is read as (``--lang``): None, or one of
    :data:`pccl.lang.files.LANGUAGES`."""
    from pccl.lang.files import LANGUAGES
    if v is None or (isinstance(v, str) and v in LANGUAGES):
        return
    _fail(func, f"lang must be None, 'pccl' or 'koord', got {_show(v)}")


def world(func, v):
    from pccl.lang.world import World
    if v is None or isinstance(v, (str, os.PathLike, World)):
        return
    _fail(func, f"world must be a path, a World or None, got {_show(v)}")


def blackbox(func, v):
    # a name, module:attribute, or an object (checked by the Model)
    if v is None or isinstance(v, str) or not isinstance(v, (int, float, bool, bytes, tuple,
                                                             list, dict, set)):
        return
    _fail(func, f"blackbox must be a name, 'module:attribute' or a blackbox object, "
                f"got {_show(v)}")


def overrides(func, v):
    if v is None:
        return
    if not isinstance(v, Mapping):
        _fail(func, f"overrides must map variable names to PCCL expressions "
                    f"(e.g. {{'k': '2'}}), got {_show(v)}")
    for k, x in v.items():
        if not isinstance(k, str):
            _fail(func, f"overrides: variable names must be strings, got {_show(k)}")
        if not isinstance(x, (str, int, float)) or isinstance(x, bool):
            _fail(func, f"overrides: the value of {k} must be a PCCL expression "
                        f"(a string), got {_show(x)}")


def rates(func, v):
    if v is None:
        return
    if not isinstance(v, Mapping):
        _fail(func, f"rates must map agent indexes to rates (e.g. {{1: 2}}), "
                    f"got {_show(v)}")
    for a, r in v.items():
        integer(func, "rates: an agent index", a, minimum=0)
        integer(func, f"rates: the rate of agent {a}", r, minimum=1)


def reduce_(func, r):
    if not (isinstance(r, str) or (isinstance(r, (list, tuple))
                                   and all(isinstance(x, str) for x in r))):
        _fail(func, f"reduce must be 'auto', 'none' or a list of reduction names, "
                    f"got {_show(r)}")
    from pccl.model.reduce import parse_request
    from pccl.lang.errors import PcclError
    try:
        parse_request(r)
    except PcclError as e:
        _fail(func, e.message if hasattr(e, "message") else str(e))


#: The execution models (docs/koord.md, "Semantics"): PCCL's (spec section 4)
#: and Koord's round semantics (spec section 14).
SEMANTICS = ("pccl", "koord")


def model_options(func, options: dict, names: Iterable[str]):
    """Check the model's ``options`` (a dict of some of ``names``: the
    options this check knows, :data:`pccl.model.options.MODEL_OPTIONS`)."""
    names = tuple(names)
    unknown = sorted(set(options) - set(names))
    if unknown:
        _fail(func, f"unknown option{'s' if len(unknown) > 1 else ''} "
                    f"{', '.join(unknown)}; options are {', '.join(names)}")
    if "delta" in options:
        number(func, "delta", options["delta"], positive=True)
    if "n0" in options:
        integer(func, "n0", options["n0"], minimum=1)
    rates(func, options.get("rates"))
    if "events" in options and options["events"] not in ("any", "first"):
        _fail(func, f"events must be 'any' or 'first', got {_show(options['events'])}")
    if "semantics" in options and options["semantics"] not in SEMANTICS:
        _fail(func, f"semantics must be None, 'pccl' or 'koord', got {_show(options['semantics'])}")
    if "skip_events" in options:
        boolean(func, "skip_events", options["skip_events"])
    if "max_time" in options:
        number(func, "max_time", options["max_time"], minimum=0, optional=True)
    if "abstract_time" in options:
        boolean(func, "abstract_time", options["abstract_time"], optional=True)
    if "collisions" in options:
        boolean(func, "collisions", options["collisions"])
    if "reduce" in options:
        reduce_(func, options["reduce"])
    if "invariants" in options:
        texts(func, "invariants", options["invariants"])
    if "properties" in options:
        texts(func, "properties", options["properties"])
    if "rand_policy" in options:
        callable_(func, "rand_policy", options["rand_policy"])
    fs = options.get("functions")
    if fs is not None and not isinstance(fs, Mapping):
        _fail(func, f"functions must map names to values, got {_show(fs)}")


def search_args(func, *, depth, max_states, deadlock, find_all, exact, progress,
                max_memory="default"):
    if max_memory != "default":
        integer(func, "max_memory", max_memory, minimum=1, optional=True)
    integer(func, "depth", depth, minimum=0, optional=True)
    integer(func, "max_states", max_states, minimum=1, optional=True)
    boolean(func, "deadlock", deadlock)
    boolean(func, "find_all", find_all)
    boolean(func, "exact", exact)
    callable_(func, "progress", progress)
