"""The shipped blackboxes and how to pick one (``--blackbox``).

``BLACKBOXES`` maps each shipped name to its instance; :func:`load_blackbox`
accepts one of those names or ``module:attribute`` for a user's own blackbox
(the interface is described in :mod:`pccl.blackboxes.base`).
"""

from __future__ import annotations

import difflib
import importlib
import importlib.util
import inspect
import os
import sys

from pccl.lang.errors import PcclError

from .base import Blackbox, Motion, Outcome
from .instant import INSTANT, Instant
from .nondet import NONDET, NONDET_FAIL, Nondet
from .pymunk_bb import PYMUNK, PymunkBlackbox
from .straight import STRAIGHT, Straight

BLACKBOXES = {
    "instant": INSTANT,
    "straight": STRAIGHT,
    "nondet": NONDET,
    "nondet-fail": NONDET_FAIL,
    "pymunk": PYMUNK,
}

DEFAULT_BLACKBOX = "straight"

__all__ = ["BLACKBOXES", "DEFAULT_BLACKBOX", "load_blackbox", "Blackbox",
           "Motion", "Outcome", "Instant", "Straight", "Nondet",
           "PymunkBlackbox", "INSTANT", "STRAIGHT", "NONDET", "NONDET_FAIL", "PYMUNK"]

_REQUIRED = ("name", "uses_time", "init_env", "step")


def _names() -> str:
    return ", ".join(sorted(BLACKBOXES))


def load_blackbox(spec: str):
    """A blackbox from a shipped name (``straight``) or ``module:attribute``.

    ``module`` is an importable module name (the current directory is
    searched too) or a path to a ``.py`` file; ``attribute`` is a blackbox
    object, or a class or zero-argument factory returning one.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise PcclError(f"empty blackbox name; valid names: {_names()} "
                        "(or module:attribute for your own)")
    spec = spec.strip()
    if ":" not in spec:
        bb = BLACKBOXES.get(spec) or BLACKBOXES.get(spec.lower())
        if bb is PYMUNK:
            from .pymunk_bb import require
            require()                 # an optional extra: say how to install it
        if bb is not None:
            return bb
        close = difflib.get_close_matches(spec.lower(), list(BLACKBOXES), n=1)
        hint = f" (did you mean '{close[0]}'?)" if close else ""
        raise PcclError(f"unknown blackbox '{spec}'{hint}; valid names: "
                        f"{_names()}, or module:attribute for your own")
    modname, _, attr = spec.rpartition(":")
    if not modname or not attr:
        raise PcclError(f"bad blackbox '{spec}': write module:attribute, "
                        f"e.g. mymodule:BLACKBOX (or one of: {_names()})")
    if modname.lower() in BLACKBOXES and importlib.util.find_spec(modname) is None:
        guess = f"{modname.lower()}-{attr.lower()}"
        hint = (f" (did you mean '{guess}'?)" if guess in BLACKBOXES else "")
        raise PcclError(f"bad blackbox '{spec}': '{modname}' is a shipped blackbox, "
                        f"not a module{hint}; valid names: {_names()}, or "
                        "module:attribute for your own")
    module = _import(modname, spec)
    obj = module
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise PcclError(f"bad blackbox '{spec}': module '{modname}' has no "
                            f"attribute '{attr}'") from None
    if not _is_blackbox(obj) and callable(obj):
        try:
            obj = obj()
        except Exception as e:  # user code: report, never a traceback
            raise PcclError(f"bad blackbox '{spec}': calling {attr}() failed: "
                            f"{type(e).__name__}: {e}") from None
    missing = [a for a in _REQUIRED if not hasattr(obj, a)]
    if missing:
        raise PcclError(f"bad blackbox '{spec}': {attr} is not a blackbox "
                        f"(missing {', '.join(missing)}; see "
                        "pccl.blackboxes.base)")
    if not isinstance(obj.name, str) or not obj.name:
        raise PcclError(f"bad blackbox '{spec}': {attr}.name must be a non-empty "
                        f"string, got {obj.name!r:.60}")
    if not callable(obj.step) or not callable(obj.init_env):
        raise PcclError(f"bad blackbox '{spec}': {attr}.step and "
                        f"{attr}.init_env must be methods")
    return obj


def _is_blackbox(obj) -> bool:
    return (not inspect.isclass(obj)
            and all(hasattr(obj, a) for a in _REQUIRED))


def _import(modname: str, spec: str):
    try:
        if modname.endswith(".py") or os.sep in modname or "/" in modname:
            path = os.path.abspath(modname)
            if not os.path.isfile(path):
                raise PcclError(f"bad blackbox '{spec}': no such file {modname}")
            name = "_pccl_user_blackbox_" + os.path.splitext(
                os.path.basename(path))[0]
            mspec = importlib.util.spec_from_file_location(name, path)
            assert mspec is not None and mspec.loader is not None, path   # a .py file
            module = importlib.util.module_from_spec(mspec)
            sys.modules[name] = module
            mspec.loader.exec_module(module)
            return module
        try:
            return importlib.import_module(modname)
        except ModuleNotFoundError as e:
            cwd = os.getcwd()
            if e.name != modname.split(".")[0] or cwd in sys.path or "" in sys.path:
                raise
            sys.path.insert(0, cwd)
            return importlib.import_module(modname)
    except PcclError:
        raise
    except ModuleNotFoundError as e:
        raise PcclError(f"bad blackbox '{spec}': cannot import module "
                        f"'{modname}' ({e})") from None
    except Exception as e:  # errors in user code: report, never a traceback
        raise PcclError(f"bad blackbox '{spec}': importing '{modname}' failed: "
                        f"{type(e).__name__}: {e}") from None
