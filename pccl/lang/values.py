"""Runtime values of PCCL and the helpers that generated code calls.

Values are plain hashable Python data so that states stay compact:

=============  ==========================================
int            ``int``
bool           ``bool``
float          ``float``
enum           ``int`` (member index; display uses the type)
ItemPosition   ``(x, y, z)`` tuple of floats
List<T>        tuple
array T[n]     tuple of length n
ObstacleList   tuple of polygons, each a tuple of (x, y)
undefined      :data:`UNDEF`
=============  ==========================================

Every stored value is *canonical*: one representation per PCCL value (state
identity hashes the representation, so ``1``, ``1.0`` and ``True`` are three
different states).  A float slot holds a finite ``float`` that is never
``-0.0``; an int slot an ``int`` (never a ``bool``); lists and positions
likewise, at every depth.  The compiler converts at the write paths (see
``Compiler.value``); :func:`fin` and :func:`pos` are the runtime checks.
"""

from __future__ import annotations

import math

from pccl.lang.errors import PcclRuntimeError


#: The value of a declared but never assigned variable.  It is Python's
#: ``Ellipsis`` singleton: no PCCL expression produces it, ``is`` tests are
#: cheap, and unlike a private class it has a canonical byte encoding
#: (``marshal``), which state fingerprints need (see :mod:`pccl.search.fingerprint`).
UNDEF = Ellipsis


def d(value, name):
    """Read check: a variable that may still be undefined."""
    if value is UNDEF:
        raise PcclRuntimeError(f"read of undefined variable '{name}'")
    return value


def ix(container, index):
    """``a[i]`` on arrays and lists, with bounds and definedness checks."""
    if container is UNDEF:
        raise PcclRuntimeError("index into an undefined value")
    if type(index) is not int and not isinstance(index, int):
        raise PcclRuntimeError(f"index {index!r} is not an integer")
    if index < 0 or index >= len(container):
        raise PcclRuntimeError(f"index {index} out of range 0..{len(container) - 1}")
    v = container[index]
    if v is UNDEF:
        raise PcclRuntimeError(f"read of undefined element [{index}]")
    return v


def agent(agents, j, what):
    """Agent j's cell, for ``x[j]``/``v[j]``/``pos[j]``: j must be an agent id."""
    if type(j) is not int or j < 0 or j >= len(agents):
        raise PcclRuntimeError(f"agent index {j!r} out of range 0..{len(agents) - 1} in '{what}'")
    return agents[j]


def agent_var(agents, j, cell, slot, name):
    """Agent j's value of a per-agent variable: ``cell`` 5 for allread
    components (``x[j]``), 4 for locals (``v[j]`` in properties)."""
    v = agent(agents, j, f"{name}[{j}]")[cell][slot]
    if v is UNDEF:
        raise PcclRuntimeError(f"read of undefined variable '{name}[{j}]'")
    return v


def div(a, b):
    """``/``: integer division truncates toward zero; float division otherwise."""
    if b == 0:
        raise PcclRuntimeError("division by zero")
    if type(a) is int and type(b) is int:
        q = abs(a) // abs(b)
        return q if (a >= 0) == (b >= 0) else -q
    return a / b


def mod(a, b):
    """``%``: remainder of truncating division (sign follows the dividend)."""
    if b == 0:
        raise PcclRuntimeError("modulo by zero")
    if type(a) is int and type(b) is int:
        r = abs(a) % abs(b)
        return r if a >= 0 else -r
    return math.fmod(a, b)


#: Integers stored in a state stay below this magnitude (10**4300, the
#: longest integer literal): a value that keeps growing (``x = x * x``) gets
#: the agent stuck instead of eating time and memory without bound.
INT_LIMIT_DIGITS = 4300
INT_LIMIT = 10 ** INT_LIMIT_DIGITS


def ib(v):
    """A computed int about to be stored: within ±10**4300, else the agent
    is stuck."""
    if -INT_LIMIT < v < INT_LIMIT:
        return v
    raise PcclRuntimeError(f"integer overflow: the result has more than "
                           f"{INT_LIMIT_DIGITS:,} digits (about {int(v.bit_length() * 0.30103):,})")


def fin(v):
    """A computed float about to be stored: finite (else the agent is stuck),
    and ``-0.0`` normalised to ``0.0`` (``-0.0 + 0.0 == +0.0``)."""
    if v - v:                     # nan for inf and nan, 0.0 otherwise
        raise PcclRuntimeError("float result is not a number (NaN)" if v != v
                               else f"float overflow: the result is {v}")
    return v + 0.0


def pos(x, y, z=0.0):
    """``ItemPosition(x, y[, z])``: canonical floats, finite."""
    x = float(x) + 0.0
    y = float(y) + 0.0
    z = float(z) + 0.0
    if x - x or y - y or z - z:
        raise PcclRuntimeError(f"ItemPosition({format_number(x)}, {format_number(y)}, "
                               f"{format_number(z)}): coordinate is not finite")
    return (x, y, z)


def dist(p, q):
    return math.sqrt((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2)


def head(xs):
    if xs is UNDEF:
        raise PcclRuntimeError("head of an undefined list")
    if not xs:
        raise PcclRuntimeError("head of an empty list")
    return xs[0]


def chk_list(xs):
    if xs is UNDEF:
        raise PcclRuntimeError("use of an undefined list")
    return xs


def list_add(xs, v):
    return chk_list(xs) + (v,)


def list_remove(xs, v):
    xs = chk_list(xs)
    for k, x in enumerate(xs):
        if x == v:
            return xs[:k] + xs[k + 1:]
    raise PcclRuntimeError(f"remove of an element not in the list: {format_value(v)}")


def set_in(container, path, value):
    """Functional update ``container[path[0]][path[1]]... = value``."""
    if container is UNDEF:
        raise PcclRuntimeError("index into an undefined value")
    k = path[0]
    if type(k) is not int or k < 0 or k >= len(container):
        raise PcclRuntimeError(f"index {k!r} out of range 0..{len(container) - 1}")
    if len(path) > 1:
        value = set_in(container[k], path[1:], value)
    return container[:k] + (value,) + container[k + 1:]


def format_number(v) -> str:
    if isinstance(v, float):
        if not math.isfinite(v):
            return str(v)                       # inf, -inf, nan
        if v == int(v) and abs(v) < 1e15:
            return f"{v:.1f}"
        return f"{v:.6g}"
    if isinstance(v, int) and not isinstance(v, bool):
        return _int_text(v)
    return str(v)


def _int_text(v: int) -> str:
    """``str(v)``, or a short description of an int too long to print
    (Python refuses to convert ints of more than 4,300 digits)."""
    try:
        return str(v)
    except ValueError:
        digits = int(abs(v).bit_length() * 0.30103) + 1
        return f"{'-' if v < 0 else ''}<integer of about {digits:,} digits>"


def format_time(t) -> str:
    """A model time as the traces print it (a float without float noise)."""
    return format_number(t) if isinstance(t, float) else str(t)


def format_value(v, ty=None) -> str:
    """Human-readable value; ``ty`` is a TypeRef-like object (optional),
    used for enum member names (``ty.members``)."""
    if v is UNDEF:
        return "undefined"
    if v is True:
        return "true"
    if v is False:
        return "false"
    members = getattr(ty, "members", None)
    if members is not None and isinstance(v, int):
        return members[v] if 0 <= v < len(members) else str(v)
    if isinstance(v, tuple):
        # three floats are a position unless the type says list (List<float>)
        if (len(v) == 3 and getattr(ty, "kind", None) not in ("list", "array")
                and all(isinstance(c, float) for c in v)):
            return "(" + ", ".join(format_number(c) for c in v) + ")"
        elem = getattr(ty, "elem", None)
        return "[" + ", ".join(format_value(x, elem) for x in v) + "]"
    return format_number(v)


def to_json(v, ty=None):
    if v is UNDEF:
        return None
    members = getattr(ty, "members", None)
    if members is not None and isinstance(v, int) and not isinstance(v, bool):
        return members[v] if 0 <= v < len(members) else v
    if isinstance(v, tuple):
        elem = getattr(ty, "elem", None)
        return [to_json(x, elem) for x in v]
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)                           # JSON has no inf or nan
    if isinstance(v, int) and not isinstance(v, bool) and v.bit_length() > 14_000:
        return _int_text(v)                     # json.dumps cannot print it
    return v
